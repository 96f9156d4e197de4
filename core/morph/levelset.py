"""Contour metamorphosis by level sets (paper section 4; ``ALGORITHMS.md``).

The aligned source region(s) morph into the target region(s) under the
Breen & Whitaker (2001) level-set flow used in the paper (Appendix B, eq. 19-20):

    d phi / dt = |grad phi| * clip(gamma_t, -c, c),    phi(0) = gamma_s,

with ``phi`` and the target signed distance ``gamma_t`` positive inside (paper
convention). The front grows where the target lies outside it and shrinks
where it lies inside, and comes to rest on the target contour; merging and
splitting are handled by the level set itself; a target part the front
cannot reach (a pod or a hole appearing) grows from a seed
(:func:`seed_unreached_parts`). Particles ride the front
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
from scipy.spatial import cKDTree
from shapely.geometry import MultiPolygon, Point, Polygon

from core.errors import BGMInputError
from core.geometry.grid import Grid, as_multipolygon, cells_covering
from core.geometry.sdf import region_signed_distance
from core.morph.backtracking import backtrack_trajectories
from core.morph.trajectories import (
    ParticleState,
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
#: Radius (cells) of the disc seeded for a part appearing (a pod, a hole) or a pod pinching out.
SEED_DISC_RADIUS_CELLS = 2.0
#: Morph times (and fronts) are recorded every this many level-set steps.
RECORD_EVERY_STEPS = 2


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
        The regions actually morphed: the source with a seed disc in every
        target part its front cannot reach (:func:`seed_unreached_parts`),
        the target a seed disc when it is empty.
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

    :func:`core.geometry.sdf.region_signed_distance` of the region's
    :meth:`Grid.rasterize` cells (the raster every stage's masks use): exact
    within ``band_cells`` of the boundary, so that the zero set lies on the
    true contour to sub-cell accuracy (particles start and stop on the real
    contours).
    """
    return region_signed_distance(grid, region, band_cells, mask=grid.rasterize(region))


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
    edge = _interface_cells(inside)
    if not edge.any():
        big = float(np.hypot(*phi.shape)) * h if band_m is None else band_m + 2 * h
        return np.where(inside, big, -big)
    rows, cols = phi.shape
    r, c = np.nonzero(edge)
    if band_m is None:
        r0, r1, c0, c1 = 0, rows, 0, cols
        out = np.empty(phi.shape)
    else:
        pad = cells_covering(band_m, h) + 2
        r0, r1 = max(int(r.min()) - pad, 0), min(int(r.max()) + pad + 1, rows)
        c0, c1 = max(int(c.min()) - pad, 0), min(int(c.max()) + pad + 1, cols)
        out = np.where(inside, band_m + 2 * h, -(band_m + 2 * h))
    shape = (r1 - r0, c1 - c0)
    # per interface cell: foot point and unit normal (row, col components)
    foot_r, foot_c, normal_r, normal_c = _foot_and_normal(phi, r, c, h)
    info = np.zeros((4,) + shape)
    info[0, r - r0, c - c0] = r - r0 + foot_r
    info[1, r - r0, c - c0] = c - c0 + foot_c
    info[2, r - r0, c - c0] = normal_r
    info[3, r - r0, c - c0] = normal_c
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


def _interface_cells(inside: np.ndarray) -> np.ndarray:
    """Cells with a 4-neighbour on the other side of the front."""
    edge = np.zeros_like(inside)
    dh = inside[:, 1:] != inside[:, :-1]
    edge[:, 1:] |= dh
    edge[:, :-1] |= dh
    dv = inside[1:, :] != inside[:-1, :]
    edge[1:, :] |= dv
    edge[:-1, :] |= dv
    return edge


