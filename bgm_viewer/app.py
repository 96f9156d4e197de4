"""The Qt main window of the BGM viewer (qtpy + PySide6, pyvistaqt, superqt).

The window only observes and drives plain objects: a :class:`ViewerModel`
(state, overrides, project file, core's pipeline) and a :class:`Scene` of
layers drawn by a :class:`SceneRenderer` into a ``pyvistaqt.QtInteractor``.
Engine runs happen in a superqt generator worker (:func:`bgm_viewer.model.compute`
on a thread of Qt's pool), and so does the next bench's band; a newer request
cancels both at core's next step (:func:`core.threads.cancelling`), progress goes
to the status bar. The parameter sliders are generated from core's
parameter specs (:data:`core.model.parameters.PARAMETERS`), with the command
line's defaults.

Qt's ``offscreen`` platform cannot host the VTK OpenGL widget; run under a
real display or ``xvfb-run``.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from qtpy import QtCore, QtGui, QtWidgets
from superqt import QLabeledDoubleSlider, QLabeledSlider
from superqt.utils import create_worker

from core.io.blastholes import Blastholes
from core.io.project import VIEWER_RANGES
from core.model.parameters import PARAMETERS, ParameterSpec
from core.threads import cancelling

from . import _vtkenv  # noqa: F401
from .builders import build_scene, empty_layer_reasons, refresh_scene
from .layer_names import LAYER_NAMES, SCREENSHOT_FORMATS, parse_layers
from .model import (
    Cancelled,
    ViewerModel,
    bodies,
    compute,
    display_unit,
    earliest_step,
    project_input,
    project_read_options,
)
from .scene import SceneRenderer, drag_on_plane
from .silence import noted, silenced

Qt = QtCore.Qt
Signal = QtCore.Signal
#: Slider groups: the method's steps, in the geologist's words.
SECTIONS = {
    "boundary": "Boundary holes (section 2.1-2.3)",
    "snake": "Edge map, GVF and snake (2.4-2.5)",
    "correspondence": "Correspondence between benches (3)",
    "morph": "Metamorphosis (4)",
    "prediction": "Prediction below the benches",
    "surface": "Surface",
}


class ParamControl(QtWidgets.QWidget):
    """A labelled slider for one core parameter, in the input's units; ``auto`` for a data-derived default.

    A flag (``kind == "flag"``) is a check box instead of a slider.
    """

    valueChanged = Signal(str, object)  #: name, value in engine units (``None``: derived from the data)

    def __init__(self, spec: ParameterSpec, value, holes, parent=None):
        super().__init__(parent)
        self.spec = spec
        self._factor, self.unit = display_unit(spec, holes)
        self._derived = spec.resolved(None, holes.hole_spacing_m)
        lay = QtWidgets.QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lo, hi = (v * self._factor for v in spec.limits(holes.hole_spacing_m))
        self.slider: QLabeledSlider | QLabeledDoubleSlider | QtWidgets.QCheckBox
        if spec.kind == "flag":
            self.slider = QtWidgets.QCheckBox()
        elif spec.integer:
            self.slider = QLabeledSlider(Qt.Orientation.Horizontal)
            self.slider.setRange(int(lo), int(hi))
        else:
            self.slider = QLabeledDoubleSlider(Qt.Orientation.Horizontal)
            self.slider.setDecimals(3)
            self.slider.setRange(lo, hi)
        lay.addWidget(self.slider, 1)
        self.auto: QtWidgets.QCheckBox | None = None
        if spec.default is None:
            self.auto = QtWidgets.QCheckBox("auto")
            self.auto.setToolTip(f"Derived from the data: {spec.auto}")
            lay.addWidget(self.auto)
        if spec.kind == "flag":
            default = "on" if spec.default else "off"
        else:
            default = spec.auto if spec.default is None else f"{spec.default * self._factor:g}"
        symbol = f" ({spec.symbol})" if spec.symbol else ""
        unit = f" in {self.unit}" if self.unit else ""
        self.setToolTip(f"<b>{spec.label}{symbol}</b>{unit}<br>{spec.help}<br>Default: {default}")
        self.slider.setToolTip(self.toolTip())
        self.set_value(value)
        if isinstance(self.slider, QtWidgets.QCheckBox):
            self.slider.toggled.connect(self._changed)
        else:
            self.slider.valueChanged.connect(self._changed)
        if self.auto is not None:
            self.auto.toggled.connect(self._changed)

    def set_value(self, value) -> None:
        """Show ``value`` (engine units; ``None``: auto) without emitting; :meth:`value` returns it unchanged."""
        self._shown = value
        for w in (self.slider, self.auto):
            if w is not None:
                w.blockSignals(True)
        shown = self._derived if value is None else value
        if isinstance(self.slider, QtWidgets.QCheckBox):
            self.slider.setChecked(bool(shown))
        elif shown is not None:
            v = shown * self._factor
            v = int(round(v)) if self.spec.integer else v
            # a value past the typical range (a project's) is shown as it is, not clamped to the range's end
            lo, hi = self.slider.minimum(), self.slider.maximum()
            if not lo <= v <= hi:
                self.slider.setRange(min(lo, v), max(hi, v))
            self.slider.setValue(v)
        if self.auto is not None:
            self.auto.setChecked(value is None)
            self._show_auto()
        for w in (self.slider, self.auto):
            if w is not None:
                w.blockSignals(False)

    def value(self):
        """The value in engine units (``None`` when auto).

        The value last set is returned exactly; a value the user picked on the
        slider is rounded to the slider's shown decimals in the input's units
        first (a slider position maps to 0.4995 where the label reads 0.5).
        """
        if self.auto is not None and self.auto.isChecked():
            return None
        if isinstance(self.slider, QtWidgets.QCheckBox):
            return self.slider.isChecked()
        if self._shown is not None:
            return self._shown
        if self.spec.integer:
            return int(round(self.slider.value() / self._factor))
        shown = round(float(self.slider.value()), self.slider.decimals())
        return float(f"{shown / self._factor:.12g}")

    def _changed(self, *_) -> None:
        self._shown = None  # the user moved it: read the slider
        if self.auto is not None:
            self._show_auto()
        self.valueChanged.emit(self.spec.name, self.value())

    def _show_auto(self) -> None:
        """Grey the slider out while ``auto`` is ticked, and hide it when the default is not known ahead.

        A default derived per geozone (the alignment cell, the morph speed clamp) has no value
        before a run: the slider showed its range's lower end, which the model does not use.
        """
        auto = self.auto is not None and self.auto.isChecked()
        self.slider.setEnabled(not auto)
        self.slider.setVisible(not (auto and self._derived is None))


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
    #: The next bench's band and suggested holes, computed in the worker thread, are drawn.
    nextBenchShown = Signal()

    def __init__(
        self, model: ViewerModel | None = None, *, debounce_ms: int = 150, auto_run: bool = True, restore: bool = True
    ):
        """The window on ``model``, run at once (``auto_run``).

        ``restore``: once the window is up, offer to restore work an earlier session autosaved
        (:meth:`offer_restore`). ``False`` for a window no one answers (the window gallery, the
        benchmarks): its modal question blocked them for good, and a restore put someone's
        unsaved work in their pictures.
        """
        super().__init__()
        from pyvistaqt import QtInteractor

        self.model = model or ViewerModel(None)
        self.setWindowTitle("BGM viewer")
        self.resize(1400, 900)
        self._jobs = itertools.count(1)
        self._job = 0
        self._worker = None
        self._stop = threading.Event()
        #: The next bench being computed in a worker thread (see _start_next_bench), its worker, and the event
        #: that cancels it (one per computation: a superseded one is told from the current one by it).
        self._next_bench = None
        self._next_bench_worker = None
        self._next_bench_stop = threading.Event()
        #: The next bench whose band and suggestions were last drawn.
        self._next_bench_drawn = None
        self._pending_step: str | None = None
        self._queued_step: str | None = None
        #: The step the run the user stopped ran from (``None``: none was stopped since): Run again runs from it.
        self._stopped_step: str | None = None
        #: Why the last run failed (``None``: it succeeded): the surfaces on screen are from an earlier run.
        self._failure: str | None = None
        #: What the last Undo (or change of bench pair) did, said when its run is done (the run's progress hid it).
        self._undo_note = ""
        #: The selection and translation last put in the dx, dy boxes (see _show_translation).
        self._boxes_show: tuple | None = None
        #: The model whose unsaved work the user discarded to open another file: its autosave goes once that
        #: file is open (see _confirm_discard).
        self._discarded: ViewerModel | None = None
        self._request_time = 0.0
        self._started = 0.0
        self.last_run_seconds = float("nan")
        self.last_update_seconds = float("nan")
        # Only the newest of a burst of worker results is drawn (drawing costs more than computing some).
        self._latest: tuple | None = None
        self._show_timer = self._single_shot(0, self._show_latest)
        self._debounce = self._single_shot(debounce_ms, self._start_queued)
        #: Writes the unsaved work to the autosave a few seconds after a change (ViewerModel.autosave).
        self._autosave_timer = self._single_shot(0, self._autosave)
        #: What runs said of an opened project's overrides naming components that do not exist, not yet shown.
        self._missing_notes: list[str] = []
        self._missing_timer = self._single_shot(0, self._tell_missing)

        # no multi-sampling: software rendering is ~4x slower with it (see issue 6)
        self.plotter = _single_render(QtInteractor(self, multi_samples=0, auto_update=False))
        self.setCentralWidget(self.plotter.interactor)
        self.scene = build_scene(
            self.model.holes,
            self.model.result,
            self.model.selection,
            visible=[name for name, shown in self.model.layer_visibility.items() if shown],
            vertical_exaggeration=self.model.vertical_exaggeration,
            deferred=True,  # the next bench in the worker thread: seconds on Kennecott
        )
        # the legend is a dock (GeozoneLegend): drawn in the view it covered the data
        self.renderer = SceneRenderer(self.plotter, self.scene, auto_render=True, legend=False)
        self._camera = "iso"
        self._fitted = False
        #: Whether the window was shown yet: the first show sets the camera (:meth:`showEvent`), no later one.
        self._shown = False
        #: The camera a project saved, put back in place of fitting the data once its run is drawn (``None``: fit).
        self._saved_camera: dict | None = self.model.camera

        self._build_menus()
        self._build_layer_panel()
        self._build_selection_panel()
        self._build_parameter_panel()
        self._build_alignment_panel()
        self._build_view_panels()
        self.progress_bar = QtWidgets.QProgressBar()
        self.progress_bar.setRange(0, 100)
        self.progress_bar.setMaximumWidth(200)
        self.statusBar().addPermanentWidget(self.progress_bar)
        # Beside the progress bar: a run on a large pit lasts tens of seconds to minutes, and the only
        # ways out of it were another change or closing the window.
        self.stop_button = QtWidgets.QToolButton()
        self.stop_button.setDefaultAction(self.stop_action)
        self.statusBar().addPermanentWidget(self.stop_button)
        self._play = QtCore.QTimer(self)
        self._play.setInterval(80)
        self._play.timeout.connect(self._advance_frame)
        self._connect_model()
        self._drag_start: tuple[int, int] | None = None
        self._click_at: tuple[int, ...] | None = None
        self._watch_mouse()
        self._update_title()
        if auto_run:
            self.request("contours", immediate=True)
        # Once the window is up (the question shows over it): work an earlier session autosaved and never saved.
        # (A timer of the window's own: one of the application's would call it on a window closed already.)
        if restore:
            self._single_shot(0, self.offer_restore).start()

    # ------------------------------------------------------------------ building
    def _single_shot(self, interval_ms: int, slot) -> QtCore.QTimer:
        timer = QtCore.QTimer(self)
        timer.setSingleShot(True)
        timer.setInterval(interval_ms)
        timer.timeout.connect(slot)
        return timer

    def _build_menus(self) -> None:
        m = self.menuBar().addMenu("&File")
        m.addAction("&Open blastholes...", self.open_input_dialog, QtGui.QKeySequence.StandardKey.Open)
        m.addAction("Open &project...", self.open_project_dialog)
        m.addAction("&Save project", self.save_project, QtGui.QKeySequence.StandardKey.Save)
        m.addAction("Save project &as...", lambda: self.save_project(ask=True))
        m.addSeparator()
        m.addAction("Export &screenshot...", self.export_screenshot_dialog)
        m.addAction("Export s&urface...", self.export_surface_dialog)
        m.addAction("Export shown surfaces to a &folder...", self.export_surfaces_dialog)
        m.addSeparator()
        m.addAction("&Quit", self.close, QtGui.QKeySequence.StandardKey.Quit)
        e = self.menuBar().addMenu("&Edit")
        self.undo_action = QtGui.QAction("&Undo alignment", self)
        self.undo_action.setShortcut(QtGui.QKeySequence.StandardKey.Undo)
        self.undo_action.triggered.connect(self.undo)
        e.addAction(self.undo_action)
        self.redo_action = QtGui.QAction("&Redo alignment", self)
        self.redo_action.setShortcut(QtGui.QKeySequence.StandardKey.Redo)
        self.redo_action.triggered.connect(self.redo)
        e.addAction(self.redo_action)
        r = self.menuBar().addMenu("&Run")
        self.stop_action = QtGui.QAction("&Stop", self)
        self.stop_action.setShortcut(QtGui.QKeySequence("Esc"))
        self.stop_action.setToolTip("Stop the run under way (Esc): the picture goes back to the last run that finished")
        self.stop_action.triggered.connect(self.stop_run)
        self.stop_action.setEnabled(False)
        r.addAction(self.stop_action)
        self.rerun_action = QtGui.QAction("Run &again", self)
        self.rerun_action.setShortcut(QtGui.QKeySequence("F5"))
        self.rerun_action.triggered.connect(self.run_again)
        r.addAction(self.rerun_action)
        v = self.menuBar().addMenu("&View")
        for cam, key in (("iso", "I"), ("top", "T"), ("front", "F"), ("side", "S")):
            v.addAction(f"Camera: {cam}", functools.partial(self.set_camera, cam), QtGui.QKeySequence(f"Ctrl+{key}"))
        v.addAction("Fit the data", self.fit_view, QtGui.QKeySequence("Ctrl+0"))
        h = self.menuBar().addMenu("&Help")
        h.addAction("&Shortcuts", self.show_shortcuts, QtGui.QKeySequence("F1"))

    def set_camera(self, camera: str) -> None:
        """Look from ``camera`` (see :meth:`SceneRenderer.set_camera`) and fit the visible data."""
        self._camera = camera
        self.renderer.set_camera(camera)
        self.plotter.render()

    def fit_view(self) -> None:
        """Fit the visible data, keeping the direction of view."""
        self.renderer.fit()
        self.plotter.render()

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if self._shown:  # shown again (un-minimised, hidden and shown): the view stays as the geologist left it
            return
        self._shown = True
        # fit once the docks are laid out: fitted before, Kennecott showed as a thin sliver
        QtCore.QTimer.singleShot(0, self._show_camera)

    def _show_camera(self) -> None:
        """The project's camera if it saved one, else look from :attr:`_camera` and fit the data."""
        if self._saved_camera is None:
            self.set_camera(self._camera)
            return
        self.renderer.set_camera_state(self._saved_camera)
        self.plotter.render()

    def _build_view_panels(self) -> None:
        from .panels import GeozoneLegend, SectionPanel

        self.legend = GeozoneLegend(self.renderer, self.model.holes)
        self.legend.surfacesChanged.connect(self._on_shown_geozones)
        self._dock("Geozones", self.legend, Qt.DockWidgetArea.LeftDockWidgetArea)
        self.sections = SectionPanel(self.renderer, self.model.holes)
        self._dock("Benches and section", self.sections, Qt.DockWidgetArea.LeftDockWidgetArea)

        w = QtWidgets.QWidget()
        form = QtWidgets.QFormLayout(w)
        self.surface_scope = QtWidgets.QComboBox()
        self.surface_scope.setToolTip("Whose surfaces are built and shown (each is the one bgm build exports)")
        self.surface_scope.currentIndexChanged.connect(self._on_shown_geozones)
        form.addRow("surfaces of", self.surface_scope)
        self.min_volume = QtWidgets.QDoubleSpinBox()
        self.min_volume.setRange(0.0, 1e12)
        self.min_volume.setDecimals(0)
        self.min_volume.setKeyboardTracking(False)
        self.min_volume.setToolTip(
            "Bodies of a surface smaller than this are not shown: a lone mislabelled hole (label noise)"
            " makes a small body of its own. The exported surfaces keep them."
        )
        self.min_volume.valueChanged.connect(self._on_body_filter)
        self._volume_label = QtWidgets.QLabel()
        form.addRow(self._volume_label, self.min_volume)
        self.min_holes = QtWidgets.QSpinBox()
        self.min_holes.setRange(0, 10000)
        self.min_holes.setKeyboardTracking(False)
        self.min_holes.setToolTip("Bodies holding fewer of their geozone's holes than this are not shown")
        self.min_holes.valueChanged.connect(self._on_body_filter)
        form.addRow("min holes in a body", self.min_holes)
        self._fill_surface_panel()
        self._dock("Surfaces", w, Qt.DockWidgetArea.LeftDockWidgetArea)

    def _fill_surface_panel(self) -> None:
        """Show the model's surface scope and body filter, in its input's units, without emitting."""
        m = self.model
        widgets = (self.surface_scope, self.min_volume, self.min_holes)
        for wid in widgets:
            wid.blockSignals(True)
        self.surface_scope.clear()
        host = bodies(m.holes)
        if host is not None:  # a host rock's surface would wrap the bodies
            rock = sorted(set(m.holes.geozones) - set(host))
            self.surface_scope.addItem(f"all but the host rock ({', '.join(rock)})", "bodies")
        for text, scope in (("all geozones", "all"), ("ticked geozones", "ticked"), ("selected geozone", "selected")):
            self.surface_scope.addItem(text, scope)
        self.surface_scope.setCurrentIndex(max(self.surface_scope.findData(m.surface_scope), 0))
        self._volume_label.setText(f"min body volume ({m.holes.frame.length_unit}³)")
        self.min_volume.setValue(m.min_body_volume_m3 / self._mpu**3)
        self.min_holes.setValue(m.min_body_holes)
        for wid in widgets:
            wid.blockSignals(False)
        if m.surface_scope == "ticked":  # a project's ticked geozones: the legend ticks them
            self.legend.set_shown(m.surface_geozones or [])

    def _on_shown_geozones(self, *_) -> None:
        """Whose surfaces are built changed (scope or legend ticks): build the ones missing."""
        scope = self.surface_scope.currentData()
        if scope == "bodies":
            zones = bodies(self.model.holes)
        elif scope == "all":
            zones = None
        else:
            # the selected geozone's surface is always built: naming it here kept it after another was selected
            zones = self.legend.shown() if scope == "ticked" else []
        built = zones != self.model.surface_geozones
        self.model.set_view(surface_scope=scope, surface_geozones=zones)
        if built:
            self.request("surface", immediate=True)

    def _on_body_filter(self, *_) -> None:
        self.model.set_view(
            min_body_volume_m3=self.min_volume.value() * self._mpu**3, min_body_holes=self.min_holes.value()
        )
        self.request("surface")

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
            item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
            item.setCheckState(Qt.CheckState.Checked if layer.visible else Qt.CheckState.Unchecked)
            self.layer_list.addItem(item)
        self.layer_list.itemChanged.connect(self._on_layer_item)
        self.layer_list.currentRowChanged.connect(self._on_layer_row)
        lay.addWidget(self.layer_list)
        form = QtWidgets.QFormLayout()
        self.opacity_slider = QtWidgets.QSlider(Qt.Orientation.Horizontal)
        self.opacity_slider.setRange(0, 100)
        self.opacity_slider.valueChanged.connect(self._on_opacity)
        form.addRow("opacity", self.opacity_slider)
        self.frame_slider = QtWidgets.QSlider(Qt.Orientation.Horizontal)
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
        # what a project and bgm view --exaggeration may ask for: a narrower range showed another value than drawn
        self.ve_spin.setDecimals(2)
        self.ve_spin.setRange(0.01, VIEWER_RANGES["vertical_exaggeration"].high)
        self.ve_spin.setSingleStep(0.5)
        self._show_ve(self.model.vertical_exaggeration)
        self.ve_spin.valueChanged.connect(self._on_ve)
        form.addRow("vertical exaggeration", self.ve_spin)
        lay.addLayout(form)
        self._dock("Layers", w, Qt.DockWidgetArea.LeftDockWidgetArea)
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
        self.picked_label = QtWidgets.QLabel("click a hole, contour or surface")
        self.picked_label.setWordWrap(True)
        self.picked_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        form.addRow("picked", self.picked_label)
        self._dock("Selection", w, Qt.DockWidgetArea.LeftDockWidgetArea)

    def _fill_selection(self) -> None:
        h, sel = self.model.holes, self.model.selection
        for wid in (self.geozone_combo, self.bench_combo, self.component_spin):
            wid.blockSignals(True)
        self.geozone_combo.clear()
        self.geozone_combo.addItems(h.geozones)
        self.geozone_combo.setCurrentText(sel.geozone)
        self.bench_combo.clear()
        for k in range(max(h.n_benches - 1, 1)):
            # one bench: no bench below it (the label read "685 -> nan m")
            below = f" -> {h.bench_z_input(k + 1):g}" if k + 1 < h.n_benches else ""
            self.bench_combo.addItem(f"{h.bench_z_input(k):g}{below} {h.frame.length_unit}")
        self.bench_combo.setCurrentIndex(sel.bench)
        self.component_spin.setValue(sel.component)
        for wid in (self.geozone_combo, self.bench_combo, self.component_spin):
            wid.blockSignals(False)

    def _carried_label(self) -> QtWidgets.QLabel:
        self.carried_label = QtWidgets.QLabel("-")
        self.carried_label.setWordWrap(True)
        self.carried_label.setToolTip(
            "How much of the selected geozone's movement between benches its prediction carries on below the"
            " deepest bench, how far its boundary moves a bench there (median), and what chose it (bgm build's"
            " report, 'Below the deepest bench')"
        )
        return self.carried_label

    def _build_parameter_panel(self) -> None:
        w = QtWidgets.QWidget()
        lay = QtWidgets.QVBoxLayout(w)
        self.param_controls: dict[str, ParamControl] = {}
        for section, title in SECTIONS.items():
            box = QtWidgets.QGroupBox(title)
            form = QtWidgets.QFormLayout(box)
            for spec in (p for p in PARAMETERS if p.section == section):
                ctl = ParamControl(spec, self.model.param(spec.name), self.model.holes)
                ctl.valueChanged.connect(self.set_param)
                label = QtWidgets.QLabel(f"{spec.label} ({ctl.unit})" if ctl.unit else spec.label)
                label.setToolTip(ctl.toolTip())
                form.addRow(label, ctl)
                self.param_controls[spec.name] = ctl
            if section == "prediction":  # what the selected geozone's prediction carries on, and what chose it
                form.addRow("movement carried", self._carried_label())
            lay.addWidget(box)
        lay.addStretch(1)
        self._param_dock = self._dock("Parameters", w, Qt.DockWidgetArea.RightDockWidgetArea)

    def _build_alignment_panel(self) -> None:
        w = QtWidgets.QWidget()
        form = QtWidgets.QFormLayout(w)
        unit = self.model.holes.frame.length_unit
        self.translation_label = QtWidgets.QLabel("-")
        self.translation_label.setToolTip(
            "How far the selected source component is moved onto the bench below before the"
            " morph (the translation t of the paper's alignment step, section 3), in the input's units"
        )
        self._unit_labels = [QtWidgets.QLabel(f"translation ({unit})"), QtWidgets.QLabel(f"Ctrl+arrow step ({unit})")]
        form.addRow(self._unit_labels[0], self.translation_label)
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
            ("Redo", self.redo),
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
        form.addRow(self._unit_labels[1], self.nudge_step)
        form.addRow(QtWidgets.QLabel("Shift + drag in the view moves the source on its bench."))
        for key, (dx, dy) in {"Left": (-1, 0), "Right": (1, 0), "Up": (0, 1), "Down": (0, -1)}.items():
            sc = QtWidgets.QShortcut(QtGui.QKeySequence(f"Ctrl+{key}"), self)
            sc.activated.connect(
                lambda dx=dx, dy=dy: self.nudge(
                    dx * self.nudge_step.value() * self._mpu, dy * self.nudge_step.value() * self._mpu
                )
            )
        self._dock("Manual alignment", w, Qt.DockWidgetArea.RightDockWidgetArea)

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
        # After a press the camera style holds the mouse and the release reaches only the style
        # (pyvista issue 4976): a click (press and release in place) is seen there.
        style = getattr(self.plotter.iren, "style", None)
        if style is not None:  # the camera style announces its moves on itself
            style.AddObserver("StartInteractionEvent", lambda *_: self.renderer.set_interacting(True))
            style.AddObserver("EndInteractionEvent", lambda *_: self._stop_interacting())
            style.AddObserver("LeftButtonReleaseEvent", lambda *_: self._on_click_release(), 10.0)

    def _stop_interacting(self) -> None:
        self.renderer.set_interacting(False)
        self.plotter.render()  # the full surfaces once the view stands still

    def _on_click_release(self) -> None:
        click, self._click_at = getattr(self, "_click_at", None), None
        if click is None or self._drag_start is not None:
            return
        pos = self.plotter.iren.interactor.GetEventPosition()
        if abs(pos[0] - click[0]) + abs(pos[1] - click[1]) <= 3:
            self.pick(*pos)  # a click, not a turn of the camera

    def _swallow(self, event: str) -> None:
        self.plotter.iren.interactor.GetCommand(self._mouse_tags[event]).SetAbortFlag(1)

    def _source_plane_z(self) -> float:
        z = float(self.model.holes.bench_levels_m[self.model.selection.bench])
        return float(self.scene.view.z(z))

    def drag_translation(self, start_px, end_px) -> np.ndarray | None:
        """World ``(dx, dy)`` metres of a drag between two display pixels on the source bench."""
        return drag_on_plane(self.plotter, start_px, end_px, self._source_plane_z())

    def _on_press(self, iren, event) -> None:
        self._click_at = tuple(iren.GetEventPosition())
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
            cur = self.model.translation_m() or (0.0, 0.0)  # the release nudges from it
            tx, ty = ((c + v) / self._mpu for c, v in zip(cur, d))
            self.statusBar().showMessage(
                f"dragging the source: translation {tx:.2f}, {ty:.2f} {self.model.holes.frame.length_unit}"
                " (release to apply)"
            )
        self._swallow(event)

    def _on_release(self, iren, event) -> None:
        if self._drag_start is None:
            self._on_click_release()
            return
        start, self._drag_start = self._drag_start, None
        self._swallow(event)
        d = self.drag_translation(start, iren.GetEventPosition())
        if d is None:
            self.statusBar().showMessage("cannot drag in a side view: turn the camera towards the benches", 5000)
            return
        if np.hypot(*d) > 0:
            self.nudge(float(d[0]), float(d[1]))

    # ------------------------------------------------------------------ picking
    def pick(self, x_px: float, y_px: float) -> dict | None:
        """Report what is under display pixel ``(x_px, y_px)`` (VTK's, origin bottom left).

        A hole: its id, geozone, bench and the input's other columns, in the
        status bar and the Selection panel. A contour: its geozone, bench
        pair and component become the selection. A surface: its geozone does.
        Returns what was reported (``None``: nothing there).
        """
        hit = self.renderer.pick(x_px, y_px)
        if hit is None:
            return None
        name, index = hit
        layer: Any = self.scene[name]
        if name == "blastholes":
            info = self.model.hole_info(index)
        elif name in ("contours", "predicted contours"):
            g, z, poly = layer.items[index]
            info = {"geozone": g, f"elevation ({self.model.holes.frame.length_unit})": self._z_input(z)}
            info.update(self._select_contour(g, z, poly))
        elif name == "surfaces":
            g = layer.meshes[index][0]
            info = {"geozone": g, "surface": "shown as bgm build exports it"}
            self._select(geozone=g, component=0)
        else:
            return None
        if name != "blastholes":
            self._fill_selection()
        text = ", ".join(f"{k} {v}" for k, v in info.items())
        self.picked_label.setText(text.replace(", ", "\n"))
        self.statusBar().showMessage(f"picked {name[:-1] if name.endswith('s') else name}: {text}", 15000)
        return info

    def _z_input(self, z_m: float) -> float:
        return round(float(self.model.holes.frame.z_to_input(z_m)), 3)

    def _select_contour(self, geozone: str, z_m: float, polygon) -> dict:
        """Select the bench pair and component of a picked contour (a modelled one; else its geozone only)."""
        h = self.model.holes
        bench = int(np.argmin(np.abs(h.bench_levels_m - z_m)))
        if abs(h.bench_levels_m[bench] - z_m) > 1e-6:
            self._select(geozone=geozone)
            return {}
        pair_bench = min(bench, max(h.n_benches - 2, 0))
        sources = self.model.result.sources(type(self.model.selection)(geozone, pair_bench, 0))
        component = next((i for i, c in enumerate(sources) if c.polygon is polygon), None)
        if bench != pair_bench or component is None:
            self._select(geozone=geozone, bench=pair_bench, component=0)
            return {"bench pair": pair_bench}
        self._select(geozone=geozone, bench=pair_bench, component=component)
        return {"bench pair": pair_bench, "component": component}

    # ------------------------------------------------------------------ layer panel
    def empty_layers(self) -> dict[str, str]:
        """``{name: why}`` of the visible layers that draw nothing."""
        m = self.model
        return empty_layer_reasons(
            self.scene, m.holes, m.result, m.selection, lambda layer: not self.renderer.actors.get(layer.name)
        )

    def _on_layer_item(self, item) -> None:
        layer = self.scene.get(item.text())
        if layer is not None:
            layer.visible = item.checkState() == Qt.CheckState.Checked
            # the project saves it: a view set up and saved came back with the default layers
            self.model.set_view(layer_visibility={**self.model.layer_visibility, layer.name: layer.visible})
            why = self.empty_layers().get(layer.name) if layer.visible and not self.busy else None
            if why:
                self.statusBar().showMessage(f"{layer.name} is empty: {why}", 10000)
            self._start_next_bench()  # shown for the first time: computed off this thread

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

    def _show_ve(self, ve: float) -> None:
        """Show the exaggeration ``ve`` as it is, one below the box's range and decimals (a project's) too.

        A project may hold any exaggeration above 0: clamped to 0.01 (or rounded to two decimals), the
        box showed another value than drawn and set the model to it, marking the project unsaved.
        """
        if ve < self.ve_spin.minimum():
            self.ve_spin.setDecimals(max(2, int(np.ceil(-np.log10(ve))) + 2))  # two significant digits
            self.ve_spin.setMinimum(ve)
        self.ve_spin.setValue(ve)

    def _on_ve(self, v: float) -> None:
        self.model.set_view(vertical_exaggeration=float(v))
        with self.renderer.batch():
            self.scene.vertical_exaggeration = float(v)
            self.renderer.fit()  # the data got taller or flatter: fit them again
        self.sections.follow_view()

    def set_layer_visible(self, name: str, visible: bool) -> None:
        item = self.layer_list.findItems(name, Qt.MatchFlag.MatchExactly)[0]
        item.setCheckState(Qt.CheckState.Checked if visible else Qt.CheckState.Unchecked)

    # ------------------------------------------------------------------ model changes
    def set_param(self, name: str, value) -> None:
        self.request(self.model.set_param(name, value))

    def _select(self, **kw) -> None:
        try:
            stage = self.model.select(**kw)
        except ValueError as exc:
            self.statusBar().showMessage(str(exc), 5000)
            return
        note = self.model.selection_note  # which component another bench pair selected: said now and when done
        if note:
            self._undo_note = note
        if stage:
            self.request(stage, immediate=True)
        if note:
            self.statusBar().showMessage(f"{self.statusBar().currentMessage()} - {note}")

    @property
    def _mpu(self) -> float:
        """Metres per input unit (the panels speak the input's units, the model metres)."""
        return float(self.model.holes.frame.metres_per_unit)

    def _align(self, change, *args) -> None:
        """Apply an alignment change of the model and re-run; a change it refuses is said in the status bar.

        These are slots (buttons, keys, a drag): an exception raised in one would
        only be printed, or end the application.
        """
        try:
            step = change(*args)
        except ValueError as exc:
            self.statusBar().showMessage(f"alignment not changed: {exc}", 10000)
            return
        self.request(step, immediate=True)

    def apply_translation(self) -> None:
        """Lock the translation typed in the panel (input units)."""
        dx, dy = self.dx_spin.value() * self._mpu, self.dy_spin.value() * self._mpu
        self._align(self.model.set_translation, dx, dy)

    def nudge(self, ddx: float, ddy: float) -> None:
        self._align(self.model.nudge, ddx, ddy)

    def lock_current(self) -> None:
        self._align(self.model.lock_current)

    def clear_override(self) -> None:
        self._align(self.model.clear_override)

    def set_association(self, target: int, flag) -> None:
        self._align(self.model.set_association, target, flag)

    def undo(self) -> None:
        stage = self.model.undo()
        if stage is None:  # the panel's Undo button is always enabled: say why it did nothing
            self.statusBar().showMessage("nothing to undo", 5000)
        if stage:
            self._undo_note = "; ".join(self.model.override_notes)
            self.request(stage, immediate=True)

    def redo(self) -> None:
        """Bring back what the last Undo took back (Edit > Redo, the panel's Redo)."""
        stage = self.model.redo()
        if stage is None:
            self.statusBar().showMessage("nothing to redo", 5000)
            return
        self._undo_note = "; ".join(self.model.override_notes)
        self.request(stage, immediate=True)

    def _connect_model(self) -> None:
        self.model.dirty_changed.connect(self._update_title)
        self.model.dirty_changed.connect(self._arm_autosave)
        self.model.overrides_changed.connect(self._on_overrides)
        self.model.params_changed.connect(self._show_params)
        self.model.params_changed.connect(self._on_overrides)  # a parameter changed: nothing left to redo
        self.model.selection_changed.connect(self._show_component)
        self.model.overrides_missing.connect(self._on_overrides_missing)
        self._on_overrides()  # a new model has nothing to undo: Edit > Undo was left enabled, doing nothing

    def _on_overrides_missing(self, notes: list[str]) -> None:
        """Say what a run dropped of an opened project's overrides (components their bench pair lacks), as opening
        says what it leaves unused: the run checks them off this thread (it traces the benches), not the opening.

        Shown from the event loop, not from within drawing the result that brought them.
        """
        self._missing_notes.extend(notes)
        self._missing_timer.start()

    def _tell_missing(self) -> None:
        notes, self._missing_notes = self._missing_notes, []
        self._tell(notes)

    def _show_params(self) -> None:
        """Show the model's parameters on the sliders (Undo can set them back).

        A slider that shows its value already is left alone: the user may be dragging it.
        """
        for name, ctl in self.param_controls.items():
            value = self.model.param(name)
            if ctl.value() != value:
                ctl.set_value(value)

    def _show_component(self, sel) -> None:
        """Show the selected source component's number (a run moves it when its override follows it)."""
        if self.component_spin.value() != sel.component:
            self.component_spin.blockSignals(True)  # the model selected it already: no second run
            self.component_spin.setValue(sel.component)
            self.component_spin.blockSignals(False)

    def _on_overrides(self) -> None:
        self.undo_action.setEnabled(self.model.can_undo)
        self.redo_action.setEnabled(self.model.can_redo)

    def _update_title(self, *_) -> None:
        name = Path(self.model.project_path).name if self.model.project_path else "untitled project"
        holes = self.model.holes
        unit = f"{holes.frame.length_unit}{', guessed' if holes.unit_guess else ''}"  # a guess stays in sight
        self.setWindowTitle(
            f"BGM viewer - {holes.source or 'input'} ({unit}) - {name}{' *' if self.model.dirty else ''}"
        )

    # ------------------------------------------------------------------ autosave
    def _arm_autosave(self, *_) -> None:
        """Autosave the unsaved work when it is due: one write for a burst of changes (a slider dragged)."""
        wait_s = self.model.autosave_due_in_s()
        if wait_s is not None and not self._autosave_timer.isActive():
            self._autosave_timer.start(int(wait_s * 1000) + 1)

    def _keep_camera(self) -> None:
        """Give the model the camera, for the project to save (turning the view is no change to prompt for)."""
        if self.plotter.render_window is not None:
            self.model.camera = self.renderer.camera_state()

    def _autosave(self) -> None:
        self._keep_camera()
        self.model.autosave()
        if self.model.autosave_note:
            self.statusBar().showMessage(self.model.autosave_note, 10000)
        self._arm_autosave()  # one put off until a run has placed the overrides is tried again

    def offer_restore(self) -> bool:
        """Offer to restore work autosaved by a session that ended without saving it; ``True`` if restored.

        No deletes the autosave. An unreadable autosave is said in the status bar.
        """
        offer = self.model.autosave_offer()
        if self.model.autosave_note:
            self.statusBar().showMessage(self.model.autosave_note, 15000)
        if offer is None:
            return False
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(offer.written))
        name = Path(self.model.project_path).name if self.model.project_path else "this table's untitled project"
        answer = QtWidgets.QMessageBox.question(
            self,
            "Restore unsaved work?",
            f"Changes to {name} were autosaved at {when} and never saved: the viewer or the machine"
            " stopped before they were. Restore them?\n\nNo deletes the autosave.",
            QtWidgets.QMessageBox.StandardButton.Yes | QtWidgets.QMessageBox.StandardButton.No,
            QtWidgets.QMessageBox.StandardButton.Yes,
        )
        if answer != QtWidgets.QMessageBox.StandardButton.Yes:
            self.model.discard_autosave()
            self._said(f"deleted the autosave {offer.path}")
            return False

        def restore() -> None:
            model, notes = noted(lambda: self.model.restored(offer))
            self._replace_model(model)
            self._tell(notes)

        restored = self._guard(restore)
        if restored:
            self._said(f"restored the changes autosaved at {when}: save the project to keep them")
        return restored

    # ------------------------------------------------------------------ worker
    @property
    def busy(self) -> bool:
        return self._pending_step is not None or self._queued_step is not None

    def request(self, step: str, immediate: bool = False) -> None:
        """Re-run from ``step`` (merged with any run not yet finished) after the debounce delay."""
        # The run replaces the model the next bench is computed from: its band is stale from now on, and
        # would keep a core busy through the debounce delay and the new run (seconds on Kennecott).
        self._cancel_next_bench()
        self._queued_step = earliest_step(step, self._queued_step, self._pending_step)
        self._request_time = time.perf_counter()
        if immediate:
            self._debounce.stop()
            self._start_queued()
        else:
            self._debounce.start()
        self._show_running()

    @property
    def running(self) -> bool:
        """A run, or the next bench's band, is under way or about to start: what Stop stops."""
        return self.busy or self._next_bench is not None

    def _show_running(self) -> None:
        """Offer Stop only while something runs (a Stop that does nothing would say "stopped" of nothing)."""
        self.stop_action.setEnabled(self.running)

    def stop_run(self) -> None:
        """Stop the run under way (and the next bench's band) at core's next step; say "stopped".

        The picture goes back to the last run that finished (:meth:`ViewerModel.stop`): the
        part-way result mixed benches of the new sliders with a model of the old. The sliders,
        alignments and selection stay; :meth:`run_again` or the next change runs from where the
        stopped run began.
        """
        if not self.running:
            return
        step = earliest_step(self._pending_step, self._queued_step)
        if step is not None:  # the next bench alone: the model is up to date, nothing to run again
            self._stopped_step = earliest_step(step, self._stopped_step)
        self._debounce.stop()
        self._cancel()  # results of the stopped run that still come are told apart by their job and dropped
        self._pending_step = self._queued_step = None
        self._worker = None
        self._latest = None
        previous = self.model.result
        said = self.model.stop()
        with self.renderer.batch():
            refresh_scene(
                self.scene, self.model.holes, self.model.result, self.model.selection, previous=previous, deferred=True
            )
        self._on_layer_row(None)
        self._show_translation()
        self.progress_bar.setRange(0, 100)  # out of the next bench's busy indicator
        self.progress_bar.setValue(0)
        self.statusBar().showMessage(said)
        self._show_running()

    def run_again(self) -> None:
        """Run again from where the stopped run began (from the contours if none was stopped)."""
        self.request(self._stopped_step or "contours", immediate=True)

    def _cancel(self) -> None:
        """Stop the running job and the next bench's at their next step (their results are ignored from now on)."""
        self._job = next(self._jobs)
        self._stop.set()
        if self._worker is not None:
            self._worker.quit()
            self._worker = None
        self._cancel_next_bench()

    def _cancel_next_bench(self) -> None:
        """Stop computing the next bench at core's next step; what it computed is not drawn.

        Its layers' next bench stays pending (or is replaced by the run to come), and is computed again
        by :meth:`_start_next_bench` if it is still shown once no run is under way.
        """
        self._next_bench_stop.set()
        self._next_bench = self._next_bench_worker = None

    def _start_queued(self) -> None:
        step, self._queued_step = self._queued_step, None
        if step is None:
            return
        # a change after a Stop runs what the stopped run had still to do as well as its own
        step, self._stopped_step = earliest_step(step, self._stopped_step) or step, None
        self._cancel()
        job, self._stop = self._job, threading.Event()
        self._pending_step = step
        self._first_update = True
        self._started = time.perf_counter()
        self.statusBar().showMessage(f"running from {step}...")
        self.progress_bar.setRange(0, 100)  # out of the next bench's busy indicator
        self.progress_bar.setValue(0)
        # errored is connected here: connected later, superqt also raised every error again in Qt's thread
        worker = create_worker(
            _quietly,
            self.model.inputs(),
            self.model.result,
            step,
            self._stop.is_set,
            _start_thread=False,
            _connect={"errored": lambda exc, job=job: self._on_failed(job, exc)},
        )
        worker.yielded.connect(lambda item, job=job: self._on_progress(job, *item))
        worker.returned.connect(lambda _, job=job: self._on_finished(job))
        self._worker = worker
        worker.start()

    def _on_progress(self, job: int, msg: str, frac: float, result) -> None:
        if job == self._job:
            self._latest = (msg, frac, result)
            self._show_timer.start()

    def _show_latest(self) -> None:
        if self._latest is None:
            return
        (msg, frac, result), self._latest = self._latest, None
        previous = self.model.result
        self.model.set_result(result)
        with self.renderer.batch():
            refresh_scene(self.scene, self.model.holes, result, self.model.selection, previous=previous, deferred=True)
        self._on_layer_row(None)
        if not self._fitted and result.complete:
            self._fitted = True  # fit once everything is drawn (the surface can reach below the benches)
            if self._saved_camera is None:
                self.renderer.fit()
            else:  # the project's view, not a fit: its clipping range with the data now drawn
                self.renderer.set_camera_state(self._saved_camera)
                self._saved_camera = None
        if self._first_update:
            self._first_update = False
            self.last_update_seconds = time.perf_counter() - self._request_time
        self._show_translation()
        self.statusBar().showMessage(f"{msg} ({int(frac * 100)}%)")
        self.progress_bar.setValue(int(frac * 100))
        self.resultShown.emit()

    def _on_finished(self, job: int) -> None:
        if job != self._job:
            return
        self._show_latest()  # the last result before saying done
        self._pending_step = None
        self._failure = None
        self._worker = None
        self.last_run_seconds = time.perf_counter() - self._started
        errors = "; ".join(f"{k}: {v}" for k, v in self.model.result.errors.items())
        empty = self.empty_layers()
        errors += (" - " if errors and empty else "") + "; ".join(f"{k} is empty: {v}" for k, v in empty.items())
        note, self._undo_note = self._undo_note, ""
        said = " - ".join(x for x in (errors, note) if x)
        self.statusBar().showMessage(f"done in {self.last_run_seconds:.2f} s" + (f" - {said}" if said else ""))
        self.progress_bar.setValue(100)
        self._start_next_bench()
        self._show_running()

    # The next bench's band and suggested holes take core 1-3.5 s on Kennecott: computed on the
    # window's thread, they froze it. They are computed in a worker thread once a run is done and
    # one of their layers is shown, and drawn when done unless a newer result replaced them.
    def _next_bench_layers(self) -> list:
        return [layer for name in ("uncertainty", "suggested holes") if (layer := self.scene.get(name)) is not None]

    def _start_next_bench(self) -> None:
        """Compute the next bench of the shown band or suggestions in a worker thread (if not done or under way)."""
        shown = [layer for layer in self._next_bench_layers() if layer.visible and layer.next_bench is not None]
        if not shown or self.busy:  # a run under way replaces them: started again when it is done
            return
        nb = shown[0].next_bench
        if nb.error or nb is self._next_bench:
            return
        if nb.computed and nb is not self._next_bench_drawn:  # by a computation superseded after its last step
            self._draw_next_bench(nb)
            return
        if not nb.pending:
            return
        # Cancelled by any newer request (_cancel_next_bench): core stops at its next step, and the old
        # computation's result, should it still come, is told apart by its event and never drawn.
        stop = self._next_bench_stop = threading.Event()
        self._next_bench, started = nb, time.perf_counter()
        self.statusBar().showMessage("computing the next bench's uncertainty band and suggested holes...")
        self.progress_bar.setRange(0, 0)  # busy: core says nothing of its progress
        worker = create_worker(
            nb.compute,
            cancelling(stop.is_set),
            _start_thread=False,
            _connect={"errored": lambda exc, nb=nb, stop=stop: self._on_next_bench(nb, stop, started, exc)},
        )
        worker.returned.connect(lambda _, nb=nb, stop=stop: self._on_next_bench(nb, stop, started))
        self._next_bench_worker = worker
        worker.start()
        self._show_running()

    def _on_next_bench(self, nb, stop: threading.Event, started: float, exc: Exception | None = None) -> None:
        """Draw the next bench just computed, unless a newer request superseded it (then start the shown one's)."""
        if stop.is_set():  # superseded: stale, whether core stopped or had finished
            return
        self._next_bench = self._next_bench_worker = None
        self._show_running()
        if not self.busy:
            self.progress_bar.setRange(0, 100)
            self.progress_bar.setValue(100)
        if not any(layer.next_bench is nb for layer in self._next_bench_layers()):
            self._start_next_bench()  # replaced meanwhile without a request (none does today): the shown one's
            return
        if exc is not None:
            nb.error = f"{type(exc).__name__}: {exc}"
            self.statusBar().showMessage(f"the next bench failed: {nb.error}")
            return
        self._draw_next_bench(nb, started)

    def _draw_next_bench(self, nb, started: float | None = None) -> None:
        """Tell the layers of ``nb`` (computed) that their data changed; say how long it took if ``started``."""
        with self.renderer.batch():
            for layer in self._next_bench_layers():
                if layer.next_bench is nb:
                    layer._emit("data")
        self._next_bench_drawn = nb
        self._on_layer_row(None)  # the budget slider's range: the suggestions' count
        if not self.busy and started is not None:
            seconds = time.perf_counter() - started
            self.statusBar().showMessage(f"next bench's band and suggested holes: done in {seconds:.2f} s")
        self.nextBenchShown.emit()

    def _on_failed(self, job: int, exc: Exception) -> None:
        if job != self._job:
            return
        self._pending_step = None
        self._worker = None
        what = str(exc) if isinstance(exc, RunFailed) else f"{type(exc).__name__}: {exc}"
        self._failure = what
        self.statusBar().showMessage(f"failed: {what}")
        # The request cancelled the next bench of what is still on screen: computed again (not drawn until then).
        self._start_next_bench()
        self._show_running()

    def _show_translation(self) -> None:
        """Show the selected source's translation, and put it in the dx, dy boxes when it is a new one.

        Every result of a run came here: a run lasts seconds (tens on a large pit) and a dx, dy the
        geologist was typing meanwhile was set back to the translation shown, then applied by Apply.
        The boxes now change only when the translation shown (or the component) does.
        """
        self.carried_label.setText(self.model.carried_text())
        t = self.model.current_translation_m()
        if t is None:
            self.translation_label.setText("-")
            return
        locked = self.model.override_here()
        lock = " (locked)" if locked is not None and locked.translation is not None else ""
        tx, ty = t[0] / self._mpu, t[1] / self._mpu
        self.translation_label.setText(f"{tx:.2f}, {ty:.2f}{lock}")
        shown = (self.model.selection, tx, ty)
        if shown == self._boxes_show:
            return
        self._boxes_show = shown
        for s, v in ((self.dx_spin, tx), (self.dy_spin, ty)):
            s.blockSignals(True)
            s.setValue(v)
            s.blockSignals(False)

    def wait_idle(self, timeout_s: float = 60.0) -> bool:
        """Process events until no run is pending (for scripts and tests)."""
        end = time.perf_counter() + timeout_s
        while self.busy and time.perf_counter() < end:
            QtWidgets.QApplication.processEvents(QtCore.QEventLoop.ProcessEventsFlag.AllEvents, 50)
            time.sleep(0.02)
        return not self.busy

    # ------------------------------------------------------------------ files
    def open_input(self, path, read_options: dict | None = None) -> list[str]:
        """Show the blastholes of ``path`` read with ``read_options`` (:func:`read_blastholes`'s keywords: units,
        columns, bench height); returns what reading them warned of (repairs, a unit guessed), also shown by the dialog.
        """
        cache = self.model.store.cache is not None
        model, notes = noted(lambda: ViewerModel(path, cache=cache, read_options=read_options))
        model.layer_visibility = dict(self.model.layer_visibility)  # another table: the layers stay as ticked
        self._replace_model(model)
        if model.holes.unit_guess:  # a unit it had to guess is said, not taken silently
            guess = model.holes.unit_guess.split(": give --units")[0]
            notes.append(f"{model.holes.source}: {guess}; if not, open it again and choose its length unit")
        self.offer_restore()
        return notes

    def _replace_model(self, model: ViewerModel) -> None:
        if self._discarded is self.model:  # its work was discarded for this file: no longer offered
            self._discarded.discard_autosave()
        self._discarded = None
        self._cancel()
        self._pending_step = self._queued_step = self._stopped_step = None
        self._failure = None  # the new input's run says its own
        self._autosave_timer.stop()  # the model replaced has nothing to autosave: saved, discarded or restored
        self.model = model
        self._connect_model()
        with self.renderer.batch():
            refresh_scene(self.scene, model.holes, model.result, model.selection, deferred=True)
            # the new input's coordinates and units on the axes and scale bar (they kept the first input's);
            # once its layers replace the old input's, which would be drawn again for nothing
            self.scene.set_input(model.holes.frame, float(np.max(model.holes.bench_levels_m)))
        self._fill_selection()
        # the sliders' units and ranges follow the input: build them again
        old = self._param_dock
        self._build_parameter_panel()
        self.tabifyDockWidget(old, self._param_dock)
        self.removeDockWidget(old)
        old.deleteLater()
        unit = model.holes.frame.length_unit
        self._unit_labels[0].setText(f"translation ({unit})")
        self._unit_labels[1].setText(f"Ctrl+arrow step ({unit})")
        self._show_ve(model.vertical_exaggeration)
        self.legend.set_holes(model.holes)
        self.sections.set_holes(model.holes)
        self._fill_surface_panel()
        self._show_layer_visibility()
        self._fitted = False
        self.renderer.set_camera("iso")
        self._saved_camera = model.camera
        if model.camera is not None:
            self.renderer.set_camera_state(model.camera)
        self._update_title()
        self.request("contours", immediate=True)

    def _show_layer_visibility(self) -> None:
        """Tick and show the layers the model shows (a project's), in one redraw."""
        self.layer_list.blockSignals(True)
        try:
            with self.renderer.batch():
                for row in range(self.layer_list.count()):
                    item = self.layer_list.item(row)
                    shown = bool(self.model.layer_visibility.get(item.text(), False))
                    item.setCheckState(Qt.CheckState.Checked if shown else Qt.CheckState.Unchecked)
                    layer = self.scene.get(item.text())
                    if layer is not None:
                        layer.visible = shown
        finally:
            self.layer_list.blockSignals(False)

    def open_input_dialog(self) -> None:
        if not self._confirm_discard(opening=True):
            return
        try:
            path, _ = QtWidgets.QFileDialog.getOpenFileName(
                self, "Open blastholes", "", "Blasthole tables (*.csv *.txt *.parquet *.pq);;All files (*)"
            )
            if not path:
                return
            from .read_options import ReadOptionsDialog

            # starts from how the current input was read: the next table of the same mine reads the same way
            dialog = ReadOptionsDialog(self, path, self.model.holes.read_options)
            if dialog.exec() == QtWidgets.QDialog.DialogCode.Accepted:
                self._guard(lambda: self._tell(self.open_input(path, dialog.options())))
        finally:
            self._discarded = None  # cancelled, or the file failed to open: the work stays, and its autosave

    def open_project(self, path) -> list[str]:
        """Open a project and its input; returns what they warned of (overrides or parameters left unused)."""

        def load() -> ViewerModel:
            inp = project_input(path)
            cache = self.model.store.cache is not None
            options = project_read_options(path)  # the units and columns it was made with
            model = (
                ViewerModel(inp, cache=cache, read_options=options)
                if inp
                else ViewerModel(self.model.holes, cache=cache)
            )
            model.load_project(path)
            return model

        model, notes = noted(load)
        self._replace_model(model)
        self.offer_restore()
        return notes

    def _tell(self, notes: list[str]) -> None:
        """Show the warnings of opening a file: only on stderr, a geologist never saw them."""
        if notes:
            QtWidgets.QMessageBox.warning(self, "BGM viewer", "\n\n".join(notes))

    def open_project_dialog(self) -> None:
        if not self._confirm_discard(opening=True):
            return
        try:
            path, _ = QtWidgets.QFileDialog.getOpenFileName(
                self, "Open project", "", "BGM project (*.json);;All files (*)"
            )
            if path:
                self._guard(lambda: self._tell(self.open_project(path)))
        finally:
            self._discarded = None  # cancelled, or the project failed to open: the work stays, and its autosave

    def save_project(self, ask: bool = False) -> bool:
        self._keep_camera()
        path = self.model.project_path
        if ask or not path:
            path, _ = QtWidgets.QFileDialog.getSaveFileName(
                self, "Save project", path or "project.bgm.json", "BGM project (*.json)"
            )
            if not path:
                return False
        saved = self._guard(lambda: self.model.save_project(path))
        if saved:
            self._said(f"saved the project to {Path(path).resolve()}")
        return saved

    def export_screenshot(self, path, size: tuple[int, int] | None = None) -> Path:
        """The current view as a picture, ``size`` pixels (width, height; default the view's), written atomically.

        The format is the extension's, in any case (:data:`SCREENSHOT_FORMATS`); a name
        without one (the file dialog adds none) gets ``.png``. Returns the path written.
        """
        from core.io.atomic import atomic_path

        path = Path(path)
        if not path.suffix:
            path = path.with_name(path.name + ".png")
        suffix = path.suffix.lower()  # PyVista knows lower-case extensions only
        if suffix not in SCREENSHOT_FORMATS:
            raise ValueError(
                f"{path.name}: no picture format {path.suffix}; use one of {', '.join(SCREENSHOT_FORMATS)}"
            )
        with atomic_path(path, suffix=suffix) as tmp:
            self.plotter.screenshot(str(tmp), window_size=list(size) if size else None)
        self._said(f"exported the view to {path.resolve()}")
        return path

    def export_screenshot_dialog(self) -> None:
        path, _ = QtWidgets.QFileDialog.getSaveFileName(
            self, "Export screenshot", "bgm.png", "Pictures (" + " ".join(f"*{s}" for s in SCREENSHOT_FORMATS) + ")"
        )
        if not path:
            return
        w, h = self.plotter.window_size
        text, ok = QtWidgets.QInputDialog.getText(self, "Picture size", "width x height in pixels", text=f"{w}x{h}")
        if not ok:
            return
        try:
            size = tuple(int(v) for v in text.lower().replace(" ", "").split("x"))
            if len(size) != 2 or min(size) < 16 or max(size) > 16384:
                raise ValueError
        except ValueError:
            QtWidgets.QMessageBox.warning(self, "BGM viewer", f"{text!r} is not a size: write it as 1920x1080")
            return
        self._guard(lambda: self.export_screenshot(path, size))

    def export_surfaces(self, folder) -> dict[str, dict]:
        """The shown geozones' surfaces, in every format ``bgm build`` writes, as ``folder/<geozone>/surface.<fmt>``.

        Each is the surface ``bgm build`` writes: the bodies the body filter hides from
        the view are kept (label-noise bodies are the geologist's call in the mine software).
        """
        from core.io.export import build_formats, dxf_layer_names, export_all
        from core.model.build import geozone_folders
        from core.model.surfaces import surface_as_written

        self._check_up_to_date()
        surfaces = {g: m for g, m in self.model.result.built.items() if self.scene.view.shows(g)}
        if not surfaces:
            raise ValueError("no surface is shown: build or tick some first")
        f = self.model.holes.frame
        names = geozone_folders(sorted(surfaces))
        problem = export_folder_problem(Path(folder), [names[g] for g in sorted(surfaces)])
        if problem is not None:
            raise ValueError(problem)
        layers = dxf_layer_names(self.model.holes.geozones)  # as bgm build names them
        out = {}
        # seconds on Kennecott: said geozone by geozone, else the window looked frozen
        with self._busy_export() as progress:
            for i, (g, mesh) in enumerate(sorted(surfaces.items())):
                progress(f"exporting the surface of geozone {g} ({i + 1} of {len(surfaces)})", i / len(surfaces))
                gdir = Path(folder) / names[g]
                gdir.mkdir(parents=True, exist_ok=True)
                moved = surface_as_written(mesh, self.model.holes)
                out[g] = export_all(
                    moved, gdir, "surface", build_formats(), name=g, layer=layers[g], units=f.length_unit
                )
        formats = ", ".join(build_formats())
        self._said(f"exported {len(out)} surfaces ({formats}) to {Path(folder).resolve()}")
        return out

    @contextlib.contextmanager
    def _busy_export(self):
        """A busy cursor and a ``progress(message, fraction)`` in the status bar while files are written.

        The window's thread writes them: events are processed between files so the status bar
        shows, but not the user's input (a second export or a click mid-export).
        """

        def progress(message: str, fraction: float) -> None:
            self.statusBar().showMessage(f"{message}...")
            self.progress_bar.setValue(int(fraction * 100))
            QtWidgets.QApplication.processEvents(QtCore.QEventLoop.ProcessEventsFlag.ExcludeUserInputEvents)

        QtWidgets.QApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        try:
            yield progress
        finally:
            QtWidgets.QApplication.restoreOverrideCursor()
            self.progress_bar.setValue(100)

    def _said(self, message: str) -> None:
        """What was written where, in the status bar (a save or export gave no word it was done)."""
        self.statusBar().showMessage(message, 30000)

    def _check_up_to_date(self) -> None:
        """Refuse to export while a run is pending or after it failed: the surfaces shown are those before the last change.

        An alignment or parameter just changed leaves the old surfaces on screen until
        they are redone; exported then, they would not hold the change. A failed run
        never redoes them: they stay those of the last run that succeeded.
        """
        if self.busy:
            raise ValueError(
                "the model is being recomputed after the last change: export once the status bar says done"
            )
        # a failed run leaves the surfaces of the run before it on screen: not those of the current parameters
        if self._failure is not None:
            raise ValueError(
                f"the last run failed ({self._failure}): the surfaces shown are from the earlier parameters or"
                " alignment; export once a run succeeds"
            )

    def export_surfaces_dialog(self) -> None:
        folder = QtWidgets.QFileDialog.getExistingDirectory(self, "Export shown surfaces to")
        if folder:
            self._guard(lambda: self.export_surfaces(folder))

    def show_shortcuts(self) -> None:
        """Help > Shortcuts: the mouse and keys of the 3D view and the panels."""
        QtWidgets.QMessageBox.information(self, "Shortcuts", SHORTCUTS_HTML)

    def export_surface(self, path) -> None:
        from core.io.export import dxf_layer_names, export_surface
        from core.model.surfaces import surface_as_written

        self._check_up_to_date()
        mesh = self.model.result.surface
        if mesh is None:
            raise ValueError("no surface has been computed yet")
        f, g = self.model.holes.frame, self.model.selection.geozone
        # its DXF layer as bgm build names it: two labels alike once made R12-safe ("ore 1", "ore_1") had one
        layer = dxf_layer_names(self.model.holes.geozones)[g]
        moved = surface_as_written(mesh, self.model.holes)
        export_surface(moved, path, name=g, layer=layer, units=f.length_unit)
        self._said(f"exported the surface of geozone {g} to {Path(path).resolve()}")

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
    def _confirm_discard(self, opening: bool = False) -> bool:
        """Ask what to do with unsaved changes; ``True`` to go on.

        ``opening``: another file is to be opened. Discarded then, the autosave goes once it is open
        (:meth:`_replace_model`): deleted at once, a file dialog cancelled or a table that failed to
        open left the work in the window, unsaved and no longer autosaved.
        """
        if not self.model.dirty:
            return True
        answer = QtWidgets.QMessageBox.question(
            self,
            "Unsaved changes",
            "The project has unsaved parameter or alignment changes. Save them?",
            QtWidgets.QMessageBox.StandardButton.Save
            | QtWidgets.QMessageBox.StandardButton.Discard
            | QtWidgets.QMessageBox.StandardButton.Cancel,
            QtWidgets.QMessageBox.StandardButton.Save,
        )
        if answer == QtWidgets.QMessageBox.StandardButton.Save:
            return self.save_project()
        if answer == QtWidgets.QMessageBox.StandardButton.Discard:
            if opening:
                self._discarded = self.model
            else:
                self.model.discard_autosave()  # discarded on purpose: not offered again at the next opening
            return True
        return False

    def closeEvent(self, event) -> None:
        if not self._confirm_discard():
            event.ignore()
            return
        self._cancel()  # let the running workers stop (the run and the next bench)
        # and wait for them (they stop at core's next step): a worker still running when Python exits
        # finds its signals deleted and prints a traceback.
        QtCore.QThreadPool.globalInstance().waitForDone(CLOSE_WAIT_MS)
        self._play.stop()
        self._autosave_timer.stop()
        if not getattr(self, "_closed", False):
            self._closed = True
            self.plotter.close()
        event.accept()


