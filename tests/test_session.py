"""The staged pipeline (core.model.session), its stage cache (core.io.cache) and the parameter specs.

A result must be reused when nothing it depends on changed, and computed
again, never served stale, when the input, a parameter or the code did.
"""

from __future__ import annotations

import dataclasses
import functools
import json

import numpy as np
import pytest
from conftest import narrowing_pit, synthetic
from test_cli import bgm

from core.errors import BGMInputError
from core.io.cache import MISSING, StageCache, content_key, source_fingerprint
from core.model.parameters import (
    PARAMETER,
    PARAMETERS,
    STAGES,
    ModelParameters,
    first_changed_stage,
    parameter_value,
    parameters_from_dict,
    parameters_to_dict,
    stage_values,
    with_values,
)
from core.model.pipeline import model_geozone
from core.model.session import ModelSession, StageStore

MINE = {"n_benches": 3, "extent_m": (140.0, 100.0), "n_pods": 1}


@pytest.fixture(scope="module")
def holes():
    return synthetic(11, **MINE)[2]


def _session(holes, cache_dir, **params) -> ModelSession:
    return ModelSession(holes, with_values(ModelParameters(), **params), None, StageStore(StageCache(cache_dir)))


def _computed(session: ModelSession) -> dict:
    """Stage -> how many results were computed (not found in memory or on disk)."""
    return {stage: n for (stage, how), n in session.store.counts.items() if how == "computed"}


def _translations(model) -> list:
    return [p.correspondence.translations.tolist() for p in model.pairs]


def test_a_second_run_on_the_same_input_is_read_from_disk(holes, tmp_path):
    first = _session(holes, tmp_path)
    model = first.geozone_model("g1")
    assert _computed(first)["contours"] == holes.n_benches and _computed(first)["morph"] == len(model.pairs)
    again = _session(holes, tmp_path)  # a new process: nothing in memory
    cached = again.geozone_model("g1")
    assert _computed(again) == {}
    assert _translations(cached) == _translations(model)
    assert [c.polygon.wkb for c in cached.contours] == [c.polygon.wkb for c in model.contours]
    # what the one-off function (no cache) computes is the same
    fresh = model_geozone(holes, "g1")
    assert _translations(fresh) == _translations(model)


def test_one_geozones_model_traces_its_own_contours_alone_and_the_same_ones(holes, tmp_path, monkeypatch):
    """``bgm predict`` of one geozone extracted every geozone's contours first (Kennecott: 11 s of 15)."""
    import core.extraction.contours as contours_module
    import core.model.session as session_module

    traced = []
    extract = contours_module.extract_bench

    def spy(holes_, bench, geozones=None, *args, **kwargs):
        traced.append(None if geozones is None else list(geozones))  # benches traced on threads: any order
        return extract(holes_, bench, geozones, *args, **kwargs)

    monkeypatch.setattr(contours_module, "extract_bench", spy)
    monkeypatch.setattr(session_module, "extract_bench", spy)
    alone = _session(holes, tmp_path / "alone").geozone_model("g1")
    assert traced == [["g1"]] * holes.n_benches
    whole = _session(holes, tmp_path / "whole")
    every = [c for c in whole.contours() if c.geozone == "g1"]
    own = alone.contours + alone.minor
    assert sorted(c.polygon.wkb for c in own) == sorted(c.polygon.wkb for c in every)
    # Several geozones are traced together, each bench's evidence once; those already traced are not again.
    traced.clear()
    others = [g for g in holes.geozones if g != "g1"]
    both = _session(holes, tmp_path / "alone").contours_of(["g1", *others])
    assert traced == [others] * holes.n_benches
    assert sorted(c.polygon.wkb for c in both["g1"]) == sorted(c.polygon.wkb for c in every)
    # Once a bench's contours are all stored, a geozone's are read from them, not traced again.
    traced.clear()
    assert [c.polygon.wkb for c in whole.geozone_contours("g1")] == [c.polygon.wkb for c in every]
    assert traced == []


def test_the_uncertainty_of_a_prediction_is_read_back_and_follows_the_parameters(holes, tmp_path):
    """A repeated ``bgm predict`` reads its bands back; its calibration may pool every geozone's contours."""
    from core.model.uncertainty import geozone_uncertainty

    z = [float(holes.bench_levels_m[-1]) - 5.0]
    session = _session(holes, tmp_path)
    first = geozone_uncertainty(session, "g1", z)[z[0]]
    assert _computed(session)["uncertainty"] == 1
    again = _session(holes, tmp_path)
    read = geozone_uncertainty(again, "g1", z)[z[0]]
    assert _computed(again) == {} and np.array_equal(read.sigma, first.sigma)
    changed = _session(holes, tmp_path, entropy_threshold=0.2)
    geozone_uncertainty(changed, "g1", z)
    assert _computed(changed)["uncertainty"] == 1


