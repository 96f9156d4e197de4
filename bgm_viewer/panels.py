"""Qt panels that pick out what the 3D view shows: geozones (the legend), benches, elevations, a section.

Each panel only sets display state on the :class:`~bgm_viewer.scene.Scene`
(hidden geozones and benches) or the :class:`~bgm_viewer.scene.SceneRenderer`
(clipping planes); nothing here runs the model.
"""

from __future__ import annotations

import numpy as np
from qtpy import QtCore, QtGui, QtWidgets

from .palette import geozone_colours
from .scene import SceneRenderer

Qt = QtCore.Qt


def _swatch(rgb) -> QtGui.QIcon:
    pix = QtGui.QPixmap(14, 14)
    pix.fill(QtGui.QColor(*rgb))
    return QtGui.QIcon(pix)


class GeozoneLegend(QtWidgets.QWidget):
    """The legend: one row per geozone with a check box (shown or not), its colour and its name.

    ``surfacesChanged`` says the checked set changed (the window builds the surfaces of the checked geozones).
    """

    surfacesChanged = QtCore.Signal()

    def __init__(self, renderer: SceneRenderer, holes, parent=None):
        super().__init__(parent)
        self.renderer = renderer
        lay = QtWidgets.QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        self.list = QtWidgets.QListWidget()
        self.list.setToolTip("Tick the geozones to show: their holes, contours and surfaces")
        lay.addWidget(self.list)
        row = QtWidgets.QHBoxLayout()
        for text, fn in (("All", self.show_all), ("None", self.hide_all)):
            b = QtWidgets.QPushButton(text)
            b.clicked.connect(fn)
            row.addWidget(b)
        lay.addLayout(row)
        self.list.itemChanged.connect(self._changed)
        self.set_holes(holes)

    def set_holes(self, holes) -> None:
        self.list.blockSignals(True)
        self.list.clear()
        counts = dict(zip(*np.unique(holes.geozone, return_counts=True)))
        for g, rgb in geozone_colours(holes.geozones).items():
            item = QtWidgets.QListWidgetItem(_swatch(rgb), f"{g}  ({counts.get(g, 0)} holes)")
            item.setData(Qt.ItemDataRole.UserRole, g)
            item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
            hidden = g in self.renderer.scene.hidden_geozones
            item.setCheckState(Qt.CheckState.Unchecked if hidden else Qt.CheckState.Checked)
            self.list.addItem(item)
        self.list.blockSignals(False)

    def shown(self) -> list[str]:
        """Labels of the checked geozones."""
        items = (self.list.item(i) for i in range(self.list.count()))
        return [it.data(Qt.ItemDataRole.UserRole) for it in items if it.checkState() == Qt.CheckState.Checked]

    def set_shown(self, labels) -> None:
        """Check exactly ``labels``."""
        labels = set(map(str, labels))
        self.list.blockSignals(True)
        for i in range(self.list.count()):
            it = self.list.item(i)
            on = it.data(Qt.ItemDataRole.UserRole) in labels
            it.setCheckState(Qt.CheckState.Checked if on else Qt.CheckState.Unchecked)
        self.list.blockSignals(False)
        self._changed()

    def show_all(self) -> None:
        self.set_shown(self.list.item(i).data(Qt.ItemDataRole.UserRole) for i in range(self.list.count()))

    def hide_all(self) -> None:
        self.set_shown(())

    def _changed(self, *_) -> None:
        shown = set(self.shown())
        every = {self.list.item(i).data(Qt.ItemDataRole.UserRole) for i in range(self.list.count())}
        self.renderer.scene.hidden_geozones = every - shown
        self.surfacesChanged.emit()


