"""Boundary extraction: labelled holes of a bench to closed geozone contours (paper section 2).

Per bench and geozone: connected components (section 2.1), boundary holes by
local entropy and gap closure (2.2-2.3), edge map synthesis (2.4), gradient
vector flow and an active contour started on the component's bounding box
(2.5). The result is one closed contour per component.

Two refinements over the paper, both for fidelity to the true boundary:

* The edge structure is drawn through the *transition* rather than through
  the boundary holes themselves: an entropy boundary hole contributes the
  midpoint to its nearest hole of another geozone, a frontier hole (gap
  closure) a point half a hole spacing out through its gap. A contour through
  the outermost holes would sit half a spacing inside the region everywhere.
* Where contours of two geozones overlap, the smaller region keeps the
  overlap: a component enclosing another geozone's component (an ore pod in
  host rock) gets it cut out as a hole, so regions on a bench never overlap.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np
import shapely
from shapely.geometry import MultiPoint, Polygon

from core.errors import Range, check_ranges
from core.extraction.boundary import (
    connected_components,
    entropy_boundary,
    gap_boundary,
    local_entropy,
    neighbour_table,
)
from core.extraction.edgemap import edge_structure, synthesize_edge_map
from core.extraction.gvf import gvf_steady_state
from core.extraction.snake import box_snake, evolve_snake
from core.geometry.grid import Grid, as_multipolygon
from core.io.blastholes import Blastholes


@dataclass(frozen=True)
class ExtractionParameters:
    """Parameters of boundary extraction; defaults from the paper (section 2, Fig. 4).

    Lengths left as ``None`` are derived from the median hole spacing ``s``.
    """

    search_radius_m: float | None = None  #: region growing and entropy radius r; default 1.6 s
    entropy_threshold: float = 0.5  #: T_entropy (section 2.2)
    gap_angle_rad: float = 2 * np.pi / 3  #: T_orient (section 2.3)
    gap_neighbours: int = 12  #: K_orient (section 2.3)
    edge_neighbours: int = 5  #: K_struct (Fig. 4)
    edge_joints: int = 4  #: K_joints (Fig. 4)
    edge_map_cells: int = 240  #: n_x ~ n_y ~ 240 (Fig. 4)
    edge_map_margin_cells: int = 8  #: p (Fig. 4)
    gvf_mu: float = 0.2  #: GVF regularisation (Xu & Prince)
    snake_alpha: float = 0.05  #: elasticity, grid units
    snake_beta: float = 0.05  #: rigidity, grid units
    snake_step: float = 1.0  #: cells per iteration at unit force
    snake_max_iterations: int = 600

    def validate(self) -> ExtractionParameters:
        """Raise :class:`core.errors.BGMInputError` naming the first parameter out of range; returns self."""
        check_ranges(self, EXTRACTION_RANGES)
        return self

    def radius_m(self, hole_spacing_m: float) -> float:
        """The search radius r actually used."""
        return self.search_radius_m if self.search_radius_m else 1.6 * hole_spacing_m


#: Valid values of each :class:`ExtractionParameters` field (grids need a few cells to hold a snake).
EXTRACTION_RANGES = {
    "search_radius_m": Range(0, low_open=True, optional=True),
    "entropy_threshold": Range(0),
    "gap_angle_rad": Range(0, 2 * np.pi, low_open=True),
    "gap_neighbours": Range(2, 1000, integer=True),
    "edge_neighbours": Range(1, 1000, integer=True),
    "edge_joints": Range(1, 1000, integer=True),
    "edge_map_cells": Range(16, 4096, integer=True),
    "edge_map_margin_cells": Range(1, 1000, integer=True),
    "gvf_mu": Range(0, 100, low_open=True),
    "snake_alpha": Range(0),
    "snake_beta": Range(0),
    "snake_step": Range(0, 100, low_open=True),
    "snake_max_iterations": Range(1, 1_000_000, integer=True),
}


@dataclass
class ExtractionFields:
    """Intermediate fields of one component, kept on request for the viewer."""

    grid: Grid
    edge_points_m: np.ndarray  #: (m, 2) where the edge structure passes
    edges: np.ndarray  #: (e, 2) index pairs into ``edge_points_m``
    edge_map: np.ndarray  #: (rows, cols) in [0, 1]
    gvf: np.ndarray  #: (2, rows, cols): x and y components
    snake_history_m: list[np.ndarray]  #: snake positions (world metres) over the iterations
    snake_iterations: int


@dataclass
class Contour:
    """Closed boundary of one connected component of a geozone on a bench."""

    geozone: str
    bench: int  #: bench index (0 = top)
    bench_z_m: float  #: bench elevation, metres
    component: int  #: component number on this bench and geozone (0 = largest)
    polygon: Polygon  #: local metres; holes where other geozones are enclosed
    holes: np.ndarray  #: indices of the component's blastholes
    entropy_holes: np.ndarray  #: boundary holes found by local entropy
    gap_holes: np.ndarray  #: boundary holes found by gap closure
    method: str = "snake"  #: "snake", or "outline" for components too small for one
    fields: ExtractionFields | None = None

    @property
    def boundary_holes(self) -> np.ndarray:
        return np.union1d(self.entropy_holes, self.gap_holes)


def extract_contours(
    holes: Blastholes,
    geozones: Iterable[str] | None = None,
    benches: Iterable[int] | None = None,
    params: ExtractionParameters | None = None,
    keep_fields: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> list[Contour]:
    """Closed contours of every component of the given geozones on the given benches.

    Parameters
    ----------
    holes : Blastholes
    geozones : iterable of str, optional
        Geozones to extract (all by default). Entropy always uses every
        geozone's holes, since boundaries are where labels change.
    benches : iterable of int, optional
        Bench indices (all by default).
    params : ExtractionParameters, optional
    keep_fields : bool
        Keep edge maps, GVF fields and snake histories (for the viewer).
    progress : callable, optional
        Called as ``progress(done, total)`` after each bench.
    """
    params = params or ExtractionParameters()
    wanted = set(holes.geozones if geozones is None else geozones)
    bench_list = list(range(holes.n_benches)) if benches is None else list(benches)
    out: list[Contour] = []
    for done, k in enumerate(bench_list, start=1):
        out.extend(extract_bench(holes, k, wanted, params, keep_fields))
        if progress:
            progress(done, len(bench_list))
    return out


def extract_bench(
    holes: Blastholes,
    bench: int,
    geozones: Iterable[str] | None = None,
    params: ExtractionParameters | None = None,
    keep_fields: bool = False,
) -> list[Contour]:
    """Contours of one bench (see :func:`extract_contours`)."""
    params = params or ExtractionParameters()
    idx = holes.on_bench(bench)
    if len(idx) == 0:
        return []
    xy = holes.xy[idx]
    labels = holes.geozone[idx]
    spacing = bench_spacing(xy, holes.hole_spacing_m)
    radius = params.radius_m(spacing)
    table = neighbour_table(xy, radius)
    entropy = local_entropy(labels, table)
    on_entropy = entropy_boundary(entropy, table, params.entropy_threshold)
    transition = _transition_points(xy, labels, table)
    wanted = set(holes.geozones if geozones is None else geozones)
    # Every geozone is extracted so enclosed regions can be cut out of their hosts.
    contours: list[Contour] = []
    for g in sorted(set(labels.tolist())):
        sel = np.flatnonzero(labels == g)
        comp = connected_components(xy[sel], radius)
        for c in range(comp.max() + 1 if len(comp) else 0):
            members = sel[comp == c]
            contours.append(
                _extract_component(
                    holes,
                    bench,
                    g,
                    c,
                    idx,
                    members,
                    on_entropy,
                    transition,
                    spacing,
                    radius,
                    params,
                    keep_fields and g in wanted,
                )
            )
    contours = _cut_enclosed(contours, holes.xy, spacing)
    return [c for c in contours if c.geozone in wanted]


#: A bench whose own hole spacing differs from the whole table's by more than
#: this factor is extracted with its own spacing (see :func:`bench_spacing`).
BENCH_SPACING_FACTOR = 2.0
#: A snake contour holding fewer of its component's holes than this gets the
#: missed holes added back (see :func:`_extract_component`).
MIN_HOLES_INSIDE = 0.9


def bench_spacing(xy: np.ndarray, table_spacing_m: float) -> float:
    """The hole spacing extraction uses on one bench.

    The table's median spacing, unless this bench is drilled on a pattern more
    than :data:`BENCH_SPACING_FACTOR` times denser or sparser (a 25 m
    exploration grid under a 3 m grade-control bench): with the table's
    spacing every hole of such a bench would be a component of its own (or a
    dense bench one blob), so the bench's own median nearest-neighbour
    distance is used. Ordinary pattern changes (5-7 m) keep the table's value.
    """
    from core.io.blastholes import median_hole_spacing

    if len(xy) < 2:
        return table_spacing_m
    own = median_hole_spacing(xy, np.zeros(len(xy), int))
    if not np.isfinite(own) or own <= 0:
        return table_spacing_m
    ratio = own / table_spacing_m
    return float(own) if ratio > BENCH_SPACING_FACTOR or ratio < 1 / BENCH_SPACING_FACTOR else table_spacing_m


def _transition_points(xy: np.ndarray, labels: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Midpoint between each hole and its nearest neighbour of another geozone (nan if none)."""
    n = len(xy)
    valid = table < n
    safe = np.where(valid, table, 0)
    other = valid & (labels[safe] != labels[:, None])
    d = np.where(other, np.hypot(*(xy[safe] - xy[:, None, :]).transpose(2, 0, 1)), np.inf)
    nearest = np.argmin(d, axis=1)
    has = np.isfinite(d[np.arange(n), nearest])
    partner = xy[safe[np.arange(n), nearest]]
    mid = 0.5 * (xy + partner)
    mid[~has] = np.nan
    return mid


