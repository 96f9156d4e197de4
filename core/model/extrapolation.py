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
Per cell, a weighted least-squares line ``F(u) = a + b u`` is fitted over the
known benches (``u`` = height above the deepest bench, in bench heights;
recent benches weigh more, by ``memory ** u``), and the section ``f`` bench
heights below is ``{a - damping * b * f > 0}``.

How much of the trend to trust is learnt from the geozone's own benches by
backtesting (:func:`choose_trend`): each upper bench is predicted from the
benches above it, for every candidate ``(memory, damping)``, and the
candidate with the best F1 over those benches is kept. A body that moves
steadily keeps its trend (damping near 1); one whose movement is shape noise
(pods, reversals) is held (damping 0), with the intercept ``a`` a denoised
section rather than the last bench's raw one.

Where a bench was not drilled its boundary is unknown, not absent: the
drilling frontier is not a boundary. ``F_j`` measures the distance to the
nearest drilled cell of the other side only; past the frontier it is the
nearest evidence of that bench, weighted down with the distance to its
drilled area and bounded by a reach, so each cell's trend rests on the
benches that were drilled there.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from shapely.geometry import MultiPolygon

from core.geometry.grid import Grid

#: Candidate (memory, damping) pairs tried by the backtest.
MEMORIES: tuple[float, ...] = (0.05, 0.4, 1.0)
DAMPINGS: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
#: Used when the geozone has too few benches to backtest (fewer than three):
#: half the trend, the choice whose worst loss over the possible dampings is smallest.
DEFAULT_TREND = (0.4, 0.5)
#: Signed distances are capped at this many hole spacings: a boundary far away
#: says nothing about how the one nearby moves.
CAP_SPACINGS = 8.0


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
    """

    grid: Grid
    z_m: np.ndarray
    distance: np.ndarray
    weight: np.ndarray
    drilled: np.ndarray

    def upto(self, n: int) -> BenchFields:
        """The first ``n`` benches only (what was known when bench ``n - 1`` was the deepest)."""
        return BenchFields(self.grid, self.z_m[:n], self.distance[:n], self.weight[:n], self.drilled[:n])


def bench_distance(region: np.ndarray, drilled: np.ndarray, cell_size_m: float, cap_m: float, reach_m: float):
    """Signed distance to a region's boundary where only drilled cells count as evidence.

    Parameters
    ----------
    region, drilled : (rows, cols) bool
        The geozone's region and the drilled area of one bench.
    cell_size_m, cap_m, reach_m : float
        Cell size; the cap on ``|F|``; how far past the drilled area the
        bench's evidence reaches (beyond it the geozone is taken as absent).

    Returns
    -------
    distance, off_drilled : (rows, cols) float
        ``F = d(other side) - d(own side)`` measured to drilled cells only
        (exact signed distance inside the drilled area; nearest-evidence
        extension past it), and the distance of each cell to the drilled area.
    """
    inside = region & drilled
    outside = drilled & ~region
    big = 2 * cap_m
    d_in = ndimage.distance_transform_edt(~inside) * cell_size_m if inside.any() else np.full(region.shape, big)
    d_out = ndimage.distance_transform_edt(~outside) * cell_size_m if outside.any() else np.full(region.shape, big)
    off = ndimage.distance_transform_edt(~drilled) * cell_size_m if drilled.any() else np.full(region.shape, big)
    distance = np.minimum(d_out - d_in, reach_m - off)
    return np.clip(distance, -cap_m, cap_m), off


def bench_fields(
    regions: Mapping[int, MultiPolygon],
    drilled: Mapping[int, np.ndarray],
    z_m: Mapping[int, float],
    grid: Grid,
    hole_spacing_m: float,
    reach_m: float,
) -> BenchFields:
    """:class:`BenchFields` of the given benches (bench index -> region, drilled mask on ``grid``, elevation)."""
    benches = sorted(regions, key=lambda k: -z_m[k])
    h = grid.cell_size_m
    cap = CAP_SPACINGS * hole_spacing_m
    dist, weight = [], []
    for k in benches:
        region = grid.rasterize(regions[k]) if not regions[k].is_empty else np.zeros(grid.shape, bool)
        d, off = bench_distance(region, drilled[k], h, cap, reach_m)
        dist.append(d)
        weight.append(np.exp(-off / hole_spacing_m))
    return BenchFields(
        grid,
        np.array([z_m[k] for k in benches], float),
        np.array(dist),
        np.array(weight),
        np.array([drilled[k] for k in benches]),
    )


def fit_trend(fields: BenchFields, memory: float, bench_height_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-cell weighted least-squares line of the signed distance against height above the deepest bench.

    Returns
    -------
    a, b : (rows, cols) float
        ``F(u) ~ a + b u`` with ``u = (z - z_deepest) / bench_height_m``: ``a``
        is the fitted distance at the deepest bench and ``-b`` its change per
        bench height downwards. ``b`` is 0 where fewer than two benches carry weight.
    """
    u = (fields.z_m - fields.z_m[-1]) / bench_height_m
    w = fields.weight * (memory**u)[:, None, None]
    s0 = w.sum(axis=0)
    s1 = np.tensordot(u, w, axes=1)
    s2 = np.tensordot(u**2, w, axes=1)
    t0 = (w * fields.distance).sum(axis=0)
    t1 = np.tensordot(u, w * fields.distance, axes=1)
    det = s0 * s2 - s1**2
    # Two benches of full weight give det ~ 1; a second bench seen only from far away gives ~0.
    ok = det > 1e-3 * np.maximum(s0, 1e-12) ** 2
    b = np.where(ok, (s0 * t1 - s1 * t0) / np.where(ok, det, 1.0), 0.0)
    a = (t0 - b * s1) / np.maximum(s0, 1e-12)
    return a, b


