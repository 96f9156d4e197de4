"""Signed distance functions of regions on a grid (paper Algorithm 3).

Convention of the paper (section 3.2.1): positive inside the region, negative
outside, zero on the boundary.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage


def signed_distance(mask: np.ndarray, cell_size_m: float = 1.0) -> np.ndarray:
    """Exact Euclidean signed distance of a pixel region, positive inside.

    Parameters
    ----------
    mask : (rows, cols) bool array
        The region.
    cell_size_m : float
        Cell size, so the result is in metres.

    Returns
    -------
    (rows, cols) float array
        Distance from each cell centre to the region boundary, which lies half
        a cell outside the outermost region cells (the half-pixel correction of
        ``../shared/ALGORITHMS.md``); positive inside, negative outside.

    Notes
    -----
    Two exact Euclidean distance transforms (Maurer's algorithm in
    ``scipy.ndimage.distance_transform_edt``): one of the region, one of its
    complement. An empty mask is everywhere "far outside"; a full mask is
    everywhere "far inside" (the grid diagonal is used as the distance).
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return np.full(mask.shape, -float(np.hypot(*mask.shape)) * cell_size_m)
    if mask.all():
        return np.full(mask.shape, float(np.hypot(*mask.shape)) * cell_size_m)
    inside = ndimage.distance_transform_edt(mask)
    outside = ndimage.distance_transform_edt(~mask)
    return np.where(mask, inside - 0.5, -(outside - 0.5)) * cell_size_m
