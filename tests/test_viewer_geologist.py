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

from conftest import narrowing_pit  # noqa: E402

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


def test_a_component_too_small_for_a_snake_says_so_not_that_its_fields_are_to_come():
    """g1's corner body of six holes, with contours smoothed over three spacings, keeps its holes' outline: no
    snake is run on it. Once the run was done the status bar still said its fields were "not computed yet"."""
    from bgm_viewer.testing import two_bodies_holes

    model = ViewerModel(two_bodies_holes(), cache=False)
    model.set_param("smoothing_spacings", 3.0)
    model.select("g1", 0, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until="morph")
    assert model.result.complete and model.result.selected_contour(model.selection).fields is None
    scene = build_scene(model.holes, model.result, model.selection, visible=["snake", "edge map", "GVF"])
    reasons = empty_layer_reasons(scene, model.holes, model.result, model.selection)
    assert set(reasons) == {"snake", "edge map", "GVF"}
    for why in reasons.values():
        assert "too small for a snake" in why and "6 holes" in why and "not computed yet" not in why


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


@pytest.mark.xdist_group("kennecott_predicted")  # one worker computes the fixture once
def test_predicted_contours_are_drawn_on_kennecott(kennecott_predicted):
    assert kennecott_predicted.holes.frame.length_unit == "ft"
    assert _predicted_pixels(kennecott_predicted) > 200


def test_a_geozone_the_deepest_bench_never_drilled_is_predicted_where_bgm_build_predicts_it(tmp_path):
    """A body at the edge of a narrowing pit, on the top three of five benches: the viewer predicted it below
    the last bench its pairs reach, between known benches where it is absent, and drew nothing where
    bgm build's prediction.geojson has its sections below the deepest bench."""
    import json

    from shapely.geometry import shape

    from core.model.build import build

    holes = narrowing_pit(gone=False)
    model = ViewerModel(holes, cache=False)
    model.select("wall", 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until="prediction")
        build(holes, tmp_path / "out", geozones=["wall"], formats=("obj",), evaluate=False, workers=1)
    assert model.result.model.pairs[-1].lower < holes.n_benches - 1  # its pairs end above the deepest bench
    shown: dict[float, float] = {}
    for _, z, poly in model.result.predicted:
        z_input = round(float(holes.frame.z_to_input(z)), 3)
        shown[z_input] = shown.get(z_input, 0.0) + poly.area
    features = json.loads((tmp_path / "out" / "wall" / "prediction.geojson").read_text())["features"]
    built = {f["properties"]["z"]: shape(f["geometry"]).area for f in features}
    assert shown and set(shown) <= set(built), (sorted(shown), sorted(built))
    assert min(shown) < float(holes.bench_z_input(holes.n_benches - 1))  # below the deepest bench
    for z, area in shown.items():
        assert area == pytest.approx(built[z], rel=1e-6)


# ---------------------------------------------------------------------------
# bearings


def test_axes_labels_and_scale_bar_are_drawn(model):
    from bgm_viewer.palette import BEARINGS

    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes"])
    plain, _ = _image(scene, legend=False, bearings=False)
    img, renderer = _image(scene, legend=False)
    bearings = _exact(img, BEARINGS) & ~_exact(plain, BEARINGS)
    assert bearings.sum() > 500, "no axes, labels or scale bar in the bearings' colour"
    # labels outside the data's box on screen: the axes are labelled, not just drawn across the data
    from bgm_viewer.scene import world_to_pixels

    plotter, renderer = plotter_for(scene, window_size=SIZE, camera="iso", legend=False)
    try:
        b = renderer.data_bounds()
        corners = np.array(np.meshgrid(*np.reshape(b, (3, 2)), indexing="ij")).reshape(3, -1).T
        px = world_to_pixels(plotter, corners)
        bar = renderer._ruler
        assert bar is not None and bar.GetTitle() == f"{bar.GetTitle().split()[0]} m"
    finally:
        plotter.close()
    rows, cols = np.nonzero(bearings)
    outside = (cols < px[:, 0].min()) | (cols > px[:, 0].max()) | (rows < px[:, 1].min()) | (rows > px[:, 1].max())
    assert outside.sum() > 100, "nothing is written outside the data box (axis labels)"


