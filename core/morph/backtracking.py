"""Curvelet backtracking: recover trajectories lost at branching points.

Paper section 4.2-4.3 (Fig. "branching point phenomenon", Algorithms 10-12)
and ``ALGORITHMS.md`` ("Curvelet backtracking"). Where the source and target
contours differ strongly in curvature (a thin arm, a star point), the
particles of :mod:`core.morph.trajectories` diverge and leave target-boundary
segments without any trajectory, although the wavefront did reach them.

Formulation used here
---------------------
The paper archives, per time step, the front pixels that no particle head
follows (curvelets, step (a)-(b)), smooths and resamples them (c), associates
curvelets of successive time steps by nearest neighbours (d)-(e) and chains
the correspondences backwards from the target to the branching point (f),
where the new track is fused with the trunk trajectory (Algorithms 11-12).

The curvelets at time ``t`` are exactly the pieces of the iso-line
``{T = t}`` of the time-of-arrival map ``T`` that lie away from the particle
heads (:func:`curvelet_pixels` extracts them), and the point-to-point
correspondence between curvelets at ``t`` and ``t - dt`` that the paper
regularises is the motion of the front along its normal, i.e. along
``-grad T`` (for an isotropic speed the rays of the eikonal equation
``F |grad T| = 1`` are the gradient lines of ``T``). We therefore chain the
correspondences in the continuum limit: from each uncovered target-boundary
point we step down an upwind gradient of ``T`` (the regularised curvelet
track, sampled every half cell) until the track comes within about half a
cell of an existing trajectory -- the branching point on the trunk -- or
reaches the source contour. The new trajectory is the trunk up to its
nearest vertex followed by the new track reversed (source -> target), with
times taken from ``T`` and made non-decreasing. Tracks are built one after
the other, longest (latest arrival) first, and each finished one becomes a
possible trunk for the next, so tracks join rather than run side by side;
gradient lines do not cross, and any residual numerical crossing is
removed by :func:`core.morph.trajectories.remove_crossings`.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy import ndimage
from scipy.spatial import cKDTree
from shapely.geometry import MultiPolygon, Polygon

from core.geometry.grid import Grid
from core.morph.trajectories import Trajectory, bilinear, remove_crossings, ring_samples


def arrival_descent_field(arrival_time: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit downhill direction of the time-of-arrival map, upwind.

    Cells the front never crossed (nan) are given the latest arrival time
    plus their distance (in cells) to the nearest crossed cell, so tracks
    never descend into them, and a track starting among them (a target
    boundary point in a corner no cell centre of which the front crossed)
    finds the nearest crossed cells. Along each axis the direction points to
    the smaller neighbour when it is smaller than the cell itself (the
    upwind choice of the eikonal equation), which keeps the jump between
    crossed and never-crossed cells from spoiling the direction.

    Returns
    -------
    t_filled : (rows, cols) float array
    v_row, v_col : (rows, cols) float arrays
        Unit vectors (zero where no neighbour is lower).
    """
    crossed = np.isfinite(arrival_time)
    if crossed.any():
        away = ndimage.distance_transform_edt(~crossed)
        T = np.where(crossed, arrival_time, float(np.nanmax(arrival_time)) + away)
    else:
        T = np.zeros(arrival_time.shape)
    P = np.pad(T, 1, constant_values=np.inf)
    left, right = P[1:-1, :-2], P[1:-1, 2:]
    low, high = P[:-2, 1:-1], P[2:, 1:-1]
    vc = np.where(np.minimum(left, right) < T, np.where(left < right, -(T - left), T - right), 0.0)
    vr = np.where(np.minimum(low, high) < T, np.where(low < high, -(T - low), T - high), 0.0)
    n = np.hypot(vr, vc)
    ok = n > 0
    vr = np.where(ok, vr / np.where(ok, n, 1.0), 0.0)
    vc = np.where(ok, vc / np.where(ok, n, 1.0), 0.0)
    return T, vr, vc


