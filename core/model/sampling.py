"""Where to sample next: the holes whose labels would most reduce the boundaries' uncertainty.

The paper's Discussion ends on adaptive sampling: a predicted slope is worth
having because it makes the next drilling and assaying "more targeted and
cost-effective". Given the calibrated :class:`core.model.uncertainty.SectionUncertainty`
of one or more geozones on the next bench, this module chooses ``N`` holes
among candidates (a planned blast pattern, or the last bench's pattern laid
over the ground that can be drilled next) greedily:

* what a label at a point settles about a geozone is the chance that the
  predicted section has the point on the wrong side, ``min(p, 1 - p)`` with
  ``p = P(inside)`` (:func:`misclassification`, doubled: 1 on the predicted
  boundary when it is uncertain, 0 deep inside or far outside). The
  section's IoU counts misclassified area, so this is what a label can gain
  it; the binary entropy, which weighs the band's tails more, bought 0.1-0.7
  IoU points less at every budget on the tuning seeds and Kennecott;
* a candidate is worth what it would settle about its neighbourhood: the
  chances summed over candidates nearby, weighted by
  ``exp(-d^2 / 2 l^2)`` (``l`` a hole spacing, :data:`REDUNDANCY_SPACINGS`);
* holes in a band (of any of the geozones) are chosen before the others;
* after each choice the chances near it are discounted by the same
  weight (``H <- H (1 - exp(-d^2 / 2 l^2))``), so the next hole goes where
  the boundary is still unknown rather than next to the last one.

Several geozones share one budget: their chances add up, and a hole
discounts it for all of them. :func:`revealed_field` is the other half: the
predicted section updated with the labels of the holes revealed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import shapely
from scipy import ndimage, sparse, special
from scipy.spatial import cKDTree

from core.io.blastholes import median_hole_spacing
from core.model.progress import CONTOURS_STAGE, FIELDS_STEP, GeozoneSteps, geozone_stage, one_at_a_time
from core.model.uncertainty import DEFAULT_PROBABILITY, SectionUncertainty, geozone_uncertainty
from core.threads import Progress, on_threads

#: Reach of a revealed label's correction of the predicted section (:func:`revealed_field`), in hole
#: spacings: a label corrects the boundary about two holes around it (chosen on tuning seeds,
#: ``bench_uncertainty.py --tuning``; 1 or 1.5 spacings lowered every strategy's estimate).
INFLUENCE_SPACINGS = 2.0
#: How far a chosen hole makes its neighbours' labels redundant when holes are suggested (the ``l``
#: of the module docstring), in hole spacings: one spacing, so a band is sampled hole by hole along
#: the predicted boundary. Chosen on the tuning seeds and Kennecott, with the correction's reach
#: fixed (IoU at 5 / 10 / 20% of the holes, tuning seeds 0-3: 80.0 / 80.7 / 81.5 against 79.2 /
#: 79.7 / 81.3 with two spacings; Kennecott 78.6 / 81.1 / 83.0 against 77.9 / 80.0 / 81.5).
REDUNDANCY_SPACINGS = 1.0
#: Neighbours further than this many ``l`` carry no weight.
KERNEL_REACH = 3.0


@dataclass(frozen=True)
class DrillPattern:
    """A blast pattern as a lattice: holes at ``origin + i along + j across`` for whole ``i, j`` (local metres).

    ``along_m`` is the step between neighbouring holes of a row, ``across_m``
    the step to the nearest hole of the next row (in a staggered pattern it
    is offset by half a spacing along the row; a staggered pattern is the
    same lattice whichever of its three short directions is taken as rows).
    """

    along_m: tuple[float, float]
    across_m: tuple[float, float]
    origin_m: tuple[float, float]

    @property
    def spacing_m(self) -> float:
        """Distance between holes along a row."""
        return float(np.hypot(*self.along_m))

    @property
    def burden_m(self) -> float:
        """Distance between rows."""
        (ax, ay), (bx, by) = self.along_m, self.across_m
        return float(abs(ax * by - ay * bx) / self.spacing_m)

    def lattice(self) -> np.ndarray:
        """``[along, across]`` as the columns of a 2 x 2 matrix."""
        return np.column_stack([self.along_m, self.across_m])


def estimate_pattern(xy: np.ndarray, neighbours: int = 6) -> DrillPattern:
    """The blast pattern of a bench's holes (``(n, 2)`` local metres, at least 3 holes).

    The vectors from each hole to its ``neighbours`` nearest holes, those no
    longer than 1.5 times the hole spacing (the median distance to the third
    nearest, :func:`core.io.blastholes.median_hole_spacing`: the nearest's
    fell to 0.6 of the spacing with holes collared 0.3 of it off the pattern,
    and the steps found were 3.8 m on a 6 m pattern), are the lattice's short
    steps. Folded onto half a turn, their most frequent
    direction (one-degree histogram smoothed over five) gives the rows, the
    most frequent of the others the next row; each step is the mean of the
    steps within 10 degrees of its direction (jitter averages out over
    thousands of steps, where a median of lengths would not place holes 30
    rows away). The lattice is then refined by least squares on every hole's
    whole lattice coordinates, and the origin is the hole nearest the centre.
    A single row gets a square pattern.
    """
    xy = np.asarray(xy, float)
    if len(xy) < 3:
        raise ValueError("a pattern needs at least three holes")
    k = min(neighbours, len(xy) - 1)
    d, idx = cKDTree(xy).query(xy, k=k + 1)
    steps = (xy[idx[:, 1:]] - xy[:, None, :]).reshape(-1, 2)
    length = d[:, 1:].ravel()
    steps = steps[(length > 0) & (length <= 1.5 * median_hole_spacing(xy))]
    along = _step_direction(steps)
    unit = along / np.hypot(*along)
    across_steps = steps[np.abs(unit[0] * steps[:, 1] - unit[1] * steps[:, 0]) > 0.25 * np.hypot(*along)]
    if len(across_steps):
        across = _step_direction(across_steps)
    else:  # a single row: its third-nearest hole is two steps away, so its step is the nearest's
        along = _step_direction(steps[np.hypot(*steps.T) <= 1.5 * np.median(d[:, 1])])
        across = np.array([-along[1], along[0]])
    centre = xy[np.argmin(np.sum((xy - xy.mean(axis=0)) ** 2, axis=1))]
    basis = np.column_stack([along, across])
    for _ in range(2):  # least squares on the whole lattice coordinates of the holes that fit
        ij = np.round(np.linalg.solve(basis, (xy - centre).T).T)
        fit = np.hypot(*(xy - centre - ij @ basis.T).T) < 0.3 * min(np.hypot(*along), np.hypot(*across))
        design = np.column_stack([np.ones(fit.sum()), ij[fit]])
        if fit.sum() < 3 or np.linalg.matrix_rank(design) < 3:  # a single row fixes no step across it
            break
        solution = np.linalg.lstsq(design, xy[fit], rcond=None)[0]
        centre, basis = solution[0], solution[1:].T
    return DrillPattern(tuple(basis[:, 0]), tuple(basis[:, 1]), (float(centre[0]), float(centre[1])))


def _step_direction(steps: np.ndarray) -> np.ndarray:
    """The mean of the steps along their most frequent direction (folded onto half a turn)."""
    angle = np.mod(np.arctan2(steps[:, 1], steps[:, 0]), np.pi)
    counts = np.bincount(np.minimum(np.degrees(angle).astype(int), 179), minlength=180).astype(float)
    peak = np.radians(int(np.argmax(ndimage.uniform_filter1d(counts, 5, mode="wrap"))) + 0.5)
    unit = np.array([np.cos(peak), np.sin(peak)])
    near = np.abs(((np.degrees(angle - peak) + 90) % 180) - 90) <= 10
    folded = steps[near] * np.sign(steps[near] @ unit)[:, None]
    return folded.mean(axis=0)


def lay_out(pattern: DrillPattern, area) -> np.ndarray:
    """The pattern's holes inside ``area`` (a shapely polygon, local metres), ``(n, 2)``."""
    if area.is_empty:
        return np.zeros((0, 2))
    basis = pattern.lattice()
    corners = np.array(shapely.get_coordinates(shapely.envelope(area))) - np.asarray(pattern.origin_m)
    ij = np.linalg.solve(basis, corners.T).T
    lo, hi = np.floor(ij.min(axis=0)) - 1, np.ceil(ij.max(axis=0)) + 1
    i, j = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1), indexing="ij")
    xy = np.asarray(pattern.origin_m) + np.column_stack([i.ravel(), j.ravel()]) @ basis.T
    return xy[shapely.contains_xy(area, xy[:, 0], xy[:, 1])]


