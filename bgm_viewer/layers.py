"""Viewer layers: plain objects that turn ``core`` results into PyVista meshes.

Modelled on napari: a layer holds its data (arrays and shapely polygons, as
``core`` returns them) and its display state (visibility, opacity, colour,
animation frame). It knows nothing of Qt or of a plotter. ``build(view)``
returns :class:`MeshItem` s (a :class:`pyvista.PolyData` and the keyword
arguments for ``Plotter.add_mesh``); the psygnal signal ``Layer.changed``
says what changed (``"visible"``, ``"opacity"``, ``"color"``, ``"frame"``,
``"data"``) so a renderer can update only what is needed. Everything here is testable without a screen.

Coordinates are the engine's local metres; :class:`ViewTransform` applies
the vertical exaggeration about a reference elevation (the top bench).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pyvista as pv
from psygnal import Signal
from shapely.geometry import MultiPolygon, Polygon

from . import _vtkenv  # noqa: F401  (must precede pyvista)
from .palette import LAYER_COLOURS, geozone_colours, lighten

RGB = tuple[int, int, int]

__all__ = [
    "BlastholesLayer",
    "ContoursLayer",
    "EdgeMapLayer",
    "GVFLayer",
    "Layer",
    "MeshItem",
    "SelectedComponentsLayer",
    "SnakeLayer",
    "SurfaceLayer",
    "TrajectoriesLayer",
    "ViewTransform",
    "WavefrontLayer",
    "polygon_rings",
    "polylines",
]


# ---------------------------------------------------------------------------
# helpers


@dataclass(frozen=True)
class ViewTransform:
    """Display mapping, ``z_display = z_ref + (z - z_ref) * vertical_exaggeration``, and what is left out.

    ``hidden_geozones``: labels whose holes, contours and surfaces are not
    drawn; ``hidden_benches_m``: bench elevations (metres) whose holes and
    contours are not drawn.
    """

    vertical_exaggeration: float = 1.0
    z_ref: float = 0.0
    hidden_geozones: frozenset[str] = frozenset()
    hidden_benches_m: frozenset[float] = frozenset()

    def shows(self, geozone: str, z_m: float | None = None) -> bool:
        """Whether an item of ``geozone`` at elevation ``z_m`` (``None``: any) is drawn."""
        return geozone not in self.hidden_geozones and (
            z_m is None or not any(abs(z_m - h) < 1e-6 for h in self.hidden_benches_m)
        )

    def shown_mask(self, geozone: np.ndarray, z_m: np.ndarray) -> np.ndarray:
        """:meth:`shows` for arrays of labels and elevations."""
        keep = ~np.isin(geozone, list(self.hidden_geozones)) if self.hidden_geozones else np.ones(len(geozone), bool)
        for h in self.hidden_benches_m:
            keep &= np.abs(np.asarray(z_m, float) - h) >= 1e-6
        return keep

    def z(self, z):
        return self.z_ref + (np.asarray(z, float) - self.z_ref) * self.vertical_exaggeration

    def z_from_display(self, z_display):
        """Elevation (metres) of a displayed ``z``: the inverse of :meth:`z`."""
        return self.z_ref + (np.asarray(z_display, float) - self.z_ref) / self.vertical_exaggeration


@dataclass
class MeshItem:
    """One mesh of a layer and how to draw it (keyword arguments of ``Plotter.add_mesh``)."""

    mesh: pv.PolyData
    style: dict = field(default_factory=dict)


def polygon_rings(geometry) -> list[np.ndarray]:
    """Exterior and interior rings of a Polygon/MultiPolygon as ``(n, 2)`` arrays (closed)."""
    if geometry is None or geometry.is_empty:
        return []
    polys = [geometry] if isinstance(geometry, Polygon) else list(getattr(geometry, "geoms", []))
    out = []
    for p in polys:
        if not isinstance(p, Polygon) or p.is_empty:
            continue
        out.append(np.asarray(p.exterior.coords)[:, :2])
        out.extend(np.asarray(r.coords)[:, :2] for r in p.interiors)
    return out


def polylines(lines: Sequence[np.ndarray], cell_rgb: Sequence[RGB] | None = None) -> pv.PolyData:
    """PolyData of open polylines (``(n, 3)`` arrays); optional RGB per line in ``"rgb"``."""
    lines = [np.asarray(p, float) for p in lines if len(p) >= 2]
    if not lines:
        return pv.PolyData()
    pts = np.vstack(lines)
    conn = []
    start = 0
    for p in lines:
        n = len(p)
        conn.append(np.concatenate([[n], np.arange(start, start + n)]))
        start += n
    mesh = pv.PolyData(pts, lines=np.concatenate(conn).astype(np.int64))
    if cell_rgb is not None:
        mesh.cell_data["rgb"] = np.asarray(cell_rgb, dtype=np.uint8).reshape(-1, 3)
    return mesh


def _xyz(xy: np.ndarray, z: float) -> np.ndarray:
    xy = np.asarray(xy, float)
    return np.column_stack([xy[:, 0], xy[:, 1], np.full(len(xy), float(z))])


def _line_style(width: float = 2.0, rgb: bool = True, color: RGB | None = None) -> dict:
    style: dict[str, object] = {"line_width": width, "lighting": False, "show_scalar_bar": False}
    if rgb:
        style.update(scalars="rgb", rgb=True)
    elif color is not None:
        style["color"] = color
    return style


# ---------------------------------------------------------------------------
# base class


class Layer:
    """Base of all layers: name, visibility, opacity, colour; ``changed(layer, what)`` after every change."""

    kind = "layer"
    changed = Signal(object, str)

    def __init__(self, name: str, *, visible: bool = True, opacity: float = 1.0, color: RGB | None = None):
        self.name = name
        self._visible = bool(visible)
        self._opacity = float(opacity)
        self._color = color

    def _emit(self, what: str) -> None:
        self.changed.emit(self, what)

    # -- display state -----------------------------------------------------
    @property
    def visible(self) -> bool:
        return self._visible

    @visible.setter
    def visible(self, value: bool) -> None:
        if bool(value) != self._visible:
            self._visible = bool(value)
            self._emit("visible")

    @property
    def opacity(self) -> float:
        return self._opacity

    @opacity.setter
    def opacity(self, value: float) -> None:
        value = float(np.clip(value, 0.0, 1.0))
        if value != self._opacity:
            self._opacity = value
            self._emit("opacity")

    @property
    def color(self) -> RGB | None:
        return self._color

    @color.setter
    def color(self, value: RGB | None) -> None:
        if value != self._color:
            self._color = value
            self._emit("color")

    # -- animation (single frame by default) ---------------------------------
    @property
    def n_frames(self) -> int:
        return 1

    @property
    def frame(self) -> int:
        return 0

    @frame.setter
    def frame(self, value: int) -> None:  # pragma: no cover - static layers ignore it
        pass

    # -- geometry ----------------------------------------------------------
    def build(self, view: ViewTransform | None = None) -> list[MeshItem]:
        """Meshes to draw (empty meshes are left out); opacity is applied here."""
        view = view or ViewTransform()
        items = [it for it in self._build(view) if it.mesh.n_points > 0]
        for it in items:
            it.style.setdefault("opacity", self.opacity)
            it.style.setdefault("pickable", False)
        return items

    def _build(self, view: ViewTransform) -> list[MeshItem]:
        raise NotImplementedError

    def legend(self) -> list[tuple[str, RGB]]:
        """``(label, rgb)`` entries for the legend."""
        return [(self.name, self.color)] if self.color is not None else []

    @property
    def is_empty(self) -> bool:
        return not self.build()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} visible={self.visible} opacity={self.opacity:g}>"


# ---------------------------------------------------------------------------
# blastholes and contours


class BlastholesLayer(Layer):
    """Blastholes as points coloured by geozone; boundary holes drawn larger.

    Parameters
    ----------
    xy : (n, 2) metres; z : (n,) metres (the bench level of each hole);
    geozone : (n,) labels; boundary : (n,) bool, optional;
    colours : {label: rgb}, optional (the fixed palette by default).
    """

    kind = "blastholes"

    def __init__(
        self,
        xy,
        z,
        geozone,
        boundary=None,
        colours=None,
        *,
        name="blastholes",
        point_size: float = 4.0,
        boundary_point_size: float = 7.0,
        **kw,
    ):
        super().__init__(name, **kw)
        self.xy = np.asarray(xy, float).reshape(-1, 2)
        self.z = np.broadcast_to(np.asarray(z, float), (len(self.xy),)).copy()
        self.geozone = np.asarray(geozone, dtype=object).astype(str)
        self.boundary = np.zeros(len(self.xy), bool) if boundary is None else np.asarray(boundary, bool)
        self.colours = dict(colours) if colours else geozone_colours(self.geozone)
        self.point_size = point_size
        self.boundary_point_size = boundary_point_size

    @classmethod
    def from_blastholes(cls, holes, contours: Iterable | None = None, colours=None, **kw) -> BlastholesLayer:
        """From :class:`core.io.blastholes.Blastholes`; boundary holes from ``core`` contours."""
        boundary = np.zeros(len(holes.xy), bool)
        for c in contours or []:
            boundary[np.asarray(c.boundary_holes, int)] = True
        z = np.asarray(holes.bench_levels_m)[holes.bench]
        return cls(holes.xy, z, holes.geozone, boundary, colours or geozone_colours(holes.geozones), **kw)

    def rgb(self) -> np.ndarray:
        """``(n, 3)`` uint8 colour of every hole."""
        lut = {g: np.array(c, np.uint8) for g, c in self.colours.items()}
        grey = np.array((200, 200, 200), np.uint8)
        return np.array([lut.get(g, grey) for g in self.geozone], np.uint8).reshape(-1, 3)

    def _build(self, view):
        rgb = self.rgb()
        pts = np.column_stack([self.xy, view.z(self.z)])
        shown = view.shown_mask(self.geozone, self.z)
        items = []
        for sel, size in ((~self.boundary, self.point_size), (self.boundary, self.boundary_point_size)):
            sel = sel & shown
            if not sel.any():
                continue
            mesh = pv.PolyData(pts[sel])
            mesh.point_data["rgb"] = rgb[sel]
            mesh.point_data["hole"] = np.flatnonzero(sel)  # what a pick reports
            items.append(
                MeshItem(
                    mesh,
                    {
                        "scalars": "rgb",
                        "rgb": True,
                        "point_size": size,
                        "render_points_as_spheres": True,  # small discs, not squares
                        "lighting": False,
                        "show_scalar_bar": False,
                        "pickable": True,
                    },
                )
            )
        return items

    def legend(self):
        present = set(self.geozone.tolist())
        return [(f"geozone {g}", c) for g, c in sorted(self.colours.items()) if g in present]


class ContoursLayer(Layer):
    """Closed contours (shapely polygons, holes included) at their bench elevations.

    ``items`` is a list of ``(geozone, z_m, polygon)``. With ``predicted=True``
    the colours are lightened (predicted contours below the deepest bench).
    """

    kind = "contours"

    def __init__(
        self,
        items: Sequence[tuple[str, float, Polygon | MultiPolygon]] = (),
        colours=None,
        *,
        name="contours",
        line_width: float = 3.0,
        predicted: bool = False,
        **kw,
    ):
        super().__init__(name, **kw)
        self.items = [(str(g), float(z), p) for g, z, p in items]
        self.colours = dict(colours) if colours else geozone_colours(g for g, _, _ in self.items)
        self.line_width = line_width
        self.predicted = predicted

    @classmethod
    def from_contours(cls, contours: Iterable, colours=None, **kw) -> ContoursLayer:
        """From :class:`core.extraction.contours.Contour` objects."""
        return cls([(c.geozone, c.bench_z_m, c.polygon) for c in contours], colours, **kw)

    def colour_of(self, geozone: str) -> RGB:
        c = self.colours.get(geozone, (200, 200, 200))
        return lighten(c, 0.55) if self.predicted else c

    def rings(self, view: ViewTransform | None = None) -> tuple[list[np.ndarray], list[RGB], list[int]]:
        """Rings of the shown items at their displayed elevations, their colours and item indices."""
        view = view or ViewTransform()
        lines, rgb, index = [], [], []
        for i, (g, z, poly) in enumerate(self.items):
            if not view.shows(g, z):
                continue
            for ring in polygon_rings(poly):
                lines.append(_xyz(ring, view.z(z)))
                rgb.append(self.colour_of(g))
                index.append(i)
        return lines, rgb, index

    def _build(self, view):
        lines, rgb, index = self.rings(view)
        mesh = polylines(lines, rgb)
        if mesh.n_points:
            mesh.point_data["item"] = np.repeat(index, [len(line) for line in lines])  # what a pick reports
        return [MeshItem(mesh, {**_line_style(self.line_width), "pickable": True})]

    def legend(self):
        """One row per geozone (its colour in every layer); predicted contours: one row for the lighter shades."""
        if self.predicted:
            return [("predicted (lighter shade)", LAYER_COLOURS["predicted"])] if self.items else []
        return [(f"geozone {g}", self.colour_of(g)) for g in sorted({g for g, _, _ in self.items})]


class SelectedComponentsLayer(ContoursLayer):
    """The selected source component(s) and their target(s), drawn wide; items are ``("source" | "target", z, polygon)``."""

    kind = "selected_components"

    def __init__(self, items=(), *, name="selected components", line_width: float = 6.0, **kw):
        colours = {"source": LAYER_COLOURS["selected_source"], "target": LAYER_COLOURS["selected_target"]}
        super().__init__(items, colours, name=name, line_width=line_width, **kw)

    def _build(self, view):
        lines, rgb, _ = self.rings(ViewTransform(view.vertical_exaggeration, view.z_ref))  # never hidden
        return [MeshItem(polylines(lines, rgb), _line_style(self.line_width))]

    def legend(self):
        present = {role for role, _, _ in self.items}
        return [(f"selected {role}", self.colours[role]) for role in ("source", "target") if role in present]


# ---------------------------------------------------------------------------
# edge map, GVF, snake


class EdgeMapLayer(Layer):
    """The synthesized edge map of one component as a grey image at its bench."""

    kind = "edge_map"

    def __init__(self, grid=None, edge_map=None, z: float = 0.0, *, name="edge map", opacity=0.85, **kw):
        kw.setdefault("color", LAYER_COLOURS["edge_map"])
        super().__init__(name, opacity=opacity, **kw)
        self.set_data(grid, edge_map, z, emit=False)

    def set_data(self, grid, edge_map, z: float = 0.0, emit: bool = True) -> None:
        self.grid, self.edge_map, self.z_m = grid, None if edge_map is None else np.asarray(edge_map, float), float(z)
        if emit:
            self._emit("data")

    def _build(self, view):
        if self.grid is None or self.edge_map is None:
            return []
        rows, cols = self.edge_map.shape
        g = self.grid
        img = pv.ImageData(
            dimensions=(cols, rows, 1),
            spacing=(g.cell_size_m, g.cell_size_m, 1.0),
            origin=(g.x0, g.y0, float(view.z(self.z_m)) - 0.05),
        )
        v = np.clip(self.edge_map, 0, 1)
        v = v / max(float(v.max()), 1e-12)
        grey = (70 + 185 * v).astype(np.uint8).ravel()  # rows = y, so C order is x fastest
        img.point_data["rgb"] = np.column_stack([grey, grey, grey])
        return [
            MeshItem(
                img.extract_surface(algorithm=None),
                {"scalars": "rgb", "rgb": True, "lighting": False, "show_scalar_bar": False},
            )
        ]


class GVFLayer(Layer):
    """Gradient vector flow as 2D arrows (shaft + two head strokes) on a sub-sampled grid.

    Parameters
    ----------
    grid : core.geometry.grid.Grid; gvf : (2, rows, cols) x and y components; z : metres;
    arrows_across : about this many arrows along the longer side.
    """

    kind = "gvf"

    def __init__(
        self, grid=None, gvf=None, z: float = 0.0, *, name="GVF", arrows_across: int = 22, line_width: float = 2.0, **kw
    ):
        kw.setdefault("color", LAYER_COLOURS["gvf"])
        super().__init__(name, **kw)
        self.arrows_across = int(arrows_across)
        self.line_width = line_width
        self.set_data(grid, gvf, z, emit=False)

    def set_data(self, grid, gvf, z: float = 0.0, emit: bool = True) -> None:
        self.grid, self.gvf, self.z_m = grid, None if gvf is None else np.asarray(gvf, float), float(z)
        if emit:
            self._emit("data")

    def arrows(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Arrow centres ``(k, 2)``, unit directions ``(k, 2)`` and arrow length (metres)."""
        if self.grid is None or self.gvf is None:
            return np.zeros((0, 2)), np.zeros((0, 2)), 0.0
        _, rows, cols = self.gvf.shape
        stride = max(1, int(round(max(rows, cols) / max(self.arrows_across, 1))))
        r = np.arange(stride // 2, rows, stride)
        c = np.arange(stride // 2, cols, stride)
        rr, cc = np.meshgrid(r, c, indexing="ij")
        u = self.gvf[0][rr, cc].ravel()
        v = self.gvf[1][rr, cc].ravel()
        mag = np.hypot(u, v)
        keep = mag > 1e-3 * max(float(mag.max()) if mag.size else 0.0, 1e-12)
        xy = self.grid.rc_to_xy(np.column_stack([rr.ravel(), cc.ravel()]).astype(float))[keep]
        d = np.column_stack([u[keep], v[keep]]) / mag[keep, None]
        return xy, d, 0.8 * stride * self.grid.cell_size_m

    def _build(self, view):
        xy, d, length = self.arrows()
        if not len(xy):
            return []
        z = float(view.z(self.z_m)) + 0.05
        tail = xy - 0.5 * length * d
        tip = xy + 0.5 * length * d
        perp = np.column_stack([-d[:, 1], d[:, 0]])
        h1 = tip - 0.35 * length * d + 0.2 * length * perp
        h2 = tip - 0.35 * length * d - 0.2 * length * perp
        k = len(xy)
        pts = np.empty((4 * k, 3))
        for j, p in enumerate((tail, tip, h1, h2)):
            pts[j::4, :2] = p
        pts[:, 2] = z
        base = 4 * np.arange(k)
        segs = np.column_stack(
            [np.full(k, 2), base, base + 1, np.full(k, 2), base + 2, base + 1, np.full(k, 2), base + 3, base + 1]
        ).ravel()
        mesh = pv.PolyData(pts, lines=segs.astype(np.int64))
        return [MeshItem(mesh, _line_style(self.line_width, rgb=False, color=self.color))]


class SnakeLayer(Layer):
    """The snake's evolution: its start (grey) and the current iteration (white).

    ``history`` is a list of ``(n, 2)`` arrays in metres (``ExtractionFields.snake_history_m``);
    ``frame`` steps through them (``-1`` or ``n_frames - 1`` = converged).
    """

    kind = "snake"

    def __init__(self, history: Sequence[np.ndarray] = (), z: float = 0.0, *, name="snake", line_width=3.0, **kw):
        kw.setdefault("color", LAYER_COLOURS["snake"])
        super().__init__(name, **kw)
        self.line_width = line_width
        self._frame = 0
        self.set_data(history, z, emit=False)

    def set_data(self, history, z: float = 0.0, emit: bool = True) -> None:
        self.history = [np.asarray(h, float) for h in (history or [])]
        self.z_m = float(z)
        self._frame = max(len(self.history) - 1, 0)
        if emit:
            self._emit("data")

    @property
    def n_frames(self) -> int:
        return max(len(self.history), 1)

    @property
    def frame(self) -> int:
        return self._frame

    @frame.setter
    def frame(self, value: int) -> None:
        value = int(value)
        if value < 0:
            value += self.n_frames
        value = int(np.clip(value, 0, self.n_frames - 1))
        if value != self._frame:
            self._frame = value
            self._emit("frame")

    def _build(self, view):
        if not self.history:
            return []
        z = float(view.z(self.z_m)) + 0.1

        def closed(a):
            return _xyz(np.vstack([a, a[:1]]), z)

        items = [
            MeshItem(
                polylines([closed(self.history[0])]), _line_style(1.5, rgb=False, color=LAYER_COLOURS["snake_start"])
            )
        ]
        items.append(
            MeshItem(
                polylines([closed(self.history[self._frame])]),
                _line_style(self.line_width, rgb=False, color=self.color),
            )
        )
        return items


# ---------------------------------------------------------------------------
# morph: wavefront and trajectories


def _colormap(values: np.ndarray, name: str = "plasma") -> np.ndarray:
    from matplotlib import colormaps

    return (np.asarray(colormaps[name](np.clip(values, 0, 1)))[:, :3] * 255).astype(np.uint8)


class WavefrontLayer(Layer):
    """Level-set fronts over morph time, stacked between source and target elevations.

    ``fronts`` are shapely regions in the motion-compensated frame (``MorphResult.fronts``)
    at ``times``; ``shift`` is the source translation ``(dx, dy)``: the front at morph
    fraction ``f`` is drawn moved by ``-(1 - f) * shift`` so it joins the real source
    contour at ``f = 0`` and the target at ``f = 1``; its elevation goes linearly from
    ``z_from`` to ``z_to``. ``frame`` shows fronts ``0..frame`` (all by default).
    """

    kind = "wavefront"

    def __init__(
        self,
        fronts=(),
        times=None,
        z_from: float = 0.0,
        z_to: float = 0.0,
        shift=(0.0, 0.0),
        *,
        name="wavefront",
        max_fronts: int = 24,
        line_width=2.0,
        **kw,
    ):
        kw.setdefault("color", LAYER_COLOURS["wavefront"])
        super().__init__(name, **kw)
        self.max_fronts = max_fronts
        self.line_width = line_width
        self.set_data(fronts, times, z_from, z_to, shift, emit=False)

    def set_data(self, fronts, times=None, z_from=0.0, z_to=0.0, shift=(0.0, 0.0), emit=True) -> None:
        self.fronts = list(fronts or [])
        n = len(self.fronts)
        self.times = np.arange(n, dtype=float) if times is None else np.asarray(times, float)[:n]
        self.z_from, self.z_to = float(z_from), float(z_to)
        self.shift = np.asarray(shift, float).reshape(2)
        self._frame = max(n - 1, 0)
        if emit:
            self._emit("data")

    @property
    def n_frames(self) -> int:
        return max(len(self.fronts), 1)

    @property
    def frame(self) -> int:
        return self._frame

    @frame.setter
    def frame(self, value: int) -> None:
        value = int(value) % self.n_frames if int(value) < 0 else int(min(value, self.n_frames - 1))
        if value != self._frame:
            self._frame = value
            self._emit("frame")

    def shown_indices(self) -> np.ndarray:
        """Indices of the fronts drawn at the current frame (sub-sampled to ``max_fronts``)."""
        n = self._frame + 1 if self.fronts else 0
        if n == 0:
            return np.zeros(0, int)
        idx = np.unique(np.round(np.linspace(0, n - 1, min(n, self.max_fronts))).astype(int))
        return idx

    def _build(self, view):
        if not self.fronts:
            return []
        t_end = float(self.times[-1]) if len(self.times) and self.times[-1] > 0 else 1.0
        lines, rgb = [], []
        for i in self.shown_indices():
            f = float(self.times[i]) / t_end
            col = tuple(_colormap(np.array([f]))[0])
            z = view.z(self.z_from + f * (self.z_to - self.z_from))
            for ring in polygon_rings(self.fronts[i]):
                lines.append(_xyz(ring - (1.0 - f) * self.shift, z))
                rgb.append(col)
        return [MeshItem(polylines(lines, rgb), _line_style(self.line_width))]


class TrajectoriesLayer(Layer):
    """Particle trajectories (cyan) and backtracked curvelet tracks (magenta) in 3D.

    ``trajectories`` have ``.xy`` (``(n, 2)`` metres, motion-compensated frame) and
    ``.backtracked``; elevation goes with normalised arc length from ``z_from`` to
    ``z_to``, and the source translation ``shift`` is removed gradually as in
    :class:`WavefrontLayer`.
    """

    kind = "trajectories"

    def __init__(
        self,
        trajectories=(),
        z_from: float = 0.0,
        z_to: float = 0.0,
        shift=(0.0, 0.0),
        *,
        name="trajectories",
        max_tracks: int = 150,
        line_width=1.5,
        **kw,
    ):
        kw.setdefault("color", LAYER_COLOURS["trajectories"])
        super().__init__(name, **kw)
        self.max_tracks = max_tracks
        self.line_width = line_width
        self.set_data(trajectories, z_from, z_to, shift, emit=False)

    def set_data(self, trajectories, z_from=0.0, z_to=0.0, shift=(0.0, 0.0), emit=True) -> None:
        self.trajectories = list(trajectories or [])
        self.z_from, self.z_to = float(z_from), float(z_to)
        self.shift = np.asarray(shift, float).reshape(2)
        if emit:
            self._emit("data")

    def _build(self, view):
        trs = self.trajectories
        if len(trs) > self.max_tracks:
            trs = [trs[i] for i in np.unique(np.linspace(0, len(trs) - 1, self.max_tracks).astype(int))]
        lines, rgb = [], []
        for tr in trs:
            xy = np.asarray(tr.xy, float)
            if len(xy) < 2:
                continue
            seg = np.hypot(*np.diff(xy, axis=0).T)
            s = np.concatenate([[0.0], np.cumsum(seg)])
            s = s / s[-1] if s[-1] > 0 else np.linspace(0, 1, len(xy))
            pts = xy - (1.0 - s)[:, None] * self.shift
            z = view.z(self.z_from + s * (self.z_to - self.z_from))
            lines.append(np.column_stack([pts, z]))
            rgb.append(LAYER_COLOURS["backtracked"] if getattr(tr, "backtracked", False) else self.color)
        return [MeshItem(polylines(lines, rgb), _line_style(self.line_width))]

    def legend(self):
        return [("trajectories", self.color), ("backtracked tracks", LAYER_COLOURS["backtracked"])]


# ---------------------------------------------------------------------------
# surfaces


class SurfaceLayer(Layer):
    """Triangulated geozone surface(s) in local metres; default opacity 0.6, shaded.

    ``drilled``: per mesh, which faces lie in drilled ground
    (:func:`core.model.surfaces.drilled_faces`), or a function giving them,
    called when first needed (a scene refresh makes every layer and keeps
    only the changed ones); the other faces (below the deepest bench,
    curtains under an upper bench's edge) are drawn in a lighter shade, as the
    predicted contours are. ``None`` draws every face alike.
    """

    kind = "surfaces"

    def __init__(
        self,
        meshes: Sequence[tuple[str, np.ndarray, np.ndarray]] = (),
        colours=None,
        *,
        name="surfaces",
        opacity: float = 0.6,
        drilled: Sequence[np.ndarray] | Callable[[], Sequence[np.ndarray]] | None = None,
        **kw,
    ):
        super().__init__(name, opacity=opacity, **kw)
        self.meshes = [(str(g), np.asarray(v, float), np.asarray(f, np.int64)) for g, v, f in meshes]
        self.colours = dict(colours) if colours else geozone_colours(g for g, _, _ in self.meshes)
        self._drilled = drilled

    @property
    def drilled(self) -> list[np.ndarray | None]:
        """Per mesh, which faces lie in drilled ground (``None``: not known, every face drawn alike)."""
        if callable(self._drilled):
            self._drilled = self._drilled()
        if self._drilled is None:
            return [None] * len(self.meshes)
        return [np.asarray(d, bool) for d in self._drilled]

    @classmethod
    def from_trimesh(cls, items: Iterable[tuple[str, Any]], colours=None, **kw) -> SurfaceLayer:
        """From ``(geozone, trimesh.Trimesh)`` pairs (``core.model.surfaces.surface_from_sections``)."""
        return cls([(g, m.vertices, m.faces) for g, m in items], colours, **kw)

    def _build(self, view):
        items = []
        drilled_of = self.drilled
        for i, (g, v, f) in enumerate(self.meshes):
            if not len(f) or not view.shows(g):
                continue
            pts = v.copy()
            pts[:, 2] = view.z(pts[:, 2])
            colour = self.colours.get(g, (200, 200, 200))
            drilled = drilled_of[i]
            parts = [(f, colour)] if drilled is None else [(f[drilled], colour), (f[~drilled], lighten(colour, 0.55))]
            items += [MeshItem(_surface_mesh(pts, part, i), _surface_style(rgb)) for part, rgb in parts if len(part)]
        return items

    def legend(self):
        rows = [(f"geozone {g}", self.colours.get(g, (200, 200, 200))) for g in sorted({g for g, _, _ in self.meshes})]
        if any(d is not None and not d.all() for d in self.drilled):
            rows.append(("predicted (lighter shade)", LAYER_COLOURS["predicted"]))
        return rows


def _surface_mesh(pts: np.ndarray, faces: np.ndarray, item: int) -> pv.PolyData:
    """One part of a surface; ``item`` is what a pick reports (the mesh's index in the layer)."""
    mesh = pv.PolyData(pts, faces=np.column_stack([np.full(len(faces), 3), faces]).ravel())
    mesh.point_data["item"] = np.full(len(pts), item)
    return mesh


def _surface_style(rgb) -> dict:
    """How a part of a surface is drawn (keyword arguments of ``Plotter.add_mesh``): flat-shaded, pickable."""
    return {"color": rgb, "smooth_shading": False, "show_scalar_bar": False, "scalars": None, "pickable": True}
