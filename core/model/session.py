"""Staged, memoised runs of the pipeline: the one pipeline ``bgm`` and the viewer share.

A :class:`ModelSession` holds the blastholes, the :class:`ModelParameters` and
the project's manual overrides, and answers for any bench or geozone with the
stage functions of :mod:`core.model.pipeline` (contours per bench;
correspondence and morph per bench pair; prediction and surface per geozone).
Every result is stored in a :class:`StageStore` under a key that hashes what
it was computed from: the bench's holes, the polygons of a bench pair, the
parameters of its stage (:func:`core.model.parameters.stage_values`), the
overrides of the pair and the engine's code. So a changed parameter re-runs
exactly its stage and the stages after it, on the benches and pairs it
changes, and nothing is ever served stale. With a
:class:`core.io.cache.StageCache` the results also outlive the process, so a
second command on the same input reuses them.

Sessions are cheap, immutable views: :meth:`ModelSession.updated` gives one
with other parameters or overrides that shares the same store (what the
viewer does on every slider move). Results in the store are shared between
sessions: treat them as read-only.
"""

from __future__ import annotations

import functools
import math
import threading
from collections import Counter, OrderedDict
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np
import shapely
from shapely.geometry import MultiPolygon

from core.errors import quoted
from core.extraction.contours import Contour, extract_bench, traced_benches
from core.geometry.grid import as_multipolygon, cell_size_within
from core.io.blastholes import Blastholes
from core.io.cache import MISSING, StageCache, content_key, engine_fingerprint
from core.io.project import Project, check_override_components, overrides_for
from core.model.extrapolation import CarriedMovement, carried_movement
from core.model.fields import BenchFields
from core.model.new_ground import known_holes
from core.model.parameters import ModelParameters, stage_values
from core.model.pipeline import (
    BenchPair,
    GeozoneModel,
    MorphStep,
    bench_pairs,
    correspond,
    geozone_fields,
    morph,
    morph_instance,
)
from core.model.prediction import predict_geozone, regions_between, with_undrilled_ground
from core.model.progress import Stages
from core.threads import Progress, on_threads

#: Iso-contours per bench interval used to build surfaces.
SURFACE_STEPS_PER_BENCH = 4
#: Results kept in memory per stage, newest first; display fields (edge maps, GVF, snake
#: histories, level-set fronts) and a geozone's bench fields (signed distances on every
#: bench) run to tens of megabytes each, so only the latest few.
MEMORY_ENTRIES = {"fields": 3, "fronts": 8, "bench_fields": 4}


class StageStore:
    """Stage results by ``(stage, key)``: the latest in memory, all of them on disk with a cache.

    Thread-safe (the viewer computes in a worker thread while its window
    reads); two threads asking for the same missing key both compute it,
    with the same result. ``counts[(stage, source)]`` tells how each request
    was answered (``memory``, ``disk`` or ``computed``).
    """

    def __init__(self, cache: StageCache | None = None, max_entries: int = 128):
        self.cache = cache
        self.max_entries = max_entries  #: per stage, except the display stages of MEMORY_ENTRIES
        self.counts: Counter = Counter()
        self._memory: dict[str, OrderedDict] = {}
        self._lock = threading.Lock()

    def get(self, stage: str, key: str, compute: Callable[[], object], *, disk: bool = True):
        """The stored result, or ``compute()`` stored (on disk too when ``disk`` and a cache is set)."""
        value = self.peek(stage, key, disk=disk)
        if value is not MISSING:
            return value
        value = compute()
        self.counts[stage, "computed"] += 1
        self.put(stage, key, value, disk=disk)
        return value

    def peek(self, stage: str, key: str, *, disk: bool = True):
        """The stored result, or :data:`core.io.cache.MISSING` (nothing is computed)."""
        value = self._recall(stage, key)
        if value is not MISSING:
            self.counts[stage, "memory"] += 1
        elif disk and self.cache is not None:
            value = self.cache.load(stage, key)
            if value is not MISSING:
                self.counts[stage, "disk"] += 1
                self._remember(stage, key, value)
        return value

    def put(self, stage: str, key: str, value, *, disk: bool = True) -> None:
        """Store a result computed elsewhere (e.g. by a worker process)."""
        self._remember(stage, key, value)
        if disk and self.cache is not None:
            self.cache.store(stage, key, value)

    def _recall(self, stage: str, key: str):
        with self._lock:
            entries = self._memory.get(stage)
            if entries is None or key not in entries:
                return MISSING
            entries.move_to_end(key)
            return entries[key]

    def _remember(self, stage: str, key: str, value) -> None:
        with self._lock:
            entries = self._memory.setdefault(stage, OrderedDict())
            entries[key] = value
            entries.move_to_end(key)
            while len(entries) > MEMORY_ENTRIES.get(stage, self.max_entries):
                entries.popitem(last=False)

    def forget(self, keep: tuple[str, ...] = ()) -> None:
        """Drop the results held in memory, but those of the stages in ``keep`` (the disk cache keeps them all)."""
        with self._lock:
            self._memory = {stage: entries for stage, entries in self._memory.items() if stage in keep}

    def __getstate__(self) -> dict:
        # Sent to other processes (dask workers): the disk cache travels, memory and lock do not.
        return {"cache": self.cache, "max_entries": self.max_entries}

    def __setstate__(self, state: dict) -> None:
        self.cache, self.max_entries = state["cache"], state["max_entries"]
        self.counts, self._memory, self._lock = Counter(), {}, threading.Lock()


