"""Where to sample next: the uncertainty band of a predicted section and the holes suggested to pin it down."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import shapely
from clirun import bgm
from conftest import straight_contacts
from shapely.geometry import box

from core.geometry.grid import Grid
from core.model.fields import bench_fields
from core.model.sampling import estimate_pattern, lay_out, revealed_field, suggest_holes
from core.model.uncertainty import (
    PLACEMENT_SPACINGS,
    Backtest,
    backtest,
    band_width_m,
    fit_scale,
    section_uncertainty,
    true_boundary_sigma,
    z_score,
)

SPACING_M = 5.0
HEIGHT_M = 10.0
BENCHES = 6
SIDE_M = 160.0


def strip_fields(offsets_m):
    """Fields of a strip 30 m wide crossing the pit north-south, its west edge at ``20 + offset`` m on each bench."""
    grid = Grid.covering((0.0, 0.0, SIDE_M, SIDE_M), SPACING_M / 2, margin_cells=4)
    regions = {k: box(50.0 + dx, -50.0, 80.0 + dx, SIDE_M + 50.0) for k, dx in enumerate(offsets_m)}
    drilled = {k: grid.rasterize(box(0.0, 0.0, SIDE_M, SIDE_M)) for k in regions}
    z = {k: 1000.0 - HEIGHT_M * k for k in regions}
    return bench_fields(regions, drilled, z, grid, SPACING_M, 3 * SPACING_M)


STEADY = [3.0 * k for k in range(BENCHES)]  # 3 m east per bench: a steady dip
REVERSING = [8.0 * (k % 2) for k in range(BENCHES)]  # 8 m east, 8 m back, every bench


def next_section(offsets):
    fields = strip_fields(offsets)
    return section_uncertainty(fields, float(fields.z_m[-1] - HEIGHT_M), SPACING_M, 0.9)


def pattern_holes(offset=(0.0, 0.0)):
    """A staggered 5 x 4.5 m pattern over the pit, rows along x."""
    rows = np.arange(2.0, SIDE_M - 2, 4.5)
    holes = [(x + (2.5 if i % 2 else 0.0), y) for i, y in enumerate(rows) for x in np.arange(2.0, SIDE_M - 4, 5.0)]
    return np.array(holes) + np.asarray(offset)


def test_a_steadily_dipping_strip_gets_a_narrow_band_that_holds_its_next_bench():
    section = next_section(STEADY)
    width = band_width_m(section)
    assert width < 2.5 * SPACING_M
    # The strip carries on: its west edge at 68 m on the next bench lies in the band, and the band is about it.
    truth = np.column_stack([np.full(20, 68.0), np.linspace(20, 140, 20)])
    assert section.in_band(truth).all()
    assert section.scale.source == "own backtest"


def test_movement_that_reverses_every_bench_gets_a_wide_band():
    narrow = band_width_m(next_section(STEADY))
    wide = band_width_m(next_section(REVERSING))
    assert wide > 2 * narrow
    # Either way the movement goes next, the edge stays in the band.
    section = next_section(REVERSING)
    for west in (50.0, 58.0):
        assert section.in_band(np.column_stack([np.full(10, west), np.linspace(20, 140, 10)])).all()


def test_probability_inside_is_one_half_on_the_predicted_boundary_and_runs_from_0_to_1():
    section = next_section(REVERSING)
    f, s, p = section.at(np.array([[30.0, 80.0], [10.0, 80.0], [70.0, 80.0]]))
    assert p[1] < 0.05 and p[2] > 0.95
    assert section.inner.within(section.predicted.buffer(1e-6))
    assert section.predicted.within(section.outer.buffer(1e-6))


@pytest.mark.parametrize("offsets", [STEADY, REVERSING], ids=["steady", "reversing"])
def test_suggestions_fall_in_the_band_not_deep_inside_or_far_outside(offsets):
    section = next_section(offsets)
    candidates = pattern_holes()
    chosen = suggest_holes({"strip": section}, candidates, 12, SPACING_M)
    assert len(chosen) == 12
    xy = np.array([c.xy_m for c in chosen])
    assert section.in_band(xy).all()
    assert all(0.02 < c.probability_inside < 0.98 for c in chosen)
    # Spread along both edges, not piled up next to each other.
    assert np.ptp(xy[:, 1]) > SIDE_M / 2
    west = xy[:, 0] < np.mean(section.predicted.bounds[::2])
    assert 0 < west.sum() < len(xy)


def test_no_hole_is_suggested_where_no_candidate_lies_in_a_band():
    """Holes far from any band (a geozone predicted absent where they can go) would tell what is known already."""
    section = next_section(REVERSING)
    candidates = pattern_holes()
    band = section.as_observed().in_band(candidates)  # the band of the labels the holes would give
    away = candidates[~band]
    assert len(away) > 20
    assert suggest_holes({"strip": section}, away, 5, SPACING_M) == []
    # One candidate in the band among them: it is suggested, and the budget's others after it.
    with_one = np.vstack([away, candidates[band][:1]])
    chosen = suggest_holes({"strip": section}, with_one, 5, SPACING_M)
    assert len(chosen) == 5 and chosen[0].candidate == len(away)


def test_a_geozone_predicted_absent_gets_no_holes_said_to_be_near_its_contact():
    """Its scale at the distance cap, a band covered the whole bench: every hole was "in the band, 41 m from
    predicted contact" (the cap), of a contact that is not there."""
    import dataclasses

    section = next_section(REVERSING)
    cap = float(np.abs(section.field).max())
    absent = dataclasses.replace(section, field=np.full_like(section.field, -cap), sigma=section.sigma + cap)
    absent = dataclasses.replace(absent, observed_sigma=absent.sigma)
    candidates = pattern_holes()
    assert absent.in_band(candidates).all()  # the band itself still holds everywhere a body may appear
    assert suggest_holes({"pod": absent}, candidates, 10, SPACING_M) == []
    # Beside a geozone with a contact, all the budget goes to that one.
    chosen = suggest_holes({"pod": absent, "strip": section}, candidates, 10, SPACING_M)
    assert len(chosen) == 10 and {c.geozone for c in chosen} == {"strip"}
    assert section.has_contact and not absent.has_contact


