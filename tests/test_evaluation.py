"""Tests of core.model.evaluation: scoring, reference predictors and the predictive-value protocol."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from shapely.geometry import MultiPolygon, Point, Polygon, box

from core.extraction.contours import extract_contours
from core.geometry.grid import Grid
from core.io.blastholes import blastholes_from_table, drilled_area
from core.model import evaluation as ev
from core.synthetic.blobs import make_mine, sample_blastholes

# ---------------------------------------------------------------------------
# precision_recall


def test_offset_squares_exact():
    p, r, pa, ga = ev.precision_recall(box(0, 0, 10, 10), box(3, 0, 13, 10))
    assert (pa, ga) == pytest.approx((100.0, 100.0))
    assert (p, r) == pytest.approx((0.7, 0.7))
    # Different sizes: the prediction lies inside the truth.
    p, r, pa, ga = ev.precision_recall(box(0, 0, 10, 10), box(0, 0, 10, 20))
    assert (p, r, pa, ga) == pytest.approx((1.0, 0.5, 100.0, 200.0))


def test_within_clips_both():
    p, r, pa, ga = ev.precision_recall(box(0, 0, 10, 10), box(3, 0, 13, 10), within=box(5, 0, 20, 10))
    assert (pa, ga) == pytest.approx((50.0, 80.0))
    assert (p, r) == pytest.approx((1.0, 50.0 / 80.0))


def test_area_weighted_over_components():
    """Overall rates are the area-weighted averages of the per-component rates of the paper."""
    pred = MultiPolygon([box(0, 0, 10, 10), box(20, 0, 24, 5)])  # areas 100, 20
    truth = MultiPolygon([box(5, 0, 15, 10), box(22, 0, 30, 5)])  # areas 100, 40
    p, r, pa, ga = ev.precision_recall(pred, truth)
    per_p = [(50 / 100, 100), (10 / 20, 20)]
    per_r = [(50 / 100, 100), (10 / 40, 40)]
    assert p == pytest.approx(sum(a * w for a, w in per_p) / sum(w for _, w in per_p))
    assert r == pytest.approx(sum(a * w for a, w in per_r) / sum(w for _, w in per_r))
    assert (pa, ga) == pytest.approx((120.0, 140.0))


def test_overlapping_parts_are_merged():
    pred = MultiPolygon([box(0, 0, 10, 10), box(5, 0, 15, 10)])  # invalid: parts overlap
    p, r, pa, ga = ev.precision_recall(pred, box(0, 0, 15, 10))
    assert pa == pytest.approx(150.0)
    assert (p, r) == pytest.approx((1.0, 1.0))


def test_empty_cases():
    square = box(0, 0, 10, 10)
    p, r, pa, ga = ev.precision_recall(MultiPolygon(), square)
    assert math.isnan(p) and r == 0.0 and pa == 0.0 and ga == pytest.approx(100.0)
    p, r, pa, ga = ev.precision_recall(square, Polygon())
    assert p == 0.0 and math.isnan(r) and ga == 0.0
    p, r, pa, ga = ev.precision_recall(MultiPolygon(), MultiPolygon())
    assert math.isnan(p) and math.isnan(r)
    # Disjoint from the evaluation area: both empty after clipping.
    p, r, _, _ = ev.precision_recall(square, square, within=box(50, 50, 60, 60))
    assert math.isnan(p) and math.isnan(r)
    assert math.isnan(ev.f1_score(float("nan"), 1.0)) and ev.f1_score(0.0, 0.0) == 0.0
    assert ev.f1_score(0.5, 1.0) == pytest.approx(2 / 3)


# ---------------------------------------------------------------------------
# Reference predictors


def test_nil_is_the_deepest_bench():
    regions = {90.0: box(5, 5, 15, 15), 100.0: box(0, 0, 10, 10), 80.0: box(20, 20, 30, 30)}
    got = ev.predict_nil(regions, 70.0)
    assert isinstance(got, MultiPolygon)
    assert got.symmetric_difference(box(20, 20, 30, 30)).area < 1e-9
    with pytest.raises(ValueError):
        ev.predict_nil({}, 0.0)


def test_linear_sdf_follows_a_moving_disc():
    step = np.array([4.0, 3.0])  # metres per 10 m bench
    disc = lambda k: Point(*(k * step)).buffer(20.0, quad_segs=32)  # noqa: E731
    regions = {100.0: disc(0), 90.0: disc(1)}
    grid = Grid.covering((-40, -40, 60, 60), 0.5)
    assert ev.iou(ev.predict_linear_sdf(regions, 80.0, grid), disc(2)) > 0.9
    # Two benches down the SDF of a translated disc no longer extrapolates exactly
    # (it squashes sideways), but still beats standing still; so does half a bench.
    for k, z in ((3, 70.0), (1.5, 85.0)):
        pred = ev.predict_linear_sdf(regions, z, grid)
        assert ev.iou(pred, disc(k)) > ev.iou(ev.predict_nil(regions, z), disc(k)) + 0.05
    # A single known bench (or an empty one) falls back to the zero-order hold.
    assert ev.iou(ev.predict_linear_sdf({100.0: disc(0)}, 90.0, grid), disc(0)) == pytest.approx(1.0)
    assert ev.iou(ev.predict_linear_sdf({100.0: MultiPolygon(), 90.0: disc(1)}, 80.0, grid), disc(1)) == pytest.approx(
        1.0
    )


def test_linear_sdf_holds_a_new_speck():
    """A region appearing from nothing (a mislabelled hole) is held, not grown by its distance to the body."""
    body = lambda k: Point(4.0 * k, 0).buffer(20.0, quad_segs=32)  # noqa: E731
    speck = Point(60, 0).buffer(3.0)
    regions = {100.0: body(0), 90.0: body(1).union(speck)}
    pred = ev.predict_linear_sdf(regions, 80.0, Grid.covering((-40, -40, 80, 40), 0.5))
    assert pred.intersection(box(45, -40, 80, 40)).area < 2 * speck.area


# ---------------------------------------------------------------------------
# Synthetic mine: implicit reference and the protocol


@pytest.fixture(scope="module")
def small_mine():
    mine = make_mine(seed=1, n_benches=4, extent_m=(160.0, 120.0), origin=(5000.0, 20000.0))
    table = sample_blastholes(mine, seed=2)
    holes = blastholes_from_table(table)
    truth = ev.truth_from_mine(mine, holes.frame)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        contours = extract_contours(holes, ["g1"])
    return mine, holes, truth, contours


def test_truth_from_mine_matches_labels(small_mine):
    mine, holes, truth, _ = small_mine
    sel = holes.on_bench(1)
    region = truth("g1", float(holes.bench_levels_m[1]))
    import shapely

    inside = shapely.contains_xy(region, holes.xy[sel, 0], holes.xy[sel, 1])
    agree = np.mean(inside == (holes.geozone[sel] == "g1"))
    assert agree > 0.97  # only label noise disagrees


def test_implicit_rbf_predicts_the_next_bench(small_mine):
    _, holes, truth, _ = small_mine
    known = holes.bench <= 2
    z = float(holes.bench_levels_m[3])
    grid = ev.default_grid([holes.xy])
    pred = ev.predict_implicit_rbf(
        holes.xy[known],
        holes.z[known],
        holes.geozone[known] == "g1",
        z,
        grid,
        bench=holes.bench[known],
        spacing_m=holes.hole_spacing_m,
        bench_height_m=holes.bench_height_m,
    )
    within = drilled_area(holes.xy[holes.on_bench(3)], holes.hole_spacing_m)
    p, r, _, _ = ev.precision_recall(pred, truth("g1", z), within)
    assert p > 0.6 and r > 0.6
    # Without the bench argument benches are found from the elevations.
    pred2 = ev.predict_implicit_rbf(holes.xy[known], holes.z[known], holes.geozone[known] == "g1", z, grid)
    assert ev.iou(pred, pred2) > 0.9


def test_implicit_rbf_where_benches_do_not_overlap_keeps_each_benchs_boundaries():
    """Two benches drilled side by side: every neighbourhood lies on one bench and has no depth trend to fit.

    Its degree-1 system is singular; the model still gives each bench's own stripes below it.
    """
    from core.geometry.grid import Grid
    from core.model.implicit import fit_implicit_rbf

    pattern = np.stack(np.meshgrid(np.arange(0, 200, 5.0), np.arange(0, 200, 5.0)), -1).reshape(-1, 2)
    xy = np.concatenate([pattern, pattern + [1000.0, 0.0]])
    z = np.repeat([100.0, 90.0], len(pattern))
    inside = (xy[:, 0] % 40) < 20  # stripes 20 m wide, 5 m holes
    model = fit_implicit_rbf(xy, z, inside, bench=(z < 95).astype(int), bench_height_m=10.0)
    grid = Grid.covering((0.0, 0.0, 1200.0, 200.0), 2.5)
    f = model.field(85.0, grid)
    on = np.column_stack([v.ravel() for v in grid.cell_centres()])
    sample = (np.abs(on[:, 0] - 100) < 80) | (np.abs(on[:, 0] - 1100) < 80)
    truth = (on[sample, 0] % 40) < 20
    away = np.abs((on[sample, 0] % 20) - 10) < 6  # not within a cell or two of a stripe's edge
    assert np.isfinite(f).all()
    assert np.mean((f.ravel()[sample] > 0)[away] == truth[away]) > 0.95


def test_the_implicit_model_evaluated_only_where_it_is_scored_is_the_same_there(small_mine):
    """The evaluation scores the implicit reference inside the next bench's drilled area and evaluates it only there."""
    import shapely

    from core.model.implicit import fit_implicit_rbf

    _, holes, _, _ = small_mine
    known = holes.bench <= 2
    grid = ev.default_grid([holes.xy])
    model = fit_implicit_rbf(holes.xy[known], holes.z[known], (holes.geozone == "g1")[known], bench=holes.bench[known])
    z = float(holes.bench_levels_m[3])
    scored = shapely.box(*holes.xy.min(axis=0), *holes.xy.mean(axis=0))  # a quarter of the pit
    everywhere, there = model.region(z, grid), model.region(z, grid, where=scored)
    assert everywhere.intersection(scored).area > 0.05 * scored.area  # the geozone is there to compare
    assert everywhere.intersection(scored).symmetric_difference(there.intersection(scored)).area < 1e-6
    # Evaluated on cells this size: two past `scored`, one more to interpolate, half a cell to trace the boundary.
    cell_m = model.resolution_spacings * model.spacing_m
    assert there.difference(scored.buffer(3.5 * cell_m)).is_empty


