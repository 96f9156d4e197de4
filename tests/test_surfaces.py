"""Closed geozone surfaces from stacked sections, and their export (core.model.surfaces, core.io.export)."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import ezdxf
import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely import affinity
from shapely.geometry import LinearRing, MultiPolygon, Point, Polygon, box, shape

from core.errors import BGMInputError
from core.io import export as export_mod
from core.io.export import (
    DEFAULT_FORMATS,
    SURFACE_FORMATS,
    export_all,
    export_surface,
    omf_available,
    write_geojson,
)
from core.model.surfaces import drilled_faces, mesh_summary, surface_from_sections, to_input_frame

MINE_ORIGIN = (650000.0, 7400000.0)


def disc(cx, cy, r, n=128):
    return Point(cx, cy).buffer(r, n)


def ellipse(cx, cy, a, b, n=128):
    return affinity.translate(affinity.scale(Point(0, 0).buffer(1.0, n), a, b), cx, cy)


def assert_closed(mesh):
    s = mesh_summary(mesh)
    assert s["watertight"], s
    assert s["winding_consistent"], s
    assert s["volume_m3"] > 0, s
    assert s["area_m2"] > 0, s
    assert s["faces"] == len(mesh.faces) and s["vertices"] == len(mesh.vertices)
    return s


@pytest.fixture(scope="module")
def small_mesh():
    """A drifting, shrinking ellipse body, coarse enough for quick exports."""
    secs = [(-10.0 * k, ellipse(3.0 * k, 2.0 * k, 40 - 3 * k, 25 - 2 * k)) for k in range(4)]
    return surface_from_sections(secs, cell_size_m=3.0)


# --------------------------------------------------------------------------- geometry


def test_cylinder_volume_and_caps_irregular_spacing():
    r, zs = 30.0, [40.0, 0.0, 7.0, 20.0]  # unsorted, irregular
    mesh = surface_from_sections([(z, disc(5.0, -3.0, r)) for z in zs], cell_size_m=1.5)
    s = assert_closed(mesh)
    expected = math.pi * r**2 * 40.0
    assert s["volume_m3"] == pytest.approx(expected, rel=0.02)
    # capped flat at the lowest and highest sections
    assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=0.05)
    assert mesh.bounds[1, 2] == pytest.approx(40.0, abs=0.05)
    # the wall follows the polygon, not its pixels
    radial = np.hypot(mesh.vertices[:, 0] - 5.0, mesh.vertices[:, 1] + 3.0)
    wall = (mesh.vertices[:, 2] > 1.0) & (mesh.vertices[:, 2] < 39.0)
    assert np.abs(radial[wall] - r).max() < 0.3 * 1.5


def test_drifting_shrinking_ellipses_volume():
    """Sections of an inclined elliptic frustum: volume = integral of pi a(z) b(z) dz."""

    def params(depth):
        return 4.0 * depth / 10, 1.5 * depth / 10, 60.0 - 2.0 * depth / 10, 35.0 - 1.5 * depth / 10

    depths = np.arange(0.0, 71.0, 10.0)  # 8 sections
    secs = [(-d, ellipse(*params(d))) for d in depths]
    mesh = surface_from_sections(secs, cell_size_m=2.0)
    s = assert_closed(mesh)
    zz = np.linspace(0.0, 70.0, 2001)
    area = np.array([math.pi * params(d)[2] * params(d)[3] for d in zz])
    expected = float(np.sum((area[1:] + area[:-1]) / 2 * np.diff(zz)))
    assert s["volume_m3"] == pytest.approx(expected, rel=0.05)
    assert mesh.bounds[0, 2] == pytest.approx(-70.0, abs=0.05)
    assert mesh.bounds[1, 2] == pytest.approx(0.0, abs=0.05)
    # the body drifts with depth: its bottom is displaced from its top by about (28, 10.5)
    top = mesh.vertices[mesh.vertices[:, 2] > -0.01]
    bot = mesh.vertices[mesh.vertices[:, 2] < -69.99]
    shift = bot[:, :2].mean(axis=0) - top[:, :2].mean(axis=0)
    assert shift == pytest.approx([28.0, 10.5], abs=1.5)


def test_default_cell_size_caps_grid_near_300_cells():
    secs = [(-10.0 * k, ellipse(0, 0, 150 - 5 * k, 100 - 4 * k)) for k in range(3)]
    mesh = surface_from_sections(secs)
    assert_closed(mesh)
    # ~1 m cells over 300 m: edges are about a cell long
    edges = mesh.edges_unique_length
    assert 0.3 < float(np.median(edges)) < 1.5


def test_region_that_splits_and_one_with_a_hole():
    one = disc(0, 0, 40)
    two = MultiPolygon([disc(-35, 0, 20), disc(35, 0, 20)])
    splitting = surface_from_sections([(0.0, one), (-10.0, one), (-20.0, two), (-30.0, two)], cell_size_m=2.0)
    s = assert_closed(splitting)
    assert len(splitting.split(only_watertight=False)) == 1  # one body, forking with depth
    assert splitting.euler_number == 2

    ring = disc(0, 0, 40).difference(disc(0, 0, 15))
    holed = surface_from_sections([(z, ring) for z in (0.0, -10.0, -20.0)], cell_size_m=2.0)
    s = assert_closed(holed)
    assert holed.euler_number == 0  # a through-hole: genus 1
    assert s["volume_m3"] == pytest.approx(ring.area * 20.0, rel=0.03)

    # a hole that exists on one bench only, and a region split in two at once
    secs = [(0.0, disc(0, 0, 40)), (-10.0, ring), (-20.0, two), (-30.0, disc(0, 0, 30))]
    mixed = surface_from_sections(secs, cell_size_m=2.0)
    assert_closed(mixed)


def test_empty_sections_end_the_body_between_benches():
    secs = [(0.0, Polygon()), (-10.0, disc(0, 0, 30)), (-20.0, disc(0, 0, 30)), (-30.0, MultiPolygon())]
    mesh = surface_from_sections(secs, cell_size_m=2.0)
    s = assert_closed(mesh)
    # the thickest part reaches about halfway towards the empty benches
    assert -7.0 < mesh.bounds[1, 2] < -4.0
    assert -26.0 < mesh.bounds[0, 2] < -23.0
    assert s["volume_m3"] > math.pi * 30**2 * 10.0

    # an empty bench in the middle splits the body in two
    secs = [(0.0, disc(0, 0, 30)), (-10.0, None), (-20.0, disc(0, 0, 30))]
    mesh = surface_from_sections(secs, cell_size_m=2.0)
    assert_closed(mesh)
    assert len(mesh.split(only_watertight=False)) == 2


def test_specks_and_slivers_narrower_than_a_cell_make_no_lenses_or_voids():
    # Between two benches where a body appears, the morph leaves specks and slivers (most under a square metre,
    # some metres long and under one wide): each became a flat lens of no volume, watertight but meaningless.
    body = disc(0, 0, 30)
    sliver = affinity.rotate(box(40.0, 10.0, 60.0, 10.8), 7.0)  # tilted: some node of the grid falls inside it
    specks = [box(50.0, 0.0, 50.6, 0.6), sliver, box(45.0, -20.0, 46.2, -18.8)]
    # On one fraction, a part a little over a cell wide around one node of the grid (nodes at even coordinates
    # here): a lens around that node alone, a fraction of a voxel.
    one_node = box(48.9, -11.1, 51.1, -8.9)
    narrow_hole = body.difference(box(-4.0, -0.4, 4.0, 0.4))
    secs = [(0.0, body), (-10.0, body)]
    secs += [(z, MultiPolygon([narrow_hole, *specks, *([one_node] if z == -5.0 else [])])) for z in (-2.5, -5.0, -7.5)]
    mesh = surface_from_sections(secs, cell_size_m=2.0)
    s = assert_closed(mesh)
    bodies = mesh.split(only_watertight=False)
    assert len(bodies) == 1, sorted(round(b.volume, 3) for b in bodies)
    assert s["volume_m3"] == pytest.approx(body.area * 10.0, rel=0.03)
    # A part or hole a cell wide somewhere is kept: a one-bench pod between the benches is its own body.
    kept = [(z, MultiPolygon([body, disc(50, 0, 3)])) for z in (-2.5, -5.0, -7.5)]
    assert len(surface_from_sections([*secs[:2], *kept], cell_size_m=2.0).split(only_watertight=False)) == 2


def test_a_dyke_narrower_than_a_coarse_cell_keeps_its_surface_when_the_holes_showed_it():
    # A geozone across a wide pit coarsens the grid past half a hole spacing: a dyke one hole wide (5 m holes,
    # 6 m cells) is then narrower than a cell, yet it is what the holes showed, not a morph's speck.
    dyke = affinity.rotate(box(-150.0, -2.0, 150.0, 2.0), 20.0)
    secs = [(z, MultiPolygon([dyke])) for z in (0.0, -10.0, -20.0)]
    mesh = surface_from_sections(secs, cell_size_m=6.0, min_width_m=2.5)
    assert_closed(mesh)
    # Left out, the geozone had no surface at all; kept, the coarse grid draws it all along its length (as
    # beads: a finer grid would join them).
    (x0, y0, _), (x1, y1, _) = mesh.bounds
    d = dyke.bounds
    assert x1 - x0 > 0.9 * (d[2] - d[0]) and y1 - y0 > 0.9 * (d[3] - d[1])


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(8, 30), st.floats(8, 30), st.floats(0, 3.1)),
        min_size=2,
        max_size=4,
    ),
    st.lists(st.floats(3.0, 15.0), min_size=3, max_size=3),
)
def test_random_stacks_are_always_closed(blobs, gaps):
    z = 0.0
    secs = []
    for k, (cx, cy, a, b, rot) in enumerate(blobs):
        secs.append((z, affinity.rotate(ellipse(cx, cy, a, b, 32), rot, use_radians=True)))
        z -= gaps[k % len(gaps)]
    assert_closed(surface_from_sections(secs, cell_size_m=2.5))


def test_bad_sections_are_refused():
    with pytest.raises(BGMInputError, match="two or more elevations"):
        surface_from_sections([(0.0, disc(0, 0, 5)), (0.0, disc(1, 0, 5))])
    with pytest.raises(BGMInputError, match="empty"):
        surface_from_sections([(0.0, Polygon()), (-5.0, MultiPolygon())])
    with pytest.raises(BGMInputError, match="finite"):
        surface_from_sections([(float("nan"), disc(0, 0, 5)), (-5.0, disc(0, 0, 5))])
    with pytest.raises(BGMInputError, match="cell size"):
        surface_from_sections([(0.0, disc(0, 0, 5)), (-5.0, disc(0, 0, 5))], cell_size_m=-1)
    with pytest.raises(BGMInputError, match="voxels"):
        surface_from_sections([(0.0, disc(0, 0, 500)), (-500.0, disc(0, 0, 500))], cell_size_m=0.5)


def test_to_input_frame_formula(small_mesh):
    mpu = 0.3048  # a survey in feet
    out = to_input_frame(small_mesh, MINE_ORIGIN, mpu)
    v = small_mesh.vertices
    assert out.vertices.dtype == np.float64
    np.testing.assert_array_equal(out.faces, small_mesh.faces)
    np.testing.assert_allclose(out.vertices[:, 0], v[:, 0] / mpu + MINE_ORIGIN[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(out.vertices[:, 1], v[:, 1] / mpu + MINE_ORIGIN[1], rtol=0, atol=1e-8)
    np.testing.assert_allclose(out.vertices[:, 2], v[:, 2] / mpu, rtol=0, atol=1e-8)
    assert out.volume == pytest.approx(small_mesh.volume / mpu**3, rel=1e-9)
    with pytest.raises(BGMInputError):
        to_input_frame(small_mesh, MINE_ORIGIN, 0.0)


# --------------------------------------------------------------------------- export


def read_back(path: Path):
    """(vertices, faces count) of an exported surface, read by an independent reader."""
    suffix = path.suffix.lower()
    if suffix in (".obj", ".ply", ".stl"):
        m = trimesh.load(path, process=False, force="mesh")
        return np.asarray(m.vertices), len(m.faces)
    if suffix == ".vtp":
        pv = pytest.importorskip("pyvista")
        poly = pv.read(path)
        assert poly.is_all_triangles
        return np.asarray(poly.points), poly.n_cells
    if suffix == ".dxf":
        doc = ezdxf.readfile(path)
        faces = doc.modelspace().query("3DFACE")
        pts = np.array([[f.dxf.vtx0, f.dxf.vtx1, f.dxf.vtx2] for f in faces], dtype=float)
        return pts.reshape(-1, 3), len(faces)
    if suffix == ".omf":
        import omf

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            project = omf.OMFReader(str(path)).get_project()
        geom = project.elements[0].geometry
        return np.asarray(geom.vertices.array), len(np.asarray(geom.triangles.array))
    raise AssertionError(suffix)


def test_every_format_reopens_with_the_same_faces(small_mesh, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        paths = export_all(small_mesh, tmp_path / "out", "g1", formats=DEFAULT_FORMATS)
    assert set(paths) == set(DEFAULT_FORMATS)
    for fmt, path in paths.items():
        assert path == tmp_path / "out" / f"g1.{fmt}" and path.is_file()
        _, n_faces = read_back(path)
        assert n_faces == len(small_mesh.faces), fmt
    doc = ezdxf.readfile(paths["dxf"])
    assert {f.dxf.layer for f in doc.modelspace().query("3DFACE")} == {"g1"}
    assert not doc.audit().has_errors
    # the re-read meshes are still closed solids of the same volume
    for fmt in ("obj", "ply", "stl"):
        m = trimesh.load(paths[fmt], force="mesh")
        assert m.is_watertight and m.volume == pytest.approx(small_mesh.volume, rel=1e-6)
    # no temporary files left behind
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(f"g1.{f}" for f in DEFAULT_FORMATS)


def test_a_geozone_named_in_another_script_is_written_in_every_format(small_mesh, tmp_path):
    """PLY's header is ASCII: a geozone "minério óxido" made the whole build end in an internal error."""
    formats = (*DEFAULT_FORMATS, "omf") if omf_available() else DEFAULT_FORMATS
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        paths = export_all(small_mesh, tmp_path, "surface", formats=formats, name="minério óxido 矿")
    for fmt, path in paths.items():
        _, n_faces = read_back(path)
        assert n_faces == len(small_mesh.faces), fmt
    header = paths["ply"].read_bytes().split(b"end_header\n")[0]
    assert header.isascii() and b"comment BGM geozone surface min\\xe9rio" in header


