"""Contour metamorphosis by level sets (paper section 4; ``ALGORITHMS.md``).

The aligned source region(s) morph into the target region(s) under the
Breen & Whitaker (2001) level-set flow used in the paper (Appendix B, eq. 19-20):

    d phi / dt = |grad phi| * clip(gamma_t, -c, c),    phi(0) = gamma_s,

with ``phi`` and the target signed distance ``gamma_t`` positive inside (paper
convention). The front grows where the target lies outside it and shrinks
where it lies inside, and comes to rest on the target contour; merging and
splitting are handled by the level set itself. Particles ride the front
(:mod:`core.morph.trajectories`) and target-boundary segments they miss are
recovered by curvelet backtracking (:mod:`core.morph.backtracking`).

Numerics: Godunov upwind gradient (Osher & Sethian), CFL time step
``dt = h / (2 max|F|)``, periodic re-initialisation of ``phi`` to a signed
distance with sub-cell accuracy (closest-point method, :func:`reinitialise`),
time of arrival recorded with sub-step (linear) interpolation. All lengths
in metres in the local frame; time is dimensionless morph time.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry import MultiPolygon, Point, Polygon

from core.errors import BGMInputError
from core.geometry.grid import Grid, as_multipolygon
from core.geometry.sdf import signed_distance
from core.morph.trajectories import (
    Trajectory,
    advect_particles,
    bilinear,
    boundary_coverage,
    drop_lost_particles,
    finished_trajectories,
    merge_close_particles,
    remove_crossings,
    ring_samples,
    seed_particles,
)

#: Margin (cells) of the morph grid around the union of source and target.
MARGIN_CELLS = 4
#: Radius (cells) of the disc seeded for a pod appearing / pinching out.
SEED_DISC_RADIUS_CELLS = 2.0


@dataclass
class MorphResult:
    """Outcome of :func:`morph_regions`.

    Attributes
    ----------
    grid : Grid
        The morph grid.
    phi_final : (rows, cols) float array
        Final level set (metres, positive inside).
    target_sdf : (rows, cols) float array
        ``gamma_t``, signed distance of the target (metres, positive inside).
    arrival_time : (rows, cols) float array
        Morph time at which the front first crossed each cell centre; nan
        where it never did (inside both, or outside both regions).
    times : (k,) float array
        Recorded time steps (about one per cell of front travel).
    fronts : list of MultiPolygon
        Front (region ``phi > 0``) at each recorded time, if ``keep_fronts``;
        otherwise empty.
    iou : float
        Intersection over union of the final region ``phi > 0`` and the
        target, on the grid.
    trajectories : list of Trajectory
        Source-to-target paths, advected first then backtracked ones, sorted
        along the source contour (ring, then arc length of the start point).
    coverage_before_backtracking : float
        Target boundary fraction covered by advected trajectories alone.
    target_boundary_coverage : float
        Target boundary fraction covered by all trajectories.
    source, target : MultiPolygon
        The regions actually morphed (after seeding a disc for an empty side).
    dt : float
        Level-set time step.
    n_steps : int
        Number of level-set steps taken.
    """

    grid: Grid
    phi_final: np.ndarray
    target_sdf: np.ndarray
    arrival_time: np.ndarray
    times: np.ndarray
    fronts: list = field(default_factory=list)
    iou: float = 0.0
    trajectories: list = field(default_factory=list)
    coverage_before_backtracking: float = 0.0
    target_boundary_coverage: float = 0.0
    source: MultiPolygon = field(default_factory=MultiPolygon)
    target: MultiPolygon = field(default_factory=MultiPolygon)
    dt: float = 0.0
    n_steps: int = 0


# ---------------------------------------------------------------------------
# signed distances and re-initialisation
# ---------------------------------------------------------------------------


def region_sdf(grid: Grid, region: Polygon | MultiPolygon, band_cells: float = 2.0) -> np.ndarray:
    """Signed distance (metres, positive inside) of a polygonal region on ``grid``.

    Exact Euclidean distance transform of the rasterised region
    (:func:`core.geometry.sdf.signed_distance`, paper Algorithm 3) everywhere, replaced
    within ``band_cells`` of the boundary by the exact distance to the
    polygon boundary, so that the zero set lies on the true contour to
    sub-cell accuracy (particles start and stop on the real contours).
    """
    h = grid.cell_size_m
    mask = grid.rasterize(region)
    sdf = signed_distance(mask, h)
    if region.is_empty:
        return sdf
    band = np.abs(sdf) <= band_cells * h
    r, c = np.nonzero(band)
    xy = grid.rc_to_xy(np.column_stack([r, c]))
    boundary = region.boundary
    d = shapely.distance(shapely.points(xy), boundary)
    inside = shapely.contains_xy(region, xy[:, 0], xy[:, 1])
    sdf[r, c] = np.where(inside, d, -d)
    return sdf


def reinitialise(phi: np.ndarray, cell_size_m: float, band_m: float | None = None) -> np.ndarray:
    """Re-initialise a level set to a signed distance, keeping its zero set.

    Closest-point method: every cell with a 4-neighbour of opposite sign is
    projected onto the zero set by one Newton step,
    ``foot = x - phi grad(phi) / |grad(phi)|^2`` (sub-cell accurate); an exact
    Euclidean distance transform then gives each cell its nearest interface
    cell, and the new value is the distance to that cell's piece of front (a
    one-cell tangent segment through its foot point), signed like ``phi``.
    Cost: one EDT (a few ms on 256 x 256).

    With ``band_m`` only the bounding box of the interface, grown by
    ``band_m + 2 h``, is recomputed; cells outside that box get
    ``+-(band_m + 2 h)`` (narrow-band use: only the sign matters there).
    """
    h = cell_size_m
    inside = phi > 0
    edge = np.zeros_like(inside)
    dh = inside[:, 1:] != inside[:, :-1]
    edge[:, 1:] |= dh
    edge[:, :-1] |= dh
    dv = inside[1:, :] != inside[:-1, :]
    edge[1:, :] |= dv
    edge[:-1, :] |= dv
    if not edge.any():
        big = float(np.hypot(*phi.shape)) * h if band_m is None else band_m + 2 * h
        return np.where(inside, big, -big)
    rows, cols = phi.shape
    r, c = np.nonzero(edge)
    if band_m is None:
        r0, r1, c0, c1 = 0, rows, 0, cols
        out = np.empty(phi.shape)
    else:
        pad = int(np.ceil(band_m / h)) + 2
        r0, r1 = max(int(r.min()) - pad, 0), min(int(r.max()) + pad + 1, rows)
        c0, c1 = max(int(c.min()) - pad, 0), min(int(c.max()) + pad + 1, cols)
        out = np.where(inside, band_m + 2 * h, -(band_m + 2 * h))
    up, dn = np.minimum(r + 1, rows - 1), np.maximum(r - 1, 0)
    rt, lt = np.minimum(c + 1, cols - 1), np.maximum(c - 1, 0)
    gy = (phi[up, c] - phi[dn, c]) / ((up - dn) * h)
    gx = (phi[r, rt] - phi[r, lt]) / ((rt - lt) * h)
    g2 = np.maximum(gx * gx + gy * gy, 1e-12)
    v = phi[r, c]
    # Newton step in cells, limited to one cell
    dr = -v * gy / g2 / h
    dc = -v * gx / g2 / h
    n = np.hypot(dr, dc)
    lim = np.where(n > 1.0, 1.0 / np.maximum(n, 1e-12), 1.0)
    shape = (r1 - r0, c1 - c0)
    g = np.sqrt(g2)
    # per interface cell: foot point and unit normal (row, col components)
    info = np.zeros((4,) + shape)
    info[0, r - r0, c - c0] = r - r0 + dr * lim
    info[1, r - r0, c - c0] = c - c0 + dc * lim
    info[2, r - r0, c - c0] = gy / g
    info[3, r - r0, c - c0] = gx / g
    ir, ic = ndimage.distance_transform_edt(~edge[r0:r1, c0:c1], return_distances=False, return_indices=True)
    fr, fc, nr, nc = info[:, ir, ic]
    rr, cc = np.indices(shape)
    wr, wc = rr - fr, cc - fc
    # distance to the interface piece of the nearest interface cell, a tangent
    # segment one cell long centred on its foot point (second-order accurate
    # on smooth fronts, exact distance to the foot beyond the segment's ends)
    dn = wr * nr + wc * nc
    dt = np.maximum(np.abs(wr * nc - wc * nr) - 0.5, 0.0)
    d = np.sqrt(dn * dn + dt * dt) * h
    out[r0:r1, c0:c1] = np.where(inside[r0:r1, c0:c1], d, -d)
    return out


class _NarrowBand:
    """Flat indices of the cells within ``width_m`` of the front and of their 4 neighbours.

    Neighbours across the grid edge are the cell itself (zero-flux boundary).
    """

    def __init__(self, phi: np.ndarray, width_m: float):
        rows, cols = phi.shape
        idx = np.flatnonzero(np.abs(phi).ravel() < width_m)
        r, c = np.divmod(idx, cols)
        self.idx = idx
        self.left = np.where(c > 0, idx - 1, idx)
        self.right = np.where(c < cols - 1, idx + 1, idx)
        self.down = np.where(r > 0, idx - cols, idx)
        self.up = np.where(r < rows - 1, idx + cols, idx)


def _band_step(
    flat: np.ndarray, band: _NarrowBand, speed_b: np.ndarray, pos_b: np.ndarray, dt: float, h: float
) -> np.ndarray:
    """New values of the band cells after one Godunov upwind step (see :func:`upwind_gradient_norm`)."""
    v = flat[band.idx]
    dmx = v - flat[band.left]
    dpx = flat[band.right] - v
    dmy = v - flat[band.down]
    dpy = flat[band.up] - v
    mnx, mxx = np.minimum(dmx, 0.0), np.maximum(dmx, 0.0)
    mnpx, mxpx = np.minimum(dpx, 0.0), np.maximum(dpx, 0.0)
    mny, mxy = np.minimum(dmy, 0.0), np.maximum(dmy, 0.0)
    mnpy, mxpy = np.minimum(dpy, 0.0), np.maximum(dpy, 0.0)
    pos = mnx * mnx + mxpx * mxpx + mny * mny + mxpy * mxpy
    neg = mxx * mxx + mnpx * mnpx + mxy * mxy + mnpy * mnpy
    return v + (dt / h) * speed_b * np.sqrt(np.where(pos_b, pos, neg))


def upwind_gradient_norm(phi: np.ndarray, speed_positive: np.ndarray, cell_size_m: float) -> np.ndarray:
    """Godunov upwind ``|grad phi|`` for ``d phi/dt = F |grad phi|``, phi positive inside.

    Where ``F > 0`` (front moving outward) ``|grad phi|^2 = min(D-x,0)^2 +
    max(D+x,0)^2 + (same in y)``; where ``F < 0`` the roles of ``min`` and
    ``max`` swap (Osher & Sethian scheme for ``psi = -phi``). Zero-flux edges.
    """
    P = np.pad(phi, 1, mode="edge")
    dx = np.diff(P[1:-1, :], axis=1)  # (rows, cols + 1): D-x = dx[:, :-1], D+x = dx[:, 1:]
    dy = np.diff(P[:, 1:-1], axis=0)
    ax, bx = np.minimum(dx, 0.0) ** 2, np.maximum(dx, 0.0) ** 2
    ay, by = np.minimum(dy, 0.0) ** 2, np.maximum(dy, 0.0) ** 2
    pos = ax[:, :-1] + bx[:, 1:] + ay[:-1, :] + by[1:, :]
    neg = bx[:, :-1] + ax[:, 1:] + by[:-1, :] + ay[1:, :]
    return np.sqrt(np.where(speed_positive, pos, neg)) / cell_size_m


# ---------------------------------------------------------------------------
# regions
# ---------------------------------------------------------------------------


def _as_region(regions) -> MultiPolygon:
    if regions is None:
        return MultiPolygon()
    if isinstance(regions, (list, tuple)):
        geoms = [g for g in regions if g is not None and not g.is_empty]
        if not geoms:
            return MultiPolygon()
        return as_multipolygon(shapely.union_all(geoms))
    return as_multipolygon(regions)


def _deepest_disc(region: MultiPolygon, cell_size_m: float) -> MultiPolygon:
    """Small disc at the deepest interior point (max of the SDF) of ``region``."""
    grid = Grid.covering(region.bounds, cell_size_m, MARGIN_CELLS)
    sdf = region_sdf(grid, region)
    i = np.unravel_index(int(np.argmax(sdf)), sdf.shape)
    x, y = grid.rc_to_xy(np.array([i], dtype=float))[0]
    r = min(SEED_DISC_RADIUS_CELLS * cell_size_m, max(float(sdf[i]), 0.5 * cell_size_m))
    return as_multipolygon(Point(x, y).buffer(r, quad_segs=16))


# ---------------------------------------------------------------------------
# the morph
# ---------------------------------------------------------------------------


def morph_regions(  # noqa: C901 - to be split into named steps
    sources,
    targets,
    *,
    cell_size_m: float | None = None,
    speed_clamp_m: float | None = None,
    keep_fronts: bool = False,
    max_cells: int = 256,
    max_steps: int | None = None,
    reinit_every_steps: int = 10,
    backtrack: bool = True,
) -> MorphResult:
    """Morph aligned source region(s) into target region(s) (paper section 4).

    Parameters
    ----------
    sources, targets : Polygon, MultiPolygon or list of them
        Source regions (already shifted by the spatial-correspondence
        translation) and target regions, in the local frame (metres). Either
        side may be empty (not both): a pod appearing (no source) starts from
        a small disc (radius 2 cells) at the target's deepest interior point,
        the maximum of its signed distance; a pod pinching out (no target)
        morphs into such a disc at the source's deepest point. The seeded
        discs are reported in ``MorphResult.source`` / ``.target``.
    cell_size_m : float, optional
        Grid cell size. Default: the longer side of the bounding box of both
        regions spread over about ``max_cells`` cells (including the margin).
    speed_clamp_m : float, optional
        ``c`` in ``clip(gamma_t, -c, c)``; default 3 cells. Keeps far parts of
        the front from racing and bounds the CFL step.
    keep_fronts : bool
        Also store the front polygons at every recorded time (slow-ish).
    max_cells : int
        Cells along the longer side when ``cell_size_m`` is not given.
    max_steps : int, optional
        Hard cap on level-set steps (default: enough for the front to cross
        the grid diagonal twice).
    reinit_every_steps : int
        Re-initialise ``phi`` to a signed distance every this many steps.
    backtrack : bool
        Run curvelet backtracking (:func:`core.morph.backtracking.backtrack_trajectories`).

    Returns
    -------
    MorphResult

    Notes
    -----
    Stopping rule: every cell farther than a tenth of a cell from the target
    contour has the right sign (pixel-exact match; IoU then exceeds 0.99 for
    any region a few cells wide) and no particle is still moving; or no cell
    changed sign for ``2 ln(c / 0.05 h) + 4`` time units (front stalled, e.g.
    a target part not reachable from the source); or ``max_steps``.
    """
    src = _as_region(sources)
    tgt = _as_region(targets)
    if src.is_empty and tgt.is_empty:
        raise BGMInputError("Cannot morph: both the source and the target region are empty.")
    if speed_clamp_m is not None and not (speed_clamp_m > 0 and np.isfinite(speed_clamp_m)):
        raise BGMInputError(f"The morph speed clamp must be a positive length, got {speed_clamp_m}.")
    both = src.union(tgt) if not (src.is_empty or tgt.is_empty) else (tgt if src.is_empty else src)
    xmin, ymin, xmax, ymax = both.bounds
    span = max(xmax - xmin, ymax - ymin, 1e-9)
    if cell_size_m is None:
        cell_size_m = span / max(max_cells - 2 * MARGIN_CELLS - 1, 8)
    h = float(cell_size_m)
    if src.is_empty:
        src = _deepest_disc(tgt, h)
    elif tgt.is_empty:
        tgt = _deepest_disc(src, h)
    grid = Grid.covering(src.union(tgt).bounds, h, MARGIN_CELLS)
    c = 3.0 * h if speed_clamp_m is None else float(speed_clamp_m)

    phi = region_sdf(grid, src)
    gamma = region_sdf(grid, tgt)
    speed = np.clip(gamma, -c, c)
    speed_pos = speed > 0
    vmax = float(np.max(np.abs(speed)))
    dt = 0.5 * h / max(vmax, 1e-12)
    if max_steps is None:
        diag = float(np.hypot(*grid.shape)) * h
        max_steps = int(np.ceil(2 * (diag / max(c, 1e-12) + 2 * np.log(max(c / (0.05 * h), 2.0)) + 4) / dt))

    phi0 = phi.copy()
    inside0 = (phi0 > 0).ravel()
    target_mask = gamma > 0
    check = np.abs(gamma) > 0.1 * h
    arrival = np.full(grid.shape, np.nan)
    arrival_flat = arrival.ravel()
    src_len = sum(p.length for p in src.geoms)
    tgt_len = sum(p.length for p in tgt.geoms)
    spacing = h * float(np.clip(src_len / max(tgt_len, 1e-12), 0.25, 1.0))
    particles = seed_particles(src, spacing)
    if len(particles.xy):
        g0 = bilinear(gamma, grid.xy_to_rc(particles.xy))
        done0 = np.abs(g0) < 0.5 * h
        particles.status[done0] = 1
        particles.end_step[done0] = 0

    record_every = 2
    times = [0.0]
    fronts = [grid.polygons_from_field(phi, 0.0)] if keep_fronts else []
    patience = int(np.ceil((2 * np.log(max(c / (0.05 * h), 2.0)) + 4) / dt))
    # the front moves at most max|F| dt = h/2 per step
    band_m = (0.5 * reinit_every_steps + 2.0) * h
    phi = reinitialise(phi, h, band_m)
    flat = phi.ravel()
    band = _NarrowBand(phi, band_m)
    speed_flat, pos_flat = speed.ravel(), speed_pos.ravel()
    speed_b, pos_b, inside0_b = speed_flat[band.idx], pos_flat[band.idx], inside0[band.idx]
    last_change = 0
    t = 0.0
    step = 0
    for step in range(1, max_steps + 1):
        gnorm = advect_particles(particles, grid, phi, gamma, dt, c, step - 1)
        old_b = flat[band.idx]
        new_b = _band_step(flat, band, speed_b, pos_b, dt, h)
        crossed = ((new_b > 0) != inside0_b) & np.isnan(arrival_flat[band.idx])
        if crossed.any():
            o, n_ = old_b[crossed], new_b[crossed]
            arrival_flat[band.idx[crossed]] = t + np.clip(o / (o - n_), 0.0, 1.0) * dt
            last_change = step
        flat[band.idx] = new_b
        t += dt
        drop_lost_particles(particles, grid, phi, gnorm)
        if step % 2 == 0:
            merge_close_particles(particles, 0.2 * h)
        if step % record_every == 0:
            times.append(t)
            if keep_fronts:
                fronts.append(grid.polygons_from_field(phi, 0.0))
        if step % reinit_every_steps == 0:
            if not np.any(particles.status == 0) and not np.any(((phi > 0) != target_mask) & check):
                break
            phi = reinitialise(phi, h, band_m)
            flat = phi.ravel()
            band = _NarrowBand(phi, band_m)
            speed_b, pos_b, inside0_b = speed_flat[band.idx], pos_flat[band.idx], inside0[band.idx]
        if step - last_change > patience:
            break
    n_steps = step
    if times[-1] != t:
        times.append(t)
        if keep_fronts:
            fronts.append(grid.polygons_from_field(phi, 0.0))
    phi = reinitialise(phi, h)
    region = phi > 0
    union = np.count_nonzero(region | target_mask)
    iou = float(np.count_nonzero(region & target_mask) / union) if union else 1.0

    trajs = remove_crossings(finished_trajectories(particles, dt, h))
    cov0 = boundary_coverage(trajs, tgt, h)
    cov = cov0
    if backtrack and cov0 < 1.0:
        from core.morph.backtracking import backtrack_trajectories

        trajs = backtrack_trajectories(trajs, arrival, grid, phi0, src, tgt)
        cov = boundary_coverage(trajs, tgt, h)
    trajs = _sort_along_source(trajs, src, h)
    return MorphResult(
        grid=grid,
        phi_final=phi,
        target_sdf=gamma,
        arrival_time=arrival,
        times=np.asarray(times),
        fronts=fronts,
        iou=iou,
        trajectories=trajs,
        coverage_before_backtracking=cov0,
        target_boundary_coverage=cov,
        source=src,
        target=tgt,
        dt=dt,
        n_steps=n_steps,
    )


def _sort_along_source(trajs: list[Trajectory], src: MultiPolygon, h: float) -> list[Trajectory]:
    """Order trajectories by (source ring, arc length of start, advected first)."""
    if not trajs:
        return trajs
    xy, ring, arc, _ = ring_samples(src, 0.25 * h)
    if not len(xy):
        return trajs
    from scipy.spatial import cKDTree

    starts = np.array([tr.xy[0] for tr in trajs])
    _, k = cKDTree(xy).query(starts)
    order = np.lexsort((np.array([tr.backtracked for tr in trajs]), arc[k], ring[k]))
    return [trajs[i] for i in order]
