"""The viewer's state, and the runs of core's pipeline it asks for, without Qt or rendering.

:class:`ViewerModel` holds the blastholes, the :class:`~core.model.parameters.ModelParameters`
(the command line's, with the same defaults), the selection (geozone, bench
pair, source component), the manual alignment overrides with an undo stack,
and the latest :class:`PipelineResult`. It tells observers of changes through
psygnal signals.

:func:`compute` asks a :class:`~core.model.session.ModelSession` (the
pipeline ``bgm build`` runs) for what the picture needs, the selected items
first, and yields the result after each step so a worker thread can show the
selected bench before the rest and can be cancelled between steps. The
session memoises every stage by content, so only what a change affects is
computed again; the viewer adds only what is drawn and nothing else needs:
the fields of the selected bench's contours (edge map, GVF, snake history)
and the fronts of the selected morph instance.

Overrides name components by number, and a parameter that changes extraction
renumbers them: each run moves its overrides to their components in its new
contours before any correspondence uses them, or drops those whose component
no single one is now, saying so (:mod:`bgm_viewer.alignment`); the model takes
them back (:class:`Relocation`). Undo of such a change brings back the parameters
the overrides were placed under as well (:class:`UndoStep`).

Steps a change re-runs from (:data:`STEPS`): core's stages, with ``snake`` for a
change of the edge map, GVF or snake alone, whose selected component can be
previewed before its bench is extracted again.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import os
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import trimesh
from psygnal import Signal

from core.errors import BGMInputError, BGMWarning
from core.extraction.contours import Contour
from core.io.blastholes import Blastholes, blastholes_from_table, read_blastholes
from core.io.cache import StageCache
from core.io.reporting import carried_json, carried_line, hole_name
from core.model.extrapolation import CarriedMovement
from core.model.parameters import (
    PARAMETER,
    PARAMETERS,
    ModelParameters,
    parameter_value,
    parameters_from_dict,
    parameters_to_dict,
)
from core.model.parameters import STAGES as CORE_STAGES
from core.model.pipeline import BenchPair, GeozoneModel, modelled_contours
from core.model.session import ModelSession, StageStore
from core.morph.levelset import MorphResult

# Cancelled: a newer request superseded a run; core's, so core's steps raise the same (long imported from here)
from core.threads import Cancelled, cancelling, on_threads

from .layer_names import DEFAULT_VISIBLE, LAYER_NAMES

STEPS = ("contours", "snake", *CORE_STAGES[1:])


def earliest_step(*steps: str | None) -> str | None:
    """The earliest of ``steps`` in :data:`STEPS` (a run from it re-runs the others too); ``None`` among none."""
    return min((s for s in steps if s), key=STEPS.index, default=None)


#: What :meth:`ViewerModel.set_view` sets: the view settings a project saves besides the selection and the camera.
VIEW_SETTINGS = (
    "vertical_exaggeration",
    "surface_scope",
    "surface_geozones",
    "min_body_volume_m3",
    "min_body_holes",
    "layer_visibility",
)


def default_layer_visibility() -> dict[str, bool]:
    """Every layer of the standard scene, shown or not when nothing else is asked for (:data:`DEFAULT_VISIBLE`)."""
    return {name: name in DEFAULT_VISIBLE for name in LAYER_NAMES}


#: Depths below the deepest bench at which the selected geozone is predicted, in bench heights.
PREDICTED_FRACTIONS = (0.5, 1.0)
#: Seconds from the first unsaved change to its autosave: a slider dragged for a while is written
#: once every few seconds, not at each step, and a crash loses at most this much work.
AUTOSAVE_DELAY_S = 3.0


def display_unit(spec, holes: Blastholes) -> tuple[float, str]:
    """Factor from engine units to what a geologist reads, and its unit: input units, degrees, or none."""
    if spec.kind == "length":
        return 1.0 / holes.frame.metres_per_unit, holes.frame.length_unit
    if spec.kind == "angle":
        return 180.0 / np.pi, "degrees"
    return 1.0, ""


def step_of(name: str) -> str:
    """The step a change of parameter ``name`` re-runs from."""
    spec = PARAMETER[name]
    return "snake" if spec.section == "snake" else spec.stage


@dataclass(frozen=True)
class Selection:
    """What the stage layers show: a geozone, the bench pair ``(bench, bench + 1)``, a source component.

    ``component`` is the source's index in the bench pair, as ``bgm correspond``
    reports it and project overrides name it: components too small to be
    modelled (see ``min_component_holes``) are not counted.
    """

    geozone: str
    bench: int = 0
    component: int = 0


@dataclass
class MorphRecord:
    """The morph of one morph instance with its fronts, and the translation used to draw it in place."""

    source_ids: list[int]
    target_ids: list[int]
    result: MorphResult
    shift_m: tuple[float, float]
    z_from_m: float
    z_to_m: float


@dataclass
class PipelineResult:
    """Everything the layers are drawn from; replaced (not mutated) by each step of a run."""

    contours: dict[int, list[Contour]] = field(default_factory=dict)  #: every geozone, by bench
    pair: BenchPair | None = None  #: the selected bench pair of the selected geozone, corresponded and morphed
    morph: MorphRecord | None = None  #: the selected source's morph instance, with fronts
    model: GeozoneModel | None = None  #: the selected geozone's whole model
    surface: trimesh.Trimesh | None = None  #: the selected geozone's surface, as ``bgm build`` exports it
    #: The surfaces shown, by geozone: ``bgm build``'s, less the bodies the body filter drops.
    surfaces: dict[str, trimesh.Trimesh] = field(default_factory=dict)
    #: The same geozones' surfaces as ``bgm build`` exports them, every body kept (what the viewer exports).
    built: dict[str, trimesh.Trimesh] = field(default_factory=dict)
    predicted: list = field(default_factory=list)  #: (geozone, z_m, polygon) below the deepest bench
    #: How the selected geozone's depth trend carries its benches' movement on there, as ``bgm build`` reports it.
    carried: CarriedMovement | None = None
    selection: Selection | None = None  #: what the pair, morph, model and surface were computed for
    min_component_holes: int = ModelParameters().min_component_holes
    timings: dict[str, float] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    complete: bool = False
    #: The run that was to update this result was stopped (:meth:`ViewerModel.stop`): what is missing or older
    #: than the sliders stays so until the next run.
    stopped: bool = False
    #: The run's overrides as they follow renumbered components, and what moved or was dropped.
    relocated: Relocation | None = None
    #: The parameters ``pair`` was computed with: an override made on it is placed under them.
    pair_params: ModelParameters | None = None
    #: The session ``model`` was computed with: the next bench's band is calibrated on it, as ``bgm build``'s is.
    session: ModelSession | None = None

    @property
    def correspondence(self):
        """The selected bench pair's :class:`~core.correspondence.pair.PairCorrespondence` (or ``None``)."""
        return None if self.pair is None else self.pair.correspondence

    def sources(self, sel: Selection) -> list[Contour]:
        """The selected bench's modelled contours of the selected geozone: the pair's sources, in order."""
        return modelled_contours(self.contours.get(sel.bench, []), sel.geozone, sel.bench, self.min_component_holes)

    def selected_contour(self, sel: Selection) -> Contour | None:
        cs = self.sources(sel)
        return cs[sel.component] if 0 <= sel.component < len(cs) else None


@dataclass(frozen=True)
class PipelineInputs:
    """An immutable snapshot of what a run needs (safe to hand to a worker thread)."""

    session: ModelSession
    selection: Selection
    #: Geozones whose surfaces are built after the selected one's (the selected one's always is).
    surface_geozones: tuple[str, ...] = ()
    #: Bodies of a surface below this volume, or holding fewer of the geozone's holes, are not shown.
    min_body_volume_m3: float = 0.0
    min_body_holes: int = 0
    #: How many times the user had changed the overrides when the run began (see :class:`Relocation`).
    override_edits: int = 0
    #: The parameters the overrides' numbers were given under (``None``: the run's own); a project's, opened
    #: and not yet placed by a run, when a slider moved since (see :func:`bgm_viewer.alignment.place_unplaced`).
    placed_params: ModelParameters | None = None


@dataclass
class Relocation:
    """The overrides of a run moved to their components in its contours (see :mod:`bgm_viewer.alignment`).

    ``edits`` is :attr:`PipelineInputs.override_edits` of the run: the viewer takes
    ``overrides`` only if the user has not changed them since. ``params`` are the
    run's parameters once every bench's overrides are placed under them (``None``
    before: the other benches' are still placed under an earlier run's).
    """

    edits: int
    overrides: list
    notes: list[str] = field(default_factory=list)
    params: ModelParameters | None = None
    #: ``(before, after)``: the run's selection, and the one it moved to because the selected source's
    #: override followed its component to another number (``None``: the selection did not move).
    followed: tuple[Selection, Selection] | None = None
    #: Overrides not yet placed (a project's) that name a component their bench pair lacks, dropped by the run
    #: so the model runs, and a sentence on each (see :func:`_without_missing_components`).
    missing: list = field(default_factory=list)
    missing_notes: list[str] = field(default_factory=list)


@dataclass
class UndoStep:
    """What Undo brings back: the overrides before a change, and the parameters before a run's change.

    A run moves or drops overrides because a parameter changed. The overrides
    alone would not do: under the new parameters the next run would drop them
    again, so Undo of a run's change brings back the parameters they were
    placed under too.
    """

    overrides: list
    #: The parameters the overrides were placed under before a run changed them; ``None``: the user's edit.
    params: ModelParameters | None = None
    #: The user's edits count when a run changed the overrides (see :meth:`ViewerModel._push_run_undo`).
    edits: int = -1
    #: Of a step Redo brings back: the parameters its overrides were placed under (``None``: those of the moment).
    placed_params: ModelParameters | None = None


