"""Viewer layers and model without a screen: meshes, colours, visibility, overrides."""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from shapely.geometry import box  # noqa: E402

from bgm_viewer.builders import LAYER_NAMES, build_scene, parse_layers  # noqa: E402
from bgm_viewer.layers import (  # noqa: E402
    BlastholesLayer,
    ContoursLayer,
    EdgeMapLayer,
    GVFLayer,
    SnakeLayer,
    SurfaceLayer,
    TrajectoriesLayer,
    ViewTransform,
    WavefrontLayer,
)
from bgm_viewer.palette import GEOZONE_PALETTE, LAYER_COLOURS, lighten  # noqa: E402
from bgm_viewer.scene import Scene  # noqa: E402
from bgm_viewer.testing import small_model  # noqa: E402
from core.geometry.grid import Grid  # noqa: E402

warnings.filterwarnings("ignore", category=FutureWarning)


@pytest.fixture(scope="module")
def model():
    return small_model()


def test_viewer_does_not_import_qt_for_layers():

    import subprocess

    code = (
        "import sys, bgm_viewer.screenshot, bgm_viewer.layers, bgm_viewer.cli_hooks;"
        "bad=[m for m in sys.modules if m.startswith(('PySide6','qtpy','pyvistaqt'))];"
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_core_does_not_import_viewer_stack():
    import subprocess

    code = (
        "import sys, core.extraction.contours, core.io.blastholes, core.synthetic.blobs;"
        "bad=[m for m in sys.modules if m.startswith(('PySide6','qtpy','pyvista','vtk','bgm_viewer'))];"
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_blastholes_layer_points_and_colours():
    xy = np.array([[0, 0], [1, 0], [2, 0], [3, 0]], float)
    layer = BlastholesLayer(xy, [10, 10, 0, 0], ["a", "b", "a", "c"], boundary=[False, True, False, False])
    items = layer.build()
    assert sum(it.mesh.n_points for it in items) == 4
    assert [it.mesh.n_points for it in items] == [3, 1]  # ordinary holes, then boundary holes (larger)
    assert items[1].style["point_size"] > items[0].style["point_size"]
    rgb = layer.rgb()
    assert tuple(rgb[0]) == GEOZONE_PALETTE[0] and tuple(rgb[1]) == GEOZONE_PALETTE[1]
    assert tuple(rgb[3]) == GEOZONE_PALETTE[2]
    np.testing.assert_array_equal(items[0].mesh.point_data["rgb"], rgb[[0, 2, 3]])
    assert [label for label, _ in layer.legend()] == ["geozone a", "geozone b", "geozone c"]


def test_vertical_exaggeration_scales_about_reference():
    layer = BlastholesLayer([[0, 0], [1, 1]], [100.0, 90.0], ["a", "a"])
    pts = layer.build(ViewTransform(3.0, 100.0))[0].mesh.points
    np.testing.assert_allclose(pts[:, 2], [100.0, 70.0])


def test_visibility_and_opacity_notify_observers():
    layer = ContoursLayer([("a", 0.0, box(0, 0, 1, 1))])
    seen = []
    layer.changed.connect(lambda lay, what: seen.append(what))
    layer.visible = False
    layer.visible = False  # no change, no event
    layer.opacity = 0.3
    layer.opacity = 7  # clipped
    assert seen == ["visible", "opacity", "opacity"]
    assert not layer.visible and layer.opacity == 1.0


def test_contours_layer_rings_and_colours():
    square = box(0, 0, 10, 10).difference(box(4, 4, 6, 6))  # one hole
    layer = ContoursLayer([("a", 5.0, square), ("b", 0.0, box(20, 0, 30, 10))])
    (item,) = layer.build()
    assert item.mesh.n_cells == 3  # exterior + interior of a, exterior of b
    assert item.mesh.n_points == 5 + 5 + 5
    assert tuple(item.mesh.cell_data["rgb"][0]) == GEOZONE_PALETTE[0]
    assert tuple(item.mesh.cell_data["rgb"][2]) == GEOZONE_PALETTE[1]
    predicted = ContoursLayer([("a", 5.0, square)], name="predicted contours", predicted=True)
    assert predicted.colour_of("a") != GEOZONE_PALETTE[0]


def _radial_gvf(n=40):
    grid = Grid(0.0, 0.0, 1.0, (n, n))
    X, Y = grid.cell_centres()
    u, v = (n / 2 - X), (n / 2 - Y)  # points to the centre
    return grid, np.stack([u, v])


def test_gvf_layer_builds_arrows():
    grid, gvf = _radial_gvf()
    layer = GVFLayer(grid, gvf, z=5.0, arrows_across=10)
    centres, d, length = layer.arrows()
    assert 80 <= len(centres) <= 100
    np.testing.assert_allclose(np.hypot(d[:, 0], d[:, 1]), 1.0)
    # arrows point to the centre
    towards = np.array([20.0, 20.0]) - centres
    assert np.all(np.einsum("ij,ij->i", towards, d) > 0)
    (item,) = layer.build()
    assert item.mesh.n_cells == 3 * len(centres)  # shaft + two head strokes each
    assert item.style["color"] == LAYER_COLOURS["gvf"]
    assert np.allclose(item.mesh.points[:, 2], 5.05)


def test_edge_map_layer_is_an_image_plane():
    grid, _ = _radial_gvf(20)
    em = np.zeros((20, 20))
    em[5, :] = 1.0
    (item,) = EdgeMapLayer(grid, em, 0.0).build()
    assert item.mesh.n_points == 400
    assert item.mesh.point_data["rgb"].max() == 255


def test_snake_layer_steps_through_iterations():
    hist = [np.array([[0, 0], [s, 0], [s, s], [0, s]], float) for s in (10, 8, 6)]
    layer = SnakeLayer(hist, 1.0)
    assert layer.n_frames == 3 and layer.frame == 2
    events = []
    layer.changed.connect(lambda lay, what: events.append(what))
    layer.frame = 0
    start, current = layer.build()
    np.testing.assert_allclose(current.mesh.points[:4, :2], hist[0])
    layer.frame = -1
    assert layer.frame == 2 and events == ["frame", "frame"]
    layer.frame = 99
    assert layer.frame == 2


def test_wavefront_and_trajectories_layers():
    fronts = [box(0, 0, s, s) for s in (2, 4, 6, 8)]
    w = WavefrontLayer(fronts, [0, 1, 2, 3], 10.0, 0.0, shift=(1.0, 0.0))
    (item,) = w.build()
    assert item.mesh.n_cells == 4
    z = np.unique(item.mesh.points[:, 2])
    np.testing.assert_allclose(sorted(z), [0.0, 10 / 3, 20 / 3, 10.0])
    # the first front is moved back by the whole shift, the last one not at all
    pts = item.mesh.points
    assert pts[pts[:, 2] == 10.0][:, 0].min() == pytest.approx(-1.0)
    w.frame = 1
    assert w.build()[0].mesh.n_cells == 2

    class T:
        def __init__(self, xy, b):
            self.xy, self.backtracked = np.asarray(xy, float), b

    t = TrajectoriesLayer([T([[0, 0], [1, 0], [2, 0]], False), T([[0, 1], [1, 1]], True)], 10.0, 0.0)
    (item,) = t.build()
    assert item.mesh.n_cells == 2 and item.mesh.n_points == 5
    assert tuple(item.mesh.cell_data["rgb"][0]) == LAYER_COLOURS["trajectories"]
    assert tuple(item.mesh.cell_data["rgb"][1]) == LAYER_COLOURS["backtracked"]
    np.testing.assert_allclose(item.mesh.points[:3, 2], [10.0, 5.0, 0.0])


def test_surface_layer_from_triangles():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    layer = SurfaceLayer([("a", v, f)])
    (item,) = layer.build(ViewTransform(2.0, 0.0))
    assert item.mesh.n_cells == 4 and item.mesh.points[:, 2].max() == 2.0
    assert item.style["opacity"] == pytest.approx(0.6)


def test_surface_layer_shades_undrilled_faces_lighter():
    """Faces in ground no bench bracketed are drawn apart, in the geozone's colour lightened, and said in the legend."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    colour = (200, 40, 40)
    drilled = np.array([True, True, False, True])
    layer = SurfaceLayer([("a", v, f)], {"a": colour}, drilled=lambda: [drilled])
    items = layer.build(ViewTransform(1.0, 0.0))
    assert [it.mesh.n_cells for it in items] == [3, 1]
    assert items[0].style["color"] == colour and items[1].style["color"] == lighten(colour, 0.55)
    assert ("predicted (lighter shade)", LAYER_COLOURS["predicted"]) in layer.legend()
    whole = SurfaceLayer([("a", v, f)], {"a": colour}, drilled=[np.ones(4, bool)])
    assert len(whole.build(ViewTransform(1.0, 0.0))) == 1 and len(whole.legend()) == 1


def test_scene_shades_the_surface_below_the_deepest_bench(model):
    """The pipeline's surfaces: what lies below the deepest bench is shaded as predicted, what the benches bracket is not."""
    res = model.result
    scene = build_scene(model.holes, res, model.selection, visible=["surfaces"])
    layer = scene["surfaces"]
    deepest = float(model.holes.bench_levels_m[-1])
    for (_, v, f), drilled in zip(layer.meshes, layer.drilled, strict=True):
        z = v[f].mean(axis=1)[:, 2]
        assert not drilled[z < deepest - 0.1].any()
        assert drilled.any()


def test_scene_from_pipeline(model):
    res = model.result
    assert res.complete and not res.errors, res.errors
    scene = build_scene(model.holes, res, model.selection, visible=LAYER_NAMES)
    assert scene.names() == list(LAYER_NAMES)
    n_holes = sum(it.mesh.n_points for it in scene["blastholes"].build())
    assert n_holes == len(model.holes.xy)
    n_rings = sum(
        len(list(getattr(c.polygon, "interiors", []))) + 1
        for cs in res.contours.values()
        for c in cs
        if not c.polygon.is_empty
    )
    assert scene["contours"].build()[0].mesh.n_cells == n_rings
    assert scene["GVF"].build()[0].mesh.n_cells > 100
    assert scene["snake"].n_frames > 1
    assert not scene["trajectories"].is_empty and not scene["wavefront"].is_empty
    assert not scene["surfaces"].is_empty
    # Predicted contours of the selected geozone, half a bench and a bench below the deepest one.
    assert not scene["predicted contours"].is_empty, res.errors
    deepest = float(model.holes.bench_levels_m[-1])
    assert {round(z - deepest, 6) for _, z, _ in res.predicted} == {
        round(-0.5 * model.holes.bench_height_m, 6),
        round(-model.holes.bench_height_m, 6),
    }
    assert all(p.is_valid and p.area > 0 for _, _, p in res.predicted)
    labels = [label for label, _ in scene.legend_entries()]
    assert "geozone g1" in labels and "GVF" in labels
    scene["GVF"].visible = False
    assert "GVF" not in [label for label, _ in scene.legend_entries()]


def test_parse_layers_aliases():
    assert parse_layers("holes, gvf,surface") == ["blastholes", "GVF", "surfaces"]
    with pytest.raises(KeyError):
        parse_layers("nonsense")


def test_scene_replace_keeps_display_state():
    scene = Scene([ContoursLayer([("a", 0.0, box(0, 0, 1, 1))])])
    scene["contours"].visible = False
    scene["contours"].opacity = 0.5
    scene.replace(ContoursLayer([("a", 0.0, box(0, 0, 2, 2))]))
    assert not scene["contours"].visible and scene["contours"].opacity == 0.5


def test_snake_parameter_reruns_only_selected_snake_first(model):
    from bgm_viewer.model import compute

    before = model.result.selected_contour(model.selection).polygon
    stage = model.set_param("gvf_mu", 0.05)
    assert stage == "snake"
    model.set_param("snake_max_iterations", 40)
    steps = compute(model.inputs(), model.result, "snake")
    msg, _, first = next(steps)
    assert msg == "snake of the selected component"
    after = first.selected_contour(model.selection).polygon
    assert not after.equals(before)
    steps.close()
    model.params = type(model.params)()  # the module's model back at the defaults for the next tests


def test_manual_alignment_undo_and_project_roundtrip(model, tmp_path):
    from bgm_viewer.model import ViewerModel

    auto = model.current_translation_m()
    assert auto is not None
    model.set_translation(auto[0] + 5.0, auto[1] - 3.0)
    model.run("correspondence", until="correspondence")
    moved = model.current_translation_m()
    np.testing.assert_allclose(moved, (auto[0] + 5.0, auto[1] - 3.0), atol=1e-9)
    assert model.dirty
    path = tmp_path / "p.bgmproj.json"
    model.save_project(path)
    assert not model.dirty

    other = ViewerModel(model.holes)
    other.load_project(path)
    assert other.selection == model.selection
    assert other.params == model.params
    other.run(until="correspondence")
    np.testing.assert_allclose(other.current_translation_m(), moved, atol=1e-9)

    assert model.can_undo
    model.undo()
    model.run("correspondence", until="correspondence")
    np.testing.assert_allclose(model.current_translation_m(), auto, atol=1e-9)
    assert model.dirty and not model.overrides


@pytest.mark.parametrize("unit", ["m", "ft"])
def test_nudges_made_before_the_run_of_the_first_is_done_add_up(unit):
    """Ctrl+Right pressed twice within a run moved the source one step: the second nudge started from the
    translation of the result on screen, from before the first, and undid it."""
    from bgm_viewer.model import ViewerModel
    from bgm_viewer.testing import small_holes

    model = ViewerModel(small_holes(unit=unit), cache=False)
    model.select("g1", 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until="correspondence")
        auto = model.current_translation_m()
        model.nudge(1.0, 0.0)
        model.nudge(1.0, 0.5)  # before the first nudge's run
        model.run("correspondence", until="correspondence")
    np.testing.assert_allclose(model.current_translation_m(), (auto[0] + 2.0, auto[1] + 0.5), atol=1e-9)
    model.undo()
    model.run("correspondence", until="correspondence")
    np.testing.assert_allclose(model.current_translation_m(), (auto[0] + 1.0, auto[1]), atol=1e-9)


def test_an_override_of_a_component_the_pair_lacks_is_refused():
    """Locking source 40 of a bench with one component broke the geozone's every run, and was saved."""
    from bgm_viewer.testing import small_model

    model = small_model(until="correspondence")
    n_sources, n_targets = len(model.result.pair.sources), len(model.result.pair.targets)
    model.select(component=n_sources + 39)
    model.run("morph", until="correspondence")
    model.dirty = False  # the selection is saved in the project: choosing one marks it unsaved
    for change in (model.lock_current, lambda: model.set_translation(1.0, 2.0), lambda: model.nudge(1.0, 0.0)):
        with pytest.raises(ValueError, match="does not exist"):
            change()
    assert not model.dirty
    model.select(component=0)
    model.run("morph", until="correspondence")
    model.dirty = False
    with pytest.raises(ValueError, match="target component"):
        model.set_association(n_targets + 5, True)
    assert not model.overrides and not model.can_undo and not model.dirty
    model.set_association(0, False)  # an existing target: accepted
    assert model.overrides


def test_a_translation_the_project_could_not_reopen_is_refused(tmp_path):
    """The viewer saved a translation longer than the input spans, which loading the project refuses."""
    from bgm_viewer.model import ViewerModel
    from bgm_viewer.testing import small_model

    model = small_model(until="correspondence")
    for bad in ((900.0, 0.0), (0.0, float("nan"))):
        with pytest.raises(ValueError, match="off the input"):
            model.set_translation(*bad)
    assert not model.overrides and not model.can_undo
    model.set_translation(100.0, -100.0)  # long but on the input: a correction
    model.save_project(tmp_path / "p.json")
    ViewerModel(model.holes).load_project(tmp_path / "p.json")


def test_a_project_saved_in_another_folder_finds_its_input(tmp_path, monkeypatch):
    """`bgm view holes.csv`, saved as sub/p.json: the project named holes.csv, read as sub/holes.csv."""
    from pathlib import Path

    from bgm_viewer.model import ViewerModel, project_input

    monkeypatch.chdir(tmp_path)
    Path("holes.csv").write_text(Path(__file__).parents[1].joinpath("assets/demo_blastholes.csv").read_text())
    model = ViewerModel("holes.csv")
    (tmp_path / "sub").mkdir()
    model.save_project("sub/p.json")
    model.save_project(tmp_path / "p.json")
    for project in ("sub/p.json", tmp_path / "p.json"):
        assert Path(project_input(project)).resolve() == (tmp_path / "holes.csv").resolve()


def test_a_project_whose_table_was_moved_says_so_and_how_to_open_it(tmp_path):
    """File > Open project (or `bgm view --project p.json`) after the table was renamed: "input file
    '.../holes.csv' does not exist", nothing saying the name came from the project nor how to open it."""
    from pathlib import Path

    from bgm_viewer.model import ViewerModel, project_input
    from core.errors import BGMInputError

    table = tmp_path / "holes.csv"
    table.write_text(Path(__file__).parents[1].joinpath("assets/demo_blastholes.csv").read_text())
    ViewerModel(table).save_project(tmp_path / "p.json")
    table.rename(tmp_path / "holes-2024.csv")
    with pytest.raises(BGMInputError) as caught:
        project_input(tmp_path / "p.json")
    said = str(caught.value)
    assert "p.json was saved for the table holes.csv" in said and "moved or renamed" in said
    assert f"bgm view TABLE --project {tmp_path / 'p.json'}" in said


@pytest.mark.parametrize("stage", ["selected geozone's model", "other geozones' surfaces"])
def test_a_superseded_run_stops_inside_a_geozones_model_at_its_next_bench_pair(stage, monkeypatch):
    """A run checked for a newer request only between its steps; a geozone's model is one step (every bench
    pair corresponded and morphed: 5 s on Kennecott), and the other geozones' surfaces ran on to the end of
    each one begun (9 s). Core's progress now raises the cancellation at the model's next bench pair."""
    from bgm_viewer.model import Cancelled, ViewerModel, compute
    from bgm_viewer.testing import small_holes
    from core.model.session import ModelSession

    corresponded: list[tuple[str, int]] = []
    correspond = ModelSession.correspond

    def recorded(self, pair, *args, **kwargs):
        corresponded.append((pair.geozone, pair.upper))
        return correspond(self, pair, *args, **kwargs)

    monkeypatch.setattr(ModelSession, "correspond", recorded)
    model = ViewerModel(small_holes(), cache=False)
    model.select("g1", 0, 0)
    assert model.inputs().surface_geozones == ("g1", "g2", "g3")

    def superseded() -> bool:  # a newer request, once the model of `stage` has corresponded its first pair
        if stage == "selected geozone's model":  # g1's bench pair 0 is corresponded first alone (the pair shown)
            return corresponded.count(("g1", 0)) >= 2
        return any(g != "g1" for g, _ in corresponded)

    with warnings.catch_warnings(), pytest.raises(Cancelled):
        warnings.simplefilter("ignore")
        for _ in compute(model.inputs(), None, "contours", superseded):
            pass
    pairs = {g: [upper for zone, upper in corresponded if zone == g] for g in ("g1", "g2", "g3")}
    if stage == "selected geozone's model":
        assert pairs == {"g1": [0, 0], "g2": [], "g3": []}  # g1's second pair (bench 1) never begun
    else:
        assert pairs["g1"] == [0, 0, 1] and pairs["g2"] == [0]  # g2 has two pairs: stopped after its first


@pytest.mark.parametrize("stage", ["selected bench", "other benches"])
def test_a_superseded_run_stops_inside_a_benchs_contour_tracing_and_a_later_run_traces_it_whole(stage, monkeypatch):
    """A bench's contours were one step of a run: superseded while it traced one (a Kennecott bench: 2-4 s, 20-40
    parts), the run traced every part of it, and of every bench begun on the other threads, before it stopped.
    Core's progress now raises the cancellation at the bench's next part, and nothing of the bench is stored."""
    import core.extraction.contours as extraction
    from bgm_viewer.model import Cancelled, ViewerModel, compute
    from bgm_viewer.testing import small_holes
    from core.model.session import ModelSession

    holes = small_holes()
    whole = {k: ModelSession(holes).bench_contours(k) for k in range(holes.n_benches)}  # never cancelled
    traced: list[int] = []  # the bench of each part traced
    part_contour = extraction._part_contour

    def recorded(holes, bench, *args, **kwargs):
        contour = part_contour(holes, bench, *args, **kwargs)
        traced.append(bench)
        return contour

    monkeypatch.setattr(extraction, "_part_contour", recorded)
    model = ViewerModel(holes, cache=False)
    model.select("g1", 0, 0)
    bench = 0 if stage == "selected bench" else 2  # bench 1 is traced with 0, the pair shown; 2 after them

    def superseded() -> bool:  # a newer request, once the bench's first part is traced
        return bench in traced

    with warnings.catch_warnings(), pytest.raises(Cancelled):
        warnings.simplefilter("ignore")
        for _ in compute(model.inputs(), None, "contours", superseded):
            pass
    assert len(whole[bench]) >= 3 and traced.count(bench) == 1  # its other parts never traced
    assert model.session().stored_bench_contours(bench, "g1") is None  # nothing half done stored
    *_, (_, _, again) = compute(model.inputs(), None, "contours", until="contours")  # a later run: whole, the same
    for k, contours in whole.items():
        assert [c.polygon.wkb for c in again.contours[k]] == [c.polygon.wkb for c in contours]


@pytest.mark.parametrize("stage", ["selected geozone's surface", "other geozones' surfaces"])
def test_a_superseded_run_stops_inside_a_geozones_surface_and_a_later_run_makes_it_whole(stage, monkeypatch):
    """A surface begun was made to its end: its sections, then the mesh (Kennecott: the other geozones' surfaces
    ran 6 s after the request). Core's progress now raises the cancellation at the surface's next step (a bench
    pair's sections, a section's depth trend or signed distance, the mesh), and nothing of it is stored."""
    import core.model.session as sessions
    import core.model.surfaces as surfaces
    from bgm_viewer.model import Cancelled, ViewerModel, compute
    from bgm_viewer.testing import small_holes

    holes = small_holes()
    begun: list[str] = []  # the geozone of each surface begun
    meshed: list[int] = []  # a mesh made of sections
    sections_of, mesh_of = sessions.surface_sections, surfaces.surface_from_sections

    def recorded_sections(model, *args, **kwargs):
        begun.append(model.geozone)
        return sections_of(model, *args, **kwargs)

    def recorded_mesh(sections, *args, **kwargs):
        meshed.append(len(sections))
        return mesh_of(sections, *args, **kwargs)

    monkeypatch.setattr(sessions, "surface_sections", recorded_sections)
    monkeypatch.setattr(surfaces, "surface_from_sections", recorded_mesh)
    model = ViewerModel(holes, cache=False)
    model.select("g1", 0, 0)
    selected = stage == "selected geozone's surface"

    def superseded() -> bool:  # a newer request, once the surface of `stage` is begun
        return "g1" in begun if selected else any(g != "g1" for g in begun)

    with warnings.catch_warnings(), pytest.raises(Cancelled):
        warnings.simplefilter("ignore")
        for _ in compute(model.inputs(), None, "contours", superseded):
            pass
    assert len(meshed) == (0 if selected else 1)  # g1's alone, when the others' were superseded
    assert model.store.counts["surface", "computed"] == len(meshed)  # nothing half done stored
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        *_, (_, _, again) = compute(model.inputs(), None, "contours")  # a later run: whole, the same
        fresh = {g: sessions.ModelSession(holes).surface(g) for g in ("g1", "g2", "g3")}  # never cancelled
    assert set(again.built) == set(fresh)
    for g, mesh in fresh.items():
        assert np.array_equal(again.built[g].vertices, mesh.vertices) and np.array_equal(
            again.built[g].faces, mesh.faces
        )


def test_a_superseded_run_stops_inside_the_selected_geozones_predictions_and_stores_none(monkeypatch):
    """The selected geozone's predictions below the deepest bench were one step: its depth trend's backtests ran
    to their end (Kennecott's 3026: 3-7 s after the request). Core's progress now raises the cancellation at the
    prediction's next step (a backtest's bench pair, an elevation), and no prediction is stored."""
    import core.model.session as sessions
    from bgm_viewer.model import Cancelled, ViewerModel, compute
    from bgm_viewer.testing import small_holes

    holes = small_holes()
    begun: list[str] = []  # the geozone of each prediction begun
    predict = sessions.predict_geozone

    def recorded(model, *args, **kwargs):
        begun.append(model.geozone)
        return predict(model, *args, **kwargs)

    monkeypatch.setattr(sessions, "predict_geozone", recorded)
    model = ViewerModel(holes, cache=False)
    model.select("g1", 0, 0)
    with warnings.catch_warnings(), pytest.raises(Cancelled):
        warnings.simplefilter("ignore")
        for _ in compute(model.inputs(), None, "contours", lambda: bool(begun)):  # a newer request, once begun
            pass
    assert begun == ["g1"]
    assert model.store.counts["prediction", "computed"] == 0  # nothing half done stored
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        *_, (_, _, again) = compute(model.inputs(), None, "contours", until="prediction")  # a later run: whole
    zs = sorted({z for _, z, _ in again.predicted})
    fresh = sessions.ModelSession(holes).predict("g1", zs)  # never cancelled
    assert sorted((z, p.wkb) for _, z, p in again.predicted) == sorted(
        (z, p.wkb) for z, region in fresh.items() for p in region.geoms
    )


def test_selecting_another_component_of_the_bench_draws_its_own_edge_map_gvf_and_snake():
    """g1's corner body (component 1) selected after its main body (component 0) on the same bench: the run
    shares the bench's contours, so the refresh found "the selected contour" unchanged in both results and kept
    the edge map, GVF and snake of component 0 on screen under component 1."""
    from bgm_viewer.builders import refresh_scene
    from bgm_viewer.model import ViewerModel, compute
    from bgm_viewer.testing import two_bodies_holes

    model = ViewerModel(two_bodies_holes(), cache=False)
    model.select("g1", 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until="morph")
        scene = build_scene(model.holes, model.result, model.selection, visible=["snake", "edge map", "GVF"])
        step = model.select(component=1)
        for _, _, result in compute(model.inputs(), model.result, step, until="morph"):
            refresh_scene(scene, model.holes, result, model.selection, previous=model.result)
            model.set_result(result)
    fields = model.result.selected_contour(model.selection).fields
    first = model.result.sources(model.selection)[0].fields
    assert not np.array_equal(fields.snake_history_m[-1], first.snake_history_m[-1])  # two bodies, two snakes
    assert np.array_equal(scene["snake"].history[-1], fields.snake_history_m[-1])
    assert scene["edge map"].edge_map is fields.edge_map and scene["GVF"].gvf is fields.gvf


def test_a_stopped_run_leaves_the_last_finished_result_on_screen_and_the_sliders_as_set():
    """A run stopped part way (the window's Stop) had shown its first bench traced with the new
    slider beside the old benches, model and surfaces: a half-updated model passed for the current one."""
    from bgm_viewer.model import compute

    model = small_model()
    finished = model.result
    model.set_param("snake_max_iterations", 10)
    steps = compute(model.inputs(), model.result, "contours")
    model.set_result(next(steps)[2])  # the selected bench pair, traced with the new slider
    steps.close()
    assert model.result.contours != finished.contours  # what Stop must not leave on screen
    said = model.stop()
    assert said.startswith("stopped")
    assert model.result.stopped and model.result.contours == finished.contours
    assert model.result.surfaces == finished.surfaces and model.result.model is finished.model
    assert model.param("snake_max_iterations") == 10
    # under another selection the last run's pair and model are not drawn as its own
    model.select("g2", 0, 0)
    model.stop()
    assert model.result.stopped and model.result.pair is None and model.result.model is None
    model.run()
    assert model.result.complete and not model.result.stopped


def test_stepping_benches_selects_the_component_the_selected_one_corresponds_to():
    """The component number was kept from bench pair to bench pair: there it was another body, or none."""
    from bgm_viewer.model import ViewerModel
    from bgm_viewer.testing import bodies_that_start_and_end_holes

    model = ViewerModel(bodies_that_start_and_end_holes())
    model.select("g1", 0, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run()
    assert model.result.model.pairs[0].correspondence.association[2].tolist() == [False, True]
    assert model.select(bench=1) == "contours"
    assert model.selection.component == 1  # body B, not a number 2 the bench below has not
    assert "source component 1 selected" in model.selection_note and "continues into it" in model.selection_note
    model.select(component=1)
    model.select(bench=0)  # one bench up: the component B continues from
    assert model.selection.component == 2, model.selection_note
    model.select(component=1)  # body A, which ends between the top two benches
    model.select(bench=1)
    assert model.selection.component == 0  # the first, not body B (number 1 there)
    assert "the first" in model.selection_note and "no correspondence" in model.selection_note
    model.select(bench=0, component=1)  # a component named with the bench is kept as named
    assert model.selection.component == 1


def test_a_project_naming_a_component_the_bench_lacks_is_said_by_its_first_run_and_the_model_runs(tmp_path):
    """A hand-edited project naming source component 5 of a bench with one opened without a word, and
    every run then failed that geozone's model. Checked on opening, it traced the benches there (the
    window's thread: 2-4 s a bench on Kennecott); the first run checks it now, where it traces them."""
    import json

    from bgm_viewer.model import ViewerModel
    from core.errors import BGMWarning

    model = small_model(until="contours")
    path = tmp_path / "p.json"
    model.save_project(path)
    z = model.holes.bench_z_input(0)
    data = json.loads(path.read_text())
    data["overrides"] = [
        {"geozone": "g1", "source_z": z, "source": 5, "translation": [1.0, 0.0]},
        {"geozone": "g1", "source_z": z, "source": 0, "associate": {"4": True}},
        {"geozone": "g1", "source_z": z, "source": 0, "translation": [2.0, 1.0]},
    ]
    path.write_text(json.dumps(data))
    opened = ViewerModel(model.holes, cache=False)
    with warnings.catch_warnings(record=True) as on_open:
        warnings.simplefilter("always")
        opened.load_project(path)
    assert not [w for w in on_open if "does not have" in str(w.message)]
    assert opened.store.counts["contours", "computed"] == 0  # nothing traced on opening
    told = []
    opened.overrides_missing.connect(told.extend)
    with pytest.warns(BGMWarning) as said:
        opened.run()
    notes = [str(w.message) for w in said if "does not have" in str(w.message)]
    pair = f"{z:g} -> {model.holes.bench_z_input(1):g} m"
    assert len(notes) == 2 and all(f"project file {path}" in n and "'g1'" in n and pair in n for n in notes)
    assert "source component 5" in notes[0] and "target component 4" in notes[1] and "dropped" in notes[0]
    assert told == notes  # what the window shows
    assert [(o.source, o.translation) for o in opened.overrides] == [(0, (2.0, 1.0))]  # the others kept
    assert opened.result.model is not None and "model" not in opened.result.errors, opened.result.errors
    assert not opened.can_undo and not opened.dirty  # they never applied: nothing to undo, nothing unsaved