def misclassification(p: np.ndarray) -> np.ndarray:
    """``2 min(p, 1 - p)``: twice the chance that a point with ``P(inside) = p`` is on the other side (1 at 1/2)."""
    p = np.asarray(p, float)
    return 2.0 * np.minimum(p, 1.0 - p)


@dataclass(frozen=True)
class Suggestion:
    """One suggested hole.

    ``candidate`` indexes the candidates it was chosen from; ``geozone`` is
    the one whose boundary it tells most about, with its ``probability_inside``
    there and ``distance_m``, the signed distance to its predicted boundary
    (positive inside); ``in_band`` whether it lies in that geozone's band;
    ``information`` what it was expected to settle: its neighbourhood's
    :func:`misclassification`, summed with the kernel's weights.

    ``probability_inside`` and ``in_band`` are those of the section as given
    (its P(inside) and band, what ``p_inside.npz``, ``uncertainty.geojson``
    and the sampling map show), although holes are chosen on its observed
    scale (:meth:`~core.model.uncertainty.SectionUncertainty.as_observed`).
    """

    candidate: int
    xy_m: tuple[float, float]
    geozone: str
    probability_inside: float
    distance_m: float
    in_band: bool
    information: float


def suggest_holes(
    sections: Mapping[str, SectionUncertainty],
    candidates_m: np.ndarray,
    budget: int,
    hole_spacing_m: float,
    progress: Progress | None = None,
) -> list[Suggestion]:
    """Choose ``budget`` of the candidates whose labels would most reduce the sections' uncertainty.

    Parameters
    ----------
    sections : mapping of geozone -> SectionUncertainty
        The predicted sections on the bench to sample (one budget for all);
        those without a predicted contact (:attr:`SectionUncertainty.has_contact`) take no part.
    candidates_m : (n, 2) float
        Where holes can go (local metres): a planned pattern, or :func:`lay_out`.
    budget : int
        Holes to choose (at most ``n``).
    hole_spacing_m : float
        Sets how far a chosen hole makes its neighbours redundant (:data:`REDUNDANCY_SPACINGS`).
    progress : callable, optional
        ``progress(chosen, budget)`` after each hole chosen; raising :class:`core.threads.Cancelled`
        there stops the choice (a viewer's superseded request).

    Returns
    -------
    list of Suggestion
        In the order chosen (most informative first); none where no candidate lies in a band.
    """
    xy = np.asarray(candidates_m, float).reshape(-1, 2)
    # A geozone predicted absent has no contact to pin down: with a scale at the distance cap its band covered
    # the whole bench, and its holes were told "in the band, 41 m from predicted contact" (the cap).
    names = [g for g in sections if sections[g].has_contact]
    if not len(xy) or not names or budget <= 0:
        return []
    # Chosen on the observed scale; told as the section given is written (its band and P(inside) in the files).
    written = {g: sections[g] for g in names}
    sections = {g: sections[g].as_observed() for g in names}
    at = {g: sections[g].at(xy) for g in names}
    info = np.stack([misclassification(at[g][2]) for g in names])  # (geozones, candidates)
    weights = influence_matrix(xy, REDUNDANCY_SPACINGS * hole_spacing_m)
    score = weights @ info.sum(axis=0)
    # A hole outside every band would tell what the prediction already knows there: holes in a band go first,
    # and where no candidate lies in one (a geozone sure of its contact) there is nothing to pin down.
    in_band = np.any([sections[g].in_band(xy) for g in names], axis=0)
    if not in_band.any():
        return []
    chosen: list[Suggestion] = []
    for _ in range(min(int(budget), len(xy))):
        first = np.where(in_band, score, -np.inf)
        c = int(np.argmax(first if np.isfinite(first).any() else score))
        chosen.append(_suggestion(c, xy, names, at, info, written, float(score[c])))
        row = weights.getrow(c)
        near, w = row.indices, row.data
        before = info[:, near].sum(axis=0)
        info[:, near] *= 1.0 - w
        score += weights[:, near] @ (info[:, near].sum(axis=0) - before)
        score[c] = -np.inf
        if progress:
            progress(len(chosen), min(int(budget), len(xy)))
    return chosen


