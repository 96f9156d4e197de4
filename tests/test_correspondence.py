"""Tests of core.correspondence.pair (paper section 3) on shapes with known truth."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely import affinity
from shapely.geometry import Point, Polygon, box

from core.correspondence.pair import (
    PairCorrespondence,
    align_translation_m,
    allocate_ports,
    association_matrix,
    correspond_pair,
    fft_translation,
    subtrees,
)
from core.errors import BGMInputError
from core.geometry.grid import Grid

HOLE = 6.0


def blob(cx=0.0, cy=0.0, radius=30.0, coeffs=(), n=128) -> Polygon:
    """Star-shaped polygon with radius ``R (1 + sum a_k cos(k theta + phase_k))``."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = np.ones_like(th)
    for k, a, ph in coeffs:
        r += a * np.cos(k * th + ph)
    r *= radius
    return Polygon(np.column_stack([cx + r * np.cos(th), cy + r * np.sin(th)]))


def ellipse(cx, cy, ax, ay) -> Polygon:
    return affinity.scale(Point(cx, cy).buffer(1.0, 64), ax, ay)


# --------------------------------------------------------------------------
# Single source, single target: FFT alignment (Algorithm 4)
# --------------------------------------------------------------------------


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    radius=st.floats(20.0, 45.0),
    a2=st.floats(-0.12, 0.12),
    a3=st.floats(-0.12, 0.12),
    p2=st.floats(0, 2 * np.pi),
    p3=st.floats(0, 2 * np.pi),
    shift_frac=st.floats(0.0, 1.5),
    shift_dir=st.floats(0, 2 * np.pi),
)
def test_shifted_blob_is_recovered_within_one_cell(radius, a2, a3, p2, p3, shift_frac, shift_dir):
    # Overlap is guaranteed for |shift| < 2 * min radius >= 1.52 R; larger
    # shifts are a region-association question, not an alignment one.
    src = blob(10.0, -5.0, radius, [(2, a2, p2), (3, a3, p3)])
    shift = radius * shift_frac * np.array([math.cos(shift_dir), math.sin(shift_dir)])
    tgt = affinity.translate(src, *shift)
    res = correspond_pair([src], [tgt], hole_spacing_m=HOLE)
    assert res.association.tolist() == [[True]]
    err = np.hypot(*(res.translations[0] - shift))
    assert err <= res.cell_size_m, (err, res.cell_size_m)


def test_fft_translation_integer_shift_exact_including_negative_lags():
    rng = np.random.default_rng(0)
    shape = (90, 120)
    for _ in range(10):
        u = np.zeros(shape, bool)
        r, c = rng.integers(0, 70), rng.integers(0, 100)
        u[r : r + 12, c : c + 15] = True
        u[r + 3 : r + 20, c + 2 : c + 6] = True  # asymmetric
        dr, dc = rng.integers(-r, shape[0] - 20 - r), rng.integers(-c, shape[1] - 15 - c)
        target = np.roll(np.roll(u, dr, 0), dc, 1)
        from core.geometry.sdf import signed_distance

        got = fft_translation(u, signed_distance(target))
        assert got == (float(dr), float(dc))


def test_no_wrap_around_for_large_shift_near_frame_edge():
    from core.geometry.sdf import signed_distance

    # Source in the top-left corner, target in the bottom-right corner: the
    # lag is most of the frame. A circular correlation without padding would
    # alias it to a small negative lag.
    u = np.zeros((64, 64), bool)
    u[2:14, 3:13] = True
    t = np.zeros_like(u)
    t[50:62, 51:61] = True
    assert fft_translation(u, signed_distance(t)) == (48.0, 48.0)
    # ... and the reverse direction (negative lag).
    assert fft_translation(t, signed_distance(u)) == (-48.0, -48.0)


def test_shifted_source_stays_inside_frame():
    u = np.zeros((40, 40), bool)
    u[15:25, 15:25] = True
    v = -np.ones((40, 40))
    v[0:3, 0:3] = 100.0  # best value in the corner; the source can only partly cover it
    d_row, d_col = fft_translation(u, v)
    assert (15 + d_row, 15 + d_col) == (0, 0)