def _foot_and_normal(phi: np.ndarray, r: np.ndarray, c: np.ndarray, h: float) -> np.ndarray:
    """``(4, n)``: offset in cells (row, col) of each cell's foot on the zero set, and the unit normal there.

    One Newton step ``-phi grad(phi) / |grad(phi)|^2`` (central differences,
    one-sided at the grid edge), limited to one cell.
    """
    rows, cols = phi.shape
    up, dn = np.minimum(r + 1, rows - 1), np.maximum(r - 1, 0)
    rt, lt = np.minimum(c + 1, cols - 1), np.maximum(c - 1, 0)
    gy = (phi[up, c] - phi[dn, c]) / ((up - dn) * h)
    gx = (phi[r, rt] - phi[r, lt]) / ((rt - lt) * h)
    g2 = np.maximum(gx * gx + gy * gy, 1e-12)
    v = phi[r, c]
    dr = -v * gy / g2 / h
    dc = -v * gx / g2 / h
    n = np.hypot(dr, dc)
    lim = np.where(n > 1.0, 1.0 / np.maximum(n, 1e-12), 1.0)
    g = np.sqrt(g2)
    return np.stack([dr * lim, dc * lim, gy / g, gx / g])


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
    """New values of the band cells after one Godunov upwind step of ``d phi/dt = F |grad phi|``.

    ``phi`` is positive inside. Where ``F > 0`` (front moving outward) ``|grad phi|^2
    = min(D-x,0)^2 + max(D+x,0)^2 + (same in y)``; where ``F < 0`` the roles of
    ``min`` and ``max`` swap (Osher & Sethian scheme for ``psi = -phi``). Edge cells
    are their own neighbours (zero flux).
    """
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


def _seed_disc(grid: Grid, rc: tuple[int, int], depth_m: float) -> Polygon:
    """Disc of radius ``min(SEED_DISC_RADIUS_CELLS, depth)`` (at least half a cell) at cell ``rc``."""
    h = grid.cell_size_m
    x, y = grid.rc_to_xy(np.array([rc], dtype=float))[0]
    return Point(x, y).buffer(min(SEED_DISC_RADIUS_CELLS * h, max(depth_m, 0.5 * h)), quad_segs=16)


def seed_unreached_parts(
    grid: Grid, source: MultiPolygon, source_mask: np.ndarray, target_sdf: np.ndarray
) -> MultiPolygon:
    """The source with a seed for every target part its front cannot reach (paper section 4, pods).

    The morph's speed is the target's signed distance, so the front only
    moves into a cell that must change sign (a target cell outside the
    source, or a source cell outside the target) from the initial front,
    through the connected part of such cells around it, and crawls where
    that part meets the front only along cells less than a cell deep in it
    (speed below one cell per unit time, dying out towards the target
    contour). Such a part (a target pod with no source over it, a hole of
    the target inside the source -- a host pod appearing inside the
    geozone -- or one that touches the source only at a pinch) grows from a
    seed instead, like an appearing pod: a disc of at most
    :data:`SEED_DISC_RADIUS_CELLS` cells at its deepest point (largest
    ``|gamma_t|``), added to the source in the target, cut out of it in a hole.

    Parameters
    ----------
    grid : Grid
    source : MultiPolygon
        Source region (may be empty).
    source_mask : (rows, cols) bool array
        Its cells (``gamma_s > 0``).
    target_sdf : (rows, cols) float array
        ``gamma_t`` (metres, positive inside).

    Returns
    -------
    MultiPolygon
        The seeded source; ``source`` itself when nothing needed a seed.
    """
    h = grid.cell_size_m
    target = target_sdf > 0
    depth = np.abs(target_sdf)
    front = _interface_cells(source_mask)
    grown: list[Polygon] = []
    cut: list[Polygon] = []
    for flip, out in ((target & ~source_mask, grown), (~target & source_mask, cut)):
        labels, n = ndimage.label(flip)
        if not n:
            continue
        part, d = labels[flip], depth[flip]
        deepest, contact = np.zeros(n + 1), np.zeros(n + 1)
        np.maximum.at(deepest, part, d)
        np.maximum.at(contact, part, np.where(front[flip], d, 0.0))
        for i in np.flatnonzero(contact < np.minimum(h, deepest)):
            rc = np.unravel_index(int(np.argmax(np.where(labels == i, depth, -1.0))), depth.shape)
            out.append(_seed_disc(grid, (int(rc[0]), int(rc[1])), float(deepest[i])))
    if not grown and not cut:
        return source
    seeded = shapely.union_all([source, *grown]) if grown else source
    if cut:
        seeded = seeded.difference(shapely.union_all(cut))
    return as_multipolygon(seeded)