@dataclass
class _Numbering:
    """The overrides as a run found them, before it moved them to renumbered components (see :meth:`ViewerModel.stop`)."""

    overrides: list
    placed_params: ModelParameters
    undo: list[UndoStep]
    redo: list[UndoStep]
    notes: list[str]
    selection: Selection
    #: The selection the run moved to, following the corrected component (``None``: it did not move it).
    moved_to: Selection | None = None
    #: Whether the user changed the overrides since the run moved them (on the run's numbers).
    edited: bool = False


Progress = tuple[str, float, PipelineResult]


class _Run:
    """One run of :func:`compute`: the result being built, timings, errors, cancellation."""

    def __init__(self, inputs: PipelineInputs, previous: PipelineResult | None, cancelled):
        self.inputs = inputs
        self.session, self.sel, self.cancelled = inputs.session, inputs.selection, cancelled
        #: Given to core's long steps (a bench's contours, a geozone's model, a surface: seconds on Kennecott),
        #: which call it between their own steps: a cancelled run stops there, not only between the run's steps.
        self.progress: Callable[[int, int], None] = cancelling(cancelled)
        prev = previous or PipelineResult()
        # What is on screen stays there until it is redone (a picture that empties and
        # fills again at every slider step is harder to follow, and slower to draw);
        # what belongs to another selection goes at once.
        same = prev.selection == self.sel
        self.res = PipelineResult(
            contours=dict(prev.contours),
            pair=prev.pair if same else None,
            pair_params=prev.pair_params if same else None,
            morph=prev.morph if same else None,
            model=prev.model if same else None,
            session=prev.session if same else None,
            surface=prev.surface if same else None,
            predicted=prev.predicted if same else [],
            # other geozones' surfaces stay on screen until redone; those no longer asked for go
            surfaces={g: m for g, m in prev.surfaces.items() if g in (*inputs.surface_geozones, self.sel.geozone)},
            built={g: m for g, m in prev.built.items() if g in (*inputs.surface_geozones, self.sel.geozone)},
            selection=self.sel,
            min_component_holes=self.session.params.min_component_holes,
            timings=dict(prev.timings),
        )

    def check(self) -> None:
        if self.cancelled():
            raise Cancelled()

    def snapshot(self) -> PipelineResult:
        r = self.res
        return replace(
            r,
            contours=dict(r.contours),
            timings=dict(r.timings),
            errors=dict(r.errors),
            surfaces=dict(r.surfaces),
            built=dict(r.built),
        )

    def step(self, name: str, fn: Callable[[], object], error_key: str | None = None):
        """``fn()`` timed as ``name``; an exception is reported under ``error_key`` (re-raised without one)."""
        self.check()
        return _timed(name, fn, error_key, self.res.timings, self.res.errors)


def stopped_result(last: PipelineResult, selection: Selection) -> PipelineResult:
    """What is shown after a run is stopped: the last finished run's ``last``, less what belongs to another selection.

    The pair, morph, model and surface of ``last`` were computed for ``last.selection``: under
    another selection they would be drawn as its own (as :class:`_Run` drops them when a run starts).
    """
    if last.selection == selection:
        return last
    return replace(
        last,
        pair=None,
        pair_params=None,
        morph=None,
        model=None,
        session=None,
        surface=None,
        predicted=[],
        selection=selection,
        complete=False,
    )


def corresponding_component(pairs: list[BenchPair], component: int, bench: int, new_bench: int) -> int | None:
    """The component of the bench pair at ``new_bench`` that component ``component`` of ``bench`` is linked to.

    Stepping one bench down, the source's first associated target (the targets of
    pair ``k`` are the sources of pair ``k + 1``, in order: :func:`modelled_contours`);
    one bench up, the first source associated with it as a target. ``None``: no
    correspondence of ``pairs`` (one geozone's) links the two benches, or the
    component is linked to nothing there (it ends between the benches).
    """
    if abs(new_bench - bench) != 1:
        return None
    upper = min(bench, new_bench)
    for pair in pairs:
        if pair.upper != upper or pair.correspondence is None:
            continue
        assoc = np.asarray(pair.correspondence.association, bool)
        if not assoc.size or component >= (assoc.shape[0] if new_bench > bench else assoc.shape[1]):
            return None
        linked = assoc[component] if new_bench > bench else assoc[:, component]
        hits = np.flatnonzero(linked)
        return int(hits[0]) if len(hits) else None
    return None


def _timed(name: str, fn: Callable[[], object], error_key: str | None, timings: dict, errors: dict):
    """``fn()``, its seconds in ``timings[name]``; an exception's message in ``errors[error_key]`` (re-raised without one)."""
    t0 = time.perf_counter()
    try:
        return fn()
    except Cancelled:
        raise  # a superseded run is no error of its step
    except Exception as exc:
        if error_key is None:
            raise
        errors[error_key] = str(exc)
        return None
    finally:
        timings[name] = time.perf_counter() - t0


def compute(
    inputs: PipelineInputs,
    previous: PipelineResult | None,
    from_step: str = "contours",
    cancelled: Callable[[], bool] = lambda: False,
    until: str = "surface",
) -> Iterator[Progress]:
    """Bring the result up to date after a change at ``from_step``; yield ``(message, fraction, result)``.

    Order: the selected component's snake (a ``snake`` change), the selected
    bench pair's contours, correspondence and morph, the other benches, then
    the selected geozone's whole model, predictions and surface. Steps after
    ``until`` are skipped. Each yielded result is a new object.
    """
    if from_step not in STEPS or until not in STEPS:
        raise ValueError(f"unknown step {from_step!r} or {until!r}; steps are {', '.join(STEPS)}")
    last = STEPS.index(until)
    run = _Run(inputs, previous, cancelled)
    if from_step == "snake" and previous is not None:
        yield from _snake_preview(run, previous)
    n = run.session.holes.n_benches
    pair_benches = [b for b in (run.sel.bench, run.sel.bench + 1) if b < n]
    yield from _bench_pair(run, pair_benches)
    _relocate(run, set(pair_benches))
    if last >= STEPS.index("correspondence"):
        yield from _pair_steps(run, pair_benches, last)
    yield from _selected_fields(run)
    t0 = time.perf_counter()
    others = [b for b in range(n) if b not in pair_benches]
    # Several benches are traced at once; each is shown as it comes. A cancelled run stops the benches begun at
    # their next part (a Kennecott bench: 2-4 s, 20-40 parts) and begins no other.
    for i, (b, contours) in enumerate(run.session.traced_contours(others, run.progress), start=1):
        run.res.contours[b] = contours
        yield f"contours of bench {b}", 0.5 + 0.3 * i / len(others), run.snapshot()
        run.check()
    run.res.timings["extraction (all)"] = time.perf_counter() - t0 + run.res.timings["extraction (pair)"]
    _relocate(run, set(range(n)))
    if last >= STEPS.index("prediction"):
        yield from _geozone_steps(run, last)
    run.res.complete = True
    yield "done", 1.0, run.snapshot()


def _pair_outlines(holes: Blastholes, contours: Callable[[int], list | None], min_holes: int):
    """``outlines(geozone, source_z)`` (:data:`bgm_viewer.alignment.PairOutlines`) of the benches' ``contours(k)``.

    ``None`` for a bench pair one of whose benches' contours are not at hand (``contours(k)`` is ``None``).
    """
    from core.io.project import same_elevation

    def outlines(geozone: str, source_z: float):
        k = next((k for k in range(holes.n_benches - 1) if same_elevation(holes.bench_z_input(k), source_z)), None)
        if k is None:
            return None
        upper, lower = contours(k), contours(k + 1)
        if upper is None or lower is None:
            return None
        return tuple(
            [c.polygon for c in modelled_contours(part, geozone, b, min_holes)]
            for b, part in ((k, upper), (k + 1, lower))
        )

    return outlines


def _relocate(run: _Run, fresh: set[int]) -> None:
    """Move the run's overrides to their components in the contours of the ``fresh`` benches (this run's).

    Before any correspondence uses them: an override whose component was renumbered names
    it by its new number, and one whose component cannot be found again is dropped, never
    applied to another component. What moved is in ``run.res.relocated`` and its errors.
    """

    from .alignment import place_unplaced, relocate_overrides

    session, res = run.session, run.res
    if session.project is None or not session.project.overrides:
        return
    holes = session.holes
    overrides = session.project.overrides
    now = _pair_outlines(holes, lambda b: res.contours.get(b, []) if b in fresh else None, res.min_component_holes)
    numbered = now  # the components the overrides not yet placed name by number
    placed = run.inputs.placed_params
    if placed is not None and placed != session.params:
        # Overrides opened from a project are numbered under its parameters: placed on those components first
        # (stored, or traced once), they follow their bodies to this run's numbers below, never its numbers.
        under = session.updated(params=placed)
        numbered = _pair_outlines(
            holes, lambda b: under.bench_contours(b, run.progress) if b in fresh else None, placed.min_component_holes
        )
    overrides, missing, missing_notes = _without_missing_components(overrides, numbered, holes)
    if numbered is not now:
        overrides = place_unplaced(overrides, numbered)
    overrides, notes = relocate_overrides(overrides, now, unit=holes.frame.length_unit)
    run.session = session.updated(project=replace(session.project, overrides=overrides))
    earlier = res.relocated
    before = earlier.notes if earlier is not None else []
    followed = earlier.followed if earlier is not None else _follow_selection(run, overrides)
    placed = session.params if fresh >= set(range(holes.n_benches)) else None
    res.relocated = Relocation(run.inputs.override_edits, overrides, before + notes, placed, followed)
    if earlier is not None:
        missing, missing_notes = earlier.missing + missing, earlier.missing_notes + missing_notes
    res.relocated.missing, res.relocated.missing_notes = missing, missing_notes
    if res.relocated.notes:
        res.errors["alignment overrides"] = "; ".join(res.relocated.notes)