def test_metric_wrapper_recovers_large_metric_shift():
    src = blob(0, 0, 25.0, [(2, 0.1, 0.3)])
    shift = np.array([-140.0, 95.0])  # far beyond overlap, towards the frame corner
    tgt = affinity.translate(src, *shift)
    got = np.array(align_translation_m(src, tgt, cell_size_m=1.0))
    assert np.hypot(*(got - shift)) <= 1.0


# --------------------------------------------------------------------------
# Region association (section 3.1)
# --------------------------------------------------------------------------


def test_association_matches_formula_for_two_discs():
    # ns = 1: s_err = 0 so nu = 2; lambda = mu_lower = 9; equal areas so K = 50.
    # p >= 0.5 iff |x - c_s| <= 9 * 2 * sqrt(2 ln 2) = 21.2 m (median over the disc).
    src = Point(0, 0).buffer(5.0, 64)
    near = Point(18.0, 0).buffer(5.0, 64)
    far = Point(26.0, 0).buffer(5.0, 64)
    grid = Grid.covering((-10, -10, 40, 10), 0.25, 2)
    assert association_matrix([src], [near], mu_lower_m=9.0, grid=grid).tolist() == [[True]]
    assert association_matrix([src], [far], mu_lower_m=9.0, grid=grid).tolist() == [[False]]


def test_overlapping_pair_always_associated():
    # Big target, small lambda: the median likelihood over the target is
    # tiny, yet the source sits on it. The safeguard must associate them.
    src = box(0, 0, 20, 20)
    tgt = box(-200, -200, 200, 200)
    assert association_matrix([src], [tgt], mu_lower_m=2.0).tolist() == [[True]]


def test_empty_inputs():
    assert association_matrix([], [box(0, 0, 1, 1)], mu_lower_m=1.0).shape == (0, 1)
    res = correspond_pair([], [box(0, 0, 10, 10)], hole_spacing_m=HOLE)
    assert res.translations.shape == (0, 2)
    assert [(m.target_ids, m.source_ids) for m in res.instances] == [([0], [])]
    res = correspond_pair([], [], hole_spacing_m=HOLE)
    assert res.instances == []


def test_pod_cases():
    src = ellipse(0, 0, 50, 30)
    tgt_main = ellipse(8, 5, 50, 30)
    pod = Point(170, 80).buffer(6.0)
    lone_source = Point(-200, -150).buffer(10.0)
    res = correspond_pair([src, lone_source], [tgt_main, pod], hole_spacing_m=HOLE)
    assert res.initial_association.tolist() == [[True, False], [False, False]]
    assert res.association.tolist() == [[True, False], [False, False]]
    inst = {(tuple(m.target_ids), tuple(m.source_ids)) for m in res.instances}
    assert inst == {((0,), (0,)), ((1,), ()), ((), (1,))}
    assert res.translations[1].tolist() == [0.0, 0.0]


# --------------------------------------------------------------------------
# Many-to-one, one-to-many, many-to-many (sections 3.2.2-3.2.4)
# --------------------------------------------------------------------------


def test_merge_two_sources_into_one_target_without_overlap():
    s0 = ellipse(-52, 0, 50, 30)
    s1 = ellipse(52, 3, 50, 30)  # 4 m gap between them
    shift = (9.0, -6.0)
    tgt = affinity.translate(s0.union(s1).buffer(4.0).buffer(-4.0), *shift)
    assert tgt.geom_type == "Polygon"
    res = correspond_pair([s0, s1], [tgt], hole_spacing_m=HOLE, keep_fields=True)
    assert res.association.tolist() == [[True], [True]]
    a0 = affinity.translate(s0, *res.translations[0])
    a1 = affinity.translate(s1, *res.translations[1])
    assert a0.intersection(a1).area < 0.02 * min(s0.area, s1.area)
    # Each source covers most of its half of the target.
    assert a0.intersection(tgt).area > 0.8 * s0.area
    assert a1.intersection(tgt).area > 0.8 * s1.area
    assert [(m.target_ids, m.source_ids) for m in res.instances] == [([0], [0, 1])]
    # Ports were allocated on the shared target: s0 (left) gets the left half.
    ports = {p.source: p for p in res.fields[0].ports}
    mid0 = ports[0].start_rad + ports[0].width_rad / 2
    assert math.cos(mid0) < -0.9


