"""Drilling a synthetic mine as a mine does: a shrinking pit, bitten benches, staggered patterns, noise.

:func:`drill_mine` drills every bench of a :class:`~core.synthetic.blobs.SyntheticMine`:

* the pit narrows bench by bench (:func:`pit_outline`, a rounded rectangle
  shrunk by :func:`pit_step_m` per bench);
* every bench has irregular polygonal bites out of its edge (:func:`edge_bite`:
  ground not drilled, ramps, old workings) and some benches are only partly
  drilled, up to a ragged front (:func:`undrilled_beyond_front`);
* holes follow a staggered pattern (a square one on request) of 5-7 m
  spacing at a random angle, both drawn per bench, with jitter
  (:func:`core.synthetic.blobs.drill_pattern`);
* 1-3% of the labels (rate drawn per mine) are replaced by another geozone
  present on the bench, as mislabelled assays are.

It returns the table the engine reads (no truth in it) and, separately, the
true label of every hole keyed by hole id.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree
from shapely import affinity
from shapely.geometry import Polygon, box

from core.io.blastholes import FEET_TO_METRES
from core.synthetic.blobs import drill_pattern

#: The deepest bench's pit is at most this fraction of the mine's smaller side narrower on each side.
PIT_SHRINK_FRACTION = 0.22
#: Corner rounding of the pit outline, as a fraction of the mine's smaller side.
PIT_ROUNDING_FRACTION = 0.15
#: Metres per unit of the drilled table, by unit name.
UNITS = {"m": 1.0, "ft": FEET_TO_METRES}


def pit_step_m(extent_m: tuple[float, float, float, float], n_benches: int, bench_height_m: float) -> float:
    """How far the pit wall steps in per bench: 0.7 bench heights, less in deep pits.

    A bench face of about 55 degrees with a berm steps in about 0.7 bench
    heights; a pit with many benches steps less so the deepest bench keeps
    at least ``1 - 2 * PIT_SHRINK_FRACTION`` of the mine's smaller side.
    """
    xmin, ymin, xmax, ymax = extent_m
    limit = PIT_SHRINK_FRACTION * min(xmax - xmin, ymax - ymin) / max(n_benches - 1, 1)
    return float(min(0.7 * bench_height_m, limit))


def pit_outline(extent_m: tuple[float, float, float, float], k: int, step_m: float) -> Polygon:
    """Outline of bench ``k``'s pit floor: the extent shrunk by ``k * step_m``, corners rounded."""
    xmin, ymin, xmax, ymax = extent_m
    shrink = k * step_m
    rounding = PIT_ROUNDING_FRACTION * min(xmax - xmin, ymax - ymin)
    area = box(xmin + shrink, ymin + shrink, xmax - shrink, ymax - shrink)
    return area.buffer(-rounding, join_style="round").buffer(rounding, join_style="round")


def pit_halfwidth_m(extent_m: tuple[float, float, float, float], k: int, step_m: float) -> float:
    """Half the smaller side of bench ``k``'s pit: every line closer than this to the centre crosses it."""
    xmin, ymin, xmax, ymax = extent_m
    return 0.5 * min(xmax - xmin, ymax - ymin) - k * step_m


def edge_bite(
    outline: Polygon, rng: np.random.Generator, radius_range_m: tuple[float, float] = (10.0, 35.0)
) -> Polygon:
    """An irregular polygonal notch centred on a random point of ``outline``'s edge.

    A star polygon of 5-9 vertices at random angles, each at 35-100% of a
    radius drawn from ``radius_range_m``.
    """
    ring = outline.exterior
    centre = ring.interpolate(rng.uniform(0, ring.length))
    n = int(rng.integers(5, 10))
    theta = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = rng.uniform(*radius_range_m) * rng.uniform(0.35, 1.0, n)
    return Polygon(np.column_stack([centre.x + r * np.cos(theta), centre.y + r * np.sin(theta)])).buffer(0)


