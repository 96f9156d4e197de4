"""Autosave and restore of the viewer's unsaved work (core.io.autosave, ViewerModel), without a screen.

An hour of manual alignment was lost to a crash or a killed session: nothing
was written between explicit saves. The viewer now autosaves a few seconds
after a change, offers the autosave on the next opening, and removes it when
the work is saved or deliberately discarded.
"""

from __future__ import annotations

import json
import os
import socket
import warnings
from pathlib import Path

import numpy as np
import pytest

from bgm_viewer.model import AUTOSAVE_DELAY_S, ViewerModel
from core.io.autosave import autosave_dir
from core.io.project import load_project


@pytest.fixture(scope="module")
def table_in_feet(tmp_path_factory) -> Path:
    """A small mine's table written in feet (a unit the viewer is told, or guesses)."""
    from core.io.blastholes import FEET_TO_METRES
    from core.synthetic.blobs import make_mine, sample_blastholes

    table = sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    for c in ("x", "y", "z"):
        table[c] = table[c] / FEET_TO_METRES
    path = tmp_path_factory.mktemp("table") / "holes.csv"
    table.to_csv(path, index=False)
    return path


class Clock:
    """A clock the test moves by hand (the autosave delay is measured on it)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def _model(path, clock: Clock, **read) -> ViewerModel:
    """A model of ``path`` read in feet (or as ``read`` says), its first bench pair corresponded."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ViewerModel(path, read_options=read or {"length_unit": "ft"})
        model.clock = clock
        model.select("g1", 0, 0)
        model.run(until="correspondence")
    model.dirty = False  # selecting is no change of the user's here
    return model


