"""The viewer's state and pipeline, without Qt or rendering.

:class:`ViewerModel` holds the blastholes, the parameters (grouped by stage),
the selection (geozone, bench pair, source component), the manual alignment
overrides with an undo stack, and the latest :class:`PipelineResult`.
:func:`compute` runs the engine stages downstream of a given stage and yields
intermediate results, so a worker thread can show the updated contour first
and the rest as it comes, and can be cancelled between steps.

Stages, in order: ``boundary`` (boundary holes, per bench), ``snake`` (edge map,
GVF and snake), ``correspondence`` (association and alignment of the selected
bench pair), ``morph`` (level-set morph of the selected component's morph
instance), ``surface`` (the selected geozone's surface from its sections).
"""

from __future__ import annotations

import contextlib
import copy
import math
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import shapely
from shapely import affinity

from core.errors import BGMInputError, BGMWarning
from core.extraction.contours import Contour, ExtractionParameters, extract_bench
from core.io.blastholes import Blastholes, blastholes_from_table, read_blastholes

STAGES = ("boundary", "snake", "correspondence", "morph", "surface")


@dataclass(frozen=True)
class ParamSpec:
    """A tunable parameter: where it acts, its range and default."""

    name: str
    label: str
    stage: str
    minimum: float
    maximum: float
    default: float
    integer: bool = False
    help: str = ""


PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec(
        "search_radius_spacings",
        "search radius (x spacing)",
        "boundary",
        1.0,
        4.0,
        1.6,
        help="region growing and entropy radius r, in hole spacings",
    ),
    ParamSpec("entropy_threshold", "entropy threshold", "boundary", 0.0, 1.5, 0.5),
    ParamSpec("gap_angle_deg", "gap-closure angle (deg)", "boundary", 60.0, 180.0, 120.0),
    ParamSpec("gap_neighbours", "gap-closure neighbours", "boundary", 4, 24, 12, integer=True),
    ParamSpec("edge_map_cells", "edge-map grid size", "snake", 80, 400, 240, integer=True),
    ParamSpec("gvf_mu", "GVF mu", "snake", 0.01, 0.5, 0.2),
    ParamSpec("snake_alpha", "snake alpha", "snake", 0.0, 0.5, 0.05),
    ParamSpec("snake_beta", "snake beta", "snake", 0.0, 0.5, 0.05),
    ParamSpec("snake_max_iterations", "snake iterations", "snake", 10, 1500, 600, integer=True),
    ParamSpec("mu_lower_spacings", "mu_lower (x spacing)", "correspondence", 0.25, 5.0, 1.5),
    ParamSpec("morph_cells", "morph grid size", "morph", 64, 384, 160, integer=True),
    ParamSpec("speed_clamp_cells", "speed clamp (cells)", "morph", 0.5, 10.0, 3.0),
    ParamSpec("surface_cells", "surface grid size", "surface", 40, 300, 120, integer=True),
)
PARAM_BY_NAME = {p.name: p for p in PARAMETERS}


def default_parameters() -> dict[str, float]:
    return {p.name: (int(p.default) if p.integer else float(p.default)) for p in PARAMETERS}


def extraction_parameters(params: dict, hole_spacing_m: float) -> ExtractionParameters:
    """The engine's :class:`ExtractionParameters` for viewer parameter values."""
    return ExtractionParameters(
        search_radius_m=float(params["search_radius_spacings"]) * hole_spacing_m,
        entropy_threshold=float(params["entropy_threshold"]),
        gap_angle_rad=math.radians(float(params["gap_angle_deg"])),
        gap_neighbours=int(params["gap_neighbours"]),
        edge_map_cells=int(params["edge_map_cells"]),
        gvf_mu=float(params["gvf_mu"]),
        snake_alpha=float(params["snake_alpha"]),
        snake_beta=float(params["snake_beta"]),
        snake_max_iterations=int(params["snake_max_iterations"]),
    )


@dataclass(frozen=True)
class Selection:
    """What the stage layers show: a geozone, the bench pair ``(bench, bench + 1)``, a source component."""

    geozone: str
    bench: int = 0
    component: int = 0


