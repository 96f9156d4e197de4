"""Regular image grids laid over the local (metre) frame.

Every stage that works on images (edge maps, GVF, SDFs, level sets) maps
between world coordinates and pixels through a :class:`Grid`. The paper uses
uniform quantisation throughout (section 2.4, footnote on image mapping); this
module is that mapping, in one place.

Conventions: array index ``[row, col]``; cell ``(i, j)`` has its centre at
``(x0 + j * cell_size_m, y0 + i * cell_size_m)``; so rows run with +y.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import MultiPolygon, Polygon
from skimage.measure import find_contours


def cell_size_within(width_m: float, height_m: float, cell_size_m: float, max_cells: int) -> float:
    """``cell_size_m``, or coarser so that a grid over ``width_m`` by ``height_m`` holds at most ``max_cells ** 2`` cells.

    The budget is the area's, not the longer side's: a square table coarsens as it did at ``max_cells`` across,
    while a long one (two pits side by side, a pit along a valley) keeps its cells. Capped by the longer side,
    two pits 3 km apart got bench grids twice as coarse as either pit alone, and contours 1-2% of their area apart.
    """
    width_m, height_m = max(float(width_m), cell_size_m), max(float(height_m), cell_size_m)
    return max(cell_size_m, float(np.sqrt(width_m * height_m)) / max_cells)


def cells_covering(length_m: float, cell_size_m: float) -> int:
    """Whole cells that cover ``length_m``: the ceiling of the ratio, taken as the whole number it is within 1e-9.

    Lengths in hole spacings over cells in hole spacings are whole numbers up to
    rounding, which a bare ceiling turned into one cell more or not by the last
    bit of the spacing: the same holes read in feet and in metres got windows a
    cell apart and snakes 0.6 m apart.
    """
    ratio = length_m / cell_size_m
    return int(np.ceil(ratio - 1e-9 * max(abs(ratio), 1.0)))


@dataclass(frozen=True)
class Grid:
    """A regular grid of square cells over the local frame.

    Attributes
    ----------
    x0, y0 : float
        Local coordinates (metres) of the centre of cell ``[0, 0]``.
    cell_size_m : float
        Cell edge length in metres.
    shape : tuple of int
        ``(rows, cols)``.
    """

    x0: float
    y0: float
    cell_size_m: float
    shape: tuple[int, int]

    @classmethod
    def covering(
        cls,
        bounds: tuple[float, float, float, float],
        cell_size_m: float,
        margin_cells: int = 8,
    ) -> Grid:
        """Smallest grid covering ``bounds = (xmin, ymin, xmax, ymax)`` plus a margin."""
        xmin, ymin, xmax, ymax = (float(b) for b in bounds)
        if not (cell_size_m > 0 and np.isfinite(cell_size_m)):
            raise ValueError(f"cell size must be positive, got {cell_size_m}")
        cols = cells_covering(xmax - xmin, cell_size_m) + 1 + 2 * margin_cells
        rows = cells_covering(ymax - ymin, cell_size_m) + 1 + 2 * margin_cells
        return cls(
            x0=xmin - margin_cells * cell_size_m,
            y0=ymin - margin_cells * cell_size_m,
            cell_size_m=float(cell_size_m),
            shape=(rows, cols),
        )

    @classmethod
    def for_extent(
        cls,
        bounds: tuple[float, float, float, float],
        cells_across: int = 240,
        margin_cells: int = 8,
        min_cell_size_m: float = 0.0,
    ) -> Grid:
        """Grid of about ``cells_across`` cells along the longer side of ``bounds``.

        The paper's edge maps use ``n_x * n_y ~ 240^2`` with a margin ``p = 8``
        (Fig. 4 caption). ``min_cell_size_m`` stops tiny components from getting
        needlessly fine cells.
        """
        xmin, ymin, xmax, ymax = bounds
        span = max(xmax - xmin, ymax - ymin, 1e-9)
        cell = max(span / max(cells_across - 2 * margin_cells - 1, 1), min_cell_size_m)
        return cls.covering(bounds, cell, margin_cells)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the cell centres."""
        rows, cols = self.shape
        return (
            self.x0,
            self.y0,
            self.x0 + (cols - 1) * self.cell_size_m,
            self.y0 + (rows - 1) * self.cell_size_m,
        )

    def xy_to_rc(self, xy: np.ndarray) -> np.ndarray:
        """World ``(n, 2)`` x, y to fractional ``(n, 2)`` row, col."""
        xy = np.asarray(xy, dtype=float)
        return np.column_stack([(xy[..., 1] - self.y0) / self.cell_size_m, (xy[..., 0] - self.x0) / self.cell_size_m])

    def nearest_cells(self, xy: np.ndarray) -> np.ndarray:
        """World ``(n, 2)`` x, y to the ``(n, 2)`` int row, col of the nearest cell (points off the grid: its edge)."""
        return np.clip(np.rint(self.xy_to_rc(xy)).astype(int), 0, np.array(self.shape) - 1)

    def rc_to_xy(self, rc: np.ndarray) -> np.ndarray:
        """Fractional ``(n, 2)`` row, col to world ``(n, 2)`` x, y."""
        rc = np.asarray(rc, dtype=float)
        return np.column_stack([self.x0 + rc[..., 1] * self.cell_size_m, self.y0 + rc[..., 0] * self.cell_size_m])

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """``(X, Y)`` arrays of cell centre coordinates, each of ``shape``."""
        rows, cols = self.shape
        xs = self.x0 + np.arange(cols) * self.cell_size_m
        ys = self.y0 + np.arange(rows) * self.cell_size_m
        return np.meshgrid(xs, ys)

    def shifted(self, dx_m: float, dy_m: float) -> Grid:
        """The same grid moved by ``(dx_m, dy_m)``."""
        return Grid(self.x0 + dx_m, self.y0 + dy_m, self.cell_size_m, self.shape)

    def rasterize(self, geometry: Polygon | MultiPolygon) -> np.ndarray:
        """Boolean mask of the cells whose centres lie inside ``geometry`` (holes honoured)."""
        mask = np.zeros(self.shape, dtype=bool)
        for poly in _polygons(geometry):
            part = ring_cells(self.xy_to_rc(np.asarray(poly.exterior.coords)), self.shape)
            for ring in poly.interiors:
                part &= ~ring_cells(self.xy_to_rc(np.asarray(ring.coords)), self.shape)
            mask |= part
        return mask

    def sample(self, field: np.ndarray, xy: np.ndarray, order: int = 1) -> np.ndarray:
        """Interpolate ``field`` (of ``shape``) at world points ``xy`` (bilinear by default)."""
        rc = self.xy_to_rc(xy)
        return ndimage.map_coordinates(field, rc.T, order=order, mode="nearest")

    def polygons_from_field(self, field: np.ndarray, level: float = 0.0) -> MultiPolygon:
        """Region ``field > level`` as valid world polygons (holes allowed).

        Uses marching squares (``skimage.measure.find_contours``) on a padded
        field so every ring closes; rings are combined by symmetric difference,
        which handles any nesting of islands and holes.
        """
        return self._enclosed_by(_level_rings(np.asarray(field, dtype=float), level))

    def polygons_from_distance(
        self, distance: np.ndarray, small_radius_cells: float = 4.0, points_per_cell: int = 3
    ) -> MultiPolygon:
        """Region ``distance > 0`` of a signed distance field, small bodies followed between the cells.

        Marching squares (:meth:`polygons_from_field`) places each vertex
        where the field crosses zero along a cell edge and joins vertices by
        chords, which cut off the segments of a curved boundary: a disc loses
        about ``1 / (4 r^2)`` of its area, ``r`` its radius in cells (5.5% at
        two cells, 0.6% at six). A lens a few holes across, held on a bench,
        lost its holding reference's F1 that way. Rings enclosing less than a
        disc of ``small_radius_cells`` get ``points_per_cell - 1`` more points
        on every chord, each moved onto the zero set of the field's cubic
        spline by one Newton step along its gradient (at most half a cell):
        the sub-cell boundary the distances describe (the paper's SDF,
        section 3.2.1). The chords' ends stay: they are the field's crossings
        on the cell edges, between values that are exact next to a contour
        (:func:`core.model.extrapolation.exact_near_boundary`), where the
        spline also rests on the cells further in, whose distances are only
        a cell's: moved too, a bench's lens 2-3 cells in radius came out 1-2%
        larger than its contour, 0.2-0.9% with them kept (marching squares:
        2-5% smaller). Larger rings keep their chords: their loss is a
        fraction of a percent, and following the spline of a transported
        field there cost 0.1-0.2 F1 points on strips, folds and splits
        (development seeds).
        """
        field = np.asarray(distance, dtype=float)
        if not (field > 0).any():
            return MultiPolygon()
        rings = _level_rings(field, 0.0)
        small = [k for k, rc in enumerate(rings) if _ring_area(rc) < np.pi * small_radius_cells**2]
        if small:  # the spline is over half the work, and most fields have no small ring
            finite = np.isfinite(field)
            # One nan or inf would spread through every coefficient of the spline.
            spline_field = np.where(finite, field, np.min(field[finite], initial=0.0) - 1.0)
            coeffs = ndimage.spline_filter(spline_field, order=3, mode="nearest")
        for k in small:
            rc = _densified(rings[k], points_per_cell)
            added = np.arange(len(rc)) % points_per_cell != 0  # the chords' ends are on the zero set already
            rc[added] = _onto_zero_set(coeffs, rc[added])
            rings[k] = rc
        return self._enclosed_by(rings)

    def _enclosed_by(self, rings: list[np.ndarray]) -> MultiPolygon:
        """The region closed rings of (row, col) points enclose, combined by symmetric difference (any nesting)."""
        region = Polygon()
        for rc in rings:
            region = region.symmetric_difference(shapely.make_valid(Polygon(self.rc_to_xy(rc))))
        return as_multipolygon(region)

    def polygons_from_mask(self, mask: np.ndarray) -> MultiPolygon:
        """Region of a boolean mask as world polygons (boundary at half a cell)."""
        return self.polygons_from_field(np.asarray(mask, dtype=float), 0.5)


