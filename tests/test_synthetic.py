"""Synthetic families, mine-like drilling and the scenario registry (core.synthetic)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import box

from core.io.atomic import atomic_write_text
from core.io.blastholes import FEET_TO_METRES, BGMWarning, blastholes_from_table
from core.model.build import load_truth, truth_sidecar
from core.model.evaluation import truth_from_mine
from core.synthetic import drilling, families
from core.synthetic.blobs import HOST, Blob, SyntheticMine
from core.synthetic.scenarios import FAMILIES, HELD_OUT_SEEDS, TUNING_SEEDS, make_family, scenario
from core.synthetic.shapes import SHAPES, make_shape, shape_scenario
from core.synthetic.solids import (
    Clipped,
    DippingContact,
    DippingLayer,
    GrowingBody,
    Hollow,
    PivotingContact,
    star_outline,
    straight_or_bent_trace,
)

SEEDS = TUNING_SEEDS[:3]


def read(table: pd.DataFrame):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        return blastholes_from_table(table, source="synthetic")


def local_xy(mine: SyntheticMine, table: pd.DataFrame) -> np.ndarray:
    """Table coordinates back in the mine's local metres."""
    return table[["x", "y"]].to_numpy() * mine.metres_per_unit - np.asarray(mine.origin)


def bench_of(table: pd.DataFrame) -> np.ndarray:
    return table["hole_id"].str.slice(1, 3).astype(int).to_numpy()


# ---------------------------------------------------------------------------
# Families


@pytest.mark.parametrize("family", FAMILIES)
def test_every_family_is_deterministic_per_seed(family):
    mine_a, table_a, true_a = scenario(family, SEEDS[0])
    mine_b, table_b, true_b = scenario(family, SEEDS[0])
    pd.testing.assert_frame_equal(table_a, table_b)
    pd.testing.assert_series_equal(true_a, true_b)
    z = float(mine_a.bench_levels_m[3])
    for g in mine_a.labels:
        assert mine_a.section(g, z).symmetric_difference(mine_b.section(g, z)).area == 0.0
    _, other, _ = scenario(family, SEEDS[1])
    assert not other[["x", "y"]].equals(table_a[["x", "y"]])


@pytest.mark.parametrize("family", FAMILIES)
def test_sections_are_valid_and_every_geozone_is_drilled(family):
    for seed in SEEDS:
        mine, table, true = scenario(family, seed)
        assert 2 <= len(mine.geozones) <= 4 and HOST not in mine.geozones
        assert set(mine.kinds) == set(mine.geozones)
        for g in mine.labels:
            drilled = 0.0
            for z in mine.bench_levels_m:
                region = mine.section(g, float(z))
                assert region.is_valid
                drilled += region.intersection(mine.footprints[float(z)]).area
            assert drilled > 0, (family, seed, g)
            assert (true == g).sum() >= 1, (family, seed, g)
        # The geozones of a bench tile the mine: no overlap, no gap.
        z = float(mine.bench_levels_m[2])
        regions = [mine.section(g, z) for g in mine.labels]
        assert sum(r.area for r in regions) == pytest.approx(box(*mine.extent_m).area, rel=1e-6)


def test_a_scenario_is_drilled_on_every_bench_at_mine_scale():
    """Thousands of holes per mine, a footprint recorded for every bench."""
    mine, table, _ = scenario("mix", SEEDS[0])
    assert 5_000 < len(table) < 30_000
    assert len(mine.footprints) == len(mine.bench_levels_m)


@pytest.mark.parametrize(
    "pattern, first_ring_holes, next_ring_spacings", [("staggered", 6, np.sqrt(3)), ("square", 4, np.sqrt(2))]
)
def test_a_bench_is_drilled_on_the_pattern_asked_for(pattern, first_ring_holes, next_ring_spacings):
    """Staggered: six holes a spacing away and the next at sqrt(3); square: four, and the diagonals at sqrt(2)."""
    mine, table, _ = scenario("strips", SEEDS[0], drilling={"pattern": pattern, "collar_scatter_spacings": 0.0})
    xy = local_xy(mine, table)[bench_of(table) == 1]
    # Nearest holes first; the median hole is inside the pattern, with its whole first ring.
    distances = cKDTree(xy).query(xy, k=first_ring_holes + 2)[0][:, 1:]
    spacing = np.median(distances[:, 0])
    assert np.allclose(np.median(distances[:, :first_ring_holes], axis=0), spacing, rtol=0.02)
    assert np.median(distances[:, first_ring_holes]) == pytest.approx(next_ring_spacings * spacing, rel=0.02)