def _reopened(path, clock: Clock, project=None, **read) -> ViewerModel:
    """The session after a crash: the table (and project) opened again, as the window does."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ViewerModel(path, read_options=read)
        model.clock = clock
        if project is not None:
            model.load_project(project)
    return model


def _autosaved_after_save(path, tmp_path, nudge_m: float = 2.0) -> tuple[Clock, Path]:
    """A project saved to ``tmp_path/p.json``, then a nudge of ``nudge_m`` autosaved a delay later: the clock, the autosave."""
    clock = Clock()
    model = _model(path, clock)
    model.save_project(tmp_path / "p.json")
    model.nudge(nudge_m, 0.0)
    clock.now += AUTOSAVE_DELAY_S
    autosave = model.autosave()
    assert autosave is not None
    return clock, autosave


def test_an_override_is_autosaved_beside_the_project_once_a_burst_of_changes_is_a_delay_old(table_in_feet, tmp_path):
    clock = Clock()
    model = _model(table_in_feet, clock)
    project = tmp_path / "p.bgm.json"
    model.save_project(project)
    saved = project.read_bytes()
    autosave = tmp_path / "p.bgm.json.autosave"
    assert model.autosave_path == autosave

    model.nudge(3.0, 0.0)  # an override
    assert model.autosave() is None and not autosave.exists()  # not at once: a burst is written once
    for step in range(1, 6):  # a nudge and an exaggeration change a second for five seconds
        clock.now += 0.5
        model.nudge(0.5, 0.0)
        clock.now += 0.5
        model.set_view(vertical_exaggeration=2.0 + step)
        written = model.autosave()
        assert (written is not None) == (step == AUTOSAVE_DELAY_S), step  # once, a delay after the first change
        if step == AUTOSAVE_DELAY_S:
            assert written == autosave and autosave.is_file()
            assert model.autosave() is None  # nothing new since
    # the changes since: due a delay after the first of them (step 4's nudge, 1.5 s ago)
    assert model.autosave_due_in_s() == pytest.approx(AUTOSAVE_DELAY_S - 1.5)
    clock.now += AUTOSAVE_DELAY_S - 1.5
    assert model.autosave() == autosave

    assert project.read_bytes() == saved  # the user's project is never written by the autosave
    kept = load_project(autosave)
    assert kept.reading == {"units": "ft"}  # read again in feet, as the session read it
    assert Path(kept.input_path) == table_in_feet.resolve()
    mpu = model.holes.frame.metres_per_unit
    assert kept.overrides[0].translation == pytest.approx(np.divide(model.translation_m(), mpu))
    assert kept.parameters["viewer"]["vertical_exaggeration"] == 7.0


def test_restore_is_offered_on_reopening_and_gives_back_the_work_unsaved(table_in_feet, tmp_path):
    clock = Clock()
    model = _model(table_in_feet, clock)
    project = tmp_path / "p.bgm.json"
    model.save_project(project)
    model.nudge(4.0, -2.0)
    model.set_param("gvf_mu", 0.12)
    model.run(until="correspondence")  # the overrides placed under the new parameter
    clock.now += AUTOSAVE_DELAY_S
    assert model.autosave() is not None
    want = model.translation_m()
    del model  # the viewer crashed

    again = _reopened(table_in_feet, clock, project, length_unit="ft")
    assert again.translation_m() is None and again.param("gvf_mu") != 0.12  # the project lacks the work
    offer = again.autosave_offer()
    assert offer is not None and offer.path == tmp_path / "p.bgm.json.autosave"
    restored = again.restored(offer)
    assert restored.dirty and restored.project_path == str(project)  # Save writes it to the project
    assert restored.param("gvf_mu") == pytest.approx(0.12)
    assert restored.holes is again.holes  # read the same way: not read again
    restored.run(until="correspondence")
    np.testing.assert_allclose(restored.translation_m(), want, atol=1e-9)
    assert offer.path.exists()  # kept until saved: a second crash loses nothing either


def test_declining_the_restore_removes_the_autosave(table_in_feet, tmp_path):
    clock, autosave = _autosaved_after_save(table_in_feet, tmp_path)

    again = _reopened(table_in_feet, clock, tmp_path / "p.json")
    assert again.autosave_offer() is not None
    again.discard_autosave()  # No
    assert not autosave.exists() and again.autosave_offer() is None
    assert (tmp_path / "p.json").exists()


def test_an_explicit_save_removes_the_autosave(table_in_feet, tmp_path):
    """Of a saved project, and of a never-saved one (the table's) once saved."""
    clock = Clock()
    model = _model(table_in_feet, clock)
    model.nudge(2.0, 0.0)
    clock.now += AUTOSAVE_DELAY_S
    unsaved = model.autosave()
    assert unsaved is not None and unsaved.parent == autosave_dir()
    model.save_project(tmp_path / "p.json")
    assert not unsaved.exists()

    model.nudge(1.0, 0.0)
    clock.now += AUTOSAVE_DELAY_S
    beside = model.autosave()
    assert beside == tmp_path / "p.json.autosave" and beside.exists()
    model.save_project(tmp_path / "p.json")
    assert not beside.exists() and not model.dirty
    assert load_project(tmp_path / "p.json").overrides  # saved, not lost
    assert _reopened(table_in_feet, clock, tmp_path / "p.json").autosave_offer() is None


@pytest.mark.parametrize(
    "content, reason",
    [
        ('{"format": "bgm-project", "version": 2, "parameters": {"gvf', "corrupt (not valid JSON"),  # half written
        ("", "corrupt (not valid JSON"),
        ('{"format": "bgm-project", "version": 1, "parameters": {"gvf_mu": -4}}', "parameter gvf_mu must be"),
        ('{"format": "bgm-project", "version": 1}', "names no table"),
        ("[1, 2]", "is not a BGM project file"),
    ],
)
def test_a_corrupt_autosave_is_set_aside_with_a_message(table_in_feet, tmp_path, content, reason):
    clock = Clock()
    model = _model(table_in_feet, clock)
    model.save_project(tmp_path / "p.json")
    autosave = tmp_path / "p.json.autosave"
    autosave.write_text(content)

    again = _reopened(table_in_feet, clock, tmp_path / "p.json")
    assert again.autosave_offer() is None
    assert again.autosave_note is not None
    assert str(autosave) in again.autosave_note and "ignored" in again.autosave_note
    assert reason in again.autosave_note, again.autosave_note
    # Set aside, kept under the name the note gives, and not reported at every opening after.
    aside = [p for p in tmp_path.iterdir() if p.name.startswith("p.json.autosave.failed-")]
    assert len(aside) == 1 and not autosave.exists() and aside[0].read_text() == content
    assert str(aside[0]) in again.autosave_note and "not be offered again" in again.autosave_note
    third = _reopened(table_in_feet, clock, tmp_path / "p.json")
    assert third.autosave_offer() is None and third.autosave_note is None


def test_a_never_saved_projects_autosave_is_kept_per_table_and_restores_its_reading(
    table_in_feet, tmp_path, monkeypatch
):
    """Keyed by the table's absolute path, in the user's state folder (never beside the table);
    restored with the table read as the session read it, though opened this time without --units."""
    clock = Clock()
    model = _model(table_in_feet, clock)
    model.nudge(5.0, 1.0)
    clock.now += AUTOSAVE_DELAY_S
    autosave = model.autosave()
    assert autosave is not None and autosave.parent == autosave_dir() and "holes" in autosave.name
    assert sorted(p.name for p in table_in_feet.parent.iterdir()) == ["holes.csv"]  # nothing beside the table
    want = model.translation_m()

    other = tmp_path / "other.csv"
    other.write_bytes(table_in_feet.read_bytes())
    assert _reopened(other, clock).autosave_offer() is None  # another table: another autosave

    monkeypatch.chdir(table_in_feet.parent)  # the same table, named from its folder
    again = _reopened("holes.csv", clock, length_unit="m")  # and read in metres this time
    offer = again.autosave_offer()
    assert offer is not None and offer.path == autosave
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        restored = again.restored(offer)
        restored.run(until="correspondence")
    assert restored.holes.frame.length_unit == "ft" and restored.project_path is None and restored.dirty
    np.testing.assert_allclose(restored.translation_m(), want, atol=1e-9)


def test_an_autosave_older_than_the_saved_project_is_not_offered(table_in_feet, tmp_path):
    """The project was saved after it (by another viewer): the later work is the project's."""
    clock, autosave = _autosaved_after_save(table_in_feet, tmp_path)
    stamp = (tmp_path / "p.json").stat().st_mtime
    os.utime(autosave, (stamp - 60, stamp - 60))
    assert _reopened(table_in_feet, clock, tmp_path / "p.json").autosave_offer() is None


def test_the_autosave_is_not_written_through_a_link_to_the_project(table_in_feet, tmp_path):
    clock = Clock()
    model = _model(table_in_feet, clock)
    model.save_project(tmp_path / "p.json")
    saved = (tmp_path / "p.json").read_bytes()
    (tmp_path / "p.json.autosave").symlink_to(tmp_path / "p.json")
    model.nudge(2.0, 0.0)
    clock.now += AUTOSAVE_DELAY_S
    assert model.autosave() is None and "is a link" in model.autosave_note
    assert (tmp_path / "p.json").read_bytes() == saved


def test_the_autosave_waits_for_the_run_that_places_the_overrides_under_a_changed_parameter(table_in_feet, tmp_path):
    """Written before, it held the overrides by their components' numbers under a parameter they
    were not placed under (what Save refuses): restored, they would name other components."""
    clock = Clock()
    model = _model(table_in_feet, clock)
    model.save_project(tmp_path / "p.json")
    model.nudge(2.0, 0.0)
    model.set_param("gvf_mu", 0.12)
    clock.now += AUTOSAVE_DELAY_S
    assert model.autosave() is None and model.autosave_due_in_s() == pytest.approx(AUTOSAVE_DELAY_S)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until="correspondence")
    clock.now += AUTOSAVE_DELAY_S
    assert model.autosave() is not None
    assert load_project(tmp_path / "p.json.autosave").parameters["gvf_mu"] == 0.12


