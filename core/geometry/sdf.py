"""Signed distance functions of regions on a grid (paper Algorithm 3).

Convention of the paper (section 3.2.1): positive inside the region, negative
outside, zero on the boundary. :func:`signed_distance` is the distance of a
pixel region; :func:`region_signed_distance` that of a polygonal region, exact
near its boundary (the morph's level sets and the surfaces' sections);
:func:`smoothed_section` takes the waver out of a boundary drawn between holes; :func:`closed_gaps` fills the
gaps and embayments of a section narrower than a disc, taking nothing away.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import MultiPolygon, Polygon

from core.geometry.grid import Grid, local_gaussian_filter


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


def boundary_distance(region: Polygon | MultiPolygon, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Distance (metres) from each point ``(xs, ys)`` to the boundary of ``region``, its holes' rings included.

    Exactly what ``shapely.distance(region.boundary, points)`` gives, but each
    point is measured to the segments an STRtree finds nearest, not to every
    segment of the boundary: from the 7,700 cells along a contour of 4,000
    vertices 0.07 s instead of 0.31 s (the constructed prediction tests ran
    10% faster).
    """
    rings = shapely.get_parts(shapely.boundary(shapely.get_parts(region)))
    coords, ring = shapely.get_coordinates(rings, return_index=True)
    same = ring[:-1] == ring[1:]  # consecutive vertices of one ring
    if not same.any():  # an empty region: no boundary, as far as GEOS is concerned (nan)
        return np.full(len(xs), np.nan)
    segments = shapely.linestrings(np.stack([coords[:-1][same], coords[1:][same]], axis=1))
    (which, _), distance = shapely.STRtree(segments).query_nearest(
        shapely.points(xs, ys), return_distance=True, all_matches=False
    )
    out = np.empty(len(xs))
    out[which] = distance
    return out


def region_signed_distance(
    grid: Grid, region: Polygon | MultiPolygon, band_cells: float = 2.0, mask: np.ndarray | None = None
) -> np.ndarray:
    """Signed distance (metres, positive inside) of a polygonal region on ``grid``, exact near its boundary.

    Parameters
    ----------
    grid : Grid
        The cells; distances are from their centres.
    region : Polygon or MultiPolygon
        The region, holes allowed, in the grid's frame (metres).
    band_cells : float
        Width, in cells, of the band around the boundary where distances are exact.
    mask : (rows, cols) bool array, optional
        The region's cells, when the caller has rasterised it already (e.g.
        with :meth:`Grid.rasterize`, whose cells on the boundary itself may
        differ); by default the cells whose centres lie inside.

    Returns
    -------
    (rows, cols) float array

    Notes
    -----
    The region's raster (cells whose centres lie inside, holes honoured,
    by prepared shapely point-in-polygon unless ``mask`` is given) gets the exact Euclidean
    distance transform of :func:`signed_distance` (paper Algorithm 3). Within
    ``band_cells`` of the boundary that raster value is replaced by the exact
    distance to the polygon boundary, signed by the exact point-in-polygon
    test, so the zero level follows the polygon to sub-cell accuracy, not its
    pixels: morph particles start and stop on the real contours and surfaces
    are not stair-stepped. A region thinner than a cell (no cell centre
    inside) is placed by exact distances in a 7 x 7 cell window around it,
    minus 3 cells elsewhere. An empty region is everywhere far outside.
    """
    h = grid.cell_size_m
    X, Y = grid.cell_centres()
    shapely.prepare(region)
    if mask is None:
        mask = shapely.contains_xy(region, X, Y)
    sdf = signed_distance(mask, h)
    if region.is_empty:
        return sdf
    band = np.abs(sdf) <= band_cells * h
    if not mask.any():
        r0, c0 = grid.nearest_cells(np.array(region.representative_point().coords))[0]
        band = np.zeros(grid.shape, dtype=bool)
        band[max(r0 - 3, 0) : r0 + 4, max(c0 - 3, 0) : c0 + 4] = True
        sdf = np.full(grid.shape, -3.0 * h)
    xs, ys = X[band], Y[band]
    d = boundary_distance(region, xs, ys)
    sdf[band] = np.where(shapely.contains_xy(region, xs, ys), d, -d)
    return sdf


