"""Contour prediction: a geozone's region at any elevation (paper section 4.1, Results).

Between two benches the region comes from the normalised particle
trajectories of the pair's morphs: a point at normalised arc length ``f`` of
a trajectory, minus the part ``(1 - f) m`` of its source's translation not
yet made, lies on the iso-contour at ``z_source + f (z_target - z_source)``
(translation plus local deformation, the paper's "displacement estimates").
Points are ordered along the source contour they started from.

Below the deepest bench (and above the top one) the last (first) pair's
movement is continued: every trajectory carries a displacement (its physical
end minus its physical start); the displacement is spread along the deepest
contour by inverse-distance weighting of the nearest trajectory ends and
smoothed along the contour, and the contour moves by ``f`` times it for a
depth of ``f`` bench heights. Smoothing along the contour keeps neighbouring
points moving alike, so the extrapolated contour does not fold; the result is
repaired to valid polygons in any case. How much of the movement is carried
on is learnt from the geozone's own benches (:func:`persistence_coefficient`),
and the region is joined with the geozone's continuation past the bench's
drilling frontier (:func:`core.model.pipeline.beyond_frontiers`).
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.ndimage import uniform_filter1d
from scipy.spatial import cKDTree
from shapely.geometry import LinearRing, MultiPolygon, Polygon

from core.geometry.grid import as_multipolygon
from core.model.pipeline import BenchPair, GeozoneModel, MorphStep
from core.morph.trajectories import normalised_arc_length


def _point_at(xy: np.ndarray, s: np.ndarray, f: float) -> np.ndarray:
    return np.array([np.interp(f, s, xy[:, 0]), np.interp(f, s, xy[:, 1])])


def _step_tracks(pair: BenchPair, step: MorphStep) -> tuple[np.ndarray, np.ndarray, list]:
    """Physical start, physical end and the trajectories of one morph instance.

    Each trajectory starts on one aligned source; its translation ``m`` is
    that source's. Physical start = aligned start - m.
    """
    trajs = [t for t in step.result.trajectories if len(t.xy) >= 1]
    if not trajs:
        return np.zeros((0, 2)), np.zeros((0, 2)), []
    starts = np.array([t.xy[0] for t in trajs])
    ends = np.array([t.xy[-1] for t in trajs])
    shift = _translations_for(pair, step, starts)
    return starts - shift, ends, trajs


def _translations_for(pair: BenchPair, step: MorphStep, points: np.ndarray) -> np.ndarray:
    """Translation of the nearest aligned source of each point (zero for a pod that appears)."""
    ids = list(step.instance.source_ids)
    if not ids:
        return np.zeros_like(points)
    if len(ids) == 1:
        return np.repeat(pair.correspondence.translations[ids[0]][None, :], len(points), axis=0)  # type: ignore[union-attr]  # set by correspond() before use
    aligned = [pair.aligned_source(i) for i in ids]
    d = np.stack([shapely.distance(a.boundary, shapely.points(points)) for a in aligned])
    return pair.correspondence.translations[np.array(ids)[np.argmin(d, axis=0)]]  # type: ignore[union-attr]  # set by correspond() before use


def _rings(region) -> list[tuple[int, bool, LinearRing]]:
    """``(polygon index, is_hole, ring)`` of every ring of a region."""
    out = []
    for k, poly in enumerate(as_multipolygon(region).geoms):
        out.append((k, False, poly.exterior))
        out.extend((k, True, r) for r in poly.interiors)
    return out


def _assemble(rings: list[tuple[int, bool, np.ndarray]], resolution_m: float = 0.0) -> MultiPolygon:
    """Polygons from moved rings: exteriors minus their holes, repaired to validity.

    Rings are first simplified to ``resolution_m`` (the grid they came from
    cannot place them more finely); repairing a dense, folded ring costs far
    more than repairing its simplified outline.
    """
    by_poly: dict[int, tuple[list, list]] = {}
    for k, is_hole, pts in rings:
        if len(pts) < 3:
            continue
        ring = Polygon(pts)
        if resolution_m > 0:
            ring = shapely.simplify(ring, resolution_m, preserve_topology=False)
        if ring.is_empty:
            continue
        poly = shapely.make_valid(ring)
        by_poly.setdefault(k, ([], []))[1 if is_hole else 0].append(poly)
    parts = []
    for outer, holes in by_poly.values():
        if not outer:
            continue
        region = shapely.union_all(outer)
        if holes:
            region = region.difference(shapely.union_all(holes))
        parts.append(region)
    if not parts:
        return MultiPolygon()
    return as_multipolygon(shapely.union_all(parts).buffer(0))


def region_between(pair: BenchPair, fraction: float) -> MultiPolygon:
    """The geozone's region a fraction ``f`` of the way from the upper to the lower bench.

    Parameters
    ----------
    pair : BenchPair
        With correspondence and morphs computed.
    fraction : float
        0 at the upper bench, 1 at the lower bench.
    """
    f = float(np.clip(fraction, 0.0, 1.0))
    rings = []
    base = 0
    resolution = 0.0
    for step in pair.morphs:
        starts_phys, _, trajs = _step_tracks(pair, step)
        if not trajs:
            continue
        shift = _translations_for(pair, step, np.array([t.xy[0] for t in trajs]))
        points = np.array([_point_at(t.xy, normalised_arc_length(t), f) for t in trajs]) - (1 - f) * shift
        # Order points along the ring of the (aligned) source they started from.
        start_aligned = np.array([t.xy[0] for t in trajs])
        source_rings = _rings(step.result.source)
        if not source_rings:
            continue
        dist = np.stack([shapely.distance(r, shapely.points(start_aligned)) for _, _, r in source_rings])
        which = np.argmin(dist, axis=0)
        for ri, (k, is_hole, ring) in enumerate(source_rings):
            sel = np.flatnonzero(which == ri)
            if len(sel) < 3:
                continue
            order = np.argsort(shapely.line_locate_point(ring, shapely.points(start_aligned[sel])))
            rings.append((base + k, is_hole, points[sel[order]]))
        base += len(as_multipolygon(step.result.source).geoms)
        resolution = max(resolution, 0.5 * step.result.grid.cell_size_m)
    return _assemble(rings, resolution)


def _moved_rings(
    region,
    anchors: np.ndarray,
    displacement: np.ndarray,
    fraction: float,
    spacing_m: float,
    smoothing_m: float,
    frontier=None,
    hold_m: float = 0.0,
) -> list[tuple[int, bool, np.ndarray]]:
    """Rings of ``region`` moved by ``fraction`` times the displacement field given at ``anchors``.

    Points on the drilling ``frontier`` stay where they are and points within
    ``hold_m`` of it move proportionally less: there the contour marks where
    sampling stopped, and its bench-to-bench change is the pit's, not the
    geozone's.
    """
    out: list[tuple[int, bool, np.ndarray]] = []
    if len(anchors) == 0:
        return out
    tree = cKDTree(anchors)
    k = min(4, len(anchors))
    for poly_index, is_hole, ring in _rings(region):
        n = max(int(np.ceil(ring.length / spacing_m)), 8)
        pts = np.array([ring.interpolate(d).coords[0] for d in np.linspace(0, ring.length, n, endpoint=False)])
        dist, idx = tree.query(pts, k=k)
        dist, idx = dist.reshape(n, k), idx.reshape(n, k)
        w = 1.0 / np.maximum(dist, 1e-6) ** 2
        disp = np.einsum("nk,nkd->nd", w, displacement[idx]) / w.sum(axis=1, keepdims=True)
        window = int(np.clip(round(smoothing_m / spacing_m), 1, n))
        if window > 1:
            disp = uniform_filter1d(disp, size=window, axis=0, mode="wrap")
        if frontier is not None and not frontier.is_empty and hold_m > 0:
            near = shapely.distance(frontier, shapely.points(pts))
            disp *= np.clip(near / hold_m, 0.0, 1.0)[:, None]
        out.append((poly_index, is_hole, pts + fraction * disp))
    return out


def pair_movements(pair: BenchPair) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Physical start (upper bench), end (lower bench) and displacement of every trajectory of a pair.

    All ``(n, 2)`` local metres; the displacement is the end minus the
    physical start (the source's translation plus the local deformation).
    """
    starts, ends = [], []
    for step in pair.morphs or []:
        s, e, trajs = _step_tracks(pair, step)
        if trajs:
            starts.append(s)
            ends.append(e)
    if not starts:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2))
    starts, ends = np.concatenate(starts), np.concatenate(ends)
    return starts, ends, ends - starts


