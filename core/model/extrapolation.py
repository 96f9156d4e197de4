"""Extrapolation below the deepest bench: how far each geozone carries on the movement its benches show.

Between benches the paper's particle trajectories give a geozone's sections
(:func:`core.model.prediction.region_between`). Below the deepest bench there
is no target to morph to, and the movement of the last bench pair has to be
carried on. Carried on as a displacement, its part *along* the boundary is
noise (the aperture problem): only the part *across* the boundary is measured
by the benches. The stages, one module each:

- :mod:`core.model.fields`: ``F_j``, each bench's signed distance to the
  geozone's boundary, measured where the bench drilled (:class:`BenchFields`);
- :mod:`core.model.movement`: the boundary's movement across itself between
  benches, its outlines' part, and how far successive bench pairs agree on it;
- :mod:`core.model.trend`: the last section carried along that movement
  (:class:`DepthTrend`);
- this module: how much of the movement to carry on. A boundary that moves
  steadily across itself changes ``F`` linearly with depth at every point,
  whichever way it moves along itself. Each part of the movement is carried on
  as far as successive bench pairs agree on it (a geozone whose bodies move
  steadily keeps its trend, one whose movement reverses or is shape noise is
  held; with two benches known, only the outlines' movement is carried), or,
  where carrying all of it or none predicted the geozone's own benches better,
  as far as that (:func:`chosen_persistence`, a backtest). The shallowest dip
  taken as movement is chosen the same way (:func:`with_backtested_dip`). A
  geozone whose bodies end between benches (lenses) has its growth held as
  well (:data:`GROWTH_CONTINUITY_POWER`). Each bench is placed with the benches
  above it as well (:func:`assimilated`), the deepest section's narrow gaps
  are filled below it where the benches showed such gaps filling
  (:func:`gap_closing_m`, a backtest), and :func:`depth_trend` is the
  geozone's trend below its deepest bench.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage
from shapely.geometry import MultiPolygon

from core.geometry.sdf import smoothed_section
from core.model.fields import CAP_SPACINGS, MIN_DIP_DEG, OBSERVED_MEMO, BenchFields, better_beyond_chance, memoised
from core.model.movement import (
    MOVEMENTS_MEMO,
    fastest_movement_m,
    fit_trend,
    geozone_body_size_m,
    geozone_persistence,
    outline_movement,
)
from core.model.progress import Stages
from core.model.trend import TRANSPORT_SMOOTHING_SPACINGS, DepthTrend, sliding_bias, with_shared_transport
from core.threads import Progress

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

#: The disc a geozone's section is closed by a bench below its deepest bench, where its own benches chose it
#: (:func:`gap_closing_m`), in hole spacings: gaps and embayments of the deepest section narrower than its
#: diameter, three spacings, rest on the one or two holes across them. Kennecott's contacts have such gaps
#: between lobes that the next bench fills (3521 from its fifth bench); the families' sections have none a
#: bench below that their generator does not draw. Development seeds 0-2 of every family and Kennecott
#: (``bench_prediction.py``; the closing chosen as below, from a scratch patch): always closed, 1.5 spacings,
#: Kennecott 75.4 -> 76.1 F1 on the next bench's holes but the families pooled 95.96 / 94.52 -> 95.3 / 94.0
#: at 5 / 10 m (a split's opening gap filled again: splits -1.0 / -0.9); 0.75 spacings 95.2 / 93.8. Where the
#: backtest chose it by any margin, Kennecott 76.0, the families 95.82 / 94.46 (116 of 470 cases changed,
#: most for the worse). Chosen by a standard deviation (below; in the engine, the disc growing over the first
#: bench): 1 spacing Kennecott 75.6, the families 95.87 / 94.54; 1.5 75.8, 95.93 / 94.56; 2 75.9 (from bench 5
#: 88.2 against 1.5's 88.4).
GAP_CLOSING_SPACINGS = 1.5
#: Standard deviations of chance by which the closing's backtest must gain (:func:`gap_closing_m`). Any margin:
#: above. One: Kennecott 75.8, the families 95.93 / 94.56, seeds 9101-9104 95.79 / 94.44 -> 95.74 / 94.39. One
#: and a half: Kennecott 75.7, seeds 9101-9104 95.77 / 94.43.
GAP_CLOSING_DEVIATIONS = 1.0

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

#: Where a geozone's typical body is smaller than a disc whose radius is the furthest a boundary moves
#: per bench (:data:`MIN_DIP_DEG`: a lens a bench's movement can end), the share of its bodies seen
#: reaching the next bench is drawn towards one half by a prior worth this many such discs of area
#: (:func:`body_continuity`): a few small bodies seen going on once or twice say little about lenses a
#: bench or two tall, whose growth then turns. Chosen on development seeds: pods (seeds 0-47) 58.6 /
#: 32.4 F1 at 5 / 10 m -> 59.1 / 33.1 against holding's 58.9 / 32.9 (a whole disc 59.2 / 33.3 but a
#: constructed body 15 m across that goes on was held); seeds 0-5 of every family pooled 96.23 /
#: 94.93 -> 96.25 / 94.97 (pods +0.7 / +0.6, widening -0.05 / -0.11); Kennecott unchanged (74.2).
LENS_PRIOR_DISCS = 0.25
#: The share of lens-sized bodies taken to reach the next bench where none could be counted.
LENS_PRIOR_SHARE = 0.5


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
    return (reached + LENS_PRIOR_SHARE * prior) / (counted + prior)


def _lens_reach_cells(fields: BenchFields, bench_height_m: float) -> float:
    """The furthest a boundary of the geozone moves a bench at :data:`MIN_DIP_DEG`, bounded by its bodies' size, in cells."""
    return fastest_movement_m(bench_height_m, geozone_body_size_m(fields)) / fields.grid.cell_size_m


