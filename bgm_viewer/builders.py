"""Layers of the standard scene, fed from a :class:`~bgm_viewer.model.PipelineResult`.

Layer names (what ``--layers`` and the layer panel use): see
:data:`bgm_viewer.layer_names.LAYER_NAMES`.
"""

from __future__ import annotations

import numpy as np

from core.model.surfaces import faces_drilled_by

from . import _vtkenv  # noqa: F401
from .layer_names import DEFAULT_VISIBLE, LAYER_NAMES, parse_layers  # noqa: F401 - long imported from here
from .layers import (
    BlastholesLayer,
    ContoursLayer,
    EdgeMapLayer,
    GVFLayer,
    Layer,
    SelectedComponentsLayer,
    SnakeLayer,
    SurfaceLayer,
    TrajectoriesLayer,
    WavefrontLayer,
)
from .model import PipelineResult, Selection
from .palette import geozone_colours
from .sampling_layers import NextBench, SuggestedHolesLayer, UncertaintyLayer
from .scene import Scene


def make_layers(holes, result: PipelineResult, selection: Selection, predicted=(), deferred=False) -> list[Layer]:
    """All standard layers for ``result`` (empty layers where a stage has not run).

    ``predicted``: ``(geozone, z_m, polygon)`` of contours predicted below the deepest bench
    (from a core prediction stage, when there is one). ``deferred``: the next bench's band and
    suggestions are left for the window's worker thread to compute (see :class:`NextBench`).
    """
    colours = geozone_colours(holes.geozones)
    contours = [c for cs in result.contours.values() for c in cs]
    layers: list[Layer] = [
        BlastholesLayer.from_blastholes(holes, contours, colours),
        ContoursLayer.from_contours(contours, colours),
    ]
    sel = result.selected_contour(selection)
    f = sel.fields if sel is not None else None
    z = float(holes.bench_levels_m[selection.bench])
    layers.append(EdgeMapLayer(f.grid if f else None, f.edge_map if f else None, z))
    layers.append(GVFLayer(f.grid if f else None, f.gvf if f else None, z))
    layers.append(SnakeLayer(f.snake_history_m if f else [], z))
    m = result.morph
    if m is not None and m.result is not None:
        layers.append(WavefrontLayer(m.result.fronts, m.result.times, m.z_from_m, m.z_to_m, m.shift_m))
        layers.append(TrajectoriesLayer(m.result.trajectories, m.z_from_m, m.z_to_m, m.shift_m))
    else:
        layers.append(WavefrontLayer())
        layers.append(TrajectoriesLayer())
    predicted = list(predicted) or list(getattr(result, "predicted", []))
    layers.append(ContoursLayer(predicted, colours, name="predicted contours", predicted=True, line_width=2.0))
    surfaces = sorted(result.surfaces.items())

    def drilled() -> list[np.ndarray]:  # when the layer is first drawn: a refresh may keep the old one
        return [faces_drilled_by(holes, mesh) for _, mesh in surfaces]

    layers.append(SurfaceLayer.from_trimesh(surfaces, colours, drilled=drilled))
    layers.append(selected_components_layer(result))
    # computed by core when one of its layers is first drawn, or by the window's worker thread (deferred)
    next_bench = NextBench(holes, result.model, session=result.session, deferred=deferred)
    layers += [UncertaintyLayer(next_bench), SuggestedHolesLayer(next_bench)]
    return layers


def selected_components_layer(result: PipelineResult) -> SelectedComponentsLayer:
    """The selected source component(s) and the target(s) they morph into (see :class:`SelectedComponentsLayer`)."""
    m, pair = result.morph, result.pair
    items: list[tuple[str, float, object]] = []
    if m is not None and pair is not None:
        for role, ids, contours in (("source", m.source_ids, pair.sources), ("target", m.target_ids, pair.targets)):
            items.extend((role, contours[i].bench_z_m, contours[i].polygon) for i in ids if 0 <= i < len(contours))
    return SelectedComponentsLayer(items)


def build_scene(
    holes,
    result: PipelineResult,
    selection: Selection,
    *,
    visible=None,
    vertical_exaggeration: float = 2.0,
    predicted=(),
    deferred: bool = False,
) -> Scene:
    """A :class:`Scene` of the standard layers with ``visible`` (names) shown (``deferred``: see :func:`make_layers`)."""
    scene = Scene(
        make_layers(holes, result, selection, predicted, deferred),
        vertical_exaggeration=vertical_exaggeration,
        z_ref=float(np.max(holes.bench_levels_m)),
        frame=holes.frame,
    )
    scene.set_visible_only(parse_layers(visible))
    return scene


