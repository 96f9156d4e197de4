"""The Qt window, driven with pytest-qt. Needs a display: run under

    xvfb-run -a -s "-screen 0 1280x1024x24" python -m pytest -m gui tests/test_viewer_window.py

(Qt's ``offscreen`` platform cannot host the VTK OpenGL widget.)
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytestmark = pytest.mark.gui

if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
    pytest.skip("no display: run the window tests under xvfb-run", allow_module_level=True)
if os.environ.get("QT_QPA_PLATFORM") == "offscreen":
    pytest.skip("Qt's offscreen platform cannot host the VTK widget", allow_module_level=True)

pytest.importorskip("pytestqt")
pytest.importorskip("pyvistaqt")

from qtpy import QtCore, QtWidgets  # noqa: E402

from bgm_viewer.app import MainWindow  # noqa: E402
from bgm_viewer.model import ViewerModel  # noqa: E402
from bgm_viewer.testing import small_holes  # noqa: E402

warnings.filterwarnings("ignore", category=FutureWarning)


@pytest.fixture(autouse=True)
def no_modal_dialogs(monkeypatch):
    """A modal dialog would block the test run: fail instead."""

    def warning(parent, title, text, *a, **k):
        raise AssertionError(f"unexpected dialog: {title}: {text}")

    monkeypatch.setattr(QtWidgets.QMessageBox, "warning", warning)
    monkeypatch.setattr(QtWidgets.QMessageBox, "question", warning)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getSaveFileName", warning)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName", warning)


@pytest.fixture(scope="module")
def warm_stage_cache(tmp_path_factory) -> Path:
    """One stage cache for the module's windows: each opens on the same table, whose first run the next window
    reads from disk instead of computing again (a run of its own cost each test 2-4 s of the suite)."""
    return tmp_path_factory.mktemp("bgm-window-cache")


@pytest.fixture
def window(qtbot, warm_stage_cache, monkeypatch):
    monkeypatch.setenv("BGM_CACHE_DIR", str(warm_stage_cache))
    model = ViewerModel(small_holes())
    model.select("g1", 0, 0)
    win = MainWindow(model, debounce_ms=10)
    win.show()  # not qtbot.addWidget: pytest-qt would close it before this fixture's teardown
    qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
    yield win
    win.model.dirty = False  # no prompt at teardown
    win.close()


def _selected_polygon(win):
    c = win.model.result.selected_contour(win.model.selection)
    return c.polygon


def _turn_camera(window) -> None:
    """Turn and zoom the view away from every preset, as a geologist does, and draw it."""
    window.set_camera("front")
    c = window.plotter.camera
    c.Azimuth(35.0)
    c.Elevation(25.0)
    c.OrthogonalizeViewUp()
    c.Zoom(1.7)
    window.plotter.render()


def test_window_shows_layers_and_results(window):
    names = [window.layer_list.item(i).text() for i in range(window.layer_list.count())]
    assert names == window.scene.names()
    assert not window.scene["contours"].is_empty and not window.scene["surfaces"].is_empty
    # toggling in the panel changes the layer (and nothing else)
    window.set_layer_visible("contours", False)
    assert not window.scene["contours"].visible
    window.set_layer_visible("contours", True)
    assert window.scene["contours"].visible
    img = window.plotter.screenshot(None, return_img=True)
    assert img.std() > 5  # something is drawn
    # how the selected geozone's prediction carries its movement on below the deepest bench, as the report says it
    assert window.carried_label.text() == window.model.carried_text() != "-"


def test_slider_change_reruns_its_stage_and_changes_the_contour(window, qtbot):
    before = _selected_polygon(window)
    ctl = window.param_controls["snake_max_iterations"]
    ctl.slider.setValue(10)  # as a user drags it (the snake converges in about 20)
    assert window.model.param("snake_max_iterations") == ctl.value() == 10
    assert window.model.dirty
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    after = _selected_polygon(window)
    assert not after.equals(before)
    assert window.model.result.timings.get("selected snake") is not None  # only its snake re-ran first
    assert window.last_update_seconds < 5.0


def test_manual_alignment_save_reload_and_undo(window, qtbot, tmp_path):
    auto = window.model.current_translation_m()
    window.dx_spin.setValue(auto[0] + 4.0)
    window.dy_spin.setValue(auto[1] + 2.0)
    want = (window.dx_spin.value(), window.dy_spin.value())  # what the user typed (2 decimals)
    window.apply_translation()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), want, atol=1e-6)
    assert abs(want[0] - auto[0] - 4.0) < 0.01
    assert "locked" in window.translation_label.text()

    path = tmp_path / "proj.json"
    window.model.project_path = str(path)
    assert window.save_project()
    assert not window.model.dirty

    window.open_project(path)
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), want, atol=1e-6)

    window.nudge(1.0, 0.0)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m()[0], want[0] + 1.0, atol=1e-6)
    window.undo()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), want, atol=1e-6)


def test_a_translation_being_typed_is_not_set_back_by_a_run_under_way(window, qtbot):
    """A run lasts seconds (tens on a large pit), and each of its results put the translation shown back in the
    dx, dy boxes: what the geologist was typing meanwhile was lost, and Apply locked the automatic translation."""
    auto = window.model.current_translation_m()
    window.dx_spin.setValue(auto[0] + 7.0)  # typed while the run below goes on
    window.dy_spin.setValue(auto[1] - 3.0)
    typed = (window.dx_spin.value(), window.dy_spin.value())
    window.request("surface", immediate=True)  # a run whose results leave the translation as it was
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    assert (window.dx_spin.value(), window.dy_spin.value()) == typed
    window.apply_translation()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), typed, atol=1e-6)
    window.undo()  # a new translation shown: the boxes show it
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose((window.dx_spin.value(), window.dy_spin.value()), auto, atol=0.006)


def test_undo_of_an_override_a_slider_dropped_sets_the_slider_back(window, qtbot):
    """Undo brings back the slider value the override was made under, shown on the slider, and says so."""
    window._select(geozone="g2", bench=0, component=0)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    window._align(window.model.set_translation, 2.0, -1.0)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    ctl = window.param_controls["min_component_holes"]
    ctl.slider.setValue(20)  # g2's one component on the top bench has 14 holes: its override is dropped
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    assert window.model.overrides == []
    window.undo()
    assert ctl.value() == 3 and ctl.slider.value() == 3
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    assert [o.source for o in window.model.overrides] == [0]
    assert "Undo brought back" in window.statusBar().currentMessage()


def test_undo_is_offered_only_when_there_is_something_to_undo(window, qtbot, tmp_path):
    """Edit > Undo (Ctrl+Z) was enabled when the window opened and after another project was opened,
    with nothing to undo, and did nothing without a word."""
    assert not window.undo_action.isEnabled()
    window.undo()  # the panel's Undo button
    assert window.statusBar().currentMessage() == "nothing to undo"
    window.nudge(1.0, 0.0)
    assert window.undo_action.isEnabled()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    path = tmp_path / "p.json"
    window.model.save_project(path)
    window.open_project(path)
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert not window.model.can_undo and not window.undo_action.isEnabled()


def test_redo_brings_back_an_undone_nudge_and_is_offered_only_then(window, qtbot):
    """Edit > Redo (Ctrl+Shift+Z) and the panel's Redo: an Undo pressed once too often lost the nudge for good."""
    assert not window.redo_action.isEnabled()
    window.redo()
    assert window.statusBar().currentMessage() == "nothing to redo"
    window.nudge(2.0, 1.0)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    nudged = window.model.current_translation_m()
    window.undo_action.trigger()
    assert window.redo_action.isEnabled() and not window.undo_action.isEnabled()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    window.redo_action.trigger()
    assert not window.redo_action.isEnabled() and window.undo_action.isEnabled()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), nudged, atol=1e-6)
    assert "locked" in window.translation_label.text()
    window.undo()
    window.param_controls["snake_max_iterations"].slider.setValue(10)  # a new change: nothing left to redo
    assert not window.redo_action.isEnabled()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)