def test_merge_sources_do_not_overlap_even_when_shift_differs():
    # Two sources both drawn towards the centre of one round target: acting
    # selfishly (no ports, no obstacles) they overlap by 15%.
    s0 = Point(-45, 0).buffer(20.0)
    s1 = Point(45, 5).buffer(20.0)
    tgt = Point(0, 0).buffer(40.0)
    res = correspond_pair([s0, s1], [tgt], hole_spacing_m=HOLE)
    assert res.association.tolist() == [[True], [True]]
    a0 = affinity.translate(s0, *res.translations[0])
    a1 = affinity.translate(s1, *res.translations[1])
    assert a0.intersection(a1).area < 0.02 * s0.area
    assert a0.intersection(tgt).area > 0.9 * s0.area
    assert a1.intersection(tgt).area > 0.9 * s1.area


def dumbbell(cx, cy) -> Polygon:
    return (
        Point(cx - 35, cy)
        .buffer(22.0, 64)
        .union(Point(cx + 35, cy).buffer(22.0, 64))
        .union(box(cx - 35, cy - 7, cx + 35, cy + 7))
    )


def test_split_source_straddles_both_targets():
    src = dumbbell(0, 0)
    shift = np.array([6.0, 5.0])
    t0 = Point(-38 + shift[0], shift[1]).buffer(21.0, 64)
    t1 = Point(38 + shift[0], shift[1]).buffer(21.0, 64)
    res = correspond_pair([src], [t0, t1], hole_spacing_m=HOLE)
    assert res.association.tolist() == [[True, True]]
    moved = affinity.translate(src, *res.translations[0])
    for t in (t0, t1):
        assert moved.intersection(t).area > 0.2 * t.area
    assert [(m.target_ids, m.source_ids) for m in res.instances] == [([0, 1], [0])]


def test_split_plain_blob_is_rewarded_for_straddling():
    # A round source splits into two round pods with a 36 m gap. Aligned
    # with the plain SDF of the targets it sits on one pod (covering 97% of
    # it and none of the other); the gap reward makes it straddle both.
    src = Point(0, 0).buffer(35.0, 64)
    t0 = Point(-40, 5).buffer(22.0, 64)
    t1 = Point(40, 5).buffer(22.0, 64)
    res = correspond_pair([src], [t0, t1], hole_spacing_m=HOLE)
    assert res.association.tolist() == [[True, True]]
    moved = affinity.translate(src, *res.translations[0])
    for t in (t0, t1):
        assert moved.intersection(t).area > 0.2 * t.area


def test_subtree_decomposition_paper_worked_example():
    # Paper Fig. 7 (type C): s0-t0, s1-{t0,t2}, s2-t2, s3-{t2,t3}; t1 unconnected.
    A = np.zeros((4, 4), bool)
    for s, t in [(0, 0), (1, 0), (1, 2), (2, 2), (3, 2), (3, 3)]:
        A[s, t] = True
    trees = subtrees(A)
    assert (trees[1].targets, trees[1].co_sources) == ([0, 2], {0: [0], 2: [2, 3]})
    assert (trees[0].targets, trees[0].co_sources) == ([0], {0: [1]})
    assert (trees[2].targets, trees[2].co_sources) == ([2], {2: [1, 3]})
    assert (trees[3].targets, trees[3].co_sources) == ([2, 3], {2: [1, 2], 3: []})
    assert [t.kind for t in trees] == ["many-to-one", "many-to-many", "many-to-one", "many-to-many"]


def test_allocate_ports_sizes_and_directions():
    ports = allocate_ports(0, (0.0, 0.0), [5, 7, 9], np.array([[-10, 0], [10, 0], [0, 10]]), np.array([2.0, 1.0, 1.0]))
    assert [p.source for p in ports] == [5, 7, 9]
    assert sum(p.width_rad for p in ports) == pytest.approx(2 * np.pi)
    assert ports[0].width_rad == pytest.approx(np.pi)
    for p, direction in zip(ports, [np.pi, 0.0, np.pi / 2]):
        assert p.contains_angle(np.array([direction]))[0]


