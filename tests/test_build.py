"""`bgm build` and `bgm predict` end to end on a small synthetic mine."""

from __future__ import annotations

import json

import ezdxf
import numpy as np
import pandas as pd
import pytest
import trimesh
from conftest import narrowing_pit
from shapely.geometry import shape
from test_cli import bgm

from core.io.atomic import atomic_write_text
from core.io.project import AlignmentOverride, Project, save_project
from core.model.build import truth_sidecar
from core.synthetic.blobs import make_mine, sample_blastholes

SMALL_MINE = {"seed": 5, "n_benches": 4, "extent_m": [200.0, 150.0], "origin": [650_000.0, 7_400_000.0], "n_pods": 1}


@pytest.fixture(scope="module")
def small_mine_csv(tmp_path_factory):
    mine = make_mine(**SMALL_MINE)
    table = sample_blastholes(mine, seed=6)
    path = tmp_path_factory.mktemp("mine") / "small.csv"
    table.to_csv(path, index=False)
    return path, table


@pytest.fixture(scope="module")
def built(small_mine_csv, tmp_path_factory):
    path, _ = small_mine_csv
    out = tmp_path_factory.mktemp("build")
    bgm("build", path, "--out", out)
    return out


@pytest.mark.xdist_group("built")  # one worker builds it once
def test_build_writes_every_output(built):
    summary = json.loads((built / "summary.json").read_text())
    assert [g["geozone"] for g in summary["geozones"]] == ["g0", "g1", "g2", "g3"]
    report = (built / "report.md").read_text()
    assert "precision_recall.png" in report and "| g1 |" in report
    assert (built / "precision_recall.png").stat().st_size > 10_000
    table = pd.read_csv(built / "evaluation.csv")
    assert {"depth_m", "precision_model", "precision_nil", "recall_model", "recall_implicit"} <= set(table.columns)
    for g in ("g1", "g2"):
        for name in ("correspondence.json", "morph.json", "prediction.geojson"):
            assert (built / g / name).exists(), (g, name)
    # How each geozone's prediction carries its benches' movement on below the deepest bench, and what chose it.
    section = report.split("## Below the deepest bench")[1].split("## ")[0]
    for g in summary["geozones"]:
        carried = g["carried"]
        assert carried["way"] in ("agreement", "all", "none") and carried["chosen_by"] == "backtest", g["geozone"]
        wrong = carried["backtest_wrong_area_m2"]
        assert set(wrong) == {"agreement", "all", "none"} and wrong[carried["way"]] == min(wrong.values())
        row = next(line for line in section.splitlines() if line.startswith(f"| {g['geozone']} | "))
        gaps = carried["gaps_filled_narrower_than_m"]  # three spacings where chosen, else none said
        assert row.endswith("|  |" if gaps is None else f"| {gaps:.1f} |"), row


def test_the_next_bench_the_report_samples_has_its_band_in_the_uncertainty_file(small_mine_csv, tmp_path):
    """Benches of uneven height: the deepest pair's gap is not the median one (the bench height). The band
    at the level the report's suggestions are for is written, its width is the report's, and the prediction
    a bench below the deepest is at that level too."""
    path, table = small_mine_csv
    table = table.copy()
    deepest = table["z"] < table["z"].min() + 4.0  # the deepest bench (10 m benches)
    table.loc[deepest, "z"] += 2.0  # the last pair 2 m shorter than the others
    uneven = tmp_path / "uneven.csv"
    table.to_csv(uneven, index=False)
    bgm("build", uneven, "--out", tmp_path / "out", "--geozone", "g1")
    sampling = next(g for g in json.loads((tmp_path / "out" / "summary.json").read_text())["geozones"])["sampling"]
    bands = json.loads((tmp_path / "out" / "g1" / "uncertainty.geojson").read_text())["features"]
    at = [f["properties"] for f in bands if np.isclose(f["properties"]["z"], sampling["z"])]
    assert at, (sampling["z"], sorted({f["properties"]["z"] for f in bands}))
    assert np.isclose(at[0]["band_width"], sampling["band_width"], rtol=1e-3)
    # One next bench: the prediction a bench below the deepest is where the suggestions and their band are,
    # a bench height (the median gap) down, not the deepest pair's shorter gap (two levels 2 m apart).
    predicted = json.loads((tmp_path / "out" / "g1" / "prediction.geojson").read_text())["features"]
    one_bench = {f["properties"]["z"] for f in predicted if f["properties"]["fraction_below"] == 1.0}
    assert one_bench and all(np.isclose(z, sampling["z"]) for z in one_bench), (one_bench, sampling["z"])


