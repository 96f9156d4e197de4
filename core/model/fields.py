"""A geozone's signed distances on its known benches, measured where each bench drilled.

Bench ``j`` gives ``F_j(x)``, the signed distance from ``x`` to the geozone's
boundary on that bench (positive inside; the paper's SDF convention, section
3.2.1), on one grid for all benches (:class:`BenchFields`). Where a bench was not
drilled its boundary is unknown, not absent: the drilling frontier is not a
boundary. ``F_j`` measures the distance to the nearest drilled cell of the other
side only; past the frontier it is the nearest evidence of that bench, weighted
down with the distance to its drilled area and bounded by a reach (no further
than the geozone's bodies are across), so each cell's trend rests on the benches
that were drilled there (:func:`bench_distance`). How the boundary moved between
them is :mod:`core.model.movement`; how it goes on below the deepest bench,
:mod:`core.model.extrapolation`.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import ndimage
from shapely.geometry import MultiPolygon

from core.geometry.grid import Grid
from core.geometry.sdf import boundary_distance
from core.io.blastholes import typical_bench_height

#: Signed distances are capped at this many hole spacings: a boundary far away
#: says nothing about how the one nearby moves, and a cell at the cap is not moved
#: by the movement of its nearest boundary (:func:`core.model.extrapolation.depth_trend`).
CAP_SPACINGS = 8.0
#: Shallowest dip taken as movement of a boundary (degrees). A change of the signed distance faster than ``1 /
#: tan(dip)`` bench heights per bench is a body appearing or vanishing (a pod, a new lens), not a boundary
#: moving: the trend is held there. 30 degrees is 1.7 bench heights per bench, a little past the shallowest
#: contacts a pit's benches follow (the synthetic strips dip 35-80 degrees); 34 degrees, the linear
#: reference's bound (:class:`core.model.evaluation.LinearSDF`), held the fastest strips (chosen on the tuning
#: seeds only: +0.4 and +1.1 F1 at 5 and 10 m, strips +1.3 and +3.2, pods -0.3 and -0.4). It is a floor: where
#: a bench pair's sections align at a larger translation (a shallower contact), that is the bound for the pair
#: (:func:`core.model.movement.movement_reach_m`). Where the geozone's bodies are smaller across than that,
#: their size is the floor instead (:func:`core.model.movement.fastest_movement_m`). A geozone's own benches
#: may choose :data:`core.model.extrapolation.SHALLOW_DIP_DEG` instead, and two benches take
#: :data:`core.model.extrapolation.TWO_BENCH_DIP_DEG` (:func:`core.model.extrapolation.with_backtested_dip`).
MIN_DIP_DEG = 30.0

#: The memo's entry of the last sections' transports (:func:`core.model.trend.with_shared_transport`), the latest last.
TRANSPORTS_MEMO = ("transports",)
#: The memo's entry holding the memo of :meth:`BenchFields.measured` (the observed benches' own results).
OBSERVED_MEMO = ("observed",)


@dataclass
class BenchFields:
    """Signed distances to a geozone's boundary on each known bench, on one grid.

    Attributes
    ----------
    grid : Grid
    z_m : (b,) float
        Bench elevations, metres (top first).
    distance : (b, rows, cols) float
        Signed distance to the boundary, metres, positive inside, capped.
    weight : (b, rows, cols) float
        How directly the bench observed each cell: 1 where drilled, falling
        off with the distance to its drilled area.
    drilled : (b, rows, cols) bool
    memo : dict
        Results that rest only on the first benches, shared with the
        benches' :meth:`through` views (the same in every view): each bench
        pair's backtest (:func:`core.model.extrapolation.carried_precision`), the trend of the
        first ``n`` benches (:func:`core.model.extrapolation.depth_trend`) and the transports of the
        last sections trends were made of (:func:`core.model.trend.with_shared_transport`).
    observed : (b, rows, cols) float or None
        The signed distances from the benches' own contours where ``distance``
        was drawn towards the benches above (:func:`core.model.extrapolation.assimilated`); see
        :meth:`measured`.
    min_dip_deg : float or None
        The shallowest dip taken as a boundary moving: :data:`MIN_DIP_DEG` or
        :data:`core.model.extrapolation.SHALLOW_DIP_DEG`, as the benches chose it
        (:func:`core.model.extrapolation.with_backtested_dip`); None until then (a view of fewer
        benches, :meth:`through`, chooses again from its own).
    height_m : float or None
        The bench height of the benches this is a view of (:meth:`through`);
        None: the median of its own (:attr:`bench_height_m`).
    reach_spacings : float or None
        How far past its drilled area a bench's evidence reaches at most, in
        hole spacings (``weight`` is ``exp(-spacings off)``); None: not known.
    """

    grid: Grid
    z_m: np.ndarray
    distance: np.ndarray
    weight: np.ndarray
    drilled: np.ndarray
    memo: dict = field(default_factory=dict, repr=False, compare=False)
    observed: np.ndarray | None = None
    min_dip_deg: float | None = None
    height_m: float | None = None
    reach_spacings: float | None = None

    def measured(self) -> BenchFields:
        """The benches' signed distances as their holes showed them (``observed``).

        That is, before :func:`core.model.extrapolation.assimilated` drew them towards the benches above.

        Their memo is kept in this one's (under ``("observed",)``), so its views share it as well.
        """
        if self.observed is None:
            return self
        memo = self.memo.setdefault(OBSERVED_MEMO, {})
        # Keyed by the sections themselves: the same sections' transports serve both.
        memo.setdefault(TRANSPORTS_MEMO, self.memo.setdefault(TRANSPORTS_MEMO, OrderedDict()))
        return replace(self, distance=self.observed, memo=memo, observed=None)

    def __getstate__(self) -> dict:
        # The memo is remade at need: not stored or sent with the fields (it holds whole trends).
        return {**self.__dict__, "memo": {}}

    @property
    def dip_deg(self) -> float:
        """:attr:`min_dip_deg`, or the usual :data:`MIN_DIP_DEG` before the benches chose."""
        return MIN_DIP_DEG if self.min_dip_deg is None else self.min_dip_deg

    @property
    def cap_m(self) -> float:
        """The largest ``|F|`` the fields hold (their cap, where a boundary is far; 0 without benches)."""
        return float(np.max(np.abs(self.distance))) if self.distance.size else 0.0

    @property
    def bench_height_m(self) -> float:
        """The height between successive benches as the reader measures it (metres, positive in either order;
        1 with one bench): :func:`core.io.blastholes.typical_bench_height`, a gap of benches not drilled counting
        as that many steps.

        A view of the first benches (:meth:`through`) keeps the height of all of them: the results kept in
        the memo are keyed by it, and on uneven benches (Kennecott's heights differ by up to 5%) each view's
        own median missed them all, so a build made every bench's trend from the benches above twice.
        """
        if self.height_m is not None:
            return self.height_m
        return typical_bench_height(self.z_m) if len(self.z_m) > 1 else 1.0

    @property
    def upwards(self) -> bool:
        """Whether the benches are bottom first (:meth:`reversed`: extrapolated upwards)."""
        return len(self.z_m) > 1 and self.z_m[0] < self.z_m[-1]

    def through(self, z_m: float) -> BenchFields:
        """The benches from the first through ``z_m``, in their order: what was known when that was the last.

        Top first (extrapolating down), the benches at or above ``z_m``; bottom
        first (:meth:`reversed`, extrapolating up), those at or below it.
        """
        n = int(np.sum(self.z_m <= z_m + 1e-6)) if self.upwards else int(np.sum(self.z_m >= z_m - 1e-6))
        observed = None if self.observed is None else self.observed[:n]
        return replace(
            self,
            z_m=self.z_m[:n],
            distance=self.distance[:n],
            weight=self.weight[:n],
            drilled=self.drilled[:n],
            observed=observed,
            min_dip_deg=self.min_dip_deg if n == len(self.z_m) else None,
            height_m=self.bench_height_m,
        )

    def reversed(self) -> BenchFields:
        """Bottom bench first: extrapolating from it extrapolates upwards."""
        observed = None if self.observed is None else self.observed[::-1]
        return replace(
            self,
            z_m=self.z_m[::-1],
            distance=self.distance[::-1],
            weight=self.weight[::-1],
            drilled=self.drilled[::-1],
            memo={},
            observed=observed,
            min_dip_deg=None,
        )


def bench_distance(
    region: np.ndarray,
    drilled: np.ndarray,
    cell_size_m: float,
    cap_m: float,
    reach_m: float,
    unclaimed: np.ndarray | None = None,
    next_undrilled: np.ndarray | None = None,
):
    """Signed distance to a region's boundary where only drilled cells count as evidence.

    Parameters
    ----------
    region, drilled : (rows, cols) bool
        The geozone's region and the drilled area of one bench.
    cell_size_m, cap_m, reach_m : float
        Cell size; the cap on ``|F|``; how far past the drilled area the
        bench's evidence reaches at most. It reaches no further than the
        drilled patch it comes from is wide (its equivalent radius): a
        handful of isolated holes says nothing about the ground around them.
    unclaimed : (rows, cols) bool, optional
        Drilled cells outside the region that say nothing of the ground past
        the drilled area: the fringe of the geozone's own holes its contours
        leave out (the drilled area reaches 0.75 spacings past the outermost
        holes, a contour about half of that). Counted as the other side
        there, they cut the geozone off at the frontier: on the Kennecott
        benches 20-40% of the ground the next bench drilled beyond the last
        one was left to no geozone at all.
    next_undrilled : (rows, cols) bool, optional
        Ground the next bench down did not drill: there the ``unclaimed``
        cells that reach the frontier are no evidence inside the drilled area
        either (:func:`_frontier_fringe`). None for the deepest bench, whose
        frontier is where what is known ends: the band holds the extension past
        it from being carried into the ground the bench drilled (a constructed
        pit whose benches all drill the same ground lost 0.26 F1 without it).

    Returns
    -------
    distance, off_drilled : (rows, cols) float
        ``F = d(other side) - d(own side)`` measured to drilled cells only
        (exact signed distance inside the drilled area; nearest-evidence
        extension past it, falling to "absent" beyond the reach), and the
        distance of each cell to the drilled area.
    """
    big = 2 * cap_m
    if not drilled.any():
        return np.full(region.shape, -cap_m), np.full(region.shape, big)
    inside = region & drilled
    outside = drilled & ~region

    def to(cells: np.ndarray) -> np.ndarray:
        return ndimage.distance_transform_edt(~cells) * cell_size_m if cells.any() else np.full(region.shape, big)

    unclaimed_outside = outside & unclaimed if unclaimed is not None else np.zeros_like(outside)
    counted = outside  # inside the drilled area, the cells that are evidence of the other side
    if next_undrilled is not None and unclaimed_outside.any():
        counted = outside & ~(_frontier_fringe(unclaimed_outside, drilled) & next_undrilled)
    d_in, d_out = to(inside), to(counted)
    off, (rows, cols) = ndimage.distance_transform_edt(~drilled, return_indices=True)
    if unclaimed_outside.any():
        d_out = np.where(off > 0, to(outside & ~unclaimed_outside), d_out)
    patches, n = ndimage.label(drilled)
    radius = np.sqrt(np.bincount(patches.ravel(), minlength=n + 1) / np.pi) * cell_size_m
    reach = np.minimum(reach_m, radius[patches[rows, cols]])
    distance = np.minimum(d_out - d_in, reach - off * cell_size_m)
    return np.clip(distance, -cap_m, cap_m), off * cell_size_m


def _frontier_fringe(unclaimed_outside: np.ndarray, drilled: np.ndarray) -> np.ndarray:
    """The parts of ``unclaimed_outside`` that reach the edge of the drilled area.

    Between a contour run along the drilling frontier and the frontier itself
    lies a band of the geozone's own fringe: counted as the other side, it put
    a false boundary at every bench's frontier, so past the deepest bench's
    drilling, where each cell's evidence is the band of the older bench that
    drilled it last, the predicted section frayed into specks and rings. Such
    a band is no evidence of the other side; a sliver a contour leaves out
    between the geozone's holes and another's is.
    """
    return parts_touching(unclaimed_outside, ndimage.binary_dilation(~drilled))


def parts_touching(mask: np.ndarray, seeds: np.ndarray, structure: np.ndarray | None = None) -> np.ndarray:
    """The connected parts of ``mask`` (``structure`` as :func:`scipy.ndimage.label`) holding a cell of ``seeds``."""
    parts, n = ndimage.label(mask, structure=structure)
    touched = np.zeros(n + 1, bool)
    touched[parts[seeds & mask]] = True  # label 0, the ground outside ``mask``, is never a seed's
    return touched[parts]


def exact_near_boundary(distance: np.ndarray, region: MultiPolygon, drilled: np.ndarray, grid: Grid) -> np.ndarray:
    """The signed distance made exact in the drilled cells next to the region's boundary.

    :func:`bench_distance` measures ``F`` between cell centres: every cell
    inside is at least one cell from one outside, and the zero level falls
    half-way between them, wherever the contour runs between the two. Held
    on a bench, that half-cell error alone lost against the contours
    themselves (holding the last bench). In the ring of cells next to the
    boundary (``|F| <= 1.5`` cells) ``|F|`` becomes the exact distance to the
    contour (the paper's SDF, section 3.2.1), its sign kept; where the nearest
    stretch of contour is further than the raster's own boundary (a contour
    run along the drilling frontier, which is no boundary), ``F`` is kept.

    Parameters
    ----------
    distance : (rows, cols) float
        ``F`` of :func:`bench_distance`, metres.
    region : MultiPolygon
        The region ``distance`` was made from (its raster on ``grid``).
    drilled : (rows, cols) bool
    grid : Grid

    Returns
    -------
    (rows, cols) float
    """
    h = grid.cell_size_m
    ring = (np.abs(distance) <= 1.5 * h) & drilled
    if region.is_empty or not ring.any():
        return distance
    xy = grid.rc_to_xy(np.argwhere(ring))  # the ring's centres only: a full grid of centres per bench is waste
    exact = boundary_distance(region, xy[:, 0], xy[:, 1])
    raster = distance[ring]
    out = distance.copy()
    out[ring] = np.where(exact <= np.abs(raster) + 0.5 * h, np.sign(raster) * np.maximum(exact, 1e-3 * h), raster)
    return out


def bench_fields(
    regions: Mapping[int, MultiPolygon],
    drilled: Mapping[int, np.ndarray],
    z_m: Mapping[int, float],
    grid: Grid,
    hole_spacing_m: float,
    reach_m: float,
    unclaimed: Mapping[int, np.ndarray] | None = None,
) -> BenchFields:
    """:class:`BenchFields` of the given benches (bench index -> region, drilled mask on ``grid``, elevation).

    ``unclaimed``: per bench, the drilled cells that are no evidence past the drilled area, nor inside it at a
    frontier the next bench down did not drill (:func:`bench_distance`).
    Past the drilled area a bench's evidence reaches ``reach_m`` at most, and no further than the geozone's
    bodies are across (:func:`body_size_m`).
    """
    benches = sorted(regions, key=lambda k: -z_m[k])
    h = grid.cell_size_m
    cap = CAP_SPACINGS * hole_spacing_m
    rasters = {
        k: grid.rasterize(regions[k]) if not regions[k].is_empty else np.zeros(grid.shape, bool) for k in benches
    }
    reach_m = min(reach_m, body_size_m([rasters[k] & drilled[k] for k in benches], h))
    dist, weight = [], []
    for k, deeper in zip(benches, [*benches[1:], None]):
        d, off = bench_distance(
            rasters[k],
            drilled[k],
            h,
            cap,
            reach_m,
            None if unclaimed is None else unclaimed[k],
            None if deeper is None else ~drilled[deeper],
        )
        dist.append(exact_near_boundary(d, regions[k], drilled[k], grid))
        weight.append(np.exp(-off / hole_spacing_m))
    return BenchFields(
        grid,
        np.array([z_m[k] for k in benches], float),
        np.array(dist),
        np.array(weight),
        np.array([drilled[k] for k in benches]),
        reach_spacings=reach_m / hole_spacing_m,
    )


def body_size_m(bodies: list[np.ndarray], cell_size_m: float) -> float:
    """How far across the geozone's bodies are: the diameter of the disc as large as the body a cell of it lies in, on average.

    Area-weighted (a few specks of label noise beside a large body do not make
    it small); ``inf`` where the benches hold none of the geozone. A body cut
    by the edge of the drilling goes on past it about as far as the bodies
    are across (:func:`bench_fields`): a lens 20 m across does not run 10 hole
    spacings beyond the last hole.
    """
    areas = []
    for inside in bodies:
        labels, n = ndimage.label(inside)
        areas.append(np.bincount(labels.ravel(), minlength=n + 1)[1:].astype(float))
    a = np.concatenate(areas) if areas else np.zeros(0)
    if not a.sum():
        return float("inf")
    return 2.0 * float(np.sqrt(np.sum(a**2) / np.sum(a) / np.pi)) * cell_size_m


def better_beyond_chance(wrong: float, other_wrong: float, differ: float, deviations: float) -> bool:
    """Whether a backtest's other prediction put fewer holes wrong than ``wrong``, by more than chance.

    ``differ``: the holes (or holes' worth of cells) where the two predictions disagree. On each of them one of the
    two is right, by chance either about half the time, so the difference in holes wrong has a standard deviation of
    ``sqrt(differ)``; the other is better where it had fewer wrong by more than ``deviations`` of them, never
    without a hole where they disagreed. The implicit model in new ground (:func:`core.model.new_ground.implicit_chosen`)
    and a section's gaps filled (:func:`core.model.extrapolation.gap_closing_m`) are chosen by it.
    """
    return bool(differ > 0 and wrong - other_wrong > deviations * np.sqrt(differ))


def memoised(fields: BenchFields, key: tuple, compute):
    """``fields.memo[key]``, computed once (``key`` names what it rests on: the first benches, see :class:`BenchFields`)."""
    if key not in fields.memo:
        fields.memo[key] = compute()
    return fields.memo[key]