def test_bgm_build_reads_the_project_not_its_autosave(table_in_feet, tmp_path):
    """The autosave is the viewer's: the command line reads the project the user saved, and only it."""
    from clirun import bgm

    clock = Clock()
    model = _model(table_in_feet, clock)
    model.save_project(tmp_path / "p.json")
    (tmp_path / "p.json.autosave").write_text(json.dumps({"format": "bgm-project", "version": 1, "parameters": 5}))
    out = tmp_path / "c.json"
    run = bgm("correspond", table_in_feet, "--geozone", "g1", "--project", tmp_path / "p.json", "--out", out)
    assert run.returncode == 0, run.stderr
    assert "autosave" not in run.stderr


def test_an_autosave_that_fails_to_restore_is_set_aside_and_not_offered_again(table_in_feet, tmp_path):
    """The table changed (cut to a corner of the pit) so the autosaved override no longer fits it: the
    restore fails, and the autosave was offered, and failed, at every opening. It is now kept under
    another name the message gives, and the next opening offers nothing."""
    import pandas as pd

    from core.errors import BGMInputError

    table = tmp_path / "holes.csv"
    table.write_bytes(table_in_feet.read_bytes())
    clock, autosave = _autosaved_after_save(table, tmp_path, nudge_m=60.0)  # the pit spans 140 m; then a crash
    kept = autosave.read_bytes()

    holes = pd.read_csv(table)
    corner = (holes.x < holes.x.min() + 131) & (holes.y < holes.y.min() + 131)  # 40 m, in feet
    holes[corner].to_csv(table, index=False)
    again = _reopened(table, clock, tmp_path / "p.json", length_unit="ft")
    offer = again.autosave_offer()
    assert offer is not None
    with pytest.raises(BGMInputError) as failed:
        again.restored(offer)
    aside = [p for p in tmp_path.iterdir() if p.name.startswith("p.json.autosave.failed-")]
    assert len(aside) == 1 and not autosave.exists()
    assert aside[0].read_bytes() == kept  # nothing lost
    message = str(failed.value)
    assert str(aside[0]) in message and "not be offered again" in message and "more than the whole input" in message
    assert _reopened(table, clock, tmp_path / "p.json", length_unit="ft").autosave_offer() is None