@pytest.mark.xdist_group("built")  # one worker builds it once
def test_contours_and_predictions_open_as_3d_polylines_in_mine_software(built):
    """The DXF strings hold the GeoJSON's rings vertex for vertex, closed, at their bench elevation."""
    features = json.loads((built / "contours.geojson").read_text())["features"]
    lines = ezdxf.readfile(built / "contours.dxf").modelspace().query("POLYLINE")
    rings = [
        r
        for f in features
        for p in getattr(shape(f["geometry"]), "geoms", [shape(f["geometry"])])
        for r in (p.exterior, *p.interiors)
    ]
    assert len(lines) == len(rings) > 0
    line, ring, feature = lines[0], rings[0], features[0]
    points = [tuple(p) for p in line.points()]
    assert line.is_closed and line.is_3d_polyline and line.dxf.layer == feature["properties"]["geozone"]
    assert [p[:2] for p in points] == list(ring.coords)[:-1]  # exact: shortest round-trip floats
    assert {p[2] for p in points} == {feature["properties"]["bench"]}
    predicted = json.loads((built / "g1" / "prediction.geojson").read_text())["features"]
    below = ezdxf.readfile(built / "g1" / "prediction.dxf").modelspace().query("POLYLINE")
    assert {round(p[2], 3) for line in below for p in line.points()} == {f["properties"]["z"] for f in predicted}


@pytest.mark.xdist_group("built")  # one worker builds it once
@pytest.mark.parametrize("geozone", ["g1", "g2"])
def test_surfaces_are_watertight_and_reopen_with_the_same_faces(built, geozone):
    from core.model.surfaces import volume_above

    summary = json.loads((built / "summary.json").read_text())
    info = next(g for g in summary["geozones"] if g["geozone"] == geozone)
    assert info["watertight"] and info["volume"] > 0
    meshes = {fmt: trimesh.load(built / geozone / f"surface.{fmt}", force="mesh") for fmt in ("obj", "ply", "stl")}
    faces = {len(m.faces) for m in meshes.values()}
    assert len(faces) == 1
    n_faces = faces.pop()
    assert meshes["ply"].is_watertight and meshes["ply"].volume > 0
    assert meshes["ply"].volume == pytest.approx(info["volume"], rel=1e-6)
    # Of it, the drilled part: down to the deepest bench, above the bench predicted below it.
    deepest = min(f["properties"]["bench"] for f in json.loads((built / "contours.geojson").read_text())["features"])
    assert 0.5 * info["volume"] < info["volume_drilled"] < info["volume"]
    assert info["volume_drilled"] == pytest.approx(volume_above(meshes["ply"], deepest), rel=1e-6)  # as written
    # Mine-grid coordinates survive in full precision (PLY stores doubles).
    assert meshes["ply"].vertices[:, 1].min() > 7_399_000
    doc = ezdxf.readfile(built / geozone / "surface.dxf")
    assert len(doc.modelspace().query("3DFACE")) == n_faces
    assert {face.dxf.layer for face in doc.modelspace().query("3DFACE")} == {geozone}  # the geozone's layer
    import pyvista

    assert pyvista.read(built / geozone / "surface.vtp").n_cells == n_faces


def test_predict_and_evaluate_on_real_style_columns_in_feet(small_mine_csv, tmp_path):
    _, table = small_mine_csv
    feet = pd.DataFrame(
        {
            "EAST": table.x / 0.3048,
            "NORTH": table.y / 0.3048,
            "RL": table.z / 0.3048,
            "HOLEID": table.hole_id,
            "lookup_domain": table.geozone.str.replace("g", "33"),
        }
    )
    path = tmp_path / "feet.csv"
    feet.to_csv(path, index=False)
    levels = sorted(feet.RL.round(-1).unique())
    below = levels[0] - 16.0  # half a 32.8 ft bench below the deepest
    between = levels[-1] - 16.0
    out = tmp_path / "p.geojson"
    bgm("predict", path, "--geozone", "331", "--elevations", f"{between},{below}", "--out", out)
    data = json.loads(out.read_text())
    zs = [f["properties"]["z"] for f in data["features"]]
    assert zs == pytest.approx([between, below])
    for f in data["features"]:
        geom = shape(f["geometry"])
        assert geom.is_valid and geom.area > 0
        assert f["geometry"]["type"] in ("Polygon", "MultiPolygon")
        # In the input's feet coordinates.
        assert feet.EAST.min() - 200 < geom.centroid.x < feet.EAST.max() + 200
    # The evaluation names each bench by its elevation in feet too (it gave metres), and its depths.
    said = bgm("evaluate", path, "--geozone", "331", "--out", tmp_path / "e").stdout
    rows = pd.read_csv(tmp_path / "e" / "evaluation_rows.csv")
    benches = rows["bench_z"].unique()
    assert len(benches) and all(np.min(np.abs(feet.RL - b)) < 1.0 for b in benches), benches
    assert np.allclose(rows["z_ft"], rows["z_m"] / 0.3048) and np.allclose(rows["depth_ft"], rows["depth_m"] / 0.3048)
    depth_ft = pd.read_csv(tmp_path / "e" / "evaluation.csv")["depth_ft"].item()
    assert depth_ft == pytest.approx(32.8, abs=0.5) and f"{depth_ft:.2f} ft below: model F1" in said, said


