"""Writing geozone surfaces and boundary polygons to files mining software reads.

Every file goes through :func:`core.io.atomic.atomic_path`: an interrupted or
failed export leaves any previous file untouched.

Formats (chosen by suffix, or by ``fmt``):

===== ======================================= ===============================
fmt   writer                                  vertex precision
===== ======================================= ===============================
obj   trimesh (text, 10 decimals)             float64 (to 1e-10 units)
ply   own binary little-endian writer         float64 (``property double``)
stl   trimesh (binary)                        float32 by the STL standard;
                                              mine-grid coordinates go to a
                                              local frame (see below)
vtp   own VTK XML PolyData writer (raw        float64 (``Float64`` points)
      appended data, UInt64 headers)
dxf   own ASCII DXF R12 writer, one 3DFACE    float64 (shortest round-trip
      per triangle on the geozone's layer     repr)
omf   optional ``omf`` package (OMF v1,       float64
      ``SurfaceElement``)
===== ======================================= ===============================

STL can only store float32, which resolves y ~ 7 400 000 to 0.5 m: vertices
a cell apart merge and the surface read back is not closed. So an STL whose
coordinates exceed ``STL_PLAIN_MAX`` is written in a local frame: the offset
(a round number per axis, :func:`stl_offset`) is subtracted before writing,
and recorded in the file's 80-byte header and in ``<name>.stl.json`` next to
it; add it back to get input coordinates.

trimesh's own PLY exporter stores float32 vertices, which is why PLY is
written here. The VTP writer does not need VTK (no vtk/pyvista import in
core). OMF: the only Open Mining Format writer on PyPI that installs on
Python 3.11 with numpy 2 is ``omf`` 1.0.1 (2019, unmaintained, OMF v1); it is
used when installed and otherwise ``.omf`` raises :class:`BGMInputError` with
the install hint.
"""

from __future__ import annotations

import json
import re
import unicodedata
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import mapping, shape
from shapely.geometry.polygon import orient

from core.errors import BGMInputError
from core.io.atomic import atomic_path

if TYPE_CHECKING:  # trimesh costs most of a second to import; only surface writers load it
    import trimesh

#: Formats :func:`export_surface` writes, by canonical name.
SURFACE_FORMATS = ("obj", "ply", "stl", "vtp", "dxf", "omf")
#: Formats :func:`export_all` writes unless told otherwise (OMF needs an extra package).
DEFAULT_FORMATS = ("obj", "ply", "stl", "vtp", "dxf")
#: What each format stores, as ``report.md`` says it.
FORMAT_NOTES = {
    "obj": "text, 10 decimals, input coordinates",
    "ply": "binary float64, input coordinates",
    "stl": "binary float32 (the STL standard): mine-grid coordinates are written in a local frame, "
    "its offset in the file's header and in surface.stl.json (add it back)",
    "vtp": "VTK XML, float64, input coordinates",
    "dxf": "R12 3DFACEs, float64, input coordinates",
    "omf": "OMF v1, float64, input coordinates",
}
#: Largest coordinate magnitude an STL holds as is: float32 resolves it to 1e-3 units.
STL_PLAIN_MAX = 8192.0

_ALIASES = {"vtkpolydata": "vtp", "vtk-polydata": "vtp"}

__all__ = [
    "DEFAULT_FORMATS",
    "SURFACE_FORMATS",
    "build_formats",
    "export_all",
    "export_surface",
    "json_default",
    "stl_offset",
    "omf_available",
    "write_geojson",
]


