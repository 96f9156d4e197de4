"""A list of layers drawn into a PyVista plotter (off-screen or in a Qt widget).

:class:`Scene` owns the layers, the vertical exaggeration and the legend;
:class:`SceneRenderer` keeps the plotter's actors in step with them: a change
of visibility or opacity touches only the actor properties, a change of data,
frame or colour rebuilds that layer's meshes (a hidden layer's once it is
shown). No Qt here; the Qt window uses
the same renderer with a ``pyvistaqt.QtInteractor`` as the plotter.
"""

from __future__ import annotations

from collections.abc import Iterable
from contextlib import contextmanager, suppress
from dataclasses import replace

import numpy as np
from psygnal import Signal

from core.io.blastholes import LocalFrame

from . import _vtkenv  # noqa: F401
from .layers import Layer, ViewTransform
from .palette import BACKGROUND, BEARINGS, to_float

CAMERAS = ("iso", "top", "front", "side")
#: Part of the picture (left, bottom, right, top; 0-1) the data is fitted into when the legend
#: is drawn in it (off-screen pictures): the legend sits in the strip on the right.
DATA_RECT_WITH_LEGEND = (0.03, 0.06, 0.76, 0.94)
DATA_RECT = (0.05, 0.06, 0.95, 0.94)
LEGEND_WIDTH = 0.2
#: Room (pixels at 72 dpi) kept between the data's box and the window's edges for the axes' labels and
#: titles: their text keeps its size in pixels, and a title ends 91 px from its edge of the box. Looking
#: along an axis (top, front, side) the axes are drawn on the box's left and bottom edges only.
AXES_MARGIN_PX = 100
#: Surfaces with more triangles are drawn coarse while the camera moves (:meth:`SceneRenderer.set_interacting`).
COARSE_ABOVE_FACES = 5000
#: Polylines with more points are drawn decimated while the camera moves.
DECIMATE_ABOVE_POINTS = 4000


class Scene:
    """Ordered layers plus view settings; ``changed(layer_or_None, what)`` after every change."""

    changed = Signal(object, str)

    def __init__(
        self,
        layers: Iterable[Layer] = (),
        *,
        vertical_exaggeration: float = 2.0,
        z_ref: float = 0.0,
        frame: LocalFrame | None = None,
    ):
        self.layers: list[Layer] = []
        self._view = ViewTransform(vertical_exaggeration, z_ref)
        #: The input's frame: axes and scale bar are labelled in its coordinates and units.
        self.frame = frame or LocalFrame(0.0, 0.0)
        for layer in layers:
            self.add(layer)

    def add(self, layer: Layer) -> Layer:
        if layer.name in self.names():
            raise ValueError(f"a layer named {layer.name!r} is already in the scene")
        self.layers.append(layer)
        layer.changed.connect(self.changed)
        self.changed.emit(layer, "added")
        return layer

    def replace(self, layer: Layer) -> Layer:
        """Put ``layer`` in place of the layer of the same name (keeping its visibility and opacity)."""
        old = self.get(layer.name)
        if old is None:
            return self.add(layer)
        layer._visible, layer._opacity = old.visible, old.opacity
        old.changed.disconnect(self.changed)
        self.layers[self.layers.index(old)] = layer
        layer.changed.connect(self.changed)
        self.changed.emit(layer, "data")
        return layer

    def get(self, name: str) -> Layer | None:
        return next((lay for lay in self.layers if lay.name == name), None)

    def __getitem__(self, name: str) -> Layer:
        layer = self.get(name)
        if layer is None:
            raise KeyError(name)
        return layer

    def names(self) -> list[str]:
        return [lay.name for lay in self.layers]

    @property
    def view(self) -> ViewTransform:
        return self._view

    @property
    def vertical_exaggeration(self) -> float:
        return self._view.vertical_exaggeration

    @vertical_exaggeration.setter
    def vertical_exaggeration(self, value: float) -> None:
        value = float(value)
        if value <= 0:
            raise ValueError("vertical exaggeration must be positive")
        if value != self._view.vertical_exaggeration:
            self._set_view(vertical_exaggeration=value)

    def set_input(self, frame: LocalFrame, z_ref: float) -> None:
        """Label the view in another input's coordinates and units (``frame``), exaggerated about ``z_ref`` metres.

        The scene outlives an input (File > Open): kept, the frame of the first one labelled the
        axes and the scale bar of the next in its origin and units (a table in feet in metres).
        """
        self.frame = frame
        self._view = replace(self._view, z_ref=float(z_ref))
        self.changed.emit(None, "view")  # one redraw, and the bearings labelled again even where nothing moved

    def _set_view(self, **changes) -> None:
        view = replace(self._view, **changes)
        if view != self._view:
            self._view = view
            self.changed.emit(None, "view")

    @property
    def hidden_geozones(self) -> frozenset[str]:
        """Geozones whose holes, contours and surfaces are not drawn."""
        return self._view.hidden_geozones

    @hidden_geozones.setter
    def hidden_geozones(self, labels: Iterable[str]) -> None:
        self._set_view(hidden_geozones=frozenset(map(str, labels)))

    @property
    def hidden_benches_m(self) -> frozenset[float]:
        """Bench elevations (metres) whose holes and contours are not drawn."""
        return self._view.hidden_benches_m

    @hidden_benches_m.setter
    def hidden_benches_m(self, levels: Iterable[float]) -> None:
        self._set_view(hidden_benches_m=frozenset(float(z) for z in levels))

    def set_visible_only(self, names: Iterable[str]) -> None:
        """Show exactly the named layers (unknown names raise ``KeyError``)."""
        names = list(names)
        for n in names:
            self[n]
        for layer in self.layers:
            layer.visible = layer.name in names

    def legend_entries(self, is_empty=None) -> list[tuple[str, tuple[int, int, int]]]:
        """Legend of the visible layers: geozones first, then layer colours (no duplicates).

        ``is_empty(layer)`` says whether a layer draws nothing (default: build it and see).
        """
        is_empty = is_empty or (lambda layer: layer.is_empty)
        out, seen = [], set()
        for layer in self.layers:
            if not layer.visible or is_empty(layer):
                continue
            for label, rgb in layer.legend():
                if rgb is not None and label not in seen:
                    seen.add(label)
                    out.append((label, rgb))
        return out


