"""Connected components and boundary holes (paper sections 2.1-2.3).

* Connected components: kD-tree region growing within a radius ``r``
  (section 2.1). Propagating the minimum cluster index between neighbours
  until nothing changes yields exactly the connected components of the
  ``r``-neighbour graph, which ``scipy.sparse.csgraph`` computes directly.
* Boundary holes by local entropy (section 2.2): ``h_n = -sum p log2(p + eps)``
  over the geozone fractions within ``r``; a hole is on a boundary when
  ``h_n >= max(T_entropy, median of h over its neighbourhood)``.
* Gap closure by orientation analysis (section 2.3): a hole whose
  ``K_orient`` nearest neighbours leave an angular gap wider than
  ``T_orient`` sits on an open frontier of the surveyed area.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components as _graph_components
from scipy.spatial import cKDTree

ENTROPY_EPS = 1e-12


def connected_components(xy: np.ndarray, search_radius_m: float) -> np.ndarray:
    """Label holes that are connected through neighbours within ``search_radius_m``.

    Parameters
    ----------
    xy : (n, 2) float
        Holes of one geozone on one bench.
    search_radius_m : float
        Region-growing radius ``r`` (section 2.1).

    Returns
    -------
    (n,) int
        Component index per hole, numbered by decreasing size (0 = largest).
    """
    n = len(xy)
    if n == 0:
        return np.zeros(0, dtype=int)
    pairs = cKDTree(xy).query_pairs(search_radius_m, output_type="ndarray")
    graph = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = _graph_components(graph, directed=False)
    sizes = np.bincount(labels)
    order = np.argsort(-sizes, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[labels]


def neighbour_table(xy: np.ndarray, search_radius_m: float, max_neighbours: int = 24) -> np.ndarray:
    """Indices of each hole's neighbours within the radius (itself included), padded with ``n``."""
    k = min(max_neighbours, len(xy))
    _, idx = cKDTree(xy).query(xy, k=k, distance_upper_bound=search_radius_m)
    return np.asarray(idx).reshape(len(xy), k)


def local_entropy(labels: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
    """Local geozone entropy ``h_n`` of every hole (section 2.2).

    Parameters
    ----------
    labels : (n,) array
        Geozone of every hole on the bench.
    neighbours : (n, k) int
        From :func:`neighbour_table` (padding value ``n``).
    """
    n = len(labels)
    kinds, codes = np.unique(labels, return_inverse=True)
    codes = codes.ravel()
    valid = neighbours < n
    rows = np.repeat(np.arange(n), neighbours.shape[1])[valid.ravel()]
    cols = codes[neighbours[valid]]
    counts = sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, len(kinds))).toarray()
    p = counts / counts.sum(axis=1, keepdims=True)
    return -np.sum(p * np.log2(p + ENTROPY_EPS), axis=1)


def entropy_boundary(entropy: np.ndarray, neighbours: np.ndarray, threshold: float = 0.5) -> np.ndarray:
    """Holes with ``h_n >= max(T_entropy, median neighbourhood entropy)`` (section 2.2)."""
    n = len(entropy)
    padded = np.append(entropy, np.nan)
    with np.errstate(all="ignore"):
        median = np.nanmedian(padded[np.minimum(neighbours, n)], axis=1)
    return entropy >= np.maximum(threshold, median)


def gap_boundary(
    xy: np.ndarray, gap_angle_rad: float = 2 * np.pi / 3, gap_neighbours: int = 12, search_radius_m: float = np.inf
) -> tuple[np.ndarray, np.ndarray]:
    """Holes on an open frontier by orientation analysis (section 2.3).

    The directions to the ``K_orient`` nearest holes of the same component
    (within ``search_radius_m``) are sorted; a gap wider than ``T_orient``
    marks a frontier hole.

    Returns
    -------
    on_gap : (n,) bool
    outward : (n, 2) float
        Unit vector through the middle of the widest gap (the way out of the
        component), zero where there is no neighbour at all.
    """
    n = len(xy)
    if n == 0:
        return np.zeros(0, bool), np.zeros((0, 2))
    if n == 1:
        return np.ones(1, bool), np.zeros((1, 2))
    k = min(gap_neighbours + 1, n)
    dist, idx = cKDTree(xy).query(xy, k=k, distance_upper_bound=search_radius_m)
    dist, idx = dist[:, 1:], idx[:, 1:]
    valid = np.isfinite(dist)
    safe = np.where(valid, idx, 0)
    d = xy[safe] - xy[:, None, :]
    angle = np.where(valid, np.arctan2(d[..., 1], d[..., 0]), np.inf)
    angle = np.sort(angle, axis=1)
    count = valid.sum(axis=1)
    # Gaps between successive directions, plus the wrap-around gap.
    first = angle[:, 0]
    last = np.take_along_axis(angle, np.maximum(count - 1, 0)[:, None], axis=1)[:, 0]
    with np.errstate(invalid="ignore"):  # a hole with no neighbour: inf - inf
        inner = np.diff(angle, axis=1)
        wrap = first + 2 * np.pi - last
    inner[~np.isfinite(inner)] = -np.inf
    gaps = np.column_stack([inner, wrap])
    widest = np.argmax(gaps, axis=1)
    gap = gaps[np.arange(n), widest]
    start = np.where(widest < inner.shape[1], angle[np.arange(n), np.minimum(widest, inner.shape[1] - 1)], last)
    middle = start + gap / 2
    outward = np.column_stack([np.cos(middle), np.sin(middle)])
    lonely = count == 0
    gap = np.where(lonely, 2 * np.pi, gap)
    outward[lonely] = 0.0
    return gap > gap_angle_rad, outward