def test_an_unknown_drilling_pattern_is_refused():
    with pytest.raises(ValueError, match="pattern 'hexagonal'"):
        scenario("strips", SEEDS[0], drilling={"pattern": "hexagonal"})


def _strips(mine: SyntheticMine):
    return [
        (g, s)
        for g, solids in mine.geozones.items()
        for s in solids
        if isinstance(s, DippingLayer) and s.growth_per_m == 0
    ]


@pytest.mark.parametrize("seed", TUNING_SEEDS[:6])
def test_strips_cross_the_pit_and_move_2_to_15_m_per_10_m_bench(seed):
    mine = make_family("strips", seed)
    strips = _strips(mine)
    assert strips
    levels = mine.bench_levels_m
    height = float(levels[0] - levels[1])
    step = drilling.pit_step_m(mine.extent_m, len(levels), height)
    for g, strip in strips:
        speed = float(np.hypot(*strip.velocity))
        assert 2.0 - 1e-9 <= speed * 10.0 <= 15.0 + 1e-9
        assert 34.0 <= np.degrees(np.arctan(1 / speed)) <= 79.0
        normal = np.asarray(strip.velocity) / speed
        # The trace runs along the strike: the movement is across it.
        trace = strip.trace_m
        along = (trace[-1] - trace[0]) / np.linalg.norm(trace[-1] - trace[0])
        assert abs(float(along @ normal)) < 0.05
        # Measure on the mine's labels along the normal through the pit's centre.
        t = np.arange(-400.0, 400.0, 0.05)
        centres = []
        for k, z in enumerate(levels):
            pit = drilling.pit_outline(mine.extent_m, k, step)
            assert len(as_parts(pit.difference(strip.section(float(z))))) >= 2, (seed, g, k)  # cuts the pit in two
            on = mine.label_at(t[:, None] * normal, float(z)) == g
            assert on.any()
            a, b = t[on].min(), t[on].max()
            assert 11.9 <= b - a <= 34.0
            centres.append(0.5 * (a + b))
        moves = np.diff(centres)
        assert np.allclose(moves, moves[0], atol=0.2)
        assert abs(moves[0]) == pytest.approx(speed * height, abs=0.2)


def _sideways_rates(mine) -> list[float]:
    """Metres per metre of depth each layer, contact and fold hinge of ``mine`` moves (not thickening layers)."""
    return [
        float(np.hypot(*s.velocity))
        for solids in mine.geozones.values()
        for s in solids
        if isinstance(s, (DippingLayer, DippingContact)) and getattr(s, "growth_per_m", 0.0) == 0
    ]


def test_a_shift_scale_moves_layers_contacts_and_hinges_that_many_times_faster():
    rates = {
        scale: [
            r
            for f in ("strips", "folds", "mix")
            for seed in TUNING_SEEDS[:6]
            for r in _sideways_rates(make_family(f, seed, shift_scale=scale))
        ]
        for scale in (1.0, 2.0)
    }
    # A fold's hinge also drifts up to 0.2 m a metre across its axis, unscaled.
    assert all(0.2 - 1e-9 <= r <= np.hypot(1.5, 0.2) for r in rates[1.0])
    assert all(0.4 - 1e-9 <= r <= np.hypot(3.0, 0.2) for r in rates[2.0])
    # Slowed where a layer would leave the pit, so not all twice as fast, but past any default.
    assert max(rates[2.0]) > 1.6
    assert np.median(rates[2.0]) > 1.3 * np.median(rates[1.0])


