"""The last section carried along its boundary's movement below the deepest bench (:class:`DepthTrend`).

The boundary moves by ``carried * f`` across itself ``f`` bench heights below,
and the last section, smoothed of the waver its contour has between holes
(:func:`core.geometry.sdf.smoothed_section`), is carried along that movement
(:meth:`DepthTrend.field`): a displacement fitted over a neighbourhood within
classes of the boundary's direction (:func:`displacement_by_direction`). A curved
boundary's slide along itself, which its movement across itself shows as growth,
is taken off (:func:`sliding_bias`). How far the movement is carried is chosen in
:mod:`core.model.extrapolation`.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from scipy import ndimage
from shapely.geometry import MultiPolygon

from core.geometry.grid import Grid, local_gaussian_filter, without_specks
from core.geometry.sdf import closed_gaps, smoothed_section
from core.model.fields import TRANSPORTS_MEMO, BenchFields, parts_touching
from core.model.movement import unit_normals

#: Neighbourhood over which the boundary's movement is fitted by a displacement when the
#: last section is carried along it (:meth:`DepthTrend.field`), in hole spacings, and the
#: number of direction classes it is fitted within (:func:`displacement_by_direction`). Chosen
#: on the tuning seeds only: every neighbourhood from 0.5 to 6 spacings gained over adding
#: the movement to ``F``; 3 spacings within 4 directions was best pooled, and kept splits
#: moving apart where one class for all directions froze their inner boundaries. Each
#: bench's section errs by a fraction of a spacing that does not repeat from bench to
#: bench; this averaging cancels it (averaging the rate as well, over 1.5 spacings before
#: the transport, no longer gained: 0.1 and 0.4 F1 points better without).
TRANSPORT_SMOOTHING_SPACINGS = 3.0
TRANSPORT_DIRECTIONS = 4

#: Ridge of the displacement's fit (:func:`displacement_by_direction`), a share of the neighbourhood's
#: weight: it keeps a straight boundary's displacement across it. Chosen on development seeds 0-11
#: among 0.1, 0.01 and 0.001 (pooled F1 at 10 m 94.1, 94.2, 94.2; 0.1 took 40% off the translation
#: of a disc's boundary, 0.01 9%, 0.001 2%, and 5%, 0.3% and 0% off a straight one's).
RIDGE_SHARE = 0.01
#: How far from a cell whose signed distance has a direction a body's ridge reaches (cells; see
#: :attr:`DepthTrend._ridge`). A signed distance's ridge is one or two cells wide (on constructed strips moving
#: further than their half-width, 1,911 of 1,935 ridge cells lay within 1.5 cells of a directed one, all within 2).
RIDGE_REACH_CELLS = 2.0

#: Evidence of a cell that only benches above the deepest observed is kept while it is more likely than not to
#: hold at the predicted elevation: while ``carried_precision ** benches`` is at least this,
#: ``carried_precision`` the share of the geozone's carried section that the next bench confirmed, backtested
#: on its own benches (:func:`core.model.extrapolation.carried_precision`). Layers, strips and folds are
#: confirmed at 0.8-0.97 a bench and keep it for 2-6 benches; lenses that end or jump within a bench or two at
#: 0.1-0.5 and lose it at once. Bodies reaching the next bench
#: (:func:`core.model.extrapolation.body_continuity`), used before, counted a lens 15 m away as reached: on
#: the tuning seeds 90% of the lenses it kept were wrong (pods +0.2 and +0.1 F1 points at 5 and 10 m, +0.8 and
#: +0.5 with 3-4 m patterns, other families and Kennecott within 0.1).
STALE_EVIDENCE_PROBABILITY = 0.5
#: At the deepest bench's own level, evidence is stale only where last seen more than this many bench heights
#: above it (a bench above the one above; half a bench's slack for uneven benches). A bench is drilled over
#: weeks: with its first blast patterns in the table, the rest of it, last seen one bench up, lost that evidence
#: at once wherever the geozone's carried sections were confirmed less than half the time, though the benches
#: above alone predicted it there (Kennecott's bench 3 drilled over its southern 40%: 3110 and 3221 predicted
#: absent from the other 60%, F1 on its held-back holes 63.9 -> 50.6). Below that level the rule is unchanged:
#: applied there too, it put pods under holding the last bench at 5 m (tuning seeds 0-11, 63.5 -> 63.1 F1).
STALE_AT_DEEPEST_BENCHES = 1.5

#: Where a partly drilled deepest bench's first holes meet the ground benches above saw last, a first hole's
#: cell moves in that ground's fit as the ground does where its own movement from the bench above is within
#: this many hole spacings of the ground's carried movement a bench (:meth:`DepthTrend._seam_filled`). On the
#: families' tuning seeds 0-2 (`bench_partial_bench.py`, 90 cuts) the first holes' mean gain over the benches
#: above alone -0.54 -> -0.48 F1 points with 1 spacing (worse by a point in 21 -> 20 cuts), -0.49 (18) with
#: 0.5; pods unchanged with either (their lenses' movement disagrees across the seam).
SEAM_AGREEMENT_SPACINGS = 1.0

#: How many sections' transports the memo keeps: a Kennecott build's 363 trends made 197 (90 sections; 16 kept, 90).
TRANSPORTS_KEPT = 4


@dataclass
class DepthTrend:
    """A geozone's signed distance below its deepest bench (see the module docstring).

    Per cell: the signed distance ``f_last`` at the deepest bench that
    observed the cell (elevation ``z_last``), the outward movement of its
    boundary per bench height downwards ``rate`` (in the direction of
    extrapolation) and the part of it that carries on, ``carried``
    (:func:`core.model.extrapolation.chosen_persistence`, :data:`core.model.extrapolation.GROWTH_CONTINUITY_POWER`). The
    boundary moves ``m = carried * (z_last - z) / bench_height_m`` metres
    outwards (along ``-grad F``), and ``F(z)`` is ``f_last`` carried by that
    movement (:meth:`field`).
    ``transport_smoothing_m``: the neighbourhood over which the movement is
    fitted by a displacement. ``carried_precision`` is the share of a
    carried section the next bench confirms (:func:`core.model.extrapolation.carried_precision`) and
    ``f_deepest`` the deepest bench's signed distance: where the benches above
    it saw the geozone and the deepest did not drill, the geozone is kept only
    while ``carried_precision ** benches`` stays at least
    :data:`STALE_EVIDENCE_PROBABILITY`. ``f_above``, the bench above the
    deepest's signed distance, is what the older ground beside a partly
    drilled deepest bench's first holes fetches at their cells
    (:attr:`_older_section`).
    """

    grid: Grid
    z_ref_m: float  #: elevation of the deepest known bench
    bench_height_m: float
    f_last: np.ndarray
    z_last: np.ndarray
    rate: np.ndarray
    carried: np.ndarray
    transport_smoothing_m: float
    carried_precision: float
    f_deepest: np.ndarray
    drilled_any: np.ndarray  #: cells some bench drilled
    #: The bench above the deepest's signed distance and the Gaussian (metres) the last section was smoothed
    #: by: where a deepest bench drilled over part of the pit meets the ground benches above saw last, that
    #: ground is carried from this section at the first holes' cells (:attr:`_older_section`). None: not kept.
    f_above: np.ndarray | None = None
    section_smoothing_m: float = 0.0
    #: The disc the carried section is closed by a bench below the deepest (:meth:`gaps_closed`), metres; 0: none.
    gap_closing_m: float = 0.0

    def movement(self, z_m: float) -> np.ndarray:
        """Metres the boundary moves outwards from ``z_last`` to ``z_m``, per cell."""
        return self.carried * (self.z_last - z_m) / self.bench_height_m

    def field(self, z_m: float) -> np.ndarray:
        """Signed distance to the predicted boundary at elevation ``z_m`` (past the deepest bench).

        The last signed distance is transported (semi-Lagrangian, as the
        level set of ALGORITHMS.md is advected) by the displacement
        ``d``, ``F(x) = f_last(x + d)``, ``d`` fitted to the movements
        ``m = d . n`` across the boundary (``n = grad F / |grad F|``) over
        ``transport_smoothing_m`` among cells whose boundary faces the same
        way (:func:`displacement_by_direction`): ``m n`` where the boundary
        is straight, the whole translation where it curves. For a section
        that moves by a translation the displacement is that translation at
        both of its boundaries, so a strip or fold limb that moves further
        than its half-width per bench is carried whole, where adding ``m`` to
        ``F`` (exact only where ``F`` is linear along the movement) thinned it
        at its ridge. On a body's ridge, where ``F`` has no direction,
        ``f_last`` moves as the slower of its two sides (:attr:`_ridge`);
        elsewhere without a direction (the cap, the ridges between bodies)
        ``f_last + m`` is kept. Where the boundary recedes
        (``d . n < 0``), ``F`` is at most ``f_last + d . n``, exact for a
        straight boundary and never reached on the trailing side of a convex
        body: a displacement wider than the gap between the two parts of a
        split fetched the other part's inside into the gap. Where only benches above the
        deepest saw the geozone and its bodies have likely ended by ``z_m``
        (see the class), the deepest bench's evidence is taken instead. A part
        of the region that no bench drilled any of is dropped (:meth:`_evidenced`). At the deepest bench's own
        level, the ground beside a partly drilled bench's first holes is carried with their cells moving as
        the ground beside them, where the two movements agree (:meth:`_seam_filled`).
        """
        movement = self.movement(z_m)
        field = self._transported(movement)
        seam = self._seam_filled(movement, z_m)
        if seam is not None:
            older, filled = seam
            field = np.where(older, self._transported(filled, self._older_section), field)
        field = np.where(self.ended(z_m), np.minimum(field, self.f_deepest), field)
        return self._evidenced(self.gaps_closed(field, z_m))

    def gaps_closed(self, field: np.ndarray, z_m: float) -> np.ndarray:
        """``field`` at ``z_m`` closed by a disc growing from none at the deepest bench to :attr:`gap_closing_m` a bench below.

        A gap or embayment of the deepest section a few spacings wide rests on the one or two holes across it, and
        where the geozone's own benches showed such gaps filling below (:func:`core.model.extrapolation.gap_closing_m`)
        they are filled: by half-way down the first bench below those half as wide (:func:`core.geometry.sdf.closed_gaps`),
        from a bench below all those narrower than the disc's diameter. The disc grows from none at the deepest
        bench's level, where the section is the one its holes show, so a surface through the two has no ledge.
        """
        benches_below = (self.z_ref_m - z_m) / self.bench_height_m
        if self.gap_closing_m <= 0 or benches_below <= 0:
            return field
        return closed_gaps(field, self.gap_closing_m * min(benches_below, 1.0), self.grid.cell_size_m)

    def _seam_filled(self, movement: np.ndarray, z_m: float) -> tuple[np.ndarray, np.ndarray] | None:
        """At a partly drilled deepest bench's level, its older ground and ``movement`` with the seam filled.

        A deepest bench drilled over part of the pit (its first blast patterns) holds its cells where it saw
        them: no movement at its own level. The displacement carrying the ground beside them, which benches
        above saw last, is fitted over :attr:`transport_smoothing_m` (three spacings), and there the first
        holes' nothing was averaged into its movement: its boundary lagged along their edge (a boundary
        moving 6 m a bench, 64 m along the seam where it is at 66). Where a first hole's cell moved from the
        bench above (``rate``) as the older ground nearest it is carried a bench (within
        :data:`SEAM_AGREEMENT_SPACINGS`), the cell takes that ground's movement in the older ground's fit;
        elsewhere it keeps its zero. Either fill everywhere (the nearest older cell's movement, or the cell's
        own from the bench above) gained strips and cost pods and fold hinges, where movement does not hold
        across the seam: the first holes' mean gain over the benches above alone on the families' 90 cuts
        -0.54 -> -0.57 and -0.63 F1 points; filled where the two agree, -0.48 (strips -0.73 -> -0.39, folds
        -0.59 -> -0.37, pods unchanged, no family down by more than 0.11).
        Returns None where there is no seam: off the deepest bench's level (below it, or above the top bench
        when the fields are extrapolated upwards), or a bench that saw every cell.
        """
        if self.transport_smoothing_m <= 0 or abs(z_m - self.z_ref_m) > 1e-6 * self.bench_height_m:
            return None
        older = ~self.seen_by_deepest
        if not older.any() or older.all():
            return None
        nearest = tuple(ndimage.distance_transform_edt(~older, return_distances=False, return_indices=True))
        # Per bench: the older ground's carried movement against the first holes' own from the bench above.
        spacing_m = self.transport_smoothing_m / TRANSPORT_SMOOTHING_SPACINGS
        agree = ~older & (np.abs(self.rate - self.carried[nearest]) <= SEAM_AGREEMENT_SPACINGS * spacing_m)
        return older, np.where(agree, movement[nearest], movement)

    def _transported(self, movement: np.ndarray, source: np.ndarray | None = None) -> np.ndarray:
        """``f_last`` carried by ``movement`` (metres outwards, per cell), before :meth:`field` ends stale evidence.

        ``source``: the section the displacement fetches from, where not ``f_last`` (:attr:`_older_section`).
        """
        source = self.f_last if source is None else source
        field = self.f_last + movement
        if self.transport_smoothing_m > 0:
            n_r, n_c, directed = self._normals
            move = movement / self.grid.cell_size_m  # the class weights are 0 where there is no direction
            d_r, d_c = displacement_by_direction(move, n_r, n_c, self._flow_systems, self._sigma_cells)
            rows, cols = np.indices(self.f_last.shape, dtype=float)
            carried = ndimage.map_coordinates(source, [rows + d_r, cols + d_c], order=1, mode="nearest")
            field = np.where(directed, carried, field)
            across = (d_r * n_r + d_c * n_c) * self.grid.cell_size_m  # metres the boundary moves outwards here
            receding = directed & (across < 0)
            field = np.where(receding, np.minimum(field, self.f_last + across), field)
            # A body's ridge moves as its sides' slower movement: a strip carried past its half-width leaves it.
            field[self._ridge] = self.f_last[self._ridge] + ridge_sides(np.where(directed, across, np.inf), self._ridge)
        return field

    def _evidenced(self, field: np.ndarray) -> np.ndarray:
        """``field`` with each part of its region that no bench drilled any cell of set outside.

        Past the drilled area a bench's ``F`` extends its nearest evidence
        (:func:`core.model.fields.bench_distance`); tens of metres out the distances to the
        nearest inside and outside holes differ by a few metres, either way,
        and a part of the region there rests on none: the demo's model drew a
        body 450 m2 in size 35-50 m past the pit's edge, where no bench had
        the geozone.
        """
        inside = field > 0
        unevidenced = inside & ~parts_touching(inside, self.drilled_any, np.ones((3, 3)))
        return np.where(unevidenced, np.minimum(field, -self.grid.cell_size_m), field)

    def ended(self, z_m: float) -> np.ndarray:
        """Cells whose evidence is older than the deepest bench and likely no longer holds at ``z_m``.

        At the deepest bench's own level, the rest of a bench drilled over part of the pit is judged as the
        benches above alone judge it (:data:`STALE_AT_DEEPEST_BENCHES`): evidence from the bench above is fresh.
        """
        benches = np.abs(self.z_last - z_m) / self.bench_height_m
        at_deepest = z_m >= self.z_ref_m - 1e-6 * self.bench_height_m
        fresh_m = STALE_AT_DEEPEST_BENCHES * self.bench_height_m if at_deepest else 0.0
        stale = np.abs(self.z_ref_m - self.z_last) > fresh_m
        return stale & (self.carried_precision**benches < STALE_EVIDENCE_PROBABILITY)

    @cached_property
    def seen_by_deepest(self) -> np.ndarray:
        """Cells the deepest bench saw last (its drilling): the first holes, where it is drilled over part of the pit."""
        return np.abs(self.z_last - self.z_ref_m) < 1e-6 * self.bench_height_m

    @cached_property
    def _older_section(self) -> np.ndarray | None:
        """The section the ground benches above saw last carries at a partly drilled deepest bench's level.

        ``f_last``, but at the deepest bench's own cells the bench above's section (:attr:`f_above`, smoothed as
        ``f_last`` is). That ground is carried a bench along its displacement, and near the seam the displacement
        fetched from the first holes' cells, whose section is already at the new level: carried a bench further, a
        boundary moving 6 m a bench moved 12. On the families' worst cut (folds, tuning seed 0, the bench's 40%
        from 64 degrees) 23 of the 32 held-back holes the first holes lost fetched from their cells; fetched from
        the bench above's section there, 25 of them came right and 5 went wrong (that cut 85.5 -> 89.6 F1, 90.9
        from the benches above alone). On the families' 90 cuts (tuning seeds 0-2) the first holes' mean gain over
        the benches above alone -0.48 -> -0.32 F1 points, every family up or unchanged (folds -0.37 -> -0.09, pods
        unchanged); Kennecott's 15 cuts 74.198 -> 74.241 with the first holes. None without :attr:`f_above`.
        Not kept for a geozone the deepest bench drilled and did not find (:func:`core.model.extrapolation._section_movement`).
        """
        if self.f_above is None:
            return None
        at_deepest = self.seen_by_deepest
        along_m = self.transport_smoothing_m
        above = smoothed_section(self.f_above, self.grid.cell_size_m, self.section_smoothing_m, along_m)
        return np.where(at_deepest, above, self.f_last)

    # What the transport needs of the last section alone: made once per trend, not per elevation.
    @cached_property
    def _sigma_cells(self) -> float:
        return self.transport_smoothing_m / self.grid.cell_size_m

    @cached_property
    def _normals(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return unit_normals(self.f_last, self.grid.cell_size_m)

    @cached_property
    def _flow_systems(self) -> list[tuple[np.ndarray, tuple]]:
        n_r, n_c, directed = self._normals
        classes = direction_classes(np.arctan2(n_r, n_c), directed, self._sigma_cells)
        return flow_systems(n_r, n_c, classes, self._sigma_cells)

    @cached_property
    def _ridge(self) -> np.ndarray:
        """Cells of a body's ridge: inside, with no normal, within :data:`RIDGE_REACH_CELLS` of cells that have one.

        Its signed distance there moves as the slower of the boundaries on either side moves (outwards: the
        least ``d . n`` of the directed cells around it), as a strip's spine does: it stays inside while both
        sides move out (a body growing), leaves when one side recedes past it (a strip carried further than
        its half-width a bench, a body thinning out). Further in lies the cap's plateau, which keeps
        ``f_last + m``. Kept as ``f_last + m`` with its nearest boundary's movement, the ridge of a strip
        carried past its half-width stayed inside: a chain of islands along the old strip's spine
        (constructed strips 12-24 m wide moving 9-16 m a bench: IoU 0.77-0.94 -> 0.84-0.97, each in one part
        where ten of twelve were in 4-20).
        """
        _, _, directed = self._normals
        if not directed.any():
            return np.zeros_like(directed)
        return ~directed & (self.f_last > 0) & (ndimage.distance_transform_edt(~directed) <= RIDGE_REACH_CELLS)

    def region(self, z_m: float) -> MultiPolygon:
        """The region ``F > 0`` at ``z_m`` less its parts and holes smaller than a cell, which the field cannot resolve.

        Those are slivers where ``F`` grazes zero (a saddle, the far field past
        the drilling): below the demo's deepest bench the host geozone had
        dozens, most of no area at all, and g2 holes of a few hundredths of a m2.
        """
        return without_specks(self.grid.polygons_from_distance(self.field(z_m)), self.grid.cell_size_m**2)

    def replaced(self, **changes) -> DepthTrend:
        """A copy with ``changes`` (not of the last section) that shares what the transport made of the last section."""
        other = replace(self, **changes)
        other.__dict__.update(self.transport())
        return other

    def transport(self) -> dict:
        """What the transport makes of the last section alone (its cached properties), to share with another trend."""
        return {name: getattr(self, name) for name in ("_sigma_cells", "_normals", "_flow_systems", "_ridge")}


def ridge_sides(across: np.ndarray, ridge: np.ndarray) -> np.ndarray:
    """At each ``ridge`` cell, the least of ``across`` within :data:`RIDGE_REACH_CELLS` (a square window).

    :func:`scipy.ndimage.minimum_filter`'s value (its reflecting edges), taken only at the ridge's cells: a
    ridge is a line a cell or two wide, and the filter over the whole grid ran at every elevation of every
    prediction and backtest.
    """
    reach = int(RIDGE_REACH_CELLS)
    padded = np.pad(across, reach, mode="symmetric")
    windows = np.lib.stride_tricks.sliding_window_view(padded, (2 * reach + 1, 2 * reach + 1))
    rows, cols = np.nonzero(ridge)
    return windows[rows, cols].min(axis=(1, 2))


def direction_classes(theta: np.ndarray, valid: np.ndarray, sigma_cells: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Weights of :data:`TRANSPORT_DIRECTIONS` overlapping classes of boundary normal, and their local sums.

    Class ``k`` weighs a cell ``max(cos(theta - theta_k), 0) ** 4`` (``theta``:
    the normal's angle, radians; 0 where not ``valid``); its local sum is the
    weight's Gaussian average over ``sigma_cells`` (at least 1e-3).
    """
    classes = []
    for k in range(TRANSPORT_DIRECTIONS):
        w = np.maximum(np.cos(theta - 2 * np.pi * k / TRANSPORT_DIRECTIONS), 0.0) ** 4 * valid
        classes.append((w, np.maximum(local_gaussian_filter(w, sigma_cells), 1e-3)))
    return classes


