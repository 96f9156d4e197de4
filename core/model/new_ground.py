"""New ground below the deepest bench: the implicit model there, where the geozone's own benches chose it (issue 12).

Below the deepest bench the model carries each cell on from the deepest bench that
drilled it (:mod:`core.model.extrapolation`). In ground no known bench drilled (a
pit pushed back) it has only the benches' evidence past their drilling's edge,
which reaches a few spacings and fades (:func:`core.model.fields.bench_distance`).
The implicit model the references use (:func:`core.model.implicit.fit_implicit_rbf`)
interpolates the holes in 3D and carries its local depth trend into that ground as
well. Which of the two predicts new ground better depends on the geozone: on
Kennecott's deeper benches a body that went on into the pushback was the implicit
model's (2310 from bench 3: 16 of the next bench's 976 new-ground holes wrong
against the model's 148), while from its top benches, where bodies ended at the
pushback, the model's (BENCHMARKS.md). No rule read from one bench tells the two
apart; the geozone's earlier benches can. Each bench pair whose lower bench drilled
ground no bench above it had is a backtest (:func:`pair_errors`): the lower bench's
holes in that ground, predicted from the benches above by each. Below the deepest
bench the implicit model's section is taken in the new ground where the backtests
together say it did better by more than chance (:func:`implicit_chosen`), and the
model's kept everywhere else (:func:`with_implicit_in_new_ground`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import MultiPolygon

from core.geometry.grid import as_multipolygon, without_specks
from core.geometry.sdf import region_signed_distance
from core.io.blastholes import Blastholes, typical_bench_height
from core.model.extrapolation import depth_trend_region
from core.model.fields import BenchFields, better_beyond_chance, memoised
from core.model.implicit import ImplicitRBF, fit_implicit_rbf
from core.model.movement import reaching_bench
from core.model.trend import STALE_AT_DEEPEST_BENCHES

#: The implicit model is taken in new ground where, over the geozone's bench pairs, the model put more of the new
#: ground's holes wrong than the implicit model did by more than this many standard deviations of chance: of ``d``
#: holes where the two disagree, each is right on about half by chance, and the difference in holes wrong has a
#: standard deviation of ``sqrt(d)``. Kennecott (the withheld bench's holes): one deviation 74.5 -> 75.2 F1 (from
#: bench 3 81.9 -> 83.0, benches 1-2 and 4-5 unchanged); two chose nothing; a difference of 0-10 holes, whatever the
#: disagreement, as one. Pits pushed back 20-40 m a bench (tuning seeds 0-2) 93.90 / 92.18 -> 93.91 / 92.20.
NEW_GROUND_DEVIATIONS = 1.0


@dataclass(frozen=True)
class KnownHoles:
    """A geozone's labelled holes, what the implicit model is fitted to.

    Attributes
    ----------
    xy : (n, 2) float
        Local metres.
    z : (n,) float
        Metres.
    bench : (n,) int
        The bench of each hole (an index of the table's bench levels).
    level_m : (n,) float
        The level of each hole's bench, metres.
    inside : (n,) bool
        Whether the hole is labelled the geozone.
    bench_height_m : float
        The table's bench height, as the references take it.
    """

    xy: np.ndarray
    z: np.ndarray
    bench: np.ndarray
    level_m: np.ndarray
    inside: np.ndarray
    bench_height_m: float

    def where(self, keep: np.ndarray) -> KnownHoles:
        """The holes ``keep`` (a bool mask) only."""
        return KnownHoles(
            self.xy[keep], self.z[keep], self.bench[keep], self.level_m[keep], self.inside[keep], self.bench_height_m
        )

    def on_level(self, z_m: float) -> np.ndarray:
        """Which holes lie on the bench at ``z_m`` (matched as :func:`core.model.prediction.bench_at` matches)."""
        return np.isclose(self.level_m, z_m, atol=1e-6)

    def down_to(self, z_m: float) -> KnownHoles:
        """The holes of the benches at or above ``z_m``: what was known when that bench was the deepest."""
        return self.where(self.level_m >= z_m - 1e-6 - 1e-5 * abs(z_m))


def known_holes(holes: Blastholes, geozone: str) -> KnownHoles:
    """``holes`` on benches (those off every bench are left out) labelled in or out of ``geozone``."""
    on = holes.bench >= 0
    levels = np.asarray(holes.bench_levels_m, float)
    height = holes.bench_height_m
    if not np.isfinite(height):
        height = typical_bench_height(levels)
    return KnownHoles(
        holes.xy[on], holes.z[on], holes.bench[on], levels[holes.bench[on]], holes.geozone[on] == geozone, float(height)
    )


def implicit_model(holes: KnownHoles) -> ImplicitRBF:
    """The implicit model of ``holes``, fitted as the evaluation's implicit reference is."""
    return fit_implicit_rbf(holes.xy, holes.z, holes.inside, bench=holes.bench, bench_height_m=holes.bench_height_m)


def drilled_down_to(fields: BenchFields, j: int | None = None) -> np.ndarray:
    """The cells of ``fields.grid`` the benches down to ``j`` (an index of ``fields.z_m``; every one: None) drilled."""
    return np.any(fields.drilled if j is None else fields.drilled[: j + 1], axis=0)


def _past_m(fields: BenchFields, drilled: np.ndarray) -> np.ndarray:
    """Each cell's distance past the ``drilled`` cells, metres (0 inside them)."""
    return ndimage.distance_transform_edt(~drilled) * fields.grid.cell_size_m


def new_ground(fields: BenchFields) -> np.ndarray:
    """The cells of ``fields.grid`` that no known bench drilled."""
    return np.logical_not(drilled_down_to(fields))


def older_ground(fields: BenchFields, j: int | None = None) -> np.ndarray:
    """The cells benches above bench ``j`` (the deepest: None) drilled and bench ``j`` did not.

    Below bench ``j`` the depth trend carries there the evidence of a bench two or more above the level it
    predicts: a table of one moment holds its deepest benches partly drilled, several at once.
    """
    j = len(fields.z_m) - 1 if j is None else j
    if j < 1:
        return np.zeros(fields.grid.shape, bool)
    return drilled_down_to(fields, j - 1) & ~fields.drilled[j]


def within_m(fields: BenchFields, reach_m: float) -> np.ndarray:
    """The cells within ``reach_m`` of some known bench's drilling."""
    drilled = drilled_down_to(fields)
    if not drilled.any():
        return np.ones(fields.grid.shape, bool)
    return _past_m(fields, drilled) <= reach_m


def pushback_m(fields: BenchFields, holes: KnownHoles, j: int) -> float:
    """How far past the drilling of the benches down to ``j`` bench ``j + 1`` drilled (metres, its furthest hole).

    Kept in ``fields.memo``: it rests on the benches down to ``j + 1`` only.
    """

    def compute() -> float:
        on = holes.where(holes.on_level(float(fields.z_m[j + 1])))
        drilled = drilled_down_to(fields, j)
        if not len(on.xy) or not drilled.any():
            return 0.0
        off_m = _past_m(fields, drilled)
        rc = fields.grid.nearest_cells(on.xy)
        return float(off_m[rc[:, 0], rc[:, 1]].max())

    return memoised(fields, ("pushback", j), compute)


def pair_errors(
    fields: BenchFields,
    holes: KnownHoles,
    j: int,
    bench_height_m: float,
    hole_spacing_m: float,
    ground: str = "new",
) -> tuple[int, int, int]:
    """Bench ``j + 1``'s holes in ground no bench down to ``j`` drilled, predicted from the benches down to ``j``.

    With ``ground="older"``, its holes in the ground benches above ``j`` drilled and ``j`` did not
    (:func:`older_ground`) instead.

    Parameters
    ----------
    fields : BenchFields
        The geozone's benches, top first, ``j + 1`` among them.
    holes : KnownHoles
        The geozone's labelled holes, those of bench ``j + 1`` among them.
    j : int
        The pair's upper bench (an index of ``fields.z_m``).
    bench_height_m, hole_spacing_m : float
        As :func:`core.model.extrapolation.depth_trend` takes them.

    Returns
    -------
    tuple of int
        The holes the model's section (:func:`core.model.extrapolation.depth_trend_region`, as
        a prediction from those benches has it) puts on the wrong side, those the implicit
        model's puts on the wrong side, and those where the two disagree. Kept in
        ``fields.memo``: it rests on the benches down to ``j + 1`` only.
    """

    def compute() -> tuple[int, int, int]:
        z_next = float(fields.z_m[j + 1])
        on = holes.where(holes.on_level(z_next))
        rc = fields.grid.nearest_cells(on.xy)
        ground_cells = np.logical_not(drilled_down_to(fields, j)) if ground == "new" else older_ground(fields, j)
        fresh = ground_cells[rc[:, 0], rc[:, 1]]
        xy, truth = on.xy[fresh], on.inside[fresh]
        if not len(xy):
            return 0, 0, 0
        z_j = float(fields.z_m[j])
        region = depth_trend_region(fields.through(z_j), bench_height_m, hole_spacing_m, z_next)
        model = shapely.contains_xy(region, xy[:, 0], xy[:, 1]) if not region.is_empty else np.zeros(len(xy), bool)
        implicit = implicit_model(holes.down_to(z_j)).at(xy, z_next) > 0
        return int(np.sum(model != truth)), int(np.sum(implicit != truth)), int(np.sum(model != implicit))

    return memoised(fields, (f"{ground} ground backtest", j, bench_height_m, hole_spacing_m), compute)


def implicit_chosen(errors: list[tuple[int, int, int]], deviations: float = NEW_GROUND_DEVIATIONS) -> bool:
    """Whether the implicit model predicted the new ground better over the bench pairs' ``errors``, beyond chance.

    ``errors``: :func:`pair_errors` of each pair (the model's holes wrong, the implicit model's, where they
    disagree), pooled. Where the two disagree one of them is right: by chance each would be on about half of
    ``d`` such holes, and the difference in holes wrong has a standard deviation of ``sqrt(d)``. The implicit
    model is chosen where the model had more wrong by more than ``deviations`` of them; never without a hole
    where they disagreed.
    """
    model_wrong, implicit_wrong, disagree = (sum(e[i] for e in errors) for i in range(3))
    return better_beyond_chance(model_wrong, implicit_wrong, disagree, deviations)


def implicit_in_new_ground(
    fields: BenchFields, holes: KnownHoles, bench_height_m: float, hole_spacing_m: float
) -> bool:
    """Whether the geozone's benches chose the implicit model in new ground below their deepest (:func:`implicit_chosen`).

    The pairs from the second bench down (:func:`pair_errors`): predicted from the top bench alone, neither the
    model nor the implicit model has a depth trend, and both hold the bench.
    """
    return implicit_chosen(
        [pair_errors(fields, holes, j, bench_height_m, hole_spacing_m) for j in range(1, len(fields.z_m) - 1)]
    )


def with_implicit_in_new_ground(
    region, fields: BenchFields, holes: KnownHoles, z_m: float, bench_height_m: float, hole_spacing_m: float
) -> MultiPolygon:
    """``region`` (the model's section at ``z_m``, at or below the deepest bench) with the implicit model's in new ground.

    Where the geozone's benches chose it (:func:`implicit_in_new_ground`): in the ground no known bench drilled
    (:func:`new_ground`) the implicit model's section of the known benches' holes, elsewhere ``region``.
    ``region`` unchanged otherwise. Kept in ``fields.memo`` with the trend's sections.
    """
    if len(fields.z_m) < 3 or not implicit_in_new_ground(fields, holes, bench_height_m, hole_spacing_m):
        return as_multipolygon(region)

    def compute() -> MultiPolygon:
        # Only as far past the drilling as the geozone's pushbacks reached (or its benches' evidence does): beyond,
        # the implicit model is its degree-1 drift alone, which drew Kennecott's 2310 up to 230 m from any hole,
        # out to the grid's edge, where no bench had ever drilled so far out.
        reach_m = max(
            (fields.reach_spacings or 0.0) * hole_spacing_m,
            *(pushback_m(fields, holes, j) for j in range(len(fields.z_m) - 1)),
        )
        new = new_ground(fields) & within_m(fields, reach_m)
        if not new.any():
            return as_multipolygon(region)
        # Evaluated in the new ground only (its coarse cells there, :meth:`ImplicitRBF.field`): over a whole
        # Kennecott grid the sections took 8.6 s of a 83 s build.
        fresh = fields.grid.polygons_from_mask(new)
        implicit = known_benches_implicit_model(fields, holes).region(z_m, fields.grid, where=fresh)
        drilled = fields.grid.polygons_from_mask(~new)
        return as_multipolygon(
            shapely.union(shapely.intersection(region, drilled), shapely.difference(implicit, drilled))
        )

    key = ("new ground section", len(fields.z_m), bench_height_m, hole_spacing_m, float(z_m))
    return memoised(fields, key, compute)


def implicit_in_older_ground(
    fields: BenchFields, holes: KnownHoles, bench_height_m: float, hole_spacing_m: float
) -> bool:
    """Whether the geozone's bench pairs chose the implicit model in older ground (:func:`pair_errors` with
    ``ground="older"``, :func:`implicit_chosen`), from the second bench down."""
    n = len(fields.z_m)
    return n >= 3 and implicit_chosen(
        [pair_errors(fields, holes, j, bench_height_m, hole_spacing_m, ground="older") for j in range(1, n - 1)]
    )


def with_implicit_in_older_ground(
    region, fields: BenchFields, holes: KnownHoles, z_m: float, bench_height_m: float, hole_spacing_m: float
) -> MultiPolygon:
    """``region`` (the model's section below the deepest bench) with the implicit model's in older ground.

    In the ground benches above the deepest drilled and the deepest did not (:func:`older_ground`), the depth
    trend carries evidence two or more benches old; there the implicit model's section, which reads every bench
    in three dimensions, where the geozone's own bench pairs chose it (:func:`pair_errors` with
    ``ground="older"``, :func:`implicit_chosen`), as in new ground. A table of one moment holds its deepest
    benches partly drilled, several at once: Kennecott cut at its hole numbers (``bench_periods.py``), the
    next bench's holes there were mostly in such ground.
    """
    n = len(fields.z_m)
    older = older_ground(fields)
    if not older.any() or not implicit_in_older_ground(fields, holes, bench_height_m, hole_spacing_m):
        return as_multipolygon(region)

    def compute() -> MultiPolygon:
        where = fields.grid.polygons_from_mask(older)
        implicit = known_benches_implicit_model(fields, holes).region(z_m, fields.grid, where=where)
        rest = fields.grid.polygons_from_mask(~older)
        return as_multipolygon(shapely.union(shapely.intersection(region, rest), shapely.intersection(implicit, where)))

    key = ("older ground section", n, bench_height_m, hole_spacing_m, float(z_m))
    return memoised(fields, key, compute)


def with_implicit_above_deepest(
    region, fields: BenchFields, holes: KnownHoles, z_m: float, hole_spacing_m: float
) -> MultiPolygon:
    """``region`` (the model's section at ``z_m``) with the implicit model's in the ground its bench did not drill.

    From the top bench's level down to the deepest's, that level excluded: in the ground the deepest bench at or
    above ``z_m`` did not drill, as far past the drilling of the benches at or above ``z_m`` as a bench's evidence
    reaches (``fields.reach_spacings``), the implicit model's section of the known benches' holes; elsewhere
    ``region``. ``region`` unchanged at and below the deepest bench's level (:func:`with_implicit_in_new_ground`
    decides there) and above the top bench's.

    There a bench's contours end at its drilling edge, which is no boundary. The depth trend
    (:func:`core.model.prediction.undrilled_extension`) carries the benches above's evidence down, and
    :func:`core.model.prediction.between_drillings` interpolates between the benches above and below; neither
    reads the bench's own holes beside that ground, and the trend reaches only ground a bench above drilled.
    Kennecott cut at its hole numbers' median (``bench_periods.py``), on the later holes at the levels above the
    deepest: in ground no bench at or above drilled (a pushback) every geozone was nearly absent, 6.6 F1 on
    1,339 holes; in ground benches above drilled and the bench had not yet (several benches are drilled at
    once), 71.1 on 3,121 holes with no bench below there and 78.2 on 654 with one; the implicit model 85.8, 81.4
    and 83.4. There the implicit model has the holes of the bench beside that ground and of the benches above
    and below, and it is taken without the backtests' choice. At the deepest bench's level the choice stays
    (:func:`with_implicit_in_new_ground`): taken there too, in its new ground or in all its undrilled ground,
    a deepest bench's undrilled rest in Kennecott's partial-bench cuts of bench 3 (``bench_partial_bench.py``)
    came out worse in 4 of 5 cuts, by 6-10 points in all ground.

    The reach is from the drilling at or above ``z_m``, not the benches' below: over all the ground only a
    bench below drilled, or as far as the geozone's pushbacks reached (the table's top bench of 20 holes
    reached 470 m), Kennecott's surfaces took the implicit model's section over the whole pit above its second
    bench (2210's volume 49 times its own), for 0.1 F1 more on the later holes.

    At a bench's level the model is evaluated there; between two benches its function is interpolated in
    depth from theirs, over the same ground (what the bench above left undrilled).
    """
    n = len(fields.z_m)
    # A bench level matched as core.model.prediction.bench_at matches it.
    at_or_above = (fields.z_m > z_m) | np.isclose(fields.z_m, z_m, atol=1e-6)
    if n < 2 or at_or_above.all() or not at_or_above.any():
        return as_multipolygon(region)
    upper = int(at_or_above.sum()) - 1  # the deepest bench at or above z_m

    def ground() -> tuple[MultiPolygon, MultiPolygon]:
        reach_m = (fields.reach_spacings or 0.0) * hole_spacing_m
        unseen = ~fields.drilled[upper] & (_past_m(fields, drilled_down_to(fields, upper)) <= reach_m)
        if not unseen.any():
            return MultiPolygon(), MultiPolygon()
        return fields.grid.polygons_from_mask(unseen), fields.grid.polygons_from_mask(~unseen)

    where, rest = memoised(fields, ("undrilled at or above", n, hole_spacing_m, upper), ground)
    if rest.is_empty:
        return as_multipolygon(region)

    def level_field(j: int) -> np.ndarray:
        z_j = float(fields.z_m[j])
        return _implicit_at(fields, holes, z_j, where, ("implicit above the deepest", n, hole_spacing_m, upper, j))

    # Between two benches the function is interpolated in depth from the two benches' levels: a surface asks
    # for several sections between each pair, and each evaluation of the model is a local solve at every cell
    # of the ground (doubled the Kennecott build's time when evaluated at every section).
    t = (float(fields.z_m[upper]) - z_m) / max(float(fields.z_m[upper] - fields.z_m[upper + 1]), 1e-9)
    f = level_field(upper) if t <= 1e-9 else (1.0 - t) * level_field(upper) + t * level_field(upper + 1)
    return _with_implicit_field(region, fields, f, rest)


def stale_ground(fields: BenchFields) -> np.ndarray:
    """The cells whose evidence the depth trend counts stale at the deepest bench's level and below.

    Last seen more than :data:`core.model.trend.STALE_AT_DEEPEST_BENCHES` bench heights above the deepest bench,
    as the trend counts it (:meth:`core.model.trend.DepthTrend.ended`): drilled last by such a bench, or drilled by
    no bench and nearest the drilling of such a bench (:func:`core.model.movement.reaching_bench`, whose evidence
    the trend carries there). Counted in elevation, not in benches of the table: where a level is missing from it,
    the bench above the deepest is two bench heights up and the trend lets its evidence go (counted by index, the
    implicit model was not taken there). The ground no bench drilled at Kennecott's median hole number: its deepest
    level's later holes there, summed over the geozones, 465 put on the wrong side without it, 305 with it (the
    implicit model 250; ``bench_periods.py``).
    """
    n = len(fields.z_m)
    if n < 2:
        return np.zeros(fields.grid.shape, bool)
    last_drilled = n - 1 - np.argmax(fields.drilled[::-1], axis=0)
    seen_last = np.where(fields.drilled.any(axis=0), last_drilled, reaching_bench(fields))
    return np.abs(fields.z_m[seen_last] - fields.z_m[-1]) > STALE_AT_DEEPEST_BENCHES * fields.bench_height_m


def with_implicit_in_stale_ground(
    region, fields: BenchFields, holes: KnownHoles, z_m: float, ended: np.ndarray | None = None
) -> MultiPolygon:
    """``region`` (a section at or below the deepest bench's level) with the implicit model's in :func:`stale_ground`.

    There the depth trend carries evidence two or more benches old and lets it go where the geozone's carried
    sections held less than half the time (:class:`core.model.trend.DepthTrend`): a table of one moment holds its
    deepest benches partly drilled, several at once, and the deepest level's later holes there were mostly
    predicted absent. The implicit model reads the holes of every bench round that ground. Kennecott cut at its
    hole numbers' median (``bench_periods.py``): on the deepest level's 1,075 later holes in ground benches
    above drilled and the deepest did not, 69.2 F1 -> 84.4 (the implicit model 85.5). Ungated, as above the
    deepest. Taken as well in the ground the bench above the deepest drilled, Kennecott's partial-bench cuts of
    bench 3 (``bench_partial_bench.py``) each came out 4-8 points lower; in all the ground no bench drilled, 4 of
    the 5 lower by up to 4 (the choice stays there, :func:`with_implicit_in_new_ground`, but where the nearest
    drilling is a stale bench's).

    Below the deepest bench, after the older ground's choice (:func:`with_implicit_in_older_ground`, whose
    backtests rarely have holes there), only in the cells ``ended`` (where the depth trend let that evidence go,
    :meth:`core.model.trend.DepthTrend.ended`): the implicit model there instead of the deepest bench's fading
    evidence. Kennecott at seven moments, next bench withheld (``bench_periods.py --next-bench``): from deepest
    known bench 5 82.2 -> 84.9 F1 (the implicit model 86.0), every cut level or up. In all the stale ground
    instead, 85.1, but a constructed body standing still, drilled on benches 3-4 in the west only, was
    predicted one bench below the deepest in the east at 0.88 F1 instead of 0.99, and the held-out families
    lost 0.1 at 5 m.
    """
    stale = stale_ground(fields)
    if ended is not None:
        stale &= ended
    if not stale.any():
        return as_multipolygon(region)
    n = len(fields.z_m)
    where, rest = memoised(
        fields,
        ("stale ground", n, None if ended is None else float(z_m)),
        lambda: (fields.grid.polygons_from_mask(stale), fields.grid.polygons_from_mask(~stale)),
    )
    f = _implicit_at(fields, holes, float(z_m), where, ("implicit in stale ground", n, float(z_m)))
    return _with_implicit_field(region, fields, f, rest)


def switched_ground(
    fields: BenchFields, holes: KnownHoles, ended: np.ndarray, bench_height_m: float, hole_spacing_m: float
) -> np.ndarray:
    """The cells whose section takes another model below the deepest bench than at its level.

    At the level the stale ground takes the implicit model's section (:func:`with_implicit_in_stale_ground`) and
    the rest of the older ground the depth trend's; below it the older ground takes the implicit model where its
    backtests chose it (:func:`with_implicit_in_older_ground`), otherwise the stale ground takes the trend's where
    the trend holds that evidence (not ``ended``). Switched: the rest of the older ground in the first case, that
    stale ground in the second.
    """
    stale = stale_ground(fields)
    if implicit_in_older_ground(fields, holes, bench_height_m, hole_spacing_m):
        return older_ground(fields) & ~stale
    return stale & ~ended


def with_deepest_level_joined(
    region, deepest_section, fields: BenchFields, switched: np.ndarray, z_m: float, hole_spacing_m: float
) -> MultiPolygon:
    """``region`` (a section less than a bench below the deepest) passing in the ``switched`` cells from
    ``deepest_section`` (the section at the deepest bench's level) to its own over the first bench below.

    There the section takes another model below the deepest bench than at its level (:func:`switched_ground`), and
    a surface's sections changed at once: Kennecott's 3310 lost 17% of its section's area (11,700 m²) between the
    deepest level and a twentieth of a bench below it, in its stale ground, and 3210 1,160 m² in its older ground,
    ledges in their surfaces. Here the two sections' signed distances, each capped at 1.5 hole spacings (the
    implicit model's own cap), are mixed in proportion to depth: at one bench and below ``region`` is unchanged.
    Elsewhere ``region``.
    """
    w = (float(fields.z_m[-1]) - z_m) / fields.bench_height_m  # the share of the way to one bench below
    if not 0 < w < 1 or not switched.any():
        return as_multipolygon(region)
    cap_m = 1.5 * hole_spacing_m
    deepest, own = (np.clip(region_signed_distance(fields.grid, s), -cap_m, cap_m) for s in (deepest_section, region))
    field = np.where(switched, (1.0 - w) * deepest + w * own, -cap_m)
    rest = fields.grid.polygons_from_mask(~switched)
    # Where the two sections meet, the region's edges and the field's cross within a cell: no body there.
    return without_specks(_with_implicit_field(region, fields, field, rest), fields.grid.cell_size_m**2)


def _implicit_at(fields: BenchFields, holes: KnownHoles, z_m: float, where, key: tuple) -> np.ndarray:
    """The implicit function of the known benches' holes at ``z_m`` over ``where``, kept under ``key``."""
    return memoised(
        fields, key, lambda: known_benches_implicit_model(fields, holes).field(z_m, fields.grid, where=where)
    )


def known_benches_implicit_model(fields: BenchFields, holes: KnownHoles) -> ImplicitRBF:
    """The implicit model of the holes of ``fields``' benches, fitted once: it keeps the cells it has evaluated
    (:class:`~core.model.implicit.ImplicitRBF`), which the grounds' sections at one level share."""
    n = len(fields.z_m)
    return memoised(fields, ("implicit model", n), lambda: implicit_model(holes.down_to(float(fields.z_m[-1]))))


def _with_implicit_field(region, fields: BenchFields, field: np.ndarray, rest) -> MultiPolygon:
    """``region`` in ``rest`` (polygons), ``field``'s section (``field`` > 0: the implicit model's) elsewhere."""
    implicit = fields.grid.polygons_from_field(field, 0.0) if (field > 0).any() else MultiPolygon()
    return as_multipolygon(shapely.union(shapely.intersection(region, rest), shapely.difference(implicit, rest)))