@pytest.mark.parametrize("scale", ["shift_scale", "length_scale"])
def test_a_scale_that_is_not_positive_is_refused(scale):
    with pytest.raises(ValueError, match=scale):
        scenario("strips", 1, **{scale: 0.0})


def test_a_length_scale_stretches_the_mine_along_x_and_draws_the_same_geology():
    """A pit of Kennecott's shape (4: 1.1-1.4 km by 240-300 m) with each seed's own geology, so layers striking along
    it cross the pit for most of a kilometre, as no default mine's (280-360 m) can."""
    longest = 0.0
    for seed in TUNING_SEEDS[:8]:
        short, long = make_family("strips", seed), make_family("strips", seed, length_scale=4.0)
        (x0, y0, x1, y1), (u0, v0, u1, v1) = short.extent_m, long.extent_m
        assert np.isclose(u1 - u0, 4 * (x1 - x0)) and (v0, v1) == (y0, y1)
        assert long.kinds == short.kinds
        top = float(long.bench_levels_m[0])
        for g, kind in long.kinds.items():
            if kind == "strip":
                parts = as_parts(long.section(g, top))
                longest = max([longest] + [max(p.bounds[2] - p.bounds[0], p.bounds[3] - p.bounds[1]) for p in parts])
    assert 600.0 < longest <= 1500.0


def as_parts(geometry):
    return [p for p in getattr(geometry, "geoms", [geometry]) if p.area > 1.0]


def test_strips_family_has_the_single_contact_variant():
    contacts = [
        seed
        for seed in TUNING_SEEDS
        if any(
            isinstance(s, DippingContact) for solids in make_family("strips", seed).geozones.values() for s in solids
        )
    ]
    assert 3 <= len(contacts) < len(TUNING_SEEDS)
    mine = make_family("strips", contacts[0])
    g = next(g for g, solids in mine.geozones.items() if isinstance(solids[0], DippingContact))
    for z in mine.bench_levels_m:
        pit = drilling.pit_outline(mine.extent_m, 0, 0.0)
        share = mine.section(g, float(z)).intersection(pit).area / pit.area
        assert 0.05 < share < 0.95  # a contact across the pit, not all or nothing


def test_widening_bodies_move_their_boundary_by_a_fixed_amount_per_bench():
    signs = set()
    for seed in TUNING_SEEDS[:8]:
        mine = make_family("widening", seed)
        for solids in mine.geozones.values():
            for body in solids:
                if not isinstance(body, GrowingBody):
                    continue
                signs.add(np.sign(body.growth_per_m))
                z0, z1 = body.z_ref_m, body.z_ref_m - 10.0
                a, b = body.section(z0), body.section(z1)
                if b.is_empty:
                    continue
                expected = abs(body.growth_per_m) * 10.0
                assert 3.0 - 1e-9 <= expected <= 15.0 + 1e-9  # half a hole spacing to several
                moved = shapely.affinity.translate(a, 10 * body.velocity[0], 10 * body.velocity[1])
                inner, outer = (moved, b) if body.growth_per_m > 0 else (b, moved)
                assert outer.hausdorff_distance(inner) == pytest.approx(expected, rel=0.02)
    assert signs == {-1.0, 1.0}


def test_folds_have_a_migrating_hinge_and_limbs_that_cross_the_pit():
    for seed in SEEDS:
        mine = make_family("folds", seed)
        layer = mine.geozones["g1"][0]
        assert isinstance(layer, DippingLayer)
        speed = float(np.hypot(*layer.velocity))
        assert speed * 10.0 >= 2.0
        levels = mine.bench_levels_m
        step = drilling.pit_step_m(mine.extent_m, len(levels), float(levels[0] - levels[1]))
        for k, z in enumerate(levels):
            pit = drilling.pit_outline(mine.extent_m, k, step)
            assert mine.section("g1", float(z)).intersection(pit).area > 12.0 * 100  # a long band, not a blob
            assert len(as_parts(pit.difference(layer.section(float(z))))) >= 2  # the limbs run across the pit


