"""Manual alignment overrides follow their components when a parameter renumbers them (no screen, no Qt).

An override names its source component by number. A slider that changes
extraction renumbers components: the override must then move to the
component at its place, or be dropped with a note naming it, never be
applied to whichever component now has its number.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from shapely.geometry import Point, box

from bgm_viewer.alignment import PlacedOverride, not_whole, relocate_overrides, same_place
from bgm_viewer.model import STEPS
from core.io.project import AlignmentOverride

Z = 685.0


def _blob(x: float, y: float, r: float = 5.0):
    return Point(x, y).buffer(r)


def _placed(source: int, sources, targets, translation=(1.0, 2.0), associate=None) -> PlacedOverride:
    o = PlacedOverride("ore", Z, source, translation, dict(associate or {}))
    o.place(sources, targets)
    return o


def _pair(sources, targets):
    return lambda geozone, z: (sources, targets) if geozone == "ore" and z == Z else None


def test_an_override_follows_its_renumbered_source_and_targets():
    west, east = _blob(0, 0), _blob(50, 0)
    low_west, low_east = _blob(1, 0), _blob(51, 0)
    o = _placed(1, [west, east], [low_west, low_east], associate={1: True, 0: False})  # the east one
    # east grew and is now number 0; the targets swapped too
    out, notes = relocate_overrides([o], _pair([_blob(50, 0, 9.0), west], [low_east, low_west]), unit="m")
    assert [(p.source, p.associate, p.translation) for p in out] == [(0, {0: True, 1: False}, (1.0, 2.0))]
    assert len(notes) == 1 and "geozone ore source 1 on bench 685 m" in notes[0] and "source 1 is 0" in notes[0]
    assert not_whole(notes) == []  # moved whole
    assert o.source == 1  # the input is not modified


def test_an_override_whose_component_went_is_dropped_with_a_note():
    west, east = _blob(0, 0), _blob(50, 0)
    o = _placed(1, [west, east], [west])
    # the east component is gone: number 1 is now another component, which must not take the override
    out, notes = relocate_overrides([o], _pair([west, _blob(0, 40)], [west]), unit="ft")
    assert out == []
    assert len(notes) == 1 and "source 1 on bench 685 ft was dropped" in notes[0]
    assert not_whole(notes) == notes


def test_an_override_of_a_split_or_merged_component_is_dropped():
    whole = box(0, 0, 40, 10)
    halves = [box(0, 0, 18, 10), box(22, 0, 40, 10)]
    out, notes = relocate_overrides([_placed(0, [whole], [whole])], _pair(halves, [whole]), unit="m")
    assert out == [] and "was dropped" in notes[0]
    # two overrides whose sources merged into one component: neither can be told from the other
    a, b = _placed(0, halves, [whole]), _placed(1, halves, [whole], translation=(3.0, 4.0))
    out, notes = relocate_overrides([a, b], _pair([whole], [whole]), unit="m")
    assert out == [] and "2 alignment overrides of geozone ore on bench 685 m were dropped" in notes[-1]
    assert not_whole(notes) == notes[-1:]  # not the note that one of them first moved onto the other's number


def test_a_lost_target_is_forgotten_and_the_rest_kept():
    src, t0, t1 = _blob(0, 0), _blob(0, 1), _blob(60, 0)
    o = _placed(0, [src], [t0, t1], translation=None, associate={0: True, 1: False})
    out, notes = relocate_overrides([o], _pair([src], [t0]), unit="m")
    assert [(p.source, p.associate) for p in out] == [(0, {0: True})]
    assert len(notes) == 1 and "no longer names target 1" in notes[0]
    assert not_whole(notes) == notes  # kept, but not whole


def test_unchanged_unplaced_and_elsewhere_overrides_are_kept_silently():
    west, east = _blob(0, 0), _blob(50, 0)
    placed = _placed(1, [west, east], [west])
    from_file = AlignmentOverride("ore", Z, 0, (1.0, 1.0))  # a project's: placed where its number says
    other_bench = AlignmentOverride("ore", 675.0, 3, (1.0, 1.0))  # its pair is not at hand
    out, notes = relocate_overrides([placed, from_file, other_bench], _pair([west, east], [west]), unit="m")
    assert notes == []
    assert [(o.source_z, o.source) for o in out] == [(Z, 1), (Z, 0), (675.0, 3)]
    assert out[1].source_outline is west and out[2].source_outline is None
    assert same_place(east, [west, east]) == 1 and same_place(box(100, 100, 101, 101), [west, east]) is None


# ---------------------------------------------------------------------------- through the viewer's model


def test_alignment_messages_give_the_elevations_in_the_inputs_unit(tmp_path):
    """A feet input was told "no bench pair from bench 2247 to align": feet or metres, not said."""
    from bgm_viewer.model import ViewerModel
    from bgm_viewer.testing import small_holes
    from core.errors import BGMWarning
    from core.io.project import Project, check_project

    holes = small_holes(unit="ft")
    model = ViewerModel(holes)  # not run: the selected pair is not computed
    z = f"{holes.bench_z_input(model.selection.bench):g}"
    with pytest.raises(ValueError, match=f"from bench {z} ft to align"):
        model.set_translation(1.0, 1.0)
    project = Project(overrides=[AlignmentOverride(holes.geozones[0], 1.5, 0, (1.0, 1.0))])
    with pytest.warns(BGMWarning, match=r"at 1\.5 ft, source 0.*upper bench at 1\.5 ft \(upper benches in ft"):
        check_project(project, holes)


@pytest.fixture
def model():
    from bgm_viewer.testing import small_model

    return small_model(until="correspondence")


def _run(model, step):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(step, until="correspondence")


def test_a_slider_that_removes_the_overridden_component_drops_the_override_and_says_so(model):
    """g2 has one component of 14 holes on the top bench: raising min_component_holes to 20 takes it away."""
    model.select("g2", 0, 0)
    _run(model, "contours")
    assert [len(c.holes) for c in model.result.pair.sources] == [14]
    model.set_translation(2.0, -1.0)
    _run(model, "correspondence")
    assert len(model.overrides) == 1
    step = model.set_param("min_component_holes", 20)
    _run(model, step)
    assert model.overrides == [], "the override still names a component that is gone"
    assert any("geozone g2 source 0" in n and "dropped" in n for n in model.override_notes), model.override_notes
    assert "g2 source 0" in model.result.errors.get("alignment overrides", "")  # the window's status bar shows these
    assert model.can_undo and model.dirty


def test_a_project_is_not_saved_before_a_run_has_moved_the_overrides_to_the_new_parameters(model, tmp_path):
    """Ctrl+S (or Save when closing) right after a slider move wrote the new parameters with the overrides
    numbered as before them: here an override of a component the new parameters no longer model, which
    bgm build --project then refused ("names source component 0, but the upper bench has no component")."""
    from core.io.project import load_project

    model.select("g2", 0, 0)
    _run(model, "contours")
    model.set_translation(2.0, -1.0)
    _run(model, "correspondence")
    step = model.set_param("min_component_holes", 20)
    path = tmp_path / "p.json"
    with pytest.raises(ValueError, match="save once the run is done"):
        model.save_project(path)
    assert not path.exists() and model.dirty
    _run(model, step)
    model.save_project(path)
    saved = load_project(path)
    assert saved.parameters["min_component_holes"] == 20 and saved.overrides == []


def test_an_override_whose_number_went_stale_is_applied_to_its_own_component(model):
    """The run finds the component at the override's place before any correspondence uses it."""
    model.set_translation(4.0, 3.0)
    model.overrides[0].source = 7  # as if extraction had renumbered the components under it
    _run(model, "correspondence")
    assert [x.source for x in model.overrides] == [0]
    assert any("source 7 is 0" in n for n in model.override_notes), model.override_notes
    assert not model.result.errors.get("correspondence")
    t = model.result.correspondence.translations[0]
    np.testing.assert_allclose(t, (4.0, 3.0), atol=1e-9)  # the locked translation, on component 0


