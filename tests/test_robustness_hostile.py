"""Hostile and careless input, class by class (issue 15), on generated cases.

Every class of failure the issue lists has at least two cases here, drawn
from seeded random generators rather than picked by hand: hostile geozone
labels, output paths that are inputs or devices, options that used to end as
"internal error", labels spelling one number two ways, coordinates in degrees,
uneven benches, elevations far outside the model, unused project overrides,
out-of-range parameters, degenerate cameras and blank pictures, isolated holes
and the frontier fill, STL precision, wide headers, decimal commas, comment
lines, compressed and mis-named files, standard input, huge labels.

Each case asserts the exit status, one ``bgm: error:`` line and no traceback
(or a correct result, with the warning where one is due), and that no file
that existed before changed. The command line runs in this process
(tests/clirun.py) to keep the suite fast; the kill test is in
test_robustness_kill.py.

Class -> tests:

* unsafe geozone folders, report/summary mapping: test_hostile_labels_get_safe_unique_folders
* outputs that are inputs, devices, outside --out: test_outputs_never_replace_inputs_or_devices,
  test_build_never_replaces_a_folder_it_did_not_write
* every write atomic: test_no_module_writes_outside_the_atomic_helper, test_a_build_opens_files_only_through_atomic_writes,
  test_a_signal_while_a_set_of_files_is_moved_in_waits_for_the_whole_set
* interrupted build keeps the previous model: test_interrupted_build_keeps_the_previous_model (and the kill test)
* Ctrl-C: exit 130, one line, workers included: test_ctrl_c_on_a_parallel_build_is_one_line (and the kill test)
* user errors that were exit 3: test_user_errors_exit_2_with_one_line
* labels 3310 / 3310.0: test_number_spellings_of_one_label_are_merged_with_a_warning (and test_properties.py),
  test_codes_with_leading_zeros_are_never_merged, test_a_float_column_gives_the_same_labels_from_csv_and_parquet,
  test_labels_differing_only_by_case_are_kept_with_a_warning
* degrees: test_degrees_are_refused
* an identifier column read as geozones: test_an_identifier_read_as_geozones_is_warned_about
* depths given as z: test_a_depth_column_given_as_z_is_warned_about,
  test_depths_in_a_column_named_as_elevations_are_warned_about
* uneven benches, z without benches: test_uneven_benches_are_taken_as_measured, test_z_that_forms_no_benches_is_refused
* far elevations: test_far_elevations_need_force
* unused overrides: test_unused_overrides_are_named
* parameter ranges: test_out_of_range_parameters_are_refused
* degenerate cameras, blank render: test_user_errors_exit_2_with_one_line, test_blank_pictures_are_errors
* frontier fill from isolated holes: test_isolated_holes_grow_no_body
* STL truth: test_hostile_labels_get_safe_unique_folders (STL read back), test_surfaces.py
* wide headers: test_wide_headers_parse_only_the_needed_columns
* decimal commas, comment lines, compressed/mis-named files, stdin, huge labels:
  test_decimal_commas_read_as_numbers, test_comment_lines_before_the_header, test_compressed_and_misnamed_files,
  test_standard_input, test_huge_labels_are_shortened_in_messages
* "on one bench only" said of geozones on several benches: test_hostile_labels_get_safe_unique_folders
* rows longer than the header (an unquoted delimiter): test_rows_longer_than_the_header_are_refused
* empty rows, line numbers after blank lines: test_empty_rows_are_skipped_and_lines_named_as_in_the_file
* a bench height that puts several benches on one: test_a_bench_height_that_puts_several_benches_on_one_is_refused
* a bench height other than the collars': test_a_bench_height_keeps_the_levels_where_the_collars_are
"""

from __future__ import annotations

import ast
import builtins
import bz2
import contextlib
import errno
import gzip
import hashlib
import io
import json
import lzma
import os
import re
import signal
import subprocess
import sys
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import shapely
import trimesh
from clirun import BGM, bgm, error_line, is_message, no_traceback, snapshot, succeeds, unchanged, warnings_of

from core.errors import BGMWarning
from core.io.blastholes import blastholes_from_table, read_blastholes
from core.synthetic.blobs import make_mine, sample_blastholes

ROOT = Path(__file__).resolve().parent.parent
ORIGIN = (650_000.0, 7_400_000.0)


def rng_for(*key) -> np.random.Generator:
    """A generator seeded by ``key`` (the same cases on every run and machine)."""
    return np.random.default_rng(int(hashlib.sha1(repr(("issue-15", *key)).encode()).hexdigest()[:12], 16))


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    """A small 3-bench synthetic mine in mine-grid coordinates (about 250 holes, 4 geozones)."""
    mine = make_mine(seed=11, n_benches=3, extent_m=(60.0, 45.0), origin=ORIGIN)
    return sample_blastholes(mine, seed=12)


@pytest.fixture
def csv(table, tmp_path) -> Path:
    path = tmp_path / "in" / "holes.csv"
    path.parent.mkdir()
    table.to_csv(path, index=False)
    return path


