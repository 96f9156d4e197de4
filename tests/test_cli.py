"""The bgm command line: contracts from the issues, clear errors, no tracebacks."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import DEMO_CSV
from shapely.geometry import shape

BGM = [sys.executable, "-c", "from core.cli import main; main()"]


def bgm(*args, check=True) -> subprocess.CompletedProcess:
    proc = subprocess.run([*BGM, *map(str, args)], capture_output=True, text=True, timeout=600)
    if check and proc.returncode != 0:
        raise AssertionError(f"bgm {args} failed ({proc.returncode}):\n{proc.stderr}")
    return proc


def test_every_command_has_help():
    out = bgm("--help").stdout
    for command in ("contours", "correspond", "morph"):
        assert command in out
        assert "Usage" in bgm(command, "--help").stdout


def test_contours_on_the_demo_writes_valid_polygons_in_input_coordinates(tmp_path):
    out = tmp_path / "contours.geojson"
    proc = bgm("contours", DEMO_CSV, "--out", out, "--geozone", "g1", "--geozone", "g2")
    summary = json.loads(proc.stdout)
    assert summary["holes_inside_min"] >= 0.95
    data = json.loads(out.read_text())
    table = pd.read_csv(DEMO_CSV)
    features = data["features"]
    assert {f["properties"]["geozone"] for f in features} == {"g1", "g2"}
    benches = {f["properties"]["bench"] for f in features}
    assert 685.0 in benches and len(benches) >= 6
    for f in features:
        geom = shape(f["geometry"])
        assert f["geometry"]["type"] == "Polygon" and geom.is_valid
        assert {"geozone", "bench", "component"} <= set(f["properties"])
        # In mine-grid coordinates, where the holes are.
        assert table.x.min() - 50 < geom.centroid.x < table.x.max() + 50
        assert table.y.min() - 50 < geom.centroid.y < table.y.max() + 50


def test_correspond_and_morph_follow_their_json_contracts(tmp_path):
    out = tmp_path / "c.json"
    bgm("correspond", DEMO_CSV, "--geozone", "g1", "--out", out)
    data = json.loads(out.read_text())
    assert data["geozone"] == "g1" and len(data["pairs"]) == 6
    for p in data["pairs"]:
        ns, nt = len(p["sources"]), len(p["targets"])
        assert np.array(p["association"]).shape == (ns, nt)
        assert len(p["translations"]) == ns
        assert {"id", "centroid", "area"} <= set(p["sources"][0])
        assert p["source_z"] > p["target_z"]
    out = tmp_path / "m.json"
    bgm("morph", DEMO_CSV, "--geozone", "g1", "--out", out)
    data = json.loads(out.read_text())
    for p in data["pairs"]:
        assert 0.0 <= p["target_boundary_coverage"] <= 1.0
        assert p["coverage_before_backtracking"] <= p["target_boundary_coverage"] + 1e-9
        t = np.array(p["trajectories"][0])
        assert t.shape[1] == 3
        assert t[0, 2] == pytest.approx(p["source_z"]) and t[-1, 2] == pytest.approx(p["target_z"])


@pytest.mark.parametrize(
    "content, message",
    [
        (None, "does not exist"),
        ("", "is empty"),
        ("a,b,c\n1,2,3\n", "no x column"),
        ("x,y,z,geozone\n1,2,nan,a\n3,4,5,b\n5,6,7,a\n", "missing, non-numeric"),
    ],
)
def test_bad_input_gives_one_line_and_exit_2(tmp_path, content, message):
    path = tmp_path / "in.csv"
    if content is not None:
        path.write_text(content)
    proc = bgm("contours", path, "--out", tmp_path / "o.geojson", check=False)
    assert proc.returncode == 2
    assert message in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "o.geojson").exists()


def test_unknown_geozone_and_single_bench(tmp_path):
    proc = bgm("correspond", DEMO_CSV, "--geozone", "nope", "--out", tmp_path / "c.json", check=False)
    assert proc.returncode == 2 and "geozones present: g0, g1, g2, g3" in proc.stderr
    t = pd.read_csv(DEMO_CSV)
    one = tmp_path / "one.csv"
    t[t.z > 680].to_csv(one, index=False)
    proc = bgm("correspond", one, "--geozone", "g1", "--out", tmp_path / "c.json", check=False)
    assert proc.returncode == 2 and "single bench" in proc.stderr and "Traceback" not in proc.stderr


def test_a_build_folder_given_as_the_input_names_the_table_it_was_built_from(tmp_path):
    """``bgm demo`` says "open it in 3D with: bgm view"; ``bgm view bgm-demo`` (or any command) was refused
    as "a directory" with no word of the table the folder holds the model of."""
    folder = tmp_path / "bgm-demo"
    folder.mkdir()
    (folder / "summary.json").write_text(json.dumps({"input": "/data/holes.csv", "holes": 3}))
    run = bgm("contours", folder, "--out", tmp_path / "c.geojson", check=False)
    assert run.returncode == 2
    assert "is a directory" in run.stderr and "built from /data/holes.csv: give that table" in run.stderr
    plain = tmp_path / "plain"
    plain.mkdir()
    run = bgm("contours", plain, "--out", tmp_path / "c.geojson", check=False)
    assert run.returncode == 2 and "built from" not in run.stderr


def test_a_build_in_batch_says_how_far_it_is_as_it_goes(tmp_path):
    """Off a terminal (a job scheduler, CI, ``2> log``) a build said nothing between its input summary and
    "wrote report.md" (on Kennecott 100-160 s, as if hung): each step is a line now, flushed as it is done."""
    import os
    import re

    table = pd.read_csv(DEMO_CSV)
    small = tmp_path / "small.csv"
    table[table.z > 650].to_csv(small, index=False)  # the top four benches
    env = {k: v for k, v in os.environ.items() if k != "BGM_PROGRESS"}
    args = [*BGM, "build", str(small), "--out", str(tmp_path / "model"), "--geozone", "g1,g2", "--workers", "1"]
    # Bytes, not text: text mode would turn a bar's carriage returns into line ends.
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    lines, running = [], None
    for line in proc.stderr:  # a pipe: not a terminal
        lines.append(line.decode().removesuffix("\n"))
        if running is None and line.startswith(b"bgm: progress: "):
            running = proc.poll() is None
    stdout = proc.stdout.read().decode()
    assert proc.wait(timeout=600) == 0, "\n".join(lines)
    assert running, lines  # the first line came while the build ran, not with its end
    progress = [line for line in lines if line.startswith("bgm: progress: ")]
    steps = [re.fullmatch(r"bgm: progress: (\d/\d \w+) \(([\w ]+), \d+\.\d s\)", p) for p in progress]
    assert all(steps), progress
    said = [(m[1], m[2]) for m in steps]
    first = said[4][1].removeprefix("correspondence and morph of geozone ")  # one worker: a geozone after the other
    second = "g1" if first == "g2" else "g2"
    assert said == [
        *((f"{k}/4 benches", "contours") for k in (1, 2, 3, 4)),
        *_geozone_steps(first, 3, 8),
        ("1/2 geozones", f"geozone {first}"),
        *_geozone_steps(second, 3, 8),
        ("2/2 geozones", f"geozone {second}"),
    ]
    wrote = next(k for k, line in enumerate(lines) if line.startswith("wrote "))
    assert lines.index(progress[-1]) < wrote  # before the end
    assert "\r" not in "".join(lines) and "\x1b" not in "".join(lines)  # lines, not a bar's redraws
    # stdout, the command line's contract, is as it was: one JSON line.
    summary = json.loads(stdout)
    assert stdout.count("\n") == 1 and summary == {
        "holes": len(pd.read_csv(small)),
        "seconds": summary["seconds"],
        "out": str(tmp_path / "model"),
    }


def _geozone_steps(geozone: str, pairs: int, total: int) -> list[tuple[str, str]]:
    """The steps a build says of one geozone: each of its bench pairs, then what follows, as (count, stage)."""
    after = ["bench fields", "predictions", "uncertainty", "surface", "evaluation"][: total - pairs]
    names = ["correspondence and morph"] * pairs + after
    return [(f"{k}/{total} steps", f"{name} of geozone {geozone}") for k, name in enumerate(names, start=1)]


def _progress_lines(command: list[str]) -> tuple[list[str], list[str]]:
    """The stderr lines of a bgm command run with ``BGM_PROGRESS=lines``, and its progress lines."""
    import os

    env = os.environ | {"BGM_PROGRESS": "lines"}
    run = subprocess.run([*BGM, *command], capture_output=True, text=True, timeout=600, env=env)
    lines = run.stderr.splitlines()
    assert run.returncode == 0, run.stderr
    return lines, [line.removeprefix("bgm: progress: ") for line in lines if line.startswith("bgm: progress: ")]


def _stages(progress: list[str]) -> list[tuple[str, str]]:
    """``(count unit, stage)`` of each progress line ("3/8 steps", "surface of geozone g1")."""
    import re

    found = [re.fullmatch(r"(\d+/\d+ \w+) \((.+), \d+\.\d s\)", line) for line in progress]
    assert all(found), progress
    return [(m[1], m[2]) for m in found]


def test_a_build_on_two_workers_says_each_geozones_steps_in_order_before_the_geozone(tmp_path):
    """Between its last bench's contours and its first geozone done, a Kennecott build said nothing for 12-41 s
    (each geozone's model, predictions, uncertainty, surface and evaluation, on the worker processes), as
    hung. The workers' steps are said as they go, each geozone's in order and before the geozone's line."""
    table = pd.read_csv(DEMO_CSV)
    small = tmp_path / "small.csv"
    table[table.z > 660].to_csv(small, index=False)  # the top three benches: two bench pairs a geozone
    lines, progress = _progress_lines(
        ["build", str(small), "--out", str(tmp_path / "model"), "--geozone", "g1,g2", "--workers", "2"]
    )
    said = _stages(progress)
    assert said[:3] == [(f"{k}/3 benches", "contours") for k in (1, 2, 3)]
    first_geozone = next(k for k, (_, stage) in enumerate(said) if stage.startswith("geozone "))
    assert first_geozone >= 3 + 7, said  # the first geozone's steps came before it: not one silence
    for g in ("g1", "g2"):
        own = [pair for pair in said if pair[1].endswith(f"of geozone {g}")]
        assert own == _geozone_steps(g, 2, 7), said  # in order, each once
        done = said.index(next(pair for pair in said if pair[1] == f"geozone {g}"))
        assert said.index(own[-1]) < done  # every step said before its geozone
    assert sorted(stage for count, stage in said if count.endswith("geozones")) == ["geozone g1", "geozone g2"]
    wrote = next(k for k, line in enumerate(lines) if line.startswith("wrote "))
    assert lines.index("bgm: progress: " + progress[-1]) < wrote


def test_two_geozones_steps_interleaved_are_each_thinned_not_a_flood(monkeypatch, capsys):
    """A table of hundreds of benches gives each geozone hundreds of steps; two workers report them
    interleaved. Thinned as one series, one geozone's lines hid the other's (level counts: none of g2's
    said) or reset it (a lower count: every step a line); each geozone's are thinned on their own."""
    from core import cli

    monkeypatch.setenv("BGM_PROGRESS", "lines")
    with cli.progress_bar("building") as update:
        staged_update = cli._staged(update)
        for done in range(1, 201):
            for g in ("g1", "g2"):
                staged_update(f"correspondence and morph of geozone {g}", done, 205)
    lines = capsys.readouterr().err.splitlines()
    for g in ("g1", "g2"):
        own = [line for line in lines if f"of geozone {g}," in line]
        assert 10 <= len(own) <= cli.PROGRESS_LINES, own


def test_suggest_says_the_contours_and_each_geozones_model_before_its_uncertainty(tmp_path):
    """``bgm suggest`` on Kennecott said nothing for 9-19 s (the benches' contours, then each geozone's model)
    before its one line a geozone: the benches and the model's steps are said as they go."""
    table = pd.read_csv(DEMO_CSV)
    small = tmp_path / "small.csv"
    table[table.z > 660].to_csv(small, index=False)  # the top three benches: two bench pairs a geozone
    args = ["suggest", str(small), "--geozone", "g1,g2", "--budget", "4", "--out", str(tmp_path / "s.csv")]
    _, progress = _progress_lines([*args, "--no-cache"])
    said = _stages(progress)
    assert said[:3] == [(f"{k}/3 benches", "contours") for k in (1, 2, 3)]
    for g in ("g1", "g2"):
        own = [pair for pair in said if pair[1].endswith(f"of geozone {g}")]
        assert own == _geozone_steps(g, 2, 3), said  # its bench pairs, then its model's bench fields
        done = said.index(next(pair for pair in said if pair[1] == f"geozone {g}"))
        assert said.index(own[-1]) < done
    assert [count for count, stage in said if stage.startswith("geozone ")] == ["1/2 geozones", "2/2 geozones"]


def test_an_output_that_is_the_next_option_is_refused(tmp_path):
    """``--out --no-cache`` took "--no-cache" as the file to write, and the flag was dropped without a word."""
    run = subprocess.run(
        [*BGM, "contours", str(DEMO_CSV), "--out", "--no-cache"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 2 and "looks like an option: was --out's value left out?" in run.stderr
    assert not (tmp_path / "--no-cache").exists()


def _commands() -> dict:
    """Every ``bgm`` command as typer builds it, the viewer's ``view`` too (as its entry point adds it)."""
    import typer.main

    from bgm_viewer.cli_hooks import register
    from core import cli

    if "view" not in {c.name for c in cli.app.registered_commands}:
        register(cli.app)
    return typer.main.get_command(cli.app).commands  # type: ignore[attr-defined]


def _flags(command) -> list:
    return [p for p in command.params if getattr(p, "is_flag", False)]


def test_no_help_shows_a_value_after_a_flag():
    """typer 0.29 printed `--keep-isolated <bool>`, `--no-cache <bool>`, even `--help <bool>`: a geologist
    typed `--keep-isolated true` and got "Got unexpected extra argument(s) (true)"."""
    import re

    from typer.testing import CliRunner

    from core import cli

    commands = _commands()
    for args in ([], *([name] for name in commands)):
        said = CliRunner().invoke(cli.app, [*args, "--help"], prog_name="bgm", terminal_width=200)
        assert said.exit_code == 0 and "Usage: bgm" in said.output, (args, said.output)
        assert "<bool>" not in said.output, (args, said.output)
        command = commands[args[0]] if args else None
        names = [(p.opts, p.secondary_opts) for p in _flags(command)] if command else []
        for opts, negative in [*names, (["--help"], [])]:
            # the flag (and its negative) then the description: nothing between them to type
            shown = " / ".join([*opts, *negative])
            assert re.search(rf"^  {re.escape(shown)}(  |\n)", said.output, re.M), (args, shown, said.output)
    # an option that takes a value still says what it takes
    said = CliRunner().invoke(cli.app, ["contours", "--help"], prog_name="bgm", terminal_width=200).output
    assert "--out <path>" in said and "--search-radius <radius>" in said


def test_help_says_what_to_type_in_plain_words():
    """typer 0.29 wrote `Usage: bgm build [OPTIONS] {input}` and `--geozone <list[str]>`, `--x <str>`:
    a literal in braces and a programmer's types. Every command's help now reads as click writes it
    (`INPUT`, `[INPUT]` when it may be left out) with placeholders named for what is typed."""
    import re

    from typer.testing import CliRunner

    from core import cli

    commands = _commands()
    for name, command in commands.items():
        said = CliRunner().invoke(cli.app, [name, "--help"], prog_name="bgm", terminal_width=200).output
        usage = said.splitlines()[0]
        takes_input = any(p.name == "input" for p in command.params)
        if takes_input:
            assert usage in (f"Usage: bgm {name} [OPTIONS] INPUT", f"Usage: bgm {name} [OPTIONS] [INPUT]"), said
            assert re.search(r"^  INPUT  ", said, re.M), said  # the argument without a type after it
        else:
            assert usage == f"Usage: bgm {name} [OPTIONS]", said
        # no Python type names anywhere a value is asked for
        assert not re.search(r"<(str|int|float|bool|list\[[^>]*\])>|\{input\}", said), (name, said)
    build = CliRunner().invoke(cli.app, ["build", "--help"], prog_name="bgm", terminal_width=200).output
    assert "Usage: bgm build [OPTIONS] INPUT" in build
    assert "--geozone <geozone>" in build and "--x <column>" in build and "--units <m|ft>" in build
    view = CliRunner().invoke(cli.app, ["view", "--help"], prog_name="bgm", terminal_width=200).output
    assert "Usage: bgm view [OPTIONS] [INPUT]" in view and "--geozone <geozone>" in view


def test_every_documented_flag_is_given_without_a_value():
    """The flags the README and --help name take no value: the word after one is the next argument."""
    commands = _commands()
    documented = {
        "contours": {"--keep-isolated", "--no-cache"},
        "predict": {"--force", "--no-cache"},
        "demo": {"--view", "--no-view", "--no-cache"},
        **{name: {"--no-cache"} for name in ("correspond", "morph", "evaluate", "build", "suggest", "view")},
    }
    for name, command in commands.items():
        flags = {o: (p, True) for p in _flags(command) for o in p.opts}
        flags |= {o: (p, False) for p in _flags(command) for o in p.secondary_opts}
        assert documented.get(name, set()) <= set(flags), (name, sorted(flags))
        for opt, (param, value) in flags.items():
            parser = command.make_parser(command.context_class(command, info_name=name))
            values, rest, _ = parser.parse_args([opt, "holes.csv"])
            # the next word is the table (or left over where a command takes none), never the flag's value
            others = [*rest, *(v for k, v in values.items() if k != param.name)]
            assert values[param.name] is value and "holes.csv" in others, (name, opt, values, rest)


def test_help_breaks_no_word_at_a_hyphen():
    """In an 80-column terminal `bgm build --help` printed `[default: bgm-` and `out]` on the next line: a
    geologist copying the default got `bgm-`. No line of any command's help ends inside a word."""
    from typer.testing import CliRunner

    from core import cli

    for args in ([], *([name] for name in _commands())):
        said = CliRunner().invoke(cli.app, [*args, "--help"], prog_name="bgm", terminal_width=80).output
        broken = [line for line in said.splitlines() if line.rstrip().endswith("-") and line.strip() != "-"]
        assert not broken, (args, broken)