def _without_missing_components(overrides: list, outlines, holes: Blastholes) -> tuple[list, list, list[str]]:
    """``overrides`` less those not yet placed that name a component their bench pair lacks; those, and why.

    A project's overrides name components by number (a hand-edited one may name source component 5 of a
    bench with 3): applied, they failed every run of their geozone
    (:func:`core.io.project.check_override_components`). Checked here, in the run, where the bench pair's
    contours are traced anyway: on the window's thread, opening a Kennecott project traced 2-4 s per bench.
    Overrides already placed (made in this session, or checked by an earlier run) and those whose bench pair
    is not at hand are kept.

    Parameters
    ----------
    overrides : list of AlignmentOverride
    outlines : callable
        The outlines of the components the numbers name (see :data:`bgm_viewer.alignment.PairOutlines`).
    holes : Blastholes
        Names the bench pairs in the notes.

    Returns
    -------
    kept, missing : list
    notes : list of str
        One per override in ``missing``, naming its geozone, bench pair and the components it lacks.
    """
    from core.io.project import same_elevation

    from .alignment import missing_components

    kept, missing, notes = [], [], []
    unit = holes.frame.length_unit
    for o in overrides:
        pair = None if getattr(o, "source_outline", None) is not None else outlines(o.geozone, o.source_z)
        lacks = [] if pair is None else missing_components(o, len(pair[0]), len(pair[1]))
        if not lacks:
            kept.append(o)
            continue
        k = next(k for k in range(holes.n_benches - 1) if same_elevation(holes.bench_z_input(k), o.source_z))
        missing.append(o)
        notes.append(
            f"the override of geozone {o.geozone!r}, bench pair {holes.bench_z_input(k):g} ->"
            f" {holes.bench_z_input(k + 1):g} {unit}, names {' and '.join(lacks)}, which the bench pair does not"
            " have: it is dropped so the model runs (save the project to remove it from the file)"
        )
    return kept, missing, notes


def _follow_selection(run: _Run, overrides: list) -> tuple[Selection, Selection] | None:
    """Select the component the selected source's override moved to; ``(before, after)``, or ``None`` if none moved.

    The geologist selected the component they corrected. Left on its old number after a
    parameter renumbered the components, the selection showed another body, and the next
    nudge or typed translation overrode that body instead of the one corrected.
    """
    from core.io.project import same_elevation

    sel, z = run.sel, float(run.session.holes.bench_z_input(run.sel.bench))
    for o in overrides:
        if o.geozone == sel.geozone and same_elevation(o.source_z, z) and o.renumbered_from == sel.component:
            run.sel = run.res.selection = replace(sel, component=o.source)
            return sel, run.sel
    return None


def _snake_preview(run: _Run, previous: PipelineResult) -> Iterator[Progress]:
    """The selected component's snake alone, on its own edge points (a snake parameter changed)."""
    c = previous.selected_contour(run.sel)
    if c is not None and c.fields is not None:
        new = run.step("selected snake", lambda: run.session.snake_preview(c, run.progress))
        bench = run.res.contours[run.sel.bench]
        run.res.contours[run.sel.bench] = [new if x is c else x for x in bench]
        yield "snake of the selected component", 0.1, run.snapshot()


def _bench_pair(run: _Run, benches: list[int]) -> Iterator[Progress]:
    """Contours of the selected bench, then of the one below it.

    The selected bench comes with its fields when they are at hand or it must
    be extracted anyway (extraction keeps them at little cost); contours
    stored without them are shown first (see :func:`_selected_fields`).
    """
    session, sel, res = run.session, run.sel, run.res
    t0 = time.perf_counter()
    stored = session.stored_bench_contours(sel.bench, sel.geozone)
    if stored is None:
        selected = functools.partial(session.bench_contours_with_fields, sel.bench, sel.geozone, run.progress)
        stored = run.step("selected bench", selected)
    res.contours[sel.bench] = stored
    yield "contours of the selected bench", 0.2, run.snapshot()
    for b in benches[1:]:
        res.contours[b] = run.step("next bench", functools.partial(session.bench_contours, b, run.progress))
        yield "contours of the bench pair", 0.3, run.snapshot()
    res.timings["extraction (pair)"] = time.perf_counter() - t0


def _selected_fields(run: _Run) -> Iterator[Progress]:
    """Edge map, GVF and snake history of the selected geozone's contours on the selected bench, if missing."""
    session, sel, res = run.session, run.sel, run.res
    own = [c for c in res.contours[sel.bench] if c.geozone == sel.geozone]
    if own and all(c.fields is None for c in own):
        fields = functools.partial(session.bench_contours_with_fields, sel.bench, sel.geozone, run.progress)
        res.contours[sel.bench] = run.step("fields", fields)
        yield "edge map, GVF and snake of the selected bench", 0.4, run.snapshot()


def _pair_steps(run: _Run, benches: list[int], last: int) -> Iterator[Progress]:
    """Correspondence and morph of the selected bench pair, with the selected instance's fronts."""
    session, sel, res = run.session, run.sel, run.res
    contours = [c for b in benches for c in res.contours[b]]
    pair = res.pair = next((p for p in session.pairs(sel.geozone, contours) if p.upper == sel.bench), None)
    res.pair_params = session.params
    if pair is None:
        res.morph = None
        return
    run.step("correspondence", lambda: session.correspond(pair), "correspondence")
    yield "correspondence", 0.35, run.snapshot()
    if pair.correspondence is None:
        res.morph = None
    elif last >= STEPS.index("morph"):
        # The shown instance first, with its fronts: the pair's morph then reuses it.
        res.morph = run.step("morph (selected instance)", lambda: _morph_record(session, pair, sel), "morph")
        run.step("morph", lambda: session.morph(pair), "morph")
        yield "morph", 0.45, run.snapshot()


def _morph_record(session: ModelSession, pair: BenchPair, sel: Selection) -> MorphRecord | None:
    corr = pair.correspondence
    index = (
        None if corr is None else next((i for i, m in enumerate(corr.instances) if sel.component in m.source_ids), None)
    )
    if corr is None or index is None:
        return None
    step = session.instance_fronts(pair, index)
    ids = list(step.instance.source_ids)
    shift = np.mean(corr.translations[ids], axis=0) if ids else np.zeros(2)
    return MorphRecord(
        ids,
        list(step.instance.target_ids),
        step.result,
        (float(shift[0]), float(shift[1])),
        pair.source_z_m,
        pair.target_z_m,
    )


def _geozone_steps(run: _Run, last: int) -> Iterator[Progress]:
    """The selected geozone's whole model, its predictions below the deepest bench, and its surface."""
    session, g, res = run.session, run.sel.geozone, run.res
    res.model = run.step("geozone model", lambda: session.geozone_model(g, progress=run.progress), "model")
    res.session = session
    yield "model of the geozone", 0.85, run.snapshot()
    model = res.model
    paired = model is not None and bool(model.pairs)
    if not paired:
        res.predicted, res.surface, res.carried = [], None, None
    else:
        # Below the input's deepest bench, as bgm build predicts (core.model.build.build_geozone), not below
        # the geozone's deepest pair: a geozone whose pairs end higher up was drawn between known benches,
        # where it is absent, while the build carries it on below the deepest bench.
        zs = [run.session.holes.below_deepest_m(f) for f in PREDICTED_FRACTIONS]
        # Seconds on a large geozone (its depth trend's backtests): a newer request stops it at its next step.
        regions = run.step("prediction", lambda: session.predict(g, zs, model, run.progress), "prediction") or {}
        res.predicted = [(g, z, poly) for z, region in regions.items() for poly in region.geoms]
        res.carried = run.step("carried movement", lambda: session.carried_movement(g, model), "prediction")
    if last >= STEPS.index("surface"):
        # A selected geozone with no bench pair (a geozone of one bench, or one a parameter left without)
        # has no surface, and the other geozones' are still redone: returning here left its surface from
        # before and every other geozone's from the last parameters on screen, and exported.
        if paired:
            res.surface = run.step("surface", lambda: session.surface(g, model, run.progress), "surface")
        _show_surface(run, g, res.surface)
        yield "surface", 0.9, run.snapshot()
        yield from _other_surfaces(run)


def _show_surface(run: _Run, geozone: str, mesh) -> None:
    """Put ``mesh`` among the built surfaces, and among the shown ones without the bodies the body filter drops."""
    from core.model.surfaces import drop_small_bodies

    inputs, holes = run.inputs, run.session.holes
    shown = None
    if mesh is not None:
        own = holes.geozone == geozone
        xyz = np.column_stack([holes.xy[own], holes.bench_levels_m[holes.bench[own]]])
        shown = drop_small_bodies(
            mesh, min_volume_m3=inputs.min_body_volume_m3, min_holes=inputs.min_body_holes, holes_xyz=xyz
        )
    for kept, surfaces in ((mesh, run.res.built), (shown, run.res.surfaces)):
        if kept is None:
            surfaces.pop(geozone, None)
        else:
            surfaces[geozone] = kept