class SceneRenderer:
    """Draw a :class:`Scene` into ``plotter`` and keep it up to date.

    ``plotter`` is a ``pyvista.Plotter`` (off-screen) or a ``pyvistaqt.QtInteractor``.
    ``auto_render``: call ``plotter.render()`` after each change (the Qt window does).
    """

    def __init__(self, plotter, scene: Scene, *, legend: bool = True, auto_render: bool = False, bearings: bool = True):
        self.plotter = plotter
        self.scene = scene
        self.show_legend = legend
        self.show_bearings = bearings
        self.auto_render = auto_render
        self.actors: dict[str, list] = {}
        #: Hidden layers whose data changed since they were last built: built when shown.
        self._unbuilt: set[str] = set()
        self._legend_shown: list | None = None
        self._batching = 0
        self._legend_stale = False
        self._bearings_stale = False
        self._bearings_shown: tuple | None = None
        self._ruler: object | None = None
        self.clip: tuple[str, float, str] | None = None
        self.elevation_range_m: tuple[float | None, float | None] = (None, None)
        with suppress(Exception):
            plotter.disable_anti_aliasing()
        ren_win = getattr(plotter, "ren_win", None)
        if ren_win is not None:
            ren_win.SetMultiSamples(0)
            ren_win.SetLineSmoothing(False)
            ren_win.SetPointSmoothing(False)
            ren_win.SetPolygonSmoothing(False)
        plotter.set_background(to_float(BACKGROUND))
        for layer in scene.layers:
            self._rebuild(layer)
        self._update_legend()
        if bearings:
            with suppress(Exception):  # an orientation widget needs an interactor on some platforms
                plotter.add_axes(
                    xlabel="E",
                    ylabel="N",
                    zlabel="Up",
                    color=to_float(BEARINGS),
                    line_width=2,
                    viewport=(0.82, 0.0, 1.0, 0.18),  # lower right: the scale bar starts at the lower left
                )
            self._update_bearings()
        scene.changed.connect(self._on_change)

    # -- updates -----------------------------------------------------------
    def _on_change(self, layer: Layer | None, what: str) -> None:
        if layer is None:  # view change: everything moves
            for lay in self.scene.layers:
                self._rebuild(lay)
        elif what in ("visible", "opacity"):
            if layer.visible and layer.name in self._unbuilt:
                self._rebuild(layer)
            for actor in self.actors.get(layer.name, []):
                actor.SetVisibility(layer.visible)
                actor.GetProperty().SetOpacity(layer.opacity)
        else:
            self._rebuild(layer)
        if what in ("visible", "added", "data", "color") or layer is None:
            self._legend_stale = True
        if what in ("visible", "added", "data", "frame") or layer is None:
            self._bearings_stale = True
        if not self._batching:
            self._refresh()

    def _refresh(self) -> None:
        if self._legend_stale:
            self._update_legend()
        if self._bearings_stale:
            self._update_bearings()
        if self.auto_render:
            self.plotter.render()

    @contextmanager
    def batch(self):
        """Apply many layer changes with one render at the end.

        A software-rendered frame costs tens of milliseconds; a pipeline
        update replaces most layers at once, and a render per layer made the
        window take over a second to show a result computed in 0.1 s.
        """
        self._batching += 1
        suppressed = getattr(self.plotter, "suppress_rendering", False)
        self.plotter.suppress_rendering = True  # pyvista's own renders (add_actor, legends)
        try:
            yield self
        finally:
            self.plotter.suppress_rendering = suppressed
            self._batching -= 1
            if not self._batching:
                self._refresh()  # the legend once for the whole batch, and one render

    def _rebuild(self, layer: Layer) -> None:
        for actor in self.actors.pop(layer.name, []):
            self.plotter.remove_actor(actor, render=False)
        if not layer.visible:
            # Built when shown: the next bench's uncertainty, hidden by default, was computed by core
            # (seconds on Kennecott) on the window's thread after every run that changed the model.
            self._unbuilt.add(layer.name)
            self.actors[layer.name] = []
            return
        self._unbuilt.discard(layer.name)
        actors = []
        planes = self._clipping_planes()
        for k, item in enumerate(layer.build(self.scene.view)):
            actor = self.plotter.add_mesh(
                item.mesh, name=f"{layer.name}#{k}", reset_camera=False, render=False, **item.style
            )
            actor.SetVisibility(layer.visible)
            for plane in planes:
                actor.GetMapper().AddClippingPlane(plane)
            actors.append(actor)
        self.actors[layer.name] = actors

    # -- a lighter picture while the camera moves ---------------------------
    def set_interacting(self, moving: bool) -> None:
        """Draw a light stand-in of the scene while the camera moves, the full one when it stops.

        Software OpenGL draws about a million triangles a second, and wide
        lines and sphere-shaded points cost a fill per pixel: Kennecott with
        every layer on took 53 ms a frame. While the user turns the view,
        surfaces of more than :data:`COARSE_ABOVE_FACES` triangles become a
        quadric clustering of themselves, polylines of more than
        :data:`DECIMATE_ABOVE_POINTS` points a decimated copy, lines are one
        pixel wide, points flat and everything opaque; stand-ins are made once
        per mesh. At rest the meshes drawn are exactly those exported.
        """
        for actors in self.actors.values():
            for actor in actors:
                if actor.GetVisibility():
                    _light_stand_in(actor, moving)

    # -- picking -----------------------------------------------------------
    def pick(self, x_px: float, y_px: float, tolerance: float = 0.01) -> tuple[str, int] | None:
        """The layer and item under display pixel ``(x_px, y_px)`` (VTK's: origin bottom left).

        The item is what the layer's meshes carry for each point: a hole's
        index (``"hole"``) or an item's index in the layer (``"item"``).
        ``None`` when nothing pickable is under the pixel. What the section plane or
        the elevation range cuts away is not picked (a cell picker honours the
        mappers' clipping planes; a point picker reported hidden holes above).
        """
        import vtk

        picker = vtk.vtkCellPicker()
        picker.SetTolerance(tolerance)
        picker.PickFromListOn()
        owner = {}
        for name, actors in self.actors.items():
            for actor in actors:
                if actor.GetVisibility() and actor.GetPickable():
                    picker.AddPickList(actor)
                    owner[id(actor)] = name
        if not owner or not picker.Pick(float(x_px), float(y_px), 0.0, self.plotter.renderer):
            return None
        actor, pid = picker.GetActor(), picker.GetPointId()
        if actor is None or pid < 0 or id(actor) not in owner:
            return None
        data = actor.GetMapper().GetInput().GetPointData()
        for key in ("hole", "item"):
            arr = data.GetArray(key)
            if arr is not None:
                return owner[id(actor)], int(arr.GetTuple1(pid))
        return None

    # -- clipping: a section plane and an elevation range ------------------
    def set_clip(self, axis: str | None, value: float = 0.0, keep: str = "below") -> None:
        """Cut the picture at ``axis`` (``"x"``, ``"y"``, ``"z"``; ``None`` for no cut) = ``value``.

        ``value`` is in drawn coordinates (local metres; z as displayed, with
        the vertical exaggeration); ``keep`` is ``"below"`` or ``"above"``
        that value. Only the mappers' clipping planes change: nothing is rebuilt.
        """
        if axis is not None and (axis not in "xyz" or len(axis) != 1 or keep not in ("below", "above")):
            raise ValueError(f"clip axis must be x, y or z and keep below or above, got {axis!r}, {keep!r}")
        self.clip = None if axis is None else (axis, float(value), keep)
        self._apply_clipping()

    def set_elevation_range(self, z_min_m: float | None = None, z_max_m: float | None = None) -> None:
        """Show only what lies between two elevations (metres; ``None``: no limit)."""
        self.elevation_range_m = (z_min_m, z_max_m)
        self._apply_clipping()

    def _clipping_planes(self) -> list:
        import vtk

        planes: list[tuple[tuple[float, ...], tuple[float, ...]]] = []
        if self.clip is not None:
            axis, value, keep = self.clip
            k = "xyz".index(axis)
            normal = tuple(float(i == k) * (-1.0 if keep == "below" else 1.0) for i in range(3))
            origin = tuple(float(i == k) * value for i in range(3))
            planes.append((origin, normal))
        lo, hi = self.elevation_range_m
        view = self.scene.view
        if lo is not None:
            planes.append(((0.0, 0.0, float(view.z(lo)) - 1e-6), (0.0, 0.0, 1.0)))
        if hi is not None:
            planes.append(((0.0, 0.0, float(view.z(hi)) + 1e-6), (0.0, 0.0, -1.0)))
        out = []
        for origin, normal in planes:  # VTK keeps the side the normal points to
            plane = vtk.vtkPlane()
            plane.SetOrigin(*origin)
            plane.SetNormal(*normal)
            out.append(plane)
        return out

    def _apply_clipping(self) -> None:
        planes = self._clipping_planes()
        for actors in self.actors.values():
            for actor in actors:
                mapper = actor.GetMapper()
                mapper.RemoveAllClippingPlanes()
                for plane in planes:
                    mapper.AddClippingPlane(plane)
        if not self._batching and self.auto_render:
            self.plotter.render()

    def _update_legend(self) -> None:
        self._legend_stale = False
        entries = self.scene.legend_entries(lambda layer: not self.actors.get(layer.name)) if self.show_legend else []
        if entries == self._legend_shown:
            return  # rebuilding an unchanged legend costs a render
        self._legend_shown = entries
        with suppress(Exception):
            self.plotter.remove_legend(render=False)
        if entries:
            rows = min(len(entries), 36)
            height = min(0.026 * rows, 0.94)
            legend = self.plotter.add_legend(
                [[label, to_float(rgb)] for label, rgb in entries[:rows]],
                bcolor=(0.1, 0.1, 0.12),
                border=False,
                size=(LEGEND_WIDTH - 0.01, height),
                face="rectangle",
            )
            # in the strip right of the data rectangle (pyvista's "upper right" drifts left with long labels)
            legend.GetPositionCoordinate().SetValue(1.0 - LEGEND_WIDTH, 0.98 - height)
            legend.GetPosition2Coordinate().SetValue(LEGEND_WIDTH - 0.01, height)

    # -- bearings: axes grid, scale bar ------------------------------------
    def data_bounds(self) -> tuple[float, ...] | None:
        """Bounds ``(xmin, xmax, ymin, ymax, zmin, zmax)`` of the visible layers as drawn (display z)."""
        boxes = [a.GetBounds() for name, actors in self.actors.items() for a in actors if a.GetVisibility() and name]
        boxes = [b for b in boxes if np.all(np.isfinite(b)) and b[1] >= b[0]]
        if not boxes:
            return None
        arr = np.array(boxes)
        return tuple(float(v) for pair in zip(arr[:, 0::2].min(axis=0), arr[:, 1::2].max(axis=0)) for v in pair)

    def _update_bearings(self) -> None:
        """A labelled box grid in the input's coordinates and units, and a scale bar, around the visible data."""
        self._bearings_stale = False
        if not self.show_bearings:
            return
        bounds = self.data_bounds()
        # the frame too: another input's data may be drawn where the last one's were, in other units
        frame = self.scene.frame
        key = None if bounds is None else (*np.round(bounds, 3), self.scene.vertical_exaggeration, frame)
        if key == self._bearings_shown:
            return
        self._bearings_shown = key
        p = self.plotter
        p.remove_bounds_axes()
        if self._ruler is not None:
            p.remove_actor(self._ruler, render=False)
            self._ruler = None
        if bounds is None:
            return
        frame, view = self.scene.frame, self.scene.view
        unit = frame.length_unit
        x0, x1, y0, y1, z0, z1 = bounds
        xin = frame.to_input(np.array([[x0, y0], [x1, y1]]))
        zin = frame.z_to_input(view.z_from_display(np.array([z0, z1])))
        colour = to_float(BEARINGS)
        p.show_bounds(
            bounds=bounds,
            axes_ranges=[xin[0, 0], xin[1, 0], xin[0, 1], xin[1, 1], zin[0], zin[1]],
            xtitle=f"Easting ({unit})",
            ytitle=f"Northing ({unit})",
            ztitle=f"Elevation ({unit})",
            grid="back",
            location="outer",
            color=colour,
            font_size=12,
            bold=False,
            n_xlabels=4,
            n_ylabels=4,
            n_zlabels=3,
            fmt="%.0f",
            render=False,
        )
        _interior_labels(getattr(p.renderer, "cube_axes_actor", None), n_labels=4)
        length = nice_length((x1 - x0) / frame.metres_per_unit / 4)
        a = np.array([x0, y0, z0])
        self._ruler = scale_bar(a, a + [length * frame.metres_per_unit, 0.0, 0.0], f"{length:g} {unit}", colour)
        # not Plotter.add_ruler: it resets the camera
        p.add_actor(self._ruler, reset_camera=False, pickable=False, render=False)

    # -- camera ------------------------------------------------------------
    def set_camera(self, camera: str | None = "iso") -> None:
        """``iso``, ``top``, ``front``, ``side``, or ``"x,y,z"`` for a view direction; then fit the data.

        The visible data fill the picture (less the legend's strip when the
        legend is drawn in it), whatever the window's shape at the time:
        call it again after a resize or a change of vertical exaggeration.
        """
        p = self.plotter
        camera = camera or "iso"
        p.camera.SetWindowCenter(0.0, 0.0)
        p.disable_parallel_projection()
        if camera == "top":
            p.view_xy()
            p.enable_parallel_projection()
        elif camera == "front":
            p.view_xz()
        elif camera == "side":
            p.view_yz()
        elif camera == "iso":
            p.view_vector((-1.0, -1.6, 1.1), viewup=(0, 0, 1))
        else:
            try:
                vec = [float(v) for v in camera.split(",")]
            except ValueError:
                raise ValueError(f"unknown camera {camera!r}: use one of {', '.join(CAMERAS)} or 'x,y,z'") from None
            if len(vec) != 3:
                raise ValueError(f"camera direction needs three numbers, got {camera!r}")
            p.view_vector(vec, viewup=(0, 0, 1))
        self.fit()

    def camera_state(self) -> dict:
        """The camera as a project saves it (:func:`core.io.project.check_camera`): plain numbers, the input's coordinates.

        Points in the input's coordinates and units with elevations not exaggerated, not the view's local
        metres: the local frame and the exaggeration's reference follow the data (a bench drilled since
        moves them), the mine's coordinates do not.
        """
        c = self.plotter.camera
        frame, view = self.scene.frame, self.scene.view

        def point(xyz) -> list[float]:
            x, y = frame.to_input(np.asarray(xyz[:2], float))
            return [float(x), float(y), float(frame.z_to_input(view.z_from_display(xyz[2])))]

        up = np.asarray(c.GetViewUp(), float) * (1.0, 1.0, 1.0 / view.vertical_exaggeration)
        return {
            "position": point(c.GetPosition()),
            "focal_point": point(c.GetFocalPoint()),
            "view_up": [float(v) for v in up / np.linalg.norm(up)],
            "parallel_scale": float(frame.length_to_input(c.GetParallelScale())) if c.GetParallelProjection() else None,
            "window_center": [float(v) for v in c.GetWindowCenter()],
        }

    def set_camera_state(self, state: dict) -> None:
        """Put the camera where :meth:`camera_state` says (a project's camera), without fitting the data."""
        c = self.plotter.camera
        frame, view = self.scene.frame, self.scene.view

        def point(xyz) -> list[float]:
            x, y = frame.to_local(np.array([xyz[0]], float), np.array([xyz[1]], float))[0]
            return [float(x), float(y), float(view.z(frame.z_to_local(xyz[2])))]

        up = np.asarray(state["view_up"], float) * (1.0, 1.0, view.vertical_exaggeration)
        # the camera's own calls: pyvista's parallel projection switches move the camera to keep the picture
        c.SetParallelProjection(state.get("parallel_scale") is not None)
        c.SetPosition(*point(state["position"]))
        c.SetFocalPoint(*point(state["focal_point"]))
        c.SetViewUp(*(up / np.linalg.norm(up)))
        c.OrthogonalizeViewUp()
        if state.get("parallel_scale") is not None:
            c.SetParallelScale(float(frame.length_to_local(state["parallel_scale"])))
        c.SetWindowCenter(*(state.get("window_center") or (0.0, 0.0)))
        self.plotter.renderer.ResetCameraClippingRange()

    def fit(self) -> None:
        """Zoom and centre the camera (keeping its direction) so the visible data fill the data rectangle."""
        p = self.plotter
        if p.render_window is None:  # closed: a fit queued before the window closed has nothing to fit
            return
        bounds = self.data_bounds()
        p.camera.SetWindowCenter(0.0, 0.0)
        p.reset_camera(bounds=bounds) if bounds is not None else p.reset_camera()
        if bounds is None:
            return
        legend = self.show_legend and bool(self._legend_shown)
        rect = np.array(DATA_RECT_WITH_LEGEND if legend else DATA_RECT)
        if self.show_bearings:  # the axes are labelled outside the box: their titles must stay in the window
            margin = AXES_MARGIN_PX * p.render_window.GetDPI() / 72.0
            along_an_axis = np.abs(p.camera.GetDirectionOfProjection()).max() > 0.999
            margins = (margin, margin, 0.0, 0.0) if along_an_axis else (margin,) * 4
            rect = inset_rect(rect, tuple(p.renderer.GetSize()), margins)
        rect = rect * 2 - 1  # view coordinates
        corners = np.array(np.meshgrid(*np.reshape(bounds, (3, 2)), indexing="ij")).reshape(3, -1).T
        for _ in range(3):  # perspective: each zoom moves the corners a little differently
            v = _view_points(p.renderer, corners)
            span = np.maximum(v.max(axis=0) - v.min(axis=0), 1e-9)
            scale = float(min((rect[2] - rect[0]) / span[0], (rect[3] - rect[1]) / span[1]))
            if abs(scale - 1.0) < 0.01:
                break
            p.camera.Zoom(scale)
            p.renderer.ResetCameraClippingRange()
        v = _view_points(p.renderer, corners)
        centre = (v.min(axis=0) + v.max(axis=0)) / 2
        target = np.array([(rect[0] + rect[2]) / 2, (rect[1] + rect[3]) / 2])
        # the window centre moves the picture, not the camera: rotation stays about the data
        p.camera.SetWindowCenter(*(centre - target))
        p.renderer.ResetCameraClippingRange()


