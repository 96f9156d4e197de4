"""Label noise: holes whose geozone label is most likely a mislabelled assay.

A geologist reading a blasthole plan does not draw a body around one hole of
``g1`` in the middle of host rock: a single odd label is far more often a
mislabelled or mixed sample than an ore body one hole across. This module
finds such holes so that extraction treats them as the geozone around them,
and reports them, instead of turning each into a contour, a surface and a
prediction (paper section 2.1 finds the components; this is the test applied
to the smallest of them).

The size threshold comes from the drilling pattern, not from a fixed count: a
hole is *isolated* when it belongs to a connected component (section 2.1) in
which no hole has more than one neighbour of its own label in the first ring
of the pattern (within :data:`FIRST_RING_SPACINGS` hole spacings). On any
staggered or square pattern that is a component of one or two holes, or a
sparse chain of them; a body three holes across, or a strip one hole wide
along a row, always has a hole with two same-label neighbours and is kept.
The component must also be surrounded: its first-ring neighbours are holes of
other geozones, at least :data:`MIN_SURROUNDING` of them (a component at the
edge of the drilled area with nothing around it is not called noise).

Three holes in a chain (one of them with a single same-label neighbour, not a
triangle) are a lens or two mislabelled holes beside a third, and which one
depends on how noisy the bench is: :func:`noise_explains_chains` compares
the chains with what the bench's own isolated holes and pairs predict, and
where noise accounts for most of them they are taken as noise too.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from core.extraction.boundary import connected_components

#: The first ring of neighbours of a staggered (or square) pattern lies within
#: about one spacing (jitter included); the second ring starts at sqrt(3) spacings.
FIRST_RING_SPACINGS = 1.35
#: Fewest holes of other geozones around a component for it to count as surrounded.
MIN_SURROUNDING = 3


def isolated_holes(
    xy: np.ndarray, labels: np.ndarray, hole_spacing_m: float, search_radius_m: float | None = None
) -> np.ndarray:
    """Holes taken as label noise: small surrounded components (see the module docstring).

    Parameters
    ----------
    xy : (n, 2) float
        Holes of one bench, metres.
    labels : (n,) array
        Geozone of every hole.
    hole_spacing_m : float
        Median hole spacing of the bench.
    search_radius_m : float, optional
        Region-growing radius of the components (section 2.1); 1.6 spacings by default.

    Returns
    -------
    (n,) bool
        True for isolated holes.
    """
    n = len(xy)
    if n < 2:
        return np.zeros(n, bool)
    ring = FIRST_RING_SPACINGS * hole_spacing_m
    radius = search_radius_m or 1.6 * hole_spacing_m
    tree = cKDTree(xy)
    pairs = tree.query_pairs(ring, output_type="ndarray")
    same = labels[pairs[:, 0]] == labels[pairs[:, 1]]
    same_count = np.bincount(pairs[same].ravel(), minlength=n)
    other_count = np.bincount(pairs[~same].ravel(), minlength=n)
    owner = np.zeros(n, int)  # every hole's component, numbered across geozones
    most: list[np.ndarray] = []  # per component, one array per geozone; so are least and around
    least: list[np.ndarray] = []
    around: list[np.ndarray] = []
    for g in np.unique(labels):
        sel = np.flatnonzero(labels == g)
        comp = connected_components(xy[sel], radius)
        owner[sel] = comp + sum(len(a) for a in most)
        # Most and fewest same-label first-ring neighbours of a hole, and holes of others around it.
        most.append(np.zeros(comp.max() + 1, int))
        least.append(np.full(comp.max() + 1, n))
        np.maximum.at(most[-1], comp, same_count[sel])
        np.minimum.at(least[-1], comp, same_count[sel])
        around.append(np.bincount(comp, weights=other_count[sel], minlength=comp.max() + 1))
    size, most_same, least_same = np.bincount(owner), np.concatenate(most), np.concatenate(least)
    surrounded = np.concatenate(around) >= MIN_SURROUNDING
    sparse = surrounded & (most_same <= 1)
    chains = surrounded & (most_same == 2) & (least_same <= 1) & (size == 3)
    if noise_explains_chains(int(np.sum(sparse & (size == 1))), int(np.sum(sparse & (size == 2))), int(chains.sum())):
        sparse |= chains
    return sparse[owner]


def noise_explains_chains(singles: int, pairs: int, chains: int) -> bool:
    """Whether label noise accounts for at least half of a bench's chains of three holes.

    Mislabelled holes fall independently, each with a small chance ``r`` per
    hole and geozone. On ``N`` holes of a staggered pattern (six neighbours a
    hole: three pairs per hole, and nine chains centred on it, the fifteen
    pairs of its neighbours less the six that close a triangle) they make
    about ``N r`` single holes, ``3 N r^2`` pairs and ``9 N r^3`` chains:
    ``pairs^2 / singles`` chains, without knowing ``r`` or ``N``. On
    development seeds 0-3 that predicted 45.5 chains where 45 were seen (43
    mislabelled) at 6-10% label noise, 28.4 for 27 (21) on pods with that
    noise, and 0.06 a bench where pods with 1-3% showed one lens's chain.
    """
    return chains > 0 and singles > 0 and pairs**2 / singles >= 0.5 * chains


def absorbed_labels(xy: np.ndarray, labels: np.ndarray, isolated: np.ndarray, neighbours: int = 6) -> np.ndarray:
    """Labels with every isolated hole given the most common label of its nearest non-isolated holes.

    Parameters
    ----------
    xy : (n, 2) float
    labels : (n,) array
    isolated : (n,) bool
        From :func:`isolated_holes`.
    neighbours : int
        How many nearest holes vote (the first ring of a staggered pattern).
    """
    out = np.asarray(labels).copy()
    keep = np.flatnonzero(~isolated)
    todo = np.flatnonzero(isolated)
    if len(todo) == 0 or len(keep) == 0:
        return out
    k = min(neighbours, len(keep))
    _, idx = cKDTree(xy[keep]).query(xy[todo], k=k)
    votes = labels[keep][np.asarray(idx).reshape(len(todo), k)]
    for row, i in enumerate(todo):
        values, counts = np.unique(votes[row], return_counts=True)
        out[i] = values[np.argmax(counts)]
    return out
