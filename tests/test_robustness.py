"""Malformed and awkward input through the command line (and the engine where cheap).

Every case ends either in one clear line naming the problem and exit status 2
(``bgm: error: ...``), or in a correct result, possibly with a documented
warning (``bgm: warning: ...``). None ends in a traceback, exit 1 (an uncaught
Click error) or exit 3 (``bgm: internal error``).
"""

from __future__ import annotations

import codecs
import gzip
import io
import json
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import clirun
import numpy as np
import pandas as pd
import pytest
import shapely
from shapely.geometry import shape

from core.errors import BGMInputError
from core.io.blastholes import BGMWarning, blastholes_from_table, read_blastholes
from core.io.tables import read_table
from core.synthetic.blobs import make_mine, sample_blastholes

ORIGIN = (650_000.0, 7_400_000.0)


def bgm(*args):
    """``bgm ARGS`` run in this process (see tests/clirun.py): fast, and the same exit codes and messages."""
    return clirun.bgm(*args)


def no_traceback(proc) -> None:
    clirun.no_traceback(proc)


def fails_cleanly(proc: subprocess.CompletedProcess, *phrases: str) -> str:
    """Exit 2 with exactly one ``bgm: error:`` line naming the problem; returns that line."""
    no_traceback(proc)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    errors = [line for line in proc.stderr.splitlines() if line.startswith("bgm: error:")]
    assert len(errors) == 1, proc.stderr
    for phrase in phrases:
        assert phrase.lower() in errors[0].lower(), (phrase, errors[0])
    return errors[0]


def succeeds(proc: subprocess.CompletedProcess) -> subprocess.CompletedProcess:
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    return proc


def strict_json(path: Path):
    """Load JSON refusing NaN/Infinity (they are not JSON)."""

    def bad(token):
        raise AssertionError(f"{path} holds {token}")

    return json.loads(Path(path).read_text(encoding="utf-8"), parse_constant=bad)


def features(path: Path) -> list[dict]:
    data = strict_json(path)
    assert data["type"] == "FeatureCollection"
    return data["features"]


def check_polygons(feats: list[dict]) -> None:
    for f in feats:
        geom = shape(f["geometry"])
        assert f["geometry"]["type"] == "Polygon"
        assert geom.is_valid and not geom.is_empty and geom.area > 0
        ring = f["geometry"]["coordinates"][0]
        assert ring[0] == ring[-1]  # closed


def bench_of(z: np.ndarray, levels) -> np.ndarray:
    return np.abs(np.asarray(z, float)[:, None] - np.asarray(levels, float)[None, :]).argmin(axis=1)


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    """A small 3-bench synthetic mine in mine-grid coordinates (about 1000 holes)."""
    mine = make_mine(seed=7, n_benches=3, extent_m=(120.0, 90.0), origin=ORIGIN)
    return sample_blastholes(mine, seed=8)


