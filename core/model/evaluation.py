"""Predictive value: precision and recall of boundaries predicted below the deepest bench.

The paper ("Results: Predictive Value") processes benches top-down, withholds
everything below the current bench floor, predicts the geozone's section at
depths ``d = 1.25, 2.5, ..., 10 m`` below it and scores the prediction against
the ground truth with area-weighted precision and recall. This module is that
protocol, plus the reference predictors a geologist would otherwise use:

* ``nil`` -- zero-order hold: the deepest known bench's region (the paper's
  "no slope information" baseline);
* ``linear`` -- linear extrapolation of the signed distance function from the
  last two benches;
* ``implicit`` -- a Leapfrog-style implicit model: a 3D radial basis function
  interpolant of signed distances at the holes, evaluated at the target depth.

The model being evaluated is supplied by the caller as a function
``model_predictor(known_holes, geozone, z_targets_m) -> {z: MultiPolygon}``.

Scoring (paper's definitions). For predicted components ``P_i`` and truth
components ``G_j``: ``p(i) = |P_i ∩ G| / |P_i|`` and ``r(j) = |G_j ∩ P| / |G_j|``;
the overall rates are their area-weighted averages, which are
``sum_i |P_i ∩ G| / sum_i |P_i| = |P ∩ G| / |P|`` and ``|P ∩ G| / |G|``
(components of a valid MultiPolygon are disjoint).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import lru_cache, partial
from pathlib import Path

import numpy as np
import pandas as pd
import shapely
from shapely.geometry import MultiPolygon, Polygon

from core.geometry.grid import Grid, as_multipolygon, cell_size_within
from core.geometry.sdf import signed_distance
from core.io.atomic import atomic_path
from core.io.blastholes import Blastholes, typical_bench_height
from core.model.implicit import fit_implicit_rbf
from core.model.new_ground import implicit_model, known_holes

#: The paper's prediction depths, as fractions of the bench height (1.25 m steps of a 10 m bench).
DEFAULT_FRACTIONS: tuple[float, ...] = tuple(i / 8 for i in range(1, 9))
#: Methods in the order tables and plots show them.
METHODS: tuple[str, ...] = ("model", "nil", "linear", "implicit")
#: Radius of the disc around each hole of the next bench that counts as drilled, in hole spacings.
DRILLED_RADIUS_SPACINGS = 0.75

ModelPredictor = Callable[[Blastholes, str, list], Mapping[float, MultiPolygon]]
Truth = Callable[[str, float], MultiPolygon]


# ---------------------------------------------------------------------------
# Scoring


def _region(geometry) -> MultiPolygon:
    """A valid MultiPolygon with disjoint parts (overlapping parts are merged)."""
    if geometry is None or geometry.is_empty:
        return MultiPolygon()
    return as_multipolygon(shapely.union_all(list(as_multipolygon(geometry).geoms)))


def precision_recall(
    predicted, truth, within: Polygon | MultiPolygon | None = None
) -> tuple[float, float, float, float]:
    """Area-weighted precision and recall of a predicted region against the truth.

    Parameters
    ----------
    predicted, truth : Polygon or MultiPolygon
        Predicted and true regions (local metres). Overlapping parts of either
        are merged first.
    within : Polygon or MultiPolygon, optional
        Evaluation area (e.g. the drilled area of the withheld bench); both
        regions are clipped to it.

    Returns
    -------
    (precision, recall, p_area, g_area)
        ``precision = |P ∩ G| / |P|``, ``recall = |P ∩ G| / |G|`` (the
        area-weighted averages of the per-component rates of the paper) and the
        areas ``|P|``, ``|G|`` after clipping. Empty sets: precision is nan when
        nothing is predicted (``|P| = 0``) and recall is nan when there is no
        truth (``|G| = 0``); the other rate is then 0 (or nan when both are
        empty). The intersection area is ``precision * p_area`` (0 when nan).
    """
    p = _region(predicted)
    g = _region(truth)
    if within is not None:
        w = _region(within)
        p = as_multipolygon(p.intersection(w))
        g = as_multipolygon(g.intersection(w))
    p_area, g_area = float(p.area), float(g.area)
    inter = float(p.intersection(g).area) if p_area > 0 and g_area > 0 else 0.0
    precision = min(inter / p_area, 1.0) if p_area > 0 else float("nan")
    recall = min(inter / g_area, 1.0) if g_area > 0 else float("nan")
    return precision, recall, p_area, g_area


def f1_score(precision: float, recall: float) -> float:
    """Harmonic mean of precision and recall: ``2 |P ∩ G| / (|P| + |G|)``, the F1 of the areas they come from.

    Parameters
    ----------
    precision, recall : float
        As :func:`precision_recall` gives them: nan where nothing was predicted
        (precision) or nothing was there (recall).

    Returns
    -------
    float
        0 if both are 0, or if one is nan and the other 0: a method that predicted
        nothing where the geozone was (or something where it was not) found none
        of it, F1 ``0 / (|P| + |G|)``. Nan where both are nan (nothing either side,
        nothing to score) or the rates cannot come from areas (one nan, the other not 0).
    """
    # A nan F1 there dropped the method from "best reference" and, for the model,
    # the margin line, while its F1 on the withheld holes said 0.
    finite = [v for v in (precision, recall) if np.isfinite(v)]
    if len(finite) == 1 and finite[0] == 0:
        return 0.0
    if len(finite) < 2:
        return float("nan")
    if precision + recall == 0:
        return 0.0
    return 2 * precision * recall / (precision + recall)


def iou(a, b) -> float:
    """Intersection over union of two regions (nan if both are empty)."""
    a, b = _region(a), _region(b)
    union = a.union(b).area
    return float(a.intersection(b).area / union) if union > 0 else float("nan")


# ---------------------------------------------------------------------------
# Reference predictors


def _deepest(regions: Mapping[float, MultiPolygon], n: int) -> list[tuple[float, MultiPolygon]]:
    if not regions:
        raise ValueError("no known bench regions to predict from")
    levels = sorted(regions, reverse=True)  # top first
    return [(float(z), _region(regions[z])) for z in levels[-n:]]


def predict_nil(regions: Mapping[float, MultiPolygon], z_m: float) -> MultiPolygon:
    """Zero-order hold: the region of the deepest known bench, whatever ``z_m``.

    ``regions`` maps bench elevation (metres) to the geozone's region there.
    """
    return _deepest(regions, 1)[-1][1]


#: The references' cells are at most this many hole spacings (:func:`reference_grid`), about what 240 cells across a
#: synthetic family's pit give (a quarter to a fifth; on Kennecott half a spacing scored the same) ...
REFERENCE_CELL_SPACINGS = 0.25
#: ... and at most this many squared over the table.
REFERENCE_MAX_CELLS = 1200


def reference_grid(xy: np.ndarray, hole_spacing_m: float) -> Grid:
    """The grid the references are predicted on over the points ``xy``: 240 cells across, finer where that is coarser
    than :data:`REFERENCE_CELL_SPACINGS` hole spacings.

    A reference is worth beating only at its best. Its cells were a fixed share of the table's width: on Kennecott
    (1.4 km) 0.9 of a hole spacing, where the model's fields have half of one; on a table of two pits 3 km apart
    13 m, and linear extrapolation of the signed distance lost 7.9 F1 points at a bench below to them (92.0 on
    half-spacing cells). Now at most :data:`REFERENCE_CELL_SPACINGS` hole spacings (but no more than
    :data:`REFERENCE_MAX_CELLS` squared); on the synthetic families the 240 cells are as fine and stay.
    """
    grid = default_grid([xy])
    width, height = np.ptp(xy, axis=0)
    finest_m = cell_size_within(width, height, REFERENCE_CELL_SPACINGS * hole_spacing_m, REFERENCE_MAX_CELLS)
    if not np.isfinite(finest_m) or grid.cell_size_m <= finest_m:
        return grid
    return default_grid([xy], cell_size_m=finest_m)


def default_grid(regions: Iterable, cell_size_m: float | None = None, cells_across: int = 240) -> Grid:
    """A grid covering the given geometries (or ``(n, 2)`` point arrays) with the standard margin."""
    bounds = []
    for r in regions:
        if isinstance(r, np.ndarray):
            if len(r):
                bounds.append((*r.min(axis=0), *r.max(axis=0)))
        elif r is not None and not r.is_empty:
            bounds.append(r.bounds)
    if not bounds:
        raise ValueError("nothing to cover with a grid")
    b = np.array(bounds, float)
    box = (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max())
    if cell_size_m:
        return Grid.covering(box, cell_size_m)
    return Grid.for_extent(box, cells_across)


class LinearSDF:
    """Signed distance extrapolated linearly from the last two known benches.

    ``phi(z) = phi_k + (z - z_k) / (z_k - z_{k-1}) * (phi_k - phi_{k-1})``,
    region ``phi > 0``. With a single known bench, or when either of the last
    two regions is empty (the SDF of an empty region is a constant, so its
    "trend" means nothing), it falls back to the zero-order hold.

    Where the two benches' signed distances differ by more than
    ``max_shift_m`` (default 1.5 bench heights, i.e. a boundary dipping at less
    than about 34 degrees), the boundaries there have no plausible
    correspondence (a pod or a mislabelled hole appearing or vanishing, a
    bench drilled only in part): the field is held there rather than
    extrapolated, otherwise a single new hole would grow by the distance to
    the nearest body at every bench.
    """

    def __init__(self, regions: Mapping[float, MultiPolygon], grid: Grid, max_shift_m: float | None = None):
        last = _deepest(regions, 2)
        self.grid = grid
        (self.z_k, self.region_k) = last[-1]
        self.phi_k = signed_distance(grid.rasterize(self.region_k), grid.cell_size_m)
        self.slope = None  # d phi / d z
        if len(last) == 2 and not last[0][1].is_empty and not self.region_k.is_empty:
            z_prev, region_prev = last[0]
            phi_prev = signed_distance(grid.rasterize(region_prev), grid.cell_size_m)
            shift = self.phi_k - phi_prev
            limit = max_shift_m if max_shift_m is not None else 1.5 * abs(self.z_k - z_prev)
            self.slope = np.where(np.abs(shift) <= limit, shift, 0.0) / (self.z_k - z_prev)

    def field(self, z_m: float) -> np.ndarray:
        if self.slope is None:
            return self.phi_k
        return self.phi_k + (z_m - self.z_k) * self.slope

    def region(self, z_m: float) -> MultiPolygon:
        if self.slope is None:
            return self.region_k
        return self.grid.polygons_from_field(self.field(z_m), 0.0)


def predict_linear_sdf(
    regions: Mapping[float, MultiPolygon], z_m: float, grid: Grid | None = None, max_shift_m: float | None = None
) -> MultiPolygon:
    """Linear extrapolation of the signed distance from the last two benches (see :class:`LinearSDF`).

    ``grid`` defaults to a 240-cell grid over the known regions.
    """
    if grid is None:
        grid = default_grid(regions.values())
    return LinearSDF(regions, grid, max_shift_m).region(z_m)


def predict_implicit_rbf(
    holes_xy: np.ndarray,
    holes_z: np.ndarray,
    inside: np.ndarray,
    z_m: float,
    grid: Grid | None = None,
    **kwargs,
) -> MultiPolygon:
    """Region ``> 0`` of the implicit model (:func:`fit_implicit_rbf`) at elevation ``z_m``.

    ``grid`` defaults to a 240-cell grid over the holes; ``kwargs`` go to
    :func:`fit_implicit_rbf`.
    """
    if grid is None:
        grid = default_grid([np.asarray(holes_xy, float)])
    return fit_implicit_rbf(holes_xy, holes_z, inside, **kwargs).region(z_m, grid)


# ---------------------------------------------------------------------------
# Protocol


#: Columns of the table :func:`evaluate_geozone` returns.
_COLUMNS = (
    "bench",
    "bench_z",
    "z_m",
    "depth_m",
    "fraction",
    "method",
    "precision",
    "recall",
    "f1",
    "p_area",
    "g_area",
    "i_area",
)


def truth_from_mine(mine, frame) -> Truth:
    """Truth function ``(geozone, z_m) -> MultiPolygon`` in the Blastholes local frame for a synthetic mine.

    ``mine`` is a :class:`core.synthetic.blobs.SyntheticMine`, ``frame`` the
    :class:`core.io.blastholes.LocalFrame` of the holes read from its table;
    :meth:`~core.synthetic.blobs.SyntheticMine.section_in` maps the mine's
    metres through the table's units and the frame's origin.
    """

    def truth(geozone: str, z_m: float) -> MultiPolygon:
        return mine.section_in(frame, geozone, z_m)

    return truth


def _lookup(predictions: Mapping[float, MultiPolygon], z: float) -> MultiPolygon:
    if z in predictions:
        return predictions[z]
    keys = list(predictions)
    if keys:
        near = min(keys, key=lambda k: abs(float(k) - z))
        if abs(float(near) - z) < 1e-6:
            return predictions[near]
    raise KeyError(f"model_predictor returned no prediction for z = {z} m")


def bench_regions(holes: Blastholes, geozone: str, contours=None) -> dict[int, MultiPolygon]:
    """Region of ``geozone`` on every bench (union of its extracted contours), keyed by bench index."""
    if contours is None:
        from core.extraction.contours import extract_contours

        contours = extract_contours(holes, [geozone])
    out: dict[int, list] = {k: [] for k in range(holes.n_benches)}
    for c in contours:
        if c.geozone == geozone and not c.polygon.is_empty:
            out[c.bench].append(c.polygon)
    return {k: _region(shapely.union_all(v)) if v else MultiPolygon() for k, v in out.items()}


def evaluate_geozone(
    holes: Blastholes,
    geozone: str,
    model_predictor: ModelPredictor | None,
    *,
    truth: Truth | None = None,
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    progress: Callable[[int, int], None] | None = None,
    contours=None,
    grid: Grid | None = None,
    references: Sequence[str] = ("nil", "linear", "implicit"),
) -> pd.DataFrame:
    """The paper's predictive-value protocol for one geozone.

    For every bench ``k >= 1`` that has a bench below it, benches ``0..k`` are
    known (two of them, ``k-1`` and ``k``, for the linear reference) and all
    below is withheld. Predictions are made at ``z_k - f * bench_height`` for
    each ``f`` in ``fractions`` and scored inside the evaluation area, the
    drilled area of bench ``k+1`` (:func:`drilled_area` of its holes).

    Parameters
    ----------
    holes : Blastholes
    geozone : str
    model_predictor : callable or None
        ``model_predictor(known_holes, geozone, z_targets_m) -> {z: MultiPolygon}``
        with ``known_holes`` the holes of benches ``0..k`` only. ``None`` scores
        the references alone.
    truth : callable, optional
        ``truth(geozone, z_m) -> MultiPolygon`` in the local frame (synthetic
        data, e.g. :func:`truth_from_mine`). Without it (real data) only the
        next bench (``f = 1``, at its actual elevation) can be scored, against
        the region extracted from its holes; other fractions are skipped.
    fractions : sequence of float
        Prediction depths as fractions of the bench height (paper: 1/8..8/8).
    progress : callable, optional
        ``progress(done, total)`` after each withheld bench.
    contours : list of Contour, optional
        Contours of ``geozone`` already extracted on all benches (extracted
        here otherwise). Each bench's contours depend only on that bench's
        holes, so extracting once does not leak withheld data.
    grid : Grid, optional
        Grid for the SDF and implicit references (240 cells over the holes).
    references : sequence of str
        Reference predictors to run (subset of nil, linear, implicit).

    Returns
    -------
    DataFrame
        One row per bench, depth and method: ``bench`` (index of the last known
        bench), ``bench_z`` (its elevation), ``z_m`` (predicted elevation),
        ``depth_m``, ``fraction``, ``method``, ``precision``, ``recall``,
        ``f1``, ``p_area``, ``g_area``, ``i_area`` (intersection area, for
        area-weighted aggregation by :func:`summary_table`); on real data (no
        ``truth``) also ``holes_in``, ``holes_in_geozone``, ``holes_geozone``,
        the scores on the withheld bench's own holes, and the same counted in
        ground the last known bench drilled (``drilled_holes_in`` ...; see
        :func:`_add_hole_scores`).
    """
    levels = np.asarray(holes.bench_levels_m, float)
    n = len(levels)
    if grid is None:
        grid = reference_grid(holes.xy, holes.hole_spacing_m)
    regions_by_bench = bench_regions(holes, geozone, contours)
    height = holes.bench_height_m
    if not np.isfinite(height):
        height = typical_bench_height(levels)
    rows: list[dict] = []
    ks = list(range(1, n - 1))
    for done, k in enumerate(ks, start=1):
        targets = _prediction_targets(levels, k, fractions, height, truth is not None)
        if targets:
            regions = {float(levels[j]): regions_by_bench[j] for j in range(k + 1)}
            z_targets = [z for _, _, z in targets]
            methods = _predictors(holes, geozone, k, regions, z_targets, model_predictor, references, grid)
            # Each prediction is scored by area and, on real data, on the holes: computed once.
            methods = {name: lru_cache(maxsize=None)(predict) for name, predict in methods.items()}
            observed = regions_by_bench[k + 1]
            rows += _scores(methods, targets, truth, geozone, observed, holes.drilled_area(k + 1), k, float(levels[k]))
            if truth is None:
                _add_hole_scores(rows[-len(methods) :], methods, targets[0][2], holes, geozone, k + 1)
        if progress:
            progress(done, len(ks))
    extra = [c for c in (*_HOLE_COLUMNS, *_DRILLED_HOLE_COLUMNS) if rows and c in rows[0]]
    return pd.DataFrame(rows, columns=[*_COLUMNS, *extra])


#: Columns added on real data (no truth function): scores on the withheld bench's holes.
_HOLE_COLUMNS = ("holes_in", "holes_in_geozone", "holes_geozone")
#: The same among those holes in ground the last known bench drilled (:func:`_add_hole_scores`).
_DRILLED_HOLE_COLUMNS = tuple(f"drilled_{c}" for c in _HOLE_COLUMNS)


def _prediction_targets(
    levels: np.ndarray, k: int, fractions: Sequence[float], height_m: float, have_truth: bool
) -> list[tuple[float, float, float]]:
    """``(fraction, depth_m, z_m)`` to predict below bench ``k``.

    Every fraction of the bench height with a truth function; without one,
    only the next bench, at its actual elevation (if 1 is among the fractions).
    """
    z_k = float(levels[k])
    if have_truth:
        return [(float(f), float(f * height_m), z_k - float(f * height_m)) for f in fractions]
    d = z_k - float(levels[k + 1])
    return [(1.0, d, float(levels[k + 1]))] if any(np.isclose(f, 1.0) for f in fractions) else []


def _predictors(
    holes: Blastholes,
    geozone: str,
    k: int,
    regions: dict[float, MultiPolygon],
    z_targets: list[float],
    model_predictor: ModelPredictor | None,
    references: Sequence[str],
    grid: Grid,
) -> dict[str, Callable[[float], MultiPolygon]]:
    """Each method's section at an elevation, knowing only benches ``0..k`` (``regions``, by elevation)."""
    known = holes.subset(holes.bench <= k)
    methods: dict[str, Callable[[float], MultiPolygon]] = {}
    if model_predictor is not None:
        methods["model"] = partial(_lookup, model_predictor(known, geozone, list(z_targets)))
    if "nil" in references:
        methods["nil"] = partial(predict_nil, regions)
    if "linear" in references:
        methods["linear"] = LinearSDF(regions, grid).region
    if "implicit" in references:
        # The one the engine takes in new ground where a geozone's pushbacks chose it (core.model.new_ground), on
        # the spacing it was tuned with, the nearest neighbour's: the engine's lowered it 2.0 / 3.2 F1 points.
        model = implicit_model(known_holes(known, geozone))
        # Evaluated only where it is scored, the next bench's drilled area: it was a fifth of a Kennecott build.
        methods["implicit"] = partial(model.region, grid=grid, where=holes.drilled_area(k + 1))
    return methods