def test_splits_split_and_merges_merge():
    seen = {"split": 0, "merge": 0}
    for seed in SEEDS:
        mine = make_family("splits", seed)
        top, bottom = float(mine.bench_levels_m[0]), float(mine.bench_levels_m[-1])
        for g, solids in mine.geozones.items():
            if len(solids) != 2:
                continue
            n_top, n_bottom = len(as_parts(mine.section(g, top))), len(as_parts(mine.section(g, bottom)))
            assert (n_top, n_bottom) in ((1, 2), (2, 1)), (seed, g)
            seen["split" if n_top == 1 else "merge"] += 1
            if n_bottom == 2:
                a, b = as_parts(mine.section(g, bottom))
                assert a.distance(b) >= 12.0  # two rows of holes or more between the lobes
    assert seen["split"] >= len(SEEDS) and seen["merge"] >= len(SEEDS)


def test_pods_are_small_and_pinch_out_between_benches():
    drifting = 0
    for seed in SEEDS:
        mine = make_family("pods", seed)
        levels = mine.bench_levels_m
        for solids in mine.geozones.values():
            for pod in solids:
                assert isinstance(pod, Blob)
                assert 5.0 <= pod.radius_top_m <= 15.0
                widest = max(np.sqrt(max(pod.section(float(z)).area, 0) / np.pi) for z in levels)
                assert widest <= 15.0 * np.sqrt(1.8) * 1.3
                assert pod.z_to_m > levels[-1] - 40 and pod.section(pod.z_to_m - 0.1).is_empty
                drifting += np.hypot(*pod.velocity) >= 0.3
    assert drifting >= 1


def test_geozones_of_different_kinds_keep_apart():
    for family in FAMILIES:
        mine = make_family(family, SEEDS[0])
        for z in mine.bench_levels_m:
            regions = {g: mine.section(g, float(z)) for g in mine.geozones}
            names = sorted(regions)
            for i, a in enumerate(names):
                for b in names[i + 1 :]:
                    if regions[a].is_empty or regions[b].is_empty:
                        continue
                    # Layers built in contact share a boundary; all else keeps two rows of holes apart.
                    d = regions[a].distance(regions[b])
                    assert d == pytest.approx(0, abs=1e-6) or d >= families.GAP_M - 1e-6


# ---------------------------------------------------------------------------
# Solids and the mine


def test_any_object_with_a_section_is_a_solid():
    class Square:
        def section(self, z_m):
            return box(0, 0, 10, 10) if z_m > 50 else shapely.Polygon()

    disc = Blob((30.0, 0.0), (0.0, 0.0), 5.0, 0.0, 1.0, 0.0, (), 100.0)
    mine = SyntheticMine({"g1": [Square(), disc]}, (-50, -50, 50, 50), np.array([100.0, 40.0]))
    assert mine.section("g1", 100.0).area == pytest.approx(100.0 + np.pi * 25, rel=1e-3)
    assert mine.section("g1", 40.0).area == pytest.approx(np.pi * 25, rel=1e-3)
    assert mine.section(HOST, 100.0).area == pytest.approx(10_000 - mine.section("g1", 100.0).area)
    assert list(mine.label_at(np.array([[5.0, 5.0], [30.0, 0.0], [-40.0, 0.0]]), 100.0)) == ["g1", "g1", HOST]
    with pytest.raises(KeyError):
        mine.section("g9", 100.0)


def test_layers_on_either_side_of_one_trace_touch_exactly():
    trace = straight_or_bent_trace((0.0, 0.0), 0.4, 300.0, bend_m=10.0, wavelength_m=400.0)
    left = DippingLayer(trace, (0.3, -0.5), 100.0, 15.0, 0.0)
    right = DippingLayer(trace, (0.3, -0.5), 100.0, 0.0, 20.0)
    a, b = left.section(80.0), right.section(80.0)
    assert a.intersection(b).area < 1e-6
    both = DippingLayer(trace, (0.3, -0.5), 100.0, 15.0, 20.0).section(80.0)
    assert a.union(b).symmetric_difference(both).area < 1e-3 * both.area