def quiet_read(path_or_table, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        if isinstance(path_or_table, pd.DataFrame):
            return blastholes_from_table(path_or_table, **kw)
        return read_blastholes(path_or_table, **kw)


# --------------------------------------------------------------------------- data loss


def hostile_labels(rng) -> list[str]:
    """Four labels that break naive folder names: traversal, a separator and its look-alike, length or reserved names."""
    word = "".join(rng.choice(list("abkxz"), 3))
    traversal = str(rng.choice(["..", ".", f"../{word}", f"..\\{word}", f"/{word}"]))
    tail = "".join(rng.choice(list("pqr"), 2))
    big = str(rng.choice(["CON", "nul", "com1", "summary.json", "Report.MD", "x" * int(rng.integers(256, 400))]))
    return [traversal, f"{word}/{tail}", f"{word}_{tail}", big]


@pytest.mark.parametrize("seed", [0, 1])
def test_hostile_labels_get_safe_unique_folders(table, tmp_path, seed):
    labels = hostile_labels(rng_for("labels", seed))
    mapping = dict(zip(sorted(set(table.geozone)), labels))
    t = table.assign(geozone=table.geozone.map(mapping))
    # A fifth geozone of lone holes on every bench: never a component to model.
    lone = t.groupby((t.z - t.z.max()).round(-1)).head(1).index
    t.loc[lone, "geozone"] = "lone"
    path = tmp_path / "holes.csv"
    t.to_csv(path, index=False)
    out = tmp_path / "out" / "model"
    out.parent.mkdir()
    before = snapshot(tmp_path)
    succeeds(bgm("build", path, "--out", out, "--workers", 2))
    unchanged(before, snapshot(tmp_path), allow_new=[out])  # nothing outside --out
    summary = json.loads((out / "summary.json").read_text())
    by_label = {g["geozone"]: g for g in summary["geozones"]}
    assert set(by_label) == {*labels, "lone"}
    folders = [g["folder"] for g in by_label.values()]
    assert len({f.casefold() for f in folders}) == len(folders)  # unique, even on a case-insensitive disk
    report = (out / "report.md").read_text()
    for label, g in by_label.items():
        folder = out / g["folder"]
        assert folder.parent == out and folder.is_dir() and g["folder"] not in (".", "..")
        assert len(g["folder"]) <= 64 and "/" not in g["folder"] and "\\" not in g["folder"]
        assert f"`{g['folder']}`" in report and label[:40].replace("|", "\\|") in report
        if g["volume"] is None:
            continue
        # The report's volume is this folder's surface, not another geozone's.
        ply = trimesh.load(out / g["files"]["ply"], force="mesh")
        assert Path(g["files"]["ply"]).parts[0] == g["folder"]
        assert ply.volume == pytest.approx(g["volume"], rel=1e-6)
        # STL holds mine-grid coordinates only in a local frame, and is closed as written.
        stl = trimesh.load(out / g["files"]["stl"], force="mesh")
        assert stl.is_watertight == g["formats"]["stl"]["watertight"] == g["watertight"], (
            label,
            stl.is_watertight,
            g["formats"]["stl"],
            g["watertight"],
        )
        assert np.allclose(stl.bounds.mean(axis=0)[:2] + g["formats"]["stl"]["offset"][:2], ORIGIN, atol=500)
    assert "on 3 benches" in by_label["lone"]["note"] and "one bench" not in by_label["lone"]["note"]


def _link(kind: str, source: Path, where: Path) -> Path:
    target = where / f"{kind}-{source.name}"
    if kind == "same":
        return source
    if kind == "symlink":
        target.symlink_to(source)
    elif kind == "hardlink":
        os.link(source, target)
    elif kind == "device":
        return Path(os.devnull)
    elif kind == "folder":
        target.mkdir()
    return target


OUTPUT_COMMANDS = {
    "contours": lambda inp, out: ("contours", inp, "--out", out),
    "correspond": lambda inp, out: ("correspond", inp, "--geozone", "g1", "--out", out),
    "morph": lambda inp, out: ("morph", inp, "--geozone", "g1", "--out", out),
    "predict": lambda inp, out: ("predict", inp, "--geozone", "g1", "--elevations", "660", "--out", out),
    "screenshot": lambda inp, out: ("view", inp, "--screenshot", out),
    "demo data": lambda inp, out: ("make-demo-data", "--out", out),
}


@pytest.mark.parametrize("command", list(OUTPUT_COMMANDS))
@pytest.mark.parametrize("kind", ["same", "symlink", "hardlink", "device", "folder"])
def test_outputs_never_replace_inputs_or_devices(csv, tmp_path, command, kind):
    if command == "demo data" and kind in ("same", "symlink", "hardlink"):
        pytest.skip("make-demo-data reads no input")
    if command == "screenshot":
        pytest.importorskip("pyvista")
    out = _link(kind, csv, tmp_path)
    before = snapshot(tmp_path, Path(os.devnull))
    line = error_line(bgm(*OUTPUT_COMMANDS[command](csv, out)))
    assert any(w in line for w in ("is the input", "device", "directory")), line
    unchanged(before, snapshot(tmp_path, Path(os.devnull)))


@pytest.mark.parametrize("command", list(OUTPUT_COMMANDS))
def test_an_output_no_file_can_be_made_in_is_refused_before_the_table_is_read(csv, command):
    """/proc takes no new file, even from root, whom permissions do not stop: refused before any work."""
    if not Path("/proc/self").exists():
        pytest.skip("no /proc here")
    if command == "screenshot":
        pytest.importorskip("pyvista")
    suffix = ".png" if command == "screenshot" else ".csv" if command == "demo data" else ".geojson"
    run = bgm(*OUTPUT_COMMANDS[command](csv, Path("/proc") / f"bgm-{command.replace(' ', '-')}{suffix}"))
    error_line(run, "cannot write", "/proc")
    assert "holes" not in run.stdout + run.stderr.replace("/proc", "")  # no input summary: the table was not read


@pytest.mark.parametrize("case", ["input inside", "a file", "foreign files", "model plus a file"])
def test_build_never_replaces_a_folder_it_did_not_write(csv, tmp_path, case):
    if case == "input inside":
        out = csv.parent
    elif case == "a file":
        out = tmp_path / "plain.txt"
        out.write_text("keep me")
    else:
        out = tmp_path / "folder"
        out.mkdir()
        (out / "notes.txt").write_text(str(rng_for(case).random()))
        if case == "model plus a file":
            (out / "summary.json").write_text(json.dumps({"input": "x.csv", "geozones": []}))
    before = snapshot(tmp_path)
    error_line(bgm("build", csv, "--out", out))
    unchanged(before, snapshot(tmp_path))


ATOMIC_ALLOWED = {"atomic.py"}  # the helper itself
WRITERS = {
    "write_text",
    "write_bytes",
    "to_csv",
    "to_parquet",
    "to_json",
    "to_excel",
    "to_pickle",
    "to_file",
    "write_table",
    "savefig",
    "imsave",
    "save",
    "savez",
    "savez_compressed",
    "savetxt",
    "screenshot",
    "export",
}


def _unsafe_writes(path: Path) -> list[str]:
    """Calls in ``path`` that write a file not given them by ``atomic_path``.

    A write is safe when its target is a name bound by ``with atomic_path(...) as NAME`` (or a
    writer's ``tmp`` parameter, which only ever receives one); ``to_csv(index=False)`` returning a
    string and ``screenshot(None, ...)`` returning an image write nothing.
    """
    tree = ast.parse(path.read_text())
    safe = {"tmp"} | {
        item.optional_vars.id
        for node in ast.walk(tree)
        if isinstance(node, ast.With)
        for item in node.items
        if isinstance(item.context_expr, ast.Call)
        and getattr(item.context_expr.func, "id", getattr(item.context_expr.func, "attr", "")) == "atomic_path"
        and isinstance(item.optional_vars, ast.Name)
    }
    bad = []
    for node in ast.walk(tree):
        target = _write_target(node) if isinstance(node, ast.Call) else None
        if target is None or (isinstance(target, ast.Constant) and target.value is None):
            continue
        if _root_name(target) not in safe:
            bad.append(f"{path}:{node.lineno}: {ast.unparse(node)[:80]}")
    return bad


def _write_target(call: ast.Call):
    """The path a call writes to, or None when it writes no file."""
    func = call.func
    if isinstance(func, ast.Name) and func.id == "open":
        mode = call.args[1] if len(call.args) > 1 else next((k.value for k in call.keywords if k.arg == "mode"), None)
        writes = isinstance(mode, ast.Constant) and any(c in str(mode.value) for c in "wax+")
        return call.args[0] if writes else None
    if not (isinstance(func, ast.Attribute) and func.attr in WRITERS):
        return None
    if func.attr in ("write_text", "write_bytes"):
        return func.value
    return call.args[0] if call.args else None


def _root_name(expr) -> str | None:
    """The variable an expression starts from: ``tmp`` in ``str(tmp)``, ``tmp.parent``, ``tmp[0]``."""
    while isinstance(expr, (ast.Call, ast.Attribute, ast.Subscript)):
        expr = expr.args[0] if isinstance(expr, ast.Call) and expr.args else getattr(expr, "value", None)
    return expr.id if isinstance(expr, ast.Name) else None


def test_no_module_writes_outside_the_atomic_helper(tmp_path):
    sources = [p for d in ("core", "bgm_viewer") for p in (ROOT / d).rglob("*.py") if p.name not in ATOMIC_ALLOWED]
    assert len(sources) > 30
    bad = [b for p in sources for b in _unsafe_writes(p)]
    assert not bad, "\n".join(bad)
    # The scan finds direct writes (it is not a test that cannot fail).
    probe = tmp_path / "probe.py"
    probe.write_text(
        "def f(df, fig, plotter, out):\n"
        "    df.to_csv(out / 'a.csv')\n    out.write_text('x')\n    fig.savefig(str(out))\n"
        "    plotter.screenshot(out)\n    open(out, 'w')\n"
        "    with atomic_path(out) as t:\n        df.to_csv(t)\n        t.write_text('ok')\n"
    )
    assert len(_unsafe_writes(probe)) == 5


def _recording_opens(monkeypatch) -> list[str]:
    """Record every file opened for writing through Python (``open``, ``io.open``, ``Path.write_*``)."""
    opened: list[str] = []
    real_open = builtins.open

    def recording_open(file, mode="r", *args, **kwargs):
        if isinstance(file, (str, os.PathLike)) and any(c in mode for c in "wax+"):
            opened.append(os.fspath(file))
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", recording_open)
    monkeypatch.setattr(io, "open", recording_open)
    return opened


def test_a_build_opens_files_only_through_atomic_writes(table, tmp_path, monkeypatch):
    holes = quiet_read(table, source=str(tmp_path / "x.csv"))
    opened = _recording_opens(monkeypatch)
    from core.model.build import build

    build(holes, tmp_path / "model", workers=1)
    monkeypatch.undo()
    assert opened
    staged = [p for p in opened if ".bgm-staging-" in p]
    assert staged == opened  # everything went into the staging folder first
    # ...and each file there through a temporary name next to its destination.
    assert all(Path(p).name.startswith(".") for p in opened), [p for p in opened if not Path(p).name.startswith(".")]
    assert not [p for p in tmp_path.iterdir() if ".bgm-" in p.name]  # staging swapped in and gone


@pytest.mark.parametrize("seed", [0, 1])
def test_interrupted_build_keeps_the_previous_model(table, tmp_path, monkeypatch, seed):
    import core.io.atomic as atomic
    from core.model.build import build

    holes = quiet_read(table, source=str(tmp_path / "x.csv"))
    out = tmp_path / "model"
    real = atomic.atomic_path
    calls = {"n": 0, "stop": 0}

    def counted(path, *a, **k):
        calls["n"] += 1
        if calls["n"] == calls["stop"]:
            raise KeyboardInterrupt
        return real(path, *a, **k)

    users = [m for m in list(sys.modules.values()) if getattr(m, "atomic_path", None) is real]
    for module in users:
        monkeypatch.setattr(module, "atomic_path", counted)
    build(holes, out, workers=1, formats=("ply", "stl"))
    before = snapshot(tmp_path)
    # Interrupt the next build at a random one of its writes (the last is the report).
    calls["stop"] = calls["n"] + int(rng_for("interrupt", seed).integers(1, calls["n"] + 1))
    with pytest.raises(KeyboardInterrupt):
        build(holes, out, workers=1, formats=("ply", "stl"))
    monkeypatch.undo()
    unchanged(before, snapshot(tmp_path))  # previous model as it was, no staging folder left


def test_folder_swap_without_an_atomic_exchange(tmp_path, monkeypatch):
    """Where the system cannot exchange two folders in one step, two renames still replace the folder whole."""
    import core.io.atomic as atomic

    for exchange in (True, False):
        out = tmp_path / f"model-{exchange}"
        out.mkdir()
        (out / "old.txt").write_text("old")
        if not exchange:
            monkeypatch.setattr(atomic, "_exchange", lambda a, b: False)
        with atomic.replaced_folder(out) as staging:
            (staging / "new.txt").write_text("new")
            assert sorted(p.name for p in out.iterdir()) == ["old.txt"]  # untouched until the end
        assert sorted(p.name for p in out.iterdir()) == ["new.txt"]
        assert sorted(p.name for p in tmp_path.iterdir() if ".bgm-" in p.name) == []
        with pytest.raises(RuntimeError), atomic.replaced_folder(out) as staging:
            (staging / "half.txt").write_text("half")
            raise RuntimeError("failed half way")
        assert sorted(p.name for p in out.iterdir()) == ["new.txt"]
        assert sorted(p.name for p in tmp_path.iterdir() if ".bgm-" in p.name) == []


def test_a_set_of_files_is_replaced_whole_or_not_at_all(tmp_path):
    """:func:`core.io.atomic.replaced_files`: a file that is a link to another folder is written through it."""
    import core.io.atomic as atomic

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "target.geojson").write_text("old target")
    (tmp_path / "p.geojson").symlink_to(elsewhere / "target.geojson")
    (tmp_path / "p.npz").write_text("old npz")
    paths = [tmp_path / "p.geojson", tmp_path / "p.npz", tmp_path / "new" / "deeper" / "q.csv", tmp_path / "n" / "r"]
    before = snapshot(tmp_path)
    with pytest.raises(RuntimeError), atomic.replaced_files(paths) as staged:
        for f in staged[:2]:
            f.write_text("new")
        raise RuntimeError("failed before the last file")
    unchanged(before, snapshot(tmp_path))
    with atomic.replaced_files(paths) as staged:
        assert [f.name for f in staged] == ["target.geojson", "p.npz", "q.csv", "r"]
        for f in staged:
            f.write_text("new")
        during = snapshot(tmp_path)
        unchanged(before, during, allow_new=[k for k in during if ".bgm-staging-" in k])  # nothing moved in yet
    assert (tmp_path / "p.geojson").is_symlink() and (elsewhere / "target.geojson").read_text() == "new"
    assert [p.read_text() for p in paths[1:]] == ["new", "new", "new"]
    assert not [p for p in tmp_path.rglob("*") if ".bgm-" in p.name]


