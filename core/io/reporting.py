"""Turning engine results into the input's coordinates and into summary figures.

The engine works in a local metric frame; everything a user reads (GeoJSON,
JSON, tables) is in the input's own coordinates and units. This module holds
the conversions and the containment figures that the ``contours`` command and
the tests report.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry import mapping

from core.extraction.contours import Contour
from core.io.blastholes import Blastholes


def to_input_geometry(geometry, holes: Blastholes):
    """A local-metre shapely geometry in the input's coordinates.

    Adding mine-grid offsets (y ~ 7,400,000) rounds coordinates to ~1e-9 m,
    which can turn a valid hair-thin sliver of a local polygon (e.g. where a
    single row of holes meets another geozone) into a self-intersection. Such
    results are repaired, keeping the type: a Polygon stays a Polygon (its
    largest part; the others are rounding debris), a MultiPolygon stays one.
    """
    out = shapely.transform(geometry, holes.frame.to_input)
    if out.is_empty or out.is_valid or out.geom_type not in ("Polygon", "MultiPolygon"):
        return out
    from core.geometry.grid import as_multipolygon

    parts = as_multipolygon(out)
    if out.geom_type == "Polygon":
        if not parts.geoms:
            return shapely.Polygon()
        return shapely.geometry.polygon.orient(max(parts.geoms, key=lambda p: p.area))
    return parts


def contour_feature(contour: Contour, holes: Blastholes) -> dict:
    """GeoJSON Feature of one contour, in the input's coordinates."""
    stats = containment(contour, holes)
    geometry = to_input_geometry(contour.polygon, holes)
    unit = holes.frame.length_unit
    return {
        "type": "Feature",
        "geometry": mapping(geometry),
        "properties": {
            "geozone": contour.geozone,
            "bench": holes.bench_z_input(contour.bench),
            "component": int(contour.component),
            "holes": int(len(contour.holes)),
            "boundary_holes": int(len(contour.boundary_holes)),
            "method": contour.method,
            f"area_{unit}2": round(float(geometry.area), 3),
            "holes_inside": round(stats["holes_inside"], 4),
            "other_holes_inside": round(stats["other_holes_inside"], 4),
            "isolated_holes": int(len(contour.isolated_holes)),
            "isolated_hole_ids": hole_ids(holes, contour.isolated_holes),
        },
    }


def prediction_feature(region, holes: Blastholes, geozone: str, z: float) -> dict:
    """GeoJSON-like feature of a predicted section, in the input's coordinates: what predict and build write.

    Parameters
    ----------
    region : shapely.MultiPolygon
        The predicted section (local metres); empty where the geozone is predicted absent.
    holes : Blastholes
        Their frame takes the section to input coordinates and units.
    geozone : str
        The geozone predicted.
    z : float
        The section's elevation, input units, as the feature gives it.

    Returns
    -------
    dict
        ``geometry`` (shapely; a Polygon where the section is one) and ``properties``
        ``geozone``, ``z`` and ``area_<unit>2`` (input units squared). One function
        for both commands: the build's features had no area where `bgm predict`'s had.
    """
    geometry = to_input_geometry(region, holes)
    if geometry.geom_type == "MultiPolygon" and len(geometry.geoms) == 1:
        geometry = geometry.geoms[0]
    area = {f"area_{holes.frame.length_unit}2": round(float(geometry.area), 3)}
    return {"geometry": geometry, "properties": {"geozone": geozone, "z": z, **area}}


#: How each way of carrying the benches' movement on below the deepest bench is said (:func:`carried_line`).
CARRIED_WORDS = {
    "agreement": "as far as its last two moves agree",
    "all": "all of it",
    "none": "none of it: the deepest bench held",
    "outlines": "its outlines' movement, not their finer changes",
}
#: What chose the way, as said.
CHOSEN_WORDS = {
    "backtest": "its own benches' backtest",
    "three benches": "three benches: their two moves' agreement",
    "two benches": "two benches: one move, no agreement to read",
    "one bench": "one bench: no movement",
}


def carried_words(carried: dict) -> str:
    """The way :func:`carried_json` says the movement is carried on, and where the agreement's share is all or
    none, which (a geozone "carried as far as its moves agree" that carries none of it is held)."""
    words = CARRIED_WORDS[carried["way"]]
    if carried["way"] == "agreement" and len(set(carried["persistence"])) == 1 and carried["persistence"][0] in (0, 1):
        words += ": none of it" if carried["persistence"][0] == 0 else ": all of it"
    return words