def test_shift_drag_moves_the_source_and_leaves_the_camera(window, qtbot):
    """A Shift + left drag in the 3D view moves the selected source by the dragged distance."""
    from bgm_viewer.scene import world_to_pixels

    auto = window.model.current_translation_m()
    window.renderer.set_camera("top")
    window.plotter.render()
    camera_before = window.plotter.camera_position
    z = window._source_plane_z()
    c = _selected_polygon(window).centroid
    px = world_to_pixels(window.plotter, np.array([[c.x, c.y, z], [c.x + 6.0, c.y + 3.0, z]]))
    h = window.plotter.window_size[1]
    (x0, y0), (x1, y1) = [(int(round(col)), int(round(h - 1 - row))) for col, row in px]
    expected = window.drag_translation((x0, y0), (x1, y1))  # what the rounded pixels mean on the bench
    np.testing.assert_allclose(expected, [6.0, 3.0], atol=1.0)

    iren = window.plotter.iren.interactor
    for event, (x, y) in (
        ("LeftButtonPressEvent", (x0, y0)),
        ("MouseMoveEvent", ((x0 + x1) // 2, (y0 + y1) // 2)),
        ("MouseMoveEvent", (x1, y1)),
        ("LeftButtonReleaseEvent", (x1, y1)),
    ):
        iren.SetEventInformation(x, y, 0, 1)  # ctrl off, shift on
        iren.InvokeEvent(event)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), np.add(auto, expected), atol=1e-6)
    assert window.plotter.camera_position == camera_before  # the drag did not turn the camera
    window.undo()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), auto, atol=1e-6)


