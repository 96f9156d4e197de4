"""Shared geometry: image grids over local metres and signed distance functions."""
