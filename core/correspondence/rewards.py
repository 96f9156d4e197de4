"""Rewards for a source splitting into several targets (paper section 3.2.3, Algorithm 7).

A source associated with several targets (one-to-many) that lie close
together should straddle them, as the boundary that splits between the two
benches did; aligned with the plain union of the targets' signed distances it
would instead drop onto the largest one. The gap between targets the source
could bridge is therefore rewarded: the "strategic location" is the convex
hull of the group, and its signed distance is the value there.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.sparse.csgraph import connected_components
from shapely.geometry import MultiPolygon

from core.correspondence.alignment import TargetRasters
from core.geometry.sdf import signed_distance

#: One-to-many reward (Algorithm 7): cells in the gap between a splitting
#: source's targets get this fraction of the SDF of the targets' convex hull
#: (1 aligns the source with the target group as if it were one region).
BRIDGE_REWARD_FRACTION = 1.0


def bridgeable_groups(target_ids: list[int], targets: list[MultiPolygon], reach_m: float) -> list[list[int]]:
    """Targets grouped by single linkage on their gaps: gaps up to ``reach_m`` join.

    :func:`scipy.sparse.csgraph.connected_components` of the graph "gap
    <= ``reach_m``" (metres). Returns the groups as lists of target ids.
    """
    n = len(target_ids)
    near = np.zeros((n, n), dtype=bool)
    for i in range(n):
        for j in range(i + 1, n):
            near[i, j] = targets[target_ids[i]].distance(targets[target_ids[j]]) <= reach_m
    _, label = connected_components(near, directed=False)
    return [[target_ids[i] for i in np.flatnonzero(label == g)] for g in np.unique(label)]


def bridge_value_function(
    target_ids: list[int],
    targets: list[MultiPolygon],
    rasters: TargetRasters,
    reach_m: float,
    v_union: np.ndarray,
) -> np.ndarray:
    """Value function with rewards for straddling several targets (Algorithm 7).

    The source's targets are grouped by :func:`bridgeable_groups` with
    ``reach_m`` the source's extent (the gaps it could actually bridge). For
    each group of two or more targets, the convex hull of the group is the
    "strategic location": the value there is the SDF of the hull, positive in
    the gap between targets (scaled by ``BRIDGE_REWARD_FRACTION``) as well as
    inside them, so the source is aligned with the target group as a whole.
    Lone targets keep their own SDF. The value function is the maximum over
    groups; ``v_union`` (the plain maximum of the targets' SDFs) is returned
    unchanged when no two targets group.
    """
    groups = bridgeable_groups(target_ids, targets, reach_m)
    if all(len(g) == 1 for g in groups):
        return v_union
    grid = rasters.grid
    out = np.full(grid.shape, -np.inf)
    for members in groups:
        if len(members) == 1:
            np.maximum(out, rasters.sdf(members[0]), out=out)
            continue
        hull_mask = grid.rasterize(shapely.union_all([targets[t] for t in members]).convex_hull)
        hull_sdf = signed_distance(hull_mask, grid.cell_size_m)
        gap = hull_mask & ~np.any([rasters.mask(t) for t in members], axis=0)
        np.maximum(out, np.where(gap, BRIDGE_REWARD_FRACTION * hull_sdf, hull_sdf), out=out)
    return out