def _told_at_least(told: list, steps: int) -> bool:
    return len(told) >= steps


def _tell(told: list, done: int, total: int) -> None:
    told.append((done, total))


def test_a_band_whose_caller_cancels_it_stops_at_that_step_and_stores_nothing_half_done(holes, tmp_path):
    """The viewer computes the next bench's band on a worker thread (1-3.5 s on Kennecott). A geologist who moved
    a slider again, chose another geozone or closed the window had it run to its end: core took no word of it.
    Core now tells ``progress`` each step (the benches backtested, here the other geozones' too as g1's own
    backtest is too short, the fit's iterations); raised there, ``Cancelled`` stops the band at that step."""
    from core.model import uncertainty
    from core.threads import Cancelled, cancelling

    z = [float(holes.bench_levels_m[-1]) - 5.0]
    told: list[tuple[int, int]] = []
    whole = uncertainty.geozone_uncertainty(
        _session(holes, tmp_path / "whole"), "g1", z, progress=lambda done, total: told.append((done, total))
    )[z[0]]
    assert whole.scale.source == "pooled backtest"
    fit = [i for i, (_, total) in enumerate(told) if total == uncertainty.FIT_MAX_ITERATIONS]
    assert fit and len(told[: fit[0]]) >= 3  # benches of three geozones' backtests, then the fit's iterations

    for steps in (1, fit[0] + 2):  # cancelled in g1's own backtest, then two iterations into the fit
        session = _session(holes, tmp_path / f"cancelled-{steps}")
        seen: list[tuple[int, int]] = []
        stopping = cancelling(functools.partial(_told_at_least, seen, steps), functools.partial(_tell, seen))
        with pytest.raises(Cancelled):
            uncertainty.geozone_uncertainty(session, "g1", z, progress=stopping)
        assert seen == told[:steps]  # stopped at the step it was told it was no longer wanted, not later
        assert "uncertainty" not in _computed(session)  # nothing half done stored
        if steps == 1:
            assert "backtest" not in _computed(session)
        again = uncertainty.geozone_uncertainty(session, "g1", z)[z[0]]  # asked again: computed whole
        assert np.array_equal(again.sigma, whole.sigma) and np.array_equal(again.field, whole.field)


def _stopping(seen: list, steps: int):
    """A cancelling progress that records what it is told and is no longer wanted once told ``steps`` steps."""
    from core.threads import cancelling

    return cancelling(functools.partial(_told_at_least, seen, steps), functools.partial(_tell, seen))


def test_a_bench_whose_caller_cancels_its_tracing_stops_at_that_part_and_stores_nothing_half_done(holes, tmp_path):
    """A bench's contours are traced part by part (edge map, GVF, snake: a Kennecott bench holds 20-40 parts and
    takes 2-4 s). A viewer run superseded while it traced one ran on to the bench's last part. Core now tells
    ``progress`` the bench's evidence found, then each part traced; raised there, ``Cancelled`` stops the bench."""
    from core.threads import Cancelled

    bench = holes.n_benches - 1
    told: list[tuple[int, int]] = []
    whole = _session(holes, tmp_path / "whole").bench_contours(bench, progress=functools.partial(_tell, told))
    parts = len(whole)
    assert parts >= 3 and told[0] == (0, parts)  # the evidence, then each part (and each part's own steps)
    assert sorted(set(told)) == [(done, parts) for done in range(parts + 1)] and told == sorted(told)
    first = told.index((1, parts))  # told (0, parts) again at the first part's own steps, before it is done

    for steps in (1, 2, first + 1):  # once the evidence is found, in the first part, after the first part
        session = _session(holes, tmp_path / f"cancelled-{steps}")
        seen: list[tuple[int, int]] = []
        with pytest.raises(Cancelled):
            session.bench_contours(bench, progress=_stopping(seen, steps))
        assert seen == told[:steps]  # stopped at the step it was told it was no longer wanted, not later
        assert "contours" not in _computed(session) and session.stored_bench_contours(bench) is None
        again = session.bench_contours(bench)  # asked again: traced whole
        assert [c.polygon.wkb for c in again] == [c.polygon.wkb for c in whole]


