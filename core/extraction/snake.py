"""Active contour evolution in a gradient vector field (paper section 2.5, Appendix A).

A closed snake of ``N`` control points with internal energy
``alpha/2 |x'|^2 + beta/2 |x''|^2`` moves under the external force of the GVF
field sampled at its points (Kass et al. 1988; Xu & Prince 1998). The
semi-implicit step is ``x_new = (I + tau A)^-1 (x + tau kappa v(x))`` with
``A`` the cyclic pentadiagonal matrix of ``alpha`` and ``beta``
(``../shared/ALGORITHMS.md``). scikit-image's ``active_contour`` hard-wires
image-gradient forces, hence this module.

Everything here is in grid units (cells); :mod:`core.extraction.contours` maps to metres.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import ndimage


def internal_stencil(n: int, alpha: float, beta: float) -> np.ndarray:
    """First row of the cyclic pentadiagonal internal-energy matrix ``A`` for ``n`` points."""
    row = np.zeros(n)
    row[0] = 2 * alpha + 6 * beta
    row[1] = row[-1] = -alpha - 4 * beta
    row[2] = row[-2] = beta
    return row


def resample_closed(points: np.ndarray, n: int) -> np.ndarray:
    """Resample a closed polyline to ``n`` points evenly spaced in arc length."""
    closed = np.vstack([points, points[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return np.repeat(points[:1], n, axis=0)
    t = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def box_snake(rc_min: np.ndarray, rc_max: np.ndarray, n: int) -> np.ndarray:
    """``n`` points evenly around a rectangle (row, col), counter-clockwise in x-y."""
    (r0, c0), (r1, c1) = rc_min, rc_max
    corners = np.array([[r0, c0], [r0, c1], [r1, c1], [r1, c0]], dtype=float)
    return resample_closed(corners, n)


def evolve_snake(
    snake_rc: np.ndarray,
    field: np.ndarray,
    *,
    alpha: float = 0.05,
    beta: float = 0.05,
    step: float = 1.0,
    max_iterations: int = 600,
    tolerance: float = 0.02,
    resample_every: int = 10,
    keep_history: bool = False,
    check: Callable[[], None] | None = None,
) -> tuple[np.ndarray, list[np.ndarray], int]:
    """Evolve a closed snake in a GVF field until it stops moving.

    Parameters
    ----------
    snake_rc : (N, 2) float
        Initial control points (row, col), e.g. :func:`box_snake`.
    field : (2, rows, cols) float
        GVF field; ``field[0]`` is the x (column) and ``field[1]`` the y (row)
        component. It is normalised to unit length where non-zero, so the snake
        travels at ``step`` cells per iteration far from edges (the raw GVF
        decays with distance, which would stall a snake started on the
        bounding box).
    alpha, beta : float
        Elasticity and rigidity (grid units).
    step : float
        Time step ``tau`` (cells per iteration at unit force).
    max_iterations : int
    tolerance : float
        Stop when the mean point movement over ``resample_every`` iterations
        falls below this many cells per iteration.
    resample_every : int
        Re-spacing interval (keeps points evenly spread along the contour).
    keep_history : bool
        Return the snake every ``resample_every`` iterations (for the viewer).
    check : callable, optional
        Called every ``resample_every`` iterations; an exception it raises
        (:class:`core.threads.Cancelled`: the caller no longer wants the
        snake) stops the evolution there.

    Returns
    -------
    snake : (N, 2) float
        Final control points (row, col).
    history : list of (N, 2) arrays
        Snake positions over the iterations (empty unless ``keep_history``).
    iterations : int
        Iterations run.
    """
    n = len(snake_rc)
    magnitude = np.hypot(field[0], field[1])
    with np.errstate(invalid="ignore", divide="ignore"):
        fx = np.where(magnitude > 1e-12, field[0] / magnitude, 0.0)
        fy = np.where(magnitude > 1e-12, field[1] / magnitude, 0.0)
    rows, cols = field.shape[1:]
    # (I + tau A) is circulant, so its inverse is a division in Fourier space:
    # O(N log N) per step instead of a dense N x N inverse.
    stencil = internal_stencil(n, alpha, beta)
    stencil[0] += 1.0 / step
    eigen = np.fft.rfft(stencil * step)
    x = np.asarray(snake_rc, dtype=float).copy()
    history = [x.copy()] if keep_history else []
    previous = x.copy()
    it = 0
    for it in range(1, max_iterations + 1):
        coords = x.T
        force_r = ndimage.map_coordinates(fy, coords, order=1, mode="nearest")
        force_c = ndimage.map_coordinates(fx, coords, order=1, mode="nearest")
        rhs = x + step * np.column_stack([force_r, force_c])
        x = np.fft.irfft(np.fft.rfft(rhs, axis=0) / eigen[:, None], n=n, axis=0)
        x[:, 0] = np.clip(x[:, 0], 0, rows - 1)
        x[:, 1] = np.clip(x[:, 1], 0, cols - 1)
        if it % resample_every == 0:
            if check:
                check()
            x = resample_closed(x, n)
            if keep_history:
                history.append(x.copy())
            # Mean normal movement = change of enclosed area / perimeter; point
            # sliding along the contour during re-spacing does not count.
            perimeter = np.sum(np.hypot(*np.diff(np.vstack([x, x[:1]]), axis=0).T))
            moved = abs(_area(x) - _area(previous)) / max(perimeter, 1e-9) / resample_every
            previous = x.copy()
            if moved < tolerance:
                break
    return x, history, it


def _area(points: np.ndarray) -> float:
    """Shoelace area of a closed polyline."""
    r, c = points[:, 0], points[:, 1]
    return 0.5 * float(np.dot(r, np.roll(c, -1)) - np.dot(c, np.roll(r, -1)))