def _override_dropped_by_two_sliders(model):
    """An override on g2, then two sliders moved before one run, which drops it; the parameters before."""
    model.select("g2", 0, 0)
    _run(model, "contours")
    model.set_translation(2.0, -1.0)
    _run(model, "correspondence")
    before = model.params
    model.set_param("snake_max_iterations", 10)
    _run(model, min(model.set_param("min_component_holes", 20), "snake", key=STEPS.index))
    return before


def test_undo_of_an_override_a_slider_dropped_brings_back_the_parameters_too(model):
    """Undo brought the dropped override back under the slider values that drop it: the next run dropped it again.

    Undo now also brings back the parameters it was placed under (two sliders moved before the
    run here), and re-runs from the earliest step they affect, so the override is applied again.
    """
    before = _override_dropped_by_two_sliders(model)
    assert model.overrides == []  # dropped: g2's one component has 14 holes

    _run(model, model.undo())
    assert [(o.geozone, o.source, o.translation) for o in model.overrides] == [("g2", 0, (2.0, -1.0))]
    assert model.params == before
    assert "alignment overrides" not in model.result.errors
    np.testing.assert_allclose(model.result.correspondence.translations[0], (2.0, -1.0), atol=1e-9)
    assert any("Undo" in n and "smallest modelled component 3" in n for n in model.override_notes), model.override_notes
    project = model.to_project()  # what Save writes
    assert len(project.overrides) == 1 and "min_component_holes" not in project.parameters