def test_a_part_whose_caller_cancels_its_tracing_stops_within_it_at_its_next_step(holes, tmp_path):
    """A part's GVF, snake and smoothing were one step (Kennecott: up to 0.9 s for a bench's largest part): a
    superseded viewer run waited for the part it had begun. Core now tells ``progress`` the parts done again at
    each of the part's own steps (its GVF solved, every few snake iterations, each step of its smoothing)."""
    import core.extraction.contours as extraction
    from core.threads import Cancelled

    bench = holes.n_benches - 1
    told: list[tuple[int, int]] = []
    whole = extraction.extract_bench(holes, bench, progress=functools.partial(_tell, told))
    within = told.index((1, len(whole))) - 1  # the first part's own steps
    assert within >= 3  # its GVF, its snake's iterations, its smoothing
    for steps in (2, within):  # its GVF solved, its last step
        seen: list[tuple[int, int]] = []
        with pytest.raises(Cancelled):
            extraction.extract_bench(holes, bench, progress=_stopping(seen, steps))
        assert seen == told[:steps] and seen[-1] == (0, len(whole))  # stopped within the first part
    again = extraction.extract_bench(holes, bench)  # not cancelled: the same contours
    assert [c.polygon.wkb for c in again] == [c.polygon.wkb for c in whole]


def test_a_surface_whose_caller_cancels_it_stops_at_that_step_and_stores_nothing_half_done(holes, tmp_path):
    """A geozone's surface (its sections, then the mesh) was one step: a superseded viewer run made every surface
    it had begun to its end (6 s on Kennecott after the request). Core now tells ``progress`` each bench pair's
    sections, the sections below the deepest bench (their depth trend's backtests, each elevation), each
    section's depth trend, each section's signed distance, the steps of closing the mesh (marching cubes done)
    and the mesh's two steps; raised there, ``Cancelled`` stops the surface at that step."""
    from core.threads import Cancelled

    told: list[tuple[int, int]] = []
    first = _session(holes, tmp_path / "whole")
    model = first.geozone_model("g1")
    whole = first.surface("g1", model, progress=functools.partial(_tell, told))
    pairs = len(model.pairs)
    # One series (core.model.progress.Stages): the model (given here), the sections, the mesh, a third each.
    fraction = [done / total for done, total in told]
    assert fraction == sorted(fraction) and fraction[-1] == 1.0
    assert fraction[:pairs] == pytest.approx([1 / 3 + 1 / 9 * done / pairs for done in range(1, pairs + 1)], abs=1e-3)
    # the sections below the deepest bench made: the second of the sections' three parts
    below = next(i for i, f in enumerate(fraction) if f >= 1 / 3 + 2 / 9 - 1e-3)
    assert below > pairs + 4  # their own steps before: the depth trend's backtests, each elevation
    assert fraction[-2:] == pytest.approx([11 / 12, 1.0], abs=1e-3)  # the mesh closed, then its specks dropped
    # closing it: before its try, after the try's marching cubes (half the mesh's third: the distances made)
    closing = len(told) - 4
    assert fraction[closing:-2] == pytest.approx([5 / 6] * 2, abs=1e-3)
    sdfs = next(i for i, f in enumerate(fraction) if f > 2 / 3 + 1e-4)  # the first section's signed distance

    # in the pairs, the predictions below, the trend, the distances, marching cubes, the mesh
    for steps in (1, pairs + 1, below + 2, sdfs + 1, closing + 1, len(told) - 1):
        session = _session(holes, tmp_path / f"cancelled-{steps}")
        zone = session.geozone_model("g1")
        seen: list[tuple[int, int]] = []
        with pytest.raises(Cancelled):
            session.surface("g1", zone, progress=_stopping(seen, steps))
        assert seen == told[:steps]
        assert "surface" not in _computed(session)  # nothing half done stored
        again = session.surface("g1", zone)  # asked again: made whole
        assert np.array_equal(again.vertices, whole.vertices) and np.array_equal(again.faces, whole.faces)


