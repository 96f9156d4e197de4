"""What a geologist needs from the viewer (issue 14), checked on pixels off-screen (no Qt, no display).

Bearings (axes, scale bar), decluttering (geozones hidden, clip plane, legend
clear of the data), predictions drawn, surfaces as ``bgm build`` exports
them, and a word on every empty layer.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from bgm_viewer.builders import build_scene, empty_layer_reasons  # noqa: E402
from bgm_viewer.model import Selection, ViewerModel, richest_pair  # noqa: E402
from bgm_viewer.palette import BACKGROUND  # noqa: E402
from bgm_viewer.screenshot import plotter_for, render_screenshot  # noqa: E402
from bgm_viewer.testing import small_holes, small_model  # noqa: E402
from core.errors import BGMInputError  # noqa: E402

warnings.filterwarnings("ignore", category=FutureWarning)
SIZE = (800, 600)


def _exact(img: np.ndarray, rgb) -> np.ndarray:
    return np.all(img == np.asarray(rgb, np.uint8), axis=-1)


def _drawn(img: np.ndarray) -> np.ndarray:
    return np.any(np.abs(img.astype(int) - np.asarray(BACKGROUND)) > 8, axis=-1)


def _image(scene, camera="iso", size=SIZE, **kw):
    plotter, renderer = plotter_for(scene, window_size=size, camera=camera, **kw)
    try:
        return np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy(), renderer
    finally:
        plotter.close()


def _quiet_model(source, geozone=None, until="surface") -> ViewerModel:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ViewerModel(source)
        if geozone is not None:
            model.select(geozone, None, 0)
        model.run(until=until)
    return model


@pytest.fixture(scope="module")
def model():
    return small_model()


@pytest.fixture(scope="module")
def demo_predicted():
    return _quiet_model(None, until="prediction")


@pytest.fixture(scope="module")
def kennecott_predicted(kennecott_csv):
    return _quiet_model(kennecott_csv, until="prediction")


# ---------------------------------------------------------------------------
# a sensible start, and a word on every empty layer


def test_opens_on_a_geozone_and_bench_pair_with_holes_on_both_benches():
    holes = small_holes()
    g, b = richest_pair(holes)
    for k in (b, b + 1):
        assert np.sum((holes.geozone == g) & (holes.bench == k)) >= 10
    # the host rock holding most holes is passed over for a body
    assert np.mean(holes.geozone == g) < 0.5
    model = ViewerModel(holes)
    assert (model.selection.geozone, model.selection.bench) == (g, b)


def test_an_empty_layer_says_why(model):
    holes = model.holes
    absent = next((g, k) for k in range(holes.n_benches - 1) for g in holes.geozones if not len(holes.on_bench(k, g)))
    sel = Selection(absent[0], absent[1], 0)
    scene = build_scene(holes, model.result, sel, visible=["snake", "GVF", "blastholes"])
    reasons = empty_layer_reasons(scene, holes, model.result, sel)
    assert set(reasons) == {"snake", "GVF"}
    assert "no holes" in reasons["snake"] and absent[0] in reasons["snake"]


def test_screenshot_of_an_empty_layer_says_why_on_stderr(tmp_path, capsys):
    holes = small_holes()
    g, k = next((g, k) for k in range(holes.n_benches - 1) for g in holes.geozones if not len(holes.on_bench(k, g)))
    out = tmp_path / "s.png"
    render_screenshot(holes, out, layers="snake,blastholes", geozone=g, bench=k, window_size=SIZE)
    err = capsys.readouterr().err
    assert out.exists() and "'snake' is empty" in err and "no holes" in err
    # with nothing else to draw, the command refuses and says why
    with pytest.raises(BGMInputError, match="no holes"):
        render_screenshot(holes, tmp_path / "t.png", layers="snake", geozone=g, bench=k, window_size=SIZE)
    assert not (tmp_path / "t.png").exists()


# ---------------------------------------------------------------------------
# predictions are drawn


def _predicted_pixels(model) -> int:
    assert model.result.predicted, "the model holds no predicted contours"
    scene = build_scene(model.holes, model.result, model.selection, visible=["predicted"])
    img, renderer = _image(scene, legend=False)
    colour = scene["predicted contours"].colour_of(model.selection.geozone)
    return int(_exact(img, colour).sum())


def test_predicted_contours_are_drawn_on_the_demo(demo_predicted):
    assert _predicted_pixels(demo_predicted) > 200


def test_predicted_contours_are_drawn_on_kennecott(kennecott_predicted):
    assert kennecott_predicted.holes.frame.length_unit == "ft"
    assert _predicted_pixels(kennecott_predicted) > 200
