"""The per-geozone pipeline: contours -> bench pairs -> correspondence -> metamorphosis.

Each stage lives in its own module; this one chains them for one geozone and
converts results to the input's coordinates for the command line. For every
pair of successive benches the upper bench's components are the *sources* and
the lower bench's the *targets* (paper section 3).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely import affinity

from core.correspondence.pair import MorphInstance, PairCorrespondence, correspond_pair
from core.extraction.contours import Contour
from core.io.blastholes import Blastholes
from core.model.extrapolation import assimilated
from core.model.fields import BenchFields, bench_fields
from core.model.parameters import ModelParameters
from core.morph.levelset import MorphResult, morph_regions
from core.morph.trajectories import trajectory_xyz

__all__ = [
    "BenchPair",
    "GeozoneModel",
    "ModelParameters",
    "MorphStep",
    "bench_pairs",
    "correspond",
    "correspondence_json",
    "geozone_fields",
    "model_geozone",
    "modelled_contours",
    "morph",
    "morph_instance",
    "morph_json",
    "pair_coverage",
]


@dataclass
class MorphStep:
    """One morph instance of a bench pair: a target group and the sources that become it."""

    instance: MorphInstance
    result: MorphResult


@dataclass
class BenchPair:
    """Two successive benches of one geozone and what links them."""

    geozone: str
    upper: int
    lower: int
    source_z_m: float
    target_z_m: float
    sources: list[Contour]
    targets: list[Contour]
    correspondence: PairCorrespondence | None = None
    morphs: list[MorphStep] = field(default_factory=list)

    def aligned_source(self, i: int):
        """Source ``i`` moved by its estimated translation (local metres)."""
        if self.correspondence is None:
            raise ValueError("the pair has no correspondence yet")
        dx, dy = self.correspondence.translations[i]
        return affinity.translate(self.sources[i].polygon, dx, dy)


@dataclass
class GeozoneModel:
    """Everything the model knows about one geozone."""

    geozone: str
    contours: list[Contour]
    pairs: list[BenchPair]
    #: Components too small to model between benches (see ``min_component_holes``);
    #: predictions hold them in place near their bench.
    minor: list[Contour] = field(default_factory=list)
    #: Signed distances to the geozone's boundary on every bench of the table
    #: (see :mod:`core.model.extrapolation`): what predictions below the
    #: deepest bench are extrapolated from.
    fields: BenchFields | None = None

    def region_at_bench(self, bench: int):
        """Union of the geozone's contours on a bench (local metres)."""
        polys = [c.polygon for c in self.contours if c.bench == bench and not c.polygon.is_empty]
        return shapely.union_all(polys) if polys else shapely.Polygon()


def modelled_contours(contours: list[Contour], geozone: str, bench: int, min_component_holes: int = 1) -> list[Contour]:
    """The geozone's contours on a bench that take part in the model, by component number.

    Their positions in this list are the source (target) indices of the
    bench pair below (above) the bench, as project overrides name them.
    """
    own = (c for c in contours if c.geozone == geozone and c.bench == bench and len(c.holes) >= min_component_holes)
    return sorted(own, key=lambda c: c.component)


def bench_pairs(
    holes: Blastholes, contours: list[Contour], geozone: str, min_component_holes: int = 1
) -> list[BenchPair]:
    """Successive bench pairs where the geozone is on at least one of the two benches."""
    own = [c for c in contours if c.geozone == geozone]
    pairs = []
    for k in range(holes.n_benches - 1):
        sources = modelled_contours(own, geozone, k, min_component_holes)
        targets = modelled_contours(own, geozone, k + 1, min_component_holes)
        if not sources and not targets:
            continue
        pairs.append(
            BenchPair(
                geozone=geozone,
                upper=k,
                lower=k + 1,
                source_z_m=float(holes.bench_levels_m[k]),
                target_z_m=float(holes.bench_levels_m[k + 1]),
                sources=sources,
                targets=targets,
            )
        )
    return pairs


def correspond(
    pair: BenchPair,
    holes: Blastholes,
    params: ModelParameters | None = None,
    overrides: tuple[dict, set, set] | None = None,
    keep_fields: bool = False,
) -> PairCorrespondence:
    """Associate and align the pair's sources with its targets (paper section 3).

    ``overrides`` is ``(locked_translations_in_input_units, forced, forbidden)``
    as :func:`core.io.project.overrides_for` returns it.
    """
    params = params or ModelParameters()
    locked, forced, forbidden = overrides or ({}, set(), set())
    locked_m = {int(i): tuple(holes.frame.length_to_local(np.asarray(v, float))) for i, v in locked.items()}
    pair.correspondence = correspond_pair(
        [c.polygon for c in pair.sources],
        [c.polygon for c in pair.targets],
        hole_spacing_m=holes.hole_spacing_m,
        mu_lower_m=params.mu_lower_m,
        cell_size_m=params.correspondence_cell_size_m,
        locked_translations=locked_m,
        forced=set(forced),
        forbidden=set(forbidden),
        keep_fields=keep_fields,
    )
    return pair.correspondence


