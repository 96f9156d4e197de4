"""Families of synthetic mines a geologist would recognise, each a seeded generator.

Every ``<family>_plan(rng)`` draws the builders of one mine of its family
(:data:`PLANS`), and :func:`compose` places them in a layout
(``core.synthetic.scenarios.make_family`` does both): a
:class:`~core.synthetic.blobs.SyntheticMine` whose geozones ``g1``,
``g2``, ... (2-4 of them, plus the host ``g0``) are built from
:mod:`core.synthetic.solids`, so their true section is exact at any
elevation. Geometry varies widely with the seed; bodies of different geozones
stay at least :data:`GAP_M` apart on every bench unless they are built to
share a contact.

* :func:`strips_plan` -- planar or gently curved dipping layers 12-32 m wide
  that cross the whole pit, moving 2-15 m sideways per 10 m of depth (dips of
  about 34-79 degrees), sometimes two in contact, sometimes with a single
  contact (a half-space geozone).
* :func:`widening_plan` -- bodies whose boundary moves outward or inward by
  0.3-1.5 m per metre of depth (3-15 m per 10 m bench: half a hole spacing to
  nearly three), and layers that thicken or thin; both signs in a mine.
* :func:`folds_plan` -- folded layers 12-30 m wide along a V or U shaped hinge
  line whose hinge migrates 2-15 m per 10 m of depth along the fold axis; the
  limbs cross the pit; sometimes the fold's core is a geozone of its own.
* :func:`splits_plan` -- a body that splits into two with depth and a pair
  that merges into one, sometimes with a third body.
* :func:`pods_plan` -- small lenses 10-30 m across that appear and pinch out
  between benches, a few drifting.
* :func:`mix_plan` -- 2-4 of the above in one mine.

Rates are per metre of depth, so a caller's bench height changes how far a
boundary moves per bench, as it would in a real pit.
``shift_scale`` multiplies the rates of dipping layers, contacts and fold
hinges (:data:`SHIFT_RANGE_PER_M`): geology moving faster than any the
engine's defaults were chosen on (see ``tests/benchmarks/bench_robustness.py``).
``length_scale`` stretches the mine along x (4: 1.1-1.4 km by 240-300 m, the
shape of Kennecott's pit): layers striking along it cross the pit for a kilometre.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
from shapely.geometry import Polygon

from core.synthetic.blobs import Blob, SyntheticMine
from core.synthetic.drilling import UNITS, pit_halfwidth_m, pit_outline, pit_step_m
from core.synthetic.solids import (
    DippingContact,
    DippingLayer,
    GrowingBody,
    fold_trace,
    offset_trace,
    star_outline,
    straight_or_bent_trace,
)

#: Least plan distance between bodies of different geozones on every bench (two rows of holes).
GAP_M = 12.0
#: Tries to place one geozone before giving up on it.
ATTEMPTS = 40
#: Sideways movement of dipping layers and contacts, and migration of fold hinges, in metres per metre
#: of depth: 2-15 m per 10 m bench, dips of atan(1 / 1.5) = 34 to atan(1 / 0.2) = 79 degrees.
SHIFT_RANGE_PER_M = (0.2, 1.5)

Geozone = list  # the solids of one geozone


@dataclass(frozen=True)
class Builder:
    """Draws one kind of geology: ``draw(rng, layout)`` returns its geozones (lists of solids), [] if it does not fit.

    ``kinds`` names what each geozone drawn is, in order (e.g. ``("strip",)``
    or ``("fold layer", "fold core")``). ``crossing`` kinds (layers, contacts,
    folds) run past the pit by design; other bodies must lie mostly inside it.
    A builder of ``pods`` is drawn that many times, one pod at a time, into a
    single geozone.
    """

    draw: Callable[[np.random.Generator, Layout], list[Geozone]]
    kinds: tuple[str, ...]
    crossing: bool = False
    pods: int = 0


@dataclass(frozen=True)
class Layout:
    """Where a mine's geology has to fit: the mine's extent, its benches and its pit."""

    extent_m: tuple[float, float, float, float]
    levels_m: np.ndarray
    bench_height_m: float
    pit_step_m: float = field(default=0.0)
    #: How many times faster than :data:`SHIFT_RANGE_PER_M` layers, contacts and fold hinges move.
    shift_scale: float = 1.0

    @property
    def shift_range_per_m(self) -> tuple[float, float]:
        """Least and greatest sideways movement of layers, contacts and fold hinges, metres per metre of depth."""
        lo, hi = SHIFT_RANGE_PER_M
        return lo * self.shift_scale, hi * self.shift_scale

    @property
    def top_m(self) -> float:
        return float(self.levels_m[0])

    @property
    def depth_m(self) -> float:
        """Vertical distance from the top bench to the deepest."""
        return float(self.levels_m[0] - self.levels_m[-1])

    @property
    def half_diagonal_m(self) -> float:
        xmin, ymin, xmax, ymax = self.extent_m
        return 0.5 * float(np.hypot(xmax - xmin, ymax - ymin))

    def reach_m(self, k: int) -> float:
        """Half the smaller side of bench ``k``'s pit."""
        return pit_halfwidth_m(self.extent_m, k, self.pit_step_m)

    @cached_property
    def pits(self) -> list[Polygon]:
        """Pit outline of every bench (before bites and partial drilling)."""
        return [pit_outline(self.extent_m, k, self.pit_step_m) for k in range(len(self.levels_m))]

    def trace_half_length_m(self, speed_per_m: float) -> float:
        """Half-length of a trace through the pit that still runs past the mine after moving with depth."""
        return self.half_diagonal_m + abs(speed_per_m) * self.depth_m + 60.0


