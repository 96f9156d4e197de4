"""A list of layers drawn into a PyVista plotter (off-screen or in a Qt widget).

:class:`Scene` owns the layers, the vertical exaggeration and the legend;
:class:`SceneRenderer` keeps the plotter's actors in step with them: a change
of visibility or opacity touches only the actor properties, a change of data,
frame or colour rebuilds that layer's meshes. No Qt here; the Qt window uses
the same renderer with a ``pyvistaqt.QtInteractor`` as the plotter.
"""

from __future__ import annotations

from collections.abc import Iterable
from contextlib import contextmanager, suppress

import numpy as np
from psygnal import Signal

from . import _vtkenv  # noqa: F401
from .layers import Layer, ViewTransform
from .palette import BACKGROUND, to_float

CAMERAS = ("iso", "top", "front", "side")


class Scene:
    """Ordered layers plus view settings; ``changed(layer_or_None, what)`` after every change."""

    changed = Signal(object, str)

    def __init__(self, layers: Iterable[Layer] = (), *, vertical_exaggeration: float = 2.0, z_ref: float = 0.0):
        self.layers: list[Layer] = []
        self._view = ViewTransform(vertical_exaggeration, z_ref)
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
            self._view = ViewTransform(value, self._view.z_ref)
            self.changed.emit(None, "view")

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

    def __init__(self, plotter, scene: Scene, *, legend: bool = True, auto_render: bool = False):
        self.plotter = plotter
        self.scene = scene
        self.show_legend = legend
        self.auto_render = auto_render
        self.actors: dict[str, list] = {}
        self._legend_shown: list | None = None
        self._batching = 0
        self._legend_stale = False
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
        scene.changed.connect(self._on_change)

    # -- updates -----------------------------------------------------------
    def _on_change(self, layer: Layer | None, what: str) -> None:
        if layer is None:  # view change: everything moves
            for lay in self.scene.layers:
                self._rebuild(lay)
        elif what in ("visible", "opacity"):
            for actor in self.actors.get(layer.name, []):
                actor.SetVisibility(layer.visible)
                actor.GetProperty().SetOpacity(layer.opacity)
        else:
            self._rebuild(layer)
        if what in ("visible", "added", "data", "color") or layer is None:
            self._legend_stale = True
        if not self._batching:
            self._refresh()

    def _refresh(self) -> None:
        if self._legend_stale:
            self._update_legend()
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
        actors = []
        for k, item in enumerate(layer.build(self.scene.view)):
            actor = self.plotter.add_mesh(
                item.mesh, name=f"{layer.name}#{k}", reset_camera=False, render=False, **item.style
            )
            actor.SetVisibility(layer.visible)
            actors.append(actor)
        self.actors[layer.name] = actors

    def _update_legend(self) -> None:
        self._legend_stale = False
        entries = self.scene.legend_entries(lambda layer: not self.actors.get(layer.name)) if self.show_legend else []
        if entries == self._legend_shown:
            return  # rebuilding an unchanged legend costs a render
        self._legend_shown = entries
        with suppress(Exception):
            self.plotter.remove_legend(render=False)
        if entries:
            self.plotter.add_legend(
                [[label, to_float(rgb)] for label, rgb in entries],
                bcolor=(0.1, 0.1, 0.12),
                border=False,
                size=(0.16, min(0.026 * len(entries), 0.5)),
                loc="upper right",
                face="rectangle",
            )

    # -- camera ------------------------------------------------------------
    def set_camera(self, camera: str | None = "iso") -> None:
        """``iso``, ``top``, ``front``, ``side``, or ``"x,y,z"`` for a view direction."""
        p = self.plotter
        camera = camera or "iso"
        p.reset_camera()
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
        p.reset_camera()


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
