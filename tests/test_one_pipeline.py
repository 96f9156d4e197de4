"""The viewer shows what `bgm build` exports, and saves what `bgm correspond --project` reads.

The viewer drives core's own pipeline (core.model.session); these tests hold
it to the command line's outputs on the same input and parameters.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import shapely
import trimesh
from conftest import DEMO_CSV
from shapely.geometry import shape
from test_cli import bgm

pytest.importorskip("psygnal")

from bgm_viewer.model import ViewerModel
from core.io.blastholes import read_blastholes
from core.io.reporting import carried_json, carried_line, to_input_geometry
from core.model.build import build
from core.model.parameters import ModelParameters
from core.model.session import ModelSession, StageStore
from core.model.surfaces import to_input_frame

GEOZONE = "g2"


@pytest.fixture(scope="module")
def demo_holes():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_blastholes(DEMO_CSV)


def _viewer(holes, geozone: str, bench: int, until: str = "surface", cache: bool = False) -> ViewerModel:
    model = ViewerModel(holes, cache=cache)  # by default computed afresh, not read back from the command's cache
    model.select(geozone, bench, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until=until)
    assert not model.result.errors, model.result.errors
    return model


def test_the_viewer_shows_the_contours_translations_and_surface_bgm_build_exports(demo_holes, tmp_path):
    holes = demo_holes
    out = tmp_path / "build"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        summary = build(holes, out, geozones=[GEOZONE], evaluate=False, workers=1)
    viewer = _viewer(holes, GEOZONE, 0)
    res = viewer.result

    # contours: every one of the geozone's contours on every bench, same vertices
    exported = {
        (f["properties"]["bench"], f["properties"]["component"]): shape(f["geometry"])
        for f in json.loads((out / "contours.geojson").read_text())["features"]
    }
    shown = {
        (holes.bench_z_input(b), c.component): to_input_geometry(c.polygon, holes)
        for b, cs in res.contours.items()
        for c in cs
        if c.geozone == GEOZONE
    }
    assert shown.keys() == exported.keys() and len(shown) >= holes.n_benches
    for key, geometry in shown.items():
        assert shapely.equals_exact(geometry, exported[key], tolerance=1e-6), key

    # translations of every bench pair, input units
    corr = json.loads((out / GEOZONE / "correspondence.json").read_text())
    mpu = holes.frame.metres_per_unit
    assert len(res.model.pairs) == len(corr["pairs"])
    for pair, written in zip(res.model.pairs, corr["pairs"]):
        assert written["source_z"] == holes.bench_z_input(pair.upper)
        np.testing.assert_allclose(pair.correspondence.translations / mpu, written["translations"], atol=1e-9)

    # the surface: the exported mesh, vertex for vertex
    info = next(g for g in summary["geozones"] if g["geozone"] == GEOZONE)
    mesh = trimesh.load(out / info["files"]["obj"], force="mesh", process=False)
    on_screen = to_input_frame(res.surface, (holes.frame.origin_x, holes.frame.origin_y), mpu)
    assert len(on_screen.faces) == len(mesh.faces)
    np.testing.assert_allclose(on_screen.vertices, mesh.vertices, atol=1e-6)
    assert on_screen.volume == pytest.approx(info["volume"], rel=1e-3)

    # how the prediction below the deepest bench carries the movement on: the report's, and bgm predict's
    assert info["carried"] and carried_json(res.carried, holes) == info["carried"]
    assert viewer.carried_text() == carried_line(info["carried"], "m")
    below = holes.bench_z_input(holes.n_benches - 1) - 10.0
    proc = bgm("predict", DEMO_CSV, "--geozone", GEOZONE, "--elevations", f"{below:g}", "--out", tmp_path / "p.geojson")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["carried"] == info["carried"]


def test_the_translation_shown_and_locked_is_bgm_corresponds(demo_holes, tmp_path):
    """Demo, g2, 675 -> 665, source 0: the viewer once aligned it 14 m away from `bgm correspond`."""
    holes = demo_holes
    bench = next(k for k in range(holes.n_benches) if holes.bench_z_input(k) == 675.0)
    viewer = _viewer(holes, GEOZONE, bench, until="correspondence", cache=True)
    auto = np.array(viewer.current_translation_m()) / holes.frame.metres_per_unit

    def translation(path) -> np.ndarray:
        pairs = json.loads(path.read_text())["pairs"]
        return np.array(next(p for p in pairs if p["source_z"] == 675.0)["translations"][0])

    bgm("correspond", DEMO_CSV, "--geozone", GEOZONE, "--out", tmp_path / "auto.json", "--no-cache")
    np.testing.assert_allclose(auto, translation(tmp_path / "auto.json"), atol=1e-9)

    locked = auto + (2.5, -1.5)
    viewer.set_translation(*(locked * holes.frame.metres_per_unit))
    viewer.save_project(tmp_path / "project.json")
    bgm(
        "correspond",
        DEMO_CSV,
        "--geozone",
        GEOZONE,
        "--project",
        tmp_path / "project.json",
        "--out",
        tmp_path / "p.json",
    )
    np.testing.assert_allclose(translation(tmp_path / "p.json"), locked, atol=1e-9)
    viewer.run("correspondence", until="correspondence")
    np.testing.assert_allclose(
        np.array(viewer.current_translation_m()) / holes.frame.metres_per_unit, locked, atol=1e-9
    )


def test_the_other_geozones_surfaces_come_several_at_once_and_each_is_its_own(demo_holes, monkeypatch):
    """The viewer makes the other geozones' surfaces on threads: each is the one made alone; a failing one is named."""
    viewer = _viewer(demo_holes, GEOZONE, 0, cache=True)  # the test's own cache, empty: computed, then stored
    others = [g for g in viewer.inputs().surface_geozones if g != GEOZONE]
    assert len(others) >= 2 and set(others) <= set(viewer.result.surfaces)
    alone = ModelSession(demo_holes, ModelParameters(), None, StageStore(None))
    for g in others:
        mesh = alone.surface(g, alone.geozone_model(g))  # the body filter is off by default
        np.testing.assert_array_equal(viewer.result.surfaces[g].vertices, mesh.vertices)
        np.testing.assert_array_equal(viewer.result.surfaces[g].faces, mesh.faces)

    failing = others[0]
    model_of = ModelSession.geozone_model

    def broken(self, g, *args, **kwargs):
        if g == failing:
            raise RuntimeError(f"no model of {g}")
        return model_of(self, g, *args, **kwargs)

    monkeypatch.setattr(ModelSession, "geozone_model", broken)
    again = ViewerModel(demo_holes)  # the same disk cache: the other geozones are read, the failing one is asked for
    again.select(GEOZONE, 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        again.run()
    assert again.result.errors == {f"model {failing}": f"no model of {failing}"}
    assert failing not in again.result.surfaces and set(others[1:]) <= set(again.result.surfaces)


def test_a_geozone_with_no_bench_pair_is_predicted_by_none_of_build_viewer_and_predict(tmp_path):
    """The demo's west part, its top four benches: g3 is six scattered holes, never three in a component.

    `bgm build` wrote no prediction for it and the viewer drew none ("never in a component of 3 or more
    holes"), while `bgm predict` a bench below the deepest returned a section of 43 m² (the depth trend of
    its two holes on the deepest bench).
    """
    import pandas as pd

    table = pd.read_csv(DEMO_CSV)
    path = tmp_path / "west.csv"
    table[(table.x < 482300) & (table.z > 655)].to_csv(path, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        holes = read_blastholes(path)
    assert holes.n_benches == 4
    below = holes.bench_z_input(3) - 10.0

    proc = bgm(
        "predict", path, "--geozone", "g3", "--elevations", f"{below:g}", "--out", tmp_path / "p.geojson", "--no-cache"
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["features"] == 0
    assert json.loads((tmp_path / "p.geojson").read_text())["features"] == []
    assert json.loads((tmp_path / "p.uncertainty.geojson").read_text())["features"] == []
    assert "never in a component of 3 or more holes" in proc.stderr and "no prediction" in proc.stderr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        summary = build(holes, tmp_path / "build", geozones=["g3"], evaluate=False, workers=1)
    assert not (tmp_path / "build" / "g3" / "prediction.geojson").exists()
    assert summary["geozones"][0]["carried"] is None
    viewer = _viewer(holes, "g3", 2, until="prediction")
    assert viewer.result.model is not None and not viewer.result.model.pairs and not viewer.result.predicted
    assert viewer.carried_text() == "-" and "carried" not in json.loads(proc.stdout)
    session = ModelSession.open(holes, cache=False)
    regions = session.predict("g3", [float(holes.frame.z_to_local(below)), float(holes.bench_levels_m[3])])
    assert all(region.is_empty for region in regions.values())