def family_rng(family: str, seed: int) -> np.random.Generator:
    """The random generator of ``family``'s mine ``seed``: one seed gives unrelated mines in different families."""
    return np.random.default_rng([int(seed), zlib.crc32(family.encode())])


def new_layout(
    rng: np.random.Generator, n_benches: int, bench_height_m: float, shift_scale: float = 1.0, length_scale: float = 1.0
) -> Layout:
    """A mine of 280-360 x 240-300 m with its top bench at 400-2200 m elevation; ``length_scale`` times as long in x."""
    if n_benches < 2:
        raise ValueError("a synthetic mine needs at least two benches")
    w, h = rng.uniform(280.0, 360.0), rng.uniform(240.0, 300.0)
    w *= length_scale  # after the draws: a seed's long mine is its default one stretched, its geology drawn alike
    extent = (-w / 2, -h / 2, w / 2, h / 2)
    levels = float(np.round(rng.uniform(400.0, 2200.0))) - bench_height_m * np.arange(n_benches)
    return Layout(extent, levels, bench_height_m, pit_step_m(extent, n_benches, bench_height_m), shift_scale)


def offset_interval(
    layout: Layout, move_per_m: float, lo_margin_m: float, hi_margin_m: float, fraction: float = 0.85
) -> tuple[float, float] | None:
    """Offsets ``c`` (from the pit's centre, at the top bench) that stay in the pit on every bench.

    ``c + move_per_m * depth_k`` must lie in ``[-fraction * R_k + lo_margin_m,
    fraction * R_k - hi_margin_m]`` on every bench ``k``, ``R_k`` being half the
    smaller side of its pit. Both bounds are linear in the bench index, so the
    top and the deepest bench decide. None if no offset fits.
    """
    lo, hi = -np.inf, np.inf
    for k in (0, len(layout.levels_m) - 1):
        d = layout.top_m - layout.levels_m[k]
        r = fraction * layout.reach_m(k)
        lo = max(lo, -r + lo_margin_m - move_per_m * d)
        hi = min(hi, r - hi_margin_m - move_per_m * d)
    return (float(lo), float(hi)) if lo <= hi else None


def unit_vector(angle_rad: float) -> np.ndarray:
    """The plan direction at ``angle_rad`` (counter-clockwise from +x)."""
    return np.array([np.cos(angle_rad), np.sin(angle_rad)])


# ---------------------------------------------------------------------------
# Dipping strips and contacts


