"""Off-screen screenshots: check pixels, not just that a file exists (no Qt, no display)."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from bgm_viewer.builders import build_scene  # noqa: E402
from bgm_viewer.model import PipelineResult, Selection, load_holes  # noqa: E402
from bgm_viewer.palette import BACKGROUND, LAYER_COLOURS, geozone_colours  # noqa: E402
from bgm_viewer.scene import display_to_plane, drag_on_plane, world_to_pixels  # noqa: E402
from bgm_viewer.screenshot import plotter_for, render_screenshot, scene_image  # noqa: E402
from bgm_viewer.testing import small_model  # noqa: E402

warnings.filterwarnings("ignore", category=FutureWarning)
SIZE = (800, 600)


def _exact(img: np.ndarray, rgb) -> np.ndarray:
    return np.all(img == np.asarray(rgb, np.uint8), axis=-1)


def _not_background(img: np.ndarray) -> np.ndarray:
    return np.any(np.abs(img.astype(int) - np.asarray(BACKGROUND)) > 8, axis=-1)


@pytest.fixture(scope="module")
def demo_holes():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_holes(None)


@pytest.fixture(scope="module")
def model():
    return small_model()


def test_demo_scene_is_not_blank_and_geozone_colours_are_where_their_holes_are(demo_holes):
    holes = demo_holes
    scene = build_scene(holes, PipelineResult(), Selection("g1"), visible=["blastholes"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera="top", legend=False)
    try:
        img = np.asarray(plotter.screenshot(None, return_img=True))[..., :3]
        drawn = _not_background(img).mean()
        assert drawn > 0.05, f"only {drawn:.1%} of the image is drawn"
        colours = geozone_colours(holes.geozones)
        top = holes.on_bench(0)
        z = renderer.scene.view.z(holes.bench_levels_m[0])
        for g, rgb in colours.items():
            idx = top[holes.geozone[top] == g]
            if len(idx) == 0:
                continue
            assert _exact(img, rgb).sum() > 20, f"colour of {g} missing"
            px = np.rint(world_to_pixels(plotter, np.column_stack([holes.xy[idx], np.full(len(idx), z)]))).astype(int)
            inside = (px[:, 0] >= 0) & (px[:, 0] < SIZE[0]) & (px[:, 1] >= 0) & (px[:, 1] < SIZE[1])
            px = px[inside]
            hit = _exact(img[px[:, 1], px[:, 0]], rgb)
            assert hit.mean() > 0.8, f"{g}: only {hit.mean():.0%} of its holes show its colour"
    finally:
        plotter.close()


def test_toggling_a_layer_changes_the_image(model):
    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes", "contours"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera="iso", legend=False)
    try:
        with_contours = np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy()
        scene["contours"].visible = False
        plotter.render()
        without = np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy()
        changed = np.any(with_contours != without, axis=-1).sum()
        assert changed > 500, changed
        scene["contours"].visible = True
        plotter.render()
        again = np.asarray(plotter.screenshot(None, return_img=True))[..., :3]
        assert np.array_equal(again, with_contours)
    finally:
        plotter.close()


def test_gvf_layer_draws_arrows(model):
    sel = model.result.selected_contour(model.selection)
    grid = sel.fields.grid
    base = build_scene(model.holes, model.result, model.selection, visible=[])
    img0 = scene_image(base, window_size=SIZE, camera="top", legend=False)
    scene = build_scene(model.holes, model.result, model.selection, visible=["GVF"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera="top", legend=False)
    try:
        img = np.asarray(plotter.screenshot(None, return_img=True))[..., :3]
        yellow = _exact(img, LAYER_COLOURS["gvf"])
        assert not _exact(img0, LAYER_COLOURS["gvf"]).any()
        assert yellow.sum() > 300, yellow.sum()
        # the arrows are within the component's grid
        _, _, length = scene["GVF"].arrows()
        xmin, ymin, xmax, ymax = np.array(grid.bounds) + np.array([-1, -1, 1, 1]) * length
        z = renderer.scene.view.z(model.holes.bench_levels_m[model.selection.bench])
        corners = world_to_pixels(plotter, np.array([[xmin, ymin, z], [xmax, ymax, z]]))
        c0, c1 = np.sort(corners[:, 0]), np.sort(corners[:, 1])
        rr, cc = np.nonzero(yellow)
        assert cc.min() >= c0[0] - 3 and cc.max() <= c0[1] + 3
        assert rr.min() >= c1[0] - 3 and rr.max() <= c1[1] + 3
        # many separate strokes, not one blob: yellow pixels are spread over the grid
        assert len(np.unique(cc // 10)) > 10 and len(np.unique(rr // 10)) > 10
    finally:
        plotter.close()


def test_stage_layers_render(model, tmp_path):
    for layers, camera in [("snake,edge map", "top"), ("wavefront,trajectories", "iso"), ("surfaces", "iso")]:
        out = render_screenshot(
            out_png=tmp_path / "x.png", layers=layers, camera=camera, model=model, window_size=SIZE, legend=False
        )
        img = np.asarray(pv.read(str(out)).point_data.active_scalars)
        assert _not_background(img[:, :3].reshape(-1, 1, 3)).mean() > 0.002, layers
    # trajectories: cyan or magenta pixels drawn
    scene = build_scene(model.holes, model.result, model.selection, visible=["trajectories"])
    img = scene_image(scene, window_size=SIZE, camera="iso", legend=False)
    assert (_exact(img, LAYER_COLOURS["trajectories"]) | _exact(img, LAYER_COLOURS["backtracked"])).sum() > 100


def test_screenshot_command_without_qt(tmp_path):
    """The CLI hook renders the small input with no Qt imported."""
    code = f"""