def test_a_narrowing_body_pinches_out():
    body = GrowingBody(star_outline((0.0, 0.0), 20.0, 1.0, 0.0), 100.0, -1.0)
    assert body.section(90.0).area == pytest.approx(np.pi * 10**2, rel=0.01)
    assert body.section(75.0).is_empty


def test_a_hollow_body_is_a_ring_and_a_clipped_one_a_fault_block():
    ring = Hollow(
        GrowingBody(shapely.Point(0, 0).buffer(40.0, quad_segs=64), 100.0, 0.5),
        GrowingBody(shapely.Point(0, 0).buffer(15.0, quad_segs=64), 100.0, 0.0),
    )
    section = ring.section(80.0)  # outside 50 m, core 15 m
    assert section.area == pytest.approx(np.pi * (50.0**2 - 15.0**2), rel=0.01)
    assert len(shapely.get_parts(section)[0].interiors) == 1
    block = Clipped(ring, box(0, -100, 100, 100))
    assert block.section(80.0).area == pytest.approx(section.area / 2, rel=0.01)


def test_a_pivoting_contact_stands_still_at_its_pivot_and_turns_with_depth():
    contact = PivotingContact((10.0, -5.0), 0.0, np.radians(0.5), 100.0)
    top, below = contact.section(100.0), contact.section(80.0)  # 10 degrees apart
    assert top.contains(shapely.Point(11.0, 0.0)) and not top.contains(shapely.Point(9.0, 0.0))
    # 100 m along strike from the pivot the contact has moved 100 tan(10 deg) = 17.6 m across.
    assert below.boundary.distance(shapely.Point(10.0, 95.0)) == pytest.approx(100 * np.sin(np.radians(10)), rel=0.01)
    assert below.boundary.distance(shapely.Point(10.0, -5.0)) < 1e-6


@pytest.mark.parametrize("shape", SHAPES)
def test_every_shape_is_deterministic_valid_and_drilled(shape):
    mine, table, true = shape_scenario(shape, HELD_OUT_SEEDS[0])
    again = make_shape(shape, HELD_OUT_SEEDS[0])
    assert len(mine.geozones) == (2 if shape == "inclusion" else 1)
    for g in mine.geozones:
        for z in mine.bench_levels_m:
            region = mine.section(g, float(z))
            assert region.is_valid and region.area > 500.0, (shape, g, z)
            assert region.symmetric_difference(again.section(g, float(z))).area == 0.0
        assert (true == g).sum() > 20
    other = make_shape(shape, HELD_OUT_SEEDS[1])
    z = float(mine.bench_levels_m[3])
    assert mine.section("g1", z).symmetric_difference(other.section("g1", z)).area > 100.0


def test_shapes_have_their_defining_features():
    """A ring has a hole, a faulted strip two offset blocks, an inclusion's contact a pipe-shaped hole."""
    for seed in HELD_OUT_SEEDS[:3]:
        z = lambda mine: float(mine.bench_levels_m[3])  # noqa: E731
        ring = make_shape("ring", seed)
        assert any(p.interiors for p in shapely.get_parts(ring.section("g1", z(ring))))
        faulted = make_shape("faulted strip", seed)
        assert len(shapely.get_parts(faulted.section("g1", z(faulted)))) == 2
        inclusion = make_shape("inclusion", seed)
        pipe, zone = inclusion.section("g1", z(inclusion)), inclusion.section("g2", z(inclusion))
        assert pipe.intersection(zone).area < 1e-6 and zone.convex_hull.contains(pipe.centroid)
        body = make_shape("angular body", seed)
        square, top = body.geozones["g1"][0], float(body.bench_levels_m[0])
        moved = np.subtract(square.section(top - 10).centroid.coords[0], square.section(top).centroid.coords[0])
        assert np.hypot(*moved) == pytest.approx(10 * np.hypot(*square.velocity), rel=1e-6)


# ---------------------------------------------------------------------------
# Drilling


