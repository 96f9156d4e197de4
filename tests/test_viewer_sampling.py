"""The viewer's where-to-sample layers: band or probability map on the next bench, suggested holes with a budget."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from clirun import bgm, succeeds  # noqa: E402

from bgm_viewer.builders import LAYER_NAMES, build_scene, parse_layers  # noqa: E402
from bgm_viewer.model import STEPS  # noqa: E402
from bgm_viewer.sampling_layers import SUGGESTED_COLOUR, NextBench, SuggestedHolesLayer, UncertaintyLayer  # noqa: E402
from bgm_viewer.testing import small_model  # noqa: E402

warnings.filterwarnings("ignore", category=FutureWarning)


@pytest.fixture(scope="module")
def viewer_model():
    return small_model(until="prediction")


def test_layers_are_in_the_standard_scene_and_drawn_from_core(viewer_model):
    assert parse_layers("band,suggestions") == ["uncertainty", "suggested holes"]
    scene = build_scene(viewer_model.holes, viewer_model.result, viewer_model.selection, visible="band,suggestions")
    band, holes = scene["uncertainty"], scene["suggested holes"]
    assert isinstance(band, UncertaintyLayer) and isinstance(holes, SuggestedHolesLayer)
    section = band.next_bench.section
    assert section is not None
    items = band.build(scene.view)
    assert items, "the next bench's uncertainty is drawn"
    z_next = section.z_m
    # On the next bench's plane, where the probability is neither 0 nor 1.
    probability_mesh = items[0].mesh
    assert np.allclose(probability_mesh.points[:, 2], scene.view.z(z_next), atol=0.2)
    xy = probability_mesh.points[:, :2]
    _, _, p = section.at(xy)
    assert ((p > 0.01) & (p < 0.99)).mean() > 0.9


def test_budget_slider_shows_the_first_n_suggestions_in_the_band(viewer_model):
    layer = SuggestedHolesLayer(NextBench(viewer_model.holes, viewer_model.result.model))
    total = layer.n_frames
    assert total > 3
    events = []
    layer.changed.connect(lambda _, what: events.append(what))
    layer.frame = 2
    assert layer.budget == 3 and events == ["frame"]
    shown = layer.build()[0].mesh.points[:, :2]
    np.testing.assert_allclose(shown, layer.next_bench.suggestions_m[:3])
    assert layer.next_bench.section.in_band(shown).all()
    layer.budget = total + 10
    assert layer.budget == total


def test_the_band_drawn_is_the_band_bgm_build_writes(viewer_model, tmp_path):
    """Three benches: g1's own backtest is too short, and bgm build calibrates its band on the other geozones'
    backtests too; the viewer calibrated on g1's alone and drew a band of 1261 m² where the build wrote 11111."""
    import json

    from shapely.geometry import shape

    from core.model.build import build

    scene = build_scene(viewer_model.holes, viewer_model.result, viewer_model.selection, visible="band")
    section = scene["uncertainty"].next_bench.section
    g, holes = viewer_model.selection.geozone, viewer_model.holes
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        build(holes, tmp_path / "out", geozones=[g], formats=("obj",), evaluate=False, workers=1)
    features = json.loads((tmp_path / "out" / g / "uncertainty.geojson").read_text())["features"]
    z = round(float(holes.frame.z_to_input(section.z_m)), 3)
    written = [f["properties"] | {"area": shape(f["geometry"]).area} for f in features]
    band = next(f for f in written if f["z"] == z and f["kind"] == "band")
    assert section.scale.source == band["calibration"] == "pooled backtest"
    assert section.band.area == pytest.approx(band["area"], rel=1e-6)


