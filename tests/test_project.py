"""Tests of core.io.project: project file round trip, errors, atomic saving."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from core.errors import BGMInputError
from core.io.project import (
    VERSION,
    AlignmentOverride,
    Project,
    load_project,
    overrides_for,
    save_project,
)


def sample_project() -> Project:
    return Project(
        parameters={"hole_spacing_m": 6.0, "cells_across": 240},
        overrides=[
            AlignmentOverride("ore", 1210.0, 2, translation=(3.5, -1.25), associate={0: True, 4: False}),
            AlignmentOverride("ore", 1195.0, 0, associate={1: True}),
            AlignmentOverride("waste", 1210.0, 1, translation=(0.0, 2.0)),
        ],
        input_path="data/blastholes.csv",
        reading={"units": "ft", "geozone_column": "DOMAIN"},
    )


def test_round_trip(tmp_path: Path):
    p = tmp_path / "a.bgm.json"
    project = sample_project()
    save_project(project, p)
    data = json.loads(p.read_text())
    assert data["format"] == "bgm-project" and data["version"] == VERSION
    assert load_project(p) == project


def test_overrides_for_matches_geozone_and_z_with_tolerance():
    project = sample_project()
    locked, forced, forbidden = overrides_for(project, "ore", 1210.0 * (1 + 1e-9))
    assert locked == {2: (3.5, -1.25)}
    assert forced == {(2, 0)} and forbidden == {(2, 4)}
    assert overrides_for(project, "ore", 1210.1) == ({}, set(), set())
    assert overrides_for(project, "ore", 1195.0) == ({}, {(0, 1)}, set())
    assert overrides_for(project, "waste", 1210.0)[0] == {1: (0.0, 2.0)}


def test_later_override_wins():
    project = Project(
        overrides=[
            AlignmentOverride("ore", 10.0, 0, associate={3: True}),
            AlignmentOverride("ore", 10.0, 0, associate={3: False}),
        ]
    )
    assert overrides_for(project, "ore", 10.0) == ({}, set(), {(0, 3)})


def test_overrides_feed_correspond_pair():
    from shapely.geometry import Point

    from core.correspondence.pair import correspond_pair

    project = Project(overrides=[AlignmentOverride("ore", 100.0, 0, translation=(1.0, 2.0), associate={1: True})])
    locked, forced, forbidden = overrides_for(project, "ore", 100.0)
    res = correspond_pair(
        [Point(0, 0).buffer(20)],
        [Point(5, 0).buffer(20), Point(200, 0).buffer(5)],
        hole_spacing_m=6.0,
        locked_translations=locked,
        forced=forced,
        forbidden=forbidden,
    )
    assert res.translations[0].tolist() == [1.0, 2.0]
    assert res.association.tolist() == [[True, True]]


def test_missing_file(tmp_path: Path):
    with pytest.raises(BGMInputError, match="does not exist"):
        load_project(tmp_path / "nope.json")


def test_corrupt_file(tmp_path: Path):
    p = tmp_path / "bad.json"
    p.write_text('{"format": "bgm-project", "version": 1, ')
    with pytest.raises(BGMInputError, match="corrupt"):
        load_project(p)


def test_wrong_format(tmp_path: Path):
    p = tmp_path / "other.json"
    p.write_text('{"format": "something-else", "version": 1}')
    with pytest.raises(BGMInputError, match="not a BGM project"):
        load_project(p)


def test_newer_version(tmp_path: Path):
    p = tmp_path / "future.json"
    p.write_text(json.dumps({"format": "bgm-project", "version": VERSION + 1}))
    with pytest.raises(BGMInputError, match=rf"version {VERSION + 1}, newer.*upgrade"):
        load_project(p)


def test_malformed_override(tmp_path: Path):
    p = tmp_path / "x.json"
    p.write_text(json.dumps({"format": "bgm-project", "version": 1, "overrides": [{"geozone": "ore", "source": 1}]}))
    with pytest.raises(BGMInputError, match="source_z"):
        load_project(p)
    p.write_text(
        json.dumps(
            {
                "format": "bgm-project",
                "version": 1,
                "overrides": [{"geozone": "ore", "source_z": 1, "source": 1, "translation": [1]}],
            }
        )
    )
    with pytest.raises(BGMInputError, match="translation"):
        load_project(p)


def test_failed_write_leaves_old_file(tmp_path: Path, monkeypatch):
    p = tmp_path / "proj.json"
    save_project(sample_project(), p)
    before = p.read_text()

    def boom(self, *args, **kwargs):  # fails after the temp file exists
        with open(self, "w") as fh:
            fh.write('{"format": "bgm-pro')
        raise OSError("disk full")

    monkeypatch.setattr(Path, "write_text", boom)
    with pytest.raises(OSError, match="disk full"):
        save_project(Project(parameters={"changed": True}), p)
    monkeypatch.undo()
    assert p.read_text() == before
    assert load_project(p) == sample_project()
    assert [f.name for f in tmp_path.iterdir()] == ["proj.json"]  # temp file cleaned up


def test_an_override_of_a_component_the_bench_pair_lacks_is_refused_naming_it():
    from core.io.project import check_override_components

    where = "geozone 'ore', benches 1210 and 1195 m"
    check_override_components(({1: (1.0, 0.0)}, {(1, 2)}, set()), 2, 3, where)  # all there: nothing said
    with pytest.raises(BGMInputError, match=r"geozone 'ore', benches 1210 .* source component 5, .* 2 components"):
        check_override_components(({5: (1.0, 0.0)}, set(), set()), 2, 3, where)
    with pytest.raises(BGMInputError, match=r"target component 7, but the lower bench has 3 components \(0 to 2\)"):
        check_override_components(({}, set(), {(0, 7)}), 2, 3, where)


def test_a_project_saved_with_a_byte_order_mark_is_read(tmp_path: Path):
    """Windows PowerShell 5 (`Out-File -Encoding utf8`) writes UTF-8 with a BOM: it was "corrupt"."""
    p = tmp_path / "p.json"
    p.write_bytes(b"\xef\xbb\xbf" + json.dumps(sample_project().to_dict()).encode())
    assert load_project(p) == sample_project()


def test_a_project_with_overrides_applied_to_another_input_is_warned_about(tmp_path: Path, recwarn):
    """Overrides name components by number: applied to another table they may move other bodies."""
    import warnings

    from core.errors import BGMWarning
    from core.io.project import check_project_input

    (tmp_path / "data").mkdir()
    saved, other = tmp_path / "data" / "blastholes.csv", tmp_path / "other.csv"
    saved.write_text("x,y,z,geozone\n")
    other.write_text("x,y,z,geozone\n")
    project, path = sample_project(), tmp_path / "p.json"  # input_path "data/blastholes.csv", beside it
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)
        check_project_input(project, path, saved)  # its own input: nothing to say
        check_project_input(Project(parameters={}, input_path="other.csv"), path, saved)  # no overrides
    with pytest.warns(BGMWarning, match=r"saved for data/blastholes.csv, not .*other.csv: its 3 alignment"):
        check_project_input(project, path, other)


def test_a_length_far_outside_its_range_in_hole_spacings_is_warned_about(recwarn):
    """Lengths are metres whatever the input's unit: 30 meant as feet is 5 spacings of a 6 m pattern."""
    import warnings

    import numpy as np
    from conftest import constructed_bench, hex_grid

    from core.errors import BGMWarning
    from core.io.project import check_project

    xy = hex_grid(12, 12)
    holes = constructed_bench(xy, np.where(xy[:, 0] > 30, "a", "b"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)
        check_project(Project(parameters={"search_radius_m": 10.0}), holes, uses_parameters=True)
    with pytest.warns(BGMWarning, match=r"search_radius_m = 30 m is 5 hole spacings .* metres, whatever"):
        check_project(Project(parameters={"search_radius_m": 30.0}), holes, uses_parameters=True)


def _table_in_feet_with_a_domain_column(tmp_path: Path) -> Path:
    """The small mine, its geozones in a column no alias finds, its 10-unit benches read as metres unless told."""
    from core.synthetic.blobs import make_mine, sample_blastholes

    table = sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    path = tmp_path / "holes.csv"
    table.rename(columns={"geozone": "DOMAIN_CODE"}).to_csv(path, index=False)
    return path


def test_a_project_reads_its_input_with_the_options_it_was_made_with(tmp_path: Path):
    """A project saved after `bgm view holes.csv --units ft --geozone-column DOMAIN_CODE` lost both:
    `bgm correspond --project` then failed (no geozone column) or, with the column found, read feet as metres.
    An option given that the project records otherwise is refused; a project without them stays version 1."""
    from clirun import bgm

    from bgm_viewer.model import ViewerModel
    from core.io.blastholes import read_blastholes

    csv = _table_in_feet_with_a_domain_column(tmp_path)
    model = ViewerModel(read_blastholes(csv, geozone="DOMAIN_CODE", length_unit="ft"))
    model.input_path = str(csv)
    model.save_project(tmp_path / "p.json")  # as File > Save project does

    out = tmp_path / "c.json"
    run = bgm("correspond", csv, "--geozone", "g1", "--project", tmp_path / "p.json", "--out", out)
    assert run.returncode == 0, run.stderr
    assert "--units ft" in run.stderr and "bench height 10.0 ft" in run.stderr  # said, and read in feet
    assert load_project(tmp_path / "p.json").reading == {"geozone_column": "DOMAIN_CODE", "units": "ft"}

    run = bgm("correspond", csv, "--geozone", "g1", "--project", tmp_path / "p.json", "--out", out, "--units", "m")
    assert run.returncode == 2 and "--units m conflicts with project file" in run.stderr
    run = bgm("correspond", csv, "--geozone", "g1", "--project", tmp_path / "p.json", "--out", out, "--units", "feet")
    assert run.returncode == 0, run.stderr  # the same unit, spelt otherwise

    save_project(
        Project(parameters={"cells_across": 240}), tmp_path / "old.json"
    )  # no reading options: what older BGMs read
    assert json.loads((tmp_path / "old.json").read_text())["version"] == 1
    assert "reading_options" not in json.loads((tmp_path / "old.json").read_text())
    assert load_project(tmp_path / "old.json").reading == {}


def test_a_project_with_unknown_reading_options_is_refused(tmp_path: Path):
    p = tmp_path / "p.json"
    p.write_text(json.dumps({"format": "bgm-project", "version": 2, "reading_options": {"units": "furlongs"}}))
    with pytest.raises(BGMInputError, match="unknown length unit"):
        load_project(p)
    p.write_text(json.dumps({"format": "bgm-project", "version": 2, "reading_options": {"unit": "ft"}}))
    with pytest.raises(BGMInputError, match="unknown option"):
        load_project(p)


def test_the_viewers_camera_and_layers_round_trip_and_a_bad_camera_is_refused_naming_it(tmp_path: Path):
    """A view set up in the viewer (camera, layers shown) was lost on saving: a project now keeps both as plain
    numbers and flags under "viewer", checked on reading; one saved before them still opens (without them)."""
    camera = {
        "position": [1500.5, -220.0, 1400.0],
        "focal_point": [1200.0, 80.25, 1190.0],
        "view_up": [0.3, 0.4, 0.866],
        "parallel_scale": None,
        "window_center": [0.05, -0.1],
    }
    viewer = {"geozone": "ore", "camera": camera, "layers": {"blastholes": False, "GVF": True}}
    project = Project(parameters={"viewer": viewer})
    save_project(project, tmp_path / "p.json")
    assert json.loads((tmp_path / "p.json").read_text())["version"] == 1  # older BGMs read it, and ignore the view
    assert load_project(tmp_path / "p.json").parameters["viewer"] == viewer

    old = {"format": "bgm-project", "version": 1, "parameters": {"viewer": {"geozone": "ore", "bench": 1}}}
    (tmp_path / "old.json").write_text(json.dumps(old))
    assert "camera" not in load_project(tmp_path / "old.json").parameters["viewer"]

    for bad, said in (
        ({**camera, "position": [1.0, 2.0]}, "position must be three finite numbers"),
        ({**camera, "focal_point": [1.0, float("nan"), 3.0]}, "focal_point must be three finite numbers"),
        ({**camera, "focal_point": camera["position"]}, "looks from its focal point"),
        ({**camera, "view_up": [0.0, 0.0, 0.0]}, "view_up must be a direction across the line of sight"),
        ({**camera, "view_up": [-601.0, 600.5, -420.0]}, "view_up must be a direction across the line of sight"),
        ({**camera, "parallel_scale": -1.0}, "parallel_scale must be a positive number or null"),
        ({**camera, "zoom": 2}, "has unknown key(s) 'zoom'"),
        ("iso", "must be an object"),
    ):
        data = {"format": "bgm-project", "version": 1, "parameters": {"viewer": {"camera": bad}}}
        (tmp_path / "bad.json").write_text(json.dumps(data).replace("NaN", '"NaN"'))
        with pytest.raises(BGMInputError, match=re.escape(f"bad.json: viewer setting camera {said}")):
            load_project(tmp_path / "bad.json")
    data = {"format": "bgm-project", "version": 1, "parameters": {"viewer": {"layers": {"GVF": "yes"}}}}
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(BGMInputError, match="viewer setting layers must be an object of layer name -> true/false"):
        load_project(tmp_path / "bad.json")