def inset_rect(rect, size_px: tuple[int, int], margins_px, max_fraction: float = 0.25) -> np.ndarray:
    """``rect`` (left, bottom, right, top; fractions of the viewport) kept ``margins_px`` from its edges.

    Parameters
    ----------
    rect : sequence of 4 float
        Left, bottom, right, top, as fractions (0-1) of the viewport.
    size_px : (int, int)
        The viewport's width and height in pixels.
    margins_px : sequence of 4 float
        Least distance, in pixels, from the left, bottom, right and top sides of ``rect`` to the
        viewport's edges.
    max_fraction : float, optional
        A margin is at most this fraction of the viewport's width (height), in a small viewport.

    Returns
    -------
    ndarray
        The rectangle, its sides that were nearer the edges than their margins moved in.
    """
    w, h = (max(float(v), 1.0) for v in size_px)
    ml, mb, mr, mt = (min(m / d, max_fraction) for m, d in zip(margins_px, (w, h, w, h)))
    left, bottom, right, top = (float(v) for v in rect)
    return np.array([max(left, ml), max(bottom, mb), min(right, 1.0 - mr), min(top, 1.0 - mt)])


def _interior_labels(axes, n_labels: int) -> None:
    """Label the easting and northing axes of ``axes`` (a ``vtkCubeAxesActor``) at their inner ticks only.

    The end labels of two axes meet at the box's corners, where seven-digit
    mine-grid coordinates printed over one another were unreadable.
    """
    import vtk

    if axes is None:
        return
    for axis, (lo, hi) in enumerate((axes.GetXAxisRange(), axes.GetYAxisRange())):
        labels = vtk.vtkStringArray()
        for k in range(n_labels):
            inner = 0 < k < n_labels - 1
            labels.InsertNextValue(f"{lo + (hi - lo) * k / (n_labels - 1):.0f}" if inner else "")
        axes.SetAxisLabels(axis, labels)