def test_evaluate_uses_the_generator_truth_when_the_sidecar_is_there(small_mine_csv, tmp_path):
    path, _ = small_mine_csv
    proc = bgm("evaluate", path, "--geozone", "g1", "--out", tmp_path / "e1")
    assert "next bench holes" in proc.stderr
    assert len(pd.read_csv(tmp_path / "e1" / "evaluation.csv")) == 1  # next bench only
    atomic_write_text(truth_sidecar(path), json.dumps({"generator": "core.synthetic.make_mine", "kwargs": SMALL_MINE}))
    try:
        proc = bgm("evaluate", path, "--geozone", "g1", "--out", tmp_path / "e2")
        assert "synthetic generator" in proc.stderr
        table = pd.read_csv(tmp_path / "e2" / "evaluation.csv")
        assert len(table) == 8  # depths 1/8 .. 8/8 of a bench
        # Against the true sections the model beats holding the last bench at a full bench below.
        deepest = table.iloc[-1]

        def f1(p, r):
            return 2 * p * r / (p + r)

        assert f1(deepest.precision_model, deepest.recall_model) > f1(deepest.precision_nil, deepest.recall_nil)
        truth_sidecar(path).write_text("{not json")
        proc = bgm("evaluate", path, "--geozone", "g1", "--out", tmp_path / "e3", check=False)
        assert proc.returncode == 2 and "truth file" in proc.stderr
    finally:
        truth_sidecar(path).unlink()


def test_a_truth_file_of_another_table_is_refused(small_mine_csv, tmp_path):
    """A generated table moved (or replaced) with its truth file left beside it was scored against another mine."""
    _, table = small_mine_csv
    moved = tmp_path / "moved.csv"
    table.assign(x=table["x"] + 300.0).to_csv(moved, index=False)
    atomic_write_text(truth_sidecar(moved), json.dumps({"generator": "core.synthetic.make_mine", "kwargs": SMALL_MINE}))
    proc = bgm("evaluate", moved, "--geozone", "g1", "--out", tmp_path / "e", check=False)
    assert proc.returncode == 2, proc.stderr
    assert "does not describe" in proc.stderr and "moved.truth.json" in proc.stderr


def test_two_labels_made_alike_for_dxf_keep_one_layer_each_in_every_dxf_of_a_build(small_mine_csv, tmp_path):
    """Labels "ox/sul" and "ox_sul" are both ox_sul in R12: contours.dxf told them apart, the surfaces did not."""
    _, table = small_mine_csv
    labels = {"g1": "ox/sul", "g2": "ox_sul"}
    csv = tmp_path / "relabelled.csv"
    table.assign(geozone=table["geozone"].replace(labels)).to_csv(csv, index=False)
    out = tmp_path / "model"
    bgm("build", csv, "--out", out, "--geozone", "ox/sul,ox_sul")
    summary = json.loads((out / "summary.json").read_text())

    def layers(path):
        return {e.dxf.layer for e in ezdxf.readfile(path).modelspace()}

    lines = iter(ezdxf.readfile(out / "contours.dxf").modelspace().query("POLYLINE"))
    by_geozone: dict[str, set] = {g: set() for g in labels.values()}
    for f in json.loads((out / "contours.geojson").read_text())["features"]:  # the DXF's rings, in order
        polygons = getattr(shape(f["geometry"]), "geoms", [shape(f["geometry"])])
        for _ in range(sum(1 + len(p.interiors) for p in polygons)):
            by_geozone[f["properties"]["geozone"]].add(next(lines).dxf.layer)
    assert all(len(v) == 1 for v in by_geozone.values()) and len(set.union(*by_geozone.values())) == 2
    for g in summary["geozones"]:
        folder = out / g["folder"]
        assert layers(folder / "surface.dxf") == by_geozone[g["geozone"]], g["geozone"]
        assert layers(folder / "prediction.dxf") == by_geozone[g["geozone"]], g["geozone"]


