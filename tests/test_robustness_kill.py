"""The kill test: ``bgm build`` into an existing model, stopped at random moments.

A model is built once and rebuilt once (timed); then the same build is started
again into that folder and stopped at moments drawn at random over the
rebuild's whole run (over less once a build ended before its stop, and that
stop is tried again), until two Ctrl-C and four SIGKILLs have landed: by
Ctrl-C (SIGINT to the process group, as a terminal sends it: the workers get
it too) or by SIGKILL (of the main process alone, or of the whole group).
After every stop the folder must hold the previous model, complete and valid
(or, for a stop after the new model was swapped in, the new one, which is
the same model), a Ctrl-C must end in exit status 130 with one line and no
traceback, and the staging folders a SIGKILL leaves behind must be cleared by
the next build.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from clirun import BGM, is_message

from core.synthetic.blobs import make_mine, sample_blastholes

ROOT = Path(__file__).resolve().parent.parent
#: The stops that must land, in turn: two Ctrl-C and four SIGKILLs. With 22 stops the test was an eighth of the
#: suite's work; a fixed count of 11 failed in CI when 2 of its 4 Ctrl-C came after the build had ended.
STOPS = ("ctrl-c", "kill main", "kill group") * 2
#: Stops tried at most, those that came too late included.
ATTEMPTS = 12
#: Moments start after the interpreter's own start-up (before it no BGM code runs to catch anything).
EARLIEST_S = 0.2
TIMED = ("seconds", "contours_seconds")


def start(csv: Path, out: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("BGM_DEBUG", None)
    # Every build computes everything, as the first one did: with the stage cache a rebuild
    # would finish long before most of the moments drawn over the first build's run.
    return subprocess.Popen(
        [*BGM, "build", str(csv), "--out", str(out), "--workers", "2", "--no-cache"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        env=env,
    )


def files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def untimed(summary: dict) -> dict:
    """A summary without its timings (the only thing two builds of one input differ in)."""
    out = {k: v for k, v in summary.items() if k not in TIMED}
    out["geozones"] = [{k: v for k, v in g.items() if k != "seconds"} for g in summary["geozones"]]
    return out


def assert_valid_model(out: Path, reference: dict[str, bytes]) -> None:
    now = files(out)
    assert set(now) == set(reference), sorted(set(now) ^ set(reference))[:5]
    for name, data in now.items():
        if name == "summary.json":
            assert untimed(json.loads(data)) == untimed(json.loads(reference[name]))
        elif name == "report.md":
            assert data.decode().startswith("# BGM build report") and data.count(b"\n") == reference[name].count(b"\n")
        elif name.endswith(".omf"):  # OMF stamps every file with new UUIDs and dates: its surface is what must match
            assert omf_surface(out / name) == omf_surface_bytes(reference[name], out), name
        else:
            assert data == reference[name], name


def omf_surface(path: Path) -> tuple:
    """An OMF file's element names, vertices and triangles (what a reader gets), as bytes."""
    import warnings

    with warnings.catch_warnings():  # omf 1.0.1's vectormath predates numpy 2
        warnings.simplefilter("ignore", DeprecationWarning)
        import omf

        return tuple(
            (e.name, np.asarray(e.geometry.vertices.array).tobytes(), np.asarray(e.geometry.triangles.array).tobytes())
            for e in omf.OMFReader(str(path)).get_project().elements
        )


def omf_surface_bytes(data: bytes, near: Path) -> tuple:
    """:func:`omf_surface` of an OMF file's content, read from a temporary file beside ``near``."""
    path = near.parent / f".reference-{os.getpid()}.omf"
    path.write_bytes(data)
    try:
        return omf_surface(path)
    finally:
        path.unlink()


@pytest.fixture(scope="module")
def small_csv(tmp_path_factory) -> Path:
    mine = make_mine(seed=21, n_benches=3, extent_m=(50.0, 40.0), origin=(650_000.0, 7_400_000.0))
    path = tmp_path_factory.mktemp("kill") / "holes.csv"
    sample_blastholes(mine, seed=22).to_csv(path, index=False)
    return path