def test_omf_export(small_mesh, tmp_path):
    if not omf_available():
        with pytest.raises(BGMInputError, match="omf"):
            export_surface(small_mesh, tmp_path / "g1.omf")
        assert not (tmp_path / "g1.omf").exists()
        pytest.skip("optional 'omf' package not installed")
    path = export_surface(to_input_frame(small_mesh, MINE_ORIGIN, 1.0), tmp_path / "g1.omf")
    verts, n_faces = read_back(path)
    assert n_faces == len(small_mesh.faces)
    assert verts.dtype == np.float64
    assert np.abs(verts - (small_mesh.vertices + [*MINE_ORIGIN, 0.0])).max() < 1e-6


def test_an_omf_surface_says_its_unit(small_mesh, tmp_path):
    """A surface in feet went to OMF with no unit (the project's ``units`` empty): a reader took it for metres."""
    if not omf_available():
        pytest.skip("optional 'omf' package not installed")
    import warnings

    import omf

    path = export_surface(small_mesh, tmp_path / "g1.omf", units="ft")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert omf.OMFReader(str(path)).get_project().units == "ft"


@pytest.mark.parametrize("fmt", ["vtp", "dxf", "ply", "obj"])
def test_mine_grid_coordinates_keep_sub_millimetre_precision(small_mesh, tmp_path, fmt):
    world = to_input_frame(small_mesh, MINE_ORIGIN, 1.0)
    assert world.vertices[:, 1].min() > 7.39e6
    path = export_surface(world, tmp_path / f"g1.{fmt}")
    verts, _ = read_back(path)
    if fmt == "dxf":
        expected = world.vertices[world.faces].reshape(-1, 3)
    else:
        expected = world.vertices
    assert verts.shape == expected.shape
    err = np.abs(verts - expected).max()
    assert err < 1e-3, f"{fmt}: {err} units"
    if fmt in ("vtp", "dxf", "ply"):
        assert err == 0.0  # float64 end to end