def undrilled_beyond_front(outline: Polygon, rng: np.random.Generator) -> Polygon:
    """The part of a partly drilled bench not drilled yet: beyond a ragged front across the pit.

    The front runs across the pit 15-35% of its smaller side from its centre,
    at a random heading, with a sideways jag of up to 8 m every 15-30 m.
    """
    xmin, ymin, xmax, ymax = outline.bounds
    size = max(xmax - xmin, ymax - ymin)
    heading = rng.uniform(0, 2 * np.pi)
    normal = np.array([np.cos(heading), np.sin(heading)])
    along = np.array([-normal[1], normal[0]])
    offset = rng.uniform(0.15, 0.35) * min(xmax - xmin, ymax - ymin)
    t = np.cumsum(np.r_[0.0, rng.uniform(15.0, 30.0, int(2 * size / 15) + 2)])
    t -= t[-1] / 2
    jag = rng.uniform(-8.0, 8.0, len(t))
    centre = np.array(outline.centroid.coords[0]) + offset * normal
    front = centre + t[:, None] * along + jag[:, None] * normal
    beyond = front + 2 * size * normal
    return Polygon(np.vstack([front, beyond[::-1]])).buffer(0)


def bench_drilled_area(outline: Polygon, rng: np.random.Generator, partial: bool) -> Polygon:
    """Drilled area of a bench: its pit outline less 1-4 edge bites, less an undrilled part if ``partial``.

    The largest remaining piece is kept (a bench is drilled from one ramp).
    """
    area = outline
    for _ in range(int(rng.integers(1, 5))):
        area = area.difference(edge_bite(outline, rng))
    if partial:
        area = area.difference(undrilled_beyond_front(outline, rng))
    pieces = getattr(area, "geoms", [area])
    return max(pieces, key=lambda p: p.area)


def drill_mine(
    mine,
    seed: int | Sequence[int],
    spacing_range_m: tuple[float, float] = (5.0, 7.0),
    label_noise_range: tuple[float, float] = (0.01, 0.03),
    partial_fraction: float = 0.35,
    z_scatter_fraction: float = 0.05,
    pushback_range_m: tuple[float, float] = (0.0, 0.0),
    collar_scatter_spacings: float = 0.08,
    pattern: str = "staggered",
    contact_noise_range: tuple[float, float] = (0.0, 0.0),
) -> tuple[pd.DataFrame, pd.Series]:
    """Drill every bench of ``mine`` and label its holes, as a mine would.

    Parameters
    ----------
    mine : SyntheticMine
        Its ``metres_per_unit`` sets the table's units (coordinates and
        elevations are divided by it; feet: 1 / 0.3048).
    seed : int or sequence of int
        Everything random in the drilling follows from it (any seed
        :func:`numpy.random.default_rng` takes).
    spacing_range_m : (float, float)
        Hole spacing, drawn per bench (metres); the burden is ``sqrt(3)/2`` of
        it (staggered pattern).
    label_noise_range : (float, float)
        Range of the mine's label noise rate, drawn once per mine.
    partial_fraction : float
        Chance that a bench below the first is only partly drilled.
    z_scatter_fraction : float
        Hole elevations scatter uniformly by this fraction of the bench height.
    pushback_range_m : (float, float)
        How far each bench's pit lies sideways of the one above (metres, drawn
        once per mine, in a random heading, cut to the mine's extent): each
        bench drills ground on one side that no bench above drilled, as a pit
        pushed back in stages does (on the Kennecott benches, 29% of the next
        bench's geozone area lies off the deepest known bench's drilling). None by default.
    collar_scatter_spacings : float
        How far holes are collared off the pattern: the standard deviation of
        their offset (each way), in spacings.
    pattern : {"staggered", "square"}
        The drilling pattern (:func:`~core.synthetic.blobs.drill_pattern`).
    contact_noise_range : (float, float)
        Range of the share of holes at a contact (a hole of another geozone
        within :data:`CONTACT_SPACINGS` spacings) labelled as that neighbour,
        drawn once per mine: mislabels where a sample mixes two geozones, as
        real assays near a contact do, rather than anywhere. None by default.

    Returns
    -------
    table : DataFrame
        ``x, y, z, geozone, hole_id`` in mine-grid coordinates and the table's
        units; ``geozone`` carries the label noise. This is what the engine reads.
    true_labels : Series
        True geozone of every hole, indexed by ``hole_id`` (name
        ``true_geozone``); ``attrs["label_noise"]`` holds the mine's noise rate.
        Each bench's drilled area is recorded in ``mine.footprints``.
    """
    rng = np.random.default_rng(seed)
    levels = np.asarray(mine.bench_levels_m, float)
    height = float(np.median(-np.diff(levels))) if len(levels) > 1 else 10.0
    step = pit_step_m(mine.extent_m, len(levels), height)
    noise = float(rng.uniform(*label_noise_range))
    # Drawn only when asked, so that the default drilling's draws stay as they were.
    contact_noise = float(rng.uniform(*contact_noise_range)) if contact_noise_range[1] > 0 else 0.0
    pushback = np.zeros(2)
    if pushback_range_m[1] > 0:  # drawn only when asked: the default drilling's draws stay as they were
        heading = rng.uniform(0, 2 * np.pi)
        pushback = rng.uniform(*pushback_range_m) * np.array([np.cos(heading), np.sin(heading)])
    mpu = float(mine.metres_per_unit)
    frames, truths = [], []
    for k, z in enumerate(levels):
        outline = pit_outline(mine.extent_m, k, step)
        if pushback.any():  # the middle bench's pit where it was; none past the mine's extent, where its geology ends
            shifted = affinity.translate(outline, *((k - (len(levels) - 1) / 2) * pushback))
            outline = shifted.intersection(box(*mine.extent_m))
        footprint = bench_drilled_area(outline, rng, partial=k > 0 and rng.random() < partial_fraction)
        mine.footprints[float(z)] = footprint
        spacing = rng.uniform(*spacing_range_m)
        xy = drill_pattern(footprint, spacing, rng.uniform(0, np.pi), collar_scatter_spacings * spacing, rng, pattern)
        # Round as the table will be written, so the truth is that of the written holes.
        xy_table = np.round((xy + np.asarray(mine.origin)) / mpu, 2)
        xy = xy_table * mpu - np.asarray(mine.origin)
        truth = mine.label_at(xy, float(z))
        labels = _with_label_noise(truth, noise, rng)
        if contact_noise > 0:
            labels = _with_contact_noise(xy, truth, labels, contact_noise, spacing, rng)
        ids = np.array([f"B{k:02d}-{i:05d}" for i in range(len(xy))], dtype=object)
        z_holes = z + rng.uniform(-z_scatter_fraction, z_scatter_fraction, len(xy)) * height
        frames.append(
            pd.DataFrame(
                {
                    "x": xy_table[:, 0],
                    "y": xy_table[:, 1],
                    "z": np.round(z_holes / mpu, 2),
                    "geozone": labels,
                    "hole_id": ids,
                }
            )
        )
        truths.append(pd.Series(truth, index=ids))
    true_labels = pd.concat(truths).rename("true_geozone")
    true_labels.index.name = "hole_id"
    true_labels.attrs["label_noise"] = noise
    return pd.concat(frames, ignore_index=True), true_labels