def persistence_coefficient(pairs: list[BenchPair], hole_spacing_m: float, no_history: float = 0.5) -> float:
    """How much of a bench pair's movement the next pair repeats, learnt from the geozone's own benches.

    For every two successive pairs ``(j-1, j)`` and ``(j, j+1)`` the
    trajectories of the lower pair that start where one of the upper pair
    ended (within a hole spacing) give a movement ``d_j`` and the movement
    before it, ``d_j-1``. The least-squares coefficient of
    ``d_j ~ beta d_j-1`` over all of them, clipped to [0, 1], is how far
    extrapolation below the deepest bench should carry the last movement: 1
    for a boundary that dips steadily (the paper's displacement estimate), 0
    where bench-to-bench movement is shape noise that does not repeat (then
    holding the last bench is the best guess). With fewer than two pairs
    there is nothing to learn from and ``no_history`` is returned: 0.5, half
    the paper's full extrapolation, is the guess whose worst error over the
    possible coefficients in [0, 1] is smallest.

    Measured (see ``tests/benchmarks/bench_prediction.py``): 0.6-0.95 for the
    synthetic dipping and splitting bodies, 0 for pods, 0-0.4 for the real
    Kennecott domains, whose 50 ft benches change shape far more than they
    drift.
    """
    num = den = 0.0
    usable = [p for p in pairs if p.morphs]
    for upper, lower in zip(usable, usable[1:]):
        if upper.lower != lower.upper:
            continue
        _, ends, before = pair_movements(upper)
        starts, _, after = pair_movements(lower)
        if len(ends) == 0 or len(starts) == 0:
            continue
        dist, idx = cKDTree(ends).query(starts)
        near = dist <= hole_spacing_m
        num += float((before[idx[near]] * after[near]).sum())
        den += float((before[idx[near]] ** 2).sum())
    if den <= 0:
        return no_history
    return float(np.clip(num / den, 0.0, 1.0))