def _extract_component(
    holes: Blastholes,
    bench: int,
    geozone: str,
    component: int,
    bench_idx: np.ndarray,
    members: np.ndarray,
    on_entropy: np.ndarray,
    transition: np.ndarray,
    spacing: float,
    radius: float,
    params: ExtractionParameters,
    keep_fields: bool,
) -> Contour:
    xy = holes.xy[bench_idx[members]]
    on_gap, outward = gap_boundary(xy, params.gap_angle_rad, params.gap_neighbours, 2.5 * radius)
    ent = on_entropy[members] & np.isfinite(transition[members, 0])
    # Where the boundary passes: mid-way to the other geozone, or half a spacing out through the gap.
    points = np.where(ent[:, None], transition[members], xy + 0.5 * spacing * outward)
    is_boundary = ent | on_gap
    contour = Contour(
        geozone=geozone,
        bench=bench,
        bench_z_m=float(holes.bench_levels_m[bench]),
        component=component,
        polygon=Polygon(),
        holes=bench_idx[members],
        entropy_holes=bench_idx[members[ent]],
        gap_holes=bench_idx[members[on_gap & ~ent]],
    )
    edge_points = points[is_boundary]
    if len(members) < 3 or len(edge_points) < 3:
        contour.polygon = _outline(np.vstack([xy, edge_points]), spacing)
        contour.method = "outline"
        return contour
    polygon, fields = snake_contour(edge_points, spacing, params, keep_fields, xy)
    inside = shapely.contains_xy(polygon, xy[:, 0], xy[:, 1]).mean() if not polygon.is_empty else 0.0
    if inside < 0.5:
        # The snake collapsed (e.g. a ring of boundary holes around a large gap):
        # the outline of the holes is the honest answer.
        polygon, contour.method = _outline(np.vstack([xy, edge_points]), spacing), "outline"
    elif inside < MIN_HOLES_INSIDE:
        # The snake's rigidity cut the corners of a small, ragged component
        # (single holes sticking out of it), or shrank along a single row of
        # holes (collinear drilling), and left more than a tenth of its holes
        # outside: add those holes' discs back (closed over a spacing)
        # so the contour holds its own holes. Contours that already hold 90%
        # are left exactly as the snake found them.
        missed = ~shapely.contains_xy(polygon, xy[:, 0], xy[:, 1])
        discs = shapely.buffer(MultiPoint(xy[missed]), 0.5 * spacing, quad_segs=8)
        merged = polygon.union(discs).buffer(0.5 * spacing, quad_segs=8).buffer(-0.5 * spacing, quad_segs=8)
        polygon = _largest_polygon(merged)
    contour.polygon = polygon
    contour.fields = fields
    return contour