def _changed(result: PipelineResult, previous: PipelineResult | None, selection: Selection) -> set[str]:
    """Names of the layers whose data differ between two results (all when unknown)."""
    if previous is None:
        return set(LAYER_NAMES)
    out = set()
    if result.contours.keys() != previous.contours.keys() or any(
        result.contours[b] is not previous.contours.get(b) for b in result.contours
    ):
        out |= {"contours", "predicted contours"}
        bh = [
            np.sort(np.concatenate([c.boundary_holes for c in cs] or [np.zeros(0, int)]))
            for r in (result, previous)
            for cs in [[c for v in r.contours.values() for c in v]]
        ]
        if len(bh[0]) != len(bh[1]) or not np.array_equal(bh[0], bh[1]):
            out.add("blastholes")
    # The fields on screen are those of the component ``previous`` was drawn for. Asked of ``previous`` with the
    # new selection, another component of the same bench (one object in both results) seemed unchanged: the
    # edge map, GVF and snake of the component selected before stayed on screen under the new one.
    drawn = previous.selection if previous.selection is not None else selection
    if result.selected_contour(selection) is not previous.selected_contour(drawn):
        out |= {"edge map", "GVF", "snake"}
    if result.morph is not previous.morph:
        out |= {"wavefront", "trajectories", "selected components"}
    if result.predicted is not previous.predicted:
        out.add("predicted contours")
    if result.surfaces.keys() != previous.surfaces.keys() or any(
        m is not previous.surfaces.get(g) for g, m in result.surfaces.items()
    ):
        out.add("surfaces")
    if result.model is not previous.model:
        out |= {"uncertainty", "suggested holes"}
    return out


def refresh_scene(
    scene: Scene,
    holes,
    result: PipelineResult,
    selection: Selection,
    predicted=(),
    previous: PipelineResult | None = None,
    deferred: bool = False,
) -> None:
    """Replace the data of the scene's layers, keeping visibility, opacity and frames where possible.

    With ``previous`` (the result on screen), only layers whose data changed are rebuilt.
    ``deferred``: see :func:`make_layers`.
    """
    changed = _changed(result, previous, selection)
    for layer in make_layers(holes, result, selection, predicted, deferred):
        if layer.name not in changed and scene.get(layer.name) is not None:
            continue
        old = scene.get(layer.name)
        # a hidden layer's frames are not counted: the suggested holes' are core's suggestions, computed to count
        if old is not None and old.visible and old.n_frames == layer.n_frames and old.n_frames > 1:
            layer.frame = old.frame
        scene.replace(layer)


# ---------------------------------------------------------------------------
# why a layer is empty


def _bench_words(holes, bench: int) -> str:
    return f"bench {holes.bench_z_input(bench):g} {holes.frame.length_unit}"


def _why_no_contour(holes, result: PipelineResult, sel: Selection) -> str:
    """Why the selected component has no contour (and so no edge map, GVF or snake)."""
    if sel.bench not in result.contours:
        return "the selected bench's contours are not extracted yet"
    on_bench = int(np.sum((holes.bench == sel.bench) & (holes.geozone == sel.geozone)))
    where = f"geozone {sel.geozone} on {_bench_words(holes, sel.bench)}"
    if on_bench == 0:
        return f"{where} has no holes: choose another geozone or bench pair"
    n = len(result.sources(sel))
    if n == 0:
        return f"{where} has no component of {result.min_component_holes} or more holes ({on_bench} hole(s) in all)"
    if sel.component >= n:
        return f"{where} has {n} component(s): source component {sel.component} does not exist"
    if _too_small_for_a_snake(result, sel):
        n_holes = len(result.sources(sel)[sel.component].holes)
        return (
            f"source component {sel.component} of {where} ({n_holes} holes) is too small for a snake:"
            " its contour is the outline of its holes, with no edge map, GVF or snake"
        )
    return f"the fields of source component {sel.component} of {where} are not computed yet"