def lens_sized(fields: BenchFields, bench_height_m: float, counts: list[int] | None = None) -> bool:
    """Whether the geozone's bodies are lens-sized: its typical body smaller than a disc of the furthest a boundary moves.

    That furthest is a bench's at :data:`MIN_DIP_DEG` whatever bound the
    benches chose, bounded by the bodies' size (:func:`core.model.movement.fastest_movement_m`);
    the typical body is :func:`typical_body_cells` (``counts``: its bodies per
    bench, where the caller has labelled them). A lens found that far from one
    on the bench above cannot be told from another lens.
    """
    return typical_body_cells(fields, counts) < np.pi * _lens_reach_cells(fields, bench_height_m) ** 2


def depth_trend(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, progress: Progress | None = None
) -> DepthTrend:
    """The geozone's :class:`DepthTrend` from its benches' :class:`BenchFields`.

    Kept in ``fields.memo``: a prediction and the uncertainty of each of its
    elevations ask for the same trend. ``progress(done, total)`` is told each
    step of its backtests (:func:`with_backtested_dip`'s bench pairs and
    dips, :func:`chosen_persistence`'s and :func:`carried_precision`'s bench
    pairs), as one series that never goes back (:class:`core.model.progress.Stages`: the
    trend's backtests, then its confirmation): a large geozone's trend takes seconds (Kennecott's 3026: 1-6 s),
    and a :class:`core.threads.Cancelled` it raises stops it at that step. What
    is kept then is whole: the backtests of the pairs done (each rests on its
    benches alone), never the trend, nor the bench pairs' movements made for it
    (:func:`dropped_movements`).
    """

    # Its dips' and ways' backtests, then the carried precision's, each counting its own pairs: one series.
    stages = Stages(progress, 2)

    def compute() -> DepthTrend:
        try:
            trend = _trend(fields, bench_height_m, hole_spacing_m, progress=stages.stage(0))
            trend = _older_evidence_carried_as_then(fields, trend, bench_height_m, hole_spacing_m)
            trend = trend.replaced(gap_closing_m=gap_closing_m(fields, bench_height_m, hole_spacing_m))
        except BaseException:
            # A cancelled trend (the viewer's newer request, Ctrl-C) is not made: its movements, three grids
            # a pair, stayed in the memo of fields the session keeps, until another trend of them was made.
            dropped_movements(fields)
            raise
        return _confirmed(fields, trend, bench_height_m, hole_spacing_m, stages.stage(1))

    return memoised(fields, ("trend", len(fields.z_m), bench_height_m, hole_spacing_m), compute)


#: The ways of carrying a movement on that :func:`chosen_persistence` chooses between, in
#: :func:`_ways_to_carry`'s order: as far as the last two moves agree, all of it, none of it.
WAYS = ("agreement", "all", "none")
#: What chooses how far the movement goes on, and the way, where too few benches are known for a backtest.
FEW_BENCHES = {3: ("three benches", "agreement"), 2: ("two benches", "outlines")}


@dataclass(frozen=True)
class CarriedMovement:
    """How a geozone's depth trend carries on the movement its benches show, and why (:func:`carried_movement`).

    Attributes
    ----------
    way : str
        One of :data:`WAYS`, or with two benches ``"outlines"`` (their one move's outlines, not its finer changes).
    chosen_by : str
        ``"backtest"`` (from the fourth bench: the way that put the fewest cells of the geozone's own benches on
        the wrong side), ``"three benches"`` (the agreement of their two moves: no backtest to choose),
        ``"two benches"`` (one move: no agreement to read) or ``"one bench"`` (no movement; way ``"none"``).
    persistence : (float, float)
        The shares of the outlines' movement and of the finer changes carried on (paper section 4's trajectories
        give the movement; issue 12 how far it goes on).
    backtest_wrong_m2 : dict or None
        Per way, the area its predictions of the backtested benches put on the wrong side (m²); None before the
        fourth bench.
    movement_m : (float, float) or None
        How far the deepest section's boundary moves a bench height below it (metres, median and 90th percentile
        over its cells the deepest bench drilled); None where that bench found none of the geozone.
    gaps_filled_m : float
        The gaps and embayments of the deepest section narrower than this (metres, the closing disc's diameter)
        are filled a bench below it, where its own benches' backtest chose it (:func:`gap_closing_m`); 0: none.
    """

    way: str
    chosen_by: str
    persistence: tuple[float, float]
    backtest_wrong_m2: dict[str, float] | None
    movement_m: tuple[float, float] | None
    gaps_filled_m: float = 0.0