@dataclass
class DepthTrend:
    """A geozone's signed distance at the deepest bench and its trend with depth (see the module docstring)."""

    grid: Grid
    z_ref_m: float  #: elevation of the deepest known bench
    bench_height_m: float
    a: np.ndarray
    b: np.ndarray
    memory: float
    damping: float

    def field(self, z_m: float) -> np.ndarray:
        """Signed distance to the predicted boundary at elevation ``z_m`` (below the deepest bench)."""
        f = max((self.z_ref_m - z_m) / self.bench_height_m, 0.0)
        return self.a - self.damping * self.b * f

    def region(self, z_m: float) -> MultiPolygon:
        field = self.field(z_m)
        if not (field > 0).any():
            return MultiPolygon()
        return self.grid.polygons_from_field(field, 0.0)


def backtest_scores(
    fields: BenchFields, bench_height_m: float, memories: Sequence[float] | None = None, dampings=None
) -> np.ndarray:
    """Intersection, predicted and true areas (cells) of every candidate, summed over the backtests.

    Bench ``j`` (for every ``j >= 2``) is predicted from benches ``0..j-1``
    and compared with its own region inside its drilled area.

    Returns
    -------
    (len(memories), len(dampings), 3) float
    """
    memories = MEMORIES if memories is None else memories
    dampings = DAMPINGS if dampings is None else dampings
    out = np.zeros((len(memories), len(dampings), 3))
    for j in range(2, len(fields.z_m)):
        known = fields.upto(j)
        f = (known.z_m[-1] - fields.z_m[j]) / bench_height_m
        within = fields.drilled[j]
        truth = (fields.distance[j] > 0) & within
        for m, memory in enumerate(memories):
            a, b = fit_trend(known, memory, bench_height_m)
            for d, damping in enumerate(dampings):
                pred = ((a - damping * b * f) > 0) & within
                out[m, d] += (np.sum(pred & truth), pred.sum(), truth.sum())
    return out


def choose_trend(
    fields: BenchFields, bench_height_m: float, memories: Sequence[float] | None = None, dampings=None
) -> tuple[float, float]:
    """The (memory, damping) whose backtest F1 over the geozone's own benches is best.

    Ties go to the least trend (smaller damping), then the longest memory:
    with nothing to choose between them, extrapolating less is the safer
    bet. Too few benches to backtest: :data:`DEFAULT_TREND`.
    """
    memories = MEMORIES if memories is None else memories
    dampings = DAMPINGS if dampings is None else dampings
    if len(memories) * len(dampings) == 1:
        return float(memories[0]), float(dampings[0])
    scores = backtest_scores(fields, bench_height_m, memories, dampings)
    inter, pred, true = scores[..., 0], scores[..., 1], scores[..., 2]
    if true.max() <= 0 and pred.max() <= 0:
        return DEFAULT_TREND
    f1 = 2 * inter / np.maximum(pred + true, 1e-12)
    best = np.max(f1)
    m_idx, d_idx = np.nonzero(f1 >= best - 1e-9)
    order = np.lexsort((-np.asarray(memories)[m_idx], np.asarray(dampings)[d_idx]))
    return float(memories[m_idx[order[0]]]), float(dampings[d_idx[order[0]]])


def depth_trend(fields: BenchFields, bench_height_m: float) -> DepthTrend:
    """The geozone's :class:`DepthTrend`, its memory and damping chosen by :func:`choose_trend`."""
    memory, damping = choose_trend(fields, bench_height_m)
    a, b = fit_trend(fields, memory, bench_height_m)
    return DepthTrend(fields.grid, float(fields.z_m[-1]), bench_height_m, a, b, memory, damping)
