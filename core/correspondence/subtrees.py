"""Decomposition of the association graph (paper section 3.2.4, Algorithms 8-9).

The association matrix of a bench pair is a bipartite graph between the
sources (upper bench components) and the targets (lower bench components).
Alignment works on one *subtree* per source (its targets, and the other
sources sharing each of them); after alignment, edges whose source no longer
touches its target are dropped, and the connected sets of what remains are
the *morph instances* the metamorphosis stage (section 4) works on.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from shapely import affinity
from shapely.geometry import MultiPolygon


@dataclass
class Subtree:
    """Subtree of the intersection graph rooted at one source (section 3.2.4).

    ``source -> targets -> co_sources[target]``: the root source, its associated
    targets, and for each of those the *other* sources associated with it.
    """

    source: int
    targets: list[int]
    co_sources: dict[int, list[int]]

    @property
    def kind(self) -> str:
        """``"none"``, ``"one-to-one"``, ``"many-to-one"``, ``"one-to-many"`` or ``"many-to-many"``."""
        if not self.targets:
            return "none"
        shared = any(self.co_sources.get(t) for t in self.targets)
        if len(self.targets) == 1:
            return "many-to-one" if shared else "one-to-one"
        return "many-to-many" if shared else "one-to-many"


@dataclass
class MorphInstance:
    """One connected set of the post-alignment association graph.

    The sources in ``source_ids`` (after translation) morph into the targets in
    ``target_ids`` (paper end of section 3). Either side may be empty: a source
    with no target pinches out, a target with no source is a new pod.
    """

    target_ids: list[int]
    source_ids: list[int]

    def to_dict(self) -> dict:
        return {"target_ids": list(self.target_ids), "source_ids": list(self.source_ids)}


def subtrees(association: np.ndarray) -> list[Subtree]:
    """Decompose the intersection graph into subtrees rooted at each source (3.2.4).

    Subtree ``s``: ``s -> {t : A[s, t]}``, each target expanded to the other
    sources associated with it. E.g. the paper's type C example gives
    ``s1 -> {t0 <- s0, t2 <- (s2, s3)}``.
    """
    A = np.asarray(association, dtype=bool)
    out = []
    for s in range(A.shape[0]):
        targets = [int(t) for t in np.nonzero(A[s])[0]]
        co = {t: [int(o) for o in np.nonzero(A[:, t])[0] if o != s] for t in targets}
        out.append(Subtree(source=s, targets=targets, co_sources=co))
    return out


def prune_association(
    association: np.ndarray,
    sources: list[MultiPolygon],
    targets: list[MultiPolygon],
    translations_m: np.ndarray,
    cell_size_m: float,
    forced: Collection[tuple[int, int]],
) -> np.ndarray:
    """Association after alignment: edges whose moved source misses its target dropped.

    Section 3.2.4, "eliminate edges where a connection does not exist": an
    edge ``(s, t)`` stays when source ``s`` translated by ``translations_m[s]``
    lies within one cell (``cell_size_m``, the alignment resolution) of target
    ``t``. Forced edges always stay.
    """
    A = np.asarray(association, dtype=bool)
    out = A.copy()
    for s, t in zip(*np.nonzero(A)):
        if (int(s), int(t)) in forced:
            continue
        moved = affinity.translate(sources[s], *translations_m[s])
        if moved.distance(targets[t]) > cell_size_m:
            out[s, t] = False
    return out


def morph_instances(association: np.ndarray) -> list[MorphInstance]:
    """Connected sets of the bipartite association graph (lone nodes included).

    Sources are graph nodes ``0..ns-1`` and targets ``ns..ns+nt-1``
    (:func:`scipy.sparse.csgraph.connected_components`). Instances are sorted
    by their first target, then (for lone sources) by their source.
    """
    A = np.asarray(association, dtype=bool)
    ns, nt = A.shape
    s, t = np.nonzero(A)
    graph = sparse.coo_matrix((np.ones(s.size), (s, ns + t)), shape=(ns + nt, ns + nt))
    _, label = connected_components(graph, directed=False)
    inst = [
        MorphInstance(
            target_ids=[int(t) for t in np.flatnonzero(label[ns:] == g)],
            source_ids=[int(s) for s in np.flatnonzero(label[:ns] == g)],
        )
        for g in np.unique(label)
    ]
    inst.sort(key=lambda m: (m.target_ids[0] if m.target_ids else nt + 1, m.source_ids[0] if m.source_ids else ns + 1))
    return inst
