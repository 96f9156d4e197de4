"""Uncertainty and suggested holes in the input's coordinates: GeoJSON bands, P(inside) grids, suggestion tables.

What ``bgm predict``, ``bgm build`` and ``bgm suggest`` write beside their
usual outputs (:mod:`core.model.uncertainty`, :mod:`core.model.sampling`):

* band features: per predicted section, three polygons, ``kind`` ``inner``
  (inside with probability ``(1 + q) / 2`` or more), ``outer`` (everything
  that may be inside) and ``band`` (outer minus inner: where the true
  boundary lies with probability ``q``);
* a P(inside) grid (NumPy ``.npz``): ``x`` (cols), ``y`` (rows) cell centres
  and ``z`` (levels) in input units, ``p_inside`` ``(levels, rows, cols)``
  and ``sigma`` (the calibrated scale, input units) of the same shape;
  ``units`` names those units (``"m"`` or ``"ft"``);
* suggestions: one row per hole, ``x, y, z, geozone, probability_inside, reason``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import shapely

from core.io.atomic import atomic_path, atomic_write_text
from core.io.blastholes import Blastholes
from core.io.reporting import to_input_geometry
from core.model.sampling import Suggestion, reason
from core.model.uncertainty import SectionUncertainty, band_width_m

#: Band polygons written per section, and what each holds.
BAND_KINDS = ("inner", "outer", "band")


def band_features(
    sections: Mapping[float, SectionUncertainty | None], holes: Blastholes, geozone: str, within=None
) -> list[dict]:
    """GeoJSON features of each section's band (:data:`BAND_KINDS`), input coordinates; empty polygons left out.

    Properties: ``geozone``, ``z`` (input units), ``kind``, ``probability``,
    ``band_width`` (median width across the predicted boundary, input units)
    and ``calibration`` (what the scale was calibrated on). ``within``
    (local polygon) limits the width's boundary points: by default the
    drilled area of the benches next to the section (:func:`drilled_around`):
    the deepest bench's below it, as the build's report measures it.
    """
    frame = holes.frame
    features = []
    for z, section in sections.items():
        if section is None:
            continue
        width = band_width_m(section, within if within is not None else drilled_around(holes, z))
        props = {
            "geozone": geozone,
            "z": round(float(frame.z_to_input(z)), 3),
            "probability": section.probability,
            "band_width": None if not np.isfinite(width) else round(float(frame.length_to_input(width)), 3),
            "calibration": section.scale.source,
        }
        for kind in BAND_KINDS:
            geometry = getattr(section, kind)
            if not geometry.is_empty:
                features.append({"geometry": to_input_geometry(geometry, holes), "properties": {**props, "kind": kind}})
    return features


def drilled_around(holes: Blastholes, z_m: float):
    """The drilled area next to elevation ``z_m`` (local metres): where a section's band width is measured.

    Below the benches the deepest bench's (the next bench lies under it), between two benches
    both of theirs, above them every bench's (a pit's top bench is often barely drilled:
    Kennecott's holds 1% of the next one's area). Measured in the deepest bench's area, a
    section between upper benches of a pit that narrows with depth had no boundary there,
    and its band width was null (Kennecott's 3310 at 540 and 490 ft).
    """
    levels = np.asarray(holes.bench_levels_m, float)  # top first
    above, below = np.flatnonzero(levels >= z_m), np.flatnonzero(levels <= z_m)
    if not len(below):
        return holes.drilled_area(len(levels) - 1)
    near = range(len(levels)) if not len(above) else sorted({int(above[-1]), int(below[0])})
    areas = [holes.drilled_area(k) for k in near]
    return areas[0] if len(areas) == 1 else shapely.union_all(areas)


def probability_grid(sections: Mapping[float, SectionUncertainty | None], holes: Blastholes, geozone: str) -> dict:
    """The arrays of a P(inside) grid (see the module docstring); levels without uncertainty are left out.

    With none left, every array is still there, with no level (a reader's ``p_inside`` has shape ``(0, 0, 0)``).
    """
    kept = {z: s for z, s in sections.items() if s is not None}
    frame = holes.frame
    if not kept:
        empty = np.zeros(0)
        none = np.zeros((0, 0, 0), np.float32)
        return {
            "geozone": np.array(geozone),
            "probability": np.array(np.nan),
            "x": empty,
            "y": empty,
            "z": empty,
            "p_inside": none,
            "sigma": none,
            "units": np.array(frame.length_unit),
        }
    first = next(iter(kept.values()))
    rows, cols = first.grid.shape
    xs = first.grid.rc_to_xy(np.column_stack([np.zeros(cols), np.arange(cols)]))[:, 0]
    ys = first.grid.rc_to_xy(np.column_stack([np.arange(rows), np.zeros(rows)]))[:, 1]
    x_in = frame.to_input(np.column_stack([xs, np.zeros(cols)]))[:, 0]
    y_in = frame.to_input(np.column_stack([np.zeros(rows), ys]))[:, 1]
    return {
        "geozone": np.array(geozone),
        "probability": np.array(first.probability),
        "x": x_in,
        "y": y_in,
        "z": np.array([float(frame.z_to_input(z)) for z in kept]),
        # Rounded to 1e-3: what a map shows, and it compresses to a fraction.
        "p_inside": np.round(np.stack([s.inside_probability for s in kept.values()]), 3).astype(np.float32),
        "sigma": np.round(np.stack([frame.length_to_input(s.sigma) for s in kept.values()]), 3).astype(np.float32),
        # x, y, z and sigma are lengths: without it an archive in feet reads as one in metres.
        "units": np.array(frame.length_unit),
    }


def write_probability_grid(path: str | Path, arrays: Mapping[str, np.ndarray]) -> Path:
    """Write :func:`probability_grid` arrays as a compressed ``.npz``, atomically."""
    with atomic_path(Path(path)) as tmp:  # keeps the .npz suffix, so numpy adds none
        np.savez_compressed(tmp, **arrays)  # type: ignore[arg-type]  # numpy's stub types **kwds as its own options
    return Path(path)


def suggestions_table(
    suggestions: Sequence[Suggestion],
    holes: Blastholes,
    z_m: float,
    probability: float,
    labels: Sequence | None = None,
) -> pd.DataFrame:
    """One row per suggested hole, in the order chosen: ``x, y, z, geozone, probability_inside, reason``.

    ``labels`` (one per candidate), when the candidates came from a planned
    pattern, adds its hole identifier as ``pattern_hole``.
    """
    frame = holes.frame
    xy = frame.to_input(np.array([s.xy_m for s in suggestions], float).reshape(-1, 2))
    unit, mpu = frame.length_unit, frame.metres_per_unit
    table = pd.DataFrame(
        {
            "x": xy[:, 0],
            "y": xy[:, 1],
            "z": np.full(len(suggestions), round(float(frame.z_to_input(z_m)), 3)),
            "geozone": [s.geozone for s in suggestions],
            "probability_inside": [round(s.probability_inside, 3) for s in suggestions],
            "reason": [reason(s, probability, unit, mpu) for s in suggestions],
        }
    )
    if labels is not None:
        table.insert(0, "pattern_hole", [labels[s.candidate] for s in suggestions])
    return table


def write_suggestions(path: str | Path, table: pd.DataFrame) -> Path:
    """Write a suggestions table as CSV, atomically (floats as their shortest exact repr)."""
    atomic_write_text(Path(path), table.to_csv(index=False))
    return Path(path)


def _refuse_far_pattern(path, xy: np.ndarray, holes: Blastholes, reach_spacings: float | None = None) -> None:
    """Refuse a pattern whose nearest hole lies further from every blasthole than the predictions reach.

    They reach as far past the drilling as a bench's evidence does: ``reach_spacings``
    hole spacings, the ``frontier_reach_spacings`` in effect (a project may set it; the
    model's default if None), and at least one spacing (a planned hole among the
    blastholes is within about one of them, whatever the reach); a pattern beyond that
    is in other coordinates.
    """
    from scipy.spatial import cKDTree

    from core.errors import BGMInputError
    from core.model.parameters import ModelParameters

    if reach_spacings is None:
        reach_spacings = ModelParameters().frontier_reach_spacings
    gap_m = float(cKDTree(holes.xy).query(xy)[0].min())
    reach_m = max(float(reach_spacings), 1.0) * holes.hole_spacing_m
    if gap_m > reach_m:
        unit = holes.frame.length_unit
        gap, centre = holes.frame.length_to_input(gap_m), holes.frame.to_input(xy.mean(axis=0, keepdims=True))[0]
        drilled = holes.frame.to_input(holes.xy.mean(axis=0, keepdims=True))[0]
        raise BGMInputError(
            f"pattern {str(path)!r} lies {gap:,.0f} {unit} from the nearest blasthole (its centre "
            f"{centre[0]:,.1f}, {centre[1]:,.1f}; the blastholes' {drilled[0]:,.1f}, {drilled[1]:,.1f}): "
            "give it in the blastholes' coordinates"
        )


def read_pattern(
    path: str | Path, holes: Blastholes, reach_spacings: float | None = None
) -> tuple[np.ndarray, list, float | None]:
    """A planned blast pattern: hole positions (local metres), their identifiers, and their elevation if given.

    The table (CSV or Parquet, read as the blasthole table is) needs x and y
    columns, found by the same names (``x/east/easting/mid_x``, ``y/north/northing/mid_y``,
    any case); a ``z`` column gives the bench's elevation (input units, the
    median), a ``hole_id`` column (``Hole ID``, ``BHID``: :func:`~core.io.blastholes.is_hole_id_column`)
    the identifiers (else the data line numbers).
    A hole listed again at the same position is kept once, with a warning.
    ``reach_spacings`` is the ``frontier_reach_spacings`` in effect (the
    model's default if None): how far from the blastholes a pattern may lie.

    Raises
    ------
    BGMInputError
        A missing column, a value that is not a finite number, fewer than one
        hole, or a pattern none of whose holes lies within the predictions'
        reach of a blasthole (other coordinates: a local grid against the
        mine grid, or another site). Collars more than half a bench height apart
        (the patterns of several benches).
    """
    from core.errors import BGMInputError
    from core.io.blastholes import COLUMN_ALIASES, coordinate_values, find_column, is_hole_id_column
    from core.io.tables import data_lines, read_table

    table = read_table(path)
    columns = [str(c) for c in table.columns]
    table.columns = columns
    if not len(table):
        raise BGMInputError(f"pattern {str(path)!r} has no holes")
    values = {}
    for role in ("x", "y", "z"):
        try:
            column = find_column(columns, role)
        except BGMInputError as exc:
            if role == "z" and not any(c.strip().lower() in COLUMN_ALIASES["z"] for c in columns):
                continue
            # The input's --x/--y/--z options do not apply to the pattern: its columns go by name.
            message = re.sub(r";? (name it|choose one) with --\w+ COLUMN", "", str(exc))
            raise BGMInputError(f"pattern {str(path)!r}: {message}") from None
        number = coordinate_values(table[column], table.attrs.get("delimiter"))  # decimal commas as the holes'
        bad = np.flatnonzero(~np.isfinite(number))
        if len(bad):
            raise BGMInputError(
                f"pattern {str(path)!r}: column {column!r} has {len(bad)} missing or non-numeric value(s) "
                f"(first on data line {data_lines(table)[bad[0]]})"
            )
        values[role] = number
    xy = holes.frame.to_local(values["x"], values["y"])
    _refuse_far_pattern(path, xy, holes, reach_spacings)
    ids = next((c for c in columns if is_hole_id_column(c)), None)
    labels = table[ids].astype(str).tolist() if ids is not None else [str(n) for n in data_lines(table)]
    z = _pattern_level(path, values["z"], holes) if "z" in values else None
    keep = _distinct_positions(path, values["x"], values["y"], data_lines(table))
    return xy[keep], [labels[i] for i in keep], z


def _distinct_positions(path, x: np.ndarray, y: np.ndarray, lines) -> np.ndarray:
    """Indices of a pattern's holes, the first of each position only; a warning names the repeats.

    A hole listed twice (a pattern exported twice into one file, or pasted
    again) is one place to drill: kept twice, it was suggested twice.
    """
    import warnings

    from core.errors import BGMWarning

    _, first = np.unique(np.column_stack([x, y]), axis=0, return_index=True)
    keep = np.sort(first)
    if len(keep) < len(x):
        repeated = np.setdiff1d(np.arange(len(x)), keep)
        shown = ", ".join(str(lines[i]) for i in repeated[:5]) + (", ..." if len(repeated) > 5 else "")
        warnings.warn(
            f"pattern {str(path)!r} lists {len(repeated)} hole(s) at the position of an earlier one (data line(s) "
            f"{shown}); each position is a candidate once (first row kept)",
            BGMWarning,
            stacklevel=3,
        )
    return keep


#: A pattern's collars may scatter this fraction of a bench height; more is holes of several benches.
MAX_PATTERN_Z_SPREAD = 0.5


def _pattern_level(path: str | Path, z: np.ndarray, holes: Blastholes) -> float:
    """The elevation of a pattern's bench (input units): its collars' median, refused if they span benches.

    The suggestions are laid on one bench: a file holding the patterns of two
    benches would be sampled at the level between them, where no hole is drilled.
    """
    from core.errors import BGMInputError

    spread = float(np.ptp(z))
    height = float(holes.frame.z_to_input(holes.bench_height_m))
    if np.isfinite(height) and spread > MAX_PATTERN_Z_SPREAD * height:
        unit = holes.frame.length_unit
        raise BGMInputError(
            f"pattern {str(path)!r} has collars from {z.min():g} to {z.max():g} {unit}, more than half a bench "
            f"({height:.4g} {unit}) apart: give one bench's pattern at a time"
        )
    return float(np.median(z))


def shade_polygons(ax, geometry, **style) -> None:
    """Fill every polygon of ``geometry`` on the matplotlib axes ``ax``, its holes left open.

    Each polygon is one compound path (exterior counter-clockwise, holes
    clockwise), so a hole shows whatever lies under it: the band around a
    ring's core, inside the hole of the band around its outside, stays shaded.
    """
    import shapely
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as PlotPath

    for poly in shapely.get_parts(geometry):
        if poly.is_empty:
            continue
        poly = shapely.geometry.polygon.orient(poly, 1.0)
        rings = [poly.exterior, *poly.interiors]
        path = PlotPath.make_compound_path(*(PlotPath(np.asarray(r.coords), closed=True) for r in rings))
        ax.add_patch(PathPatch(path, **style))


def plot_sampling_map(plan, holes: Blastholes, path: str | Path, title: str = "") -> Path | None:
    """A map of the band and the suggested holes on the bench to sample (PNG), or None without matplotlib.

    ``plan`` is a :class:`core.model.sampling.SamplingPlan`: its sections'
    band (shaded) and predicted boundary (line), the candidate holes (grey
    dots) and the suggestions (red, numbered in the order chosen), in the
    input's coordinates.
    """
    try:
        from matplotlib.figure import Figure  # a bare Figure renders with Agg, no pyplot global state
    except ImportError:
        return None
    import shapely

    fig = Figure(figsize=(6.5, 6.0), dpi=110)
    ax = fig.add_subplot()
    for section in plan.sections.values():
        shade_polygons(ax, to_input_geometry(section.band, holes), color="#f4a261", alpha=0.45, lw=0)
        for poly in to_input_geometry(section.predicted, holes).geoms:  # the predicted boundary
            for ring in [poly.exterior, *poly.interiors]:
                ax.plot(*np.asarray(ring.coords).T, color="#264653", lw=1.0)
    cand = holes.frame.to_input(plan.candidates_m)
    ax.scatter(cand[:, 0], cand[:, 1], s=2, color="#adb5bd", label="candidate holes")
    chosen = holes.frame.to_input(np.array([s.xy_m for s in plan.suggestions], float).reshape(-1, 2))
    ax.scatter(chosen[:, 0], chosen[:, 1], s=18, color="#d62828", label="suggested", zorder=3)
    if len(chosen):
        lo, hi = chosen.min(axis=0), chosen.max(axis=0)
        bands = [to_input_geometry(s.outer, holes) for s in plan.sections.values() if not s.outer.is_empty]
        if bands:
            bx0, by0, bx1, by1 = shapely.union_all(bands).bounds
            lo, hi = np.minimum(lo, [bx0, by0]), np.maximum(hi, [bx1, by1])
        pad = 0.05 * float(np.max(hi - lo)) + 1.0
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.tick_params(labelsize=7)
    unit = holes.frame.length_unit
    ax.set_title(title or f"z = {float(holes.frame.z_to_input(plan.z_m)):g} {unit}", fontsize=9)
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, format="png")
    return Path(path)