def region_beyond(
    pair: BenchPair,
    fraction: float,
    hole_spacing_m: float,
    downward: bool = True,
    smoothing_spacings: float = 10.0,
    deformation_weight: float = 1.0,
    frontier=None,
    translation_weight: float = 1.0,
    persistence: float = 1.0,
) -> MultiPolygon:
    """Extrapolate the pair's movement beyond its lower (or above its upper) bench.

    Parameters
    ----------
    pair : BenchPair
        The deepest (``downward``) or the top (not ``downward``) pair.
    fraction : float
        Distance beyond the bench, in bench heights (0.5 = half a bench).
    hole_spacing_m : float
        Sets the contour sampling (a quarter spacing) and the smoothing of the
        displacement along the contour (three spacings).
    downward : bool
        Continue below the lower bench (True) or above the upper bench.
    smoothing_spacings : float
        Window, in hole spacings, over which displacements are averaged along
        the contour: wider than the contour's own jitter (about a spacing,
        from where boundary holes happen to fall), narrower than real changes
        of shape. 10 spacings measured best on synthetic mines (3 and 6 gave
        lower precision and recall at 5-10 m).
    deformation_weight : float
        Weight of the local deformation relative to the rigid translation
        (1 = the paper's displacement estimate). Lower values damp shape
        change, which helps pods that pinch out but hurts splitting bodies.
    frontier : shapely line, optional
        Outline of the bench's drilled area: contour points on it are held
        (see :func:`_moved_rings`).
    translation_weight : float
        Weight of the rigid translation.
    persistence : float
        Fraction of the movement carried on below the deepest bench (see
        :func:`persistence_coefficient`); 1 is the paper's displacement estimate.
    """
    rings: list[tuple[int, bool, np.ndarray]] = []
    base = 0
    for step in pair.morphs:
        if downward and not step.instance.target_ids:
            continue  # pinched out between the benches: nothing continues below
        if not downward and not step.instance.source_ids:
            continue  # appeared between the benches: nothing above
        starts_phys, ends, trajs = _step_tracks(pair, step)
        if not trajs:
            continue
        # Rigid translation of the component plus its local deformation.
        aligned_starts = np.array([t.xy[0] for t in trajs])
        translation = aligned_starts - starts_phys
        deformation = ends - aligned_starts
        displacement = translation_weight * translation + deformation_weight * deformation
        displacement *= persistence
        if downward:
            region = shapely.union_all([pair.targets[j].polygon for j in step.instance.target_ids])
            anchors, sign = ends, 1.0
        else:
            region = shapely.union_all([pair.sources[i].polygon for i in step.instance.source_ids])
            anchors, sign = starts_phys, -1.0
        moved = _moved_rings(
            region,
            anchors,
            sign * displacement,
            fraction,
            hole_spacing_m / 4,
            smoothing_spacings * hole_spacing_m,
            frontier,
            hole_spacing_m,
        )
        rings.extend((base + k, h, p) for k, h, p in moved)
        base += len(as_multipolygon(region).geoms)
    return _assemble(rings, hole_spacing_m / 8)