def test_suggestions_tell_the_band_and_probability_the_files_hold():
    """A hole said to lie in the 90% band lies in the band of uncertainty.geojson and the map, its P(inside) p_inside's.

    Holes are chosen on the wider observed scale: those in its band but outside the written one were told "boundary band".
    """
    section = next_section(REVERSING)
    candidates = pattern_holes()
    observed = section.as_observed().in_band(candidates)
    assert observed.sum() > section.in_band(candidates).sum()  # the two bands differ here: the test means something
    chosen = suggest_holes({"strip": section}, candidates, int(observed.sum()), SPACING_M)
    xy = np.array([c.xy_m for c in chosen])
    assert [c.in_band for c in chosen] == section.in_band(xy).tolist()
    np.testing.assert_allclose([c.probability_inside for c in chosen], section.at(xy)[2])
    # Still chosen on the observed scale: every hole of its band first.
    assert section.as_observed().in_band(xy).all()


def test_several_geozones_share_one_budget():
    # Two equally unsure geozones in different places: the budget is split between them.
    sections = {"west": next_section(REVERSING), "east": next_section([60.0 + dx for dx in REVERSING])}
    chosen = suggest_holes(sections, pattern_holes(), 10, SPACING_M)
    assert len(chosen) == 10
    counts = {g: sum(c.geozone == g for c in chosen) for g in sections}
    assert min(counts.values()) >= 3, counts
    # A sure geozone beside an unsure one: the holes go where they narrow a band most.
    sections = {"steady": next_section(STEADY), "reversing": next_section(REVERSING)}
    chosen = suggest_holes(sections, pattern_holes(), 10, SPACING_M)
    assert len(chosen) == 10
    assert sum(c.geozone == "reversing" for c in chosen) > sum(c.geozone == "steady" for c in chosen)


def test_a_planned_pattern_is_respected():
    rng = np.random.default_rng(3)
    planned = pattern_holes()[rng.random(len(pattern_holes())) < 0.6]
    chosen = suggest_holes({"strip": next_section(REVERSING)}, planned, 15, SPACING_M)
    picked = np.array([c.xy_m for c in chosen])
    assert len({c.candidate for c in chosen}) == 15
    np.testing.assert_array_equal(picked, planned[[c.candidate for c in chosen]])


