"""How a geozone's boundary moved between its benches, across itself (issue 12; paper section 3.3).

FFT alignment of a long strip is not determined along its length (the aperture
problem), and a trajectory's end on a smooth target can slide along it freely.
Only the part *across* the boundary is measured by the benches. Per cell, the
movement across itself of the nearest boundary between the last two benches that
observed it, matched along its normal to the boundary facing the same way
(:func:`boundary_movement`, as far as the geozone's sections moved:
:func:`movement_reach_m`), is the rate of movement (:func:`fit_trend`). It is
split into the movement of each outline as a whole (its translation, growth and
elongation, :func:`outline_movement`) and the finer changes, and successive bench
pairs' agreement on each part along the trajectories of the geozone's boundary is
how far it carries on (:func:`geozone_persistence`). The signed distances are
:mod:`core.model.fields`'; the carrying on, :mod:`core.model.extrapolation`.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from core.correspondence.alignment import fft_translation, shift_mask
from core.model.fields import MIN_DIP_DEG, BenchFields, body_size_m, memoised, parts_touching

#: Cells within this many cells of the deepest boundary measure the persistence of its movement
#: (:func:`geozone_persistence`); every cell takes the movement of its nearest boundary point,
#: and cells far from it would weigh a boundary by the empty ground around it.
PERSISTENCE_BAND_CELLS = 2.0
#: A movement carries on as far as its agreement from bench to bench is this many standard
#: errors above chance (:func:`geozone_persistence`). Chosen on development seeds 0-11,
#: Kennecott and the constructed noisy bodies among 0 (before), 1 and 2. With 1 the families
#: are unchanged pooled (95.6 / 94.1 at 5 / 10 m; strips -0.1 / -0.2, splits -0.1 / -0.2, pods
#: +0.1 / +0.2), Kennecott 73.9 -> 74.1 on the holes (84.4 -> 84.8 from the deepest known bench
#: 4, where the outlines moved on by less than their last two moves agreed), and a static body
#: whose outline changes at random is no longer under holding with 3-5 benches known. With 2,
#: Kennecott 74.2 and 85.2 but a disc moving 6 m a bench through 6% shape noise carried as
#: little as 0.42 of its translation (-0.6 to -0.8 F1 with 4-5 benches known).
PERSISTENCE_STANDARD_ERRORS = 1.0

#: Degrees of freedom of an outline's movement (:func:`outline_movement`: growth, translation, elongation).
OUTLINE_DEGREES = 5

#: Shallowest dip looked for where much of a geozone's boundary moved further than :data:`MIN_DIP_DEG`
#: allows, one way (:func:`coherent_reach_m`): 20 degrees, 2.7 bench heights a bench. Taken as the bound
#: everywhere instead, it matched lenses to others up to 27 m away (development seeds 0-3 of the families,
#: F1 at 5 / 10 m 96.37 / 94.96 -> 96.14 / 94.38).
COHERENT_DIP_DEG = 20.0
#: The share of the boundary that must have moved past :data:`MIN_DIP_DEG`'s bound, and how nearly one way
#: (the mean movement vector's length over the mean length). A contact moving 20 m a bench scores 0.95 and
#: 0.97, a lens growing all round about 0. The fast families' ``mix`` (development seeds 0-2) gained the same
#: with 0.1 / 0.6, 0.25 / 0.8 and 0.5 / 0.9; travelling waves moving 3-30 m a bench (``bench_foreign.py``'s
#: generator, development seeds 100-111) +0.3 / +0.6 F1 at 5 / 10 m with 0.25 / 0.8, none with 0.5 / 0.9.
COHERENT_SHARE = 0.25
COHERENCE = 0.8


def geozone_persistence(fields: BenchFields, hole_spacing_m: float) -> tuple[float, float]:
    """How much of the last bench-to-bench movement carries on, for the geozone's boundary as a whole, in [0, 1].

    Two figures: for the movement of each outline as a whole and for the
    finer changes (:func:`outline_movement`). For each, the agreement of the
    last movement of the boundary (``d1``) with the one before along its
    trajectory (``d2``, :func:`movements_along_trajectories`; where there is
    no trajectory, the changes of the signed distance ``F_k - F_k-1`` and
    ``F_k-1 - F_k-2``), summed over the cells on the deepest boundary that
    three benches observed::

        rho = 2 sum(d1 d2) / sum(d1^2 + d2^2)   in [-1, 1]

    is 1 for a boundary that keeps moving the same way at the same rate, -1
    for one whose movement reverses, 0 for changes that do not repeat
    (shape noise). The persistence is ``clip(2 rho_low, 0, 1)``: full where the
    repeated movement is at least as large as what does not repeat (section
    noise lowers ``rho`` of a steady boundary towards 1/2 when it is as
    large as the movement), none where the movement reverses or is noise.
    ``rho_low = rho - k (1 - rho^2) / sqrt(N - 1)`` is ``rho`` less
    :data:`PERSISTENCE_STANDARD_ERRORS` ``k`` standard errors of a correlation
    over ``N`` independent samples (:func:`_agreement`): five per outline for
    the outlines' movement (the degrees of freedom of its fit) and one per
    hole spacing of boundary for the finer changes. A geozone's movement is
    carried on as far as its benches show it beyond chance; a steady one
    (``rho`` near 1) keeps it whatever ``N``.
    The two parts are judged apart because they repeat apart: a strip's
    outline moves steadily while its edges wobble from bench to bench, and a
    body splitting pinches at its neck bench after bench, which its outline's
    movement does not hold. With fewer than three benches nothing tells
    either: the outlines' movement is carried (1) and the finer changes are
    not (0). A part with no such cell, or no change on them, is carried (1).
    Changes faster than a boundary of the geozone moves
    (:func:`movement_reach_m`) are left out: they are bodies appearing.

    Measured over the whole boundary rather than per neighbourhood
    (:data:`PERSISTENCE_BAND_CELLS`): a lens's boundary gives a few dozen
    cells, whose agreement by chance is as often positive as not, and a
    local estimate clipped at 0 kept half of every lens's noise.
    """
    if len(fields.z_m) < 3:
        return 1.0, 0.0
    # The benches as their holes showed them: drawn towards the benches above (core.model.extrapolation.assimilated),
    # their movements agree by construction (a test's travelling waves agree under 0.5 observed, 0.53 drawn).
    fields = fields.measured()
    n = len(fields.z_m)
    fastest = geozone_fastest_movement_m(fields, float(abs(fields.z_m[-2] - fields.z_m[-1])))
    reach1, reach2 = movement_reach_m(fields, n - 2, n - 1, fastest), movement_reach_m(fields, n - 3, n - 2, fastest)
    d1, d2 = movements_along_trajectories(fields, reach1, reach2)
    seen = np.all(fields.weight[-3:] >= OBSERVED_WEIGHT, axis=0)
    on_boundary = np.abs(fields.distance[-1]) <= PERSISTENCE_BAND_CELLS * fields.grid.cell_size_m
    w = seen & on_boundary & (np.abs(d1) <= reach1) & (np.abs(d2) <= reach2)
    h = fields.grid.cell_size_m
    # d2 is carried to the deepest boundary along the trajectories: both are fitted on its outlines, at once
    outline1, outline2 = outline_movement(np.where(w, [d1, d2], 0.0), w, fields.distance[-1], h)
    # Outlines counted as the pieces of its inner side three benches saw (a stretch the drilling cut counts apart).
    outlines = ndimage.label(w & (fields.distance[-1] > 0), structure=np.ones((3, 3)))[1]
    # The band is 2 PERSISTENCE_BAND_CELLS cells wide: its cells over that are the boundary's length in cells.
    length_spacings = w.sum() / (2 * PERSISTENCE_BAND_CELLS) * h / hole_spacing_m
    return (
        _agreement(outline1[w], outline2[w], OUTLINE_DEGREES * max(outlines, 1)),
        _agreement((d1 - outline1)[w], (d2 - outline2)[w], length_spacings),
    )


def _agreement(d1: np.ndarray, d2: np.ndarray, samples: float) -> float:
    """``clip(2 rho_low, 0, 1)`` of ``rho = 2 sum(d1 d2) / sum(d1^2 + d2^2)``, 1 without change.

    ``rho_low`` is ``rho`` less :data:`PERSISTENCE_STANDARD_ERRORS` standard
    errors of a correlation over ``samples`` independent samples,
    ``(1 - rho^2) / sqrt(samples - 1)`` (:func:`geozone_persistence`).
    """
    energy = float(np.sum(d1**2 + d2**2))
    if energy <= 0:
        return 1.0
    rho = float(np.clip(2 * np.sum(d1 * d2) / energy, -1.0, 1.0))
    low = rho - PERSISTENCE_STANDARD_ERRORS * (1 - rho**2) / np.sqrt(max(samples - 1, 1.0))
    return float(np.clip(2 * low, 0.0, 1.0))


def movements_along_trajectories(
    fields: BenchFields, reach1_m: float, reach2_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """The last two bench-to-bench changes at each cell, ``(d1, d2)`` in metres, outwards.

    ``d1`` is the :func:`boundary_movement` of the cell's nearest boundary
    over the last bench pair and ``d2`` the movement, over the pair before,
    of the boundary point it came from (along its trajectory, as the paper's
    particles follow the front). The changes of the signed distance at the
    cell itself (``F_k - F_k-1`` and ``F_k-1 - F_k-2``) are the same for a
    boundary moving less than its body's half-width per bench; for one moving
    further they mix the movements of two boundaries (the leading edge's and
    the trailing edge's) and a steady movement looks like one that reverses.
    Where a boundary has no counterpart they are taken instead.
    """
    f, n = fields.distance, len(fields.z_m)
    d1, d2 = f[-1] - f[-2], f[-2] - f[-3]
    moved1, origin = pair_movement(fields, n - 2, n - 1, reach1_m)
    moved2, _ = pair_movement(fields, n - 3, n - 2, reach2_m)
    traced = np.isfinite(moved1)
    before = np.full(moved1.shape, np.nan)
    before[traced] = ndimage.map_coordinates(
        np.nan_to_num(moved2, nan=np.inf), origin[:, traced], order=0, mode="nearest"
    )
    traced &= np.isfinite(before)
    return np.where(traced, moved1, d1), np.where(traced, before, d2)


#: A bench observed a cell when the cell lies within this weight of its drilled
#: area (``exp(-d / s)``: about half a hole spacing past its outermost holes' discs).
OBSERVED_WEIGHT = 0.5


def last_observations(fields: BenchFields) -> tuple[np.ndarray, np.ndarray]:
    """Per cell, the index of the deepest bench that observed it and of the one before (-1 if none).

    A bench observes its drilled area and, within :data:`OBSERVED_WEIGHT`, the ground just past it, where its
    evidence is its outermost holes' carried on; that fringe is no observation of ground a bench above drilled,
    except at the edge of a pit narrowing downwards (:func:`narrowing_edges`).
    """
    seen = fields.weight >= OBSERVED_WEIGHT
    # A bench's fringe replaced there the bench above's holes with its own edge's guess: with a deepest bench
    # drilled over part of the pit, the next row of its pattern, held back, took the first holes' label from a
    # spacing away instead of the bench above's, carried on (widening, tuning seed 2, 40% of the bench drilled
    # in a strip: 86.0 F1 on the held-back holes from the benches above alone, 76.0 with the first holes).
    drilled_above = np.logical_or.accumulate(fields.drilled, axis=0)[:-1]
    seen[1:] &= fields.drilled[1:] | ~drilled_above | narrowing_edges(fields)
    last = np.full(fields.grid.shape, -1)
    before = np.full(fields.grid.shape, -1)
    for j in range(len(fields.z_m)):  # top down: later benches replace earlier ones
        before = np.where(seen[j], last, before)
        last = np.where(seen[j], j, last)
    return last, before


def narrowing_edges(fields: BenchFields) -> np.ndarray:
    """Per bench below the first, the ground the bench directly above drilled in a band no more than a hole
    spacing wide past the bench's own drilling: a pit's edge narrowing downwards, which the bench's fringe observes.

    Elsewhere a bench's fringe gives way to the holes of the benches above (its first patterns,
    :func:`last_observations`). In a band the bench above drilled a few metres further, as a pit narrowing a
    few metres a side a bench does, the deeper bench's own edge is the newer evidence (the travelling waves of
    ``bench_foreign.py --speed 2``, the pit narrowing 4 m a side a bench: F1 at one bench 76.1 with the older
    bench's evidence there, 76.3 with the deeper bench's; on seeds 300-323, 75.9 and 76.1). A band that reaches
    further than a spacing anywhere is first patterns' ground, left whole to the bench above.
    """
    band = fields.drilled[:-1] & ~fields.drilled[1:]
    past_spacing = fields.weight[1:] < np.exp(-1.0)  # weight is exp(-spacings past the drilling)
    narrow = np.zeros_like(band)
    for j, (b, far) in enumerate(zip(band, past_spacing)):
        narrow[j] = b & ~parts_touching(b, far, structure=np.ones((3, 3), bool))
    return narrow


def unit_normals(distance: np.ndarray, cell_size_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit normal ``grad F / |grad F|`` of a signed distance (pointing inside), per cell, and where it has one.

    A signed distance changes by a cell size per cell; at its cap and on its
    ridges it does not, and the normal there is no direction (``directed``
    false where ``|grad F|`` is under a fifth of a cell size; the normal is
    then not meaningful).
    """
    g_r, g_c = np.gradient(distance)
    norm = np.hypot(g_r, g_c)
    directed = norm > 0.2 * cell_size_m
    norm = np.maximum(norm, 1e-9)
    return g_r / norm, g_c / norm, directed


