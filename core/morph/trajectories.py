"""Particle trajectories of a contour morph and wave-speed adjustment.

Paper section 4 ("Contour metamorphosis", subsections "Iso-contours and wave
speed adjustment" and "Challenges") and ``ALGORITHMS.md`` ("Particle
advection"). Particles start evenly along the source contour and ride the
level-set front of :mod:`core.morph.levelset` along its normal,

    x_{k+1} = x_k - dt * F(x_k) * grad(phi) / |grad(phi)|,   F = clip(gamma_t, -c, c),

(``phi`` positive inside, so ``grad(phi)`` points inward and a particle where
the target lies outside the front, ``gamma_t > 0``, moves outward). ``F`` is
the same clamped speed that moves the front, so a particle stays on the zero
set. A particle ends once it reaches the target contour, ``|gamma_t| < h/2``.

Everything here works in the local metric frame (metres); times are the
dimensionless morph time of :func:`core.morph.levelset.morph_regions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import MultiPolygon, Polygon

from core.geometry.grid import Grid, _polygons


@dataclass
class Trajectory:
    """Path of one particle from the source contour to the target contour.

    Attributes
    ----------
    xy : (n, 2) float array
        Positions in the local frame (metres); ``xy[0]`` lies on the source
        contour, ``xy[-1]`` on the target contour.
    t : (n,) float array
        Morph time of each position, non-decreasing.
    backtracked : bool
        True for trajectories recovered by curvelet backtracking
        (:mod:`core.morph.backtracking`) rather than by particle advection.
    """

    xy: np.ndarray
    t: np.ndarray
    backtracked: bool = False


@dataclass
class ParticleState:
    """Mutable state of the particles during one morph (internal bookkeeping).

    Attributes
    ----------
    xy : (n, 2) float array
        Current positions (metres).
    status : (n,) int array
        0 active, 1 reached the target, 2 lost the front (discarded).
    end_step : (n,) int array
        Step index of the last position of finished particles (-1 while active).
    history : list of (n, 2) arrays
        Positions after every step (``history[0]`` = seeds).
    """

    xy: np.ndarray
    status: np.ndarray
    end_step: np.ndarray
    history: list = field(default_factory=list)


# ---------------------------------------------------------------------------
# sampling helpers
# ---------------------------------------------------------------------------


def bilinear(field_: np.ndarray, rc: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``field_`` at fractional ``(row, col)`` points.

    Points outside the grid are clamped to its edge (like
    ``Grid.sample(..., mode="nearest")``), but this is several times faster
    than ``scipy.ndimage.map_coordinates`` for a few hundred points.

    Parameters
    ----------
    field_ : (rows, cols) array
    rc : (n, 2) array of fractional row, col

    Returns
    -------
    (n,) float array
    """
    rows, cols = field_.shape
    r = np.minimum(np.maximum(rc[:, 0], 0.0), rows - 1.000001)
    c = np.minimum(np.maximum(rc[:, 1], 0.0), cols - 1.000001)
    r0 = r.astype(np.intp)
    c0 = c.astype(np.intp)
    fr = r - r0
    fc = c - c0
    flat = field_.ravel()
    i = r0 * cols + c0
    a = flat[i]
    b = flat[i + 1]
    d = flat[i + cols]
    e = flat[i + cols + 1]
    return (a * (1 - fc) + b * fc) * (1 - fr) + (d * (1 - fc) + e * fc) * fr


