"""How sure a predicted section is: a calibrated scale, P(inside) and a band around the boundary.

Below the deepest bench a geozone's section is ``{F(z) > 0}``, ``F`` the
extrapolated signed distance of :class:`core.model.extrapolation.DepthTrend`.
The error of ``F`` at a point of the true boundary is the (signed) distance
from that point to the predicted boundary. This module models it as
``N(0, sigma^2)`` with a per-cell scale built from what the trend knows
(paper, Discussion: slope predictions to target sampling)::

    sigma^2 = (c0 s)^2 + (c1 h d)^2 + (c2 p |r| d)^2 + (c3 (1 - p) |r| d)^2

with ``s`` the hole spacing, ``h`` the bench height, ``d`` the depth below
the cell's last observed bench in bench heights, ``r`` its change of ``F`` per
bench and ``p`` its persistence. The terms are: where holes can place a
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

From the calibrated ``sigma``: ``P(inside) = Phi(F / sigma)`` and the band
that holds the true boundary with probability ``q`` is
``{|F| <= z_q sigma}``, between the inner polygon ``{F >= z_q sigma}`` and the
outer polygon ``{F > -z_q sigma}``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from scipy import ndimage, optimize, stats
from shapely.geometry import MultiPolygon
from skimage import measure

from core.geometry.grid import Grid, as_multipolygon
from core.geometry.sdf import region_signed_distance
from core.model.extrapolation import (
    CAP_SPACINGS,
    MIN_DIP_DEG,
    OBSERVED_WEIGHT,
    PERSISTENCE_SPACINGS,
    BenchFields,
    DepthTrend,
    depth_trend,
    last_observations,
)

#: Default probability that the band holds the true boundary.
DEFAULT_PROBABILITY = 0.9
#: Names of the terms of the scale, in the order of the coefficients.
TERMS = ("spacing", "depth", "carried movement", "held movement", "inconsistent movement")
#: Coefficients used when neither the geozone nor the input's other geozones can be backtested:
#: half a hole spacing (where holes can place a boundary), a bench height per bench of depth (a
#: boundary of unknown dip, taken at 45 degrees), and all of the movement the prediction does not carry on.
PRIOR_COEFFICIENTS = (0.5, 1.0, 0.0, 1.0, 1.0)
#: How far above a backtested bench its prediction is made from, in benches.
BACKTEST_DEPTHS = (1, 2)
#: A geozone's own backtest is used when it covers this many benches and boundary points.
MIN_BACKTEST_BENCHES = 2
MIN_BACKTEST_POINTS = 30
#: Weight of a backtest relative to one made knowing one bench more (see :func:`fit_scale`).
RECENCY = 0.25
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
    terms_m : (n, 4) float
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
    depth = np.maximum(trend.z_last - z_m, 0.0) / trend.bench_height_m
    movement = np.abs(trend.rate) * depth
    return np.stack(
        [
            np.full(trend.f_last.shape, hole_spacing_m),
            depth * trend.bench_height_m,
            trend.persistence * movement,
            (1.0 - trend.persistence) * movement,
            movement_inconsistency(fields, PERSISTENCE_SPACINGS * hole_spacing_m) * depth,
        ],
        axis=-1,
    )


def predicted_distance(trend: DepthTrend, z_m: float, hole_spacing_m: float) -> np.ndarray:
    """Signed distance to the predicted boundary at ``z_m`` (metres, positive inside), capped as the fields are.

    The trend's ``F`` has the right zero set but not the right slope: where
    the movement squeezes or stretches it (a narrow strip whose two sides
    cross a cell in turn) ``|grad F|`` is far from 1, and ``F`` is no distance.
    Errors, scales and bands are distances, so the predicted section is
    measured afresh: exact near its boundary, by distance transform elsewhere
    (:func:`core.geometry.sdf.region_signed_distance`).
    """
    cap = CAP_SPACINGS * hole_spacing_m
    field = trend.field(z_m)
    if not (field > 0).any():
        return np.full(field.shape, -cap)
    distance = region_signed_distance(trend.grid, trend.region(z_m), mask=field > 0)
    return np.clip(distance, -cap, cap)


def movement_inconsistency(fields: BenchFields, smoothing_m: float) -> np.ndarray:
    """How much the movement changed between the last two bench pairs, metres per bench (RMS nearby).

    With ``d1 = F_k - F_k-1`` and ``d2 = F_k-1 - F_k-2`` (as
    :func:`core.model.extrapolation.local_persistence`), the root mean square
    of ``d1 - d2`` over a Gaussian neighbourhood of ``smoothing_m``, where the
    three benches observed the cell and the changes are movements (not bodies
    appearing). 0 for a boundary moving steadily, twice the movement for one
    that reverses; 0 with fewer than three benches (nothing measured).
    """
    if len(fields.z_m) < 3:
        return np.zeros(fields.grid.shape)
    d1 = fields.distance[-1] - fields.distance[-2]
    d2 = fields.distance[-2] - fields.distance[-3]
    seen = np.prod(fields.weight[-3:] >= OBSERVED_WEIGHT, axis=0).astype(float)
    h = float(abs(fields.z_m[-2] - fields.z_m[-1]))
    fastest = h / np.tan(np.radians(MIN_DIP_DEG))
    w = seen * ((np.abs(d1) <= fastest) & (np.abs(d2) <= fastest))
    sigma = smoothing_m / fields.grid.cell_size_m
    energy = ndimage.gaussian_filter(w * (d1 - d2) ** 2, sigma)
    support = ndimage.gaussian_filter(w, sigma)
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
    fields: BenchFields, bench_height_m: float, hole_spacing_m: float, depths: Sequence[int] = BACKTEST_DEPTHS
) -> Backtest:
    """Predict each known bench from the benches above it and measure the errors at its true boundary.

    Bench ``j`` is predicted from ``fields.down_to(z_{j-m})`` for every ``m``
    in ``depths`` with ``j - m >= 0``: the trend's ``F`` at ``z_j`` is sampled
    at the points of the ``F_j = 0`` set inside bench ``j``'s drilled area
    (:func:`boundary_points`) that the known benches observed (elsewhere the
    prediction rests on no evidence: a barely drilled top bench predicts
    nothing), with the scale's terms there. Nothing below the predicting
    bench is used. Predictions from a single bench (which hold it:
    no movement is known yet) are kept apart, ``known == 1``, for the prior.
    """
    parts = []
    grid = fields.grid
    ring = noise_ring_area_m2(hole_spacing_m)
    for j in range(1, len(fields.z_m)):
        pts = boundary_points(fields.distance[j], fields.drilled[j], grid, ring)
        if not len(pts):
            continue
        for m in depths:
            if j - m < 0:
                continue
            known = fields.down_to(float(fields.z_m[j - m]))
            seen = pts[_observed(known, pts)]
            if not len(seen):
                continue
            trend = depth_trend(known, bench_height_m, hole_spacing_m)
            z = float(fields.z_m[j])
            error = grid.sample(predicted_distance(trend, z, hole_spacing_m), seen)
            terms = scale_terms(known, trend, z, hole_spacing_m)
            sampled = np.column_stack([grid.sample(terms[..., t], seen) for t in range(terms.shape[-1])])
            n = len(seen)
            parts.append(Backtest(error, sampled, np.full(n, j), np.full(n, m), np.full(n, j - m + 1)))
    return Backtest.concat(parts)


def _observed(fields: BenchFields, xy: np.ndarray) -> np.ndarray:
    """Whether any of the benches observed the cell of each point: where the prediction rests on evidence."""
    last, _ = last_observations(fields)
    rc = np.clip(np.round(fields.grid.xy_to_rc(xy)).astype(int), 0, np.array(fields.grid.shape) - 1)
    return last[rc[:, 0], rc[:, 1]] >= 0


def _negative_log_likelihood(log_v: np.ndarray, t2: np.ndarray, e2: np.ndarray) -> float:
    var = np.maximum(t2 @ np.exp(log_v), 1e-12)
    return float(np.sum(np.log(var) + e2 / var))


def fit_scale(samples: Backtest, probability: float = DEFAULT_PROBABILITY, source: str = "own backtest"):
    """Coefficients of the scale fitted to backtest errors, calibrated to hold ``probability`` of them.

    First the shape: maximum likelihood of ``error ~ N(0, sigma^2)`` over the
    squared coefficients (log-parametrised, so they stay positive), started
    from :data:`PRIOR_COEFFICIENTS`. Then the level: every coefficient is
    multiplied by ``quantile(|error| / sigma, probability) / z_q``, so that
    exactly the share ``probability`` of the backtest points lies within
    ``z_q sigma`` of the predicted boundary, whatever the tails.
    """
    t2 = samples.terms_m**2
    e2 = samples.error_m**2
    start = np.log(np.maximum(np.asarray(PRIOR_COEFFICIENTS, float) ** 2, 1e-4))
    result = optimize.minimize(
        _negative_log_likelihood, start, args=(t2, e2), method="L-BFGS-B", bounds=[(-18.0, 6.0)] * len(TERMS)
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


def calibrate(own: Backtest, pooled: Sequence[Backtest] = (), probability: float = DEFAULT_PROBABILITY):
    """The geozone's :class:`UncertaintyScale`, from the best backtest there is.

    In order, the first that covers :data:`MIN_BACKTEST_BENCHES` benches and
    :data:`MIN_BACKTEST_POINTS` points (benches of different geozones count
    apart: they are different boundaries):

    1. its own backtest, predictions from two benches or more (what the
       trend does: it needs two benches to see movement);
    2. the same pooled with the backtests of the input's other geozones (``pooled``);
    3. all of those including predictions from a single bench, which hold
       it: a prior from how far the input's boundaries move per bench;
    4. :data:`PRIOR_COEFFICIENTS`, not calibrated.
    """
    trended = [b.subset(b.known >= 2) for b in (own, *pooled)]
    candidates = (
        ("own backtest", trended[:1]),
        ("pooled backtest", trended),
        ("pooled single-bench backtest", [own, *pooled]),
    )
    for source, parts in candidates:
        parts = [p for p in parts if len(p.error_m)]
        benches = sum(p.benches for p in parts)
        every = Backtest.concat(parts)
        if benches >= MIN_BACKTEST_BENCHES and len(every.error_m) >= MIN_BACKTEST_POINTS:
            scale = fit_scale(every, probability, source)
            return UncertaintyScale(scale.coefficients, source, scale.points, benches)
    return UncertaintyScale(PRIOR_COEFFICIENTS, "prior", 0, 0)


def z_score(probability: float) -> float:
    """``z_q``: a two-sided band of ``z_q`` standard deviations holds ``probability`` of a normal error."""
    return float(stats.norm.ppf(0.5 + probability / 2))


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
        Calibrated scale of its error (metres).
    scale : UncertaintyScale
    """

    grid: Grid
    z_m: float
    probability: float
    field: np.ndarray
    sigma: np.ndarray
    scale: UncertaintyScale

    @property
    def half_width(self) -> np.ndarray:
        """How far the band reaches on either side of the predicted boundary, ``z_q sigma`` (metres)."""
        return z_score(self.probability) * self.sigma

    @property
    def inside_probability(self) -> np.ndarray:
        """``P(inside) = Phi(F / sigma)`` on the grid."""
        return stats.norm.cdf(self.field / np.maximum(self.sigma, 1e-9))

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
        return f, s, stats.norm.cdf(f / s)

    def in_band(self, xy: np.ndarray) -> np.ndarray:
        """Whether each point lies in the band, ``|F_pred| <= z_q sigma``."""
        f, s, _ = self.at(xy)
        return np.abs(f) <= z_score(self.probability) * s

    def _region(self, field: np.ndarray) -> MultiPolygon:
        return self.grid.polygons_from_field(field, 0.0) if (field > 0).any() else MultiPolygon()