def boundary_movement(
    older: np.ndarray, newer: np.ndarray, cell_size_m: float, reach_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """How far the boundary nearest each cell moved outwards from one bench to the next, and from where.

    ``F_newer - F_older`` at a cell is the movement only while the nearest
    boundary on both benches is the same one: in a strip that moved further
    than its half-width, the trailing edge's cells are nearer the older
    leading edge, and the trailing edge seemed to stand still while the
    leading one advanced (the strip widened, 10% of its area on the tuning
    seeds). Here each point of the newer boundary is matched along its normal
    to the nearest boundary of the older bench that faces the same way (``F``
    rising inwards along it), within ``reach_m`` (the furthest a boundary
    moves, :data:`MIN_DIP_DEG`); the outward distance between the two is the
    movement, and every cell takes the movement of its nearest boundary point.

    Parameters
    ----------
    older, newer : (rows, cols) float
        Signed distances (positive inside) on the two benches, metres.
    cell_size_m, reach_m : float

    Returns
    -------
    moved : (rows, cols) float
        Outward movement, metres (negative where the boundary retreated);
        nan where the nearest boundary has no counterpart within the reach
        (a body appearing) and everywhere when ``newer`` has no boundary.
    origin : (2, rows, cols) float
        Where on the older boundary the cell's boundary point came from (the
        end of its trajectory on the bench above), (row, col) in cells; the
        boundary point itself where there is no counterpart.
    """
    n_r, n_c, directed = unit_normals(newer, cell_size_m)
    band = (np.abs(newer) <= cell_size_m) & directed
    if not band.any():
        return np.full(newer.shape, np.nan), np.full((2, *newer.shape), np.nan)
    n_r, n_c = n_r[band], n_c[band]
    rows, cols = np.nonzero(band)
    to_boundary = newer[band] / cell_size_m  # from each band cell to the boundary point, along -normal
    steps = np.arange(-reach_m, reach_m + 1e-9, 0.5 * cell_size_m) / cell_size_m
    along = [
        (rows - to_boundary * n_r)[:, None] + steps * n_r[:, None],
        (cols - to_boundary * n_c)[:, None] + steps * n_c[:, None],
    ]
    f = ndimage.map_coordinates(older, along, order=1, mode="nearest")
    entering = (f[:, :-1] <= 0) & (f[:, 1:] > 0)  # the older boundary, facing the same way
    t = np.where(entering, f[:, :-1] / np.where(entering, f[:, :-1] - f[:, 1:], 1.0), 0.0)
    offset_m = (steps[:-1] + t * (steps[1] - steps[0])) * cell_size_m
    nearest = np.argmin(np.where(entering, np.abs(offset_m), np.inf), axis=1)
    pick = np.arange(len(nearest))
    matched = entering[pick, nearest]
    moved = np.full(newer.shape, np.nan)
    moved[band] = np.where(matched, offset_m[pick, nearest], np.nan)
    _, (r, c) = ndimage.distance_transform_edt(~band, return_indices=True)
    # The older boundary point each band cell's boundary point was matched to, along its normal.
    along = np.where(matched, offset_m[pick, nearest], 0.0) / cell_size_m - to_boundary
    origin = np.full((2, *newer.shape), np.nan)
    origin[0][band], origin[1][band] = rows + along * n_r, cols + along * n_c
    return moved[r, c], origin[:, r, c]


def pair_movement(fields: BenchFields, older: int, newer: int, reach_m: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`boundary_movement` from bench ``older`` to ``newer``, kept in ``fields.memo``.

    A trend, its persistence and the backtests of the benches above ask for the same
    pairs; :func:`core.model.extrapolation.depth_trend` drops them (:data:`MOVEMENTS_MEMO`) once its trend is made.
    """
    movements = fields.memo.setdefault(MOVEMENTS_MEMO, {})
    if (older, newer, reach_m) not in movements:
        f = fields.distance
        movements[older, newer, reach_m] = boundary_movement(f[older], f[newer], fields.grid.cell_size_m, reach_m)
    return movements[older, newer, reach_m]


#: The memo's entry of bench pairs' movements: three grids a pair, kept only while a trend is made.

#: The memo's entry of bench pairs' movements: three grids a pair, kept only while a trend is made.
MOVEMENTS_MEMO = ("movements",)


def fastest_movement_m(bench_height_m: float, body_size_m: float = np.inf, min_dip_deg: float = MIN_DIP_DEG) -> float:
    """How far a boundary moves across itself in ``bench_height_m``: at the shallowest dip ``min_dip_deg``.

    And no further than the geozone's bodies are across (``body_size_m``,
    :func:`geozone_body_size_m`): a lens found a lens-width from where one
    was the bench above is another lens, not the first one moved. The dip
    alone lets a boundary move 1.7 bench heights a bench, and on 15 m
    benches (26 m) pods 16-23 m across read lenses appearing beside others
    as the others moving or growing and carried that on (development seeds
    0-47 of the pods drilled on 15 m benches in feet, F1 at half / one bench
    below 58.87 / 30.55 against holding's 58.44 / 30.74; bounded, 59.15 /
    31.18; by half the size, 58.87 / 31.13 and the pods on 10 m benches
    59.36 / 33.28 -> 59.25 / 33.05). On 10 m benches (17 m) the bound moves
    the pods little (59.40 / 33.35) and layers, strips and folds, 40-130 m
    across, not at all (development seeds 0-5 of every family and Kennecott
    unchanged).
    """
    return min(bench_height_m / float(np.tan(np.radians(min_dip_deg))), body_size_m)


def geozone_body_size_m(fields: BenchFields) -> float:
    """:func:`body_size_m` of the geozone's bodies on its benches (inside their drilled areas), kept in ``fields.memo``."""

    def compute() -> float:
        return body_size_m([(d > 0) & dr for d, dr in zip(fields.distance, fields.drilled)], fields.grid.cell_size_m)

    return memoised(fields, ("body size", len(fields.z_m)), compute)


def geozone_fastest_movement_m(fields: BenchFields, bench_height_m: float) -> float:
    """:func:`fastest_movement_m` of the geozone's boundary over ``bench_height_m``, bounded by its bodies' size.

    At the fields' shallowest dip (:attr:`BenchFields.min_dip_deg`; the usual one, :data:`MIN_DIP_DEG`, before
    the benches chose).
    """
    return fastest_movement_m(bench_height_m, geozone_body_size_m(fields), fields.dip_deg)


def movement_reach_m(fields: BenchFields, older: int, newer: int, fastest_m: float) -> float:
    """How far a boundary of the geozone may have moved from bench ``older`` to ``newer``, metres.

    At least ``fastest_m`` (:data:`MIN_DIP_DEG`); further where the geozone as
    a whole moved further: the translation that best aligns the older bench's
    section with the newer's signed distance (FFT cross-correlation, paper
    section 3.2.1, eqs. (10)-(12)) inside the area both drilled, taken when the
    section moved by it overlaps the newer one better than the section held
    does and by at least half, and the held section is within ``fastest_m`` of
    the newer one (a contact dipping shallower than the benches' usual, not a
    lens ending and another beginning further away). Kept in ``fields.memo``.
    """

    def compute() -> float:
        both = fields.drilled[older] & fields.drilled[newer]
        source, target = (fields.distance[older] > 0) & both, (fields.distance[newer] > 0) & both
        if not source.any() or not target.any():
            return fastest_m
        d_row, d_col = fft_translation(source, np.where(both, fields.distance[newer], 0.0))
        shift_m = float(np.hypot(d_row, d_col)) * fields.grid.cell_size_m
        if shift_m <= fastest_m:
            return fastest_m
        moved = shift_mask(source, int(d_row), int(d_col)) & both

        def overlap(a: np.ndarray) -> float:
            return float(np.sum(a & target)) / max(float(np.sum(a | target)), 1.0)

        # the section moved, not a body vanishing and another appearing further away than a boundary moves
        held = overlap(source)
        gap_m = (
            0.0 if held > 0 else float(ndimage.distance_transform_edt(~target)[source].min()) * fields.grid.cell_size_m
        )
        confirmed = gap_m <= fastest_m and overlap(moved) >= max(0.5, held)
        return shift_m + fields.grid.cell_size_m if confirmed else fastest_m

    def reach() -> float:
        aligned = compute()
        return aligned if aligned > fastest_m else coherent_reach_m(fields, older, newer, fastest_m)

    return memoised(fields, ("reach", older, newer, fastest_m), reach)


def coherent_reach_m(fields: BenchFields, older: int, newer: int, fastest_m: float) -> float:
    """How far the geozone's boundary moved from ``older`` to ``newer`` if much of it moved further than ``fastest_m`` one way.

    The sections' alignment (:func:`movement_reach_m`) finds a translation
    only where the whole section moves with it: a contact or a layer crossing
    the drilling, one part of a geozone whose other parts stand, stays put
    under it (moved, it leaves the drilled area as much as it gains). Here the
    newer boundary is matched to the older one as far as a boundary dipping
    :data:`COHERENT_DIP_DEG` moves (:func:`boundary_movement`); when enough of
    its points (:data:`COHERENT_SHARE`) moved further than ``fastest_m``, and
    those movements, as vectors along the boundary's normals, point the same
    way (the length of their mean at least :data:`COHERENCE` of their mean
    length: a translation, not a lens growing or another appearing around it),
    the further reach is the pair's. Found on development seeds 0-2 of the
    families moving 10-25 m a bench (a scratch variant of the generator): the
    contacts of ``mix`` (F1 at 5 / 10 m 93.1 / 88.8 -> 96.5 / 95.2); the
    families as generated and Kennecott, whose boundaries move within the
    bound, unchanged (held-out pods within 0.04).
    """
    cell_m = fields.grid.cell_size_m
    f_new = fields.distance[newer]
    both = fields.drilled[older] & fields.drilled[newer]
    near, _ = pair_movement(fields, older, newer, fastest_m)
    n_r, n_c, directed = unit_normals(f_new, cell_m)
    band = (np.abs(f_new) <= cell_m) & directed & both
    # Points matched within the bound cannot leave the share that moved further: spare the wider search.
    if np.sum(np.isfinite(near[band])) > (1.0 - COHERENT_SHARE) * np.sum(band):
        return fastest_m
    far_m = fastest_m * float(np.tan(np.radians(fields.dip_deg)) / np.tan(np.radians(COHERENT_DIP_DEG)))
    # The fields' own bound is already as shallow (core.model.extrapolation.with_backtested_dip).
    if far_m <= fastest_m:
        return fastest_m
    moved, _ = pair_movement(fields, older, newer, far_m)
    band &= np.isfinite(moved)
    beyond = band & (np.abs(moved) > fastest_m)
    if not beyond.any() or np.sum(beyond) < COHERENT_SHARE * np.sum(band):
        return fastest_m
    vectors = moved[beyond] * np.stack([n_r[beyond], n_c[beyond]])
    coherence = float(np.linalg.norm(vectors.mean(axis=1)) / np.mean(np.linalg.norm(vectors, axis=0)))
    return far_m if coherence >= COHERENCE else fastest_m


def fit_trend(fields: BenchFields, bench_height_m: float) -> tuple[np.ndarray, ...]:
    """Per cell, the last observed signed distance, where it was observed and its change with depth.

    Each cell's trend rests on the last two benches drilled there (the
    deepest one, ``j1``, and the one above it that was drilled there,
    ``j2``): the :func:`boundary_movement` of its nearest boundary from
    ``j2`` to ``j1`` (within :func:`movement_reach_m`), per bench height; where that boundary has no
    counterpart, the change from ``F_j2`` to ``F_j1``, held where faster than
    a boundary moves (:data:`MIN_DIP_DEG`). A cell drilled by one bench only
    has no change here (its outline's movement is given it later,
    :func:`outline_movement`); a cell none drilled takes the nearest evidence of
    the bench whose drilling is nearest within its evidence's reach (:func:`reaching_bench`), with no change.

    Returns
    -------
    f_last, z_last, rate : (rows, cols) float
        ``F_j1``, the elevation of ``j1`` (metres) and the outward movement
        of the boundary per bench height downwards.
    matched : (rows, cols) bool
        Where ``rate`` is the movement of a boundary matched on both benches.
    unmeasured : (rows, cols) bool
        Cells one bench observed: no bench pair measured their movement.
    """
    last, before = last_observations(fields)
    z = fields.z_m

    def take(idx: np.ndarray) -> np.ndarray:
        return np.take_along_axis(fields.distance, np.maximum(idx, 0)[None], axis=0)[0]

    f_last = take(last)
    fastest_m = geozone_fastest_movement_m(fields, bench_height_m)
    two = (last >= 0) & (before >= 0)
    # signed: negative when extrapolating upwards (fields reversed), as the rate is per bench in that direction
    benches = np.where(two, z[np.maximum(before, 0)] - z[np.maximum(last, 0)], bench_height_m) / bench_height_m
    # Where a boundary has no counterpart (the inner edges of a split, a lens appearing) the change of F
    # is all the benches say, held where faster than a boundary moves.
    rate = np.where(two, (f_last - take(before)) / benches, 0.0)
    rate = np.where(np.abs(rate) > fastest_m, 0.0, rate)
    n = len(z)
    pairs = [divmod(int(code), n) for code in np.unique(last[two] * n + before[two])]  # each cell's (j1, j2), once
    matched = np.zeros(rate.shape, bool)
    for j1, j2 in pairs:
        cells = (last == j1) & (before == j2)
        gap = float(benches[cells][0])
        reach = movement_reach_m(fields, j2, j1, fastest_m * abs(gap))
        moved, _ = pair_movement(fields, j2, j1, reach)
        matched[cells] = np.isfinite(moved[cells])
        rate[cells] = np.where(matched[cells], moved[cells] / gap, rate[cells])
    observed = last >= 0
    speaks = reaching_bench(fields)
    f_last = np.where(observed, f_last, take(speaks))
    return f_last, np.where(observed, z[np.maximum(last, 0)], z[speaks]), rate, matched, observed & (before < 0)


def reaching_bench(fields: BenchFields) -> np.ndarray:
    """Per cell, the bench whose drilling is nearest, of those whose evidence reaches it; the deepest where none does.

    Of benches drilled equally near, the deepest. Ground no bench drilled took the deepest bench's nearest evidence:
    a deepest bench drilled over part of the pit (its first blast patterns) reaches a few spacings round them, and
    past the drilling of the bench above, where that bench's evidence reaches, a body it showed going on was dropped
    (Kennecott's 2310 on bench 4: 385 of its held-back holes predicted from the benches above, 101 with the first 5%
    of bench 4 drilled, 396 now with :func:`core.model.prediction.undrilled_extension` reaching past the drilling at
    the deepest bench's level). But the deepest bench reaching a cell is not the nearest to see it: first patterns
    30-60 m off took over the ground just past the benches above's drilling, where their fringe is other geozones
    (Kennecott at its median hole number: 3310 at its deepest level, 48 of its 338 later holes there found; 196 with
    the nearest drilling's evidence, BENCHMARKS.md).
    """
    n = len(fields.z_m)
    if fields.reach_spacings is None or n == 0:
        return np.full(fields.grid.shape, max(n - 1, 0))
    reached = np.where(fields.weight >= np.exp(-fields.reach_spacings), fields.weight, 0.0)
    # argmax takes the first of equal weights, so the deepest bench, and with none reaching (all 0) the deepest.
    return n - 1 - np.argmax(reached[::-1], axis=0)


def outline_movement(
    rate: np.ndarray, matched: np.ndarray, f_last: np.ndarray, cell_size_m: float, unmeasured: np.ndarray | None = None
) -> np.ndarray:
    """The part of a movement that moves each outline as a whole: translation, growth and elongation.

    Per connected stretch of the boundary of ``f_last`` (the outline of a
    body, of a hole in one, or a contact crossing the grid; traced on its
    inner side, so that two bodies a gap of a few cells apart keep two
    outlines), the least-squares
    fit of its outward movement ``rate`` over its cells by harmonics 0-2 of
    the direction of the outward normal ``n = (cos t, sin t)``::

        a + b cos t + c sin t + d cos 2t + e sin 2t

    (``a`` growth, ``(b, c)`` a translation, ``(d, e)`` the normal movement of
    a stretch along an axis: a body elongating or splitting), bounded by the
    5th and 95th percentiles of the movement measured on the stretch (on a
    long winding contact whose normals point some way at a few cells only,
    the harmonics alone made up movements no cell showed: single geozones of
    the mix family lost 10-27 F1 points). Every cell in ``matched`` (its boundary's movement measured,
    :func:`boundary_movement`) takes the fit at its nearest boundary cell, and
    so does every cell in ``unmeasured`` (observed by one bench only, so no
    bench pair measured its movement: a bite the deepest bench left undrilled,
    ground only it drilled); the others keep ``rate``. ``rate`` may hold several
    movements stacked on a first axis, fitted on the same outlines at once.

    The finer changes are what shape noise is made of, and with two benches
    known nothing tells them from a change that carries on
    (:func:`geozone_persistence`). Carried on, they lost 2.9 F1 points to
    holding the last bench on a constructed body whose outline changes at
    random from bench to bench; the outline's movement alone, 0.8
    (BENCHMARKS.md). Without the elongation that noise was held entirely but
    a body splitting in two lost 4.5 points.
    """
    inward_r, inward_c, directed = unit_normals(f_last, cell_size_m)
    band = (np.abs(f_last) <= cell_size_m) & directed
    # Traced on both sides, the outlines of the two parts of a body that has just split joined across their gap:
    # one fit of their opposite movements cancelled them (a constructed split carried half of its parting).
    inner = band & (f_last > 0)
    rings, n = ndimage.label(inner, structure=np.ones((3, 3)))
    if n == 0:
        return rate
    _, (ring_r, ring_c) = ndimage.distance_transform_edt(~inner, return_indices=True)
    stretches = np.where(band, rings[ring_r, ring_c], 0)
    owner, use = stretches[band], matched[band]
    values = rate[..., band].reshape(-1, owner.size).T  # (band cells, movements)
    n_r, n_c = -inward_r[band], -inward_c[band]
    design = np.column_stack([np.ones(owner.size), n_r, n_c, n_r**2 - n_c**2, 2 * n_r * n_c])
    fitted = np.full(values.shape, np.nan)
    for stretch in np.unique(owner[use]):
        fit, cells = use & (owner == stretch), owner == stretch
        if fit.sum() >= design.shape[1]:
            coef, *_ = np.linalg.lstsq(design[fit], values[fit], rcond=None)
            fitted[cells] = np.clip(design[cells] @ coef, *np.percentile(values[fit], [5, 95], axis=0))
    on_band = np.full(rate.shape, np.nan)
    on_band[..., band] = fitted.T.reshape(rate[..., band].shape)
    _, (r, c) = ndimage.distance_transform_edt(~band, return_indices=True)
    nearest = on_band[..., r, c]
    takes = matched if unmeasured is None else matched | unmeasured
    return np.where(takes & np.isfinite(nearest), nearest, rate)