def test_true_labels_are_the_true_sections_at_the_holes():
    mine, table, true = scenario("mix", SEEDS[1])
    assert "true_geozone" not in table.columns and true.name == "true_geozone"
    assert list(true.index) == list(table["hole_id"]) and table["hole_id"].is_unique
    xy, bench = local_xy(mine, table), bench_of(table)
    for k, z in enumerate(mine.bench_levels_m):
        on = bench == k
        assert (mine.label_at(xy[on], float(z)) == true.to_numpy()[on]).all()
    # Mine-grid coordinates.
    assert 600_000 < table["x"].median() < 700_000 and 7_350_000 < table["y"].median() < 7_450_000


@pytest.mark.parametrize("family", FAMILIES)
def test_label_noise_is_1_to_3_percent_drawn_per_mine(family):
    rates = []
    for seed in SEEDS:
        _, table, true = scenario(family, seed)
        rate = true.attrs["label_noise"]
        assert 0.01 <= rate <= 0.03
        measured = float(np.mean(table["geozone"].to_numpy() != true.to_numpy()))
        # Flips need another geozone on the bench, which every bench here has.
        assert abs(measured - rate) <= 4 * np.sqrt(rate * (1 - rate) / len(table)) + 1e-3
        rates.append(rate)
    assert len(set(rates)) == len(rates)


def test_contact_noise_mislabels_holes_at_contacts_only_and_leaves_the_default_drilling_alone():
    _, default_table, _ = scenario("strips", SEEDS[0])
    mine, table, true = scenario(
        "strips", SEEDS[0], drilling={"label_noise_range": (0.0, 0.0), "contact_noise_range": (0.2, 0.2)}
    )
    _, again, _ = scenario("strips", SEEDS[0])
    assert again.equals(default_table)  # drawn only when asked
    labels, truth = table["geozone"].to_numpy(), true.to_numpy()
    wrong = labels != truth
    assert wrong.sum() > 50
    bench, xy = bench_of(table), local_xy(mine, table)
    for k in np.unique(bench):
        on = np.flatnonzero(bench == k)
        spacing = np.median(cKDTree(xy[on]).query(xy[on], k=2)[0][:, 1])
        for i in on[wrong[on]]:
            near = on[np.hypot(*(xy[on] - xy[i]).T) < drilling.CONTACT_SPACINGS * spacing * 1.2]
            assert labels[i] in set(truth[near])  # it took the label of a neighbour across the contact


def test_footprints_shrink_bench_by_bench_and_have_bites():
    mine, table, _ = scenario("folds", SEEDS[0])
    levels = mine.bench_levels_m
    step = drilling.pit_step_m(mine.extent_m, len(levels), float(levels[0] - levels[1]))
    assert step > 0
    pits = [drilling.pit_outline(mine.extent_m, k, step) for k in range(len(levels))]
    n_bites = 0
    for k, z in enumerate(levels):
        footprint = mine.footprints[float(z)]
        assert footprint.is_valid and footprint.geom_type == "Polygon"
        assert footprint.difference(pits[k]).area < 1e-6  # drilled inside its pit
        if k:
            assert pits[k].area < pits[k - 1].area and pits[k].difference(pits[k - 1]).area < 1e-6
        bites = as_parts(pits[k].difference(footprint))
        assert bites, k
        n_bites += len(bites)
        # Irregular notches, not only straight cuts: some bite has several corners off any straight line.
        assert max(len(b.exterior.coords) for b in bites) >= 6
    assert n_bites >= len(levels)
    xy, bench = local_xy(mine, table), bench_of(table)
    spacings = [np.median(cKDTree(xy[bench == k]).query(xy[bench == k], k=2)[0][:, 1]) for k in range(len(levels))]
    assert all(4.0 < s < 7.5 for s in spacings)
    assert np.ptp(spacings) > 0.1  # drawn per bench


def test_edge_bite_is_an_irregular_notch_on_the_edge():
    rng = np.random.default_rng(4)
    outline = drilling.pit_outline((-150, -120, 150, 120), 0, 0.0)
    for _ in range(20):
        bite = drilling.edge_bite(outline, rng)
        assert bite.is_valid and bite.area > 10
        assert 5 <= len(bite.exterior.coords) - 1 <= 9
        assert bite.intersects(outline.exterior)
        assert 0 < outline.intersection(bite).area < bite.area


