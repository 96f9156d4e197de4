"""Spatial correspondence (paper section 3): associate and align components of successive benches."""