def test_the_implicit_model_solves_each_cell_of_a_level_once_and_gives_each_ground_what_a_fresh_model_gives(
    small_mine,
):
    """A model's sections at one level are asked for over several grounds (the surfaces' ground above the deepest
    bench asks for each bench level twice), and each cell is a local solve: the cells evaluated are kept."""
    import shapely

    from core.model.implicit import ImplicitRBF, fit_implicit_rbf

    _, holes, _, _ = small_mine
    known = holes.bench <= 2

    def fitted():
        return fit_implicit_rbf(
            holes.xy[known], holes.z[known], (holes.geozone == "g1")[known], bench=holes.bench[known]
        )

    grid = ev.default_grid([holes.xy])
    z = float(holes.bench_levels_m[3])
    (x0, y0), (x1, y1) = holes.xy.min(axis=0), holes.xy.max(axis=0)
    west, middle = shapely.box(x0, y0, (x0 + x1) / 2, y1), shapely.box((3 * x0 + x1) / 4, y0, (x0 + 3 * x1) / 4, y1)
    model = fitted()
    solved = []
    model._at = lambda points: solved.append(len(points)) or ImplicitRBF._at(model, points)
    for where in (west, middle, west):
        np.testing.assert_array_equal(model.field(z, grid, where), fitted().field(z, grid, where))
    np.testing.assert_array_equal(model.field(z - 1.0, grid, west), fitted().field(z - 1.0, grid, west))
    fresh = fitted()
    fresh._at = lambda points: solved.append(-len(points)) or ImplicitRBF._at(fresh, points)
    fresh.field(z, grid, west.union(middle))
    fresh.field(z - 1.0, grid, west)
    assert len(solved) == 5 and sum(solved[:3]) == -sum(solved[3:])  # the third ground was all solved before