def closed_gaps(distance: np.ndarray, radius_m: float, cell_size_m: float) -> np.ndarray:
    """A section's signed distance closed by a disc of ``radius_m``: gaps and embayments narrower than its diameter filled.

    The morphological closing (dilation, then erosion, by the disc) of the
    region ``distance > 0``, from Euclidean distance transforms: a gap, neck
    or embayment narrower than ``2 * radius_m`` is filled, a body of any
    size keeps all of its area, and bodies further apart than the diameter
    stay apart. Inside the closed region the result is at least the closed
    region's own signed distance; elsewhere it is ``distance``.

    Parameters
    ----------
    distance : (rows, cols) float
        Signed distance, metres, positive inside.
    radius_m, cell_size_m : float

    Returns
    -------
    (rows, cols) float
    """
    if radius_m <= 0 or not (distance > 0).any():
        return distance
    r_cells = radius_m / cell_size_m
    grown = ndimage.distance_transform_edt(distance <= 0) <= r_cells
    if grown.all():  # nothing outside to erode from: the closing of a region filling the grid is the grid
        return np.maximum(distance, cell_size_m)
    closed = ndimage.distance_transform_edt(grown) * cell_size_m - radius_m  # > 0 in the closed region
    return np.where(grown, np.maximum(distance, closed), distance)


def smoothed_section(distance: np.ndarray, cell_size_m: float, sigma_m: float, along_m: float) -> np.ndarray:
    """A section's signed distance smoothed by a Gaussian of ``sigma_m`` near its boundary, the boundary kept in place.

    A bench's boundary runs between its holes and wavers by a fraction of a
    spacing from where the geozone's boundary is; the waver does not repeat
    from bench to bench, and carried on it is error
    (:data:`core.model.extrapolation.SECTION_SMOOTHING_SPACINGS`, and each contour on its bench:
    :data:`core.extraction.contours.CONTOUR_SMOOTHING_SPACINGS`). A Gaussian of a signed distance takes
    out wavers shorter than a few ``sigma_m``, but moves a curved boundary
    inwards (by ``sigma_m ** 2 k / 2``, ``k`` its curvature: ``F`` spreads as by
    the heat equation and ``lap F = -k`` on a signed distance; at half a
    spacing a disc two spacings across lost 30% of its area). That shift is
    the change the Gaussian makes averaged along the boundary over ``along_m``
    (where a waver's change averages out) and is put back. The change is
    bounded by ``sigma_m / 2``, so a gap or a neck wider than ``sigma_m``
    (two bodies that have just split) is not closed or cut, and it fades out
    from one to two ``sigma_m`` off the boundary: what a boundary's movement
    carries is its zero level, and a narrow body's ridge (the value a strip
    moving further than its half-width is carried by) stays.

    Parameters
    ----------
    distance : (rows, cols) float
        Signed distance, metres, positive inside.
    cell_size_m, sigma_m, along_m : float

    Returns
    -------
    (rows, cols) float
    """
    return smoothed_sections(distance, cell_size_m, [sigma_m], along_m)[0]


def smoothed_sections(
    distance: np.ndarray, cell_size_m: float, sigmas_m: list[float], along_m: float
) -> list[np.ndarray]:
    """:func:`smoothed_section` at each of ``sigmas_m``; the boundary's band and weights along it are found once."""
    band = np.abs(distance) <= cell_size_m
    if not band.any():
        return [distance for _ in sigmas_m]
    along = along_m / cell_size_m
    weight = np.maximum(local_gaussian_filter(band.astype(float), along), 1e-9)
    _, (r, c) = ndimage.distance_transform_edt(~band, return_indices=True)
    out = []
    for sigma_m in sigmas_m:
        change = ndimage.gaussian_filter(distance, sigma_m / cell_size_m, mode="nearest") - distance
        shift = local_gaussian_filter(np.where(band, change, 0.0), along) / weight
        fade = np.clip(2.0 - np.abs(distance) / sigma_m, 0.0, 1.0)
        out.append(distance + fade * np.clip(change - shift[r, c], -0.5 * sigma_m, 0.5 * sigma_m))
    return out