def export_folder_problem(folder: Path, subfolders: list[str]) -> str | None:
    """Why the surfaces cannot be exported into ``folder/<subfolder>/`` (``None``: nothing in the way).

    A file where a folder must be (``folder`` itself, a folder above it, or a geozone's
    sub-folder) failed the export with a raw "[Errno 20] Not a directory" naming neither
    the path nor what was expected.
    """
    for above in [*reversed(folder.parents), folder]:
        if above.exists() and not above.is_dir():
            if above == folder:
                return f"{folder} is a file: choose a folder to export the surfaces into (one sub-folder per geozone)"
            return (
                f"{above} is a file, so {folder} cannot be a folder in it: choose a folder to export the surfaces into"
            )
    for name in subfolders:
        inner = folder / name
        if inner.exists() and not inner.is_dir():
            return (
                f"{inner} is a file where the surfaces of geozone folder {name!r} go: move it or choose another folder"
            )
    return None


#: How long closing the window waits for a cancelled run to reach its next step.
CLOSE_WAIT_MS = 10_000


SHORTCUTS_HTML = """<table>
<tr><td><b>Left drag</b></td><td>turn the view about the data</td></tr>
<tr><td><b>Right drag / wheel</b></td><td>zoom</td></tr>
<tr><td><b>Middle drag</b></td><td>pan</td></tr>
<tr><td><b>Click</b></td><td>pick: a hole shows its id, geozone, bench and grade; a contour or surface
selects its geozone (and bench pair and component)</td></tr>
<tr><td><b>Shift + left drag</b></td><td>move the selected source component on its bench</td></tr>
<tr><td><b>Ctrl + arrows</b></td><td>nudge the selected source by the step of the alignment panel</td></tr>
<tr><td><b>Ctrl+Z</b></td><td>undo the last alignment change</td></tr>
<tr><td><b>Ctrl+Shift+Z / Ctrl+Y</b></td><td>redo what Undo took back</td></tr>
<tr><td><b>Ctrl+I / T / F / S</b></td><td>camera: iso, top, front, side</td></tr>
<tr><td><b>Ctrl+0</b></td><td>fit the visible data</td></tr>
<tr><td><b>Ctrl+O / Ctrl+S</b></td><td>open blastholes / save the project</td></tr>
<tr><td><b>Esc / F5</b></td><td>stop the run under way / run again</td></tr>
<tr><td><b>F1</b></td><td>this page</td></tr>
</table>
<p>The Geozones dock shows or hides each geozone; Benches and section hides benches, limits
elevations and cuts the view with a plane you drag along its axis.</p>"""


