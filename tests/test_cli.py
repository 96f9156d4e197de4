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
    steps = [re.fullmatch(r"bgm: progress: (\d/\d \w+) \((contours|geozone g[12]), \d+\.\d s\)", p) for p in progress]
    assert all(steps), progress
    assert [m[1] for m in steps] == [
        "1/4 benches",
        "2/4 benches",
        "3/4 benches",
        "4/4 benches",
        "1/2 geozones",
        "2/2 geozones",
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