class SectionPanel(QtWidgets.QWidget):
    """Benches to show, an elevation range and an axis-aligned section plane (draggable in the view)."""

    def __init__(self, renderer: SceneRenderer, holes, parent=None):
        super().__init__(parent)
        self.renderer = renderer
        self._widget = None
        form = QtWidgets.QFormLayout(self)
        self.benches = QtWidgets.QListWidget()
        self.benches.setMaximumHeight(140)
        self.benches.setToolTip("Tick the benches whose holes and contours are shown")
        self.benches.itemChanged.connect(self._benches_changed)
        form.addRow("benches", self.benches)
        self.z_min = QtWidgets.QDoubleSpinBox()
        self.z_max = QtWidgets.QDoubleSpinBox()
        row = QtWidgets.QHBoxLayout()
        for spin in (self.z_min, self.z_max):
            spin.setDecimals(1)
            spin.setRange(-1e6, 1e6)
            spin.setKeyboardTracking(False)
            spin.valueChanged.connect(self._range_changed)
            row.addWidget(spin)
        self._range_label = QtWidgets.QLabel("elevations")
        form.addRow(self._range_label, row)
        self.axis = QtWidgets.QComboBox()
        self.axis.addItems(["off", "easting (x)", "northing (y)", "elevation (z)"])
        self.axis.setToolTip("Cut the view with a plane across this axis; drag the plane's handle in the view")
        self.keep = QtWidgets.QComboBox()
        self.keep.addItems(["keep below", "keep above"])
        self.position = QtWidgets.QSlider(Qt.Orientation.Horizontal)
        self.position.setRange(0, 1000)
        self.position.setValue(500)
        for w in (self.axis, self.keep):
            w.currentIndexChanged.connect(self._clip_changed)
        self.position.valueChanged.connect(self._clip_changed)
        clip = QtWidgets.QHBoxLayout()
        clip.addWidget(self.axis)
        clip.addWidget(self.keep)
        form.addRow("section", clip)
        form.addRow("position", self.position)
        self.set_holes(holes)

    def set_holes(self, holes) -> None:
        self.holes = holes
        unit = holes.frame.length_unit
        self.benches.blockSignals(True)
        self.benches.clear()
        # The view keeps hiding the benches hidden before (another project of the same input): they were
        # ticked here while not drawn. As the legend does for geozones, they are shown unticked.
        hidden = self.renderer.scene.hidden_benches_m
        for k in range(holes.n_benches):
            z = float(holes.bench_levels_m[k])
            item = QtWidgets.QListWidgetItem(f"{holes.bench_z_input(k):g} {unit}")
            item.setData(Qt.ItemDataRole.UserRole, z)
            item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
            off = any(abs(z - h) < 1e-6 for h in hidden)
            item.setCheckState(Qt.CheckState.Unchecked if off else Qt.CheckState.Checked)
            self.benches.addItem(item)
        self.benches.blockSignals(False)
        self._benches_changed()  # and only those: an elevation the new input has no bench at is forgotten
        self._range_label.setText(f"elevations ({unit})")
        zs = holes.frame.z_to_input(holes.bench_levels_m)
        lo, hi = float(np.min(zs)), float(np.max(zs))
        margin = max(hi - lo, 1.0)
        for spin, value in ((self.z_min, lo - margin), (self.z_max, hi + margin)):
            spin.blockSignals(True)
            spin.setValue(value)
            spin.blockSignals(False)
        self.renderer.set_elevation_range(None, None)
        self.follow_view()  # a section in the new data where its slider says, not where it cut the old

    def _benches_changed(self, *_) -> None:
        items = [self.benches.item(i) for i in range(self.benches.count())]
        hidden = [it.data(Qt.ItemDataRole.UserRole) for it in items if it.checkState() != Qt.CheckState.Checked]
        self.renderer.scene.hidden_benches_m = hidden

    def set_elevation_range(self, lo_input: float, hi_input: float) -> None:
        """Show only what lies between two elevations in the input's units."""
        for spin, value in ((self.z_min, lo_input), (self.z_max, hi_input)):
            spin.blockSignals(True)
            spin.setValue(value)
            spin.blockSignals(False)
        self._range_changed()

    def _range_changed(self, *_) -> None:
        f = self.holes.frame
        self.renderer.set_elevation_range(
            float(f.z_to_local(self.z_min.value())), float(f.z_to_local(self.z_max.value()))
        )

    def follow_view(self) -> None:
        """Put the section back where its slider says in the data, after the drawing changed.

        The cut is in drawn coordinates: after a change of vertical exaggeration an
        elevation section kept its drawn height and so cut another elevation, and after
        another input was opened a section stayed where it cut the old one.
        """
        if self.clip_axis() is not None:
            self._clip_changed()

    def clip_axis(self) -> str | None:
        return (None, "x", "y", "z")[self.axis.currentIndex()]

    def _clip_changed(self, *_) -> None:
        axis = self.clip_axis()
        self._remove_widget()
        if axis is None:
            self.renderer.set_clip(None)
            return
        bounds = self.renderer.data_bounds()
        if bounds is None:
            return
        i = "xyz".index(axis)
        lo, hi = bounds[2 * i], bounds[2 * i + 1]
        value = lo + (hi - lo) * self.position.value() / 1000.0
        self.renderer.set_clip(axis, value, "below" if self.keep.currentIndex() == 0 else "above")
        self._add_widget(axis, value, bounds)

    def _add_widget(self, axis: str, value: float, bounds) -> None:
        """A plane in the view the user drags along its axis; the slider follows."""
        plotter = self.renderer.plotter
        if not hasattr(plotter, "iren") or plotter.iren is None:
            return
        origin = [(bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2, (bounds[4] + bounds[5]) / 2]
        origin["xyz".index(axis)] = value
        self._widget = plotter.add_plane_widget(
            self._dragged,
            normal=axis,
            origin=origin,
            bounds=bounds,
            assign_to_axis=axis,
            normal_rotation=False,
            outline_translation=False,
            implicit=True,
            interaction_event="always",
            color="white",
        )

    def _remove_widget(self) -> None:
        if self._widget is not None:
            self._widget.Off()
            plotter = self.renderer.plotter
            # PyVista 0.47 moved the plotter's widget lists under ``widgets``; older ones keep them on the plotter.
            planes = getattr(getattr(plotter, "widgets", plotter), "plane_widgets", [])
            if self._widget in planes:
                planes.remove(self._widget)
            self._widget = None

    def _dragged(self, normal, origin) -> None:
        axis = self.clip_axis()
        bounds = self.renderer.data_bounds()
        if axis is None or bounds is None:
            return
        i = "xyz".index(axis)
        lo, hi = bounds[2 * i], bounds[2 * i + 1]
        value = float(origin[i])
        self.renderer.set_clip(axis, value, "below" if self.keep.currentIndex() == 0 else "above")
        self.position.blockSignals(True)
        self.position.setValue(int(round(1000 * (value - lo) / max(hi - lo, 1e-9))))
        self.position.blockSignals(False)