def morph(
    pair: BenchPair,
    params: ModelParameters | None = None,
    keep_fronts: bool = False,
    hole_spacing_m: float | None = None,
) -> list[MorphStep]:
    """Morph every instance of a corresponded pair (paper section 4); see :func:`morph_instance`."""
    if pair.correspondence is None:
        raise ValueError("morph needs the pair's correspondence first")
    pair.morphs = [
        morph_instance(pair, inst, params, keep_fronts, hole_spacing_m) for inst in pair.correspondence.instances
    ]
    return pair.morphs


def morph_instance(
    pair: BenchPair,
    instance: MorphInstance,
    params: ModelParameters | None = None,
    keep_fronts: bool = False,
    hole_spacing_m: float | None = None,
) -> MorphStep:
    """Morph one instance of a corresponded pair: its aligned sources into its targets.

    With ``hole_spacing_m`` the level-set cells are never finer than a
    quarter of it: contours cannot be placed more finely than the holes
    allow, and a small pod on a 256-cell grid would cost as much as a pit.
    """
    params = params or ModelParameters()
    sources = [pair.aligned_source(i) for i in instance.source_ids]
    targets = [pair.targets[j].polygon for j in instance.target_ids]
    cell = None
    if hole_spacing_m:
        xmin, ymin, xmax, ymax = shapely.union_all([*sources, *targets]).bounds
        cell = max(max(xmax - xmin, ymax - ymin) / params.morph_max_cells, hole_spacing_m / 4)
    result = morph_regions(
        sources,
        targets,
        cell_size_m=cell,
        speed_clamp_m=params.speed_clamp_m,
        keep_fronts=keep_fronts,
        max_cells=params.morph_max_cells,
    )
    return MorphStep(instance, result)