def test_the_pattern_of_a_bench_is_recovered_and_laid_out_again():
    angle = np.radians(30.0)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    xy = pattern_holes() @ rot.T + np.random.default_rng(0).normal(0, 0.2, (len(pattern_holes()), 2))
    pattern = estimate_pattern(xy)
    # A staggered pattern is a lattice that more than one row direction describes; its area per hole is its own.
    assert pattern.spacing_m * pattern.burden_m == pytest.approx(5.0 * 4.5, rel=0.08)
    assert min(pattern.spacing_m, pattern.burden_m) == pytest.approx(4.5, abs=0.4)
    area = shapely.MultiPoint(xy).convex_hull.buffer(-2.0)
    again = lay_out(pattern, area)
    assert len(again) == pytest.approx(np.sum(shapely.contains_xy(area, xy[:, 0], xy[:, 1])), rel=0.1)
    # Laid out again, the holes fall on the bench's holes (within the jitter), not between them.
    from scipy.spatial import cKDTree

    assert np.median(cKDTree(xy).query(again)[0]) < 1.0


def test_the_pattern_of_holes_collared_off_it_is_still_its_own():
    """Holes 0.3 of a spacing off a 5 x 4.5 m pattern: the nearest neighbours' steps (3 m) are not the lattice."""
    xy = pattern_holes() + np.random.default_rng(0).normal(0, 0.3 * 5.0, (len(pattern_holes()), 2))
    pattern = estimate_pattern(xy)
    assert pattern.spacing_m * pattern.burden_m == pytest.approx(5.0 * 4.5, rel=0.1)
    assert min(pattern.spacing_m, pattern.burden_m) == pytest.approx(4.5, rel=0.15)


def test_a_single_row_of_holes_gets_a_square_pattern_along_it():
    """A bench drilled as one row (a trench, a ramp): its least squares fix no step across, which was singular."""
    angle = np.radians(20.0)
    xy = np.column_stack([np.cos(angle), np.sin(angle)]) * np.arange(40.0)[:, None] * 6.0
    xy += np.random.default_rng(1).normal(0, 0.1, xy.shape)
    pattern = estimate_pattern(xy)
    assert pattern.spacing_m == pytest.approx(6.0, rel=0.05) and pattern.burden_m == pytest.approx(6.0, rel=0.05)


def test_revealed_labels_pull_the_section_to_the_truth():
    section = next_section(REVERSING)  # holds the last bench: the west edge at 58 m; it goes back to 50 m
    xy = pattern_holes()
    truth_inside = (xy[:, 0] > 50.0) & (xy[:, 0] < 80.0)
    near = np.abs(xy[:, 0] - 54.0) < 6.0
    probe = np.array([[55.5, 80.0], [46.0, 80.0], [65.0, 80.0]])  # among the revealed holes inside; outside; inside
    before = section.grid.sample(section.field, probe)
    after = section.grid.sample(revealed_field(section, xy[near], truth_inside[near], SPACING_M), probe)
    assert before[0] < 0 < after[0]  # now inside, as it is
    assert after[1] < 0 < after[2]  # and the rest of the section where it was


# --------------------------------------------------------------------------- command line


@pytest.fixture(scope="module")
def strip_csv(tmp_path_factory):
    """A small pit: a strip dipping steadily east under host rock, on staggered 5 x 4.5 m patterns."""
    rows = []
    for k, dx in enumerate(STEADY):
        for i, (x, y) in enumerate(pattern_holes()):
            label = "ore" if 50.0 + dx <= x <= 80.0 + dx else "host"
            rows.append((f"b{k}h{i}", 400_000.0 + x, 7_000_000.0 + y, 1000.0 - HEIGHT_M * k, label))
    path = tmp_path_factory.mktemp("strip") / "strip.csv"
    pd.DataFrame(rows, columns=["hole_id", "x", "y", "z", "geozone"]).to_csv(path, index=False)
    return path


def test_suggest_writes_budget_rows_in_input_coordinates(strip_csv, tmp_path):
    out = tmp_path / "s.csv"
    run = bgm("suggest", strip_csv, "--geozone", "ore", "--budget", "8", "--out", out)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["suggested"] == 8 and summary["z"] == pytest.approx(940.0)
    table = pd.read_csv(out)
    assert list(table.columns) == ["x", "y", "z", "geozone", "probability_inside", "reason"]
    assert len(table) == 8 and (table["z"] == 940.0).all()
    # Next to the strip's edges as they will be at 940 (68 and 98 m east of the origin), in mine coordinates.
    east = table["x"] - 400_000.0
    assert (np.minimum(np.abs(east - 68.0), np.abs(east - 98.0)) < 3 * SPACING_M).all()
    assert table["probability_inside"].between(0, 1).all() and table["reason"].str.contains("band").all()


