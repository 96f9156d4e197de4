"""Ports: angular sectors of a shared target, one per source (paper section 3.2.2, Algorithms 5-6).

When several sources are associated with one target (many-to-one), each may
only align with its own sector of the target: the target is cut into angular
*ports* around its centroid, each as wide as its source's share of the total
source area, in the sources' angular order. A source's value function marks
the target cells in the other sources' ports with a large negative value, so
the sources spread over the target instead of piling onto its deepest part.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import MultiPolygon

#: Value given to target cells in ports reserved for other sources, as a
#: multiple of the deepest target SDF value (Algorithm 5-6 "large negative").
PORT_PENALTY_FACTOR = 4.0


@dataclass
class Port:
    """An angular sector of a target reserved for one source (Algorithms 5-6).

    Attributes
    ----------
    target : int
        Target index.
    source : int
        Source index the sector is reserved for.
    start_rad : float
        Start angle (radians, counter-clockwise from +x) around ``centre_xy``.
    width_rad : float
        Angular width of the sector, proportional to the source area.
    centre_xy : tuple of float
        Target centroid (metres) the sectors radiate from.
    """

    target: int
    source: int
    start_rad: float
    width_rad: float
    centre_xy: tuple[float, float]

    def contains_angle(self, angle_rad: np.ndarray) -> np.ndarray:
        """Whether angles (radians) fall inside this sector."""
        return np.mod(np.asarray(angle_rad) - self.start_rad, 2 * np.pi) < self.width_rad

    def to_dict(self) -> dict:
        return {
            "target": self.target,
            "source": self.source,
            "start_rad": self.start_rad,
            "width_rad": self.width_rad,
            "centre_xy": list(self.centre_xy),
        }


def allocate_ports(
    target: int,
    centre_xy: tuple[float, float],
    source_ids: list[int],
    source_centroids_xy: np.ndarray,
    source_areas_m2: np.ndarray,
) -> list[Port]:
    """Divide a target into angular ports, one per source (Algorithms 5-6).

    Parameters
    ----------
    target : int
        Target index (recorded in the ports).
    centre_xy : (float, float)
        Target centroid, metres; sectors radiate from it.
    source_ids : list of int
        Sources sharing the target.
    source_centroids_xy : (n, 2) array
        Their centroids, metres (same order as ``source_ids``).
    source_areas_m2 : (n,) array
        Their areas; each port's angular width is proportional to its area.

    Returns
    -------
    list of Port
        One per source, in ``source_ids`` order; together they cover the circle.

    Notes
    -----
    Each source's direction is ``theta_s = atan2(c_s - c_t)``. Contiguous
    sectors taken in the sources' angular order never cross, so the
    assignment keeps that cyclic order; the free rotation ``alpha`` of the
    whole arrangement then minimises the sum of squared (circular) angular
    differences between each sector's bisector and its source's direction,
    i.e. ``alpha`` is the circular mean of ``theta_s - offset_s``.
    """
    n = len(source_ids)
    c = np.asarray(centre_xy, dtype=float)
    xy = np.asarray(source_centroids_xy, dtype=float).reshape(n, 2)
    areas = np.maximum(np.asarray(source_areas_m2, dtype=float), 0.0)
    if n == 0:
        return []
    if areas.sum() <= 0:
        areas = np.ones(n)
    widths = 2 * np.pi * areas / areas.sum()
    theta = np.arctan2(xy[:, 1] - c[1], xy[:, 0] - c[0])
    order = np.argsort(theta, kind="stable")
    starts_rel = np.concatenate([[0.0], np.cumsum(widths[order])[:-1]])
    mids_rel = starts_rel + widths[order] / 2
    alpha = float(np.angle(np.sum(np.exp(1j * (theta[order] - mids_rel)))))
    ports: dict[int, Port] = {}
    for k, idx in enumerate(order):
        ports[int(idx)] = Port(
            target=int(target),
            source=int(source_ids[idx]),
            start_rad=float(np.mod(alpha + starts_rel[k], 2 * np.pi)),
            width_rad=float(widths[idx]),
            centre_xy=(float(c[0]), float(c[1])),
        )
    return [ports[i] for i in range(n)]


def shared_target_ports(
    association: np.ndarray, sources: list[MultiPolygon], targets: list[MultiPolygon]
) -> dict[int, list[Port]]:
    """Ports of every target shared by two or more sources, from the sources' original positions.

    Returns ``{target: ports}`` (:func:`allocate_ports`); targets with one
    source, or empty ones, have no ports.
    """
    A = np.asarray(association, dtype=bool)
    areas = np.array([g.area for g in sources])
    centroids = np.array([[g.centroid.x, g.centroid.y] if not g.is_empty else [0.0, 0.0] for g in sources])
    out: dict[int, list[Port]] = {}
    for t in range(A.shape[1]):
        sharing = [int(s) for s in np.nonzero(A[:, t])[0]]
        if len(sharing) > 1 and not targets[t].is_empty:
            ct = targets[t].centroid
            out[t] = allocate_ports(t, (ct.x, ct.y), sharing, centroids[sharing], areas[sharing])
    return out


def penalise_foreign_ports(
    value: np.ndarray,
    source: int,
    target_ids: list[int],
    ports_by_target: dict[int, list[Port]],
    target_masks: dict[int, np.ndarray],
    cell_xy: tuple[np.ndarray, np.ndarray],
    cell_size_m: float,
) -> tuple[np.ndarray, list[Port]]:
    """A source's value function with the other sources' ports made unattractive.

    Target cells (``target_masks``) in the ports of other sources get
    ``-PORT_PENALTY_FACTOR`` times the deepest value of ``value`` (at least one
    cell, ``cell_size_m``). ``cell_xy`` are the grid's cell centres
    ``(X, Y)``. Returns the new value function and all ports of the source's
    shared targets (its own and the others').
    """
    deepest = max(float(value.max()), cell_size_m)
    out = value.copy()
    X, Y = cell_xy
    used: list[Port] = []
    for t in target_ids:
        if t not in ports_by_target:
            continue
        ports = ports_by_target[t]
        used.extend(ports)
        angle = np.arctan2(Y - ports[0].centre_xy[1], X - ports[0].centre_xy[0])
        for port in ports:
            if port.source != source:
                out[target_masks[t] & port.contains_angle(angle)] = -PORT_PENALTY_FACTOR * deepest
    return out, used