def test_drag_and_lock_start_from_a_nudge_whose_run_is_not_done(window, qtbot):
    """The Shift+drag preview and Lock used the translation on screen, the one before a nudge still
    running: the preview said the wrong translation, and Lock undid the nudge."""
    auto = window.model.current_translation_m()
    window.renderer.set_camera("top")
    window.plotter.render()
    window.nudge(8.0, 0.0)
    assert window.busy and window.model.current_translation_m() == auto  # its run is not done
    w, h = window.plotter.window_size
    start, end = (w // 2, h // 2), (w // 2 + 20, h // 2)
    d = window.drag_translation(start, end)
    iren = window.plotter.iren.interactor
    for event, (x, y) in (("LeftButtonPressEvent", start), ("MouseMoveEvent", end)):
        iren.SetEventInformation(x, y, 0, 1)  # shift on
        iren.InvokeEvent(event)
    tx, ty = (np.add(auto, d) + [8.0, 0.0]) / window._mpu
    assert f"translation {tx:.2f}, {ty:.2f}" in window.statusBar().currentMessage()
    window._drag_start = None  # not released: no second nudge
    window.lock_current()
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    np.testing.assert_allclose(window.model.current_translation_m(), np.add(auto, [8.0, 0.0]), atol=1e-6)


def test_closing_with_unsaved_changes_prompts(window, monkeypatch):
    asked = []

    def fake_question(*args, **kwargs):
        asked.append(args)
        return QtWidgets.QMessageBox.Cancel if len(asked) == 1 else QtWidgets.QMessageBox.Discard

    monkeypatch.setattr(QtWidgets.QMessageBox, "question", fake_question)
    window.model.set_param("gvf_mu", 0.1)
    assert window.model.dirty
    assert not window.close()  # cancelled: stays open
    assert len(asked) == 1 and window.isVisible()
    assert window.close()  # discard
    assert len(asked) == 2


def test_no_prompt_when_saved(window, monkeypatch):
    monkeypatch.setattr(
        QtWidgets.QMessageBox, "question", lambda *a, **k: pytest.fail("should not ask when nothing changed")
    )
    assert not window.model.dirty
    assert window.close()


def test_panels_speak_the_inputs_units_and_sliders_keep_values(qtbot):
    """A feet input: the alignment panel says ft and shows feet; a slider never rounds a value."""
    model = ViewerModel(small_holes(unit="ft"))
    win = MainWindow(model, debounce_ms=10)
    win.show()
    try:
        qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
        assert "(ft)" in win._unit_labels[0].text() and "(ft)" in win._unit_labels[1].text()
        h = win.model.holes  # the bench pairs are elevations in feet too
        assert win.bench_combo.itemText(0) == f"{h.bench_z_input(0):g} -> {h.bench_z_input(1):g} ft"
        t_m = win.model.current_translation_m()
        assert t_m is not None
        np.testing.assert_allclose([win.dx_spin.value(), win.dy_spin.value()], np.divide(t_m, 0.3048), atol=0.01)
        spacing = win.param_controls["snake_max_iterations"]  # any slider: values set are kept exactly
        ctl = win.param_controls["entropy_threshold"]
        ctl.set_value(0.5)
        assert ctl.value() == 0.5
        ctl.slider.setValue(0.5)  # as the user leaves it at the label's 0.5
        assert win.model.param("entropy_threshold") == 0.5
        assert spacing.toolTip() and spacing.slider.toolTip() == spacing.toolTip()
    finally:
        win.model.dirty = False
        win.close()


def test_a_slider_shows_a_projects_value_past_its_typical_range(qtbot):
    """A project's search radius of 200 ft (slider 21.5-86 ft) showed 86 on the slider, and 3000 snake
    iterations showed 1500, while the model used 200 and 3000."""
    model = ViewerModel(small_holes(unit="ft"), cache=False)
    model.set_param("search_radius_m", 200 * 0.3048)
    model.set_param("snake_max_iterations", 3000)
    model.set_param("gvf_mu", 0.001)
    win = MainWindow(model, auto_run=False)
    win.show()
    try:
        assert win.param_controls["search_radius_m"].slider.value() == pytest.approx(200.0)
        assert win.param_controls["snake_max_iterations"].slider.value() == 3000
        assert win.param_controls["gvf_mu"].slider.value() == pytest.approx(0.001)
        for name in ("search_radius_m", "snake_max_iterations", "gvf_mu"):
            assert win.param_controls[name].value() == model.param(name)
    finally:
        win.model.dirty = False
        win.close()


def test_an_auto_parameter_shows_no_value_the_model_does_not_use(window):
    """The alignment cell size and morph speed clamp are derived per geozone when auto: their greyed sliders
    read the range's lower end (2.248 ft on Kennecott, a tenth of a spacing), which the model does not use."""
    spacing = window.model.holes.hole_spacing_m
    for name in ("correspondence_cell_size_m", "speed_clamp_m"):
        ctl = window.param_controls[name]
        assert ctl.auto.isChecked() and not ctl.slider.isVisibleTo(ctl), name
    radius = window.param_controls["search_radius_m"]  # 1.6 spacings: known ahead, shown
    assert radius.auto.isChecked() and radius.slider.isVisibleTo(radius)
    assert radius.slider.value() == pytest.approx(1.6 * spacing, abs=1e-3)
    ctl = window.param_controls["speed_clamp_m"]
    ctl.auto.setChecked(False)  # a value of the user's: the slider is back, and what it reads is used
    assert ctl.slider.isVisibleTo(ctl) and ctl.slider.isEnabled()
    assert window.model.param("speed_clamp_m") == pytest.approx(ctl.slider.value(), abs=1e-3)
    ctl.auto.setChecked(True)
    assert window.model.param("speed_clamp_m") is None and not ctl.slider.isVisibleTo(ctl)


def test_clicking_a_hole_reports_its_id_and_grade(qtbot, tmp_path):
    """A click (press and release in place) on a known hole reports its id, geozone, bench and grade."""
    from bgm_viewer.scene import world_to_pixels

    holes = small_holes()
    table = pd.DataFrame(
        {
            "x": holes.xy[:, 0],
            "y": holes.xy[:, 1],
            "z": holes.z,
            "geozone": holes.geozone,
            "hole_id": [f"H{i:04d}" for i in range(len(holes.xy))],
            "cu_pct": np.round(np.arange(len(holes.xy)) * 0.001, 3),
        }
    )
    path = tmp_path / "holes.csv"
    table.to_csv(path, index=False)
    win = MainWindow(ViewerModel(str(path)), debounce_ms=10)
    win.show()
    try:
        qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
        win.set_camera("top")
        h = win.model.holes
        i = int(h.on_bench(0)[len(h.on_bench(0)) // 2])
        z = win.scene.view.z(h.bench_levels_m[0])
        col, row = world_to_pixels(win.plotter, np.array([[*h.xy[i], z]]))[0]
        x, y = int(round(col)), int(round(win.plotter.window_size[1] - 1 - row))
        iren = win.plotter.iren.interactor
        for event in ("LeftButtonPressEvent", "LeftButtonReleaseEvent"):
            iren.SetEventInformation(x, y, 0, 0)
            iren.InvokeEvent(event)
        want = table.iloc[
            int(np.argmin(np.hypot(table.x - h.xy[i, 0] - h.frame.origin_x, table.y - h.xy[i, 1] - h.frame.origin_y)))
        ]
        assert want.hole_id in win.picked_label.text()
        assert f"cu_pct {want.cu_pct}" in win.statusBar().currentMessage()
        assert f"geozone {want.geozone}" in win.statusBar().currentMessage()
    finally:
        win.model.dirty = False
        win.close()


def test_exports_the_view_at_a_chosen_size_and_the_shown_surfaces(window, tmp_path):
    from PIL import Image

    png = tmp_path / "view.png"
    window.export_screenshot(png, (640, 360))
    img = np.asarray(Image.open(png))
    assert img.shape[:2] == (360, 640) and img[..., :3].std() > 5
    written = window.export_surfaces(tmp_path / "surfaces")
    assert set(written) == set(window.model.result.surfaces)
    for geozone, files in written.items():
        assert {"ply", "obj", "stl"} <= set(files) and all(p.stat().st_size > 0 for p in files.values())
        assert f"\n8\n{geozone}\n" in files["dxf"].read_text()  # its faces on the geozone's DXF layer
    assert "Shift" in __import__("bgm_viewer.app").app.SHORTCUTS_HTML


def test_the_window_picture_holds_the_rendered_view_and_the_docks(qtbot, tmp_path):
    from qtpy import QtGui

    from bgm_viewer.model import bodies
    from bgm_viewer.palette import BACKGROUND, geozone_colours
    from bgm_viewer.window_gallery import WINDOW_SIZE, window_picture

    holes = small_holes()
    out = window_picture(holes, ("blastholes", "contours", "surfaces"), tmp_path / "window.png")
    picture = QtGui.QImage(str(out)).convertToFormat(QtGui.QImage.Format.Format_RGB888)
    assert (picture.width(), picture.height()) == WINDOW_SIZE
    img = np.frombuffer(picture.constBits(), np.uint8, picture.sizeInBytes())
    img = img.reshape(picture.height(), picture.bytesPerLine())[:, : 3 * picture.width()].reshape(*WINDOW_SIZE[::-1], 3)
    # the 3D view (an OpenGL surface a widget grab leaves black) sits between the docks
    view = img[:, WINDOW_SIZE[0] // 3 : 2 * WINDOW_SIZE[0] // 3]
    assert np.all(view == np.asarray(BACKGROUND, np.uint8), axis=-1).mean() > 0.2
    shown = bodies(holes)  # the host rock's holes are unticked so that the bodies show
    for g, rgb in geozone_colours(holes.geozones).items():
        drawn = np.all(view == np.asarray(rgb, np.uint8), axis=-1).sum()
        assert drawn > 20 if g in shown else drawn == 0, f"{g}: {drawn} pixels"
    # the docks are drawn too: the left third is mostly Qt's light panels, not the view
    assert img[:, : WINDOW_SIZE[0] // 6].mean() > 150


def test_the_window_gallery_asks_no_one_to_restore_a_tables_autosave(qtbot, monkeypatch, tmp_path):
    """`xvfb-run python -m bgm_viewer.window_gallery` on a table the viewer had autosaved (a session that ended
    without saving) put the modal "Restore unsaved work?" over the window: no one answers it there, and the
    gallery waited for good. It asks nothing now, and the autosave stays for the geologist's next session."""
    from bgm_viewer.window_gallery import window_picture

    h = small_holes()
    table = pd.DataFrame({"x": h.xy[:, 0], "y": h.xy[:, 1], "z": h.z, "geozone": h.geozone})
    table.to_csv(tmp_path / "holes.csv", index=False)
    earlier = ViewerModel(tmp_path / "holes.csv", cache=False)
    earlier.set_param("snake_max_iterations", 100)
    autosave = earlier.autosave(now=earlier.clock() + 60)  # an earlier session's work, never saved
    assert autosave is not None and autosave.is_file()
    asked = []
    monkeypatch.setattr(QtWidgets.QMessageBox, "question", lambda *a, **k: asked.append(a[1:3]))
    window_picture(tmp_path / "holes.csv", ("blastholes", "contours"), tmp_path / "window.png")
    assert asked == [] and (tmp_path / "window.png").is_file()
    assert autosave.is_file()


def test_the_window_opens_on_what_the_command_line_asked_for(qtbot):
    """`bgm view --geozone --bench --layers --camera --exaggeration` chose a screenshot's view and not the window's."""
    from qtpy.QtCore import Qt

    from bgm_viewer.app import viewer_window
    from bgm_viewer.layer_names import DEFAULT_VISIBLE, LAYER_NAMES

    def shown(win) -> set[str]:
        items = {n: win.layer_list.findItems(n, Qt.MatchFlag.MatchExactly)[0] for n in LAYER_NAMES}
        return {n for n, item in items.items() if item.checkState() == Qt.CheckState.Checked}

    def looks_down(win) -> bool:
        return abs(win.plotter.camera.direction[2]) > 0.99

    holes = small_holes()
    for asked in ({"geozone": "g2", "bench": 1, "layers": "contours,Surfaces", "camera": "top"}, {}):
        win = viewer_window(holes, vertical_exaggeration=3 if asked else None, **asked)
        try:
            win.show()
            qtbot.waitUntil(lambda w=win: not w.busy and w.model.result.complete, timeout=60_000)
            qtbot.wait(50)  # the camera is set once the window is laid out
            selected = (win.model.selection.geozone, win.model.selection.bench)
            if asked:
                assert shown(win) == {"contours", "surfaces"} and selected == ("g2", 1)
                assert win.model.vertical_exaggeration == 3.0 and looks_down(win)
            else:
                assert shown(win) == set(DEFAULT_VISIBLE) and selected != ("g2", 1) and not looks_down(win)
        finally:
            win.model.dirty = False
            win.close()


def test_an_alignment_the_model_refuses_is_said_in_the_status_bar(window, qtbot):
    """Ctrl+arrow on a source the bench lacks raised out of the key's slot instead of saying why."""
    window.component_spin.setValue(40)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    window.nudge(1.0, 0.0)
    assert "does not exist" in window.statusBar().currentMessage()
    assert not window.model.overrides and not window.busy


def test_a_run_superseded_or_failing_raises_nothing_in_the_window(window, qtbot, monkeypatch):
    """A run cancelled in the middle of a step (switching geozones on Kennecott) raised ``Cancelled``
    in Qt's thread, and a failed run its error, besides saying it in the status bar."""
    import threading

    import bgm_viewer.app as app
    from bgm_viewer.model import Cancelled

    started = threading.Event()

    def slow_step(inputs, previous, from_step, cancelled, until="surface"):
        started.set()
        while not cancelled():  # a long step, cancelled half-way: compute's run.check() raises
            threading.Event().wait(0.01)
        raise Cancelled()
        yield

    monkeypatch.setattr(app, "compute", slow_step)
    with qtbot.captureExceptions() as raised:
        window.geozone_combo.setCurrentText("g2")
        assert started.wait(10)
        window.geozone_combo.setCurrentText("g3")  # cancels the first
        qtbot.wait(300)
        window._cancel()  # the second too (as closing the window does)
        qtbot.wait(300)
    assert not raised, raised[0][1]

    def failing(*args, **kwargs):
        raise ValueError("boom")
        yield

    monkeypatch.setattr(app, "compute", failing)
    with qtbot.captureExceptions() as raised:
        window.geozone_combo.setCurrentText("g1")
        qtbot.waitUntil(lambda: "boom" in window.statusBar().currentMessage(), timeout=10_000)
        qtbot.wait(100)
    assert not raised, raised[0][1]
    assert not window.busy


def test_a_run_failing_with_a_runtime_error_is_reported_and_ends(window, qtbot, monkeypatch):
    """superqt takes a RuntimeError for a deleted worker and drops it: the window said
    "running..." for ever, and stayed busy (``wait_idle`` waited out its timeout)."""
    import bgm_viewer.app as app

    def failing(*args, **kwargs):
        raise RuntimeError("SuperLU failed")
        yield

    monkeypatch.setattr(app, "compute", failing)
    window.geozone_combo.setCurrentText("g2")
    qtbot.waitUntil(lambda: not window.busy, timeout=10_000)
    assert "failed: RuntimeError: SuperLU failed" in window.statusBar().currentMessage()


def test_exported_surfaces_keep_the_bodies_the_body_filter_hides(window, qtbot, tmp_path):
    """The filter's tooltip says the exported surfaces keep the small bodies; they were dropped."""
    import trimesh

    g = max(
        window.model.result.surfaces, key=lambda k: len(window.model.result.surfaces[k].split(only_watertight=False))
    )
    whole = window.model.result.surfaces[g]
    volumes = sorted(abs(b.volume) for b in whole.split(only_watertight=False))
    assert len(volumes) > 1
    # only the biggest body is shown: the box counts whole units, and the biggest body's volume itself, rounded up
    # past it, hid every body
    window.min_volume.setValue((volumes[-2] + volumes[-1]) / 2 / window._mpu**3)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    assert len(window.model.result.surfaces[g].faces) < len(whole.faces)
    assert "keep" in window.min_volume.toolTip()
    written = window.export_surfaces(tmp_path)
    exported = trimesh.load(written[g]["ply"], force="mesh")
    assert len(exported.faces) == len(whole.faces)
    window.min_volume.setValue(2 * volumes[-1] / window._mpu**3)  # every body hidden
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    assert g not in window.model.result.surfaces
    exported = trimesh.load(window.export_surfaces(tmp_path / "all hidden")[g]["ply"], force="mesh")
    assert len(exported.faces) == len(whole.faces)


def test_a_surface_is_not_exported_before_the_last_change_is_in_it(window, qtbot, tmp_path):
    """Exported right after an alignment change, the surface was the one from before it."""
    auto = window.model.current_translation_m()
    window.dx_spin.setValue(auto[0] + 8.0)
    window.apply_translation()
    assert window.busy
    for export in (window.export_surface, window.export_surfaces):
        with pytest.raises(ValueError, match="recomputed"):
            export(tmp_path / "surface.obj")
    assert not list(tmp_path.iterdir())
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    window.export_surface(tmp_path / "surface.obj")
    assert (tmp_path / "surface.obj").stat().st_size > 0


def test_no_surface_is_exported_after_a_failed_run_until_one_succeeds(window, qtbot, monkeypatch, tmp_path):
    """A run that failed left the surfaces of the parameters before it on screen, and exported them as current."""
    import core.model.session as session

    extract = session.extract_bench

    def failing(*args, **kwargs):
        raise ValueError("boom")

    monkeypatch.setattr(session, "extract_bench", failing)
    window.param_controls["snake_max_iterations"].slider.setValue(10)
    qtbot.waitUntil(lambda: not window.busy, timeout=10_000)
    assert "failed: ValueError: boom" in window.statusBar().currentMessage()
    for export in (window.export_surface, window.export_surfaces):
        with pytest.raises(ValueError, match="last run failed.*earlier parameters"):
            export(tmp_path / "surface.obj")
    assert not list(tmp_path.iterdir())
    monkeypatch.setattr(session, "extract_bench", extract)
    window.param_controls["snake_max_iterations"].slider.setValue(12)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    window.export_surface(tmp_path / "surface.obj")
    assert (tmp_path / "surface.obj").stat().st_size > 0


def test_saving_and_exporting_say_what_was_written_where(window, tmp_path):
    """Export shown surfaces took seconds on Kennecott with no progress, and it, Export surface and Save
    project ended with no word of what they had written."""
    said: list[str] = []
    window.statusBar().messageChanged.connect(said.append)
    written = window.export_surfaces(tmp_path / "surfaces")
    n = len(written)
    assert n > 1 and f"exporting the surface of geozone {sorted(written)[-1]} ({n} of {n})..." in said
    assert said[-1].startswith(f"exported {n} surfaces (") and str((tmp_path / "surfaces").resolve()) in said[-1]
    window.export_surface(tmp_path / "g1.obj")
    assert said[-1] == f"exported the surface of geozone g1 to {(tmp_path / 'g1.obj').resolve()}"
    window.model.project_path = str(tmp_path / "p.bgm.json")
    assert window.save_project()
    assert said[-1] == f"saved the project to {(tmp_path / 'p.bgm.json').resolve()}"
    window.export_screenshot(tmp_path / "view.png", (64, 48))
    assert said[-1] == f"exported the view to {(tmp_path / 'view.png').resolve()}"


def test_the_view_a_project_saves_marks_it_unsaved_and_reopens_as_it_was(window, qtbot, tmp_path):
    """The selection and the exaggeration are saved, but changing them left the project "saved": closing lost
    them without a prompt. The surface scope and body filter were not saved: a project reopened showed others."""
    for change in (
        lambda: window.geozone_combo.setCurrentText("g2"),
        lambda: window.ve_spin.setValue(5.0),
        lambda: window.surface_scope.setCurrentText("ticked geozones"),
        lambda: window.legend.set_shown(["g2", "g3"]),
        lambda: window.min_holes.setValue(3),
    ):
        window.model.dirty = False
        change()
        assert window.model.dirty
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    assert set(window.model.result.surfaces) == {"g2", "g3"}
    path = tmp_path / "p.bgm.json"
    window.model.save_project(path)
    window.legend.show_all()
    window.surface_scope.setCurrentText("all geozones")
    window.min_holes.setValue(0)
    window.open_project(path)
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert window.surface_scope.currentText() == "ticked geozones" and window.legend.shown() == ["g2", "g3"]
    assert window.min_holes.value() == 3 and window.model.min_body_holes == 3
    assert set(window.model.result.surfaces) == {"g2", "g3"} and not window.model.dirty


def test_a_project_reopens_with_the_camera_and_the_layers_it_was_saved_with(window, qtbot, tmp_path):
    """A geologist who set up a view (turned the camera, chose the layers), saved the project and opened it again
    found the default camera and layers. Both are saved now; a project saved before them opens as before."""
    import json

    from bgm_viewer.layer_names import DEFAULT_VISIBLE

    def camera():
        c = window.plotter.camera
        return np.array([c.GetPosition(), c.GetFocalPoint(), c.GetViewUp()])

    def shown():
        ticked = {
            window.layer_list.item(i).text()
            for i in range(window.layer_list.count())
            if window.layer_list.item(i).checkState() == QtCore.Qt.CheckState.Checked
        }
        assert ticked == {layer.name for layer in window.scene.layers if layer.visible}  # the panel says what is drawn
        return ticked

    _turn_camera(window)
    window.model.dirty = False
    window.set_layer_visible("trajectories", False)
    window.set_layer_visible("GVF", True)
    assert window.model.dirty  # a layer shown or hidden is a change the project saves
    saved_camera, saved_layers = camera(), shown()
    window.model.project_path = str(tmp_path / "p.bgm.json")
    assert window.save_project()

    window.set_camera("iso")
    window.set_layer_visible("GVF", False)
    window.set_layer_visible("trajectories", True)
    window.open_project(tmp_path / "p.bgm.json")
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    np.testing.assert_allclose(camera(), saved_camera, rtol=1e-6, atol=1e-6)  # not fitted again once drawn
    assert shown() == saved_layers and "GVF" in saved_layers and "trajectories" not in saved_layers
    assert not window.model.dirty

    data = json.loads((tmp_path / "p.bgm.json").read_text())
    del data["parameters"]["viewer"]["camera"], data["parameters"]["viewer"]["layers"]  # saved before them
    (tmp_path / "old.bgm.json").write_text(json.dumps(data))
    window.open_project(tmp_path / "old.bgm.json")
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert shown() == set(DEFAULT_VISIBLE)
    iso = np.array((1.0, 1.6, -1.1))  # the default view's direction (SceneRenderer.set_camera)
    np.testing.assert_allclose(window.plotter.camera.GetDirectionOfProjection(), iso / np.linalg.norm(iso), atol=1e-6)


def test_surfaces_of_the_selected_geozone_follow_the_selection(window, qtbot, tmp_path):
    """With "surfaces of: selected geozone", the geozone selected when it was chosen kept its surface on
    screen (and in Export shown surfaces) beside every geozone selected after it."""
    window.surface_scope.setCurrentText("selected geozone")
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    assert set(window.model.result.surfaces) == {"g1"}
    window.geozone_combo.setCurrentText("g2")
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert window.model.selection.geozone == "g2"
    assert set(window.model.result.surfaces) == {"g2"}
    assert set(window.export_surfaces(tmp_path)) == {"g2"}


def test_a_single_bench_says_there_is_no_bench_below(qtbot, tmp_path):
    """One bench drilled: the bench pair read "684.98 -> nan m", and once the run was done the status bar
    still said the trajectories were empty because the pair was "not corresponded yet"."""
    h = small_holes()
    top = h.bench == 0
    table = pd.DataFrame(
        {"x": h.xy[top, 0] + 650_000, "y": h.xy[top, 1] + 7_400_000, "z": h.z[top], "geozone": h.geozone[top]}
    )
    table.to_csv(tmp_path / "one.csv", index=False)
    win = MainWindow(ViewerModel(tmp_path / "one.csv", cache=False), debounce_ms=10)
    win.show()
    try:
        qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
        labels = [win.bench_combo.itemText(i) for i in range(win.bench_combo.count())]
        assert labels == [f"{win.model.holes.bench_z_input(0):g} m"]
        said = win.statusBar().currentMessage()
        assert said.startswith("done") and "trajectories is empty: the input has one bench" in said, said
        assert "not corresponded yet" not in said and "not computed yet" not in said
    finally:
        win.close()


def test_the_bench_panel_says_which_benches_are_hidden_after_a_project_is_opened(window, qtbot, tmp_path):
    """A bench unticked, then File > Open project (the same input): the panel ticked every bench again
    while the view still hid that one's holes and contours."""
    window.sections.benches.item(0).setCheckState(QtCore.Qt.CheckState.Unchecked)
    z0 = float(window.model.holes.bench_levels_m[0])
    assert window.scene.hidden_benches_m == {z0}
    path = tmp_path / "p.json"
    window.model.save_project(path)
    window.open_project(path)
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    items = [window.sections.benches.item(i) for i in range(window.sections.benches.count())]
    ticked = [it.checkState() == QtCore.Qt.CheckState.Checked for it in items]
    drawn = [window.scene.view.shows("g1", float(it.data(QtCore.Qt.ItemDataRole.UserRole))) for it in items]
    assert ticked == drawn == [False, True, True]


def test_an_exported_surface_is_on_the_dxf_layer_bgm_build_puts_it_on(qtbot, tmp_path):
    """Geozones "ore 1" and "ore_1" are both ore_1 once made R12-safe: bgm build puts the second on ore_1_2,
    File > Export surface put it on ore_1, the other geozone's layer (mine software merges the two)."""
    import ezdxf

    from core.io.blastholes import blastholes_from_table
    from core.model.build import build

    h = small_holes()
    labels = pd.Series(h.geozone).replace({"g1": "ore 1", "g2": "ore_1"}).to_numpy()
    table = pd.DataFrame({"x": h.xy[:, 0], "y": h.xy[:, 1], "z": h.z, "geozone": labels})
    holes = blastholes_from_table(table, source="relabelled")
    model = ViewerModel(holes, cache=False)
    model.select("ore_1", 0, 0)
    win = MainWindow(model, debounce_ms=10)
    win.show()
    try:
        qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
        win.export_surface(tmp_path / "ore_1.dxf")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            build(holes, tmp_path / "out", geozones=["ore_1"], formats=("dxf",), evaluate=False, workers=1)
        built = next((tmp_path / "out").glob("ore_1*/surface.dxf"))
        layers = [{e.dxf.layer for e in ezdxf.readfile(p).modelspace()} for p in (tmp_path / "ore_1.dxf", built)]
        assert layers[0] == layers[1] == {"ore_1_2"}
    finally:
        win.model.dirty = False  # selected: no prompt on closing
        win.close()


def test_a_layer_emptied_by_hiding_every_geozone_says_so(window, qtbot):
    """Every geozone unticked in the legend: the status bar said "contours is empty: no contours are extracted
    yet" and "blastholes is empty: nothing to draw for this selection" after each run."""
    window.legend.hide_all()
    window.request("surface", immediate=True)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    said = window.statusBar().currentMessage()
    for name in ("blastholes", "contours", "surfaces"):
        assert f"{name} is empty: what it would draw is hidden" in said, said
    assert "not extracted yet" not in said and "nothing to draw for this selection" not in said


def test_opening_another_input_shows_its_own_surface_settings(window, qtbot, tmp_path):
    """After File > Open, the Surfaces dock still said m³, showed the old body filter (which no
    longer applied) and named the old input's host rock."""
    from core.io.blastholes import FEET_TO_METRES

    window.min_volume.setValue(500.0)
    window.min_holes.setValue(3)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    h = small_holes()
    feet = pd.DataFrame(
        {
            "x": h.xy[:, 0] / FEET_TO_METRES + 10_000,
            "y": h.xy[:, 1] / FEET_TO_METRES + 20_000,
            "z": h.z / FEET_TO_METRES,
            "geozone": [f"z{g}" for g in h.geozone],
        }
    )
    feet.to_csv(tmp_path / "feet.csv", index=False)
    window.open_input(tmp_path / "feet.csv")
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert window.model.holes.frame.length_unit == "ft"
    assert window._volume_label.text() == "min body volume (ft³)"
    assert (window.min_volume.value(), window.min_holes.value()) == (0.0, 0)
    assert (window.model.min_body_volume_m3, window.model.min_body_holes) == (0.0, 0)
    assert window.surface_scope.currentText() == "all but the host rock (zg0)"


def test_another_input_opened_is_labelled_in_its_own_coordinates_and_units(window, qtbot, tmp_path):
    """After File > Open of a table in feet on another mine grid, the axes and the scale bar were still those of
    the first input: its eastings, northings and elevations, in metres."""
    from core.io.blastholes import FEET_TO_METRES

    h = small_holes()
    feet = pd.DataFrame(
        {
            "x": h.xy[:, 0] / FEET_TO_METRES + 10_000,
            "y": h.xy[:, 1] / FEET_TO_METRES + 20_000,
            "z": h.z / FEET_TO_METRES,
            "geozone": h.geozone,
        }
    )
    feet.to_csv(tmp_path / "feet.csv", index=False)
    window.open_input(tmp_path / "feet.csv")
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    axes = window.plotter.renderer.cube_axes_actor
    assert "(ft)" in axes.GetXTitle() and "(ft)" in axes.GetZTitle()
    lo, hi = axes.GetXAxisRange()
    assert lo <= feet.x.min() + 1 and hi >= feet.x.max() - 1 and hi - lo < 1.2 * (feet.x.max() - feet.x.min()) + 50
    lo, hi = axes.GetYAxisRange()
    assert lo <= feet.y.min() + 1 and hi >= feet.y.max() - 1
    benches_ft = window.model.holes.frame.z_to_input(window.model.holes.bench_levels_m)
    z_lo, z_hi = axes.GetZAxisRange()
    assert z_lo <= benches_ft.min() + 1 and z_hi >= benches_ft.max() - 1
    assert window.renderer._ruler.GetTitle().endswith(" ft")


def test_opening_a_project_says_which_overrides_it_leaves_unused(window, monkeypatch, tmp_path):
    """File > Open project: check_project's warnings (an override of a geozone or bench the
    input lacks is not used) went to stderr only, and the geologist thought it applied."""
    import json

    path = tmp_path / "p.json"
    window.model.save_project(path)
    data = json.loads(path.read_text())
    data["overrides"] = [{"geozone": "nope", "source_z": 1.0, "source": 0, "translation": [1.0, 0.0]}]
    path.write_text(json.dumps(data))
    shown = []
    monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName", lambda *a, **k: (str(path), ""))
    monkeypatch.setattr(QtWidgets.QMessageBox, "warning", lambda parent, title, text, *a: shown.append(text))
    with pytest.warns(UserWarning, match="is not used"):  # on stderr as before
        window.open_project_dialog()
    assert len(shown) == 1 and "'nope'" in shown[0] and "is not used" in shown[0]


def test_opening_a_project_naming_a_component_the_bench_lacks_says_so_and_the_model_runs(window, monkeypatch, tmp_path):
    """A hand-edited project naming a component that does not exist opened without a word; the run then
    failed that geozone's model. Checked on opening, on the window's thread, it traced every bench with an
    override there (2-4 s a bench on Kennecott): the window froze. The run checks it now, off that thread,
    and what it drops is said as opening says the rest."""
    import json
    import threading

    from core.model import session

    path = tmp_path / "p.json"
    window.model.save_project(path)
    data = json.loads(path.read_text())
    z = window.model.holes.bench_z_input(0)
    data["overrides"] = [{"geozone": "g1", "source_z": z, "source": 7, "translation": [1.0, 0.0]}]
    data["parameters"]["snake_max_iterations"] = 300  # benches no earlier run traced
    path.write_text(json.dumps(data))
    shown, on_main = [], []
    real = session.extract_bench

    def spy(*args, **kw):  # core's tracing of a bench, and the thread it is called on
        on_main.append(threading.current_thread() is threading.main_thread())
        return real(*args, **kw)

    monkeypatch.setattr(session, "extract_bench", spy)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName", lambda *a, **k: (str(path), ""))
    monkeypatch.setattr(QtWidgets.QMessageBox, "warning", lambda parent, title, text, *a: shown.append(text))
    window.open_project_dialog()
    assert not any(on_main) and shown == []  # opened without tracing a bench here (the run traces)
    assert window.wait_idle()
    assert on_main and not any(on_main), on_main  # traced by the run, off the window's thread
    QtWidgets.QApplication.processEvents()
    assert len(shown) == 1 and str(path) in shown[0] and "'g1'" in shown[0] and "dropped" in shown[0], shown
    assert "source component 7" in shown[0]
    assert window.model.overrides == [] and not window.model.dirty and not window.model.can_undo
    assert window.model.result.complete and "model" not in window.model.result.errors


@pytest.mark.parametrize("exaggeration", [50.0, 0.05, 0.004])
def test_the_exaggeration_panel_shows_the_exaggeration_drawn(qtbot, exaggeration):
    """`bgm view --exaggeration 50` (or a project's) drew 50 while the panel, limited to 0.1-20, said 20."""
    from bgm_viewer.app import viewer_window

    win = viewer_window(small_holes(), vertical_exaggeration=exaggeration)
    try:
        assert win.scene.vertical_exaggeration == win.model.vertical_exaggeration == exaggeration
        assert win.ve_spin.value() == exaggeration
    finally:
        win.model.dirty = False
        win.close()


def test_a_projects_exaggeration_below_the_boxs_range_is_shown_and_kept(window, tmp_path):
    """The box stopped at 0.01: a project's 0.004 was shown as 0.01, and the model set to it (unsaved)."""
    path = tmp_path / "p.bgm.json"
    window.model.vertical_exaggeration = 0.004
    window.model.save_project(path)
    window.model.vertical_exaggeration = 2.0
    window.open_project(path)
    assert window.ve_spin.value() == window.model.vertical_exaggeration == window.scene.vertical_exaggeration == 0.004
    assert not window.model.dirty


def test_a_screenshot_named_in_capitals_or_without_an_extension_is_written(window, tmp_path):
    """File > Export screenshot: View.PNG and a name the dialog left without .png failed with
    PyVista's "Unsupported extension" (of the temporary file's random name, for the latter)."""
    assert window.export_screenshot(tmp_path / "View.PNG", (320, 240)) == tmp_path / "View.PNG"
    assert window.export_screenshot(tmp_path / "view", (320, 240)) == tmp_path / "view.png"
    for name in ("View.PNG", "view.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="no picture format .gif"):
        window.export_screenshot(tmp_path / "view.gif")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["View.PNG", "view.png"]


def test_an_elevation_section_stays_at_its_elevation_when_the_exaggeration_changes(window):
    """The section plane is drawn in display z: after a change of vertical exaggeration it cut another elevation."""

    def cut_elevation() -> float:
        axis, value, _ = window.renderer.clip
        assert axis == "z"
        view = window.scene.view
        return view.z_ref + (value - view.z_ref) / view.vertical_exaggeration

    window.sections.axis.setCurrentIndex(3)  # elevation (z)
    window.sections.position.setValue(700)
    before = cut_elevation()
    window.ve_spin.setValue(5.0)
    assert window.scene.view.vertical_exaggeration == 5.0
    assert cut_elevation() == pytest.approx(before, abs=0.05)  # the glyphs of the holes do not scale


def _another_input(tmp_path: Path) -> Path:
    """A small table of another mine, twice as wide as :func:`small_holes`'s, written as CSV."""
    from core.synthetic.blobs import make_mine, sample_blastholes

    mine = make_mine(seed=7, n_benches=3, extent_m=(280.0, 90.0), n_pods=1)
    path = tmp_path / "another.csv"
    sample_blastholes(mine, seed=8).to_csv(path, index=False)
    return path


def test_a_section_is_placed_in_another_input_once_opened(window, qtbot, tmp_path):
    """File > Open with a section on: the cut and its plane handle stayed where they cut the old input."""
    window.sections.axis.setCurrentIndex(1)  # easting (x)
    window.sections.position.setValue(900)
    old_cut = window.renderer.clip[1]
    window.open_input(_another_input(tmp_path))
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=120_000)
    lo, hi = window.renderer.data_bounds()[:2]
    axis, value, _ = window.renderer.clip
    assert axis == "x" and (value - lo) / (hi - lo) == pytest.approx(0.9, abs=0.02)
    assert abs((old_cut - lo) / (hi - lo) - 0.9) > 0.1  # a cut left where it was would not be at 90%


def test_a_click_reports_what_is_shown_not_what_a_section_hides(window):
    """With only the deepest bench shown, a click on its holes reported holes of the benches
    above (hidden by the elevation range): the picker ignored the clipping planes."""
    from bgm_viewer.scene import world_to_pixels

    h = window.model.holes
    for name in ("contours", "snake", "trajectories", "surfaces", "predicted contours"):
        window.set_layer_visible(name, False)
    window.set_camera("top")
    deep = h.n_benches - 1
    z_input = float(h.frame.z_to_input(h.bench_levels_m[deep]))
    window.sections.set_elevation_range(z_input - 1.0, z_input + 1.0)
    z = window.scene.view.z(h.bench_levels_m[deep])
    on_bench = h.on_bench(deep)
    reported = []
    for i in on_bench[:: max(len(on_bench) // 12, 1)]:
        col, row = world_to_pixels(window.plotter, np.array([[*h.xy[i], z]]))[0]
        info = window.pick(int(round(col)), int(round(window.plotter.window_size[1] - 1 - row)))
        reported.append(None if info is None else info[f"bench ({h.frame.length_unit})"])
    assert reported and set(reported) == {z_input}
    # contours are picked as before: a click on a contour's vertex selects its geozone
    window.sections.set_elevation_range(-1e5, 1e5)
    window.set_layer_visible("blastholes", False)
    window.set_layer_visible("contours", True)
    g, z_m, poly = window.scene["contours"].items[0]
    x, y = poly.exterior.coords[0]
    col, row = world_to_pixels(window.plotter, np.array([[x, y, window.scene.view.z(z_m)]]))[0]
    info = window.pick(int(round(col)), int(round(window.plotter.window_size[1] - 1 - row)))
    assert info is not None and info["geozone"] == g


def test_closing_the_window_during_a_run_waits_for_its_worker(qtbot):
    """A worker still running when Python exits finds its signals deleted and prints a traceback."""
    model = ViewerModel(small_holes())
    model.select("g1", 0, 0)
    win = MainWindow(model, debounce_ms=10)
    win.show()
    qtbot.waitUntil(lambda: win.busy, timeout=10_000)  # the first run has started
    win.model.dirty = False
    win.close()
    assert QtCore.QThreadPool.globalInstance().activeThreadCount() == 0


def test_a_table_opened_in_feet_with_its_geozone_column_named_reopens_so_from_its_project(
    window, qtbot, monkeypatch, tmp_path
):
    """A project saved after `bgm view holes.csv --units ft --geozone-column DOMAIN_CODE` reopened without
    either (File > Open project: "no geozone column", or feet read as metres); and File > Open blastholes
    offered no units or columns. The project reads it so again, and the dialog sets both."""

    from core.io.blastholes import read_blastholes
    from core.synthetic.blobs import make_mine, sample_blastholes

    table = sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    csv = tmp_path / "holes.csv"
    table.rename(columns={"geozone": "DOMAIN_CODE"}).to_csv(csv, index=False)
    model = ViewerModel(read_blastholes(csv, geozone="DOMAIN_CODE", length_unit="ft"))  # as bgm view reads it
    model.input_path = str(csv)
    model.save_project(tmp_path / "p.json")
    window.open_project(tmp_path / "p.json")
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert window.model.holes.frame.length_unit == "ft"
    assert window.model.holes.bench_height_m == pytest.approx(10 * 0.3048)

    from bgm_viewer import read_options

    def choose(dialog):
        assert dialog.columns["geozone"].findText("DOMAIN_CODE") >= 0  # the table's columns are offered
        dialog.units.setCurrentText("feet (ft)")
        dialog.columns["geozone"].setCurrentText("DOMAIN_CODE")
        return QtWidgets.QDialog.DialogCode.Accepted

    window.open_input(_another_input(tmp_path))  # another input in between
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName", lambda *a, **k: (str(csv), ""))
    monkeypatch.setattr(read_options.ReadOptionsDialog, "exec", choose)
    window.open_input_dialog()
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert window.model.holes.frame.length_unit == "ft" and "(ft)" in window.windowTitle()
    assert window.model.holes.bench_height_m == pytest.approx(10 * 0.3048)


@pytest.mark.parametrize("opened", ["cancelled", "a bad table", "another table"])
def test_unsaved_work_discarded_to_open_a_file_keeps_its_autosave_until_the_file_is_open(
    qtbot, monkeypatch, tmp_path, opened
):
    """File > Open blastholes, Discard, then the file dialog cancelled (or a table that fails to open): the
    autosave was deleted at Discard while the work stayed in the window, unsaved, and a crash then lost it."""
    from bgm_viewer import read_options

    h = small_holes()
    table = pd.DataFrame({"x": h.xy[:, 0], "y": h.xy[:, 1], "z": h.z, "geozone": h.geozone})
    table.to_csv(tmp_path / "holes.csv", index=False)
    table.drop(columns="geozone").to_csv(tmp_path / "bad.csv", index=False)
    table.to_csv(tmp_path / "other.csv", index=False)
    win = MainWindow(ViewerModel(tmp_path / "holes.csv", cache=False), debounce_ms=10)
    win.show()
    try:
        qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
        win.set_param("snake_max_iterations", 100)
        qtbot.waitUntil(lambda: not win.busy, timeout=60_000)
        autosave = win.model.autosave_path
        win.model.autosave(now=win.model.clock() + 60)  # written now, unless the window's timer did already
        assert autosave is not None and autosave.is_file()
        worked = win.model
        chosen = {
            "cancelled": "",
            "a bad table": str(tmp_path / "bad.csv"),
            "another table": str(tmp_path / "other.csv"),
        }
        said = []
        monkeypatch.setattr(
            QtWidgets.QMessageBox, "question", lambda *a, **k: QtWidgets.QMessageBox.StandardButton.Discard
        )
        monkeypatch.setattr(QtWidgets.QMessageBox, "warning", lambda parent, title, text, *a: said.append(text))
        monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName", lambda *a, **k: (chosen[opened], ""))
        monkeypatch.setattr(read_options.ReadOptionsDialog, "exec", lambda d: QtWidgets.QDialog.DialogCode.Accepted)
        win.open_input_dialog()
        if opened == "another table":  # discarded on purpose: not offered again
            assert win.model is not worked and not autosave.exists()
        else:
            assert win.model is worked and win.model.dirty and autosave.is_file()
            assert said == ([] if opened == "cancelled" else [said[0]]) and (not said or "geozone" in said[0])
        qtbot.waitUntil(lambda: not win.busy, timeout=60_000)
    finally:
        win.model.dirty = False
        win.close()


def test_the_next_bench_is_computed_off_the_windows_thread_and_a_stale_one_is_not_drawn(window, qtbot, monkeypatch):
    """Showing the uncertainty or suggested-holes layer ran core's band of the next bench (1-3.5 s on Kennecott)
    on the window's thread: the window froze. It runs in a worker thread now, said in the status bar, drawn when
    done as a synchronous NextBench draws it, and one whose geozone was changed meanwhile is not drawn."""
    import threading
    import time

    from bgm_viewer.sampling_layers import NextBench
    from core.model import uncertainty

    gate, on_main = threading.Event(), []
    real = uncertainty.geozone_uncertainty

    def slow(*args, **kw):  # core's band, held until the test lets it go
        on_main.append(threading.current_thread() is threading.main_thread())
        gate.wait(5)
        return real(*args, **kw)

    monkeypatch.setattr(uncertainty, "geozone_uncertainty", slow)
    start = time.perf_counter()
    window.set_layer_visible("uncertainty", True)
    assert time.perf_counter() - start < 2.0  # the window is not held by core
    qtbot.waitUntil(lambda: bool(on_main), timeout=10_000)
    assert on_main == [False]  # core's band is computed on another thread
    assert "computing the next bench" in window.statusBar().currentMessage()
    stale = window.scene["uncertainty"].next_bench
    assert stale.pending and not window.renderer.actors["uncertainty"]

    window._select(geozone="g2", bench=0, component=0)  # another model while the band is computed
    gate.set()
    with qtbot.waitSignal(window.nextBenchShown, timeout=120_000):
        pass
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    drawn = window.scene["uncertainty"].next_bench
    assert drawn is not stale and drawn.model is window.model.result.model and drawn.model.geozone == "g2"
    assert window.renderer.actors["uncertainty"] and "done in" in window.statusBar().currentMessage()
    m = window.model
    same = NextBench(m.holes, m.result.model, session=m.result.session)  # as a screenshot (and bgm build) draws it
    assert drawn.section.band.equals(same.section.band)
    np.testing.assert_allclose(drawn.section.inside_probability, same.section.inside_probability)
    np.testing.assert_allclose(drawn.suggestions_m, same.suggestions_m)


def test_a_band_superseded_by_a_slider_or_the_window_closing_stops_and_is_never_drawn(window, qtbot, monkeypatch):
    """The next bench's band went on to its end after a newer request (1-3.5 s of a core on Kennecott), and one
    whose slider was moved again was drawn while the new run had not yet replaced the model on screen. A request
    now cancels it at core's next step; its result is not drawn, and closing the window stops it too."""
    import threading

    import bgm_viewer.app as app
    from core.model import uncertainty

    gate, ends, begun = threading.Event(), [], []
    real = uncertainty.geozone_uncertainty

    def held(*args, **kw):  # core's band, held until the test lets it go; how it ended is recorded
        begun.append(True)
        gate.wait(10)
        try:
            out = real(*args, **kw)
        except Exception as exc:
            ends.append(type(exc).__name__)
            raise
        ends.append("finished")
        return out

    run_gate = threading.Event()
    compute = app.compute

    def held_run(*args, **kw):  # the new run, held before its first result: the old model stays on screen
        run_gate.wait(10)
        yield from compute(*args, **kw)

    monkeypatch.setattr(uncertainty, "geozone_uncertainty", held)
    monkeypatch.setattr(app, "compute", held_run)
    shown = []
    window.nextBenchShown.connect(lambda: shown.append(window.scene["uncertainty"].next_bench))
    window.set_layer_visible("uncertainty", True)
    qtbot.waitUntil(lambda: window._next_bench is not None, timeout=10_000)
    old = window._next_bench
    window.set_param("entropy_threshold", 0.2)  # a slider moved: a new run
    qtbot.waitUntil(lambda: window._pending_step is not None, timeout=10_000)
    gate.set()  # the old band computes on, while the new run waits
    qtbot.waitUntil(lambda: bool(ends), timeout=30_000)
    qtbot.wait(200)  # its result, had it one, reaches the window
    assert ends == ["Cancelled"] and shown == []  # stopped at core's next step, and nothing stale drawn
    assert window.scene["uncertainty"].next_bench is old and not window.renderer.actors["uncertainty"]

    with qtbot.waitSignal(window.nextBenchShown, timeout=120_000):
        run_gate.set()  # the new run, then its own band
    assert ends == ["Cancelled", "finished"] and shown[-1].model is window.model.result.model is not old.model

    gate.clear()
    bands = len(begun)
    window._select(geozone="g2", bench=0, component=0)  # another geozone, its band computing when the window closes
    qtbot.waitUntil(lambda: window._next_bench is not None and not window.busy, timeout=60_000)
    qtbot.waitUntil(lambda: len(begun) > bands, timeout=60_000)  # begun (on a loaded machine it starts later)
    cancel = window._cancel
    # Let go once closing has asked it to stop (a timer of 0.2 s let it run to its end on a loaded machine).
    monkeypatch.setattr(window, "_cancel", lambda: (cancel(), gate.set()))
    window.model.dirty = False  # no prompt for the slider's change
    window.close()  # waits for the workers: the band stops at its next step, not at its end
    assert ends[-1] == "Cancelled" and shown[-1].model.geozone != "g2", (ends, len(begun), bands)


def test_work_autosaved_before_a_crash_is_offered_restored_and_discarded_on_quitting(qtbot, monkeypatch, tmp_path):
    """An hour of alignment was lost to a crash: nothing was written between saves. `bgm view` now
    offers the autosave; restored, the work is back and unsaved; quitting without saving removes it."""
    from bgm_viewer.app import viewer_window
    from bgm_viewer.model import AUTOSAVE_DELAY_S
    from core.synthetic.blobs import make_mine, sample_blastholes

    csv = tmp_path / "holes.csv"
    table = sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    table.to_csv(csv, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        crashed = ViewerModel(csv)
        crashed.select("g1", 0, 0)
        crashed.run(until="correspondence")
    project = tmp_path / "p.bgm.json"
    crashed.save_project(project)
    crashed.nudge(6.0, -3.0)
    autosave = crashed.autosave(now=crashed.clock() + AUTOSAVE_DELAY_S)
    assert autosave is not None
    want = crashed.translation_m()

    asked = []

    def answer(parent, title, text, *a, **k):
        asked.append((title, text))
        return QtWidgets.QMessageBox.StandardButton.Yes if len(asked) == 1 else QtWidgets.QMessageBox.Discard

    monkeypatch.setattr(QtWidgets.QMessageBox, "question", answer)
    win = viewer_window(csv, project)  # what `bgm view holes.csv --project p.bgm.json` opens
    win.show()
    qtbot.waitUntil(lambda: bool(asked) and not win.busy and win.model.result.complete, timeout=60_000)
    assert asked[0][0] == "Restore unsaved work?" and "p.bgm.json" in asked[0][1]
    assert win.model.dirty and win.windowTitle().endswith(" *") and win.model.project_path == str(project)
    np.testing.assert_allclose(win.model.translation_m(), want, atol=1e-9)
    assert autosave.exists()  # until saved or discarded

    assert win.close()  # "Save them?" Discard: the work is thrown away on purpose
    assert len(asked) == 2 and not autosave.exists()


def test_the_component_shown_follows_the_corrected_body_when_a_run_renumbers_it(qtbot):
    """The selection panel showed the old number of the corrected body after a run renumbered it (see
    test_viewer_alignment.py): the spin box now shows the number the selection followed to."""
    from bgm_viewer.testing import two_bodies_holes

    model = ViewerModel(two_bodies_holes(), cache=False)
    model.select("g1", 0, 1)
    win = MainWindow(model, debounce_ms=10)
    win.show()
    try:
        qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
        win.apply_translation()  # lock the corner body where it is
        qtbot.waitUntil(lambda: not win.busy, timeout=60_000)
        win.component_spin.setValue(0)  # as if numbered 0 before a parameter renumbered it
        qtbot.waitUntil(lambda: not win.busy, timeout=60_000)
        win.model.overrides[0].source = 0
        win.request("correspondence", immediate=True)
        qtbot.waitUntil(lambda: not win.busy, timeout=60_000)
        assert win.model.selection.component == 1 and win.component_spin.value() == 1
        assert "locked" in win.translation_label.text()
    finally:
        win.model.dirty = False
        win.close()


def test_stop_ends_a_run_shows_the_last_finished_one_and_keeps_the_sliders(window, qtbot):
    """A run on a large pit lasts tens of seconds to minutes; another change or closing the window
    were the only ways out. Stop (Esc, the Run menu, the button beside the progress bar) ends it,
    shows the last finished run again (not the part-way mix of new and old benches), says
    "stopped", keeps the slider, and Run again brings the picture up to the slider."""
    finished = window.model.result
    before = _selected_polygon(window)
    assert not window.stop_action.isEnabled()  # nothing to stop
    assert window.stop_action.shortcut().toString() == "Esc"
    assert window.stop_button.defaultAction() is window.stop_action
    enabled_while_running = []

    def stop_at_first_result():
        if window.busy:
            enabled_while_running.append(window.stop_action.isEnabled())
            window.stop_action.trigger()

    window.resultShown.connect(stop_at_first_result)
    window.param_controls["snake_max_iterations"].slider.setValue(10)
    qtbot.waitUntil(lambda: not window.busy, timeout=60_000)
    window.resultShown.disconnect(stop_at_first_result)
    assert enabled_while_running == [True]
    qtbot.wait(500)  # what the stopped run still yields is never drawn
    result = window.model.result
    assert result.stopped and not window.stop_action.isEnabled()
    assert window.statusBar().currentMessage().startswith("stopped")
    # the last finished run's benches and surfaces, not the stopped run's first bench with the new slider
    assert result.contours == finished.contours and result.surfaces == finished.surfaces
    assert _selected_polygon(window).equals(before)
    assert window.model.param("snake_max_iterations") == 10  # what the user set is kept
    assert window.param_controls["snake_max_iterations"].value() == 10
    window.run_again()
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    assert not window.model.result.stopped and not _selected_polygon(window).equals(before)
    assert window.statusBar().currentMessage().startswith("done")


def test_a_layer_a_stopped_run_did_not_compute_says_the_run_was_stopped(window, qtbot):
    """After Stop, "not computed yet" promised a result no run was computing."""
    window.resultShown.connect(window.stop_run)
    window.geozone_combo.setCurrentText("g2")  # another selection: no model for it yet
    qtbot.waitUntil(lambda: window.model.result.stopped, timeout=60_000)
    window.resultShown.disconnect(window.stop_run)
    empty = window.empty_layers()
    assert "surfaces" not in empty or "stopped" in empty["surfaces"]
    assert empty and all("yet" not in why for why in empty.values()), empty
    assert any("the run was stopped" in why for why in empty.values()), empty


def test_stepping_bench_pairs_says_which_component_is_selected(qtbot):
    """The component number was kept silently when the bench pair changed: there it named another body."""
    from bgm_viewer.testing import bodies_that_start_and_end_holes

    model = ViewerModel(bodies_that_start_and_end_holes())
    model.select("g1", 0, 2)
    win = MainWindow(model, debounce_ms=10, restore=False)
    win.show()
    try:
        qtbot.waitUntil(lambda: not win.busy and win.model.result.complete, timeout=60_000)
        win.bench_combo.setCurrentIndex(1)
        assert win.component_spin.value() == win.model.selection.component == 1
        assert "source component 1 selected" in win.statusBar().currentMessage()
        qtbot.waitUntil(lambda: not win.busy, timeout=60_000)
        message = win.statusBar().currentMessage()
        assert message.startswith("done") and "source component 1 selected" in message
    finally:
        win.model.dirty = False
        win.close()


@pytest.mark.parametrize("where", ["the folder", "a folder above it", "a geozone's folder"])
def test_exporting_surfaces_where_a_file_is_says_which_path_and_that_a_folder_is_expected(window, tmp_path, where):
    """Exporting surfaces into a path that is a file gave a raw "[Errno 20] Not a directory"."""
    from core.model.build import geozone_folders

    file = tmp_path / "surfaces.txt"
    folder = {"the folder": file, "a folder above it": file / "out"}.get(where, tmp_path / "out")
    if where == "a geozone's folder":
        shown = sorted(g for g in window.model.result.built if window.scene.view.shows(g))
        file = folder / geozone_folders(shown)[shown[0]]
        folder.mkdir()
    file.write_text("notes")
    with pytest.raises(ValueError) as err:
        window.export_surfaces(folder)
    said = str(err.value)
    assert "Errno" not in said and "\n" not in said
    assert f"{file} is a file" in said and "folder" in said
    assert file.read_text() == "notes"  # nothing written over it


def test_showing_the_window_again_keeps_the_camera_and_a_projects_saved_one(window, qtbot, tmp_path):
    """Each show of the window (hidden and shown again, or un-minimised) looked from the default camera and fitted
    the data again: the view the geologist had turned to, or the one a project opened with, was lost."""

    def camera():
        c = window.plotter.camera
        return np.array([c.GetPosition(), c.GetFocalPoint(), c.GetViewUp()])

    def show_again():
        window.hide()
        window.show()
        qtbot.waitExposed(window)
        qtbot.wait(50)  # a camera set on showing is set once the window is laid out

    _turn_camera(window)
    turned = camera()
    show_again()
    np.testing.assert_allclose(camera(), turned, rtol=1e-9, atol=1e-9)
    window.showMinimized()
    qtbot.wait(50)
    window.showNormal()
    qtbot.wait(50)
    np.testing.assert_allclose(camera(), turned, rtol=1e-9, atol=1e-9)

    window.model.project_path = str(tmp_path / "p.bgm.json")
    assert window.save_project()
    window.set_camera("iso")
    window.open_project(tmp_path / "p.bgm.json")
    qtbot.waitUntil(lambda: not window.busy and window.model.result.complete, timeout=60_000)
    np.testing.assert_allclose(camera(), turned, rtol=1e-6, atol=1e-6)  # the project's
    show_again()
    np.testing.assert_allclose(camera(), turned, rtol=1e-6, atol=1e-6)


def test_a_warning_on_the_windows_thread_while_a_run_is_under_way_is_not_lost(recwarn):
    """A run silenced its warnings with ``warnings.catch_warnings``, which changes the filters of the whole process:
    a warning the window's thread gave while the run was under way (a project's override dropped) never reached
    stderr, and two runs overlapping could leave every warning silenced for good. Only the run's own are now,
    with those of the threads it starts."""
    import threading

    from bgm_viewer.app import _quietly
    from core.errors import BGMWarning

    model = ViewerModel(small_holes())
    model.select("g1", 0, 0)
    paused, go_on = threading.Event(), threading.Event()
    run_threads: set[str] = set()

    def cancelled() -> bool:  # called by the run between its steps, on its own thread and on those it starts
        run_threads.add(threading.current_thread().name)
        warnings.warn("the run's own warning", UserWarning, stacklevel=1)
        if not paused.is_set():
            paused.set()
            go_on.wait(60)
        return False

    yielded: list = []
    worker = threading.Thread(
        target=lambda: yielded.extend(_quietly(model.inputs(), model.result, "contours", cancelled)), name="run"
    )
    worker.start()
    try:
        assert paused.wait(60)
        warnings.warn("the window's warning", BGMWarning, stacklevel=1)  # the run is under way
    finally:
        go_on.set()
        worker.join(120)
    assert yielded and yielded[-1][2].complete
    assert len(run_threads) > 1  # on_threads' threads too
    said = [str(w.message) for w in recwarn]
    assert said == ["the window's warning"]

    # a run cancelled while the next one starts: the first's end put back no filters over the second's
    recwarn.clear()
    first = _quietly(model.inputs(), model.result, "contours", lambda: False)
    second = _quietly(model.inputs(), model.result, "contours", lambda: False)
    next(first), next(second)
    first.close()
    second.close()
    warnings.warn("after both", BGMWarning, stacklevel=1)
    assert [str(w.message) for w in recwarn] == ["after both"]