def snake_contour(
    edge_points_m: np.ndarray,
    hole_spacing_m: float,
    params: ExtractionParameters,
    keep_fields: bool = False,
    component_xy_m: np.ndarray | None = None,
) -> tuple[Polygon, ExtractionFields | None]:
    """Edge map, GVF and active contour for one component's boundary points (sections 2.4-2.5).

    Parameters
    ----------
    edge_points_m : (m, 2) float
        Where the boundary passes, metres.
    hole_spacing_m : float
        Median hole spacing; sets the edge lengths and the finest cell size.
    params : ExtractionParameters
    keep_fields : bool
    component_xy_m : (n, 2) float, optional
        The component's holes: the edge map keeps only the outline of the
        edge structure filled around them (see :func:`synthesize_edge_map`).

    Returns
    -------
    polygon : shapely Polygon
        The converged snake as a valid polygon (local metres).
    fields : ExtractionFields or None
    """
    lo, hi = edge_points_m.min(axis=0), edge_points_m.max(axis=0)
    grid = Grid.for_extent(
        (lo[0], lo[1], hi[0], hi[1]),
        cells_across=params.edge_map_cells,
        margin_cells=params.edge_map_margin_cells,
        min_cell_size_m=hole_spacing_m / 8.0,
    )
    edges = edge_structure(
        edge_points_m, 2.5 * hole_spacing_m, params.edge_neighbours, params.edge_joints, 4.0 * hole_spacing_m
    )
    f = synthesize_edge_map(grid, edge_points_m, edges, component_xy_m, 0.5 * hole_spacing_m)
    field = gvf_steady_state(f, params.gvf_mu)
    rc = grid.xy_to_rc(edge_points_m)
    pad = 3.0
    rows, cols = grid.shape
    rc_min = np.maximum(rc.min(axis=0) - pad, 0)
    rc_max = np.minimum(rc.max(axis=0) + pad, [rows - 1, cols - 1])
    perimeter = 2 * np.sum(rc_max - rc_min)
    n_points = int(np.clip(perimeter / 1.5, 48, 480))
    snake, history, iterations = evolve_snake(
        box_snake(rc_min, rc_max, n_points),
        field,
        alpha=params.snake_alpha,
        beta=params.snake_beta,
        step=params.snake_step,
        max_iterations=params.snake_max_iterations,
        keep_history=keep_fields,
    )
    polygon = _largest_polygon(shapely.make_valid(Polygon(grid.rc_to_xy(snake))))
    fields = None
    if keep_fields:
        fields = ExtractionFields(
            grid=grid,
            edge_points_m=edge_points_m,
            edges=edges,
            edge_map=f,
            gvf=field,
            snake_history_m=[grid.rc_to_xy(s) for s in history],
            snake_iterations=iterations,
        )
    return polygon, fields


