"""Contour prediction (paper section 4.1, Results): between, below and above the benches."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely.geometry import Point

from conftest import iou, synthetic
from core.build import predictor_from_model
from core.correspondence import correspond_pair
from core.evaluation import evaluate_geozone, summary_table, truth_from_mine
from core.extraction import Contour
from core.extraction import extract_contours
from core.pipeline import BenchPair, GeozoneModel, ModelParameters, model_geozone, morph
from core.prediction import predict_geozone, region_beyond, region_between


def _contour(poly, bench, z) -> Contour:
    e = np.zeros(0, int)
    return Contour("g", bench, z, 0, poly, e, e, e)


def moving_pair(shift=(6.0, 3.0), r0=30.0, r1=30.0) -> BenchPair:
    src = Point(0, 0).buffer(r0, quad_segs=32)
    tgt = Point(*shift).buffer(r1, quad_segs=32)
    pair = BenchPair("g", 0, 1, 100.0, 90.0, [_contour(src, 0, 100.0)], [_contour(tgt, 1, 90.0)])
    pair.correspondence = correspond_pair([src], [tgt], hole_spacing_m=5.0)
    morph(pair)
    return pair


def test_between_benches_the_region_goes_from_source_to_target():
    pair = moving_pair(r1=40.0)
    src, tgt = pair.sources[0].polygon, pair.targets[0].polygon
    assert iou(region_between(pair, 0.0), src) > 0.97
    assert iou(region_between(pair, 1.0), tgt) > 0.97
    mid = region_between(pair, 0.5)
    assert mid.is_valid
    # Half-way: centroid half-way, radius half-way (a growing, drifting disc).
    assert np.allclose([mid.centroid.x, mid.centroid.y], [3.0, 1.5], atol=1.0)
    assert np.sqrt(mid.area / np.pi) == pytest.approx(35.0, abs=1.5)


def test_below_the_deepest_bench_the_movement_continues():
    pair = moving_pair()
    below = region_beyond(pair, 1.0, hole_spacing_m=5.0)
    expected = Point(12.0, 6.0).buffer(30.0)
    assert below.is_valid
    assert iou(below, expected) > 0.93
    above = region_beyond(pair, 1.0, hole_spacing_m=5.0, downward=False)
    assert iou(above, Point(-6.0, -3.0).buffer(30.0)) > 0.93


def test_frontier_parts_of_a_contour_are_held():
    pair = moving_pair()
    frontier = shapely.LineString([(-100, 20), (100, 20)])  # the drilling stopped along y = 20
    held = region_beyond(pair, 1.0, hole_spacing_m=5.0, frontier=frontier)
    free = region_beyond(pair, 1.0, hole_spacing_m=5.0)
    # Far from the frontier both move alike; near it the held one stays on the bench's contour.
    assert held.is_valid and not held.equals(free)
    top_target = pair.targets[0].polygon.intersection(shapely.box(-100, 18, 100, 22))
    assert held.intersection(top_target).area > free.intersection(top_target).area


def test_predict_geozone_picks_bench_between_below_and_above():
    pair = moving_pair()
    model = GeozoneModel("g", [pair.sources[0], pair.targets[0]], [pair])
    out = predict_geozone(model, [110.0, 100.0, 95.0, 90.0, 80.0], 5.0)
    assert out[100.0].equals(shapely.MultiPolygon([pair.sources[0].polygon]))
    assert iou(out[95.0], Point(3.0, 1.5).buffer(30.0)) > 0.93
    assert iou(out[80.0], Point(12.0, 6.0).buffer(30.0)) > 0.93
    assert iou(out[110.0], Point(-6.0, -3.0).buffer(30.0)) > 0.93


def test_a_splitting_body_keeps_splitting_below_the_benches():
    src = Point(0, 0).buffer(20.0).union(Point(12, 0).buffer(20.0))
    tgt = shapely.union_all([Point(-12, 0).buffer(17.0), Point(26, 0).buffer(17.0)])
    parts = list(tgt.geoms)
    pair = BenchPair("g", 0, 1, 100.0, 90.0, [_contour(src, 0, 100.0)], [_contour(p, 1, 90.0) for p in parts])
    pair.correspondence = correspond_pair([src], parts, hole_spacing_m=5.0)
    morph(pair)
    below = region_beyond(pair, 1.0, hole_spacing_m=5.0)
    assert below.is_valid and len(below.geoms) == 2
    xs = sorted(g.centroid.x for g in below.geoms)
    assert xs[0] < -12.5 and xs[1] > 26.5  # the lobes keep moving apart


@pytest.mark.parametrize("geozone", ["g1", "g2"])
def test_model_beats_nil_below_withheld_benches_on_a_fresh_mine(geozone):
    mine, _, holes = synthetic(47)
    contours = extract_contours(holes)
    params = ModelParameters()
    model = model_geozone(holes, geozone, contours=contours, params=params)
    rows = evaluate_geozone(
        holes, geozone, predictor_from_model(model, holes, params),
        truth=truth_from_mine(mine, holes.frame), contours=contours, references=("nil",),
    )
    table = summary_table(rows).set_index("fraction")
    for fraction in (0.5, 1.0):  # 5 m and 10 m below a 10 m bench
        r = table.loc[fraction]
        assert r.precision_model > r.precision_nil, r
        assert r.recall_model > r.recall_nil, r