@dataclass(frozen=True, eq=False)
class ModelSession:
    """The pipeline on one input, stage by stage, with every result memoised (see the module docstring).

    Parameters
    ----------
    holes : Blastholes
    params : ModelParameters
    project : core.io.project.Project, optional
        Manual overrides (locked translations, forced and forbidden associations).
    store : StageStore
        Where results are kept; give it a :class:`~core.io.cache.StageCache` to keep them on disk.
    """

    holes: Blastholes
    params: ModelParameters = field(default_factory=ModelParameters)
    project: Project | None = None
    store: StageStore = field(default_factory=StageStore)

    @classmethod
    def open(cls, holes: Blastholes, params=None, project=None, *, cache: bool = True) -> ModelSession:
        """A session on the user's disk cache (``cache=False``: in memory only, as ``--no-cache``)."""
        return cls(holes, params or ModelParameters(), project, StageStore(StageCache() if cache else None))

    def updated(self, **changes) -> ModelSession:
        """The same input and store with other ``params`` and/or ``project``."""
        return replace(self, **changes)

    # -- keys ------------------------------------------------------------------------------
    def bench_key(self, bench: int) -> str:
        """Hash of what extraction reads of one bench: its holes (positions, labels, indices) and spacing."""
        h, idx = self.holes, self.holes.on_bench(bench)
        level = float(h.bench_levels_m[bench])
        return content_key(engine_fingerprint(), idx, h.xy[idx], h.geozone[idx], float(h.hole_spacing_m), level)

    def _contours_key(self, bench: int) -> str:
        return content_key("contours", self.bench_key(bench), stage_values(self.params, "contours"))

    def _pair_keys(self, pair: BenchPair) -> tuple[str, str]:
        """Keys of a pair's correspondence and of its morph."""
        locked, forced, forbidden = self.overrides(pair)
        corr = content_key(
            "correspondence",
            engine_fingerprint(),
            [c.polygon for c in pair.sources],
            [c.polygon for c in pair.targets],
            float(self.holes.hole_spacing_m),
            float(self.holes.frame.metres_per_unit),  # locked translations are in input units
            stage_values(self.params, "correspondence"),
            {int(k): tuple(map(float, v)) for k, v in locked.items()},
            set(forced),
            set(forbidden),
        )
        return corr, content_key("morph", corr, stage_values(self.params, "morph"))

    def _fields_key(self, geozone: str, own: list[Contour]) -> str:
        """Key of a geozone's bench fields: every bench's holes (drilled areas), the geozone's contours, the reach."""
        return content_key(
            "bench_fields",
            [self.bench_key(k) for k in range(self.holes.n_benches)],
            geozone,
            sorted(((int(c.bench), int(c.component), c.polygon) for c in own), key=lambda t: t[:2]),
            float(self.params.frontier_reach_spacings),
        )

    def _model_key(self, model: GeozoneModel) -> str:
        return content_key(
            "model",
            [self._pair_keys(p)[1] for p in model.pairs],
            [c.polygon for c in model.contours],
            [c.polygon for c in model.minor],
            self._fields_key(model.geozone, [*model.contours, *model.minor]),
            float(self.holes.hole_spacing_m),
        )

    def uncertainty_key(self, model: GeozoneModel, z_m: list[float], probability: float) -> str:
        """Key of the uncertainty of the model's sections at ``z_m``.

        Its calibration may pool the other geozones' backtests: their contours
        rest on the same holes and contour parameters as the model's own.
        """
        return content_key(
            "uncertainty",
            self._model_key(model),
            [float(z) for z in z_m],
            float(probability),
            stage_values(self.params, "contours"),
            stage_values(self.params, "prediction"),
        )

    # -- contours (paper section 2) ------------------------------------------------------------
    def bench_contours(self, bench: int, progress: Progress | None = None) -> list[Contour]:
        """Contours of every geozone on one bench.

        ``progress`` is told the parts traced (:func:`core.extraction.contours.extract_bench`) when the
        bench is not stored; a :class:`core.threads.Cancelled` it raises stores nothing.
        """
        key = self._contours_key(bench)
        return self.store.get(
            "contours", key, lambda: extract_bench(self.holes, bench, None, self.params.extraction, progress=progress)
        )

    def geozone_contours(self, geozone: str) -> list[Contour]:
        """Contours of one geozone on every bench, in bench order (see :meth:`contours_of`)."""
        return self.contours_of([geozone])[geozone]

    def contours_of(
        self, geozones: list[str], progress: Callable[[int, int], None] | None = None
    ) -> dict[str, list[Contour]]:
        """Contours of the given geozones on every bench, in bench order, by geozone.

        A geozone's contours depend on the others' only through the bench's
        evidence, so a bench whose contours are not stored yet is traced for
        these geozones alone, on one evidence (a Kennecott ``bgm predict``
        extracted all thirteen geozones for one: 11 of its 15 s), benches on
        threads (:func:`traced_benches`); stored whole, they are filtered.
        ``progress(done, total)`` is called as each bench to trace is traced
        (never when all are stored).
        """
        found: dict[int, dict[str, list[Contour]]] = {}
        missing: dict[tuple[str, ...], list[int]] = {}  # the geozones a bench lacks -> those benches
        keys = [self._contours_key(k) for k in range(self.holes.n_benches)]
        for k, key in enumerate(keys):
            every = self.store.peek("contours", key)
            if every is not MISSING:
                found[k] = {g: [c for c in cast(list, every) if c.geozone == g] for g in geozones}
                continue
            found[k] = {g: self.store.peek("contours", content_key(key, g)) for g in geozones}
            lacking = tuple(g for g, own in found[k].items() if own is MISSING)
            if lacking:
                missing.setdefault(lacking, []).append(k)
        done, total = 0, sum(len(benches) for benches in missing.values())
        for lacking, benches in missing.items():
            for k, traced in traced_benches(self.holes, benches, lacking, self.params.extraction):
                self.store.counts["contours", "computed"] += 1
                done += 1
                if progress:
                    progress(done, total)
                for g in lacking:
                    found[k][g] = [c for c in traced if c.geozone == g]
                    self.store.put("contours", content_key(keys[k], g), found[k][g])
        return {g: [c for k in sorted(found) for c in found[k][g]] for g in geozones}

    def traced_contours(
        self, benches: Iterable[int], progress: Progress | None = None
    ) -> Iterator[tuple[int, list[Contour]]]:
        """``(bench, contours of every geozone)``: the stored benches first, then the others as they are traced.

        The others are traced several at once (:meth:`bench_contours` on
        threads, :func:`core.threads.on_threads`), each stored as it comes;
        the order is the order they finish in. ``progress`` is told each
        bench's parts as they are traced, from the bench's thread (its counts
        are the bench's): a :class:`core.threads.Cancelled` it raises stops
        the benches begun at their next part, and the others are not begun.
        """
        todo = []
        for k in benches:
            stored = self.store.peek("contours", self._contours_key(k))
            if stored is MISSING:
                todo.append(k)
            else:
                yield k, cast(list, stored)
        yield from on_threads(functools.partial(self.bench_contours, progress=progress), todo)

    def bench_contours_with_fields(self, bench: int, geozone: str, progress: Progress | None = None) -> list[Contour]:
        """:meth:`bench_contours`, with the edge map, GVF and snake history of ``geozone``'s contours.

        Kept in memory only, for the newest few requests: fields are large. Once the
        bench's contours are stored, only ``geozone``'s are traced again, with their
        fields (the viewer's switch of geozone on a Kennecott bench: 0.4 s, not 2-5 s
        tracing all thirteen). ``progress`` is told the parts traced (see :meth:`bench_contours`).
        """
        key = self._contours_key(bench)

        def extract() -> list[Contour]:
            stored = self.store.peek("contours", key)
            if stored is not MISSING:
                own = extract_bench(
                    self.holes, bench, [geozone], self.params.extraction, keep_fields=True, progress=progress
                )
                if len(own) == sum(c.geozone == geozone for c in stored):  # a geozone's contours come in order
                    traced = iter(own)
                    return [next(traced) if c.geozone == geozone else c for c in stored]
            full = extract_bench(self.holes, bench, None, self.params.extraction, keep_fields=True, progress=progress)
            if self.store.peek("contours", key, disk=False) is MISSING:
                self.store.put("contours", key, [replace(c, fields=None) for c in full])
            return [c if c.geozone == geozone else replace(c, fields=None) for c in full]

        return self.store.get("fields", content_key(key, geozone), extract, disk=False)

    def stored_bench_contours(self, bench: int, geozone: str | None = None) -> list[Contour] | None:
        """The bench's contours if they need no computing (with ``geozone``'s fields when at hand), else ``None``."""
        key = self._contours_key(bench)
        found = MISSING if geozone is None else self.store.peek("fields", content_key(key, geozone), disk=False)
        if found is MISSING:
            found = self.store.peek("contours", key)
        return None if found is MISSING else cast(list, found)

    def contours(self, benches=None, progress: Callable[[int, int], None] | None = None) -> list[Contour]:
        """Contours of every geozone on the given benches (all by default), in bench order."""
        benches = list(range(self.holes.n_benches)) if benches is None else list(benches)
        by_bench: dict[int, list[Contour]] = {}
        for done, (k, contours) in enumerate(self.traced_contours(benches), start=1):
            by_bench[k] = contours
            if progress:
                progress(done, len(benches))
        return [c for k in benches for c in by_bench[k]]

    def snake_preview(self, contour: Contour, progress: Progress | None = None) -> Contour:
        """The contour extracted again, with its fields, with this session's parameters.

        A quick preview for a snake parameter change, before the whole bench
        is extracted again: only the contour's geozone is traced (its bench's
        evidence, then the snake of each of its parts). The contour itself when
        the new parameters give the geozone no part of that number. ``progress`` is told the parts traced.
        """
        fresh = extract_bench(
            self.holes, contour.bench, [contour.geozone], self.params.extraction, keep_fields=True, progress=progress
        )
        return next((c for c in fresh if c.component == contour.component), contour)

    # -- correspondence and morph (sections 3-4) -------------------------------------------------
    def pairs(self, geozone: str, contours: list[Contour] | None = None) -> list[BenchPair]:
        """The geozone's bench pairs (not yet corresponded)."""
        contours = self.geozone_contours(geozone) if contours is None else contours
        return bench_pairs(self.holes, contours, geozone, self.params.min_component_holes)

    def overrides(self, pair: BenchPair) -> tuple[dict, set, set]:
        """The project's overrides of one bench pair (input units), as :func:`correspond` takes them."""
        if self.project is None:
            return {}, set(), set()
        upper = self.holes.bench_z_input(pair.upper)
        found = overrides_for(self.project, pair.geozone, upper)
        where = (
            f"geozone {quoted(pair.geozone)}, benches {upper:g} and {self.holes.bench_z_input(pair.lower):g} "
            f"{self.holes.frame.length_unit}"
        )
        check_override_components(found, len(pair.sources), len(pair.targets), where)
        return found

    def correspond(self, pair: BenchPair, keep_fields: bool = False):
        """The pair's correspondence (set on ``pair``); with ``keep_fields`` computed afresh with its fields."""
        if keep_fields:
            return correspond(pair, self.holes, self.params, self.overrides(pair), keep_fields=True)
        key, _ = self._pair_keys(pair)
        pair.correspondence = self.store.get(
            "correspondence", key, lambda: correspond(pair, self.holes, self.params, self.overrides(pair))
        )
        return pair.correspondence

    def morph(self, pair: BenchPair, keep_fronts: bool = False) -> list[MorphStep]:
        """The morphs of every instance of the pair (set on ``pair``), corresponding it first if needed."""
        if pair.correspondence is None:
            self.correspond(pair)
        spacing = self.holes.hole_spacing_m
        if keep_fronts:
            return morph(pair, self.params, keep_fronts=True, hole_spacing_m=spacing)
        _, key = self._pair_keys(pair)
        pair.morphs = self.store.get("morph", key, lambda: self._morph_instances(pair, key))
        return pair.morphs

    def _morph_instances(self, pair: BenchPair, key: str) -> list[MorphStep]:
        """:func:`core.model.pipeline.morph`, reusing instances already morphed with their fronts."""
        corr = pair.correspondence
        if corr is None:
            raise ValueError("the pair has no correspondence yet")
        steps = []
        for i, instance in enumerate(corr.instances):
            shown = self.store.peek("fronts", content_key("fronts", key, i), disk=False)
            if shown is MISSING:
                steps.append(morph_instance(pair, instance, self.params, False, self.holes.hole_spacing_m))
            else:  # recording fronts changes nothing else
                steps.append(MorphStep(shown.instance, replace(shown.result, fronts=[])))
        return steps

    def instance_fronts(self, pair: BenchPair, index: int) -> MorphStep:
        """Morph instance ``index`` of a corresponded pair with its fronts kept (for display).

        Asked before :meth:`morph`, the pair's morph reuses it instead of morphing that instance twice.
        """
        if pair.correspondence is None:
            raise ValueError("the pair has no correspondence yet")
        instance = pair.correspondence.instances[index]
        key = content_key("fronts", self._pair_keys(pair)[1], index)
        return self.store.get(
            "fronts",
            key,
            lambda: morph_instance(pair, instance, self.params, True, self.holes.hole_spacing_m),
            disk=False,
        )

    # -- a geozone's model, prediction and surface ------------------------------------------------------
    def geozone_model(
        self,
        geozone: str,
        *,
        contours: list[Contour] | None = None,
        stages: tuple[str, ...] = ("correspond", "morph"),
        keep_fields: bool = False,
        progress: Callable[[int, int], None] | None = None,
    ) -> GeozoneModel:
        """Everything the model knows about one geozone (see :func:`core.model.pipeline.model_geozone`)."""
        if contours is None:
            if keep_fields:
                contours = [c for k in range(self.holes.n_benches) for c in self.bench_contours_with_fields(k, geozone)]
            else:
                contours = self.geozone_contours(geozone)
        pairs = self.pairs(geozone, contours)
        for done, pair in enumerate(pairs, start=1):
            if "correspond" in stages or "morph" in stages:
                self.correspond(pair, keep_fields)
            if "morph" in stages:
                self.morph(pair, keep_fronts=keep_fields)
            if progress:
                progress(done, len(pairs))
        own = [c for c in contours if c.geozone == geozone]
        big = [c for c in own if len(c.holes) >= self.params.min_component_holes]
        minor = [c for c in own if len(c.holes) < self.params.min_component_holes]
        for k in range(self.holes.n_benches):  # evaluation scores on drilled areas: kept with the other results
            self.drilled_area(k)
        return GeozoneModel(geozone, big, pairs, minor, self.bench_fields(geozone, own))

    def drilled_area(self, bench: int):
        """The bench's drilled area (:meth:`Blastholes.drilled_area`), stored with the other results."""
        area = self.store.get("drilled", self.bench_key(bench), lambda: self.holes.drilled_area(bench))
        self.holes._drilled.setdefault(bench, area)  # what Blastholes.drilled_area would compute
        return area

    def bench_fields(self, geozone: str, own: list[Contour]) -> BenchFields:
        """:func:`core.model.pipeline.geozone_fields` of the geozone from its own contours (of every size)."""
        reach = self.params.frontier_reach_spacings
        return self.store.get(
            "bench_fields", self._fields_key(geozone, own), lambda: geozone_fields(self.holes, own, reach)
        )

    def predict(self, geozone: str, z_m, model: GeozoneModel | None = None, progress: Progress | None = None) -> dict:
        """The geozone's region at each elevation (metres); see :func:`core.model.prediction.predict_geozone`.

        ``progress`` is told the model's bench pairs when ``model`` is not given, then the
        prediction's steps (each elevation, the depth trend's backtests); a
        :class:`core.threads.Cancelled` it raises stops it there, and nothing of it is stored.

        A geozone with no bench pair (never in a component of ``min_component_holes`` or more holes:
        label noise to the model, :func:`core.model.build.no_pair_note`) is predicted nowhere, at every
        elevation: ``bgm build`` writes no prediction for it and the viewer draws none. The depth trend
        of its holes' own small contours gave ``bgm predict`` a section of 43 m² below the deepest bench
        that the other two never showed.
        """
        stages = Stages(progress, 2)  # the model, then the prediction: one series that never goes back
        model = model or self.geozone_model(geozone, progress=stages.stage(0))
        z_m = [float(z) for z in z_m]
        if not model.pairs:
            return {z: MultiPolygon() for z in z_m}
        key = content_key("prediction", self._model_key(model), z_m, stage_values(self.params, "prediction"))
        spacing_m = self.holes.hole_spacing_m
        return self.store.get(
            "prediction",
            key,
            lambda: predict_geozone(model, z_m, spacing_m, self.params, progress=stages.stage(1), holes=self.holes),
        )

    def carried_movement(self, geozone: str, model: GeozoneModel | None = None) -> CarriedMovement | None:
        """How the geozone's depth trend carries its benches' movement on below the deepest bench, and why
        (:func:`core.model.extrapolation.carried_movement`); None for a geozone with no bench pair (predicted nowhere).

        Kept with the stage cache as its prediction is: a prediction served from the cache made no trend, and this
        reads one.
        """
        model = model or self.geozone_model(geozone)
        if not model.pairs or model.fields is None:
            return None
        fields, spacing_m = model.fields, self.holes.hole_spacing_m
        key = content_key("carried movement", self._model_key(model), stage_values(self.params, "prediction"))
        return self.store.get(
            "carried movement", key, lambda: carried_movement(fields, fields.bench_height_m, spacing_m)
        )

    def surface(self, geozone: str, model: GeozoneModel | None = None, progress: Progress | None = None):
        """The geozone's closed surface (trimesh, local metres): what ``bgm build`` exports.

        ``progress`` is told the model's bench pairs when ``model`` is not given, then the
        sections made (:func:`surface_sections`), then the mesh's steps
        (:func:`core.model.surfaces.surface_from_sections`). A
        :class:`core.threads.Cancelled` it raises stops the surface at that step, and
        nothing of it is stored.

        Raises
        ------
        core.errors.BGMInputError or RuntimeError
            When no surface can be made (every section empty, a mesh that will not close).
        """
        from core.model.surfaces import surface_from_sections

        stages = Stages(progress, 3)  # the model, its sections, the mesh: one series that never goes back
        model = model or self.geozone_model(geozone, progress=stages.stage(0))
        key = content_key(
            "surface",
            self._model_key(model),
            stage_values(self.params, "prediction"),
            stage_values(self.params, "surface"),
        )

        def compute():
            sections = surface_sections(model, self.holes, self.params, progress=stages.stage(1))
            cell = surface_cell_size(model, self.holes, self.params.surface_max_cells)
            # What the holes showed is at least about a spacing wide: on a grid coarsened past half a spacing
            # (a geozone across a wide pit) a dyke one hole wide is narrower than a cell, and no morph speck.
            return surface_from_sections(
                sections, cell_size_m=cell, min_width_m=0.5 * self.holes.hole_spacing_m, progress=stages.stage(2)
            )

        return self.store.get("surface", key, compute)