def test_the_implicit_model_solves_only_neighbourhoods_whose_holes_differ_and_gives_what_solving_every_one_gives(
    small_mine,
):
    """Deep inside or outside a body every hole of a neighbourhood carries the capped distance: its solution is
    that constant, so it is not solved, and the field is SciPy's own solve of every cell."""
    from scipy.spatial import cKDTree

    from core.model.implicit import fit_implicit_rbf

    _, holes, _, _ = small_mine
    model = fit_implicit_rbf(holes.xy, holes.z, holes.geozone == "g1", bench=holes.bench)
    interpolator = model.interpolator
    asked = []

    class Counted:  # the interpolator, counting the points it is asked to solve
        def __getattr__(self, name):
            return getattr(interpolator, name)

        def __call__(self, points):
            asked.append(len(points))
            return interpolator(points)

    model.interpolator = Counted()
    grid = ev.default_grid([holes.xy])
    z = float(holes.bench_levels_m[-1]) - 5.0
    X, Y = grid.cell_centres()
    points = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, z * model.z_scale)])[::7]
    values = interpolator.d[cKDTree(interpolator.y).query(points, interpolator.neighbors)[1], 0]
    uniform = (values == values[:, :1]).all(axis=1)
    assert 0.2 < uniform.mean() < 0.9  # both kinds of neighbourhood are here
    np.testing.assert_allclose(model.at(points[:, :2], z), interpolator(points).reshape(-1), rtol=0, atol=1e-9)
    assert asked == [int((~uniform).sum())]