@pytest.mark.xdist_group("built")  # one worker builds it once
def test_a_build_writes_omf_surfaces_in_input_coordinates_where_omf_is_installed(built):
    """The README promises `surface.omf` "too with pip install omf"; the build wrote none."""
    from core.io.export import omf_available

    if not omf_available():
        pytest.skip("optional 'omf' package not installed")
    import warnings

    import omf

    summary = json.loads((built / "summary.json").read_text())
    assert "omf" in summary["formats"]
    for g in summary["geozones"]:
        if not g["files"]:
            continue
        assert g["files"]["omf"] == f"{g['folder']}/surface.omf"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            project = omf.OMFReader(str(built / g["files"]["omf"])).get_project()
        element = project.elements[0]
        ply = trimesh.load(built / g["files"]["ply"], force="mesh", process=False)
        assert project.units == summary["units"] == "m"  # said in the file: a reader takes feet for metres otherwise
        assert element.name == g["geozone"]
        assert np.array_equal(np.asarray(element.geometry.vertices.array), ply.vertices)  # mine grid, float64
        assert np.array_equal(np.asarray(element.geometry.triangles.array), ply.faces)


def test_evaluate_rows_name_their_geozone_as_a_builds_do(small_mine_csv, tmp_path):
    """Evaluated one geozone after another into one folder, nothing in the rows said whose they were."""
    path, _ = small_mine_csv
    for g in ("g1", "g2"):
        bgm("evaluate", path, "--geozone", g, "--out", tmp_path / "e")
        rows = pd.read_csv(tmp_path / "e" / "evaluation_rows.csv")
        assert rows.columns[0] == "geozone" and set(rows["geozone"]) == {g}


def test_a_build_in_feet_gives_its_evaluation_depths_in_feet_in_the_report_and_summary(small_mine_csv, tmp_path):
    """evaluation.csv and `bgm evaluate` gave the depths in feet; report.md and summary.json in metres only."""
    _, table = small_mine_csv
    feet = table.assign(x=table.x / 0.3048, y=table.y / 0.3048, z=table.z / 0.3048)
    path = tmp_path / "feet.csv"
    feet.to_csv(path, index=False)
    out = tmp_path / "model"
    bgm("build", path, "--out", out, "--geozone", "g1")
    depth_ft = pd.read_csv(out / "evaluation.csv")["depth_ft"].tolist()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["units"] == "ft"
    assert [r["depth_ft"] for r in summary["evaluation"]] == pytest.approx(depth_ft)
    report = (out / "report.md").read_text()
    assert "| depth_m | depth_ft | precision_model |" in report
    assert all(f"| {d:.2f} |" in report for d in depth_ft)


def test_a_file_browsers_metadata_does_not_stop_a_rebuild(tmp_path):
    """Finder and Explorer leave .DS_Store or Thumbs.db in a model folder a geologist looked at; anything
    else the build did not write still stops it."""
    from core.errors import BGMInputError
    from core.model.build import check_model_folder

    model = tmp_path / "model"
    model.mkdir()
    (model / "summary.json").write_text(json.dumps({"input": "x.csv", "geozones": []}))
    (model / ".DS_Store").write_bytes(b"\x00\x00\x00\x01Bud1")
    check_model_folder(model)
    browsed = tmp_path / "browsed"
    browsed.mkdir()
    (browsed / "Thumbs.db").write_bytes(b"\xd0\xcf")
    check_model_folder(browsed)
    (model / "notes.txt").write_text("keep me")
    with pytest.raises(BGMInputError, match="notes.txt"):
        check_model_folder(model)


def test_a_geozone_the_deepest_benches_never_drilled_is_predicted_below_the_deepest_bench(tmp_path):
    """A body at the edge of a narrowing pit, seen on the top three benches only: its predictions were made
    below the last bench its pairs reach, between two known benches where it is always absent, so its
    prediction.geojson was empty where `bgm predict` carries it on below the deepest bench."""
    from core.model.build import PREDICTION_FRACTIONS, build
    from core.model.session import ModelSession

    holes = narrowing_pit(gone=False)
    session = ModelSession(holes)
    model = session.geozone_model("wall")
    assert model.pairs[-1].lower < holes.n_benches - 1  # its pairs end above the deepest bench
    zs = [float(holes.bench_levels_m[-1]) - 10.0 * f for f in PREDICTION_FRACTIONS]
    expected = {
        round(float(holes.frame.z_to_input(z)), 3): r.area for z, r in session.predict("wall", zs, model).items()
    }
    assert any(area > 0 for area in expected.values())  # the depth trend carries it on below the deepest bench

    build(holes, tmp_path / "out", geozones=["wall"], formats=("obj",), evaluate=False, workers=1)
    features = json.loads((tmp_path / "out" / "wall" / "prediction.geojson").read_text())["features"]
    written = {f["properties"]["z"]: shape(f["geometry"]).area for f in features}
    assert written and set(written) <= set(expected), (sorted(written), sorted(expected))
    for z, area in written.items():
        assert area == pytest.approx(expected[z], rel=1e-6)