import sys, warnings
warnings.simplefilter('ignore')
from bgm_viewer.testing import small_holes
from bgm_viewer.screenshot import render_screenshot
p = render_screenshot(small_holes(), r'{tmp_path / "s.png"}', layers='blastholes,contours', camera='top',
                      window_size=(400, 300))
assert p.stat().st_size > 1000
bad = [m for m in sys.modules if m.startswith(('PySide6', 'qtpy', 'pyvistaqt'))]
assert not bad, bad
"""
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


@pytest.mark.parametrize("camera", ["iso", "top"])
def test_a_mouse_drag_is_measured_on_the_bench_plane(model, camera):
    """Pixels under the mouse map back to the bench plane, so a drag recovers a known shift."""
    scene = build_scene(model.holes, model.result, model.selection, visible=["blastholes"])
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera=camera, legend=False)
    try:
        plotter.render()
        z = float(renderer.scene.view.z(model.holes.bench_levels_m[model.selection.bench]))
        cx, cy = model.holes.xy.mean(axis=0)
        world = np.array([[cx, cy, z], [cx + 12.0, cy - 7.0, z]])
        px = world_to_pixels(plotter, world)
        h = plotter.window_size[1]
        display = [(c, h - 1 - r) for c, r in px]  # image rows back to VTK display y
        for (x, y), w in zip(display, world):
            np.testing.assert_allclose(display_to_plane(plotter, x, y, z), w[:2], atol=0.05 * 12.0)
        np.testing.assert_allclose(drag_on_plane(plotter, display[0], display[1], z), [12.0, -7.0], atol=0.6)
        plotter.view_xz()  # a side view looks along the plane: no answer rather than a wild one
        plotter.enable_parallel_projection()
        plotter.render()
        assert display_to_plane(plotter, *display[0], z) is None
    finally:
        plotter.close()


def test_a_moving_camera_draws_light_stand_ins_and_the_exact_scene_at_rest(model, monkeypatch):
    import bgm_viewer.scene as scene_module

    monkeypatch.setattr(scene_module, "COARSE_ABOVE_FACES", 50)
    monkeypatch.setattr(scene_module, "DECIMATE_ABOVE_POINTS", 50)
    scene = build_scene(
        model.holes, model.result, model.selection, visible=["blastholes", "contours", "trajectories", "surfaces"]
    )
    plotter, renderer = plotter_for(scene, window_size=SIZE, camera="iso", legend=False)
    try:
        at_rest = np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy()
        actors = [a for layer in ("contours", "surfaces") for a in renderer.actors[layer]]
        meshes = [a.GetMapper().GetInput() for a in actors]
        sizes = [(m.GetNumberOfPoints(), m.GetNumberOfPolys()) for m in meshes]
        widths = [a.GetProperty().GetLineWidth() for a in actors]
        renderer.set_interacting(True)
        moving = [a.GetMapper().GetInput() for a in actors]
        assert all(m.GetNumberOfPoints() < n for m, (n, _) in zip(moving, sizes, strict=True) if n > 50)
        assert all(a.GetProperty().GetLineWidth() == 1.0 for a in actors)
        plotter.render()
        light = np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy()
        assert _not_background(light).mean() > 0.01, "the stand-in scene is blank"
        renderer.set_interacting(False)
        assert all(a.GetMapper().GetInput() is m for a, m in zip(actors, meshes, strict=True))
        assert [a.GetProperty().GetLineWidth() for a in actors] == widths
        plotter.render()
        assert np.array_equal(np.asarray(plotter.screenshot(None, return_img=True))[..., :3], at_rest)
    finally:
        plotter.close()


@pytest.mark.parametrize("camera", ["iso", "top"])
def test_a_saved_camera_is_in_the_inputs_coordinates_and_comes_back_looking_at_the_same_place(camera):
    """A project's camera is saved in the mine's coordinates and units, elevations not exaggerated (the view's
    local metres and exaggeration reference follow the data): looking at a hole, it says the hole's easting,
    northing and elevation in feet, and put back under another exaggeration it looks at that hole again."""
    from bgm_viewer.testing import small_holes

    holes = small_holes(unit="ft")
    sel = Selection(holes.geozones[0], 0, 0)
    scene = build_scene(holes, PipelineResult(), sel, visible=["blastholes"], vertical_exaggeration=3.0)
    plotter, renderer = plotter_for(scene, window_size=(200, 150), camera=camera, legend=False)
    try:
        hole = 17
        x_m, y_m, z_m = (*holes.xy[hole], holes.z[hole])
        plotter.camera.SetFocalPoint(x_m, y_m, float(scene.view.z(z_m)))
        plotter.camera.SetPosition(x_m - 300.0, y_m - 200.0, float(scene.view.z(z_m)) + 400.0)
        plotter.camera.SetViewUp(0.0, 0.0, 1.0)
        plotter.camera.OrthogonalizeViewUp()
        state = renderer.camera_state()
        in_feet = [*holes.frame.to_input(holes.xy[hole]), float(holes.frame.z_to_input(z_m))]
        np.testing.assert_allclose(state["focal_point"], in_feet, rtol=1e-9)
        assert (state["parallel_scale"] is not None) == (camera == "top")

        scene.vertical_exaggeration = 1.0
        renderer.set_camera_state(state)
        np.testing.assert_allclose(plotter.camera.GetFocalPoint(), (x_m, y_m, z_m), rtol=1e-9, atol=1e-6)
        scene.vertical_exaggeration = 3.0  # as saved: the same view
        renderer.set_camera_state(state)
        back = renderer.camera_state()
        for key in ("position", "focal_point", "view_up", "window_center"):
            np.testing.assert_allclose(back[key], state[key], rtol=1e-9, atol=1e-9)
        assert back["parallel_scale"] == pytest.approx(state["parallel_scale"])
    finally:
        plotter.close()


def test_a_screenshot_of_a_project_shows_its_saved_camera_and_layers_unless_the_command_line_says_otherwise(tmp_path):
    """``bgm view --screenshot --project`` drew the default layers from the default iso camera, not the view the
    geologist saved in the project. It draws the saved one now; ``--camera`` and ``--layers`` win over it."""
    from PIL import Image

    from bgm_viewer.cli_hooks import view_command
    from bgm_viewer.layer_names import LAYER_NAMES
    from bgm_viewer.model import ViewerModel
    from bgm_viewer.screenshot import DEFAULT_SIZE
    from bgm_viewer.testing import small_holes

    holes = small_holes(unit="ft")
    hole = 17
    x_ft, y_ft = holes.frame.to_input(holes.xy[hole])
    z_ft = float(holes.frame.z_to_input(holes.z[hole]))
    # looking straight down at one hole, 20 ft of the mine across half the picture's height
    saved = {
        "position": [float(x_ft), float(y_ft), z_ft + 800.0],
        "focal_point": [float(x_ft), float(y_ft), z_ft],
        "view_up": [0.0, 1.0, 0.0],
        "parallel_scale": 20.0,
        "window_center": [0.0, 0.0],
    }
    model = ViewerModel(holes)
    model.select("g1", 0, 0)
    model.layer_visibility = {name: name == "blastholes" for name in LAYER_NAMES}
    model.camera = saved
    project = tmp_path / "p.bgm.json"
    model.save_project(project)

    def shot(name: str, **options) -> np.ndarray:
        out = tmp_path / name
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert view_command(holes, project, out, options.get("layers"), options.get("camera")) == 0
        return np.asarray(Image.open(out))[..., :3]

    def expected(layers, camera) -> np.ndarray:
        """The picture of the project's model with ``layers`` from ``camera`` (a name, or a saved camera)."""
        opened = ViewerModel(holes)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            opened.load_project(project)
            opened.run(until="contours")
        scene = build_scene(opened.holes, opened.result, opened.selection, visible=layers, vertical_exaggeration=2.0)
        plotter, renderer = plotter_for(scene, camera=camera if isinstance(camera, str) else "iso")
        try:
            if isinstance(camera, dict):
                renderer.set_camera_state(camera)
            centre = world_to_pixels(plotter, np.array([[*holes.xy[hole], scene.view.z(holes.z[hole])]]))[0]
            return np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy(), centre
        finally:
            plotter.close()

    as_saved, centre = expected(["blastholes"], saved)
    np.testing.assert_allclose(centre, np.array(DEFAULT_SIZE) / 2, atol=1.0)  # the saved camera looks at the hole
    picture = shot("saved.png")
    assert np.array_equal(picture, as_saved), "the project's saved camera and layers were not drawn"
    colour = geozone_colours(holes.geozones)[str(holes.geozone[hole])]
    row, col = DEFAULT_SIZE[1] // 2, DEFAULT_SIZE[0] // 2
    assert _exact(picture[row - 1 : row + 2, col - 1 : col + 2], colour).any(), "the hole is not in the middle"

    # the command line's camera and layers win over the project's
    assert np.array_equal(shot("top.png", camera="top"), expected(["blastholes"], "top")[0])
    assert np.array_equal(shot("contours.png", layers="contours"), expected(["contours"], saved)[0])

    model.layer_visibility = dict.fromkeys(LAYER_NAMES, False)  # a project showing no layer: said, not a blank file
    model.save_project(project)
    from core.errors import BGMInputError

    with pytest.raises(BGMInputError, match="the project shows no layer; name the layers with --layers"):
        shot("none.png")
    assert not (tmp_path / "none.png").exists()
