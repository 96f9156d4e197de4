"""Contour prediction (paper section 4.1, Results): between, below and above the benches."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from conftest import iou, synthetic
from shapely.geometry import Point

from core.correspondence.pair import correspond_pair
from core.extraction.contours import Contour, extract_contours
from core.model.build import predictor_from_model
from core.model.evaluation import evaluate_geozone, summary_table, truth_from_mine
from core.model.pipeline import BenchPair, GeozoneModel, ModelParameters, beyond_frontiers, model_geozone, morph
from core.model.prediction import persistence_coefficient, predict_geozone, region_between, region_beyond


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
    # One pair: no history to learn persistence from, so half the movement carries on.
    assert iou(out[80.0], Point(9.0, 4.5).buffer(30.0)) > 0.93
    assert iou(out[110.0], Point(-3.0, -1.5).buffer(30.0)) > 0.93


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
        holes,
        geozone,
        predictor_from_model(model, holes, params),
        truth=truth_from_mine(mine, holes.frame),
        contours=contours,
        references=("nil",),
    )
    table = summary_table(rows).set_index("fraction")
    for fraction in (0.5, 1.0):  # 5 m and 10 m below a 10 m bench
        r = table.loc[fraction]
        assert r.precision_model > r.precision_nil, r
        assert r.recall_model > r.recall_nil, r


def _pair_between(src_contour, centre, bench, r=30.0) -> BenchPair:
    tgt = _contour(Point(*centre).buffer(r, quad_segs=32), bench + 1, 100.0 - 10 * (bench + 1))
    pair = BenchPair("g", bench, bench + 1, 100.0 - 10 * bench, 100.0 - 10 * (bench + 1), [src_contour], [tgt])
    pair.correspondence = correspond_pair([src_contour.polygon], [tgt.polygon], hole_spacing_m=5.0)
    morph(pair)
    return pair


def _three_benches(first_shift, second_shift) -> list[BenchPair]:
    top = _contour(Point(0, 0).buffer(30.0, quad_segs=32), 0, 100.0)
    a = _pair_between(top, first_shift, 0)
    b = _pair_between(a.targets[0], np.add(first_shift, second_shift), 1)
    return [a, b]


def test_persistence_is_learnt_from_the_geozones_own_benches():
    steady = persistence_coefficient(_three_benches((8.0, 4.0), (8.0, 4.0)), 5.0)
    back_and_forth = persistence_coefficient(_three_benches((8.0, 4.0), (-8.0, -4.0)), 5.0)
    assert steady > 0.9
    assert back_and_forth == 0.0
    # One pair: nothing to learn from, half the paper's extrapolation.
    assert persistence_coefficient(_three_benches((8.0, 4.0), (8.0, 4.0))[:1], 5.0) == 0.5


def test_a_steady_dip_is_carried_on_and_a_wobble_is_held():
    for second, expected in (((8.0, 4.0), (24.0, 12.0)), ((-8.0, -4.0), (0.0, 0.0))):
        pairs = _three_benches((8.0, 4.0), second)
        model = GeozoneModel("g", [pairs[0].sources[0], pairs[0].targets[0], pairs[1].targets[0]], pairs)
        below = predict_geozone(model, [70.0], 5.0)[70.0]
        assert iou(below, Point(*expected).buffer(30.0)) > 0.9, (second, below.centroid)


def test_a_geozone_goes_on_past_the_drilling_frontier():
    import pandas as pd

    from core.io.blastholes import blastholes_from_table

    # Bench 0 (z 100) drilled over x < 150 with the geozone on y > 20; bench 1 (z 90)
    # drilled over x < 100 only, with the geozone on y > 0.
    rows = []
    for z, x_end, y_cut in ((100.0, 150.0, 20.0), (90.0, 100.0, 0.0)):
        gx, gy = np.meshgrid(np.arange(0.0, x_end, 5.0), np.arange(-50.0, 50.0, 5.0))
        for x, y in zip(gx.ravel(), gy.ravel()):
            rows.append((x, y, z, "a" if y > y_cut else "b"))
    holes = blastholes_from_table(pd.DataFrame(rows, columns=["x", "y", "z", "geozone"]))
    beyond = beyond_frontiers(holes, "a", {1}, reach_spacings=20)[1]
    to_local = lambda x, y: Point(*holes.frame.to_local(np.array([x]), np.array([y]))[0])  # noqa: E731
    assert beyond.is_valid and beyond.intersection(holes.drilled_area(1)).area < 1e-6
    assert beyond.contains(to_local(120.0, 30.0))  # bench 0 was drilled there: its label
    assert not beyond.contains(to_local(120.0, 10.0))  # bench 0 says b, though bench 1's nearest hole is a
    assert beyond.contains(to_local(165.0, 10.0))  # past every bench: the nearest hole of bench 1
    assert not beyond.contains(to_local(165.0, -10.0))
    assert not beyond.contains(to_local(230.0, 30.0))  # further than the reach
    assert beyond_frontiers(holes, "a", {1}, reach_spacings=0)[1].difference(holes.drilled_area(0)).area < 1e-6
