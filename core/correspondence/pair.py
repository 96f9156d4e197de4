"""Spatial correspondence between two successive benches (paper section 3).

Given the component boundaries of one geozone on an upper bench ("sources")
and on the bench below ("targets"), this stage

1. decides which sources may interact with which targets (region association,
   paper section 3.1, eqs. (1)-(9)), and
2. estimates a rigid translation per source that best aligns it with its
   targets, subject to spatial constraints (component alignment, section 3.2,
   Algorithms 4-7), decomposing complex relations into subtrees (3.2.4).

The result groups sources and targets into *morph instances*: connected sets
of the post-alignment association graph, which the contour metamorphosis stage
(paper section 4) then works on in the motion-compensated frame.

Everything here works on shapely polygons in the local metric frame (metres)
and on one common :class:`core.geometry.grid.Grid` per bench pair. No global state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
import shapely
from scipy import ndimage
from shapely import affinity
from shapely.geometry import MultiPolygon, Polygon

from core.errors import BGMInputError
from core.geometry.grid import Grid, as_multipolygon
from core.geometry.sdf import signed_distance

#: Default lower limit of the association radius, as a multiple of the hole
#: spacing (``mu_lower`` in eqs. (6)-(7)). Lateral drift of a boundary between
#: benches is typically of the order of one or two hole spacings.
MU_LOWER_PER_HOLE_SPACING = 1.5
#: Default cells per hole spacing for the alignment grid.
CELLS_PER_HOLE_SPACING = 4
#: The default cell size is enlarged so the grid stays at most this many cells across.
MAX_CELLS_ACROSS = 512
#: Explicit cell sizes that would make the grid larger than this are refused.
HARD_MAX_CELLS_ACROSS = 4096
#: Value given to target cells in ports reserved for other sources, as a
#: multiple of the deepest target SDF value (Algorithm 5-6 "large negative").
PORT_PENALTY_FACTOR = 4.0
#: One-to-many reward (Algorithm 7): cells in the gap between a splitting
#: source's targets get this fraction of the SDF of the targets' convex hull
#: (1 aligns the source with the target group as if it were one region).
BRIDGE_REWARD_FRACTION = 1.0


# ----------------------------------------------------------------------------
# Data classes
# ----------------------------------------------------------------------------


@dataclass
class Port:
    """An angular sector of a target reserved for one source (Algorithms 5-6).

    Attributes
    ----------
    target : int
        Target index.
    source : int
        Source index the sector is reserved for.
    start_rad : float
        Start angle (radians, counter-clockwise from +x) around ``centre_xy``.
    width_rad : float
        Angular width of the sector, proportional to the source area.
    centre_xy : tuple of float
        Target centroid (metres) the sectors radiate from.
    """

    target: int
    source: int
    start_rad: float
    width_rad: float
    centre_xy: tuple[float, float]

    def contains_angle(self, angle_rad: np.ndarray) -> np.ndarray:
        """Whether angles (radians) fall inside this sector."""
        return np.mod(np.asarray(angle_rad) - self.start_rad, 2 * np.pi) < self.width_rad

    def to_dict(self) -> dict:
        return {
            "target": self.target,
            "source": self.source,
            "start_rad": self.start_rad,
            "width_rad": self.width_rad,
            "centre_xy": list(self.centre_xy),
        }


@dataclass
class Subtree:
    """Subtree of the intersection graph rooted at one source (section 3.2.4).

    ``source -> targets -> co_sources[target]``: the root source, its associated
    targets, and for each of those the *other* sources associated with it.
    """

    source: int
    targets: list[int]
    co_sources: dict[int, list[int]]

    @property
    def kind(self) -> str:
        """``"none"``, ``"one-to-one"``, ``"many-to-one"``, ``"one-to-many"`` or ``"many-to-many"``."""
        if not self.targets:
            return "none"
        shared = any(self.co_sources.get(t) for t in self.targets)
        if len(self.targets) == 1:
            return "many-to-one" if shared else "one-to-one"
        return "many-to-many" if shared else "one-to-many"


@dataclass
class MorphInstance:
    """One connected set of the post-alignment association graph.

    The sources in ``source_ids`` (after translation) morph into the targets in
    ``target_ids`` (paper end of section 3). Either side may be empty: a source
    with no target pinches out, a target with no source is a new pod.
    """

    target_ids: list[int]
    source_ids: list[int]

    def to_dict(self) -> dict:
        return {"target_ids": list(self.target_ids), "source_ids": list(self.source_ids)}


@dataclass
class SourceField:
    """What the alignment of one source saw (for viewers and debugging)."""

    source: int
    target_ids: list[int]
    value_function: np.ndarray | None
    ports: list[Port]
    locked: bool = False

    def to_dict(self, include_arrays: bool = False) -> dict:
        out = {
            "source": self.source,
            "target_ids": list(self.target_ids),
            "ports": [p.to_dict() for p in self.ports],
            "locked": self.locked,
        }
        if include_arrays and self.value_function is not None:
            out["value_function"] = self.value_function.tolist()
        return out


@dataclass
class PairCorrespondence:
    """Result of :func:`correspond_pair` for one source/target bench pair.

    Attributes
    ----------
    association : (ns, nt) bool array
        Final association: the tentative matrix (with overrides) minus edges
        whose source, once translated, no longer touches the target (section
        3.2.4: "eliminate edges where a connection does not exist"); forced
        pairs are always kept.
    translations : (ns, 2) float array
        Translation ``(dx, dy)`` in metres applied to each source.
    instances : list of MorphInstance
        Connected sets of ``association`` (plus lone sources / lone targets).
    initial_association : (ns, nt) bool array
        Association before alignment (eq. (8) plus safeguard plus overrides).
    cell_size_m : float
        Cell size of the alignment grid.
    mu_lower_m : float
        Lower limit of the association radius used.
    grid : Grid or None
        The alignment grid (``None`` when there was nothing to grid).
    fields : dict
        Per-source :class:`SourceField` when ``keep_fields`` was requested.
    """

    association: np.ndarray
    translations: np.ndarray
    instances: list[MorphInstance]
    initial_association: np.ndarray
    cell_size_m: float
    mu_lower_m: float
    grid: Grid | None = None
    fields: dict[int, SourceField] = field(default_factory=dict)

    def to_dict(self, include_arrays: bool = False) -> dict:
        """JSON-friendly summary (value-function arrays only if ``include_arrays``)."""
        out = {
            "association": self.association.astype(bool).tolist(),
            "initial_association": self.initial_association.astype(bool).tolist(),
            "translations_m": np.asarray(self.translations, dtype=float).tolist(),
            "instances": [i.to_dict() for i in self.instances],
            "cell_size_m": float(self.cell_size_m),
            "mu_lower_m": float(self.mu_lower_m),
        }
        if self.grid is not None:
            out["grid"] = {
                "x0": self.grid.x0,
                "y0": self.grid.y0,
                "cell_size_m": self.grid.cell_size_m,
                "shape": list(self.grid.shape),
            }
        if self.fields:
            out["fields"] = {str(k): f.to_dict(include_arrays) for k, f in sorted(self.fields.items())}
        return out


# ----------------------------------------------------------------------------
# Region association (section 3.1)
# ----------------------------------------------------------------------------


def _geom(g) -> MultiPolygon:
    return as_multipolygon(g)


def _union_bounds(geoms) -> tuple[float, float, float, float] | None:
    bs = [g.bounds for g in geoms if not g.is_empty]
    if not bs:
        return None
    b = np.array(bs)
    return (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max())


def _cell_xy(grid: Grid, mask: np.ndarray, geom) -> np.ndarray:
    """World coordinates of the cells of ``mask``; a representative point if none."""
    rr, cc = np.nonzero(mask)
    if rr.size == 0:
        p = geom.representative_point()
        return np.array([[p.x, p.y]])
    return grid.rc_to_xy(np.column_stack([rr, cc]))


def association_matrix(
    sources: list[Polygon | MultiPolygon],
    targets: list[Polygon | MultiPolygon],
    *,
    mu_lower_m: float,
    grid: Grid | None = None,
    target_masks: dict[int, np.ndarray] | None = None,
) -> np.ndarray:
    """Tentative source-target association matrix (paper section 3.1).

    Parameters
    ----------
    sources, targets : list of Polygon or MultiPolygon
        Components of the upper ("source") and lower ("target") bench, local
        frame, metres.
    mu_lower_m : float
        Lower limit ``mu_lower`` of the association scale (eq. (6)), metres;
        it also normalises the standard error in ``nu`` (eq. (7)).
    grid : Grid, optional
        Grid on which the likelihood is evaluated over each target's cells.
        Default: about 256 cells across the union of all components.
    target_masks : dict, optional
        Cache ``{target: rasterised mask on grid}``; missing entries are
        rasterised and stored (lets the caller reuse them).

    Returns
    -------
    (ns, nt) bool array
        ``A[s, t]`` true when source ``s`` may interact with target ``t``.

    Notes
    -----
    * ``d_{s,t}`` is the shapely polygon-to-polygon distance (0 when the two
      overlap or touch). We prefer it to the centroid distance: a component's
      boundary is what moves between benches, and centroid distances between
      components of very different size would swamp the apparent motion
      statistics. Then ``d_min[s] = min_t d_{s,t}`` (eq. (1)), ``mu`` and
      ``sigma`` its mean and (population) standard deviation (eq. (2)), and
      ``s = sigma / sqrt(ns)`` the standard error.
    * ``lambda_s = max(min(mu, phi_s), mu_lower)`` with ``phi_s =
      sqrt(a_s / pi)`` (eq. (6)); ``nu = 4 / (1 + exp(-s / mu_lower))``
      (eq. (7)); ``p_s(x) = exp(-(|x - c_s| / lambda_s)^2 / (2 nu^2))``
      (eq. (5)) with ``c_s`` the source centroid.
    * ``A(s, t) = 1`` iff the ``K``-th percentile of ``p_s`` over the cells of
      target ``t`` is at least 0.5, ``K = 50 (1 + (1 - min(a_s / a_t, 1)))``
      (eqs. (8)-(9)). A target too small to contain a cell centre is
      represented by one interior point.
    * Safeguard (not in the paper): a source and a target that overlap or
      touch (``d_{s,t} = 0``) are always associated. With a large target and a
      small ``lambda_s`` the median likelihood over the target can fall below
      0.5 even when the source lies right on top of it, which would wrongly
      make the target a new pod.
    * Empty geometries are associated with nothing and do not enter the
      statistics.
    """
    ns, nt = len(sources), len(targets)
    A = np.zeros((ns, nt), dtype=bool)
    if ns == 0 or nt == 0:
        return A
    if not (mu_lower_m > 0 and np.isfinite(mu_lower_m)):
        raise ValueError(f"mu_lower_m must be positive, got {mu_lower_m}")
    src = [_geom(s) for s in sources]
    tgt = [_geom(t) for t in targets]
    s_ok = np.array([not g.is_empty for g in src])
    t_ok = np.array([not g.is_empty for g in tgt])
    if not s_ok.any() or not t_ok.any():
        return A

    d = np.full((ns, nt), np.inf)
    si, ti = np.nonzero(s_ok[:, None] & t_ok[None, :])
    d[si, ti] = shapely.distance(np.array(src, dtype=object)[si], np.array(tgt, dtype=object)[ti])
    d_min = d[s_ok].min(axis=1)
    n_eff = int(s_ok.sum())
    mu = float(np.mean(d_min))
    sigma = float(np.sqrt(max(np.mean(d_min**2) - mu**2, 0.0)))
    s_err = sigma / math.sqrt(n_eff)
    nu = 4.0 / (1.0 + math.exp(-s_err / mu_lower_m))

    a_s = np.array([g.area for g in src])
    a_t = np.array([g.area for g in tgt])
    phi = np.sqrt(a_s / np.pi)
    lam = np.maximum(np.minimum(mu, phi), mu_lower_m)
    c_s = np.array([[g.centroid.x, g.centroid.y] if not g.is_empty else [np.nan, np.nan] for g in src])

    if grid is None:
        grid = Grid.for_extent(_union_bounds(src + tgt), cells_across=256, margin_cells=2)
    if target_masks is None:
        target_masks = {}

    ok_src = np.nonzero(s_ok)[0]
    for t in np.nonzero(t_ok)[0]:
        if t not in target_masks:
            target_masks[t] = grid.rasterize(tgt[t])
        xy = _cell_xy(grid, target_masks[t], tgt[t])
        diff = xy[None, :, :] - c_s[ok_src, None, :]
        r2 = np.einsum("sck,sck->sc", diff, diff) / lam[ok_src, None] ** 2
        p = np.exp(-r2 / (2.0 * nu**2))
        ratio = np.minimum(a_s[ok_src] / max(a_t[t], 1e-300), 1.0)
        K = 50.0 * (1.0 + (1.0 - ratio))
        for row, s in enumerate(ok_src):
            A[s, t] = np.percentile(p[row], K[row]) >= 0.5
    A |= d <= 0.0  # safeguard: overlapping / touching pairs always associate
    return A


# ----------------------------------------------------------------------------
# Displacement estimation (section 3.2.1, Algorithm 4)
# ----------------------------------------------------------------------------


def fft_translation(
    source_mask: np.ndarray,
    value_function: np.ndarray,
    *,
    obstacle_mask: np.ndarray | None = None,
    subpixel: bool = False,
) -> tuple[float, float]:
    """Lag maximising the cross-correlation of a source mask with a value function.

    Implements eqs. (10)-(12) (Algorithm 4): ``r[m] = sum_i v[i] u[i - m]``
    computed as ``F^-1(V U*)``, returning ``argmax_m r[m]`` as ``(d_row,
    d_col)``: moving the source by ``+d_row`` rows and ``+d_col`` columns puts
    it where it best matches ``v``. (Eq. (11) writes ``u[i + m]``; the lag
    returned here is the shift to apply to the source, i.e. ``-m``.)

    Parameters
    ----------
    source_mask : (rows, cols) bool array
        ``u``, the source indicator.
    value_function : (rows, cols) float array
        ``v``, normally the target SDF (positive inside), possibly with port
        penalties or rewards.
    obstacle_mask : (rows, cols) bool array, optional
        Cells the shifted source must not cover (e.g. already placed sources).
        Lags covering any of them are excluded; if every lag does, the
        constraint is dropped.
    subpixel : bool
        Refine the peak by a separable parabola fit (within half a cell) when
        all four neighbouring lags are admissible.

    Returns
    -------
    (d_row, d_col) : tuple of float
        The lag in cells (integers unless ``subpixel``). ``(0, 0)`` for an
        empty source.

    Notes
    -----
    The source is cropped to its bounding box ``h x w`` and correlated with
    ``v`` zero padded to ``next_fast_len(rows + h - 1)`` by
    ``next_fast_len(cols + w - 1)`` (the full linear correlation length), so
    no lag wraps around (paper footnote on first-quadrant support and padding,
    Gonzalez & Woods 4.6.4). Only lags keeping the whole shifted source inside
    the frame are considered ("valid" correlation), so the zero padding never
    enters a score. Ties are broken by the smallest shift.
    """
    u = np.asarray(source_mask, dtype=bool)
    v = np.asarray(value_function, dtype=float)
    if u.shape != v.shape:
        raise ValueError(f"source mask {u.shape} and value function {v.shape} differ in shape")
    if not u.any():
        return (0.0, 0.0)
    rows, cols = u.shape
    rr = np.nonzero(u.any(axis=1))[0]
    cc = np.nonzero(u.any(axis=0))[0]
    r0, r1, c0, c1 = rr[0], rr[-1], cc[0], cc[-1]
    crop = u[r0 : r1 + 1, c0 : c1 + 1].astype(float)
    h, w = crop.shape
    nr = scipy.fft.next_fast_len(rows + h - 1, real=True)
    nc = scipy.fft.next_fast_len(cols + w - 1, real=True)
    U_conj = np.conj(scipy.fft.rfft2(crop, s=(nr, nc)))

    def correlate(field: np.ndarray) -> np.ndarray:
        F = scipy.fft.rfft2(field, s=(nr, nc))
        return scipy.fft.irfft2(F * U_conj, s=(nr, nc))[: rows - h + 1, : cols - w + 1]

    r = correlate(v)
    valid = np.ones(r.shape, dtype=bool)
    if obstacle_mask is not None and np.any(obstacle_mask):
        hits = correlate(np.asarray(obstacle_mask, dtype=float))
        free = hits < 0.5
        if free.any():
            valid = free
    score = np.where(valid, r, -np.inf)
    best = float(score.max())
    tol = 1e-9 * max(float(np.abs(r[valid]).max()), 1.0)
    cand_r, cand_c = np.nonzero(score >= best - tol)
    lag_r = cand_r - r0
    lag_c = cand_c - c0
    k = int(np.argmin(lag_r.astype(float) ** 2 + lag_c.astype(float) ** 2))
    a, b = int(cand_r[k]), int(cand_c[k])
    d_row, d_col = float(a - r0), float(b - c0)
    if subpixel:
        d_row += _parabolic(score, valid, (a, b), axis=0)
        d_col += _parabolic(score, valid, (a, b), axis=1)
    return (d_row, d_col)


def _parabolic(score: np.ndarray, valid: np.ndarray, at: tuple[int, int], axis: int) -> float:
    a, b = at
    n = score.shape[axis]
    i = at[axis]
    if i <= 0 or i >= n - 1:
        return 0.0
    if axis == 0:
        idx = [(a - 1, b), (a, b), (a + 1, b)]
    else:
        idx = [(a, b - 1), (a, b), (a, b + 1)]
    if not all(valid[p] for p in idx):
        return 0.0
    fm, f0, fp = (float(score[p]) for p in idx)
    den = fm - 2.0 * f0 + fp
    if not den < 0:
        return 0.0
    return float(np.clip(0.5 * (fm - fp) / den, -0.5, 0.5))


def _frame_for(geoms, cell_size_m: float, pad_m: float) -> Grid:
    b = _union_bounds(geoms)
    return Grid.covering((b[0] - pad_m, b[1] - pad_m, b[2] + pad_m, b[3] + pad_m), cell_size_m, 0)


def align_translation_m(
    source: Polygon | MultiPolygon,
    target: Polygon | MultiPolygon,
    *,
    cell_size_m: float,
    subpixel: bool = True,
) -> tuple[float, float]:
    """Single-source single-target translation in metres (Algorithm 4).

    Rasterises both polygons on a common grid of ``cell_size_m`` padded by the
    source extent (so the source can reach any placement overlapping the
    target), correlates the source mask with the target SDF (core.geometry.sdf,
    Algorithm 3) and returns ``(dx_m, dy_m)`` to add to the source.
    """
    src, tgt = _geom(source), _geom(target)
    if src.is_empty or tgt.is_empty:
        return (0.0, 0.0)
    xmin, ymin, xmax, ymax = src.bounds
    pad = max(xmax - xmin, ymax - ymin) + 4 * cell_size_m
    grid = _frame_for([src, tgt], cell_size_m, pad)
    v = signed_distance(grid.rasterize(tgt), cell_size_m)
    d_row, d_col = fft_translation(grid.rasterize(src), v, subpixel=subpixel)
    return (d_col * cell_size_m, d_row * cell_size_m)


# ----------------------------------------------------------------------------
# Graph decomposition and port allocation (sections 3.2.2-3.2.4)
# ----------------------------------------------------------------------------


def subtrees(association: np.ndarray) -> list[Subtree]:
    """Decompose the intersection graph into subtrees rooted at each source (3.2.4).

    Subtree ``s``: ``s -> {t : A[s, t]}``, each target expanded to the other
    sources associated with it. E.g. the paper's type C example gives
    ``s1 -> {t0 <- s0, t2 <- (s2, s3)}``.
    """
    A = np.asarray(association, dtype=bool)
    out = []
    for s in range(A.shape[0]):
        targets = [int(t) for t in np.nonzero(A[s])[0]]
        co = {t: [int(o) for o in np.nonzero(A[:, t])[0] if o != s] for t in targets}
        out.append(Subtree(source=s, targets=targets, co_sources=co))
    return out


def allocate_ports(
    target: int,
    centre_xy: tuple[float, float],
    source_ids: list[int],
    source_centroids_xy: np.ndarray,
    source_areas_m2: np.ndarray,
) -> list[Port]:
    """Divide a target into angular ports, one per source (Algorithms 5-6).

    Parameters
    ----------
    target : int
        Target index (recorded in the ports).
    centre_xy : (float, float)
        Target centroid, metres; sectors radiate from it.
    source_ids : list of int
        Sources sharing the target.
    source_centroids_xy : (n, 2) array
        Their centroids, metres (same order as ``source_ids``).
    source_areas_m2 : (n,) array
        Their areas; each port's angular width is proportional to its area.

    Returns
    -------
    list of Port
        One per source, in ``source_ids`` order; together they cover the circle.

    Notes
    -----
    Each source's direction is ``theta_s = atan2(c_s - c_t)``. Contiguous
    sectors taken in the sources' angular order never cross, so the
    assignment keeps that cyclic order; the free rotation ``alpha`` of the
    whole arrangement then minimises the sum of squared (circular) angular
    differences between each sector's bisector and its source's direction,
    i.e. ``alpha`` is the circular mean of ``theta_s - offset_s``.
    """
    n = len(source_ids)
    c = np.asarray(centre_xy, dtype=float)
    xy = np.asarray(source_centroids_xy, dtype=float).reshape(n, 2)
    areas = np.maximum(np.asarray(source_areas_m2, dtype=float), 0.0)
    if n == 0:
        return []
    if areas.sum() <= 0:
        areas = np.ones(n)
    widths = 2 * np.pi * areas / areas.sum()
    theta = np.arctan2(xy[:, 1] - c[1], xy[:, 0] - c[0])
    order = np.argsort(theta, kind="stable")
    starts_rel = np.concatenate([[0.0], np.cumsum(widths[order])[:-1]])
    mids_rel = starts_rel + widths[order] / 2
    alpha = float(np.angle(np.sum(np.exp(1j * (theta[order] - mids_rel)))))
    ports: dict[int, Port] = {}
    for k, idx in enumerate(order):
        ports[int(idx)] = Port(
            target=int(target),
            source=int(source_ids[idx]),
            start_rad=float(np.mod(alpha + starts_rel[k], 2 * np.pi)),
            width_rad=float(widths[idx]),
            centre_xy=(float(c[0]), float(c[1])),
        )
    return [ports[i] for i in range(n)]


# ----------------------------------------------------------------------------
# Main entry
# ----------------------------------------------------------------------------


def default_parameters(hole_spacing_m: float, extent_m: float, cell_size_m: float | None = None) -> tuple[float, float]:
    """Default ``(mu_lower_m, cell_size_m)`` for a hole spacing.

    ``mu_lower_m = 1.5 * hole_spacing_m`` (lateral drift of a boundary between
    benches is of the order of a hole spacing or two). The cell size is a
    quarter of the hole spacing, enlarged if needed so a grid spanning
    ``extent_m`` stays within :data:`MAX_CELLS_ACROSS` cells.
    """
    mu_lower = MU_LOWER_PER_HOLE_SPACING * hole_spacing_m
    if cell_size_m is None:
        cell_size_m = hole_spacing_m / CELLS_PER_HOLE_SPACING
        cell_size_m = max(cell_size_m, extent_m / (MAX_CELLS_ACROSS - 1))
    return mu_lower, cell_size_m


def _check_positive(name: str, value) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise BGMInputError(f"{name} must be a number, got {value!r}.") from None
    if not (value > 0 and np.isfinite(value)):
        raise BGMInputError(f"{name} must be a positive finite number, got {value}.")
    return value


def correspond_pair(  # noqa: C901 - to be split into named steps
    sources: list[Polygon | MultiPolygon],
    targets: list[Polygon | MultiPolygon],
    *,
    hole_spacing_m: float,
    mu_lower_m: float | None = None,
    cell_size_m: float | None = None,
    locked_translations: dict[int, tuple[float, float]] | None = None,
    forced: set[tuple[int, int]] = frozenset(),
    forbidden: set[tuple[int, int]] = frozenset(),
    keep_fields: bool = False,
) -> PairCorrespondence:
    """Associate and align the components of two successive benches (section 3).

    Parameters
    ----------
    sources, targets : list of Polygon or MultiPolygon
        Components of one geozone on the upper (source) and lower (target)
        bench, in the local frame, metres.
    hole_spacing_m : float
        Typical blasthole spacing; sets the defaults below.
    mu_lower_m : float, optional
        Minimum association scale ``mu_lower`` (eq. (6)). Default
        ``1.5 * hole_spacing_m``.
    cell_size_m : float, optional
        Alignment grid cell. Default ``hole_spacing_m / 4``, enlarged so the
        grid stays within 512 cells across.
    locked_translations : dict, optional
        ``{source: (dx_m, dy_m)}``: these sources use the given translation
        (manual override) and act as fixed obstacles for the others.
    forced, forbidden : set of (source, target)
        Pairs added to / removed from the association matrix. Forced pairs are
        kept in the final association even if the aligned source misses the
        target.
    keep_fields : bool
        Keep each source's value function and ports in ``fields``.

    Returns
    -------
    PairCorrespondence

    Notes
    -----
    Steps:

    1. Tentative association (section 3.1, :func:`association_matrix`), then
       the overrides.
    2. Sources are placed one at a time: locked sources and sources without
       any target first (fixed: the latter get ``(0, 0)``), then the rest by
       decreasing area. For source ``s`` the subtree ``s -> T_s -> co-sources``
       (section 3.2.4) defines its value function ``v``:

       * the SDF of the union of its targets (Algorithm 3, section 3.2.1);
       * many-to-one (3.2.2): every target shared with other sources is cut
         into angular ports (:func:`allocate_ports`); target cells in ports of
         other sources get ``-PORT_PENALTY_FACTOR * max(SDF)``;
       * one-to-many (3.2.3, Algorithm 7): targets the source could bridge
         (gap below its extent) are grouped and the gap of their convex hull
         is rewarded (:func:`_split_value_function`), so straddling pays;
       * already placed sources (dilated by one cell) are hard obstacles, so
         aligned sources do not overlap each other.

       The translation is the arg-max of the FFT cross-correlation of the
       source mask with ``v`` (:func:`fft_translation`, Algorithm 4), refined to
       sub-cell precision by a parabola fit.
    3. Edges of the tentative association whose translated source is more than
       one cell away from the target are dropped (section 3.2.4); forced edges
       stay. Connected sets of the result are the morph instances.
    """
    hole_spacing_m = _check_positive("hole_spacing_m", hole_spacing_m)
    if mu_lower_m is not None:
        mu_lower_m = _check_positive("mu_lower_m", mu_lower_m)
    if cell_size_m is not None:
        cell_size_m = _check_positive("cell_size_m", cell_size_m)
    src = [_geom(s) for s in sources]
    tgt = [_geom(t) for t in targets]
    ns, nt = len(src), len(tgt)
    locked = {} if locked_translations is None else dict(locked_translations)
    _check_overrides(ns, nt, locked, forced, forbidden)

    extents = [max(g.bounds[2] - g.bounds[0], g.bounds[3] - g.bounds[1]) for g in src if not g.is_empty]
    max_extent = max(extents, default=0.0)
    bounds = _union_bounds(src + tgt)
    span = 0.0 if bounds is None else max(bounds[2] - bounds[0], bounds[3] - bounds[1])
    mu_default, cell = default_parameters(
        hole_spacing_m, span + max_extent + 8 * hole_spacing_m / CELLS_PER_HOLE_SPACING, cell_size_m
    )
    mu_lower = mu_default if mu_lower_m is None else mu_lower_m

    translations = np.zeros((ns, 2))
    if bounds is None:
        A0 = np.zeros((ns, nt), dtype=bool)
        return PairCorrespondence(A0, translations, _instances(A0), A0.copy(), cell, mu_lower, None, {})

    # Frame: all components plus half the largest source extent (a source
    # aligned over a target rarely sticks out further than that) and 4 cells.
    pad = 0.5 * max_extent + 4 * cell
    grid = _frame_for(src + tgt, cell, pad)
    if max(grid.shape) > HARD_MAX_CELLS_ACROSS:
        raise BGMInputError(
            f"cell size {cell} m makes a {grid.shape[0]} x {grid.shape[1]} alignment grid; "
            f"use a cell size of at least {span / MAX_CELLS_ACROSS:.3g} m."
        )

    t_masks: dict[int, np.ndarray] = {}
    A = association_matrix(src, tgt, mu_lower_m=mu_lower, grid=grid, target_masks=t_masks)
    for s, t in forced:
        A[s, t] = True
    for s, t in forbidden:
        A[s, t] = False
    A_initial = A.copy()

    # Per-target SDFs (computed lazily: only associated targets need them).
    t_sdfs: dict[int, np.ndarray] = {}

    def target_sdf(t: int) -> np.ndarray:
        if t not in t_masks:
            t_masks[t] = grid.rasterize(tgt[t])
        if t not in t_sdfs:
            t_sdfs[t] = signed_distance(t_masks[t], cell)
        return t_sdfs[t]

    a_s = np.array([g.area for g in src])
    c_s = np.array([[g.centroid.x, g.centroid.y] if not g.is_empty else [0.0, 0.0] for g in src])

    # Ports for every shared target (computed once, from original positions).
    ports_by_target: dict[int, list[Port]] = {}
    for t in range(nt):
        sharing = [int(s) for s in np.nonzero(A[:, t])[0]]
        if len(sharing) > 1 and not tgt[t].is_empty:
            ct = tgt[t].centroid
            ports_by_target[t] = allocate_ports(t, (ct.x, ct.y), sharing, c_s[sharing], a_s[sharing])

    X, Y = grid.cell_centres()
    trees = subtrees(A)
    fields: dict[int, SourceField] = {}
    placed_mask = np.zeros(grid.shape, dtype=bool)

    def place(s: int, d_xy, mask: np.ndarray | None = None) -> None:
        # Obstacle for later sources: the placed source, dilated by one cell
        # (which also covers the sub-cell rounding of ``mask``).
        translations[s] = d_xy
        if src[s].is_empty:
            return
        if mask is None:
            mask = grid.rasterize(affinity.translate(src[s], float(d_xy[0]), float(d_xy[1])))
        placed_mask[:] |= ndimage.binary_dilation(mask)

    fixed = [s for s in range(ns) if s in locked or not trees[s].targets or src[s].is_empty]
    for s in fixed:
        place(s, locked.get(s, (0.0, 0.0)))
        if keep_fields:
            fields[s] = SourceField(s, trees[s].targets, None, [], locked=s in locked)
    movable = sorted((s for s in range(ns) if s not in fixed), key=lambda s: (-a_s[s], s))

    for s in movable:
        tree = trees[s]
        v = np.max(np.stack([target_sdf(t) for t in tree.targets]), axis=0)
        if len(tree.targets) > 1:
            b = src[s].bounds
            reach = max(b[2] - b[0], b[3] - b[1])
            v = _split_value_function(grid, tree.targets, tgt, t_masks, t_sdfs, reach, v)
        deepest = max(float(v.max()), cell)
        used_ports: list[Port] = []
        for t in tree.targets:
            if t in ports_by_target:
                used_ports.extend(ports_by_target[t])
                ang = np.arctan2(Y - ports_by_target[t][0].centre_xy[1], X - ports_by_target[t][0].centre_xy[0])
                for port in ports_by_target[t]:
                    if port.source == s:
                        continue
                    banned = t_masks[t] & port.contains_angle(ang)
                    v[banned] = -PORT_PENALTY_FACTOR * deepest
        u = grid.rasterize(src[s])
        d_row, d_col = fft_translation(u, v, obstacle_mask=placed_mask, subpixel=True)
        place(s, (d_col * cell, d_row * cell), _shift_mask(u, round(d_row), round(d_col)))
        if keep_fields:
            fields[s] = SourceField(s, tree.targets, v, used_ports)

    # Post-alignment association (3.2.4): drop edges that no longer touch.
    A_final = A.copy()
    for s, t in zip(*np.nonzero(A)):
        if (int(s), int(t)) in forced:
            continue
        moved = affinity.translate(src[s], *translations[s])
        if moved.distance(tgt[t]) > cell:
            A_final[s, t] = False

    return PairCorrespondence(
        association=A_final,
        translations=translations,
        instances=_instances(A_final),
        initial_association=A_initial,
        cell_size_m=cell,
        mu_lower_m=mu_lower,
        grid=grid,
        fields=fields if keep_fields else {},
    )


def _shift_mask(mask: np.ndarray, d_row: int, d_col: int) -> np.ndarray:
    """``mask`` moved by whole cells, zero filled (no wrap-around)."""
    out = np.zeros_like(mask)
    rows, cols = mask.shape
    r_src = slice(max(0, -d_row), min(rows, rows - d_row))
    c_src = slice(max(0, -d_col), min(cols, cols - d_col))
    r_dst = slice(max(0, d_row), min(rows, rows + d_row))
    c_dst = slice(max(0, d_col), min(cols, cols + d_col))
    if r_src.start < r_src.stop and c_src.start < c_src.stop:
        out[r_dst, c_dst] = mask[r_src, c_src]
    return out


def _split_value_function(
    grid: Grid,
    targets: list[int],
    tgt: list[MultiPolygon],
    t_masks: dict[int, np.ndarray],
    t_sdfs: dict[int, np.ndarray],
    reach_m: float,
    v_union: np.ndarray,
) -> np.ndarray:
    """Value function with rewards for straddling several targets (Algorithm 7).

    The source's targets are clustered by single linkage on their gaps: two
    targets closer than ``reach_m`` (the source's extent, i.e. gaps it could
    actually bridge) belong together. For each cluster of two or more
    targets, the convex hull of the cluster is the "strategic location": the
    value there is the SDF of the hull, positive in the gap between targets
    (scaled by ``BRIDGE_REWARD_FRACTION``) as well as inside them, so the
    source is aligned with the target group as a whole. Lone targets keep
    their own SDF. The value function is the maximum over clusters.
    """
    n = len(targets)
    parent = list(range(n))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            if tgt[targets[i]].distance(tgt[targets[j]]) <= reach_m:
                parent[find(i)] = find(j)
    clusters: dict[int, list[int]] = {}
    for i in range(n):
        clusters.setdefault(find(i), []).append(targets[i])
    if all(len(c) == 1 for c in clusters.values()):
        return v_union
    out = np.full(grid.shape, -np.inf)
    for members in clusters.values():
        if len(members) == 1:
            np.maximum(out, t_sdfs[members[0]], out=out)
            continue
        hull = shapely.union_all([tgt[t] for t in members]).convex_hull
        hull_mask = grid.rasterize(hull)
        hull_sdf = signed_distance(hull_mask, grid.cell_size_m)
        inside = np.zeros(grid.shape, dtype=bool)
        for t in members:
            inside |= t_masks[t]
        gap = hull_mask & ~inside
        value = np.where(gap, BRIDGE_REWARD_FRACTION * hull_sdf, hull_sdf)
        np.maximum(out, value, out=out)
    return out


def _check_overrides(ns, nt, locked, forced, forbidden) -> None:
    for s, d in locked.items():
        if not (isinstance(s, (int, np.integer)) and 0 <= s < ns):
            raise BGMInputError(f"locked translation refers to source {s}, but there are {ns} sources.")
        if len(tuple(d)) != 2 or not all(np.isfinite(float(x)) for x in d):
            raise BGMInputError(f"locked translation of source {s} must be two finite numbers, got {d!r}.")
    for name, pairs in (("forced", forced), ("forbidden", forbidden)):
        for s, t in pairs:
            if not (0 <= s < ns and 0 <= t < nt):
                raise BGMInputError(f"{name} association ({s}, {t}) is out of range for {ns} sources and {nt} targets.")
    both = set(forced) & set(forbidden)
    if both:
        raise BGMInputError(f"association {sorted(both)[0]} is both forced and forbidden.")


def _instances(A: np.ndarray) -> list[MorphInstance]:
    """Connected sets of the bipartite association graph (lone nodes included)."""
    ns, nt = A.shape
    parent = list(range(ns + nt))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for s, t in zip(*np.nonzero(A)):
        a, b = find(int(s)), find(ns + int(t))
        if a != b:
            parent[a] = b
    groups: dict[int, tuple[list[int], list[int]]] = {}
    for i in range(ns + nt):
        g = groups.setdefault(find(i), ([], []))
        if i < ns:
            g[1].append(i)
        else:
            g[0].append(i - ns)
    inst = [MorphInstance(target_ids=sorted(ts), source_ids=sorted(ss)) for ts, ss in groups.values()]
    inst.sort(key=lambda m: (m.target_ids[0] if m.target_ids else nt + 1, m.source_ids[0] if m.source_ids else ns + 1))
    return inst
