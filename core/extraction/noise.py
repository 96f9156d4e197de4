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

Past that, a component of three to six holes is a small body or mislabelled holes
that happen to lie together, and which one depends on how noisy the bench is:
:func:`noise_groups` compares the bench's components of each size with what
its own single odd holes and pairs predict, and where noise accounts for at
least half of them they are taken as noise too.

Mislabels also gather where samples mix two geozones: at a contact, a hole
of one side labelled as the other. Such a hole is no component of its own
but a bump on its neighbour's body, and a contour that keeps every hole on
its side carries the bump. :func:`contact_votes` takes a hole at a contact
whose neighbours, weighted by distance, say otherwise as noise too, on a
bench where there are more of them than clean contacts make
(:data:`CONTACT_NOISE_SHARE`).
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
#: Connected groups of k holes on a staggered pattern, per hole (fixed site animals of the
#: triangular lattice), for the component sizes :func:`noise_groups` weighs.
GROUPS_PER_HOLE = {3: 11, 4: 44, 5: 186, 6: 814}
#: Width of the Gaussian weights of the neighbours' vote at a contact (hole spacings); it reaches
#: 2.5 times that.
VOTE_SIGMA_SPACINGS = 1.0
#: A bench's contact holes outvoted by their neighbours are noise when they are more than this share
#: of its contact holes, and at least :data:`MIN_CONTACT_NOISE` of them. Clean contacts (tips, necks
#: and thin layers) give 0.3-3.2% at the 90th percentile of a family's benches, contacts with 10-25%
#: of their holes mislabelled 3.7-10% at the 10th (development seeds 0-2; 2 of 126 clean benches,
#: splits and pods, pass).
CONTACT_NOISE_SHARE = 0.035
MIN_CONTACT_NOISE = 6
#: A contact hole that keeps its label with less than this share of its neighbours' weighted vote is a
#: near tie: a hole on a contact that wavers between holes.
NEAR_TIE_SHARE = 0.6
#: Mislabels at a contact are outvoted outright; a real contact that wavers by a fraction of a spacing
#: leaves near ties beside each hole it outvotes. The outvoted holes are noise only where they are at
#: least this share of the outvoted holes and near ties together: with 10-25% of the contact holes
#: mislabelled 0.25-0.50 (10th-90th percentile of the benches, development seeds 0-2), contacts
#: wavering half a spacing every five 0.05-0.27, clean contacts 0.00-0.20, Kennecott's benches 0.24-0.40.
OUTVOTED_AGAINST_TIES = 0.3


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
    owner = geozone_components(xy, labels, radius)
    size = np.bincount(owner)
    # Per component: most same-label first-ring neighbours of a hole, and holes of others around it.
    most_same = np.zeros(len(size), int)
    np.maximum.at(most_same, owner, same_count)
    surrounded = np.bincount(owner, weights=other_count) >= MIN_SURROUNDING
    noisy = surrounded & (most_same <= 1)
    singles, pairs = int(np.sum(noisy & (size == 1))), int(np.sum(noisy & (size == 2)))
    for k in GROUPS_PER_HOLE:
        groups = surrounded & (size == k) & ~noisy
        if groups.any() and noise_groups(singles, pairs, n, k) >= 0.5 * groups.sum():
            noisy |= groups  # noise accounts for at least half of them
    return noisy[owner]


def noise_groups(singles: int, pairs: int, holes: int, k: int) -> float:
    """How many groups of ``k`` mislabelled holes a bench of ``holes`` holes has by chance.

    Mislabelled holes fall independently, each with a small chance ``r`` per
    hole and geozone. On ``N`` holes of a staggered pattern they make about
    ``N r`` single holes, ``3 N r^2`` pairs (three per hole) and ``a_k N r^k``
    groups of ``k`` holes (``a_k``: :data:`GROUPS_PER_HOLE`): ``a_k singles
    r^(k - 1)`` with ``r = pairs / (3 singles)``, at most ``singles / N`` (a few
    odd holes and one pair are a real pair, not a noise rate of a third). On
    development seeds 0-3 at 6-10% label noise the chains of three (9 of the
    11 groups of three a hole) came to 45.5 where 45 were seen (43 of them
    mislabelled), and to 0.06 a bench on pods with 1-3% noise, where one lens
    made a chain in four mines. On a square pattern the diagonals lie within
    the components' radius (1.6 spacings): four pairs a hole, and 20, 110,
    638 and 3832 groups of 3-6 holes; ``r`` read with three pairs is then 4/3
    too high, and the two errors nearly cancel (the predicted groups 2-10% too
    few). Constants of the square pattern left its extraction at 6-10% label
    noise unchanged (median IoU 0.867 against 0.866, development seeds 0-3).
    """
    if singles == 0:
        return 0.0
    r = min(pairs / (3 * singles), singles / holes)
    return GROUPS_PER_HOLE[k] * singles * r ** (k - 1)


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


