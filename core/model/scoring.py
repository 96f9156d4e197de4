"""How well extracted contours and trajectories match the truth: the extraction benchmark's figures.

Three figures, each per geozone and bench (or bench pair):

* **bench IoU** -- the union of a geozone's contours on a bench against its
  true section, both clipped to the bench's drilled footprint
  (:func:`bench_iou`);
* **holes inside** -- the share of a geozone's true holes that its contours
  hold, and the share of the holes its contours hold that truly belong to
  another geozone (:func:`holes_inside`);
* **target-boundary coverage** -- the share of each lower bench's boundary
  reached by the trajectories of the morph (paper section 4), per bench pair
  (:func:`coverage_by_pair`).

On synthetic mines the truth is the generator's (true sections and the true
label of every hole, see :mod:`core.synthetic.scenarios`); on real data the
file's labels stand in for the true labels and there is no IoU.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np
import pandas as pd
import shapely
from shapely.geometry import MultiPolygon

from core.geometry.grid import as_multipolygon
from core.io.blastholes import Blastholes
from core.model.pipeline import GeozoneModel, pair_coverage


def _union(polygons: Iterable) -> MultiPolygon:
    parts = [p for p in polygons if p is not None and not p.is_empty]
    return as_multipolygon(shapely.union_all(parts)) if parts else MultiPolygon()


def bench_iou(contours_region, true_region, footprint) -> float:
    """Intersection over union of a geozone's contours and its true section on one bench.

    Parameters
    ----------
    contours_region : Polygon or MultiPolygon
        Union of the geozone's contours on the bench (local metres).
    true_region : Polygon or MultiPolygon
        The geozone's true section at the bench's elevation.
    footprint : Polygon or MultiPolygon
        The bench's drilled area; both regions are clipped to it, since nothing
        outside it was sampled.

    Returns
    -------
    float
        ``|C ∩ G| / |C ∪ G|`` of the clipped regions; nan when both are empty
        (the geozone is not on the bench and no contour claims it).
    """
    c = as_multipolygon(as_multipolygon(contours_region).intersection(footprint))
    g = as_multipolygon(as_multipolygon(true_region).intersection(footprint))
    union = c.union(g).area
    return float(c.intersection(g).area / union) if union > 0 else float("nan")


def holes_inside(xy: np.ndarray, labels: np.ndarray, geozone: str, region) -> tuple[float, float]:
    """Shares of holes a geozone's contours hold, against the holes' labels.

    Parameters
    ----------
    xy : (n, 2) array
        Holes of one bench (local metres).
    labels : (n,) array of str
        Their true labels (or, on real data, the file's labels).
    geozone : str
    region : Polygon or MultiPolygon
        Union of the geozone's contours on the bench.

    Returns
    -------
    own_inside : float
        Share of the holes labelled ``geozone`` that lie inside ``region``
        (nan if there are none).
    other_inside : float
        Share of the holes inside ``region`` whose label is another geozone
        (nan if no hole is inside).
    """
    xy = np.asarray(xy, float).reshape(-1, 2)
    labels = np.asarray(labels, dtype=object)
    inside = shapely.contains_xy(region, xy[:, 0], xy[:, 1]) if not region.is_empty else np.zeros(len(xy), bool)
    own = labels == geozone
    own_inside = float(inside[own].mean()) if own.any() else float("nan")
    other_inside = float((inside & ~own).sum() / inside.sum()) if inside.any() else float("nan")
    return own_inside, other_inside


def labels_by_hole(holes: Blastholes, true_labels: pd.Series) -> np.ndarray:
    """The true label of each of ``holes`` (in their order), looked up by hole id.

    Raises
    ------
    ValueError
        If the holes have no ids or some id has no true label.
    """
    if holes.hole_id is None:
        raise ValueError("the holes carry no hole ids to look their true labels up by")
    found = true_labels.reindex(pd.Index(holes.hole_id))
    if found.isna().any():
        missing = list(found.index[found.isna()][:3])
        raise ValueError(f"{int(found.isna().sum())} hole(s) have no true label, e.g. {missing}")
    return found.to_numpy(dtype=object)


def extraction_scores(
    holes: Blastholes,
    contours: list,
    labels: np.ndarray,
    truth: Callable[[str, float], MultiPolygon] | None = None,
    footprint: Callable[[int], MultiPolygon] | None = None,
    geozones: Iterable[str] | None = None,
) -> pd.DataFrame:
    """Bench IoU and holes-inside shares of every geozone on every bench.

    Parameters
    ----------
    holes : Blastholes
    contours : list of Contour
        Contours as :func:`core.extraction.contours.extract_contours` returns them.
    labels : (n,) array of str
        True label of each hole (:func:`labels_by_hole`), or the file's labels on real data.
    truth : callable, optional
        ``truth(geozone, z_m)`` -> true section in the holes' local frame
        (e.g. :func:`core.model.evaluation.truth_from_mine`); without it the IoU is nan.
    footprint : callable, optional
        ``footprint(bench)`` -> the bench's drilled footprint in the local frame;
        :meth:`Blastholes.drilled_area` by default.
    geozones : iterable of str, optional
        Geozones to score (default: every label in ``labels`` or the holes).

    Returns
    -------
    DataFrame
        One row per geozone and bench where the geozone has true holes or
        contours: ``geozone, bench, iou, own_inside, other_inside, own_holes,
        holes_inside``.
    """
    labels = np.asarray(labels, dtype=object)
    footprint = footprint or holes.drilled_area
    wanted = sorted(set(geozones) if geozones is not None else set(labels.tolist()) | set(holes.geozones))
    by_cell: dict[tuple[str, int], list] = {}
    for c in contours:
        by_cell.setdefault((c.geozone, c.bench), []).append(c.polygon)
    rows = []
    for k in range(holes.n_benches):
        on = holes.on_bench(k)
        xy, lab = holes.xy[on], labels[on]
        z = float(holes.bench_levels_m[k])
        for g in wanted:
            region = _union(by_cell.get((g, k), []))
            n_own = int(np.sum(lab == g))
            if region.is_empty and n_own == 0:
                continue
            own, other = holes_inside(xy, lab, g, region)
            iou = bench_iou(region, truth(g, z), footprint(k)) if truth is not None else float("nan")
            n_in = int(shapely.contains_xy(region, xy[:, 0], xy[:, 1]).sum()) if not region.is_empty else 0
            rows.append(
                {
                    "geozone": g,
                    "bench": k,
                    "iou": iou,
                    "own_inside": own,
                    "other_inside": other,
                    "own_holes": n_own,
                    "holes_inside": n_in,
                }
            )
    columns = ["geozone", "bench", "iou", "own_inside", "other_inside", "own_holes", "holes_inside"]
    return pd.DataFrame(rows, columns=columns)


def coverage_by_pair(models: Iterable[GeozoneModel]) -> pd.DataFrame:
    """Target-boundary coverage of every morphed bench pair (paper section 4).

    Parameters
    ----------
    models : iterable of GeozoneModel
        Built up to the morph stage (:func:`core.model.pipeline.model_geozone`).

    Returns
    -------
    DataFrame
        ``geozone, upper, lower, coverage, coverage_before_backtracking``: the
        share of the lower bench's boundary reached by trajectories after (and
        before) curvelet backtracking, weighted by boundary length over the
        pair's morph instances (:func:`core.model.pipeline.pair_coverage`).
        Pairs with nothing to cover are left out.
    """
    rows = []
    for model in models:
        for pair in model.pairs:
            after, before = pair_coverage(pair)
            if np.isfinite(after):
                rows.append(
                    {
                        "geozone": model.geozone,
                        "upper": pair.upper,
                        "lower": pair.lower,
                        "coverage": after,
                        "coverage_before_backtracking": before,
                    }
                )
    return pd.DataFrame(rows, columns=["geozone", "upper", "lower", "coverage", "coverage_before_backtracking"])


def coverage_summary(coverage: pd.Series) -> tuple[float, float]:
    """Minimum and median of per-pair coverages (nan, nan when there are none)."""
    values = pd.to_numeric(coverage, errors="coerce").dropna().to_numpy()
    if not len(values):
        return float("nan"), float("nan")
    return float(values.min()), float(np.median(values))
