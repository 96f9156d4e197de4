"""The implicit model of a geozone: a 3D radial basis function interpolant of signed distances at its holes.

Leapfrog-style: each hole's signed distance to its bench's boundary is
estimated from the labels alone (half the distance to the nearest hole of the
other label, capped at 1.5 spacings), and a degree-1 RBF interpolant through
them, with depth scaled so a bench counts like a few hole spacings, is
evaluated at any elevation. It is one of the references of
:mod:`core.model.evaluation`: it rests on the holes' labels rather than the
contours, and on every bench at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np
import shapely
from scipy import ndimage
from scipy.interpolate import RBFInterpolator
from scipy.spatial import cKDTree
from shapely.geometry import MultiPolygon, Polygon

from core.geometry.grid import Grid
from core.io.blastholes import detect_benches, median_hole_spacing


def _bench_groups(z: np.ndarray, bench: np.ndarray | None, bench_height_m: float | None) -> tuple[np.ndarray, float]:
    """Bench index of each hole and the bench height: as given, or detected from the elevations."""
    if bench is not None and bench_height_m is not None and np.isfinite(bench_height_m):
        return np.asarray(bench), float(bench_height_m)
    levels, found, height, _ = detect_benches(
        z, bench_height_m if bench_height_m and np.isfinite(bench_height_m) else None
    )
    if not np.isfinite(height):
        height = 10.0  # a single bench: z does not matter, any scale will do
    if bench is None:
        # Off-bench holes (-1) still get the nearest level.
        found = np.argmin(np.abs(z[:, None] - np.asarray(levels)[None, :]), axis=1)
    return np.asarray(bench if bench is not None else found), float(height)


def hole_signed_distance(xy: np.ndarray, inside: np.ndarray, groups: np.ndarray, cap_m: float) -> np.ndarray:
    """Signed distance of each hole to its bench's boundary, estimated from the labels alone.

    The boundary lies midway between holes of different labels, so a hole's
    distance to it is half the distance to the nearest hole of the other label
    on the same bench (positive inside). Values are capped at ``±cap_m``, which
    is also the value of benches where the label is absent or everywhere.
    """
    d = np.empty(len(xy))
    for g in np.unique(groups):
        sel = np.flatnonzero(groups == g)
        ins, out = sel[inside[sel]], sel[~inside[sel]]
        if len(ins) == 0 or len(out) == 0:
            d[sel] = cap_m if len(out) == 0 else -cap_m
            continue
        d[ins] = 0.5 * cKDTree(xy[out]).query(xy[ins])[0]
        d[out] = -0.5 * cKDTree(xy[ins]).query(xy[out])[0]
    return np.clip(d, -cap_m, cap_m)


@dataclass
class ImplicitRBF:
    """A fitted Leapfrog-style implicit model of one geozone (see :func:`fit_implicit_rbf`)."""

    interpolator: RBFInterpolator | None
    z_scale: float  #: z is multiplied by this before interpolation
    spacing_m: float
    constant: float = 0.0  #: value everywhere when there is nothing to interpolate
    n_points: int = 0
    resolution_spacings: float = 1.0  #: evaluation cell size, in hole spacings
    #: The coarse cells already evaluated, by elevation and coarse grid (NaN where not yet): a model's sections
    #: at one level are asked for over several grounds (each bench level twice by the surfaces' ground above
    #: the deepest bench), and each cell is a local solve.
    _evaluated: dict[tuple[float, Grid], np.ndarray] = dataclass_field(default_factory=dict, repr=False, compare=False)
    #: The fitted points' kD-tree, to find a neighbourhood's values before solving it (:meth:`_at`).
    _points_tree: cKDTree | None = dataclass_field(default=None, repr=False, compare=False)

    def field(self, z_m: float, grid: Grid, where: Polygon | MultiPolygon | None = None) -> np.ndarray:
        """The implicit function on ``grid`` at elevation ``z_m`` (positive inside).

        Evaluated on cells of ``resolution_spacings`` hole spacings (the data
        cannot resolve much finer, and the cost grows with the number of
        cells) and interpolated bilinearly onto ``grid``. With ``where``, only
        within two of those cells of it (the evaluation scores inside the next
        bench's drilled area, a quarter of a Kennecott grid): the same values
        there, ``-spacing_m`` (outside) further out. (Unless a neighbourhood
        further out alone would have made the model give up its depth trend,
        :meth:`_at`; on Kennecott and development seeds 0-1 of the families none did.)
        """
        if self.interpolator is None:
            return np.full(grid.shape, self.constant)
        step = max(1, int(round(self.resolution_spacings * self.spacing_m / grid.cell_size_m)))
        rows, cols = grid.shape
        coarse = Grid(grid.x0, grid.y0, grid.cell_size_m * step, ((rows - 1) // step + 2, (cols - 1) // step + 2))
        X, Y = coarse.cell_centres()
        needed = (
            np.ones(coarse.shape, bool)
            if where is None
            else shapely.contains_xy(where.buffer(2 * coarse.cell_size_m), X, Y)
        )
        evaluated = self._evaluated.setdefault((float(z_m), coarse), np.full(coarse.shape, np.nan))
        todo = needed & np.isnan(evaluated)
        if todo.any():
            interpolator = self.interpolator
            points = np.column_stack([X[todo], Y[todo], np.full(todo.sum(), z_m * self.z_scale)])
            evaluated[todo] = self._at(points).reshape(-1)
            if self.interpolator is not interpolator:  # it gave up its depth trend: every cell of it again
                return self.field(z_m, grid, where)
        values = np.where(needed, evaluated, -self.spacing_m)
        if step == 1:
            return values[:rows, :cols]
        rr, cc = np.mgrid[0:rows, 0:cols] / step
        return ndimage.map_coordinates(values, [rr, cc], order=1, mode="nearest")

    def at(self, xy: np.ndarray, z_m: float) -> np.ndarray:
        """The implicit function at the points ``xy`` (``(n, 2)`` local metres) at elevation ``z_m`` (positive inside).

        Evaluated at the points themselves, not on :meth:`field`'s coarse cells: a backtest on a bench's
        holes asks for a few hundred points, not a grid.
        """
        xy = np.asarray(xy, float).reshape(-1, 2)
        if self.interpolator is None or not len(xy):
            return np.full(len(xy), self.constant)
        points = np.column_stack([xy, np.full(len(xy), z_m * self.z_scale)])
        return self._at(points).reshape(-1)

    def _at(self, points: np.ndarray) -> np.ndarray:
        """The interpolant at ``points``; without a depth trend anywhere if some neighbourhood lies on one bench.

        The degree-1 polynomial of a neighbourhood whose holes all share one
        elevation has no slope in depth to fit: its system is singular, and a
        constant term is all those holes determine. SciPy solves every
        neighbourhood in one call and says only that one failed, so the model
        changes to degree 0 for good, once, rather than failing again at every
        elevation.

        A neighbourhood whose holes all carry one value (the capped distance, deep inside or outside a body:
        73% of a Kennecott build's cells) is not solved: a constant lies in the polynomial's span, so the
        solution is that constant with no kernel weights (SciPy's solve gave it within 2e-13 m).
        """
        assert self.interpolator is not None
        if self._points_tree is None:
            self._points_tree = cKDTree(self.interpolator.y)
        k = self.interpolator.neighbors or len(self.interpolator.y)
        values = self.interpolator.d[self._points_tree.query(points, k)[1].reshape(len(points), -1), 0]
        uniform = (values == values[:, :1]).all(axis=1)
        out = values[:, 0].copy()
        if uniform.all():
            return out
        try:
            out[~uniform] = self.interpolator(points[~uniform]).reshape(-1)
        except np.linalg.LinAlgError:
            self.interpolator = _without_depth_trend(self.interpolator)
            self._evaluated.clear()  # cells evaluated with the depth trend are not this model's
            out[~uniform] = self.interpolator(points[~uniform]).reshape(-1)
        return out

    def region(self, z_m: float, grid: Grid, where: Polygon | MultiPolygon | None = None) -> MultiPolygon:
        """The region ``field > 0`` (:meth:`field`; with ``where``, exact only within it)."""
        f = self.field(z_m, grid, where)
        if not (f > 0).any():
            return MultiPolygon()
        return grid.polygons_from_field(f, 0.0)


def _without_depth_trend(interpolator: RBFInterpolator) -> RBFInterpolator:
    """The same interpolant with a degree-0 polynomial (``y`` and ``d`` are its data points and values)."""
    return RBFInterpolator(
        interpolator.y,
        interpolator.d,
        kernel=interpolator.kernel,
        neighbors=interpolator.neighbors,
        smoothing=interpolator.smoothing,
        degree=0,
    )


def fit_implicit_rbf(
    holes_xy: np.ndarray,
    holes_z: np.ndarray,
    inside: np.ndarray,
    *,
    bench: np.ndarray | None = None,
    spacing_m: float | None = None,
    bench_height_m: float | None = None,
    z_spacings: float = 1.5,
    kernel: str = "linear",
    neighbors: int = 96,
    smoothing: float = 1.0,
    resolution_spacings: float = 2.0,
    cap_spacings: float = 1.5,
) -> ImplicitRBF:
    """Fit a 3D RBF interpolant of signed distances at the holes (Leapfrog-style implicit model).

    Parameters
    ----------
    holes_xy : (n, 2) local metres; holes_z : (n,) metres
        Known holes (all geozones).
    inside : (n,) bool
        Whether each hole belongs to the geozone.
    bench : (n,) int, optional
        Bench of each hole; found from ``holes_z`` when omitted.
    spacing_m, bench_height_m : float, optional
        Hole spacing (median nearest-neighbour distance on a bench by default)
        and bench height (median gap between benches by default).
    z_spacings : float
        Anisotropy: z is scaled so one bench height counts like this many hole
        spacings horizontally. Labels are dense along a bench and sparse across
        benches, so without it the interpolant would see neighbouring holes of
        one bench as much closer than the bench above. With the distances
        capped (``cap_spacings``) 1.5 spacings and 96 neighbours were chosen
        among 1, 1.5 and 2 spacings and 64-256 neighbours (development seeds
        0-1 of every family: F1 92.7 / 87.3 at 5 / 10 m against 91.9 / 85.5
        with 2 and 64; Kennecott from the deepest known bench 4: 85.1 against
        84.5; travelling waves 87.2 / 75.4 against 87.4 / 75.9); 128
        neighbours gave Kennecott 85.4 at 1.5 times the cost.
    kernel, neighbors, smoothing
        Passed to :class:`scipy.interpolate.RBFInterpolator` (degree 1
        polynomial, so the field extrapolates its local linear trend in depth).
        ``smoothing`` absorbs label noise.
    resolution_spacings : float
        Cell size at which the field is evaluated (then interpolated
        bilinearly onto the caller's grid), in hole spacings.
    cap_spacings : float
        Distances are estimated from the labels (:func:`hole_signed_distance`)
        and capped at this many hole spacings: further from a boundary the
        labels say only which side a hole is on. A larger cap (6 spacings
        until 2026-11-28) lets a lens appearing or a stray label on one bench
        change the far field by tens of metres from the bench above, and the
        degree-1 drift carries that change on below the data as new bodies
        (F1 72.1 / 50.5 at 5 / 10 m below the deepest bench on development
        seeds 0-1 of strips, splits and pods, 89.9 / 79.2 capped at 2
        spacings, 90.7 / 83.0 at 1). Chosen among 0.5-2 on development seeds
        0-3 of every family (1.5: 92.4 / 86.1, 1: 92.3 / 86.5), Kennecott and
        the travelling waves of ``bench_foreign.py`` (BENCHMARKS.md): a
        reference is only worth beating at its best. Every hole is fitted:
        holes further than two spacings from a boundary were thinned to a
        random 5% for speed, and with the cap they only hold the side.
    """
    xy = np.asarray(holes_xy, float)
    z = np.asarray(holes_z, float)
    inside = np.asarray(inside, bool)
    if len(xy) == 0:
        raise ValueError("no holes to fit an implicit model to")
    groups, bench_height_m = _bench_groups(z, bench, bench_height_m)
    if spacing_m is None or not np.isfinite(spacing_m):
        # The nearest neighbour's, which it was tuned with (5 m if no bench has two holes).
        spacing_m = median_hole_spacing(xy, groups, neighbour=1)
        spacing_m = spacing_m if np.isfinite(spacing_m) else 5.0
    z_scale = z_spacings * spacing_m / bench_height_m
    if inside.all() or not inside.any():
        cap = cap_spacings * spacing_m
        return ImplicitRBF(
            None, z_scale, spacing_m, constant=cap if inside.all() else -cap, resolution_spacings=resolution_spacings
        )
    sd = hole_signed_distance(xy, inside, groups, cap_spacings * spacing_m)
    pts = np.column_stack([xy, z * z_scale])
    # Holes of one bench share z: a neighbourhood on one bench has no depth trend (ImplicitRBF._at).
    interp = RBFInterpolator(pts, sd, kernel=kernel, neighbors=min(neighbors, len(sd)), smoothing=smoothing, degree=1)
    return ImplicitRBF(interp, z_scale, spacing_m, n_points=len(sd), resolution_spacings=resolution_spacings)