def test_the_report_says_which_geozone_ends_for_want_of_drilling_and_its_surface_reaches_its_predictions(tmp_path):
    """``wall`` ends above the deepest bench because the benches below did not drill its ground: the report
    says so, and its surface runs down to the sections predicted below the deepest bench. ``gone`` ends where
    the benches below drilled its ground and found the host: no note, nothing predicted below."""
    import trimesh

    from core.model.build import build

    holes = narrowing_pit()
    summary = build(holes, tmp_path / "out", geozones=["wall", "gone"], formats=("ply",), evaluate=False, workers=1)
    by_name = {g["geozone"]: g for g in summary["geozones"]}
    assert "bench below drilled 0%" in by_name["wall"]["note"] and "depth trend" in by_name["wall"]["note"]
    assert by_name["gone"]["note"] == ""
    wall = trimesh.load(tmp_path / "out" / by_name["wall"]["folder"] / "surface.ply")
    features = json.loads((tmp_path / "out" / by_name["wall"]["folder"] / "prediction.geojson").read_text())
    assert features["features"]  # predicted below the deepest bench, and the surface gets there
    assert wall.bounds[0][2] <= min(f["properties"]["z"] for f in features["features"]) + 0.01
    gone = json.loads((tmp_path / "out" / by_name["gone"]["folder"] / "prediction.geojson").read_text())
    assert gone["features"] == []
    assert "depth trend" in (tmp_path / "out" / "report.md").read_text()


def test_a_build_without_an_evaluation_says_why(small_mine_csv, tmp_path):
    """On two benches the build wrote no evaluation.csv and report.md no 'Predictive value', without a word of why."""
    _, table = small_mine_csv
    path = tmp_path / "two.csv"
    table[table["z"] > table["z"].max() - 16.0].to_csv(path, index=False)  # the top two of its 10 m benches
    run = bgm("build", path, "--out", tmp_path / "out")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert len(summary["benches"]) == 2 and summary["evaluation"] is None
    assert "three or more benches; this input has 2" in summary["evaluation_note"]
    assert summary["evaluation_note"] in run.stderr
    report = (tmp_path / "out" / "report.md").read_text()
    assert "## Predictive value" in report and "needs three or more benches" in report


@pytest.fixture(scope="module")
def built_in_feet(small_mine_csv, tmp_path_factory):
    """The small mine in feet: a build of g1 and `bgm predict` of it below the deepest bench."""
    _, table = small_mine_csv
    feet = table.assign(x=table.x / 0.3048, y=table.y / 0.3048, z=table.z / 0.3048)
    folder = tmp_path_factory.mktemp("feet")
    path = folder / "feet.csv"
    feet.to_csv(path, index=False)
    bgm("build", path, "--out", folder / "model", "--geozone", "g1")
    below = json.loads((folder / "model" / "g1" / "prediction.geojson").read_text())["features"][0]["properties"]["z"]
    said = bgm("predict", path, "--geozone", "g1", "--elevations", str(below), "--out", folder / "p.geojson").stdout
    (folder / "predict.json").write_text(said)
    return folder


@pytest.mark.xdist_group("built_in_feet")  # one worker builds it once
def test_every_file_of_a_build_or_prediction_in_feet_says_feet(built_in_feet):
    """band_width (feet) in uncertainty.geojson, the GeoJSONs' coordinates and areas, p_inside.npz's x, y, z and
    sigma, and surface.stl.json's offset were in feet with nothing in the file saying so: read as metres."""
    model = built_in_feet / "model"
    for path in [model / "contours.geojson", *(model / "g1").glob("*.geojson"), *built_in_feet.glob("p*.geojson")]:
        data = json.loads(path.read_text())
        assert data["units"] == "ft" and data["features"], path
        assert all(f["properties"]["units"] == "ft" for f in data["features"]), path
    for grid in (model / "g1" / "p_inside.npz", built_in_feet / "p.p_inside.npz"):
        assert str(np.load(grid)["units"]) == "ft", grid
    assert json.loads((model / "g1" / "surface.stl.json").read_text())["units"] == "ft"
    # how far the movement carries on below the deepest bench: feet, bgm predict's the build's
    carried = json.loads((model / "summary.json").read_text())["geozones"][0]["carried"]
    assert carried["movement_per_bench_ft"] and carried["backtest_wrong_area_ft2"]
    assert json.loads((built_in_feet / "predict.json").read_text())["carried"] == carried