@pytest.mark.parametrize("camera", ["top", "iso", "front"])
def test_scale_bar_and_orientation_widget_do_not_overlap(model, camera):
    """The scale bar (with its title below it) and the orientation widget are both readable in every view."""
    from bgm_viewer.scene import world_to_pixels

    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera=camera, legend=False)
    try:
        widget = plotter.renderer.axes_widget
        assert widget is not None, "no orientation widget"
        x0, y0, x1, y1 = widget.GetViewport()  # fractions of the window, y up
        w, h = plotter.window_size
        bar = renderer._ruler
        ends = np.array([bar.GetPositionCoordinate().GetValue(), bar.GetPosition2Coordinate().GetValue()], float)
        cols, rows = world_to_pixels(plotter, ends).T
        title_px = 40  # the title is drawn below the bar
        bar_box = (cols.min(), cols.max(), rows.min(), rows.max() + title_px)
        widget_box = (x0 * w, x1 * w, (1 - y1) * h, (1 - y0) * h)
        apart = (
            bar_box[1] < widget_box[0]
            or widget_box[1] < bar_box[0]
            or bar_box[3] < widget_box[2]
            or widget_box[3] < bar_box[2]
        )
        assert apart, f"scale bar {bar_box} under the orientation widget {widget_box} ({camera} view)"
    finally:
        plotter.close()


def _title_boxes(plotter) -> dict[str, tuple[int, int, int, int] | None]:
    """Each axis title's pixels ``(col0, row0, col1, row1)`` as drawn (None if none is), found by recolouring it."""
    axes = plotter.renderer.cube_axes_actor
    drawn = np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy()
    boxes = {}
    for axis, name in enumerate("xyz"):
        prop = axes.GetTitleTextProperty(axis)
        colour = prop.GetColor()
        prop.SetColor(1.0, 0.0, 1.0)
        axes.Modified()
        plotter.render()
        recoloured = np.asarray(plotter.screenshot(None, return_img=True))[..., :3]
        prop.SetColor(*colour)
        axes.Modified()
        plotter.render()
        rows, cols = np.nonzero(np.any(recoloured != drawn, axis=-1))
        boxes[name] = (cols.min(), rows.min(), cols.max(), rows.max()) if len(rows) else None
    return boxes


@pytest.mark.parametrize("legend", [True, False])
@pytest.mark.parametrize("camera, titled", [("top", "xy"), ("front", "xz"), ("side", "yz"), ("iso", "xyz")])
def test_axis_titles_are_inside_the_picture(model, camera, titled, legend):
    """The titles of the axes drawn in a view lie whole inside the picture (the top view lost its northing's)."""
    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes", "contours"])
    plotter, _ = plotter_for(scene, window_size=SIZE, camera=camera, legend=legend)
    try:
        boxes = _title_boxes(plotter)
    finally:
        plotter.close()
    w, h = SIZE
    for name in titled:
        box = boxes[name]
        assert box is not None, f"the {name} axis title is not drawn in the {camera} view: {boxes}"
        c0, r0, c1, r1 = box
        assert c0 >= 2 and c1 < w - 2 and r0 >= 2 and r1 < h - 2, f"{name} title at {box} cut by the edge ({camera})"


def test_axes_are_labelled_in_the_inputs_coordinates_and_units():
    model = ViewerModel(small_holes(unit="ft"))
    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, legend=False)
    try:
        axes = plotter.renderer.cube_axes_actor
        assert "(ft)" in axes.GetXTitle() and "Elevation" in axes.GetZTitle()
        f = model.holes.frame
        x_in = f.to_input(model.holes.xy)[:, 0]
        lo, hi = axes.GetXAxisRange()
        assert lo <= x_in.min() + 1 and hi >= x_in.max() - 1 and hi - lo < 1.2 * (x_in.max() - x_in.min()) + 50
        assert renderer._ruler.GetTitle().endswith(" ft")
    finally:
        plotter.close()


def test_vertical_exaggeration_refits_the_camera(model):
    from bgm_viewer.scene import world_to_pixels

    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera="front", legend=False)
    try:
        for ve in (1.0, 8.0):
            scene.vertical_exaggeration = ve
            renderer.fit()
            b = renderer.data_bounds()
            corners = np.array(np.meshgrid(*np.reshape(b, (3, 2)), indexing="ij")).reshape(3, -1).T
            px = world_to_pixels(plotter, corners)
            assert px.min() >= -2 and px[:, 0].max() <= SIZE[0] + 2 and px[:, 1].max() <= SIZE[1] + 2
            fill = max(np.ptp(px[:, 0]) / SIZE[0], np.ptp(px[:, 1]) / SIZE[1])
            # less the room the axes' titles take at the left and bottom (AXES_MARGIN_PX)
            assert fill > 0.75, f"exaggeration {ve}: the data fill only {fill:.0%} of the picture"
    finally:
        plotter.close()