def _level_rings(field: np.ndarray, level: float) -> list[np.ndarray]:
    """Closed rings (row, col) of ``field`` at ``level`` by marching squares, padded so every ring closes."""
    low = min(float(np.nanmin(field)), level) - 1.0
    padded = np.pad(field, 1, constant_values=low)
    return [ring - 1.0 for ring in find_contours(padded, level) if len(ring) >= 4]


def _densified(ring: np.ndarray, points_per_chord: int) -> np.ndarray:
    """A closed ring of (row, col) points with ``points_per_chord - 1`` evenly spaced points added on each chord."""
    start, step = ring[:-1], np.diff(ring, axis=0)
    t = np.arange(points_per_chord) / points_per_chord
    dense = (start[:, None, :] + t[None, :, None] * step[:, None, :]).reshape(-1, 2)
    return np.vstack([dense, dense[:1]])


def _ring_area(rc: np.ndarray) -> float:
    """Area enclosed by a closed ring of (row, col) points, in cells (shoelace)."""
    return 0.5 * abs(float(np.dot(rc[:-1, 0], rc[1:, 1]) - np.dot(rc[1:, 0], rc[:-1, 1])))


def _onto_zero_set(coeffs: np.ndarray, rc: np.ndarray, delta: float = 0.25) -> np.ndarray:
    """Points (row, col) moved by one Newton step onto the zero set of a cubic spline (``coeffs``).

    The gradient is a central difference over ``delta`` cells; the step is
    bounded by half a cell, and points on the grid's border (where the ring
    was closed by padding) or without a finite step stay.
    """

    def at(points: np.ndarray) -> np.ndarray:
        return ndimage.map_coordinates(coeffs, points.T, order=3, mode="nearest", prefilter=False)

    f = at(rc)
    grad = np.column_stack(
        [(at(rc + [delta, 0.0]) - at(rc - [delta, 0.0])), (at(rc + [0.0, delta]) - at(rc - [0.0, delta]))]
    ) / (2 * delta)
    norm2 = np.maximum(np.sum(grad**2, axis=1), 1e-12)
    step = -(f / norm2)[:, None] * grad
    length = np.hypot(step[:, 0], step[:, 1])
    step *= np.minimum(1.0, 0.5 / np.maximum(length, 1e-12))[:, None]
    rows, cols = coeffs.shape
    inner = (rc[:, 0] > 0) & (rc[:, 0] < rows - 1) & (rc[:, 1] > 0) & (rc[:, 1] < cols - 1)
    inner &= np.all(np.isfinite(step), axis=1)
    return np.where(inner[:, None], rc + step, rc)