def export_surface(
    mesh: trimesh.Trimesh,
    path: str | Path,
    fmt: str | None = None,
    *,
    name: str | None = None,
    layer: str | None = None,
    units: str | None = None,
) -> Path:
    """Write ``mesh`` to ``path`` atomically and return the path.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The surface (any frame; vertices are written in float64 where the
        format allows).
    path : path-like
        Destination. Its suffix picks the format unless ``fmt`` is given.
    fmt : str, optional
        One of :data:`SURFACE_FORMATS` (case-insensitive, leading dot allowed).
    name : str, optional
        Geozone name: the DXF layer, the OMF element and the VTP/PLY comment.
        Defaults to the file stem.
    layer : str, optional
        The DXF layer, when the caller gives every geozone of a model its own
        (:func:`dxf_layer_names`, as the contours' DXF does); else ``name``
        made R12-safe.
    units : str, optional
        Length unit of the vertices (``"m"`` or ``"ft"``), recorded where the
        format has a place for it: the OMF project's ``units``, a comment in
        PLY, OBJ and VTP, the STL header (and ``.stl.json``). DXF R12 has
        none (``$INSUNITS`` came with R2000).

    Raises
    ------
    BGMInputError
        Unknown format, an empty mesh, non-finite vertices, or OMF without the
        ``omf`` package.
    """
    path = Path(path)
    fmt = _resolve_format(path, fmt)
    name = name if name is not None else path.stem
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0:
        raise BGMInputError(f"cannot export an empty surface to {path}")
    if not np.all(np.isfinite(vertices)):
        raise BGMInputError(f"surface has non-finite vertex coordinates; not writing {path}")

    if fmt == "omf":
        _require_omf()

    with atomic_path(path) as tmp:
        # The DXF writer names its layer after ``name``; a layer already R12-safe keeps its name. The unit goes
        # where the format has a place for it (OMF's field, a comment or header): a reader takes feet for metres.
        _WRITERS[fmt](tmp, vertices, faces, layer if fmt == "dxf" and layer else name, mesh, units or "")
    if fmt == "stl":
        _record_stl_offset(path, stl_offset(vertices), units)
    return path


def stl_offset(vertices: np.ndarray) -> np.ndarray:
    """What is subtracted from an STL's vertices so float32 holds them to 1e-3 units.

    Zero on axes whose coordinates stay within ``STL_PLAIN_MAX``; elsewhere the
    middle of the vertices' range rounded to a multiple of 1000 (a number a
    person can add back).
    """
    v = np.asarray(vertices, dtype=np.float64)
    if len(v) == 0:
        return np.zeros(3)
    lo, hi = v.min(axis=0), v.max(axis=0)
    needed = np.maximum(np.abs(lo), np.abs(hi)) > STL_PLAIN_MAX
    return np.where(needed, np.round((lo + hi) / 2, -3), 0.0)


def _record_stl_offset(path: Path, offset: np.ndarray, units: str | None = None) -> None:
    """``<name>.stl.json`` beside an STL written in a local frame (a stale one removed otherwise).

    It records the offset and ``units``, the vertices' length unit (the offset's too), when given.
    """
    side = path.with_name(path.name + ".json")
    if not offset.any():
        side.unlink(missing_ok=True)
        return
    from core.io.atomic import atomic_write_text

    note = {
        "format": "stl",
        "offset": [float(o) for o in offset],
        **({"units": units} if units else {}),
        "note": "the STL's vertices are in a local frame: add offset to each vertex to get input coordinates",
    }
    atomic_write_text(side, json.dumps(note, indent=1) + "\n")


def export_all(
    mesh: trimesh.Trimesh,
    out_dir: str | Path,
    stem: str,
    formats: Iterable[str] = DEFAULT_FORMATS,
    name: str | None = None,
    layer: str | None = None,
    units: str | None = None,
) -> dict[str, Path]:
    """Write ``mesh`` as ``out_dir/stem.<fmt>`` for every format; returns ``{fmt: path}``.

    ``name`` is the geozone's name (DXF layer, OMF element; ``stem`` if not
    given), ``layer`` its DXF layer if not ``name``'s, ``units`` the vertices' length
    unit (see :func:`export_surface`).
    All formats are validated before anything is written.
    """
    fmts = [_canonical(f) for f in formats]
    if "omf" in fmts:
        _require_omf()
    out_dir = Path(out_dir)
    return {
        f: export_surface(mesh, out_dir / f"{stem}.{f}", f, name=name or stem, layer=layer, units=units) for f in fmts
    }