def test_hidden_next_bench_layers_are_computed_only_once_shown(viewer_model):
    """Hidden by default, the next bench's uncertainty and suggestions were computed by core whenever a
    run changed the model, on the window's thread: 1-3.5 s with the window frozen on Kennecott."""
    from bgm_viewer.builders import refresh_scene
    from bgm_viewer.model import PipelineResult
    from bgm_viewer.screenshot import plotter_for

    res = viewer_model.result
    scene = build_scene(viewer_model.holes, PipelineResult(), viewer_model.selection)
    plotter, renderer = plotter_for(scene, window_size=(320, 240), legend=False, bearings=False)
    try:
        refresh_scene(scene, viewer_model.holes, res, viewer_model.selection, previous=PipelineResult())
        next_bench = scene["uncertainty"].next_bench
        assert next_bench is scene["suggested holes"].next_bench and next_bench.model is res.model
        assert "section" not in vars(next_bench) and "suggestions_m" not in vars(next_bench)  # not computed
        scene["uncertainty"].visible = True
        assert "section" in vars(next_bench) and renderer.actors["uncertainty"]  # drawn once shown
        scene["suggested holes"].visible = True
        assert len(renderer.actors["suggested holes"]) == 1
    finally:
        plotter.close()


def test_without_a_model_the_layers_are_empty(viewer_model):
    nothing = NextBench(viewer_model.holes, None)
    assert UncertaintyLayer(nothing).build() == [] and SuggestedHolesLayer(nothing).build() == []
    assert SuggestedHolesLayer(nothing).n_frames == 1


def test_every_layer_says_which_step_a_screenshot_must_run_for_it():
    from bgm_viewer import screenshot

    assert set(screenshot._NEEDS) == set(LAYER_NAMES)
    assert set(screenshot._NEEDS.values()) <= set(STEPS)


@pytest.mark.parametrize("layer", ["uncertainty", "suggested holes"])
def test_bgm_view_draws_the_next_bench_layers_offscreen(layer, tmp_path):
    """Both layers are advertised by ``--layers``: a screenshot of either draws it (it once raised KeyError)."""
    from core.synthetic.blobs import make_mine, sample_blastholes

    csv, png = tmp_path / "mine.csv", tmp_path / "next.png"
    sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4).to_csv(csv)
    succeeds(bgm("view", csv, "--screenshot", png, "--layers", layer, "--geozone", "g1", "--camera", "top"))
    img = np.asarray(pv.read(str(png)).point_data.active_scalars)[:, :3].astype(int)
    if layer == "suggested holes":
        drawn = np.all(img == SUGGESTED_COLOUR, axis=1)
    else:  # the probability map, red to blue; the axes' own colours take a few hundred pixels
        drawn = img.max(axis=1) - img.min(axis=1) > 80
    assert drawn.sum() > (500 if layer == "suggested holes" else 20_000)


def test_a_superseded_next_bench_stops_at_cores_next_step_and_is_computed_whole_when_asked_again(viewer_model):
    """The window computes the next bench on a worker thread; a newer request (a slider moved again, another
    geozone, the window closed) let it run to its end, a core busy for 1-3.5 s on Kennecott. Cancelled through
    its progress, it stops at core's next step and stays pending, with nothing half computed kept."""
    import threading

    from core.model.session import ModelSession, StageStore
    from core.threads import Cancelled, cancelling

    m, res = viewer_model, viewer_model.result

    def fresh():  # the model's session with nothing stored yet: the band computed from its start
        return ModelSession(m.holes, res.session.params, res.session.project, StageStore(None))

    steps: list[tuple[int, int]] = []
    NextBench(m.holes, res.model, session=fresh(), deferred=True).compute(
        lambda done, total: steps.append((done, total))
    )
    assert len(steps) > 10  # the band's backtests and fit, the suggested holes: each step told

    for told in (1, len(steps) - 1):  # superseded as it begins, and at its last step (after the suggested holes)
        nb = NextBench(m.holes, res.model, session=fresh(), deferred=True)
        stop, seen = threading.Event(), []

        def tell(done, total, seen=seen, stop=stop, told=told):
            seen.append((done, total))
            if len(seen) == told:
                stop.set()  # what the window does when a newer request comes

        with pytest.raises(Cancelled):
            nb.compute(cancelling(stop.is_set, tell))
        assert len(seen) == told  # not a step further
        assert nb.pending and not nb.computed and not {"section", "suggestions_m"} & set(vars(nb))
        assert UncertaintyLayer(nb).build() == [] and SuggestedHolesLayer(nb).build() == []  # nothing stale drawn
        nb.compute()  # asked again (its model still on screen): computed whole
        whole = NextBench(m.holes, res.model, session=res.session)
        assert nb.section.band.equals(whole.section.band)
        np.testing.assert_allclose(nb.suggestions_m, whole.suggestions_m)