#: A process that replaces three files with :func:`core.io.atomic.replaced_files` and gets a signal (argv[2]) right
#: after the first rename, handled by Python's default or by ``bgm``'s handler (argv[3]).
SIGNALLED_SET = """
import os, signal, sys
from pathlib import Path
import core.io.atomic as atomic
from core import cli

folder, signum, handler = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
if handler == "bgm":
    signal.signal(signum, cli._on_ctrl_c)
elif signum == signal.SIGINT:  # Python's own, as under a terminal (a run in a script's background has it ignored)
    signal.signal(signum, signal.default_int_handler)
replace, done = os.replace, []

def replace_then_signal(src, dst):
    replace(src, dst)
    done.append(dst)
    if len(done) == 1:
        os.kill(os.getpid(), signum)

atomic.os.replace = replace_then_signal
paths = [folder / n for n in ("p.geojson", "p.uncertainty.geojson", "p.uncertainty.npz")]
with atomic.replaced_files(paths) as staged:
    for f in staged:
        f.write_text("new")
print("went on")
"""


@pytest.mark.parametrize(
    ("sig", "handler"), [(signal.SIGTERM, "default"), (signal.SIGTERM, "bgm"), (signal.SIGINT, "default")]
)
def test_a_signal_while_a_set_of_files_is_moved_in_waits_for_the_whole_set(tmp_path, sig, handler):
    """``kill`` between two renames of ``bgm predict``'s three files (only Ctrl-C was held) left the new prediction
    beside the previous uncertainty files. Held until the set is in, then the process ends as the signal says."""
    names = ["p.geojson", "p.uncertainty.geojson", "p.uncertainty.npz"]
    for name in names:
        (tmp_path / name).write_text("old")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run(
        [sys.executable, "-c", SIGNALLED_SET, str(tmp_path), str(int(sig)), handler],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    assert [(tmp_path / n).read_text() for n in names] == ["new"] * 3, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names)  # no staging folder left
    assert "went on" not in proc.stdout  # the signal still stopped it, once the set was in
    # SIGTERM's default ends the process by it; a KeyboardInterrupt left uncaught, by SIGINT (as Python exits then).
    ended = -sig if (sig, handler) == (signal.SIGTERM, "default") else -signal.SIGINT
    assert proc.returncode == ended, (proc.returncode, proc.stderr)


# --------------------------------------------------------------------------- exit codes