def test_undo_returns_the_earliest_step_of_the_parameters_it_brings_back(model):
    """The sliders follow (``params_changed``); an edit's undo leaves the parameters alone, as before."""
    before = _override_dropped_by_two_sliders(model)
    shown = []
    model.params_changed.connect(lambda: shown.append(model.param("min_component_holes")))
    assert model.undo() == "snake"  # snake_max_iterations's step, before min_component_holes's
    assert shown == [before.min_component_holes]
    _run(model, "snake")
    model.nudge(1.0, 0.0)
    assert model.undo() == "correspondence" and model.params == before and shown == [3]


def test_redo_brings_back_what_undo_took_back_and_a_new_change_empties_it(model):
    """There was no Redo: an Undo pressed once too often lost the alignment it undid, to be made again by hand."""
    auto = model.current_translation_m()
    _run(model, model.set_translation(auto[0] + 4.0, auto[1] - 2.0))
    _run(model, model.set_association(0, True))
    made = [(o.source, o.translation, dict(o.associate)) for o in model.overrides]
    _run(model, model.undo())
    _run(model, model.undo())
    assert model.overrides == [] and model.can_redo
    np.testing.assert_allclose(model.current_translation_m(), auto, atol=1e-9)
    _run(model, model.redo())
    np.testing.assert_allclose(model.current_translation_m(), (auto[0] + 4.0, auto[1] - 2.0), atol=1e-9)
    assert model.redo() == "correspondence" and not model.can_redo
    assert [(o.source, o.translation, dict(o.associate)) for o in model.overrides] == made
    assert model.dirty and model.redo() is None  # nothing more to redo
    model.undo()
    model.nudge(1.0, 0.0)  # a new change: what was undone before it cannot be redone on top of it
    assert not model.can_redo and model.redo() is None
    model.undo()
    model.set_param("snake_max_iterations", 10)  # the parameters the undone overrides were placed under changed
    assert not model.can_redo


def test_redo_of_an_undo_that_brought_back_the_parameters_sets_them_as_they_were(model):
    """Undo of an override a slider dropped brings back the slider values it was placed under; Redo goes back to
    the slider values the geologist chose, the override dropped, and Undo again works as the first time."""
    before = _override_dropped_by_two_sliders(model)
    chosen = model.params
    _run(model, model.undo())
    assert model.params == before and len(model.overrides) == 1
    step = model.redo()
    assert step == "snake" and model.params == chosen and model.overrides == []
    assert any("Redo" in n and "smallest modelled component 20" in n for n in model.override_notes), (
        model.override_notes
    )
    _run(model, step)
    assert model.overrides == [] and model.to_project().parameters["min_component_holes"] == 20
    _run(model, model.undo())
    assert model.params == before and [(o.source, o.translation) for o in model.overrides] == [(0, (2.0, -1.0))]
    np.testing.assert_allclose(model.result.correspondence.translations[0], (2.0, -1.0), atol=1e-9)


def test_a_parameter_that_does_not_exist_is_refused_at_once_naming_it_and_the_parameters():
    """``set_param("gvf_muu", ...)`` set nothing and raised a bare ``KeyError`` after; a project saved
    between the two kept a change the geologist thought was made."""
    from bgm_viewer.model import ViewerModel
    from bgm_viewer.testing import small_holes
    from core.model.parameters import PARAMETER

    model = ViewerModel(small_holes(3))
    before, dirty = model.params, model.dirty
    with pytest.raises(ValueError) as raised:
        model.set_param("gvf_muu", 0.12)
    message = str(raised.value)
    assert not isinstance(raised.value, KeyError)
    assert "'gvf_muu'" in message and all(name in message for name in PARAMETER)
    assert model.params == before and model.dirty == dirty
    assert model.set_param("gvf_mu", 0.12) == "snake" and model.param("gvf_mu") == 0.12


