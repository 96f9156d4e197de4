"""The transition field of a bench: where each geozone's boundary passes (paper sections 2.2-2.4).

Between two holes of different geozones the boundary is, on the evidence of
the labels alone, half-way between them (the paper's entropy boundary holes
sit on either side of it); at the edge of the drilled area it is where
sampling stopped (gap closure, section 2.3). The *transition field* of
geozone ``g`` encodes both as a signed distance on an image grid (positive
inside, the paper's SDF convention, section 3.2.1)::

    phi_g(x) = 1/2 (min over h != g of d_h(x)  -  d_g(x))

with ``d_h`` the distance to the nearest hole of geozone ``h``: zero on the
perpendicular bisector between a hole of ``g`` and its nearest neighbour of
another geozone, ``+-`` the distance to that bisector elsewhere. The raw
bisector zig-zags with the drilling pattern, so the field is smoothed over
about a hole spacing before use; a body one hole wide keeps a positive ridge
through its holes, so strips 1-3 holes wide survive the smoothing. The
geozones of the bench then partition the drilled area by the largest
smoothed field.

The edge map of a component (section 2.4) is the ridge along the zero set of
its field: it holds the transitions to every other geozone and the drilling
frontier, and nothing inside the component, so the GVF snake (section 2.5)
has one line to settle on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from skimage.morphology import disk

from core.geometry.grid import Grid, cell_size_within, cells_covering

#: Cell size of the bench grid, in hole spacings: fine enough to place a
#: boundary to a quarter of the spacing the holes resolve.
CELL_SPACINGS = 0.25
#: A bench grid holds at most this many cells squared (coarser cells beyond; keeps huge benches cheap).
MAX_CELLS = 1200


@dataclass
class TransitionField:
    """Smoothed transition fields of every geozone on one bench.

    Attributes
    ----------
    grid : Grid
        Bench grid (local metres).
    geozones : list of str
        Geozone of each field, in order.
    phi : (g, rows, cols) float
        Smoothed signed distance to each geozone's boundary (positive inside), metres.
    drilled_sdf : (rows, cols) float
        Signed distance to the edge of the drilled area (positive inside), metres.
    label : (rows, cols) int
        Index into ``geozones`` of the geozone each cell belongs to; -1 outside the drilled area.
    """

    grid: Grid
    geozones: list[str]
    phi: np.ndarray
    drilled_sdf: np.ndarray
    label: np.ndarray

    def sides(self, i: int, window: tuple[slice, slice] = (slice(None), slice(None))) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`region_sdf` of geozone ``i`` and the signed distance to every other geozone's region, together.

        The second (positive inside the others' region, drilled area only) has
        the zero set the first has between geozones, to a fraction of a cell,
        where the cells of :attr:`label` make a staircase; one margin for both.
        """
        phi = self.phi[(slice(None), *window)]
        drilled = self.drilled_sdf[window]
        if len(self.geozones) == 1:  # nothing else: "far outside" everywhere, finite for marching squares
            far = float(np.hypot(*self.grid.shape)) * self.grid.cell_size_m
            return drilled.copy(), np.full(phi.shape[1:], -far)
        # Half the margin of i's field over the strongest other's: both fields move with the boundary.
        margin = 0.5 * (phi[i] - np.max(np.delete(phi, i, axis=0), axis=0))
        return np.minimum(margin, drilled), np.minimum(-margin, drilled)

    def region_sdf(self, i: int, window: tuple[slice, slice] = (slice(None), slice(None))) -> np.ndarray:
        """Signed distance to the boundary of geozone ``i``'s region (positive inside), metres.

        The margin of its field over the strongest other geozone, halved (both
        move with the boundary), capped by the drilled-area distance; on the
        cells of ``window`` (row and column slices) only, if given.
        """
        return self.sides(i, window)[0]