def test_ctrl_c_on_a_parallel_build_is_one_line(csv, tmp_path):
    """SIGINT to the whole process group (as a terminal sends it) during a 2-worker build."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("BGM_DEBUG", None)
    interrupted = 0
    for k, delay in enumerate(rng_for("ctrl-c").uniform(1.5, 3.0, 2)):
        out = tmp_path / f"model{k}"
        proc = subprocess.Popen(
            [*BGM, "build", csv, "--out", out, "--workers", "2"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
            env=env,
        )
        time.sleep(delay)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        if proc.returncode == 0:  # finished before the signal
            continue
        interrupted += 1
        assert proc.returncode == 130, err
        lines = [line for line in err.splitlines() if line.strip()]
        assert "Traceback" not in err and lines[-1].startswith("bgm: interrupted"), err
        assert len([line for line in lines if line.startswith("bgm:") and is_message(line)]) == 1, err
        # No half model: none at all, or (a Ctrl-C a library swallowed) a whole one.
        assert not out.exists() or json.loads((out / "summary.json").read_text())["geozones"]
        assert not [p for p in tmp_path.iterdir() if ".bgm-" in p.name]
    assert interrupted


def test_a_swallowed_ctrl_c_ends_the_command_at_its_next_step(monkeypatch):
    """A Ctrl-C a library caught (it is remembered, not raised) stops the work at the next progress step."""
    from core import cli

    with cli.progress_bar("building") as update:
        update(1, 3)  # no Ctrl-C: the work goes on
        monkeypatch.setattr(cli, "_INTERRUPTS", [signal.SIGINT])
        with pytest.raises(KeyboardInterrupt):
            update(2, 3)


def _wait_ignoring_ctrl_c() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    time.sleep(60)


def test_an_interrupted_command_leaves_no_worker_behind():
    """What ``bgm`` does on its way out after a Ctrl-C: a worker that ignores Ctrl-C is ended, not orphaned."""
    import multiprocessing

    from core.cli import _stop_worker_processes

    worker = multiprocessing.get_context("fork").Process(target=_wait_ignoring_ctrl_c)
    worker.start()
    _stop_worker_processes()
    worker.join(timeout=10)
    assert not worker.is_alive() and worker.exitcode == -signal.SIGTERM


def _garbage(rng, n=8) -> str:
    return "".join(rng.choice(list("abcdefghij-_#@"), n))


def user_error_cases(csv: Path, tmp_path: Path) -> list[tuple]:
    """(args, phrase) of the user errors that used to end as "internal error" (exit 3), with random values."""
    rng = rng_for("user errors")
    a_file = tmp_path / "afile.txt"
    a_file.write_text("x")
    folder = tmp_path / "shots"
    folder.mkdir()
    project = tmp_path / "project.json"
    shift = float(10.0 ** rng.uniform(7, 300))
    project.write_text(
        json.dumps(
            {
                "format": "bgm-project",
                "version": 1,
                "overrides": [{"geozone": "g1", "source_z": 685.0, "source": 0, "translation": [shift, 0.0]}],
            }
        )
    )
    view_project = tmp_path / "view.json"
    ratio = str(rng.choice(["Infinity", "-Infinity", "0", "-2", "1e300"]))
    view = '{"vertical_exaggeration": RATIO}'.replace("RATIO", ratio)  # JSON as Python writes it: Infinity too
    view_project.write_text(f'{{"format": "bgm-project", "version": 1, "parameters": {{"viewer": {view}}}}}')
    proc = f"/proc/{_garbage(rng, 5)}/out"
    vertical = f"0,0,{rng.uniform(-5, 5):.3f}"
    return [
        (("build", csv, "--out", a_file), "is a file"),
        (("evaluate", csv, "--geozone", "g1", "--out", a_file), "is a file"),
        (("build", csv, "--out", proc), "cannot write"),
        (("evaluate", csv, "--geozone", "g1", "--out", proc), "cannot write"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--layers", _garbage(rng)), "--layers"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--camera", _garbage(rng)), "--camera"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--geozone", _garbage(rng)), "not in"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--bench", int(rng.integers(2, 999))), "--bench"),
        (("view", csv, "--screenshot", folder), "directory"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--camera", "0,0,0"), "--camera"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--camera", vertical), "--camera"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--exaggeration", "inf"), "--exaggeration"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--exaggeration", -rng.uniform(0, 9)), "--exaggeration"),
        (("view", csv, "--screenshot", tmp_path / "s.png", "--project", view_project), "vertical_exaggeration"),
        (("build", csv, "--out", tmp_path / "m1", "--scheduler", _garbage(rng)), "scheduler"),
        (("build", csv, "--out", tmp_path / "m2", "--scheduler", f"{_garbage(rng)}://::"), "scheduler"),
        (("correspond", csv, "--geozone", "g1", "--project", project, "--out", tmp_path / "c.json"), "override 0"),
        (("build", csv, "--out", tmp_path / "m3", "--project", project), "override 0"),
        (("build", csv, "--out", tmp_path / "m4", "--workers", -int(rng.integers(0, 9))), "--workers"),
    ]


def test_user_errors_exit_2_with_one_line(csv, tmp_path):
    pytest.importorskip("pyvista")
    cases = user_error_cases(csv, tmp_path)
    before = snapshot(tmp_path)
    for args, phrase in cases:
        error_line(bgm(*args), phrase)
    unchanged(before, snapshot(tmp_path))


def test_blank_pictures_are_errors(csv, tmp_path):
    pytest.importorskip("pyvista")
    t = pd.read_csv(csv)
    bench0 = t.z > t.z.max() - 5
    counts = t[~bench0 & (t.geozone != "g0")].geozone.value_counts()
    absent = counts.index[0]
    # A geozone taken off the top bench: the stage layers of bench pair 0 have nothing to show.
    t.loc[bench0 & (t.geozone == absent), "geozone"] = "g0"
    t.to_csv(csv, index=False)
    for layers in ("edge-map", "gvf,snake"):
        out = tmp_path / f"{layers}.png"
        error_line(
            bgm("view", csv, "--screenshot", out, "--layers", layers, "--geozone", absent, "--bench", 0), "blank"
        )
        assert not out.exists()


def test_a_picture_name_bgm_cannot_write_is_refused_before_the_table_is_read(tmp_path):
    # A table no reader accepts: the extension must be the error, so it was checked first.
    junk = tmp_path / "junk.csv"
    junk.write_bytes(b"\x00\xff not a table")
    before = snapshot(tmp_path)
    for name in ("out.txt", "out", "out.svg", "out.png.gz"):
        line = error_line(bgm("view", junk, "--screenshot", tmp_path / name), "--screenshot", ".png", ".tiff")
        assert name in line
    unchanged(before, snapshot(tmp_path))


# --------------------------------------------------------------------------- silently wrong results


def spellings(rng, value: int) -> list[str]:
    forms = [str(value), f"{value}.0", f"{value}.00", f"+{value}", f"{value}e0", f"{value * 10}e-1"]
    return list(rng.choice(forms, 2, replace=False))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_number_spellings_of_one_label_are_merged_with_a_warning(table, tmp_path, seed):
    rng = rng_for("spellings", seed)
    codes = {g: int(rng.integers(100, 99999)) for g in sorted(set(table.geozone))}
    t = table.assign(geozone=table.geozone.map(codes).astype(str))
    target = str(codes["g1"])
    forms = spellings(rng, codes["g1"])
    rows = np.flatnonzero(t.geozone == target)
    t.loc[rows, "geozone"] = rng.choice(forms, len(rows))
    path = tmp_path / "codes.csv"
    t.to_csv(path, index=False)
    out = tmp_path / "c.geojson"
    proc = succeeds(bgm("contours", path, "--out", out, "--geozone", forms[0]))
    assert any("merged" in w for w in warnings_of(proc)), proc.stderr
    labels = {f["properties"]["geozone"] for f in json.loads(out.read_text())["features"]}
    assert labels == {target}  # one geozone, under its plain spelling
    assert "4 geozones" in proc.stderr


@pytest.mark.parametrize("seed", [0, 1])
def test_codes_with_leading_zeros_are_never_merged(table, tmp_path, seed):
    """Codes 007, 010, 0010 and 10 are four geozones: a float column never writes leading zeros."""
    rng = rng_for("leading zeros", seed)
    value = int(rng.integers(1, 99))
    codes = [f"00{value + 1}", f"0{value}", f"00{value}", str(value)]
    t = table.assign(geozone=table.geozone.map(dict(zip(sorted(set(table.geozone)), codes))))
    path = tmp_path / "codes.csv"
    t.to_csv(path, index=False)
    out = tmp_path / "c.geojson"
    proc = succeeds(bgm("contours", path, "--out", out))
    assert not any("merged" in w for w in warnings_of(proc)), proc.stderr
    assert "4 geozones" in proc.stderr
    assert {f["properties"]["geozone"] for f in json.loads(out.read_text())["features"]} <= set(codes)
    assert sorted(quiet_read(path).geozones) == sorted(codes)
    error_line(bgm("contours", path, "--out", out, "--geozone", f"000{value}"), "not in", f"0{value}")


@pytest.mark.parametrize("seed", [0, 1])
def test_a_float_column_gives_the_same_labels_from_csv_and_parquet(table, tmp_path, seed):
    """Codes 3310.0 everywhere (a float column) are 3310 whether the table is CSV or Parquet."""
    rng = rng_for("float labels", seed)
    codes = rng.choice(np.arange(100, 9999), 4, replace=False).astype(float)
    t = table.assign(geozone=table.geozone.map(dict(zip(sorted(set(table.geozone)), codes))))
    t.to_csv(tmp_path / "f.csv", index=False)
    t.to_parquet(tmp_path / "f.parquet")
    csv_labels = quiet_read(tmp_path / "f.csv").geozones
    assert csv_labels == quiet_read(tmp_path / "f.parquet").geozones == sorted(str(int(c)) for c in codes)
    # Non-integral codes keep their fraction, the same way from both.
    t = t.assign(geozone=t.geozone + 0.5)
    t.to_csv(tmp_path / "h.csv", index=False)
    t.to_parquet(tmp_path / "h.parquet")
    assert quiet_read(tmp_path / "h.csv").geozones == quiet_read(tmp_path / "h.parquet").geozones
    assert quiet_read(tmp_path / "h.csv").geozones == sorted(f"{c + 0.5}" for c in codes)


@pytest.mark.parametrize("seed", [0, 1])
def test_an_identifier_read_as_geozones_is_warned_about(table, tmp_path, seed):
    """``--geozone-column HOLEID`` made one geozone per hole without a word."""
    rng = rng_for("identifier", seed)
    ids = [f"{int(rng.integers(10**9, 10**10))}-{i}" for i in range(len(table))]
    # A few holes share an id (redrills): still an identifier.
    k = len(ids) // 20
    ids[k : 2 * k] = ids[:k]
    path = tmp_path / "ids.csv"
    table.assign(HOLEID=ids).to_csv(path, index=False)
    out = tmp_path / "c.geojson"
    proc = succeeds(bgm("contours", path, "--out", out, "--geozone-column", "HOLEID", "--geozone", ids[-1]))
    assert any("'HOLEID'" in w and "identifier" in w and "--geozone-column" in w for w in warnings_of(proc))
    assert not any("identifier" in w for w in warnings_of(succeeds(bgm("contours", path, "--out", out))))


def test_labels_differing_only_by_case_are_kept_with_a_warning(table, tmp_path):
    t = table.assign(geozone=table.geozone.replace({"g1": "G0"}))
    path = tmp_path / "case.csv"
    t.to_csv(path, index=False)
    proc = succeeds(bgm("contours", path, "--out", tmp_path / "c.geojson"))
    assert any("'G0' and 'g0'" in w and "only by case" in w for w in warnings_of(proc)), proc.stderr
    assert "4 geozones" in proc.stderr


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_depth_column_given_as_z_is_warned_about(table, tmp_path, seed):
    """Depths (positive down) read as elevations put the deepest bench on top: say so, naming the column."""
    rng = rng_for("depth", seed)
    name = str(rng.choice(["depth", "Depth", "DEPTH", "depth_m", "from", "to", "Hole Depth (m)"]))
    t = table.assign(**{name: 700.0 - table.z}).drop(columns="z")
    path = tmp_path / "depth.csv"
    t.to_csv(path, index=False)
    proc = succeeds(bgm("contours", path, "--out", tmp_path / "c.geojson", "--z", name))
    assert any(repr(name) in w and "elevation" in w and "--z" in w for w in warnings_of(proc)), proc.stderr
    # The elevations under an elevation's name get no such warning.
    t.assign(RL=table.z).to_csv(path, index=False)
    proc = succeeds(bgm("contours", path, "--out", tmp_path / "c.geojson", "--z", "RL"))
    assert not any("depth" in w for w in warnings_of(proc)), proc.stderr


def test_depths_in_a_column_named_as_elevations_are_warned_about(tmp_path):
    """Depths below a datum (positive down) in a column named ``RL`` or ``z`` read as elevations, upside down, without
    a word: every prediction below the deepest bench lay above the top one. The pit widening with depth says so."""
    from core.synthetic.scenarios import scenario

    rng = rng_for("depth in z")
    name = str(rng.choice(["z", "Z", "RL", "elevation"]))
    _, pit, _ = scenario("widening", 4, n_benches=5, drilling={"spacing_range_m": (10.0, 12.0)})
    datum = float(np.ceil(pit.z.max())) + rng.uniform(5.0, 50.0)
    path = tmp_path / "pit.csv"
    pit.assign(z=np.round(datum - pit.z, 2)).rename(columns={"z": name}).to_csv(path, index=False)
    proc = succeeds(bgm("contours", path, "--out", tmp_path / "c.geojson"))
    said = [w for w in warnings_of(proc) if "widen with depth" in w]
    assert len(said) == 1 and repr(name) in said[0] and "depths (positive down)" in said[0], proc.stderr
    assert "give elevations" in said[0] and "upside down" in said[0], said
    pit.rename(columns={"z": name}).to_csv(path, index=False)  # the elevations: not a word
    proc = succeeds(bgm("contours", path, "--out", tmp_path / "c.geojson"))
    assert not any("widen" in w or "upside down" in w for w in warnings_of(proc)), proc.stderr


@pytest.mark.parametrize("seed", [0, 1])
def test_degrees_are_refused(table, tmp_path, seed):
    rng = rng_for("degrees", seed)
    lon, lat = rng.uniform(-179, 179), rng.uniform(-70, 70)
    x = lon + (table.x - ORIGIN[0]) / (111_320 * np.cos(np.radians(lat)))
    y = lat + (table.y - ORIGIN[1]) / 110_540
    t = table.assign(x=y, y=x) if seed % 2 else table.assign(x=x, y=y)  # latitude first in one case
    path = tmp_path / "degrees.csv"
    t.to_csv(path, index=False)
    before = snapshot(tmp_path)
    error_line(bgm("contours", path, "--out", tmp_path / "o.geojson"), "degrees", "longitude and latitude")
    unchanged(before, snapshot(tmp_path))


def bench_table(levels, rng, scatter=0.5, n_side=12) -> pd.DataFrame:
    rows = []
    for z in levels:
        g = np.arange(n_side) * 5.0
        gx, gy = np.meshgrid(g, g)
        xy = np.column_stack([gx.ravel(), gy.ravel()]) + rng.normal(0, 0.4, (gx.size, 2))
        for (x, y), dz in zip(xy, rng.uniform(-scatter, scatter, len(xy))):
            rows.append((ORIGIN[0] + x, ORIGIN[1] + y, z + dz, "ore" if x < 30 else "waste"))
    return pd.DataFrame(rows, columns=["x", "y", "z", "geozone"])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_uneven_benches_are_taken_as_measured(tmp_path, seed):
    rng = rng_for("uneven", seed)
    heights = rng.uniform(6.0, 18.0, int(rng.integers(2, 4)))
    levels = np.round(700.0 - np.concatenate([[0], np.cumsum(heights)]), 1)
    path = tmp_path / "uneven.csv"
    bench_table(levels, rng).to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    succeeds(bgm("contours", path, "--out", out))
    found = sorted({f["properties"]["bench"] for f in json.loads(out.read_text())["features"]}, reverse=True)
    assert np.allclose(found, levels, atol=0.15), (found, levels)


@pytest.mark.parametrize("seed", [0, 1])
def test_z_that_forms_no_benches_is_refused(tmp_path, seed):
    rng = rng_for("continuous", seed)
    t = bench_table([0.0], rng)
    t["z"] = rng.uniform(500, 500 + rng.uniform(60, 150), len(t))
    path = tmp_path / "continuous.csv"
    t.to_csv(path, index=False)
    before = snapshot(tmp_path)
    error_line(bgm("contours", path, "--out", tmp_path / "o.geojson"), "does not form benches")
    error_line(bgm("contours", path, "--out", tmp_path / "o.geojson", "--bench-height", 10), "does not form benches")
    unchanged(before, snapshot(tmp_path))


def test_far_elevations_need_force(csv, tmp_path):
    rng = rng_for("far")
    far = [665 - 10 * float(rng.uniform(3.5, 500)), float(10 ** rng.uniform(5, 300)), -5000.0]
    before = snapshot(tmp_path)
    for z in far:
        error_line(
            bgm("predict", csv, "--geozone", "g1", "--elevations", z, "--out", tmp_path / "p.geojson"), "--force"
        )
    unchanged(before, snapshot(tmp_path))
    out = tmp_path / "p.geojson"
    succeeds(bgm("predict", csv, "--geozone", "g1", "--elevations", f"{far[0]},660", "--out", out, "--force"))
    assert out.exists()


def test_a_decimal_comma_in_elevations_is_said_to_be_one(csv, tmp_path):
    """``--elevations 652,5`` is the elevations 652 and 5: 5 was refused as far away, with only --force offered."""
    before = snapshot(tmp_path)
    out = tmp_path / "p.geojson"
    line = error_line(bgm("predict", csv, "--geozone", "g1", "--elevations", "652,5", "--out", out))
    assert "--elevations 5 is more than 3 bench heights" in line, line
    assert "separated by commas" in line and "652,5 is read as 652 and 5" in line and "(652.5)" in line, line
    assert "--force" not in line, line
    line = error_line(bgm("predict", csv, "--geozone", "g1", "--elevations", "660,652,25", "--out", out))
    assert "652,25 is read as 652 and 25" in line and "(652.25)" in line, line
    unchanged(before, snapshot(tmp_path))
    # Far elevations given as such (a separate item, a list joined by ';') keep the plain refusal.
    for given in ("660, 5", "660;5", "660,-5000"):
        line = error_line(bgm("predict", csv, "--geozone", "g1", "--elevations", given, "--out", out), "--force")
        assert "is read as" not in line, line


def test_unused_overrides_are_named(csv, tmp_path):
    rng = rng_for("overrides")
    project = tmp_path / "p.json"
    missing = _garbage(rng)
    unknown = "no_such_" + _garbage(rng).replace("#", "_").replace("@", "_")
    top = quiet_read(csv).bench_z_input(0)
    project.write_text(
        json.dumps(
            {
                "format": "bgm-project",
                "version": 1,
                "parameters": {"gvf_mu": 0.2, unknown: 1.0},
                "overrides": [
                    {"geozone": missing, "source_z": top, "source": 0, "translation": [1.0, 0.0]},
                    {"geozone": "g1", "source_z": top + float(rng.uniform(1, 9)), "source": 0, "translation": [1, 0]},
                    {"geozone": "g1", "source_z": top, "source": 0, "translation": [0.5, 0.0]},
                ],
            }
        )
    )
    proc = succeeds(bgm("correspond", csv, "--geozone", "g1", "--project", project, "--out", tmp_path / "c.json"))
    found = warnings_of(proc)
    assert any("override 0" in w and missing in w for w in found), found
    assert any("override 1" in w and "no bench pair" in w for w in found), found
    assert not any("override 2" in w for w in found), found
    # every command applies the model's parameters: gvf_mu is used, a name the model does not know is not
    assert any(unknown in w and "not use" in w for w in found), found
    assert not any("gvf_mu" in w for w in found), found


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_out_of_range_parameters_are_refused(csv, tmp_path, seed):
    rng = rng_for("parameters", seed)
    name, bad = [("gvf_mu", -1), ("snake_max_iterations", -5), ("edge_map_cells", 0), ("snake_step", 0)][seed % 4]
    bad = bad - float(rng.integers(0, 5))
    project = tmp_path / "p.json"
    project.write_text(json.dumps({"format": "bgm-project", "version": 1, "parameters": {name: bad}}))
    before = snapshot(tmp_path)
    error_line(bgm("correspond", csv, "--geozone", "g1", "--project", project, "--out", tmp_path / "c.json"), name)
    radius = ["-5", "nan", "inf", "0", "-inf"][int(rng.integers(0, 5))]
    error_line(bgm("contours", csv, "--search-radius", radius, "--out", tmp_path / "o.geojson"), "--search-radius")
    unchanged(before, snapshot(tmp_path))


@pytest.mark.parametrize("seed", [0, 1])
def test_isolated_holes_grow_no_body(table, seed):
    """A handful of holes far from everything: the prediction holds them, it does not grow a body from them."""
    from core.model.pipeline import model_geozone
    from core.model.prediction import predict_geozone

    rng = rng_for("isolated", seed)
    n = int(rng.integers(3, 7))
    deepest = table.z.min() + 1
    far = table.x.max() + rng.uniform(200, 400)
    xs = far + 5.0 * np.arange(n) + rng.normal(0, 0.3, n)
    extra = pd.DataFrame({"x": xs, "y": table.y.mean() + rng.normal(0, 2, n), "z": deepest, "geozone": "iso"})
    holes = quiet_read(pd.concat([table, extra], ignore_index=True))
    model = model_geozone(holes, "iso")
    z = holes.bench_levels_m[-1] - 0.5 * holes.bench_height_m
    region = predict_geozone(model, [z], holes.hole_spacing_m)[z]
    spacing = holes.hole_spacing_m
    # At most the holes' own footprint (a disc of two spacings around each), not a reach of 10 spacings.
    assert region.area <= n * np.pi * (2 * spacing) ** 2, region.area
    local = holes.frame.to_local(extra.x, extra.y)
    assert shapely.MultiPoint(local).buffer(3 * spacing).contains(region)


# --------------------------------------------------------------------------- hangs and unclear messages


@pytest.mark.parametrize("n_columns", [20_000, 100_000])
def test_wide_headers_parse_only_the_needed_columns(table, tmp_path, monkeypatch, n_columns):
    rng = rng_for("wide", n_columns)
    small = table.iloc[::4].reset_index(drop=True)
    header = [f"c{i}" for i in range(n_columns)]
    where = {}
    for name in ("x", "y", "z", "geozone"):
        where[name] = int(rng.integers(0, len(header) + 1))
        header.insert(where[name], name)
    rows = [",".join(header)]
    for _, r in small.iterrows():
        cells = ["1"] * n_columns
        for name in ("x", "y", "z", "geozone"):
            cells.insert(where[name], str(r[name]))
        rows.append(",".join(cells))
    path = tmp_path / "wide.csv"
    path.write_text("\n".join(rows) + "\n")
    parsed = []
    real = pd.read_csv

    def spy(*args, **kwargs):
        parsed.append(kwargs.get("usecols"))
        return real(*args, **kwargs)

    monkeypatch.setattr(pd, "read_csv", spy)
    holes = quiet_read(path)
    assert len(holes.xy) == len(small) and parsed and all(u is not None and len(u) <= 5 for u in parsed)
    monkeypatch.undo()
    # A missing column is named without listing 100,000 others.
    line = error_line(bgm("contours", path, "--z", "nope", "--out", tmp_path / "o.geojson"), "nope", "more")
    assert len(line) < 1200


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_decimal_commas_read_as_numbers(table, tmp_path, seed):
    rng = rng_for("commas", seed)
    sep = [";", "\t", ","][seed % 3]
    t = table.drop(columns=["hole_id"])
    path = tmp_path / "commas.csv"
    if sep == ",":  # quoted thousands separators
        text = t.to_csv(index=False, float_format="%.2f")
        rows = [text.splitlines()[0]]
        for _, r in t.iterrows():
            rows.append(f'"{r.x:,.2f}","{r.y:,.2f}",{r.z:.2f},{r.geozone}')
        path.write_text("\n".join(rows) + "\n")
    else:
        t.to_csv(path, index=False, sep=sep, decimal=",", float_format=f"%.{int(rng.integers(2, 4))}f")
    holes = quiet_read(path)
    reference = quiet_read(t)
    assert len(holes.xy) == len(reference.xy)
    assert np.allclose(holes.frame.to_input(holes.xy), reference.frame.to_input(reference.xy), atol=0.006)
    succeeds(bgm("contours", path, "--out", tmp_path / "o.geojson", "--geozone", "g1"))


@pytest.mark.parametrize("seed", [0, 1])
def test_comment_lines_before_the_header(table, tmp_path, seed):
    rng = rng_for("comments", seed)
    n = int(rng.integers(1, 6))
    lines = [f"{rng.choice(['#', '//', '%'])} exported {_garbage(rng)}, columns: x;y" for _ in range(n)]
    path = tmp_path / "commented.csv"
    bad_row = int(rng.integers(0, len(table)))
    t = table.astype({"x": object})
    path.write_text("\n".join(lines) + "\n" + t.to_csv(index=False))
    assert len(quiet_read(path).xy) == len(quiet_read(table).xy)
    t.loc[bad_row, "x"] = "12a"
    path.write_text("\n".join(lines) + "\n" + t.to_csv(index=False))
    # The file line named is the one an editor shows: comments, header, then the row.
    error_line(bgm("contours", path, "--out", tmp_path / "o.geojson"), f"line(s) {bad_row + n + 2}")


def test_compressed_and_misnamed_files(table, tmp_path):
    text = table.to_csv(index=False).encode()
    files = {
        "gzip.csv.gz": gzip.compress(text),
        "bzip.csv.bz2": bz2.compress(text),
        "xz.csv": lzma.compress(text),  # compressed and not named so
        "text.parquet": text,  # CSV named .parquet
    }
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    with zipfile.ZipFile(tmp_path / "zipped.zip", "w") as z:
        z.writestr("holes.csv", text)
    table.to_parquet(tmp_path / "parquet.csv")  # Parquet named .csv
    n = len(quiet_read(table).xy)
    for path in sorted(tmp_path.iterdir()):
        assert len(quiet_read(path).xy) == n, path.name
    proc = succeeds(bgm("contours", tmp_path / "text.parquet", "--out", tmp_path / "o.geojson", "--geozone", "g1"))
    assert any("not Parquet" in w for w in warnings_of(proc))
    # A spreadsheet is named as one.
    with zipfile.ZipFile(tmp_path / "book.xlsx", "w") as z:
        z.writestr("xl/workbook.xml", "<workbook/>")
        z.writestr("[Content_Types].xml", "<Types/>")
    error_line(bgm("contours", tmp_path / "book.xlsx", "--out", tmp_path / "x.geojson"), "Excel")


def test_standard_input(csv, tmp_path):
    data = csv.read_bytes()
    out = tmp_path / "o.geojson"
    proc = succeeds(bgm("contours", "-", "--out", out, "--geozone", "g1", stdin=data))
    assert "standard input" in proc.stderr and out.exists()
    error_line(bgm("contours", "-", "--out", tmp_path / "e.geojson", stdin=b""), "standard input is empty")
    # /dev/stdin is a pipe here: read to its end like a file.
    proc = subprocess.run(
        [*BGM, "contours", "/dev/stdin", "--out", tmp_path / "p.geojson", "--geozone", "g1"],
        input=data,
        capture_output=True,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        timeout=300,
    )
    no_traceback(proc)
    assert proc.returncode == 0 and (tmp_path / "p.geojson").exists(), proc.stderr


def test_huge_labels_are_shortened_in_messages(csv, tmp_path):
    t = pd.read_csv(csv)
    t.loc[0, "geozone"] = "Q" * 50_000_000  # a broken export: a 50 MB label
    big = tmp_path / "big.csv"
    t.to_csv(big, index=False)
    line = error_line(bgm("contours", big, "--geozone", "nope", "--out", tmp_path / "o.geojson"), "nope", "characters")
    assert len(line) < 1200
    line = error_line(bgm("contours", csv, "--geozone", "W" * 5_000_000, "--out", tmp_path / "o.geojson"), "not in")
    assert len(line) < 1200


@pytest.mark.parametrize("seed", [0, 1])
def test_rows_longer_than_the_header_are_refused(table, tmp_path, seed):
    """Labels holding an unquoted comma shift their rows: read by the columns needed, two geozones became one."""
    rng = rng_for("long rows", seed)
    t = table[["x", "y", "z", "geozone", "hole_id"]]
    names = dict(zip(sorted(t.geozone.unique())[:2], ["ore, oxide", "ore, sulphide"]))
    lines = ["x,y,z,geozone,hole_id"] + [
        f"{r.x},{r.y},{r.z},{names.get(r.geozone, r.geozone)},{r.hole_id}" for r in t.itertuples()
    ]
    first = 2 + int(np.flatnonzero(t.geozone.isin(list(names)).to_numpy())[0])  # the file line of the first one
    path = tmp_path / "unquoted.csv"
    path.write_text("\n".join(lines) + "\n")
    before = snapshot(tmp_path)
    error_line(bgm("contours", path, "--out", tmp_path / "o.geojson"), f"line {first} has 6 fields", "quote")
    unchanged(before, snapshot(tmp_path))
    # Trailing delimiters (empty fields past the header's, as spreadsheets export them) are no shift.
    trailing = [
        line + "," * int(rng.integers(1, 3)) if i else line for i, line in enumerate(t.to_csv(index=False).splitlines())
    ]
    path.write_text("\n".join(trailing) + "\n")
    assert len(quiet_read(path).xy) == len(quiet_read(t).xy)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_empty_rows_are_skipped_and_lines_named_as_in_the_file(table, tmp_path, seed):
    """Spreadsheets end a CSV with ``,,,,`` rows (a hard error); after a blank line, errors named the line before."""
    rng = rng_for("empty rows", seed)
    lines = table.to_csv(index=False).splitlines()
    empty = "," * (len(table.columns) - 1)
    for at in sorted(rng.choice(np.arange(2, len(lines)), 4, replace=False), reverse=True):
        lines.insert(int(at), str(rng.choice(["", "   ", empty])))
    path = tmp_path / "excel.csv"
    path.write_text("\n".join([*lines, empty, empty]) + "\n")
    with pytest.warns(BGMWarning, match="empty row"):
        holes = read_blastholes(path)
    assert len(holes.xy) == len(quiet_read(table).xy)
    # A bad value is named by the line an editor shows it on.
    bad = int(rng.integers(len(lines) // 2, len(lines)))
    while not lines[bad - 1].strip(",").strip():  # a data row (line numbers are 1-based)
        bad -= 1
    lines[bad - 1] = "abc" + lines[bad - 1][lines[bad - 1].index(",") :]
    path.write_text("\n".join(lines) + "\n")
    error_line(bgm("contours", path, "--out", tmp_path / "o.geojson"), f"data line(s) {bad} ", "'abc'")


@pytest.mark.parametrize("factor", [4, 12])
def test_a_bench_height_that_puts_several_benches_on_one_is_refused(tmp_path, factor):
    """Benches 10 m apart read with ``--bench-height 40``: the holes of four benches were contoured as one."""
    rng = rng_for("merged benches", factor)
    path = tmp_path / "benches.csv"
    bench_table(700.0 - 10.0 * np.arange(6), rng).to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    error_line(bgm("contours", path, "--out", out, "--bench-height", 10 * factor), "bench height", "on one bench")
    succeeds(bgm("contours", path, "--out", out, "--bench-height", 10))
    assert len({f["properties"]["bench"] for f in json.loads(out.read_text())["features"]}) == 6


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_bench_height_keeps_the_levels_where_the_collars_are(tmp_path, seed):
    """``--bench-height 9.5`` on 10 m benches moved the levels (the bottom one 2.9 m off) and dropped holes."""
    rng = rng_for("given height", seed)
    levels = np.round(rng.uniform(600, 700) - 10.0 * np.arange(int(rng.integers(4, 8))), 1)
    path = tmp_path / "benches.csv"
    bench_table(levels, rng).to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    for wrong in (rng.uniform(8.5, 9.6), rng.uniform(10.4, 11.5), 5.0):
        error_line(bgm("contours", path, "--out", out, "--bench-height", f"{wrong:.2f}"), "disagrees", "10 apart")
    # A height that agrees with the collars (within a few percent) leaves every level and hole where it is.
    proc = succeeds(bgm("contours", path, "--out", out, "--bench-height", f"{rng.uniform(9.75, 10.25):.2f}"))
    assert not warnings_of(proc), proc.stderr
    found = sorted({f["properties"]["bench"] for f in json.loads(out.read_text())["features"]}, reverse=True)
    assert np.allclose(found, levels, atol=0.15), (found, levels)


def test_benches_of_two_holes_are_refused_as_such(tmp_path):
    """Two holes a bench, the same two collars on every bench: said to be too few holes, not "spread continuously"."""
    rows = [(100.0 + 6.0 * i, 100.0, 100.0 - 10.0 * k, "ab"[i]) for k in range(4) for i in range(2)]
    path = tmp_path / "two.csv"
    pd.DataFrame(rows, columns=["x", "y", "z", "geozone"]).to_csv(path, index=False)
    error_line(bgm("contours", path, "--out", tmp_path / "o.geojson"), "4 levels", "at least 3 holes a bench")


def test_tall_benches_are_feet_only_where_their_holes_make_a_pattern_in_feet(tmp_path):
    """30-unit benches drilled 5 units apart are metres (in feet: a 9 m bench drilled every 1.5 m); 50 ft ones are feet."""
    rng = rng_for("tall benches")
    metric = bench_table(700.0 - 30.0 * np.arange(3), rng)
    with pytest.warns(BGMWarning, match="read as metres"):
        holes = blastholes_from_table(metric)
    assert holes.frame.length_unit == "m" and holes.bench_height_m == pytest.approx(30.0, abs=0.5)
    imperial = bench_table(2300.0 - 50.0 * np.arange(3), rng)
    for axis, origin in zip(("x", "y"), ORIGIN):  # 17.5 ft apart: 5.3 m
        imperial[axis] = origin + (imperial[axis] - origin) * 3.5
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)
        holes = blastholes_from_table(imperial)
    assert holes.frame.length_unit == "ft" and holes.bench_height_m == pytest.approx(50.0 * 0.3048, abs=0.2)


@pytest.mark.parametrize("case", ["outlined nowhere scored", "first on the deepest bench", "on the top bench alone"])
def test_an_evaluation_with_nothing_to_score_says_why_instead_of_printing_nan(table, tmp_path, case):
    """A geozone whose every score would be 0 / 0 is refused, naming where its holes are, not scored NaN.

    A body on the top bench alone, which no bench scored holds, was said to be one or two holes of label noise.
    """
    bench = (
        table["z"] >= table["z"].max() - 1.0
        if case == "on the top bench alone"
        else table["z"] <= table["z"].min() + 1.0
    )
    west_to_east = table.loc[bench, "x"].sort_values().index
    # Two holes far apart are label noise (no contour); fifteen side by side are a body no bench above shows.
    picked = [west_to_east[0], west_to_east[-1]] if case == "outlined nowhere scored" else west_to_east[:15]
    path = tmp_path / "holes.csv"
    table.assign(geozone=table["geozone"].where(~table.index.isin(picked), "late")).to_csv(path, index=False)
    line = error_line(bgm("evaluate", path, "--geozone", "late", "--out", tmp_path / "e"), "nothing to evaluate")
    assert re.search(r"its holes are on the bench at [-0-9.]+ m\b", line), line  # that bench alone
    assert ("no contour" in line) == (case == "outlined nowhere scored"), line
    assert ("label noise" in line) == (case == "outlined nowhere scored"), line
    assert ("has no hole on any bench it could be scored on" in line) == (case == "on the top bench alone"), line


@pytest.mark.parametrize("shift_m", [0.0, 60.0, 5000.0])
def test_a_planned_pattern_in_other_coordinates_is_refused(csv, table, tmp_path, shift_m):
    """A pattern kilometres from every blasthole (a local grid against the mine grid) is named, not sampled as absent."""
    deepest = table[table["z"] <= table["z"].min() + 1.0]
    pattern = tmp_path / "planned.csv"
    deepest.assign(x=deepest["x"] + shift_m)[["x", "y"]].to_csv(pattern, index=False)
    run = bgm("suggest", csv, "--geozone", "g1", "--budget", "3", "--pattern", pattern, "--out", tmp_path / "s.csv")
    if shift_m < 100:  # beside the drilling (60 m: within ten hole spacings of it), sampled as planned
        assert run.returncode == 0, run.stderr
    else:
        line = error_line(run, "from the nearest blasthole", "coordinates")
        assert "4,9" in line or "5,0" in line, line  # how far, in the input's units


@pytest.mark.parametrize("reach, shift_m", [(5.0, 100.0), (20.0, 150.0)])
def test_a_planned_pattern_is_judged_far_on_the_projects_reach(csv, table, tmp_path, reach, shift_m):
    """The far-pattern check used the default frontier_reach_spacings (10) whatever the project set.

    100 m off, the pattern's nearest hole is 7.8 hole spacings from a blasthole, 150 m off 16.5: beyond a
    project's reach of 5 the first is refused, within its reach of 20 the second is sampled.
    """
    deepest = table[table["z"] <= table["z"].min() + 1.0]
    pattern = tmp_path / "planned.csv"
    deepest.assign(x=deepest["x"] + shift_m)[["x", "y"]].to_csv(pattern, index=False)
    project = tmp_path / "p.json"
    project.write_text(
        json.dumps({"format": "bgm-project", "version": 1, "parameters": {"frontier_reach_spacings": reach}})
    )
    args = ("--geozone", "g1", "--budget", "3", "--pattern", pattern, "--project", project)
    run = bgm("suggest", csv, *args, "--out", tmp_path / "s.csv")
    if reach < 10:
        error_line(run, "from the nearest blasthole", "coordinates")
    else:
        assert run.returncode == 0, run.stderr


def test_geozones_given_with_commas_as_suggest_takes_them_and_a_label_holding_a_comma_whole(table, tmp_path):
    path = tmp_path / "holes.csv"
    table.assign(geozone=table["geozone"].replace({"g3": "ore, oxide"})).to_csv(path, index=False)  # quoted
    out = tmp_path / "c.geojson"
    for asked, expected in ((["g1,g2"], {"g1", "g2"}), (["g1", "ore, oxide"], {"g1", "ore, oxide"})):
        options = [a for g in asked for a in ("--geozone", g)]
        assert bgm("contours", path, *options, "--out", out).returncode == 0
        assert {f["properties"]["geozone"] for f in json.loads(out.read_text())["features"]} == expected, asked
    error_line(bgm("contours", path, "--geozone", "g1,nope", "--out", out), "'nope' is not in")


def test_sigterm_stops_the_engines_commands_but_leaves_a_window_to_die_as_windows_do():
    """SIGTERM becomes a Ctrl-C for ``bgm build`` and the like; ``bgm view``'s Qt loop would never run that handler."""
    from core import cli

    previous = signal.getsignal(signal.SIGTERM)
    try:
        for argv, handled in ((["build", "h.csv"], True), (["contours", "h.csv"], True), (["view", "h.csv"], False)):
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            cli._stop_on_sigterm(argv)
            assert (signal.getsignal(signal.SIGTERM) is cli._on_ctrl_c) is handled, argv
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_main_leaves_sigterm_as_it_found_it(tmp_path):
    """Run inside another program (the tests), ``bgm`` left SIGTERM ignored: a process forked later could not be
    terminated (test_an_interrupted_command_leaves_no_worker_behind failed after any in-process command)."""
    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        bgm("make-demo-data", "--family", "strips", "--out", tmp_path / "m.csv")
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    finally:
        signal.signal(signal.SIGTERM, previous)