@dataclass(frozen=True)
class StripStyle:
    """What the layers of one sequence share: strike, dip direction and rate, and bending of the trace."""

    strike_rad: float
    shift_per_m: float  #: sideways movement along the left normal of the strike per metre of depth (signed), at a shift_scale of 1
    bend_m: float
    wavelength_m: float
    phase_rad: float


def strip_style(rng: np.random.Generator) -> StripStyle:
    """Random strike; 2-15 m of sideways movement per 10 m of depth, either way; straight 40% of the time."""
    straight = rng.random() < 0.4
    return StripStyle(
        strike_rad=float(rng.uniform(0, np.pi)),
        shift_per_m=float(rng.uniform(*SHIFT_RANGE_PER_M) * rng.choice([-1.0, 1.0])),
        bend_m=0.0 if straight else float(rng.uniform(4.0, 15.0)),
        wavelength_m=float(rng.uniform(350.0, 900.0)),
        phase_rad=float(rng.uniform(0, 2 * np.pi)),
    )


def _strip_trace(layout: Layout, style: StripStyle, offset_m: float, shift_per_m: float) -> np.ndarray:
    normal = unit_vector(style.strike_rad + np.pi / 2)
    return straight_or_bent_trace(
        tuple(offset_m * normal),
        style.strike_rad,
        layout.trace_half_length_m(shift_per_m),
        style.bend_m,
        style.wavelength_m,
        style.phase_rad,
        step_m=5.0,
    )


def _fitting_offset(
    rng: np.random.Generator,
    layout: Layout,
    shift: float,
    lo_margin: float,
    hi_margin: float,
    fraction: float = 0.85,
    min_speed: float = 0.0,
):
    """An offset and rate that keep a trace in the pit, slowing the rate (not below ``min_speed``) until one fits."""
    while True:
        interval = offset_interval(layout, shift, lo_margin, hi_margin, fraction)
        if interval is not None:
            return float(rng.uniform(*interval)), shift
        if abs(shift) * 0.85 < min_speed or shift == 0:
            return None, shift
        shift *= 0.85


def _layer_shift(rng: np.random.Generator, style: StripStyle, layout: Layout) -> float:
    """The style's rate, varied by up to 20% for one layer (dips differ a little), kept in the layout's range."""
    lo, hi = layout.shift_range_per_m
    rate = abs(style.shift_per_m) * layout.shift_scale * rng.uniform(0.8, 1.2)
    return float(np.sign(style.shift_per_m) * np.clip(rate, lo, hi))


def strips_builder(style: StripStyle, widths_m: tuple[float, ...]) -> Builder:
    """Layers of the given widths side by side in contact (one geozone each), following ``style``.

    One width is a single strip; two are two geozones sharing a contact.
    """

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        total = float(sum(widths_m))
        margin = total / 2 + style.bend_m
        c, shift = _fitting_offset(
            rng, layout, _layer_shift(rng, style, layout), margin, margin, min_speed=layout.shift_range_per_m[0]
        )
        if c is None:
            return []
        normal = unit_vector(style.strike_rad + np.pi / 2)
        velocity = tuple(shift * normal)
        if len(widths_m) == 1:
            trace = _strip_trace(layout, style, c, shift)
            return [[DippingLayer(trace, velocity, layout.top_m, total / 2, total / 2)]]
        # Two layers sharing the trace as their contact: the first on its left (+normal), the second on its right.
        w1, w2 = widths_m
        trace = _strip_trace(layout, style, c + (w2 - w1) / 2, shift)
        return [
            [DippingLayer(trace, velocity, layout.top_m, w1, 0.0)],
            [DippingLayer(trace, velocity, layout.top_m, 0.0, w2)],
        ]

    return Builder(build, ("strip",) * len(widths_m), crossing=True)