def _deepest_disc(region: MultiPolygon, cell_size_m: float) -> MultiPolygon:
    """Seed disc (:func:`_seed_disc`) at the deepest interior point (max of the SDF) of ``region``."""
    grid = Grid.covering(region.bounds, cell_size_m, MARGIN_CELLS)
    sdf = region_sdf(grid, region)
    i = np.unravel_index(int(np.argmax(sdf)), sdf.shape)
    return as_multipolygon(_seed_disc(grid, (int(i[0]), int(i[1])), float(sdf[i])))


# ---------------------------------------------------------------------------
# the morph
# ---------------------------------------------------------------------------


def morph_regions(
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
        side may be empty (not both). A target part the front cannot reach
        from the source -- a pod appearing (no source over it), a host pod
        appearing inside the geozone (a hole of the target inside the
        source), or one the source touches only at a pinch -- grows from a
        small disc (radius 2 cells) at its deepest point
        (:func:`seed_unreached_parts`); a pod pinching out (no target) morphs
        into such a disc at the source's deepest point. The seeded discs are
        reported in ``MorphResult.source`` / ``.target``.
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
    Steps: regions and grid, signed distances, seeds for the target parts
    the front cannot reach, particles on the source contour, level-set
    evolution (:func:`_evolve_front`), trajectories.
    """
    src, tgt, grid = _morph_frame(sources, targets, cell_size_m, speed_clamp_m, max_cells)
    h = grid.cell_size_m
    c = 3.0 * h if speed_clamp_m is None else float(speed_clamp_m)
    gamma = region_sdf(grid, tgt)
    phi0 = region_sdf(grid, src) if not src.is_empty else np.full(grid.shape, -float(np.hypot(*grid.shape)) * h)
    seeded = seed_unreached_parts(grid, src, phi0 > 0, gamma)
    if seeded is not src:
        src, phi0 = seeded, region_sdf(grid, seeded)
    speed = np.clip(gamma, -c, c)
    dt = 0.5 * h / max(float(np.max(np.abs(speed))), 1e-12)  # CFL: the front moves at most h/2 a step
    if max_steps is None:  # enough to cross the grid diagonal twice
        max_steps = int(np.ceil(2 * (float(np.hypot(*grid.shape)) * h / max(c, 1e-12) + _stall_time(c, h)) / dt))
    particles = _seeded_particles(src, tgt, grid, gamma)
    run = _evolve_front(phi0, gamma, speed, particles, grid, dt, c, max_steps, reinit_every_steps, keep_fronts)
    phi = reinitialise(run.phi, h)
    trajs, cov0, cov = _trajectories(particles, dt, run.arrival_time, grid, phi0, src, tgt, backtrack)
    return MorphResult(
        grid=grid,
        phi_final=phi,
        target_sdf=gamma,
        arrival_time=run.arrival_time,
        times=np.asarray(run.times),
        dt=dt,
        n_steps=run.n_steps,
        fronts=run.fronts,
        iou=_iou(phi > 0, gamma > 0),
        source=src,
        target=tgt,
        trajectories=trajs,
        coverage_before_backtracking=cov0,
        target_boundary_coverage=cov,
    )


def _morph_frame(
    sources, targets, cell_size_m: float | None, speed_clamp_m: float | None, max_cells: int
) -> tuple[MultiPolygon, MultiPolygon, Grid]:
    """The source and target regions (a seed disc for an empty target) and the morph grid.

    Checks the input (not both regions empty, a positive speed clamp); the
    cell size defaults to the longer side of both regions over ``max_cells``
    cells, margin included.
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
    if tgt.is_empty:
        tgt = _deepest_disc(src, h)
    return src, tgt, Grid.covering(both.bounds, h, MARGIN_CELLS)


def _stall_time(speed_clamp_m: float, cell_size_m: float) -> float:
    """Morph time without any cell changing sign after which the front counts as stalled."""
    return 2 * np.log(max(speed_clamp_m / (0.05 * cell_size_m), 2.0)) + 4


def _seeded_particles(src: MultiPolygon, tgt: MultiPolygon, grid: Grid, target_sdf: np.ndarray) -> ParticleState:
    """Particles along the source contour, those already on the target contour finished.

    Spacing: a cell, closer where the target contour is the shorter one (down
    to a quarter cell), so the target boundary still gets about one per cell.
    """
    h = grid.cell_size_m
    src_len = sum(p.length for p in src.geoms)
    tgt_len = sum(p.length for p in tgt.geoms)
    particles = seed_particles(src, h * float(np.clip(src_len / max(tgt_len, 1e-12), 0.25, 1.0)))
    if len(particles.xy):
        g0 = bilinear(target_sdf, grid.xy_to_rc(particles.xy))
        done0 = np.abs(g0) < 0.5 * h
        particles.status[done0] = 1
        particles.end_step[done0] = 0
    return particles


class _BandedFront:
    """The level set during the evolution, updated on its narrow band, and its time-of-arrival map.

    ``phi`` is re-initialised (:func:`reinitialise`) on a band of ``band_m``
    and the band rebuilt every few steps (:meth:`reinitialise`); between
    those, :meth:`advance` moves the band cells by one upwind step and records
    when each cell first changes sign from its initial one.
    """

    def __init__(self, phi0: np.ndarray, speed: np.ndarray, cell_size_m: float, band_m: float):
        self.h = cell_size_m
        self.band_m = band_m
        self.arrival_time = np.full(phi0.shape, np.nan)
        self._arrival_flat = self.arrival_time.ravel()
        self._speed, self._positive = speed.ravel(), (speed > 0).ravel()
        self._inside0 = (phi0 > 0).ravel()
        self.phi = phi0
        self.reinitialise()

    def reinitialise(self) -> None:
        self.phi = reinitialise(self.phi, self.h, self.band_m)
        self._flat = self.phi.ravel()
        self.band = _NarrowBand(self.phi, self.band_m)
        idx = self.band.idx
        self._speed_b, self._positive_b, self._inside0_b = self._speed[idx], self._positive[idx], self._inside0[idx]

    def advance(self, t: float, dt: float) -> bool:
        """One step from time ``t``; whether any cell crossed the front for the first time."""
        idx = self.band.idx
        old_b = self._flat[idx]
        new_b = _band_step(self._flat, self.band, self._speed_b, self._positive_b, dt, self.h)
        crossed = ((new_b > 0) != self._inside0_b) & np.isnan(self._arrival_flat[idx])
        if crossed.any():
            o, n = old_b[crossed], new_b[crossed]
            # a cell sitting exactly on the front (o == n == 0) crossed at the step's end
            frac = np.divide(o, o - n, out=np.ones_like(o), where=o != n)
            self._arrival_flat[idx[crossed]] = t + np.clip(frac, 0.0, 1.0) * dt
        self._flat[idx] = new_b
        return bool(crossed.any())


@dataclass
class _Evolution:
    """What :func:`_evolve_front` leaves: the last ``phi`` (not re-initialised), arrival times, recorded times."""

    phi: np.ndarray
    arrival_time: np.ndarray
    times: list[float]
    fronts: list[MultiPolygon]
    n_steps: int


def _evolve_front(
    phi0: np.ndarray,
    gamma: np.ndarray,
    speed: np.ndarray,
    particles: ParticleState,
    grid: Grid,
    dt: float,
    speed_clamp_m: float,
    max_steps: int,
    reinit_every_steps: int,
    keep_fronts: bool,
) -> _Evolution:
    """Evolve ``phi`` from ``phi0`` at ``speed`` (``gamma`` clamped to ``speed_clamp_m``), advecting ``particles``.

    Stopping rule: every cell farther than a tenth of a cell from the target
    contour has the right sign (pixel-exact match; IoU then exceeds 0.99 for
    any region a few cells wide) and no particle is still moving; or no cell
    changed sign for ``2 ln(c / 0.05 h) + 4`` time units (front stalled, e.g.
    a target part not reachable from the source); or ``max_steps``. Times
    (and fronts, if ``keep_fronts``) are recorded every
    :data:`RECORD_EVERY_STEPS` steps and at the end.
    """
    h, c = grid.cell_size_m, speed_clamp_m
    target_mask = gamma > 0
    wrong_sign_matters = np.abs(gamma) > 0.1 * h
    times = [0.0]
    fronts = [grid.polygons_from_field(phi0, 0.0)] if keep_fronts else []
    patience = int(np.ceil(_stall_time(c, h) / dt))
    # the front moves at most max|F| dt = h/2 per step
    front = _BandedFront(phi0, speed, h, (0.5 * reinit_every_steps + 2.0) * h)
    last_change, t, step = 0, 0.0, 0
    for step in range(1, max_steps + 1):
        gnorm = advect_particles(particles, grid, front.phi, gamma, dt, c, step - 1)
        if front.advance(t, dt):
            last_change = step
        t += dt
        drop_lost_particles(particles, grid, front.phi, gnorm)
        if step % 2 == 0:
            merge_close_particles(particles, 0.2 * h)
        if step % RECORD_EVERY_STEPS == 0:
            times.append(t)
            if keep_fronts:
                fronts.append(grid.polygons_from_field(front.phi, 0.0))
        if step % reinit_every_steps == 0:
            if not np.any(particles.status == 0) and not np.any(((front.phi > 0) != target_mask) & wrong_sign_matters):
                break
            front.reinitialise()
        if step - last_change > patience:
            break
    if times[-1] != t:
        times.append(t)
        if keep_fronts:
            fronts.append(grid.polygons_from_field(front.phi, 0.0))
    return _Evolution(front.phi, front.arrival_time, times, fronts, step)


def _iou(region: np.ndarray, target: np.ndarray) -> float:
    """Intersection over union of two cell masks (1 when both are empty)."""
    union = np.count_nonzero(region | target)
    return float(np.count_nonzero(region & target)) / float(union) if union else 1.0


def _trajectories(
    particles: ParticleState,
    dt: float,
    arrival_time: np.ndarray,
    grid: Grid,
    source_sdf: np.ndarray,
    src: MultiPolygon,
    tgt: MultiPolygon,
    backtrack: bool,
) -> tuple[list[Trajectory], float, float]:
    """Source-to-target trajectories and the target boundary coverage before and after backtracking.

    The particles' paths, crossings removed; where they leave part of the
    target boundary uncovered (and ``backtrack``), curvelet backtracking
    (:func:`core.morph.backtracking.backtrack_trajectories`) adds tracks. Sorted
    along the source contour (:func:`_sort_along_source`).
    """
    h = grid.cell_size_m
    trajs = remove_crossings(finished_trajectories(particles, dt, h))
    cov0 = boundary_coverage(trajs, tgt, h)
    cov = cov0
    if backtrack and cov0 < 1.0:
        trajs = backtrack_trajectories(trajs, arrival_time, grid, source_sdf, src, tgt)
        cov = boundary_coverage(trajs, tgt, h)
    return _sort_along_source(trajs, src, h), cov0, cov


def _sort_along_source(trajs: list[Trajectory], src: MultiPolygon, h: float) -> list[Trajectory]:
    """Order trajectories by (source ring, arc length of start, advected first)."""
    if not trajs:
        return trajs
    xy, ring, arc, _ = ring_samples(src, 0.25 * h)
    if not len(xy):
        return trajs
    starts = np.array([tr.xy[0] for tr in trajs])
    _, k = cKDTree(xy).query(starts)
    order = np.lexsort((np.array([tr.backtracked for tr in trajs]), arc[k], ring[k]))
    return [trajs[i] for i in order]
