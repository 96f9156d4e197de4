"""`bgm view` is the viewer's plug-in: the engine's command line never imports the viewer."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from importlib.metadata import EntryPoint
from pathlib import Path
from types import SimpleNamespace

import pytest
import typer
from clirun import bgm, error_line, succeeds

from core import cli

ROOT = Path(__file__).resolve().parent.parent
#: ``bgm`` with the viewer's command registered as an installed entry point would register it.
BGM_WITH_VIEWER = "from core.cli import app, main; from bgm_viewer.cli_hooks import register; register(app); main()"


def _entry_points():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"][cli.PLUGIN_GROUP]
    return [EntryPoint(name, value, cli.PLUGIN_GROUP) for name, value in declared.items()]


def test_the_viewer_declares_its_command_as_an_entry_point():
    from bgm_viewer.cli_hooks import register

    (view,) = _entry_points()
    assert view.name == "view" and view.load() is register


def test_plugins_add_their_commands_and_a_broken_one_does_not_break_bgm(monkeypatch, capsys):
    broken = EntryPoint("broken", "no_such_package.cli:register", cli.PLUGIN_GROUP)
    monkeypatch.setattr("importlib.metadata.entry_points", lambda group: [*_entry_points(), broken])
    app = typer.Typer()
    app.command("contours")(lambda: None)
    assert cli.load_plugins(app) == ["view"]
    assert {c.name for c in app.registered_commands} == {"contours", "view"}
    assert "'broken' command could not be loaded" in capsys.readouterr().err
    assert cli.load_plugins(app) == []  # loading twice adds nothing


def test_bgm_view_renders_a_screenshot(tmp_path):
    pytest.importorskip("pyvista")
    from core.synthetic.blobs import make_mine, sample_blastholes

    csv = tmp_path / "mine.csv"
    table = sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    # Columns no reader would find by name: the viewer takes the options every reading command takes.
    table.rename(columns={"x": "E (grid)", "y": "N (grid)", "z": "toe"}).to_csv(csv, index=False)
    png = tmp_path / "view.PNG"  # PyVista knows lower-case extensions only; bgm takes any case
    args = ["view", str(csv), "--screenshot", str(png), "--layers", "blastholes,contours", "--geozone", "g1"]
    args += ["--x", "E (grid)", "--y", "N (grid)", "--z", "toe", "--bench-height", "10"]
    proc = subprocess.run([sys.executable, "-c", BGM_WITH_VIEWER, *args], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert png.stat().st_size > 10_000 and f"wrote {png}" in proc.stderr


def test_a_screenshot_in_batch_says_how_far_it_is_as_it_goes(tmp_path):
    """A screenshot of the surfaces runs the whole pipeline (16 s on the demo) and said nothing until
    "wrote": in batch it looked hung. Each step is a line now, flushed while it runs, never going back."""
    pytest.importorskip("pyvista")
    import os
    import re

    from core.synthetic.blobs import make_mine, sample_blastholes

    csv = tmp_path / "mine.csv"
    sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4).to_csv(
        csv, index=False
    )
    png = tmp_path / "view.png"
    args = ["view", str(csv), "--screenshot", str(png), "--layers", "surfaces", "--no-cache"]
    env = {k: v for k, v in os.environ.items() if k != "BGM_PROGRESS"}  # a pipe: a line a step
    proc = subprocess.Popen([sys.executable, "-c", BGM_WITH_VIEWER, *args], stderr=subprocess.PIPE, env=env)
    lines, running = [], None
    for line in proc.stderr:
        lines.append(line.decode().removesuffix("\n"))
        if running is None and line.startswith(b"bgm: progress: "):
            running = proc.poll() is None
    assert proc.wait(timeout=600) == 0, lines
    assert running, lines  # the first line came while it ran, not with its end
    # BGM's own lines; the C libraries under the renderer (EGL, Mesa) may write a line of their own to the stream
    # now and then (a run of the suite on a loaded machine had one), but a Python traceback never comes.
    said = [line for line in lines if line.startswith(("bgm:", "wrote "))]
    assert not any("Traceback" in line for line in lines), "\n".join(lines)
    steps = [re.fullmatch(r"bgm: progress: (\d+)/100 percent \((.+), \d+\.\d s\)", line) for line in said[:-1]]
    assert all(steps) and len(steps) >= 5, "\n".join(lines)
    done = [int(m[1]) for m in steps]
    assert done == sorted(done) and done[-1] == 100 and done.count(100) == 1, lines
    assert any("surface" in m[2] for m in steps) and said[-1] == f"wrote {png}", lines


def test_bgm_view_without_qt_and_pyvista_says_what_to_install(tmp_path):
    hide = "import sys; [sys.modules.__setitem__(m, None) for m in ('pyvista', 'qtpy', 'pyvistaqt', 'vtk')]; "
    for args in (["view", "--screenshot", str(tmp_path / "x.png")], ["view"]):
        proc = subprocess.run(
            [sys.executable, "-c", hide + BGM_WITH_VIEWER, *args], capture_output=True, text=True, timeout=600
        )
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "pip install -e '.[viewer]'" in lines[0], proc.stderr
    # and the engine's commands still work
    proc = subprocess.run([sys.executable, "-c", hide + BGM_WITH_VIEWER, "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "correspond" in proc.stdout


def test_the_picture_formats_bgm_view_takes_are_those_pyvista_writes():
    pytest.importorskip("pyvista")
    from pyvista.plotting.plotter import SUPPORTED_FORMATS

    from bgm_viewer.cli_hooks import SCREENSHOT_FORMATS

    assert sorted(SCREENSHOT_FORMATS) == sorted(SUPPORTED_FORMATS)


@pytest.mark.parametrize(
    ("platform", "env", "refused"),
    [
        ("linux", {}, True),
        ("linux", {"QT_QPA_PLATFORM": "xcb"}, True),
        ("freebsd14", {"QT_QPA_PLATFORM": "wayland;xcb"}, True),
        ("linux", {"DISPLAY": ":0"}, False),
        ("linux", {"WAYLAND_DISPLAY": "wayland-0"}, False),
        ("linux", {"QT_QPA_PLATFORM": "offscreen"}, False),
        ("linux", {"QT_QPA_PLATFORM": "minimal:enable_fonts"}, False),
        ("darwin", {}, False),
        ("win32", {}, False),
    ],
)
def test_bgm_view_with_no_display_says_so_in_one_line_before_qt_starts(monkeypatch, platform, env, refused):
    """Qt finding no display aborts the process (exit 134, a plug-in dump): bgm refuses first, where it matters."""
    pytest.importorskip("pyvista")
    import bgm_viewer.app
    from bgm_viewer import cli_hooks

    opened = []
    monkeypatch.setattr(bgm_viewer.app, "run_viewer", lambda *args, **kw: opened.append(args) or 0)
    monkeypatch.setattr(cli_hooks, "sys", SimpleNamespace(platform=platform))
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"):
        monkeypatch.delenv(name, raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    run = bgm("view", cli.DEMO_CSV)
    if refused:
        assert error_line(run) == f"bgm: error: {cli_hooks.NO_DISPLAY}" and not opened
        assert len(run.stderr.splitlines()) == 1  # refused before the table is read
    else:
        assert succeeds(run) and len(opened) == 1


@pytest.fixture
def demo_build_stub(monkeypatch):
    """``bgm demo``'s build replaced by a report (the build is tested in test_build.py): the folders it was asked for."""
    built = []

    def build(holes, out, *args, **kw):
        built.append(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "report.md").write_text("# demo report\n")

    monkeypatch.setattr(cli, "_run_build", build)
    return built