def write_geojson(
    features: Iterable[Mapping],
    path: str | Path,
    *,
    name: str | None = None,
    units: str | None = None,
) -> Path:
    """Write Polygon/MultiPolygon features as a GeoJSON FeatureCollection, atomically.

    Each feature is a mapping with ``"geometry"`` (a shapely Polygon or
    MultiPolygon, or a GeoJSON-like geometry mapping) and optional
    ``"properties"`` (JSON-serialisable; numpy scalars are converted). Already
    complete GeoJSON Feature dicts are accepted as well.

    Coordinates are written with Python's shortest round-trip float repr, so
    float64 values (e.g. y ~ 7 400 000.123456) read back bit-identical.
    Coordinates are whatever frame they are in (usually the input mine grid);
    note RFC 7946 strictly expects WGS84, so no ``crs`` member is written.
    ``units`` (``"m"`` or ``"ft"``), the length unit of the coordinates and
    lengths, is written as the collection's ``units`` (as in ``summary.json``)
    and as every feature's ``units`` property: a GIS drops the collection's
    foreign members on import, and feet read as metres give no warning.
    """
    out = []
    for k, feat in enumerate(features):
        if not isinstance(feat, Mapping) or "geometry" not in feat:
            raise BGMInputError(f"feature {k} must be a mapping with a 'geometry'")
        geom = feat["geometry"]
        if not isinstance(geom, shapely.Geometry):
            try:
                geom = shape(geom)
            except Exception as exc:
                raise BGMInputError(f"feature {k} has an unreadable geometry: {exc}") from None
        if geom.geom_type not in ("Polygon", "MultiPolygon"):
            raise BGMInputError(f"feature {k} is a {geom.geom_type}; only Polygon and MultiPolygon are written")
        if not geom.is_empty and not np.all(np.isfinite(shapely.get_coordinates(geom))):
            raise BGMInputError(f"feature {k} has non-finite coordinates")
        props = dict(feat.get("properties") or {})
        if units is not None:
            props.setdefault("units", units)
        entry = {"type": "Feature", "properties": props, "geometry": _plain(mapping(_right_hand(geom)))}
        if "id" in feat:
            entry["id"] = feat["id"]
        out.append(entry)
    collection: dict = {"type": "FeatureCollection"}
    if name is not None:
        collection["name"] = name
    if units is not None:
        collection["units"] = units
    collection["features"] = out
    try:
        text = json.dumps(collection, default=json_default, allow_nan=False, indent=None)
    except (TypeError, ValueError) as exc:
        raise BGMInputError(f"GeoJSON properties must be finite JSON values: {exc}") from None
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return path


def _right_hand(geom):
    """``geom`` with its rings wound by RFC 7946's right-hand rule: outlines counterclockwise, holes clockwise.

    Sections come out of the level set and the union of components wound either way (a predicted section's
    outlines were clockwise, a contour's counterclockwise); a GIS or web map that fills by winding then
    draws an outline wound the wrong way as a hole, or a hole as ground. Only the order of each ring's
    vertices changes, never a coordinate.
    """
    if geom.is_empty:
        return geom
    if geom.geom_type == "Polygon":
        return orient(geom, sign=1.0)
    return shapely.MultiPolygon([orient(part, sign=1.0) for part in geom.geoms])


def build_formats() -> tuple[str, ...]:
    """The formats ``bgm build`` writes: :data:`DEFAULT_FORMATS`, and OMF where the ``omf`` package is installed."""
    return (*DEFAULT_FORMATS, "omf") if omf_available() else DEFAULT_FORMATS