def _two_bodies_model():
    """A model of :func:`bgm_viewer.testing.two_bodies_holes`, the corner body of g1 (component 1) selected."""
    from bgm_viewer.model import ViewerModel
    from bgm_viewer.testing import two_bodies_holes

    model = ViewerModel(two_bodies_holes(), cache=False)
    model.select("g1", 0, 1)
    _run(model, "contours")
    return model


def test_the_selection_follows_the_corrected_component_when_it_is_renumbered():
    """The geologist corrects the small corner body, then a slider renumbers the components: the override
    followed its body, but the selection stayed on the old number, now the main body. The panel showed the
    main body's translation, and the next nudge overrode the main body instead of the corner one."""
    model = _two_bodies_model()
    assert len(model.result.pair.sources) == 2
    model.set_translation(3.0, -2.0)  # the corner body, component 1
    _run(model, "correspondence")
    # As if a parameter had renumbered the components: the corner body was number 0 and selected as such.
    model.select(component=0)
    model.overrides[0].source = 0
    _run(model, "correspondence")

    assert model.overrides[0].source == 1  # the override followed its body
    assert model.selection.component == 1, "the selection stayed on another body"
    np.testing.assert_allclose(model.translation_m(), (3.0, -2.0), atol=1e-9)
    model.nudge(1.0, 0.0)
    _run(model, "correspondence")
    assert [(o.source, o.translation) for o in model.overrides] == [(1, (4.0, -2.0))]
    np.testing.assert_allclose(model.result.correspondence.translations[1], (4.0, -2.0), atol=1e-9)


def _three_bodies_holes():
    """:func:`bgm_viewer.testing.small_holes`' mine with two more g1 bodies on the top bench pair: a large one near
    the main body (B), one g1 hole in two on a ring around it, and a small one in the opposite corner (C).

    Without isolated holes kept, the contact holes are voted away and B joins the main body: g1's sources are
    [B and main, C]; with them kept (``keep_isolated_holes``), [B, main, C], largest first. Ticking the box
    renumbers C from 1 to 2, and number 1 is then the main body.
    """
    from core.io.blastholes import blastholes_from_table
    from core.synthetic.blobs import make_mine, sample_blastholes

    t = sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    d = np.hypot(t.x - t.x.min() - 25, t.y - t.y.max() + 25)
    t.loc[(d < 20) & (t.geozone == "g0"), "geozone"] = "g1"
    ring = np.flatnonzero((d >= 20) & (d < 23) & (t.geozone == "g0") & (t.z > t.z.max() - 5))
    t.loc[t.index[ring[::2]], "geozone"] = "g1"
    t.loc[(np.hypot(t.x - t.x.max() + 20, t.y - t.y.min() - 20) < 11) & (t.geozone == "g0"), "geozone"] = "g1"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return blastholes_from_table(t, length_unit="m", source="small mine with three g1 bodies")


def test_an_override_opened_from_a_project_stays_on_its_body_when_a_slider_renumbers_before_the_first_run(tmp_path):
    """A project's overrides name components by number; opened, they were placed by those numbers by the first run
    that finished, under whatever parameters it had. Ticking "keep isolated holes" before then (the run of the
    project's parameters cancelled) renumbered g1's sources and C's override landed on the main body. Placed
    under the project's parameters, it follows its body to its new number by its outline, as a slider's run does."""
    from bgm_viewer.model import ViewerModel
    from core.model.pipeline import modelled_contours

    holes = _three_bodies_holes()
    model = ViewerModel(holes, cache=False)
    model.select("g1", 0, 1)
    _run(model, "contours")
    sources = [c.polygon for c in model.result.pair.sources]
    assert len(sources) == 2 and sources[1].centroid.x > 40.0  # C, in the corner
    model.set_translation(3.0, -2.0)
    _run(model, "correspondence")
    path = tmp_path / "p.bgm.json"
    model.save_project(path)

    opened = ViewerModel(holes, cache=False)
    opened.load_project(path)
    step = opened.set_param("keep_isolated_holes", True)  # before any run under the project's parameters ends
    _run(opened, step)
    now = modelled_contours(opened.result.contours[0], "g1", 0, opened.params.min_component_holes)
    assert len(now) == 3 and now[2].polygon.centroid.x > 40.0  # C renumbered 1 -> 2; 1 is the main body
    assert [(o.source, o.translation) for o in opened.overrides] == [(2, (3.0, -2.0))], "on another body"
    assert any("source 1 is now 2" in n or "is 2" in n for n in opened.override_notes), opened.override_notes
    np.testing.assert_allclose(opened.result.correspondence.translations[2], (3.0, -2.0), atol=1e-9)


