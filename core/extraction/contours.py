"""Boundary extraction: labelled holes of a bench to closed geozone contours (paper section 2).

Per bench:

1. label noise (:mod:`core.extraction.noise`): holes in components of one or
   two holes surrounded by other geozones are taken as mislabelled and
   counted with the geozone around them (reported on the contour that holds
   them, never a contour of their own), and on a bench whose contacts are
   noisy, holes there that their neighbours outvote take the vote's geozone;
2. connected components (section 2.1), boundary holes by local entropy and
   gap closure (sections 2.2-2.3);
3. the transition field (:mod:`core.extraction.transition`): where each
   geozone's boundary passes, half-way between holes of different geozones
   and at the drilling frontier, smoothed over about a hole spacing; it
   partitions the drilled area among the geozones, and every hole's own
   surroundings (:data:`OWN_HOLE_SPACINGS`) stay with its geozone;
4. per connected part of a geozone's region: the edge map (section 2.4, the
   ridge along the part's boundary where boundary holes found one), its
   gradient vector flow (Appendix A, one sparse solve) and the active contour
   (section 2.5), which closes in on the boundary from the part's outline
   offset outward by a hole spacing;
5. the contour is the snake, less the regions of other geozones, so regions
   on a bench do not overlap and enclosed bodies are holes in their host,
   smoothed of its waver between the holes with no hole changing side
   (:func:`smoothed_contour`; a part too small for a snake keeps its
   outline); a contour holding less than its holes' share
   of the bench is then offset out to it (a lens of a few holes, by a
   fraction of a spacing into its host).

Departures from the paper, each measured on synthetic mines with known
sections (``tests/benchmarks/bench_extraction.py``):

* The edge map is the transition line rather than segments joining boundary
  holes to their ``K_struct`` nearest neighbours: across a strip one to three
  holes wide those segments join both sides and fill it, and the snake then
  has nothing to find (IoU of such strips 0.68 with the segments).
* The snake starts on the part's outline offset outward, not on its bounding
  box: a box around a strip that crosses the pit diagonally holds mostly
  other geozones, and the snake cannot find its way into the strip.
* The converged snake is put on the crest of its edge map (:func:`onto_crest`):
  the GVF of a curved ridge stops it inside the crest, and pods lost 8% of
  their area to it (median IoU of pods 0.714 -> 0.743 on tuning seeds 0-11,
  every other family within 0.003). The other geozones' regions are cut off
  it along their field's zero set, not their cells' staircase.
* The contour is smoothed over up to a hole spacing, its curvature kept
  (:func:`smoothed_contour`, as the model smooths the section it carries on):
  it runs between holes and wavers about the boundary by a fraction of a
  spacing. Near a hole the smoothing would put on the other side, it is
  smoothed less (area-weighted bench IoU of every family 0.943 -> 0.952 on
  development seeds 0-1; :data:`CONTOUR_SMOOTHING_SPACINGS`).
* A contour encloses at least its holes' share of the bench (the cells
  nearer them than any other hole, :func:`at_least_its_share`): smoothing the
  transition field over a spacing shrank lenses of 3-5 holes to 0.73 of their
  true area (median IoU of pods 0.732 -> 0.746 on tuning seeds 0-11, strips,
  splits and mix 0.000-0.001 higher on seeds 0-5).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy import ndimage
from scipy.spatial import cKDTree
from shapely.geometry import MultiPolygon, Polygon
from skimage.measure import find_contours

from core.errors import Range, check_ranges
from core.extraction.boundary import entropy_boundary, gap_boundary, local_entropy, neighbour_table
from core.extraction.gvf import gvf_steady_state
from core.extraction.noise import FIRST_RING_SPACINGS, absorbed_labels, contact_votes, isolated_holes
from core.extraction.snake import evolve_snake, resample_closed
from core.extraction.transition import TransitionField, bench_grid, edge_map, nearest_hole, transition_field
from core.geometry.grid import Grid, as_multipolygon, cells_covering
from core.geometry.sdf import region_signed_distance, signed_distance, smoothed_sections
from core.io.blastholes import Blastholes, median_hole_spacing
from core.threads import Progress, on_threads

#: Cells within this many hole spacings of a hole belong to the hole's geozone,
#: whatever the smoothed field says: a contour holds its own holes.
OWN_HOLE_SPACINGS = 0.4
#: A snake contour must hold this share of its part's holes, or the part's outline is used.
MIN_HOLES_INSIDE = 0.95
#: The snake starts this many hole spacings outside its part's outline.
SNAKE_START_SPACINGS = 1.0
#: Each contour is smoothed of its waver between holes over these many hole spacings, the widest
#: that keeps every hole of the bench on its side where it does (:func:`smoothed_contour`), as the
#: model smooths the deepest section it carries on; the other geozones' regions it is cut by again
#: are smoothed the same way. Straight contacts through a staggered pattern lie 0.12 spacings from
#: the true line (root mean square, 24 draws); 0.15 smoothed over half a spacing everywhere with the
#: other geozones cut off unsmoothed (the round before), which put their waver back. On development seeds 0-1 of
#: every family, area-weighted bench IoU against the true sections 0.943 -> 0.952 (seeds 2-5:
#: 0.951 -> 0.958; 6-10% label noise 0.927 -> 0.936, 9-12 m patterns 0.900 -> 0.904, holes off the
#: pattern 0.935 -> 0.943, square patterns 0.941 -> 0.949). Widest 1.5 spacings: the same IoU within
#: 0.002 and straight contacts 0.11, but a straight edge within 2-4 spacings of a corner moved out by
#: 0.12 spacings (the curvature the corner loses, put back along the edge); widest 3 spacings less
#: (pods -0.006); half a spacing alone, with the others smoothed: 0.948.
CONTOUR_SMOOTHING_SPACINGS = (1.0, 0.75, 0.5)
#: Within this many hole spacings of a hole the smoothing would move across the contour, it steps
#: to the next narrower scale (then to 3/4, 1/2, 1/4 of the narrowest and none), elsewhere it stays.
SMOOTHING_STEP_BACK_SPACINGS = 1.5


@dataclass(frozen=True)
class ExtractionParameters:
    """Parameters of boundary extraction; defaults from the paper (section 2, Fig. 4) or measured.

    Lengths left as ``None`` are derived from the median hole spacing ``s``.
    """

    search_radius_m: float | None = None  #: region growing and entropy radius r; default 1.6 s
    entropy_threshold: float = 0.5  #: T_entropy (section 2.2)
    gap_angle_rad: float = 2 * np.pi / 3  #: T_orient (section 2.3)
    gap_neighbours: int = 12  #: K_orient (section 2.3)
    #: Smoothing of the transition line, in hole spacings (see :mod:`core.extraction.transition`).
    smoothing_spacings: float = 0.75
    #: Keep components of one or two holes surrounded by other geozones (see
    #: :mod:`core.extraction.noise`); by default they are taken as label noise.
    keep_isolated_holes: bool = False
    edge_map_cells: int = 240  #: n_x ~ n_y ~ 240 (Fig. 4): most cells across a component's grid
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
    "smoothing_spacings": Range(0, 10),
    "edge_map_cells": Range(16, 4096, integer=True),
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
    edge_points_m: np.ndarray  #: (m, 2) where the boundary holes put the boundary
    edges: np.ndarray  #: (e, 2) index pairs into ``edge_points_m`` (none: the edge map is the transition line)
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
    #: Holes labelled as another geozone, inside the contour, taken as label noise
    #: (see :mod:`core.extraction.noise`); not in ``holes``.
    isolated_holes: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

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
    """Closed contours of every component of the given geozones on the given benches, in bench order.

    The benches are traced several at once (:func:`traced_benches`).

    Parameters
    ----------
    holes : Blastholes
    geozones : iterable of str, optional
        Geozones to extract (all by default). Every geozone's holes are used,
        since boundaries are where labels change.
    benches : iterable of int, optional
        Bench indices (all by default).
    params : ExtractionParameters, optional
    keep_fields : bool
        Keep edge maps, GVF fields and snake histories (for the viewer).
    progress : callable, optional
        Called as ``progress(done, total)`` after each bench.
    """
    bench_list = list(range(holes.n_benches)) if benches is None else list(benches)
    by_bench: dict[int, list[Contour]] = {}
    for done, (k, contours) in enumerate(traced_benches(holes, bench_list, geozones, params, keep_fields), start=1):
        by_bench[k] = contours
        if progress:
            progress(done, len(bench_list))
    return [c for k in bench_list for c in by_bench[k]]


def traced_benches(
    holes: Blastholes,
    benches: Iterable[int],
    geozones: Iterable[str] | None = None,
    params: ExtractionParameters | None = None,
    keep_fields: bool = False,
    threads: int | None = None,
) -> Iterator[tuple[int, list[Contour]]]:
    """``(bench, contours)`` of each bench (:func:`extract_bench`) as it is traced, several benches at once.

    A bench's contours depend on its own holes only, and the heavy steps of
    extraction (the GVF's sparse factorisation, distance transforms,
    Gaussian filters, shapely's vectorised predicates) release the GIL, so
    benches are traced on ``threads`` threads (default: one per available
    core) and come in the order they finish: the demo's seven benches in
    2.0 s instead of 3.7 s on two cores, Kennecott's in 6.7 s instead of 10.2.
    """
    wanted = None if geozones is None else list(geozones)  # read by every thread: not a one-pass iterator
    return on_threads(lambda k: extract_bench(holes, k, wanted, params, keep_fields), benches, threads)


def bench_spacing(xy: np.ndarray, table_spacing_m: float) -> float:
    """The hole spacing extraction uses on one bench: the bench's own (:func:`median_hole_spacing`).

    Patterns change from bench to bench (5 to 7 m on one pit, a 25 m
    exploration grid under a 3 m grade-control bench). Every length of
    extraction is in spacings of the pattern the bench was drilled on: with
    the table's median on a bench drilled 1.15 times sparser, the first ring
    of the label-noise test (:data:`core.extraction.noise.FIRST_RING_SPACINGS`)
    held two of a hole's six neighbours, single mislabelled holes were no
    longer surrounded and each became a contour (on the tuning seeds: 54
    contours per pods mine instead of 33, the 90th percentile of other
    geozones' holes inside a pods contour 52% instead of 6%). The table's
    spacing is kept for a bench of fewer than two holes.
    """
    if len(xy) < 2:
        return table_spacing_m
    own = median_hole_spacing(xy)
    return float(own) if np.isfinite(own) and own > 0 else table_spacing_m


@dataclass
class BenchEvidence:
    """What one bench's holes say about its boundaries, shared by all its components."""

    bench_idx: np.ndarray  #: indices (into the table) of the bench's holes
    xy: np.ndarray  #: their positions
    labels: np.ndarray  #: geozones as used (label noise absorbed)
    isolated: np.ndarray  #: (n,) bool: taken as label noise
    on_entropy: np.ndarray  #: (n,) bool: boundary holes by local entropy
    spacing_m: float
    transition: TransitionField
    parts: dict[str, np.ndarray]  #: geozone -> raster of its connected parts (0 = not it)
    nearest_hole: np.ndarray  #: (rows, cols) int: the bench hole nearest each cell (its share of the bench)


def bench_evidence(holes: Blastholes, bench: int, params: ExtractionParameters) -> BenchEvidence | None:
    """Label noise, boundary holes and the transition field of one bench (steps 1-3 of the module)."""
    idx = holes.on_bench(bench)
    if len(idx) == 0:
        return None
    xy = holes.xy[idx]
    spacing = bench_spacing(xy, holes.hole_spacing_m)
    radius = params.radius_m(spacing)
    given = holes.geozone[idx]
    if params.keep_isolated_holes:
        isolated, voted = np.zeros(len(idx), bool), given
    else:
        isolated = isolated_holes(xy, given, spacing, radius)
        voted = contact_votes(xy, given, spacing, radius, isolated)
    labels = absorbed_labels(xy, voted, isolated)
    isolated = isolated | (voted != given)  # the contacts' mislabels are label noise too
    table = neighbour_table(xy, radius)
    on_entropy = entropy_boundary(local_entropy(labels, table), table, params.entropy_threshold)
    grid = bench_grid(xy, spacing)
    transition = transition_field(xy, labels, spacing, grid, params.smoothing_spacings * spacing)
    _claim_own_cells(transition, xy, labels, spacing)
    parts = {g: ndimage.label(transition.label == i)[0] for i, g in enumerate(transition.geozones)}
    nearest = nearest_hole(xy, grid)
    return BenchEvidence(idx, xy, labels, isolated, on_entropy, spacing, transition, parts, nearest)


def at_least_its_share(
    polygon: Polygon, share_m2: float, bench_xy: np.ndarray | None = None, passes: int = 2
) -> Polygon:
    """``polygon`` offset outwards until it encloses ``share_m2`` (unchanged if it already does).

    Each pass offsets by the missing area over the perimeter (exact for a
    straight boundary, a little short on a convex one). The offset takes in
    none of the holes ``bench_xy`` outside ``polygon``: each keeps a bite
    reaching back to the polygon (the missing area is mostly at the drilling's
    edge, and a contour hugging its holes within the offset would otherwise be
    pushed past holes of another geozone).
    """
    grown = polygon
    for _ in range(passes):
        if grown.is_empty or grown.area >= share_m2:
            break
        grown = _largest_polygon(grown.buffer((share_m2 - grown.area) / grown.length, quad_segs=8))
    if bench_xy is None or grown is polygon:
        return grown
    points = shapely.points(bench_xy)
    taken = shapely.contains(grown, points) & ~shapely.contains(polygon, points)
    if not taken.any():
        return grown
    reach = np.maximum(shapely.distance(polygon, points[taken]), 1e-6)  # a hole on the contour stays out too
    return _largest_polygon(grown.difference(shapely.union_all(shapely.buffer(points[taken], reach, quad_segs=8))))


def _claim_own_cells(transition: TransitionField, xy: np.ndarray, labels: np.ndarray, spacing_m: float) -> None:
    """Give each hole's surroundings, and the way to its first-ring neighbours of its geozone, to its geozone.

    Cells within :data:`OWN_HOLE_SPACINGS` of a hole, or of the segment to a
    neighbour of the same geozone in the first ring of the pattern, take the
    hole's geozone (in place) where their nearest hole is of it: a contour
    holds its own holes, and a connected component (section 2.1) stays one
    region where smoothing thinned it.
    """
    holes = cKDTree(xy)
    pairs = holes.query_pairs(FIRST_RING_SPACINGS * spacing_m, output_type="ndarray")
    pairs = pairs[labels[pairs[:, 0]] == labels[pairs[:, 1]]]
    t = np.linspace(0.0, 1.0, 5)[1:-1]
    along = xy[pairs[:, 0], None, :] + t[None, :, None] * (xy[pairs[:, 1]] - xy[pairs[:, 0]])[:, None, :]
    points = np.vstack([xy, along.reshape(-1, 2)])
    owner = np.concatenate([labels, np.repeat(labels[pairs[:, 0]], len(t))])
    X, Y = transition.grid.cell_centres()
    radius = OWN_HOLE_SPACINGS * spacing_m
    cells = np.column_stack([X.ravel(), Y.ravel()])
    dist, nearest = cKDTree(points).query(cells, distance_upper_bound=radius)
    near = np.flatnonzero(np.isfinite(dist))
    # The chord between two host holes around a pod would otherwise cut into the pod's half of the way.
    closest = holes.query(cells[near])[1]
    near = near[labels[closest] == owner[nearest[near]]]
    code = {g: i for i, g in enumerate(transition.geozones)}
    flat = transition.label.ravel()
    flat[near] = np.array([code[g] for g in owner])[nearest[near]]
    transition.label = flat.reshape(transition.grid.shape)


def extract_bench(
    holes: Blastholes,
    bench: int,
    geozones: Iterable[str] | None = None,
    params: ExtractionParameters | None = None,
    keep_fields: bool = False,
    progress: Progress | None = None,
) -> list[Contour]:
    """Contours of one bench (see :func:`extract_contours`).

    ``progress(done, total)`` is told as the bench's evidence is found (``0``)
    and as each part's contour is traced (its edge map, GVF and snake: a
    Kennecott bench holds 20-40 parts, 0.1-0.9 s each); raising
    :class:`core.threads.Cancelled` there stops the bench at that part, and
    nothing of it is returned. Within a part it is told the parts done again
    at each of the part's own steps (its GVF solved, every few of the snake's
    iterations, each step of its smoothing), so a large part stops there too.
    """
    params = params or ExtractionParameters()
    ev = bench_evidence(holes, bench, params)
    if ev is None:
        return []
    wanted = set(holes.geozones if geozones is None else geozones)
    # Every part is found before any is traced, so the count told is the bench's whole.
    traces = [
        trace
        for g in ev.transition.geozones
        if g in wanted
        for trace in _geozone_parts(holes, bench, g, ev, params, keep_fields)
    ]
    if progress:
        progress(0, len(traces))
    contours: list[Contour] = []
    for trace in traces:
        # Told the same count within the part: no part more is done, but the caller may stop it there.
        within = functools.partial(progress, len(contours), len(traces)) if progress else None
        contours.append(trace(within))
        if progress:
            progress(len(contours), len(traces))
    return contours


def _geozone_parts(
    holes: Blastholes, bench: int, geozone: str, ev: BenchEvidence, params: ExtractionParameters, keep_fields: bool
) -> list[Callable[[Callable[[], None] | None], Contour]]:
    """The tracing of each connected part of the geozone's region that holds its holes, largest first.

    One call a part gives its contour (:func:`_part_contour`, given its ``check``),
    so the caller can tell its progress between parts.
    """
    parts = ev.parts[geozone]
    grid = ev.transition.grid
    own = np.flatnonzero(ev.labels == geozone)
    rc = grid.nearest_cells(ev.xy[own])
    part_of = _nearest_part(parts, rc)
    ids, counts = np.unique(part_of[part_of > 0], return_counts=True)
    order = ids[np.argsort(-counts, kind="stable")]
    radius = params.radius_m(ev.spacing_m)
    gap_local = np.zeros(len(ev.xy), bool)
    sel = own
    if len(sel):
        gap_local[sel] = gap_boundary(ev.xy[sel], params.gap_angle_rad, params.gap_neighbours, 2.5 * radius)[0]
    i = ev.transition.geozones.index(geozone)
    return [
        functools.partial(
            _part_contour,
            holes,
            bench,
            geozone,
            number,
            ev,
            i,
            parts == part,
            own[part_of == part],
            gap_local,
            params,
            keep_fields,
        )
        for number, part in enumerate(order)
    ]


def _part_contour(
    holes: Blastholes,
    bench: int,
    geozone: str,
    number: int,
    ev: BenchEvidence,
    i: int,
    mask: np.ndarray,
    members: np.ndarray,
    gap_local: np.ndarray,
    params: ExtractionParameters,
    keep_fields: bool,
    check: Callable[[], None] | None = None,
) -> Contour:
    """Edge map, GVF and snake of one part (steps 4-5 of the module).

    ``check()`` is called between the part's steps (:func:`snake_contour`'s,
    :func:`smoothed_contour`'s); a :class:`core.threads.Cancelled` it raises
    stops the part there.
    """
    window, (rs, cs) = _window(ev.transition.grid, mask, (SNAKE_START_SPACINGS + 2.0) * ev.spacing_m)
    outline = window.polygons_from_mask(mask[rs, cs])
    boundary = ev.on_entropy[members] | gap_local[members]
    contour = Contour(
        geozone=geozone,
        bench=bench,
        bench_z_m=float(holes.bench_levels_m[bench]),
        component=number,
        polygon=Polygon(),
        holes=ev.bench_idx[members[~ev.isolated[members]]],
        entropy_holes=ev.bench_idx[members[ev.on_entropy[members]]],
        gap_holes=ev.bench_idx[members[gap_local[members] & ~ev.on_entropy[members]]],
        isolated_holes=ev.bench_idx[members[ev.isolated[members]]],
    )
    polygon = Polygon()
    xy = ev.xy[members]
    others_field, claimed = _others_and_claimed(ev, i, rs, cs)
    others = window.polygons_from_field(others_field, 0.0)
    if len(members) >= 3:
        snake, contour.fields = snake_contour(ev, i, mask, ev.xy[members[boundary]], params, keep_fields, check)
        # The cells around its own holes are the geozone's (see _claim_own_cells):
        # where the snake cut a corner off a neck, they are given back.
        if not snake.is_empty:
            missed = xy[~shapely.contains_xy(snake, xy[:, 0], xy[:, 1])]
            own = shapely.buffer(shapely.MultiPoint(missed), OWN_HOLE_SPACINGS * ev.spacing_m, quad_segs=4)
            given_back = window.polygons_from_mask(claimed)
            polygon = _largest_holding(snake.union(own).union(given_back).difference(others), xy)
    if polygon.is_empty or shapely.contains_xy(polygon, xy[:, 0], xy[:, 1]).mean() < MIN_HOLES_INSIDE:
        # Too small for a snake, or the snake pinched off part of the region (a
        # parametric snake cannot split where the region narrows to one row):
        # the part's outline is the honest answer.
        polygon, contour.method = _outline_holding(outline, others, xy, ev.spacing_m), "outline"
    # Each hole stands for the cells nearest it: the share the holes give a body is what its area is
    # on their evidence, and no smaller (smoothing over a spacing shrank a lens of 3-5 holes to 0.7 of it).
    share = np.isin(ev.nearest_hole[rs, cs], members) & (ev.transition.label[rs, cs] >= 0)
    if contour.method == "snake":
        # An outline (a part too small for a snake) is a few cells' staircase around its holes: smoothed, a
        # part of one hole shrank to nothing, and its share then blew it up (a Kennecott speck to 6,500 m2).
        polygon = smoothed_contour(polygon, others, ev.xy, xy, ev.spacing_m, check)
    contour.polygon = at_least_its_share(polygon, float(share.sum()) * window.cell_size_m**2, ev.xy)
    return contour


def smoothed_contour(
    polygon: Polygon,
    others: MultiPolygon,
    bench_xy: np.ndarray,
    own_xy: np.ndarray,
    spacing_m: float,
    check: Callable[[], None] | None = None,
) -> Polygon:
    """``polygon`` with the waver it has between the holes smoothed out, no hole of the bench changing side.

    A contour runs between holes of different geozones and wavers about the
    geozone's boundary by a fraction of a spacing (the own holes' surroundings
    and the cells given back add bumps of their own). Its signed distance is
    smoothed over the widest of :data:`CONTOUR_SMOOTHING_SPACINGS` hole
    spacings, the boundary kept in place where it curves
    (:func:`core.geometry.sdf.smoothed_section`), and the other geozones'
    regions, smoothed alike, are cut off it again (unsmoothed, they put their
    waver back). Around a hole of the bench (``bench_xy``) the smoothing would
    move to the other side, it steps down to narrower scales, then to shares of
    the narrowest, else to none (:func:`_stepped_back`): the holes are the
    evidence, and a contour keeps every one on its side, smoothed as far as
    they allow where they allow it.

    Parameters
    ----------
    polygon : Polygon
        The part's contour (local metres).
    others : MultiPolygon
        The other geozones' regions near it.
    bench_xy : (n, 2) float
        Every hole of the bench.
    own_xy : (m, 2) float
        The part's own holes (the polygon kept is the one holding most of them).
    spacing_m : float
        The bench's hole spacing.
    check : callable, optional
        Called between steps (the smoothings, each step down); a large part's smoothing takes up to half a
        second on Kennecott, and a :class:`core.threads.Cancelled` it raises stops it there.
    """
    if polygon.is_empty:
        return polygon
    check = check or _nothing
    x0, y0, x1, y1 = polygon.bounds
    pad = 2.0 * spacing_m
    grid = Grid.covering((x0 - pad, y0 - pad, x1 + pad, y1 + pad), spacing_m / 6, margin_cells=0)
    distance = region_signed_distance(grid, polygon)
    changes = _smoothing_ladder(distance, grid.cell_size_m, spacing_m)
    check()
    outside = None
    if not others.is_empty:
        others_distance = region_signed_distance(grid, others)
        outside = (others_distance, _smoothing_ladder(others_distance, grid.cell_size_m, spacing_m))
        check()
    before = shapely.contains_xy(polygon, bench_xy[:, 0], bench_xy[:, 1])
    level = np.zeros(grid.shape)
    for _ in range(2 * len(changes)):
        check()
        field = distance + _at_level(changes, level)
        if outside is not None:
            field = np.minimum(field, -(outside[0] + _at_level(outside[1], level)))
        smooth = _largest_holding(grid.polygons_from_field(field, 0.0), own_xy)
        if smooth.is_empty:
            break
        moved = shapely.contains_xy(smooth, bench_xy[:, 0], bench_xy[:, 1]) != before
        if not moved.any():
            return smooth
        stepped = _stepped_back(level, grid, bench_xy[moved], spacing_m, len(changes) - 1)
        if np.array_equal(stepped, level):
            break
        level = stepped
    return polygon


def _nothing() -> None:
    """A ``check`` that never stops anything."""


def _smoothing_ladder(distance: np.ndarray, cell_size_m: float, spacing_m: float) -> np.ndarray:
    """The changes :func:`smoothed_contour` steps down: each scale, then shares of the narrowest, then none."""
    sigmas_m = [f * spacing_m for f in CONTOUR_SMOOTHING_SPACINGS]
    changes = [smooth - distance for smooth in smoothed_sections(distance, cell_size_m, sigmas_m, 3.0 * spacing_m)]
    changes += [share * changes[-1] for share in (0.75, 0.5, 0.25, 0.0)]
    return np.stack(changes)


def _at_level(changes: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Per cell, the change of ``changes`` at the fractional step ``level`` (linear between steps)."""
    low = np.floor(level).astype(int)
    high = np.minimum(low + 1, len(changes) - 1)
    t = level - low
    pick = np.take_along_axis
    return (1 - t) * pick(changes, low[None], 0)[0] + t * pick(changes, high[None], 0)[0]


def _stepped_back(level: np.ndarray, grid: Grid, moved_xy: np.ndarray, spacing_m: float, last: int) -> np.ndarray:
    """``level`` one step further within :data:`SMOOTHING_STEP_BACK_SPACINGS` of the holes that moved, fading out.

    The step fades over a spacing beyond, so the contour does not jump where
    two scales meet.
    """
    rc = grid.nearest_cells(moved_xy)  # a hole can only change side where the grid reaches
    hit = np.zeros(grid.shape, bool)
    hit[rc[:, 0], rc[:, 1]] = True
    near = ndimage.distance_transform_edt(~hit) * grid.cell_size_m <= SMOOTHING_STEP_BACK_SPACINGS * spacing_m
    step = ndimage.gaussian_filter(near.astype(float), spacing_m / grid.cell_size_m)
    step = np.maximum(step / step.max(), near)
    return np.minimum(level + step, last)


def _others_and_claimed(ev: BenchEvidence, i: int, rs: slice, cs: slice) -> tuple[np.ndarray, np.ndarray]:
    """The other geozones' region as a field, and the cells claimed for ``i`` against the field, in a window.

    The field (positive inside the others' region) is cut at its zero set, not
    along the cells' staircase, which would take slivers off a snake that sits
    on that same line (4% of the area of a pod three spacings across). Cells
    :func:`_claim_own_cells` gave to a hole's geozone against the field are
    turned by half a cell in it where another geozone claimed them, and
    returned as a mask where ``i`` did: the snake follows the field, and those
    are added to it as the others' are taken off it, so neither side gains
    from the claims.
    """
    region, others = ev.transition.sides(i, (rs, cs))
    label = ev.transition.label[rs, cs]
    other = (label >= 0) & (label != i)
    half = 0.5 * ev.transition.grid.cell_size_m
    field = np.where(other & (others <= 0), half, np.where(~other & (others > 0), -half, others))
    return field, (label == i) & (region <= 0)


def _nearest_part(parts: np.ndarray, rc: np.ndarray) -> np.ndarray:
    """Part number at each cell ``rc``, or of the nearest part where a cell is in none.

    A hole's own cell can go to a closer hole of another geozone (two holes
    a fraction of a cell apart); the hole then joins its geozone's nearest part.
    """
    part_of = parts[rc[:, 0], rc[:, 1]]
    missing = part_of == 0
    if missing.any() and parts.any():
        _, (rows, cols) = ndimage.distance_transform_edt(parts == 0, return_indices=True)
        part_of[missing] = parts[rows[rc[missing, 0], rc[missing, 1]], cols[rc[missing, 0], rc[missing, 1]]]
    return part_of


def _window(grid: Grid, mask: np.ndarray, pad_m: float) -> tuple[Grid, tuple[slice, slice]]:
    """The part of ``grid`` around ``mask``'s cells plus ``pad_m``: a sub-grid and its index slices."""
    rows, cols = np.nonzero(mask)
    pad = cells_covering(pad_m, grid.cell_size_m)
    r0, c0 = max(rows.min() - pad, 0), max(cols.min() - pad, 0)
    r1, c1 = min(rows.max() + pad + 1, grid.shape[0]), min(cols.max() + pad + 1, grid.shape[1])
    h = grid.cell_size_m
    sub = Grid(grid.x0 + c0 * h, grid.y0 + r0 * h, h, (int(r1 - r0), int(c1 - c0)))
    return sub, (slice(r0, r1), slice(c0, c1))


def snake_contour(
    ev: BenchEvidence,
    i: int,
    mask: np.ndarray,
    boundary_xy_m: np.ndarray,
    params: ExtractionParameters,
    keep_fields: bool = False,
    check: Callable[[], None] | None = None,
) -> tuple[Polygon, ExtractionFields | None]:
    """Edge map, GVF and active contour of one part of a geozone's region (sections 2.4-2.5).

    Parameters
    ----------
    ev : BenchEvidence
        The bench's transition field and boundary holes.
    i : int
        Index of the geozone in ``ev.transition.geozones``.
    mask : (rows, cols) bool
        The part, on the bench grid.
    boundary_xy_m : (m, 2) float
        Its boundary holes: the edge map keeps the ridge only within a search
        radius of them (the paper builds its edge map from boundary holes).
    params : ExtractionParameters
    keep_fields : bool
    check : callable, optional
        Called once the GVF is solved and every few of the snake's iterations
        (:func:`core.extraction.snake.evolve_snake`); a :class:`core.threads.Cancelled`
        it raises stops the part there.

    Returns
    -------
    polygon : shapely Polygon
        The converged snake as a valid polygon (local metres); empty if it failed.
    fields : ExtractionFields or None
    """
    spacing = ev.spacing_m
    grid = _component_grid(ev.transition.grid, mask, params.edge_map_cells, spacing)
    bench_sdf = ev.transition.region_sdf(i)
    X, Y = grid.cell_centres()
    cells = np.column_stack([X.ravel(), Y.ravel()])
    smooth = ev.transition.grid.sample(np.where(np.isfinite(bench_sdf), bench_sdf, 1e6), cells).reshape(grid.shape)
    # Re-distanced exactly: the smoothed field's slope is well under 1 across a
    # thin strip, and a ridge that wide would let the snake run through it.
    sdf = signed_distance(smooth > 0, grid.cell_size_m)
    f = edge_map(sdf, grid.cell_size_m)
    if len(boundary_xy_m):
        near = cKDTree(boundary_xy_m).query(cells, distance_upper_bound=params.radius_m(spacing))[0]
        f *= np.isfinite(near).reshape(grid.shape)
    else:
        f[:] = 0.0
    gvf = gvf_steady_state(f, params.gvf_mu)
    if check:
        check()
    start = _start_ring(grid, sdf, SNAKE_START_SPACINGS * spacing)
    if start is None:
        return Polygon(), None
    snake, history, iterations = evolve_snake(
        start,
        gvf,
        alpha=params.snake_alpha,
        beta=params.snake_beta,
        step=params.snake_step,
        max_iterations=params.snake_max_iterations,
        keep_history=keep_fields,
        check=check,
    )
    snake = onto_crest(snake, smooth / grid.cell_size_m, f, spacing / grid.cell_size_m)
    if keep_fields:
        history.append(snake)  # the viewer's last frame: the snake on its crest
    polygon = _largest_polygon(shapely.make_valid(Polygon(grid.rc_to_xy(snake))))
    fields = None
    if keep_fields:
        fields = ExtractionFields(
            grid=grid,
            edge_points_m=boundary_xy_m,
            edges=np.zeros((0, 2), int),
            edge_map=f,
            gvf=gvf,
            snake_history_m=[grid.rc_to_xy(s) for s in history],
            snake_iterations=iterations,
        )
    return polygon, fields


def onto_crest(
    snake_rc: np.ndarray, field_cells: np.ndarray, edge: np.ndarray, smoothing_cells: float, steps: int = 2
) -> np.ndarray:
    """Move the converged snake onto the zero set of the field whose edge map it followed, smoothly.

    The GVF (section 2.5) diffuses the edge map's gradient, and on a curved
    ridge the outside's inward vectors outweigh the inside's outward ones: the
    snake stops inside the crest, by a fraction of a cell on a large body and
    by enough to lose 10% of the area of a pod three spacings across. Where
    the edge map holds a ridge (``edge > 0.1``), each point's distance to the
    zero set along the field's gradient (a Newton step) is averaged along the
    snake over ``smoothing_cells`` and the point moved by it: the bias goes,
    the snake's smoothness over the drilling pattern's zig-zag stays;
    elsewhere the snake's bridging stays as it is.

    Parameters
    ----------
    snake_rc : (N, 2) float
        Converged snake (row, col), points evenly spaced.
    field_cells : (rows, cols) float
        Signed distance (positive inside) the edge map was made from, in cells.
    edge : (rows, cols) float
        The edge map (section 2.4).
    smoothing_cells : float
        Standard deviation of the average along the snake, cells of arc length.
    steps : int
        Newton steps.
    """
    grad = np.gradient(field_cells)
    x = np.asarray(snake_rc, float).copy()
    on = ndimage.map_coordinates(edge, x.T, order=1, mode="nearest") > 0.1
    if not on.any():
        return x
    arc = float(np.mean(np.hypot(*np.diff(np.vstack([x, x[:1]]), axis=0).T)))
    if arc < 1e-6:  # collapsed onto a point: nothing to put anywhere
        return x
    sigma = min(smoothing_cells / arc, float(len(x)))  # wider than the ring is its mean
    for _ in range(steps):
        value = ndimage.map_coordinates(field_cells, x.T, order=1, mode="nearest")
        g = np.column_stack([ndimage.map_coordinates(d, x.T, order=1, mode="nearest") for d in grad])
        norm = np.hypot(g[:, 0], g[:, 1])
        use = on & (norm > 0.2) & (np.abs(value) < 3.0)
        distance = np.where(use, -value / np.maximum(norm, 1e-12), 0.0)
        # Averaged over the points that measured it, so a stretch without a ridge does not dilute it.
        weight = ndimage.gaussian_filter1d(use.astype(float), sigma, mode="wrap")
        mean = ndimage.gaussian_filter1d(distance, sigma, mode="wrap") / np.maximum(weight, 1e-12)
        move = np.clip(np.where(on & (weight > 0.05), mean, 0.0), -2.0, 2.0)
        x += move[:, None] * g / np.maximum(norm, 1e-12)[:, None]
    return x


def _component_grid(bench_grid_: Grid, mask: np.ndarray, cells_across: int, spacing_m: float) -> Grid:
    """Grid around one part: its bounding box plus room for the snake's start, at most ``cells_across`` cells."""
    rows, cols = np.nonzero(mask)
    lo = bench_grid_.rc_to_xy(np.array([[rows.min(), cols.min()]]))[0]
    hi = bench_grid_.rc_to_xy(np.array([[rows.max(), cols.max()]]))[0]
    pad = (SNAKE_START_SPACINGS + 1.0) * spacing_m
    bounds = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)
    return Grid.for_extent(bounds, cells_across, margin_cells=4, min_cell_size_m=bench_grid_.cell_size_m)


def _start_ring(grid: Grid, sdf: np.ndarray, offset_m: float) -> np.ndarray | None:
    """The snake's start: the outline of the part grown by ``offset_m``, as (row, col) points."""
    grown = np.pad(sdf > -offset_m, 1)
    rings = find_contours(grown.astype(float), 0.5)
    if not rings:
        return None
    ring = max(rings, key=len) - 1.0
    perimeter = float(np.sum(np.hypot(*np.diff(ring, axis=0).T)))
    return resample_closed(ring, int(np.clip(perimeter / 1.5, 24, 4000)))


def _largest_polygon(geometry) -> Polygon:
    parts = list(as_multipolygon(geometry).geoms)
    if not parts:
        return Polygon()
    return shapely.geometry.polygon.orient(max(parts, key=lambda p: p.area))


def _outline_holding(outline: MultiPolygon, others: MultiPolygon, xy: np.ndarray, spacing_m: float) -> Polygon:
    """A part's outline less the other geozones' regions, holding its holes ``xy``.

    A hole the cells miss (a hole of one or two at the edge of another geozone's region, on the edge of its own
    cell) gets the disc the snake's missed holes get (:data:`OWN_HOLE_SPACINGS`): without it, a Kennecott speck's
    contour was a cell beside its hole, holding none of it. Where the other regions cover the hole too, they
    are not cut from it: its own holes are the part's evidence.
    """
    polygon = _largest_holding(outline.difference(others), xy)
    missed = ~shapely.contains_xy(polygon, xy[:, 0], xy[:, 1])
    if not missed.any():
        return polygon
    own = outline.union(shapely.buffer(shapely.MultiPoint(xy[missed]), OWN_HOLE_SPACINGS * spacing_m, quad_segs=4))
    polygon = _largest_holding(own.difference(others), xy)
    return polygon if shapely.contains_xy(polygon, xy[:, 0], xy[:, 1]).any() else _largest_holding(own, xy)


def _largest_holding(geometry, xy: np.ndarray) -> Polygon:
    """The polygon of ``geometry`` holding most of the points ``xy`` (ties: the largest)."""
    parts = list(as_multipolygon(geometry).geoms)
    if not parts:
        return Polygon()
    best = max(parts, key=lambda q: (int(shapely.contains_xy(q, xy[:, 0], xy[:, 1]).sum()), q.area))
    return shapely.geometry.polygon.orient(best)