def contact_builder(style: StripStyle) -> Builder:
    """A single dipping contact: the geozone is everything on one side of it (a half-space)."""

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        # Both sides keep a good share of every bench.
        c, shift = _fitting_offset(
            rng,
            layout,
            _layer_shift(rng, style, layout),
            0.0,
            0.0,
            fraction=0.55,
            min_speed=layout.shift_range_per_m[0],
        )
        if c is None:
            return []
        normal = unit_vector(style.strike_rad + np.pi / 2)
        trace = _strip_trace(layout, style, c, shift)
        # The geozone is the smaller side at mid-depth, leaving room for layers on the other.
        side = tuple(normal * (1.0 if c + shift * layout.depth_m / 2 >= 0 else -1.0))
        return [[DippingContact(trace, tuple(shift * normal), layout.top_m, side)]]

    return Builder(build, ("contact",), crossing=True)


def strips_plan(rng: np.random.Generator) -> list[Builder]:
    """Dipping layers crossing the whole pit, sometimes with a single contact.

    2-3 geozones of one strike (random): layers 12-32 m wide in plan, moving
    2-15 m sideways per 10 m of depth with dips within 20% of each other; in
    30% of mines two layers share a contact, in 35% one geozone is a
    half-space (a single contact of the same strike, on the smaller side).
    """
    style = strip_style(rng)
    builders: list[Builder] = []
    n_layers = int(rng.integers(2, 4))
    if rng.random() < 0.35:
        builders.append(contact_builder(style))
        n_layers -= 1
    if rng.random() < 0.3:
        builders.append(strips_builder(style, tuple(rng.uniform(12.0, 32.0, 2))))
        n_layers -= 1
    builders += [strips_builder(style, (float(rng.uniform(12.0, 32.0)),)) for _ in range(max(n_layers, 0))]
    return builders


# ---------------------------------------------------------------------------
# Widening and narrowing


def growing_body_builder(sign: float) -> Builder:
    """A body whose boundary moves outward (``sign > 0``: widening downward) or inward by 0.3-1.5 m per metre.

    The body is largest (28-50 m in radius, more if needed) at the top when
    narrowing and at the deepest bench when widening. Half of them move
    0.3-0.6 m per metre and are seen on every bench; the others move 0.4-1.5 m
    per metre, are seen on three benches or more and may pinch out at the
    narrow end. Half of them also drift.
    """

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        # Its narrowest part is at least 60% of the radius (aspect and wobble). Half
        # the bodies are seen on every bench; the others, faster, on three or more.
        if rng.random() < 0.5:
            rate = float(rng.uniform(0.3, 0.6))
            radius = max(float(rng.uniform(28.0, 50.0)), (rate * layout.depth_m + 6.0) / 0.6)
        else:
            rate = float(np.exp(rng.uniform(np.log(0.4), np.log(1.5))))
            radius = max(float(rng.uniform(28.0, 50.0)), (2 * rate * layout.bench_height_m + 6.0) / 0.6)
        z_ref = layout.top_m if sign < 0 else float(layout.levels_m[-1])
        drift = np.zeros(2)
        if rng.random() < 0.5:
            drift = rng.uniform(0.1, 0.5) * unit_vector(rng.uniform(0, 2 * np.pi))
        mid = len(layout.levels_m) // 2
        centre_mid = rng.uniform(-0.7, 0.7, 2) * layout.reach_m(mid)
        centre_ref = centre_mid + drift * (float(layout.levels_m[mid]) - z_ref)
        outline = star_outline(
            tuple(centre_ref),
            radius,
            float(rng.uniform(1.0, 1.6)),
            float(rng.uniform(0, np.pi)),
            tuple((float(rng.uniform(0, 0.08)), float(rng.uniform(0, 2 * np.pi))) for _ in range(3)),
        )
        return [[GrowingBody(outline, z_ref, sign * rate, tuple(drift))]]

    return Builder(build, ("widening body" if sign > 0 else "narrowing body",))