def test_some_benches_are_partly_drilled():
    partial = 0
    for seed in SEEDS:
        mine, _, _ = scenario("strips", seed)
        levels = mine.bench_levels_m
        step = drilling.pit_step_m(mine.extent_m, len(levels), float(levels[0] - levels[1]))
        for k, z in enumerate(levels):
            pit = drilling.pit_outline(mine.extent_m, k, step)
            partial += mine.footprints[float(z)].area < 0.8 * pit.area
    assert partial >= 1


def test_bench_height_is_the_callers():
    mine, table, _ = scenario("splits", SEEDS[0], n_benches=5, bench_height_m=15.0)
    holes = read(table)
    assert holes.n_benches == 5
    assert holes.bench_height_m == pytest.approx(15.0, abs=0.5)
    assert np.diff(mine.bench_levels_m) == pytest.approx(-15.0)


def test_feet_scenarios_give_the_same_truth_through_the_frame():
    mine_m, table_m, true_m = scenario("folds", SEEDS[2])
    mine_ft, table_ft, true_ft = scenario("folds", SEEDS[2], units="ft")
    pd.testing.assert_series_equal(true_m, true_ft)
    assert np.allclose(table_ft[["x", "y", "z"]].to_numpy() * FEET_TO_METRES, table_m[["x", "y", "z"]], atol=0.01)
    holes_m, holes_ft = read(table_m), read(table_ft)
    assert holes_ft.frame.length_unit == "ft" and holes_m.frame.length_unit == "m"
    truth_m, truth_ft = truth_from_mine(mine_m, holes_m.frame), truth_from_mine(mine_ft, holes_ft.frame)
    # Both frames put the true sections where the holes of each geozone are.
    for holes, truth, true in ((holes_m, truth_m, true_m), (holes_ft, truth_ft, true_ft)):
        labels = true.reindex(holes.hole_id).to_numpy()
        for k in (0, holes.n_benches - 1):
            on = holes.on_bench(k)
            z = float(holes.bench_levels_m[k])
            for g in ("g1", "g2"):
                inside = shapely.contains_xy(truth(g, z), holes.xy[on, 0], holes.xy[on, 1])
                assert (inside == (labels[on] == g)).mean() > 0.999
    # And the same section, up to where each frame puts its origin.
    z = float(holes_m.bench_levels_m[3])
    shift = np.array([holes_m.frame.origin_x, holes_m.frame.origin_y]) - FEET_TO_METRES * np.array(
        [holes_ft.frame.origin_x, holes_ft.frame.origin_y]
    )
    moved = shapely.affinity.translate(truth_m("g1", z), *shift)
    assert moved.symmetric_difference(truth_ft("g1", z)).area < 1e-3 * moved.area


# ---------------------------------------------------------------------------
# Registry and truth sidecar


def test_held_out_and_tuning_seeds_are_disjoint():
    assert not set(HELD_OUT_SEEDS) & set(TUNING_SEEDS)
    assert len(HELD_OUT_SEEDS) >= 3 and len(TUNING_SEEDS) >= len(HELD_OUT_SEEDS)


def test_unknown_family_or_seed_is_refused():
    with pytest.raises(ValueError, match="unknown family"):
        scenario("blobs", 1)
    with pytest.raises(ValueError, match="seed"):
        scenario("pods", -1)


def test_scenario_truth_sidecar_gives_the_generators_truth(tmp_path):
    mine, table, true = scenario("widening", SEEDS[0])
    path = tmp_path / "widening.csv"
    table.to_csv(path, index=False)
    atomic_write_text(
        truth_sidecar(path),
        json.dumps({"generator": "core.synthetic.scenario", "family": "widening", "seed": SEEDS[0]}),
    )
    holes = read(pd.read_csv(path))
    truth = load_truth(path, holes)
    expected = truth_from_mine(mine, holes.frame)
    for z in holes.bench_levels_m[[0, -1]]:
        for g in mine.labels:
            assert truth(g, float(z)).symmetric_difference(expected(g, float(z))).area < 1e-6