def test_build_killed_at_random_moments_leaves_the_previous_model(small_csv, tmp_path):
    out = tmp_path / "model"
    first = start(small_csv, out)
    _, err = first.communicate(timeout=600)
    assert first.returncode == 0, err
    reference = files(out)
    assert "summary.json" in reference and any(name.endswith("surface.stl") for name in reference)
    # The moments are drawn over a rebuild's run, timed: the first build, with cold caches of the interpreter
    # and the disk, took about twice as long in a CI run, where 11 of 22 stops came after the build had ended.
    t0 = time.perf_counter()
    rebuild = start(small_csv, out)
    _, err = rebuild.communicate(timeout=600)
    whole = time.perf_counter() - t0
    assert rebuild.returncode == 0, err
    assert_valid_model(out, reference)

    rng = np.random.default_rng(15)
    outcomes = {"interrupted": 0, "killed": 0, "finished": 0}
    window = 1.1 * whole
    plan = list(STOPS)
    for i in range(ATTEMPTS):
        if not plan:
            break
        how = plan[0]
        moment = rng.uniform(EARLIEST_S, window)
        proc = start(small_csv, out)
        time.sleep(moment)
        with contextlib.suppress(ProcessLookupError):
            if how == "ctrl-c":
                os.killpg(proc.pid, signal.SIGINT)
            elif how == "kill main":
                os.kill(proc.pid, signal.SIGKILL)
            else:
                os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=600)
        with contextlib.suppress(ProcessLookupError):  # orphaned workers of a killed main process hold the pipes
            os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=600)
        context = f"stop {i} ({how} at {moment:.2f} s of {window:.2f} s): exit {proc.returncode}\n{err}"
        if proc.returncode == 0:
            outcomes["finished"] += 1
            # A build that ended before its stop takes less than that moment on this machine now (a rebuild
            # timed while the other test worker was busy took twice as long as the stops' builds did).
            window = max(moment, 2 * EARLIEST_S)
        elif how == "ctrl-c":
            outcomes["interrupted"] += 1
            assert proc.returncode == 130, context
            lines = [
                line
                for line in err.splitlines()
                if (line.startswith("bgm:") and is_message(line)) or "Traceback" in line
            ]
            assert lines == ["bgm: interrupted; files being written were left as they were"], context
        else:
            outcomes["killed"] += 1
            assert proc.returncode == -signal.SIGKILL, context
        if proc.returncode != 0:
            plan.pop(0)
        assert_valid_model(out, reference)
        if how == "ctrl-c":  # a Ctrl-C cleans up after itself (a kill cannot: the next build does)
            assert not [p.name for p in tmp_path.iterdir() if f".bgm-staging-{proc.pid}-" in p.name], context
    assert not plan, f"{len(plan)} stops never landed in {ATTEMPTS} tries: {outcomes}"

    # The next build clears what the kills left behind, and writes the same model.
    final = start(small_csv, out)
    _, err = final.communicate(timeout=600)
    assert final.returncode == 0, err
    assert_valid_model(out, reference)
    assert not [p.name for p in tmp_path.iterdir() if ".bgm-" in p.name]


def children(pid: int) -> list[int]:
    """The live child processes of ``pid`` (Linux's /proc)."""
    with contextlib.suppress(OSError):
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    return []


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, dead but not yet reaped by init, does not)."""
    with contextlib.suppress(OSError):
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    return False


def started_workers(proc: subprocess.Popen, timeout: float = 120) -> list[int]:
    """The build's worker processes, once it has started them."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        workers = children(proc.pid)
        if workers:
            return workers
        time.sleep(0.05)
    raise AssertionError("the build started no worker process")