def wedge_builder(sign: float) -> Builder:
    """A dipping layer that thickens (``sign > 0``) or thins downward by 0.3-1.2 m per metre, 10-50 m wide."""

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        style = strip_style(rng)
        shift = style.shift_per_m * 0.4 * layout.shift_scale
        style = StripStyle(style.strike_rad, shift, style.bend_m, style.wavelength_m, style.phase_rad)
        wide = float(rng.uniform(32.0, 50.0))
        rate = min(float(rng.uniform(0.3, 1.2)), (wide - 10.0) / layout.depth_m)
        top_width = wide - rate * layout.depth_m if sign > 0 else wide
        # Contacts move by half the width change each way; the margin holds the widest section.
        c, shift = _fitting_offset(rng, layout, style.shift_per_m, wide / 2 + style.bend_m, wide / 2 + style.bend_m)
        if c is None:
            return []
        normal = unit_vector(style.strike_rad + np.pi / 2)
        trace = _strip_trace(layout, style, c, shift)
        layer = DippingLayer(trace, tuple(shift * normal), layout.top_m, top_width / 2, top_width / 2, sign * rate)
        return [[layer]]

    return Builder(build, ("thickening layer" if sign > 0 else "thinning layer",), crossing=True)


def widening_plan(rng: np.random.Generator) -> list[Builder]:
    """2-4 bodies that widen or narrow with depth, both signs in every mine; a quarter are thickening or thinning layers."""
    first = rng.choice([-1.0, 1.0])
    signs = [first * (-1.0) ** i for i in range(int(rng.integers(2, 5)))]
    return [wedge_builder(s) if rng.random() < 0.25 else growing_body_builder(s) for s in signs]


# ---------------------------------------------------------------------------
# Folds


def fold_builder(n_layers: int, with_core: bool) -> Builder:
    """Folded layers (one geozone each) around a V or U shaped hinge line, and optionally the fold's core.

    Half-angle of the limbs 20-50 degrees from the axis, hinge radius 1-35 m
    (V to U), layers 12-30 m wide, 12-30 m apart or (30%) in contact, outer
    layers parallel to the inner one. The hinge migrates 2-15 m per 10 m of
    depth along the axis, either way, with a little drift across it.
    """

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        axis = float(rng.uniform(0, 2 * np.pi))
        along, across = unit_vector(axis), unit_vector(axis + np.pi / 2)
        widths = rng.uniform(12.0, 30.0, n_layers)
        gaps = np.where(rng.random(n_layers) < 0.3, 0.0, rng.uniform(12.0, 30.0, n_layers))
        inner = np.r_[0.0, np.cumsum(widths[:-1] + gaps[:-1])]  # inner contact of each layer, outward from layer 0's
        migration = float(rng.uniform(*layout.shift_range_per_m) * rng.choice([-1.0, 1.0]))
        lateral = float(rng.uniform(-0.2, 0.2))
        # The outermost hinge sits inner[-1] + widths[-1] behind the inner one (against the axis).
        p, migration = _fitting_offset(
            rng, layout, migration, inner[-1] + widths[-1], 0.0, fraction=0.6, min_speed=layout.shift_range_per_m[0]
        )
        q, lateral = _fitting_offset(rng, layout, lateral, 0.0, 0.0, fraction=0.3)
        if p is None or q is None:
            return []
        hinge = p * along + q * across
        half_length = layout.trace_half_length_m(abs(migration) + abs(lateral))
        trace = fold_trace(
            tuple(hinge), axis, np.radians(rng.uniform(20.0, 50.0)), float(rng.uniform(1.0, 35.0)), half_length
        )
        velocity = tuple(migration * along + lateral * across)
        geozones: list[Geozone] = []
        start = 0  # first layer of the run of layers in contact that layer i belongs to
        for i in range(n_layers):
            if i > 0 and gaps[i - 1] > 0:
                start = i
            # Left of the trace is the outer (convex) side of the fold. A layer in contact
            # with the one inside it grows from the same contact trace over both; the
            # inner layer takes precedence, so the two touch exactly.
            contact = offset_trace(trace, inner[start])
            thickness = float(inner[i] - inner[start] + widths[i])
            geozones.append([DippingLayer(contact, velocity, layout.top_m, thickness, 0.0)])
        if with_core:
            geozones.append([DippingContact(trace, velocity, layout.top_m, tuple(along))])
        return geozones

    return Builder(build, ("fold layer",) * n_layers + (("fold core",) if with_core else ()), crossing=True)