def curvelet_pixels(
    arrival_time: np.ndarray,
    grid: Grid,
    trajectories: list[Trajectory],
    t0: float,
    t1: float,
    radius_cells: float = 1.5,
) -> np.ndarray:
    """Front pixels crossed in ``(t0, t1]`` farther than ``radius_cells`` from every particle head.

    Paper section 4.3 step (a): the set ``P^t`` of wavefront pixels which have
    drifted away from the particle trajectories. Heads at ``t1`` are the
    trajectory positions interpolated at that time (a finished trajectory's
    head stays at its end point). Diagnostic: :func:`backtrack_trajectories`
    follows these pixels implicitly through the arrival-time gradient.

    Returns
    -------
    (k, 2) float array of pixel centres (metres).
    """
    sel = (arrival_time > t0) & (arrival_time <= t1)
    r, c = np.nonzero(sel)
    xy = grid.rc_to_xy(np.column_stack([r, c]).astype(float))
    if not len(xy) or not trajectories:
        return xy
    heads = np.array([[np.interp(t1, tr.t, tr.xy[:, 0]), np.interp(t1, tr.t, tr.xy[:, 1])] for tr in trajectories])
    d, _ = cKDTree(heads).query(xy)
    return xy[d > radius_cells * grid.cell_size_m]