def test_stl_at_mine_grid_magnitudes_is_written_in_a_local_frame(small_mesh, tmp_path):
    """float32 cannot hold y ~ 7 400 000 (0.5 m steps): the STL gets a local frame, its offset recorded."""
    world = to_input_frame(small_mesh, MINE_ORIGIN, 1.0)
    path = export_surface(world, tmp_path / "g1.stl")
    verts, n = read_back(path)
    assert n == len(world.faces)
    side = json.loads((tmp_path / "g1.stl.json").read_text())
    offset = np.array(side["offset"])
    assert np.allclose(offset, [*MINE_ORIGIN, 0.0], atol=1000)
    assert path.read_bytes()[:80].decode().startswith(f"BGM add offset x={offset[0]:.0f} y={offset[1]:.0f}")
    # Offset added back, the vertices are the input's to float32 precision of local numbers.
    err = np.abs(verts.reshape(-1, 3, 3) + offset - world.vertices[world.faces]).max()
    assert err < 1e-3
    # Read as readers read it (vertices merged), the surface is as closed as the mesh.
    assert trimesh.load(path, force="mesh").is_watertight
    # A surface near the origin needs no frame: no offset, no sidecar (a stale one is removed).
    export_surface(small_mesh, path)
    assert not (tmp_path / "g1.stl.json").exists()
    assert trimesh.load(path, force="mesh").is_watertight