def _run_until(model, step: str, done) -> None:
    """Take a run's results from ``step`` until ``done()``, then stop taking them (the run is then stopped)."""
    from bgm_viewer.model import compute

    steps = compute(model.inputs(), model.result, step, until="correspondence")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _, _, result in steps:
            model.set_result(result)
            if done():
                break
    steps.close()


def test_stop_gives_the_overrides_back_the_numbers_of_the_last_finished_run():
    """A slider's run moves the overrides to their renumbered components as soon as it has traced the selected
    bench pair (and the selection with the corrected one). Stopped then, the picture went back to the last finished
    run but the overrides kept the stopped run's numbers: the panel showed C's lock on the main body's number,
    and Undo undid the slider instead of the last edit. Stop now gives them back the picture's numbers."""
    from bgm_viewer.model import ViewerModel

    model = ViewerModel(_three_bodies_holes(), cache=False)
    model.select("g1", 0, 1)
    _run(model, "contours")
    model.set_translation(3.0, -2.0)  # C, component 1 under the default parameters
    _run(model, "correspondence")
    finished = model.result
    assert finished.complete and finished.pair.sources[1].polygon.centroid.x > 40.0

    step = model.set_param("keep_isolated_holes", True)  # renumbers C 1 -> 2 (see _three_bodies_holes)
    _run_until(model, step, lambda: model.overrides[0].source == 2)
    assert (model.overrides[0].source, model.selection.component) == (2, 2)  # the stopped run's numbers

    model.stop()
    assert [(o.source, o.translation) for o in model.overrides] == [(1, (3.0, -2.0))]
    assert model.result.stopped and model.result.pair is finished.pair  # the picture: the last finished run
    assert model.selection.component == 1 and model.override_here() is model.overrides[0]
    assert model.result.selected_contour(model.selection).polygon.centroid.x > 40.0  # C, as the override says
    np.testing.assert_allclose(model.translation_m(), (3.0, -2.0), atol=1e-9)
    assert model.param("keep_isolated_holes") is True  # the slider stays as set
    with pytest.raises(ValueError, match=r"the run was stopped\): run again"):
        model.save_project("never-written.bgm.json")
    model.undo()  # the last edit, the lock, not the stopped run's renumbering
    assert model.overrides == [] and model.param("keep_isolated_holes") is True
    model.redo()

    _run(model, "contours")  # Run again: the overrides follow C to its new number, as the stopped run had
    assert [(o.source, o.translation) for o in model.overrides] == [(2, (3.0, -2.0))]
    assert model.selection.component == 2
    np.testing.assert_allclose(model.result.correspondence.translations[2], (3.0, -2.0), atol=1e-9)


