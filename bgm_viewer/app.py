"""The Qt main window of the BGM viewer (qtpy + PySide6, pyvistaqt).

The window only observes and drives plain objects: a :class:`ViewerModel`
(state, pipeline, overrides, project file) and a :class:`Scene` of layers
drawn by a :class:`SceneRenderer` into a ``pyvistaqt.QtInteractor``. Engine
runs happen in a worker thread (:func:`bgm_viewer.model.compute`); a newer
request cancels an older one, progress goes to the status bar.

Qt's ``offscreen`` platform cannot host the VTK OpenGL widget; run under a
real display or ``xvfb-run``.
"""

from __future__ import annotations

import itertools
import queue
import threading
import time
import traceback
import warnings
from pathlib import Path

import numpy as np
from qtpy import QtCore, QtGui, QtWidgets

from . import _vtkenv  # noqa: F401
from .builders import DEFAULT_VISIBLE, LAYER_NAMES, build_scene, refresh_scene
from .model import PARAMETERS, STAGES, Cancelled, ViewerModel, compute
from .scene import SceneRenderer, drag_on_plane

Signal = QtCore.Signal
SLIDER_STEPS = 1000


class ParamControl(QtWidgets.QWidget):
    """A slider with a numeric field for one :class:`~bgm_viewer.model.ParamSpec`."""

    valueChanged = Signal(str, float)

    def __init__(self, spec, value, parent=None):
        super().__init__(parent)
        self.spec = spec
        lay = QtWidgets.QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        self.slider = QtWidgets.QSlider(QtCore.Qt.Horizontal)
        self.slider.setRange(0, SLIDER_STEPS)
        if spec.integer:
            self.field = QtWidgets.QSpinBox()
            self.field.setRange(int(spec.minimum), int(spec.maximum))
        else:
            self.field = QtWidgets.QDoubleSpinBox()
            self.field.setDecimals(3)
            self.field.setRange(spec.minimum, spec.maximum)
            self.field.setSingleStep((spec.maximum - spec.minimum) / 100)
        self.field.setKeyboardTracking(False)
        self.field.setToolTip(spec.help or spec.label)
        lay.addWidget(self.slider, 3)
        lay.addWidget(self.field, 1)
        self.set_value(value)
        self.slider.valueChanged.connect(self._from_slider)
        self.field.valueChanged.connect(self._from_field)

    def _to_slider(self, v: float) -> int:
        s = self.spec
        return int(round((v - s.minimum) / (s.maximum - s.minimum) * SLIDER_STEPS))

    def _from_slider(self, pos: int) -> None:
        s = self.spec
        v = s.minimum + pos / SLIDER_STEPS * (s.maximum - s.minimum)
        v = int(round(v)) if s.integer else v
        self.field.blockSignals(True)
        self.field.setValue(v)
        self.field.blockSignals(False)
        self.valueChanged.emit(s.name, float(v))

    def _from_field(self, v) -> None:
        self.slider.blockSignals(True)
        self.slider.setValue(self._to_slider(v))
        self.slider.blockSignals(False)
        self.valueChanged.emit(self.spec.name, float(v))

    def set_value(self, v) -> None:
        for w, val in ((self.field, v), (self.slider, self._to_slider(v))):
            w.blockSignals(True)
            w.setValue(val)
            w.blockSignals(False)

    def value(self) -> float:
        return float(self.field.value())


def _single_render(interactor):
    """Make the VTK widget show a frame VTK has just rendered without rendering it again.

    pyvistaqt's widget renders the scene again in every ``paintGL`` (so a
    scene changed without a render never shows stale), and every VTK render
    (camera interaction, :class:`SceneRenderer`) schedules such a paint: each
    frame was drawn twice, ~65 ms instead of ~30 ms with software OpenGL.
    After a finished VTK render the next paint only copies its image, as the
    C++ ``QVTKOpenGLNativeWidget`` does; every other paint still renders.
    """
    if not hasattr(interactor, "_in_paint"):
        return interactor  # a pyvistaqt without the hook: keep its behaviour
    fresh = {"frame": False}

    def rendered(*_):
        if not interactor._in_paint:
            fresh["frame"] = True

    interactor.ren_win.AddObserver("EndEvent", rendered)
    paint = interactor.paintGL

    def paint_gl():
        if not fresh["frame"]:
            return paint()
        fresh["frame"] = False
        interactor._in_paint = True  # pyvistaqt then blits without rendering
        try:
            return paint()
        finally:
            interactor._in_paint = False

    interactor.paintGL = paint_gl
    return interactor