def bench_grid(xy: np.ndarray, hole_spacing_m: float, margin_spacings: float = 3.0) -> Grid:
    """Grid over a bench's holes with cells of :data:`CELL_SPACINGS` spacings (at most :data:`MAX_CELLS` squared)."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    width, height = hi - lo
    cell = cell_size_within(width, height, CELL_SPACINGS * hole_spacing_m, MAX_CELLS)
    margin = cells_covering(margin_spacings * hole_spacing_m, cell)
    return Grid.covering((lo[0], lo[1], hi[0], hi[1]), cell, margin_cells=margin)


def nearest_hole(xy: np.ndarray, grid: Grid) -> np.ndarray:
    """Index into ``xy`` (at least one hole) of the hole nearest each cell, ``(rows, cols)``.

    One exact Euclidean distance transform finds each cell's nearest cell
    holding a hole: exact up to which of two almost equidistant holes is
    nearest (a fraction of a cell).
    """
    rc = grid.nearest_cells(xy)
    holder = np.full(grid.shape, -1)
    holder[rc[:, 0], rc[:, 1]] = np.arange(len(xy))
    _, (ri, ci) = ndimage.distance_transform_edt(holder < 0, return_indices=True)
    return holder[ri, ci]


def hole_distances(xy: np.ndarray, labels: np.ndarray, geozones: list[str], grid: Grid) -> np.ndarray:
    """Distance from every cell to the nearest hole of each geozone, metres, shape ``(g, rows, cols)``.

    Measured to the hole :func:`nearest_hole` finds among the geozone's, not
    to the cell holding it.
    """
    X, Y = grid.cell_centres()
    out = np.empty((len(geozones), *grid.shape))
    for i, g in enumerate(geozones):
        sel = np.flatnonzero(labels == g)
        nearest = sel[nearest_hole(xy[sel], grid)]
        out[i] = np.hypot(X - xy[nearest, 0], Y - xy[nearest, 1])
    return out


def drilled_mask(distance_to_hole_m: np.ndarray, hole_spacing_m: float, cell_size_m: float) -> np.ndarray:
    """Drilled area on the grid: within 0.75 spacings of a hole, closed over one spacing.

    The raster form of :func:`core.io.blastholes.drilled_area` (discs of 0.75
    spacings around the holes, gaps of a spacing closed): sampling stopped
    half a spacing or so past the outermost holes.
    """
    near = distance_to_hole_m <= 0.75 * hole_spacing_m
    radius = max(int(round(hole_spacing_m / cell_size_m)), 1)
    padded = np.pad(near, radius)
    closed = ndimage.binary_closing(padded, disk(radius))
    return closed[radius:-radius, radius:-radius] | near


def transition_field(
    xy: np.ndarray,
    labels: np.ndarray,
    hole_spacing_m: float,
    grid: Grid,
    smoothing_m: float,
) -> TransitionField:
    """Transition fields of every geozone of a bench (see the module docstring).

    Parameters
    ----------
    xy : (n, 2) float
        Holes of the bench, metres.
    labels : (n,) array
        Their geozones (label noise already absorbed).
    hole_spacing_m : float
        Hole spacing of the bench (sets the drilled area, see :func:`drilled_mask`).
    grid : Grid
    smoothing_m : float
        Standard deviation of the Gaussian that smooths the bisector's zig-zag.
    """
    geozones = sorted(set(np.asarray(labels).tolist()))
    distance = hole_distances(xy, labels, geozones, grid)
    sigma = smoothing_m / grid.cell_size_m
    if len(geozones) > 1:
        two = np.partition(distance, 1, axis=0)[:2]  # nearest and second-nearest geozone distance per cell
        phi = np.empty_like(distance)
        for i in range(len(geozones)):
            nearest_other = np.where(distance[i] == two[0], two[1], two[0])
            raw = 0.5 * (nearest_other - distance[i])
            phi[i] = smooth_without_shrinking(raw, sigma) if sigma > 0 else raw
        label = np.argmax(phi, axis=0)
    else:
        phi = -distance  # a single geozone: everything drilled is it
        label = np.zeros(grid.shape, int)
    h = grid.cell_size_m
    drilled = drilled_mask(distance.min(axis=0), hole_spacing_m, h)
    drilled_sdf = (ndimage.distance_transform_edt(drilled) - ndimage.distance_transform_edt(~drilled)) * h
    label = np.where(drilled, label, -1)
    return TransitionField(grid, geozones, phi, drilled_sdf, label)


def smooth_without_shrinking(field: np.ndarray, sigma_cells: float) -> np.ndarray:
    """Gaussian smoothing of a signed distance whose zero set does not move with its curvature.

    ``G_s * phi ~ phi + s^2/2 Lap(phi)``: plain smoothing moves a boundary
    inwards by about ``s^2 kappa / 2`` (a pod of radius ``R`` shrinks by
    ``s^2 / 2R``). ``2 G_s * phi - G_(s sqrt 2) * phi`` cancels that term
    (Richardson extrapolation in ``s^2``) and still averages out the
    bisector's zig-zag, whose wavelength is a hole spacing.
    """
    once = ndimage.gaussian_filter(field, sigma_cells)
    return 2.0 * once - ndimage.gaussian_filter(field, sigma_cells * np.sqrt(2.0))


def edge_map(region_sdf: np.ndarray, cell_size_m: float, width_cells: float = 1.5) -> np.ndarray:
    """Edge map of a region (section 2.4): a ridge of height 1 along the zero set of its signed distance.

    ``f = exp(-(phi / w)^2)`` with ``w = width_cells`` cells: thin, so the GVF
    (section 2.5) points at the ridge's crest from both sides and the snake
    settles on the boundary itself rather than on the inner side of a band.
    """
    w = width_cells * cell_size_m
    return np.exp(-np.square(np.nan_to_num(region_sdf, posinf=1e9, neginf=-1e9) / w))