def folds_plan(rng: np.random.Generator) -> list[Builder]:
    """1-3 folded layers whose hinge migrates along the fold axis; half the mines also have the core as a geozone."""
    n_layers = int(rng.choice([1, 2, 3], p=[0.45, 0.4, 0.15]))
    return [fold_builder(n_layers, with_core=n_layers == 1 or rng.random() < 0.5)]


# ---------------------------------------------------------------------------
# Splits and merges


def lobes_builder(merging: bool) -> Builder:
    """Two lobes of one geozone, joined at the top and apart at depth (a split), or the reverse (a merge).

    Lobes 18-30 m in radius; joined, their centres are 15-50% of their summed
    inner radii apart; apart, 12-35 m of other ground lies between them. They
    move in opposite directions plus a shared drift of up to 0.4 m per metre.
    """

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        radii = rng.uniform(18.0, 30.0, 2)
        aspects = rng.uniform(1.0, 1.4, 2)
        harmonics = [
            tuple((float(rng.uniform(0, 0.06)), float(rng.uniform(0, 2 * np.pi))) for _ in range(2)) for _ in radii
        ]
        wobble = np.array([sum(a for a, _ in h) for h in harmonics])
        r_in = radii / np.sqrt(aspects) * (1 - wobble)
        r_out = radii * np.sqrt(aspects) * (1 + wobble)
        joined = rng.uniform(0.15, 0.5) * r_in.sum()
        apart = r_out.sum() + rng.uniform(12.0, 35.0)
        d_top, d_bottom = (apart, joined) if merging else (joined, apart)
        sep = (d_bottom - d_top) / layout.depth_m
        u = unit_vector(rng.uniform(0, np.pi))
        drift = rng.uniform(0, 0.4) * unit_vector(rng.uniform(0, 2 * np.pi))
        mid = len(layout.levels_m) // 2
        centre_top = rng.uniform(-0.75, 0.75, 2) * layout.reach_m(mid) - drift * (layout.top_m - layout.levels_m[mid])
        lobes = []
        for sgn, r, a, h in zip((-1.0, 1.0), radii, aspects, harmonics):
            lobes.append(
                Blob(
                    centre_top=tuple(centre_top + sgn * d_top / 2 * u),
                    velocity=tuple(drift + sgn * sep / 2 * u),
                    radius_top_m=float(r),
                    radius_rate=0.0,
                    aspect=float(a),
                    angle_rad=float(rng.uniform(0, np.pi)),
                    harmonics=h,
                    z_top_m=layout.top_m,
                )
            )
        return [lobes]

    return Builder(build, ("merge" if merging else "split",))


def dipping_body_builder() -> Builder:
    """A single body 20-35 m in radius drifting 0.3-0.9 m per metre of depth, changing size a little."""

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        velocity = rng.uniform(0.3, 0.9) * unit_vector(rng.uniform(0, 2 * np.pi))
        mid = len(layout.levels_m) // 2
        centre_top = rng.uniform(-0.75, 0.75, 2) * layout.reach_m(mid) - velocity * (
            layout.top_m - layout.levels_m[mid]
        )
        body = Blob(
            centre_top=tuple(centre_top),
            velocity=tuple(velocity),
            radius_top_m=float(rng.uniform(20.0, 35.0)),
            radius_rate=float(rng.uniform(-0.15, 0.15)),
            aspect=float(rng.uniform(1.0, 2.0)),
            angle_rad=float(rng.uniform(0, np.pi)),
            harmonics=tuple((float(rng.uniform(0, 0.1)), float(rng.uniform(0, 2 * np.pi))) for _ in range(3)),
            z_top_m=layout.top_m,
        )
        return [[body]]

    return Builder(build, ("dipping body",))


def splits_plan(rng: np.random.Generator) -> list[Builder]:
    """A body that splits into two with depth, a pair that merges into one, and in half the mines a third body."""
    builders = [lobes_builder(merging=False), lobes_builder(merging=True)]
    if rng.random() < 0.5:
        third = rng.choice(["split", "merge", "dipping"])
        builders.append(dipping_body_builder() if third == "dipping" else lobes_builder(third == "merge"))
    return builders