def test_suggest_picks_from_a_planned_pattern(strip_csv, tmp_path):
    planned = pd.DataFrame(pattern_holes((1.0, 1.0)) + [400_000.0, 7_000_000.0], columns=["X", "Y"])
    planned.insert(0, "hole_id", [f"p{i}" for i in range(len(planned))])
    planned["Z"] = 935.0
    path = tmp_path / "planned.csv"
    planned.to_csv(path, index=False)
    out = tmp_path / "s.csv"
    run = bgm("suggest", strip_csv, "--geozone", "ore,host", "--budget", "6", "--pattern", path, "--out", out)
    assert run.returncode == 0, run.stderr
    table = pd.read_csv(out)
    assert len(table) == 6 and (table["z"] == 935.0).all()
    merged = table.merge(planned, left_on="pattern_hole", right_on="hole_id")
    assert len(merged) == 6
    np.testing.assert_allclose(merged[["x", "y"]].to_numpy(), merged[["X", "Y"]].to_numpy())


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--budget", "0"], "--budget must be 1 or more"),
        (["--budget", "3", "--elevation", "1000"], "not below the deepest bench"),
        (["--budget", "3", "--elevation", "949.99999"], "elevation 949.99999 is the deepest bench's level (950 m)"),
        (["--budget", "3", "--elevation", "500"], "bench heights below the deepest bench"),
        (["--budget", "3", "--band-probability", "1.5"], "--band-probability"),
        (["--budget", "3", "--geozone", "nope"], "nope"),
    ],
)
def test_suggest_bad_input_gets_one_line_and_exit_2(strip_csv, tmp_path, extra, message):
    run = bgm("suggest", strip_csv, "--geozone", "ore", *extra, "--out", tmp_path / "s.csv")
    assert run.returncode == 2
    assert message in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "s.csv").exists()


@pytest.mark.parametrize(
    "content, message",
    [("a,b\n1,2\n", "no x column"), ("x,y\n1,2\nfoo,3\n", "non-numeric"), ("x,y\n", "no holes")],
)
def test_suggest_bad_pattern_gets_one_line_and_exit_2(strip_csv, tmp_path, content, message):
    path = tmp_path / "planned.csv"
    path.write_text(content)
    run = bgm("suggest", strip_csv, "--geozone", "ore", "--budget", "3", "--pattern", path, "--out", tmp_path / "s.csv")
    assert run.returncode == 2, run.stderr
    assert message in run.stderr and len(run.stderr.strip().splitlines()) <= 2


def test_predict_writes_bands_and_probability_grid_beside_its_output(strip_csv, tmp_path):
    out = tmp_path / "p.geojson"
    run = bgm("predict", strip_csv, "--geozone", "ore", "--elevations", "945,940,975", "--out", out)
    assert run.returncode == 0, run.stderr
    predicted = json.loads(out.read_text())["features"]
    assert {tuple(sorted(f["properties"])) for f in predicted} == {("area_m2", "geozone", "units", "z")}
    bands = json.loads((tmp_path / "p.uncertainty.geojson").read_text())["features"]
    kinds = {(f["properties"]["z"], f["properties"]["kind"]) for f in bands}
    assert {(945.0, "band"), (940.0, "inner"), (940.0, "outer"), (975.0, "band")} <= kinds
    grid = np.load(tmp_path / "p.p_inside.npz")
    assert list(grid["z"]) == [945.0, 940.0, 975.0]
    assert grid["p_inside"].shape == (3, len(grid["y"]), len(grid["x"]))
    # Inside the strip's predicted position at 940 (68-98 m east) and outside it.
    col = lambda east: int(np.argmin(np.abs(grid["x"] - 400_000.0 - east)))  # noqa: E731
    row = int(np.argmin(np.abs(grid["y"] - 7_000_080.0)))
    assert grid["p_inside"][1, row, col(83.0)] > 0.9 > 0.1 > grid["p_inside"][1, row, col(30.0)]


def test_a_prediction_only_at_benches_still_writes_every_array_of_the_probability_grid(strip_csv, tmp_path):
    """At a bench level the section is the bench's contours, with no uncertainty: the grid has no level,
    and a reader still finds ``p_inside`` (it found no array at all)."""
    out = tmp_path / "p.geojson"
    run = bgm("predict", strip_csv, "--geozone", "ore", "--elevations", "990", "--out", out)
    assert run.returncode == 0, run.stderr
    grid = np.load(tmp_path / "p.p_inside.npz")
    assert grid["p_inside"].shape == (0, 0, 0) and len(grid["z"]) == 0 and str(grid["geozone"]) == "ore"