@pytest.mark.parametrize(
    "case, phrase",
    [("no x column", "no x column"), ("two benches", "at least three"), ("nothing to score", "nothing to evaluate")],
)
def test_an_evaluation_refused_leaves_no_output_folder(table, tmp_path, case, phrase):
    """bgm evaluate made its --out folder before reading the input: a refused input left it behind, empty."""
    path = tmp_path / "holes.csv"
    if case == "no x column":
        table.rename(columns={"x": "u"}).to_csv(path, index=False)
    elif case == "two benches":
        table[table["z"] > table["z"].min() + 1.0].to_csv(path, index=False)
    else:  # two holes far apart on the deepest bench: label noise, no contour to score
        deepest = table.loc[table["z"] <= table["z"].min() + 1.0, "x"].sort_values().index
        noise = table.index.isin(deepest[[0, -1]])
        table.assign(geozone=table["geozone"].where(~noise, "late")).to_csv(path, index=False)
    out = tmp_path / "new" / "evaluation"
    geozone = "late" if case == "nothing to score" else "g1"
    error_line(bgm("evaluate", path, "--geozone", geozone, "--out", out), phrase)
    assert not (tmp_path / "new").exists()


def _failing_after_first(monkeypatch, module: str, name: str, exc) -> None:
    """Make ``module.name`` (a writer the command imports when it runs, not the set's first) raise ``exc(path)``."""
    import importlib

    def failing(path, *args, **kwargs):
        raise exc(path)

    monkeypatch.setattr(importlib.import_module(module), name, failing)