def rows_as_written(rows: pd.DataFrame, holes: Blastholes) -> pd.DataFrame:
    """:func:`evaluate_geozone`'s rows as files give them: ``bench_z`` in the input's units and elevations.

    The engine's columns named in metres (``z_m``, ``depth_m``; areas in m2) stay in metres; an input in
    other units gets them in its own as well (``z_ft``, ``depth_ft``; ``p_area_ft2``, ``g_area_ft2``,
    ``i_area_ft2``).
    """
    rows = rows.assign(bench_z=[holes.bench_z_input(int(k)) for k in rows["bench"]])
    rows = summary_as_written(rows, holes).assign(**_in_input_units(rows, holes, "z", holes.frame.z_to_input))
    unit, mpu = holes.frame.length_unit, holes.frame.metres_per_unit
    if unit == "m":
        return rows
    # The areas' names say no unit: beside z_ft and depth_ft, a table in feet read them as square feet.
    return rows.assign(**{f"{c}_{unit}2": np.round(rows[c].to_numpy() / mpu**2, 6) for c in _AREA_COLUMNS})


#: The area columns of :func:`evaluate_geozone` (square metres).
_AREA_COLUMNS = ("p_area", "g_area", "i_area")


def summary_as_written(summary: pd.DataFrame, holes: Blastholes) -> pd.DataFrame:
    """``summary`` (or rows) with the prediction depths in the input's units too (``depth_ft`` for feet)."""
    return summary.assign(**_in_input_units(summary, holes, "depth", holes.frame.length_to_input))