def model_geozone(
    holes: Blastholes,
    geozone: str,
    *,
    contours: list[Contour] | None = None,
    params: ModelParameters | None = None,
    project=None,
    stages: tuple[str, ...] = ("correspond", "morph"),
    keep_fields: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> GeozoneModel:
    """Run the pipeline for one geozone up to the requested stages.

    A one-off :class:`core.model.session.ModelSession` (no disk cache):
    commands and the viewer that run more than once keep a session instead.

    Parameters
    ----------
    holes : Blastholes
    geozone : str
    contours : list of Contour, optional
        Contours already extracted (any geozones); extracted when omitted.
    params : ModelParameters, optional
    project : core.io.project.Project, optional
        Manual overrides (locked translations, forced/forbidden associations)
        applied on every run.
    stages : tuple of str
        ``"correspond"`` and/or ``"morph"``.
    keep_fields : bool
        Keep intermediate fields for the viewer.
    progress : callable, optional
        ``progress(done, total)`` over bench pairs.
    """
    from core.model.session import ModelSession  # the session orchestrates this module's stages

    session = ModelSession(holes, params or ModelParameters(), project)
    return session.geozone_model(geozone, contours=contours, stages=stages, keep_fields=keep_fields, progress=progress)


def geozone_fields(holes: Blastholes, contours: list[Contour], reach_spacings: float) -> BenchFields:
    """The geozone's :class:`BenchFields` on every bench of the table, from its contours and the holes.

    The grid covers the holes with cells of half a hole spacing (at most
    :data:`FIELD_MAX_CELLS` squared); a bench's drilled area is the raster
    form of :meth:`Blastholes.drilled_area`. Drilled cells nearer one of the
    geozone's own holes than any other hole are no evidence past the drilled
    area where its contours leave them out (``unclaimed``, :func:`bench_distance`).
    Each bench's signed distance is then drawn towards its prediction from the
    benches above (:func:`assimilated`).
    """
    from core.extraction.transition import drilled_mask, hole_distances
    from core.geometry.grid import Grid, cell_size_within

    spacing = holes.hole_spacing_m
    lo, hi = holes.xy.min(axis=0), holes.xy.max(axis=0)
    width, height = hi - lo
    cell = cell_size_within(width, height, FIELD_CELL_SPACINGS * spacing, FIELD_MAX_CELLS)
    grid = Grid.covering((lo[0], lo[1], hi[0], hi[1]), cell, margin_cells=8)
    geozone = contours[0].geozone if contours else None
    regions, drilled, z, unclaimed = {}, {}, {}, {}
    for k in np.unique(holes.bench[holes.bench >= 0]):  # benches with holes: an empty level says nothing
        on = holes.on_bench(k)
        polys = [c.polygon for c in contours if c.bench == k and not c.polygon.is_empty]
        regions[k] = shapely.union_all(polys) if polys else shapely.MultiPolygon()
        z[k] = float(holes.bench_levels_m[k])
        mine = holes.geozone[on] == geozone
        nearest = hole_distances(holes.xy[on], np.full(len(on), "hole"), ["hole"], grid)[0]
        drilled[k] = drilled_mask(nearest, spacing, cell)
        # Cells nearer one of the geozone's holes than any other's (those outside its contours are its fringe).
        own = hole_distances(holes.xy[on], np.where(mine, "own", ""), ["own"], grid)[0] if mine.any() else np.inf
        unclaimed[k] = drilled[k] & (own <= nearest + 1e-9)
    fields = bench_fields(regions, drilled, z, grid, spacing, reach_spacings * spacing, unclaimed)
    return assimilated(fields, fields.bench_height_m, spacing)


#: Cell size of a geozone's field grid, in hole spacings (a quarter gained 0.3 F1 on the
#: synthetic tuning seeds but lost 1.2 on the real Kennecott benches).
FIELD_CELL_SPACINGS = 0.5
#: A geozone's field grid holds at most this many cells squared.
FIELD_MAX_CELLS = 600


# ---------------------------------------------------------------------------
# JSON in the input's coordinates


def _component_dict(i: int, contour: Contour, holes: Blastholes) -> dict:
    poly = contour.polygon
    c = holes.frame.to_input(np.array([[poly.centroid.x, poly.centroid.y]]))[0]
    mpu = holes.frame.metres_per_unit
    return {
        "id": i,
        "component": int(contour.component),
        "centroid": [float(c[0]), float(c[1])],
        "area": float(poly.area / mpu**2),
        "holes": int(len(contour.holes)),
    }


def correspondence_json(model: GeozoneModel, holes: Blastholes) -> dict:
    """``bgm correspond`` output: association matrix and translations per bench pair."""
    pairs = []
    for p in model.pairs:
        corr = p.correspondence
        if corr is None:
            raise ValueError(f"bench pair {p.upper}-{p.lower} of {model.geozone} has no correspondence yet")
        pairs.append(
            {
                "source_z": holes.bench_z_input(p.upper),
                "target_z": holes.bench_z_input(p.lower),
                "sources": [_component_dict(i, c, holes) for i, c in enumerate(p.sources)],
                "targets": [_component_dict(j, c, holes) for j, c in enumerate(p.targets)],
                "association": corr.association.astype(int).tolist(),
                "translations": holes.frame.length_to_input(corr.translations).reshape(-1, 2).tolist(),
                "instances": [
                    {"sources": list(map(int, m.source_ids)), "targets": list(map(int, m.target_ids))}
                    for m in corr.instances
                ],
            }
        )
    return {"geozone": model.geozone, "units": holes.frame.length_unit, "pairs": pairs}


def pair_coverage(pair: BenchPair) -> tuple[float, float]:
    """Target-boundary coverage of a pair (after, before backtracking), weighted by boundary length."""
    weights, after, before = [], [], []
    for step in pair.morphs:
        length = step.result.target.length
        if length <= 0:
            continue
        weights.append(length)
        after.append(step.result.target_boundary_coverage)
        before.append(step.result.coverage_before_backtracking)
    if not weights:
        return float("nan"), float("nan")
    w = np.asarray(weights)
    return float(np.dot(w, after) / w.sum()), float(np.dot(w, before) / w.sum())


def morph_json(model: GeozoneModel, holes: Blastholes, decimals: int = 3) -> dict:
    """``bgm morph`` output: coverage and 3D trajectories per bench pair, input coordinates."""
    pairs = []
    for p in model.pairs:
        after, before = pair_coverage(p)
        trajectories, backtracked = [], []
        for step in p.morphs:
            for traj in step.result.trajectories:
                xyz = trajectory_xyz(traj, p.source_z_m, p.target_z_m)
                xy = holes.frame.to_input(xyz[:, :2])
                z = holes.frame.z_to_input(xyz[:, 2])
                trajectories.append(np.round(np.column_stack([xy, z]), decimals).tolist())
                backtracked.append(bool(traj.backtracked))
        pairs.append(
            {
                "source_z": holes.bench_z_input(p.upper),
                "target_z": holes.bench_z_input(p.lower),
                "target_boundary_coverage": _finite(after),
                "coverage_before_backtracking": _finite(before),
                "instances": [
                    {
                        "sources": list(map(int, s.instance.source_ids)),
                        "targets": list(map(int, s.instance.target_ids)),
                        "iou": _finite(s.result.iou),
                        "trajectories": len(s.result.trajectories),
                    }
                    for s in p.morphs
                ],
                "backtracked": backtracked,
                "trajectories": trajectories,
            }
        )
    return {"geozone": model.geozone, "units": holes.frame.length_unit, "pairs": pairs}


def _finite(v: float) -> float | None:
    return None if v is None or not np.isfinite(v) else round(float(v), 4)