@pytest.mark.parametrize("folder", ["existing", "new"])
def test_an_evaluation_that_fails_after_its_plot_leaves_the_previous_set(csv, tmp_path, monkeypatch, folder):
    """The plot was written first: a full disk or Ctrl-C after it left a new plot beside the previous tables, or a
    new folder holding only the plot (an empty folder when the plot itself failed)."""
    out = tmp_path / "out" / "evaluation"
    if folder == "existing":
        out.mkdir(parents=True)
        for name in ("evaluation_rows.csv", "evaluation.csv", "precision_recall.png", "mine.txt"):
            (out / name).write_text(f"previous {name}")
    before = snapshot(tmp_path)

    def full(path) -> OSError:  # as the storage says it, naming the file being written
        return OSError(errno.ENOSPC, "No space left on device", str(path))

    _failing_after_first(monkeypatch, "core.io.atomic", "atomic_write_text", full)
    run = bgm("evaluate", csv, "--geozone", "g1", "--out", out)
    unchanged(before, snapshot(tmp_path))  # no new plot, no stray or staging file, no empty folder
    line = error_line(run, "no space left")
    assert "evaluation_rows.csv" in line and ".bgm-" not in line, line  # named where it was going, not staged
    monkeypatch.undo()
    succeeds(bgm("evaluate", csv, "--geozone", "g1", "--out", out))
    written = sorted(p.name for p in out.iterdir())
    assert written == sorted(
        ["evaluation_rows.csv", "evaluation.csv", "precision_recall.png"] + ["mine.txt"] * (folder == "existing")
    )
    assert not [p for p in out.parent.rglob("*") if ".bgm-" in p.name]