def omf_available() -> bool:
    """True when the optional ``omf`` package is importable."""
    try:
        _require_omf()
    except BGMInputError:
        return False
    return True


# --------------------------------------------------------------------------- formats


def _resolve_format(path: Path, fmt: str | None) -> str:
    if fmt is None:
        if not path.suffix:
            raise BGMInputError(
                f"cannot tell the surface format of {path} (no suffix); use one of: {', '.join(SURFACE_FORMATS)}"
            )
        return _canonical(path.suffix)
    return _canonical(fmt)


def _canonical(fmt: str) -> str:
    f = str(fmt).strip().lower().lstrip(".")
    f = _ALIASES.get(f, f)
    if f not in SURFACE_FORMATS:
        raise BGMInputError(f"unknown surface format {fmt!r}; supported: {', '.join(SURFACE_FORMATS)}")
    return f


def _write_obj(tmp: Path, vertices, faces, name, mesh, units: str = "") -> None:
    import trimesh

    m = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    text = trimesh.exchange.obj.export_obj(
        m, include_normals=False, include_color=False, include_texture=False, digits=10
    )
    if units:
        text = f"# units: {units}\n{text}"
    tmp.write_text(text, encoding="utf-8")


def _write_stl(tmp: Path, vertices, faces, name, mesh, units: str = "") -> None:
    """Binary STL, in a local frame when float32 cannot hold the coordinates (offset in the header)."""
    import trimesh

    offset = stl_offset(vertices)
    m = trimesh.Trimesh(vertices=vertices - offset, faces=faces, process=False)
    data = bytearray(trimesh.exchange.stl.export_stl(m))
    header = f"BGM {_one_line(name)[:20]}"
    if offset.any():
        header = f"BGM add offset x={offset[0]:.0f} y={offset[1]:.0f} z={offset[2]:.0f}"
    if units:
        header = f"{header} units {units}"
    data[:80] = header.encode("ascii", "replace")[:80].ljust(80, b" ")
    tmp.write_bytes(bytes(data))


def _write_ply(tmp: Path, vertices, faces, name, mesh, units: str = "") -> None:
    """Binary little-endian PLY with double vertices and int32 triangle indices.

    The header is ASCII (the PLY format's): a geozone named in another script
    (``minério``) is written in its comment with escapes (``min\\xe9rio``).
    The mesh's face flags (:func:`face_flags`) follow each face's indices as ``uchar`` properties.
    """
    flags = face_flags(mesh, len(faces))
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment BGM geozone surface {_ascii_line(name)}\n"
        + (f"comment units {_ascii_line(units)}\n" if units else "")
        + f"element vertex {len(vertices)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {len(faces)}\n"
        "property list uchar int vertex_indices\n" + "".join(f"property uchar {k}\n" for k in flags) + "end_header\n"
    ).encode("ascii")
    if len(vertices) >= 2**31:
        raise BGMInputError("too many vertices for PLY int indices")
    face_rec = np.empty(len(faces), dtype=[("n", "u1"), ("v", "<i4", (3,))] + [(k, "u1") for k in flags])
    face_rec["n"] = 3
    face_rec["v"] = faces
    for k, values in flags.items():
        face_rec[k] = values
    with open(tmp, "wb") as fh:
        fh.write(header)
        fh.write(np.ascontiguousarray(vertices, dtype="<f8").tobytes())
        fh.write(face_rec.tobytes())


def face_flags(mesh, n_faces: int) -> dict[str, np.ndarray]:
    """The mesh's boolean face attributes (``drilled``: :func:`core.model.surfaces.drilled_faces`) as 0/1 bytes.

    Written per face where the format has a place for it (PLY, VTP), so mine software can
    tell the surface in drilled ground from the depth trend carried beyond it.
    """
    attributes = getattr(mesh, "face_attributes", None) or {}
    return {
        str(k): np.asarray(v, np.uint8)
        for k, v in attributes.items()
        if str(k).isidentifier() and np.asarray(v).dtype == bool and np.shape(v) == (n_faces,)
    }