# ---------------------------------------------------------------------------
# Pods


def pods_builder(n_pods: int) -> Builder:
    """One geozone of ``n_pods`` lenses 10-30 m across, each 1-3.5 bench heights tall; 30% drift 0.3-1 m per metre.

    Pods start and end between benches anywhere from above the top bench to
    near the deepest; each is placed on its own, away from everything else.
    """

    def build(rng: np.random.Generator, layout: Layout) -> list[Geozone]:
        h = layout.bench_height_m
        z_from = float(rng.uniform(layout.levels_m[-1] + 0.5 * h, layout.top_m + h))
        z_to = z_from - float(rng.uniform(1.0, 3.5)) * h
        drifting = rng.random() < 0.3
        speed = rng.uniform(0.3, 1.0) if drifting else rng.uniform(0.0, 0.1)
        velocity = speed * unit_vector(rng.uniform(0, 2 * np.pi))
        k = int(np.argmin(np.abs(layout.levels_m - 0.5 * (z_from + z_to))))
        centre_mid = rng.uniform(-0.8, 0.8, 2) * layout.reach_m(k)
        pod = Blob(
            centre_top=tuple(centre_mid - velocity * (layout.top_m - 0.5 * (z_from + z_to))),
            velocity=tuple(velocity),
            radius_top_m=float(rng.uniform(5.0, 15.0)),
            radius_rate=0.0,
            aspect=float(rng.uniform(1.0, 1.8)),
            angle_rad=float(rng.uniform(0, np.pi)),
            harmonics=tuple((float(rng.uniform(0, 0.08)), float(rng.uniform(0, 2 * np.pi))) for _ in range(3)),
            z_top_m=layout.top_m,
            z_from_m=z_from,
            z_to_m=z_to,
        )
        return [[pod]]

    return Builder(build, ("pods",), pods=n_pods)


def pods_plan(rng: np.random.Generator) -> list[Builder]:
    """2-4 geozones of 3-8 pods each."""
    return [pods_builder(int(rng.integers(3, 9))) for _ in range(int(rng.integers(2, 5)))]


# ---------------------------------------------------------------------------
# Mix

#: What :func:`mix_plan` draws from, in the order they are placed (crossing bodies first).
MIX_PARTS = ("contact", "strip", "fold", "wedge", "growing", "split", "merge", "dipping", "pods")


def _mix_builder(part: str, rng: np.random.Generator) -> Builder:
    sign = float(rng.choice([-1.0, 1.0]))
    return {
        "contact": lambda: contact_builder(strip_style(rng)),
        "strip": lambda: strips_builder(strip_style(rng), (float(rng.uniform(12.0, 32.0)),)),
        "fold": lambda: fold_builder(1, False),
        "wedge": lambda: wedge_builder(sign),
        "growing": lambda: growing_body_builder(sign),
        "split": lambda: lobes_builder(False),
        "merge": lambda: lobes_builder(True),
        "dipping": dipping_body_builder,
        "pods": lambda: pods_builder(int(rng.integers(2, 6))),
    }[part]()


def mix_plan(rng: np.random.Generator) -> list[Builder]:
    """2-4 geozones, each a different kind drawn from :data:`MIX_PARTS` (at most one contact)."""
    parts = sorted(rng.choice(len(MIX_PARTS), size=int(rng.integers(2, 5)), replace=False))
    return [_mix_builder(MIX_PARTS[i], rng) for i in parts]


# ---------------------------------------------------------------------------
# Placement


#: Each family's plan, by name.
PLANS: dict[str, Callable[[np.random.Generator], list[Builder]]] = {
    "strips": strips_plan,
    "widening": widening_plan,
    "folds": folds_plan,
    "splits": splits_plan,
    "pods": pods_plan,
    "mix": mix_plan,
}