def test_how_far_the_movement_carries_on_is_said_in_the_inputs_units():
    """The summary's and ``bgm predict``'s movement a bench and backtest areas: a 3.048 m move is 10 ft, 9.290 m² of
    wrong area 100 ft², each key naming its unit; a geozone with no bench pair says nothing; one line for the viewer."""
    from types import SimpleNamespace

    from core.io.blastholes import LocalFrame
    from core.io.reporting import carried_json, carried_line
    from core.model.extrapolation import CarriedMovement

    feet = SimpleNamespace(frame=LocalFrame(0.0, 0.0, 0.3048, "ft"))
    said = CarriedMovement(
        "all", "backtest", (1.0, 0.5), {"agreement": 18.58, "all": 9.290304, "none": 0.0}, (3.048, 6.096)
    )
    assert carried_json(said, feet) == {
        "way": "all",
        "chosen_by": "backtest",
        "persistence": [1.0, 0.5],
        "movement_per_bench_ft": [10.0, 20.0],
        "backtest_wrong_area_ft2": {"agreement": 200.0, "all": 100.0, "none": 0.0},
        "gaps_filled_narrower_than_ft": None,
    }
    assert carried_json(None, feet) is None and carried_line(None, "ft") == "-"
    assert (
        carried_line(carried_json(said, feet), "ft")
        == "all of it, 10.0 ft a bench (chosen by its own benches' backtest)"
    )
    agreeing_on_none = CarriedMovement("agreement", "backtest", (0.0, 0.0), None, (0.0, 0.0))
    assert carried_line(carried_json(agreeing_on_none, feet), "ft").startswith(
        "as far as its last two moves agree: none of it, 0.0 ft a bench"
    )
    partly = CarriedMovement("agreement", "backtest", (1.0, 0.2), None, (3.048, 3.048))
    assert carried_line(carried_json(partly, feet), "ft").startswith("as far as its last two moves agree, 10.0 ft")
    filling = CarriedMovement("all", "backtest", (1.0, 0.5), None, (3.048, 6.096), 9.144)
    assert carried_json(filling, feet)["gaps_filled_narrower_than_ft"] == 30.0
    assert carried_line(carried_json(filling, feet), "ft").endswith("; gaps under 30.0 ft filled a bench below")
    held = CarriedMovement("none", "three benches", (0.0, 0.0), None, None)
    assert carried_json(held, feet)["backtest_wrong_area_ft2"] is None
    assert carried_line(carried_json(held, feet), "ft").startswith(
        "none of it: the deepest bench held (chosen by three"
    )


def test_a_geologists_file_follows_its_geozone_when_the_folder_is_named_differently(small_mine_csv, tmp_path):
    """Carried by folder name, ``g1/notes.txt`` of a build of g1 alone was put beside g1's folder ``g1-<hash>/`` by a
    build of g1 and G1 (labels that differ in case get distinct folders), in a folder of no geozone; so was
    ``g1-<hash>/notes.txt`` by a later build of g1 alone (``g1/``). It goes by the geozone's label, and the warning
    says where; a geozone not built keeps its folder and its label for the next build."""
    from core.model.build import geozone_folders

    path, table = small_mine_csv
    twins = tmp_path / "twins.csv"
    table.assign(geozone=table.geozone.replace({"g2": "G1"})).to_csv(twins, index=False)
    hashed = geozone_folders(["g1", "G1"])
    out = tmp_path / "model"
    bgm("build", twins, "--out", out, "--geozone", "g1")
    (out / "g1" / "notes.txt").write_text("bench 1180: check the contact")

    proc = bgm("build", twins, "--out", out, "--geozone", "g1,G1")
    assert (out / hashed["g1"] / "notes.txt").read_text() == "bench 1180: check the contact"
    assert not (out / "g1").exists()
    assert (
        f"g1/notes.txt; those of g1/ went into {hashed['g1']}/, the folder of geozone 'g1' in this build" in proc.stderr
    )

    bgm("build", twins, "--out", out, "--geozone", "G1")  # g1 not built: its folder kept, with its label
    assert (out / hashed["g1"] / "notes.txt").exists()
    assert json.loads((out / "summary.json").read_text())["kept_geozones"] == {hashed["g1"]: "g1"}
    bgm("build", twins, "--out", out, "--geozone", "g1")
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["g1"]
    assert (out / "g1" / "notes.txt").read_text() == "bench 1180: check the contact"