def test_evaluate_geozone_with_truth(small_mine, tmp_path):
    _, holes, truth, contours = small_mine
    seen = []

    def true_section(known, geozone, z_targets):
        seen.append((int(known.bench.max()), list(z_targets)))
        return {z: truth(geozone, z) for z in z_targets}

    progress = []
    df = ev.evaluate_geozone(
        holes, "g1", true_section, truth=truth, contours=contours, progress=lambda d, n: progress.append((d, n))
    )
    fractions = ev.DEFAULT_FRACTIONS
    n_eval = holes.n_benches - 2  # benches 1 .. n-2 have two known benches and one below
    assert len(df) == n_eval * len(fractions) * 4
    for col in ("bench_z", "depth_m", "fraction", "method", "precision", "recall", "f1", "p_area", "g_area"):
        assert col in df.columns
    assert set(df["method"]) == {"model", "nil", "linear", "implicit"}
    assert progress[-1] == (n_eval, n_eval)
    # The model only ever saw benches 0..k, and was asked for the depths below bench k.
    for (kmax, zs), k in zip(seen, range(1, holes.n_benches - 1)):
        assert kmax == k
        expected = holes.bench_levels_m[k] - np.array(fractions) * holes.bench_height_m
        assert np.allclose(zs, expected)
    rates = df[["precision", "recall", "f1"]].to_numpy()
    assert np.isfinite(rates).all() and (rates >= 0).all() and (rates <= 1).all()
    assert np.allclose(sorted(set(df["depth_m"])), np.array(fractions) * holes.bench_height_m)
    model = df[df["method"] == "model"]
    assert (model["precision"] > 0.95).all() and (model["recall"] > 0.95).all()
    # References are reasonable on a dipping body.
    assert (df.loc[df["method"] != "model", "recall"] > 0.5).all()

    summary = ev.summary_table(df)
    assert len(summary) == len(fractions)
    assert summary["precision_model"].min() > 0.95
    assert np.allclose(summary["precision_gain"], summary["precision_model"] - summary["precision_nil"])
    assert np.allclose(summary["recall_gain"], summary["recall_model"] - summary["recall_nil"])
    # Area weighting: the summary is sum of intersections over sum of areas.
    nil = df[(df["method"] == "nil") & (df["fraction"] == 1.0)]
    expect = (nil["precision"] * nil["p_area"]).sum() / nil["p_area"].sum()
    assert summary.loc[summary["fraction"] == 1.0, "precision_nil"].item() == pytest.approx(expect)
    assert "depth_m" in ev.format_table(summary)

    png = tmp_path / "pr.png"
    ev.plot_precision_recall(summary, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left


def test_summary_gives_each_methods_f1_and_the_models_margin_over_the_best_reference():
    """Issue 12's measure: pooled F1 per method, the model's F1 less the best reference's, on area and on holes."""
    import pandas as pd

    # Two benches, one depth; per method (intersection, predicted, true) areas and hole counts.
    scores = {"model": (60, 80, 100, 6, 8, 10), "nil": (50, 60, 100, 5, 6, 10), "linear": (70, 140, 100, 7, 14, 10)}
    rows = [
        {"bench": k, "fraction": 1.0, "depth_m": 10.0, "method": m, "i_area": i / 2, "p_area": pa / 2}
        | {"g_area": ga / 2, "holes_in_geozone": h, "holes_in": hi, "holes_geozone": hg}
        for k in (1, 2)
        for m, (i, pa, ga, h, hi, hg) in scores.items()
    ]
    summary = ev.summary_table(pd.DataFrame(rows)).iloc[0]
    f1 = {m: 2 * i / (pa + ga) for m, (i, pa, ga, *_) in scores.items()}  # model 2/3, nil 10/16, linear 7/12
    for m in scores:
        assert summary[f"f1_{m}"] == pytest.approx(f1[m])
        assert summary[f"f1_holes_{m}"] == pytest.approx(f1[m])  # the hole counts are the areas over ten
    assert summary["best_reference"] == summary["best_holes_reference"] == "nil"
    assert summary["f1_margin"] == pytest.approx(f1["model"] - f1["nil"])
    assert summary["f1_holes_margin"] == pytest.approx(f1["model"] - f1["nil"])
    # A model worse than a reference has a negative margin, and the table and lines say so.
    worse = pd.DataFrame([{**r, "i_area": r["i_area"] / 2} if r["method"] == "model" else r for r in rows])
    assert ev.summary_table(worse)["f1_margin"].item() < 0
    assert "f1_margin" in ev.format_table(ev.summary_table(worse))
    (line,) = ev.margin_lines(ev.summary_table(worse))
    assert "best reference nil" in line and "(-" in line


def test_a_method_that_predicts_nothing_where_the_geozone_is_has_f1_zero_not_nan():
    """bgm evaluate wrote no F1 (nan) for a method that predicted nothing where the geozone was.

    A geozone of three holes a bench: the implicit model drew nothing on any bench,
    evaluation.csv had f1_implicit empty while f1_holes_implicit said 0, and a model
    predicting nothing lost its margin line. F1 is ``2 |P ∩ G| / (|P| + |G|)``: 0 there.
    """
    import pandas as pd

    def row(k, method, i, pa, ga):
        return {"bench": k, "fraction": 1.0, "depth_m": 10.0, "method": method, "i_area": i, "p_area": pa, "g_area": ga}

    rows = [row(k, "nil", 40, 50, 60) for k in (1, 2)] + [row(k, "implicit", 0, 0, 60) for k in (1, 2)]
    summary = ev.summary_table(pd.DataFrame([*rows, row(1, "model", 40, 50, 60), row(2, "model", 40, 50, 60)]))
    assert summary["f1_implicit"].item() == 0.0 and math.isnan(summary["precision_implicit"].item())
    # The model predicting nothing: F1 0, its margin said, not left out.
    blind = ev.summary_table(pd.DataFrame([*rows, row(1, "model", 0, 0, 60), row(2, "model", 0, 0, 60)]))
    assert blind["f1_model"].item() == 0.0
    assert blind["f1_margin"].item() == pytest.approx(-80 / 110)
    (line,) = ev.margin_lines(blind)
    assert "model F1 0.0, best reference nil 72.7" in line
    # Predicted where the geozone is not (no truth on any bench scored): F1 0 too; nothing either side stays nan.
    assert ev.f1_score(0.0, float("nan")) == 0.0 and math.isnan(ev.f1_score(float("nan"), float("nan")))


def test_n_counts_the_benches_scored_not_those_where_the_geozone_was_neither_predicted_nor_there():
    """``n`` is the benches scored: one where no method predicted the geozone and it was absent scored nothing.

    The demo's g3 is on neither side on two of its five benches, and ``n`` said 5.
    """
    import pandas as pd

    def row(k, method, i, pa, ga):
        return {"bench": k, "fraction": 1.0, "depth_m": 10.0, "method": method, "i_area": i, "p_area": pa, "g_area": ga}

    rows = [row(1, m, 40, 50, 60) for m in ("model", "nil")]  # scored
    rows += [row(2, "model", 0, 30, 0), row(2, "nil", 0, 0, 0)]  # predicted where it is not: scored
    rows += [row(3, "model", 0, 0, 20), row(3, "nil", 0, 0, 20)]  # there, predicted by none: scored
    rows += [row(4, m, 0, 0, 0) for m in ("model", "nil")]  # neither: nothing scored
    summary = ev.summary_table(pd.DataFrame(rows)).iloc[0]
    assert summary["n"] == 3
    assert summary["precision_model"] == pytest.approx(40 / 80) and summary["recall_model"] == pytest.approx(40 / 80)
    # On real data a bench whose only sign of the geozone is a few holes (no contour) is scored on them.
    holes = [{**r, "holes_in": 0, "holes_in_geozone": 0, "holes_geozone": 2 if r["bench"] == 4 else 0} for r in rows]
    assert ev.summary_table(pd.DataFrame(holes)).iloc[0]["n"] == 4


def test_the_plot_gives_the_depths_the_table_beside_it_gives(tmp_path, monkeypatch):
    """On a table in feet, bgm evaluate prints 49.38 ft below: its plot showed 15.05 m."""
    import pandas as pd
    from matplotlib.figure import Figure

    summary = pd.DataFrame(
        {"fraction": [0.5, 1.0], "depth_m": [7.62, 15.24], "n": [3, 3]}
        | {f"{what}_{m}": [0.9, 0.8] for what in ("precision", "recall", "f1") for m in ("model", "nil")}
        | {"depth_ft": [25.0, 50.0]}
    )
    drawn = []
    save = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: (drawn.append(fig), save(fig, *a, **k))[1])
    ev.plot_precision_recall(summary, tmp_path / "pr.png", unit="ft")
    (fig,) = drawn
    for ax in fig.axes:
        assert ax.get_xlabel() == "prediction depth (ft)"
        for line in ax.get_lines():
            np.testing.assert_allclose(line.get_xdata(), [25.0, 50.0])
    assert "ft below" in ev.margin_lines(summary.assign(f1_margin=0.1, best_reference="nil"), "ft")[0]


