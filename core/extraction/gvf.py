"""Gradient vector flow (Xu & Prince 1998; paper section 2.5 and Appendix A).

The GVF field ``v = (u, w)`` of an edge map ``f`` minimises
``mu (|grad u|^2 + |grad w|^2) + |grad f|^2 |v - grad f|^2``. Its steady state
solves one sparse linear system per component,
``(b I - mu L) u = b f_x`` and ``(b I - mu L) w = b f_y`` with
``b = f_x^2 + f_y^2`` and ``L`` the 5-point Laplacian with reflecting borders
(``../shared/ALGORITHMS.md``). The matrix is shared, so it is factorised once
and solved twice. The classic explicit iteration is kept for comparison in the
benchmark (:func:`gvf_explicit`): a few hundred iterations stop far short of
the steady state, which limits how far the field reaches into concavities.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu


def laplacian_matrix(shape: tuple[int, int]) -> sparse.csc_matrix:
    """5-point Laplacian on a unit grid with reflecting (Neumann) borders."""
    rows, cols = shape

    def second_difference(n: int) -> sparse.csr_matrix:
        main = -2.0 * np.ones(n)
        main[0] = main[-1] = -1.0  # reflecting border: the ghost cell equals the edge cell
        off = np.ones(n - 1)
        return sparse.diags([off, main, off], [-1, 0, 1], format="csr")

    if rows < 2 or cols < 2:
        raise ValueError(f"GVF grid must be at least 2 x 2, got {shape}")
    return (
        sparse.kron(sparse.identity(rows), second_difference(cols))
        + sparse.kron(second_difference(rows), sparse.identity(cols))
    ).tocsc()


def edge_gradient(edge_map: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(f_x, f_y)``: gradient of the edge map along columns (x) and rows (y)."""
    f_y, f_x = np.gradient(np.asarray(edge_map, dtype=float))
    return f_x, f_y


def gvf_steady_state(edge_map: np.ndarray, mu: float = 0.2) -> np.ndarray:
    """Steady-state gradient vector flow of an edge map by one sparse solve.

    Parameters
    ----------
    edge_map : (rows, cols) float
        Edge map ``f``, normalised to [0, 1] (paper Algorithm 2 output).
    mu : float
        Regularisation weight on a unit grid (Xu & Prince use 0.1-0.2).

    Returns
    -------
    (2, rows, cols) float
        ``v[0]`` is the x (column) component, ``v[1]`` the y (row) component.
    """
    f = np.asarray(edge_map, dtype=float)
    f_x, f_y = edge_gradient(f)
    b = (f_x**2 + f_y**2).ravel()
    if not np.any(b > 0):
        return np.zeros((2, *f.shape))
    system = (sparse.diags(b) - mu * laplacian_matrix(f.shape)).tocsc()
    lu = splu(system, permc_spec="MMD_AT_PLUS_A")
    u = lu.solve(b * f_x.ravel())
    w = lu.solve(b * f_y.ravel())
    return np.stack([u.reshape(f.shape), w.reshape(f.shape)])


def gvf_explicit(edge_map: np.ndarray, mu: float = 0.2, iterations: int = 200, dt: float | None = None) -> np.ndarray:
    """The classic explicit GVF iteration (for comparison only).

    ``v += dt (mu Lap(v) - b (v - grad f))`` with ``dt = 1 / (4 mu)`` (the
    stability limit on a unit grid) unless given.
    """
    f = np.asarray(edge_map, dtype=float)
    f_x, f_y = edge_gradient(f)
    b = f_x**2 + f_y**2
    dt = 1.0 / (4.0 * mu) if dt is None else dt
    dt = min(dt, 0.9 / (4.0 * mu + b.max() + 1e-12))
    u, w = f_x.copy(), f_y.copy()
    for _ in range(iterations):
        u = u + dt * (mu * _laplacian(u) - b * (u - f_x))
        w = w + dt * (mu * _laplacian(w) - b * (w - f_y))
    return np.stack([u, w])


def gvf_residual(edge_map: np.ndarray, field: np.ndarray, mu: float = 0.2) -> float:
    """Relative residual of the steady-state equations: 0 at steady state."""
    f_x, f_y = edge_gradient(edge_map)
    b = f_x**2 + f_y**2
    res_u = mu * _laplacian(field[0]) - b * (field[0] - f_x)
    res_w = mu * _laplacian(field[1]) - b * (field[1] - f_y)
    scale = np.linalg.norm(b * f_x) + np.linalg.norm(b * f_y) + 1e-300
    return float((np.linalg.norm(res_u) + np.linalg.norm(res_w)) / scale)


def _laplacian(a: np.ndarray) -> np.ndarray:
    p = np.pad(a, 1, mode="edge")
    return p[:-2, 1:-1] + p[2:, 1:-1] + p[1:-1, :-2] + p[1:-1, 2:] - 4.0 * a
