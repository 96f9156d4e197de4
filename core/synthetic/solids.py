"""Solids with analytic horizontal sections: dipping layers and contacts, folds, growing bodies.

Each class is a :class:`core.synthetic.blobs.Solid`: ``section(z_m)`` returns
its exact region at elevation ``z_m`` (local metres) as a shapely polygon.
Sections are built from a plan *trace* (a polyline that runs well past the
mine) or an *outline* moved with depth, so every section is one shapely
operation (a buffer and a translation) and costs well under a millisecond.

* :class:`DippingLayer` -- a layer between two contacts parallel to a trace
  that moves sideways at a constant rate with depth: a planar (straight trace)
  or gently curved dipping strip, or a folded layer when the trace is V or U
  shaped and moves along the fold axis (a plunging fold whose hinge migrates).
* :class:`DippingContact` -- everything on one side of such a trace (a single
  contact, or the core of a fold).
* :class:`GrowingBody` -- an outline whose boundary moves outward (widening) or
  inward (narrowing) by a fixed distance per metre of depth, optionally
  drifting; it pinches out where it narrows to nothing.
* :class:`PivotingContact` -- everything on one side of a straight contact that
  turns about a fixed point with depth (its dip changes along strike).
* :class:`Hollow` and :class:`Clipped` -- one solid less another (a ring, a
  body with a core of other rock), and a solid cut by a fixed plan polygon (one
  block of a faulted layer).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString, MultiPolygon, Polygon

from core.synthetic.blobs import Solid


def _moved(trace_m: np.ndarray, velocity: tuple[float, float], depth_m: float) -> np.ndarray:
    return np.asarray(trace_m, float) + depth_m * np.asarray(velocity, float)


@dataclass(frozen=True, eq=False)
class DippingLayer:
    """A layer bounded by two contacts parallel to a moving plan trace.

    At elevation ``z`` the trace sits at ``trace_m + (z_ref_m - z) * velocity``;
    the layer extends ``left_m`` to the left of it and ``right_m`` to the right
    (looking along the trace), each side growing by ``growth_per_m / 2`` per
    metre of depth (and stopping at the trace when it thins). A straight trace moving along its normal at ``s`` metres per
    metre of depth is a planar contact dipping at ``atan(1 / s)``.

    Parameters
    ----------
    trace_m : (n, 2) array
        Plan polyline at ``z_ref_m`` (local metres); must run past the mine on both ends.
    velocity : (vx, vy)
        Plan movement of the trace per metre of depth.
    z_ref_m : float
        Elevation at which the trace is ``trace_m``.
    left_m, right_m : float
        Plan extent of the layer on either side of the trace at ``z_ref_m``.
    growth_per_m : float
        Change of the layer's plan width per metre of depth (negative: thins).
    """

    trace_m: np.ndarray
    velocity: tuple[float, float]
    z_ref_m: float
    left_m: float
    right_m: float
    growth_per_m: float = 0.0

    def section(self, z_m: float) -> Polygon | MultiPolygon:
        depth = self.z_ref_m - z_m
        line = LineString(_moved(self.trace_m, self.velocity, depth))
        # Each side grows by half the width change and stops at the trace.
        grow = 0.5 * self.growth_per_m * depth
        left, right = max(self.left_m + grow, 0.0), max(self.right_m + grow, 0.0)
        if left == right:
            return line.buffer(left, cap_style="flat", quad_segs=8) if left > 0 else Polygon()
        # Single-sided buffers share the trace exactly, so two layers on either
        # side of one trace touch without a gap or an overlap.
        parts = [line.buffer(d, single_sided=True, quad_segs=8) for d in (left, -right) if d != 0]
        return shapely.union_all(parts) if parts else Polygon()


@dataclass(frozen=True, eq=False)
class DippingContact:
    """Everything on one side of a moving plan trace: a single contact, or a fold's core.

    The region at ``z`` is bounded by the trace at ``trace_m + (z_ref_m - z) *
    velocity`` and extends ``far_m`` from it in the direction ``side`` (far
    enough to leave the mine). The trace must be a graph over the direction
    perpendicular to ``side`` (no folding back), which straight, gently curved
    and V/U-shaped traces are.
    """

    trace_m: np.ndarray
    velocity: tuple[float, float]
    z_ref_m: float
    side: tuple[float, float]
    far_m: float = 5000.0

    def section(self, z_m: float) -> Polygon:
        line = _moved(self.trace_m, self.velocity, self.z_ref_m - z_m)
        side = np.asarray(self.side, float)
        side = side / np.hypot(*side)
        return shapely.make_valid(Polygon(np.vstack([line, (line + self.far_m * side)[::-1]])))


@dataclass(frozen=True, eq=False)
class GrowingBody:
    """A body whose outline moves along its normal by ``growth_per_m`` per metre of depth.

    ``section(z) = (outline moved by (z_ref - z) * velocity).buffer((z_ref - z) * growth_per_m)``:
    every point of the boundary moves outward (``growth_per_m > 0``, widening
    downward) or inward (narrowing) by the same distance, so a bench height of
    ``h`` moves the boundary by ``h * growth_per_m`` everywhere. A narrowing
    body pinches out (empty section) once it has shrunk to nothing.
    """

    outline_m: Polygon
    z_ref_m: float
    growth_per_m: float
    velocity: tuple[float, float] = (0.0, 0.0)

    def section(self, z_m: float) -> Polygon | MultiPolygon:
        depth = self.z_ref_m - z_m
        moved = affinity.translate(self.outline_m, depth * self.velocity[0], depth * self.velocity[1])
        grow = depth * self.growth_per_m
        return moved.buffer(grow, quad_segs=8) if grow != 0 else moved


def star_outline(
    centre: tuple[float, float],
    radius_m: float,
    aspect: float,
    angle_rad: float,
    harmonics: tuple[tuple[float, float], ...] = (),
    n: int = 120,
) -> Polygon:
    """A smooth star-shaped outline, ``r(theta) = radius * (1 + sum_k a_k cos(k theta + p_k))``.

    Stretched by ``sqrt(aspect)`` along its long axis (and compressed across it),
    rotated by ``angle_rad``; ``harmonics`` are ``(a_k, p_k)`` for k = 2, 3, ...
    """
    theta = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = np.ones_like(theta)
    for k, (a, p) in enumerate(harmonics, start=2):
        r += a * np.cos(k * theta + p)
    r *= radius_m
    x = r * np.cos(theta) * np.sqrt(aspect)
    y = r * np.sin(theta) / np.sqrt(aspect)
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return Polygon(np.column_stack([centre[0] + c * x - s * y, centre[1] + s * x + c * y]))


def straight_or_bent_trace(
    centre: tuple[float, float],
    strike_rad: float,
    half_length_m: float,
    bend_m: float = 0.0,
    wavelength_m: float = 600.0,
    phase_rad: float = 0.0,
    step_m: float = 2.0,
) -> np.ndarray:
    """Plan trace through ``centre`` along ``strike_rad``, bent sideways by ``bend_m * sin(2 pi t / wavelength + phase)``."""
    t = np.arange(-half_length_m, half_length_m + step_m, step_m)
    along = np.array([np.cos(strike_rad), np.sin(strike_rad)])
    across = np.array([-along[1], along[0]])
    offset = bend_m * (np.sin(2 * np.pi * t / wavelength_m + phase_rad) - np.sin(phase_rad))
    return np.asarray(centre, float) + t[:, None] * along + offset[:, None] * across


def fold_trace(
    hinge: tuple[float, float],
    axis_rad: float,
    half_angle_rad: float,
    hinge_radius_m: float,
    half_length_m: float,
) -> np.ndarray:
    """V or U shaped plan trace of a folded layer, opening along ``axis_rad`` from ``hinge``.

    Across-axis coordinate ``t``, along-axis ``(sqrt(t^2 + r^2) - r) / tan(half_angle)``:
    a sharp V for a small hinge radius ``r``, a rounded U for a large one; the
    limbs make ``half_angle_rad`` with the axis far from the hinge. Vertices
    are 0.5 m apart near the hinge and 4 m along the limbs, which are nearly straight.
    """
    near = np.arange(0.0, 20.0, 0.5)
    far = np.arange(20.0, half_length_m + 4.0, 4.0)
    half = np.r_[near, far]
    t = np.r_[-half[:0:-1], half]
    along = np.array([np.cos(axis_rad), np.sin(axis_rad)])
    across = np.array([-along[1], along[0]])
    f = (np.sqrt(t**2 + hinge_radius_m**2) - hinge_radius_m) / np.tan(half_angle_rad)
    return np.asarray(hinge, float) + t[:, None] * across + f[:, None] * along


def offset_trace(trace_m: np.ndarray, distance_m: float) -> np.ndarray:
    """The trace moved ``distance_m`` along its left normal at every vertex (parallel curve).

    Exact for straight parts; on the convex side of a bend the parallel curve
    never folds back, which is how the outer layers of a fold are built.
    """
    tangent = np.gradient(np.asarray(trace_m, float), axis=0)
    tangent /= np.linalg.norm(tangent, axis=1)[:, None]
    left = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    return trace_m + distance_m * left


def half_plane(point_m, normal: np.ndarray, far_m: float = 5000.0) -> Polygon:
    """The plan on the ``normal`` side of the line through ``point_m`` (a square ``far_m`` deep and twice as long)."""
    n = np.asarray(normal, float)
    t = np.array([-n[1], n[0]]) * far_m
    p = np.asarray(point_m, float)
    return Polygon([p + t, p + t + n * far_m, p - t + n * far_m, p - t])


@dataclass(frozen=True, eq=False)
class PivotingContact:
    """Everything on one side of a straight contact through ``pivot_m`` that turns with depth.

    At elevation ``z`` the contact's normal (pointing into the region) is at
    ``normal_rad + (z_ref_m - z) * turn_rad_per_m``: the contact stands still
    at the pivot and moves faster the further along strike from it, as a
    contact whose dip changes along strike does.
    """

    pivot_m: tuple[float, float]
    normal_rad: float
    turn_rad_per_m: float
    z_ref_m: float
    far_m: float = 5000.0

    def section(self, z_m: float) -> Polygon:
        a = self.normal_rad + (self.z_ref_m - z_m) * self.turn_rad_per_m
        return half_plane(self.pivot_m, np.array([np.cos(a), np.sin(a)]), self.far_m)


@dataclass(frozen=True, eq=False)
class Hollow:
    """The section of ``outer`` less that of ``inner``: a ring, or a body around a core of other rock."""

    outer: Solid
    inner: Solid

    def section(self, z_m: float) -> Polygon | MultiPolygon:
        return self.outer.section(z_m).difference(self.inner.section(z_m))


@dataclass(frozen=True, eq=False)
class Clipped:
    """The section of ``solid`` inside the fixed plan polygon ``keep_m`` (one block of a faulted body)."""

    solid: Solid
    keep_m: Polygon

    def section(self, z_m: float) -> Polygon | MultiPolygon:
        return self.solid.section(z_m).intersection(self.keep_m)