def test_the_rows_of_a_table_in_feet_give_the_areas_in_square_feet_too():
    """evaluation_rows.csv gave a table in feet z_ft and depth_ft beside areas in m2 named p_area: read as ft2."""
    import pandas as pd

    xy = np.array(
        [(x + 3.0 * (i % 2), y) for i, y in enumerate(np.arange(0.0, 200.0, 17.0)) for x in range(0, 240, 20)]
    )
    inside = np.hypot(xy[:, 0] - 120, xy[:, 1] - 100) < 60
    table = pd.concat(
        [
            pd.DataFrame({"x": xy[:, 0], "y": xy[:, 1], "z": 1000.0 - 40 * k, "geozone": np.where(inside, "a", "b")})
            for k in range(4)
        ]
    )
    holes = blastholes_from_table(table, length_unit="ft")
    rows = ev.rows_as_written(ev.evaluate_geozone(holes, "a", None, references=("nil",)), holes)
    assert (rows["g_area"] > 0).all()
    for area in ("p_area", "g_area", "i_area"):
        np.testing.assert_allclose(rows[f"{area}_ft2"], rows[area] / 0.3048**2, rtol=1e-6)
    # A circle of 60 ft radius, its holes on a 20 ft pattern: about its area, in square feet.
    assert rows["g_area_ft2"].iloc[0] == pytest.approx(np.pi * 60**2, rel=0.2)


