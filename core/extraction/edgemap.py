"""Edge map synthesis (paper section 2.4, Algorithm 2).

Boundary holes are joined to their nearest boundary neighbours by line
segments; the segments are densely sampled onto the image grid, given a
margin, and closed morphologically. The result is the edge map ``f`` that the
gradient vector flow diffuses (section 2.5).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree
from skimage import morphology

from core.geometry.grid import Grid


def edge_structure(
    points_m: np.ndarray,
    max_edge_m: float,
    edge_neighbours: int = 5,
    edge_joints: int = 4,
    max_joint_m: float | None = None,
) -> np.ndarray:
    """Segments joining boundary holes to their neighbours.

    Parameters
    ----------
    points_m : (m, 2) float
        Boundary hole positions (metres).
    max_edge_m : float
        Longest ordinary edge: each point joins its ``K_struct`` nearest
        boundary holes that are closer than this.
    edge_neighbours : int
        ``K_struct`` (paper default 5).
    edge_joints : int
        ``K_joints`` (paper default 4): each point is always joined to this
        many nearest boundary holes, up to ``max_joint_m``, so boundary holes
        separated by a missing hole still link into one outline.
    max_joint_m : float, optional
        Longest joint; ``1.6 * max_edge_m`` by default.

    Returns
    -------
    (e, 2) int
        Unique index pairs ``i < j``.
    """
    m = len(points_m)
    if m < 2:
        return np.zeros((0, 2), dtype=int)
    max_joint_m = 1.6 * max_edge_m if max_joint_m is None else max_joint_m
    k = min(max(edge_neighbours, edge_joints) + 1, m)
    dist, idx = cKDTree(points_m).query(points_m, k=k)
    dist, idx = dist[:, 1:], idx[:, 1:]
    rank = np.arange(k - 1)[None, :]
    keep = ((rank < edge_neighbours) & (dist <= max_edge_m)) | ((rank < edge_joints) & (dist <= max_joint_m))
    i = np.repeat(np.arange(m), k - 1).reshape(m, k - 1)[keep]
    j = idx[keep]
    pairs = np.sort(np.column_stack([i, j]), axis=1)
    return np.unique(pairs, axis=0)


def synthesize_edge_map(
    grid: Grid,
    points_m: np.ndarray,
    edges: np.ndarray,
    interior_m: np.ndarray | None = None,
    interior_radius_m: float = 0.0,
    margin_cells: float = 0.0,
    closing_cells: int = 1,
    smoothing_cells: float = 1.5,
) -> np.ndarray:
    """Rasterise an edge structure into an edge map in [0, 1] (Algorithm 2).

    Each segment is sampled every half cell; pixels within ``margin_cells`` of
    a sample receive edge energy; a morphological closing with a disc of
    radius ``closing_cells`` gives the edges thickness (section 2.4,
    footnote); a Gaussian blur turns each edge into a ridge. Edges are kept
    thin on purpose: a thick flat band has no gradient inside, so the GVF
    vanishes there and the snake would sink to the band's inner side instead
    of settling on the outermost edge line.

    When ``interior_m`` (the component's holes) is given, the edge structure
    and discs of ``interior_radius_m`` around those holes are filled into a
    solid and only its outline is kept. Edges inside a component (around a
    mislabelled hole, or cross edges of ``K_struct``) would otherwise trap a
    snake closing in from the bounding box; the outline is what it must find.
    """
    rows, cols = grid.shape
    hit = np.zeros(grid.shape, dtype=bool)
    if len(points_m):
        rc_points = grid.xy_to_rc(points_m)
        samples = [rc_points]
        if len(edges):
            a, b = rc_points[edges[:, 0]], rc_points[edges[:, 1]]
            length = np.hypot(*(b - a).T)
            steps = np.maximum(np.ceil(length * 2).astype(int), 1)
            seg = np.repeat(np.arange(len(edges)), steps + 1)
            t = np.concatenate([np.linspace(0, 1, s + 1) for s in steps])
            samples.append(a[seg] + (b - a)[seg] * t[:, None])
        rc = np.rint(np.vstack(samples)).astype(int)
        ok = (rc[:, 0] >= 0) & (rc[:, 0] < rows) & (rc[:, 1] >= 0) & (rc[:, 1] < cols)
        hit[rc[ok, 0], rc[ok, 1]] = True
    if margin_cells >= 1:
        hit = ndimage.binary_dilation(hit, morphology.disk(max(int(round(margin_cells)), 1)))
    if closing_cells > 0:
        hit = ndimage.binary_closing(hit, morphology.disk(closing_cells))
    if interior_m is not None and len(interior_m):
        radius = max(int(np.ceil(interior_radius_m / grid.cell_size_m)), 1)
        rc = np.rint(grid.xy_to_rc(interior_m)).astype(int)
        ok = (rc[:, 0] >= 0) & (rc[:, 0] < rows) & (rc[:, 1] >= 0) & (rc[:, 1] < cols)
        seeds = np.zeros(grid.shape, dtype=bool)
        seeds[rc[ok, 0], rc[ok, 1]] = True
        solid = ndimage.binary_fill_holes(hit | ndimage.binary_dilation(seeds, morphology.disk(radius)))
        hit = solid & ~ndimage.binary_erosion(solid)
    f = ndimage.gaussian_filter(hit.astype(float), smoothing_cells) if smoothing_cells > 0 else hit.astype(float)
    top = f.max()
    return f / top if top > 0 else f