@dataclass
class MorphRecord:
    """The morph of one morph instance, with the translation used to draw it in place."""

    source_ids: list[int]
    target_ids: list[int]
    result: object  # core.morph.levelset.MorphResult
    shift_m: tuple[float, float]
    z_from_m: float
    z_to_m: float


@dataclass
class PipelineResult:
    """Everything the layers are drawn from; replaced (not mutated) by each run."""

    contours: dict[int, list[Contour]] = field(default_factory=dict)
    correspondence: object | None = None  # core.correspondence.pair.PairCorrespondence
    morph: MorphRecord | None = None
    surface: object | None = None  # trimesh.Trimesh
    predicted: list = field(default_factory=list)  # (geozone, z_m, polygon) below the deepest bench
    timings: dict[str, float] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)
    complete: bool = False

    def geozone_contours(self, geozone: str, bench: int) -> list[Contour]:
        """Contours of one geozone on one bench, by component number."""
        return sorted((c for c in self.contours.get(bench, []) if c.geozone == geozone), key=lambda c: c.component)

    def selected_contour(self, sel: Selection) -> Contour | None:
        cs = self.geozone_contours(sel.geozone, sel.bench)
        return cs[sel.component] if 0 <= sel.component < len(cs) else None


class Cancelled(Exception):
    """A newer request superseded this run."""


@dataclass(frozen=True)
class PipelineInputs:
    """An immutable snapshot of what a run needs (safe to hand to a worker thread)."""

    holes: Blastholes
    params: dict
    selection: Selection
    locked: dict  # source -> (dx_m, dy_m)
    forced: frozenset
    forbidden: frozenset


Progress = tuple[str, float, PipelineResult]


