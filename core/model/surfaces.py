"""Closed boundary surfaces of a geozone from its horizontal sections.

The paper (section "Results: Visualization") triangulates the stacked contours
of each geozone into a surface. Joining contours directly is fragile when a
region splits, merges, gains a hole or vanishes between two benches, so this
module uses an implicit route that handles all of those the same way:

1. every section ``(z, region)`` is rasterised on one common :class:`Grid` and
   turned into a signed distance function (positive inside; exact polygon
   distances in a band of a few cells around the boundary, so the surface is
   not stair-stepped by the raster);
2. between two consecutive sections the SDF is interpolated linearly in z on
   a number of intermediate slices (about one cell apart), which is the
   classic "shape-based interpolation" of contours;
3. the volume is padded with an *outside* layer all round; the padding layers
   above the top section and below the bottom section sit a hair
   (``1e-3`` of a slice) beyond them, so the solid is capped flat at the top
   and bottom sections;
4. :func:`skimage.measure.marching_cubes` extracts the zero level set, whose
   vertices are mapped back to metres (z through the piecewise-linear map of
   slice index to elevation, so irregular bench spacing is honoured exactly);
5. the mesh is oriented outward (positive volume) and checked to be
   watertight and consistently wound.

What the grid cannot hold is left out rather than meshed as a meaningless
piece: parts and holes of a section narrower than a cell everywhere
(:func:`_resolved`), and bodies or voids of less than a voxel
(:func:`_without_specks`).

A region that is empty at some elevation ends between that section and its
neighbour: the empty section is given a uniform SDF of minus the largest
inside depth of its neighbours, so the thickest part of the body reaches about
halfway to the empty section and the rest closes before it (a rounded
pinch-out rather than a flat cut).

Precision: all arithmetic is float64. Meshes are built in a local metric frame
(small numbers); :func:`to_input_frame` moves them back to mine-grid or
projected coordinates (x ~ 650 000, y ~ 7 400 000), where float32 would only
resolve about 0.5 m. Keep float64 on export: ``core.io.export`` writes float64 in
PLY, VTP, OBJ (text), DXF and OMF; STL is float32 by definition.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Sequence

import numpy as np
import shapely
import trimesh
from scipy import ndimage
from shapely.geometry import MultiPolygon, Polygon
from skimage import measure

from core.errors import BGMInputError
from core.geometry.grid import Grid, as_multipolygon, union_bounds
from core.geometry.sdf import region_signed_distance
from core.model.progress import Stages
from core.threads import Progress

#: Default number of cells along the longer horizontal side of the sections.
DEFAULT_CELLS_ACROSS = 300
#: Margin of outside cells around the sections' bounding box.
MARGIN_CELLS = 3
#: Width (in cells) of the band where the raster SDF is replaced by exact polygon distances.
EXACT_BAND_CELLS = 2.5
#: At most this many slices are interpolated in z (the spacing grows beyond it).
MAX_Z_SLICES = 400
#: Refuse volumes larger than this many voxels (about 0.5 GB of float64).
MAX_VOXELS = 60_000_000

__all__ = [
    "DEFAULT_CELLS_ACROSS",
    "drilled_faces",
    "faces_drilled_by",
    "surface_as_written",
    "drop_small_bodies",
    "mesh_summary",
    "surface_from_sections",
    "to_input_frame",
]


def surface_from_sections(
    sections: Sequence[tuple[float, Polygon | MultiPolygon]],
    *,
    cell_size_m: float | None = None,
    z_spacing_m: float | None = None,
    min_width_m: float | None = None,
    progress: Progress | None = None,
) -> trimesh.Trimesh:
    """Closed, outward-oriented triangle mesh of the solid stacked from ``sections``.

    Parameters
    ----------
    sections : sequence of ``(z, region)``
        Elevation in metres and the region at that elevation as a shapely
        Polygon or MultiPolygon (holes allowed; empty allowed) in a local
        metric frame. Any order; at least two distinct elevations; at least
        one non-empty region. Regions given twice at one elevation are united.
        Parts and holes narrower than ``min_width_m`` everywhere are left out
        (filled): the grid cannot hold them, and they made flat lenses and
        voids of no volume.
    cell_size_m : float, optional
        Horizontal cell size of the working grid. Default: the longer side of
        the sections' bounding box divided by about
        :data:`DEFAULT_CELLS_ACROSS` (300), i.e. the grid is capped near 300
        cells across; the surface is then accurate to a small fraction of a
        cell (the boundary band uses exact polygon distances).
    z_spacing_m : float, optional
        Target spacing of the interpolated slices between sections. Default:
        ``cell_size_m`` (near-cubic voxels), coarsened so that no more than
        :data:`MAX_Z_SLICES` slices are used. Section elevations are always
        slices themselves.
    min_width_m : float, optional
        Narrower parts and holes are left out (:func:`_resolved`). Default: a
        cell. On a grid coarsened past half a hole spacing, give half a
        spacing: a geozone one hole wide (a dyke across a wide pit) is
        narrower than a cell there, but it is what the holes showed.
    progress : callable, optional
        ``progress(done, total)``, told as each section's signed distance is
        computed (the first half), then as the mesh is closed and its specks
        are dropped (the second), and at the steps of closing it (the volume
        filled, each marching cubes done, each smoothed try): one series that
        never goes back (:class:`core.model.progress.Stages`). A large geozone's surface takes a second or two; a
        :class:`core.threads.Cancelled` it raises stops it at that step.

    Returns
    -------
    trimesh.Trimesh
        Watertight, consistently wound, positive-volume mesh; vertices in the
        same local frame (x, y, z in metres, float64). The solid is capped at
        the lowest and highest sections.

    Raises
    ------
    BGMInputError
        Fewer than two elevations, non-finite elevations, all regions empty,
        a non-positive cell size, or a grid too large for memory.
    """
    levels = _normalise_sections(sections)
    zs = np.array([z for z, _ in levels], dtype=float)
    grid = _section_grid([r for _, r in levels], cell_size_m)
    width_m = grid.cell_size_m if min_width_m is None else min(float(min_width_m), grid.cell_size_m)
    regions = [_resolved(r, width_m) for _, r in levels]
    if all(r.is_empty for r in regions):
        raise BGMInputError("the sections enclose no volume at this cell size")
    z_levels, src = _z_slices(zs, z_spacing_m if z_spacing_m is not None else grid.cell_size_m)
    n_vox = (len(z_levels) + 2) * (grid.shape[0] + 2) * (grid.shape[1] + 2)
    if n_vox > MAX_VOXELS:
        raise BGMInputError(
            f"the surface grid would have {n_vox:,} voxels (more than {MAX_VOXELS:,}); "
            f"use a larger cell size than {grid.cell_size_m:g} m or a larger z spacing"
        )
    stages = Stages(progress, 2)  # the sections' signed distances, then the mesh: a bar never goes back
    vol = _sdf_volume(regions, grid, src, stages.stage(0))
    # Closing the mesh takes up to half a second on Kennecott (marching cubes, trimesh's checks, tried
    # again smoothed where it must): told between its steps, with none of the mesh's two steps done.
    mesh_done = stages.stage(1)
    mesh = _closed_mesh(vol, grid, z_levels, functools.partial(mesh_done, 0, 2) if mesh_done else None)
    if mesh_done:
        mesh_done(1, 2)
    voxel_m3 = grid.cell_size_m**2 * float(np.median(np.diff(z_levels)))
    mesh = _without_specks(mesh, voxel_m3)
    if mesh_done:
        mesh_done(2, 2)
    return mesh


def _without_specks(mesh: trimesh.Trimesh, voxel_m3: float) -> trimesh.Trimesh:
    """The mesh without its bodies (or voids) of less than a voxel, when a larger one is left.

    A part of a section a little over a cell wide (see :func:`_resolved`) can
    still hold a single node of the grid, barely inside: marching cubes closes
    a lens of eight faces around it, a tenth of a metre thick and of a cubic
    metre or less (Kennecott: 14 of them over its geozones), which no grid
    of this size can tell from nothing. Each body is closed on its own, so
    the rest stays watertight.
    """
    bodies = mesh.split(only_watertight=False)
    kept = [b for b in bodies if abs(b.volume) >= voxel_m3]
    if len(kept) == len(bodies) or not kept:
        return mesh
    joined = kept[0] if len(kept) == 1 else trimesh.util.concatenate(kept)
    if not isinstance(joined, trimesh.Trimesh):  # concatenate's declared type is any geometry
        return mesh
    _check(joined)
    return joined


def _section_grid(regions: list[MultiPolygon], cell_size_m: float | None) -> Grid:
    """The common horizontal grid of all sections (at least one not empty), with an outside margin."""
    bounds = union_bounds(regions)
    assert bounds is not None  # _normalise_sections refuses all-empty sections
    span = max(bounds[2] - bounds[0], bounds[3] - bounds[1])
    if cell_size_m is None:
        cell_size_m = max(span, 1e-6) / (DEFAULT_CELLS_ACROSS - 2 * MARGIN_CELLS - 1)
    cell_size_m = float(cell_size_m)
    if not (math.isfinite(cell_size_m) and cell_size_m > 0):
        raise BGMInputError(f"cell size must be a positive number of metres, got {cell_size_m!r}")
    return Grid.covering(bounds, cell_size_m, margin_cells=MARGIN_CELLS)


def _sdf_volume(
    regions: list[MultiPolygon], grid: Grid, slices: list[tuple[int, float]], progress: Progress | None = None
) -> np.ndarray:
    """Signed distances on every slice, axes (slice, row, col), padded by one outside layer all round.

    Each section's SDF (:func:`_section_sdf`; empty sections pinch out,
    :func:`_fill_empty_sections`) is interpolated linearly in z onto the
    slices between sections (``slices`` from :func:`_z_slices`). Exact zeros
    are nudged to a tiny positive value: marching cubes would emit zero-area
    triangles there. ``progress(done, len(regions))`` is told as each section's is computed.
    """
    h = grid.cell_size_m
    computed: list[np.ndarray | None] = []
    for r in regions:
        computed.append(_section_sdf(grid, r))
        if progress:
            progress(len(computed), len(regions))
    sdfs = _fill_empty_sections(computed, h)
    outside = -(max(float(np.max(s)) for s in sdfs) + 2.0 * h)
    vol = np.full((len(slices) + 2, grid.shape[0] + 2, grid.shape[1] + 2), outside)
    for k, (i, t) in enumerate(slices):
        vol[k + 1, 1:-1, 1:-1] = sdfs[i] if t == 0.0 else (1.0 - t) * sdfs[i] + t * sdfs[i + 1]
    vol[vol == 0.0] = 1e-9 * h
    return vol


def _closed_mesh(
    vol: np.ndarray, grid: Grid, z_levels: np.ndarray, check: Callable[[], None] | None = None
) -> trimesh.Trimesh:
    """Watertight mesh of the zero level of ``vol``, smoothing the slices only if it must.

    Parts of a section that touch only at a cell corner make marching cubes
    emit non-manifold edges that no repair closes. Smoothing each slice by a
    fraction of a cell removes such contacts and moves the surface by well
    under a cell, so it is the fallback, not the default. ``check()`` is
    called before each try and after its marching cubes; a
    :class:`core.threads.Cancelled` it raises stops the mesh there.
    """
    h = grid.cell_size_m
    for sigma in (0.0, 0.5, 1.0):
        if check:
            check()
        field = vol if sigma == 0.0 else ndimage.gaussian_filter(vol, (0.0, sigma, sigma), mode="nearest")
        field[field == 0.0] = 1e-9 * h
        mesh = _mesh_from_volume(field, grid, h, z_levels, check)
        if _problems(mesh) == []:
            break
    _check(mesh)
    return mesh


def _mesh_from_volume(
    vol: np.ndarray, grid: Grid, cell_size_m: float, z_levels: np.ndarray, check: Callable[[], None] | None = None
) -> trimesh.Trimesh:
    """Marching cubes of the padded (slice, row, col) volume, in local metres, outward-oriented.

    ``check()`` is called once marching cubes is done, before the mesh is built and oriented.
    """
    # A value (almost) exactly 0 at a node puts the vertices of every edge
    # through it a hair apart: a float32 export (STL) then merges them and the
    # mesh no longer closes. Kept a thousandth of a cell away from 0.
    eps = 1e-3 * cell_size_m
    vol = np.where(np.abs(vol) < eps, np.where(vol < 0, -eps, eps), vol)
    verts, faces, _normals, _values = measure.marching_cubes(vol, level=0.0, allow_degenerate=False)
    if check:
        check()
    verts = verts.astype(np.float64)

    # Slice index -> elevation: the pads sit 1e-3 of a slice beyond the end sections.
    dz_end_lo = (z_levels[1] - z_levels[0]) if len(z_levels) > 1 else 1.0
    dz_end_hi = (z_levels[-1] - z_levels[-2]) if len(z_levels) > 1 else 1.0
    z_of_index = np.concatenate([[z_levels[0] - 1e-3 * dz_end_lo], z_levels, [z_levels[-1] + 1e-3 * dz_end_hi]])
    index = np.arange(len(z_of_index), dtype=float)
    xyz = np.column_stack(
        [
            grid.x0 + (verts[:, 2] - 1.0) * cell_size_m,
            grid.y0 + (verts[:, 1] - 1.0) * cell_size_m,
            np.interp(verts[:, 0], index, z_of_index),
        ]
    )

    mesh = trimesh.Trimesh(vertices=xyz, faces=faces, process=True)
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise BGMInputError("the sections enclose no volume at this cell size")
    if mesh.volume < 0:
        mesh.invert()
    if not mesh.is_winding_consistent:
        mesh.fix_normals(multibody=False)
        if mesh.volume < 0:
            mesh.invert()
    if not (mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0):
        mesh = _repair(mesh)
    return mesh


def inside_mesh(mesh: trimesh.Trimesh, points: np.ndarray, enough: int | None = None) -> np.ndarray:
    """Whether each point lies inside a closed mesh, by its generalised winding number.

    The winding number is the solid angle the mesh subtends at the point over
    4 pi (van Oosterom and Strackee's formula per triangle): 1 inside, 0
    outside, robust to small gaps. ``O(points x faces)``, in chunks of about
    two million point-triangle pairs; with ``enough``, points are tested only
    until that many are found inside (the rest are reported outside).
    """
    points = np.asarray(points, float).reshape(-1, 3)
    tri = mesh.vertices[mesh.faces]
    out = np.zeros(len(points), bool)
    chunk = max(1, 2_000_000 // max(len(tri), 1))
    for start in range(0, len(points), chunk):
        if enough is not None and out.sum() >= enough:
            break
        a, b, c = (tri[None, :, k, :] - points[start : start + chunk, None, :] for k in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
        det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc
        den += np.einsum("pfi,pfi->pf", b, c) * la + np.einsum("pfi,pfi->pf", c, a) * lb
        winding = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
        out[start : start + chunk] = np.abs(winding) > 0.5
    return out


def drop_small_bodies(
    mesh: trimesh.Trimesh, *, min_volume_m3: float = 0.0, min_holes: int = 0, holes_xyz: np.ndarray | None = None
) -> trimesh.Trimesh | None:
    """The mesh without its bodies (connected parts) smaller than ``min_volume_m3`` or holding fewer holes.

    A lone mislabelled hole becomes a small body of its own in a geozone's
    surface (label noise): a body is kept when its volume is at least
    ``min_volume_m3`` and at least ``min_holes`` of ``holes_xyz`` (the
    geozone's holes, local metres) lie inside it. Holes on a body's flat top
    are tested a millimetre below it. ``None`` when no body is left.
    """
    if min_volume_m3 <= 0 and (min_holes <= 0 or holes_xyz is None):
        return mesh
    bodies = mesh.split(only_watertight=False)
    pts = None if holes_xyz is None else np.asarray(holes_xyz, float).reshape(-1, 3) - [0.0, 0.0, 1e-3]
    keep = []
    for body in bodies:
        if abs(body.volume) < min_volume_m3:
            continue
        if min_holes > 0 and pts is not None:
            lo, hi = body.bounds
            near = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
            if len(near) < min_holes or inside_mesh(body, near, enough=min_holes).sum() < min_holes:
                continue
        keep.append(body)
    if not keep:
        return None
    joined = keep[0] if len(keep) == 1 else trimesh.util.concatenate(keep)
    return joined if isinstance(joined, trimesh.Trimesh) else None


def mesh_summary(mesh: trimesh.Trimesh) -> dict:
    """Plain-number summary of a mesh: volume, area, counts and closedness checks."""
    watertight = bool(mesh.is_watertight)
    return {
        "volume_m3": float(mesh.volume) if watertight else float("nan"),
        "area_m2": float(mesh.area),
        "faces": int(len(mesh.faces)),
        "vertices": int(len(mesh.vertices)),
        "watertight": watertight,
        "winding_consistent": bool(mesh.is_winding_consistent),
    }


def drilled_faces(
    mesh: trimesh.Trimesh,
    bench_levels_m: Sequence[float],
    drilled_areas: Sequence,
    reach_m: float,
) -> np.ndarray:
    """Which faces of a surface lie in drilled ground (bool per face).

    A face is drilled where the benches on both sides of it drilled within
    ``reach_m`` of it: at a bench level, that bench; between two benches, both
    of them. Elsewhere the surface is the depth trend carried into ground no
    bench bracketed (section "Contour Prediction"): below the deepest bench,
    and where a pit narrowing with depth left ground under an upper bench's
    drilling that the next bench did not drill (the "curtains" hanging under
    an upper bench's edge). A viewer shades those faces as predicted.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The surface, in the frame of the benches (local metres).
    bench_levels_m : (b,) float
        Bench elevations, top first.
    drilled_areas : sequence of b polygons
        Each bench's drilled area (``Blastholes.drilled_area``).
    reach_m : float
        How far past a bench's drilled area a face still counts as drilled:
        a contour along a frontier runs up to a hole spacing past its holes.

    Returns
    -------
    (f,) bool
    """
    levels = np.asarray(bench_levels_m, float)
    if not len(mesh.faces) or not len(levels):
        return np.zeros(len(mesh.faces), bool)
    centre = mesh.triangles_center
    # Faces within a hair of a bench (its cap, its section) belong to that bench alone.
    tol = 1e-3 * (float(np.ptp(levels)) or 1.0)
    above = np.clip(np.searchsorted(-levels, -(centre[:, 2] - tol), side="right") - 1, 0, None)
    below = np.searchsorted(-levels, -(centre[:, 2] + tol), side="left")
    drilled = below < len(levels)
    for k, area in enumerate(drilled_areas):
        ask = drilled & ((above == k) | (below == k))
        if not ask.any():
            continue
        reach = shapely.buffer(area, reach_m) if area is not None and not area.is_empty else None
        inside = shapely.contains_xy(reach, centre[ask, 0], centre[ask, 1]) if reach is not None else False
        drilled[np.flatnonzero(ask)] &= inside
    return drilled


def faces_drilled_by(holes, mesh: trimesh.Trimesh) -> np.ndarray:
    """:func:`drilled_faces` of ``mesh`` (local metres) with the benches and drilling of ``holes`` (a ``Blastholes``).

    A contour along a drilling frontier runs up to half a spacing past the discs of a bench's drilled area.
    """
    areas = [holes.drilled_area(k) for k in range(len(holes.bench_levels_m))]
    return drilled_faces(mesh, holes.bench_levels_m, areas, 0.5 * holes.hole_spacing_m)


def surface_as_written(mesh: trimesh.Trimesh, holes) -> trimesh.Trimesh:
    """``mesh`` (local metres) as ``bgm build`` and the viewer write it: in the input's coordinates, each face
    flagged ``drilled`` (:func:`faces_drilled_by`, as the viewer shades it)."""
    frame = holes.frame
    written = to_input_frame(mesh, (frame.origin_x, frame.origin_y), frame.metres_per_unit)
    written.face_attributes["drilled"] = faces_drilled_by(holes, mesh)
    return written


def volume_above(mesh: trimesh.Trimesh, z_m: float) -> float:
    """The volume of a closed mesh above the plane ``z = z_m`` (cubic metres).

    By the divergence theorem with the field ``(0, 0, z - z_m)``, whose
    divergence is 1 and which vanishes on the plane: the sum over the
    surface above it (clipped there) of ``(z - z_m) n_z dA``, exact per
    triangle at its centroid. No cap is triangulated.
    """
    part = trimesh.intersections.slice_mesh_plane(mesh, plane_normal=[0, 0, 1], plane_origin=[0, 0, z_m], cap=False)
    if part is None or not len(part.faces):
        return 0.0
    height = part.triangles[:, :, 2].mean(axis=1) - z_m
    return float(np.sum(part.area_faces * part.face_normals[:, 2] * height))


def to_input_frame(mesh: trimesh.Trimesh, origin_xy: tuple[float, float], metres_per_unit: float) -> trimesh.Trimesh:
    """Copy of ``mesh`` moved from the local metric frame back to input coordinates.

    ``x = x_local / metres_per_unit + origin_x``, ``y`` likewise,
    ``z = z_local / metres_per_unit``. Computed in float64; the vertices are
    not merged or reordered, so faces and their attributes are unchanged. A non-positive scale
    would mirror the mesh and is refused.

    Note the result's volume and area are in input units (cubed / squared).
    """
    mpu = float(metres_per_unit)
    if not (math.isfinite(mpu) and mpu > 0):
        raise BGMInputError(f"metres per unit must be a positive number, got {metres_per_unit!r}")
    ox, oy = (float(v) for v in origin_xy)
    if not (math.isfinite(ox) and math.isfinite(oy)):
        raise BGMInputError(f"origin must be finite, got {origin_xy!r}")
    v = np.asarray(mesh.vertices, dtype=np.float64)
    out = np.empty_like(v)
    out[:, 0] = v[:, 0] / mpu + ox
    out[:, 1] = v[:, 1] / mpu + oy
    out[:, 2] = v[:, 2] / mpu
    moved = trimesh.Trimesh(vertices=out, faces=np.array(mesh.faces), process=False)
    moved.face_attributes.update({k: np.array(a) for k, a in mesh.face_attributes.items()})  # e.g. "drilled"
    return moved


# --------------------------------------------------------------------------- helpers


def _normalise_sections(sections: Iterable) -> list[tuple[float, MultiPolygon]]:
    by_z: dict[float, list] = {}
    for item in sections:
        try:
            z, region = item
        except (TypeError, ValueError):
            raise BGMInputError("each section must be a pair (elevation, polygon)") from None
        z = float(z)
        if not math.isfinite(z):
            raise BGMInputError(f"section elevation must be finite, got {z!r}")
        if region is not None and not isinstance(region, shapely.Geometry):
            raise BGMInputError(f"section at z={z:g} is not a shapely geometry: {type(region).__name__}")
        by_z.setdefault(z, []).append(region)
    if len(by_z) < 2:
        raise BGMInputError(f"a surface needs sections at two or more elevations, got {len(by_z)}")
    out = []
    for z in sorted(by_z):
        parts = [as_multipolygon(r) for r in by_z[z]]
        region = parts[0] if len(parts) == 1 else as_multipolygon(shapely.union_all(parts))
        if not region.is_empty and not np.all(np.isfinite(region.bounds)):
            raise BGMInputError(f"section at z={z:g} has non-finite coordinates")
        out.append((z, region))
    if all(r.is_empty for _, r in out):
        raise BGMInputError("every section is empty: there is no solid to mesh")
    return out


def _z_slices(zs: np.ndarray, dz_target: float) -> tuple[np.ndarray, list[tuple[int, float]]]:
    """Slice elevations and, for each, ``(section i, weight t of section i+1)``."""
    span = float(zs[-1] - zs[0])
    dz = max(float(dz_target), span / MAX_Z_SLICES)
    if not (math.isfinite(dz) and dz > 0):
        raise BGMInputError(f"z spacing must be a positive number of metres, got {dz_target!r}")
    levels: list[float] = []
    src: list[tuple[int, float]] = []
    for i in range(len(zs) - 1):
        gap = zs[i + 1] - zs[i]
        n = max(1, int(math.ceil(gap / dz - 1e-9)))
        for k in range(n):
            t = k / n
            levels.append(zs[i] + t * gap)
            src.append((i, t))
    levels.append(float(zs[-1]))
    src.append((len(zs) - 1, 0.0))
    return np.array(levels, dtype=float), src


def _resolved(region: MultiPolygon, width_m: float) -> MultiPolygon:
    """The region without the parts and holes narrower than ``width_m`` everywhere (a cell of the grid, or less).

    The grid samples each section's signed distance at its nodes, a cell
    apart: a part narrower than a cell holds a node or none, barely inside,
    and became a flat lens of its own a fraction of a slice thick (0.02-0.2 m:
    watertight, of no volume) wherever a node fell in it; a hole that narrow,
    a void as meaningless. Such specks and slivers are what the morph leaves
    between two benches where a body appears or comes back (dozens at each
    fraction, most under a square metre, some a few metres long and under one
    wide), not anything the holes showed: a hole's own contour is a spacing,
    two cells, across. Parts and holes wider somewhere are kept whole, so a
    body's own pinch-out is unchanged.

    Parameters
    ----------
    region : MultiPolygon
    width_m : float
        A part (hole) is dropped (filled) when no disc of this diameter fits
        inside it.

    Returns
    -------
    MultiPolygon
    """
    half = 0.5 * width_m

    def narrow(polygon: Polygon) -> bool:
        return bool(polygon.buffer(-half).is_empty)

    kept = []
    for part in region.geoms:
        if narrow(part):
            continue
        kept.append(Polygon(part.exterior, [ring for ring in part.interiors if not narrow(Polygon(ring))]))
    return MultiPolygon(kept)


def _section_sdf(grid: Grid, region: MultiPolygon) -> np.ndarray | None:
    """Signed distance (m, positive inside) of ``region`` on ``grid``; None if empty.

    :func:`core.geometry.sdf.region_signed_distance` with exact distances in a
    band of :data:`EXACT_BAND_CELLS` cells around the boundary, so the zero
    level follows the polygon, not its pixels.
    """
    if region.is_empty:
        return None
    return region_signed_distance(grid, region, EXACT_BAND_CELLS)


def _fill_empty_sections(sdfs: list[np.ndarray | None], cell_size_m: float) -> list[np.ndarray]:
    """Signed distances with empty sections (``None``) given a uniform outside value.

    The value is minus the largest inside depth of the neighbouring sections,
    so the thickest part of a body reaches about halfway to the empty section.
    """
    shape = next(s.shape for s in sdfs if s is not None)
    depth = [float(np.max(s)) if s is not None else None for s in sdfs]
    out = []
    for i, s in enumerate(sdfs):
        if s is None:
            near = [d for j in (i - 1, i + 1) if 0 <= j < len(sdfs) and (d := depth[j]) is not None]
            m = max(near) if near else cell_size_m
            s = np.full(shape, -(max(m, 0.0) + 0.5 * cell_size_m))
        out.append(s)
    return out


def _repair(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Standard repairs for the rare marching-cubes mesh that does not close.

    Merging coincident vertices, dropping zero-area faces and filling small
    holes closes meshes opened by near-degenerate voxel configurations; the
    result is checked again by :func:`_check`.
    """
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    trimesh.repair.fill_holes(mesh)
    trimesh.repair.fix_normals(mesh, multibody=True)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _check(mesh: trimesh.Trimesh) -> None:
    problems = _problems(mesh)
    if problems:
        raise RuntimeError("surface extraction produced a bad mesh: " + ", ".join(problems))


def _problems(mesh: trimesh.Trimesh) -> list[str]:
    problems = []
    if not mesh.is_watertight:
        problems.append("not watertight")
    if not mesh.is_winding_consistent:
        problems.append("inconsistent winding")
    if not mesh.volume > 0:
        problems.append(f"non-positive volume {mesh.volume:g}")
    return problems