def test_unknown_format_names_the_supported_ones(small_mesh, tmp_path):
    with pytest.raises(BGMInputError) as info:
        export_surface(small_mesh, tmp_path / "g1.xyz")
    for f in SURFACE_FORMATS:
        assert f in str(info.value)
    with pytest.raises(BGMInputError, match="supported"):
        export_all(small_mesh, tmp_path, "g1", formats=("obj", "gltfx"))
    assert not any(tmp_path.iterdir())  # nothing written when one format is bad
    # fmt overrides the suffix
    p = export_surface(small_mesh, tmp_path / "surface.dat", fmt=".PLY")
    assert read_back(p.rename(tmp_path / "surface.ply"))[1] == len(small_mesh.faces)


@pytest.mark.parametrize("fmt", ["vtp", "dxf", "ply"])
def test_failed_export_leaves_previous_file_intact(small_mesh, tmp_path, monkeypatch, fmt):
    path = export_surface(small_mesh, tmp_path / f"g1.{fmt}")
    before = path.read_bytes()

    real = export_mod._WRITERS[fmt]

    def crashing(tmp, *args):
        real(tmp, *args)  # a full write to the temporary file...
        with open(tmp, "ab") as fh:
            fh.write(b"garbage")
        raise OSError("disk full")  # ...then a failure before the rename

    monkeypatch.setitem(export_mod._WRITERS, fmt, crashing)
    bigger = surface_from_sections([(0.0, disc(0, 0, 10)), (-5.0, disc(0, 0, 10))], cell_size_m=2.0)
    with pytest.raises(OSError, match="disk full"):
        export_surface(bigger, path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


# --------------------------------------------------------------------------- GeoJSON


def test_write_geojson_round_trips_float64(tmp_path):
    x0, y0 = 650123.123456789, 7401234.987654321
    holed = box(x0, y0, x0 + 50.5, y0 + 30.25).difference(box(x0 + 10, y0 + 10, x0 + 20.000001, y0 + 20))
    multi = MultiPolygon([box(x0 - 100, y0, x0 - 90, y0 + 10), box(x0 - 80, y0, x0 - 70, y0 + 10)])
    features = [
        {"geometry": holed, "properties": {"geozone": "g1", "z": np.float64(-12.5), "bench": np.int64(3)}},
        {
            "geometry": {"type": "MultiPolygon", "coordinates": [[list(p.exterior.coords)] for p in multi.geoms]},
            "properties": {"geozone": "g2"},
            "id": 7,
        },
    ]
    path = write_geojson(features, tmp_path / "sub" / "zones.geojson", name="bench 3")
    data = json.loads(path.read_text())
    assert data["type"] == "FeatureCollection" and data["name"] == "bench 3"
    assert [f["properties"]["geozone"] for f in data["features"]] == ["g1", "g2"]
    assert data["features"][0]["properties"] == {"geozone": "g1", "z": -12.5, "bench": 3}
    assert data["features"][1]["id"] == 7
    back = shape(data["features"][0]["geometry"])
    # Bit-identical coordinates; rings may be wound the other way (right-hand rule), hence normalize.
    assert back.normalize().equals_exact(holed.normalize(), 0.0) and len(back.interiors) == 1
    assert shape(data["features"][1]["geometry"]).normalize().equals_exact(multi.normalize(), 0.0)

    with pytest.raises(BGMInputError, match="Point"):
        write_geojson([{"geometry": Point(0, 0)}], tmp_path / "bad.geojson")
    with pytest.raises(BGMInputError):
        write_geojson([{"geometry": holed, "properties": {"v": float("nan")}}], tmp_path / "bad.geojson")
    assert not (tmp_path / "bad.geojson").exists()


def test_write_geojson_is_atomic(tmp_path, monkeypatch):
    path = write_geojson([{"geometry": box(0, 0, 1, 1)}], tmp_path / "zones.geojson")
    before = path.read_bytes()

    def crashing(self, text, *args, **kwargs):
        with open(self, "w") as fh:
            fh.write(text[: len(text) // 2])
        raise KeyboardInterrupt

    monkeypatch.setattr(Path, "write_text", crashing)
    with pytest.raises(KeyboardInterrupt):
        write_geojson([{"geometry": box(0, 0, 2, 2)}], path)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["zones.geojson"]


@pytest.mark.parametrize("z_m", [-1.0, 0.0, 3.0, 9.5, 10.0, 12.0])
def test_the_volume_above_a_plane_is_the_part_of_the_closed_mesh_above_it(z_m):
    from core.model.surfaces import volume_above

    box = trimesh.creation.box(
        extents=(2.0, 3.0, 10.0), transform=trimesh.transformations.translation_matrix((0, 0, 5))
    )
    assert volume_above(box, z_m) == pytest.approx(6.0 * np.clip(10.0 - z_m, 0.0, 10.0), abs=1e-9)
    ball = trimesh.creation.icosphere(subdivisions=4, radius=5.0)
    h = float(np.clip(5.0 - z_m / 2, 0.0, 10.0))  # the cap above z_m / 2: pi h^2 (3 r - h) / 3
    assert volume_above(ball, z_m / 2) == pytest.approx(np.pi * h**2 * (15.0 - h) / 3, abs=0.005 * ball.volume)


def test_geozones_only_accents_tell_apart_get_their_own_dxf_layers(tmp_path):
    """Sanitised for R12, "Süd/Oxid" and "Sud_Oxid" were one layer: mine software merges what shares a layer."""
    from core.io.export import write_polylines_dxf

    labels = ["Süd/Oxid", "Sud_Oxid", "Süd-Oxid", "g1", "Zone Nord éste"]
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    path = write_polylines_dxf([(g, 600.0 + k, square + k) for k, g in enumerate(labels)], tmp_path / "c.dxf")
    lines = list(ezdxf.readfile(path).modelspace().query("POLYLINE"))
    by_z = {round(line.dxf.elevation[2]) - 600: line.dxf.layer for line in lines}
    layers = [by_z[k] for k in range(len(labels))]
    assert len(set(layers)) == len(labels), layers
    assert layers[1] == "Sud_Oxid" and layers[2] == "Sud-Oxid" and layers[4] == "Zone_Nord_este", layers
    assert all(len(layer) <= 31 and layer.isascii() for layer in layers)


def test_geozones_only_case_tells_apart_get_their_own_dxf_layers(tmp_path):
    """DXF layer names are case-insensitive: "ox" and "OX" on layers "ox" and "OX" were read back as one layer."""
    from core.io.export import write_polylines_dxf

    labels = ["ox", "OX", "Ox_2", "sulphide"]
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    path = write_polylines_dxf([(g, 600.0 + k, square + k) for k, g in enumerate(labels)], tmp_path / "c.dxf")
    doc = ezdxf.readfile(path)
    lines = list(doc.modelspace().query("POLYLINE"))
    by_z = {round(line.dxf.elevation[2]) - 600: line.dxf.layer.casefold() for line in lines}
    layers = [by_z[k] for k in range(len(labels))]
    assert len(set(layers)) == len(labels), layers
    # Every geozone's layer is in the layer table as read back (one entry per case-folded name).
    assert {layer.dxf.name.casefold() for layer in doc.layers} >= set(layers)


def test_write_geojson_winds_rings_by_the_right_hand_rule(tmp_path):
    """RFC 7946: outlines counterclockwise, holes clockwise; predicted sections came out wound the other way."""
    x0, y0 = 650123.0, 7401234.0
    # GEOS overlays wind their outlines clockwise: a section made by difference or union, as predictions are.
    holed = box(x0, y0, x0 + 50, y0 + 30).difference(box(x0 + 10, y0 + 10, x0 + 20, y0 + 20))
    clockwise = Polygon(list(box(x0 - 100, y0, x0 - 90, y0 + 10).exterior.coords)[::-1])
    assert not holed.exterior.is_ccw and not clockwise.exterior.is_ccw  # the cases the rule is about
    features = [{"geometry": holed}, {"geometry": MultiPolygon([clockwise, box(x0 - 80, y0, x0 - 70, y0 + 10)])}]
    data = json.loads(write_geojson(features, tmp_path / "sections.geojson").read_text())
    polygons = [data["features"][0]["geometry"]["coordinates"], *data["features"][1]["geometry"]["coordinates"]]
    assert [LinearRing(p[0]).is_ccw for p in polygons] == [True, True, True]
    assert [LinearRing(hole).is_ccw for p in polygons for hole in p[1:]] == [False]
    # Only the order of the vertices changed: the same ground, to the bit.
    assert shape(data["features"][0]["geometry"]).normalize().equals_exact(holed.normalize(), 0.0)
    assert shape(data["features"][1]["geometry"]).area == MultiPolygon([clockwise, box(0, 0, 10, 10)]).area


def test_drilled_faces_shade_ground_no_bench_bracketed():
    """A pit narrowing with depth: the surface under the upper bench's outer drilling, and below the
    deepest bench, lies in ground no two benches bracket; between the benches' common drilling it does not."""
    levels = [100.0, 90.0]
    drilled_areas = [box(0, -50, 200, 50), box(0, -50, 100, 50)]  # the lower bench drilled half as far east
    body = box(20, -30, 180, 30)
    mesh = surface_from_sections([(100.0, body), (90.0, body), (80.0, body)])
    drilled = drilled_faces(mesh, levels, drilled_areas, reach_m=3.0)
    x, z = mesh.triangles_center[:, 0], mesh.triangles_center[:, 2]
    between = (z < 99.0) & (z > 91.0)
    assert drilled[between & (x < 90)].all()
    assert not drilled[between & (x > 110)].any()
    assert not drilled[z < 89.0].any()  # below the deepest bench: its depth trend
    top = z > 100.0 - 1e-6
    assert drilled[top & (x < 190)].all()  # the top bench drilled its whole section
    area = mesh.area_faces
    assert 0.2 < area[drilled].sum() / area.sum() < 0.6


def test_drilled_faces_needs_a_bench_on_each_side():
    """A surface over ground neither bench drilled is drilled nowhere; with no bench, nowhere either."""
    mesh = surface_from_sections([(100.0, box(0, 0, 50, 50)), (90.0, box(0, 0, 50, 50))])
    far = [box(500, 500, 600, 600)] * 2
    assert not drilled_faces(mesh, [100.0, 90.0], far, reach_m=5.0).any()
    assert not drilled_faces(mesh, [], [], reach_m=5.0).any()


def test_drilled_faces_are_written_per_face_in_vtp_and_ply(tmp_path):
    """A surface's drilled faces reach mine software: VTP cell data and a PLY face property, face for face."""
    import pyvista as pv

    mesh = trimesh.creation.box(extents=(10.0, 10.0, 10.0))
    drilled = np.arange(len(mesh.faces)) % 3 == 0
    mesh.face_attributes["drilled"] = drilled
    moved = to_input_frame(mesh, MINE_ORIGIN, 0.3048)
    vtp = pv.read(export_surface(moved, tmp_path / "s.vtp"))
    assert vtp.n_cells == len(drilled) and np.array_equal(vtp.cell_data["drilled"].astype(bool), drilled)
    ply = trimesh.load(export_surface(moved, tmp_path / "s.ply"), process=False)
    assert np.array_equal(ply.metadata["_ply_raw"]["face"]["data"]["drilled"].astype(bool), drilled)
    assert np.allclose(ply.vertices, moved.vertices)
