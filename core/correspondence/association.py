"""Region association: which sources may interact with which targets (paper section 3.1, eqs. (1)-(9)).

A source (a component on the upper bench) is associated with a target (a
component on the bench below) when the target lies, for the most part, where
a Gaussian likelihood centred on the source -- scaled by the source's size and
by how far the components of the two benches typically lie apart -- is high.
In detail (:func:`association_matrix`):

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

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from core.geometry.grid import Grid, as_multipolygon, union_bounds


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
    The equations and the one safeguard added to them are in the module
    docstring.
    """
    ns, nt = len(sources), len(targets)
    A = np.zeros((ns, nt), dtype=bool)
    if ns == 0 or nt == 0:
        return A
    if not (mu_lower_m > 0 and np.isfinite(mu_lower_m)):
        raise ValueError(f"mu_lower_m must be positive, got {mu_lower_m}")
    src = [as_multipolygon(s) for s in sources]
    tgt = [as_multipolygon(t) for t in targets]
    s_ok = np.array([not g.is_empty for g in src])
    t_ok = np.array([not g.is_empty for g in tgt])
    if not s_ok.any() or not t_ok.any():
        return A
    d = np.full((ns, nt), np.inf)
    si, ti = np.nonzero(s_ok[:, None] & t_ok[None, :])
    d[si, ti] = shapely.distance(np.array(src, dtype=object)[si], np.array(tgt, dtype=object)[ti])
    mu, nu = _gap_statistics(d[s_ok].min(axis=1), mu_lower_m)
    a_s = np.array([g.area for g in src])
    lam = np.maximum(np.minimum(mu, np.sqrt(a_s / np.pi)), mu_lower_m)
    c_s = np.array([[g.centroid.x, g.centroid.y] if not g.is_empty else [np.nan, np.nan] for g in src])
    if grid is None:
        bounds = union_bounds(src + tgt)
        assert bounds is not None  # some source and some target are not empty
        grid = Grid.for_extent(bounds, cells_across=256, margin_cells=2)
    masks = {} if target_masks is None else target_masks
    ok = np.nonzero(s_ok)[0]
    for t in np.flatnonzero(t_ok).tolist():
        if t not in masks:
            masks[t] = grid.rasterize(tgt[t])
        xy = _cell_xy(grid, masks[t], tgt[t])
        A[ok, t] = _likely_over_target(xy, c_s[ok], lam[ok], nu, a_s[ok] / max(tgt[t].area, 1e-300))
    A |= d <= 0.0  # safeguard: overlapping / touching pairs always associate
    return A


def _gap_statistics(d_min: np.ndarray, mu_lower_m: float) -> tuple[float, float]:
    """``(mu, nu)`` from each source's gap to its nearest target (eqs. (1), (2), (7))."""
    mu = float(np.mean(d_min))
    sigma = float(np.sqrt(max(np.mean(d_min**2) - mu**2, 0.0)))
    s_err = sigma / math.sqrt(len(d_min))
    return mu, 4.0 / (1.0 + math.exp(-s_err / mu_lower_m))


def _likely_over_target(
    cells_xy: np.ndarray, centroids_xy: np.ndarray, scales_m: np.ndarray, nu: float, area_ratio: np.ndarray
) -> np.ndarray:
    """Whether each source's likelihood (eq. (5)) passes the percentile test over a target's cells (eqs. (8)-(9)).

    ``area_ratio`` is ``a_s / a_t`` per source.
    """
    diff = cells_xy[None, :, :] - centroids_xy[:, None, :]
    r2 = np.einsum("sck,sck->sc", diff, diff) / scales_m[:, None] ** 2
    p = np.exp(-r2 / (2.0 * nu**2))
    K = 50.0 * (1.0 + (1.0 - np.minimum(area_ratio, 1.0)))
    return np.array([np.percentile(p[row], K[row]) >= 0.5 for row in range(len(p))], dtype=bool)


def _cell_xy(grid: Grid, mask: np.ndarray, geom: MultiPolygon) -> np.ndarray:
    """World coordinates of the cells of ``mask``; a representative point if none."""
    rr, cc = np.nonzero(mask)
    if rr.size == 0:
        p = geom.representative_point()
        return np.array([[p.x, p.y]])
    return grid.rc_to_xy(np.column_stack([rr, cc]))