def test_a_prediction_stopped_after_its_first_file_leaves_the_previous_three(csv, tmp_path, monkeypatch):
    """`bgm predict` wrote its prediction, then the uncertainty file and P(inside) grid one by one: Ctrl-C or a
    failure between them left a new prediction beside the previous uncertainty files."""
    out = tmp_path / "p.geojson"
    files = [out, tmp_path / "p.uncertainty.geojson", tmp_path / "p.p_inside.npz"]
    for f in files:
        f.write_text(f"previous {f.name}")
    before = snapshot(tmp_path)
    args = ("predict", csv, "--geozone", "g1", "--elevations", "655", "--out", out)
    _failing_after_first(
        monkeypatch, "core.io.uncertainty_export", "write_probability_grid", lambda path: KeyboardInterrupt()
    )
    run = bgm(*args)
    assert run.returncode == 130, run.stderr
    unchanged(before, snapshot(tmp_path))
    _failing_after_first(
        monkeypatch, "core.io.uncertainty_export", "write_probability_grid", lambda path: RuntimeError("a bug")
    )
    assert bgm(*args).returncode == 3
    unchanged(before, snapshot(tmp_path))
    monkeypatch.undo()
    succeeds(bgm(*args))
    assert all(not f.read_bytes().startswith(b"previous") for f in files)
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "in") == sorted(f.name for f in files)


FOLDER_COMMANDS = {
    "build": lambda inp, out: ("build", inp, "--out", out),
    "evaluate": lambda inp, out: ("evaluate", inp, "--geozone", "g1", "--out", out),
    "demo": lambda inp, out: ("demo", "--out", out),
}


@pytest.mark.parametrize("command", list(FOLDER_COMMANDS))
def test_an_output_folder_that_cannot_be_made_is_refused_before_the_table_is_read(csv, command):
    """`bgm build --out /proc/x` read the whole table (its summary line said so) before refusing the folder."""
    if not Path("/proc/self").exists():
        pytest.skip("no /proc here")
    run = bgm(*FOLDER_COMMANDS[command](csv, Path("/proc") / f"bgm-{command}"))
    error_line(run, "cannot write", "/proc")
    assert "holes" not in run.stdout + run.stderr.replace("/proc", "")  # no input summary: the table was not read