def test_make_demo_data_writes_the_demo_by_default_and_a_family_on_request(tmp_path):
    from conftest import DEMO_CSV
    from test_cli import bgm

    demo = tmp_path / "demo.csv"
    bgm("make-demo-data", "--out", demo)
    assert demo.read_bytes() == DEMO_CSV.read_bytes()  # the bundled demo is unchanged
    assert json.loads(truth_sidecar(demo).read_text()) == {"generator": "core.synthetic.demo_dataset", "seed": 2019}
    path = tmp_path / "pods.csv"
    bgm("make-demo-data", "--family", "pods", "--seed", "3", "--out", path)
    spec = json.loads(truth_sidecar(path).read_text())
    assert spec == {"generator": "core.synthetic.scenario", "family": "pods", "seed": 3}
    written = pd.read_csv(path)
    _, table, _ = scenario("pods", 3)
    assert list(written.columns) == list(table.columns)
    assert (
        np.allclose(written[["x", "y", "z"]], table[["x", "y", "z"]]) and (written["geozone"] == table["geozone"]).all()
    )
    bad = bgm("make-demo-data", "--family", "blobs", "--out", tmp_path / "x.csv", check=False)
    assert bad.returncode == 2 and bad.stderr.strip().count("\n") == 0 and "unknown family" in bad.stderr


def test_make_demo_data_writes_a_shape_whose_truth_the_build_can_read(tmp_path):
    from clirun import bgm

    path = tmp_path / "ring.csv"
    assert bgm("make-demo-data", "--shape", "ring", "--seed", "3", "--out", path).returncode == 0
    assert json.loads(truth_sidecar(path).read_text()) == {
        "generator": "core.synthetic.shape_scenario",
        "shape": "ring",
        "seed": 3,
    }
    holes = read(pd.read_csv(path))
    mine, table, _ = shape_scenario("ring", 3)
    assert len(holes.xy) == len(table)
    truth, expected = load_truth(path, holes), truth_from_mine(mine, holes.frame)
    z = float(holes.bench_levels_m[2])
    assert truth("g1", z).area > 0 and truth("g1", z).symmetric_difference(expected("g1", z)).area < 1e-6
    both = bgm("make-demo-data", "--shape", "ring", "--family", "pods", "--out", tmp_path / "x.csv")
    assert both.returncode == 2 and "not both" in both.stderr
    bad = bgm("make-demo-data", "--shape", "blob", "--out", tmp_path / "x.csv")
    assert bad.returncode == 2 and bad.stderr.strip().count("\n") == 0 and "unknown shape" in bad.stderr


def test_make_demo_data_without_out_writes_in_the_working_folder_and_never_over_the_bundled_demo(tmp_path, monkeypatch):
    from clirun import bgm as bgm_here
    from conftest import DEMO_CSV

    shipped = DEMO_CSV.read_bytes(), truth_sidecar(DEMO_CSV).read_bytes()
    monkeypatch.chdir(tmp_path)
    assert bgm_here("make-demo-data", "--family", "pods", "--seed", "3").returncode == 0
    assert bgm_here("make-demo-data", "--shape", "faulted strip", "--seed", "2").returncode == 0
    assert bgm_here("make-demo-data").returncode == 0
    assert (DEMO_CSV.read_bytes(), truth_sidecar(DEMO_CSV).read_bytes()) == shipped
    written = sorted(p.name for p in tmp_path.glob("*.csv"))
    assert written == ["demo_blastholes.csv", "faulted_strip_2.csv", "pods_3.csv"], written
    assert (tmp_path / "demo_blastholes.csv").read_bytes() == shipped[0]
    spec = json.loads(truth_sidecar(tmp_path / "pods_3.csv").read_text())
    assert spec == {"generator": "core.synthetic.scenario", "family": "pods", "seed": 3}