def carried_line(carried: dict | None, unit: str) -> str:
    """:func:`carried_json` in one line, as the viewer shows it: ``all of it, 4.1 m a bench (median; its own ...)``."""
    if carried is None:
        return "-"
    moved = carried[f"movement_per_bench_{unit}"]
    how_far = "" if moved is None else f", {moved[0]:.1f} {unit} a bench"
    gaps = carried.get(f"gaps_filled_narrower_than_{unit}")
    filled = f"; gaps under {gaps:.1f} {unit} filled a bench below" if gaps else ""
    return f"{carried_words(carried)}{how_far} (chosen by {CHOSEN_WORDS[carried['chosen_by']]}){filled}"


def carried_json(carried, holes: Blastholes) -> dict | None:
    """A :class:`core.model.extrapolation.CarriedMovement` as ``bgm build``'s summary and ``bgm predict`` give it.

    Lengths and areas in the input's units (``movement_per_bench_<unit>``: median and 90th percentile;
    ``backtest_wrong_area_<unit>2``: per way, None before the fourth bench; ``gaps_filled_narrower_than_<unit>``:
    the deepest section's gaps narrower than that are filled a bench below, None where its backtest did not choose
    it). None stays None (no bench pair).
    """
    if carried is None:
        return None
    unit = holes.frame.length_unit
    to_input = holes.frame.length_to_input
    moved = None if carried.movement_m is None else [round(float(to_input(m)), 2) for m in carried.movement_m]
    wrong = carried.backtest_wrong_m2
    return {
        "way": carried.way,
        "chosen_by": carried.chosen_by,
        "persistence": [round(p, 3) for p in carried.persistence],
        f"movement_per_bench_{unit}": moved,
        f"backtest_wrong_area_{unit}2": None
        if wrong is None
        else {w: round(float(to_input(to_input(a))), 1) for w, a in wrong.items()},
        f"gaps_filled_narrower_than_{unit}": round(float(to_input(carried.gaps_filled_m)), 2)
        if carried.gaps_filled_m > 0
        else None,
    }


def hole_ids(holes: Blastholes, index: np.ndarray) -> list:
    """Hole ids of the given holes as written in the input; where it has none, the file line each was read from.

    The file lines are those the reading warnings name (:attr:`Blastholes.data_line`), so a hole can be found in
    the file; a table built in memory (no lines) numbers its holes from 1.
    """
    index = np.asarray(index, int)
    if holes.hole_id is None:
        if holes.data_line is not None:
            return [int(v) for v in holes.data_line[index]]
        return [int(i) + 1 for i in index]
    return [str(v) for v in holes.hole_id[index]]


def hole_name(holes: Blastholes, i: int) -> str:
    """How a geologist finds hole ``i`` in the input: its id, else ``line N`` (its file line), else ``#N``."""
    name = hole_ids(holes, np.array([i]))[0]
    if holes.hole_id is not None:
        return str(name)
    return f"line {name}" if holes.data_line is not None else f"#{name}"


def containment(contour: Contour, holes: Blastholes) -> dict:
    """How well a contour separates its geozone on its bench.

    Returns
    -------
    dict
        ``holes_inside``: fraction of the component's holes inside the contour;
        ``other_holes_inside``: holes of other geozones inside the contour, as a
        fraction of the component's hole count.
    """
    poly = contour.polygon
    own = holes.xy[contour.holes]
    bench = holes.on_bench(contour.bench)
    others = bench[holes.geozone[bench] != contour.geozone]
    if poly.is_empty:
        return {"holes_inside": 0.0, "other_holes_inside": 0.0}
    inside = shapely.contains_xy(poly, own[:, 0], own[:, 1]).mean() if len(own) else 1.0
    if len(others):
        lo = np.array(poly.bounds[:2])
        hi = np.array(poly.bounds[2:])
        near = others[np.all((holes.xy[others] >= lo) & (holes.xy[others] <= hi), axis=1)]
        n_other = shapely.contains_xy(poly, holes.xy[near, 0], holes.xy[near, 1]).sum()
    else:
        n_other = 0
    return {"holes_inside": float(inside), "other_holes_inside": float(n_other / max(len(own), 1))}


def containment_summary(contours: list[Contour], holes: Blastholes, min_holes: int = 15) -> dict:
    """Containment figures over the contours of at least ``min_holes`` holes."""
    rows = [containment(c, holes) for c in contours if len(c.holes) >= min_holes]
    if not rows:
        return {"contours": 0}
    inside = np.array([r["holes_inside"] for r in rows])
    other = np.array([r["other_holes_inside"] for r in rows])
    return {
        "contours": len(rows),
        "min_holes": min_holes,
        "holes_inside_median": float(np.median(inside)),
        "holes_inside_min": float(inside.min()),
        "contours_with_95pct_inside": float(np.mean(inside >= 0.95)),
        "other_holes_inside_median": float(np.median(other)),
        "other_holes_inside_max": float(other.max()),
        "contours_with_at_most_5pct_other": float(np.mean(other <= 0.05)),
    }