def compute(  # noqa: C901 - to be split into named steps
    inputs: PipelineInputs,
    previous: PipelineResult | None,
    from_stage: str,
    cancelled: Callable[[], bool] = lambda: False,
    until: str = "surface",
) -> Iterator[Progress]:
    """Run the stages from ``from_stage`` on; yield ``(message, fraction, result)`` as parts finish.

    The selected component is updated first (for a snake-stage change, by re-running
    only its snake), then the selected bench pair's correspondence and morph, then
    the other benches, then the surface. Each yielded result is a new object.
    Stages after ``until`` are skipped.
    """
    if from_stage not in STAGES:
        raise ValueError(f"unknown stage {from_stage!r}; stages are {', '.join(STAGES)}")
    holes, sel, params = inputs.holes, inputs.selection, inputs.params
    start = STAGES.index(from_stage)
    last = STAGES.index(until)
    if previous is None or not previous.contours:
        start = 0
    # Benches not yet redone keep showing their previous contours until they are.
    res = PipelineResult(
        contours=dict(previous.contours) if previous else {},
        correspondence=previous.correspondence if previous and start > 2 else None,
        morph=previous.morph if previous and start > 3 else None,
        surface=None,
        timings=dict(previous.timings) if previous else {},
    )
    ep = extraction_parameters(params, holes.hole_spacing_m)
    n = holes.n_benches
    pair = [b for b in (sel.bench, sel.bench + 1) if 0 <= b < n]

    def check():
        if cancelled():
            raise Cancelled()

    def snapshot(**kw) -> PipelineResult:
        return replace(res, contours=dict(res.contours), timings=dict(res.timings), errors=dict(res.errors), **kw)

    if start <= 1:
        # 1. fast path: the selected component's snake only (snake-stage change)
        if start == 1:
            c = res.selected_contour(sel) if previous else None
            if c is not None and c.fields is not None:
                t0 = time.perf_counter()
                fresh = extract_bench(holes, sel.bench, [sel.geozone], ep, keep_fields=True)
                new = next((x for x in fresh if x.component == c.component), c)
                res.contours[sel.bench] = [new if x is c else x for x in res.contours[sel.bench]]
                res.timings["selected snake"] = time.perf_counter() - t0
                check()
                yield "snake of the selected component", 0.1, snapshot()
        # 2. the selected bench pair, then the others
        order = pair + [b for b in range(n) if b not in pair]
        t0 = time.perf_counter()
        for i, b in enumerate(order):
            check()
            res.contours[b] = extract_bench(holes, b, None, ep, keep_fields=(b == sel.bench))
            if i == 0 and len(pair) > 1:
                yield "contours of the selected bench", 0.2, snapshot()
            if i == len(pair) - 1:
                res.timings["extraction (pair)"] = time.perf_counter() - t0
                yield "contours of the bench pair", 0.3, snapshot()
                yield from _pair_stages(inputs, res, snapshot, check, 2, last)
            elif i >= len(pair):
                yield f"contours of bench {b}", 0.5 + 0.4 * (i + 1) / len(order), snapshot()
        res.timings["extraction (all)"] = time.perf_counter() - t0
    else:
        yield from _pair_stages(inputs, res, snapshot, check, start, last)
    check()
    if last >= 4:
        t0 = time.perf_counter()
        try:
            res.surface = _surface(inputs, res)
        except Exception as exc:
            res.errors["surface"] = str(exc)
        res.timings["surface"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        try:
            res.predicted = _predict(inputs, res)
        except Exception as exc:
            res.errors["prediction"] = str(exc)
        res.timings["prediction"] = time.perf_counter() - t0
    res.complete = True
    yield "done", 1.0, snapshot()


def _pair_stages(inputs: PipelineInputs, res: PipelineResult, snapshot, check, start: int, last: int = 4):
    if start <= 2 <= last:
        check()
        t0 = time.perf_counter()
        try:
            res.correspondence = _correspond(inputs, res)
        except Exception as exc:
            res.correspondence, res.errors["correspondence"] = None, str(exc)
        res.timings["correspondence"] = time.perf_counter() - t0
        yield "correspondence", 0.35, snapshot()
    if start <= 3 <= last:
        check()
        t0 = time.perf_counter()
        try:
            res.morph = _morph(inputs, res)
        except Exception as exc:
            res.morph, res.errors["morph"] = None, str(exc)
        res.timings["morph"] = time.perf_counter() - t0
        yield "morph", 0.5, snapshot()


def _correspond(inputs: PipelineInputs, res: PipelineResult):
    from core.correspondence.pair import correspond_pair

    holes, sel = inputs.holes, inputs.selection
    if sel.bench + 1 >= holes.n_benches:
        return None
    src = [c.polygon for c in res.geozone_contours(sel.geozone, sel.bench)]
    tgt = [c.polygon for c in res.geozone_contours(sel.geozone, sel.bench + 1)]
    if not src and not tgt:
        return None
    ns, nt = len(src), len(tgt)
    locked = {s: t for s, t in inputs.locked.items() if s < ns}
    forced = {p for p in inputs.forced if p[0] < ns and p[1] < nt}
    forbidden = {p for p in inputs.forbidden if p[0] < ns and p[1] < nt}
    return correspond_pair(
        src,
        tgt,
        hole_spacing_m=holes.hole_spacing_m,
        mu_lower_m=float(inputs.params["mu_lower_spacings"]) * holes.hole_spacing_m,
        locked_translations=locked,
        forced=forced,
        forbidden=forbidden,
    )


def _morph(inputs: PipelineInputs, res: PipelineResult) -> MorphRecord | None:
    from core.morph.levelset import morph_regions

    pc = res.correspondence
    sel, holes, params = inputs.selection, inputs.holes, inputs.params
    if pc is None:
        return None
    inst = next((i for i in pc.instances if sel.component in i.source_ids), None)
    if inst is None:
        return None
    src = [c.polygon for c in res.geozone_contours(sel.geozone, sel.bench)]
    tgt = [c.polygon for c in res.geozone_contours(sel.geozone, sel.bench + 1)]
    moved = [affinity.translate(src[s], *pc.translations[s]) for s in inst.source_ids]
    targets = [tgt[t] for t in inst.target_ids]
    union = shapely.union_all([g for g in moved + targets if not g.is_empty])
    xmin, ymin, xmax, ymax = union.bounds
    h = max(xmax - xmin, ymax - ymin, 1e-6) / max(int(params["morph_cells"]) - 9, 8)
    kw = {"cell_size_m": h, "speed_clamp_m": float(params["speed_clamp_cells"]) * h, "keep_fronts": True}
    result = morph_regions(moved, targets, **kw)
    shift = np.mean(pc.translations[inst.source_ids], axis=0) if inst.source_ids else np.zeros(2)
    z = holes.bench_levels_m
    return MorphRecord(
        list(inst.source_ids),
        list(inst.target_ids),
        result,
        (float(shift[0]), float(shift[1])),
        float(z[sel.bench]),
        float(z[sel.bench + 1]),
    )


def _predict(inputs: PipelineInputs, res: PipelineResult) -> list:
    """The selected geozone half a bench and one bench below the deepest bench (core.model.prediction)."""
    from core.model.pipeline import GeozoneModel, ModelParameters, geozone_fields
    from core.model.prediction import predict_geozone

    holes, sel = inputs.holes, inputs.selection
    contours = [c for b in sorted(res.contours) for c in res.contours[b]]
    own = [c for c in contours if c.geozone == sel.geozone]
    if not own or holes.n_benches < 2:
        return []
    fields = geozone_fields(holes, own, ModelParameters().frontier_reach_spacings)
    model = GeozoneModel(sel.geozone, own, [], fields=fields)
    height = float(holes.bench_levels_m[-2] - holes.bench_levels_m[-1])
    deepest = float(holes.bench_levels_m[-1])
    out = predict_geozone(model, [deepest - f * height for f in (0.5, 1.0)], holes.hole_spacing_m)
    return [(sel.geozone, z, poly) for z, region in out.items() for poly in region.geoms]


def _surface(inputs: PipelineInputs, res: PipelineResult):
    """Surface of the selected geozone: its bench sections plus the morph's intermediate fronts."""
    from core.model.surfaces import surface_from_sections

    holes, sel = inputs.holes, inputs.selection
    sections = []
    for b in range(holes.n_benches):
        cs = res.geozone_contours(sel.geozone, b)
        region = shapely.union_all([c.polygon for c in cs]) if cs else shapely.Polygon()
        sections.append((float(holes.bench_levels_m[b]), region))
    m = res.morph
    if m is not None and m.result is not None and len(getattr(m.result, "fronts", [])) > 2:
        # the selected instance's fronts between the pair, moved back from the aligned frame
        times = np.asarray(m.result.times, float)
        t_end = times[-1] if times[-1] > 0 else 1.0
        for f in (0.25, 0.5, 0.75):
            i = int(np.argmin(np.abs(times / t_end - f)))
            front = affinity.translate(m.result.fronts[i], -(1 - f) * m.shift_m[0], -(1 - f) * m.shift_m[1])
            z = m.z_from_m + f * (m.z_to_m - m.z_from_m)
            others = [
                c.polygon for k, c in enumerate(res.geozone_contours(sel.geozone, sel.bench)) if k not in m.source_ids
            ]
            # other components keep their upper-bench section half-way down
            sections.append((z, shapely.union_all([front, *others]) if others else front))
    if sum(not r.is_empty for _, r in sections) == 0:
        return None
    bounds = np.array([r.bounds for _, r in sections if not r.is_empty])
    span = max(bounds[:, 2].max() - bounds[:, 0].min(), bounds[:, 3].max() - bounds[:, 1].min())
    cell = span / max(int(inputs.params["surface_cells"]) - 7, 8)
    return surface_from_sections(sections, cell_size_m=cell)


# ---------------------------------------------------------------------------
# the model


def load_holes(source=None) -> Blastholes:
    """Blastholes from a path, a ``Blastholes``, or the bundled demo (``None``)."""
    if isinstance(source, Blastholes):
        return source
    if source is None or str(source) == "demo":
        from core.synthetic.blobs import demo_dataset

        _, table = demo_dataset()
        return blastholes_from_table(table, source="demo")
    return read_blastholes(source)


class ViewerModel:
    """State of a viewing session; observers hear ``what`` ("result", "selection", "overrides", "dirty")."""

    def __init__(self, holes: Blastholes | str | Path | None = None, *, selection: Selection | None = None):
        self.holes = load_holes(holes)
        self.input_path: str | None = None if not isinstance(holes, (str, Path)) else str(holes)
        self.params = default_parameters()
        zones = self.holes.geozones
        default_zone = next((g for g in zones if g != zones[0]), zones[0]) if len(zones) > 1 else zones[0]
        self.selection = selection or Selection(default_zone, 0, 0)
        self.vertical_exaggeration = 2.0
        self.overrides: list = []  # core.io.project.AlignmentOverride
        self._undo: list[list] = []
        self.result: PipelineResult = PipelineResult()
        self.dirty = False
        self.project_path: str | None = None
        self._listeners: list[Callable[[str], None]] = []

    # -- observers -----------------------------------------------------------
    def connect(self, cb: Callable[[str], None]) -> None:
        self._listeners.append(cb)

    def _emit(self, what: str) -> None:
        for cb in list(self._listeners):
            cb(what)

    def _set_dirty(self) -> None:
        self.dirty = True
        self._emit("dirty")

    # -- inputs for a run ------------------------------------------------------
    def source_z_input(self) -> float:
        return float(self.holes.bench_z_input(self.selection.bench))

    def overrides_here(self) -> tuple[dict, set, set]:
        """Locked translations (metres), forced and forbidden pairs of the selected bench pair."""
        from core.io.project import Project, overrides_for

        locked_in, forced, forbidden = overrides_for(
            Project(overrides=self.overrides), self.selection.geozone, self.source_z_input()
        )
        mpu = self.holes.frame.metres_per_unit
        locked = {s: (t[0] * mpu, t[1] * mpu) for s, t in locked_in.items()}
        return locked, forced, forbidden

    def inputs(self) -> PipelineInputs:
        locked, forced, forbidden = self.overrides_here()
        return PipelineInputs(
            self.holes, dict(self.params), self.selection, locked, frozenset(forced), frozenset(forbidden)
        )

    def run(
        self,
        from_stage: str = "boundary",
        cancelled=lambda: False,
        progress: Callable[[str, float], None] | None = None,
        until: str = "surface",
    ) -> PipelineResult:
        """Run synchronously (screenshots, tests); the window uses a worker with :func:`compute`."""
        for msg, frac, res in compute(self.inputs(), self.result, from_stage, cancelled, until):
            self.set_result(res)
            if progress:
                progress(msg, frac)
        return self.result

    def set_result(self, result: PipelineResult) -> None:
        self.result = result
        self._emit("result")

    # -- parameters and selection ------------------------------------------------
    def set_param(self, name: str, value) -> str:
        """Set a parameter; returns the stage to re-run from."""
        spec = PARAM_BY_NAME[name]
        value = int(round(value)) if spec.integer else float(value)
        value = type(value)(min(max(value, spec.minimum), spec.maximum))
        if self.params.get(name) != value:
            self.params[name] = value
            self._set_dirty()
        return spec.stage

    def select(self, geozone: str | None = None, bench: int | None = None, component: int | None = None) -> str | None:
        """Change the selection; returns the stage to re-run from (or ``None``)."""
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
        if sel == old:
            return None
        self.selection = sel
        self._emit("selection")
        if sel.bench != old.bench:
            return "boundary"  # fields of the new bench are needed
        if sel.geozone != old.geozone:
            return "boundary"
        return "morph"

    # -- manual alignment ------------------------------------------------------------
    def _override(self, create: bool = True):
        from core.io.project import AlignmentOverride, _same_z

        sel, z = self.selection, self.source_z_input()
        for o in self.overrides:
            if o.geozone == sel.geozone and o.source == sel.component and _same_z(o.source_z, z):
                return o
        if not create:
            return None
        o = AlignmentOverride(sel.geozone, z, sel.component)
        self.overrides.append(o)
        return o

    def _push_undo(self) -> None:
        self._undo.append(copy.deepcopy(self.overrides))
        del self._undo[:-50]

    def current_translation_m(self) -> tuple[float, float] | None:
        pc = self.result.correspondence
        if pc is None or self.selection.component >= len(pc.translations):
            return None
        t = pc.translations[self.selection.component]
        return float(t[0]), float(t[1])

    def set_translation(self, dx_m: float, dy_m: float) -> str:
        """Lock the selected source's translation to ``(dx_m, dy_m)`` metres; returns the stage to re-run."""
        self._push_undo()
        mpu = self.holes.frame.metres_per_unit
        self._override().translation = (float(dx_m) / mpu, float(dy_m) / mpu)
        self._changed_overrides()
        return "correspondence"

    def nudge(self, ddx_m: float, ddy_m: float) -> str:
        """Move the selected source by ``(ddx_m, ddy_m)`` from its current translation."""
        cur = self.current_translation_m() or (0.0, 0.0)
        return self.set_translation(cur[0] + ddx_m, cur[1] + ddy_m)

    def lock_current(self) -> str:
        """Lock the selected source at its current (automatic) translation."""
        cur = self.current_translation_m() or (0.0, 0.0)
        return self.set_translation(*cur)

    def set_association(self, target: int, flag: bool | None) -> str:
        """Force (``True``), forbid (``False``) or reset (``None``) association with ``target``."""
        self._push_undo()
        o = self._override()
        if flag is None:
            o.associate.pop(int(target), None)
        else:
            o.associate[int(target)] = bool(flag)
        self._changed_overrides()
        return "correspondence"

    def clear_override(self) -> str:
        o = self._override(create=False)
        if o is not None:
            self._push_undo()
            self.overrides.remove(o)
            self._changed_overrides()
        return "correspondence"

    def _changed_overrides(self) -> None:
        self.overrides = [o for o in self.overrides if o.translation is not None or o.associate]
        self._set_dirty()
        self._emit("overrides")

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    def undo(self) -> str | None:
        """Restore the overrides before the last change; returns the stage to re-run."""
        if not self._undo:
            return None
        self.overrides = self._undo.pop()
        self._set_dirty()
        self._emit("overrides")
        return "correspondence"

    # -- project file ------------------------------------------------------------------
    def to_project(self):
        from core.io.project import Project

        params = dict(self.params)
        params["viewer"] = {
            "geozone": self.selection.geozone,
            "bench": self.selection.bench,
            "component": self.selection.component,
            "vertical_exaggeration": self.vertical_exaggeration,
        }
        return Project(parameters=params, overrides=copy.deepcopy(self.overrides), input_path=self.input_path)

    def save_project(self, path: str | Path) -> None:
        from core.io.project import save_project

        save_project(self.to_project(), path)
        self.project_path = str(path)
        self.dirty = False
        self._emit("dirty")

    def load_project(self, path: str | Path) -> None:
        """Apply a project file's parameters, selection and overrides (the input is not reloaded)."""
        from core.io.project import load_project

        proj = load_project(path)
        params = dict(proj.parameters)
        viewer = params.pop("viewer", {}) or {}
        for name, value in params.items():
            spec = PARAM_BY_NAME.get(name)
            if spec is None:
                warnings.warn(
                    f"project parameter {name!r} is not a viewer parameter; not used", BGMWarning, stacklevel=2
                )
            elif not spec.minimum <= value <= spec.maximum:  # a finite number: load_project checked
                raise BGMInputError(
                    f"project file {path}: parameter {name} must be between {spec.minimum:g} and {spec.maximum:g}, "
                    f"got {value!r}"
                )
            else:
                self.params[name] = int(round(value)) if spec.integer else float(value)
        if isinstance(viewer, dict):
            with contextlib.suppress(ValueError, TypeError):
                self.select(viewer.get("geozone"), viewer.get("bench"), viewer.get("component"))
            ve = viewer.get("vertical_exaggeration")
            if isinstance(ve, (int, float)) and ve > 0:
                self.vertical_exaggeration = float(ve)
        self.overrides = list(proj.overrides)
        self._undo.clear()
        self.project_path = str(path)
        self.dirty = False
        self._emit("overrides")
        self._emit("dirty")