def contact_votes(
    xy: np.ndarray, labels: np.ndarray, hole_spacing_m: float, search_radius_m: float, isolated: np.ndarray
) -> np.ndarray:
    """Labels with the mislabels at a noisy bench's contacts replaced by their neighbours' vote.

    A hole at a contact (a hole of another geozone in its first ring) is
    outvoted when the Gaussian-weighted labels of the holes around it
    (:data:`VOTE_SIGMA_SPACINGS`, itself included) favour another geozone. On
    clean contacts that is a tip or a neck; where samples at the contacts are
    mislabelled it is most of the mislabels (three in four of the holes
    outvoted, development seeds 0-2 with 10-25% of the contact holes
    mislabelled), so the outvoted holes take the vote only where they are
    more than :data:`CONTACT_NOISE_SHARE` of the contact holes, and only
    where they stand out against the near ties (:data:`OUTVOTED_AGAINST_TIES`):
    a real contact that wavers by less than a spacing outvotes some of its
    holes too, and leaves many more nearly tied. Holes of a
    body no larger than the vote's reach (every hole of it is at its edge)
    and holes already ``isolated`` keep their label: lenses are judged by
    :func:`isolated_holes`.

    Parameters
    ----------
    xy : (n, 2) float
        Holes of one bench, metres.
    labels : (n,) array
        Geozone of every hole.
    hole_spacing_m : float
        Median hole spacing of the bench.
    search_radius_m : float
        Region-growing radius of the components (section 2.1).
    isolated : (n,) bool
        From :func:`isolated_holes`.

    Returns
    -------
    (n,) array
        ``labels``, the outvoted holes given the vote's geozone where the bench is noisy.
    """
    n = len(xy)
    if n < 3:
        return labels
    tree = cKDTree(xy)
    pairs = tree.query_pairs(FIRST_RING_SPACINGS * hole_spacing_m, output_type="ndarray")
    at_contact = np.zeros(n, bool)
    at_contact[pairs[labels[pairs[:, 0]] != labels[pairs[:, 1]]].ravel()] = True
    if np.sum(at_contact & ~isolated) < MIN_CONTACT_NOISE:
        return labels
    sigma = VOTE_SIGMA_SPACINGS * hole_spacing_m
    reach_holes = np.pi * (2.5 * sigma) ** 2 / (np.sqrt(3) / 2 * hole_spacing_m**2)  # staggered pattern
    owner = geozone_components(xy, labels, search_radius_m)
    voters = np.flatnonzero(at_contact & ~isolated & (np.bincount(owner)[owner] > reach_holes))
    if len(voters) < MIN_CONTACT_NOISE:
        return labels
    codes, label_codes = np.unique(labels, return_inverse=True)
    near = tree.query_ball_point(xy[voters], 2.5 * sigma)
    rows = np.repeat(np.arange(len(voters)), [len(j) for j in near])
    cols = np.concatenate([np.asarray(j, int) for j in near])
    weight = np.exp(-0.5 * (np.linalg.norm(xy[cols] - xy[voters[rows]], axis=1) / sigma) ** 2)
    votes = np.zeros((len(voters), len(codes)))
    np.add.at(votes, (rows, label_codes[cols]), weight)
    winner = np.argmax(votes, axis=1)
    outvoted = winner != label_codes[voters]
    if outvoted.sum() < MIN_CONTACT_NOISE or outvoted.sum() <= CONTACT_NOISE_SHARE * at_contact.sum():
        return labels
    near_ties = ~outvoted & (votes[np.arange(len(voters)), label_codes[voters]] < NEAR_TIE_SHARE * votes.sum(axis=1))
    if outvoted.sum() < OUTVOTED_AGAINST_TIES * (outvoted.sum() + near_ties.sum()):
        return labels  # a contact wavering between holes, not mislabels
    out = np.asarray(labels).copy()
    out[voters[outvoted]] = codes[winner[outvoted]]
    return out


def geozone_components(xy: np.ndarray, labels: np.ndarray, search_radius_m: float) -> np.ndarray:
    """Each hole's connected component (section 2.1) of its own geozone, numbered across geozones."""
    owner = np.zeros(len(xy), int)
    first = 0
    for g in np.unique(labels):
        sel = np.flatnonzero(labels == g)
        comp = connected_components(xy[sel], search_radius_m)
        owner[sel] = comp + first
        first += comp.max() + 1
    return owner