@pytest.fixture(scope="module")
def base_csv(table, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("base") / "holes.csv"
    table.to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def base_contours(base_csv, tmp_path_factory) -> list[dict]:
    out = tmp_path_factory.mktemp("base_out") / "contours.geojson"
    succeeds(bgm("contours", base_csv, "--out", out))
    return features(out)


def comparable(feats: list[dict]) -> list[tuple]:
    """Features reduced to what must not change between equivalent inputs (areas to 1e-6 relative)."""
    return sorted(
        (
            f["properties"]["geozone"],
            f["properties"]["bench"],
            f["properties"]["component"],
            f["properties"]["holes"],
            pytest.approx(shape(f["geometry"]).area, rel=1e-3),
        )
        for f in feats
    )


# ---------------------------------------------------------------------------
# Files and tables that cannot be read: one line, exit 2, nothing written


def _with(table: pd.DataFrame, column: str, row: int, value) -> pd.DataFrame:
    t = table.astype({column: object}).copy()
    t.loc[row, column] = value
    return t


BAD_TABLES = {
    "missing column": (lambda t: t.drop(columns=["z"]), ("no z column", "--z")),
    "ambiguous column": (lambda t: t.assign(Easting=t.x), ("ambiguous x column", "Easting", "--x")),
    "non-numeric value": (lambda t: _with(t, "x", 5, "12a"), ("'x'", "non-numeric", "line(s) 7")),
    "NaN coordinate": (lambda t: _with(t, "y", 3, np.nan), ("'y'", "missing", "line(s) 5")),
    "infinite coordinate": (lambda t: _with(t, "x", 4, np.inf), ("'x'", "infinite", "line(s) 6")),
    "minus infinite elevation": (lambda t: _with(t, "z", 0, "-inf"), ("'z'", "infinite", "line(s) 2")),
    "absurd coordinate": (lambda t: _with(t, "x", 9, 1e300), ("'x'", "too large", "line(s) 11")),
    "empty geozone label": (lambda t: _with(t, "geozone", 2, ""), ("geozone", "empty", "line(s) 4")),
    "single hole": (lambda t: t.iloc[:1], ("only 1 hole",)),
    "two holes": (lambda t: t.iloc[:2], ("only 2 hole",)),
    "all holes at one point": (
        lambda t: t.iloc[:50].assign(x=ORIGIN[0], y=ORIGIN[1], z=685.0),
        ("cannot measure the hole spacing", "no bench has two distinct holes"),
    ),
}


@pytest.mark.parametrize("case", list(BAD_TABLES))
def test_bad_tables_fail_with_one_line(table, tmp_path, case):
    mutate, phrases = BAD_TABLES[case]
    path = tmp_path / "holes.csv"
    mutate(table).to_csv(path, index=False)
    out = tmp_path / "out.geojson"
    fails_cleanly(bgm("contours", path, "--out", out), *phrases)
    assert not out.exists()
    # The engine raises the same sentence.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        with pytest.raises(BGMInputError, match=phrases[0].replace("(", r"\(").replace(")", r"\)")):
            read_blastholes(path)


def _write_bytes(data: bytes):
    def make(path: Path) -> Path:
        path.write_bytes(data)
        return path

    return make


#: A table's text large enough that its compressed stream spans many deflate blocks.
_TABLE_TEXT = "".join(
    f"{650000 + 5.3 * i:.2f},{7400000 + 3.1 * (i % 97):.2f},{685 - 10 * (i % 3)},g{i % 4}\n" for i in range(4000)
)
_TABLE_TEXT = ("x,y,z,geozone\n" + _TABLE_TEXT).encode()


def _zipped(flag_bits: int = 0) -> bytes:
    """The table in a zip archive, its member marked encrypted when ``flag_bits`` has bit 0."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("holes.csv", _TABLE_TEXT)
    data = bytearray(buf.getvalue())
    data[6] |= flag_bits  # the local header's flags, then the central directory's
    data[data.find(b"PK\x01\x02") + 8] |= flag_bits
    return bytes(data)


def _damaged(data: bytes, at: float = 0.5) -> bytes:
    """``data`` with 40 bytes inverted ``at`` its length: a disk or transfer error inside the stream."""
    out = bytearray(data)
    start = int(len(out) * at)
    for i in range(start, start + 40):
        out[i] ^= 0xFF
    return bytes(out)


BAD_FILES = {
    "missing file": (lambda p: p.parent / "nope.csv", ("does not exist",)),
    "empty file": (_write_bytes(b""), ("is empty",)),
    "blank lines only": (_write_bytes(b"\n\n   \n"), ("cannot read",)),
    "header only": (_write_bytes(b"x,y,z,geozone\n"), ("header but no rows",)),
    "directory": (lambda p: p.parent, ("is a directory",)),
    "Parquet that is damaged": (
        lambda p: _write_bytes(b"PAR1 x,y,z,geozone\n1,2,3,a\n")(p.with_suffix(".parquet")),
        ("as Parquet",),
    ),
    "binary junk": (_write_bytes(bytes(range(256)) * 8), ("cannot read",)),
    # Archives as a download or a copy that did not finish, or a disk error, leaves them.
    "zip cut short": (
        lambda p: _write_bytes(_zipped()[:300])(p.with_suffix(".zip")),
        ("zip archive is damaged or incomplete",),
    ),
    "zip damaged inside": (
        lambda p: _write_bytes(_damaged(_zipped(), 0.3))(p.with_suffix(".zip")),
        ("compressed data is damaged",),
    ),
    "gzip damaged inside": (
        lambda p: _write_bytes(_damaged(gzip.compress(_TABLE_TEXT), 0.3))(p.with_suffix(".csv.gz")),
        ("compressed data is damaged",),
    ),
    "zip encrypted": (lambda p: _write_bytes(_zipped(0x1))(p.with_suffix(".zip")), ("encrypted",)),
    "UTF-16 text": (
        lambda p: (p.write_text("x,y,z,geozone\n1,2,3,a\n4,5,6,b\n", encoding="utf-16"), p)[1],
        ("not UTF-8",),
    ),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_unreadable_files_fail_with_one_line(tmp_path, case):
    make, phrases = BAD_FILES[case]
    (tmp_path / "in").mkdir()
    path = make(tmp_path / "in" / "holes.csv")
    out = tmp_path / "out.geojson"
    fails_cleanly(bgm("contours", path, "--out", out), *phrases)
    assert not out.exists()
    with pytest.raises(BGMInputError, match=phrases[0]):
        read_blastholes(path)


def _windows_1252(table: pd.DataFrame):
    """The table with an accented label and a degree sign, as Excel on Windows saves "CSV (Comma delimited)"."""

    def make(path: Path) -> Path:
        text = table.assign(geozone=table.geozone.replace({"g1": "Pórfido"}), comment="buzamiento 10°")
        path.write_bytes(text.to_csv(index=False).encode("cp1252"))
        return path

    return make


def test_windows_1252_text_is_read_with_a_warning(table, tmp_path):
    path = _windows_1252(table)(tmp_path / "excel.csv")
    with pytest.raises(UnicodeDecodeError):
        path.read_bytes().decode("utf-8")
    out = tmp_path / "o.geojson"
    proc = succeeds(bgm("contours", path, "--out", out))
    warning = [line for line in proc.stderr.splitlines() if line.startswith("bgm: warning:")]
    assert len(warning) == 1 and str(path) in warning[0] and "read as Windows-1252" in warning[0], proc.stderr
    utf8 = tmp_path / "utf8.csv"
    utf8.write_bytes(path.read_bytes().decode("cp1252").encode("utf-8"))
    succeeds(bgm("contours", utf8, "--out", tmp_path / "utf8.geojson"))
    assert comparable(features(out)) == comparable(features(tmp_path / "utf8.geojson"))
    assert "Pórfido" in {f["properties"]["geozone"] for f in features(out)}
    # The engine: the labels and the other columns as written, and the same warning.
    with pytest.warns(BGMWarning, match="read as Windows-1252"):
        holes = read_blastholes(path)
    assert "Pórfido" in holes.geozones
    with pytest.warns(BGMWarning, match="excel.csv"):
        assert set(read_table(path).comment) == {"buzamiento 10°"}


def test_utf8_with_a_byte_order_mark_is_read_without_warning(table, tmp_path):
    path = tmp_path / "utf8.csv"
    path.write_bytes(
        table.assign(geozone=table.geozone.replace({"g1": "Pórfido"})).to_csv(index=False).encode("utf-8-sig")
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)
        assert "Pórfido" in read_blastholes(path).geozones
        assert list(read_table(path).columns) == list(table.columns)


@pytest.mark.parametrize(
    "where, phrases",
    [
        ("header", ("neither UTF-8 nor Windows-1252", "byte 0x81 on line 1", "CSV UTF-8")),
        ("label", ("neither UTF-8 nor Windows-1252", "byte 0x9D on line 5", "CSV UTF-8")),
        ("late", ("neither UTF-8 nor Windows-1252", "byte 0x8F on line", "CSV UTF-8")),
        ("byte order mark", ("starts as UTF-8", "not UTF-8", "byte 0xB0 on line 2")),
    ],
)
def test_text_in_no_known_encoding_fails_with_one_line(table, tmp_path, where, phrases):
    """Windows-1252 leaves 0x81, 0x8D, 0x8F, 0x90 and 0x9D undefined: such a file is no text BGM can read."""
    text = table.assign(geozone=table.geozone.replace({"g1": "Pórfido"}), comment="°" * 40)
    text = text.to_csv(index=False).encode("cp1252")
    assert len(text) > 64 * 1024
    if where == "header":
        text = text.replace(b"geozone", b"geozone\x81", 1)
    elif where == "label":
        lines = text.split(b"\n")
        lines[4] = lines[4] + b"\x9d"
        text = b"\n".join(lines)
    elif where == "late":  # past the first 64 KiB the reader looks at before choosing an encoding
        text = text + b"650000,7400000,685,g\x8f\n"
    else:
        text = codecs.BOM_UTF8 + text
    path = tmp_path / "holes.csv"
    path.write_bytes(text)
    out = tmp_path / "o.geojson"
    fails_cleanly(bgm("contours", path, "--out", out), str(path), *phrases)
    assert not out.exists()
    with pytest.raises(BGMInputError, match=phrases[0]):
        read_blastholes(path)


@pytest.mark.parametrize(
    "args, phrases",
    [
        (("--units", "yards"), ("unknown length unit", "yards")),
        (("--bench-height", "-5"), ("bench height must be a positive number",)),
        (("--x", "EE"), ("column 'EE' given for x is not in the table",)),
        (("--y", "x"), ("one column is used for two roles",)),
        (("--geozone", "nope"), ("geozone 'nope' is not in", "geozones present: g0, g1")),
    ],
)
def test_bad_options_fail_with_one_line(base_csv, tmp_path, args, phrases):
    fails_cleanly(bgm("contours", base_csv, "--out", tmp_path / "o.geojson", *args), *phrases)


def test_output_path_that_is_a_directory(base_csv, tmp_path):
    fails_cleanly(bgm("contours", base_csv, "--out", tmp_path), "is a directory", str(tmp_path))
    assert [p.name for p in tmp_path.iterdir()] == []  # no temporary file left behind


def test_unknown_geozone_for_correspond_and_morph(base_csv, tmp_path):
    for command in ("correspond", "morph"):
        fails_cleanly(bgm(command, base_csv, "--geozone", "3310", "--out", tmp_path / "o.json"), "'3310'", "present")


@pytest.mark.parametrize("given", ["", ".", "/"])
@pytest.mark.parametrize("command", ["contours", "build", "predict"])
def test_an_input_with_no_file_name_is_said_to_be_a_folder(tmp_path, command, given):
    """``bgm build "$TABLE"`` with the variable unset, or a folder: was ``internal error: ValueError: PosixPath('.')
    has an empty name`` (exit 3)."""
    more = {"predict": ("--geozone", "g1", "--elevations", "600")}.get(command, ())
    out = tmp_path / ("o" if command == "build" else "o.geojson")
    fails_cleanly(bgm(command, given, "--out", out, *more), "is a directory, not a CSV or Parquet file")
    assert not out.exists()


@pytest.mark.parametrize("command", ["correspond", "morph"])
def test_a_geozone_with_no_bench_pair_says_why(table, tmp_path, command):
    """A geozone of one hole (a lone assay of its own label): ``"pairs": 0`` came with no word of why."""
    t = table.astype({"geozone": object}).copy()
    t.loc[t.index[0], "geozone"] = "lonely"
    path = tmp_path / "lonely.csv"
    t.to_csv(path, index=False)
    proc = succeeds(bgm(command, path, "--geozone", "lonely", "--out", tmp_path / "o.json"))
    assert json.loads(proc.stdout)["pairs"] == 0
    assert "bgm: note: geozone lonely is on one bench, never in a component of 3 or more holes" in proc.stderr


ONE_GEOZONE = {
    "correspond": ("--out", "o.json"),
    "morph": ("--out", "o.json"),
    "predict": ("--elevations", "0", "--out", "o.geojson"),
    "evaluate": ("--out", "ev"),
    "view": ("--screenshot", "o.png"),
}


@pytest.mark.parametrize("command", sorted(ONE_GEOZONE))
@pytest.mark.parametrize(
    "given, phrases",
    [
        (("g0,g1",), ("'g0,g1' names 2: g0, g1",)),
        (("g0, nope",), ("names 2: g0, nope", "'nope' not in")),
        (("g0 g1",), ("'g0 g1' names 2: g0, g1",)),
        (("g0", "g1"), ("--geozone is given 2 times: 'g0', 'g1'",)),
    ],
)
def test_a_command_that_models_one_geozone_says_so_when_given_several(base_csv, tmp_path, command, given, phrases):
    """``bgm predict --geozone 3320,3310`` said "'3320,3310' is not in" the table; given twice, the last was taken."""
    options = [a if a.startswith("-") or a == "0" else tmp_path / a for a in ONE_GEOZONE[command]]
    geozones = [a for g in given for a in ("--geozone", g)]
    line = fails_cleanly(bgm(command, base_csv, *geozones, *options), f"bgm {command} takes one geozone", *phrases)
    assert "is not in" not in line
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------
# Project files (--project)


@pytest.mark.parametrize(
    "content, phrases",
    [
        ('{"format": "bgm-project", "version": 1, "overr', ("corrupt", "not valid JSON")),
        ('{"format": "bgm-project", "version": 99, "overrides": []}', ("version 99", "newer", "upgrade")),
        ('{"format": "something-else", "version": 1}', ("not a BGM project file",)),
        ('{"format": "bgm-project", "version": 1, "overrides": [{"geozone": "g1"}]}', ("lacks the field",)),
        (b"\xff\xfe\x00\x81 junk", ("cannot be read",)),
        (None, ("is a directory",)),
        ("missing", ("does not exist",)),
    ],
)
def test_bad_project_files_fail_with_one_line(base_csv, tmp_path, content, phrases):
    project = tmp_path / "project.json"
    if content is None:
        project.mkdir()
    elif isinstance(content, bytes):
        project.write_bytes(content)
    elif content != "missing":
        project.write_text(content)
    out = tmp_path / "c.json"
    fails_cleanly(bgm("correspond", base_csv, "--geozone", "g1", "--project", project, "--out", out), *phrases)
    assert not out.exists()


# ---------------------------------------------------------------------------
# Awkward but valid input: a correct result (and a warning where documented)


@pytest.mark.parametrize("sep, suffix", [(";", ".csv"), ("\t", ".tsv"), ("\t", ".csv"), ("|", ".txt")])
def test_other_delimiters_give_the_same_contours(table, base_contours, tmp_path, sep, suffix):
    path = tmp_path / f"holes{suffix}"
    table.to_csv(path, index=False, sep=sep)
    out = tmp_path / "o.geojson"
    succeeds(bgm("contours", path, "--out", out))
    assert comparable(features(out)) == comparable(base_contours)


def test_parquet_gives_the_same_contours(table, base_contours, tmp_path):
    path = tmp_path / "holes.parquet"
    table.to_parquet(path)
    out = tmp_path / "o.geojson"
    succeeds(bgm("contours", path, "--out", out))
    assert comparable(features(out)) == comparable(base_contours)


def test_single_bench_contours_work_but_correspondence_needs_two(table, tmp_path):
    top = table[bench_of(table.z, [685, 675, 665]) == 0]
    path = tmp_path / "one_bench.csv"
    top.to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    succeeds(bgm("contours", path, "--out", out))
    feats = features(out)
    check_polygons(feats)
    benches = {f["properties"]["bench"] for f in feats}
    assert len(benches) == 1 and abs(benches.pop() - 685.0) < 0.5
    assert {f["properties"]["geozone"] for f in feats} == set(top.geozone)
    big = [f for f in feats if f["properties"]["holes"] >= 15]
    assert big and all(f["properties"]["holes_inside"] >= 0.9 for f in big)
    for command in ("correspond", "morph"):
        o = tmp_path / f"{command}.json"
        fails_cleanly(bgm(command, path, "--geozone", "g1", "--out", o), "single bench", "two or more benches")
        assert not o.exists()


def test_one_geozone_everywhere(table, tmp_path):
    path = tmp_path / "ore.csv"
    table.assign(geozone="ore").to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    proc = succeeds(bgm("contours", path, "--out", out))
    assert "holes, 1 geozone, 3 benches" in proc.stderr, proc.stderr  # not "1 geozones"
    feats = features(out)
    check_polygons(feats)
    assert {f["properties"]["geozone"] for f in feats} == {"ore"}
    # Every bench is one region holding (nearly) all its holes.
    per_bench = {}
    for f in feats:
        per_bench[f["properties"]["bench"]] = per_bench.get(f["properties"]["bench"], 0) + f["properties"]["holes"]
    counts = pd.Series(bench_of(table.z, [685, 675, 665])).value_counts()
    assert len(per_bench) == 3
    for k, z in enumerate((685.0, 675.0, 665.0)):
        assert per_bench[z] == counts[k]
    c = tmp_path / "c.json"
    succeeds(bgm("correspond", path, "--geozone", "ore", "--out", c))
    pairs = strict_json(c)["pairs"]
    assert len(pairs) == 2 and all(len(p["sources"]) >= 1 and len(p["targets"]) >= 1 for p in pairs)


def test_coincident_holes_with_conflicting_labels_are_merged_with_a_warning(table, base_contours, tmp_path):
    dup = table.iloc[:25].copy()
    dup["geozone"] = np.where(dup.geozone == "g0", "g2", "g0")  # conflicting labels at the same spots
    path = tmp_path / "dup.csv"
    pd.concat([table, dup], ignore_index=True).to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    proc = succeeds(bgm("contours", path, "--out", out))
    warning = [line for line in proc.stderr.splitlines() if line.startswith("bgm: warning:")]
    assert len(warning) == 1 and "25 duplicate hole(s)" in warning[0] and "conflicting" in warning[0]
    # The first row is kept: the result is that of the table without the duplicates.
    assert comparable(features(out)) == comparable(base_contours)


def collinear_table() -> pd.DataFrame:
    """One straight row of 40 holes per bench (benches at exact levels), two geozones along it."""
    rows = []
    for z in (100.0, 90.0, 80.0):
        shift = (100.0 - z) / 2  # the ore interval drifts along the row with depth
        for i in range(40):
            x = i * 5.0
            rows.append((ORIGIN[0] + x, ORIGIN[1] + 0.5 * x, z, "ore" if 50 + shift <= x < 125 + shift else "waste"))
    return pd.DataFrame(rows, columns=["x", "y", "z", "geozone"])


def test_collinear_holes(tmp_path):
    t = collinear_table()
    path = tmp_path / "row.csv"
    t.to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    proc = succeeds(bgm("contours", path, "--out", out))
    assert "3 benches" in proc.stderr and "warning" not in proc.stderr  # exact levels are three benches, no duplicates
    feats = features(out)
    check_polygons(feats)
    for z in (100.0, 90.0, 80.0):
        ore = t[(t.z == z) & (t.geozone == "ore")]
        polys = [
            shape(f["geometry"]) for f in feats if f["properties"]["bench"] == z and f["properties"]["geozone"] == "ore"
        ]
        assert polys, z
        region = shapely.union_all(polys)
        assert shapely.contains_xy(region.buffer(1e-6), ore.x.to_numpy(), ore.y.to_numpy()).all()
        waste = t[(t.z == z) & (t.geozone == "waste")]
        assert not shapely.contains_xy(region, waste.x.to_numpy(), waste.y.to_numpy()).any()
    for command in ("correspond", "morph"):
        o = tmp_path / f"{command}.json"
        succeeds(bgm(command, path, "--geozone", "ore", "--out", o))
        assert len(strict_json(o)["pairs"]) == 2


@pytest.mark.parametrize("geozone, keep_bench", [("g1", 0), ("g1", 1), ("g3", 2)])
def test_geozone_on_one_bench_only(table, tmp_path, geozone, keep_bench):
    b = bench_of(table.z, [685, 675, 665])
    t = table.copy()
    t.loc[(t.geozone == geozone) & (b != keep_bench), "geozone"] = "g0"
    assert (t.geozone == geozone).sum() >= 15
    path = tmp_path / "one.csv"
    t.to_csv(path, index=False)
    c = tmp_path / "c.json"
    succeeds(bgm("correspond", path, "--geozone", geozone, "--out", c))
    pairs = strict_json(c)["pairs"]
    z = (685.0, 675.0, 665.0)[keep_bench]
    assert pairs
    # The geozone shows as components on its bench only, the other side of each pair is empty.
    for p in pairs:
        assert (len(p["sources"]) > 0) == (p["source_z"] == z)
        assert (len(p["targets"]) > 0) == (p["target_z"] == z)
        assert np.array(p["association"]).size == 0
    m = tmp_path / "m.json"
    succeeds(bgm("morph", path, "--geozone", geozone, "--out", m))
    data = strict_json(m)
    assert len(data["pairs"]) == len(pairs)
    for p in data["pairs"]:
        for traj in p["trajectories"]:
            assert np.isfinite(np.array(traj, float)).all()


def test_benches_of_very_different_sizes(tmp_path):
    """A densely drilled bench (about 2000 holes) above a sparse one (30 holes)."""
    rng = np.random.default_rng(3)
    rows = []
    for z, spacing, n_side in ((100.0, 3.0, 45), (90.0, 25.0, 6), (80.0, 12.0, 12)):
        g = (np.arange(n_side) - (n_side - 1) / 2) * spacing
        gx, gy = np.meshgrid(g, g[: max(5, n_side - (1 if n_side == 6 else 0))])
        xy = np.column_stack([gx.ravel(), gy.ravel()]) + rng.normal(0, 0.05 * spacing, (gx.size, 2))
        ore = np.hypot(xy[:, 0] - 5 * (100 - z) / 10, xy[:, 1]) < 40.0
        for (x, y), o in zip(xy, ore):
            rows.append((ORIGIN[0] + x, ORIGIN[1] + y, z + rng.uniform(-0.3, 0.3), "ore" if o else "waste"))
    t = pd.DataFrame(rows, columns=["x", "y", "z", "geozone"])
    counts = pd.Series(bench_of(t.z, [100, 90, 80])).value_counts().sort_index().tolist()
    assert counts[0] >= 2000 and counts[1] == 30
    path = tmp_path / "sizes.csv"
    t.to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    succeeds(bgm("contours", path, "--out", out))
    feats = features(out)
    check_polygons(feats)
    assert {f["properties"]["bench"] for f in feats} == {100.0, 90.0, 80.0}
    # Each bench is read at its own pattern: one ore body per bench, not one "component" per sparse hole.
    ore = [f["properties"]["bench"] for f in feats if f["properties"]["geozone"] == "ore"]
    assert sorted(ore) == [80.0, 90.0, 100.0]
    for f in feats:
        if f["properties"]["holes"] >= 15:
            assert f["properties"]["holes_inside"] >= 0.9, f["properties"]
    for command in ("correspond", "morph"):
        o = tmp_path / f"{command}.json"
        succeeds(bgm(command, path, "--geozone", "ore", "--out", o))
        assert len(strict_json(o)["pairs"]) == 2


def test_mine_grid_coordinates_round_trip_below_a_millimetre(table, base_contours, tmp_path):
    """Same holes in a local grid and in the mine grid: the same contours, shifted, to < 0.1 mm."""
    local = table.assign(x=table.x - ORIGIN[0], y=table.y - ORIGIN[1])
    path = tmp_path / "local.csv"
    local.to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    succeeds(bgm("contours", path, "--out", out))
    local_feats = features(out)
    assert len(local_feats) == len(base_contours)
    key = lambda f: (f["properties"]["geozone"], f["properties"]["bench"], f["properties"]["component"])  # noqa: E731
    grid = {key(f): np.array(f["geometry"]["coordinates"][0]) for f in base_contours}
    for f in local_feats:
        a = np.array(f["geometry"]["coordinates"][0])
        b = grid[key(f)]
        assert b[:, 1].min() > 7_399_000  # results in the input's own coordinates
        assert a.shape == b.shape
        assert np.abs(b - np.array(ORIGIN) - a).max() < 1e-4
    # Holes go to the engine's frame and back to sub-millimetre precision.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = blastholes_from_table(table)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(table[["x", "y"]].to_numpy()).query(holes.frame.to_input(holes.xy))
    assert d.max() < 1e-6


def test_feet_give_the_same_contours_scaled(table, base_contours, tmp_path):
    ft = table.assign(x=table.x / 0.3048, y=table.y / 0.3048, z=table.z / 0.3048)
    path = tmp_path / "feet.csv"
    ft.to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    proc = succeeds(bgm("contours", path, "--out", out))
    assert "ft" in proc.stderr
    feet = features(out)
    assert len(feet) == len(base_contours)
    metres = {
        (f["properties"]["geozone"], f["properties"]["component"], f["properties"]["bench"]): f for f in base_contours
    }
    for f in feet:
        g = metres[
            (f["properties"]["geozone"], f["properties"]["component"], round(f["properties"]["bench"] * 0.3048, 1))
        ]
        assert f["properties"]["holes"] == g["properties"]["holes"]
        a = shapely.affinity.scale(shape(f["geometry"]), 0.3048, 0.3048, origin=(0, 0))
        b = shape(g["geometry"])
        assert a.hausdorff_distance(b) < 0.25  # metres: the same contour up to grid discretisation (cells ~1.3 m)
        assert "area_ft2" in f["properties"] and f["properties"]["area_ft2"] == pytest.approx(
            g["properties"]["area_m2"] / 0.3048**2, rel=5e-3
        )


def test_units_option_overrides_the_guess(table, tmp_path):
    ft = table.assign(x=table.x / 0.3048, y=table.y / 0.3048, z=table.z / 0.3048)
    path = tmp_path / "feet.csv"
    ft.to_csv(path, index=False)
    proc = succeeds(bgm("contours", path, "--units", "feet", "--out", tmp_path / "o.geojson"))
    assert "bench height 32.8 ft" in proc.stderr


@pytest.mark.parametrize("scale", [1000.0, 100.0, 0.05])
def test_a_table_in_no_length_unit_blastholes_have_is_refused(table, tmp_path, scale):
    """Millimetres read as "bench height 10003.6 ft, hole spacing 5542 ft"; now refused, naming the spacing."""
    scaled = table.assign(x=table.x * scale, y=table.y * scale, z=table.z * max(scale, 1.0))
    path = tmp_path / "scaled.csv"
    scaled.to_csv(path, index=False)
    out = tmp_path / "o.geojson"
    fails_cleanly(bgm("contours", path, "--out", out), "median hole spacing", " m)" if scale > 1 else " m,", "--units")
    # Given --units, the user vouches for the unit: a warning only.
    proc = succeeds(bgm("contours", path, "--units", "m", "--out", out))
    assert "bgm: warning: the median hole spacing" in proc.stderr


def test_the_summary_says_when_feet_were_guessed(table, base_csv, tmp_path):
    ft = table.assign(x=table.x / 0.3048, y=table.y / 0.3048, z=table.z / 0.3048)
    path = tmp_path / "feet.csv"
    ft.to_csv(path, index=False)
    guessed = succeeds(bgm("contours", path, "--out", tmp_path / "o.geojson")).stderr
    assert "feet guessed from the 32.8-unit bench height" in guessed and "--units m" in guessed
    assert "guessed" not in succeeds(bgm("contours", path, "--units", "ft", "--out", tmp_path / "o.geojson")).stderr
    assert "guessed" not in succeeds(bgm("contours", base_csv, "--out", tmp_path / "o.geojson")).stderr  # metres


# ---------------------------------------------------------------------------
# Atomic saves: an interrupted write leaves the previous output intact


def test_interrupted_geojson_write_keeps_the_previous_file(base_csv, tmp_path, monkeypatch):
    from pathlib import Path as _Path

    from typer.testing import CliRunner

    from core.cli import app

    out = tmp_path / "contours.geojson"
    runner = CliRunner()
    result = runner.invoke(app, ["contours", str(base_csv), "--out", str(out), "--geozone", "g1"])
    assert result.exit_code == 0, result.output
    before = out.read_bytes()
    assert json.loads(before)["features"]

    real_write_text = _Path.write_text
    written = {}

    def write_half_then_interrupt(self, data, *args, **kwargs):
        # The writer gets half its text on disk, then the user presses Ctrl-C.
        real_write_text(self, data[: len(data) // 2], *args, **kwargs)
        written["tmp"] = _Path(self)
        raise KeyboardInterrupt

    monkeypatch.setattr(_Path, "write_text", write_half_then_interrupt)
    result = runner.invoke(app, ["contours", str(base_csv), "--out", str(out), "--geozone", "g2"])
    monkeypatch.undo()
    assert result.exit_code != 0
    # The write really started next to the destination, and was rolled back.
    assert written["tmp"].parent == tmp_path and written["tmp"] != out
    assert not written["tmp"].exists()
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["contours.geojson"]


@pytest.mark.parametrize("command", ["contours", "build"])
def test_a_full_disk_is_said_in_one_line_and_leaves_the_previous_output(base_csv, tmp_path, monkeypatch, command):
    """A disk that fills up while BGM writes (or a quota, a share gone read-only) is the user's to fix.

    It was ``bgm: internal error: OSError: [Errno 28] No space left on device`` (exit 3, as a bug).
    Now one line names the file and the reason (exit 2), and the previous output is as it was.
    """
    import errno
    import os

    out = tmp_path / ("contours.geojson" if command == "contours" else "model")
    if command == "contours":
        out.write_text("previous result\n")

    def disk_full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # where a full disk shows on NFS and some others

    monkeypatch.setattr(os, "fsync", disk_full)
    args = ("--workers", "1") if command == "build" else ()
    line = fails_cleanly(bgm(command, base_csv, "--out", out, *args), "cannot write", "no space left on device")
    monkeypatch.undo()
    if command == "contours":
        assert str(out) in line and out.read_text() == "previous result\n"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["contours.geojson"]
    else:  # named where it was going, not in BGM's staging folder, and nothing left behind
        assert f"{out / 'contours.geojson'}" in line and "nothing was written" in line
        assert list(tmp_path.iterdir()) == []


def test_interrupt_during_json_dump_keeps_the_previous_file(base_csv, tmp_path, monkeypatch):
    """Same through ``correspond`` (atomic_write_text), interrupting while the JSON is encoded."""
    from typer.testing import CliRunner

    import core.cli
    from core.cli import app

    out = tmp_path / "c.json"
    out.write_text("previous result\n")
    before = out.read_bytes()
    real_dumps = json.dumps

    def dumps(obj, *args, **kwargs):
        if isinstance(obj, dict) and "pairs" in obj and "units" in obj:
            raise KeyboardInterrupt
        return real_dumps(obj, *args, **kwargs)

    monkeypatch.setattr(core.cli.json, "dumps", dumps)
    result = CliRunner().invoke(app, ["correspond", str(base_csv), "--geozone", "g1", "--out", str(out)])
    monkeypatch.undo()
    assert result.exit_code != 0
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json"]


def test_ctrl_c_in_the_cli_exits_130_with_one_line(base_csv, tmp_path):
    """``main()`` turns a KeyboardInterrupt while writing into one line and exit 130, old file intact."""
    out = tmp_path / "contours.geojson"
    out.write_text("previous\n")
    code = (
        "import pathlib, core.io.atomic\n"
        "real = pathlib.Path.write_text\n"
        "def boom(self, data, *a, **k):\n"
        "    real(self, data[:10], *a, **k)\n"
        "    raise KeyboardInterrupt\n"
        "pathlib.Path.write_text = boom\n"
        "from core.cli import main; main()\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, "contours", str(base_csv), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert "Traceback" not in proc.stderr
    assert proc.returncode == 130
    assert out.read_text() == "previous\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["contours.geojson"]


@pytest.mark.parametrize(
    "command",
    [
        ["contours"],
        ["correspond", "--geozone", "g1"],
        ["predict", "--geozone", "g1", "--elevations", "600"],
        ["suggest", "--geozone", "g1", "--budget", "3"],
        ["evaluate", "--geozone", "g1"],
        ["build"],
    ],
)
def test_out_dash_is_refused_not_written_as_a_file_named_dash(base_csv, tmp_path, monkeypatch, command):
    """``-`` reads standard input, so ``--out -`` reads as standard output: no file named ``-`` is made."""
    monkeypatch.chdir(tmp_path)
    fails_cleanly(bgm(command[0], base_csv, *command[1:], "--out", "-"), "--out -", "named '-'")
    assert not (tmp_path / "-").exists()


@pytest.mark.parametrize("case", ["input", "project", "folder"])
def test_predict_refuses_uncertainty_files_it_cannot_write_before_any_work(base_csv, tmp_path, case):
    """``--out q.geojson`` also writes q.uncertainty.geojson and q.p_inside.npz: they overwrote an input or a
    project file of that name, and a folder there failed only after q.geojson was written."""
    from core.io.project import Project, save_project

    sidecar = tmp_path / "q.uncertainty.geojson"
    args = []
    if case == "folder":
        sidecar.mkdir()
        data = base_csv
    elif case == "input":
        data = tmp_path / "q.p_inside.npz"
        data.write_bytes(base_csv.read_bytes())
    else:
        data = base_csv
        save_project(Project(), sidecar)
        args = ["--project", sidecar]
    kept = data.read_bytes()
    run = bgm("predict", data, "--geozone", "g1", "--elevations", "600", "--out", tmp_path / "q.geojson", *args)
    fails_cleanly(run, "directory" if case == "folder" else "would be overwritten")
    assert data.read_bytes() == kept and not (tmp_path / "q.geojson").exists()