def test_bgm_demo_view_opens_the_viewer_on_the_demo_it_built(monkeypatch, tmp_path, demo_build_stub):
    """It once failed after the build: the viewer was called without the table options (KeyError: 'x')."""
    pytest.importorskip("pyvista")
    import bgm_viewer.app

    opened = []
    monkeypatch.setattr(bgm_viewer.app, "run_viewer", lambda *args, **kw: opened.append((args, kw)) or 0)
    monkeypatch.setenv("DISPLAY", ":0")
    run = succeeds(bgm("demo", "--out", tmp_path / "demo", "--view"))
    assert "# demo report" in run.stdout and demo_build_stub == [tmp_path / "demo"]
    assert opened == [((cli.DEMO_CSV, None), {"cache": True})]  # the build's stages, from the cache


def test_bgm_demo_view_with_no_display_is_refused_before_the_build(monkeypatch, tmp_path, demo_build_stub):
    from bgm_viewer import cli_hooks

    monkeypatch.setattr(cli_hooks, "sys", SimpleNamespace(platform="linux"))
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"):
        monkeypatch.delenv(name, raising=False)
    error_line(bgm("demo", "--out", tmp_path / "demo", "--view"), "no display")
    assert demo_build_stub == [] and not (tmp_path / "demo").exists()


def _view_option_help(name: str) -> str:
    """The ``--help`` text of ``bgm view``'s option ``name``, as typer shows it."""
    from typer.main import get_command

    from bgm_viewer.cli_hooks import register

    if "view" not in {c.name for c in cli.app.registered_commands}:
        register(cli.app)  # as its installed entry point does
    command = get_command(cli.app).get_command(None, "view")  # type: ignore[attr-defined]
    return next(p.help for p in command.params if p.name == name)


def test_view_layers_help_lists_exactly_the_names_it_accepts():
    from bgm_viewer.layer_names import LAYER_NAMES, parse_layers

    text = _view_option_help("layers")
    listed = text.split("): ", 1)[1].split(" (default")[0].split(", ")
    assert listed == list(LAYER_NAMES)  # uncertainty and suggested holes too
    for name in listed:
        for spelling in (name, name.upper(), name.replace(" ", "-"), name.replace(" ", "_")):
            assert parse_layers(spelling) == [name]


def test_view_bench_is_a_bench_pair_and_its_range_is_stated(tmp_path):
    pytest.importorskip("pyvista")
    from core.synthetic.blobs import make_mine, sample_blastholes

    assert "pair" in _view_option_help("bench") and "upper bench" in _view_option_help("bench")
    csv = tmp_path / "mine.csv"
    sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4).to_csv(csv)
    for bench in (2, -1):
        error_line(bgm("view", csv, "--screenshot", tmp_path / "s.png", "--bench", bench), "3 bench", "0 to 1")


def test_bgm_view_hands_its_view_options_to_the_window(monkeypatch):
    """--geozone, --bench, --layers, --camera and --exaggeration were checked, then only a screenshot used them."""
    pytest.importorskip("pyvista")
    import bgm_viewer.app

    opened = []
    monkeypatch.setattr(bgm_viewer.app, "run_viewer", lambda *args, **kw: opened.append(kw) or 0)
    monkeypatch.setenv("DISPLAY", ":0")
    asked = ("--geozone", "g2", "--bench", "1", "--layers", "contours", "--camera", "top", "--exaggeration", "3")
    succeeds(bgm("view", cli.DEMO_CSV, *asked))
    succeeds(bgm("view", cli.DEMO_CSV))
    view = {"geozone": "g2", "bench": 1, "layers": "contours", "camera": "top", "vertical_exaggeration": 3.0}
    assert opened == [{"cache": True, **view}, {"cache": True}]