def test_predict_interrupted_while_computing_the_bands_leaves_its_three_files_as_they_were(
    strip_csv, tmp_path, monkeypatch
):
    """The prediction was written before the bands were computed (seconds of backtests): an interrupt
    then left a new prediction beside the old bands. Nothing is written until all three are computed."""
    from typer.testing import CliRunner

    import core.model.uncertainty as uncertainty
    from core.cli import app

    out = tmp_path / "p.geojson"
    args = ["predict", str(strip_csv), "--geozone", "ore", "--elevations", "945", "--out", str(out), "--no-cache"]
    assert CliRunner().invoke(app, args).exit_code == 0
    files = [out, tmp_path / "p.uncertainty.geojson", tmp_path / "p.p_inside.npz"]
    before = [f.read_bytes() for f in files]

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(uncertainty, "geozone_uncertainty", interrupted)
    args[args.index("945")] = "940"
    assert CliRunner().invoke(app, args).exit_code != 0
    assert [f.read_bytes() for f in files] == before


def test_evaluate_interrupted_while_plotting_leaves_its_tables_as_they_were(strip_csv, tmp_path, monkeypatch):
    """The tables were written, then the plot drawn: an interrupt while drawing left new tables beside an
    old plot. The plot is drawn first."""
    from typer.testing import CliRunner

    import core.model.evaluation as evaluation
    from core.cli import app

    out = tmp_path / "eval"
    args = ["evaluate", str(strip_csv), "--geozone", "ore", "--out", str(out)]
    assert CliRunner().invoke(app, args).exit_code == 0
    tables = [out / "evaluation_rows.csv", out / "evaluation.csv"]
    for t in tables:
        t.write_text("an earlier evaluation")

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(evaluation, "plot_precision_recall", interrupted)
    assert CliRunner().invoke(app, args).exit_code != 0
    assert [t.read_text() for t in tables] == ["an earlier evaluation"] * 2


def test_predict_starts_without_the_surface_library(strip_csv, tmp_path):
    # trimesh takes most of a second to import: only commands that write surfaces load it.
    probe = "import atexit, sys; atexit.register(lambda: print('trimesh loaded:', 'trimesh' in sys.modules)); "
    env = {**os.environ, "BGM_CACHE_DIR": str(tmp_path / "cache")}

    def loaded(*args) -> bool:
        code = probe + "from core.cli import main; main()"
        run = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, env=env)
        assert run.returncode == 0, run.stderr
        return "trimesh loaded: True" in run.stdout

    assert not loaded("predict", strip_csv, "--geozone", "ore", "--elevations", "940", "--out", tmp_path / "p.geojson")
    assert loaded("build", "--help")  # build imports it up front, with Ctrl-C held (see core.cli)


def test_the_band_is_about_the_true_boundary_not_the_holes_placement_of_it():
    # Backtest errors against extracted boundaries = the prediction's error against the true one plus
    # where holes 6 m apart placed it. Calibrated on those, then the placement taken out, the 90% band
    # holds about 90% of the true errors; the calibrated scale alone holds more.
    rng = np.random.default_rng(3)
    spacing, n = 6.0, 20000
    true_error = rng.normal(0.0, 2.0, n)
    observed = true_error + rng.normal(0.0, PLACEMENT_SPACINGS * spacing, n)
    terms = np.column_stack([np.full(n, spacing), np.zeros((n, 4))])
    one = np.ones(n, int)
    scale = fit_scale(Backtest(observed, terms, np.arange(n) % 5, one, 2 * one), 0.9)
    sigma = scale.sigma(terms)
    half = z_score(0.9) * true_boundary_sigma(sigma, spacing, cap_m=1e3, probability=0.9)
    assert abs(np.mean(np.abs(true_error) <= half) - 0.9) < 0.02
    assert np.mean(np.abs(true_error) <= z_score(0.9) * sigma) > 0.93
    # Never below the placement of the benches the prediction rests on; a band reaching the cap stays.
    floor = PLACEMENT_SPACINGS * spacing
    assert true_boundary_sigma(np.array([0.5]), spacing, 1e3, 0.9)[0] == pytest.approx(floor)
    assert true_boundary_sigma(np.array([30.0]), spacing, 40.0, 0.9)[0] == 30.0