def _largest_polygon(geometry) -> Polygon:
    parts = list(as_multipolygon(geometry).geoms)
    if not parts:
        return Polygon()
    return shapely.geometry.polygon.orient(max(parts, key=lambda p: p.area))


def _part_with_most(geometry, xy: np.ndarray) -> Polygon:
    """The polygon of ``geometry`` holding most of the points ``xy`` (ties: the largest)."""
    parts = list(as_multipolygon(geometry).geoms)
    if not parts:
        return Polygon()
    best = max(parts, key=lambda q: (int(shapely.contains_xy(q, xy[:, 0], xy[:, 1]).sum()), q.area))
    return shapely.geometry.polygon.orient(best)


def _outline(points: np.ndarray, spacing: float) -> Polygon:
    """Outline of a handful of holes: their discs of half a spacing, closed over gaps of a spacing."""
    discs = shapely.buffer(MultiPoint(points), 0.5 * spacing, quad_segs=8)
    closed = discs.buffer(0.5 * spacing, quad_segs=8).buffer(-0.5 * spacing, quad_segs=8)
    return _largest_polygon(closed)


def _cut_enclosed(  # noqa: C901 - to be split into named steps
    contours: list[Contour], holes_xy: np.ndarray | None = None, spacing: float | None = None
) -> list[Contour]:
    """Resolve overlaps between geozones on a bench: the smaller region wins.

    A region enclosed by a larger one (a pod in host rock) becomes a hole in
    it; one that overlaps the edge of a larger one (a body at the drilling
    frontier) is cut from it, so regions on a bench never overlap.

    With ``holes_xy`` and ``spacing``, when the cut would leave the larger
    contour holding less than :data:`MIN_HOLES_INSIDE` of its holes because
    the smaller regions' contours overreach its holes along their common
    boundary (holes of the larger component inside a smaller region, within
    half a spacing of its edge), those holes' discs (0.4 spacing) stay with the
    larger region and are taken out of the smaller ones. Holes deep inside a
    smaller region (mislabelled assays in a pod) still go with it; contours
    that keep 90% of their holes are cut exactly as before.
    """
    polys = [c.polygon for c in contours]
    tree = shapely.STRtree(polys)
    keep_out = [[] for _ in contours]  # discs given back to a larger neighbour, per smaller contour
    cutters: list[list[int]] = []
    for i, c in enumerate(contours):
        p = polys[i]
        cut = []
        if not p.is_empty:
            for j in tree.query(p):
                q = polys[j]
                if j == i or contours[j].geozone == c.geozone or q.is_empty or q.area >= p.area:
                    continue
                if p.intersects(q):
                    cut.append(j)
        cutters.append(cut)
        if not cut or holes_xy is None or not spacing:
            continue
        own = holes_xy[c.holes]
        inside = shapely.contains_xy(p, own[:, 0], own[:, 1])
        lost = [shapely.contains_xy(polys[j], own[:, 0], own[:, 1]) & inside for j in cut]
        if (inside & ~np.any(lost, axis=0)).mean() >= MIN_HOLES_INSIDE:
            continue  # the cut leaves this contour holding 90% of its holes: as before
        for j, lost_j in zip(cut, lost):
            if lost_j.any():
                pts = own[lost_j]
                near = shapely.distance(polys[j].boundary, shapely.points(pts)) < 0.5 * spacing
                if near.any():
                    keep_out[j].append(shapely.buffer(MultiPoint(pts[near]), 0.4 * spacing, quad_segs=8))
    # The smaller regions first lose the discs they overreached into ...
    shrunk = list(polys)
    for j, discs in enumerate(keep_out):
        if discs:
            shrunk[j] = _largest_polygon(polys[j].difference(shapely.union_all(discs)))
    # ... then are cut out of the larger ones.
    out = []
    for i, c in enumerate(contours):
        p = polys[i]
        if cutters[i]:
            p = p.difference(shapely.union_all([shrunk[j] for j in cutters[i]]))
            # A smaller region across it may split it: keep the part holding
            # most of the component's holes (the largest one when unknown).
            p = _largest_polygon(p) if holes_xy is None else _part_with_most(p, holes_xy[c.holes])
        if p is not polys[i] or shrunk[i] is not polys[i]:
            p = p if not keep_out[i] else _largest_polygon(p.difference(shapely.union_all(keep_out[i])))
            c = replace(c, polygon=p)
        out.append(c)
    return out