def ring_samples(
    region: Polygon | MultiPolygon, spacing_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Evenly spaced points along every ring (exterior and holes) of ``region``.

    Parameters
    ----------
    region : Polygon or MultiPolygon
    spacing_m : float
        Wanted spacing; each ring gets ``ceil(length / spacing_m)`` points, so
        the actual spacing is at most ``spacing_m``.

    Returns
    -------
    xy : (n, 2) float array
    ring : (n,) int array
        Ring number of each point.
    arc_m : (n,) float array
        Arc-length position of each point along its ring.
    weight_m : (n,) float array
        Boundary length represented by each point (sums to the perimeter).
    """
    xs, rings, arcs, weights = [], [], [], []
    k = 0
    for poly in _polygons(region):
        for ring in [poly.exterior, *poly.interiors]:
            length = ring.length
            if length <= 0:
                continue
            n = max(int(np.ceil(length / spacing_m)), 3)
            d = np.arange(n) * (length / n)
            pts = _along(shapely.get_coordinates(ring), d)
            xs.append(pts)
            rings.append(np.full(n, k))
            arcs.append(d)
            weights.append(np.full(n, length / n))
            k += 1
    if not xs:
        empty = np.zeros(0)
        return np.zeros((0, 2)), empty.astype(int), empty, empty
    return np.vstack(xs), np.concatenate(rings), np.concatenate(arcs), np.concatenate(weights)


def _along(coords: np.ndarray, arc_m: np.ndarray) -> np.ndarray:
    """Points at arc lengths ``arc_m`` along the polyline ``coords`` (linear interpolation).

    Same points as ``shapely.line_interpolate_point``, which walks the ring
    once per point (quadratic on long contours).
    """
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(coords, axis=0).T))])
    return np.column_stack([np.interp(arc_m, cum, coords[:, 0]), np.interp(arc_m, cum, coords[:, 1])])


# ---------------------------------------------------------------------------
# particle advection (ALGORITHMS.md "Particle advection"; paper Appendix B eq. 26)
# ---------------------------------------------------------------------------


def seed_particles(source: Polygon | MultiPolygon, spacing_m: float) -> ParticleState:
    """Particles evenly along the source contour(s), about ``spacing_m`` apart."""
    xy, _, _, _ = ring_samples(source, spacing_m)
    n = len(xy)
    return ParticleState(
        xy=xy.copy(),
        status=np.zeros(n, dtype=np.int8),
        end_step=np.full(n, -1, dtype=np.intp),
        history=[xy.copy()],
    )


def advect_particles(
    state: ParticleState,
    grid: Grid,
    phi: np.ndarray,
    gamma_t: np.ndarray,
    dt: float,
    speed_clamp_m: float,
    step: int,
) -> np.ndarray:
    """Move the active particles one level-set step along the front normal.

    ``x <- x - dt * clip(gamma_t, -c, c) * grad(phi)/|grad(phi)|`` with
    ``phi`` (the level set *before* this step's update) and ``gamma_t``
    sampled bilinearly; ``grad(phi)`` is a central difference of bilinear
    samples one cell apart. Particles reaching ``|gamma_t| < h/2`` are marked
    finished at ``step + 1``. Appends the new positions to the history.

    Returns
    -------
    (n,) float array
        ``|grad phi|`` at the particles (nan for inactive ones), used by
        :func:`drop_lost_particles`.
    """
    h = grid.cell_size_m
    act = np.flatnonzero(state.status == 0)
    gnorm = np.full(len(state.xy), np.nan)
    if act.size:
        rc = grid.xy_to_rc(state.xy[act])
        m = len(act)
        off = np.array([[0.0, 1.0], [0.0, -1.0], [1.0, 0.0], [-1.0, 0.0]])
        pts = (rc[None, :, :] + off[:, None, :]).reshape(-1, 2)
        v = bilinear(phi, pts).reshape(4, m)
        gx = (v[0] - v[1]) / (2 * h)
        gy = (v[2] - v[3]) / (2 * h)
        norm = np.hypot(gx, gy)
        speed = np.clip(bilinear(gamma_t, rc), -speed_clamp_m, speed_clamp_m)
        ok = norm > 1e-9
        scale = np.where(ok, -dt * speed / np.where(ok, norm, 1.0), 0.0)
        new = state.xy[act] + np.column_stack([scale * gx, scale * gy])
        state.xy[act] = new
        gnorm[act] = norm
        g_new = bilinear(gamma_t, grid.xy_to_rc(new))
        done = np.abs(g_new) < 0.5 * h
        state.status[act[done]] = 1
        state.end_step[act[done]] = step + 1
    state.history.append(state.xy.copy())
    return gnorm


def drop_lost_particles(
    state: ParticleState, grid: Grid, phi: np.ndarray, grad_norm: np.ndarray, max_offset_cells: float = 1.5
) -> None:
    """Discard active particles that are no longer on the front.

    After fronts collide (regions merging, or a shock where a front folds
    onto itself) a particle ends up inside or outside the region, away from
    the zero set; such a particle describes interior material, not the
    boundary, and is dropped. The distance to the front is estimated as
    ``|phi| / |grad phi|``.
    """
    act = np.flatnonzero(state.status == 0)
    if not act.size:
        return
    val = bilinear(phi, grid.xy_to_rc(state.xy[act]))
    gn = np.maximum(np.nan_to_num(grad_norm[act], nan=1.0), 0.2)
    lost = np.abs(val) / gn > max_offset_cells * grid.cell_size_m
    state.status[act[lost]] = 2


def merge_close_particles(state: ParticleState, min_distance_m: float) -> None:
    """Discard active particles closer than ``min_distance_m`` to another active one.

    Where the front converges (a region shrinking, a concave target) the
    particles bunch up; once two are this close they follow the same path,
    so only the first (in seed order) is kept. This bounds the particle
    density and keeps converging trajectories from crossing numerically.
    """
    act = np.flatnonzero(state.status == 0)
    if act.size < 2:
        return
    pairs = cKDTree(state.xy[act]).query_pairs(min_distance_m, output_type="ndarray")
    if not len(pairs):
        return
    # keep the lower index of each pair unless it is itself discarded
    drop = np.zeros(act.size, dtype=bool)
    for i, j in pairs[np.argsort(pairs[:, 0], kind="stable")]:
        if not drop[i]:
            drop[j] = True
    state.status[act[drop]] = 2


def finished_trajectories(state: ParticleState, dt: float, min_spacing_m: float) -> list[Trajectory]:
    """Trajectories of the particles that reached the target, in seed order.

    Consecutive positions closer than ``min_spacing_m`` along the path are
    thinned out (the front slows down exponentially near the target, giving
    many tiny steps); the first and last positions are always kept.
    """
    hist = np.stack(state.history)  # (steps + 1, n, 2)
    out = []
    steps = np.diff(hist, axis=0)
    seg = np.hypot(steps[..., 0], steps[..., 1])
    cum = np.vstack([np.zeros((1, hist.shape[1])), np.cumsum(seg, axis=0)])
    for i in np.flatnonzero(state.status == 1):
        end = int(state.end_step[i])
        c = cum[: end + 1, i]
        bucket = np.floor(c / min_spacing_m)
        keep = np.ones(end + 1, dtype=bool)
        keep[1:] = bucket[1:] != bucket[:-1]
        keep[0] = keep[-1] = True
        idx = np.flatnonzero(keep)
        if idx.size == 1:
            idx = np.array([0, 0])
        xy = hist[idx, i, :]
        out.append(Trajectory(xy=xy, t=idx * dt, backtracked=False))
    return out


# ---------------------------------------------------------------------------
# wave-speed adjustment (paper section 4.1)
# ---------------------------------------------------------------------------


def normalised_arc_length(traj: Trajectory) -> np.ndarray:
    """Arc-length parameter ``s`` of each point, 0 on the source, 1 on the target.

    This is the wave-speed adjustment of paper section 4.1: re-parameterising
    every trajectory by its own normalised arc length makes all particles
    leave the source at ``s = 0`` and reach the target together at
    ``s = 1``, so points of equal ``s`` form an iso-contour. A trajectory of
    zero length (source and target contours coincide there) is parameterised
    by point index.
    """
    xy = np.asarray(traj.xy, dtype=float)
    if len(xy) < 2:
        return np.zeros(len(xy))
    seg = np.hypot(*np.diff(xy, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] <= 0:
        return np.linspace(0.0, 1.0, len(xy))
    return cum / cum[-1]


def trajectory_xyz(traj: Trajectory, z_source: float, z_target: float) -> np.ndarray:
    """``(n, 3)`` points of ``traj`` with elevation linear in normalised arc length.

    ``z = z_source + s * (z_target - z_source)``; see :func:`normalised_arc_length`.
    """
    s = normalised_arc_length(traj)
    z = z_source + s * (z_target - z_source)
    return np.column_stack([np.asarray(traj.xy, dtype=float), z])


def positions_at(trajectories: list[Trajectory], fraction: float) -> np.ndarray:
    """Point of each trajectory at normalised arc length ``fraction`` (0..1).

    Gives the iso-contour points at the intermediate elevation
    ``z_source + fraction * (z_target - z_source)``, in the order of
    ``trajectories`` (which :func:`core.morph.levelset.morph_regions` returns ordered
    along the source contour).
    """
    f = float(np.clip(fraction, 0.0, 1.0))
    out = np.empty((len(trajectories), 2))
    for k, tr in enumerate(trajectories):
        s = normalised_arc_length(tr)
        out[k, 0] = np.interp(f, s, tr.xy[:, 0])
        out[k, 1] = np.interp(f, s, tr.xy[:, 1])
    return out


# ---------------------------------------------------------------------------
# crossing checks and coverage
# ---------------------------------------------------------------------------


def _segments(trajectories: list[Trajectory]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All non-degenerate segments ``a -> b`` of the trajectories and their owner index."""
    if not trajectories:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, dtype=int)
    lengths = np.array([len(tr.xy) for tr in trajectories])
    pts = np.concatenate([np.asarray(tr.xy, dtype=float) for tr in trajectories])
    owner = np.repeat(np.arange(len(trajectories)), lengths)
    keep = (owner[:-1] == owner[1:]) & np.any(pts[:-1] != pts[1:], axis=1)
    return pts[:-1][keep], pts[1:][keep], owner[:-1][keep]


def crossing_pairs(trajectories: list[Trajectory], checked_prefix: int = 0) -> np.ndarray:
    """Pairs ``(i, j)``, ``i < j``, of trajectories whose paths properly cross.

    ``checked_prefix``: the first ``checked_prefix`` trajectories are known
    not to cross one another (only pairs involving a later one are sought;
    much faster when a few trajectories are added to a checked set).

    Identical segments (the trunk part a backtracked trajectory shares with
    its trunk) are tested once. Segments longer than the 95th percentile
    length are split into collinear pieces, candidate pairs are pieces whose
    midpoints lie within one piece length (cKDTree), and candidates are
    tested exactly with orientation signs: a crossing
    needs each segment's end points strictly on opposite sides of the other.
    Touching (a shared vertex, e.g. a backtracked trajectory leaving its
    trunk) and collinear overlap are not crossings.

    Returns
    -------
    (k, 2) int array of unique pairs.
    """
    a, b, owner = _segments(trajectories)
    if len(a) < 2:
        return np.zeros((0, 2), dtype=int)
    if any(tr.backtracked for tr in trajectories):
        a, b, owner_sorted, bounds = _merge_identical_segments(a, b, owner)
    else:
        owner_sorted, bounds = owner, np.arange(len(owner) + 1)
    pa, pb, parent, piece = _short_pieces(a, b)
    mid = 0.5 * (pa + pb)
    if checked_prefix > 0:
        # pieces of segments all of whose owners are new, against every piece
        new_seg = np.minimum.reduceat(owner_sorted, bounds[:-1]) >= checked_prefix
        qi = np.flatnonzero(new_seg[parent])
        if not qi.size:
            return np.zeros((0, 2), dtype=int)
        dm = cKDTree(mid[qi]).sparse_distance_matrix(cKDTree(mid), piece, output_type="ndarray")
        i, j = qi[dm["i"]], dm["j"].astype(np.intp)
    else:
        near = cKDTree(mid).query_pairs(piece, output_type="ndarray")
        if not len(near):
            return np.zeros((0, 2), dtype=int)
        i, j = near[:, 0], near[:, 1]
    sel = parent[i] != parent[j]
    i, j = i[sel], j[sel]
    if not i.size:
        return np.zeros((0, 2), dtype=int)
    cross = _properly_cross(pa[i], pb[i], pa[j], pb[j])
    pairs = set()
    for u, v in zip(parent[i[cross]], parent[j[cross]]):
        for x in owner_sorted[bounds[u] : bounds[u + 1]]:
            for y in owner_sorted[bounds[v] : bounds[v + 1]]:
                if x != y:
                    pairs.add((int(min(x, y)), int(max(x, y))))
    if not pairs:
        return np.zeros((0, 2), dtype=int)
    return np.array(sorted(pairs), dtype=int)


def _merge_identical_segments(
    a: np.ndarray, b: np.ndarray, owner: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Identical segments (shared trunks) once each, with their owners grouped.

    Returns the unique segments ``a -> b``, the owners sorted by segment and
    the bounds of each segment's run in them (``owners[bounds[u]:bounds[u + 1]]``).
    """
    rows = np.ascontiguousarray(np.hstack([a, b]))
    key = rows.view(np.dtype((np.void, rows.dtype.itemsize * 4))).ravel()
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    order = np.argsort(inv, kind="stable")
    return a[first], b[first], owner[order], np.searchsorted(inv[order], np.arange(len(first) + 1))


def _short_pieces(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Segments split into collinear pieces no longer than about the 95th percentile length.

    Then two pieces can only intersect if their midpoints are within one
    piece length. Returns the pieces ``pa -> pb``, each piece's segment, and
    the piece length.
    """
    length = np.hypot(*(b - a).T)
    piece = max(1.01 * float(np.quantile(length, 0.95)), 1e-12)
    k = np.maximum(np.ceil(length / piece).astype(int), 1)
    parent = np.repeat(np.arange(len(a)), k)
    sub = np.arange(len(parent)) - np.repeat(np.cumsum(k) - k, k)
    f0 = (sub / k[parent])[:, None]
    f1 = ((sub + 1) / k[parent])[:, None]
    d = b[parent] - a[parent]
    return a[parent] + f0 * d, a[parent] + f1 * d, parent, piece


def _properly_cross(p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, p4: np.ndarray) -> np.ndarray:
    """Whether segments ``p1 -> p2`` and ``p3 -> p4`` cross: each one's ends strictly on both sides of the other."""

    def orient(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    tol = 1e-9 * np.hypot(*(p2 - p1).T) * np.hypot(*(p4 - p3).T)
    o1, o2 = orient(p1, p2, p3), orient(p1, p2, p4)
    o3, o4 = orient(p3, p4, p1), orient(p3, p4, p2)
    cross = ((o1 > tol) & (o2 < -tol)) | ((o1 < -tol) & (o2 > tol))
    return cross & (((o3 > tol) & (o4 < -tol)) | ((o3 < -tol) & (o4 > tol)))


def remove_crossings(trajectories: list[Trajectory], checked_prefix: int = 0) -> list[Trajectory]:
    """Drop as few trajectories as needed so that no two cross.

    Greedy: repeatedly remove the trajectory in the most crossings (ties:
    backtracked before advected, then the shorter one). Order is preserved.
    ``checked_prefix`` as in :func:`crossing_pairs`.
    """
    pairs = crossing_pairs(trajectories, checked_prefix)
    if not len(pairs):
        return list(trajectories)
    removed: set[int] = set()
    live = pairs
    while len(live):
        counts = np.bincount(live.ravel(), minlength=len(trajectories))
        cand = np.flatnonzero(counts == np.max(counts))
        key = [(not trajectories[c].backtracked, len(trajectories[c].xy)) for c in cand]
        worst = int(cand[min(range(len(cand)), key=lambda k: key[k])])
        removed.add(worst)
        live = live[(live[:, 0] != worst) & (live[:, 1] != worst)]
    return [tr for k, tr in enumerate(trajectories) if k not in removed]


def boundary_coverage(
    trajectories: list[Trajectory],
    target: Polygon | MultiPolygon,
    cell_size_m: float,
    radius_cells: float = 1.0,
) -> float:
    """Fraction of the target boundary length near a trajectory end point.

    The boundary is sampled every quarter cell; a sample is covered when a
    trajectory end point lies within ``radius_cells`` cells of it (cKDTree).
    This is the success measure of curvelet backtracking (paper section 4.3;
    ``ALGORITHMS.md``). An empty target boundary counts as fully covered.
    """
    xy, _, _, w = ring_samples(target, 0.25 * cell_size_m)
    if not len(xy):
        return 1.0
    if not trajectories:
        return 0.0
    ends = np.array([tr.xy[-1] for tr in trajectories])
    d, _ = cKDTree(ends).query(xy)
    return float(np.sum(w[d <= radius_cells * cell_size_m]) / np.sum(w))