def test_evaluate_geozone_real_data_mode(small_mine):
    """Without truth only the next bench is scored, against its extracted region."""
    _, holes, _, contours = small_mine

    def hold(known, geozone, z_targets):
        regions = ev.bench_regions(known, geozone, [c for c in contours if c.bench <= known.bench.max()])
        last = regions[int(known.bench.max())]
        return dict.fromkeys(z_targets, last)

    df = ev.evaluate_geozone(holes, "g1", hold, contours=contours, references=("nil", "linear"))
    assert len(df) == (holes.n_benches - 2) * 3
    assert set(df["fraction"]) == {1.0}
    assert np.allclose(df["depth_m"], holes.bench_height_m, atol=0.5)
    # The stand-in model is the zero-order hold, so it scores exactly like nil.
    m = df[df["method"] == "model"].reset_index(drop=True)
    n = df[df["method"] == "nil"].reset_index(drop=True)
    assert np.allclose(m[["precision", "recall"]], n[["precision", "recall"]])
    assert ((df["precision"] > 0.5) & (df["recall"] > 0.5)).all()
    summary = ev.summary_table(df)
    assert len(summary) == 1 and summary["precision_gain"].item() == pytest.approx(0.0)


def test_real_data_is_also_scored_on_the_withheld_benchs_holes():
    """A body that does not move: holding the last bench holds nearly every hole of the next one."""
    import pandas as pd

    from core.io.blastholes import blastholes_from_table

    rows = np.arange(0.0, 120.0, 6.0 * np.sqrt(3) / 2)
    xy = np.array([(x + (i % 2) * 3.0, y) for i, y in enumerate(rows) for x in np.arange(0.0, 150.0, 6.0)])
    inside = np.hypot(xy[:, 0] - 75, xy[:, 1] - 60) < 30
    table = pd.concat(
        [
            pd.DataFrame({"x": xy[:, 0], "y": xy[:, 1], "z": 100.0 - 10 * k, "geozone": np.where(inside, "a", "b")})
            for k in range(4)
        ]
    )
    holes = blastholes_from_table(table)
    df = ev.evaluate_geozone(holes, "a", None, references=("nil",))
    assert {"holes_in", "holes_in_geozone", "holes_geozone"} <= set(df.columns)
    hit, inside_n, labelled = df["holes_in_geozone"].sum(), df["holes_in"].sum(), df["holes_geozone"].sum()
    assert labelled == 2 * inside.sum()  # benches 2 and 3 withheld in turn
    assert hit / labelled > 0.97 and hit / inside_n > 0.97