def _write_vtp(tmp: Path, vertices, faces, name, mesh, units: str = "") -> None:
    """VTK XML PolyData, raw appended binary, Float64 points, Int64 connectivity, face flags as UInt8 cell data."""
    flags = face_flags(mesh, len(faces))
    blocks = [
        np.ascontiguousarray(vertices, dtype="<f8").tobytes(),
        np.ascontiguousarray(faces, dtype="<i8").ravel().tobytes(),
        (np.arange(1, len(faces) + 1, dtype="<i8") * 3).tobytes(),
    ] + [values.tobytes() for values in flags.values()]
    offsets = []
    pos = 0
    for b in blocks:
        offsets.append(pos)
        pos += 8 + len(b)
    name_xml = _xml_escape(_one_line(name))
    cell_data = "".join(
        f'        <DataArray type="UInt8" Name="{k}" format="appended" offset="{offsets[3 + i]}"/>\n'
        for i, k in enumerate(flags)
    )
    head = (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n'
        "  <PolyData>\n"
        f"    <!-- BGM geozone surface: {name_xml.replace('--', '- -')}{f', units {_xml_escape(units)}' if units else ''} -->\n"
        f'    <Piece NumberOfPoints="{len(vertices)}" NumberOfVerts="0" NumberOfLines="0" '
        f'NumberOfStrips="0" NumberOfPolys="{len(faces)}">\n'
        + (f"      <CellData>\n{cell_data}      </CellData>\n" if flags else "")
        + "      <Points>\n"
        '        <DataArray type="Float64" Name="Points" NumberOfComponents="3" '
        f'format="appended" offset="{offsets[0]}"/>\n'
        "      </Points>\n"
        "      <Polys>\n"
        '        <DataArray type="Int64" Name="connectivity" '
        f'format="appended" offset="{offsets[1]}"/>\n'
        '        <DataArray type="Int64" Name="offsets" '
        f'format="appended" offset="{offsets[2]}"/>\n'
        "      </Polys>\n"
        "    </Piece>\n"
        "  </PolyData>\n"
        '  <AppendedData encoding="raw">\n   _'
    ).encode()
    with open(tmp, "wb") as fh:
        fh.write(head)
        for b in blocks:
            fh.write(np.array([len(b)], dtype="<u8").tobytes())
            fh.write(b)
        fh.write(b"\n  </AppendedData>\n</VTKFile>\n")


def _write_dxf(tmp: Path, vertices, faces, name, mesh, units: str = "") -> None:
    """ASCII DXF R12 (AC1009): one 3DFACE per triangle on the geozone's layer.

    Written directly rather than through ezdxf's object model, which takes
    about a minute for 300 000 faces; ezdxf reads the result back (and its
    auditor finds nothing to fix). R12 3DFACEs are read by every mining and
    CAD package. Coordinates use Python's shortest round-trip float repr, so
    float64 vertices read back exactly. The fourth corner repeats the third
    (a triangle, as the DXF reference specifies). ``units`` is not written:
    R12 has no header variable for it.
    """
    layer = _dxf_layer_name(name)
    head = _dxf_head([layer], vertices.min(axis=0), vertices.max(axis=0))
    # Each vertex's coordinates formatted once per corner's group codes, not once per face it is a corner of: the
    # same text (Kennecott's eleven surfaces 4.2 -> 1.1 s under cProfile).
    xyz = [[repr(v) for v in column] for column in np.asarray(vertices).T.tolist()]
    corner = [np.array([f"1{k}\n{x}\n2{k}\n{y}\n3{k}\n{z}\n" for x, y, z in zip(*xyz)], dtype=object) for k in range(4)]
    faces = np.asarray(faces)
    with open(tmp, "w", encoding="ascii", newline="\n") as fh:
        fh.write("\n".join(head) + "\n")
        for i in range(0, len(faces), 20000):
            chunk = faces[i : i + 20000]
            parts = np.empty((len(chunk), 5), dtype=object)
            parts[:, 0] = "0\n3DFACE\n8\n" + layer + "\n"
            for k, column in enumerate((0, 1, 2, 2)):  # the fourth corner repeats the third
                parts[:, k + 1] = corner[k][chunk[:, column]]
            fh.write("".join(parts.ravel().tolist()))
        fh.write("0\nENDSEC\n0\nEOF\n")