# ---------------------------------------------------------------------------
# decluttering


def test_hiding_a_geozone_removes_its_colour(model):
    from bgm_viewer.palette import geozone_colours

    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes", "contours", "surfaces"])
    colours = geozone_colours(model.holes.geozones)
    g = model.selection.geozone
    img, _ = _image(scene, camera="top", legend=False, bearings=False)
    assert _exact(img, colours[g]).sum() > 100
    scene.hidden_geozones = {g}
    img, _ = _image(scene, camera="top", legend=False, bearings=False)
    assert _exact(img, colours[g]).sum() == 0
    other = next(o for o in model.holes.geozones if o != g)
    assert _exact(img, colours[other]).sum() > 100


def test_palette_is_distinct_for_twenty_geozones_and_stable():
    from bgm_viewer.palette import LAYER_COLOURS, geozone_colours

    labels = [f"z{i:02d}" for i in range(24)]
    colours = geozone_colours(labels)
    assert len(set(colours.values())) == 24
    assert geozone_colours(reversed(labels)) == colours  # the same label, the same colour
    rgb = np.array(list(colours.values()), int)
    gaps = np.abs(rgb[:, None] - rgb[None]).sum(-1) + np.eye(24, dtype=int) * 999
    assert gaps.min() >= 40, "two geozone colours are too alike"
    assert not set(colours.values()) & set(LAYER_COLOURS.values())


def test_a_clip_plane_removes_the_half_it_should(model):
    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes", "contours"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera="top", legend=False, bearings=False)
    try:
        full = _drawn(np.asarray(plotter.screenshot(None, return_img=True))[..., :3])
        b = renderer.data_bounds()
        from bgm_viewer.scene import world_to_pixels

        mid = (b[0] + b[1]) / 2
        col = world_to_pixels(plotter, np.array([[mid, b[2], b[5]]]))[0, 0]
        renderer.set_clip("x", mid, keep="below")
        plotter.render()
        cut = _drawn(np.asarray(plotter.screenshot(None, return_img=True))[..., :3])
    finally:
        plotter.close()
    left, right = int(col) - 3, int(col) + 3
    assert full[:, right:].sum() > 2000 and full[:, :left].sum() > 2000
    assert cut[:, right:].sum() == 0, "the right half is still drawn"
    assert cut[:, :left].sum() > 0.95 * full[:, :left].sum(), "the left half was cut too"


@pytest.mark.xdist_group("kennecott_predicted")  # one worker computes the fixture once
def test_legend_does_not_cover_the_data(kennecott_predicted):
    from bgm_viewer.scene import LEGEND_WIDTH, world_to_pixels

    m = kennecott_predicted
    scene = build_scene(m.holes, m.result, m.selection, visible=["blastholes", "contours"])
    plotter, renderer = plotter_for(scene, window_size=SIZE)
    try:
        assert len(renderer._legend_shown) == len(m.holes.geozones)  # one row per geozone
        b = renderer.data_bounds()
        corners = np.array(np.meshgrid(*np.reshape(b, (3, 2)), indexing="ij")).reshape(3, -1).T
        px = world_to_pixels(plotter, corners)
        legend_left = (1 - LEGEND_WIDTH) * SIZE[0]
        assert px[:, 0].max() < legend_left, "the data's box reaches under the legend"
        assert px[:, 0].min() >= 0 and np.ptp(px[:, 0]) > 0.6 * SIZE[0]
    finally:
        plotter.close()


# ---------------------------------------------------------------------------
# every surface, as bgm build exports it