def test_the_withheld_benchs_holes_are_also_counted_in_the_ground_the_last_bench_drilled():
    """Each bench is drilled 20 m further east than the one above: holding the last bench holds every hole under
    its drilling and none beyond it, and the counts in drilled ground say so where the total cannot."""
    import pandas as pd

    from core.io.blastholes import blastholes_from_table

    def bench(k: int) -> pd.DataFrame:
        xs, ys = np.meshgrid(np.arange(20.0 * k, 120.0 + 20 * k, 6.0), np.arange(0.0, 60.0, 6.0))
        inside = ys.ravel() < 30  # a contact along the pit: the geozone reaches the new ground
        return pd.DataFrame(
            {"x": xs.ravel(), "y": ys.ravel(), "z": 100.0 - 10 * k, "geozone": np.where(inside, "a", "b")}
        )

    holes = blastholes_from_table(pd.concat([bench(k) for k in range(4)]))
    df = ev.evaluate_geozone(holes, "a", None, references=("nil",))
    assert len(df) == 2  # benches 2 and 3 withheld in turn
    for _, row in df.iterrows():
        k = int(row["bench"])
        on = holes.on_bench(k + 1)
        mine = holes.geozone[on] == "a"
        x = holes.frame.to_input(holes.xy[on])[:, 0]
        beyond = x > 20 * k + 114 + 0.75 * 6.0  # past the discs of the last bench's easternmost holes
        assert 0 < (mine & beyond).sum() < mine.sum()
        assert row["holes_geozone"] == mine.sum()
        assert row["drilled_holes_geozone"] == (mine & ~beyond).sum()
        assert row["drilled_holes_in_geozone"] == row["drilled_holes_geozone"]  # held where it was drilled
        assert row["drilled_holes_in"] == row["drilled_holes_in_geozone"]
        assert row["holes_in_geozone"] == row["drilled_holes_in_geozone"]  # and nothing beyond