def influence_matrix(xy: np.ndarray, influence_m: float):
    """Sparse ``exp(-d^2 / 2 l^2)`` between points within :data:`KERNEL_REACH` ``l`` (1 on the diagonal)."""
    tree = cKDTree(xy)
    pairs = tree.sparse_distance_matrix(tree, KERNEL_REACH * influence_m, output_type="coo_matrix")
    weights = sparse.coo_matrix(
        (np.exp(-(pairs.data**2) / (2 * influence_m**2)), (pairs.row, pairs.col)), shape=(len(xy), len(xy))
    ).tocsr()
    return weights + sparse.identity(len(xy), format="csr")  # the zero distances left out above


def _suggestion(c, xy, names, at, info, written, information) -> Suggestion:
    """The suggestion of candidate ``c``, told for the geozone it informs most (else the nearest boundary).

    Its P(inside) and band are those of ``written`` (the sections as the files hold them, not
    the observed scale they were chosen on): a hole said to lie in the 90% band lies in the band
    of ``uncertainty.geojson`` and the sampling map, which it did not always (12 of the demo's 62).
    """
    if info[:, c].max() > 0:
        k = int(np.argmax(info[:, c]))
    else:
        k = int(np.argmin([abs(at[g][0][c]) for g in names]))
    g = names[k]
    point = xy[c : c + 1]
    f, _, p = (float(v[0]) for v in written[g].at(point))
    band = bool(written[g].in_band(point)[0])
    return Suggestion(c, (float(xy[c, 0]), float(xy[c, 1])), g, p, f, band, information)