def _in_input_units(df: pd.DataFrame, holes: Blastholes, column: str, to_input) -> dict[str, np.ndarray]:
    """``{column_<unit>: to_input(df[column_m])}``, for an input in other units than metres (else nothing)."""
    unit = holes.frame.length_unit
    return {} if unit == "m" else {f"{column}_{unit}": np.round(to_input(df[f"{column}_m"].to_numpy()), 6)}


def _scores(
    methods: Mapping[str, Callable[[float], MultiPolygon]],
    targets: list[tuple[float, float, float]],
    truth: Truth | None,
    geozone: str,
    observed: MultiPolygon,
    within: Polygon | MultiPolygon,
    k: int,
    z_k: float,
) -> list[dict]:
    """Rows of :func:`evaluate_geozone` for bench ``k``: every method at every target, scored inside ``within``.

    The truth is ``truth(geozone, z)``, or without a truth function the
    region ``observed`` on the next bench.
    """
    rows = []
    for f, depth, z in targets:
        g = truth(geozone, z) if truth is not None else observed
        for name, predict in methods.items():
            p, r, pa, ga = precision_recall(predict(z), g, within)
            row = dict(zip(_COLUMNS, (k, z_k, z, depth, f, name, p, r, f1_score(p, r), pa, ga)))
            row["i_area"] = 0.0 if not np.isfinite(p) else p * pa
            rows.append(row)
    return rows