def test_the_placement_taken_out_is_where_extraction_puts_a_straight_boundary():
    # Straight boundaries at random offsets and headings through a staggered 6 m pattern (holes 0.08
    # of a spacing off it): the contour's distance to the true line, as a standard deviation in
    # spacings. Uniform between two holes would be 0.29. A straight boundary is the easiest one: the
    # placement the band takes out (the families' curved sections', whose contour points lie 0.20
    # spacings from the true boundary) is well above it: 0.08 here, 0.13 when contours were smoothed
    # over half a spacing only.
    offsets = [offset for _, _, offset in straight_contacts(5, 8)]
    measured = float(np.sqrt(np.mean(np.square(np.concatenate(offsets)))))
    assert 0.3 * PLACEMENT_SPACINGS < measured < 0.6 * PLACEMENT_SPACINGS, measured


def test_an_upward_backtest_predicts_each_bench_from_the_benches_below_it_only():
    # Between benches the band also rests on extrapolating upwards; its calibration must not see the bench it predicts.
    fields = strip_fields(REVERSING).reversed()
    assert list(fields.through(970.0).z_m) == [950.0, 960.0, 970.0]
    up = backtest(fields, HEIGHT_M, SPACING_M)
    down = backtest(strip_fields(REVERSING), HEIGHT_M, SPACING_M)
    # The strip moves 8 m every bench: predicted from one side, a bench is missed by metres, either way.
    assert np.median(np.abs(up.error_m)) > 2.0
    assert np.median(np.abs(up.error_m)) == pytest.approx(np.median(np.abs(down.error_m)), rel=0.25)


def test_half_way_between_benches_the_band_holds_the_boundary_narrower_than_from_one_side():
    fields = strip_fields(STEADY)  # west edge at 50 + 3k m on bench k
    z = 1000.0 - 2.5 * HEIGHT_M  # half-way between benches 2 and 3: the edge at 57.5 m
    section = box(57.5, -50.0, 87.5, SIDE_M + 50.0)  # what the trajectories give there
    between = section_uncertainty(fields, z, SPACING_M, 0.9, region=section)
    below = section_uncertainty(fields.through(980.0), z, SPACING_M, 0.9)  # bench 2 the deepest known
    edge = np.column_stack([np.full(20, 57.5), np.linspace(20, 140, 20)])
    assert between.in_band(edge).all()
    # Two benches' placement errors partly cancel half-way: less than a one-sided band's floor.
    assert band_width_m(between) < 0.8 * band_width_m(below)
    assert band_width_m(between) < 2 * z_score(0.9) * PLACEMENT_SPACINGS * SPACING_M


def test_the_band_width_between_upper_benches_is_measured_where_they_were_drilled():
    """In a pit narrowing with depth, a section between upper benches has no boundary in the deepest bench's
    drilled area: ``bgm predict`` wrote its band width as null (Kennecott's 3310 at 540 and 490 ft)."""
    from types import SimpleNamespace

    from core.io.blastholes import LocalFrame
    from core.io.uncertainty_export import band_features

    fields = strip_fields(STEADY)
    z = 1000.0 - 0.5 * HEIGHT_M  # between benches 0 and 1: the west edge at 51.5 m
    section = section_uncertainty(fields, z, SPACING_M, 0.9, region=box(51.5, -50.0, 81.5, SIDE_M + 50.0))
    pit = box(0.0, 0.0, SIDE_M, SIDE_M)
    areas = dict.fromkeys(range(BENCHES), pit) | {BENCHES - 1: box(90.0, 0.0, SIDE_M, SIDE_M)}  # east of its west edge
    holes = SimpleNamespace(
        frame=LocalFrame(0.0, 0.0), bench_levels_m=fields.z_m, n_benches=BENCHES, drilled_area=areas.__getitem__
    )
    (width,) = {f["properties"]["band_width"] for f in band_features({z: section}, holes, "strip")}
    assert width == pytest.approx(band_width_m(section, pit), rel=1e-3)
    # Below the benches it is still measured in the deepest bench's area, as the build's report measures it.
    below = next_section(STEADY)
    (width,) = {f["properties"]["band_width"] for f in band_features({below.z_m: below}, holes, "strip")}
    assert width == pytest.approx(band_width_m(below, areas[BENCHES - 1]), rel=1e-3)


