"""Geology none of the six families draws, to measure the engine on shapes it was not built on.

The families of :mod:`core.synthetic.families` are what the engine's defaults
were chosen on (their tuning seeds). The shapes here were added after those
choices and no default is tuned on them: they are a check that the model
generalises, reported by ``tests/benchmarks/bench_robustness.py``.
``make_shape(shape, seed)`` returns a :class:`~core.synthetic.blobs.SyntheticMine`
with one shape (plus the host ``g0``), drilled like any family's mine:

* ``ring`` -- a body around a core of host rock, both growing or shrinking and
  drifting with depth (a section with a hole in it).
* ``faulted strip`` -- a dipping layer cut by a vertical fault that offsets one
  block 15-40 m across strike (a section in two parts that move together).
* ``inclusion`` -- a contact that moves with depth around a pipe of another
  geozone (a region with a hole of another geozone, and the pipe itself).
* ``pivoting contact`` -- a straight contact that turns 1.5-4 degrees per 10 m
  about a point in the pit (movement changing along strike).
* ``angular body`` -- a rectangle 40-80 m across translating 3-9 m per 10 m
  (sharp corners).
* ``arc`` -- a curved layer 16-30 m wide moving across itself, centred 90-150 m
  from the pit's centre (strong curvature).
* ``shallow layer`` -- a layer 30-60 m wide dipping 16-29 degrees: 18-35 m
  sideways per 10 m of depth, faster than any family's contacts (a bench's
  section barely overlaps the one above).

Rates are per metre of depth, as in the families.
"""

from __future__ import annotations

import zlib

import numpy as np
import pandas as pd
import shapely
from shapely import affinity
from shapely.geometry import Point

from core.synthetic.blobs import SyntheticMine
from core.synthetic.drilling import drill_mine
from core.synthetic.families import Geozone, Layout, family_rng, new_layout, placed_mine, star_outline, unit_vector
from core.synthetic.solids import (
    Clipped,
    DippingContact,
    DippingLayer,
    GrowingBody,
    Hollow,
    PivotingContact,
    half_plane,
    straight_or_bent_trace,
)

#: Shape names, in the order reports list them.
SHAPES: tuple[str, ...] = (
    "ring",
    "faulted strip",
    "inclusion",
    "pivoting contact",
    "angular body",
    "arc",
    "shallow layer",
)


def _deepest_reach_m(layout: Layout) -> float:
    """Half the smaller side of the deepest bench's pit: where a shape's middle bench is placed from."""
    return layout.reach_m(len(layout.levels_m) - 1)


def _ring(rng: np.random.Generator, layout: Layout) -> list[tuple[str, Geozone]]:
    r_last = _deepest_reach_m(layout)
    drift = rng.uniform(0.1, 0.3) * unit_vector(rng.uniform(0, 2 * np.pi))
    centre = rng.uniform(-0.2, 0.2, 2) * r_last - drift * 0.5 * layout.depth_m
    aspect, angle = rng.uniform(1.0, 1.4), rng.uniform(0, np.pi)
    disc = star_outline(tuple(centre), rng.uniform(40.0, 55.0), aspect, angle)
    core = star_outline(tuple(centre), rng.uniform(12.0, 22.0), aspect, angle)
    # The ring stays 10 m thick or more: its outside grows, its core changes by less.
    ring = Hollow(
        GrowingBody(disc, layout.top_m, rng.uniform(0.0, 0.4), tuple(drift)),
        GrowingBody(core, layout.top_m, rng.uniform(-0.2, 0.1), tuple(drift)),
    )
    return [("ring", [ring])]


def _faulted_strip(rng: np.random.Generator, layout: Layout) -> list[tuple[str, Geozone]]:
    strike = rng.uniform(0, np.pi)
    across = unit_vector(strike + np.pi / 2)
    speed = rng.uniform(0.2, 1.0) * rng.choice([-1.0, 1.0])
    throw = rng.uniform(15.0, 40.0) * rng.choice([-1.0, 1.0])
    width = rng.uniform(16.0, 32.0)
    r_last = _deepest_reach_m(layout)
    # The strip's middle bench crosses the pit's middle half.
    offset = rng.uniform(-0.3, 0.3) * r_last - speed * 0.5 * layout.depth_m - 0.5 * throw
    fault = unit_vector(strike + rng.uniform(np.radians(50), np.radians(130)))  # a vertical fault through the centre
    sides = [half_plane((0.0, 0.0), s * np.array([-fault[1], fault[0]])) for s in (1.0, -1.0)]
    blocks = []
    for side, shift in zip(sides, (0.0, throw)):
        trace = straight_or_bent_trace(tuple((offset + shift) * across), strike, 1000.0)
        layer = DippingLayer(trace, tuple(speed * across), layout.top_m, width / 2, width / 2)
        blocks.append(Clipped(layer, side))
    return [("faulted strip", blocks)]