def _quietly(inputs, previous, step, cancelled):
    """:func:`compute` with the engine's warnings silenced (the status bar reports errors).

    Only the run's own (and its threads'): the window's thread warns on stderr meanwhile as
    ever (see :mod:`bgm_viewer.silence`). A run a newer request cancelled just ends: it is no
    error. An engine's ``RuntimeError`` is raised as :class:`RunFailed`: superqt takes a
    ``RuntimeError`` for a deleted worker and drops it, and the run would never end.
    """
    with contextlib.suppress(Cancelled):
        try:
            yield from silenced(compute(inputs, previous, step, cancelled))
        except RuntimeError as exc:
            raise RunFailed(f"{type(exc).__name__}: {exc}") from exc


class RunFailed(Exception):
    """A run of the engine failed with a ``RuntimeError`` (the message names it)."""


def run_viewer(input_path=None, project_path=None, *, cache: bool = True, **view) -> int:
    """Open the viewer window on ``input_path`` (demo if ``None``) and a project; returns the exit code.

    ``view``: the command line's choices of what to show first (see :func:`viewer_window`).
    """
    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication([])
    window = viewer_window(input_path, project_path, cache=cache, **view)
    window.show()
    return int(app.exec())


def viewer_window(
    input_path=None,
    project_path=None,
    *,
    cache: bool = True,
    geozone: str | None = None,
    bench: int | None = None,
    layers=None,
    camera: str | None = None,
    vertical_exaggeration: float | None = None,
) -> MainWindow:
    """The viewer's window on ``input_path`` and a project, showing what ``bgm view``'s options ask for.

    The geozone and bench pair selected, the layers shown (see :data:`bgm_viewer.layer_names.LAYER_NAMES`),
    the camera and the vertical exaggeration are what a screenshot with the same options shows.
    """
    options = None
    if project_path is not None and not isinstance(input_path, Blastholes):
        input_path = input_path if input_path is not None else project_input(project_path)
        options = project_read_options(project_path)  # read as the project was made: feet stay feet
    model = ViewerModel(input_path, cache=cache, read_options=options)
    if isinstance(input_path, Blastholes) and Path(input_path.source).is_file():
        model.input_path = input_path.source  # read with the command line's options: its file, for the extra columns
    if project_path is not None:
        model.load_project(project_path)
    if geozone is not None or bench is not None:
        model.select(geozone, bench)
    if vertical_exaggeration:
        model.vertical_exaggeration = float(vertical_exaggeration)
    if layers is not None:  # in place of the project's
        shown = parse_layers(layers)
        model.layer_visibility = {name: name in shown for name in LAYER_NAMES}
    model.dirty = False  # the command line's view is no change to save
    window = MainWindow(model)
    if camera:
        window._camera = camera  # applied once the window is laid out (showEvent), in place of the project's
        window._saved_camera = None
    return window