def test_the_map_shades_a_band_inside_the_hole_of_another():
    """A ring's band: around its outside an annulus, around its core another one inside the first's hole."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from core.io.uncertainty_export import shade_polygons

    def annulus(r_out, r_in):
        return shapely.Point(0, 0).buffer(r_out).difference(shapely.Point(0, 0).buffer(r_in))

    fig = Figure(figsize=(4, 4), dpi=50)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    shade_polygons(ax, shapely.MultiPolygon([annulus(10, 4), annulus(50, 40)]), color="red", lw=0)
    ax.set_xlim(-55, 55)
    ax.set_ylim(-55, 55)
    canvas.draw()
    pixels = np.asarray(canvas.buffer_rgba())

    def colour(x, y):
        col, row = ax.transData.transform((x, y))
        return tuple(pixels[int(pixels.shape[0] - row), int(col), :3])

    assert colour(7, 0) == colour(45, 0) == (255, 0, 0)  # both bands shaded
    assert colour(0, 0) == colour(25, 0) == (255, 255, 255)  # the core and the ring itself open


def test_the_geozones_of_one_suggestion_are_modelled_several_at_once_as_one_by_one():
    """`bgm suggest` models its geozones on threads: the same bands and holes as each modelled alone."""
    from conftest import synthetic

    from core.model.parameters import ModelParameters
    from core.model.sampling import plan_sampling
    from core.model.session import ModelSession, StageStore
    from core.model.uncertainty import geozone_uncertainty

    _, _, holes = synthetic(4)
    geozones = list(holes.geozones)[1:3]  # two at once show it as well as four (and take half the time)
    z = float(holes.bench_levels_m[-1]) - float(holes.bench_height_m)

    def fresh() -> ModelSession:
        return ModelSession(holes, ModelParameters(), None, StageStore(None))

    alone = fresh()
    sections = {g: geozone_uncertainty(alone, g, [z])[z] for g in geozones}
    sections = {g: s for g, s in sections.items() if s is not None}
    together = plan_sampling(fresh(), geozones, 12, z)
    assert len(sections) >= 2 and together.sections.keys() == sections.keys()
    for g, section in sections.items():
        np.testing.assert_array_equal(together.sections[g].sigma, section.sigma)
        np.testing.assert_array_equal(together.sections[g].field, section.field)
    one_by_one = plan_sampling(fresh(), geozones, 12, z, sections=sections)
    assert together.suggestions and together.suggestions == one_by_one.suggestions


def test_a_pattern_with_decimal_commas_reads_as_the_holes_do(strip_csv, tmp_path):
    """A pattern exported with semicolons and decimal commas, as the blasthole table may be, is read, not refused."""
    planned = pd.DataFrame(pattern_holes((1.0, 1.0)) + [400_000.0, 7_000_000.0], columns=["X", "Y"])
    planned["Z"] = 935.5
    runs = []
    for name, style in (("comma.csv", {}), ("semicolon.csv", {"sep": ";", "decimal": ","})):
        planned.to_csv(tmp_path / name, index=False, **style)
        out = tmp_path / f"s-{name}"
        run = bgm("suggest", strip_csv, "--geozone", "ore", "--budget", "4", "--pattern", tmp_path / name, "--out", out)
        assert run.returncode == 0, run.stderr
        runs.append(pd.read_csv(out))
    pd.testing.assert_frame_equal(runs[0], runs[1])
    assert (runs[1]["z"] == 935.5).all()


def test_a_pattern_spanning_two_benches_is_refused(strip_csv, tmp_path):
    """Two benches' patterns in one file were sampled at the level between them, where no hole is drilled."""
    planned = pd.DataFrame(pattern_holes((1.0, 1.0)) + [400_000.0, 7_000_000.0], columns=["X", "Y"])
    planned["Z"] = np.where(np.arange(len(planned)) % 2, 935.0, 925.0)
    path = tmp_path / "two.csv"
    planned.to_csv(path, index=False)
    out = tmp_path / "s.csv"
    run = bgm("suggest", strip_csv, "--geozone", "ore", "--budget", "3", "--pattern", path, "--out", out)
    assert run.returncode == 2, run.stderr
    assert "collars from 925 to 935 m" in run.stderr and "one bench's pattern" in run.stderr
    assert not out.exists()


