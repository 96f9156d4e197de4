"""Contour prediction: a geozone's region at any elevation (paper section 4.1, Results).

Between two benches the region comes from the normalised particle
trajectories of the pair's morphs: a point at normalised arc length ``f`` of
a trajectory, minus the part ``(1 - f) m`` of its source's translation not
yet made, lies on the iso-contour at ``z_source + f (z_target - z_source)``
(translation plus local deformation, the paper's "displacement estimates").
Points are ordered along the source contour they started from.

Below the deepest bench (and above the top one) there is no next section to
morph to: the region is extrapolated from the depth trend of the signed
distance to the geozone's boundary (:mod:`core.model.extrapolation`), which
carries on the movement across the boundary that the benches measured and
holds where they show none. It is the trajectories' movement less its part
along the boundary, which no bench determines.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import LinearRing, MultiPolygon, Polygon

from core.geometry.grid import as_multipolygon
from core.geometry.sdf import boundary_distance
from core.io.blastholes import Blastholes
from core.model.extrapolation import depth_trend, depth_trend_region
from core.model.fields import BenchFields, memoised
from core.model.new_ground import (
    KnownHoles,
    known_holes,
    switched_ground,
    with_deepest_level_joined,
    with_implicit_above_deepest,
    with_implicit_in_new_ground,
    with_implicit_in_older_ground,
    with_implicit_in_stale_ground,
)
from core.model.pipeline import BenchPair, GeozoneModel, MorphStep
from core.model.progress import Stages
from core.morph.trajectories import normalised_arc_length
from core.threads import Progress


def _point_at(xy: np.ndarray, s: np.ndarray, f: float) -> np.ndarray:
    return np.array([np.interp(f, s, xy[:, 0]), np.interp(f, s, xy[:, 1])])


def _translations_for(pair: BenchPair, step: MorphStep, points: np.ndarray) -> np.ndarray:
    """Translation of the nearest aligned source of each point (zero for a pod that appears)."""
    ids = list(step.instance.source_ids)
    if not ids:
        return np.zeros_like(points)
    if len(ids) == 1:
        return np.repeat(pair.correspondence.translations[ids[0]][None, :], len(points), axis=0)  # type: ignore[union-attr]  # set by correspond() before use
    aligned = [pair.aligned_source(i) for i in ids]
    d = np.stack([boundary_distance(a, points[:, 0], points[:, 1]) for a in aligned])
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
    return regions_between(pair, [fraction])[0]


def regions_between(pair: BenchPair, fractions: list[float]) -> list[MultiPolygon]:
    """:func:`region_between` at each of ``fractions``.

    What does not depend on the fraction (each trajectory's source translation and arc length, their order
    along the source rings they started from) is found once for all of them: the surface's sections between
    two benches are several fractions of one pair.
    """
    tracks = []  # per morph step: its trajectories, their arc lengths, translations and rings' point order
    base = 0
    resolution = 0.0
    for step in pair.morphs:
        trajs = [t for t in step.result.trajectories if len(t.xy) >= 1]
        if not trajs:
            continue
        # Order points along the ring of the (aligned) source they started from.
        start_aligned = np.array([t.xy[0] for t in trajs])
        shift = _translations_for(pair, step, start_aligned)
        source_rings = _rings(step.result.source)
        if not source_rings:
            continue
        dist = np.stack([shapely.distance(r, shapely.points(start_aligned)) for _, _, r in source_rings])
        which = np.argmin(dist, axis=0)
        ordered = []  # per source ring: its id, whether a hole, and its trajectories in order along it
        for ri, (k, is_hole, ring) in enumerate(source_rings):
            sel = np.flatnonzero(which == ri)
            if len(sel) < 3:
                continue
            order = np.argsort(shapely.line_locate_point(ring, shapely.points(start_aligned[sel])))
            ordered.append((base + k, is_hole, sel[order]))
        tracks.append((trajs, [normalised_arc_length(t) for t in trajs], shift, ordered))
        base += len(as_multipolygon(step.result.source).geoms)
        resolution = max(resolution, 0.5 * step.result.grid.cell_size_m)
    out = []
    for fraction in fractions:
        f = float(np.clip(fraction, 0.0, 1.0))
        rings: list[tuple[int, bool, np.ndarray]] = []
        for trajs, lengths, shift, order in tracks:
            points = np.array([_point_at(t.xy, s, f) for t, s in zip(trajs, lengths)]) - (1 - f) * shift
            rings.extend((k, is_hole, points[idx]) for k, is_hole, idx in order)
        out.append(_assemble(rings, resolution))
    return out


def bench_at(levels, z_m: float) -> int | None:
    """The index of the bench whose level ``z_m`` is (metres), or None: where a section is that bench's contours.

    ``np.isclose`` with its relative tolerance (1e-5 of ``z_m``: 6 mm at 625 m), as
    :func:`core.model.uncertainty.directions` tells a bench level from a predicted one
    (no uncertainty there); callers refusing bench levels must match the same way.
    """
    at = np.flatnonzero(np.isclose(np.asarray(levels, float), z_m, atol=1e-6))
    return int(at[0]) if len(at) else None


def undrilled_extension(model: GeozoneModel, z_m: float, hole_spacing_m: float) -> MultiPolygon:
    """The geozone's depth trend at ``z_m`` where benches above drilled and no bench at or below ``z_m`` did.

    There a known bench's contour ends at its drilling edge, no boundary. The
    trend is the one :func:`predict_geozone` extrapolates below the deepest
    bench (:func:`core.model.extrapolation.depth_trend` of the geozone's
    fields): it carries each cell on from the deepest bench that drilled it,
    and ends it where that evidence has likely run out. The ground drilled below is
    taken half a spacing in from its edge (a contour ends about that short of
    it, and the trend closes the seam) and bounded by signed distances, so the
    extension's edge there is smooth, not the raster's steps. Empty at and
    below the deepest bench.
    """
    fields = model.fields
    if fields is None or not len(fields.z_m):
        return MultiPolygon()
    at_or_below = fields.z_m <= z_m + 1e-6 + 1e-5 * abs(z_m)  # a bench level matched as bench_at does
    if at_or_below.all() or not at_or_below.any():
        return MultiPolygon()
    # The bound depends only on which benches lie at or below: made once for all sections between two benches.
    n_below = int(at_or_below.sum())
    # At the deepest bench's level the trend reaches past every bench's drilling, as it does below it: a bench
    # drilled over part of the pit (its first blast patterns) lost there the ground past the bench above's
    # drilling that the benches above alone predicted (see core.model.movement.reaching_bench).
    deepest = n_below == 1 and bench_at(fields.z_m, z_m) == len(fields.z_m) - 1
    bound = memoised(
        fields,
        ("undrilled bound", len(fields.z_m), hole_spacing_m, n_below, deepest),
        lambda: _undrilled_bound(fields, n_below, hole_spacing_m, beyond_drilling=deepest),
    )
    if bound is None:
        return MultiPolygon()

    def compute() -> MultiPolygon:
        field = np.minimum(depth_trend(fields, fields.bench_height_m, hole_spacing_m).field(z_m), bound)
        return as_multipolygon(fields.grid.polygons_from_distance(field)) if (field > 0).any() else MultiPolygon()

    # The surface and a prediction at the same elevation ask for the same extension.
    key = ("undrilled extension", len(fields.z_m), fields.bench_height_m, hole_spacing_m, float(z_m))
    return memoised(fields, key, compute)


def between_drillings(model: GeozoneModel, z_m: float, hole_spacing_m: float) -> MultiPolygon:
    """The geozone at a bench's level in the ground a bench above and a bench below drilled and it did not.

    Several benches are drilled at once, each over weeks: a table of one moment can hold the bench below
    drilled where the bench itself is not yet. There its contours end at its drilling edge, which is no
    boundary, and :func:`undrilled_extension` stops where a bench below drilled: every geozone was absent
    from that ground at the bench's level, between benches that both showed it (Kennecott cut at its
    hole numbers' median: 26 F1 on such holes, holding the benches above 68, this 78). Each cell's signed distance
    is interpolated in depth between the deepest bench above and the shallowest bench below that drilled
    it, as their holes showed them (:meth:`core.model.fields.BenchFields.measured`), half a spacing into
    the bench's own drilling (closing the seam, as the extension does) and no further than both
    drillings. Empty off the benches' levels, at the top and deepest benches, and where no such ground is.
    With the known holes :func:`with_undrilled_ground` takes the implicit model's section there instead (on
    such Kennecott holes this 78.2 F1, the implicit model 83.4): this is the section without them.
    """
    fields = model.fields
    k = None if fields is None else bench_at(fields.z_m, z_m)
    if fields is None or k is None or k == 0 or k == len(fields.z_m) - 1:
        return MultiPolygon()
    drilled = fields.drilled
    above, below = np.any(drilled[:k], axis=0), np.any(drilled[k + 1 :], axis=0)
    if not (above & below & ~drilled[k]).any():
        return MultiPolygon()

    def compute() -> MultiPolygon:
        distance = fields.measured().distance
        upper = k - 1 - np.argmax(drilled[k - 1 :: -1], axis=0)  # the deepest bench above that drilled the cell
        lower = k + 1 + np.argmax(drilled[k + 1 :], axis=0)  # the shallowest below
        rows, cols = np.indices(upper.shape)
        f_upper, f_lower = distance[upper, rows, cols], distance[lower, rows, cols]
        t = (fields.z_m[upper] - z_m) / (fields.z_m[upper] - fields.z_m[lower])
        h = fields.grid.cell_size_m

        bound = np.minimum.reduce(
            [0.5 * hole_spacing_m - _inside_m(drilled[k], h), _inside_m(above, h), _inside_m(below, h)]
        )
        field = np.minimum(f_upper + t * (f_lower - f_upper), bound)
        return as_multipolygon(fields.grid.polygons_from_distance(field)) if (field > 0).any() else MultiPolygon()

    return memoised(fields, ("between drillings", len(fields.z_m), hole_spacing_m, float(z_m)), compute)


def with_undrilled_extension(region, model: GeozoneModel, z_m: float, hole_spacing_m: float) -> MultiPolygon:
    """``region`` (a section at ``z_m``) with the geozone's :func:`undrilled_extension` there, less its slivers.

    At a bench's level, with :func:`between_drillings` as well.

    The extension reaches half a spacing into the ground the benches below
    drilled, to close the seam where a bench's contour ends short of its
    drilling edge. Where that bench drilled and found none of the geozone at
    its edge, the strip held slivers of the trend alone: a geozone absent
    from the deepest bench was "predicted" there as five parts of 0.8 m² in
    all. A part of the extension that touches no part of ``region`` and
    covers less than one hole's share of the ground (a spacing squared) is no
    body the holes could show, and is left out.
    """
    extension = as_multipolygon(
        shapely.union(undrilled_extension(model, z_m, hole_spacing_m), between_drillings(model, z_m, hole_spacing_m))
    )
    if extension.is_empty:
        return as_multipolygon(region)
    near = region.buffer(0.25 * hole_spacing_m) if not region.is_empty else region
    kept = [p for p in extension.geoms if p.area >= hole_spacing_m**2 or p.intersects(near)]
    return as_multipolygon(region.union(MultiPolygon(kept)))


def with_undrilled_ground(
    region, model: GeozoneModel, z_m: float, hole_spacing_m: float, known: KnownHoles | None
) -> MultiPolygon:
    """``region`` (a section at ``z_m``) completed where the benches at or below ``z_m`` did not drill.

    :func:`with_undrilled_extension` there; with the known benches' ``known`` holes, above the deepest bench's
    level the ground the bench at or above ``z_m`` did not drill (a pushback, ground only benches below drilled,
    ground the benches above drilled and it has not yet) takes the implicit model's section
    (:func:`core.model.new_ground.with_implicit_above_deepest`), and at the deepest bench's level the ground no
    bench drilled takes it where the geozone's pushbacks chose it, as below the deepest bench
    (:func:`core.model.new_ground.with_implicit_in_new_ground`), and the ground only benches two or more above
    it drilled takes it (:func:`core.model.new_ground.with_implicit_in_stale_ground`). A bench drilled over part of
    the pit (its first blast patterns) is the deepest: without this its undrilled rest was the depth trend's
    alone, and lost what the implicit model gave one bench below the bench above.
    """
    region = with_undrilled_extension(region, model, z_m, hole_spacing_m)
    fields = model.fields
    if known is None or fields is None:
        return region
    if bench_at(fields.z_m, z_m) != len(fields.z_m) - 1:
        return with_implicit_above_deepest(region, fields, known, z_m, hole_spacing_m)
    region = with_implicit_in_new_ground(region, fields, known, z_m, fields.bench_height_m, hole_spacing_m)
    return with_implicit_in_stale_ground(region, fields, known, z_m)


def _undrilled_bound(
    fields: BenchFields, n_below: int, hole_spacing_m: float, beyond_drilling: bool = False
) -> np.ndarray | None:
    """Where :func:`undrilled_extension` may reach, as a signed distance: inside what the upper benches drilled
    (anywhere, ``beyond_drilling``), outside what the lowest ``n_below`` benches drilled (half a spacing in from
    its edge); None if nowhere."""
    below = fields.drilled[-n_below:].any(axis=0)
    above = fields.drilled[:-n_below].any(axis=0)
    if not (above & ~below).any():
        return None
    h = fields.grid.cell_size_m
    outside_below = _inside_m(~below, h)
    if beyond_drilling:
        return outside_below + 0.5 * hole_spacing_m
    return np.minimum(outside_below + 0.5 * hole_spacing_m, _inside_m(above, h))


def _inside_m(mask, cell_size_m: float) -> np.ndarray:
    """Signed distance into ``mask`` (metres): positive inside, negative outside."""
    return (ndimage.distance_transform_edt(mask) - ndimage.distance_transform_edt(~mask)) * cell_size_m


def predict_geozone(
    model: GeozoneModel,
    z_m: list[float],
    hole_spacing_m: float,
    params=None,
    progress: Progress | None = None,
    holes: Blastholes | None = None,
) -> dict[float, MultiPolygon]:
    """The geozone's region at each elevation (metres): at, between, below or above the benches.

    At a bench level the bench's own contours are returned; between two
    benches of a modelled pair :func:`region_between` (empty between benches
    where the geozone is on neither); at and between benches, with the depth
    trend in ground the bench(es) below did not drill (:func:`undrilled_extension`,
    what the surface holds there); below the deepest bench of the table
    (above the top one) the depth trend of :mod:`core.model.extrapolation`
    over every bench, so a geozone that pinched out above the deepest bench is
    predicted absent below it. ``hole_spacing_m`` sets the trend's
    neighbourhoods (the transport's smoothing, the distance cap); ``params``
    is unused (kept for callers). With the table's ``holes`` (the known benches'), at and below the deepest bench
    the ground no known bench drilled takes the implicit model's section where the geozone's own benches chose it
    (:func:`core.model.new_ground.with_implicit_in_new_ground`), below it the ground only benches two or more
    above the deepest drilled takes it where the trend let that evidence go
    (:func:`core.model.new_ground.with_implicit_in_stale_ground`), and within a bench below it the ground that
    takes another model than at its level passes from the one to the other
    (:func:`core.model.new_ground.with_deepest_level_joined`); above it the ground the bench at or above
    the elevation did not drill takes it (:func:`with_undrilled_ground`); without them, the depth trend's throughout.

    ``progress(done, total)`` is told, as one series that never goes back
    (:class:`core.model.progress.Stages`), each step of the depth trend's
    backtests the first time it is needed (:func:`depth_trend`), then each
    elevation predicted: below the
    deepest bench a large geozone takes seconds (Kennecott's 3026: 1-6 s), and
    a :class:`core.threads.Cancelled` it raises stops the prediction at that
    step, nothing of it returned.
    """
    fields = model.fields
    pairs = [p for p in model.pairs if p.correspondence is not None]
    out: dict[float, MultiPolygon] = {}
    if fields is None or not len(fields.z_m):
        return {z: MultiPolygon() for z in z_m}
    levels = fields.z_m
    height = fields.bench_height_m
    beyond: dict[bool, BenchFields] = {}  # the fields extrapolated down (True) or up, one view each
    deepest_section = None  # the section at the deepest bench's level, made once when needed below it
    # The holes of the benches the fields know: the implicit model's, in new ground below the deepest bench.
    known = None if holes is None else known_holes(holes, model.geozone).down_to(float(levels[-1]))
    # The depth trend's backtests (made at the first elevation off the benches), then the elevations: told as one
    # series that never goes back, not the elevations' 1 of 4 between the backtests' 5 of 6.
    stages = Stages(progress, 2)
    trend_progress, progress = stages.stage(0), stages.stage(1)
    for z in z_m:
        at = bench_at(levels, z)
        if at is not None:
            out[z] = with_undrilled_ground(model.region_at_bench(at), model, z, hole_spacing_m, known)
        elif z < levels[-1] or z > levels[0]:
            down = bool(z < levels[-1])
            if down not in beyond:
                beyond[down] = fields if down else fields.reversed()
            out[z] = depth_trend_region(beyond[down], height, hole_spacing_m, z, trend_progress)
            if down and known is not None:
                out[z] = with_implicit_in_new_ground(out[z], fields, known, z, height, hole_spacing_m)
                out[z] = with_implicit_in_older_ground(out[z], fields, known, z, height, hole_spacing_m)
                ended = depth_trend(fields, height, hole_spacing_m).ended(z)
                out[z] = with_implicit_in_stale_ground(out[z], fields, known, z, ended)
                if z > levels[-1] - height:  # within a bench below: a passage where the ground takes another model
                    if deepest_section is None:
                        deepest_section = with_undrilled_ground(
                            model.region_at_bench(len(levels) - 1), model, float(levels[-1]), hole_spacing_m, known
                        )
                    switched = switched_ground(fields, known, ended, height, hole_spacing_m)
                    out[z] = with_deepest_level_joined(out[z], deepest_section, fields, switched, z, hole_spacing_m)
        else:
            pair = next((p for p in pairs if p.target_z_m <= z <= p.source_z_m), None)
            region = MultiPolygon()
            if pair is not None:
                region = region_between(pair, (pair.source_z_m - z) / (pair.source_z_m - pair.target_z_m))
            out[z] = with_undrilled_ground(region, model, z, hole_spacing_m, known)
        if progress:
            progress(len(out), len(z_m))
    return out