def test_shown_surfaces_are_the_exported_ones(tmp_path):
    import trimesh

    from core.model.build import build

    holes = small_holes()
    model = _quiet_model(holes)
    shown = model.result.surfaces
    assert set(shown) >= {model.selection.geozone} and len(shown) >= 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        build(holes, tmp_path / "out", evaluate=False, workers=1)
    f = holes.frame
    for g, mesh in shown.items():
        files = list((tmp_path / "out").glob(f"{g}*/surface.ply"))
        assert len(files) == 1, g
        exported = trimesh.load(files[0], force="mesh")
        local = exported.vertices - [f.origin_x, f.origin_y, 0.0]
        local = local * f.metres_per_unit
        assert len(exported.faces) == len(mesh.faces)
        np.testing.assert_allclose(np.sort(local, axis=0), np.sort(mesh.vertices, axis=0), atol=1e-6)


def test_surfaces_are_redone_when_the_selected_geozone_has_no_bench_pair():
    """g3 has 0, 1 and 11 holes on the three benches. Selected, with a smallest modelled component of 12 it
    has no bench pair: the run stopped there, and its surface from before stayed on screen (and in the
    exports), as did every other geozone's from before each later slider move."""
    model = _quiet_model(small_holes(), geozone="g3")
    assert model.selection.geozone == "g3" and "g3" in model.result.surfaces
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(model.set_param("min_component_holes", 12))
        assert not model.result.model.pairs
        assert "g3" not in model.result.surfaces and "g3" not in model.result.built
        model.run(model.set_param("surface_max_cells", 5))  # a coarse grid: fewer faces
        session = model.session()
        for g in ("g1", "g2"):  # redone after the slider move
            assert len(model.result.built[g].faces) == len(session.surface(g).faces), g


def test_the_body_filter_drops_label_noise_bodies():
    model = _quiet_model(small_holes())
    g = max(model.result.surfaces, key=lambda k: len(model.result.surfaces[k].split(only_watertight=False)))
    before = model.result.surfaces[g].split(only_watertight=False)
    model.min_body_volume_m3 = float(np.median([abs(b.volume) for b in before])) + 1e-9
    model.run("surface")
    after = model.result.surfaces[g].split(only_watertight=False)
    big = [b for b in before if abs(b.volume) >= model.min_body_volume_m3]
    assert len(after) == len(big) < len(before)


@pytest.mark.parametrize("sep", [";", "\t"])
def test_a_clicked_hole_shows_its_own_grade_from_a_decimal_comma_table(tmp_path, sep):
    """x, y and z written ``482499,97``: the grades were matched by a second reading that saw no numbers (a crash)."""
    import pandas as pd

    holes = small_holes()
    table = pd.DataFrame(
        {
            "x": holes.xy[:, 0] + 482_000.0,
            "y": holes.xy[:, 1] + 7_445_000.0,
            "z": holes.z,
            "geozone": holes.geozone,
            "cu_pct": np.round(np.random.default_rng(0).uniform(0, 2, len(holes.xy)), 3),
        }
    )
    path = tmp_path / "holes.csv"
    table.to_csv(path, index=False, sep=sep, decimal=",", float_format="%.3f")
    model = ViewerModel(str(path))
    h = model.holes
    for i in np.random.default_rng(1).choice(len(h.xy), 20, replace=False):
        x, y = h.frame.to_input(h.xy[i : i + 1])[0]
        want = table.iloc[int(np.argmin(np.hypot(table.x - x, table.y - y)))]
        assert float(model.hole_info(int(i))["cu_pct"].replace(",", ".")) == want.cu_pct  # shown as written


def test_a_windows_1252_table_opens_with_a_warning_and_its_accents(tmp_path):
    """Excel on Windows saves "CSV (Comma delimited)" as Windows-1252: opened, said once, accents kept."""
    import pandas as pd

    holes = small_holes()
    table = pd.DataFrame(
        {
            "x": holes.xy[:, 0] + 482_000.0,
            "y": holes.xy[:, 1] + 7_445_000.0,
            "z": holes.z,
            "geozone": np.where(holes.geozone == holes.geozones[0], "Pórfido", holes.geozone),
            "comentario": "buzamiento 10°",
        }
    )
    path = tmp_path / "excel.csv"
    path.write_bytes(table.to_csv(index=False).encode("cp1252"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = ViewerModel(str(path))
        assert model.hole_info(0)["comentario"] == "buzamiento 10°"  # a second reading, not said again
    said = [str(w.message) for w in caught if "Windows-1252" in str(w.message)]
    assert len(said) == 1 and "excel.csv" in said[0], said
    assert "Pórfido" in model.holes.geozones
