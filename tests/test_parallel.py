"""Per-geozone work runs serially, on local processes or on a dask cluster, with identical results."""

from __future__ import annotations

import json
import warnings

import pytest

from core.io.blastholes import BGMWarning, blastholes_from_table
from core.model.build import build
from core.synthetic.blobs import make_mine, sample_blastholes


@pytest.fixture(scope="module")
def holes():
    mine = make_mine(seed=9, n_benches=3, extent_m=(140.0, 100.0), n_pods=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        return blastholes_from_table(sample_blastholes(mine, seed=10))


def _results(out):
    summary = json.loads((out / "summary.json").read_text())
    geozones = {
        g["geozone"]: {k: g[k] for k in ("components", "bench_pairs", "coverage_after", "volume")}
        for g in summary["geozones"]
    }
    predictions = {
        g: (out / g / "prediction.geojson").read_text() for g in geozones if (out / g / "prediction.geojson").exists()
    }
    contours = (out / "contours.geojson").read_text()
    return geozones, predictions, contours


@pytest.fixture(scope="module")
def serial(holes, tmp_path_factory):
    """What a serial build writes, for each way of running in parallel to match."""
    out = tmp_path_factory.mktemp("serial")
    build(holes, out, workers=1, evaluate=False, formats=("ply",))
    return _results(out)


@pytest.mark.xdist_group("serial_build")  # one worker builds it once
def test_local_processes_match_a_serial_run(holes, serial, tmp_path):
    build(holes, tmp_path / "parallel", workers=2, evaluate=False, formats=("ply",))
    assert _results(tmp_path / "parallel") == serial


@pytest.mark.xdist_group("serial_build")
def test_a_dask_cluster_matches_a_serial_run(holes, serial, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        build(holes, tmp_path / "dask", scheduler=cluster.scheduler_address, evaluate=False, formats=("ply",))
    assert _results(tmp_path / "dask") == serial


def test_unreachable_scheduler_is_a_clear_error(holes, tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    import core.model.build
    from core.errors import BGMInputError

    monkeypatch.setattr(core.model.build, "SCHEDULER_TIMEOUT_S", 1.0)  # nothing listens there: no need to wait 10 s

    with pytest.raises(BGMInputError, match="cannot reach the dask scheduler"):
        build(holes, tmp_path / "x", scheduler="tcp://127.0.0.1:9", evaluate=False, formats=("ply",))


def test_a_client_that_could_not_connect_is_closed_before_the_error(monkeypatch):
    """A client whose scheduler could not be reached was left to a later garbage collection, whose finaliser takes
    the lock every client's start holds: run in the thread the next client started, it deadlocked that start (the
    suite hung in a test trying two bad addresses in one process). No half-made client outlives the error."""
    distributed = pytest.importorskip("distributed")
    import gc

    import core.model.build
    from core.errors import BGMInputError

    monkeypatch.setattr(core.model.build, "SCHEDULER_TIMEOUT_S", 1.0)
    gc.disable()  # only the build's own collection may clear it
    try:
        with pytest.raises(BGMInputError, match="cannot reach the dask scheduler"):
            list(core.model.build._dask_map(None, None, [0], "tcp://127.0.0.1:9"))
        clients = [o for o in gc.get_objects() if isinstance(o, distributed.Client)]
    finally:
        gc.enable()
    assert not clients


def _interrupt_in(stage: str):
    """A progress callback that interrupts the build as ``stage`` (contours, geozone) reports its first result."""

    def progress(what, done, total):
        if what.startswith(stage):
            raise KeyboardInterrupt

    return progress


@pytest.mark.parametrize("stage", ["contours", "geozone"])
def test_an_interrupt_between_results_stops_the_workers_at_once(holes, tmp_path, stage):
    """A Ctrl-C while the build handles a finished job (not while it waits) leaves no worker running.

    The workers ignore Ctrl-C and share the terminal's pipes: left running they keep a
    ``bgm build`` that has already said "interrupted" from ever ending.
    """
    import multiprocessing

    with pytest.raises(KeyboardInterrupt):
        build(holes, tmp_path / "model", workers=2, evaluate=False, formats=("ply",), progress=_interrupt_in(stage))
    assert multiprocessing.active_children() == []
    assert not (tmp_path / "model").exists()


def test_an_interrupt_while_the_pool_winds_down_stops_the_workers(holes, tmp_path, monkeypatch):
    """A Ctrl-C just as every job is done, while the idle workers are being told to leave.

    Python's own shutdown, cut short there, leaves idle workers waiting for work forever
    (the case that hung a CI run after "bgm: interrupted").
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    shutdown = ProcessPoolExecutor.shutdown
    calls = []

    def interrupted_shutdown(self, wait=True, *, cancel_futures=False):
        calls.append(wait)
        if len(calls) == 1:
            raise KeyboardInterrupt
        return shutdown(self, wait, cancel_futures=cancel_futures)

    monkeypatch.setattr(ProcessPoolExecutor, "shutdown", interrupted_shutdown)
    with pytest.raises(KeyboardInterrupt):
        build(holes, tmp_path / "model", workers=2, evaluate=False, formats=("ply",))
    assert calls and multiprocessing.active_children() == []