def gone(pids: list[int], timeout: float = 30) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and any(alive(p) for p in pids):
        time.sleep(0.1)
    return not any(alive(p) for p in pids)


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="reads processes from Linux's /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_a_build_stopped_by_kill_leaves_no_worker_running(small_csv, tmp_path, sig):
    """``kill`` (SIGTERM, as timeout and job schedulers stop a job) ends a build as Ctrl-C does, and
    a main process killed outright takes its workers with it instead of leaving them waiting for work."""
    proc = start(small_csv, tmp_path / "model")
    try:
        workers = started_workers(proc)
        os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=120)
        assert gone(workers), f"workers {workers} outlived the build's main process"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    if sig == signal.SIGTERM:
        assert proc.returncode == 143, err
        lines = [
            line for line in err.splitlines() if (line.startswith("bgm:") and is_message(line)) or "Traceback" in line
        ]
        assert lines == ["bgm: terminated; files being written were left as they were"], err
        assert not [p.name for p in tmp_path.iterdir() if ".bgm-" in p.name]


@pytest.mark.skipif(not hasattr(os, "fork"), reason="forks a process")
def test_a_worker_stopped_before_it_set_its_own_handlers_ends_quietly():
    """A worker forked by a build inherits the command's SIGTERM handler until its initializer replaces it; a
    stop in between (the parent terminating its workers) raised KeyboardInterrupt there, and the worker printed
    "Exception in initializer" and a traceback under the command's one line (seen in CI)."""
    from core import cli

    pid = os.fork()
    if pid == 0:  # the worker, its handlers still the command's
        try:
            cli._on_ctrl_c(signal.SIGTERM, None)
        except BaseException:
            os._exit(1)
        os._exit(2)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 128 + signal.SIGTERM


@pytest.fixture
def ctrl_c_handled():
    """SIGINT handled as ``bgm`` handles it while a command runs (``core.cli._on_ctrl_c``).

    The interrupt is raised again by simulating SIGINT (``_thread.interrupt_main``), which does nothing
    where SIGINT is ignored: a test run started in the background of a script inherits it ignored, and
    Python then installs no handler of its own.
    """
    import core.cli as cli

    previous = signal.signal(signal.SIGINT, cli._on_ctrl_c)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def test_an_interrupt_python_can_only_print_is_raised_again_without_a_traceback(capsys, monkeypatch, ctrl_c_handled):
    """SIGTERM landing in a fork hook or a finalizer (logging's lock release as a build forks its workers)
    printed "Exception ignored" and a traceback, and the interrupt was lost there: it is raised again,
    quietly. Anything else Python can only print is printed as before."""
    import sys

    import core.cli as cli

    class Finalizer:
        def __init__(self, exc):
            self.exc = exc

        def __del__(self):
            raise self.exc

    monkeypatch.setattr(cli, "_INTERRUPTS", [signal.SIGTERM])  # a termination under way
    monkeypatch.setattr(sys, "unraisablehook", cli._interrupt_again)
    with pytest.raises(KeyboardInterrupt):
        Finalizer(KeyboardInterrupt())  # dropped at once: its __del__ raises where nothing can catch it
        for _ in range(1000):  # raised again at the main thread's next check, well within this
            time.sleep(0.001)
    assert capsys.readouterr().err == ""
    Finalizer(ValueError("boom"))
    assert "boom" in capsys.readouterr().err


def test_an_interrupt_raised_again_is_not_lost_in_the_hook_on_a_loaded_machine(monkeypatch, ctrl_c_handled):
    """The interrupt was raised again from a 10 ms timer counted from the timer's own start: where starting a
    thread took longer (a loaded machine; CI failed so), it fired inside the hook, still in ``start()``, and was
    lost there as unraisable. The hook now returns first, and the interrupt comes after."""
    import threading
    import types

    import core.cli as cli

    start = threading.Thread.start

    def slow_start(self):  # a loaded machine: the starting thread gets the processor back late
        start(self)
        time.sleep(0.05)

    monkeypatch.setattr(threading.Thread, "start", slow_start)
    monkeypatch.setattr(cli, "_INTERRUPTS", [signal.SIGTERM])
    unraisable = types.SimpleNamespace(exc_value=KeyboardInterrupt())
    returned = False
    with pytest.raises(KeyboardInterrupt):
        cli._interrupt_again(unraisable)  # returns: the interrupt is not raised inside the hook
        returned = True
        for _ in range(1000):
            time.sleep(0.001)
    assert returned, "raised inside the hook, where it is lost"