def test_the_references_on_a_table_of_two_pits_km_apart_score_as_on_one(small_mine):
    """A reference is worth beating only at its best: its grid was 240 cells across the table, 11 m cells on the
    same pit twice, 2.5 km apart, and linear extrapolation of the signed distance scored 0.83 F1 there against 0.95
    on the pit alone (the demo twice, 3 km apart: 7.9 points lost a bench below). Its cells are now at most a
    quarter of a hole spacing (half of one here, at 1,200 cells across), and the two pits score as one."""
    import pandas as pd
    import shapely
    from shapely import affinity

    mine, holes, truth, contours = small_mine
    assert (
        ev.reference_grid(holes.xy, holes.hole_spacing_m).cell_size_m == ev.default_grid([holes.xy]).cell_size_m
    )  # a small pit's: kept
    table = sample_blastholes(mine, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        two = blastholes_from_table(pd.concat([table, table.assign(x=table["x"] + 2500.0)], ignore_index=True))
        contours_two = extract_contours(two, ["g1"])
    assert (
        ev.reference_grid(two.xy, two.hole_spacing_m).cell_size_m <= 0.5 * two.hole_spacing_m
    )  # 1,200 cells across at most
    west = ev.truth_from_mine(mine, two.frame)

    def truth_two(geozone, z):
        return shapely.union(west(geozone, z), affinity.translate(west(geozone, z), 2500.0, 0.0))

    def linear_f1(h, cs, t, grid=None):
        nothing = lambda known, geozone, zs: {z: MultiPolygon() for z in zs}  # noqa: E731  (not compared here)
        rows = ev.evaluate_geozone(h, "g1", nothing, truth=t, contours=cs, references=("linear",), grid=grid)
        linear = rows[rows["method"] == "linear"]
        right = (linear["precision"] * linear["p_area"]).sum()
        return 2 * right / (linear["p_area"].sum() + linear["g_area"].sum())

    one = linear_f1(holes, contours, truth)
    assert linear_f1(two, contours_two, truth_two) == pytest.approx(one, abs=0.01)
    assert linear_f1(two, contours_two, truth_two, ev.default_grid([two.xy])) < one - 0.05  # as it was scored