def _dxf_head(layers: list[str], lo: np.ndarray, hi: np.ndarray) -> list[str]:
    """Group codes and values of an R12 DXF's header, line-type and layer tables, up to its ENTITIES."""
    extent = []
    for name, corner in (("$EXTMIN", lo), ("$EXTMAX", hi)):
        extent += ["9", name] + [v for code, c in zip(("10", "20", "30"), corner) for v in (code, repr(float(c)))]
    ltype = ["0", "TABLE", "2", "LTYPE", "70", "1", "0", "LTYPE", "2", "CONTINUOUS", "70", "0", "3", "Solid line"]
    ltype += ["72", "65", "73", "0", "40", "0.0", "0", "ENDTAB"]
    head = ["0", "SECTION", "2", "HEADER", "9", "$ACADVER", "1", "AC1009", *extent, "0", "ENDSEC"]
    head += ["0", "SECTION", "2", "TABLES", *ltype, "0", "TABLE", "2", "LAYER", "70", str(len(layers))]
    for layer in layers:
        head += ["0", "LAYER", "2", layer, "70", "0", "62", "7", "6", "CONTINUOUS"]
    return head + ["0", "ENDTAB", "0", "ENDSEC", "0", "SECTION", "2", "ENTITIES"]


def write_polylines_dxf(
    rings: Iterable[tuple[str, float, np.ndarray]], path: str | Path, layers: Mapping[str, str] | None = None
) -> Path:
    """Write closed 3D polylines as an R12 DXF, atomically: contours and predicted sections for mine software.

    Each ring is ``(geozone, z, xy)``: its vertices ``xy`` (n, 2) at
    elevation ``z``, on the geozone's layer. Vulcan, Surpac, Datamine,
    Leapfrog and Deswik all read R12 POLYLINEs as strings or polylines, the
    usual way to bring digitised bench contours in. ``layers`` maps geozones
    to their layers when the caller names those of a whole model (every DXF
    of a build puts a geozone on one layer); by default :func:`dxf_layer_names`
    of the rings' geozones.
    """
    rings = list(rings)
    layer = dxf_layer_names(g for g, _, _ in rings) | dict(layers or {})
    rings = [(layer[g], float(z), np.asarray(xy, float)) for g, z, xy in rings]
    xyz = [np.column_stack([xy, np.full(len(xy), z)]) for _, z, xy in rings if len(xy)]
    pts = np.vstack(xyz) if xyz else np.zeros((1, 3))
    body = _dxf_head(sorted({g for g, _, _ in rings}) or ["BGM"], pts.min(axis=0), pts.max(axis=0))
    for layer, z, xy in rings:
        if len(xy) > 1 and np.allclose(xy[0], xy[-1]):
            xy = xy[:-1]  # closed by flag 1, not by a repeated vertex
        body += ["0", "POLYLINE", "8", layer, "66", "1", "70", "9", "10", "0.0", "20", "0.0", "30", repr(z)]
        for x, y in xy.tolist():
            body += ["0", "VERTEX", "8", layer, "10", repr(x), "20", repr(y), "30", repr(z), "70", "32"]
        body += ["0", "SEQEND", "8", layer]
    body += ["0", "ENDSEC", "0", "EOF"]
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(body) + "\n", encoding="ascii")
    return path