def reason(suggestion: Suggestion, probability: float, unit: str, metres_per_unit: float) -> str:
    """A short reason for a suggestion, e.g. ``boundary band 90%, 3.2 m from predicted contact (inside)``."""
    distance = abs(suggestion.distance_m) / metres_per_unit
    side = "inside" if suggestion.distance_m > 0 else "outside"
    where = f"boundary band {probability:.0%}" if suggestion.in_band else f"beyond the {probability:.0%} band"
    return f"{where}, {distance:.1f} {unit} from predicted contact ({side})"


def revealed_field(
    section: SectionUncertainty, xy_m: np.ndarray, inside: np.ndarray, hole_spacing_m: float
) -> np.ndarray:
    """The predicted signed distance updated with the labels of revealed holes.

    Each label says on which side of the boundary its hole lies. Under the
    prediction's ``N(F, sigma^2)`` at the hole, that makes ``F`` there a
    truncated normal, whose mean and variance (inverse Mills ratio ``lambda``:
    ``F + sign sigma lambda`` and ``sigma^2 (1 - lambda (lambda + sign F /
    sigma))``) are taken as an observation of ``F`` (variance at least half
    a hole spacing squared: where holes place a boundary). The residuals are
    spread by simple kriging with covariance ``sigma(x) sigma(y) exp(-d^2 / 2 l^2)``
    (``l`` = :data:`INFLUENCE_SPACINGS` hole spacings): a hole corrects the section around
    it, not the whole bench.

    Returns
    -------
    (rows, cols) float
        The updated field on the section's grid; ``> 0`` is the updated section.
    """
    xy = np.asarray(xy_m, float).reshape(-1, 2)
    if not len(xy):
        return section.field.copy()
    section = section.as_observed()
    f, s, _ = section.at(xy)
    sign = np.where(np.asarray(inside, bool), 1.0, -1.0)
    a = sign * f / s
    mills = np.exp(-0.5 * a**2 - 0.5 * np.log(2 * np.pi) - special.log_ndtr(a))  # phi(a) / Phi(a), stable in the tails
    mean = f + sign * s * mills
    var = np.maximum(s**2 * (1 - mills * (mills + a)), (0.5 * hole_spacing_m) ** 2)
    ell = INFLUENCE_SPACINGS * hole_spacing_m
    rho = influence_matrix(xy, ell).toarray()
    cov = s[:, None] * s[None, :] * rho + np.diag(var)
    weights = np.linalg.solve(cov, mean - f)
    # sum_i weights_i s_i rho(x, x_i) on the grid: impulses smoothed by a Gaussian of l (peak 1).
    grid = section.grid
    rc = grid.nearest_cells(xy)
    impulses = np.zeros(grid.shape)
    np.add.at(impulses, (rc[:, 0], rc[:, 1]), weights * s)
    width = ell / grid.cell_size_m
    spread = ndimage.gaussian_filter(impulses, width, mode="constant", truncate=KERNEL_REACH) * (2 * np.pi * width**2)
    return section.field + section.sigma * spread


