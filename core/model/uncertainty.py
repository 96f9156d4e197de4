"""How sure a predicted section is: a calibrated scale, P(inside) and a band around the boundary.

Below the deepest bench a geozone's section is ``{F(z) > 0}``, ``F`` the
extrapolated signed distance of :class:`core.model.extrapolation.DepthTrend`.
The error of ``F`` at a point of the true boundary is the (signed) distance
from that point to the predicted boundary. This module models it as
``N(0, sigma^2)`` with a per-cell scale built from what the trend knows
(paper, Discussion: slope predictions to target sampling)::

    sigma^2 = (c0 s)^2 + (c1 h d)^2 + (c2 |m| d)^2 + (c3 |r - m| d)^2

with ``s`` the hole spacing, ``h`` the bench height, ``d`` the depth below
the cell's last observed bench in bench heights, ``r`` the movement of its
boundary per bench and ``m`` the part of it carried on. The terms are: where holes can place a
boundary at all (``s``); the vertical distance to the last observation (a
boundary dipping at 45 degrees moves across itself by as much); the movement
the prediction carries on (its disagreement with holding the last bench, the
nil reference); and the movement it does not carry on (its disagreement with
the linear reference).

The coefficients are calibrated by backtesting on the geozone's own benches
(:func:`backtest`): every known bench ``j >= 2`` is predicted from the benches
above it, one and two benches up, and the signed distance from the points of
its true boundary (its own ``F_j = 0`` set inside its drilled area) to the
predicted boundary is measured. :func:`fit_scale` fits the coefficients by
maximum likelihood and then scales them so that exactly the share ``q`` of
the backtest errors falls inside ``z_q sigma`` (a quantile calibration, robust
to the heavy tails of bodies that appear). With too few benches to backtest,
the backtests of the input's other geozones are pooled; with none at all, the
documented prior :data:`PRIOR_COEFFICIENTS` is used.

The backtests measure errors against each bench's extracted boundary, which
holes place only to within their spacing: the true boundary lies somewhere
between the last hole inside and the first outside, a placement error of
about :data:`PLACEMENT_SPACINGS` spacings (standard deviation) that the
calibrated ``sigma`` includes and the true boundary lacks.
:func:`true_boundary_sigma` takes it out (down to that), so the band is
about the geology, not about the next bench's contours; sampling plans on
the calibrated scale
(:meth:`SectionUncertainty.as_observed`).

From that ``sigma``: ``P(inside) = Phi(F / sigma)`` and the band
that holds the true boundary with probability ``q`` is
``{|F| <= z_q sigma}``, between the inner polygon ``{F >= z_q sigma}`` and the
outer polygon ``{F > -z_q sigma}``.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from scipy import ndimage, special
from shapely.geometry import MultiPolygon
from skimage import measure

from core.geometry.grid import Grid, as_multipolygon, local_gaussian_filter
from core.geometry.sdf import region_signed_distance
from core.model.extrapolation import depth_trend
from core.model.fields import BenchFields
from core.model.movement import fastest_movement_m, last_observations
from core.model.pipeline import GeozoneModel
from core.model.prediction import predict_geozone
from core.model.trend import DepthTrend
from core.threads import Progress

#: Default probability that the band holds the true boundary.
DEFAULT_PROBABILITY = 0.9
#: Names of the terms of the scale, in the order of the coefficients.
TERMS = ("spacing", "depth", "carried movement", "held movement", "inconsistent movement")
#: Coefficients used when neither the geozone nor the input's other geozones can be backtested:
#: half a hole spacing (where holes can place a boundary), 1.7 bench heights per bench of depth (a
#: boundary of unknown dip, taken at the shallowest the model reads as movement,
#: :data:`core.model.extrapolation.MIN_DIP_DEG`, 30 degrees), and all of the movement the prediction does
#: not carry on. A pit's first benches are often drilled too sparsely to backtest on (Kennecott's top
#: bench: 1% of the next one's area); with 45 degrees (one bench height) the band held 71% of bench 2's
#: boundary there.
PRIOR_COEFFICIENTS = (0.5, fastest_movement_m(1.0), 0.0, 1.0, 1.0)
#: Where the maximum-likelihood fit of the coefficients starts (:func:`fit_scale`): the prior with a
#: bench height per bench of depth. Fits of few, heavy-tailed backtests (pods) have several optima;
#: this start is the one the band was measured with.
FIT_START = (0.5, 1.0, 0.0, 1.0, 1.0)
#: How far above a backtested bench its prediction is made from, in benches.
BACKTEST_DEPTHS = (1, 2)
#: A geozone's own backtest is used when it covers this many benches and boundary points.
MIN_BACKTEST_BENCHES = 2
MIN_BACKTEST_POINTS = 30
#: Weight of a backtest relative to one made knowing one bench more (see :func:`fit_scale`).
RECENCY = 0.25
#: Most iterations of the scale's fit (scipy's L-BFGS-B default, named: the fit tells its progress out of it).
FIT_MAX_ITERATIONS = 15000
#: Neighbourhood over which the consistency of the movement is measured, in hole spacings.
CONSISTENCY_SPACINGS = 3.0
#: A change of the signed distance faster than this many bench heights per bench is a body appearing or
#: vanishing, not a boundary moving (a dip of 34 degrees); it is left out of the movement's consistency.
FASTEST_MOVE_BENCHES = 1.5
#: Standard deviation of where extraction puts a boundary against where it is, in hole spacings. Between
#: the last hole inside and the first outside, uniformly, it would be ``1 / sqrt(12)`` = 0.29; measured
#: (the contours of :mod:`core.extraction.contours` against the true sections): 0.08 on straight
#: boundaries through a staggered pattern (``tests/test_uncertainty.py``; 0.13 when each contour was
#: smoothed over half a spacing only, 0.17 unsmoothed), about 0.17-0.20 on the synthetic families'
#: curved sections (0.18-0.21 unsmoothed; their contour points lie 0.20 spacings from the true
#: boundary, root mean square on development seeds 0-1, 0.23 when smoothed over half a spacing).
#: The smoothed half-way line averages the neighbouring holes' evidence, and a boundary across
#: a staggered pattern meets rows much closer together than a spacing. Kept at the families' figure:
#: with the smoothed contours, on tuning seeds 0-3 (``bench_uncertainty.py --tuning --seeds 4``),
#: 0.19 holds the true boundary at 94.0% pooled (every family but pods 94.2-95.7%) and 0.155 at 94.6%
#: (four families over the 95% target).
PLACEMENT_SPACINGS = 0.19
#: Boundary rings around fewer holes than this are label noise, not boundaries (see :func:`boundary_points`);
#: the pipeline's ``min_component_holes``.
NOISE_RING_HOLES = 3


@dataclass
class Backtest:
    """Errors of a geozone's backtested predictions at points of the true boundary.

    Attributes
    ----------
    error_m : (n,) float
        Predicted signed distance ``F_pred`` at each true boundary point,
        metres: positive where the prediction reaches past the true boundary.
    terms_m : (n, 5) float
        The scale's terms (:data:`TERMS`) at each point, metres.
    bench : (n,) int
        Index (in the fields, top first) of the bench each point lies on.
    depth : (n,) int
        How many benches above it the prediction was made from.
    known : (n,) int
        How many benches were known when it was made.
    """

    error_m: np.ndarray
    terms_m: np.ndarray
    bench: np.ndarray
    depth: np.ndarray
    known: np.ndarray

    @classmethod
    def empty(cls) -> Backtest:
        return cls(np.zeros(0), np.zeros((0, len(TERMS))), *(np.zeros(0, int) for _ in range(3)))

    @classmethod
    def concat(cls, parts: Sequence[Backtest]) -> Backtest:
        parts = [p for p in parts if len(p.error_m)]
        if not parts:
            return cls.empty()
        return cls(
            np.concatenate([p.error_m for p in parts]),
            np.concatenate([p.terms_m for p in parts]),
            np.concatenate([p.bench for p in parts]),
            np.concatenate([p.depth for p in parts]),
            np.concatenate([p.known for p in parts]),
        )

    def subset(self, keep: np.ndarray) -> Backtest:
        return Backtest(self.error_m[keep], self.terms_m[keep], self.bench[keep], self.depth[keep], self.known[keep])

    @property
    def benches(self) -> int:
        """Number of distinct benches backtested."""
        return len(np.unique(self.bench))


@dataclass(frozen=True)
class UncertaintyScale:
    """Calibrated coefficients of the scale ``sigma`` (see the module docstring).

    ``source`` says where they come from: ``"own backtest"``, ``"pooled
    backtest"`` (the input's other geozones) or ``"prior"``; ``points`` and
    ``benches`` how much backtest they rest on.
    """

    coefficients: tuple[float, ...]
    source: str
    points: int = 0
    benches: int = 0

    def sigma(self, terms_m: np.ndarray) -> np.ndarray:
        """``sigma`` (metres) from the terms (last axis of ``terms_m``, metres)."""
        c = np.asarray(self.coefficients, float)
        return np.sqrt(np.sum((terms_m * c) ** 2, axis=-1))


def scale_terms(fields: BenchFields, trend: DepthTrend, z_m: float, hole_spacing_m: float) -> np.ndarray:
    """The scale's terms (:data:`TERMS`) on the trend's grid at elevation ``z_m``, ``(rows, cols, 5)`` metres.

    ``fields`` are the benches the trend extrapolates (for the consistency of their movement).
    """
    depth = np.abs(trend.z_last - z_m) / trend.bench_height_m  # bench heights from the last observation, either way
    return np.stack(
        [
            np.full(trend.f_last.shape, hole_spacing_m),
            depth * trend.bench_height_m,
            np.abs(trend.carried) * depth,
            np.abs(trend.rate - trend.carried) * depth,
            movement_inconsistency(fields, CONSISTENCY_SPACINGS * hole_spacing_m) * depth,
        ],
        axis=-1,
    )


def predicted_region(fields: BenchFields, z_m: float, hole_spacing_m: float) -> MultiPolygon:
    """The section the model predicts at ``z_m`` from ``fields`` alone (outside their benches).

    :func:`core.model.prediction.predict_geozone` on a model that knows only
    the fields (in either order): below the deepest bench (above the top one)
    it extrapolates them, exactly as ``bgm predict`` and ``bgm build`` do.
    """
    if fields.upwards:
        fields = fields.reversed()  # a model's benches are top first; it extrapolates up or down itself
    model = GeozoneModel("", [], [], fields=fields)
    return predict_geozone(model, [float(z_m)], hole_spacing_m)[float(z_m)]


def section_distance(fields: BenchFields, region) -> np.ndarray:
    """Signed distance to a predicted section's boundary on the fields' grid (metres, positive inside), capped.

    Errors, scales and bands are distances, so the section is measured
    afresh (:func:`core.geometry.sdf.region_signed_distance`): exact near its
    boundary, by distance transform elsewhere, capped as the fields are (a
    boundary that far says nothing here).
    """
    cap = fields.cap_m
    if region.is_empty:
        return np.full(fields.grid.shape, -cap)
    return np.clip(region_signed_distance(fields.grid, region), -cap, cap)


def movement_inconsistency(fields: BenchFields, smoothing_m: float) -> np.ndarray:
    """How much the movement changed between the last two bench pairs, metres per bench (RMS nearby).

    With ``d1 = F_k - F_k-1`` and ``d2 = F_k-1 - F_k-2`` (as
    :func:`core.model.extrapolation.geozone_persistence`), the root mean square
    of ``d1 - d2`` over a Gaussian neighbourhood of ``smoothing_m``, where the
    three benches drilled the cell and the changes are movements (not bodies
    appearing). 0 for a boundary moving steadily, twice the movement for one
    that reverses; 0 with fewer than three benches (nothing measured).
    """
    if len(fields.z_m) < 3:
        return np.zeros(fields.grid.shape)
    fields = fields.measured()  # as the benches' holes showed them, as the persistence reads them
    d1 = fields.distance[-1] - fields.distance[-2]
    d2 = fields.distance[-2] - fields.distance[-3]
    seen = np.prod(fields.drilled[-3:], axis=0).astype(float)
    h = float(abs(fields.z_m[-2] - fields.z_m[-1]))
    fastest = FASTEST_MOVE_BENCHES * h
    w = seen * ((np.abs(d1) <= fastest) & (np.abs(d2) <= fastest))
    sigma = smoothing_m / fields.grid.cell_size_m
    energy = local_gaussian_filter(w * (d1 - d2) ** 2, sigma)
    support = local_gaussian_filter(w, sigma)
    return np.sqrt(np.where(support > 0.05, energy / np.maximum(support, 1e-9), 0.0))


def boundary_points(distance: np.ndarray, drilled: np.ndarray, grid: Grid, min_ring_area_m2: float = 0.0) -> np.ndarray:
    """Points of a bench's boundary (its ``F = 0`` set) between drilled cells, ``(n, 2)`` metres.

    Marching squares on ``F``; a point counts where the cells around it were
    drilled (the drilled area shrunk by a cell), so the drilling frontier and
    the reach past it are never taken for a boundary. Closed rings enclosing
    less than ``min_ring_area_m2`` are left out: a ring around a hole or two
    is a mislabelled assay to the model (it leaves components of fewer than
    ``min_component_holes`` out between benches), not a boundary it predicts.
    Points are about a cell apart.
    """
    inner = ndimage.binary_erosion(drilled, iterations=1)
    min_cells = min_ring_area_m2 / grid.cell_size_m**2
    rings = [c for c in measure.find_contours(distance, 0.0) if len(c) > 1 and not _small_ring(c, min_cells)]
    if not rings or not inner.any():
        return np.zeros((0, 2))
    rc = np.concatenate(rings)
    cell = np.clip(np.round(rc).astype(int), 0, np.array(distance.shape) - 1)
    keep = inner[cell[:, 0], cell[:, 1]]
    return grid.rc_to_xy(rc[keep])


def _small_ring(rc: np.ndarray, min_cells: float) -> bool:
    """Whether a marching-squares line is a closed ring enclosing fewer than ``min_cells`` cells."""
    if not np.allclose(rc[0], rc[-1]):
        return False
    area = 0.5 * abs(np.dot(rc[:-1, 0], rc[1:, 1]) - np.dot(rc[1:, 0], rc[:-1, 1]))
    return bool(area < min_cells)


def noise_ring_area_m2(hole_spacing_m: float) -> float:
    """Area of :data:`NOISE_RING_HOLES` holes of a staggered pattern (spacing times burden each)."""
    return NOISE_RING_HOLES * hole_spacing_m**2 * np.sqrt(3) / 2


def backtest(
    fields: BenchFields,
    bench_height_m: float,
    hole_spacing_m: float,
    depths: Sequence[int] = BACKTEST_DEPTHS,
    progress: Progress | None = None,
) -> Backtest:
    """Predict each known bench from the benches above it and measure the errors at its true boundary.

    Bench ``j`` is predicted from ``fields.through(z_{j-m})`` for every ``m``
    in ``depths`` with ``j - m >= 0``: the trend's ``F`` at ``z_j`` is sampled
    at the points of the observed ``F_j = 0`` set (the contours' own,
    :meth:`BenchFields.measured`) inside bench ``j``'s drilled area
    (:func:`boundary_points`) that the known benches observed (elsewhere the
    prediction rests on no evidence: a barely drilled top bench predicts
    nothing), with the scale's terms there. Nothing below the predicting
    bench is used. Predictions from a single bench (which hold it:
    no movement is known yet) are kept apart, ``known == 1``, for the prior.
    ``progress(done, total)`` is told as each bench is backtested (it may raise
    :class:`core.threads.Cancelled` to stop there).
    """
    parts = []
    grid = fields.grid
    ring = noise_ring_area_m2(hole_spacing_m)
    # The boundary the holes showed: drawn towards the benches above (assimilated), each bench is nearer its
    # prediction than its holes' boundary is, and bands calibrated on it held 90.6% of the true boundary, not 93.1%.
    observed = fields.measured().distance
    for j in range(1, len(fields.z_m)):
        pts = boundary_points(observed[j], fields.drilled[j], grid, ring)
        if not len(pts):
            continue
        for m in depths:
            if j - m < 0:
                continue
            known = fields.through(float(fields.z_m[j - m]))
            seen = pts[_observed(known, pts)]
            if not len(seen):
                continue
            trend = depth_trend(known, bench_height_m, hole_spacing_m)
            z = float(fields.z_m[j])
            error = grid.sample(section_distance(known, predicted_region(known, z, hole_spacing_m)), seen)
            terms = scale_terms(known, trend, z, hole_spacing_m)
            sampled = np.column_stack([grid.sample(terms[..., t], seen) for t in range(terms.shape[-1])])
            n = len(seen)
            parts.append(Backtest(error, sampled, np.full(n, j), np.full(n, m), np.full(n, j - m + 1)))
        if progress:
            progress(j, len(fields.z_m) - 1)
    return Backtest.concat(parts)


def _observed(fields: BenchFields, xy: np.ndarray) -> np.ndarray:
    """Whether any of the benches observed the cell of each point: where the prediction rests on evidence."""
    last = last_observations(fields)[0]
    rc = fields.grid.nearest_cells(xy)
    return last[rc[:, 0], rc[:, 1]] >= 0


def _negative_log_likelihood(log_v: np.ndarray, t2: np.ndarray, e2: np.ndarray) -> float:
    var = np.maximum(t2 @ np.exp(log_v), 1e-12)
    return float(np.sum(np.log(var) + e2 / var))


def fit_scale(
    samples: Backtest,
    probability: float = DEFAULT_PROBABILITY,
    source: str = "own backtest",
    progress: Progress | None = None,
):
    """Coefficients of the scale fitted to backtest errors, calibrated to hold ``probability`` of them.

    First the shape: maximum likelihood of ``error ~ N(0, sigma^2)`` over the
    squared coefficients (log-parametrised, so they stay positive), started
    from :data:`FIT_START`. Then the level: every coefficient is
    multiplied by ``quantile(|error| / sigma, probability) / z_q``, so that
    exactly the share ``probability`` of the backtest points lies within
    ``z_q sigma`` of the predicted boundary, whatever the tails.
    ``progress(iteration, FIT_MAX_ITERATIONS)`` is told after each iteration of
    the fit (half a second on Kennecott: a cancelled band stops within it).
    """
    t2 = samples.terms_m**2
    e2 = samples.error_m**2
    start = np.log(np.maximum(np.asarray(FIT_START, float) ** 2, 1e-4))
    from scipy import optimize  # only when fitting: it takes a tenth of a second to import

    iterations = itertools.count(1)
    result = optimize.minimize(
        _negative_log_likelihood,
        start,
        args=(t2, e2),
        method="L-BFGS-B",
        bounds=[(-18.0, 6.0)] * len(TERMS),
        options={"maxiter": FIT_MAX_ITERATIONS},
        callback=(lambda _: progress(next(iterations), FIT_MAX_ITERATIONS)) if progress else None,
    )
    coefficients = np.sqrt(np.exp(result.x))
    sigma = np.sqrt(np.maximum(t2 @ coefficients**2, 1e-12))
    # The level from the next-bench predictions where there are enough (what the band is mostly for),
    # the recent ones weighing more: they were made knowing as many benches as the prediction will.
    next_bench = samples.depth == 1 if np.sum(samples.depth == 1) >= MIN_BACKTEST_POINTS else np.ones(len(e2), bool)
    weight = RECENCY ** (samples.known.max() - samples.known)
    ratio = np.abs(samples.error_m) / sigma
    level = weighted_quantile(ratio[next_bench], weight[next_bench], probability) / z_score(probability)
    coefficients = coefficients * max(float(level), 1e-3)
    return UncertaintyScale(tuple(float(c) for c in coefficients), source, int(len(samples.error_m)), samples.benches)


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The ``q`` quantile of ``values`` with ``weights`` (the smallest value whose weight share reaches ``q``)."""
    order = np.argsort(values)
    share = np.cumsum(weights[order]) / np.sum(weights)
    return float(values[order][min(int(np.searchsorted(share, q)), len(values) - 1)])