def carried_movement(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> CarriedMovement:
    """What :func:`depth_trend` carries on below the deepest bench, and which of its backtests chose it.

    A geologist reads from it whether the predicted slope is the benches' movement carried on or the deepest
    bench held, and how clearly the geozone's own benches chose that. It reads the trend and the backtests kept
    in ``fields.memo``; the two moves' agreement is measured again (its movements are dropped once a trend is made).
    """
    trend = depth_trend(fields, bench_height_m, hole_spacing_m)
    known = with_backtested_dip(fields, bench_height_m, hole_spacing_m)
    n = len(known.z_m)
    try:
        persistence = chosen_persistence(known, bench_height_m, hole_spacing_m)
    finally:
        dropped_movements(fields)
    chosen_by, way = FEW_BENCHES.get(n, ("one bench", "none"))
    wrong_m2 = None
    if n >= 4:  # the backtest chose: the way with the fewest cells wrong (chosen_persistence's, from the memo)
        cells = _ways_wrong_cells(known, bench_height_m, hole_spacing_m)
        chosen_by, way = "backtest", WAYS[int(np.argmin(cells))]
        wrong_m2 = {w: float(c) * fields.grid.cell_size_m**2 for w, c in zip(WAYS, cells)}
    edge = (np.abs(trend.f_last) <= fields.grid.cell_size_m) & fields.drilled[-1]
    moved = np.abs(trend.carried[edge])
    movement = (float(np.median(moved)), float(np.percentile(moved, 90))) if moved.size else None
    persistence = (float(persistence[0]), float(persistence[1]))
    return CarriedMovement(way, chosen_by, persistence, wrong_m2, movement, 2.0 * trend.gap_closing_m)


def _older_evidence_carried_as_then(
    fields: BenchFields, trend: DepthTrend, bench_height_m: float, hole_spacing_m: float
) -> DepthTrend:
    """``trend`` with the cells a bench above the deepest saw last carried as the benches above it carried them.

    How far a movement carries on (:func:`chosen_persistence`) is read from the last benches' agreement. A
    deepest bench drilled over part of the pit (its first blast patterns) measures its movement on those holes
    only, and its agreement, on a few cells, said nothing: the rest of the bench, which it did not drill, lost
    the movement the benches above carried there (folds, tuning seed 2, 15% of the bench drilled in a strip:
    one geozone's mean carried movement 2.0 -> 0.0 m). Those cells keep the trend of the benches down to the
    bench above the deepest (its backtests are those of the same bench pairs, kept in ``fields.memo``).
    """
    if len(fields.z_m) < 3:
        return trend
    # Not only the bench above's cells: where it did not drill (benches that do not nest, a pushback), the rest
    # of the new bench was last seen further up and was held where that bench left it (folds, tuning seed 2, a
    # 15% strip drilled: 93.6 F1 on the held-back holes from the benches above alone, 86.4 with the first holes).
    older_seen = ~trend.seen_by_deepest
    if not older_seen.any():
        return trend
    then = _trend(fields.through(float(fields.z_m[-2])), bench_height_m, hole_spacing_m)
    same = older_seen & (np.abs(then.z_last - trend.z_last) < 1e-6 * bench_height_m)
    return trend.replaced(carried=np.where(same, then.carried, trend.carried))


def depth_trend_region(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, z_m: float, progress: Progress | None = None
) -> MultiPolygon:
    """:meth:`DepthTrend.region` at ``z_m`` of :func:`depth_trend`, kept in ``fields.memo`` with the trend.

    A geozone's prediction, its uncertainty's backtest, the evaluation and its surface ask for the same sections.
    ``progress`` goes to :func:`depth_trend`.
    """
    key = ("trend region", len(fields.z_m), bench_height_m, hole_spacing_m, float(z_m))
    return memoised(fields, key, lambda: depth_trend(fields, bench_height_m, hole_spacing_m, progress).region(z_m))


def _confirmed(
    fields: BenchFields,
    trend: DepthTrend,
    bench_height_m: float,
    hole_spacing_m: float,
    progress: Progress | None = None,
) -> DepthTrend:
    """``trend`` with its :func:`carried_precision` backtested on ``fields``; the bench pairs' movements dropped.

    The movements (three grids a pair, in the memo and in the observed benches' memo) are kept only while a
    trend is made. ``progress`` goes to :func:`carried_precision`.
    """
    try:
        confirmed = carried_precision(fields, bench_height_m, hole_spacing_m, trend.carried_precision, progress)
    finally:
        dropped_movements(fields)  # made, or cancelled: the movements are not needed again
    return trend.replaced(carried_precision=confirmed)  # shares the trend's arrays and its transport's fits


def dropped_movements(fields: BenchFields) -> None:
    """Drop the bench pairs' movements from ``fields.memo`` and its observed benches' memo.

    They are kept only while a trend is made (:data:`MOVEMENTS_MEMO`): three grids a pair, a geozone's
    whole column of them held as long as the session keeps its fields.

    Parameters
    ----------
    fields : BenchFields
        The fields whose memo (shared with their :meth:`~BenchFields.through` views) held them.
    """
    fields.memo.pop(MOVEMENTS_MEMO, None)
    fields.memo.get(OBSERVED_MEMO, {}).pop(MOVEMENTS_MEMO, None)


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


def with_backtested_dip(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, progress: Progress | None = None
) -> BenchFields:
    """``fields`` with the shallowest dip taken as movement that best predicted the geozone's own benches.

    A backtest (issue 12: how far to carry the movement on is learnt from
    the geozone's benches): from the third bench on, each bench ``j + 1`` is
    predicted from the benches down to ``j`` with each bound
    (:data:`MIN_DIP_DEG`, :data:`SHALLOW_DIP_DEG`), their movement carried as
    far as their agreement says (:func:`core.model.movement.geozone_persistence`), and the cells
    of ``j + 1``'s drilled area (drilled on ``j`` as well) put on the wrong
    side are summed over the pairs. The shallower bound is taken only where it
    put a share :data:`SHALLOW_DIP_GAIN` fewer cells wrong: a boundary whose movement outruns the usual bound
    (travelling waves' boundaries moving 20-40 m a bench) is followed, and
    lenses that appear beside others, which the shallower bound reads as
    moving, keep the usual one. With fewer than three benches nothing can be
    backtested: :data:`TWO_BENCH_DIP_DEG`, but the usual bound where the
    geozone's bodies are lens-sized (:func:`lens_sized`: a lens beside the
    one above is another lens). Each pair's count rests on its benches
    alone: kept in ``fields.memo``. ``progress(done, total)`` is told as each
    pair is counted with each bound (and, within, the backtests of the
    benches above it); a :class:`core.threads.Cancelled` it raises stops the
    backtest there.
    """
    if fields.min_dip_deg is not None:
        return fields
    n = len(fields.z_m)
    if n < 3:
        return replace(fields, min_dip_deg=MIN_DIP_DEG if lens_sized(fields, bench_height_m) else TWO_BENCH_DIP_DEG)

    def wrong_cells(dip: float, j: int) -> float:
        def compute() -> float:
            known = replace(fields.through(float(fields.z_m[j])), min_dip_deg=dip)
            persistence = geozone_persistence(known, hole_spacing_m)
            trend = _trend(known, bench_height_m, hole_spacing_m, persistence, progress)
            return float(_backtest_rows(fields, j, [trend])[0, 0])

        return memoised(fields, ("dip backtest", dip, j, bench_height_m, hole_spacing_m), compute)

    counts = {}
    steps = [(dip, j) for dip in (MIN_DIP_DEG, SHALLOW_DIP_DEG) for j in range(1, n - 1)]
    for done, (dip, j) in enumerate(steps, start=1):
        counts[dip, j] = wrong_cells(dip, j)
        if progress:
            progress(done, len(steps))
    usual, shallow = (sum(counts[dip, j] for j in range(1, n - 1)) for dip in (MIN_DIP_DEG, SHALLOW_DIP_DEG))
    chosen = SHALLOW_DIP_DEG if shallow < (1.0 - SHALLOW_DIP_GAIN) * usual else MIN_DIP_DEG
    return replace(fields, min_dip_deg=chosen)


#: The most a bench's signed distance is drawn towards its prediction from the benches above
#: (:func:`assimilated`), and the largest disagreement, in hole spacings, that is drawn at all: with both,
#: a bench's boundary moves at most 0.2 spacings, less than the half-gap between its holes.
#: Chosen on development seeds 3-5 of every family (pooled F1 at 5 / 10 m 96.63 / 95.55 without
#: it): gates of 0.5, 0.7, 1 and 1.5 spacings at weight 0.3 96.80 / 95.73, 96.91 / 95.87,
#: 97.01 / 96.01, 97.02 / 96.03 (no gate: pods -5.9 / -4.5, lenses the benches above did not see
#: drawn away); weights 0.2 and 0.3 (the benches' agreement read from their own contours,
#: :meth:`BenchFields.measured`) 96.88 / 95.85 and 96.94 / 95.91, seeds 0-2 95.04 / 93.33 ->
#: 95.41 / 93.76 with 0.2; Kennecott 74.3 -> 74.2 on the holes (85.2 from bench 4 both). 0.3 drew
#: a growing body of a test's fresh mine under holding's precision at 5 m (93.71 against 93.74).
#: Under it, each bench's weight is measured (:func:`assimilation_weight`).
ASSIMILATION_WEIGHT = 0.2
ASSIMILATION_GATE_SPACINGS = 1.0
#: How far a bench's own boundary lies from the true one, in hole spacings (a standard deviation): its holes place
#: it anywhere in the gap between an inside and an outside hole, a spacing wide (uniform: 1 / sqrt(12)).
BENCH_BOUNDARY_SPREAD_SPACINGS = 1.0 / np.sqrt(12.0)
#: A disagreement counts at most this many hole spacings in :func:`assimilation_weight`: a lens appearing is
#: not a prediction's error of its size.
DISAGREEMENT_CLIP_SPACINGS = 3.0
#: Fewest boundary cells a bench needs for its own weight; with fewer it takes :data:`ASSIMILATION_WEIGHT`.
MIN_BOUNDARY_CELLS = 20


def assimilated(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> BenchFields:
    """The benches' signed distances, each drawn towards the prediction of it from the benches above.

    A bench's holes place its boundary only within the gap between an inside
    and an outside hole (its contour runs about half-way, up to half a hole
    spacing off); the benches above predict it (:func:`depth_trend`) with an
    error of their own, and the two together place it better than either (an
    update of the kind a Kalman filter makes; not in the paper). From the
    third bench down, where the prediction is within
    :data:`ASSIMILATION_GATE_SPACINGS` of the bench's own ``F`` in a cell both
    the bench and the one above drilled, ``F`` moves part of the way to it,
    as far as the benches above predicted that bench's boundary well
    (:func:`assimilation_weight`), and at most :data:`ASSIMILATION_WEIGHT`:
    its boundary moves at most 0.2 spacings (the weight times the gate), less
    than the half-gap between its holes, so no hole changes side. Where they
    disagree by more, the bench shows what the benches above could not (a
    split, a lens appearing) and stands. Benches are taken top down, each
    predicted from the benches above as already drawn; their backtests stay
    in the result's memo.
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
        trends = _ways_trends(above, bench_height_m, hole_spacing_m)
        trend = _confirmed(
            above, trends[_chosen_way(above, bench_height_m, hole_spacing_m)], bench_height_m, hole_spacing_m
        )
        predicted = trend.field(float(out.z_m[j]))
        disagreement = predicted - out.distance[j]
        both = out.drilled[j] & out.drilled[j - 1]
        on_boundary = both & (np.abs(out.distance[j]) <= 0.5 * out.grid.cell_size_m)
        weight = assimilation_weight(disagreement[on_boundary], hole_spacing_m)
        drawn = both & (np.abs(disagreement) <= gate)
        out.distance[j] += np.where(drawn, weight * disagreement, 0.0)
        out.memo[("backtest", j - 1, bench_height_m, hole_spacing_m)] = _backtest_rows(
            out, j - 1, trends, GAP_CLOSING_SPACINGS * hole_spacing_m
        )
    return out


def assimilation_weight(disagreement_m: np.ndarray, hole_spacing_m: float) -> float:
    """How far a bench's signed distance moves towards its prediction: the gain of a Kalman filter's update.

    The bench's own boundary is off the true one by
    :data:`BENCH_BOUNDARY_SPREAD_SPACINGS` (``s_b``), its prediction from the
    benches above by ``s_p``; the two together are placed best at the share
    ``s_b^2 / (s_b^2 + s_p^2)`` of the way to the prediction. Their
    disagreement on the bench's boundary has the variance ``s_b^2 + s_p^2``,
    so the gain is measured on the geozone's own benches: a geozone whose
    benches predict each other to within about 0.65 spacings (most of the
    families' benches) is drawn by the ceiling, as before, one whose contacts
    change from bench to bench by more than their movement says (Kennecott:
    0.7-3 spacings RMS, weights 0.01-0.16) keeps its holes' boundary. Not in the paper.

    Parameters
    ----------
    disagreement_m : (n,) float
        Prediction minus the bench's own signed distance on the bench's boundary (metres), where both the bench
        and the one above drilled; each counts at most :data:`DISAGREEMENT_CLIP_SPACINGS`.
    hole_spacing_m : float

    Returns
    -------
    float
        In [0, :data:`ASSIMILATION_WEIGHT`]; :data:`ASSIMILATION_WEIGHT` with fewer than
        :data:`MIN_BOUNDARY_CELLS` cells to measure on.
    """
    if len(disagreement_m) < MIN_BOUNDARY_CELLS:
        return ASSIMILATION_WEIGHT
    clipped = np.minimum(np.abs(disagreement_m), DISAGREEMENT_CLIP_SPACINGS * hole_spacing_m)
    own = (BENCH_BOUNDARY_SPREAD_SPACINGS * hole_spacing_m) ** 2
    # min(own / variance, ceiling), with no division by a variance of 0 (a prediction exact on every cell)
    return own / max(float(np.mean(clipped**2)), own / ASSIMILATION_WEIGHT)


def carried_precision(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, prior: float, progress: Progress | None = None
) -> float:
    """The share of the geozone's carried section that the next bench confirmed, over its own benches.

    A backtest: each bench ``j + 1`` is predicted from the benches down to
    ``j`` (their trend with the body continuity as its prior, carried on the
    way their backtest chose, :func:`_pair_backtest`)
    and the predicted section, inside ``j + 1``'s drilled area, is scored by
    the cells of it that ``j + 1`` has in the geozone; the counts are pooled
    over the pairs. The ``prior`` share is worth one of the geozone's typical
    bodies (:func:`typical_body_cells`): a backtest of a few cells at the edge
    of the drilling says little, and where nothing was predicted that the next
    bench drilled (too few benches), the prior stands. ``progress(done, total)``
    is told as each pair is backtested.
    """
    pairs = []
    for j in range(len(fields.z_m) - 1):
        pairs.append(_pair_backtest(fields, j, bench_height_m, hole_spacing_m))
        if progress:
            progress(len(pairs), len(fields.z_m) - 1)
    confirmed, predicted = sum(c for c, _ in pairs), sum(p for _, p in pairs)
    weight = typical_body_cells(fields)
    return (confirmed + prior * weight) / (predicted + weight) if predicted + weight > 0 else prior


def _pair_backtest(fields: BenchFields, j: int, bench_height_m: float, hole_spacing_m: float) -> tuple[int, int]:
    """Cells of bench ``j + 1``'s drilled area predicted inside from the benches down to ``j``: (confirmed, predicted).

    Predicted the way :func:`_chosen_way` chose from those benches.
    """
    way = _chosen_way(fields.through(float(fields.z_m[j])), bench_height_m, hole_spacing_m)
    _, confirmed, predicted = _ways_backtest(fields, j, bench_height_m, hole_spacing_m)[way, :3]
    return int(confirmed), int(predicted)


def _ways_backtest(fields: BenchFields, j: int, bench_height_m: float, hole_spacing_m: float) -> np.ndarray:
    """Bench ``j + 1`` predicted from the benches down to ``j`` each way to carry (:func:`_ways_to_carry`).

    Per way, a row: the cells put on the wrong side where ``j`` and ``j + 1``
    both drilled, and the cells of ``j + 1``'s drilled area predicted inside
    that it confirmed, and all of them; then the same prediction with its gaps
    closed (:func:`_backtest_rows`, :func:`gap_closing_m`). With fewer than three benches down to
    ``j`` the agreement's way alone (nothing chooses between them yet). Kept in
    ``fields.memo``: it rests only on the benches down to ``j + 1``.
    """

    def compute() -> np.ndarray:
        trends = _ways_trends(fields.through(float(fields.z_m[j])), bench_height_m, hole_spacing_m)
        return _backtest_rows(fields, j, trends, GAP_CLOSING_SPACINGS * hole_spacing_m)

    return memoised(fields, ("backtest", j, bench_height_m, hole_spacing_m), compute)


def _ways_trends(known: BenchFields, bench_height_m: float, hole_spacing_m: float) -> list[DepthTrend]:
    """The benches' trend carried each way of :func:`_ways_to_carry` (the agreement's alone with fewer than three)."""
    known = with_backtested_dip(known, bench_height_m, hole_spacing_m)
    ways = _ways_to_carry(known, hole_spacing_m)
    return _trends(known, bench_height_m, hole_spacing_m, list(ways if len(known.z_m) >= 3 else ways[:1]))


def _backtest_rows(fields: BenchFields, j: int, trends: list[DepthTrend], closing_m: float = 0.0) -> np.ndarray:
    """:func:`_ways_backtest`'s rows of bench ``j + 1`` predicted by ``trends`` (from the benches down to ``j``).

    Per trend: the cells put on the wrong side where ``j`` and ``j + 1`` both drilled, the cells of ``j + 1``'s
    drilled area predicted inside that it confirmed, and all of them; then, with its gaps closed by
    ``closing_m`` (:meth:`DepthTrend.gaps_closed`; none with 0), the cells put on the wrong side and the cells
    where the closing changed the side (both where ``j`` and ``j + 1`` drilled; :func:`gap_closing_m`).
    """
    z_next = float(fields.z_m[j + 1])
    drilled, inside = fields.drilled[j + 1], fields.distance[j + 1] > 0
    both = drilled & fields.drilled[j]
    rows = []
    for trend in trends:
        field = trend.field(z_next)
        p = field > 0
        closed = trend.replaced(gap_closing_m=closing_m).gaps_closed(field, z_next) > 0 if closing_m else p
        rows.append(
            [
                np.sum((p != inside) & both),
                np.sum(p & drilled & inside),
                np.sum(p & drilled),
                np.sum((closed != inside) & both),
                np.sum((closed != p) & both),
            ]
        )
    return np.array(rows, float)


def typical_body_cells(fields: BenchFields, counts: list[int] | None = None) -> float:
    """The mean area in cells of the geozone's bodies (connected parts inside a bench's drilled area).

    ``counts``: the number of bodies on each bench, where the caller has labelled them already.
    """
    if counts is None:
        counts = [ndimage.label((d > 0) & drilled)[1] for d, drilled in zip(fields.distance, fields.drilled)]
    cells = float(np.sum((fields.distance > 0) & fields.drilled))
    return cells / sum(counts) if sum(counts) else 0.0


def chosen_persistence(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, progress: Progress | None = None
) -> tuple[float, float]:
    """The persistence of each part of the movement whose way of carrying it on best predicted the geozone's benches.

    A backtest (issue 12): from the fourth bench on, each bench ``j + 1`` is
    predicted from the benches down to ``j`` three ways (:func:`_ways_to_carry`:
    as far as their last two movements agree, :func:`core.model.movement.geozone_persistence`;
    all of it; none of it), and the cells of its drilled area (drilled on ``j``
    as well) each way put on the wrong side are summed over the pairs. The
    way with the fewest is taken, the agreement on a tie and with fewer than
    four benches. The agreement of two movements is one sample of how a
    geozone moves: travelling waves, whose modes drift apart, change shape so
    that two moves agree little while each bench goes on as the one above it
    moved; and a contact drifting at random is held though its last two moves
    agreed by chance. With three benches the agreement alone decides, read
    as with more: against 0, what two independent moves agree. Read against
    section noise's -1/2 (a still boundary's two moves share the middle
    bench's error with opposite signs), travelling waves with three benches
    known were carried better (development seeds 100-111 of
    ``bench_foreign.py`` at 3-30 m a bench: 86.2 / 70.8 F1 against 85.0 /
    69.4 at half / one bench), but real contacts drifting at random were carried on: on
    Kennecott's benches from 415 ft down, three benches known, 85.9 against
    holding's 87.8 on the next bench's holes under the last one's drilling
    (87.9 read against 0), and the families alike within 0.01.
    ``progress(done, total)`` is told as each pair is backtested.
    """
    return _ways_to_carry(fields, hole_spacing_m)[_chosen_way(fields, bench_height_m, hole_spacing_m, progress)]


def _chosen_way(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, progress: Progress | None = None
) -> int:
    """Which of :func:`_ways_to_carry` the benches' backtest takes (0, the agreement, with fewer than four benches).

    :func:`chosen_persistence` takes it from the fourth bench; with three it reads the agreement otherwise.
    ``progress(done, total)`` is told as each pair is backtested.
    """
    return (
        int(np.argmin(_ways_wrong_cells(fields, bench_height_m, hole_spacing_m, progress)))
        if len(fields.z_m) >= 4
        else 0
    )


def _ways_wrong_cells(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, progress: Progress | None = None
) -> np.ndarray:
    """Per way of :func:`_ways_to_carry`, the cells its backtests from the fourth bench on put on the wrong side.

    ``progress(done, total)`` is told as each pair is backtested.
    """
    n = len(fields.z_m)
    rows = []
    for j in range(2, n - 1):
        rows.append(_ways_backtest(fields, j, bench_height_m, hole_spacing_m)[:, 0])
        if progress:
            progress(len(rows), n - 3)
    return np.sum(rows, axis=0)


def gap_closing_m(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> float:
    """The disc the geozone's section is closed by a bench below its deepest bench (:meth:`DepthTrend.gaps_closed`), metres.

    A backtest, as the way to carry the movement is chosen (:func:`chosen_persistence`): from the second bench
    pair down, each bench ``j + 1`` predicted from the benches down to ``j`` the way the benches chose, as
    it is and with its gaps closed by :data:`GAP_CLOSING_SPACINGS` (:func:`_backtest_rows`). The closing is
    taken where, summed over the pairs, it put fewer cells on the wrong side, by more than
    :data:`GAP_CLOSING_DEVIATIONS` standard deviations of chance over the holes' worth of cells where the
    closing changed the side (:func:`core.model.fields.better_beyond_chance`; a hole's worth: a spacing
    squared). 0 with fewer than three benches, or where the closing did not gain by that much.
    """
    n = len(fields.z_m)
    if n < 3:
        return 0.0
    known = with_backtested_dip(fields, bench_height_m, hole_spacing_m)
    way = _chosen_way(known, bench_height_m, hole_spacing_m)
    rows = [_ways_backtest(fields, j, bench_height_m, hole_spacing_m) for j in range(1, n - 1)]
    cells = np.sum([r[min(way, len(r) - 1), [0, 3, 4]] for r in rows], axis=0)  # wrong, wrong closed, changed
    wrong, wrong_closed, changed = cells / (hole_spacing_m / fields.grid.cell_size_m) ** 2
    return (
        GAP_CLOSING_SPACINGS * hole_spacing_m
        if better_beyond_chance(wrong, wrong_closed, changed, GAP_CLOSING_DEVIATIONS)
        else 0.0
    )


def _ways_to_carry(fields: BenchFields, hole_spacing_m: float) -> tuple[tuple[float, float], ...]:
    """The persistences :func:`chosen_persistence` chooses between: the benches' agreement, all, none."""
    return geozone_persistence(fields, hole_spacing_m), (1.0, 1.0), (0.0, 0.0)


def _trend(
    fields: BenchFields,
    bench_height_m: float,
    hole_spacing_m: float,
    persistence: tuple[float, float] | None = None,
    progress: Progress | None = None,
) -> DepthTrend:
    """The depth trend with the share of bodies reaching the next bench as its :attr:`DepthTrend.carried_precision`.

    Not kept: the backtest of the next bench pair and :func:`depth_trend` of
    the same benches both start from it, and keeping it for every prefix of
    the benches took a Kennecott build from 1.41 to 2.11 GB (all processes)
    for no measurable time (37.6-40.5 s against 38.7-39.1 s). ``persistence``
    (outlines, finer changes) is :func:`chosen_persistence`'s unless given. ``progress`` is told the
    steps of both backtests.
    """
    fields = with_backtested_dip(fields, bench_height_m, hole_spacing_m, progress)
    if persistence is None:
        persistence = chosen_persistence(fields, bench_height_m, hole_spacing_m, progress)
    return _trends(fields, bench_height_m, hole_spacing_m, [persistence])[0]


def _trends(
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, persistences: list[tuple[float, float]]
) -> list[DepthTrend]:
    """The depth trend carrying each of ``persistences`` (outlines, finer changes), all from one fit."""
    key = ("section movement", len(fields.z_m), fields.dip_deg, bench_height_m, hole_spacing_m)
    section, rate, at_cap, outline, continuity = memoised(
        fields, key, lambda: _section_movement(fields, bench_height_m, hole_spacing_m)
    )
    carried = []
    for kept_outline, kept_finer in persistences:
        # The outlines' fit reaches every matched cell, those at the cap too: they are held all the same.
        moved = np.where(at_cap, 0.0, kept_outline * outline + kept_finer * (rate - outline))
        carried.append(np.where(moved > 0, moved * continuity**GROWTH_CONTINUITY_POWER, moved))
    first = section.replaced(
        rate=rate, carried=carried[0], carried_precision=_evidence_prior(fields, bench_height_m, continuity)
    )
    return [first, *(first.replaced(carried=c) for c in carried[1:])]


def _evidence_prior(fields: BenchFields, bench_height_m: float, continuity: float) -> float:
    """The prior share of the carried section the next bench confirms: the bodies' ``continuity``.

    Lens-sized bodies of which no next bench drilled any (their continuity is
    then 1.0: the prior draws every counted share under it), where the deepest
    bench drilled none of the geozone, take :data:`LENS_PRIOR_SHARE` instead, so
    that what an older bench saw of them is let go after a bench, not carried
    on for ever: Kennecott's 5121, one hole on the top bench that no bench
    below drilled, came back 300 ft under it.
    Their growth still carries on with the continuity (pods lost 0.3 / 0.6 F1
    points at half / one bench when it did not, held-out seeds).
    """
    if continuity == 1.0 and not _found_on_deepest(fields) and lens_sized(fields, bench_height_m):
        return LENS_PRIOR_SHARE
    return continuity


def _found_on_deepest(fields: BenchFields) -> bool:
    """Whether the deepest bench drilled any of the geozone."""
    return bool(((fields.distance[-1] > 0) & fields.drilled[-1]).any())


def _section_movement(fields: BenchFields, bench_height_m: float, hole_spacing_m: float) -> tuple:
    """What :func:`_trends` carries, whatever the persistences: the last section (smoothed, with its transport's
    fits), its movement (less its slide's bias, none at the cap), where it is at the cap, the outlines' part of
    the movement and the bodies' continuity.

    Read-only: kept in ``fields.memo`` for the trends of the same benches and dip (the dips' backtests,
    :func:`with_backtested_dip`, the ways' backtests and the assimilation, and :func:`depth_trend` make the same
    ones: a Kennecott build fitted 363 trends, 162 distinct).
    """
    f_last, z_last, rate, matched, unmeasured = fit_trend(fields, bench_height_m)
    smoothing_m = TRANSPORT_SMOOTHING_SPACINGS * hole_spacing_m
    # The outlines are traced on the section as measured: smoothed, the gap between two parts that have just split
    # narrows, and traced as one outline their opposite movements cancelled (the constructed split lost 0.1 IoU).
    outlines_of = f_last
    section_smoothing_m = SECTION_SMOOTHING_SPACINGS * hole_spacing_m
    f_last = smoothed_section(f_last, fields.grid.cell_size_m, section_smoothing_m, smoothing_m)
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
        # What the older ground beside a partly drilled deepest bench's first holes fetches at their cells; none
        # where the deepest bench drilled and found none of the geozone: it ended there, and carried from the
        # bench above beside it, 63 and 213 m2 of a strip the deepest bench did not find came back past its edge.
        fields.distance[-2] if len(fields.z_m) > 1 and _found_on_deepest(fields) else None,
        section_smoothing_m,
    )
    section = with_shared_transport(fields, section)
    rate = rate - sliding_bias(rate, matched, section)
    # A cell at the cap has no boundary within it: the movement of the nearest one, further away, does not move
    # its signed distance (carried over many benches it would raise a body out of nothing there).
    at_cap = np.abs(f_last) >= CAP_SPACINGS * hole_spacing_m - 1e-6
    rate = np.where(at_cap, 0.0, rate)
    continuity = body_continuity(fields, bench_height_m)
    # A cell one bench observed has no movement of its own: held, a bite of the deepest bench or ground only it
    # drilled lagged the rest of its body (a pit pushed back 20-40 m a bench: 0.8 F1 at one bench, tuning seeds).
    unmeasured &= ~at_cap
    outline = outline_movement(rate, matched, outlines_of, fields.grid.cell_size_m, unmeasured)
    rate = np.where(unmeasured, outline, rate)
    for a in (f_last, z_last, rate, at_cap, outline):
        a.setflags(write=False)
    return section, rate, at_cap, outline, continuity