def _add_hole_scores(
    rows: list[dict],
    methods: Mapping[str, Callable[[float], MultiPolygon]],
    z: float,
    holes: Blastholes,
    geozone: str,
    bench: int,
) -> None:
    """Score each method on the withheld bench's holes as well (real data, in place).

    ``holes_in``: holes of the bench inside the prediction; ``holes_in_geozone``:
    those labelled ``geozone``; ``holes_geozone``: all its holes labelled
    ``geozone``. Precision is ``holes_in_geozone / holes_in``, recall
    ``holes_in_geozone / holes_geozone``, summed over benches by the caller:
    a score on the samples themselves, free of how the bench was contoured.
    ``drilled_holes_in``, ``drilled_holes_in_geozone`` and ``drilled_holes_geozone``
    count the same among the holes in ground the last known bench drilled
    (:meth:`Blastholes.drilled_area`); the rest are in ground it did not.
    """
    on = holes.on_bench(bench)
    xy, mine = holes.xy[on], holes.geozone[on] == geozone
    # Under the last known bench's holes every method has its section to start from; beyond them only what it
    # makes of the movement (or its fit) reaches: two different questions, told apart by the bench's own holes.
    above = holes.drilled_area(bench - 1)
    drilled = shapely.contains_xy(above, xy[:, 0], xy[:, 1]) if not above.is_empty else np.zeros(len(xy), bool)
    for row, predict in zip(rows, methods.values()):
        region = _region(predict(z))
        inside = shapely.contains_xy(region, xy[:, 0], xy[:, 1]) if not region.is_empty else np.zeros(len(xy), bool)
        for prefix, where in (("", slice(None)), ("drilled_", drilled)):
            row[f"{prefix}holes_in"] = int(inside[where].sum())
            row[f"{prefix}holes_in_geozone"] = int((inside & mine)[where].sum())
            row[f"{prefix}holes_geozone"] = int(mine[where].sum())