class MainWindow(QtWidgets.QMainWindow):
    """BGM viewer main window."""

    resultShown = Signal()

    def __init__(self, model: ViewerModel | None = None, *, debounce_ms: int = 150, auto_run: bool = True):
        super().__init__()
        from pyvistaqt import QtInteractor

        self.model = model or ViewerModel(None)
        self.setWindowTitle("BGM viewer")
        self.resize(1400, 900)
        self._jobs = itertools.count(1)
        self.emit_times: list[float] = []
        self._job = 0
        self._pending_stage: str | None = None
        self._queued_stage: str | None = None
        self._request_time = 0.0
        self.last_run_seconds = float("nan")
        self.last_update_seconds = float("nan")
        # Worker results come back through a queue polled by a timer: passing Python
        # objects through Qt signals from a plain thread can corrupt reference counts.
        self._inbox: queue.Queue = queue.Queue()
        self._poll = QtCore.QTimer(self)
        self._poll.setInterval(20)
        self._poll.timeout.connect(self._drain)
        self._poll.start()
        self._debounce = QtCore.QTimer(self)
        self._debounce.setSingleShot(True)
        self._debounce.setInterval(debounce_ms)
        self._debounce.timeout.connect(self._start_queued)

        # no multi-sampling: software rendering is ~4x slower with it (see issue 6)
        self.plotter = _single_render(QtInteractor(self, multi_samples=0, auto_update=False))
        self.setCentralWidget(self.plotter.interactor)
        self.scene = build_scene(
            self.model.holes,
            self.model.result,
            self.model.selection,
            visible=DEFAULT_VISIBLE,
            vertical_exaggeration=self.model.vertical_exaggeration,
        )
        self.renderer = SceneRenderer(self.plotter, self.scene, auto_render=True)
        self.renderer.set_camera("iso")

        self._build_menus()
        self._build_layer_panel()
        self._build_selection_panel()
        self._build_parameter_panel()
        self._build_alignment_panel()
        self.progress_bar = QtWidgets.QProgressBar()
        self.progress_bar.setRange(0, 100)
        self.progress_bar.setMaximumWidth(200)
        self.statusBar().addPermanentWidget(self.progress_bar)
        self._play = QtCore.QTimer(self)
        self._play.setInterval(80)
        self._play.timeout.connect(self._advance_frame)
        self.model.connect(self._on_model)
        self._drag_start: tuple[int, int] | None = None
        self._watch_mouse()
        self._update_title()
        if auto_run:
            self.request("boundary", immediate=True)

    # ------------------------------------------------------------------ building
    def _build_menus(self) -> None:
        m = self.menuBar().addMenu("&File")
        m.addAction("&Open blastholes...", self.open_input_dialog, QtGui.QKeySequence.Open)
        m.addAction("Open &project...", self.open_project_dialog)
        m.addAction("&Save project", self.save_project, QtGui.QKeySequence.Save)
        m.addAction("Save project &as...", lambda: self.save_project(ask=True))
        m.addSeparator()
        m.addAction("Export &screenshot...", self.export_screenshot_dialog)
        m.addAction("Export s&urface...", self.export_surface_dialog)
        m.addSeparator()
        m.addAction("&Quit", self.close, QtGui.QKeySequence.Quit)
        e = self.menuBar().addMenu("&Edit")
        self.undo_action = e.addAction("&Undo alignment", self.undo, QtGui.QKeySequence.Undo)
        v = self.menuBar().addMenu("&View")
        for cam in ("iso", "top", "front", "side"):
            v.addAction(f"Camera: {cam}", lambda c=cam: (self.renderer.set_camera(c), self.plotter.render()))

    def _dock(self, title: str, widget: QtWidgets.QWidget, area) -> QtWidgets.QDockWidget:
        dock = QtWidgets.QDockWidget(title, self)
        scroll = QtWidgets.QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(widget)
        dock.setWidget(scroll)
        dock.setObjectName(title)
        self.addDockWidget(area, dock)
        return dock

    def _build_layer_panel(self) -> None:
        w = QtWidgets.QWidget()
        lay = QtWidgets.QVBoxLayout(w)
        self.layer_list = QtWidgets.QListWidget()
        for layer in self.scene.layers:
            item = QtWidgets.QListWidgetItem(layer.name)
            item.setFlags(item.flags() | QtCore.Qt.ItemIsUserCheckable)
            item.setCheckState(QtCore.Qt.Checked if layer.visible else QtCore.Qt.Unchecked)
            self.layer_list.addItem(item)
        self.layer_list.itemChanged.connect(self._on_layer_item)
        self.layer_list.currentRowChanged.connect(self._on_layer_row)
        lay.addWidget(self.layer_list)
        form = QtWidgets.QFormLayout()
        self.opacity_slider = QtWidgets.QSlider(QtCore.Qt.Horizontal)
        self.opacity_slider.setRange(0, 100)
        self.opacity_slider.valueChanged.connect(self._on_opacity)
        form.addRow("opacity", self.opacity_slider)
        self.frame_slider = QtWidgets.QSlider(QtCore.Qt.Horizontal)
        self.frame_slider.valueChanged.connect(self._on_frame)
        form.addRow("frame", self.frame_slider)
        buttons = QtWidgets.QHBoxLayout()
        self.play_button = QtWidgets.QPushButton("Play")
        self.play_button.setCheckable(True)
        self.play_button.toggled.connect(lambda on: self._play.start() if on else self._play.stop())
        step = QtWidgets.QPushButton("Step")
        step.clicked.connect(self._advance_frame)
        buttons.addWidget(self.play_button)
        buttons.addWidget(step)
        form.addRow(buttons)
        self.ve_spin = QtWidgets.QDoubleSpinBox()
        self.ve_spin.setRange(0.1, 20.0)
        self.ve_spin.setSingleStep(0.5)
        self.ve_spin.setValue(self.model.vertical_exaggeration)
        self.ve_spin.valueChanged.connect(self._on_ve)
        form.addRow("vertical exaggeration", self.ve_spin)
        lay.addLayout(form)
        self._dock("Layers", w, QtCore.Qt.LeftDockWidgetArea)
        self.layer_list.setCurrentRow(0)

    def _build_selection_panel(self) -> None:
        w = QtWidgets.QWidget()
        form = QtWidgets.QFormLayout(w)
        self.geozone_combo = QtWidgets.QComboBox()
        self.bench_combo = QtWidgets.QComboBox()
        self.component_spin = QtWidgets.QSpinBox()
        self.component_spin.setRange(0, 999)
        self._fill_selection()
        self.geozone_combo.currentTextChanged.connect(lambda g: self._select(geozone=g, component=0))
        self.bench_combo.currentIndexChanged.connect(lambda i: self._select(bench=i) if i >= 0 else None)
        self.component_spin.valueChanged.connect(lambda c: self._select(component=c))
        form.addRow("geozone", self.geozone_combo)
        self.geozone_list = self.geozone_combo  # alias used by tests / docs
        form.addRow("bench pair", self.bench_combo)
        form.addRow("source component", self.component_spin)
        self._dock("Selection", w, QtCore.Qt.LeftDockWidgetArea)

    def _fill_selection(self) -> None:
        h, sel = self.model.holes, self.model.selection
        for wid in (self.geozone_combo, self.bench_combo, self.component_spin):
            wid.blockSignals(True)
        self.geozone_combo.clear()
        self.geozone_combo.addItems(h.geozones)
        self.geozone_combo.setCurrentText(sel.geozone)
        self.bench_combo.clear()
        for k in range(max(h.n_benches - 1, 1)):
            lo = h.bench_z_input(k + 1) if k + 1 < h.n_benches else float("nan")
            self.bench_combo.addItem(f"{h.bench_z_input(k):g} -> {lo:g}")
        self.bench_combo.setCurrentIndex(sel.bench)
        self.component_spin.setValue(sel.component)
        for wid in (self.geozone_combo, self.bench_combo, self.component_spin):
            wid.blockSignals(False)

    def _build_parameter_panel(self) -> None:
        w = QtWidgets.QWidget()
        lay = QtWidgets.QVBoxLayout(w)
        self.param_controls: dict[str, ParamControl] = {}
        for stage in STAGES:
            specs = [p for p in PARAMETERS if p.stage == stage]
            if not specs:
                continue
            box = QtWidgets.QGroupBox(stage)
            form = QtWidgets.QFormLayout(box)
            for spec in specs:
                ctl = ParamControl(spec, self.model.params[spec.name])
                ctl.valueChanged.connect(self.set_param)
                form.addRow(spec.label, ctl)
                self.param_controls[spec.name] = ctl
            lay.addWidget(box)
        lay.addStretch(1)
        self._dock("Parameters", w, QtCore.Qt.RightDockWidgetArea)

    def _build_alignment_panel(self) -> None:
        w = QtWidgets.QWidget()
        form = QtWidgets.QFormLayout(w)
        self.translation_label = QtWidgets.QLabel("-")
        form.addRow("translation (m)", self.translation_label)
        self.dx_spin = QtWidgets.QDoubleSpinBox()
        self.dy_spin = QtWidgets.QDoubleSpinBox()
        for s in (self.dx_spin, self.dy_spin):
            s.setRange(-1e4, 1e4)
            s.setDecimals(2)
        row = QtWidgets.QHBoxLayout()
        row.addWidget(self.dx_spin)
        row.addWidget(self.dy_spin)
        form.addRow("dx, dy", row)
        buttons = QtWidgets.QHBoxLayout()
        for text, fn in (
            ("Apply", self.apply_translation),
            ("Lock", self.lock_current),
            ("Clear", self.clear_override),
            ("Undo", self.undo),
        ):
            b = QtWidgets.QPushButton(text)
            b.clicked.connect(fn)
            buttons.addWidget(b)
        form.addRow(buttons)
        self.target_spin = QtWidgets.QSpinBox()
        self.target_spin.setRange(0, 999)
        assoc = QtWidgets.QHBoxLayout()
        assoc.addWidget(self.target_spin)
        for text, flag in (("Force", True), ("Forbid", False), ("Reset", None)):
            b = QtWidgets.QPushButton(text)
            b.clicked.connect(lambda _=False, f=flag: self.set_association(self.target_spin.value(), f))
            assoc.addWidget(b)
        form.addRow("target", assoc)
        self.nudge_step = QtWidgets.QDoubleSpinBox()
        self.nudge_step.setRange(0.1, 100.0)
        self.nudge_step.setValue(1.0)
        form.addRow("Ctrl+arrow step (m)", self.nudge_step)
        form.addRow(QtWidgets.QLabel("Shift + drag in the view moves the source on its bench."))
        for key, (dx, dy) in {"Left": (-1, 0), "Right": (1, 0), "Up": (0, 1), "Down": (0, -1)}.items():
            sc = QtWidgets.QShortcut(QtGui.QKeySequence(f"Ctrl+{key}"), self)
            sc.activated.connect(
                lambda dx=dx, dy=dy: self.nudge(dx * self.nudge_step.value(), dy * self.nudge_step.value())
            )
        self._dock("Manual alignment", w, QtCore.Qt.RightDockWidgetArea)

    # ------------------------------------------------------------------ mouse alignment
    def _watch_mouse(self) -> None:
        """Shift + left drag in the 3D view moves the selected source on its bench plane.

        The observers sit on the VTK interactor ahead of the camera style and
        swallow the events of a Shift drag, so the camera stays put while the
        source moves; any other drag turns the camera as usual.
        """
        iren = self.plotter.iren.interactor
        self._mouse_tags = {}
        for event, handler in (
            ("LeftButtonPressEvent", self._on_press),
            ("MouseMoveEvent", self._on_move),
            ("LeftButtonReleaseEvent", self._on_release),
        ):
            self._mouse_tags[event] = iren.AddObserver(event, handler, 10.0)

    def _swallow(self, event: str) -> None:
        self.plotter.iren.interactor.GetCommand(self._mouse_tags[event]).SetAbortFlag(1)

    def _source_plane_z(self) -> float:
        z = float(self.model.holes.bench_levels_m[self.model.selection.bench])
        return float(self.scene.view.z(z))

    def drag_translation(self, start_px, end_px) -> np.ndarray | None:
        """World ``(dx, dy)`` metres of a drag between two display pixels on the source bench."""
        return drag_on_plane(self.plotter, start_px, end_px, self._source_plane_z())

    def _on_press(self, iren, event) -> None:
        if not iren.GetShiftKey() or self.model.current_translation_m() is None:
            return
        self._drag_start = tuple(iren.GetEventPosition())
        self.statusBar().showMessage("dragging the source: release to apply")
        self._swallow(event)

    def _on_move(self, iren, event) -> None:
        if self._drag_start is None:
            return
        d = self.drag_translation(self._drag_start, iren.GetEventPosition())
        if d is not None:
            cur = self.model.current_translation_m() or (0.0, 0.0)
            self.statusBar().showMessage(
                f"dragging the source: translation {cur[0] + d[0]:.2f}, {cur[1] + d[1]:.2f} m (release to apply)"
            )
        self._swallow(event)

    def _on_release(self, iren, event) -> None:
        if self._drag_start is None:
            return
        start, self._drag_start = self._drag_start, None
        self._swallow(event)
        d = self.drag_translation(start, iren.GetEventPosition())
        if d is None:
            self.statusBar().showMessage("cannot drag in a side view: turn the camera towards the benches", 5000)
            return
        if np.hypot(*d) > 0:
            self.nudge(float(d[0]), float(d[1]))

    # ------------------------------------------------------------------ layer panel
    def _on_layer_item(self, item) -> None:
        layer = self.scene.get(item.text())
        if layer is not None:
            layer.visible = item.checkState() == QtCore.Qt.Checked

    def _current_layer(self):
        item = self.layer_list.currentItem()
        return self.scene.get(item.text()) if item else None

    def _on_layer_row(self, _row) -> None:
        layer = self._current_layer()
        if layer is None:
            return
        for wid, val in ((self.opacity_slider, int(round(layer.opacity * 100))),):
            wid.blockSignals(True)
            wid.setValue(val)
            wid.blockSignals(False)
        self.frame_slider.blockSignals(True)
        self.frame_slider.setRange(0, max(layer.n_frames - 1, 0))
        self.frame_slider.setValue(layer.frame)
        self.frame_slider.setEnabled(layer.n_frames > 1)
        self.frame_slider.blockSignals(False)

    def _on_opacity(self, v: int) -> None:
        layer = self._current_layer()
        if layer is not None:
            layer.opacity = v / 100.0

    def _on_frame(self, v: int) -> None:
        layer = self._current_layer()
        if layer is not None and layer.n_frames > 1:
            layer.frame = v

    def _advance_frame(self) -> None:
        layer = self._current_layer()
        if layer is None or layer.n_frames <= 1:
            names = [n for n in ("snake", "wavefront") if self.scene[n].n_frames > 1]
            if not names:
                return
            self.layer_list.setCurrentRow(list(LAYER_NAMES).index(names[0]))
            layer = self.scene[names[0]]
        layer.frame = (layer.frame + 1) % layer.n_frames
        self.frame_slider.blockSignals(True)
        self.frame_slider.setValue(layer.frame)
        self.frame_slider.blockSignals(False)

    def _on_ve(self, v: float) -> None:
        self.model.vertical_exaggeration = float(v)
        self.scene.vertical_exaggeration = float(v)

    def set_layer_visible(self, name: str, visible: bool) -> None:
        item = self.layer_list.findItems(name, QtCore.Qt.MatchExactly)[0]
        item.setCheckState(QtCore.Qt.Checked if visible else QtCore.Qt.Unchecked)

    # ------------------------------------------------------------------ model changes
    def set_param(self, name: str, value: float) -> None:
        stage = self.model.set_param(name, value)
        self.request(stage)

    def _select(self, **kw) -> None:
        try:
            stage = self.model.select(**kw)
        except ValueError as exc:
            self.statusBar().showMessage(str(exc), 5000)
            return
        if stage:
            self.request(stage, immediate=True)

    def apply_translation(self) -> None:
        self.request(self.model.set_translation(self.dx_spin.value(), self.dy_spin.value()), immediate=True)

    def nudge(self, ddx: float, ddy: float) -> None:
        self.request(self.model.nudge(ddx, ddy), immediate=True)

    def lock_current(self) -> None:
        self.request(self.model.lock_current(), immediate=True)

    def clear_override(self) -> None:
        self.request(self.model.clear_override(), immediate=True)

    def set_association(self, target: int, flag) -> None:
        self.request(self.model.set_association(target, flag), immediate=True)

    def undo(self) -> None:
        stage = self.model.undo()
        if stage:
            self.request(stage, immediate=True)

    def _on_model(self, what: str) -> None:
        if what == "dirty":
            self._update_title()
        elif what == "overrides":
            self.undo_action.setEnabled(self.model.can_undo)

    def _update_title(self) -> None:
        name = Path(self.model.project_path).name if self.model.project_path else "untitled project"
        self.setWindowTitle(
            f"BGM viewer - {self.model.holes.source or 'input'} - {name}{' *' if self.model.dirty else ''}"
        )

    # ------------------------------------------------------------------ worker
    @property
    def busy(self) -> bool:
        return self._pending_stage is not None or self._queued_stage is not None

    def request(self, stage: str, immediate: bool = False) -> None:
        """Re-run from ``stage`` (merged with any run not yet finished) after the debounce delay."""
        stages = [s for s in (stage, self._queued_stage, self._pending_stage) if s]
        self._queued_stage = min(stages, key=STAGES.index)
        self._request_time = time.perf_counter()
        if immediate:
            self._debounce.stop()
            self._start_queued()
        else:
            self._debounce.start()

    def _start_queued(self) -> None:
        stage, self._queued_stage = self._queued_stage, None
        if stage is None:
            return
        self._job = job = next(self._jobs)
        self._pending_stage = stage
        self._first_update = True
        inputs = self.model.inputs()
        previous = self.model.result
        self.statusBar().showMessage(f"running from {stage}...")
        self.progress_bar.setValue(0)
        inbox = self._inbox

        def work():
            t0 = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    for msg, frac, res in compute(inputs, previous, stage, lambda: self._job != job):
                        self.emit_times.append(time.perf_counter())
                        inbox.put((self._on_progress, (job, msg, frac, res)))
                inbox.put((self._on_finished, (job, time.perf_counter() - t0)))
            except Cancelled:
                pass
            except Exception:
                inbox.put((self._on_failed, (job, traceback.format_exc(limit=3))))

        threading.Thread(target=work, name=f"bgm-pipeline-{job}", daemon=True).start()

    def _drain(self) -> None:
        """Handle what the worker sent; only the newest progress of a burst is drawn."""
        items = []
        while True:
            try:
                items.append(self._inbox.get_nowait())
            except queue.Empty:
                break
        for i, (fn, args) in enumerate(items):
            later = any(f == self._on_progress for f, _ in items[i + 1 :])
            if fn == self._on_progress and later:
                continue
            fn(*args)

    def _on_progress(self, job: int, msg: str, frac: float, result) -> None:
        if job != self._job:
            return  # superseded
        previous = self.model.result
        self.model.set_result(result)
        with self.renderer.batch():
            refresh_scene(self.scene, self.model.holes, result, self.model.selection, previous=previous)
        self._on_layer_row(None)
        if self._first_update:
            self._first_update = False
            self.last_update_seconds = time.perf_counter() - self._request_time
        self._show_translation()
        self.statusBar().showMessage(f"{msg} ({int(frac * 100)}%)")
        self.progress_bar.setValue(int(frac * 100))
        self.resultShown.emit()

    def _on_finished(self, job: int, seconds: float) -> None:
        if job != self._job:
            return
        self._pending_stage = None
        self.last_run_seconds = seconds
        errors = "; ".join(f"{k}: {v}" for k, v in self.model.result.errors.items())
        self.statusBar().showMessage(f"done in {seconds:.2f} s" + (f" - {errors}" if errors else ""))
        self.progress_bar.setValue(100)

    def _on_failed(self, job: int, text: str) -> None:
        if job != self._job:
            return
        self._pending_stage = None
        self.statusBar().showMessage("failed: " + text.strip().splitlines()[-1])

    def _show_translation(self) -> None:
        t = self.model.current_translation_m()
        if t is None:
            self.translation_label.setText("-")
            return
        locked = self.model._override(create=False)
        lock = " (locked)" if locked is not None and locked.translation is not None else ""
        self.translation_label.setText(f"{t[0]:.2f}, {t[1]:.2f}{lock}")
        for s, v in ((self.dx_spin, t[0]), (self.dy_spin, t[1])):
            s.blockSignals(True)
            s.setValue(v)
            s.blockSignals(False)

    def wait_idle(self, timeout_s: float = 60.0) -> bool:
        """Process events until no run is pending (for scripts and tests)."""
        end = time.perf_counter() + timeout_s
        while self.busy and time.perf_counter() < end:
            QtWidgets.QApplication.processEvents(QtCore.QEventLoop.AllEvents, 50)
            time.sleep(0.02)
        return not self.busy

    # ------------------------------------------------------------------ files
    def open_input(self, path) -> None:
        model = ViewerModel(path)
        self._replace_model(model)

    def _replace_model(self, model: ViewerModel) -> None:
        self._job = next(self._jobs)  # cancel running work
        self._pending_stage = self._queued_stage = None
        self.model = model
        self.model.connect(self._on_model)
        with self.renderer.batch():
            refresh_scene(self.scene, model.holes, model.result, model.selection)
        self._fill_selection()
        for name, ctl in self.param_controls.items():
            ctl.set_value(model.params[name])
        self.ve_spin.setValue(model.vertical_exaggeration)
        self.renderer.set_camera("iso")
        self._update_title()
        self.request("boundary", immediate=True)

    def open_input_dialog(self) -> None:
        if not self._confirm_discard():
            return
        path, _ = QtWidgets.QFileDialog.getOpenFileName(
            self, "Open blastholes", "", "Blasthole tables (*.csv *.txt *.parquet *.pq);;All files (*)"
        )
        if path:
            self._guard(lambda: self.open_input(path))

    def open_project(self, path) -> None:
        from .cli_hooks import _project_input

        inp = _project_input(path)
        model = ViewerModel(inp) if inp else ViewerModel(self.model.holes)
        model.load_project(path)
        self._replace_model(model)

    def open_project_dialog(self) -> None:
        if not self._confirm_discard():
            return
        path, _ = QtWidgets.QFileDialog.getOpenFileName(self, "Open project", "", "BGM project (*.json);;All files (*)")
        if path:
            self._guard(lambda: self.open_project(path))

    def save_project(self, ask: bool = False) -> bool:
        path = self.model.project_path
        if ask or not path:
            path, _ = QtWidgets.QFileDialog.getSaveFileName(
                self, "Save project", path or "project.bgm.json", "BGM project (*.json)"
            )
            if not path:
                return False
        return self._guard(lambda: self.model.save_project(path))

    def export_screenshot(self, path) -> None:
        from core.io.atomic import atomic_path

        with atomic_path(path) as tmp:
            self.plotter.screenshot(str(tmp))

    def export_screenshot_dialog(self) -> None:
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self, "Export screenshot", "bgm.png", "PNG (*.png)")
        if path:
            self._guard(lambda: self.export_screenshot(path))

    def export_surface(self, path) -> None:
        from core.io.export import export_surface
        from core.model.surfaces import to_input_frame

        mesh = self.model.result.surface
        if mesh is None:
            raise ValueError("no surface has been computed yet")
        f = self.model.holes.frame
        export_surface(
            to_input_frame(mesh, (f.origin_x, f.origin_y), f.metres_per_unit), path, name=self.model.selection.geozone
        )

    def export_surface_dialog(self) -> None:
        path, _ = QtWidgets.QFileDialog.getSaveFileName(
            self,
            "Export surface",
            f"{self.model.selection.geozone}.obj",
            "Surfaces (*.obj *.ply *.stl *.vtp *.dxf *.omf)",
        )
        if path:
            self._guard(lambda: self.export_surface(path))

    def _guard(self, fn) -> bool:
        try:
            fn()
            return True
        except Exception as exc:
            QtWidgets.QMessageBox.warning(self, "BGM viewer", str(exc))
            return False

    # ------------------------------------------------------------------ closing
    def _confirm_discard(self) -> bool:
        """Ask what to do with unsaved changes; ``True`` to go on."""
        if not self.model.dirty:
            return True
        answer = QtWidgets.QMessageBox.question(
            self,
            "Unsaved changes",
            "The project has unsaved parameter or alignment changes. Save them?",
            QtWidgets.QMessageBox.Save | QtWidgets.QMessageBox.Discard | QtWidgets.QMessageBox.Cancel,
            QtWidgets.QMessageBox.Save,
        )
        if answer == QtWidgets.QMessageBox.Save:
            return self.save_project()
        return answer == QtWidgets.QMessageBox.Discard

    def closeEvent(self, event) -> None:
        if not self._confirm_discard():
            event.ignore()
            return
        self._job = next(self._jobs)  # let a running worker stop
        self._play.stop()
        if not getattr(self, "_closed", False):
            self._closed = True
            self.plotter.close()
        event.accept()


def run_viewer(input_path=None, project_path=None) -> int:
    """Open the viewer window on ``input_path`` (demo if ``None``) and a project; returns the exit code."""
    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication([])
    if input_path is None and project_path is not None:
        from .cli_hooks import _project_input

        input_path = _project_input(project_path)
    model = ViewerModel(input_path)
    if project_path is not None:
        model.load_project(project_path)
    window = MainWindow(model)
    window.show()
    return int(app.exec())