def test_a_carried_file_goes_to_its_geozones_folder_of_this_build():
    """By the label each folder had, into the folder the label has now; an unbuilt geozone's folder is kept, renamed
    where a built geozone's folder now differs from it only by case (one folder on a case-insensitive disk)."""
    from pathlib import Path

    from core.model.build import carried_places, geozone_folders, kept_folders

    previous = {"ox": "ox", "OX-1": "OX", "sulph": "sulph"}
    carried = [Path("ox", "notes.txt"), Path("OX-1", "a.dxf"), Path("sulph", "s")]
    folders = geozone_folders(["ox", "OX"])
    places = carried_places(carried, previous, folders)
    assert places == {
        Path("ox", "notes.txt"): Path(folders["ox"], "notes.txt"),
        Path("OX-1", "a.dxf"): Path(folders["OX"], "a.dxf"),
        Path("sulph", "s"): Path("sulph", "s"),
    }
    assert kept_folders(places, previous, folders) == {"sulph": "sulph"}
    alone = carried_places([Path("OX", "a.dxf")], {"OX": "OX"}, geozone_folders(["ox"]))
    # renamed as a build of both names it: the folder it is carried from next time, if OX is built beside ox
    assert alone[Path("OX", "a.dxf")].parts[0] == geozone_folders(["ox", "OX"])["OX"]
    assert carried_places([Path("x", "n")], {}, folders) == {Path("x", "n"): Path("x", "n")}  # no label: as it was


@pytest.mark.xdist_group("built_in_feet")  # one worker builds it once
def test_a_builds_predicted_sections_carry_what_bgm_predict_gives_for_the_same_section(built_in_feet):
    """`bgm predict` gave each section's area (area_ft2); the build's prediction.geojson, the same section, had none."""
    built = json.loads((built_in_feet / "model" / "g1" / "prediction.geojson").read_text())["features"][0]
    predicted = json.loads((built_in_feet / "p.geojson").read_text())["features"][0]
    assert set(predicted["properties"]) <= set(built["properties"]), (predicted["properties"], built["properties"])
    assert built["properties"]["area_ft2"] == pytest.approx(predicted["properties"]["area_ft2"], rel=1e-9)
    assert built["properties"]["area_ft2"] == pytest.approx(shape(built["geometry"]).area, rel=1e-6)


@pytest.mark.xdist_group("built_in_feet")  # one worker builds it once
def test_a_builds_surfaces_in_feet_say_feet_where_their_format_has_room(built_in_feet):
    """PLY, OBJ, VTP and STL surfaces of a table in feet held feet with nothing saying so (OMF alone had a field);
    mine software that assumes metres scaled the surface by 3.28 without a word. DXF R12 has no field for it."""
    g1 = built_in_feet / "model" / "g1"
    assert b"\ncomment units ft\n" in (g1 / "surface.ply").read_bytes()[:400]
    assert (g1 / "surface.obj").read_text().startswith("# units: ft\n")
    assert "units ft -->" in (g1 / "surface.vtp").read_bytes()[:600].decode()
    assert (g1 / "surface.stl").read_bytes()[:80].rstrip().endswith(b" units ft")
    for fmt in ("ply", "obj", "stl"):  # and each still reads back
        assert len(trimesh.load(g1 / f"surface.{fmt}", force="mesh").faces) > 0


