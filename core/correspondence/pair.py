"""Spatial correspondence between two successive benches (paper section 3).

Given the component boundaries of one geozone on an upper bench ("sources")
and on the bench below ("targets"), this stage

1. decides which sources may interact with which targets (region association,
   paper section 3.1, eqs. (1)-(9)), and
2. estimates a rigid translation per source that best aligns it with its
   targets, subject to spatial constraints (component alignment, section 3.2,
   Algorithms 4-7), decomposing complex relations into subtrees (3.2.4).

The result groups sources and targets into *morph instances*: connected sets
of the post-alignment association graph, which the contour metamorphosis stage
(paper section 4) then works on in the motion-compensated frame.

This module orchestrates the steps; each lives in a module of its own:

* :mod:`core.correspondence.association` -- region association (3.1);
* :mod:`core.correspondence.alignment` -- FFT cross-correlation (3.2.1, Alg. 4);
* :mod:`core.correspondence.ports` -- ports of shared targets (3.2.2, Alg. 5-6);
* :mod:`core.correspondence.rewards` -- rewards for splitting sources (3.2.3, Alg. 7);
* :mod:`core.correspondence.subtrees` -- subtrees, pruning, instances (3.2.4, Alg. 8-9).

Everything here works on shapely polygons in the local metric frame (metres)
and on one common :class:`core.geometry.grid.Grid` per bench pair. No global state.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from shapely import affinity
from shapely.geometry import MultiPolygon, Polygon

from core.correspondence.alignment import (
    TargetRasters,
    align_translation_m,
    fft_translation,
    frame_for,
    shift_mask,
)
from core.correspondence.association import association_matrix
from core.correspondence.ports import Port, allocate_ports, penalise_foreign_ports, shared_target_ports
from core.correspondence.rewards import bridge_value_function
from core.correspondence.subtrees import MorphInstance, Subtree, morph_instances, prune_association, subtrees
from core.errors import BGMInputError
from core.geometry.grid import Grid, as_multipolygon, union_bounds

__all__ = [
    "MorphInstance",
    "PairCorrespondence",
    "Port",
    "SourceField",
    "Subtree",
    "align_translation_m",
    "allocate_ports",
    "association_matrix",
    "correspond_pair",
    "default_parameters",
    "fft_translation",
    "subtrees",
]

#: Default lower limit of the association radius, as a multiple of the hole
#: spacing (``mu_lower`` in eqs. (6)-(7)). Lateral drift of a boundary between
#: benches is typically of the order of one or two hole spacings.
MU_LOWER_PER_HOLE_SPACING = 1.5
#: Default cells per hole spacing for the alignment grid.
CELLS_PER_HOLE_SPACING = 4
#: The default cell size is enlarged so the grid stays at most this many cells across.
MAX_CELLS_ACROSS = 512
#: Explicit cell sizes that would make the grid larger than this are refused.
HARD_MAX_CELLS_ACROSS = 4096

Pairs = Collection[tuple[int, int]]


@dataclass
class SourceField:
    """What the alignment of one source saw (for viewers and debugging)."""

    source: int
    target_ids: list[int]
    value_function: np.ndarray | None
    ports: list[Port]
    locked: bool = False

    def to_dict(self, include_arrays: bool = False) -> dict:
        out = {
            "source": self.source,
            "target_ids": list(self.target_ids),
            "ports": [p.to_dict() for p in self.ports],
            "locked": self.locked,
        }
        if include_arrays and self.value_function is not None:
            out["value_function"] = self.value_function.tolist()
        return out


@dataclass
class PairCorrespondence:
    """Result of :func:`correspond_pair` for one source/target bench pair.

    Attributes
    ----------
    association : (ns, nt) bool array
        Final association: the tentative matrix (with overrides) minus edges
        whose source, once translated, no longer touches the target (section
        3.2.4: "eliminate edges where a connection does not exist"); forced
        pairs are always kept.
    translations : (ns, 2) float array
        Translation ``(dx, dy)`` in metres applied to each source.
    instances : list of MorphInstance
        Connected sets of ``association`` (plus lone sources / lone targets).
    initial_association : (ns, nt) bool array
        Association before alignment (eq. (8) plus safeguard plus overrides).
    cell_size_m : float
        Cell size of the alignment grid.
    mu_lower_m : float
        Lower limit of the association radius used.
    grid : Grid or None
        The alignment grid (``None`` when there was nothing to grid).
    fields : dict
        Per-source :class:`SourceField` when ``keep_fields`` was requested.
    """

    association: np.ndarray
    translations: np.ndarray
    instances: list[MorphInstance]
    initial_association: np.ndarray
    cell_size_m: float
    mu_lower_m: float
    grid: Grid | None = None
    fields: dict[int, SourceField] = field(default_factory=dict)

    @classmethod
    def unaligned(cls, ns: int, nt: int, cell_size_m: float, mu_lower_m: float) -> PairCorrespondence:
        """No association and no translation (every component is empty: nothing to align)."""
        nothing = np.zeros((ns, nt), dtype=bool)
        return cls(nothing, np.zeros((ns, 2)), morph_instances(nothing), nothing.copy(), cell_size_m, mu_lower_m)

    def to_dict(self, include_arrays: bool = False) -> dict:
        """JSON-friendly summary (value-function arrays only if ``include_arrays``)."""
        out = {
            "association": self.association.astype(bool).tolist(),
            "initial_association": self.initial_association.astype(bool).tolist(),
            "translations_m": np.asarray(self.translations, dtype=float).tolist(),
            "instances": [i.to_dict() for i in self.instances],
            "cell_size_m": float(self.cell_size_m),
            "mu_lower_m": float(self.mu_lower_m),
        }
        if self.grid is not None:
            out["grid"] = {
                "x0": self.grid.x0,
                "y0": self.grid.y0,
                "cell_size_m": self.grid.cell_size_m,
                "shape": list(self.grid.shape),
            }
        if self.fields:
            out["fields"] = {str(k): f.to_dict(include_arrays) for k, f in sorted(self.fields.items())}
        return out


def default_parameters(hole_spacing_m: float, extent_m: float, cell_size_m: float | None = None) -> tuple[float, float]:
    """Default ``(mu_lower_m, cell_size_m)`` for a hole spacing.

    ``mu_lower_m = 1.5 * hole_spacing_m`` (lateral drift of a boundary between
    benches is of the order of a hole spacing or two). The cell size is a
    quarter of the hole spacing, enlarged if needed so a grid spanning
    ``extent_m`` stays within :data:`MAX_CELLS_ACROSS` cells.
    """
    mu_lower = MU_LOWER_PER_HOLE_SPACING * hole_spacing_m
    if cell_size_m is None:
        cell_size_m = hole_spacing_m / CELLS_PER_HOLE_SPACING
        cell_size_m = max(cell_size_m, extent_m / (MAX_CELLS_ACROSS - 1))
    return mu_lower, cell_size_m


def correspond_pair(
    sources: list[Polygon | MultiPolygon],
    targets: list[Polygon | MultiPolygon],
    *,
    hole_spacing_m: float,
    mu_lower_m: float | None = None,
    cell_size_m: float | None = None,
    locked_translations: dict[int, tuple[float, float]] | None = None,
    forced: Pairs = frozenset(),
    forbidden: Pairs = frozenset(),
    keep_fields: bool = False,
) -> PairCorrespondence:
    """Associate and align the components of two successive benches (section 3).

    Parameters
    ----------
    sources, targets : list of Polygon or MultiPolygon
        Components of one geozone on the upper (source) and lower (target)
        bench, in the local frame, metres.
    hole_spacing_m : float
        Typical blasthole spacing; sets the defaults below.
    mu_lower_m : float, optional
        Minimum association scale ``mu_lower`` (eq. (6)). Default
        ``1.5 * hole_spacing_m``.
    cell_size_m : float, optional
        Alignment grid cell. Default ``hole_spacing_m / 4``, enlarged so the
        grid stays within 512 cells across.
    locked_translations : dict, optional
        ``{source: (dx_m, dy_m)}``: these sources use the given translation
        (manual override) and act as fixed obstacles for the others.
    forced, forbidden : set of (source, target)
        Pairs added to / removed from the association matrix. Forced pairs are
        kept in the final association even if the aligned source misses the
        target.
    keep_fields : bool
        Keep each source's value function and ports in ``fields``.

    Returns
    -------
    PairCorrespondence

    Notes
    -----
    Steps: tentative association (3.1) plus the overrides; the sources
    placed one at a time, each by FFT cross-correlation with a value function
    from its subtree (:func:`_place_sources`); edges whose moved source misses
    its target dropped (3.2.4); the connected sets of the rest.
    """
    hole_spacing_m = _check_positive("hole_spacing_m", hole_spacing_m)
    if mu_lower_m is not None:
        mu_lower_m = _check_positive("mu_lower_m", mu_lower_m)
    if cell_size_m is not None:
        cell_size_m = _check_positive("cell_size_m", cell_size_m)
    src = [as_multipolygon(s) for s in sources]
    tgt = [as_multipolygon(t) for t in targets]
    locked = {} if locked_translations is None else dict(locked_translations)
    _check_overrides(len(src), len(tgt), locked, forced, forbidden)
    cell, mu_lower, max_extent = _pair_scales(src, tgt, hole_spacing_m, mu_lower_m, cell_size_m)
    grid = _alignment_grid(src + tgt, cell, max_extent)
    if grid is None:
        return PairCorrespondence.unaligned(len(src), len(tgt), cell, mu_lower)
    rasters = TargetRasters(grid, tgt)
    A = association_matrix(src, tgt, mu_lower_m=mu_lower, grid=rasters.grid, target_masks=rasters.masks)
    for s, t in forced:
        A[s, t] = True
    for s, t in forbidden:
        A[s, t] = False
    translations, fields = _place_sources(src, tgt, A, rasters, locked, keep_fields)
    A_final = prune_association(A, src, tgt, translations, cell, forced)
    return PairCorrespondence(
        association=A_final,
        translations=translations,
        instances=morph_instances(A_final),
        initial_association=A,
        cell_size_m=cell,
        mu_lower_m=mu_lower,
        grid=rasters.grid,
        fields=fields,
    )


def _extent_m(geom: MultiPolygon) -> float:
    """Longer side of the bounding box of a non-empty geometry."""
    b = geom.bounds
    return max(b[2] - b[0], b[3] - b[1])


def _pair_scales(
    src: list[MultiPolygon],
    tgt: list[MultiPolygon],
    hole_spacing_m: float,
    mu_lower_m: float | None,
    cell_size_m: float | None,
) -> tuple[float, float, float]:
    """``(cell_size_m, mu_lower_m, largest source extent)`` of a bench pair.

    The given scales, or the defaults of :func:`default_parameters` for the
    frame the sources may move in (all components, plus the largest source
    extent and two hole spacings).
    """
    max_extent = max((_extent_m(g) for g in src if not g.is_empty), default=0.0)
    bounds = union_bounds(src + tgt)
    span = 0.0 if bounds is None else max(bounds[2] - bounds[0], bounds[3] - bounds[1])
    frame_m = span + max_extent + 8 * hole_spacing_m / CELLS_PER_HOLE_SPACING
    mu_default, cell = default_parameters(hole_spacing_m, frame_m, cell_size_m)
    return cell, (mu_default if mu_lower_m is None else mu_lower_m), max_extent


def _alignment_grid(geoms: list[MultiPolygon], cell_size_m: float, max_extent_m: float) -> Grid | None:
    """The common alignment grid of a bench pair; ``None`` when every component is empty.

    All components plus half the largest source extent (a source aligned over
    a target rarely sticks out further than that) and 4 cells. Grids over
    :data:`HARD_MAX_CELLS_ACROSS` cells across are refused.
    """
    bounds = union_bounds(geoms)
    if bounds is None:
        return None
    grid = frame_for(geoms, cell_size_m, 0.5 * max_extent_m + 4 * cell_size_m)
    if max(grid.shape) > HARD_MAX_CELLS_ACROSS:
        span = max(bounds[2] - bounds[0], bounds[3] - bounds[1])
        raise BGMInputError(
            f"cell size {cell_size_m} m makes a {grid.shape[0]} x {grid.shape[1]} alignment grid; "
            f"use a cell size of at least {span / MAX_CELLS_ACROSS:.3g} m."
        )
    return grid


@dataclass
class _Placement:
    """Sources placed so far: their translations, and the cells they cover (obstacles for the rest)."""

    grid: Grid
    translations_m: np.ndarray
    occupied: np.ndarray

    def place(self, s: int, source: MultiPolygon, d_xy: tuple[float, float], mask: np.ndarray | None = None) -> None:
        """Record source ``s`` moved by ``d_xy`` (metres); ``mask`` its cells there, if known."""
        self.translations_m[s] = d_xy
        if source.is_empty:
            return
        if mask is None:
            mask = self.grid.rasterize(affinity.translate(source, float(d_xy[0]), float(d_xy[1])))
        # Dilated by one cell, which also covers the sub-cell rounding of ``mask``.
        self.occupied |= ndimage.binary_dilation(mask)


def _place_sources(
    src: list[MultiPolygon],
    tgt: list[MultiPolygon],
    association: np.ndarray,
    rasters: TargetRasters,
    locked: dict[int, tuple[float, float]],
    keep_fields: bool,
) -> tuple[np.ndarray, dict[int, SourceField]]:
    """Translation of every source (section 3.2), and what each alignment saw if ``keep_fields``.

    Locked sources, empty ones and sources without any target are placed first
    and stay fixed (the latter two at ``(0, 0)``); the rest follow by
    decreasing area. Each is moved to the arg-max of the FFT
    cross-correlation of its mask with its value function
    (:func:`_value_function`, :func:`~core.correspondence.alignment.fft_translation`,
    Algorithm 4), refined to sub-cell precision by a parabola fit; already
    placed sources (dilated by one cell) are hard obstacles, so aligned
    sources do not overlap each other.
    """
    grid = rasters.grid
    ns = len(src)
    trees = subtrees(association)
    ports_by_target = shared_target_ports(association, src, tgt)
    placement = _Placement(grid, np.zeros((ns, 2)), np.zeros(grid.shape, dtype=bool))
    fields: dict[int, SourceField] = {}
    fixed = [s for s in range(ns) if s in locked or not trees[s].targets or src[s].is_empty]
    for s in fixed:
        placement.place(s, src[s], locked.get(s, (0.0, 0.0)))
        if keep_fields:
            fields[s] = SourceField(s, trees[s].targets, None, [], locked=s in locked)
    areas = [g.area for g in src]
    movable = sorted((s for s in range(ns) if s not in fixed), key=lambda s: (-areas[s], s))
    cell_xy = grid.cell_centres()
    h = grid.cell_size_m
    for s in movable:
        v, used_ports = _value_function(src[s], trees[s], tgt, rasters, ports_by_target, cell_xy)
        u = grid.rasterize(src[s])
        d_row, d_col = fft_translation(u, v, obstacle_mask=placement.occupied, subpixel=True)
        placement.place(s, src[s], (d_col * h, d_row * h), shift_mask(u, round(d_row), round(d_col)))
        if keep_fields:
            fields[s] = SourceField(s, trees[s].targets, v, used_ports)
    return placement.translations_m, fields


def _value_function(
    source: MultiPolygon,
    tree: Subtree,
    tgt: list[MultiPolygon],
    rasters: TargetRasters,
    ports_by_target: dict[int, list[Port]],
    cell_xy: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, list[Port]]:
    """The value function ``v`` a source is aligned with, from its subtree ``s -> T_s -> co-sources``.

    * the SDF of the union of its targets (Algorithm 3, section 3.2.1);
    * one-to-many (3.2.3, Algorithm 7): targets the source could bridge (gap
      below its extent) are grouped and the gap of their convex hull is
      rewarded (:func:`~core.correspondence.rewards.bridge_value_function`), so
      straddling pays;
    * many-to-one (3.2.2): target cells in ports of other sources get
      ``-PORT_PENALTY_FACTOR * max(v)``
      (:func:`~core.correspondence.ports.penalise_foreign_ports`).

    Returns ``v`` and the ports of the source's shared targets.
    """
    v = np.max(np.stack([rasters.sdf(t) for t in tree.targets]), axis=0)
    if len(tree.targets) > 1:
        v = bridge_value_function(tree.targets, tgt, rasters, _extent_m(source), v)
    return penalise_foreign_ports(
        v, tree.source, tree.targets, ports_by_target, rasters.masks, cell_xy, rasters.grid.cell_size_m
    )


def _check_positive(name: str, value) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise BGMInputError(f"{name} must be a number, got {value!r}.") from None
    if not (value > 0 and np.isfinite(value)):
        raise BGMInputError(f"{name} must be a positive finite number, got {value}.")
    return value


def _check_overrides(ns: int, nt: int, locked: dict, forced: Pairs, forbidden: Pairs) -> None:
    for s, d in locked.items():
        if not (isinstance(s, (int, np.integer)) and 0 <= s < ns):
            raise BGMInputError(f"locked translation refers to source {s}, but there are {ns} sources.")
        if len(tuple(d)) != 2 or not all(np.isfinite(float(x)) for x in d):
            raise BGMInputError(f"locked translation of source {s} must be two finite numbers, got {d!r}.")
    for name, pairs in (("forced", forced), ("forbidden", forbidden)):
        for s, t in pairs:
            if not (0 <= s < ns and 0 <= t < nt):
                raise BGMInputError(f"{name} association ({s}, {t}) is out of range for {ns} sources and {nt} targets.")
    both = set(forced) & set(forbidden)
    if both:
        raise BGMInputError(f"association {sorted(both)[0]} is both forced and forbidden.")