def test_a_prediction_whose_caller_cancels_it_stops_at_that_step_and_stores_nothing_half_done(holes, tmp_path):
    """Below the deepest bench a geozone is predicted by its depth trend, whose backtests (each bench pair with
    each dip, each bench pair's ways to carry the movement, its confirmation) took 1-6 s on Kennecott as one
    step: a superseded viewer run waited for it. Core now tells ``progress`` each backtest's step and each
    elevation; raised there, ``Cancelled`` stops the prediction at that step, and nothing of it is stored."""
    from core.threads import Cancelled

    z = [holes.below_deepest_m(f) for f in (0.25, 0.5, 0.75, 1.0)]
    first = _session(holes, tmp_path / "whole")
    told: list[tuple[int, int]] = []
    whole = first.predict("g1", z, first.geozone_model("g1"), progress=functools.partial(_tell, told))
    # One series (core.model.progress.Stages): the model (given here), then the prediction: its depth trend's
    # backtests, then each elevation, at the end.
    fraction = [done / total for done, total in told]
    assert fraction == sorted(fraction)
    assert fraction[-len(z) :] == pytest.approx([0.75 + 0.25 * done / len(z) for done in range(1, len(z) + 1)])
    trend = len(told) - len(z)
    assert trend >= 3  # the depth trend's backtests, before the first elevation below

    for steps in (1, trend - 1, trend + 2):  # in the dip's backtest, its confirmation, the elevations
        session = _session(holes, tmp_path / f"cancelled-{steps}")
        model = session.geozone_model("g1")
        seen: list[tuple[int, int]] = []
        with pytest.raises(Cancelled):
            session.predict("g1", z, model, progress=_stopping(seen, steps))
        assert seen == told[:steps]  # stopped at the step it was told it was no longer wanted, not later
        assert "prediction" not in _computed(session)  # nothing half done stored
        made = any(key[0] == "trend" for key in model.fields.memo)
        assert made == (steps >= trend)  # a trend is kept whole, never of half its backtests
        again = session.predict("g1", z, model)  # asked again: predicted whole, the same
        assert [again[h].wkb for h in z] == [whole[h].wkb for h in z]


def test_a_changed_hole_label_recomputes_its_bench_and_what_follows(holes, tmp_path):
    _session(holes, tmp_path).geozone_model("g1")
    on = holes.on_bench(1)
    g1 = on[holes.geozone[on] == "g1"]
    # relabel the hole in the middle of g1 on bench 1 and its two nearest holes: they become a pod of g0
    # cut out of g1's contour (one hole alone would be taken as label noise, see core.extraction.noise)
    middle = g1[np.argmin(np.hypot(*(holes.xy[g1] - holes.xy[g1].mean(axis=0)).T))]
    pod = g1[np.argsort(np.hypot(*(holes.xy[g1] - holes.xy[middle]).T))[:3]]
    labels = holes.geozone.copy()
    labels[pod] = "g0"
    changed = dataclasses.replace(holes, geozone=labels, _drilled={})
    session = _session(changed, tmp_path)
    model = session.geozone_model("g1")
    computed = _computed(session)
    assert computed["contours"] == 1  # bench 1 only; benches 0 and 2 come from the cache
    assert computed["correspondence"] == 2  # both pairs touch bench 1
    assert not any(middle in c.holes for c in model.contours)
    assert _translations(model) == _translations(model_geozone(changed, "g1"))


def test_a_changed_parameter_recomputes_its_stage_and_the_later_ones(holes, tmp_path):
    base = _session(holes, tmp_path)
    base.geozone_model("g1")
    morph = _session(holes, tmp_path, morph_max_cells=128)
    morph.geozone_model("g1")
    assert set(_computed(morph)) == {"morph"}
    assert first_changed_stage(base.params, morph.params) == "morph"
    boundary = _session(holes, tmp_path, entropy_threshold=0.7)
    model = boundary.geozone_model("g1")
    assert _computed(boundary)["contours"] == holes.n_benches
    params = boundary.params
    assert _translations(model) == _translations(model_geozone(holes, "g1", params=params))
    same = _session(holes, tmp_path, entropy_threshold=0.7)
    same.geozone_model("g1")
    assert _computed(same) == {}


def test_an_unreadable_cache_entry_is_computed_again(holes, tmp_path):
    session = _session(holes, tmp_path)
    contours = session.bench_contours(0)
    (entry,) = (tmp_path / "contours").rglob("*.pkl")
    entry.write_bytes(b"not a pickle")
    again = _session(holes, tmp_path)
    assert [c.polygon.wkb for c in again.bench_contours(0)] == [c.polygon.wkb for c in contours]
    assert _computed(again) == {"contours": 1}
    assert entry.read_bytes() != b"not a pickle"  # replaced by a good entry