def test_many_to_many_runs_and_groups_instances():
    s0 = ellipse(-60, 0, 30, 20)
    s1 = ellipse(0, 0, 22, 20)
    s2 = ellipse(60, 0, 30, 20)
    t0 = ellipse(-32, 3, 42, 22)  # s0 + s1 merge
    t1 = ellipse(58, 3, 28, 20)
    res = correspond_pair([s0, s1, s2], [t0, t1], hole_spacing_m=HOLE)
    moved = [affinity.translate(s, *d) for s, d in zip([s0, s1, s2], res.translations)]
    for i in range(3):
        for j in range(i + 1, 3):
            assert moved[i].intersection(moved[j]).area < 0.02 * min(moved[i].area, moved[j].area)
    groups = {(tuple(m.target_ids), tuple(m.source_ids)) for m in res.instances}
    assert ((0,), (0, 1)) in groups and ((1,), (2,)) in groups


# --------------------------------------------------------------------------
# Overrides and serialisation
# --------------------------------------------------------------------------


def test_locked_translation_is_used_exactly():
    src = ellipse(0, 0, 40, 25)
    tgt = ellipse(10, 4, 40, 25)
    res = correspond_pair([src], [tgt], hole_spacing_m=HOLE, locked_translations={0: (3.25, -1.5)})
    assert res.translations[0].tolist() == [3.25, -1.5]


def test_forbidden_and_forced_pairs():
    src = ellipse(0, 0, 40, 25)
    tgt = ellipse(10, 4, 40, 25)
    far = Point(300, 200).buffer(10.0)
    res = correspond_pair([src], [tgt, far], hole_spacing_m=HOLE, forbidden={(0, 0)})
    assert res.association.tolist() == [[False, False]]
    assert res.translations[0].tolist() == [0.0, 0.0]
    res = correspond_pair([src], [tgt, far], hole_spacing_m=HOLE, forced={(0, 1)})
    assert res.initial_association.tolist() == [[True, True]]
    assert res.association[0, 1]
    assert [(m.target_ids, m.source_ids) for m in res.instances] == [([0, 1], [0])]


def test_bad_overrides_and_parameters_raise_clear_errors():
    src, tgt = ellipse(0, 0, 40, 25), ellipse(10, 4, 40, 25)
    with pytest.raises(BGMInputError, match="source 3"):
        correspond_pair([src], [tgt], hole_spacing_m=HOLE, locked_translations={3: (0, 0)})
    with pytest.raises(BGMInputError, match="out of range"):
        correspond_pair([src], [tgt], hole_spacing_m=HOLE, forced={(0, 5)})
    with pytest.raises(BGMInputError, match="both forced and forbidden"):
        correspond_pair([src], [tgt], hole_spacing_m=HOLE, forced={(0, 0)}, forbidden={(0, 0)})
    with pytest.raises(BGMInputError, match="hole_spacing_m"):
        correspond_pair([src], [tgt], hole_spacing_m=0.0)


def test_defaults_scale_with_hole_spacing_and_grid_is_capped():
    src = ellipse(0, 0, 40, 25)
    res = correspond_pair([src], [src], hole_spacing_m=8.0)
    assert res.mu_lower_m == pytest.approx(12.0)
    assert res.cell_size_m == pytest.approx(2.0)
    huge = ellipse(0, 0, 3000, 2000)
    res = correspond_pair([huge], [affinity.translate(huge, 50, 0)], hole_spacing_m=6.0)
    assert max(res.grid.shape) <= 520
    assert abs(res.translations[0][0] - 50) <= res.cell_size_m


def test_to_dict_is_json_serialisable():
    s0, s1 = ellipse(-52, 0, 50, 30), ellipse(52, 3, 50, 30)
    tgt = affinity.translate(s0.union(s1).buffer(4.0).buffer(-4.0), 5, 0)
    res = correspond_pair([s0, s1], [tgt], hole_spacing_m=HOLE, keep_fields=True)
    assert isinstance(res, PairCorrespondence)
    d = json.loads(json.dumps(res.to_dict()))
    assert d["association"] == [[True], [True]]
    assert len(d["translations_m"]) == 2 and d["instances"] == [{"target_ids": [0], "source_ids": [0, 1]}]
    assert len(d["fields"]["0"]["ports"]) == 2
    assert res.fields[0].value_function.shape == res.grid.shape