def flow_systems(
    n_r: np.ndarray, n_c: np.ndarray, classes: list[tuple[np.ndarray, np.ndarray]], sigma_cells: float
) -> list[tuple[np.ndarray, tuple]]:
    """Per direction class, its weight and the inverse of the normal equations of :func:`displacement_by_direction`.

    They rest on the boundary's normals alone: made once per section, not per
    elevation. The inverse is a 3 x 3 nested tuple of per-cell arrays.
    """
    systems = []
    for w, weight in classes:
        rr, rc, r1, c1 = (local_gaussian_filter(w * x, sigma_cells) for x in (n_r * n_r, n_r * n_c, n_r, n_c))
        cc = weight - rr  # n_r^2 + n_c^2 = 1 where w > 0
        ridge = RIDGE_SHARE * weight + 1e-9
        systems.append(
            (w, _inverse_symmetric_3x3([[rr + ridge, rc, r1], [rc, cc + ridge, c1], [r1, c1, weight + ridge]]))
        )
    return systems


def displacement_by_direction(
    movement: np.ndarray, n_r: np.ndarray, n_c: np.ndarray, systems: list[tuple[np.ndarray, tuple]], sigma_cells: float
) -> tuple[np.ndarray, np.ndarray]:
    """The displacement that moves each boundary cell's neighbourhood as its movements across itself say.

    The benches measure only the movement of a boundary across itself,
    ``m_i = d . n_i`` (``n_i`` the unit normal, pointing inside): the aperture
    problem. Where the boundary curves within a neighbourhood its normals
    turn, and together they fix the whole displacement (normal flow, as
    Lucas-Kanade solves it). Per cell, the least-squares fit over a Gaussian
    neighbourhood of ``sigma_cells`` of::

        m_i = v . n_i + a

    a translation ``v`` and a growth ``a``, with a ridge of
    :data:`RIDGE_SHARE` of the neighbourhood's weight (where the normals do
    not turn, it leaves ``v`` across the boundary only), gives the displacement ``v + a n`` at the
    cell. A translating body's end moves whole; averaging ``m_i n_i`` instead
    moved it by the mean of ``cos^2`` over the arc (0.6 of the movement on a
    lobe 22 m in radius), the far ends of merging lobes running out.

    Each section's boundary errs by a fraction of a hole spacing that does
    not repeat from bench to bench; the fit over the neighbourhood cancels it.
    Across a narrow gap, the opposite movements of two parts moving apart (a
    split) would cancel too, so each cell fits only with cells whose boundary
    faces its way: within each of the :func:`direction_classes`, weighted by
    its class weight (``systems``: :func:`flow_systems`). ``movement`` in
    cells; returns ``(d_r, d_c)`` in cells.
    """
    out_r, out_c, total = np.zeros_like(movement), np.zeros_like(movement), np.zeros_like(movement)
    for w, inverse in systems:
        b = [local_gaussian_filter(w * movement * x, sigma_cells) for x in (n_r, n_c, 1.0)]
        v_r, v_c, a = (row[0] * b[0] + row[1] * b[1] + row[2] * b[2] for row in inverse)
        out_r += w * (v_r + a * n_r)
        out_c += w * (v_c + a * n_c)
        total += w
    total = np.maximum(total, 1e-9)
    return out_r / total, out_c / total