def _other_surfaces(run: _Run) -> Iterator[Progress]:
    """The surfaces of the other geozones asked for (each is ``bgm build``'s), several at once, each shown as it comes.

    A geozone's model and surface release the GIL in their heavy steps:
    Kennecott's twelve others on two threads take three quarters of the time
    they take one after another (22 s against 29), and come out the same.
    """
    others = [g for g in run.inputs.surface_geozones if g != run.sel.geozone]
    t0 = time.perf_counter()
    run.check()
    # The geozones begun stop at their model's next bench pair or their surface's next section: on_threads
    # waits for them.
    surfaces = on_threads(functools.partial(_geozone_surface, run.session, progress=run.progress), others)
    for i, (g, (mesh, timings, errors)) in enumerate(surfaces, start=1):
        run.res.timings.update(timings)
        run.res.errors.update(errors)
        _show_surface(run, g, mesh)
        yield f"surface of geozone {g}", 0.9 + 0.1 * i / len(others), run.snapshot()
        run.check()  # cancelled: the geozones not begun are dropped
    run.res.timings["other surfaces"] = time.perf_counter() - t0


def _geozone_surface(
    session: ModelSession, g: str, progress: Callable[[int, int], None] | None = None
) -> tuple[trimesh.Trimesh | None, dict, dict]:
    """``g``'s model and surface, on a worker thread: ``(mesh, timings, errors)``, errors as messages.

    Timed as :meth:`_Run.step` times them, into dicts of its own: the window's
    snapshots copy the run's while this thread would write them. ``progress``
    goes to the model (:meth:`ModelSession.geozone_model`) and the surface
    (:meth:`ModelSession.surface`): a cancelled run stops either at its next step.
    """
    timings: dict[str, float] = {}
    errors: dict[str, str] = {}
    model_of = functools.partial(session.geozone_model, g, progress=progress)
    model = _timed(f"model of {g}", model_of, f"model {g}", timings, errors)
    mesh = None
    if model is not None and model.pairs:
        surface_of = functools.partial(session.surface, g, model, progress)
        mesh = _timed(f"surface of {g}", surface_of, f"surface {g}", timings, errors)
    return mesh, timings, errors


# ---------------------------------------------------------------------------
# the model


def load_holes(source=None, read_options: dict | None = None) -> Blastholes:
    """Blastholes from a path (read with ``read_options``, :func:`read_blastholes`'s keywords), a ``Blastholes``,
    or the bundled demo (``None``)."""
    if isinstance(source, Blastholes):
        return source
    if source is None or str(source) == "demo":
        from core.synthetic.blobs import demo_dataset

        _, table = demo_dataset()
        return blastholes_from_table(table, source="demo")
    return read_blastholes(source, **(read_options or {}))


def project_input(project_path) -> str | None:
    """The input a project file names, resolved against the project's folder (``None`` if it names none).

    Raises
    ------
    BGMInputError
        If that table is not there (moved, renamed, or read from standard input): the reader said only
        "input file ... does not exist", with nothing to tell the geologist it came from the project
        or how to open the project on the table where it is now.
    """
    from core.io.project import load_project, saved_input

    project = load_project(project_path)
    path = saved_input(project, project_path)
    if path is not None and not path.exists():
        where = (
            "a table read from standard input"
            if project.input_path == "-"
            else f"the table {project.input_path}, which is not at {path} (moved or renamed?)"
        )
        raise BGMInputError(
            f"project file {project_path} was saved for {where}: open the table with the project, as"
            f" bgm view TABLE --project {project_path}"
        )
    return None if path is None else str(path)


def project_read_options(project_path) -> dict:
    """The options a project file's input was read with, as :func:`read_blastholes` takes them (``{}``: none saved)."""
    from core.io.project import load_project

    return load_project(project_path).read_keywords()


def input_relative_to(input_path: str | None, project_path) -> str | None:
    """``input_path`` as a project file at ``project_path`` names it: relative to the project's folder.

    :func:`project_input` reads it against that folder; named as given (relative to
    the folder the viewer was started in), a project saved in another folder did not
    find its input. An input that is no file (``-``, the demo) is named as given, and
    one that no relative path reaches (another drive) by its absolute path.
    """
    if input_path is None or not Path(input_path).is_file():
        return input_path
    absolute = Path(input_path).resolve()
    try:
        return os.path.relpath(absolute, Path(project_path).resolve().parent)
    except ValueError:
        return str(absolute)


def _hole_attributes(path: str | None, holes: Blastholes):
    from scipy.spatial import cKDTree

    from core.io.blastholes import coordinate_values, table_columns
    from core.io.tables import read_table

    if path is None or str(path) == "-":
        return None
    try:
        with warnings.catch_warnings():  # the first reading warned already (its encoding, blank rows)
            warnings.simplefilter("ignore", BGMWarning)
            table = read_table(path)
        named = {k: v for k, v in holes.read_options.items() if k in ("x", "y", "z", "geozone")}
        cols = table_columns(list(table.columns), **named)  # the columns the holes were read from
    except Exception:  # the reader already accepted the file; a second read failing only loses the extras
        return None
    extra = [c for c in table.columns if c not in cols.values()]
    if not extra:
        return None
    # Read as the engine read them (decimal commas, thousands separators), or rows go missing
    # and holes take a neighbour's attributes.
    x, y, z = (coordinate_values(table[cols[r]], table.attrs.get("delimiter")) for r in ("x", "y", "z"))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    if not ok.any():
        return None
    xyz = np.column_stack([holes.frame.to_local(x[ok], y[ok]), holes.frame.z_to_local(z[ok])])
    _, row = cKDTree(xyz).query(np.column_stack([holes.xy, holes.z]))
    return table.loc[ok, extra].iloc[row].reset_index(drop=True)


def bodies(holes: Blastholes) -> list[str] | None:
    """Geozones other than a host rock holding over half the holes (``None``: every geozone, there is none)."""
    labels, counts = np.unique(holes.geozone, return_counts=True)
    host = labels[counts > 0.5 * len(holes.geozone)]
    if len(host) == 0 or len(labels) == 1:
        return None
    return [g for g in holes.geozones if g not in set(host.tolist())]


def richest_pair(holes: Blastholes) -> tuple[str, int]:
    """The geozone and upper bench of the bench pair where that geozone has the most holes on both benches.

    The viewer opens there, so its stage layers (snake, GVF, morph) show
    something: a geozone absent from the selected bench has no contour to
    draw. A geozone holding over half the holes is taken for the host rock
    around the bodies and passed over when there are others. Ties go to the
    top bench and the first label; with one bench, the geozone with most holes on it.
    """
    n = holes.n_benches
    zones = holes.geozones
    counts = np.zeros((len(zones), max(n, 1)), int)
    index = {g: i for i, g in enumerate(zones)}
    np.add.at(counts, (np.array([index[g] for g in holes.geozone], int), np.asarray(holes.bench, int)), 1)
    both = np.minimum(counts[:, :-1], counts[:, 1:]) if n > 1 else counts
    host = counts.sum(axis=1) > 0.5 * len(holes.geozone)
    if len(zones) > 1:
        both[host] = -1
    b, g = np.unravel_index(int(np.argmax(both.T)), both.T.shape)  # bench-major: ties go to the top
    return zones[int(g)], int(b)