def test_a_code_change_changes_every_key(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\n")
    before = source_fingerprint(tmp_path)
    (tmp_path / "a.py").write_text("x = 2\n")
    assert source_fingerprint(tmp_path) != before
    assert content_key(before, 1) != content_key(source_fingerprint(tmp_path), 1)


def test_another_library_version_changes_every_key(monkeypatch):
    """The cache folder is the user's, shared by every environment: one with another shapely (another GEOS)
    was served the contours, morphs and surfaces the other computed, the fingerprint being the source's alone."""
    from importlib import metadata

    from core.io import cache

    real = metadata.version
    cache.engine_fingerprint.cache_clear()
    before = cache.engine_fingerprint()
    monkeypatch.setattr(metadata, "version", lambda name: "0.0.1" if name == "shapely" else real(name))
    cache.engine_fingerprint.cache_clear()
    try:
        assert cache.engine_fingerprint() != before
    finally:
        cache.engine_fingerprint.cache_clear()


@pytest.mark.parametrize("value", ["abc", "nan", "-5", "2 GB"])
def test_a_cache_size_limit_that_is_no_number_of_megabytes_is_refused_by_name(monkeypatch, tmp_path, value):
    """$BGM_CACHE_MAX_MB=abc ended every command with 'internal error: ValueError'; -5 kept nothing, unsaid."""
    monkeypatch.setenv("BGM_CACHE_MAX_MB", value)
    with pytest.raises(BGMInputError, match=r"\$BGM_CACHE_MAX_MB must be .* megabytes"):
        StageCache(tmp_path)
    monkeypatch.setenv("BGM_CACHE_MAX_MB", "100")
    assert StageCache(tmp_path).max_bytes == 100_000_000


def test_content_keys_see_values_not_identities():
    a = np.arange(6, dtype=float).reshape(3, 2)
    assert content_key(a, "g1", {"x": 1.0}) == content_key(a.copy(), "g1", {"x": 1.0})
    assert content_key(a, "g1") != content_key(a + 1e-12, "g1")
    assert content_key(np.array(["g1", "g2"], dtype=object)) != content_key(np.array(["g1", "g3"], dtype=object))
    assert content_key(1) != content_key(1.0) != content_key("1")


def test_the_cache_is_pruned_to_its_size_limit(tmp_path):
    cache = StageCache(tmp_path, max_bytes=50_000)
    for i in range(10):
        cache.store("s", content_key(i), np.zeros(1000))  # about 8 kB each
    cache.prune()
    kept = list(tmp_path.rglob("*.pkl"))
    assert 0 < len(kept) <= 6 and sum(p.stat().st_size for p in kept) <= 50_000


# ----------------------------------------------------------------------------------------------
# parameter specs


def test_every_parameter_has_one_spec_with_a_stage_a_kind_and_a_range():
    assert len(PARAMETERS) == len(PARAMETER)
    for spec in PARAMETERS:
        assert spec.stage in STAGES and spec.kind in ("length", "angle", "count", "ratio", "flag")
        assert spec.minimum < spec.maximum and spec.help and spec.label
        default = spec.default
        if default is None:
            assert spec.kind == "length" and spec.auto  # derived from the data, and says how
        else:
            assert spec.minimum <= default <= spec.maximum, spec.name
    assert sum(len(stage_values(ModelParameters(), s)) for s in STAGES) == len(PARAMETERS)


def test_parameters_round_trip_through_a_project_and_are_checked():
    params = with_values(ModelParameters(), search_radius_m=9.5, morph_max_cells=200, entropy_threshold=0.4)
    stored = json.loads(json.dumps(parameters_to_dict(params)))
    assert stored == {"search_radius_m": 9.5, "morph_max_cells": 200, "entropy_threshold": 0.4}
    assert parameters_from_dict({**stored, "viewer": {"bench": 1}}) == params
    assert parameter_value(params, "search_radius_m") == 9.5
    for bad in ({"morph_max_cells": 2.5}, {"search_radius_m": -1.0}, {"gvf_mu": "high"}, {"gvf_mu": float("nan")}):
        with pytest.raises(BGMInputError):
            parameters_from_dict(bad)


def _small_csv(tmp_path, seed: int):
    _, table, _ = synthetic(seed, **MINE)
    path = tmp_path / "mine.csv"
    table.to_csv(path, index=False)
    return path, table


def _source_sizes(path) -> list[int]:
    return [s["holes"] for pair in json.loads(path.read_text())["pairs"] for s in pair["sources"]]


def test_the_command_line_applies_a_projects_parameters(tmp_path):
    csv, _ = _small_csv(tmp_path, 12)
    bgm("correspond", csv, "--geozone", "g1", "--out", tmp_path / "default.json")
    project = tmp_path / "p.json"
    # Mislabelled single holes kept as components, and components of one hole modelled.
    parameters = {"min_component_holes": 1, "keep_isolated_holes": True}
    project.write_text(json.dumps({"format": "bgm-project", "version": 1, "parameters": parameters}))
    bgm("correspond", csv, "--geozone", "g1", "--project", project, "--out", tmp_path / "tuned.json")
    assert min(_source_sizes(tmp_path / "default.json")) >= 3
    assert min(_source_sizes(tmp_path / "tuned.json")) < 3, "the project's min_component_holes = 1 was not applied"


def test_a_second_command_reuses_the_cache_and_a_changed_file_is_not_served_stale(tmp_path, own_stage_cache):
    csv, table = _small_csv(tmp_path, 13)
    args = ("correspond", csv, "--geozone", "g1")
    bgm(*args, "--out", tmp_path / "1.json")
    entries = sorted(own_stage_cache.rglob("*.pkl"))
    assert len(entries) > 3
    bgm(*args, "--out", tmp_path / "2.json")
    assert sorted(own_stage_cache.rglob("*.pkl")) == entries  # nothing new: all reused
    assert (tmp_path / "1.json").read_text() == (tmp_path / "2.json").read_text()
    # one hole of g1 on the deepest bench relabelled in the file: recomputed, and the output follows the file
    row = table.index[(table["z"] < table["z"].min() + 1.0) & (table["geozone"] == "g1")][0]
    table.loc[row, "geozone"] = "g0"
    table.to_csv(csv, index=False)
    bgm(*args, "--out", tmp_path / "3.json")
    assert len(list(own_stage_cache.rglob("*.pkl"))) > len(entries)
    bgm(*args, "--out", tmp_path / "4.json", "--no-cache")
    assert (tmp_path / "3.json").read_text() == (tmp_path / "4.json").read_text()
    assert (tmp_path / "3.json").read_text() != (tmp_path / "1.json").read_text()


def test_bgm_parameters_lists_every_parameter_with_its_stage():
    out = bgm("parameters").stdout
    for spec in PARAMETERS:
        assert spec.name in out, spec.name


def test_memory_keeps_the_newest_results_of_each_stage():
    store = StageStore(max_entries=2)
    for i in range(3):
        store.get("contours", str(i), lambda i=i: i)
    store.get("morph", "a", lambda: "a")
    assert store.get("contours", "0", lambda: "again") == "again"  # the oldest contours were let go
    assert store.get("contours", "2", lambda: "again") == 2 and store.get("morph", "a", lambda: "again") == "a"
    for i in range(5):
        store.get("fields", str(i), lambda i=i: i)  # display fields: only the latest few
    assert store.get("fields", "0", lambda: "again") == "again"


def test_a_build_worker_lets_go_of_a_geozones_results_once_it_has_sent_them(monkeypatch, tmp_path):
    """Held, each worker grew by ~100 MB a geozone on the Kennecott build; the shared stages stay."""
    from types import SimpleNamespace

    import core.model.build as build

    store = StageStore(StageCache(tmp_path))
    session = SimpleNamespace(store=store)
    ctx = build.BuildContext(session, [], None, tmp_path, (), False)  # a build's context, as a worker holds it
    monkeypatch.setattr(build, "_WORKER_CONTEXT", ctx)
    store.get("contours", "bench 0", lambda: "contours")

    def job(ctx, geozone):
        ctx.session.store.get("morph", geozone, lambda: f"morph of {geozone}")
        return geozone

    assert build._call_in_worker(job, "g1") == "g1"
    assert store.peek("morph", "g1", disk=False) is MISSING  # not held in memory
    assert store.peek("morph", "g1") == "morph of g1"  # still on disk, with a cache
    assert store.peek("contours", "bench 0", disk=False) == "contours"


def test_a_geozones_fields_on_a_traced_bench_trace_that_geozone_alone(holes, tmp_path, monkeypatch):
    """The viewer's switch of geozone traced the whole bench again for one geozone's fields (Kennecott: 2-5 s)."""
    import core.model.session as session_module

    session = _session(holes, tmp_path)
    stored = session.bench_contours(1)
    traced = []
    extract = session_module.extract_bench

    def spy(holes_, bench, geozones=None, *args, **kwargs):
        traced.append(None if geozones is None else list(geozones))
        return extract(holes_, bench, geozones, *args, **kwargs)

    monkeypatch.setattr(session_module, "extract_bench", spy)
    for g in ("g1", "g2"):
        with_fields = session.bench_contours_with_fields(1, g)
        assert [c.polygon.wkb for c in with_fields] == [c.polygon.wkb for c in stored]
        assert {c.geozone for c in with_fields if c.fields is not None} == {g}
    assert traced == [["g1"], ["g2"]]


def test_a_project_override_of_a_missing_component_names_the_geozone_and_the_benches(holes, tmp_path):
    from core.io.project import AlignmentOverride, Project

    session = _session(holes, tmp_path / "cache")
    g = next(g for g in holes.geozones if session.pairs(g))
    upper = holes.bench_z_input(session.pairs(g)[0].upper)
    project = Project(overrides=[AlignmentOverride(g, upper, 99, translation=(1.0, 0.0))])
    session = ModelSession(holes, session.params, project, StageStore(StageCache(tmp_path / "cache")))
    with pytest.raises(BGMInputError, match=rf"override of geozone '{g}', benches {upper:g} .* source component 99"):
        session.geozone_model(g)


def _disc_benches(on_benches, n_benches=5, spacing=6.0, radius_m=120.0, disc=(50.0, 20.0, 28.0)):
    """Holes on a staggered pattern, 10 m benches: geozone ``a`` in a disc on ``on_benches``, ``host`` elsewhere."""
    import pandas as pd

    from core.io.blastholes import blastholes_from_table

    rows = np.arange(-radius_m, radius_m, spacing * np.sqrt(3) / 2)
    xy = np.array(
        [(x + (i % 2) * spacing / 2, y) for i, y in enumerate(rows) for x in np.arange(-radius_m, radius_m, spacing)]
    )
    xy = xy[np.hypot(*xy.T) < radius_m]
    inside = np.hypot(xy[:, 0] - disc[0], xy[:, 1] - disc[1]) < disc[2]
    frames = [
        pd.DataFrame(
            {
                "x": xy[:, 0] + 650_000,
                "y": xy[:, 1] + 7_400_000,
                "z": 500.0 - 10 * k,
                "geozone": np.where(inside & (k in on_benches), "a", "host"),
            }
        )
        for k in range(n_benches)
    ]
    return blastholes_from_table(pd.concat(frames, ignore_index=True), source="constructed")


def test_a_geozone_gone_for_benches_and_back_has_no_surface_through_the_benches_drilled_without_it():
    """On the top and the deepest bench only: the upper body closed towards the next pair's upper bench, past
    the next bench, where every hole is the host's (here 0.3 m past it; 7.8 m for a 30 m disc on 6 m holes)."""
    holes = _disc_benches(on_benches={0, 4})
    session = ModelSession(holes)
    model = session.geozone_model("a")
    assert [(p.upper, p.lower) for p in model.pairs] == [(0, 1), (3, 4)]
    z = session.surface("a", model).vertices[:, 2]
    levels = holes.bench_levels_m
    assert z.max() == pytest.approx(levels[0], abs=0.01) and (z < levels[3]).any()  # both bodies are there
    assert not ((z < levels[1]) & (z > levels[3])).any(), np.sort(z[(z < levels[1]) & (z > levels[3])])[-3:]


def _section_area_m2(mesh, z_m: float) -> float:
    """The area of the closed mesh's section at ``z_m``."""
    section = mesh.section(plane_origin=[0.0, 0.0, z_m], plane_normal=[0.0, 0.0, 1.0])
    if section is None:
        return 0.0
    planar, _ = section.to_2D()
    return float(sum(p.area for p in planar.polygons_full))


def test_a_body_the_lower_benches_did_not_drill_runs_on_down_to_its_predictions_below_the_deepest_bench():
    """``wall``'s pairs end above the deepest bench because the benches below did not drill its ground: its
    surface pinched out under its last bench (471.4 m, 11 m above the deepest) while its predictions below the
    deepest bench carried it on (2400 m² at 457.5 m). Now it is one closed body down to those predictions."""
    from core.model.build import PREDICTION_FRACTIONS

    holes = narrowing_pit()
    session = ModelSession(holes)
    model = session.geozone_model("wall")
    levels = holes.bench_levels_m
    assert model.pairs[-1].lower < holes.n_benches - 1  # its pairs end above the deepest bench
    mesh = session.surface("wall", model)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    assert len(mesh.split(only_watertight=False)) == 1
    z = float(levels[-1]) - 10.0 * PREDICTION_FRACTIONS[1]  # a quarter of a bench below the deepest
    predicted = session.predict("wall", [z], model)[z].area
    assert predicted > 0
    assert _section_area_m2(mesh, z) == pytest.approx(predicted, rel=0.1)
    between = float(levels[2] + levels[3]) / 2  # under its last bench, where `bgm predict` gives the same
    assert _section_area_m2(mesh, between) == pytest.approx(session.predict("wall", [between])[between].area, rel=0.1)


def test_a_body_cut_by_the_lower_benchs_drilling_edge_does_not_end_at_that_edge():
    """The third bench drilled 576 m² of ``wall``'s 1520 (a cylinder): its section there was the drilled part
    alone, ending at the drilling edge. Past that edge the section now holds the depth trend, as below the
    deepest bench, which carries the cylinder on."""
    holes = narrowing_pit()
    session = ModelSession(holes)
    mesh = session.surface("wall")
    z = float(holes.bench_levels_m[2]) + 0.01
    assert _section_area_m2(mesh, z) > 0.9 * np.pi * 22.0**2


def test_a_body_absent_from_the_benches_that_drilled_its_ground_closes_above_them_and_is_not_predicted_below():
    """``gone`` is on the top three benches; the fourth and fifth drilled its ground and found the host: its
    surface closes between its last bench and the next, and nothing of it is predicted below the deepest."""
    holes = narrowing_pit()
    session = ModelSession(holes)
    model = session.geozone_model("gone")
    levels = holes.bench_levels_m
    z = session.surface("gone", model).vertices[:, 2]
    assert levels[3] < z.min() < levels[2]
    below = [float(levels[-1]) - 2.5 * k for k in range(1, 5)]
    assert all(region.is_empty for region in session.predict("gone", below, model).values())


def test_a_dyke_one_hole_wide_across_a_wide_pit_is_one_body_not_a_string_of_beads():
    """A dyke 5 m wide (one 5 m hole spacing) and 2 km long: the grid of a geozone that wide was coarsened to
    6.7 m (300 cells across), and its surface was 109 beads."""
    from types import SimpleNamespace

    from shapely import affinity
    from shapely.geometry import MultiPolygon, box

    from core.model.pipeline import GeozoneModel
    from core.model.session import surface_cell_size
    from core.model.surfaces import surface_from_sections

    dyke = affinity.rotate(box(-1000.0, -2.5, 1000.0, 2.5), 20.0)
    contours = [SimpleNamespace(polygon=dyke, bench=k) for k in range(4)]
    model = GeozoneModel("dyke", contours, [], [], None)  # type: ignore[arg-type]  # only the contours are read
    cell = surface_cell_size(model, SimpleNamespace(hole_spacing_m=5.0), max_cells=300)  # type: ignore[arg-type]
    sections = [(-10.0 * k, MultiPolygon([dyke])) for k in range(4)]
    mesh = surface_from_sections(sections, cell_size_m=cell, min_width_m=2.5)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert len(mesh.split(only_watertight=False)) == 1
    assert mesh.volume == pytest.approx(dyke.area * 30.0, rel=0.02)


def test_a_surfaces_and_a_predictions_progress_never_goes_back(holes, tmp_path):
    """A surface's stages (the model's pairs, the sections, the prediction below the deepest bench between
    its depth trend's backtests, the sections' signed distances, the mesh) each counted their own steps into
    the same ``progress(done, total)``: 9 of 9, then 0 of 2; an elevation's 1 of 4 between the backtests'
    5 of 6. A bar on it went back and forth. Each stage now has its own share of one series."""
    for geozone in sorted(set(holes.geozone.tolist())):
        surface: list[tuple[int, int]] = []
        _session(holes, tmp_path / f"surface-{geozone}").surface(geozone, progress=functools.partial(_tell, surface))
        z = [holes.below_deepest_m(f) for f in (0.5, 1.0)]
        prediction: list[tuple[int, int]] = []  # afresh: the model's pairs and the depth trend's backtests too
        _session(holes, tmp_path / f"predict-{geozone}").predict(
            geozone, z, progress=functools.partial(_tell, prediction)
        )
        for told in (surface, prediction):
            fraction = [done / total for done, total in told]
            assert len(fraction) > 5 and fraction[-1] == 1.0, (geozone, told)
            backs = [(a, b) for a, b in zip(fraction, fraction[1:]) if b < a]
            assert not backs, (geozone, backs)
            assert len({total for _, total in told}) == 1, (geozone, told)  # one series, one total