def test_a_rebuild_keeps_the_files_a_geologist_added_to_a_geozone_folder(small_mine_csv, tmp_path):
    """The build replaced its folder whole: notes or a marked-up section put in ``g1/`` were deleted without a
    word by the next build. They are carried over byte for byte, named in a warning, also when ``g1`` is not
    built again; the build's own files are written afresh, a stale one (a format no longer built) never kept."""
    from core.io.export import SURFACE_FORMATS
    from core.model.build import GEOZONE_FILES

    path, _ = small_mine_csv
    out = tmp_path / "model"
    bgm("build", path, "--out", out, "--geozone", "g1")
    written = {p.name for p in (out / "g1").iterdir()}
    formats = json.loads((out / "summary.json").read_text())["formats"]
    assert written <= GEOZONE_FILES, written - GEOZONE_FILES  # the set holds every file a build writes...
    unbuilt = {f"surface.{f}" for f in SURFACE_FORMATS if f not in formats}
    assert GEOZONE_FILES - written <= unbuilt, GEOZONE_FILES - written  # ...and nothing it does not

    mine = {
        "g1/notes.txt": "pit wall sloughing on 1180 bench — résumé à revoir\r\n".encode(),
        "g1/surface.omf_old_copy.dxf": b"0\nSECTION\n2\nENTITIES\n0\nENDSEC\n0\nEOF\n",
        "g1/sections/my_section.dxf": bytes(range(256)),
    }
    for rel, data in mine.items():
        (out / rel).parent.mkdir(exist_ok=True)
        (out / rel).write_bytes(data)
    built_morph = (out / "g1" / "morph.json").read_bytes()
    (out / "g1" / "morph.json").write_text("edited by hand")  # a build's name: written afresh
    stale = next(iter(unbuilt), "surface.omf")
    (out / "g1" / stale).write_bytes(b"from a build with more formats")

    proc = bgm("build", path, "--out", out, "--geozone", "g1")
    for rel, data in mine.items():
        assert (out / rel).read_bytes() == data, rel
    assert (
        "g1/notes.txt" in proc.stderr and "g1/surface.omf_old_copy.dxf" in proc.stderr and "g1/sections" in proc.stderr
    )
    assert "morph.json" not in proc.stderr and stale not in proc.stderr.replace("surface.omf_old_copy", "")
    assert (out / "g1" / "morph.json").read_bytes() == built_morph
    assert not (out / "g1" / stale).exists() or (out / "g1" / stale).read_bytes() != b"from a build with more formats"

    bgm("build", path, "--out", out, "--geozone", "g2")  # g1 not built: its folder keeps the geologist's files
    assert {p.name for p in (out / "g1").iterdir()} == {"notes.txt", "surface.omf_old_copy.dxf", "sections"}
    assert json.loads((out / "summary.json").read_text())["kept_folders"] == ["g1"]
    bgm("build", path, "--out", out, "--geozone", "g1")  # a kept folder does not stop the next build
    for rel, data in mine.items():
        assert (out / rel).read_bytes() == data, rel
    assert (out / "g1" / "morph.json").read_bytes() == built_morph


def test_evaluate_scores_the_model_a_project_makes_and_refuses_another_tables_project(small_mine_csv, tmp_path):
    """`bgm evaluate` had no --project: a geologist's corrections could not be scored against withheld benches.

    The project's parameters make the model scored (no evidence carried past the drilling here), as a
    build with the project scores it; the references are the same rows. A project made on another table, its override naming a component this
    table's bench does not have, is refused in one line, as `bgm correspond --project` refuses it.
    """
    path, _ = small_mine_csv
    project = tmp_path / "p.json"
    save_project(Project(parameters={"frontier_reach_spacings": 0}), project)
    bgm("evaluate", path, "--geozone", "g1", "--out", tmp_path / "plain")
    bgm("evaluate", path, "--geozone", "g1", "--out", tmp_path / "project", "--project", project)
    plain, tuned = (pd.read_csv(tmp_path / f / "evaluation_rows.csv") for f in ("plain", "project"))
    assert list(plain.columns) == list(tuned.columns) and len(plain) == len(tuned)

    def of(rows, methods):
        return rows[rows["method"].isin(methods)].reset_index(drop=True)

    pd.testing.assert_frame_equal(of(plain, {"nil", "linear", "implicit"}), of(tuned, {"nil", "linear", "implicit"}))
    assert not np.allclose(of(plain, {"model"})["p_area"], of(tuned, {"model"})["p_area"])
    bgm("build", path, "--geozone", "g1", "--out", tmp_path / "model", "--project", project, "--workers", "1")
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "model" / "evaluation_rows.csv"), tuned)  # a build's scores

    other = tmp_path / "other.json"
    override = AlignmentOverride("g1", 685.0, source=3, translation=(2.0, 1.0))  # the top bench of g1 has one body
    save_project(Project(overrides=[override], input_path="elsewhere/holes.csv"), other)
    proc = bgm("evaluate", path, "--geozone", "g1", "--out", tmp_path / "other", "--project", other, check=False)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert "saved for elsewhere/holes.csv" in proc.stderr  # the warning every --project command gives
    (error,) = [line for line in proc.stderr.splitlines() if line.startswith("bgm: error:")]
    assert "names source component 3, but the upper bench has 1 component" in error
    assert not (tmp_path / "other").exists()
    other.write_text('{"format": "bgm-project", "version": 1, "overr')  # a project cut short
    proc = bgm("evaluate", path, "--geozone", "g1", "--out", tmp_path / "other", "--project", other, check=False)
    assert proc.returncode == 2 and "corrupt" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