class ViewerModel:
    """State of a viewing session; changes are announced on the psygnal signals below."""

    result_changed = Signal(object)  #: a new :class:`PipelineResult`
    selection_changed = Signal(object)  #: a new :class:`Selection`
    overrides_changed = Signal()
    params_changed = Signal()  #: :attr:`params` changed (the sliders show them)
    #: Sentences on a project's overrides a run dropped: they name components their bench pair lacks.
    overrides_missing = Signal(object)
    dirty_changed = Signal(bool)

    def __init__(
        self,
        holes: Blastholes | str | Path | None = None,
        *,
        selection: Selection | None = None,
        cache: bool = True,
        read_options: dict | None = None,
    ):
        self.holes = load_holes(holes, read_options)
        self.input_path: str | None = None if not isinstance(holes, (str, Path)) else str(holes)
        self.params = ModelParameters()
        # One store for the whole session: every run shares what earlier ones computed.
        self.store = StageStore(StageCache() if cache else None)
        self.selection = selection or Selection(*richest_pair(self.holes), 0)
        self.vertical_exaggeration = 2.0
        #: Geozones whose surfaces are shown besides the selected one's (``None``: all); bodies below the body
        #: filter are not shown.
        #: By default all but a host rock holding over half the holes: its surface wraps the others.
        self.surface_geozones: list[str] | None = bodies(self.holes)
        #: How the Surfaces panel chose :attr:`surface_geozones` (:data:`core.io.project.SURFACE_SCOPES`).
        self.surface_scope = "bodies" if self.surface_geozones is not None else "all"
        self.min_body_volume_m3 = 0.0
        self.min_body_holes = 0
        #: Which layers are shown, by name (:data:`bgm_viewer.layer_names.LAYER_NAMES`).
        self.layer_visibility = default_layer_visibility()
        #: The 3D view's camera as a project saves it (:func:`core.io.project.check_camera`: the input's
        #: coordinates, plain numbers); ``None``: the window's default view. The window sets it on saving.
        self.camera: dict | None = None
        self.overrides: list = []  # bgm_viewer.alignment.PlacedOverride
        self._undo: list[UndoStep] = []
        #: What Undo took back, for Redo (latest last); a new change empties it.
        self._redo: list[UndoStep] = []
        self._override_edits = 0  # changes the user made to the overrides (see Relocation)
        #: The parameters the overrides were placed under (by the last run taken, or an edit).
        self._placed_params = self.params
        #: What the last runs said of overrides whose components were renumbered (moved or dropped).
        self.override_notes: list[str] = []
        #: What the overrides were before the run under way moved them (``None``: it did not; see :meth:`stop`).
        self._before_relocation: _Numbering | None = None
        #: Names the file the overrides were opened from in what is said of them (see :meth:`_drop_missing`).
        self._overrides_source = "the project"
        #: What was said of overrides dropped for naming components their bench pair lacks (each is said once).
        self._missing_said: list[str] = []
        #: Which component the last change of bench pair selected, and why (``None``: it changed no bench pair).
        self.selection_note: str | None = None
        self.result: PipelineResult = PipelineResult()
        #: The result of the last run that finished (what Stop shows again; see :meth:`stop`).
        self.last_complete: PipelineResult = self.result
        self._dirty = False
        self.project_path: str | None = None
        #: The clock the autosave delay is measured on (tests set their own).
        self.clock: Callable[[], float] = time.monotonic
        #: When the first change not in the autosave was made (``None``: none is).
        self._unsaved_since: float | None = None
        #: What the last autosave or restore offer could not do, for the status bar (``None``: nothing to say).
        self.autosave_note: str | None = None
        #: The autosave another viewer running now writes, this session's had it not (see :attr:`autosave_path`).
        self._shared_autosave: Path | None = None
        #: An autosave of another name this session offered or restored: removed with its own on saving or discarding.
        self._taken_autosave: Path | None = None

    @property
    def dirty(self) -> bool:
        """Unsaved parameter or alignment changes."""
        return self._dirty

    @dirty.setter
    def dirty(self, value: bool) -> None:
        self._dirty = bool(value)
        if not self._dirty:
            self._unsaved_since = None  # saved, opened or discarded: nothing left to autosave
        elif self._unsaved_since is None:
            self._unsaved_since = self.clock()
        self.dirty_changed.emit(self._dirty)

    # -- inputs for a run ------------------------------------------------------
    def session(self) -> ModelSession:
        """Core's pipeline with the current parameters and overrides (a snapshot, sharing this model's store)."""
        from core.io.project import Project

        return ModelSession(self.holes, self.params, Project(overrides=copy.deepcopy(self.overrides)), self.store)

    def inputs(self) -> PipelineInputs:
        zones = self.holes.geozones if self.surface_geozones is None else self.surface_geozones
        return PipelineInputs(
            self.session(),
            self.selection,
            tuple(zones),
            float(self.min_body_volume_m3),
            int(self.min_body_holes),
            self._override_edits,
            self._placed_params,
        )

    def source_z_input(self) -> float:
        return float(self.holes.bench_z_input(self.selection.bench))

    def run(
        self,
        from_step: str = "contours",
        cancelled=lambda: False,
        progress: Callable[[str, float], None] | None = None,
        until: str = "surface",
    ) -> PipelineResult:
        """Run synchronously (screenshots, tests); the window runs :func:`compute` in a worker thread."""
        for msg, frac, res in compute(self.inputs(), self.result, from_step, cancelled, until):
            self.set_result(res)
            if progress:
                progress(msg, frac)
        return self.result

    def set_result(self, result: PipelineResult) -> None:
        self._take_relocated(result.relocated)
        self.result = result
        if result.complete:
            self.last_complete = result
            self._before_relocation = None  # the overrides as this run left them are those of the picture
        self.result_changed.emit(result)

    def stop(self) -> str:
        """Show what the last finished run computed, marked stopped, in place of a stopped run's part-way result.

        A run stopped part way (:meth:`bgm_viewer.app.MainWindow.stop_run`) left some benches
        traced with the new sliders and the rest, the model and the surfaces with the old: shown
        as they were, that mix passed for the model of the sliders. The parameters, overrides
        and selection stay as the user set them; the next change or a run again brings the
        picture up to them. Returns what the status bar says.
        """
        self._restore_numbering()
        shown = stopped_result(self.last_complete, self.selection)
        if self.result.complete and self.result.selection == self.selection:
            shown = self.result  # only the next bench was under way: the model on screen is whole
        self.result = replace(shown, stopped=True)
        self.result_changed.emit(self.result)
        return (
            "stopped: the picture is of the last run that finished; the sliders and alignments are kept"
            " (Run > Run again, F5, or the next change brings it up to date)"
        )

    def _restore_numbering(self) -> None:
        """Give the overrides back the numbers of the last finished run, which a stopped run had moved.

        A run that renumbers components moves the overrides to their new numbers (and the selection
        with the corrected one) as soon as it has traced the selected bench pair. Stopped after that,
        the picture went back to the last finished run while the overrides kept the stopped run's
        numbers: the panel showed another component's override, and the next edit mixed the two
        numberings. Edits made since the run moved them were made on its numbers: they follow their
        components back to the picture's (:meth:`_edited_on_stopped_numbers`).
        """
        before, self._before_relocation = self._before_relocation, None
        if before is None or (before.edited and not self._edited_on_stopped_numbers(before)):
            return
        if not before.edited:
            self.overrides = before.overrides
            self._placed_params = before.placed_params
            self._undo, self._redo = before.undo, before.redo
            self.override_notes = before.notes
        if before.moved_to is not None and self.selection == before.moved_to:
            self.selection = before.selection
            self.selection_changed.emit(self.selection)
        self.overrides_changed.emit()

    def _edited_on_stopped_numbers(self, before: _Numbering) -> bool:
        """Move overrides edited on a stopped run's numbers to the picture's components, by where they are.

        Each follows its components' outlines (:func:`bgm_viewer.alignment.relocate_overrides`) into the
        last finished run's contours; Undo then brings back the overrides as they were before the run
        moved them. When one has no single component there (a body only the new sliders draw), none is
        moved and the notes say why: False, and they keep the run's numbers, as Run again needs them.
        """
        from .alignment import not_whole, relocate_overrides

        shown = self.last_complete
        if shown is None:
            return False
        outlines = _pair_outlines(self.holes, shown.contours.get, shown.min_component_holes)
        back, notes = relocate_overrides(self.overrides, outlines, unit=self.holes.frame.length_unit)
        lost = not_whole(notes)
        if lost:
            self.override_notes = [
                "Stop kept the alignment overrides on the stopped run's component numbers: " + "; ".join(lost)
            ]
            self.overrides_changed.emit()
            return False
        self.overrides = back
        self._placed_params = before.placed_params
        self._undo = [*before.undo, UndoStep(copy.deepcopy(before.overrides))]  # the edits: one step
        self._redo = []
        self.override_notes = []
        return True

    def _take_relocated(self, relocated: Relocation | None) -> None:
        """Take a run's overrides as they followed renumbered components (unless the user changed them since).

        Moved or dropped overrides are a change Undo reverts, with the parameters before it,
        said in :attr:`override_notes` (and in the result's errors, which the window's status bar shows).
        Overrides of a project naming components their bench pair lacks are dropped for good (they
        never applied), each said once in a warning and on :attr:`overrides_missing`. What the overrides
        were before the run took them is kept until it finishes, for :meth:`stop`.
        """
        if relocated is None or relocated.edits != self._override_edits:
            return
        self._drop_missing(relocated)  # for good: Stop does not bring them back either
        if self._before_relocation is None:
            self._before_relocation = _Numbering(
                copy.deepcopy(self.overrides),
                self._placed_params,
                list(self._undo),
                list(self._redo),
                list(self.override_notes),
                self.selection,
            )
        changed = relocated.overrides != self.overrides  # numbers changed or overrides dropped
        if changed:
            self._push_run_undo(relocated.edits)
        self.overrides = copy.deepcopy(relocated.overrides)  # with the outlines the run placed them at
        if relocated.followed is not None and self.selection == relocated.followed[0]:
            # the selection follows the corrected component to its new number, as the run did
            self.selection = self._before_relocation.moved_to = relocated.followed[1]
            self.selection_changed.emit(self.selection)
        if relocated.params is not None:
            self._placed_params = relocated.params
        if changed:
            self.override_notes = list(relocated.notes)
            self.dirty = True
            self.overrides_changed.emit()

    def _drop_missing(self, relocated: Relocation) -> None:
        """Drop the overrides the run found naming components their bench pair lacks; say each once.

        No Undo brings them back: they never applied, and the next run would drop them again.
        """
        if not relocated.missing:
            return
        self.overrides = [o for o in self.overrides if o not in relocated.missing]
        new = [f"{self._overrides_source}: {n}" for n in relocated.missing_notes]
        new = [n for n in new if n not in self._missing_said]
        self._missing_said.extend(new)
        for note in new:
            warnings.warn(note, BGMWarning, stacklevel=2)
        if new:
            self.overrides_missing.emit(new)

    # -- what a picked hole reports ------------------------------------------------
    def hole_info(self, i: int) -> dict[str, object]:
        """A hole's id, geozone, bench elevation (input units) and the input's other columns (grade...)."""
        h = self.holes
        info: dict[str, object] = {
            "hole": hole_name(h, i),
            "geozone": str(h.geozone[i]),
            f"bench ({h.frame.length_unit})": h.bench_z_input(int(h.bench[i])),
        }
        extra = self.hole_attributes()
        if extra is not None:
            info.update({str(k): v for k, v in extra.iloc[i].items()})
        return info

    def hole_attributes(self):
        """The input's columns other than x, y, z, geozone and hole id, one row per hole (``None``: none).

        The engine reads only the columns it models; the rest (grades...) are
        read here once and matched to the holes by position, which survives
        the rows the reader drops or merges.
        """
        if not hasattr(self, "_attributes"):
            self._attributes = _hole_attributes(self.input_path, self.holes)
        return self._attributes

    # -- parameters and selection ------------------------------------------------
    def param(self, name: str):
        """The value of parameter ``name`` (engine units; ``None``: derived from the data)."""
        return parameter_value(self.params, name)

    def set_param(self, name: str, value) -> str:
        """Set a parameter (engine units, ``None`` for the data-derived default); returns the step to re-run.

        Raises
        ------
        ValueError
            ``name`` is no parameter (the message names it and the parameters),
            or the value is not one it takes (:class:`core.errors.BGMInputError`).
        """
        if name not in PARAMETER:
            # parameters_from_dict leaves unknown keys alone (a project file may hold others'): a misspelt
            # name set nothing, and step_of raised a bare KeyError after.
            raise ValueError(f"{name!r} is no model parameter; the parameters are {', '.join(PARAMETER)}")
        params = parameters_from_dict({name: value}, self.params)
        if params != self.params:
            self.params = params
            # the overrides Undo took back were placed under the parameters before: Redo would misplace them
            self._redo.clear()
            self.dirty = True
            self.params_changed.emit()
        return step_of(name)

    def set_view(self, **settings) -> bool:
        """Set view settings the project saves (:attr:`vertical_exaggeration`, :attr:`surface_scope`,
        :attr:`surface_geozones`, :attr:`min_body_volume_m3`, :attr:`min_body_holes`); ``True`` if one changed.

        A change marks the project unsaved: saved with it, it was lost on closing without a prompt.
        """
        unknown = set(settings) - set(VIEW_SETTINGS)
        if unknown:
            raise ValueError(f"{', '.join(sorted(unknown))}: no view setting; they are {', '.join(VIEW_SETTINGS)}")
        changed = {k: v for k, v in settings.items() if getattr(self, k) != v}
        for name, value in changed.items():
            setattr(self, name, value)
        if changed:
            self.dirty = True
        return bool(changed)

    def select(self, geozone: str | None = None, bench: int | None = None, component: int | None = None) -> str | None:
        """Change the selection; returns the step to re-run from (or ``None``).

        Another bench pair of the same geozone without a ``component`` selects the component
        the selected one corresponds to there, else the first; :attr:`selection_note` says which.
        """
        old = self.selection
        sel = Selection(
            geozone if geozone is not None else old.geozone,
            int(bench) if bench is not None else old.bench,
            int(component) if component is not None else old.component,
        )
        if sel.geozone not in self.holes.geozones:
            raise ValueError(f"geozone {sel.geozone!r} is not in the input")
        if not 0 <= sel.bench < max(self.holes.n_benches - 1, 1):
            raise ValueError(f"bench pair {sel.bench} is out of range")
        self.selection_note = None
        if component is None and sel.bench != old.bench:
            # the number kept named another body on the new bench, or none
            sel, self.selection_note = self._stepped(old, sel)
        if sel == old:
            return None
        self.selection = sel
        self.dirty = True  # the project saves the selection
        self.selection_changed.emit(sel)
        if sel.bench != old.bench or sel.geozone != old.geozone:
            return "contours"  # the fields of the newly selected contours are needed
        return "morph"

    def _stepped(self, old: Selection, new: Selection) -> tuple[Selection, str]:
        """``new`` with the component that corresponds to ``old``'s on its bench (else the first), and what to say."""
        r = self.result
        # the whole geozone's pairs once its model is computed; until then the selected pair's own
        pairs = [*(r.model.pairs if r.model is not None else []), *([r.pair] if r.pair is not None else [])]
        pairs = [p for p in pairs if p.geozone == new.geozone]
        same_zone = old.geozone == new.geozone
        found = corresponding_component(pairs, old.component, old.bench, new.bench) if same_zone else None
        where = f"bench {self.holes.bench_z_input(new.bench):g} {self.holes.frame.length_unit}"
        n = len(r.sources(new)) if new.bench in r.contours else None
        if found is not None:
            old_where = f"{self.holes.bench_z_input(old.bench):g} {self.holes.frame.length_unit}"
            said = f"source component {found} selected on {where}: component {old.component} of {old_where} continues into it"
            return replace(new, component=found), said
        said = f"source component 0 (the first) selected on {where}"
        if n == 0:
            said += f": geozone {new.geozone} has no modelled component there"
        elif same_zone:
            said += f": no correspondence links component {old.component} to it"
        return replace(new, component=0), said

    # -- manual alignment ------------------------------------------------------------
    def override_here(self, create: bool = False):
        """The override of the selected source (``None`` if it has none and ``create`` is false)."""
        from core.io.project import same_elevation

        from .alignment import PlacedOverride

        sel, z = self.selection, self.source_z_input()
        for o in self.overrides:
            if o.geozone == sel.geozone and o.source == sel.component and same_elevation(o.source_z, z):
                return o
        if not create:
            return None
        o = PlacedOverride(sel.geozone, z, sel.component)
        self.overrides.append(o)
        return o

    def _push_undo(self, params: ModelParameters | None = None, edits: int = -1) -> None:
        """Keep the overrides as they are for Undo (and ``params``, before a run's change; see :class:`UndoStep`).

        A new change: what Undo took back before it can no longer be redone on top of it.
        """
        self._undo.append(UndoStep(copy.deepcopy(self.overrides), params, edits))
        del self._undo[:-50]
        self._redo.clear()

    def _push_run_undo(self, edits: int) -> None:
        """Keep the overrides and the parameters they were placed under, before a run moves or drops overrides.

        A run's changes with no edit between them are one step: a run takes its bench
        pair's overrides before the other benches', and a slider moved meanwhile cancels
        it half way. Undo goes back to before the first, where the overrides were placed.
        """
        top = self._undo[-1] if self._undo else None
        if top is None or top.params is None or top.edits != edits:
            self._push_undo(self._placed_params, edits)

    def carried_text(self) -> str:
        """How the selected geozone's prediction below the deepest bench carries its benches' movement on, in one
        line (what ``bgm build``'s report says of it); ``-`` until its model is run."""
        shown = self.result.selection
        if self.result.carried is None or shown is None or shown.geozone != self.selection.geozone:
            return "-"
        return carried_line(carried_json(self.result.carried, self.holes), self.holes.frame.length_unit)

    def current_translation_m(self) -> tuple[float, float] | None:
        """The selected source's translation (metres), ``None`` until its bench pair is corresponded."""
        pc = self.result.correspondence if self.result.selection == self.selection else None
        if pc is None or not 0 <= self.selection.component < len(pc.translations):
            return None
        t = pc.translations[self.selection.component]
        return float(t[0]), float(t[1])

    def _selected_pair(self) -> BenchPair:
        """The selected bench pair, whose selected source an override corrects.

        Raises
        ------
        ValueError
            If the pair is not computed yet, the selected geozone has no
            component on one of its benches, or the selected source is not
            among its components: an override of it would name a component
            the model does not have, and fail every run of the geozone.
        """
        sel, res = self.selection, self.result
        unit = self.holes.frame.length_unit
        pair = res.pair if res.selection == sel else None
        if pair is None or pair.upper != sel.bench:
            raise ValueError(
                f"geozone {sel.geozone} has no bench pair from bench {self.source_z_input():g} {unit} to align"
                " (not computed yet, or no component on one of its benches)"
            )
        if not 0 <= sel.component < len(pair.sources):
            raise ValueError(
                f"source component {sel.component} does not exist: geozone {sel.geozone} has"
                f" {len(pair.sources)} on bench {self.source_z_input():g} {unit}"
            )
        return pair

    def set_translation(self, dx_m: float, dy_m: float) -> str:
        """Lock the selected source's translation to ``(dx_m, dy_m)`` metres; returns the step to re-run.

        Raises
        ------
        ValueError
            If the selected source does not exist (see :meth:`_selected_pair`), or the
            translation is not finite or longer than the input spans (a project holding it
            would not open: :func:`core.io.project.check_project`).
        """
        from core.io.project import input_extent, translation_fits

        pair = self._selected_pair()
        mpu = self.holes.frame.metres_per_unit
        t = (float(dx_m) / mpu, float(dy_m) / mpu)
        extent = input_extent(self.holes)
        if not translation_fits(t, extent):
            unit = self.holes.frame.length_unit
            raise ValueError(
                f"a translation of ({t[0]:.6g}, {t[1]:.6g}) {unit} moves the source off the input,"
                f" which spans {extent:.6g} {unit}"
            )
        self._push_undo()
        o = self.override_here(create=True)
        o.translation = t
        self._place(o, pair)
        self._changed_overrides()
        return "correspondence"

    def nudge(self, ddx_m: float, ddy_m: float) -> str:
        """Move the selected source by ``(ddx_m, ddy_m)`` from its current translation.

        From its locked translation when it has one: the result's is the one before the last nudge
        until that nudge's run is done, and a second Ctrl+arrow or drag before then undid the first.
        """
        cur = self.translation_m() or (0.0, 0.0)
        return self.set_translation(cur[0] + ddx_m, cur[1] + ddy_m)

    def translation_m(self) -> tuple[float, float] | None:
        """The selected source's translation (metres) as the next run uses it: its locked one when it has one.

        The result's (:meth:`current_translation_m`) is the one before the last change until that
        change's run is done: a drag's preview, a nudge or Lock started from it undid the change.
        """
        o = self.override_here()
        if o is not None and o.translation is not None:
            mpu = self.holes.frame.metres_per_unit
            return o.translation[0] * mpu, o.translation[1] * mpu
        return self.current_translation_m()

    def lock_current(self) -> str:
        """Lock the selected source at its current translation (its automatic one, or the one locked already)."""
        cur = self.translation_m()
        if cur is None:
            self._selected_pair()  # says why, when the source does not exist
            raise ValueError("the selected source has no translation to lock yet: its correspondence failed")
        return self.set_translation(*cur)

    def set_association(self, target: int, flag: bool | None) -> str:
        """Force (``True``), forbid (``False``) or reset (``None``) association with ``target``.

        Raises
        ------
        ValueError
            If the selected source or ``target`` is not a component of the selected bench pair.
        """
        pair = self._selected_pair()
        if flag is not None and not 0 <= int(target) < len(pair.targets):
            raise ValueError(
                f"target component {target} does not exist: geozone {pair.geozone} has"
                f" {len(pair.targets)} on bench {self.holes.bench_z_input(pair.lower):g} {self.holes.frame.length_unit}"
            )
        self._push_undo()
        o = self.override_here(create=True)
        if flag is None:
            o.associate.pop(int(target), None)
        else:
            o.associate[int(target)] = bool(flag)
        self._place(o, pair)
        self._changed_overrides()
        return "correspondence"

    def clear_override(self) -> str:
        o = self.override_here()
        if o is not None:
            self._push_undo()
            self.overrides.remove(o)
            self._changed_overrides()
        return "correspondence"

    def _place(self, o, pair: BenchPair) -> None:
        """Remember where the components ``o`` names are, so it follows them when they are renumbered."""
        o.place([c.polygon for c in pair.sources], [c.polygon for c in pair.targets])
        if self.result.pair_params is not None:
            self._placed_params = self.result.pair_params

    def _changed_overrides(self) -> None:
        self.overrides = [o for o in self.overrides if o.translation is not None or o.associate]
        self._edited_overrides()
        self.override_notes = []
        self.dirty = True
        self.overrides_changed.emit()

    def _edited_overrides(self) -> None:
        """Count a change of the overrides by the user: a run begun before it no longer changes them.

        Made after a run moved them to its numbers, Stop moves them back by where their components are.
        """
        self._override_edits += 1
        if self._before_relocation is not None:
            self._before_relocation.edited = True

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    def _now(self, like: UndoStep) -> UndoStep:
        """The overrides as they are, to go back to from a step like ``like`` (the parameters too, for a run's)."""
        params = None if like.params is None else self.params
        return UndoStep(copy.deepcopy(self.overrides), params, like.edits, self._placed_params)

    def undo(self) -> str | None:
        """Restore the overrides before the last change; returns the step to re-run.

        A change a run made (overrides moved or dropped when a parameter changed)
        is undone with that parameter change: the parameters the overrides were
        placed under come back too, and the step returned is the earliest they
        affect, so the next run applies the overrides to their own components.
        """
        if not self._undo:
            return None
        undone = self._undo.pop()
        self._redo.append(self._now(undone))
        self.overrides = undone.overrides
        self._edited_overrides()
        step = "correspondence"
        if undone.params is None:
            self.override_notes = []  # an edit undone: no run's note holds any more, as after an edit
        elif undone.params != self.params:
            step = earliest_step(step, self._restore_params(undone.params)) or step
        else:
            self.override_notes = ["Undo brought back the alignment overrides a run had moved or dropped"]
        self.dirty = True
        self.overrides_changed.emit()
        return step

    def redo(self) -> str | None:
        """Bring back the overrides (and parameters) the last Undo took back; returns the step to re-run.

        Without it, an Undo pressed once too often lost the alignment it undid for good: the
        geologist had to make it again. A new change (an edit, a parameter) empties what can be redone.
        """
        if not self._redo:
            return None
        redone = self._redo.pop()
        self._undo.append(self._now(redone))
        self.overrides = copy.deepcopy(redone.overrides)
        self._edited_overrides()
        step = "correspondence"
        self.override_notes = []
        if redone.params is not None and redone.params != self.params:
            step = earliest_step(step, self._restore_params(redone.params, "Redo")) or step
        if redone.placed_params is not None:
            self._placed_params = redone.placed_params  # the overrides are placed as they were before the Undo
        self.dirty = True
        self.overrides_changed.emit()
        return step

    def _restore_params(self, params: ModelParameters, action: str = "Undo") -> str:
        """Set the parameters back to ``params``, saying so in :attr:`override_notes`; returns the step to re-run."""
        names = [p.name for p in PARAMETERS if parameter_value(params, p.name) != parameter_value(self.params, p.name)]
        values = ", ".join(self._shown_value(params, n) for n in names)
        self.override_notes = [
            f"{action} brought back the alignment overrides and the parameters they were placed under: {values}"
        ]
        self.params = self._placed_params = params
        self.params_changed.emit()
        return earliest_step(*(step_of(n) for n in names)) or "contours"  # every field has a spec

    def _shown_value(self, params: ModelParameters, name: str) -> str:
        """Parameter ``name`` of ``params`` as the sliders show it: its label and value in the input's units."""
        spec, value = PARAMETER[name], parameter_value(params, name)
        if value is None:
            return f"{spec.label} auto"
        factor, unit = display_unit(spec, self.holes)
        shown = value if isinstance(value, bool) else f"{value * factor:g}"
        return f"{spec.label} {shown}{f' {unit}' if unit else ''}"

    # -- project file ------------------------------------------------------------------
    def _load_surface_view(self, viewer: dict) -> None:
        """The surface scope and body filter a project saved (checked by :func:`core.io.project.load_project`).

        A project without them (saved before they were) keeps the defaults; a scope of the host
        rock's bodies on an input without a host rock is all geozones, as the panel offers.
        """
        scope = viewer.get("surfaces")
        if scope == "all" or (scope == "bodies" and bodies(self.holes) is None):
            self.surface_scope, self.surface_geozones = "all", None
        elif scope == "bodies":
            self.surface_scope, self.surface_geozones = scope, bodies(self.holes)
        elif scope == "selected":
            self.surface_scope, self.surface_geozones = scope, []
        elif scope == "ticked":
            zones = viewer.get("surface_geozones") or []
            self.surface_scope, self.surface_geozones = scope, [g for g in self.holes.geozones if g in zones]
        if viewer.get("min_body_volume_m3") is not None:
            self.min_body_volume_m3 = float(viewer["min_body_volume_m3"])
        if viewer.get("min_body_holes") is not None:
            self.min_body_holes = int(viewer["min_body_holes"])

    def _load_layers_and_camera(self, viewer: dict, source: str) -> None:
        """The layers shown and the camera a project saved (checked by :func:`core.io.project.load_project`).

        A project without them (saved before they were) shows the default layers from the default view.
        A layer this viewer does not have (a newer one's) is said in a warning and left out.
        """
        self.layer_visibility = default_layer_visibility()
        saved = viewer.get("layers") or {}
        unknown = sorted(set(saved) - set(LAYER_NAMES))
        if unknown:
            warnings.warn(
                f"{source}: viewer setting layers names {', '.join(map(repr, unknown))}, no layer of this viewer"
                f" (its layers: {', '.join(LAYER_NAMES)}); left out",
                BGMWarning,
                stacklevel=3,
            )
        self.layer_visibility.update({name: bool(shown) for name, shown in saved.items() if name in LAYER_NAMES})
        self.camera = copy.deepcopy(viewer.get("camera"))

    def to_project(self):
        """Parameters (as ``bgm --project`` reads them), overrides, the view settings and the input's reading options."""
        from core.io.project import Project

        params = parameters_to_dict(self.params)
        params["viewer"] = {
            "geozone": self.selection.geozone,
            "bench": self.selection.bench,
            "component": self.selection.component,
            "vertical_exaggeration": self.vertical_exaggeration,
            "surfaces": self.surface_scope,
            "min_body_volume_m3": self.min_body_volume_m3,
            "min_body_holes": self.min_body_holes,
            "layers": dict(self.layer_visibility),
        }
        if self.camera is not None:
            params["viewer"]["camera"] = copy.deepcopy(self.camera)
        if self.surface_scope == "ticked":
            params["viewer"]["surface_geozones"] = list(self.surface_geozones or [])
        from core.io.project import reading_of

        return Project(
            parameters=params,
            overrides=copy.deepcopy(self.overrides),
            input_path=self.input_path,
            reading=reading_of(self.holes.read_options),  # read again its way: feet stay feet
        )

    def save_project(self, path: str | Path) -> None:
        """Write the project to ``path``, naming the input relative to the project's folder (as it is read).

        Raises
        ------
        ValueError
            If the alignment overrides are placed under other parameters than the current ones: a
            parameter changed and no run has moved them to their components yet. Saved then, they
            would name components by their numbers before the change, under the parameters after it
            (``bgm build --project`` refuses such a project, or applies them to other components).
        """
        from core.io.project import save_project

        if self.overrides and self._placed_params != self.params:
            if self.result.stopped:  # no run is moving them: the one that would was stopped
                raise ValueError(
                    "the alignment overrides are not yet moved to the components of the changed parameters (the run"
                    " was stopped): run again (F5), and save once it is done"
                )
            raise ValueError(
                "the alignment overrides are being moved to the components of the changed parameters:"
                " save once the run is done"
            )
        project = self.to_project()
        project.input_path = input_relative_to(self.input_path, path)
        save_project(project, path)
        # The saved project holds the work now: the autosave it had (or the table's, never saved
        # before, or the one beside the project saved as another) would only offer it again.
        before = self.autosave_path
        self.project_path = str(path)
        for autosave in {before, self.autosave_path, self._taken_autosave}:
            self._remove_autosave(autosave)
        self._taken_autosave = None
        self.dirty = False

    def load_project(self, path: str | Path) -> None:
        """Apply a project file's parameters, selection, view and overrides (the input is not reloaded).

        Overrides and parameters the model cannot use are named in warnings
        (:func:`core.io.project.check_project`); parameters out of range are refused. An override
        naming a component its bench pair lacks is dropped, and said, by the first run that traces
        that pair (:attr:`overrides_missing`): tracing here held the window's thread for seconds a bench.
        """
        from core.io.project import load_project

        self._apply_project(load_project(path), f"project file {path}")
        self.project_path = str(path)
        self.dirty = False

    def _apply_project(self, proj, source: str = "the project") -> None:
        """Take a :class:`~core.io.project.Project`'s parameters, view and overrides (see :meth:`load_project`).

        ``source`` names the file in the warnings (``"project file p.json"``).
        """
        from core.io.project import check_project

        check_project(proj, self.holes, command="the viewer", uses_parameters=True)
        self.params = self._placed_params = parameters_from_dict(proj.parameters)
        self.params_changed.emit()
        viewer = proj.parameters.get("viewer", {}) or {}
        if isinstance(viewer, dict):
            with contextlib.suppress(ValueError, TypeError):
                self.select(viewer.get("geozone"), viewer.get("bench"), viewer.get("component"))
            ve = viewer.get("vertical_exaggeration")
            if isinstance(ve, (int, float)) and ve > 0:
                self.vertical_exaggeration = float(ve)
            self._load_surface_view(viewer)
            self._load_layers_and_camera(viewer, source)
        from .alignment import PlacedOverride

        # Overrides naming a component their bench pair lacks are dropped by the first run (it traces the
        # benches anyway; here, on the window's thread, a Kennecott project took 2-4 s a bench), said then.
        self.overrides = [PlacedOverride.of(o) for o in proj.overrides]
        self._overrides_source, self._missing_said = source, []
        self._edited_overrides()
        self._undo.clear()
        self._redo.clear()
        self.overrides_changed.emit()

    # -- autosave ----------------------------------------------------------------------
    @property
    def autosave_path(self) -> Path | None:
        """Where this session's unsaved work is autosaved: beside its project, else one per table (``None``: nowhere).

        See :func:`core.io.autosave.autosave_path`. When another viewer running now writes that
        autosave (two viewers on one project), this session's goes to a name of its own
        (:func:`core.io.autosave.own_autosave_path`): the last to write no longer wins.
        """
        from core.io.autosave import autosave_path, own_autosave_path

        path = autosave_path(self.project_path, self.input_path)
        return own_autosave_path(path) if path is not None and path == self._shared_autosave else path

    def _share_autosave_if_another_writes_it(self) -> bool:
        """Take a name of this session's own when another viewer running now writes the autosave; ``True`` if so.

        Said in :attr:`autosave_note` (the window's status bar), naming the other viewer and both files.
        """
        from core.io.autosave import autosave_path, live_writer

        path = autosave_path(self.project_path, self.input_path)
        if path is None or path == self._shared_autosave:
            return False
        writer = live_writer(path)
        if writer is None:
            return False
        self._shared_autosave = path
        self.autosave_note = (
            f"another viewer (process {writer['pid']} on {writer['host']}) is autosaving this project to {path}:"
            f" it is not offered nor overwritten; this session autosaves to {self.autosave_path}"
        )
        return True

    def autosave_due_in_s(self, now: float | None = None) -> float | None:
        """Seconds until the unsaved changes are due to be autosaved (0: now; ``None``: none to autosave)."""
        if self._unsaved_since is None or self.autosave_path is None:
            return None
        now = self.clock() if now is None else now
        return max(0.0, self._unsaved_since + AUTOSAVE_DELAY_S - now)

    def autosave(self, now: float | None = None) -> Path | None:
        """Write the unsaved work to :attr:`autosave_path` if it is due (:data:`AUTOSAVE_DELAY_S`); returns where.

        Never the project file, and never raises: what goes wrong is said in :attr:`autosave_note`
        and tried again at the next change. Overrides not yet moved to the components of a changed
        parameter (a run is on its way) would be written under parameters they were not placed
        under: the autosave waits a delay more for the run.

        Parameters
        ----------
        now : float, optional
            The time on :attr:`clock` (default: now).
        """
        from core.errors import BGMInputError
        from core.io.autosave import write_autosave

        due = self.autosave_due_in_s(now)
        if due is None or due > 0:
            return None
        now = self.clock() if now is None else now
        if self.overrides and self._placed_params != self.params:
            self._unsaved_since = now  # tried again once the run has placed them
            return None
        self._unsaved_since = None
        # Another viewer may have opened the project since this one did, and autosaved first.
        switched = self._share_autosave_if_another_writes_it()
        path = self.autosave_path
        if path is None:
            return None
        try:
            write_autosave(self.to_project(), path, self.project_path, self.input_path)
        except (BGMInputError, OSError) as exc:
            self.autosave_note = f"autosave not written: {exc}"
            return None
        if not switched:
            self.autosave_note = None
        return path

    def _remove_autosave(self, path: Path | None) -> None:
        """Delete the autosave at ``path``; failing to is said in :attr:`autosave_note`, never raised."""
        from core.errors import BGMInputError
        from core.io.autosave import remove_autosave

        try:
            remove_autosave(path)
        except BGMInputError as exc:
            self.autosave_note = str(exc)

    def discard_autosave(self) -> None:
        """Delete this session's autosave: the user chose not to keep the unsaved work (or declined to restore it)."""
        self._unsaved_since = None
        self._remove_autosave(self.autosave_path)
        self._remove_autosave(self._taken_autosave)
        self._taken_autosave = None

    def autosave_offer(self):
        """The autosave to offer to restore on opening, or ``None``; one unreadable is set aside, said in :attr:`autosave_note`.

        Offered when it is at least as new as the saved project, or there is no saved project
        (:func:`core.io.autosave.pending_autosave`). The window asks; :meth:`restored` applies it.
        One another viewer running now writes is neither offered nor overwritten (said in the
        note); the autosave of a viewer that wrote under a name of its own and ended without
        saving is offered when the project's own is not.
        """
        from core.io.autosave import live_writer, other_viewers_autosaves, pending_autosave

        self.autosave_note = None
        offer, note = None, None
        if not self._share_autosave_if_another_writes_it():
            offer, note = pending_autosave(self.autosave_path, self.project_path, self.input_path)
        base = self._shared_autosave or self.autosave_path
        for other in [] if offer is not None or base is None else other_viewers_autosaves(base):
            if other != self.autosave_path and live_writer(other) is None:
                offer, _ = pending_autosave(other, self.project_path, self.input_path)
                if offer is not None:
                    break
        if note is not None and self.autosave_path is not None:
            note = self._set_unreadable_autosave_aside(self.autosave_path, note)
        self.autosave_note = self.autosave_note or note
        self._taken_autosave = offer.path if offer is not None and offer.path != self.autosave_path else None
        return offer

    @staticmethod
    def _set_unreadable_autosave_aside(path: Path, note: str) -> str:
        """Set the unreadable autosave at ``path`` aside (:func:`core.io.autosave.set_aside`); ``note`` saying where.

        Left where it was, an autosave that cannot be read (half written by a full disk, edited
        by hand) was ignored with the same note at every opening, forever: it is kept under a
        name the note gives, as one whose restore failed, and not reported again.
        """
        from core.errors import BGMInputError
        from core.io.autosave import set_aside

        try:
            return f"{note}; it is kept as {set_aside(path)} and will not be offered again"
        except BGMInputError as why:
            return f"{note}; {why}"

    def restored(self, offer) -> ViewerModel:
        """A model of this session's table holding the autosave's work, unsaved (its project is this one's).

        The table is read again the autosave's way when it was read otherwise (a table opened
        in feet, reopened without ``--units``): the overrides and parameters were made on it
        read so. Otherwise the holes and the computed stages are shared.

        A restore that fails sets the autosave aside (:func:`core.io.autosave.set_aside`): kept
        under a name the message gives, and not offered again at every opening.

        Raises
        ------
        BGMInputError
            If the table must be read again and is no file (standard input), or an override
            cannot be honoured (:func:`core.io.project.check_project`).
        """
        from core.errors import BGMInputError
        from core.io.autosave import set_aside

        try:
            return self._restored(offer)
        except (BGMInputError, ValueError, OSError) as exc:
            # Left where it was, the autosave that cannot fit this table was offered, and failed, at every opening.
            try:
                aside = f"it is kept as {set_aside(offer.path)} and will not be offered again"
            except BGMInputError as why:
                aside = str(why)
            raise BGMInputError(f"the autosave {offer.path} cannot be restored: {exc}; {aside}") from None

    def _restored(self, offer) -> ViewerModel:
        """:meth:`restored` without setting the autosave aside when it fails."""
        from core.errors import BGMInputError
        from core.io.project import comparable_reading, reading_of

        want, have = comparable_reading(offer.project.reading), comparable_reading(reading_of(self.holes.read_options))
        if want == have:
            model = ViewerModel(self.holes, selection=self.selection, cache=False)
            model.store, model.input_path = self.store, self.input_path  # one store: the stages computed stay
        elif self.input_path is not None and Path(self.input_path).is_file():
            options = offer.project.read_keywords()
            model = ViewerModel(self.input_path, cache=self.store.cache is not None, read_options=options)
        else:
            raise BGMInputError(
                f"it was made reading the table with {want}, not {have}, and the table cannot be read"
                " again: open it from its file"
            )
        model._apply_project(offer.project, f"the autosave {offer.path}")
        model.project_path = self.project_path
        model._shared_autosave, model._taken_autosave = self._shared_autosave, self._taken_autosave
        model.dirty = True  # the project file does not hold it: Save writes it, closing asks
        model._unsaved_since = None  # the autosave holds it already
        return model