def test_a_hole_listed_twice_in_a_planned_pattern_is_suggested_once(strip_csv, tmp_path):
    planned = pd.DataFrame(pattern_holes((1.0, 1.0)) + [400_000.0, 7_000_000.0], columns=["x", "y"])
    planned.insert(0, "hole_id", [f"p{i}" for i in range(len(planned))])
    path = tmp_path / "planned.csv"
    pd.concat([planned, planned.iloc[:20]]).to_csv(path, index=False)  # 20 holes pasted again
    out = tmp_path / "s.csv"
    run = bgm("suggest", strip_csv, "--geozone", "ore", "--budget", "100000", "--pattern", path, "--out", out)
    assert run.returncode == 0, run.stderr
    assert "20 hole(s) at the position of an earlier one" in run.stderr
    table = pd.read_csv(out)
    assert json.loads(run.stdout)["candidates"] == len(planned) == len(table)
    assert not table.duplicated(["x", "y"]).any() and not table["pattern_hole"].duplicated().any()


def test_suggest_says_so_when_no_hole_suggested_lies_in_the_band_it_reports(strip_csv, tmp_path):
    """Planned holes all in the wider band holes are chosen on, none in the written band each row's in_band is:
    holes are suggested with "in_band": 0, and the note says none lies in the 90% band (it said nothing)."""
    from core.io.blastholes import read_blastholes
    from core.model.sampling import plan_sampling
    from core.model.session import ModelSession

    holes = read_blastholes(strip_csv)
    xy = holes.frame.to_local(*(pattern_holes() + [400_000.0, 7_000_000.0]).T)
    z = float(holes.frame.z_to_local(940.0))
    section = plan_sampling(ModelSession.open(holes), ["ore"], 1, z, xy).sections["ore"]
    beyond = section.as_observed().in_band(xy) & ~section.in_band(xy)
    assert beyond.sum() >= 3  # the two bands differ here: the test means something
    path = tmp_path / "planned.csv"
    pd.DataFrame(holes.frame.to_input(xy[beyond]), columns=["x", "y"]).to_csv(path, index=False)
    out = tmp_path / "s.csv"
    run = bgm("suggest", strip_csv, "--geozone", "ore", "--budget", "3", "--pattern", path, "--out", out)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["suggested"] == 3 and summary["in_band"] == 0
    assert "no candidate hole lies in the 90% band of ore's predicted boundary" in run.stderr
    assert pd.read_csv(out)["reason"].str.startswith("beyond the 90% band").all()


def test_an_elevation_given_twice_is_one_level_in_every_file(strip_csv, tmp_path):
    """615,615 (or 615 and 615.0000001) wrote two identical predicted features beside one band and one grid level."""
    out = tmp_path / "p.geojson"
    run = bgm("predict", strip_csv, "--geozone", "ore", "--elevations", "945,940,945,940.0000001", "--out", out)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["elevations"] == [945.0, 940.0]
    assert "945, 940 more than once" in run.stderr
    assert [f["properties"]["z"] for f in json.loads(out.read_text())["features"]] == [945.0, 940.0]
    bands = json.loads((tmp_path / "p.uncertainty.geojson").read_text())["features"]
    assert sorted(f["properties"]["z"] for f in bands if f["properties"]["kind"] == "band") == [940.0, 945.0]
    assert list(np.load(tmp_path / "p.p_inside.npz")["z"]) == [945.0, 940.0]


def test_the_suggest_note_leaves_out_the_band_of_a_geozone_predicted_absent():
    """Its band covers the bench, so every candidate lay "in the band": holes all beyond the strip's band were
    said to be "none of the suggested" rather than that no candidate lies in a band around a contact."""
    import dataclasses

    from core.cli import _outside_band_note
    from core.model.sampling import SamplingPlan

    section = next_section(REVERSING)
    cap = float(np.abs(section.field).max())
    absent = dataclasses.replace(section, field=np.full_like(section.field, -cap), sigma=section.sigma + cap)
    candidates = pattern_holes()
    away = candidates[~section.in_band(candidates) & section.as_observed().in_band(candidates)]
    assert len(away) >= 3 and absent.in_band(away).all()
    chosen = suggest_holes({"pod": absent, "strip": section}, away, 3, SPACING_M)
    plan = SamplingPlan(section.z_m, section.probability, away, {"pod": absent, "strip": section}, chosen)
    note = _outside_band_note(plan, ["pod", "strip"])
    assert len(chosen) == 3 and note.startswith("bgm: note: no candidate hole lies in the 90% band of strip's"), note
