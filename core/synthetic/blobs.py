"""Seeded synthetic ore bodies with known 3D geometry, sampled as blastholes.

The real test of the method is how well it recovers geometry it cannot see.
:class:`SyntheticMine` defines geozones as solids whose horizontal sections are
known exactly at any elevation:

* a *dipping body* whose section drifts laterally with depth and changes shape;
* a *splitting body*, one lobe at the top that separates into two with depth;
* small *pods* that appear and pinch out between benches;
* the host rock, everything else inside the drilled footprint.

:func:`sample_blastholes` drills it bench by bench on staggered patterns
(5-7 m spacing, jitter, a footprint that shrinks with depth and is only partly
drilled on some benches, a little label noise), as a mine would.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import pandas as pd
import shapely
import shapely.affinity
from shapely.geometry import MultiPolygon, Polygon, box
from shapely.ops import unary_union

from core.geometry.grid import as_multipolygon

HOST = "g0"


@dataclass(frozen=True)
class Blob:
    """A smooth star-shaped section whose centre, size and shape vary linearly with depth.

    Radius ``r(theta) = R(z) * (1 + sum_k a_k cos(k theta + p_k))`` around
    ``centre(z) = centre_top + velocity * (z_top - z)``.
    """

    centre_top: tuple[float, float]
    velocity: tuple[float, float]  # lateral metres per metre of depth
    radius_top_m: float
    radius_rate: float  # change of radius per metre of depth
    aspect: float  # x/y stretch
    angle_rad: float
    harmonics: tuple[tuple[float, float], ...]  # (a_k, p_k), k = 2, 3, ...
    z_top_m: float
    z_from_m: float = np.inf  # exists for z <= z_from
    z_to_m: float = -np.inf  # and z >= z_to (pods)

    def section(self, z_m: float, n: int = 180) -> Polygon:
        if not (self.z_to_m <= z_m <= self.z_from_m):
            return Polygon()
        depth = self.z_top_m - z_m
        radius = self.radius_top_m + self.radius_rate * depth
        if self.z_from_m < np.inf and self.z_to_m > -np.inf:
            # Pods are lens shaped: widest mid-way, zero at their ends.
            mid = 0.5 * (self.z_from_m + self.z_to_m)
            half = 0.5 * (self.z_from_m - self.z_to_m)
            radius = self.radius_top_m * np.sqrt(max(1.0 - ((z_m - mid) / half) ** 2, 0.0))
        if radius <= 0.5:
            return Polygon()
        theta = np.linspace(0, 2 * np.pi, n, endpoint=False)
        r = np.ones_like(theta)
        for k, (a, p) in enumerate(self.harmonics, start=2):
            r += a * np.cos(k * theta + p)
        r *= radius
        x = r * np.cos(theta) * np.sqrt(self.aspect)
        y = r * np.sin(theta) / np.sqrt(self.aspect)
        c, s = np.cos(self.angle_rad), np.sin(self.angle_rad)
        cx = self.centre_top[0] + self.velocity[0] * depth
        cy = self.centre_top[1] + self.velocity[1] * depth
        return Polygon(np.column_stack([cx + c * x - s * y, cy + s * x + c * y]))


class Solid(Protocol):
    """A 3D body known by its horizontal sections: anything with ``section(z_m)``.

    ``section(z_m)`` returns the body's region at elevation ``z_m`` (metres,
    in the mine's local frame) as a shapely Polygon or MultiPolygon, empty
    where the body is absent. :class:`Blob` is one; :mod:`core.synthetic.solids`
    has more.
    """

    def section(self, z_m: float) -> Polygon | MultiPolygon: ...


@dataclass
class SyntheticMine:
    """Geozones as unions of solids, with an exact section at any elevation.

    Each geozone is a list of solids (:class:`Solid`: :class:`Blob` or any
    object with ``section(z_m)``). Geozones listed first take precedence where
    solids overlap; the host :data:`HOST` is everything else inside the extent.

    Geometry is in local metres. The drilled table is in ``metres_per_unit``
    units (1 for metres, 0.3048 for feet): a local point ``p`` (metres) is
    written as ``(p + origin) / metres_per_unit``, ``origin`` being the
    mine-grid position of the local origin in metres, and an elevation ``z``
    as ``z / metres_per_unit``.
    """

    geozones: Mapping[str, Sequence[Solid]]
    extent_m: tuple[float, float, float, float]
    bench_levels_m: np.ndarray
    origin: tuple[float, float] = (0.0, 0.0)
    footprints: dict[float, Polygon] = field(default_factory=dict)
    metres_per_unit: float = 1.0
    #: What each geozone is, in a geologist's words ("strip", "fold core", "pods"...), where the generator says.
    kinds: dict[str, str] = field(default_factory=dict)

    def sections(self, z_m: float) -> dict[str, MultiPolygon]:
        """True region of every geozone (host included) at elevation ``z_m``, inside the extent."""
        frame = box(*self.extent_m)
        taken = Polygon()
        out = {}
        for name, solids in self.geozones.items():
            region = unary_union([s.section(z_m) for s in solids]).intersection(frame).difference(taken)
            out[name] = as_multipolygon(region)
            taken = taken.union(region)
        out[HOST] = as_multipolygon(frame.difference(taken))
        return out

    def section(self, geozone: str, z_m: float) -> MultiPolygon:
        """True region of ``geozone`` at elevation ``z_m`` (local metres), inside the extent."""
        if geozone != HOST and geozone not in self.geozones:
            raise KeyError(geozone)
        return self.sections(z_m)[geozone]

    def label_at(self, xy: np.ndarray, z_m: float) -> np.ndarray:
        """True geozone label of points ``xy`` (local metres) at elevation ``z_m``."""
        labels = np.full(len(xy), HOST, dtype=object)
        unset = np.ones(len(xy), bool)
        for name, solids in self.geozones.items():
            region = unary_union([s.section(z_m) for s in solids])
            if region.is_empty:
                continue
            inside = shapely.contains_xy(region, xy[:, 0], xy[:, 1]) & unset
            labels[inside] = name
            unset &= ~inside
        return labels

    def scale_to(self, frame) -> float:
        """Engine metres per mine metre when the drilled table is read in ``frame``.

        1 unless the table is read in other units than it was written in.
        """
        return frame.metres_per_unit / self.metres_per_unit

    def offset_to(self, frame) -> tuple[float, float]:
        """Shift from this mine's local metres (scaled by :meth:`scale_to`) to a frame's metres.

        A mine point ``p`` is written as ``(p + origin) / metres_per_unit``
        and the frame maps input ``q`` to ``(q - frame.origin) * frame.metres_per_unit``,
        so ``p`` lands at ``scale * p + offset``.
        """
        s, mpu = self.scale_to(frame), frame.metres_per_unit
        return (s * self.origin[0] - frame.origin_x * mpu, s * self.origin[1] - frame.origin_y * mpu)

    def _to_frame(self, frame, geometry):
        s = self.scale_to(frame)
        if s != 1.0:
            geometry = shapely.affinity.scale(geometry, s, s, origin=(0, 0))
        return shapely.affinity.translate(geometry, *self.offset_to(frame))

    def section_in(self, frame, geozone: str, z_m: float) -> MultiPolygon:
        """True section of ``geozone`` at the frame's elevation ``z_m``, in the frame's local metres."""
        return as_multipolygon(self._to_frame(frame, self.section(geozone, z_m / self.scale_to(frame))))

    def footprint_in(self, frame, z_m: float) -> Polygon:
        """Drilled area of the bench nearest the frame's elevation ``z_m``, in the frame's local metres."""
        z_mine = z_m / self.scale_to(frame)
        level = min(self.footprints, key=lambda q: abs(q - z_mine))
        return self._to_frame(frame, self.footprints[level])

    @property
    def labels(self) -> list[str]:
        return [HOST, *self.geozones]


def _random_pods(rng, n_pods: int, extent_m, top_m: float, depth_total: float, bench_height_m: float, harmonics):
    """Small lenses that exist over part of the depth range (the pods of :func:`make_mine`)."""
    w, h = extent_m
    pods = []
    for _ in range(n_pods):
        z_from = top_m - rng.uniform(0.0, 0.6) * depth_total
        length = rng.uniform(1.5, 3.5) * bench_height_m
        pods.append(
            Blob(
                centre_top=(rng.uniform(-0.4 * w, 0.4 * w), rng.uniform(-0.4 * h, 0.4 * h)),
                velocity=(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2)),
                radius_top_m=rng.uniform(10.0, 16.0),
                radius_rate=0.0,
                aspect=rng.uniform(1.0, 1.6),
                angle_rad=rng.uniform(0, np.pi),
                harmonics=harmonics(0.08),
                z_top_m=top_m,
                z_from_m=z_from,
                z_to_m=z_from - length,
            )
        )
    return pods


def make_mine(
    seed: int = 0,
    n_benches: int = 7,
    bench_height_m: float = 10.0,
    extent_m: tuple[float, float] = (300.0, 220.0),
    origin: tuple[float, float] = (0.0, 0.0),
    top_m: float = 685.0,
    n_pods: int = 3,
) -> SyntheticMine:
    """A random mine with a dipping body, a splitting body and pods.

    Parameters
    ----------
    seed : int
        Everything random follows from it.
    n_benches : int
        Number of benches (>= 2).
    bench_height_m : float
        Vertical distance between benches.
    extent_m : (width, height)
        Size of the mine area (local frame centred on 0).
    origin : (x, y)
        Mine-grid coordinates of the local origin.
    top_m : float
        Elevation of the top bench.
    n_pods : int
        Number of small pods.
    """
    rng = np.random.default_rng(seed)
    w, h = extent_m
    depth_total = bench_height_m * (n_benches - 1)
    levels = top_m - bench_height_m * np.arange(n_benches)

    def harmonics(scale: float) -> tuple[tuple[float, float], ...]:
        return tuple((float(rng.uniform(0, scale)), float(rng.uniform(0, 2 * np.pi))) for _ in range(3))

    # Dipping body: drifts 0.3-0.8 m per metre of depth in a random direction.
    speed = rng.uniform(0.4, 0.9)
    heading = rng.uniform(0, 2 * np.pi)
    vel = (speed * np.cos(heading), speed * np.sin(heading))
    drift = np.array(vel) * depth_total
    cx = rng.uniform(-0.2 * w, -0.05 * w) - drift[0] / 2
    cy = rng.uniform(-0.1 * h, 0.1 * h) - drift[1] / 2
    dipping = Blob(
        centre_top=(cx, cy),
        velocity=vel,
        radius_top_m=rng.uniform(0.2, 0.25) * min(w, h),
        radius_rate=rng.uniform(-0.25, 0.15),
        aspect=rng.uniform(1.2, 2.0),
        angle_rad=rng.uniform(0, np.pi),
        harmonics=harmonics(0.12),
        z_top_m=top_m,
    )
    # Splitting body: two lobes that coincide at the top and separate with depth.
    sx, sy = rng.uniform(0.12 * w, 0.2 * w), rng.uniform(-0.1 * h, 0.1 * h)
    split_dir = rng.uniform(0, np.pi)
    sep_rate = rng.uniform(0.5, 0.9)  # each lobe moves this many m per m of depth
    r0 = rng.uniform(0.11, 0.14) * min(w, h)
    lobes = [
        Blob(
            centre_top=(sx, sy),
            velocity=(sgn * sep_rate * np.cos(split_dir), sgn * sep_rate * np.sin(split_dir)),
            radius_top_m=r0,
            radius_rate=rng.uniform(-0.1, 0.0),
            aspect=rng.uniform(1.0, 1.4),
            angle_rad=split_dir,
            harmonics=harmonics(0.06),
            z_top_m=top_m,
        )
        for sgn in (-1.0, 1.0)
    ]
    pods = _random_pods(rng, n_pods, extent_m, top_m, depth_total, bench_height_m, harmonics)
    return SyntheticMine(
        geozones={"g1": [dipping], "g2": lobes, "g3": pods},
        extent_m=(-w / 2, -h / 2, w / 2, h / 2),
        bench_levels_m=levels,
        origin=origin,
    )


#: Drilling patterns :func:`drill_pattern` lays out.
PATTERNS = ("staggered", "square")


def drill_pattern(
    footprint: Polygon,
    spacing_m: float,
    angle_rad: float,
    jitter_m: float,
    rng: np.random.Generator,
    pattern: str = "staggered",
) -> np.ndarray:
    """Blasthole pattern covering ``footprint``: ``"staggered"`` (hexagonal-ish) or ``"square"``."""
    if pattern not in PATTERNS:
        raise ValueError(f"unknown drilling pattern {pattern!r}; expected one of {PATTERNS}")
    xmin, ymin, xmax, ymax = footprint.bounds
    span = np.hypot(xmax - xmin, ymax - ymin)
    staggered = pattern == "staggered"
    burden = spacing_m * np.sqrt(3) / 2 if staggered else spacing_m
    rows = np.arange(-span / 2, span / 2 + burden, burden)
    cols = np.arange(-span / 2, span / 2 + spacing_m, spacing_m)
    gx, gy = np.meshgrid(cols, rows)
    if staggered:
        gx = gx + (np.arange(len(rows))[:, None] % 2) * spacing_m / 2
    pts = np.column_stack([gx.ravel(), gy.ravel()])
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    pts = pts @ np.array([[c, s], [-s, c]])
    pts += np.array([(xmin + xmax) / 2, (ymin + ymax) / 2])
    pts += rng.normal(0.0, jitter_m, pts.shape)
    return pts[shapely.contains_xy(footprint, pts[:, 0], pts[:, 1])]


def bench_footprint(mine: SyntheticMine, k: int, rng: np.random.Generator, partial: bool) -> Polygon:
    """Drilled area of bench ``k``: the pit shrinks with depth; some benches are only partly drilled."""
    xmin, ymin, xmax, ymax = mine.extent_m
    # The pit narrows by 3% of its width per bench, to at most 30% (deep pits keep a floor).
    shrink = min(0.03 * k, 0.3) * min(xmax - xmin, ymax - ymin)
    area = box(xmin + shrink, ymin + shrink, xmax - shrink, ymax - shrink)
    area = area.buffer(-0.1 * (ymax - ymin), join_style="round").buffer(0.1 * (ymax - ymin), join_style="round")
    if partial:
        # Not yet drilled: a corner cut off by a random line.
        ang = rng.uniform(0, 2 * np.pi)
        normal = np.array([np.cos(ang), np.sin(ang)])
        cx, cy = area.centroid.x, area.centroid.y
        offset = rng.uniform(0.25, 0.4) * min(xmax - xmin, ymax - ymin)
        far = 10 * (xmax - xmin)
        p = np.array([cx, cy]) + normal * offset
        t = np.array([-normal[1], normal[0]])
        cut = Polygon([p + t * far, p + t * far + normal * far, p - t * far + normal * far, p - t * far])
        area = area.difference(cut)
    return area


def sample_blastholes(
    mine: SyntheticMine,
    seed: int = 0,
    spacing_range_m: tuple[float, float] = (5.0, 7.0),
    label_noise: float = 0.01,
    partial_fraction: float = 0.4,
    z_scatter_m: float = 0.5,
) -> pd.DataFrame:
    """Drill every bench of ``mine`` and label the holes.

    Returns a table with columns ``x, y, z, geozone, hole_id`` in mine-grid
    coordinates (``mine.origin`` added). Also records each bench's drilled
    footprint in ``mine.footprints`` (keyed by bench elevation) so tests can
    compare with the truth inside the drilled area.
    """
    rng = np.random.default_rng(seed)
    frames = []
    for k, z in enumerate(mine.bench_levels_m):
        footprint = bench_footprint(mine, k, rng, partial=k > 0 and rng.random() < partial_fraction)
        spacing = rng.uniform(*spacing_range_m)
        xy = drill_pattern(footprint, spacing, rng.uniform(0, np.pi), 0.08 * spacing, rng)
        labels = mine.label_at(xy, z)
        flip = rng.random(len(xy)) < label_noise
        if flip.any():
            # A mislabelled assay takes the label of another geozone present on the bench.
            present = sorted(set(labels.tolist()))
            labels[flip] = [rng.choice([g for g in present if g != lab] or [lab]) for lab in labels[flip]]
        mine.footprints[float(z)] = footprint
        frames.append(
            pd.DataFrame(
                {
                    "x": np.round(xy[:, 0] + mine.origin[0], 2),
                    "y": np.round(xy[:, 1] + mine.origin[1], 2),
                    "z": np.round(z + rng.uniform(-z_scatter_m, z_scatter_m, len(xy)), 2),
                    "geozone": labels,
                    "hole_id": [f"B{k:02d}-{i:05d}" for i in range(len(xy))],
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def demo_dataset(seed: int = 2019) -> tuple[SyntheticMine, pd.DataFrame]:
    """The bundled demo: 7 benches of 10 m in mine-grid coordinates (see ``assets/``)."""
    mine = make_mine(seed=seed, origin=(482_350.0, 7_445_120.0))
    return mine, sample_blastholes(mine, seed=seed + 1)