def extrapolation_trend(
    fields: BenchFields, z_m: float, hole_spacing_m: float
) -> tuple[DepthTrend, BenchFields] | None:
    """The depth trend that predicts elevation ``z_m`` and the fields it extrapolates, or None.

    Below the deepest bench the fields top down, above the top bench the
    fields reversed (as :func:`core.model.prediction.predict_geozone` does);
    None at or between the benches, where the section is interpolated from
    the benches on both sides instead of extrapolated.
    """
    levels = fields.z_m
    if not len(levels) or levels[-1] - 1e-6 <= z_m <= levels[0] + 1e-6:
        return None
    height = float(np.median(-np.diff(levels))) if len(levels) > 1 else 1.0
    down = bool(z_m < levels[-1])
    used = fields if down else fields.reversed()
    return depth_trend(used, height, hole_spacing_m), used


def section_uncertainty(
    fields: BenchFields,
    z_m: float,
    hole_spacing_m: float,
    probability: float = DEFAULT_PROBABILITY,
    pooled: Sequence[Backtest] = (),
    scale: UncertaintyScale | None = None,
) -> SectionUncertainty | None:
    """The predicted section at ``z_m`` (outside the benches) with its calibrated uncertainty.

    Parameters
    ----------
    fields : BenchFields
        The geozone's benches (``GeozoneModel.fields``).
    z_m : float
        Elevation, metres, below the deepest bench or above the top one.
    hole_spacing_m : float
    probability : float
        The band's probability of holding the true boundary, in (0, 1).
    pooled : sequence of Backtest
        Backtests of the input's other geozones, used when this one's own
        backtest is too short (see :func:`calibrate`).
    scale : UncertaintyScale, optional
        Already calibrated (e.g. one scale for several elevations).

    Returns
    -------
    SectionUncertainty or None
        None at or between the benches.
    """
    found = extrapolation_trend(fields, z_m, hole_spacing_m)
    if found is None:
        return None
    trend, used = found
    if scale is None:
        scale = calibrate(backtest(used, trend.bench_height_m, hole_spacing_m), pooled, probability)
    sigma = scale.sigma(scale_terms(used, trend, z_m, hole_spacing_m))
    field = predicted_distance(trend, z_m, hole_spacing_m)
    return SectionUncertainty(fields.grid, float(z_m), float(probability), field, sigma, scale)


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