def calibrate(
    own: Backtest,
    pooled: Sequence[Backtest] | Callable[[], Sequence[Backtest]] = (),
    probability: float = DEFAULT_PROBABILITY,
    progress: Progress | None = None,
) -> UncertaintyScale:
    """The geozone's :class:`UncertaintyScale`, from the best backtest there is.

    In order, the first that covers :data:`MIN_BACKTEST_BENCHES` benches and
    :data:`MIN_BACKTEST_POINTS` points (benches of different geozones count
    apart: they are different boundaries):

    1. its own backtest, predictions from two benches or more (what the
       trend does: it needs two benches to see movement);
    2. the same pooled with the backtests of the input's other geozones
       (``pooled``, or a function giving them: only called when needed);
    3. all of those including predictions from a single bench, which hold
       it: a prior from how far the input's boundaries move per bench;
    4. :data:`PRIOR_COEFFICIENTS`, not calibrated.

    ``progress`` is told the fit's iterations (:func:`fit_scale`).
    """
    own_trended = own.subset(own.known >= 2)
    if _enough([own_trended]):
        return _fitted([own_trended], probability, "own backtest", progress)
    others = list(pooled() if callable(pooled) else pooled)
    candidates = (
        ("pooled backtest", [own_trended, *(b.subset(b.known >= 2) for b in others)]),
        ("pooled single-bench backtest", [own, *others]),
    )
    for source, parts in candidates:
        if _enough(parts):
            return _fitted(parts, probability, source, progress)
    return UncertaintyScale(PRIOR_COEFFICIENTS, "prior", 0, 0)


