"""Manual alignment overrides that follow their components when extraction renumbers them.

A project override names its source component by number (and the targets it
forces or forbids by number), as ``bgm correspond`` reports them. A parameter
that changes extraction renumbers components: the number then names another
component, or none. The viewer's overrides (:class:`PlacedOverride`) also keep
the outlines their components had when they were made, and
:func:`relocate_overrides` finds each again in the new contours: the override
moves to the one component at the same place, or is dropped, with a note
naming it, when no single component is. It is never applied to another
component. No Qt, no rendering.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from shapely.geometry.base import BaseGeometry

from core.io.project import AlignmentOverride

#: ``(geozone, source_z) -> (sources, targets)``: the outlines (local metres) of a bench pair's
#: modelled components in index order, or ``None`` when they are not at hand.
PairOutlines = Callable[[str, float], "tuple[Sequence[BaseGeometry], Sequence[BaseGeometry]] | None"]


@dataclass
class PlacedOverride(AlignmentOverride):
    """An alignment override and where its components were (viewer session only, not in project files).

    Attributes
    ----------
    source_outline : shapely geometry or None
        The source component's outline (local metres) when the override was last placed;
        ``None`` until it is (an override read from a project file).
    target_outlines : dict of int to shapely geometry
        The outlines of the targets ``associate`` names.
    renumbered_from : int or None
        The source's number before :func:`relocate_overrides` last moved the override to its
        renumbered component (``None``: it was not moved), so a selection of it can follow.
    """

    source_outline: BaseGeometry | None = field(default=None, compare=False, repr=False)
    target_outlines: dict[int, BaseGeometry] = field(default_factory=dict, compare=False, repr=False)
    renumbered_from: int | None = field(default=None, compare=False, repr=False)

    @classmethod
    def of(cls, o: AlignmentOverride) -> PlacedOverride:
        """``o`` as a placed override (itself if it is one)."""
        if isinstance(o, PlacedOverride):
            return o
        return cls(o.geozone, o.source_z, o.source, o.translation, dict(o.associate))

    def place(self, sources: Sequence[BaseGeometry], targets: Sequence[BaseGeometry]) -> None:
        """Remember the outlines of the components the override names now (indices out of range are skipped)."""
        if 0 <= self.source < len(sources):
            self.source_outline = sources[self.source]
        self.target_outlines = {t: targets[t] for t in self.associate if 0 <= t < len(targets)}


def override_name(o: AlignmentOverride, unit: str) -> str:
    """How messages name an override: its geozone, source component and bench (its elevation in ``unit``, the input's)."""
    return f"the alignment override of geozone {o.geozone} source {o.source} on bench {o.source_z:g} {unit}"


def same_place(outline: BaseGeometry, components: Sequence[BaseGeometry]) -> int | None:
    """The one component at the place of ``outline``, or ``None`` when no single one is.

    A component is at its place when it covers a point inside ``outline``
    (its representative point). When another component of the list lies
    inside ``outline`` too (the old component split), or none covers the
    point (it went), no component is.

    Parameters
    ----------
    outline : shapely geometry
        A component's outline before the change (local metres).
    components : sequence of shapely geometry
        The outlines after it, in index order.

    Returns
    -------
    int or None
    """
    if outline is None or outline.is_empty:
        return None
    point = outline.representative_point()
    hits = [i for i, c in enumerate(components) if not c.is_empty and c.covers(point)]
    if len(hits) != 1:
        return None
    inside = [i for i, c in enumerate(components) if not c.is_empty and outline.covers(c.representative_point())]
    return hits[0] if set(inside) <= set(hits) else None


def missing_components(o: AlignmentOverride, n_sources: int, n_targets: int) -> list[str]:
    """What ``o`` names that its bench pair, of ``n_sources`` and ``n_targets`` components, lacks (empty: nothing).

    >>> missing_components(AlignmentOverride("ore", 685.0, 5, associate={0: True, 4: False}), 3, 2)
    ['source component 5 (the upper bench has 3)', 'target component 4 (the lower bench has 2)']
    """
    lacks = [f"source component {o.source} (the upper bench has {n_sources})"] if o.source >= n_sources else []
    lacks += [f"target component {t} (the lower bench has {n_targets})" for t in sorted(o.associate) if t >= n_targets]
    return lacks


def place_unplaced(overrides: Sequence[AlignmentOverride], outlines: PairOutlines) -> list[AlignmentOverride]:
    """The overrides not yet placed (read from a project file) placed on the components their numbers name in
    ``outlines``; the others, and those whose bench pair is not at hand, as they are.

    A project's overrides name components by number, under the project's parameters. Placed by
    :func:`relocate_overrides` on the first run that reaches them, they named the components of that
    run's parameters: a slider moved before it renumbered them, and an override landed on another body.
    Placed first on the components of the parameters they were numbered under (``outlines``), they then
    follow their bodies to the run's components by their outlines, as after any slider.

    Parameters
    ----------
    overrides : sequence of AlignmentOverride
        Placed (:class:`PlacedOverride` with an outline) or not.
    outlines : callable
        ``outlines(geozone, source_z)`` under the parameters the overrides' numbers were given under
        (see :data:`PairOutlines`).

    Returns
    -------
    list
        New objects for those placed here; ``overrides`` is not modified.
    """
    out: list[AlignmentOverride] = []
    for original in overrides:
        pair = None
        if not (isinstance(original, PlacedOverride) and original.source_outline is not None):
            pair = outlines(original.geozone, original.source_z)
        if pair is None:
            out.append(original)
            continue
        o = copy.deepcopy(PlacedOverride.of(original))
        o.place(*pair)
        out.append(o)
    return out


def not_whole(notes: Sequence[str]) -> list[str]:
    """The notes of :func:`relocate_overrides` on overrides that did not follow their components whole.

    Those dropped, and those kept without a target they named; the notes of moved ones are left out. The
    wording it reads is :func:`relocate_overrides`' own, in this module.
    """
    return [n for n in notes if " dropped: " in n or " no longer names target " in n]


def relocate_overrides(
    overrides: Sequence[AlignmentOverride], outlines: PairOutlines, *, unit: str
) -> tuple[list, list[str]]:
    """The overrides moved to their components in new contours, and a note on each one moved or dropped.

    Parameters
    ----------
    overrides : sequence of AlignmentOverride
        Overrides not yet placed (plain :class:`~core.io.project.AlignmentOverride`) are placed
        where their numbers say, as before.
    outlines : callable
        ``outlines(geozone, source_z)``: the bench pair's source and target outlines now (local
        metres, index order), or ``None`` when they are not at hand (the override is kept as is).
    unit : str
        The input's length unit, the overrides' elevations' (the notes name benches by them).

    Returns
    -------
    overrides : list of PlacedOverride
        New objects; ``overrides`` is not modified.
    notes : list of str
        One sentence per override that now names another component (moved) or was dropped
        (no single component is where its source, or a target it names, was; or two overrides
        would name one component).
    """
    out: list[PlacedOverride] = []
    overrides_kept: list[AlignmentOverride] = []  # the original of each in ``out``
    notes: list[str] = []
    for original in overrides:
        o = copy.deepcopy(PlacedOverride.of(original))
        pair = outlines(o.geozone, o.source_z)
        if pair is None:
            out.append(o)
            overrides_kept.append(original)
            continue
        sources, targets = pair
        if o.source_outline is None:  # first seen: it names the components its numbers name now
            o.place(sources, targets)
            out.append(o)
            overrides_kept.append(original)
            continue
        name = override_name(o, unit)
        s = same_place(o.source_outline, sources)
        if s is None:
            notes.append(f"{name} was dropped: no single component is now where its source was")
            continue
        associate: dict[int, bool] = {}
        moved_targets = []
        for t, flag in sorted(o.associate.items()):
            old = o.target_outlines.get(t)
            u = t if old is None else same_place(old, targets)
            if u is None or u in associate:
                notes.append(f"{name} no longer names target {t}: no single component is where it was")
                continue
            associate[u] = flag
            if u != t:
                moved_targets.append(f"target {t} is {u}")
        if o.translation is None and not associate:
            notes.append(f"{name} was dropped: no target it named is still where it was")
            continue
        if s != o.source or moved_targets:
            moves = ([f"source {o.source} is {s}"] if s != o.source else []) + moved_targets
            notes.append(f"{name} follows its components, renumbered: {', '.join(moves)}")
        o.renumbered_from = o.source if s != o.source else None
        o.source, o.associate = s, associate
        o.place(sources, targets)
        out.append(o)
        overrides_kept.append(original)
    # two overrides moved onto one component (their components merged): neither can be told from the other
    groups: dict[tuple, list[tuple[int, PlacedOverride]]] = {}
    for o, was in zip(out, (x.source for x in overrides_kept)):
        groups.setdefault((o.geozone, round(o.source_z, 6), o.source), []).append((was, o))
    clashes = [[o for _, o in g] for g in groups.values() if len({was for was, _ in g}) > 1]
    for group in clashes:
        notes.append(
            f"{len(group)} alignment overrides of geozone {group[0].geozone} on bench {group[0].source_z:g} {unit} were "
            f"dropped: their sources are now one component, {group[0].source}"
        )
    dropped = {id(o) for group in clashes for o in group}
    return [o for o in out if id(o) not in dropped], notes