def ring_cells(rc: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Cells of ``shape`` whose centres lie inside or on the closed ring of ``(n, 2)`` (row, col) vertices.

    The cells :func:`skimage.draw.polygon` draws, to the cell (the crossing
    test of O'Rourke, Computational Geometry in C, 7.4: a centre on an edge or
    a vertex is inside), found row by row from the edges that straddle each
    row rather than by testing every edge at every cell of the ring's bounding
    box: a contour of a few thousand vertices took 0.7 s that way, 11 ms a
    ring in a Kennecott build.
    """
    r, c = np.ascontiguousarray(rc[:, 0], float), np.ascontiguousarray(rc[:, 1], float)
    mask = np.zeros(shape, dtype=bool)
    r0, r1 = int(max(0, r.min())), min(shape[0] - 1, int(np.ceil(r.max())))
    c0, c1 = int(max(0, c.min())), min(shape[1] - 1, int(np.ceil(c.max())))
    if r1 < r0 or c1 < c0:
        return mask
    rows, cols = np.arange(r0, r1 + 1, dtype=float), np.arange(c0, c1 + 1, dtype=float)
    y0, y1 = r[None, :] - rows[:, None], np.roll(r, 1)[None, :] - rows[:, None]  # vertices i and i - 1
    odd = []
    for straddles, side in (((y0 > 0) != (y1 > 0), 1.0), ((y0 < 0) != (y1 < 0), -1.0)):
        row, edge = np.nonzero(straddles)
        x0, x1 = c[edge][:, None] - cols, np.roll(c, 1)[edge][:, None] - cols
        a, b = y0[row, edge][:, None], y1[row, edge][:, None]
        crosses = side * (x0 * b - x1 * a) / (b - a) > 0  # the edge crosses the ray to the right (left)
        counts = np.zeros((len(rows), len(cols)), np.int64)
        np.add.at(counts, row, crosses)
        odd.append(counts % 2 == 1)
    inside = odd[0] | (odd[0] != odd[1])  # inside, or on an edge (the two rays' parities differ)
    on_vertex = (np.abs(r - np.round(r)) < 1e-12) & (np.abs(c - np.round(c)) < 1e-12)
    vr, vc = np.round(r[on_vertex]).astype(int) - r0, np.round(c[on_vertex]).astype(int) - c0
    keep = (vr >= 0) & (vr < len(rows)) & (vc >= 0) & (vc < len(cols))
    inside[vr[keep], vc[keep]] = True
    mask[r0 : r1 + 1, c0 : c1 + 1] = inside
    return mask


def _polygons(geometry) -> list[Polygon]:
    if geometry is None or geometry.is_empty:
        return []
    if isinstance(geometry, Polygon):
        return [geometry]
    if isinstance(geometry, MultiPolygon):
        return list(geometry.geoms)
    return [g for g in getattr(geometry, "geoms", []) if isinstance(g, Polygon)]


def union_bounds(geometries: Iterable) -> tuple[float, float, float, float] | None:
    """``(xmin, ymin, xmax, ymax)`` of the non-empty geometries together; ``None`` if all are empty."""
    bs = [g.bounds for g in geometries if not g.is_empty]
    if not bs:
        return None
    b = np.array(bs, dtype=float)
    return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max()))


def as_multipolygon(geometry) -> MultiPolygon:
    """Keep only the polygonal parts of ``geometry`` as a valid MultiPolygon."""
    if geometry is None or geometry.is_empty:
        return MultiPolygon()
    geometry = shapely.make_valid(geometry)
    parts: list[Polygon] = []
    stack = [geometry]
    while stack:
        g = stack.pop()
        if isinstance(g, Polygon):
            if not g.is_empty and g.area > 0:
                parts.append(g)
        elif hasattr(g, "geoms"):
            stack.extend(g.geoms)
    return MultiPolygon(parts)


def without_specks(region: MultiPolygon, min_area_m2: float) -> MultiPolygon:
    """``region`` less its parts and holes smaller than ``min_area_m2`` (what a field of that cell cannot resolve)."""
    return MultiPolygon(
        [
            Polygon(part.exterior, [hole for hole in part.interiors if Polygon(hole).area >= min_area_m2])
            for part in region.geoms
            if part.area >= min_area_m2
        ]
    )


def local_gaussian_filter(values: np.ndarray, sigma_cells: float) -> np.ndarray:
    """:func:`scipy.ndimage.gaussian_filter` (its default reflecting edges and reach) of a mostly-zero 2-D array.

    Filtered only over the box of its non-zero cells and the kernel's reach
    around it (``int(4 sigma + 0.5)`` cells): outside that box the filter is
    zero, and inside it the box's margin of zeros reflects as the zeros beyond
    it, so every value is the whole array's, to the bit (a zero may lose its
    sign). The extrapolation's fits weigh only cells near a geozone's
    boundary, on a grid over every hole of the table: on Kennecott the box is
    0.4 of the grid on average.
    """
    values = np.asarray(values, float)
    rows, cols = np.flatnonzero(values.any(axis=1)), np.flatnonzero(values.any(axis=0))
    out = np.zeros_like(values)
    if rows.size == 0:
        return out
    reach = int(4.0 * float(sigma_cells) + 0.5)
    r0, r1 = max(rows[0] - reach, 0), min(rows[-1] + reach + 1, values.shape[0])
    c0, c1 = max(cols[0] - reach, 0), min(cols[-1] + reach + 1, values.shape[1])
    out[r0:r1, c0:c1] = ndimage.gaussian_filter(values[r0:r1, c0:c1], sigma_cells)
    return out