def predict_geozone(
    model: GeozoneModel, z_m: list[float], hole_spacing_m: float, params=None
) -> dict[float, MultiPolygon]:
    """The geozone's region at each elevation (metres): above, between or below the benches.

    At a bench level the bench's own contours are returned; between benches
    :func:`region_between`; below the deepest (above the top) bench of the
    model :func:`region_beyond` from the deepest (top) pair, carrying the
    movement on as far as the geozone's own benches say it persists
    (:func:`persistence_coefficient`), joined with the geozone's continuation
    past that bench's drilling frontier (``model.beyond_frontier``).
    """
    from core.model.pipeline import ModelParameters

    params = params or ModelParameters()
    extra = {
        "smoothing_spacings": params.smoothing_spacings,
        "deformation_weight": params.deformation_weight,
        "translation_weight": params.translation_weight,
    }
    pairs = [p for p in model.pairs if p.correspondence is not None and p.morphs is not None]
    out: dict[float, MultiPolygon] = {}
    if not pairs:
        for z in z_m:
            out[z] = MultiPolygon()
        return out
    top, bottom = pairs[0], pairs[-1]
    persistence = persistence_coefficient(pairs, hole_spacing_m)
    for z in z_m:
        exact = [b for b in {p.upper for p in pairs} | {p.lower for p in pairs} if abs(_bench_z(pairs, b) - z) < 1e-6]
        if exact:
            out[z] = as_multipolygon(model.region_at_bench(exact[0]))
        elif z < bottom.target_z_m:
            height = bottom.source_z_m - bottom.target_z_m
            moved = region_beyond(
                bottom,
                (bottom.target_z_m - z) / height,
                hole_spacing_m,
                True,
                **extra,
                frontier=model.frontiers.get(bottom.lower),
                persistence=persistence,
            )
            out[z] = _with_continuation(moved, model.beyond_frontier.get(bottom.lower))
        elif z > top.source_z_m:
            height = top.source_z_m - top.target_z_m
            moved = region_beyond(
                top,
                (z - top.source_z_m) / height,
                hole_spacing_m,
                False,
                **extra,
                frontier=model.frontiers.get(top.upper),
                persistence=persistence,
            )
            out[z] = _with_continuation(moved, model.beyond_frontier.get(top.upper))
        else:
            pair = next(p for p in pairs if p.target_z_m <= z <= p.source_z_m)
            f = (pair.source_z_m - z) / (pair.source_z_m - pair.target_z_m)
            out[z] = region_between(pair, f)
    return out


def _with_continuation(region, continuation) -> MultiPolygon:
    if continuation is None or continuation.is_empty:
        return as_multipolygon(region)
    return as_multipolygon(shapely.union_all([region, continuation]).buffer(0))


def _bench_z(pairs: list[BenchPair], bench: int) -> float:
    for p in pairs:
        if p.upper == bench:
            return p.source_z_m
        if p.lower == bench:
            return p.target_z_m
    return float("nan")