def sliding_bias(rate: np.ndarray, matched: np.ndarray, section: DepthTrend) -> np.ndarray:
    """The part of a boundary's measured movement that is its slide along itself, seen across a curve.

    :func:`core.model.movement.boundary_movement` measures along the newer boundary's normal. A
    curved boundary that translates by ``d`` lies ``d . n + k (d . t)^2 / 2``
    outside its older self there (``k`` its curvature, ``t`` its tangent):
    at the sides of a disc moving 10 m a bench, 2 m of seeming growth per
    bench, which carried on widened it by 6 m across its path one bench down
    (exact signed distances, no holes). The slide ``d . t`` is the
    displacement that :func:`displacement_by_direction` fits to the
    movements with the fits ``section``'s transport makes of its last
    section ``f_last`` (shared with it); the curvature is the boundary's,
    averaged over the same neighbourhood. Returns the bias per cell (metres,
    as ``rate``: each cell takes its nearest boundary cell's), 0 where the
    movement was not matched.
    """
    f_last, cell_size_m, sigma = section.f_last, section.grid.cell_size_m, section._sigma_cells
    n_r, n_c, directed = section._normals
    band = (np.abs(f_last) <= cell_size_m) & directed & matched
    if not band.any():
        return np.zeros_like(rate)
    movement = np.where(matched, rate, 0.0) / cell_size_m
    d_r, d_c = displacement_by_direction(movement, n_r, n_c, section._flow_systems, sigma)
    slide_m = (d_c * n_r - d_r * n_c) * cell_size_m
    # The level sets' curvature, -div n (positive where the geozone is convex), averaged along the boundary.
    s_r, s_c, _ = unit_normals(ndimage.gaussian_filter(f_last, 1.0), cell_size_m)
    curvature = -(np.gradient(s_r, axis=0) + np.gradient(s_c, axis=1)) / cell_size_m
    weight = local_gaussian_filter(band.astype(float), sigma)
    curvature = local_gaussian_filter(np.where(band, curvature, 0.0), sigma) / np.maximum(weight, 1e-9)
    bias = np.where(band, 0.5 * curvature * slide_m**2, 0.0)
    _, (r, c) = ndimage.distance_transform_edt(~band, return_indices=True)
    return np.where(matched, bias[r, c], 0.0)