def _run_seeds(uncovered: np.ndarray, ring: np.ndarray, every: int) -> np.ndarray:
    """Indices of seeds along each run of uncovered boundary samples.

    Seeds sit ``every`` samples apart, the first and last within
    ``every / 2`` samples of the run's ends, and every run (however short)
    gets at least one seed, at its middle.
    """
    u = uncovered.astype(np.int8)
    brk = np.ones(len(u) + 1, dtype=bool)
    brk[1:-1] = (np.diff(u) != 0) | (ring[1:] != ring[:-1])
    edges = np.flatnonzero(brk)
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        if not u[a]:
            continue
        n = b - a
        if n <= every:
            out.append(a + n // 2)
            continue
        k = np.arange(a + every // 2, b, every)
        out.extend(k.tolist())
        if b - 1 - k[-1] > every // 2:
            out.append(b - 1)
    return np.asarray(out, dtype=np.intp)


def _thinned(xy: np.ndarray, t: np.ndarray, start: int, every: int = 2) -> Trajectory:
    """Backtracked trajectory keeping the trunk part and every ``every``-th new point.

    Vertex indices up to ``start`` (the trunk part) are unchanged, so the
    owner raster's vertex numbers stay valid for later splices.
    """
    keep = np.zeros(len(xy), dtype=bool)
    keep[: start + 1] = True
    keep[start + 1 :: every] = True
    keep[-1] = True
    return Trajectory(xy=xy[keep], t=t[keep], backtracked=True)


class _OwnerRaster:
    """Half-cell raster of which trajectory passes within about half a cell.

    Vertices of trajectories are at most half a cell apart (trunks are
    marked with their segment midpoints too), and each marks its half-cell
    and the 8 around it, so the marked band of a path is connected and at
    least three half-cells wide: a track stepping half a cell cannot jump
    over it.
    """

    def __init__(self, grid: Grid, factor: int = 2):
        self.grid = grid
        self.f = factor
        self.shape = (grid.shape[0] * factor + 2, grid.shape[1] * factor + 2)
        self.owner = np.full(self.shape[0] * self.shape[1], -1, dtype=np.int64)
        w = self.shape[1]
        self._off = np.array([dr * w + dc for dr in (-1, 0, 1) for dc in (-1, 0, 1)])

    def cells_rc(self, rc: np.ndarray) -> np.ndarray:
        """Flat half-cell index of fractional ``(..., 2)`` row, col points (edge-clamped)."""
        r = np.clip(np.rint(rc[..., 0] * self.f).astype(np.int64) + 1, 1, self.shape[0] - 2)
        c = np.clip(np.rint(rc[..., 1] * self.f).astype(np.int64) + 1, 1, self.shape[1] - 2)
        return r * self.shape[1] + c

    def mark(self, cells: np.ndarray, owner) -> None:
        idx = (cells[:, None] + self._off[None, :]).ravel()
        self.owner[idx] = np.repeat(owner, len(self._off)) if np.ndim(owner) else owner

    def lookup(self, cells: np.ndarray) -> np.ndarray:
        return self.owner[cells]


def _descend(
    seeds_xy: np.ndarray,
    grid: Grid,
    t_filled: np.ndarray,
    v_row: np.ndarray,
    v_col: np.ndarray,
    source_sdf: np.ndarray,
    step_cells: float,
    max_steps: int,
    stall_steps: int = 8,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """March all seeds down the arrival time at once.

    A seed stops when it reaches the source contour (``|gamma_s| <= h/2``),
    when the downhill direction vanishes, or when its arrival time has not
    decreased over ``stall_steps`` steps (caught in a never-crossed area or
    zig-zagging on a ridge). A stopped seed is cut back to its earliest
    arrival time; it counts as reaching the source contour when that point
    lies within a cell diagonal (1.5 cells) of it: the arrival time is known
    at cell centres only, the cells next to the contour on its resting side
    are never crossed, and the first crossed ones can lie up to a diagonal
    away. Any other stopped seed is unusable.

    Returns the ``(steps + 1, m, 2)`` positions (fractional row, col), their
    ``(steps + 1, m)`` arrival times, the last step index of each seed, and
    whether it reached the source contour.
    """
    h = grid.cell_size_m
    pos = grid.xy_to_rc(seeds_xy)
    m = len(pos)
    hist = [pos.copy()]
    t_hist = [bilinear(t_filled, pos)]
    last = np.zeros(m, dtype=np.intp)
    reached = np.abs(bilinear(source_sdf, pos)) <= 0.5 * h
    active = ~reached
    for k in range(1, max_steps + 1):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        p = pos[idx]
        vr = bilinear(v_row, p)
        vc = bilinear(v_col, p)
        n = np.hypot(vr, vc)
        ok = n > 0.05
        p = p + step_cells * np.column_stack([vr, vc]) / np.where(ok, n, 1.0)[:, None] * ok[:, None]
        pos[idx] = p
        last[idx] = k
        tk = t_hist[-1].copy()
        tk[idx] = bilinear(t_filled, p)
        t_hist.append(tk)
        hit = np.abs(bilinear(source_sdf, p)) <= 0.5 * h
        reached[idx[hit]] = True
        stall = np.zeros(idx.size, dtype=bool)
        if k >= stall_steps:
            stall = tk[idx] >= t_hist[-1 - stall_steps][idx]
        active[idx[hit | ~ok | stall]] = False
        hist.append(pos.copy())
    hist_a, t_a = np.stack(hist), np.stack(t_hist)
    stopped = np.flatnonzero(~reached)
    if stopped.size:
        steps = np.arange(len(t_a))[:, None]
        t_stop = np.where(steps <= last[stopped], t_a[:, stopped], np.inf)
        best = np.argmin(t_stop, axis=0)
        last[stopped] = best
        reached[stopped] = np.abs(bilinear(source_sdf, hist_a[best, stopped])) <= 1.5 * h
    return hist_a, t_a, last, reached


def backtrack_trajectories(
    trajectories: list[Trajectory],
    arrival_time: np.ndarray,
    grid: Grid,
    source_sdf: np.ndarray,
    source: Polygon | MultiPolygon,
    target: Polygon | MultiPolygon,
    *,
    cover_radius_cells: float = 0.9,
    seed_spacing_cells: float = 1.0,
    step_cells: float = 0.5,
) -> list[Trajectory]:
    """Add backtracked trajectories so that the whole target boundary is reached.

    Parameters
    ----------
    trajectories : list of Trajectory
        Advected (trunk) trajectories; returned first, unchanged.
    arrival_time : (rows, cols) float array
        Time-of-arrival map of the morph (nan where never crossed).
    grid : Grid
    source_sdf : (rows, cols) float array
        Signed distance of the source (``phi`` at time 0).
    source, target : Polygon or MultiPolygon
        The morphed regions.
    cover_radius_cells : float
        Target boundary points farther than this from every trajectory end
        are uncovered and seed new tracks.
    seed_spacing_cells : float
        Spacing of the seeds along uncovered boundary stretches.
    step_cells : float
        Track step length.

    Returns
    -------
    list of Trajectory
        Input trajectories followed by the new ones (``backtracked=True``),
        every one running source -> target, none crossing another.

    Notes
    -----
    See the module docstring for how this realises steps (a)-(f) of paper
    section 4.3 and Algorithms 10-12.
    """
    h = grid.cell_size_m
    xy, ring, _, _ = ring_samples(target, 0.25 * h)
    if not len(xy) or not np.isfinite(arrival_time).any():
        return list(trajectories)
    seeds = _uncovered_seeds(
        trajectories, xy, ring, cover_radius_cells * h, max(int(round(seed_spacing_cells / 0.25)), 1)
    )
    if not seeds.size:
        return list(trajectories)

    T, v_row, v_col = arrival_descent_field(arrival_time)
    max_steps = int(2 * (grid.shape[0] + grid.shape[1]) / step_cells)
    hist, t_hist, last, reached = _descend(xy[seeds], grid, T, v_row, v_col, source_sdf, step_cells, max_steps)
    hist_xy = grid.rc_to_xy(hist.reshape(-1, 2)).reshape(hist.shape)

    all_trajs = list(trajectories)
    raster = _trunk_raster(grid, all_trajs)
    hist_cells = raster.cells_rc(hist)
    boundary = source.boundary
    for s in np.argsort(-t_hist[0], kind="stable"):
        n = last[s] + 1
        track = _joined_track(hist_xy[:n, s], t_hist[:n, s], hist_cells[:n, s], raster, all_trajs, reached[s], boundary)
        if track is None:
            continue
        new_xy, new_t, start, new_cells = track
        all_trajs.append(_thinned(new_xy, np.maximum.accumulate(np.maximum(new_t, 0.0)), start))
        raster.mark(new_cells, len(all_trajs) - 1)
    return remove_crossings(all_trajs, checked_prefix=len(trajectories))


def _uncovered_seeds(
    trajectories: list[Trajectory], xy: np.ndarray, ring: np.ndarray, cover_radius_m: float, every: int
) -> np.ndarray:
    """Seeds (indices into the target boundary samples ``xy``) along the stretches no trajectory ends near."""
    if trajectories:
        ends = np.array([tr.xy[-1] for tr in trajectories])
        d, _ = cKDTree(ends).query(xy)
    else:
        d = np.full(len(xy), np.inf)
    return _run_seeds(d > cover_radius_m, ring, every)


def _trunk_raster(grid: Grid, trajectories: list[Trajectory]) -> _OwnerRaster:
    """Owner raster with every trajectory (vertices and segment midpoints) marked: the possible trunks."""
    raster = _OwnerRaster(grid)
    if trajectories:
        pts = np.vstack([tr.xy for tr in trajectories])
        own = np.concatenate([np.full(len(tr.xy), k) for k, tr in enumerate(trajectories)])
        same = own[:-1] == own[1:]
        mids = 0.5 * (pts[:-1] + pts[1:])[same]
        cells = raster.cells_rc(grid.xy_to_rc(np.vstack([pts, mids])))
        raster.mark(cells, np.concatenate([own, own[:-1][same]]))
    return raster


def _joined_track(
    path_xy: np.ndarray,
    path_t: np.ndarray,
    cells: np.ndarray,
    raster: _OwnerRaster,
    trunks: list[Trajectory],
    reached: bool,
    source_boundary,
) -> tuple[np.ndarray, np.ndarray, int, np.ndarray] | None:
    """A track descended from the target boundary, as a source -> target path (Algorithms 11-12).

    Where the track first comes near a trunk (``raster``), the path is the
    trunk up to its nearest vertex followed by the track reversed; a track
    that reached the source contour without meeting one starts at its foot
    on ``source_boundary``; any other track is dropped (``None``). Returns the
    path's points and times, the index of its last trunk vertex, and the
    half-cells of the new part.
    """
    owners = raster.lookup(cells)
    hits = np.flatnonzero(owners >= 0)
    if hits.size:
        j = int(hits[0])
        trunk = trunks[int(owners[j])]
        v = int(np.argmin(np.hypot(*(trunk.xy - path_xy[j]).T)))
        new_xy = np.vstack([trunk.xy[: v + 1], path_xy[j::-1]])
        return new_xy, np.concatenate([trunk.t[: v + 1], path_t[j::-1]]), v, cells[: j + 1]
    if reached:
        foot = shapely.get_coordinates(shapely.shortest_line(source_boundary, shapely.points(path_xy[-1])))[0]
        return np.vstack([foot, path_xy[::-1]]), np.concatenate([[0.0], path_t[::-1]]), 0, cells
    return None