def _inclusion(rng: np.random.Generator, layout: Layout) -> list[tuple[str, Geozone]]:
    normal = rng.uniform(0, 2 * np.pi)
    side = unit_vector(normal)
    speed = rng.uniform(0.2, 0.8)
    r_last = _deepest_reach_m(layout)
    # The contact crosses the pit's middle half at mid depth; the region is on the side of ``side``.
    start = (rng.uniform(-0.3, 0.1) * r_last - speed * 0.5 * layout.depth_m) * side
    trace = straight_or_bent_trace(tuple(start), normal + np.pi / 2, 1000.0)
    contact = DippingContact(trace, tuple(speed * side), layout.top_m, tuple(side))
    drift = rng.uniform(0.0, 0.4) * unit_vector(rng.uniform(0, 2 * np.pi))
    along = unit_vector(normal + np.pi / 2) * rng.uniform(-0.3, 0.3) * r_last
    centre = start + speed * 0.5 * layout.depth_m * side + rng.uniform(35.0, 55.0) * side + along
    pipe_outline = star_outline(tuple(centre - drift * 0.5 * layout.depth_m), rng.uniform(14.0, 24.0), 1.2, 0.0)
    pipe = GrowingBody(pipe_outline, layout.top_m, rng.uniform(-0.1, 0.1), tuple(drift))
    return [("pipe", [pipe]), ("contact around a pipe", [contact])]


def _pivoting_contact(rng: np.random.Generator, layout: Layout) -> list[tuple[str, Geozone]]:
    r_last = _deepest_reach_m(layout)
    pivot = rng.uniform(-0.4, 0.4, 2) * r_last
    turn = np.radians(rng.uniform(0.15, 0.4)) * rng.choice([-1.0, 1.0])
    normal = rng.uniform(0, 2 * np.pi) - turn * 0.5 * layout.depth_m
    return [("pivoting contact", [PivotingContact(tuple(pivot), normal, turn, layout.top_m)])]


def _angular_body(rng: np.random.Generator, layout: Layout) -> list[tuple[str, Geozone]]:
    r_last = _deepest_reach_m(layout)
    velocity = rng.uniform(0.3, 0.9) * unit_vector(rng.uniform(0, 2 * np.pi))
    centre = rng.uniform(-0.3, 0.3, 2) * r_last - velocity * 0.5 * layout.depth_m
    a, b = rng.uniform(40.0, 80.0), rng.uniform(40.0, 70.0)
    box = affinity.rotate(shapely.box(-a / 2, -b / 2, a / 2, b / 2), rng.uniform(0, 90.0))
    body = GrowingBody(affinity.translate(box, *centre), layout.top_m, rng.uniform(-0.1, 0.1), tuple(velocity))
    return [("angular body", [body])]


def _arc(rng: np.random.Generator, layout: Layout) -> list[tuple[str, Geozone]]:
    direction = rng.uniform(0, 2 * np.pi)
    distance = rng.uniform(90.0, 150.0)
    centre = tuple(-distance * unit_vector(direction))
    speed = rng.uniform(0.2, 0.8) * rng.choice([-1.0, 1.0])
    width = rng.uniform(16.0, 30.0)
    # The arc's middle bench passes within 0.3 of the pit's half width of its centre.
    inner = distance + rng.uniform(-0.3, 0.3) * _deepest_reach_m(layout) - speed * 0.5 * layout.depth_m
    arc = Hollow(
        GrowingBody(Point(centre).buffer(inner + width, quad_segs=64), layout.top_m, speed),
        GrowingBody(Point(centre).buffer(inner, quad_segs=64), layout.top_m, speed),
    )
    return [("arc", [arc])]


def _shallow_layer(rng: np.random.Generator, layout: Layout) -> list[tuple[str, Geozone]]:
    strike = rng.uniform(0, np.pi)
    across = unit_vector(strike + np.pi / 2)
    speed = rng.uniform(1.8, 3.5) * rng.choice([-1.0, 1.0])
    width = rng.uniform(30.0, 60.0)
    # The layer's middle bench crosses the pit's middle half; above and below it may leave the pit.
    offset = rng.uniform(-0.3, 0.3) * _deepest_reach_m(layout) - speed * 0.5 * layout.depth_m
    trace = straight_or_bent_trace(tuple(offset * across), strike, 1000.0)
    layer = DippingLayer(trace, tuple(speed * across), layout.top_m, width / 2, width / 2)
    return [("shallow layer", [layer])]


_BUILDERS = {
    "ring": _ring,
    "faulted strip": _faulted_strip,
    "inclusion": _inclusion,
    "pivoting contact": _pivoting_contact,
    "angular body": _angular_body,
    "arc": _arc,
    "shallow layer": _shallow_layer,
}


def make_shape(
    shape: str, seed: int, n_benches: int = 7, bench_height_m: float = 10.0, units: str = "m"
) -> SyntheticMine:
    """The mine of one ``shape`` (see the module docstring) at ``seed``; ValueError for an unknown shape."""
    if shape not in _BUILDERS:
        raise ValueError(f"unknown shape {shape!r}; shapes: {', '.join(SHAPES)}")
    rng = family_rng(f"shape {shape}", seed)
    layout = new_layout(rng, n_benches, bench_height_m)
    return placed_mine(rng, layout, _BUILDERS[shape](rng, layout), units)


def shape_scenario(shape: str, seed: int, **kwargs) -> tuple[SyntheticMine, pd.DataFrame, pd.Series]:
    """The mine of ``shape`` at ``seed`` drilled with the default drilling: as :func:`core.synthetic.scenarios.scenario`.

    ``kwargs`` go to :func:`make_shape` (``n_benches``, ``bench_height_m``, ``units``).
    """
    mine = make_shape(shape, seed, **kwargs)
    table, true_labels = drill_mine(mine, seed=[int(seed), zlib.crc32(f"shape {shape}".encode()), 1])
    return mine, table, true_labels