def _inverse_symmetric_3x3(m: list[list[np.ndarray]]) -> tuple:
    """The inverse of a symmetric, nonsingular 3 x 3 matrix per element, by its adjugate."""
    c00 = m[1][1] * m[2][2] - m[1][2] ** 2
    c01 = m[0][2] * m[1][2] - m[0][1] * m[2][2]
    c02 = m[0][1] * m[1][2] - m[0][2] * m[1][1]
    c11 = m[0][0] * m[2][2] - m[0][2] ** 2
    c12 = m[0][1] * m[0][2] - m[0][0] * m[1][2]
    c22 = m[0][0] * m[1][1] - m[0][1] ** 2
    det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02
    i00, i01, i02, i11, i12, i22 = (c / det for c in (c00, c01, c02, c11, c12, c22))
    return ((i00, i01, i02), (i01, i11, i12), (i02, i12, i22))


def with_shared_transport(fields: BenchFields, section: DepthTrend) -> DepthTrend:
    """``section`` sharing its transport (:meth:`DepthTrend.transport`) with the fields' recent trends of the same section.

    The benches' trends at each dip (:func:`core.model.extrapolation.with_backtested_dip`) and each way
    to carry the movement (:func:`core.model.extrapolation._ways_backtest`) start from the same last
    section, one after another: a Kennecott build made 363 trends of 90
    sections, and the transport's normals and fits were a tenth of its time.
    The last :data:`TRANSPORTS_KEPT` are kept in ``fields.memo`` (each a few
    dozen grids), keyed by the section itself.
    """
    kept = fields.memo.setdefault(TRANSPORTS_MEMO, OrderedDict())
    f_last = section.f_last  # its bytes in C order, whatever its layout
    key = (
        f_last.shape,
        section.grid.cell_size_m,
        section.transport_smoothing_m,
        hashlib.blake2b(f_last.tobytes(), digest_size=16).digest(),
    )
    if key in kept:
        kept.move_to_end(key)
        section.__dict__.update(kept[key])
    else:
        kept[key] = section.transport()
        if len(kept) > TRANSPORTS_KEPT:
            kept.popitem(last=False)
    return section