def _too_small_for_a_snake(result: PipelineResult, sel: Selection) -> bool:
    """Whether the selected component has no fields because extraction ran no snake on it (not because they are
    still to come).

    A part too small for a snake keeps its outline and gets no edge map, GVF or snake
    (:func:`core.extraction.contours.snake_contour`). The bench's fields are computed once
    another component of the geozone there has them, or the run is done (it computes them
    before the other benches): "not computed yet" then stayed in the status bar for good.
    """
    contour = result.selected_contour(sel)
    if contour is None or contour.fields is not None:
        return False
    own = [c for c in result.contours.get(sel.bench, []) if c.geozone == sel.geozone]
    return result.complete or any(c.fields is not None for c in own)


#: Why nothing between benches is drawn for an input of one bench (it never will be: no bench below).
ONE_BENCH = "the input has one bench: there is no bench below it to model"


def _why_no_morph(holes, result: PipelineResult, sel: Selection) -> str:
    if result.selected_contour(sel) is None:
        return _why_no_contour(holes, result, sel)
    if holes.n_benches < 2:
        return ONE_BENCH
    if "correspondence" in result.errors or "morph" in result.errors:
        return result.errors.get("morph") or result.errors["correspondence"]
    if result.pair is None or result.correspondence is None:
        return "the selected bench pair is not corresponded yet"
    below = _bench_words(holes, sel.bench + 1)
    return f"source component {sel.component} has no target on {below}: it ends between the benches"


def _why_no_model_output(stage: str):
    def why(holes, result: PipelineResult, sel: Selection) -> str:
        if stage in result.errors or "model" in result.errors:
            return result.errors.get(stage) or result.errors["model"]
        if holes.n_benches < 2:
            return ONE_BENCH
        if not result.complete:
            return f"the {stage} is not computed yet"
        if result.model is None or not result.model.pairs:
            return f"geozone {sel.geozone} is never in a component of {result.min_component_holes} or more holes on two benches"
        return f"the {stage} of geozone {sel.geozone} is empty"

    return why


#: ``layer name -> why(holes, result, selection)``: what to tell the user when that layer draws nothing.
EMPTY_REASONS = {
    "contours": lambda holes, result, sel: "no contours are extracted yet",
    "edge map": _why_no_contour,
    "GVF": _why_no_contour,
    "snake": _why_no_contour,
    "wavefront": _why_no_morph,
    "trajectories": _why_no_morph,
    "predicted contours": _why_no_model_output("prediction"),
    "surfaces": _why_no_model_output("surface"),
    "selected components": _why_no_morph,
    "uncertainty": _why_no_model_output("prediction"),
    "suggested holes": _why_no_model_output("prediction"),
}


#: Why a next-bench layer draws nothing yet: the worker thread is computing it.
NEXT_BENCH_PENDING = "the next bench's band and suggested holes are being computed"

#: Layers that leave out the geozones and benches the Geozones and Benches panels hide.
HIDEABLE = ("blastholes", "contours", "predicted contours", "surfaces", "selected components")
HIDDEN = "what it would draw is hidden: tick its geozones (Geozones) or benches (Benches and section)"


def empty_layer_reasons(
    scene: Scene, holes, result: PipelineResult, selection: Selection, is_empty=None
) -> dict[str, str]:
    """``{layer name: why it draws nothing}`` for the visible layers of ``scene`` that are empty.

    ``is_empty(layer)`` says whether a layer draws nothing (default: build it and see).
    """
    from dataclasses import replace

    is_empty = is_empty or (lambda layer: layer.is_empty)
    unhidden = replace(scene.view, hidden_geozones=frozenset(), hidden_benches_m=frozenset())
    out = {}
    for layer in scene.layers:
        if layer.visible and is_empty(layer):
            # with every geozone unticked the status bar said "no contours are extracted yet"
            if layer.name in HIDEABLE and unhidden != scene.view and layer.build(unhidden):
                out[layer.name] = HIDDEN
                continue
            nb = getattr(layer, "next_bench", None)
            if nb is not None and (nb.pending or nb.error):  # not "empty": computing, or failed
                pending = STOPPED if result.stopped else NEXT_BENCH_PENDING
                out[layer.name] = f"the next bench failed: {nb.error}" if nb.error else pending
                continue
            why = EMPTY_REASONS.get(layer.name)
            out[layer.name] = why(holes, result, selection) if why else "nothing to draw for this selection"
            if result.stopped and out[layer.name].endswith(" yet"):
                out[layer.name] = STOPPED  # "not computed yet" promised what no run is computing
    return out


#: Why a layer draws nothing after the run that was to compute it was stopped.
STOPPED = "the run was stopped before it was computed: Run > Run again (F5) or change a setting"
