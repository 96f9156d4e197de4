"""Contour metamorphosis (paper section 4): level-set morph, particle trajectories, curvelet backtracking."""