def polygon_rings(geometry) -> list[np.ndarray]:
    """The exterior and interior rings of a Polygon or MultiPolygon, as (n, 2) arrays."""
    polys = getattr(geometry, "geoms", [geometry])
    return [np.asarray(r.coords) for p in polys if not p.is_empty for r in (p.exterior, *p.interiors)]


def _write_omf(tmp: Path, vertices, faces, name, mesh, units: str = "") -> None:
    omf = _require_omf()
    with warnings.catch_warnings():
        # omf 1.0.1 / vectormath predate numpy 2 and emit DeprecationWarnings.
        warnings.simplefilter("ignore", DeprecationWarning)
        element = omf.SurfaceElement(
            name=str(name),
            description="BGM geozone boundary surface",
            geometry=omf.SurfaceGeometry(
                vertices=np.asarray(vertices, dtype=np.float64),
                triangles=np.asarray(faces, dtype=np.int64),
            ),
        )
        project = omf.Project(name=str(name), elements=[element], units=units)
        project.validate()
        omf.OMFWriter(project, str(tmp))


_WRITERS = {
    "obj": _write_obj,
    "ply": _write_ply,
    "stl": _write_stl,
    "vtp": _write_vtp,
    "dxf": _write_dxf,
    "omf": _write_omf,
}


# --------------------------------------------------------------------------- helpers


def _require_omf():
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            import omf
    except Exception as exc:
        raise BGMInputError(
            "OMF export needs the optional 'omf' package (pip install omf); "
            f"it could not be imported ({exc.__class__.__name__}: {exc})"
        ) from None
    return omf


_DXF_BAD = re.compile(r"[^A-Za-z0-9_$-]")


def _dxf_layer_name(name: str) -> str:
    """R12-safe layer name: letters, digits, ``_ $ -`` only, at most 31 characters.

    Accented letters lose their accents (``Süd`` is ``Sud``); anything else becomes ``_``.
    """
    ascii_name = unicodedata.normalize("NFKD", str(name).strip()).encode("ascii", "ignore").decode()
    layer = _DXF_BAD.sub("_", ascii_name if ascii_name.strip() else str(name).strip())
    return layer[:31] or "BGM_SURFACE"


def dxf_layer_names(names: Iterable[str]) -> dict[str, str]:
    """Each name's R12 layer (:func:`_dxf_layer_name`), distinct names on distinct layers (``_2``, ``_3``...).

    Two labels that only non-ASCII characters tell apart (``Süd/Oxid``, ``Süd-Oxid``) would share one
    layer, and mine software would merge the two geozones. So would two that only case tells apart
    (``ox``, ``OX``): DXF layer names are case-insensitive (AutoCAD, Vulcan and ezdxf keep one of the
    two layer entries), so layers are told apart case-folded.
    """
    layers: dict[str, str] = {}
    taken: set[str] = set()
    for name in sorted(set(names)):
        base = layer = _dxf_layer_name(name)
        n = 1
        while layer.casefold() in taken:
            n += 1
            layer = f"{base[: 31 - len(str(n)) - 1]}_{n}"
        layers[name] = layer
        taken.add(layer.casefold())
    return layers


def _one_line(text) -> str:
    return " ".join(str(text).split())


def _ascii_line(text) -> str:
    """:func:`_one_line` in ASCII, other characters as Python escapes: for headers a format keeps ASCII."""
    return _one_line(text).encode("ascii", "backslashreplace").decode("ascii")


def _xml_escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _plain(obj):
    """shapely mapping (tuples) -> lists, for stable JSON."""
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [v if isinstance(v, float) else _plain(v) for v in obj]  # a coordinate's numbers as they are
    return obj


def json_default(obj):
    """``json.dumps(default=...)`` for what the engine writes: numpy scalars and arrays, paths.

    Non-finite numbers come out as the floats they are; write with
    ``allow_nan=False`` to refuse them, or replace them first.
    """
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")