def compose(
    family: str,
    seed: int,
    plan: Callable[[np.random.Generator], list[Builder]],
    n_benches: int,
    bench_height_m: float,
    units: str,
    shift_scale: float = 1.0,
    length_scale: float = 1.0,
) -> SyntheticMine:
    """The mine of ``family`` at ``seed``: a layout, then the builders ``plan`` draws, placed by :func:`assemble`.

    A plan whose builders leave fewer than two geozones placed (e.g. layers
    moving so fast that only one fits in the pit) is drawn again.
    """
    rng = family_rng(family, seed)
    layout = new_layout(rng, n_benches, bench_height_m, shift_scale, length_scale)
    for _ in range(20):
        geozones = assemble(rng, layout, plan(rng))
        if len(geozones) >= 2:
            return placed_mine(rng, layout, geozones, units)
    raise RuntimeError(f"could not place two geozones in {family} mine {seed}")


def assemble(rng: np.random.Generator, layout: Layout, builders: list[Builder]) -> list[tuple[str, Geozone]]:
    """``(kind, geozone)`` from ``builders``, each redrawn until it keeps :data:`GAP_M` from those already placed.

    A builder that cannot be placed in :data:`ATTEMPTS` tries is dropped.
    """
    placed: list[tuple[str, Geozone]] = []
    taken = [shapely.Polygon() for _ in layout.levels_m]  # union of placed bodies per bench
    for build in builders:
        placed.extend(zip(build.kinds, _place(rng, layout, build, taken)))
    return placed


def _place(rng: np.random.Generator, layout: Layout, build: Builder, taken: list) -> list[Geozone]:
    """The builder's geozones once placed (pods one by one into one geozone), [] if they do not fit."""
    if not build.pods:
        return _place_one(rng, layout, build, taken)
    pods = []
    for _ in range(build.pods):
        for geozone in _place_one(rng, layout, build, taken):
            pods.extend(geozone)
    return [pods] if pods else []


def _place_one(rng: np.random.Generator, layout: Layout, build: Builder, taken: list) -> list[Geozone]:
    frame = shapely.box(*layout.extent_m)
    for _ in range(ATTEMPTS):
        geozones = build.draw(rng, layout)
        if not geozones:
            continue
        sections = []
        seen = False
        for z, pit, other in zip(layout.levels_m, layout.pits, taken):
            region = shapely.union_all([s.section(float(z)) for g in geozones for s in g]).intersection(frame)
            fits, shows = _fits_bench(region, pit, other, build.crossing)
            if not fits:
                break
            seen |= shows
            sections.append(region)
        if len(sections) < len(taken) or not seen:
            continue
        for k, region in enumerate(sections):
            taken[k] = taken[k].union(region)
        return geozones
    return []


def _fits_bench(region, pit: Polygon, other, crossing: bool, max_outside: float = 0.25) -> tuple[bool, bool]:
    """(fits, shows) on one bench: at least :data:`GAP_M` from placed bodies and,
    unless crossing, at most ``max_outside`` of it outside the pit; shows when 30 m2 of it are in the pit."""
    if region.is_empty:
        return True, False
    if not other.is_empty and region.distance(other) < GAP_M:
        return False, False
    inside = region.intersection(pit).area
    if not crossing and inside < (1 - max_outside) * region.area:
        return False, False
    return True, inside >= 30.0


def placed_mine(
    rng: np.random.Generator, layout: Layout, geozones: list[tuple[str, Geozone]], units: str
) -> SyntheticMine:
    """The mine of ``(kind, geozone)`` pairs placed in ``layout``: geozones g1, g2, ... at a mine-grid origin near (650 km, 7,400 km)."""
    if units not in UNITS:
        raise ValueError(f"unknown units {units!r}: use one of {', '.join(UNITS)}")
    origin = (
        float(np.round(650_000.0 + rng.uniform(-20_000, 20_000))),
        float(np.round(7_400_000.0 + rng.uniform(-20_000, 20_000))),
    )
    return SyntheticMine(
        geozones={f"g{i}": list(g) for i, (_, g) in enumerate(geozones, start=1)},
        extent_m=layout.extent_m,
        bench_levels_m=np.asarray(layout.levels_m, float),
        origin=origin,
        metres_per_unit=UNITS[units],
        kinds={f"g{i}": kind for i, (kind, _) in enumerate(geozones, start=1)},
    )
