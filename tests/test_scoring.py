"""Extraction figures (core.model.scoring) on constructed cases with known answers."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from shapely.geometry import MultiPolygon, Polygon, box

from core.correspondence.pair import MorphInstance
from core.extraction.contours import Contour
from core.io.blastholes import blastholes_from_table
from core.model import scoring
from core.model.pipeline import BenchPair, GeozoneModel, MorphStep

# ---------------------------------------------------------------------------
# Bench IoU


def test_bench_iou_clips_both_regions_to_the_footprint():
    # Contours [0, 10] x [0, 10], truth [5, 15] x [0, 10], drilled [0, 12] x [0, 10]:
    # clipped contours 100, clipped truth [5, 12] -> 70, overlap 50, union 120.
    assert scoring.bench_iou(box(0, 0, 10, 10), box(5, 0, 15, 10), box(0, 0, 12, 10)) == pytest.approx(50 / 120)
    # Without the clip the answer would be 50 / 150: the footprint matters.
    assert scoring.bench_iou(box(0, 0, 10, 10), box(5, 0, 15, 10), box(-100, -100, 100, 100)) == pytest.approx(1 / 3)


def test_bench_iou_empty_cases():
    footprint = box(0, 0, 20, 20)
    assert math.isnan(scoring.bench_iou(MultiPolygon(), Polygon(), footprint))
    assert scoring.bench_iou(MultiPolygon(), box(0, 0, 5, 5), footprint) == 0.0  # a missed body
    assert scoring.bench_iou(box(0, 0, 5, 5), Polygon(), footprint) == 0.0  # a contour where there is none
    # Truth outside the drilled area does not count.
    assert math.isnan(scoring.bench_iou(MultiPolygon(), box(50, 50, 60, 60), footprint))


# ---------------------------------------------------------------------------
# Holes inside


def test_holes_inside_shares():
    # Ten g1 holes along x = 0..9, five of them inside [-0.5, 4.5] x [-1, 1];
    # four g0 holes, one of them inside.
    xy = np.array([[x, 0.0] for x in range(10)] + [[2.0, 0.5], [20, 0], [21, 0], [22, 0]])
    labels = np.array(["g1"] * 10 + ["g0"] * 4, dtype=object)
    own, other = scoring.holes_inside(xy, labels, "g1", box(-0.5, -1, 4.5, 1))
    assert own == pytest.approx(0.5)
    assert other == pytest.approx(1 / 6)
    # The host seen the same way: one of its four holes inside, and five g1 holes with it.
    own, other = scoring.holes_inside(xy, labels, "g0", box(-0.5, -1, 4.5, 1))
    assert own == pytest.approx(0.25) and other == pytest.approx(5 / 6)


def test_holes_inside_empty_cases():
    xy = np.array([[0.0, 0.0], [1.0, 0.0]])
    labels = np.array(["g0", "g0"], dtype=object)
    own, other = scoring.holes_inside(xy, labels, "g1", box(-1, -1, 2, 1))
    assert math.isnan(own) and other == 1.0  # no g1 hole; everything inside is another geozone
    own, other = scoring.holes_inside(xy, labels, "g0", MultiPolygon())
    assert own == 0.0 and math.isnan(other)


# ---------------------------------------------------------------------------
# Per geozone and bench


def _two_benches():
    """A 10 x 6 grid of holes at 1 m on two benches: g1 where x < 3 (true), the file mislabels one hole."""
    gx, gy = np.meshgrid(np.arange(10.0), np.arange(6.0))
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    rows = []
    for k, z in enumerate((100.0, 90.0)):
        for i, (x, y) in enumerate(xy):
            rows.append({"x": x, "y": y, "z": z, "geozone": "g1" if x < 3 else "g0", "hole_id": f"B{k}-{i:03d}"})
    table = pd.DataFrame(rows)
    true = table.set_index("hole_id")["geozone"].copy()
    table.loc[table["hole_id"] == "B0-005", "geozone"] = "g1"  # x = 5: a mislabelled host hole
    return table, true


def _contour(geozone, bench, polygon, holes):
    on = holes.on_bench(bench, geozone)
    return Contour(geozone, bench, float(holes.bench_levels_m[bench]), 0, polygon, on, on[:0], on[:0])


def test_extraction_scores_against_true_labels_and_sections():
    table, true = _two_benches()
    holes = blastholes_from_table(table, bench_height=10.0, length_unit="m")
    labels = scoring.labels_by_hole(holes, true)
    assert (labels == true.reindex(holes.hole_id).to_numpy()).all()
    ox, oy = holes.frame.origin_x, holes.frame.origin_y

    def local(x0, y0, x1, y1):
        return box(x0 - ox, y0 - oy, x1 - ox, y1 - oy)

    # Bench 0: a contour that swells to x = 5.5 around the mislabelled hole; bench 1: exact.
    contours = [
        _contour("g1", 0, local(-0.5, -0.5, 5.5, 5.5), holes),
        _contour("g1", 1, local(-0.5, -0.5, 2.5, 5.5), holes),
    ]

    def truth(g, z):
        return local(-0.5, -0.5, 2.5, 5.5) if g == "g1" else local(2.5, -0.5, 9.5, 5.5)

    footprint = local(-0.5, -0.5, 9.5, 5.5)
    df = scoring.extraction_scores(holes, contours, labels, truth, lambda k: footprint, geozones=["g1"])
    assert list(df["bench"]) == [0, 1]
    b0, b1 = df.iloc[0], df.iloc[1]
    assert b0["iou"] == pytest.approx(18 / 36)
    assert b0["own_inside"] == 1.0 and b0["own_holes"] == 18
    assert b0["holes_inside"] == 36 and b0["other_inside"] == pytest.approx(18 / 36)
    assert b1["iou"] == pytest.approx(1.0) and b1["other_inside"] == 0.0 and b1["own_inside"] == 1.0
    # Real data: the file's labels stand in for the truth, and there is no IoU.
    df = scoring.extraction_scores(holes, contours, holes.geozone, geozones=["g1"])
    assert df["iou"].isna().all()
    assert df.iloc[0]["own_holes"] == 19 and df.iloc[0]["other_inside"] == pytest.approx(17 / 36)


def test_labels_by_hole_refuses_holes_without_truth():
    table, true = _two_benches()
    holes = blastholes_from_table(table, bench_height=10.0, length_unit="m")
    with pytest.raises(ValueError, match="no true label"):
        scoring.labels_by_hole(holes, true.drop("B1-007"))


# ---------------------------------------------------------------------------
# Coverage


def _step(target_length: float, after: float, before: float) -> MorphStep:
    # A square target of the given perimeter; pair_coverage weighs instances by it.
    side = target_length / 4
    result = SimpleNamespace(
        target=box(0, 0, side, side), target_boundary_coverage=after, coverage_before_backtracking=before
    )
    return MorphStep(MorphInstance([0], [0]), result)


def _pair(upper: int, steps: list) -> BenchPair:
    return BenchPair("g1", upper, upper + 1, 100.0 - 10 * upper, 90.0 - 10 * upper, [], [], morphs=steps)


def test_coverage_by_pair_weighs_instances_by_target_boundary_length():
    model = GeozoneModel(
        "g1",
        [],
        [
            _pair(0, [_step(40.0, 1.0, 0.9), _step(10.0, 0.5, 0.5)]),  # (40 * 1 + 10 * 0.5) / 50 = 0.9
            _pair(1, [_step(20.0, 0.8, 0.6)]),
            _pair(2, []),  # nothing morphed: left out
        ],
    )
    other = GeozoneModel("g2", [], [_pair(0, [_step(8.0, 0.96, 0.7)])])
    df = scoring.coverage_by_pair([model, other])
    assert list(zip(df["geozone"], df["upper"])) == [("g1", 0), ("g1", 1), ("g2", 0)]
    assert df["coverage"].tolist() == pytest.approx([0.9, 0.8, 0.96])
    assert df["coverage_before_backtracking"].tolist() == pytest.approx([0.82, 0.6, 0.7])
    assert scoring.coverage_summary(df["coverage"]) == pytest.approx((0.8, 0.9))
    assert all(math.isnan(v) for v in scoring.coverage_summary(pd.Series([], dtype=float)))