def summary_table(df: pd.DataFrame) -> pd.DataFrame:
    """Area-weighted precision and recall per depth and method, like the paper's Table.

    Precision at a depth is ``sum |P ∩ G| / sum |P|`` over all benches (and
    geozones, if ``df`` concatenates several), recall ``sum |P ∩ G| / sum |G|``.

    Returns
    -------
    DataFrame
        One row per fraction: ``fraction``, ``depth_m`` (mean), ``n`` (benches
        scored: where some method predicted the geozone or it was there; a bench
        with neither adds nothing to any rate and is not counted), then ``precision_<method>`` and ``recall_<method>`` for each
        method present (in :data:`METHODS` order), and, when both ``model`` and
        ``nil`` are present, ``precision_gain`` and ``recall_gain`` (model minus
        nil); ``f1_<method>`` for each method and, with the model and a
        reference, ``f1_margin`` (the model's F1 less the best reference's,
        issue 12's measure) and ``best_reference``. On real data (rows with
        :data:`_HOLE_COLUMNS`) also ``f1_holes_<method>``, ``f1_holes_margin``
        and ``best_holes_reference``: the same on the withheld benches' holes, free of
        how those benches were contoured. Rates are fractions in [0, 1] (nan
        when nothing was predicted or there was no truth at that depth).
    """
    if df.empty:
        return pd.DataFrame(columns=["fraction", "depth_m", "n"])
    present = [m for m in METHODS if m in set(df["method"])] + sorted(set(df["method"]) - set(METHODS))
    out = []
    for f, part in df.groupby("fraction", sort=True):
        row = {"fraction": float(f), "depth_m": float(part["depth_m"].mean()), "n": _benches_scored(part)}
        for m in present:
            sub = part[part["method"] == m]
            i, pa, ga = sub["i_area"].sum(), sub["p_area"].sum(), sub["g_area"].sum()
            row[f"precision_{m}"] = i / pa if pa > 0 else np.nan
            row[f"recall_{m}"] = i / ga if ga > 0 else np.nan
        if "model" in present and "nil" in present:
            row["precision_gain"] = row["precision_model"] - row["precision_nil"]
            row["recall_gain"] = row["recall_model"] - row["recall_nil"]
        row.update(_f1_columns({m: f1_score(row[f"precision_{m}"], row[f"recall_{m}"]) for m in present}, ""))
        if all(c in part for c in _HOLE_COLUMNS):
            row.update(_f1_columns({m: _holes_f1(part[part["method"] == m]) for m in present}, "holes_"))
        out.append(row)
    table = pd.DataFrame(out)
    order = ["fraction", "depth_m", "n"]
    order += [f"precision_{m}" for m in present] + (["precision_gain"] if "precision_gain" in table else [])
    order += [f"recall_{m}" for m in present] + (["recall_gain"] if "recall_gain" in table else [])
    order += [c for c in table.columns if c.startswith(("f1_", "best_"))]
    return table[order]


