"""Extrapolation below the deepest bench: the depth trend of the distance to the boundary.

Between benches the paper's particle trajectories give a geozone's sections
(:func:`core.model.prediction.region_between`). Below the deepest bench there
is no target to morph to, and the movement of the last bench pair has to be
carried on. Carried on as a displacement, its part *along* the boundary is
noise: FFT alignment of a long strip is not determined along its length (the
aperture problem), and a trajectory's end on a smooth target can slide along
it freely. Only the part *across* the boundary is measured by the benches.

This module carries on exactly that part. On a grid over the geozone, bench
``j`` gives ``F_j(x)``, the signed distance from ``x`` to the geozone's
boundary on that bench (positive inside; the paper's SDF convention,
section 3.2.1). A boundary that moves steadily across itself changes ``F``
linearly with depth at every point, whichever way it moves along itself.
Per cell, the movement across itself of the nearest boundary between the
last two benches that observed it, matched along its normal to the boundary
facing the same way (:func:`boundary_movement`, as far as the geozone's
sections moved: :func:`movement_reach_m`), is the rate of movement
(:func:`fit_trend`). It is split into the movement of each outline as a
whole (its translation, growth and elongation, :func:`outline_movement`) and
the finer changes, and each part is carried on as far as successive bench
pairs agree on it along the trajectories of the geozone's boundary
(:func:`geozone_persistence`: a geozone whose bodies move steadily keeps its
trend, one whose movement reverses or is shape noise is held; with two
benches known, only the outlines' movement is carried), or, where carrying
all of it or none predicted the geozone's own benches better, as far as that
(:func:`chosen_persistence`). A geozone whose
bodies end between benches (lenses) has its growth held as well
(:data:`GROWTH_CONTINUITY_POWER`). The boundary moves by ``carried * f``
across itself ``f`` bench heights below, and the last section, smoothed of
the waver its contour has between holes (:func:`core.geometry.sdf.smoothed_section`), is
carried along that movement (:meth:`DepthTrend.field`).

Where a bench was not drilled its boundary is unknown, not absent: the
drilling frontier is not a boundary. ``F_j`` measures the distance to the
nearest drilled cell of the other side only; past the frontier it is the
nearest evidence of that bench, weighted down with the distance to its
drilled area and bounded by a reach (no further than the geozone's bodies
are across), so each cell's trend rests on the benches that were drilled
there. A curved boundary's slide along itself, which its movement across
itself shows as growth, is taken off (:func:`sliding_bias`).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import MultiPolygon

from core.correspondence.alignment import fft_translation, shift_mask
from core.geometry.grid import Grid, local_gaussian_filter
from core.geometry.sdf import boundary_distance, smoothed_section

#: Neighbourhood over which the boundary's movement is fitted by a displacement when the
#: last section is carried along it (:meth:`DepthTrend.field`), in hole spacings, and the
#: number of direction classes it is fitted within (:func:`displacement_by_direction`). Chosen
#: on the tuning seeds only: every neighbourhood from 0.5 to 6 spacings gained over adding
#: the movement to ``F``; 3 spacings within 4 directions was best pooled, and kept splits
#: moving apart where one class for all directions froze their inner boundaries. Each
#: bench's section errs by a fraction of a spacing that does not repeat from bench to
#: bench; this averaging cancels it (averaging the rate as well, over 1.5 spacings before
#: the transport, no longer gained: 0.1 and 0.4 F1 points better without).
TRANSPORT_SMOOTHING_SPACINGS = 3.0
TRANSPORT_DIRECTIONS = 4
#: The deepest section is smoothed over this many hole spacings before it is carried on
#: (:func:`core.geometry.sdf.smoothed_section`): its boundary runs between holes and wavers by a fraction of a
#: spacing, as each bench's does, and that waver carried on is error. Chosen on development
#: seeds 0-5 of every family (pooled F1 at 5 / 10 m 96.26 / 95.00 without). A plain Gaussian:
#: 0.5 spacings 96.48 / 95.13 but pods -1.3 / -1.2 (lenses shrank), 1 spacing 95.58 / 94.26.
#: With the curvature's shift put back: 0.35, 0.5 and 0.75 spacings 96.41 / 95.08, 96.49 / 95.09,
#: 96.45 / 94.93, but a constructed split's 4 m gap and narrow strips moving further than their
#: half-width were carried worse. With the change bounded and faded off the boundary, and the
#: shift measured as the Gaussian's own change along it: 0.25 spacings 96.31 / 95.03, 0.5
#: 96.42 / 95.06, and with the outlines traced on the section as measured (the split) 96.45 /
#: 95.13, every family up at both depths (pods +0.3 / +0.2, holding 63.4 / 37.3).
SECTION_SMOOTHING_SPACINGS = 0.5
#: Ridge of the displacement's fit (:func:`displacement_by_direction`), a share of the neighbourhood's
#: weight: it keeps a straight boundary's displacement across it. Chosen on development seeds 0-11
#: among 0.1, 0.01 and 0.001 (pooled F1 at 10 m 94.1, 94.2, 94.2; 0.1 took 40% off the translation
#: of a disc's boundary, 0.01 9%, 0.001 2%, and 5%, 0.3% and 0% off a straight one's).
RIDGE_SHARE = 0.01
#: How far from a cell whose signed distance has a direction a body's ridge reaches (cells; see
#: :attr:`DepthTrend._ridge`). A signed distance's ridge is one or two cells wide (on constructed strips moving
#: further than their half-width, 1,911 of 1,935 ridge cells lay within 1.5 cells of a directed one, all within 2).
RIDGE_REACH_CELLS = 2.0
#: Cells within this many cells of the deepest boundary measure the persistence of its movement
#: (:func:`geozone_persistence`); every cell takes the movement of its nearest boundary point,
#: and cells far from it would weigh a boundary by the empty ground around it.
PERSISTENCE_BAND_CELLS = 2.0
#: A movement carries on as far as its agreement from bench to bench is this many standard
#: errors above chance (:func:`geozone_persistence`). Chosen on development seeds 0-11,
#: Kennecott and the constructed noisy bodies among 0 (before), 1 and 2. With 1 the families
#: are unchanged pooled (95.6 / 94.1 at 5 / 10 m; strips -0.1 / -0.2, splits -0.1 / -0.2, pods
#: +0.1 / +0.2), Kennecott 73.9 -> 74.1 on the holes (84.4 -> 84.8 from the deepest known bench
#: 4, where the outlines moved on by less than their last two moves agreed), and a static body
#: whose outline changes at random is no longer under holding with 3-5 benches known. With 2,
#: Kennecott 74.2 and 85.2 but a disc moving 6 m a bench through 6% shape noise carried as
#: little as 0.42 of its translation (-0.6 to -0.8 F1 with 4-5 benches known).
PERSISTENCE_STANDARD_ERRORS = 1.0
#: With three benches known, where no backtest chooses how far to carry the movement
#: (:func:`chosen_persistence`), the agreement of its two moves read as none
#: (:func:`geozone_persistence`): a still boundary's two moves share the middle bench's error with
#: opposite signs, so section noise alone agrees at -1/2 (a reversing movement at -1). Read against 0
#: (as the backtest's middle way is), the agreement held movements that went on: travelling waves,
#: whose modes drift apart, agree near 0 and yet go on as they moved (development seeds 100-111 of
#: ``bench_foreign.py``'s generator at 3-30 m a bench, three benches known: 5.5% less area wrong).
THREE_BENCH_CHANCE = -0.5
#: Degrees of freedom of an outline's movement (:func:`outline_movement`: growth, translation, elongation).
OUTLINE_DEGREES = 5
#: Signed distances are capped at this many hole spacings: a boundary far away
#: says nothing about how the one nearby moves, and a cell at the cap is not moved
#: by the movement of its nearest boundary (:func:`depth_trend`).
CAP_SPACINGS = 8.0
#: Shallowest dip taken as movement of a boundary (degrees). A change of the
#: signed distance faster than ``1 / tan(dip)`` bench heights per bench is a
#: body appearing or vanishing (a pod, a new lens), not a boundary moving: the
#: trend is held there. 30 degrees is 1.7 bench heights per bench, a little past the
#: shallowest contacts a pit's benches follow (the synthetic strips dip 35-80 degrees);
#: 34 degrees, the linear reference's bound (:class:`core.model.evaluation.LinearSDF`),
#: held the fastest strips (chosen on the tuning seeds only: +0.4 and +1.1 F1 at 5 and
#: 10 m, strips +1.3 and +3.2, pods -0.3 and -0.4). It is a floor: where a bench pair's
#: sections align at a larger translation (a shallower contact), that is the bound for the
#: pair (:func:`movement_reach_m`). Where the geozone's bodies are smaller across than that, their
#: size is the floor instead (:func:`fastest_movement_m`). A geozone's own benches may choose
#: :data:`SHALLOW_DIP_DEG` instead, and two benches take :data:`TWO_BENCH_DIP_DEG` (:func:`with_backtested_dip`).
MIN_DIP_DEG = 30.0
#: Shallowest dip looked for where much of a geozone's boundary moved further than :data:`MIN_DIP_DEG`
#: allows, one way (:func:`coherent_reach_m`): 20 degrees, 2.7 bench heights a bench. Taken as the bound
#: everywhere instead, it matched lenses to others up to 27 m away (development seeds 0-3 of the families,
#: F1 at 5 / 10 m 96.37 / 94.96 -> 96.14 / 94.38).
COHERENT_DIP_DEG = 20.0
#: The share of the boundary that must have moved past :data:`MIN_DIP_DEG`'s bound, and how nearly one way
#: (the mean movement vector's length over the mean length). A contact moving 20 m a bench scores 0.95 and
#: 0.97, a lens growing all round about 0. The fast families' ``mix`` (development seeds 0-2) gained the same
#: with 0.1 / 0.6, 0.25 / 0.8 and 0.5 / 0.9; travelling waves moving 3-30 m a bench (``bench_foreign.py``'s
#: generator, development seeds 100-111) +0.3 / +0.6 F1 at 5 / 10 m with 0.25 / 0.8, none with 0.5 / 0.9.
COHERENT_SHARE = 0.25
COHERENCE = 0.8
#: A boundary's outward movement (a body growing) carries on by ``continuity ** 4`` of what
#: its persistence carries, ``continuity`` the share of the geozone's bodies that reach the next bench
#: (:func:`body_continuity`). A lens's section widens only down to its middle and its radius
#: goes as a square root of the depth from its tip: growth seen between two benches has
#: mostly stopped or turned by the next one (on the tuning seeds 2-22% of the pods' carried
#: growth was right). Layers, strips and folds reach every next bench (continuity 1) and keep
#: their growth. Chosen on the tuning seeds only among powers 1, 2, 4, 8 and holding all
#: growth once a body ends: pods +0.8 and +1.0 F1 points at 5 and 10 m with 4 (1: +0.5,
#: +0.5), every other family unchanged, Kennecott unchanged (holding: -0.2).
GROWTH_CONTINUITY_POWER = 4.0
#: Evidence of a cell that only benches above the deepest observed is kept while it is more likely
#: than not to hold at the predicted elevation: while ``carried_precision ** benches`` is at least
#: this, ``carried_precision`` the share of the geozone's carried section that the next bench
#: confirmed, backtested on its own benches (:func:`carried_precision`). Layers, strips and folds
#: are confirmed at 0.8-0.97 a bench and keep it for 2-6 benches; lenses that end or jump within a
#: bench or two at 0.1-0.5 and lose it at once. Bodies reaching the next bench
#: (:func:`body_continuity`), used before, counted a lens 15 m away as reached: on the tuning seeds
#: 90% of the lenses it kept were wrong (pods +0.2 and +0.1 F1 points at 5 and 10 m, +0.8 and
#: +0.5 with 3-4 m patterns, other families and Kennecott within 0.1).
STALE_EVIDENCE_PROBABILITY = 0.5
#: Where a geozone's typical body is smaller than a disc whose radius is the furthest a boundary moves
#: per bench (:data:`MIN_DIP_DEG`: a lens a bench's movement can end), the share of its bodies seen
#: reaching the next bench is drawn towards one half by a prior worth this many such discs of area
#: (:func:`body_continuity`): a few small bodies seen going on once or twice say little about lenses a
#: bench or two tall, whose growth then turns. Chosen on development seeds: pods (seeds 0-47) 58.6 /
#: 32.4 F1 at 5 / 10 m -> 59.1 / 33.1 against holding's 58.9 / 32.9 (a whole disc 59.2 / 33.3 but a
#: constructed body 15 m across that goes on was held); seeds 0-5 of every family pooled 96.23 /
#: 94.93 -> 96.25 / 94.97 (pods +0.7 / +0.6, widening -0.05 / -0.11); Kennecott unchanged (74.2).
LENS_PRIOR_DISCS = 0.25


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
        pair's backtest (:func:`carried_precision`), the trend of the
        first ``n`` benches (:func:`depth_trend`) and the transports of the
        last sections trends were made of (:func:`_with_shared_transport`).
    observed : (b, rows, cols) float or None
        The signed distances from the benches' own contours where ``distance``
        was drawn towards the benches above (:func:`assimilated`); see
        :meth:`measured`.
    min_dip_deg : float or None
        The shallowest dip taken as a boundary moving: :data:`MIN_DIP_DEG` or
        :data:`SHALLOW_DIP_DEG`, as the benches chose it
        (:func:`with_backtested_dip`); None until then (a view of fewer
        benches, :meth:`through`, chooses again from its own).
    height_m : float or None
        The bench height of the benches this is a view of (:meth:`through`);
        None: the median of its own (:attr:`bench_height_m`).
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

    def measured(self) -> BenchFields:
        """The benches' signed distances as their holes showed them (``observed``), before :func:`assimilated`.

        Their memo is kept in this one's (under ``("observed",)``), so its views share it as well.
        """
        if self.observed is None:
            return self
        memo = self.memo.setdefault(_OBSERVED, {})
        # Keyed by the sections themselves: the same sections' transports serve both.
        memo.setdefault(_TRANSPORTS, self.memo.setdefault(_TRANSPORTS, OrderedDict()))
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
        """The median height between successive benches (metres, positive in either order; 1 with one bench).

        A view of the first benches (:meth:`through`) keeps the height of all of them: the results kept in
        the memo are keyed by it, and on uneven benches (Kennecott's heights differ by up to 5%) each view's
        own median missed them all, so a build made every bench's trend from the benches above twice.
        """
        if self.height_m is not None:
            return self.height_m
        return float(np.median(np.abs(np.diff(self.z_m)))) if len(self.z_m) > 1 else 1.0

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


def geozone_persistence(fields: BenchFields, hole_spacing_m: float, chance: float = 0.0) -> tuple[float, float]:
    """How much of the last bench-to-bench movement carries on, for the geozone's boundary as a whole, in [0, 1].

    Two figures: for the movement of each outline as a whole and for the
    finer changes (:func:`outline_movement`). For each, the agreement of the
    last movement of the boundary (``d1``) with the one before along its
    trajectory (``d2``, :func:`movements_along_trajectories`; where there is
    no trajectory, the changes of the signed distance ``F_k - F_k-1`` and
    ``F_k-1 - F_k-2``), summed over the cells on the deepest boundary that
    three benches observed::

        rho = 2 sum(d1 d2) / sum(d1^2 + d2^2)   in [-1, 1]

    is 1 for a boundary that keeps moving the same way at the same rate, -1
    for one whose movement reverses, 0 for changes that do not repeat
    (shape noise). The persistence is ``clip(2 rho_low, 0, 1)``: full where the
    repeated movement is at least as large as what does not repeat (section
    noise lowers ``rho`` of a steady boundary towards 1/2 when it is as
    large as the movement), none where the movement reverses or is noise.
    ``rho_low = rho - k (1 - rho^2) / sqrt(N - 1)`` is ``rho`` less
    :data:`PERSISTENCE_STANDARD_ERRORS` ``k`` standard errors of a correlation
    over ``N`` independent samples (:func:`_agreement`): five per outline for
    the outlines' movement (the degrees of freedom of its fit) and one per
    hole spacing of boundary for the finer changes. A geozone's movement is
    carried on as far as its benches show it beyond chance; a steady one
    (``rho`` near 1) keeps it whatever ``N``. ``chance`` is the agreement read
    as none, ``clip(2 (rho_low - chance), 0, 1)``: 0, what two independent
    draws agree, or :data:`THREE_BENCH_CHANCE`, what a still boundary's
    section noise agrees, where the agreement alone decides
    (:func:`chosen_persistence`).
    The two parts are judged apart because they repeat apart: a strip's
    outline moves steadily while its edges wobble from bench to bench, and a
    body splitting pinches at its neck bench after bench, which its outline's
    movement does not hold. With fewer than three benches nothing tells
    either: the outlines' movement is carried (1) and the finer changes are
    not (0). A part with no such cell, or no change on them, is carried (1).
    Changes faster than a boundary of the geozone moves
    (:func:`movement_reach_m`) are left out: they are bodies appearing.

    Measured over the whole boundary rather than per neighbourhood
    (:data:`PERSISTENCE_BAND_CELLS`): a lens's boundary gives a few dozen
    cells, whose agreement by chance is as often positive as not, and a
    local estimate clipped at 0 kept half of every lens's noise.
    """
    if len(fields.z_m) < 3:
        return 1.0, 0.0
    # The benches as their holes showed them: drawn towards the benches above (:func:`assimilated`), their
    # movements agree by construction (a test's travelling waves agree under 0.5 observed, 0.53 drawn).
    fields = fields.measured()
    n = len(fields.z_m)
    fastest = geozone_fastest_movement_m(fields, float(abs(fields.z_m[-2] - fields.z_m[-1])))
    reach1, reach2 = movement_reach_m(fields, n - 2, n - 1, fastest), movement_reach_m(fields, n - 3, n - 2, fastest)
    d1, d2 = movements_along_trajectories(fields, reach1, reach2)
    seen = np.all(fields.weight[-3:] >= OBSERVED_WEIGHT, axis=0)
    on_boundary = np.abs(fields.distance[-1]) <= PERSISTENCE_BAND_CELLS * fields.grid.cell_size_m
    w = seen & on_boundary & (np.abs(d1) <= reach1) & (np.abs(d2) <= reach2)
    h = fields.grid.cell_size_m
    # d2 is carried to the deepest boundary along the trajectories: both are fitted on its outlines, at once
    outline1, outline2 = outline_movement(np.where(w, [d1, d2], 0.0), w, fields.distance[-1], h)
    # Outlines counted as the pieces of its inner side three benches saw (a stretch the drilling cut counts apart).
    outlines = ndimage.label(w & (fields.distance[-1] > 0), structure=np.ones((3, 3)))[1]
    # The band is 2 PERSISTENCE_BAND_CELLS cells wide: its cells over that are the boundary's length in cells.
    length_spacings = w.sum() / (2 * PERSISTENCE_BAND_CELLS) * h / hole_spacing_m
    return (
        _agreement(outline1[w], outline2[w], OUTLINE_DEGREES * max(outlines, 1), chance),
        _agreement((d1 - outline1)[w], (d2 - outline2)[w], length_spacings, chance),
    )


def _agreement(d1: np.ndarray, d2: np.ndarray, samples: float, chance: float = 0.0) -> float:
    """``clip(2 (rho_low - chance), 0, 1)`` of ``rho = 2 sum(d1 d2) / sum(d1^2 + d2^2)``, 1 without change.

    ``rho_low`` is ``rho`` less :data:`PERSISTENCE_STANDARD_ERRORS` standard
    errors of a correlation over ``samples`` independent samples,
    ``(1 - rho^2) / sqrt(samples - 1)`` (:func:`geozone_persistence`).
    ``chance``: the agreement read as none (:func:`geozone_persistence`).
    """
    energy = float(np.sum(d1**2 + d2**2))
    if energy <= 0:
        return 1.0
    rho = float(np.clip(2 * np.sum(d1 * d2) / energy, -1.0, 1.0))
    low = rho - PERSISTENCE_STANDARD_ERRORS * (1 - rho**2) / np.sqrt(max(samples - 1, 1.0))
    return float(np.clip(2 * (low - chance), 0.0, 1.0))


def movements_along_trajectories(
    fields: BenchFields, reach1_m: float, reach2_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """The last two bench-to-bench changes at each cell, ``(d1, d2)`` in metres, outwards.

    ``d1`` is the :func:`boundary_movement` of the cell's nearest boundary
    over the last bench pair and ``d2`` the movement, over the pair before,
    of the boundary point it came from (along its trajectory, as the paper's
    particles follow the front). The changes of the signed distance at the
    cell itself (``F_k - F_k-1`` and ``F_k-1 - F_k-2``) are the same for a
    boundary moving less than its body's half-width per bench; for one moving
    further they mix the movements of two boundaries (the leading edge's and
    the trailing edge's) and a steady movement looks like one that reverses.
    Where a boundary has no counterpart they are taken instead.
    """
    f, n = fields.distance, len(fields.z_m)
    d1, d2 = f[-1] - f[-2], f[-2] - f[-3]
    moved1, origin = pair_movement(fields, n - 2, n - 1, reach1_m)
    moved2, _ = pair_movement(fields, n - 3, n - 2, reach2_m)
    traced = np.isfinite(moved1)
    before = np.full(moved1.shape, np.nan)
    before[traced] = ndimage.map_coordinates(
        np.nan_to_num(moved2, nan=np.inf), origin[:, traced], order=0, mode="nearest"
    )
    traced &= np.isfinite(before)
    return np.where(traced, moved1, d1), np.where(traced, before, d2)


#: A bench observed a cell when the cell lies within this weight of its drilled
#: area (``exp(-d / s)``: about half a hole spacing past its outermost holes' discs).
OBSERVED_WEIGHT = 0.5


def last_observations(fields: BenchFields) -> tuple[np.ndarray, np.ndarray]:
    """Per cell, the index of the deepest bench that observed it and of the one before (-1 if none)."""
    seen = fields.weight >= OBSERVED_WEIGHT
    last = np.full(fields.grid.shape, -1)
    before = np.full(fields.grid.shape, -1)
    for j in range(len(fields.z_m)):  # top down: later benches replace earlier ones
        before = np.where(seen[j], last, before)
        last = np.where(seen[j], j, last)
    return last, before


def unit_normals(distance: np.ndarray, cell_size_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit normal ``grad F / |grad F|`` of a signed distance (pointing inside), per cell, and where it has one.

    A signed distance changes by a cell size per cell; at its cap and on its
    ridges it does not, and the normal there is no direction (``directed``
    false where ``|grad F|`` is under a fifth of a cell size; the normal is
    then not meaningful).
    """
    g_r, g_c = np.gradient(distance)
    norm = np.hypot(g_r, g_c)
    directed = norm > 0.2 * cell_size_m
    norm = np.maximum(norm, 1e-9)
    return g_r / norm, g_c / norm, directed


def boundary_movement(
    older: np.ndarray, newer: np.ndarray, cell_size_m: float, reach_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """How far the boundary nearest each cell moved outwards from one bench to the next, and from where.

    ``F_newer - F_older`` at a cell is the movement only while the nearest
    boundary on both benches is the same one: in a strip that moved further
    than its half-width, the trailing edge's cells are nearer the older
    leading edge, and the trailing edge seemed to stand still while the
    leading one advanced (the strip widened, 10% of its area on the tuning
    seeds). Here each point of the newer boundary is matched along its normal
    to the nearest boundary of the older bench that faces the same way (``F``
    rising inwards along it), within ``reach_m`` (the furthest a boundary
    moves, :data:`MIN_DIP_DEG`); the outward distance between the two is the
    movement, and every cell takes the movement of its nearest boundary point.

    Parameters
    ----------
    older, newer : (rows, cols) float
        Signed distances (positive inside) on the two benches, metres.
    cell_size_m, reach_m : float

    Returns
    -------
    moved : (rows, cols) float
        Outward movement, metres (negative where the boundary retreated);
        nan where the nearest boundary has no counterpart within the reach
        (a body appearing) and everywhere when ``newer`` has no boundary.
    origin : (2, rows, cols) float
        Where on the older boundary the cell's boundary point came from (the
        end of its trajectory on the bench above), (row, col) in cells; the
        boundary point itself where there is no counterpart.
    """
    n_r, n_c, directed = unit_normals(newer, cell_size_m)
    band = (np.abs(newer) <= cell_size_m) & directed
    if not band.any():
        return np.full(newer.shape, np.nan), np.full((2, *newer.shape), np.nan)
    n_r, n_c = n_r[band], n_c[band]
    rows, cols = np.nonzero(band)
    to_boundary = newer[band] / cell_size_m  # from each band cell to the boundary point, along -normal
    steps = np.arange(-reach_m, reach_m + 1e-9, 0.5 * cell_size_m) / cell_size_m
    along = [
        (rows - to_boundary * n_r)[:, None] + steps * n_r[:, None],
        (cols - to_boundary * n_c)[:, None] + steps * n_c[:, None],
    ]
    f = ndimage.map_coordinates(older, along, order=1, mode="nearest")
    entering = (f[:, :-1] <= 0) & (f[:, 1:] > 0)  # the older boundary, facing the same way
    t = np.where(entering, f[:, :-1] / np.where(entering, f[:, :-1] - f[:, 1:], 1.0), 0.0)
    offset_m = (steps[:-1] + t * (steps[1] - steps[0])) * cell_size_m
    nearest = np.argmin(np.where(entering, np.abs(offset_m), np.inf), axis=1)
    pick = np.arange(len(nearest))
    matched = entering[pick, nearest]
    moved = np.full(newer.shape, np.nan)
    moved[band] = np.where(matched, offset_m[pick, nearest], np.nan)
    _, (r, c) = ndimage.distance_transform_edt(~band, return_indices=True)
    # The older boundary point each band cell's boundary point was matched to, along its normal.
    along = np.where(matched, offset_m[pick, nearest], 0.0) / cell_size_m - to_boundary
    origin = np.full((2, *newer.shape), np.nan)
    origin[0][band], origin[1][band] = rows + along * n_r, cols + along * n_c
    return moved[r, c], origin[:, r, c]


def pair_movement(fields: BenchFields, older: int, newer: int, reach_m: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`boundary_movement` from bench ``older`` to ``newer``, kept in ``fields.memo``.

    A trend, its persistence and the backtests of the benches above ask for the same
    pairs; :func:`depth_trend` drops them (:data:`_MOVEMENTS`) once its trend is made.
    """
    movements = fields.memo.setdefault(_MOVEMENTS, {})
    if (older, newer, reach_m) not in movements:
        f = fields.distance
        movements[older, newer, reach_m] = boundary_movement(f[older], f[newer], fields.grid.cell_size_m, reach_m)
    return movements[older, newer, reach_m]


#: The memo's entry of bench pairs' movements: three grids a pair, kept only while a trend is made.
_MOVEMENTS = ("movements",)
#: The memo's entry of the last sections' transports (:func:`_with_shared_transport`), the latest last.
_TRANSPORTS = ("transports",)
#: How many sections' transports the memo keeps: a Kennecott build's 363 trends made 197 (90 sections; 16 kept, 90).
TRANSPORTS_KEPT = 4
#: The memo's entry holding the memo of :meth:`BenchFields.measured` (the observed benches' own results).
_OBSERVED = ("observed",)


def fastest_movement_m(bench_height_m: float, body_size_m: float = np.inf, min_dip_deg: float = MIN_DIP_DEG) -> float:
    """How far a boundary moves across itself in ``bench_height_m``: at the shallowest dip ``min_dip_deg``.

    And no further than the geozone's bodies are across (``body_size_m``,
    :func:`geozone_body_size_m`): a lens found a lens-width from where one
    was the bench above is another lens, not the first one moved. The dip
    alone lets a boundary move 1.7 bench heights a bench, and on 15 m
    benches (26 m) pods 16-23 m across read lenses appearing beside others
    as the others moving or growing and carried that on (development seeds
    0-47 of the pods drilled on 15 m benches in feet, F1 at half / one bench
    below 58.87 / 30.55 against holding's 58.44 / 30.74; bounded, 59.15 /
    31.18; by half the size, 58.87 / 31.13 and the pods on 10 m benches
    59.36 / 33.28 -> 59.25 / 33.05). On 10 m benches (17 m) the bound moves
    the pods little (59.40 / 33.35) and layers, strips and folds, 40-130 m
    across, not at all (development seeds 0-5 of every family and Kennecott
    unchanged).
    """
    return min(bench_height_m / float(np.tan(np.radians(min_dip_deg))), body_size_m)


def geozone_body_size_m(fields: BenchFields) -> float:
    """:func:`body_size_m` of the geozone's bodies on its benches (inside their drilled areas), kept in ``fields.memo``."""

    def compute() -> float:
        return body_size_m([(d > 0) & dr for d, dr in zip(fields.distance, fields.drilled)], fields.grid.cell_size_m)

    return _memoised(fields, ("body size", len(fields.z_m)), compute)


def geozone_fastest_movement_m(fields: BenchFields, bench_height_m: float) -> float:
    """:func:`fastest_movement_m` of the geozone's boundary over ``bench_height_m``, bounded by its bodies' size.

    At the fields' shallowest dip (:attr:`BenchFields.min_dip_deg`; the usual one, :data:`MIN_DIP_DEG`, before
    the benches chose).
    """
    return fastest_movement_m(bench_height_m, geozone_body_size_m(fields), fields.dip_deg)


def movement_reach_m(fields: BenchFields, older: int, newer: int, fastest_m: float) -> float:
    """How far a boundary of the geozone may have moved from bench ``older`` to ``newer``, metres.

    At least ``fastest_m`` (:data:`MIN_DIP_DEG`); further where the geozone as
    a whole moved further: the translation that best aligns the older bench's
    section with the newer's signed distance (FFT cross-correlation, paper
    section 3.2.1, eqs. (10)-(12)) inside the area both drilled, taken when the
    section moved by it overlaps the newer one better than the section held
    does and by at least half, and the held section is within ``fastest_m`` of
    the newer one (a contact dipping shallower than the benches' usual, not a
    lens ending and another beginning further away). Kept in ``fields.memo``.
    """

    def compute() -> float:
        both = fields.drilled[older] & fields.drilled[newer]
        source, target = (fields.distance[older] > 0) & both, (fields.distance[newer] > 0) & both
        if not source.any() or not target.any():
            return fastest_m
        d_row, d_col = fft_translation(source, np.where(both, fields.distance[newer], 0.0))
        shift_m = float(np.hypot(d_row, d_col)) * fields.grid.cell_size_m
        if shift_m <= fastest_m:
            return fastest_m
        moved = shift_mask(source, int(d_row), int(d_col)) & both

        def overlap(a: np.ndarray) -> float:
            return float(np.sum(a & target)) / max(float(np.sum(a | target)), 1.0)

        # the section moved, not a body vanishing and another appearing further away than a boundary moves
        held = overlap(source)
        gap_m = (
            0.0 if held > 0 else float(ndimage.distance_transform_edt(~target)[source].min()) * fields.grid.cell_size_m
        )
        confirmed = gap_m <= fastest_m and overlap(moved) >= max(0.5, held)
        return shift_m + fields.grid.cell_size_m if confirmed else fastest_m

    def reach() -> float:
        aligned = compute()
        return aligned if aligned > fastest_m else coherent_reach_m(fields, older, newer, fastest_m)

    return _memoised(fields, ("reach", older, newer, fastest_m), reach)


def coherent_reach_m(fields: BenchFields, older: int, newer: int, fastest_m: float) -> float:
    """How far the geozone's boundary moved from ``older`` to ``newer`` if much of it moved further than ``fastest_m`` one way.

    The sections' alignment (:func:`movement_reach_m`) finds a translation
    only where the whole section moves with it: a contact or a layer crossing
    the drilling, one part of a geozone whose other parts stand, stays put
    under it (moved, it leaves the drilled area as much as it gains). Here the
    newer boundary is matched to the older one as far as a boundary dipping
    :data:`COHERENT_DIP_DEG` moves (:func:`boundary_movement`); when enough of
    its points (:data:`COHERENT_SHARE`) moved further than ``fastest_m``, and
    those movements, as vectors along the boundary's normals, point the same
    way (the length of their mean at least :data:`COHERENCE` of their mean
    length: a translation, not a lens growing or another appearing around it),
    the further reach is the pair's. Found on development seeds 0-2 of the
    families moving 10-25 m a bench (a scratch variant of the generator): the
    contacts of ``mix`` (F1 at 5 / 10 m 93.1 / 88.8 -> 96.5 / 95.2); the
    families as generated and Kennecott, whose boundaries move within the
    bound, unchanged (held-out pods within 0.04).
    """
    cell_m = fields.grid.cell_size_m
    f_new = fields.distance[newer]
    both = fields.drilled[older] & fields.drilled[newer]
    near, _ = pair_movement(fields, older, newer, fastest_m)
    n_r, n_c, directed = unit_normals(f_new, cell_m)
    band = (np.abs(f_new) <= cell_m) & directed & both
    # Points matched within the bound cannot leave the share that moved further: spare the wider search.
    if np.sum(np.isfinite(near[band])) > (1.0 - COHERENT_SHARE) * np.sum(band):
        return fastest_m
    far_m = fastest_m * float(np.tan(np.radians(fields.dip_deg)) / np.tan(np.radians(COHERENT_DIP_DEG)))
    if far_m <= fastest_m:  # the fields' own bound is already as shallow (:func:`with_backtested_dip`)
        return fastest_m
    moved, _ = pair_movement(fields, older, newer, far_m)
    band &= np.isfinite(moved)
    beyond = band & (np.abs(moved) > fastest_m)
    if not beyond.any() or np.sum(beyond) < COHERENT_SHARE * np.sum(band):
        return fastest_m
    vectors = moved[beyond] * np.stack([n_r[beyond], n_c[beyond]])
    coherence = float(np.linalg.norm(vectors.mean(axis=1)) / np.mean(np.linalg.norm(vectors, axis=0)))
    return far_m if coherence >= COHERENCE else fastest_m


def fit_trend(fields: BenchFields, bench_height_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per cell, the last observed signed distance, where it was observed and its change with depth.

    Each cell's trend rests on the last two benches drilled there (the
    deepest one, ``j1``, and the one above it that was drilled there,
    ``j2``): the :func:`boundary_movement` of its nearest boundary from
    ``j2`` to ``j1`` (within :func:`movement_reach_m`), per bench height; where that boundary has no
    counterpart, the change from ``F_j2`` to ``F_j1``, held where faster than
    a boundary moves (:data:`MIN_DIP_DEG`). A cell drilled by one bench only
    has no change; a cell none drilled takes the deepest bench's nearest
    evidence, with no change.

    Returns
    -------
    f_last, z_last, rate : (rows, cols) float
        ``F_j1``, the elevation of ``j1`` (metres) and the outward movement
        of the boundary per bench height downwards.
    matched : (rows, cols) bool
        Where ``rate`` is the movement of a boundary matched on both benches.
    """
    last, before = last_observations(fields)
    z = fields.z_m

    def take(idx: np.ndarray) -> np.ndarray:
        return np.take_along_axis(fields.distance, np.maximum(idx, 0)[None], axis=0)[0]

    f_last = take(last)
    fastest_m = geozone_fastest_movement_m(fields, bench_height_m)
    two = (last >= 0) & (before >= 0)
    # signed: negative when extrapolating upwards (fields reversed), as the rate is per bench in that direction
    benches = np.where(two, z[np.maximum(before, 0)] - z[np.maximum(last, 0)], bench_height_m) / bench_height_m
    # Where a boundary has no counterpart (the inner edges of a split, a lens appearing) the change of F
    # is all the benches say, held where faster than a boundary moves.
    rate = np.where(two, (f_last - take(before)) / benches, 0.0)
    rate = np.where(np.abs(rate) > fastest_m, 0.0, rate)
    n = len(z)
    pairs = [divmod(int(code), n) for code in np.unique(last[two] * n + before[two])]  # each cell's (j1, j2), once
    matched = np.zeros(rate.shape, bool)
    for j1, j2 in pairs:
        cells = (last == j1) & (before == j2)
        gap = float(benches[cells][0])
        reach = movement_reach_m(fields, j2, j1, fastest_m * abs(gap))
        moved, _ = pair_movement(fields, j2, j1, reach)
        matched[cells] = np.isfinite(moved[cells])
        rate[cells] = np.where(matched[cells], moved[cells] / gap, rate[cells])
    observed = last >= 0
    f_last = np.where(observed, f_last, fields.distance[-1])
    return f_last, np.where(observed, z[np.maximum(last, 0)], z[-1]), rate, matched


def outline_movement(rate: np.ndarray, matched: np.ndarray, f_last: np.ndarray, cell_size_m: float) -> np.ndarray:
    """The part of a movement that moves each outline as a whole: translation, growth and elongation.

    Per connected stretch of the boundary of ``f_last`` (the outline of a
    body, of a hole in one, or a contact crossing the grid; traced on its
    inner side, so that two bodies a gap of a few cells apart keep two
    outlines), the least-squares
    fit of its outward movement ``rate`` over its cells by harmonics 0-2 of
    the direction of the outward normal ``n = (cos t, sin t)``::

        a + b cos t + c sin t + d cos 2t + e sin 2t

    (``a`` growth, ``(b, c)`` a translation, ``(d, e)`` the normal movement of
    a stretch along an axis: a body elongating or splitting), bounded by the
    5th and 95th percentiles of the movement measured on the stretch (on a
    long winding contact whose normals point some way at a few cells only,
    the harmonics alone made up movements no cell showed: single geozones of
    the mix family lost 10-27 F1 points). Every cell in ``matched`` (its boundary's movement measured,
    :func:`boundary_movement`) takes the fit at its nearest boundary cell;
    the others keep ``rate``. ``rate`` may hold several movements stacked on
    a first axis, fitted on the same outlines at once.

    The finer changes are what shape noise is made of, and with two benches
    known nothing tells them from a change that carries on
    (:func:`geozone_persistence`). Carried on, they lost 2.9 F1 points to
    holding the last bench on a constructed body whose outline changes at
    random from bench to bench; the outline's movement alone, 0.8
    (BENCHMARKS.md). Without the elongation that noise was held entirely but
    a body splitting in two lost 4.5 points.
    """
    inward_r, inward_c, directed = unit_normals(f_last, cell_size_m)
    band = (np.abs(f_last) <= cell_size_m) & directed
    # Traced on both sides, the outlines of the two parts of a body that has just split joined across their gap:
    # one fit of their opposite movements cancelled them (a constructed split carried half of its parting).
    inner = band & (f_last > 0)
    rings, n = ndimage.label(inner, structure=np.ones((3, 3)))
    if n == 0:
        return rate
    _, (ring_r, ring_c) = ndimage.distance_transform_edt(~inner, return_indices=True)
    stretches = np.where(band, rings[ring_r, ring_c], 0)
    owner, use = stretches[band], matched[band]
    values = rate[..., band].reshape(-1, owner.size).T  # (band cells, movements)
    n_r, n_c = -inward_r[band], -inward_c[band]
    design = np.column_stack([np.ones(owner.size), n_r, n_c, n_r**2 - n_c**2, 2 * n_r * n_c])
    fitted = np.full(values.shape, np.nan)
    for stretch in np.unique(owner[use]):
        fit, cells = use & (owner == stretch), owner == stretch
        if fit.sum() >= design.shape[1]:
            coef, *_ = np.linalg.lstsq(design[fit], values[fit], rcond=None)
            fitted[cells] = np.clip(design[cells] @ coef, *np.percentile(values[fit], [5, 95], axis=0))
    on_band = np.full(rate.shape, np.nan)
    on_band[..., band] = fitted.T.reshape(rate[..., band].shape)
    _, (r, c) = ndimage.distance_transform_edt(~band, return_indices=True)
    nearest = on_band[..., r, c]
    return np.where(matched & np.isfinite(nearest), nearest, rate)


@dataclass
class DepthTrend:
    """A geozone's signed distance below its deepest bench (see the module docstring).

    Per cell: the signed distance ``f_last`` at the deepest bench that
    observed the cell (elevation ``z_last``), the outward movement of its
    boundary per bench height downwards ``rate`` (in the direction of
    extrapolation) and the part of it that carries on, ``carried``
    (:func:`chosen_persistence`, :data:`GROWTH_CONTINUITY_POWER`). The
    boundary moves ``m = carried * (z_last - z) / bench_height_m`` metres
    outwards (along ``-grad F``), and ``F(z)`` is ``f_last`` carried by that
    movement (:meth:`field`).
    ``transport_smoothing_m``: the neighbourhood over which the movement is
    fitted by a displacement. ``carried_precision`` is the share of a
    carried section the next bench confirms (:func:`carried_precision`) and
    ``f_deepest`` the deepest bench's signed distance: where the benches above
    it saw the geozone and the deepest did not drill, the geozone is kept only
    while ``carried_precision ** benches`` stays at least
    :data:`STALE_EVIDENCE_PROBABILITY`.
    """

    grid: Grid
    z_ref_m: float  #: elevation of the deepest known bench
    bench_height_m: float
    f_last: np.ndarray
    z_last: np.ndarray
    rate: np.ndarray
    carried: np.ndarray
    transport_smoothing_m: float
    carried_precision: float
    f_deepest: np.ndarray
    drilled_any: np.ndarray  #: cells some bench drilled

    def movement(self, z_m: float) -> np.ndarray:
        """Metres the boundary moves outwards from ``z_last`` to ``z_m``, per cell."""
        return self.carried * (self.z_last - z_m) / self.bench_height_m

    def field(self, z_m: float) -> np.ndarray:
        """Signed distance to the predicted boundary at elevation ``z_m`` (past the deepest bench).

        The last signed distance is transported (semi-Lagrangian, as the
        level set of ALGORITHMS.md is advected) by the displacement
        ``d``, ``F(x) = f_last(x + d)``, ``d`` fitted to the movements
        ``m = d . n`` across the boundary (``n = grad F / |grad F|``) over
        ``transport_smoothing_m`` among cells whose boundary faces the same
        way (:func:`displacement_by_direction`): ``m n`` where the boundary
        is straight, the whole translation where it curves. For a section
        that moves by a translation the displacement is that translation at
        both of its boundaries, so a strip or fold limb that moves further
        than its half-width per bench is carried whole, where adding ``m`` to
        ``F`` (exact only where ``F`` is linear along the movement) thinned it
        at its ridge. On a body's ridge, where ``F`` has no direction,
        ``f_last`` moves as the slower of its two sides (:attr:`_ridge`);
        elsewhere without a direction (the cap, the ridges between bodies)
        ``f_last + m`` is kept. Where the boundary recedes
        (``d . n < 0``), ``F`` is at most ``f_last + d . n``, exact for a
        straight boundary and never reached on the trailing side of a convex
        body: a displacement wider than the gap between the two parts of a
        split fetched the other part's inside into the gap. Where only benches above the
        deepest saw the geozone and its bodies have likely ended by ``z_m``
        (see the class), the deepest bench's evidence is taken instead. A part
        of the region that no bench drilled any of is dropped (:meth:`_evidenced`).
        """
        movement = self.movement(z_m)
        field = self.f_last + movement
        if self.transport_smoothing_m > 0:
            n_r, n_c, directed = self._normals
            move = movement / self.grid.cell_size_m  # the class weights are 0 where there is no direction
            d_r, d_c = displacement_by_direction(move, n_r, n_c, self._flow_systems, self._sigma_cells)
            rows, cols = np.indices(self.f_last.shape, dtype=float)
            carried = ndimage.map_coordinates(self.f_last, [rows + d_r, cols + d_c], order=1, mode="nearest")
            field = np.where(directed, carried, field)
            across = (d_r * n_r + d_c * n_c) * self.grid.cell_size_m  # metres the boundary moves outwards here
            receding = directed & (across < 0)
            field = np.where(receding, np.minimum(field, self.f_last + across), field)
            # A body's ridge moves as its sides' slower movement: a strip carried past its half-width leaves it.
            field[self._ridge] = self.f_last[self._ridge] + ridge_sides(np.where(directed, across, np.inf), self._ridge)
        field = np.where(self._ended(z_m), np.minimum(field, self.f_deepest), field)
        return self._evidenced(field)

    def _evidenced(self, field: np.ndarray) -> np.ndarray:
        """``field`` with each part of its region that no bench drilled any cell of set outside.

        Past the drilled area a bench's ``F`` extends its nearest evidence
        (:func:`bench_distance`); tens of metres out the distances to the
        nearest inside and outside holes differ by a few metres, either way,
        and a part of the region there rests on none: the demo's model drew a
        body 450 m2 in size 35-50 m past the pit's edge, where no bench had
        the geozone.
        """
        inside = field > 0
        unevidenced = inside & ~parts_touching(inside, self.drilled_any, np.ones((3, 3)))
        return np.where(unevidenced, np.minimum(field, -self.grid.cell_size_m), field)

    def _ended(self, z_m: float) -> np.ndarray:
        """Cells whose evidence is older than the deepest bench and likely no longer holds at ``z_m``."""
        benches = np.abs(self.z_last - z_m) / self.bench_height_m
        stale = self.z_last != self.z_ref_m
        return stale & (self.carried_precision**benches < STALE_EVIDENCE_PROBABILITY)

    # What the transport needs of the last section alone: made once per trend, not per elevation.
    @cached_property
    def _sigma_cells(self) -> float:
        return self.transport_smoothing_m / self.grid.cell_size_m

    @cached_property
    def _normals(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return unit_normals(self.f_last, self.grid.cell_size_m)

    @cached_property
    def _flow_systems(self) -> list[tuple[np.ndarray, tuple]]:
        n_r, n_c, directed = self._normals
        classes = direction_classes(np.arctan2(n_r, n_c), directed, self._sigma_cells)
        return flow_systems(n_r, n_c, classes, self._sigma_cells)

    @cached_property
    def _ridge(self) -> np.ndarray:
        """Cells of a body's ridge: inside, with no normal, within :data:`RIDGE_REACH_CELLS` of cells that have one.

        Its signed distance there moves as the slower of the boundaries on either side moves (outwards: the
        least ``d . n`` of the directed cells around it), as a strip's spine does: it stays inside while both
        sides move out (a body growing), leaves when one side recedes past it (a strip carried further than
        its half-width a bench, a body thinning out). Further in lies the cap's plateau, which keeps
        ``f_last + m``. Kept as ``f_last + m`` with its nearest boundary's movement, the ridge of a strip
        carried past its half-width stayed inside: a chain of islands along the old strip's spine
        (constructed strips 12-24 m wide moving 9-16 m a bench: IoU 0.77-0.94 -> 0.84-0.97, each in one part
        where ten of twelve were in 4-20).
        """
        _, _, directed = self._normals
        if not directed.any():
            return np.zeros_like(directed)
        return ~directed & (self.f_last > 0) & (ndimage.distance_transform_edt(~directed) <= RIDGE_REACH_CELLS)

    def region(self, z_m: float) -> MultiPolygon:
        """The region ``F > 0`` at ``z_m`` less its parts and holes smaller than a cell, which the field cannot resolve.

        Those are slivers where ``F`` grazes zero (a saddle, the far field past
        the drilling): below the demo's deepest bench the host geozone had
        dozens, most of no area at all, and g2 holes of a few hundredths of a m2.
        """
        region = self.grid.polygons_from_distance(self.field(z_m))
        cell = self.grid.cell_size_m**2
        return MultiPolygon(
            [
                shapely.Polygon(part.exterior, [hole for hole in part.interiors if shapely.Polygon(hole).area >= cell])
                for part in region.geoms
                if part.area >= cell
            ]
        )

    def replaced(self, **changes) -> DepthTrend:
        """A copy with ``changes`` (not of the last section) that shares what the transport made of the last section."""
        other = replace(self, **changes)
        other.__dict__.update(self.transport())
        return other

    def transport(self) -> dict:
        """What the transport makes of the last section alone (its cached properties), to share with another trend."""
        return {name: getattr(self, name) for name in ("_sigma_cells", "_normals", "_flow_systems", "_ridge")}


def ridge_sides(across: np.ndarray, ridge: np.ndarray) -> np.ndarray:
    """At each ``ridge`` cell, the least of ``across`` within :data:`RIDGE_REACH_CELLS` (a square window).

    :func:`scipy.ndimage.minimum_filter`'s value (its reflecting edges), taken only at the ridge's cells: a
    ridge is a line a cell or two wide, and the filter over the whole grid ran at every elevation of every
    prediction and backtest.
    """
    reach = int(RIDGE_REACH_CELLS)
    padded = np.pad(across, reach, mode="symmetric")
    windows = np.lib.stride_tricks.sliding_window_view(padded, (2 * reach + 1, 2 * reach + 1))
    rows, cols = np.nonzero(ridge)
    return windows[rows, cols].min(axis=(1, 2))


def direction_classes(theta: np.ndarray, valid: np.ndarray, sigma_cells: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Weights of :data:`TRANSPORT_DIRECTIONS` overlapping classes of boundary normal, and their local sums.

    Class ``k`` weighs a cell ``max(cos(theta - theta_k), 0) ** 4`` (``theta``:
    the normal's angle, radians; 0 where not ``valid``); its local sum is the
    weight's Gaussian average over ``sigma_cells`` (at least 1e-3).
    """
    classes = []
    for k in range(TRANSPORT_DIRECTIONS):
        w = np.maximum(np.cos(theta - 2 * np.pi * k / TRANSPORT_DIRECTIONS), 0.0) ** 4 * valid
        classes.append((w, np.maximum(local_gaussian_filter(w, sigma_cells), 1e-3)))
    return classes


def flow_systems(
    n_r: np.ndarray, n_c: np.ndarray, classes: list[tuple[np.ndarray, np.ndarray]], sigma_cells: float
) -> list[tuple[np.ndarray, tuple]]:
    """Per direction class, its weight and the inverse of the normal equations of :func:`displacement_by_direction`.

    They rest on the boundary's normals alone: made once per section, not per
    elevation. The inverse is a 3 x 3 nested tuple of per-cell arrays.
    """
    systems = []
    for w, weight in classes:
        rr, rc, r1, c1 = (local_gaussian_filter(w * x, sigma_cells) for x in (n_r * n_r, n_r * n_c, n_r, n_c))
        cc = weight - rr  # n_r^2 + n_c^2 = 1 where w > 0
        ridge = RIDGE_SHARE * weight + 1e-9
        systems.append(
            (w, _inverse_symmetric_3x3([[rr + ridge, rc, r1], [rc, cc + ridge, c1], [r1, c1, weight + ridge]]))
        )
    return systems


def displacement_by_direction(
    movement: np.ndarray, n_r: np.ndarray, n_c: np.ndarray, systems: list[tuple[np.ndarray, tuple]], sigma_cells: float
) -> tuple[np.ndarray, np.ndarray]:
    """The displacement that moves each boundary cell's neighbourhood as its movements across itself say.

    The benches measure only the movement of a boundary across itself,
    ``m_i = d . n_i`` (``n_i`` the unit normal, pointing inside): the aperture
    problem. Where the boundary curves within a neighbourhood its normals
    turn, and together they fix the whole displacement (normal flow, as
    Lucas-Kanade solves it). Per cell, the least-squares fit over a Gaussian
    neighbourhood of ``sigma_cells`` of::

        m_i = v . n_i + a

    a translation ``v`` and a growth ``a``, with a ridge of
    :data:`RIDGE_SHARE` of the neighbourhood's weight (where the normals do
    not turn, it leaves ``v`` across the boundary only), gives the displacement ``v + a n`` at the
    cell. A translating body's end moves whole; averaging ``m_i n_i`` instead
    moved it by the mean of ``cos^2`` over the arc (0.6 of the movement on a
    lobe 22 m in radius), the far ends of merging lobes running out.

    Each section's boundary errs by a fraction of a hole spacing that does
    not repeat from bench to bench; the fit over the neighbourhood cancels it.
    Across a narrow gap, the opposite movements of two parts moving apart (a
    split) would cancel too, so each cell fits only with cells whose boundary
    faces its way: within each of the :func:`direction_classes`, weighted by
    its class weight (``systems``: :func:`flow_systems`). ``movement`` in
    cells; returns ``(d_r, d_c)`` in cells.
    """
    out_r, out_c, total = np.zeros_like(movement), np.zeros_like(movement), np.zeros_like(movement)
    for w, inverse in systems:
        b = [local_gaussian_filter(w * movement * x, sigma_cells) for x in (n_r, n_c, 1.0)]
        v_r, v_c, a = (row[0] * b[0] + row[1] * b[1] + row[2] * b[2] for row in inverse)
        out_r += w * (v_r + a * n_r)
        out_c += w * (v_c + a * n_c)
        total += w
    total = np.maximum(total, 1e-9)
    return out_r / total, out_c / total


def sliding_bias(rate: np.ndarray, matched: np.ndarray, section: DepthTrend) -> np.ndarray:
    """The part of a boundary's measured movement that is its slide along itself, seen across a curve.

    :func:`boundary_movement` measures along the newer boundary's normal. A
    curved boundary that translates by ``d`` lies ``d . n + k (d . t)^2 / 2``
    outside its older self there (``k`` its curvature, ``t`` its tangent):
    at the sides of a disc moving 10 m a bench, 2 m of seeming growth per
    bench, which carried on widened it by 6 m across its path one bench down
    (exact signed distances, no holes). The slide ``d . t`` is the
    displacement that :func:`displacement_by_direction` fits to the
    movements with the fits ``section``'s transport makes of its last
    section ``f_last`` (shared with it); the curvature is the boundary's,
    averaged over the same neighbourhood. Returns the bias per cell (metres,
    as ``rate``: each cell takes its nearest boundary cell's), 0 where the
    movement was not matched.
    """
    f_last, cell_size_m, sigma = section.f_last, section.grid.cell_size_m, section._sigma_cells
    n_r, n_c, directed = section._normals
    band = (np.abs(f_last) <= cell_size_m) & directed & matched
    if not band.any():
        return np.zeros_like(rate)
    movement = np.where(matched, rate, 0.0) / cell_size_m
    d_r, d_c = displacement_by_direction(movement, n_r, n_c, section._flow_systems, sigma)
    slide_m = (d_c * n_r - d_r * n_c) * cell_size_m
    # The level sets' curvature, -div n (positive where the geozone is convex), averaged along the boundary.
    s_r, s_c, _ = unit_normals(ndimage.gaussian_filter(f_last, 1.0), cell_size_m)
    curvature = -(np.gradient(s_r, axis=0) + np.gradient(s_c, axis=1)) / cell_size_m
    weight = local_gaussian_filter(band.astype(float), sigma)
    curvature = local_gaussian_filter(np.where(band, curvature, 0.0), sigma) / np.maximum(weight, 1e-9)
    bias = np.where(band, 0.5 * curvature * slide_m**2, 0.0)
    _, (r, c) = ndimage.distance_transform_edt(~band, return_indices=True)
    return np.where(matched, bias[r, c], 0.0)


def _inverse_symmetric_3x3(m: list[list[np.ndarray]]) -> tuple:
    """The inverse of a symmetric, nonsingular 3 x 3 matrix per element, by its adjugate."""
    c00 = m[1][1] * m[2][2] - m[1][2] ** 2
    c01 = m[0][2] * m[1][2] - m[0][1] * m[2][2]
    c02 = m[0][1] * m[1][2] - m[0][2] * m[1][1]
    c11 = m[0][0] * m[2][2] - m[0][2] ** 2
    c12 = m[0][1] * m[0][2] - m[0][0] * m[1][2]
    c22 = m[0][0] * m[1][1] - m[0][1] ** 2
    det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02
    i00, i01, i02, i11, i12, i22 = (c / det for c in (c00, c01, c02, c11, c12, c22))
    return ((i00, i01, i02), (i01, i11, i12), (i02, i12, i22))


def body_continuity(fields: BenchFields, bench_height_m: float) -> float:
    """The share of a geozone's bodies that reach the next bench, by area, in [0, 1].

    A body is a connected part of the geozone inside a bench's drilled area;
    it reaches the next bench when that bench has the geozone within the
    furthest a boundary moves per bench (:data:`MIN_DIP_DEG`, whatever bound
    the benches chose, :func:`with_backtested_dip`: with the shallower one,
    bodies of a geozone that go on read as lens-sized and lost their growth)
    of it. Only
    bodies the next bench drilled (half of their area or more) count. Layers,
    strips and folds reach every next bench (1.0 on every synthetic family
    but pods); lenses a bench or two tall do not (pods: median 0.5). 1.0
    where nothing can be counted. Where the geozone's bodies are lens-sized
    (smaller than a disc of the furthest a boundary moves per bench), the
    share is drawn towards one half by :data:`LENS_PRIOR_DISCS` such discs.
    """
    reach_cells = _lens_reach_cells(fields, bench_height_m)
    reached = counted = 0.0
    counts = []  # bodies per bench, for the typical body: each bench is labelled once
    for j in range(len(fields.z_m) - 1):
        bodies, n = ndimage.label((fields.distance[j] > 0) & fields.drilled[j])
        counts.append(n)
        below = fields.distance[j + 1] > 0
        if n == 0 or not fields.drilled[j + 1].any():
            continue
        ids = np.arange(1, n + 1)
        area = np.bincount(bodies.ravel(), minlength=n + 1)[1:].astype(float)
        drilled_next = ndimage.mean(fields.drilled[j + 1], bodies, ids) >= 0.5
        reaches = np.zeros(n, bool)
        if below.any():
            reaches = ndimage.minimum(ndimage.distance_transform_edt(~below), bodies, ids) <= reach_cells
        counted += float(np.sum(area[drilled_next]))
        reached += float(np.sum(area[drilled_next & reaches]))
    if not counted:
        return 1.0
    counts.append(ndimage.label((fields.distance[-1] > 0) & fields.drilled[-1])[1])
    if not lens_sized(fields, bench_height_m, counts):
        return reached / counted
    prior = LENS_PRIOR_DISCS * np.pi * reach_cells**2
    return (reached + 0.5 * prior) / (counted + prior)


def _lens_reach_cells(fields: BenchFields, bench_height_m: float) -> float:
    """The furthest a boundary of the geozone moves a bench at :data:`MIN_DIP_DEG`, bounded by its bodies' size, in cells."""
    return fastest_movement_m(bench_height_m, geozone_body_size_m(fields)) / fields.grid.cell_size_m


def lens_sized(fields: BenchFields, bench_height_m: float, counts: list[int] | None = None) -> bool:
    """Whether the geozone's bodies are lens-sized: its typical body smaller than a disc of the furthest a boundary moves.

    That furthest is a bench's at :data:`MIN_DIP_DEG` whatever bound the
    benches chose, bounded by the bodies' size (:func:`fastest_movement_m`);
    the typical body is :func:`typical_body_cells` (``counts``: its bodies per
    bench, where the caller has labelled them). A lens found that far from one
    on the bench above cannot be told from another lens.
    """
    return typical_body_cells(fields, counts) < np.pi * _lens_reach_cells(fields, bench_height_m) ** 2


def depth_trend(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> DepthTrend:
    """The geozone's :class:`DepthTrend` from its benches' :class:`BenchFields`.

    Kept in ``fields.memo``: a prediction and the uncertainty of each of its
    elevations ask for the same trend.
    """

    def compute() -> DepthTrend:
        return _confirmed(fields, _trend(fields, bench_height_m, hole_spacing_m), bench_height_m, hole_spacing_m)

    return _memoised(fields, ("trend", len(fields.z_m), bench_height_m, hole_spacing_m), compute)


def depth_trend_region(fields: BenchFields, bench_height_m: float, hole_spacing_m: float, z_m: float) -> MultiPolygon:
    """:meth:`DepthTrend.region` at ``z_m`` of :func:`depth_trend`, kept in ``fields.memo`` with the trend.

    A geozone's prediction, its uncertainty's backtest, the evaluation and its surface ask for the same sections.
    """
    key = ("trend region", len(fields.z_m), bench_height_m, hole_spacing_m, float(z_m))
    return _memoised(fields, key, lambda: depth_trend(fields, bench_height_m, hole_spacing_m).region(z_m))


def _confirmed(fields: BenchFields, trend: DepthTrend, bench_height_m: float, hole_spacing_m: float) -> DepthTrend:
    """``trend`` with its :func:`carried_precision` backtested on ``fields``; the bench pairs' movements dropped.

    The movements (three grids a pair, in the memo and in the observed benches' memo) are kept only while a
    trend is made.
    """
    confirmed = carried_precision(fields, bench_height_m, hole_spacing_m, trend.carried_precision)
    fields.memo.pop(_MOVEMENTS, None)
    fields.memo.get(_OBSERVED, {}).pop(_MOVEMENTS, None)
    return trend.replaced(carried_precision=confirmed)  # shares the trend's arrays and its transport's fits


#: The shallower dip a geozone's own benches may choose instead of :data:`MIN_DIP_DEG`
#: (:func:`with_backtested_dip`): 15 degrees, 3.7 bench heights a bench, taken where it put at
#: least :data:`SHALLOW_DIP_GAIN` fewer cells of the backtested benches on the wrong side. Travelling
#: waves moving 3-30 m a bench (``bench_foreign.py``'s generator, development seeds 100-111), F1 at 5 /
#: 10 m: 80.6 / 63.2 with 30 degrees, 83.0 / 67.0 with 15 everywhere (the implicit model 81.9 / 65.2),
#: 81.7 / 65.0 chosen so (0.1; 82.1 / 65.6 with no gain asked). The families (development seeds 0-3)
#: lose by 15 everywhere (96.37 / 94.96 -> 95.8 / 93.7: lenses matched to others further away), by
#: nothing chosen with a gain of 0.1 (-0.02 / -0.05 with 0.05, -0.1 / -0.2 with none); Kennecott 74.5
#: -> 74.4 on the holes (74.1 with none): there the two bounds' counts differ by a few per cent, for
#: the waves by 10-20%.
SHALLOW_DIP_DEG = 15.0
SHALLOW_DIP_GAIN = 0.1
#: The bound with two benches known, where no bench pair can backtest one (:func:`with_backtested_dip`):
#: 20 degrees, 2.7 bench heights a bench. Two benches cannot tell a boundary moving fast from a body
#: appearing beside another, and on fast geology the first is the commoner. Chosen on development seeds
#: (2026-12-03, F1 at 5 / 10 m below the deepest bench): travelling waves moving 3-30 m a bench
#: (``bench_foreign.py``'s generator, seeds 100-123) 80.5 / 62.9 with 30 degrees, 81.0 / 63.6 with 20
#: (15: 81.2 / 63.9; 25: 80.7 / 63.2), 2-20 m a bench 88.9 / 78.8 -> 89.2 / 79.2; the families (seeds
#: 0-3) 96.42 / 95.06 -> 96.40 / 95.01 (15: 96.38 / 94.96; 25: 96.41 / 95.05), where a few mislabelled
#: holes 17-27 m from the geozone's boundary now grow as a boundary would; Kennecott unchanged. Not where
#: the geozone's bodies are lens-sized (:func:`lens_sized`): with 20 degrees there too, pods (seeds 4-19)
#: went from 61.89 / 34.04 F1 (holding: 61.86 / 33.97) to 61.99 / 33.87. As it is: pods unchanged, the
#: families 96.40 / 95.02, the waves as with 20 degrees everywhere.
TWO_BENCH_DIP_DEG = 20.0


def with_backtested_dip(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> BenchFields:
    """``fields`` with the shallowest dip taken as movement that best predicted the geozone's own benches.

    A backtest (issue 12: how far to carry the movement on is learnt from
    the geozone's benches): from the third bench on, each bench ``j + 1`` is
    predicted from the benches down to ``j`` with each bound
    (:data:`MIN_DIP_DEG`, :data:`SHALLOW_DIP_DEG`), their movement carried as
    far as their agreement says (:func:`geozone_persistence`), and the cells
    of ``j + 1``'s drilled area (drilled on ``j`` as well) put on the wrong
    side are summed over the pairs. The shallower bound is taken only where it
    put a share :data:`SHALLOW_DIP_GAIN` fewer cells wrong: a boundary whose movement outruns the usual bound
    (travelling waves' boundaries moving 20-40 m a bench) is followed, and
    lenses that appear beside others, which the shallower bound reads as
    moving, keep the usual one. With fewer than three benches nothing can be
    backtested: :data:`TWO_BENCH_DIP_DEG`, but the usual bound where the
    geozone's bodies are lens-sized (:func:`lens_sized`: a lens beside the
    one above is another lens). Each pair's count rests on its benches
    alone: kept in ``fields.memo``.
    """
    if fields.min_dip_deg is not None:
        return fields
    n = len(fields.z_m)
    if n < 3:
        return replace(fields, min_dip_deg=MIN_DIP_DEG if lens_sized(fields, bench_height_m) else TWO_BENCH_DIP_DEG)

    def wrong_cells(dip: float, j: int) -> float:
        def compute() -> float:
            known = replace(fields.through(float(fields.z_m[j])), min_dip_deg=dip)
            trend = _trend(known, bench_height_m, hole_spacing_m, geozone_persistence(known, hole_spacing_m))
            return float(_backtest_rows(fields, j, [trend])[0, 0])

        return _memoised(fields, ("dip backtest", dip, j, bench_height_m, hole_spacing_m), compute)

    usual, shallow = (sum(wrong_cells(dip, j) for j in range(1, n - 1)) for dip in (MIN_DIP_DEG, SHALLOW_DIP_DEG))
    chosen = SHALLOW_DIP_DEG if shallow < (1.0 - SHALLOW_DIP_GAIN) * usual else MIN_DIP_DEG
    return replace(fields, min_dip_deg=chosen)


#: How far a bench's signed distance is drawn towards its prediction from the benches above
#: (:func:`assimilated`), and the largest disagreement, in hole spacings, that is drawn at all.
#: Chosen on development seeds 3-5 of every family (pooled F1 at 5 / 10 m 96.63 / 95.55 without
#: it): gates of 0.5, 0.7, 1 and 1.5 spacings at weight 0.3 96.80 / 95.73, 96.91 / 95.87,
#: 97.01 / 96.01, 97.02 / 96.03 (no gate: pods -5.9 / -4.5, lenses the benches above did not see
#: drawn away); weights 0.2 and 0.3 (the benches' agreement read from their own contours,
#: :meth:`BenchFields.measured`) 96.88 / 95.85 and 96.94 / 95.91, seeds 0-2 95.04 / 93.33 ->
#: 95.41 / 93.76 with 0.2; Kennecott 74.3 -> 74.2 on the holes (85.2 from bench 4 both). 0.3 drew
#: a growing body of a test's fresh mine under holding's precision at 5 m (93.71 against 93.74).
ASSIMILATION_WEIGHT = 0.2
ASSIMILATION_GATE_SPACINGS = 1.0


def assimilated(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> BenchFields:
    """The benches' signed distances, each drawn towards the prediction of it from the benches above.

    A bench's holes place its boundary only within the gap between an inside
    and an outside hole (its contour runs about half-way, up to half a hole
    spacing off); the benches above predict it (:func:`depth_trend`) with an
    error of their own, and the two together place it better than either (an
    update of the kind a Kalman filter makes; not in the paper). From the
    third bench down, where the prediction is within
    :data:`ASSIMILATION_GATE_SPACINGS` of the bench's own ``F`` in a cell both
    the bench and the one above drilled, ``F`` moves
    :data:`ASSIMILATION_WEIGHT` of the way to it: its boundary moves at most
    0.2 spacings (the weight times the gate), less than the half-gap between
    its holes, so no hole changes side. Where they disagree by more, the bench
    shows what the benches above could not (a split, a lens appearing) and
    stands. Benches are taken top down, each predicted from the benches above
    as already drawn; their backtests stay in the result's memo.
    How far the movement carries on is still judged on the benches as their
    holes showed them (:meth:`BenchFields.measured`).

    Parameters
    ----------
    fields : BenchFields
        Top first.
    bench_height_m, hole_spacing_m : float

    Returns
    -------
    BenchFields
        A copy; ``fields`` is not changed.
    """
    out = replace(fields, distance=fields.distance.copy(), memo={}, observed=fields.distance)
    gate = ASSIMILATION_GATE_SPACINGS * hole_spacing_m
    for j in range(2, len(out.z_m)):
        above = out.through(float(out.z_m[j - 1]))
        # The trends the backtest of bench j makes (its rows kept below, not the trends): a trend kept for
        # every bench took a Kennecott build from 2.0 to 2.8 GB, and making them twice took it 58.6 -> 63 s.
        # With three benches above, the backtest's agreement (read against 0), not chosen_persistence's.
        trends = _ways_trends(above, bench_height_m, hole_spacing_m)
        trend = _confirmed(
            above, trends[_chosen_way(above, bench_height_m, hole_spacing_m)], bench_height_m, hole_spacing_m
        )
        predicted = trend.field(float(out.z_m[j]))
        disagreement = predicted - out.distance[j]
        drawn = out.drilled[j] & out.drilled[j - 1] & (np.abs(disagreement) <= gate)
        out.distance[j] += np.where(drawn, ASSIMILATION_WEIGHT * disagreement, 0.0)
        out.memo[("backtest", j - 1, bench_height_m, hole_spacing_m)] = _backtest_rows(out, j - 1, trends)
    return out


def _with_shared_transport(fields: BenchFields, section: DepthTrend) -> DepthTrend:
    """``section`` sharing its transport (:meth:`DepthTrend.transport`) with the fields' recent trends of the same section.

    The benches' trends at each dip (:func:`with_backtested_dip`) and each way
    to carry the movement (:func:`_ways_backtest`) start from the same last
    section, one after another: a Kennecott build made 363 trends of 90
    sections, and the transport's normals and fits were a tenth of its time.
    The last :data:`TRANSPORTS_KEPT` are kept in ``fields.memo`` (each a few
    dozen grids), keyed by the section itself.
    """
    kept = fields.memo.setdefault(_TRANSPORTS, OrderedDict())
    f_last = section.f_last  # its bytes in C order, whatever its layout
    key = (
        f_last.shape,
        section.grid.cell_size_m,
        section.transport_smoothing_m,
        hashlib.blake2b(f_last.tobytes(), digest_size=16).digest(),
    )
    if key in kept:
        kept.move_to_end(key)
        section.__dict__.update(kept[key])
    else:
        kept[key] = section.transport()
        if len(kept) > TRANSPORTS_KEPT:
            kept.popitem(last=False)
    return section


def _memoised(fields: BenchFields, key: tuple, compute):
    """``fields.memo[key]``, computed once (``key`` names what it rests on: the first benches, see :class:`BenchFields`)."""
    if key not in fields.memo:
        fields.memo[key] = compute()
    return fields.memo[key]


def carried_precision(fields: BenchFields, bench_height_m: float, hole_spacing_m: float, prior: float) -> float:
    """The share of the geozone's carried section that the next bench confirmed, over its own benches.

    A backtest: each bench ``j + 1`` is predicted from the benches down to
    ``j`` (their trend with the body continuity as its prior, carried on the
    way their backtest chose, :func:`_pair_backtest`)
    and the predicted section, inside ``j + 1``'s drilled area, is scored by
    the cells of it that ``j + 1`` has in the geozone; the counts are pooled
    over the pairs. The ``prior`` share is worth one of the geozone's typical
    bodies (:func:`typical_body_cells`): a backtest of a few cells at the edge
    of the drilling says little, and where nothing was predicted that the next
    bench drilled (too few benches), the prior stands.
    """
    pairs = [_pair_backtest(fields, j, bench_height_m, hole_spacing_m) for j in range(len(fields.z_m) - 1)]
    confirmed, predicted = sum(c for c, _ in pairs), sum(p for _, p in pairs)
    weight = typical_body_cells(fields)
    return (confirmed + prior * weight) / (predicted + weight) if predicted + weight > 0 else prior


def _pair_backtest(fields: BenchFields, j: int, bench_height_m: float, hole_spacing_m: float) -> tuple[int, int]:
    """Cells of bench ``j + 1``'s drilled area predicted inside from the benches down to ``j``: (confirmed, predicted).

    Predicted the way :func:`_chosen_way` chose from those benches: with
    three, the agreement read against 0, as the ways' backtests read it, not
    against :data:`THREE_BENCH_CHANCE` as :func:`chosen_persistence` does.
    """
    way = _chosen_way(fields.through(float(fields.z_m[j])), bench_height_m, hole_spacing_m)
    _, confirmed, predicted = _ways_backtest(fields, j, bench_height_m, hole_spacing_m)[way]
    return int(confirmed), int(predicted)


def _ways_backtest(fields: BenchFields, j: int, bench_height_m: float, hole_spacing_m: float) -> np.ndarray:
    """Bench ``j + 1`` predicted from the benches down to ``j`` each way to carry (:func:`_ways_to_carry`).

    Per way, a row: the cells put on the wrong side where ``j`` and ``j + 1``
    both drilled, and the cells of ``j + 1``'s drilled area predicted inside
    that it confirmed, and all of them. With fewer than three benches down to
    ``j`` the agreement's way alone (nothing chooses between them yet). Kept in
    ``fields.memo``: it rests only on the benches down to ``j + 1``.
    """

    def compute() -> np.ndarray:
        return _backtest_rows(
            fields, j, _ways_trends(fields.through(float(fields.z_m[j])), bench_height_m, hole_spacing_m)
        )

    return _memoised(fields, ("backtest", j, bench_height_m, hole_spacing_m), compute)


def _ways_trends(known: BenchFields, bench_height_m: float, hole_spacing_m: float) -> list[DepthTrend]:
    """The benches' trend carried each way of :func:`_ways_to_carry` (the agreement's alone with fewer than three)."""
    known = with_backtested_dip(known, bench_height_m, hole_spacing_m)
    ways = _ways_to_carry(known, hole_spacing_m)
    return _trends(known, bench_height_m, hole_spacing_m, list(ways if len(known.z_m) >= 3 else ways[:1]))


def _backtest_rows(fields: BenchFields, j: int, trends: list[DepthTrend]) -> np.ndarray:
    """:func:`_ways_backtest`'s rows of bench ``j + 1`` predicted by ``trends`` (from the benches down to ``j``)."""
    drilled, inside = fields.drilled[j + 1], fields.distance[j + 1] > 0
    both = drilled & fields.drilled[j]
    predictions = [trend.field(float(fields.z_m[j + 1])) > 0 for trend in trends]
    return np.array(
        [[np.sum((p != inside) & both), np.sum(p & drilled & inside), np.sum(p & drilled)] for p in predictions],
        float,
    )


def typical_body_cells(fields: BenchFields, counts: list[int] | None = None) -> float:
    """The mean area in cells of the geozone's bodies (connected parts inside a bench's drilled area).

    ``counts``: the number of bodies on each bench, where the caller has labelled them already.
    """
    if counts is None:
        counts = [ndimage.label((d > 0) & drilled)[1] for d, drilled in zip(fields.distance, fields.drilled)]
    cells = float(np.sum((fields.distance > 0) & fields.drilled))
    return cells / sum(counts) if sum(counts) else 0.0


def chosen_persistence(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> tuple[float, float]:
    """The persistence of each part of the movement whose way of carrying it on best predicted the geozone's benches.

    A backtest (issue 12): from the fourth bench on, each bench ``j + 1`` is
    predicted from the benches down to ``j`` three ways (:func:`_ways_to_carry`:
    as far as their last two movements agree, :func:`geozone_persistence`;
    all of it; none of it), and the cells of its drilled area (drilled on ``j``
    as well) each way put on the wrong side are summed over the pairs. The
    way with the fewest is taken, the agreement on a tie and with fewer than
    four benches. The agreement of two movements is one sample of how a
    geozone moves: travelling waves, whose modes drift apart, change shape so
    that two moves agree little while each bench goes on as the one above it
    moved; and a contact drifting at random is held though its last two moves
    agreed by chance. With three benches the agreement alone decides, read
    against section noise's (:data:`THREE_BENCH_CHANCE`); the backtests of
    the benches below still try the agreement read against 0 as their middle
    way (read otherwise there, it tied with carrying all of it and took the
    place of the agreement of more benches: travelling waves with four benches
    known had 2.5% more area wrong).
    """
    if len(fields.z_m) == 3:
        return geozone_persistence(fields, hole_spacing_m, THREE_BENCH_CHANCE)
    return _ways_to_carry(fields, hole_spacing_m)[_chosen_way(fields, bench_height_m, hole_spacing_m)]


def _chosen_way(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> int:
    """Which of :func:`_ways_to_carry` the benches' backtest takes (0, the agreement, with fewer than four benches).

    :func:`chosen_persistence` takes it from the fourth bench; with three it reads the agreement otherwise.
    """
    n = len(fields.z_m)
    if n < 4:
        return 0
    errors = sum(_ways_backtest(fields, j, bench_height_m, hole_spacing_m)[:, 0] for j in range(2, n - 1))
    return int(np.argmin(errors))


def _ways_to_carry(fields: BenchFields, hole_spacing_m: float) -> tuple[tuple[float, float], ...]:
    """The persistences :func:`chosen_persistence` chooses between: the benches' agreement, all, none."""
    return geozone_persistence(fields, hole_spacing_m), (1.0, 1.0), (0.0, 0.0)


def _trend(
    fields: BenchFields,
    bench_height_m: float,
    hole_spacing_m: float,
    persistence: tuple[float, float] | None = None,
) -> DepthTrend:
    """The depth trend with the share of bodies reaching the next bench as its :attr:`DepthTrend.carried_precision`.

    Not kept: the backtest of the next bench pair and :func:`depth_trend` of
    the same benches both start from it, and keeping it for every prefix of
    the benches took a Kennecott build from 1.41 to 2.11 GB (all processes)
    for no measurable time (37.6-40.5 s against 38.7-39.1 s). ``persistence``
    (outlines, finer changes) is :func:`chosen_persistence`'s unless given.
    """
    fields = with_backtested_dip(fields, bench_height_m, hole_spacing_m)
    if persistence is None:
        persistence = chosen_persistence(fields, bench_height_m, hole_spacing_m)
    return _trends(fields, bench_height_m, hole_spacing_m, [persistence])[0]


def _trends(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, persistences: list[tuple[float, float]]
) -> list[DepthTrend]:
    """The depth trend carrying each of ``persistences`` (outlines, finer changes), all from one fit."""
    key = ("section movement", len(fields.z_m), fields.dip_deg, bench_height_m, hole_spacing_m)
    section, rate, at_cap, outline, continuity = _memoised(
        fields, key, lambda: _section_movement(fields, bench_height_m, hole_spacing_m)
    )
    carried = []
    for kept_outline, kept_finer in persistences:
        # The outlines' fit reaches every matched cell, those at the cap too: they are held all the same.
        moved = np.where(at_cap, 0.0, kept_outline * outline + kept_finer * (rate - outline))
        carried.append(np.where(moved > 0, moved * continuity**GROWTH_CONTINUITY_POWER, moved))
    first = section.replaced(rate=rate, carried=carried[0], carried_precision=continuity)
    return [first, *(first.replaced(carried=c) for c in carried[1:])]


def _section_movement(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> tuple:
    """What :func:`_trends` carries, whatever the persistences: the last section (smoothed, with its transport's
    fits), its movement (less its slide's bias, none at the cap), where it is at the cap, the outlines' part of
    the movement and the bodies' continuity.

    Read-only: kept in ``fields.memo`` for the trends of the same benches and dip (the dips' backtests,
    :func:`with_backtested_dip`, the ways' backtests and the assimilation, and :func:`depth_trend` make the same
    ones: a Kennecott build fitted 363 trends, 162 distinct).
    """
    f_last, z_last, rate, matched = fit_trend(fields, bench_height_m)
    smoothing_m = TRANSPORT_SMOOTHING_SPACINGS * hole_spacing_m
    # The outlines are traced on the section as measured: smoothed, the gap between two parts that have just split
    # narrows, and traced as one outline their opposite movements cancelled (the constructed split lost 0.1 IoU).
    outlines_of = f_last
    f_last = smoothed_section(f_last, fields.grid.cell_size_m, SECTION_SMOOTHING_SPACINGS * hole_spacing_m, smoothing_m)
    # The last section and its transport's fits, which the slide's bias rests on as well; rate and carried set
    # by each trend (:func:`_trends`).
    section = DepthTrend(
        fields.grid,
        float(fields.z_m[-1]),
        bench_height_m,
        f_last,
        z_last,
        rate,
        rate,
        smoothing_m,
        1.0,
        fields.distance[-1],
        np.any(fields.drilled, axis=0),
    )
    section = _with_shared_transport(fields, section)
    rate = rate - sliding_bias(rate, matched, section)
    # A cell at the cap has no boundary within it: the movement of the nearest one, further away, does not move
    # its signed distance (carried over many benches it would raise a body out of nothing there).
    at_cap = np.abs(f_last) >= CAP_SPACINGS * hole_spacing_m - 1e-6
    rate = np.where(at_cap, 0.0, rate)
    continuity = body_continuity(fields, bench_height_m)
    outline = outline_movement(rate, matched, outlines_of, fields.grid.cell_size_m)
    for a in (f_last, z_last, rate, at_cap, outline):
        a.setflags(write=False)
    return section, rate, at_cap, outline, continuity