#: Another viewer: writes the project's autosave as a viewer does, then runs until its standard input closes.
OTHER_VIEWER = """
import sys
from core.io.autosave import write_autosave
from core.io.project import load_project
write_autosave(load_project(sys.argv[1]), sys.argv[2], sys.argv[1], sys.argv[3])
print("written", flush=True)
sys.stdin.read()
"""


def test_two_viewers_on_one_project_keep_each_their_autosave(table_in_feet, tmp_path):
    """Two viewers on one project shared its autosave and the last to write won. A viewer that finds
    the autosave of another running now neither offers it nor overwrites it: it autosaves to a name of
    its own and says so; once that other has ended, its autosave is offered again."""
    import subprocess
    import sys

    clock = Clock()
    first = _model(table_in_feet, clock)  # opened before the other viewer autosaved
    project = tmp_path / "p.json"
    first.save_project(project)
    base = tmp_path / "p.json.autosave"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    other = subprocess.Popen(
        [sys.executable, "-c", OTHER_VIEWER, str(project), str(base), str(table_in_feet)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert other.stdout is not None and other.stdout.readline().strip() == "written"
        theirs = base.read_bytes()
        assert json.loads(theirs)["autosave"]["writer"]["pid"] == other.pid

        first.nudge(2.0, 0.0)
        clock.now += AUTOSAVE_DELAY_S
        mine = first.autosave()
        assert mine is not None and mine != base and str(os.getpid()) in mine.name
        assert base.read_bytes() == theirs  # not overwritten
        assert str(other.pid) in first.autosave_note and str(mine) in first.autosave_note

        second = _reopened(table_in_feet, clock, project, length_unit="ft")  # opened while the other runs
        assert second.autosave_offer() is None
        assert str(base) in second.autosave_note and str(other.pid) in second.autosave_note
        assert second.autosave_path == mine.with_name(f"p.json.autosave-{os.getpid()}")
    finally:
        other.communicate("")  # the other viewer ends
    assert other.returncode == 0

    after = _reopened(table_in_feet, clock, project, length_unit="ft")
    offer = after.autosave_offer()
    assert offer is not None and offer.path == base  # no viewer writes it now: offered
    after.discard_autosave()
    offer = _reopened(table_in_feet, clock, project, length_unit="ft").autosave_offer()
    assert offer is not None and offer.path == mine  # the one this session wrote under its own name


def test_a_writer_whose_process_id_was_reused_or_is_on_another_machine_is_no_running_viewer(tmp_path):
    """A crashed viewer's process id, reused by another program, hid its autosave forever."""
    from core.io.autosave import _process_start, live_writer

    path = tmp_path / "p.json.autosave"
    parent = os.getppid()  # a process that runs now, not this one

    def written(**writer) -> Path:
        path.write_text(json.dumps({"autosave": {"writer": writer}}))
        return path

    host = socket.gethostname()
    started = _process_start(parent)
    assert live_writer(written(pid=parent, host=host, started=started)) is not None
    assert live_writer(written(pid=os.getpid(), host=host, started=_process_start(os.getpid()))) is None  # this one
    assert live_writer(written(pid=parent, host=host + "-elsewhere", started=started)) is None
    if started is not None:  # where the start of a process can be told (Linux)
        assert live_writer(written(pid=parent, host=host, started=started + 1)) is None