def _benches_scored(rows: pd.DataFrame) -> int:
    """The benches of ``rows`` where something was scored: a method predicted the geozone, or it was there.

    On the others every rate is 0 / 0 (no area predicted, none true; on real data
    no hole inside either): counted, a geozone absent from benches (the demo's g3 on
    two of five) had ``n`` say they were scored.
    """
    scored = (rows["p_area"] > 0) | (rows["g_area"] > 0)
    for column in ("holes_in", "holes_geozone"):
        if column in rows:
            scored |= rows[column] > 0
    return int(rows.loc[scored, "bench"].nunique())


def _f1_columns(f1: dict[str, float], kind: str) -> dict:
    """``f1_<kind><method>`` of each method and, with the model and a reference, the model's margin over the best."""
    row: dict = {f"f1_{kind}{m}": v for m, v in f1.items()}
    scored = {m: v for m, v in f1.items() if m != "model" and np.isfinite(v)}
    if "model" in f1 and scored:
        best = max(scored, key=lambda m: scored[m])
        row[f"f1_{kind}margin"] = f1["model"] - scored[best]
        row[f"best_{kind}reference"] = best
    return row


def _holes_f1(rows: pd.DataFrame) -> float:
    """F1 of one method's rows on the withheld benches' holes, pooled (``2 hits / (inside + labelled)``)."""
    hits, inside, labelled = (float(rows[c].sum()) for c in ("holes_in_geozone", "holes_in", "holes_geozone"))
    return 2 * hits / (inside + labelled) if inside + labelled > 0 else float("nan")