def _enough(parts: Sequence[Backtest]) -> bool:
    points = sum(len(p.error_m) for p in parts)
    return sum(p.benches for p in parts if len(p.error_m)) >= MIN_BACKTEST_BENCHES and points >= MIN_BACKTEST_POINTS


def _fitted(parts: Sequence[Backtest], probability: float, source: str, progress=None) -> UncertaintyScale:
    scale = fit_scale(Backtest.concat(parts), probability, source, progress)
    benches = sum(p.benches for p in parts if len(p.error_m))
    return UncertaintyScale(scale.coefficients, source, scale.points, benches)


def z_score(probability: float) -> float:
    """``z_q``: a two-sided band of ``z_q`` standard deviations holds ``probability`` of a normal error."""
    return float(special.ndtri(0.5 + probability / 2))


@dataclass
class SectionUncertainty:
    """How sure the predicted section of a geozone at one elevation is (all on the trend's grid).

    Attributes
    ----------
    grid : Grid
    z_m : float
    probability : float
        The band's probability ``q`` of holding the true boundary.
    field : (rows, cols) float
        Predicted signed distance to the boundary ``F_pred`` (metres, positive inside).
    sigma : (rows, cols) float
        Scale of its error against the true boundary (metres; :func:`true_boundary_sigma`).
    scale : UncertaintyScale
    observed_sigma : (rows, cols) float
        Scale of its error against the boundary the bench's holes will show
        (the calibrated scale, placement included, at least the placement
        error of :func:`true_boundary_sigma`): what sampling plans for
        (:meth:`as_observed`).
    """

    grid: Grid
    z_m: float
    probability: float
    field: np.ndarray
    sigma: np.ndarray
    scale: UncertaintyScale
    observed_sigma: np.ndarray

    def as_observed(self) -> SectionUncertainty:
        """The same section about the boundary its holes will show: sampling's view.

        Labels of new holes are turned into that bench's contours, so the
        holes worth assaying are where those contours are unsure, placement
        error included (on the tuning seeds, planning on the true-boundary
        scale lost 0.5-1.4 IoU points of the suggestions' value per family).
        """
        return dataclasses.replace(self, sigma=self.observed_sigma)

    @property
    def half_width(self) -> np.ndarray:
        """How far the band reaches on either side of the predicted boundary, ``z_q sigma`` (metres)."""
        return z_score(self.probability) * self.sigma

    @property
    def has_contact(self) -> bool:
        """Whether the predicted section has a boundary on the grid: ``F_pred`` takes both signs.

        A geozone predicted absent (or everywhere) has none. Its band, where its
        scale reaches the distance cap, still holds everywhere a body may appear
        (what the calibration measures), but it lies around no predicted contact:
        no hole in it is near one, and none can pin one down (:mod:`core.model.sampling`).
        """
        return bool((self.field > 0).any() and (self.field <= 0).any())

    @property
    def inside_probability(self) -> np.ndarray:
        """``P(inside) = Phi(F / sigma)`` on the grid."""
        return special.ndtr(self.field / np.maximum(self.sigma, 1e-9))

    @property
    def predicted(self) -> MultiPolygon:
        """The predicted section ``{F > 0}``."""
        return self._region(self.field)

    @property
    def inner(self) -> MultiPolygon:
        """Inside with probability ``(1 + q) / 2`` or more: ``{F >= z_q sigma}``."""
        return self._region(self.field - self.half_width)

    @property
    def outer(self) -> MultiPolygon:
        """Everything that may be inside: ``{F > -z_q sigma}``."""
        return self._region(self.field + self.half_width)

    @property
    def band(self) -> MultiPolygon:
        """Where the true boundary lies with probability ``q``: outer minus inner."""
        return as_multipolygon(self.outer.difference(self.inner))

    def at(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``F_pred``, ``sigma`` and ``P(inside)`` at points ``xy`` (``(n, 2)`` metres)."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        f = self.grid.sample(self.field, xy)
        s = np.maximum(self.grid.sample(self.sigma, xy), 1e-9)
        return f, s, special.ndtr(f / s)

    def in_band(self, xy: np.ndarray) -> np.ndarray:
        """Whether each point lies in the band, ``|F_pred| <= z_q sigma``."""
        f, s, _ = self.at(xy)
        return np.abs(f) <= z_score(self.probability) * s

    def _region(self, field: np.ndarray) -> MultiPolygon:
        return self.grid.polygons_from_distance(field)


def _direction(fields: BenchFields, down: bool) -> BenchFields:
    """The fields in the order they are extrapolated: top first downwards, bottom first upwards."""
    return fields if down else fields.reversed()


def direction_scale(
    fields: BenchFields,
    down: bool,
    hole_spacing_m: float,
    probability: float = DEFAULT_PROBABILITY,
    pooled: Sequence[Backtest] | Callable[[], Sequence[Backtest]] = (),
    progress: Progress | None = None,
) -> UncertaintyScale:
    """The calibrated scale of predictions below the deepest bench (``down``) or above the top one.

    ``progress`` is told the benches backtested, then the fit's iterations.
    """
    return calibrate(direction_backtest(fields, down, hole_spacing_m, progress), pooled, probability, progress)


def direction_backtest(
    fields: BenchFields, down: bool, hole_spacing_m: float, progress: Progress | None = None
) -> Backtest:
    """:func:`backtest` of extrapolating ``fields`` downwards (``down``) or upwards, at their bench height."""
    used = _direction(fields, down)
    return backtest(used, used.bench_height_m, hole_spacing_m, progress=progress)


def _sigma(used: BenchFields, z_m: float, hole_spacing_m: float, scale: UncertaintyScale) -> np.ndarray:
    """The calibrated scale at ``z_m`` of extrapolating ``used`` (in the order extrapolated)."""
    trend = depth_trend(used, used.bench_height_m, hole_spacing_m)
    return scale.sigma(scale_terms(used, trend, z_m, hole_spacing_m))


def section_uncertainty(
    fields: BenchFields,
    z_m: float,
    hole_spacing_m: float,
    probability: float = DEFAULT_PROBABILITY,
    pooled: Sequence[Backtest] | Callable[[], Sequence[Backtest]] = (),
    region=None,
    scales: dict[bool, UncertaintyScale] | None = None,
    progress: Progress | None = None,
) -> SectionUncertainty | None:
    """The predicted section at ``z_m`` with its calibrated uncertainty (None at a bench level).

    Below the deepest bench (above the top one) the scale is calibrated on
    the benches' backtest in that direction. Between two benches the section
    is constrained from both sides: its scale combines the extrapolations
    from the bench above and from the bench below, ``1 / sigma^2 = 1 /
    sigma_down^2 + 1 / sigma_up^2`` (each calibrated; their combination is
    not backtested, as there is no bench between benches to test it on).

    Parameters
    ----------
    fields : BenchFields
        The geozone's benches (``GeozoneModel.fields``).
    z_m : float
        Elevation, metres.
    hole_spacing_m : float
    probability : float
        The band's probability of holding the true boundary, in (0, 1).
    pooled : sequence of Backtest, or a function giving them
        Backtests of the input's other geozones, used when this one's own
        backtest is too short (see :func:`calibrate`).
    region : Polygon or MultiPolygon, optional
        The predicted section (what ``bgm predict`` wrote); by default
        predicted from the fields (:func:`predicted_region`, outside the benches only).
    scales : dict, optional
        Scales already calibrated, by direction (``True``: down); filled in as calibrated.
    progress : callable, optional
        ``progress(done, total)`` of each step as it runs (the benches of a backtest,
        the iterations of its fit); raising :class:`core.threads.Cancelled` there stops the work.

    Returns
    -------
    SectionUncertainty or None
        None at a bench level, where the section is the bench's contours, and
        between benches without ``region``.
    """
    ways = directions(fields, z_m)
    if not ways or (len(ways) == 2 and region is None):
        return None
    scales = {} if scales is None else scales
    sigmas = []
    for down in ways:
        if down not in scales:
            scales[down] = direction_scale(fields, down, hole_spacing_m, probability, pooled, progress)
        # Between benches each direction extrapolates only the benches on its side.
        known = _direction(fields, down).through(z_m)
        sigmas.append((_sigma(known, z_m, hole_spacing_m, scales[down]), scales[down]))
    precisions = [1.0 / np.maximum(s, 1e-9) ** 2 for s, _ in sigmas]
    sigma = 1.0 / np.sqrt(sum(precisions))
    # Combined by their precisions, the two benches' placement errors (independent) partly cancel.
    placement_share = sum((p * sigma**2) ** 2 for p in precisions)
    true_sigma = true_boundary_sigma(sigma, hole_spacing_m, fields.cap_m, probability, placement_share)
    if region is None:
        region = predicted_region(fields, z_m, hole_spacing_m)
    field = section_distance(fields, region)
    # The boundary the holes will show is placed by them to within their spacing, however well the benches
    # above were predicted (their backtests' contours may hold no placement error: exact constructed ones).
    observed = np.sqrt(np.maximum(sigma**2, placement_variance(hole_spacing_m, placement_share)))
    return SectionUncertainty(fields.grid, float(z_m), float(probability), field, true_sigma, sigmas[0][1], observed)


def placement_variance(hole_spacing_m: float, placement_share: float | np.ndarray = 1.0) -> float | np.ndarray:
    """Variance of a boundary placed by holes: ``placement_share * (PLACEMENT_SPACINGS s)^2``.

    The share is what two benches' independent placements leave between them
    (see :func:`true_boundary_sigma`).
    """
    return placement_share * (PLACEMENT_SPACINGS * hole_spacing_m) ** 2


def true_boundary_sigma(
    sigma: np.ndarray,
    hole_spacing_m: float,
    cap_m: float,
    probability: float,
    placement_share: float | np.ndarray = 1.0,
) -> np.ndarray:
    """The scale of the error against the true boundary, from the scale calibrated on extracted ones.

    The backtests' truth is each bench's extracted boundary, placed by holes
    to within their spacing (:func:`placement_variance`). It is taken out of ``sigma^2``, down
    to that variance: the prediction rests on benches whose boundaries were
    placed no better, and the backtest cannot tell how much of a small error
    was placement. Between benches the section rests on two benches whose
    placement errors are independent: weighted ``w`` and ``1 - w`` (by the
    precisions of the two directions), ``placement_share = w^2 + (1 - w)^2``
    of that variance remains (1/2 half-way), and both the part taken out and
    the floor are that share. Where the band reaches the signed distance's cap ``cap_m``
    (``z_q sigma >= cap_m``) it is left as it is: there the backtests' errors
    were censored at the cap (the prediction had no boundary nearby, a body
    appeared) and the band holds everything the cap does.
    """
    placement = placement_variance(hole_spacing_m, placement_share)
    exact = np.sqrt(np.maximum(sigma**2 - placement, placement))
    return np.where(z_score(probability) * sigma >= cap_m, sigma, exact)


def directions(fields: BenchFields, z_m: float) -> tuple[bool, ...]:
    """How the section at ``z_m`` is extrapolated: ``(True,)`` down, ``(False,)`` up, both between benches, none at one."""
    levels = fields.z_m
    if not len(levels) or np.isclose(levels, z_m, atol=1e-6).any():
        return ()
    if levels[-1] < z_m < levels[0]:
        return (True, False)
    return (bool(z_m < levels[-1]),)


def band_width_m(section: SectionUncertainty, within=None) -> float:
    """Median width of the band across the predicted boundary, ``2 z_q sigma`` there (metres; nan if none).

    ``within`` (a polygon) limits the boundary points considered, e.g. to a drilled area.
    """
    rc = [c for c in measure.find_contours(section.field, 0.0) if len(c)]
    if not rc:
        return float("nan")
    xy = section.grid.rc_to_xy(np.concatenate(rc))
    if within is not None:
        xy = xy[shapely.contains_xy(within, xy[:, 0], xy[:, 1])]
    if not len(xy):
        return float("nan")
    _, s, _ = section.at(xy)
    return float(np.median(2 * z_score(section.probability) * s))


# ---------------------------------------------------------------------------
# On a session: the geozones of one input, with backtests kept with the other stage results


def session_backtest(
    session, geozone: str, down: bool = True, model: GeozoneModel | None = None, progress: Progress | None = None
) -> Backtest:
    """The geozone's backtest (:func:`backtest`) in one direction, memoised in the session's store.

    ``session`` is a :class:`core.model.session.ModelSession`; the key hashes
    the geozone's bench fields, so a changed bench or parameter is backtested again.
    ``progress`` is told the benches backtested (a backtest it stops is not stored).
    """
    from core.io.cache import content_key, engine_fingerprint

    if model is not None and model.fields is not None:
        fields = model.fields
    else:
        own = session.geozone_contours(geozone)
        fields = session.bench_fields(geozone, own)
    spacing = float(session.holes.hole_spacing_m)
    key = content_key("backtest", engine_fingerprint(), fields.z_m, fields.distance, fields.drilled, spacing, down)
    return session.store.get("backtest", key, lambda: direction_backtest(fields, down, spacing, progress))


def _backtests(session, geozones: list[str], down: bool, progress: Progress | None = None) -> list[Backtest]:
    session.contours_of(geozones)  # traced together: each bench's evidence once for all of them
    return [session_backtest(session, g, down, progress=progress) for g in geozones]


def geozone_uncertainty(
    session,
    geozone: str,
    z_m: Sequence[float],
    model: GeozoneModel | None = None,
    probability: float = DEFAULT_PROBABILITY,
    progress: Progress | None = None,
) -> dict[float, SectionUncertainty | None]:
    """The calibrated uncertainty of the geozone's predicted section at each elevation (metres).

    Parameters
    ----------
    session : core.model.session.ModelSession
    geozone : str
    z_m : sequence of float
    model : GeozoneModel, optional
        The geozone's model (computed by the session when omitted).
    probability : float
        The band's probability of holding the true boundary.
    progress : callable, optional
        ``progress(done, total)`` of each step as it runs: the geozone's model (bench
        pairs, when not given), its backtests (benches; the other geozones' too when
        they are pooled), the fit (iterations), the sections. A callback that raises
        (:class:`core.threads.Cancelled`: a viewer's superseded band) stops the work
        at that step, and nothing half done is stored.

    Returns
    -------
    dict of float -> SectionUncertainty or None
        None at bench levels (the section is the bench's contours) and where
        the geozone has no fields or no bench pair (it is predicted nowhere).

    Notes
    -----
    The scale is calibrated on the geozone's own backtest; when that is too
    short, the backtests of the input's other geozones are pooled (computed
    only then; see :func:`calibrate`). Kept in the session's store (on its
    disk cache): a repeated ``bgm predict`` reads it back.
    """
    if not 0 < probability < 1:
        raise ValueError(f"the band's probability must lie between 0 and 1, got {probability}")
    model = model or session.geozone_model(geozone, progress=progress)
    z_m = [float(z) for z in z_m]
    if model.fields is None or not len(model.fields.z_m) or not model.pairs:
        return dict.fromkeys(z_m)  # no pair: nothing predicted (ModelSession.predict), so no band around it
    fields = model.fields
    key = session.uncertainty_key(model, z_m, probability)
    return session.store.get("uncertainty", key, lambda: _sections(session, model, fields, z_m, probability, progress))


def _sections(
    session, model: GeozoneModel, fields: BenchFields, z_m: list[float], probability: float, progress=None
) -> dict:
    """:func:`geozone_uncertainty` computed (its scales calibrated once per direction)."""
    if progress:
        progress(0, len(z_m))  # nothing begun yet: a band superseded while queued stops here
    geozone = model.geozone
    regions = session.predict(geozone, z_m, model)
    spacing = float(session.holes.hole_spacing_m)
    scales: dict[bool, UncertaintyScale] = {}
    out: dict[float, SectionUncertainty | None] = {}
    others = [g for g in session.holes.geozones if g != geozone]
    for i, z in enumerate(z_m, start=1):
        for down in directions(fields, z):
            if down not in scales:
                scales[down] = calibrate(
                    session_backtest(session, geozone, down, model, progress),
                    functools.partial(_backtests, session, others, down, progress),
                    probability,
                    progress,
                )
        out[z] = section_uncertainty(fields, z, spacing, probability, region=regions.get(z), scales=scales)
        if progress:
            progress(i, len(z_m))
    return out