def surface_sections(
    model: GeozoneModel,
    holes: Blastholes,
    params: ModelParameters,
    below_fraction: float = 1.0,
    progress: Progress | None = None,
):
    """Stacked regions (z metres, region) from the top bench to one bench below the table's deepest.

    A pair's lower bench is a section of its own where the next pair does not
    start from it: the geozone is on neither of the benches between (it
    disappears for two benches or more and comes back), and its empty
    section there ends the body above it. Without it the body reached on to
    about halfway to the next pair's upper bench, through benches drilled
    without it.

    Past a bench's drilling edge, in ground the benches above drilled and no
    bench at or below the section did (a pit narrowing with depth), a section
    holds the geozone's depth trend as well, as :func:`predict_geozone` does at
    every elevation (:func:`core.model.prediction.undrilled_extension`): a
    bench's contour ends at its drilling edge, which is no boundary, and a body
    cut there ended on the slope to that edge, or pinched out under its last
    bench where the predictions below the deepest bench carried it on. Where
    the geozone's pairs end above the deepest bench, the sections run on below
    the deepest as every other geozone's do, empty but for that trend: a body
    absent from benches that drilled its ground closes above them. Down to the
    deepest bench's level the ground the bench at or above a section did not drill is as
    :func:`predict_geozone` has it there (:func:`core.model.prediction.with_undrilled_ground`).

    ``progress(done, total)`` is told as each bench pair's sections are made, then the
    steps of the sections below the deepest bench (:func:`predict_geozone`: each
    elevation, the depth trend's backtests), then as each section takes in the depth
    trend: each a third of one series that never goes back (:class:`core.model.progress.Stages`). Seconds on a large
    geozone (Kennecott's 3026: 3 s); a :class:`core.threads.Cancelled` it raises stops
    them there.
    """
    stages = Stages(progress, 3)  # the pairs' sections, those below the deepest, the trend taken in
    progress = stages.stage(0)
    sections = []
    for i, p in enumerate(model.pairs):
        if p.correspondence is None:
            continue
        fractions = [s / SURFACE_STEPS_PER_BENCH for s in range(SURFACE_STEPS_PER_BENCH)]
        between = regions_between(p, fractions[1:])  # the fractions' trajectories ordered once
        for s, f in enumerate(fractions):
            z = p.source_z_m + f * (p.target_z_m - p.source_z_m)
            region = model.region_at_bench(p.upper) if s == 0 else between[s - 1]
            sections.append((z, as_multipolygon(region)))
        if i + 1 < len(model.pairs) and model.pairs[i + 1].upper != p.lower:
            sections.append((p.target_z_m, as_multipolygon(model.region_at_bench(p.lower))))
        if progress:
            progress(i + 1, len(model.pairs))
    if not model.pairs:
        return sections
    last = model.pairs[-1]
    sections.append((last.target_z_m, as_multipolygon(model.region_at_bench(last.lower))))
    levels = np.asarray(holes.bench_levels_m, float)
    # On down to the table's deepest bench where the geozone's pairs end above it: empty but for the trend.
    for upper, lower in zip(levels[last.lower : -1], levels[last.lower + 1 :]):
        sections.extend((float(upper + f * (lower - upper)), MultiPolygon()) for f in np.linspace(0.25, 1.0, 4))
    zs = [holes.below_deepest_m(f) for f in np.linspace(0.25, below_fraction, 4)]
    below = stages.stage(1)
    sections.extend(predict_geozone(model, zs, holes.hole_spacing_m, params, progress=below, holes=holes).items())
    if below:
        below(1, 1)
    trended, progress = [], stages.stage(2)
    known = known_holes(holes, model.geozone).down_to(float(levels[-1]))
    for z, r in sections:
        trended.append((z, with_undrilled_ground(r, model, z, holes.hole_spacing_m, known)))
        if progress:
            progress(len(trended), len(sections))
    return trended


