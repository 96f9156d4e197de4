"""Displacement estimation by FFT cross-correlation (paper section 3.2.1, eqs. (10)-(13), Algorithm 4).

A source is aligned with its target(s) by sliding its mask ``u`` over a
*value function* ``v`` -- the targets' signed distance (Algorithm 3),
possibly with port penalties (:mod:`core.correspondence.ports`) and bridge
rewards (:mod:`core.correspondence.rewards`) -- and keeping the lag with the
largest correlation ``r[m] = sum_i v[i] u[i - m]``, computed through the FFT.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from shapely.geometry import MultiPolygon, Polygon

from core.geometry.grid import Grid, as_multipolygon, union_bounds
from core.geometry.sdf import signed_distance


@dataclass
class TargetRasters:
    """Masks and signed distances (Algorithm 3) of the targets on the alignment grid.

    Each is computed once, when first asked for: only associated targets need
    a signed distance. ``masks`` can be shared with
    :func:`core.correspondence.association.association_matrix`, which fills it.
    """

    grid: Grid
    targets: list[MultiPolygon]
    masks: dict[int, np.ndarray] = field(default_factory=dict)
    sdfs: dict[int, np.ndarray] = field(default_factory=dict)

    def mask(self, t: int) -> np.ndarray:
        """Cells of target ``t``."""
        if t not in self.masks:
            self.masks[t] = self.grid.rasterize(self.targets[t])
        return self.masks[t]

    def sdf(self, t: int) -> np.ndarray:
        """Signed distance of target ``t`` (metres, positive inside)."""
        if t not in self.sdfs:
            self.sdfs[t] = signed_distance(self.mask(t), self.grid.cell_size_m)
        return self.sdfs[t]


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
    correlate, corner = _source_correlator(u)
    r = correlate(v)
    valid = np.ones(r.shape, dtype=bool)
    if obstacle_mask is not None and np.any(obstacle_mask):
        free = correlate(np.asarray(obstacle_mask, dtype=float)) < 0.5
        if free.any():
            valid = free
    return _best_lag(r, valid, corner, subpixel)


def _source_correlator(u: np.ndarray) -> tuple[Callable[[np.ndarray], np.ndarray], tuple[int, int]]:
    """Valid linear cross-correlation with the source ``u`` cropped to its bounding box.

    Returns the function ``field -> r`` (one FFT of ``field`` each call; the
    source's transform is computed once here) and the crop's top-left cell
    ``(r0, c0)``: entry ``[a, b]`` of ``r`` is the lag ``(a - r0, b - c0)``.
    """
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

    return correlate, (int(r0), int(c0))


def _best_lag(r: np.ndarray, valid: np.ndarray, corner: tuple[int, int], subpixel: bool) -> tuple[float, float]:
    """Admissible lag of largest correlation, the smallest shift among ties (see :func:`fft_translation`)."""
    r0, c0 = corner
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


def frame_for(geoms: list[MultiPolygon], cell_size_m: float, pad_m: float) -> Grid:
    """Grid of ``cell_size_m`` over the union of ``geoms`` (not all empty) grown by ``pad_m`` metres."""
    b = union_bounds(geoms)
    if b is None:
        raise ValueError("cannot frame empty geometries")
    return Grid.covering((b[0] - pad_m, b[1] - pad_m, b[2] + pad_m, b[3] + pad_m), cell_size_m, 0)


def shift_mask(mask: np.ndarray, d_row: int, d_col: int) -> np.ndarray:
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
    src, tgt = as_multipolygon(source), as_multipolygon(target)
    if src.is_empty or tgt.is_empty:
        return (0.0, 0.0)
    xmin, ymin, xmax, ymax = src.bounds
    pad = max(xmax - xmin, ymax - ymin) + 4 * cell_size_m
    grid = frame_for([src, tgt], cell_size_m, pad)
    v = signed_distance(grid.rasterize(tgt), cell_size_m)
    d_row, d_col = fft_translation(grid.rasterize(src), v, subpixel=subpixel)
    return (d_col * cell_size_m, d_row * cell_size_m)