def margin_lines(summary: pd.DataFrame, unit: str = "m") -> list[str]:
    """One line per depth: the model's F1 against the best reference's (percent; issue 12's measure).

    The depth is given in ``unit``, from the summary's ``depth_<unit>`` column (:func:`summary_as_written`).
    """
    lines = []
    for _, r in summary.iterrows():
        if "f1_margin" not in r or not np.isfinite(r["f1_margin"]):
            continue
        best = r["best_reference"]
        line = (
            f"{r[f'depth_{unit}']:.2f} {unit} below: model F1 {100 * r['f1_model']:.1f}, best reference {best} "
            f"{100 * r[f'f1_{best}']:.1f} ({100 * r['f1_margin']:+.1f})"
        )
        if "f1_holes_margin" in r and np.isfinite(r["f1_holes_margin"]):
            line += f"; on the withheld holes {100 * r['f1_holes_model']:.1f} ({100 * r['f1_holes_margin']:+.1f})"
        lines.append(line)
    return lines


def format_table(summary: pd.DataFrame, unit: str = "m") -> str:
    """The summary as text in percent, like the paper's Table, its depths in ``unit`` (``depth_<unit>``)."""
    cols = [c for c in summary.columns if c.startswith(("precision_", "recall_", "f1_"))]
    depth = f"depth_{unit}"
    shown = summary[[depth, *cols]].copy()
    for c in cols:
        shown[c] = (100 * shown[c]).round(1)
    shown[depth] = shown[depth].round(2)
    return shown.to_string(index=False)