def surface_cell_size(model: GeozoneModel, holes: Blastholes, max_cells: int = 300) -> float:
    """Half a hole spacing, coarsened so the surface grid holds under ``max_cells`` squared; less for a thin geozone.

    Half a hole spacing resolves all the data can tell; finer only adds faces.
    The grid covers the geozone's own sections only. Where it is coarsened
    (a geozone across a wide pit), a geozone whose parts are typically
    narrower than two cells (twice its contours' area over their perimeter:
    a dyke one hole wide) has the grid's nodes inside it here and not there,
    and was drawn as a string of beads (a constructed dyke 5 m wide and 2 km
    long on 6.7 m cells: 102 bodies, 41% of its volume). Its cell is then half
    that width, no finer than half a spacing nor than ``2 max_cells`` squared
    (the same dyke on 3.3 m cells: one body, 99.6%).
    """
    polys = [c.polygon for c in model.contours if not c.polygon.is_empty]
    half_spacing_m = 0.5 * holes.hole_spacing_m
    if not polys:
        return half_spacing_m
    xmin, ymin, xmax, ymax = shapely.union_all(polys).bounds
    cell_m = cell_size_within(xmax - xmin, ymax - ymin, half_spacing_m, max_cells)
    perimeter_m = sum(p.length for p in polys)
    width_m = 2.0 * sum(p.area for p in polys) / perimeter_m if perimeter_m > 0 else math.inf
    if width_m < 2.0 * cell_m:
        cell_m = cell_size_within(xmax - xmin, ymax - ymin, max(half_spacing_m, 0.5 * width_m), 2 * max_cells)
    return cell_m