def _view_points(renderer, xyz: np.ndarray) -> np.ndarray:
    """View coordinates (-1..1 across the viewport) of world points."""
    out = np.empty((len(xyz), 2))
    for i, q in enumerate(xyz):
        renderer.SetWorldPoint(q[0], q[1], q[2], 1.0)
        renderer.WorldToView()
        out[i] = renderer.GetViewPoint()[:2]
    return out


def _light_stand_in(actor, moving: bool) -> None:
    """Swap ``actor`` to its light stand-in (``moving``) or back to its own mesh and look."""
    mapper, prop = actor.GetMapper(), actor.GetProperty()
    if not moving:
        saved = getattr(actor, "_at_rest", None)
        if saved is not None:
            mesh, width, spheres, opacity = saved
            mapper.SetInputData(mesh)
            prop.SetLineWidth(width)
            prop.SetRenderPointsAsSpheres(spheres)
            prop.SetOpacity(opacity)
            actor._at_rest = None
        return
    if getattr(actor, "_at_rest", None) is not None:
        return  # already light
    mesh = mapper.GetInput()
    actor._at_rest = (mesh, prop.GetLineWidth(), prop.GetRenderPointsAsSpheres(), prop.GetOpacity())
    if getattr(actor, "_stand_in", None) is None or actor._stand_in[0] is not mesh:
        light = mesh
        if mesh is not None and mesh.GetNumberOfPolys() > COARSE_ABOVE_FACES:
            light = _coarse(mesh)
        elif mesh is not None and mesh.GetNumberOfLines() and mesh.GetNumberOfPoints() > DECIMATE_ABOVE_POINTS:
            light = _decimated_lines(mesh)
        actor._stand_in = (mesh, light)
    mapper.SetInputData(actor._stand_in[1])
    prop.SetLineWidth(1.0)
    prop.SetRenderPointsAsSpheres(False)
    prop.SetOpacity(1.0)  # blending translucent faces over the whole view costs more than drawing them