#: A hole is at a contact when a hole of another true geozone lies within this many spacings.
CONTACT_SPACINGS = 1.5


def _with_contact_noise(
    xy: np.ndarray, truth: np.ndarray, labels: np.ndarray, rate: float, spacing_m: float, rng: np.random.Generator
) -> np.ndarray:
    """Labels where a share ``rate`` of the holes at a contact take their nearest other geozone's label."""
    tree = cKDTree(xy)
    pairs = tree.query_pairs(CONTACT_SPACINGS * spacing_m, output_type="ndarray")
    pairs = pairs[truth[pairs[:, 0]] != truth[pairs[:, 1]]]
    if not len(pairs):
        return labels
    both = np.concatenate([pairs, pairs[:, ::-1]])
    gap = np.linalg.norm(xy[both[:, 0]] - xy[both[:, 1]], axis=1)
    order = np.lexsort((gap, both[:, 0]))  # each hole's nearest hole of another geozone first
    first = np.unique(both[order, 0], return_index=True)[1]
    at_contact, neighbour = both[order][first].T
    flip = rng.random(len(at_contact)) < rate
    out = labels.copy()
    out[at_contact[flip]] = truth[neighbour[flip]]
    return out


def _with_label_noise(truth: np.ndarray, rate: float, rng: np.random.Generator) -> np.ndarray:
    """Labels with a share ``rate`` replaced by another geozone present on the bench (drawn uniformly)."""
    labels = truth.copy()
    flip = np.flatnonzero(rng.random(len(labels)) < rate)
    present = sorted(set(truth.tolist()))
    if len(present) < 2 or not len(flip):
        return labels
    for i in flip:
        others = [g for g in present if g != truth[i]]
        labels[i] = others[int(rng.integers(len(others)))]
    return labels