def next_bench_candidates(holes, bench: int | None = None) -> np.ndarray:
    """Where the next bench's holes would go without a planned pattern, ``(n, 2)`` local metres.

    The pattern of bench ``bench`` (the deepest by default; :func:`estimate_pattern`)
    laid over its drilled area: a pit narrows with depth, so the next bench
    lies under the last one, drilled on the same spacing and orientation.
    """
    k = holes.n_benches - 1 if bench is None else int(bench)
    xy = holes.xy[holes.on_bench(k)]
    if len(xy) < 3:
        raise ValueError(f"bench {holes.bench_z_input(k)} has {len(xy)} hole(s); its pattern needs three or more")
    return lay_out(estimate_pattern(xy), holes.drilled_area(k))


@dataclass
class SamplingPlan:
    """Suggested holes on one bench for one or more geozones, and what they were chosen from."""

    z_m: float
    probability: float
    candidates_m: np.ndarray
    sections: dict[str, SectionUncertainty]
    suggestions: list[Suggestion]


def plan_sampling(
    session,
    geozones: list[str],
    budget: int,
    z_m: float,
    candidates_m: np.ndarray | None = None,
    probability: float = DEFAULT_PROBABILITY,
    sections: dict | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> SamplingPlan:
    """Choose ``budget`` holes at elevation ``z_m`` for ``geozones`` (one budget shared by all).

    ``session`` is a :class:`core.model.session.ModelSession`; candidates are
    a planned pattern's holes, or :func:`next_bench_candidates`. Geozones
    without a predicted section there with its uncertainty (at a bench level)
    take no part. ``sections`` (geozone -> SectionUncertainty at ``z_m``)
    saves computing them again. ``progress(stage, done, total)`` is told
    each bench traced (stage ``"contours"``), each step of a geozone's model
    (its bench pairs, then its bench fields: ``"bench fields of geozone
    3310"``) and each geozone's section done (``"geozone 3310"``), as
    :mod:`core.model.progress` says; from several threads, one call at a time.
    """
    spacing = float(session.holes.hole_spacing_m)
    if candidates_m is None:
        candidates_m = next_bench_candidates(session.holes)
    if sections is None:
        geozones = list(geozones)
        say = one_at_a_time(progress)
        # Traced together: each bench's evidence once for all of them.
        session.contours_of(geozones, progress=lambda done, total: say(CONTOURS_STAGE, done, total))

        def section_of(g: str):
            # The model first, step by step (what geozone_uncertainty would make, silently, the same).
            steps = GeozoneSteps(say, g)
            model = session.geozone_model(g, progress=steps.pair)
            steps.step(FIELDS_STEP)
            return geozone_uncertainty(session, g, [z_m], model, probability=probability)[float(z_m)]

        # Each geozone's model and backtests release the GIL in their heavy steps: several at once.
        found = {}
        for g, section in on_threads(section_of, geozones):
            found[g] = section
            say(geozone_stage(g), len(found), len(geozones))
        sections = {g: found[g] for g in geozones if found[g] is not None}  # in the order asked
    chosen = suggest_holes(sections, candidates_m, budget, spacing)
    return SamplingPlan(float(z_m), float(probability), np.asarray(candidates_m, float), sections, chosen)