_STYLE = {
    "model": {"color": "0.55", "marker": "o", "lw": 2.0},
    "nil": {"color": "black", "marker": "s", "lw": 1.5},
    "linear": {"color": "tab:blue", "marker": "^", "lw": 1.0, "ls": "--"},
    "implicit": {"color": "tab:orange", "marker": "v", "lw": 1.0, "ls": "--"},
}


def plot_precision_recall(summary: pd.DataFrame, path: str | Path, title: str | None = None, unit: str = "m") -> Path:
    """Precision, recall and F1 (percent) vs prediction depth, one line per method, saved as PNG.

    Like the paper's Figure (gray: model, black: nil), with the other
    references dashed. The depths are in ``unit``, from the summary's
    ``depth_<unit>`` column (:func:`summary_as_written`), as :func:`format_table`
    and :func:`margin_lines` give them. The file is written atomically.
    """
    # A bare Figure renders with the Agg canvas without touching pyplot's global backend.
    from matplotlib.figure import Figure

    methods = [c[len("precision_") :] for c in summary.columns if c.startswith("precision_") and c != "precision_gain"]
    shown = ("precision", "recall", "f1") if all(f"f1_{m}" in summary for m in methods) else ("precision", "recall")
    fig = Figure(figsize=(5 * len(shown), 4), dpi=120)
    axes = fig.subplots(1, len(shown), sharex=True)
    # The table printed beside it gives feet for a table in feet: a plot in metres showed other depths.
    depth = summary[f"depth_{unit}"]
    for ax, what in zip(axes, shown):
        for m in methods:
            ax.plot(depth, 100 * summary[f"{what}_{m}"], label=m, **_STYLE.get(m, {}))
        ax.set_xlabel(f"prediction depth ({unit})")
        name = {"precision": "Precision", "recall": "Recall", "f1": "F1"}[what]
        ax.set_ylabel(f"{name} (%)")
        ax.set_title(name)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="lower left")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
    return path