def _decimated_lines(mesh, keep: float = 0.25):
    """``mesh``'s polylines with about ``keep`` of their points (``vtkDecimatePolylineFilter``)."""
    import vtk

    decimate = vtk.vtkDecimatePolylineFilter()
    decimate.SetInputData(mesh)
    decimate.SetTargetReduction(1.0 - keep)
    decimate.Update()
    out = vtk.vtkPolyData()
    out.DeepCopy(decimate.GetOutput())
    return out


def _coarse(mesh, divisions: int = 32):
    """A few-thousand-triangle stand-in of ``mesh`` (``vtkQuadricClustering`` on a ``divisions``-cube grid)."""
    import vtk

    cluster = vtk.vtkQuadricClustering()
    cluster.SetInputData(mesh)
    cluster.SetNumberOfDivisions(divisions, divisions, max(divisions // 4, 8))
    cluster.AutoAdjustNumberOfDivisionsOn()
    cluster.Update()
    out = vtk.vtkPolyData()
    out.DeepCopy(cluster.GetOutput())
    return out


def scale_bar(a, b, title: str, colour) -> object:
    """A bar between world points ``a`` and ``b`` with end ticks and ``title`` (a ``vtkAxisActor2D``)."""
    import vtk

    bar = vtk.vtkAxisActor2D()
    for coord, point in ((bar.GetPositionCoordinate(), a), (bar.GetPosition2Coordinate(), b)):
        coord.SetCoordinateSystemToWorld()
        coord.SetValue(*(float(v) for v in point))
    bar.SetTitle(title)
    bar.AdjustLabelsOff()
    bar.SetNumberOfLabels(2)
    bar.SetLabelVisibility(False)
    bar.SetFontFactor(0.9)
    bar.SetTickLength(8)
    bar.GetProperty().SetColor(*colour)
    bar.GetProperty().SetLineWidth(3)
    title_text = bar.GetTitleTextProperty()
    title_text.SetColor(*colour)
    title_text.SetShadow(False)
    title_text.SetBold(True)
    title_text.SetItalic(False)
    return bar


def nice_length(approx: float) -> float:
    """The 1, 2 or 5 times a power of ten closest below ``approx`` (a scale bar's length)."""
    if not np.isfinite(approx) or approx <= 0:
        return 1.0
    power = 10.0 ** np.floor(np.log10(approx))
    return float(max(m for m in (1.0, 2.0, 5.0) if m * power <= approx * (1 + 1e-9)) * power)


def world_to_pixels(plotter, xyz: np.ndarray) -> np.ndarray:
    """Image ``(col, row)`` (row 0 at the top, like a screenshot array) of world points."""
    ren = plotter.renderer
    h = plotter.window_size[1]
    out = np.empty((len(xyz), 2))
    for i, p in enumerate(np.asarray(xyz, float)):
        ren.SetWorldPoint(p[0], p[1], p[2], 1.0)
        ren.WorldToDisplay()
        x, y, _ = ren.GetDisplayPoint()
        out[i] = (x, h - 1 - y)
    return out


def display_to_plane(plotter, x_px: float, y_px: float, z_display: float) -> np.ndarray | None:
    """World ``(x, y)`` under a display pixel, on the horizontal plane ``z = z_display``.

    ``(x_px, y_px)`` are VTK display coordinates (origin at the bottom left,
    as the interactor reports mouse positions). The view ray through the
    pixel is intersected with the plane; ``None`` when the ray runs parallel
    to it (a side view), where a drag cannot say where on the bench it is.
    """
    ren = plotter.renderer
    ends = []
    for depth in (0.0, 1.0):
        ren.SetDisplayPoint(float(x_px), float(y_px), depth)
        ren.DisplayToWorld()
        w = np.asarray(ren.GetWorldPoint(), float)
        ends.append(w[:3] / w[3])
    near, far = ends
    dz = far[2] - near[2]
    if abs(dz) < 1e-9 * max(1.0, float(np.linalg.norm(far - near))):
        return None
    t = (z_display - near[2]) / dz
    return (near + t * (far - near))[:2]


def drag_on_plane(plotter, start_px, end_px, z_display: float) -> np.ndarray | None:
    """World ``(dx, dy)`` of a mouse drag between two display pixels, measured on the plane ``z = z_display``."""
    a = display_to_plane(plotter, start_px[0], start_px[1], z_display)
    b = display_to_plane(plotter, end_px[0], end_px[1], z_display)
    if a is None or b is None:
        return None
    return b - a