def test_an_alignment_edited_during_a_renumbering_run_follows_its_body_back_when_the_run_is_stopped():
    """An edit made after a slider's run had moved the overrides to its numbers was made on those numbers. Stopped
    then, the picture went back to the last finished run while the edited override kept the stopped run's number:
    C's new shift sat on component 2, which the picture does not have. It now follows C back to number 1."""
    from bgm_viewer.model import ViewerModel

    model = ViewerModel(_three_bodies_holes(), cache=False)
    model.select("g1", 0, 1)
    _run(model, "contours")
    model.set_translation(3.0, -2.0)  # C, component 1 under the default parameters
    _run(model, "correspondence")
    assert len(model.result.pair.sources) == 2

    step = model.set_param("keep_isolated_holes", True)  # renumbers C 1 -> 2 (see _three_bodies_holes)
    _run_until(model, step, lambda: model.overrides[0].source == 2)
    assert model.selection.component == 2
    model.set_translation(5.0, 1.0)  # C again, on the stopped run's number
    assert [(o.source, o.translation) for o in model.overrides] == [(2, (5.0, 1.0))]

    model.stop()
    assert [(o.source, o.translation) for o in model.overrides] == [(1, (5.0, 1.0))]
    assert model.selection.component == 1 and model.override_here() is model.overrides[0]
    assert model.result.selected_contour(model.selection).polygon.centroid.x > 40.0  # C, as the override says
    np.testing.assert_allclose(model.translation_m(), (5.0, 1.0), atol=1e-9)
    model.undo()  # the edit made during the run, on the picture's numbers
    assert [(o.source, o.translation) for o in model.overrides] == [(1, (3.0, -2.0))]
    assert model.param("keep_isolated_holes") is True
    model.redo()

    _run(model, "contours")  # Run again: C's override follows it to its new number
    assert [(o.source, o.translation) for o in model.overrides] == [(2, (5.0, 1.0))]
    np.testing.assert_allclose(model.result.correspondence.translations[2], (5.0, 1.0), atol=1e-9)


def test_an_edit_naming_a_target_the_picture_lacks_keeps_the_stopped_runs_numbers_and_says_so():
    """With isolated holes kept, single g1 holes on the target bench are targets of their own; the picture, traced
    without them, has none there. C's override edited during the stopped run to associate one of them cannot follow
    C back whole: moved, it would keep its shift and silently lose the association. It keeps the run's numbers."""
    from bgm_viewer.model import ViewerModel

    model = ViewerModel(_three_bodies_holes(), cache=False)
    model.select("g1", 0, 1)
    _run(model, model.set_param("min_component_holes", 1))  # a one-hole component is a target
    assert len(model.result.pair.targets) == 1
    model.set_translation(3.0, -2.0)  # C
    _run(model, "correspondence")
    _run_until(model, model.set_param("keep_isolated_holes", True), lambda: model.overrides[0].source == 2)
    lone = [i for i, c in enumerate(model.result.pair.targets) if len(c.holes) == 1]
    assert lone, "no single hole is a target of its own"
    model.set_association(lone[-1], True)
    edited = [(2, (3.0, -2.0), {lone[-1]: True})]
    assert [(o.source, o.translation, o.associate) for o in model.overrides] == edited

    model.stop()
    assert [(o.source, o.translation, o.associate) for o in model.overrides] == edited
    assert any(
        "Stop kept the alignment overrides" in n and f"no longer names target {lone[-1]}" in n
        for n in model.override_notes
    ), model.override_notes
    _run(model, "contours")  # Run again: the association applies to the target it named
    assert [(o.source, o.translation, o.associate) for o in model.overrides] == edited


def test_edits_on_bodies_the_picture_does_not_tell_apart_keep_the_stopped_runs_numbers_and_say_so():
    """B and the main body are one component under the picture's parameters: shifts edited on both during the
    stopped runs cannot both follow them back. Nothing is lost: they keep the runs' numbers, which Run again
    needs, and the notes say why."""
    from bgm_viewer.model import ViewerModel

    model = ViewerModel(_three_bodies_holes(), cache=False)
    model.select("g1", 0, 1)
    _run(model, "contours")
    model.set_translation(3.0, -2.0)
    _run(model, "correspondence")
    _run_until(model, model.set_param("keep_isolated_holes", True), lambda: model.overrides[0].source == 2)
    for component, shift in ((0, (1.0, 0.0)), (1, (0.0, 1.0))):  # B, then the main body: one component before
        _run_until(
            model,
            model.select("g1", 0, component),
            lambda: model.result.selection == model.selection and model.result.pair is not None,
        )
        model.set_translation(*shift)
    edited = sorted((o.source, o.translation) for o in model.overrides)
    assert edited == [(0, (1.0, 0.0)), (1, (0.0, 1.0)), (2, (3.0, -2.0))]
    assert len(model.last_complete.pair.sources) == 2  # the picture: B and the main body are one component

    model.stop()
    assert sorted((o.source, o.translation) for o in model.overrides) == edited
    assert any("Stop kept the alignment overrides" in n and "dropped" in n for n in model.override_notes)
    _run(model, "contours")  # Run again: each applies to its own body
    assert sorted((o.source, o.translation) for o in model.overrides) == edited
