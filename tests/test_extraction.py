"""Boundary extraction (paper section 2): each step tested for the property it exists for."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from conftest import component_truth, iou, synthetic
from scipy import ndimage

from core.extraction.boundary import (
    connected_components,
    entropy_boundary,
    gap_boundary,
    local_entropy,
    neighbour_table,
)
from core.extraction.contours import ExtractionParameters, extract_contours, snake_contour
from core.extraction.edgemap import edge_structure, synthesize_edge_map
from core.extraction.gvf import gvf_explicit, gvf_residual, gvf_steady_state
from core.extraction.snake import box_snake, evolve_snake
from core.geometry.grid import Grid
from core.io.reporting import containment


def hex_grid(nx: int, ny: int, spacing: float = 6.0) -> np.ndarray:
    rows = np.arange(ny) * spacing * np.sqrt(3) / 2
    pts = [(i * spacing + (j % 2) * spacing / 2, y) for j, y in enumerate(rows) for i in range(nx)]
    return np.array(pts, dtype=float)


def test_components_are_separated_clusters_ordered_by_size():
    a = hex_grid(8, 8)
    b = hex_grid(3, 3) + [200.0, 0.0]
    labels = connected_components(np.vstack([b, a]), search_radius_m=9.0)
    assert labels.max() == 1
    assert set(labels[len(b) :]) == {0}  # the larger cluster is component 0
    assert set(labels[: len(b)]) == {1}


def test_entropy_marks_holes_along_the_geozone_transition_only():
    xy = hex_grid(20, 20)
    labels = np.where(xy[:, 0] < 60.0, "a", "b")
    table = neighbour_table(xy, 1.6 * 6.0)
    h = local_entropy(labels, table)
    on = entropy_boundary(h, table, 0.5)
    distance_to_transition = np.abs(xy[:, 0] - 60.0)
    assert on.any()
    assert distance_to_transition[on].max() <= 1.6 * 6.0
    # Every hole right at the transition is found.
    assert on[distance_to_transition < 3.0].all()


def test_gap_closure_marks_the_frontier_of_a_patch():
    xy = hex_grid(12, 12)
    on, outward = gap_boundary(xy, 2 * np.pi / 3, 12, search_radius_m=25.0)
    hull = shapely.MultiPoint(xy).convex_hull
    d = np.array([hull.exterior.distance(shapely.Point(p)) for p in xy])
    assert on[d < 1.0].mean() > 0.95
    assert not on[d > 8.0].any()
    # Outward directions point away from the patch centre.
    centre = xy.mean(axis=0)
    radial = xy[on] - centre
    assert np.mean(np.sum(radial * outward[on], axis=1) > 0) > 0.95


def _circle_edge_map(radius_cells: float = 40.0, size: int = 128):
    yy, xx = np.mgrid[:size, :size]
    r = np.hypot(xx - size / 2, yy - size / 2)
    f = ndimage.gaussian_filter((np.abs(r - radius_cells) < 0.7).astype(float), 1.5)
    return f / f.max()


def test_gvf_sparse_solve_reaches_steady_state_explicit_does_not():
    f = _circle_edge_map()
    steady = gvf_steady_state(f, mu=0.2)
    explicit = gvf_explicit(f, mu=0.2, iterations=200)
    r_steady = gvf_residual(f, steady, 0.2)
    r_explicit = gvf_residual(f, explicit, 0.2)
    assert r_steady < 1e-6
    assert r_explicit > 100 * r_steady
    # At the centre the field is defined (steady state reaches into the interior).
    c = f.shape[0] // 2
    assert np.hypot(*steady[:, c + 20, c]) > 0


def test_snake_converges_onto_a_circle_from_its_bounding_box():
    f = _circle_edge_map(40.0)
    field = gvf_steady_state(f, 0.2)
    c = f.shape[0] / 2
    snake, _, _ = evolve_snake(box_snake(np.array([c - 50, c - 50]), np.array([c + 50, c + 50]), 160), field)
    r = np.hypot(snake[:, 0] - c, snake[:, 1] - c)
    assert np.abs(r - 40.0).max() < 1.5


def test_snake_contour_hugs_a_concave_outline():
    # L-shaped component of holes: the contour must follow the inner corner.
    xy = hex_grid(14, 14)
    keep = ~((xy[:, 0] > 45) & (xy[:, 1] > 40))
    holes = xy[keep]
    on, outward = gap_boundary(holes, 2 * np.pi / 3, 12, 25.0)
    points = holes[on] + 3.0 * outward[on]
    poly, fields = snake_contour(points, 6.0, ExtractionParameters(), keep_fields=True, component_xy_m=holes)
    assert poly.is_valid
    assert shapely.contains_xy(poly, holes[:, 0], holes[:, 1]).mean() >= 0.95
    truth = shapely.MultiPoint(holes).buffer(3.0).buffer(3.0).buffer(-3.0)
    assert iou(poly, truth) > 0.9
    assert fields.snake_history_m and fields.gvf.shape[0] == 2


@pytest.mark.parametrize("seed", [101, 202])
def test_contours_match_the_true_sections_on_fresh_mines(seed):
    mine, _, holes = synthetic(seed)
    contours = extract_contours(holes)
    big = [c for c in contours if len(c.holes) >= 15]
    assert big
    scores = []
    for c in big:
        assert c.polygon.is_valid and not c.polygon.is_empty
        truth, footprint = component_truth(mine, holes, c)
        scores.append(iou(c.polygon.intersection(footprint), truth))
        stats = containment(c, holes)
        assert stats["holes_inside"] >= 0.95, (c.geozone, c.bench, c.component, stats)
        assert stats["other_holes_inside"] <= 0.05, (c.geozone, c.bench, c.component, stats)
    assert np.median(scores) >= 0.90, sorted(scores)


def test_keep_fields_returns_what_the_viewer_draws():
    _, _, holes = synthetic(7, n_benches=3)
    contours = extract_contours(holes, ["g1"], benches=[0], keep_fields=True)
    c = max(contours, key=lambda c: len(c.holes))
    f = c.fields
    assert f is not None
    assert f.edge_map.shape == f.grid.shape and f.edge_map.min() >= 0 and f.edge_map.max() <= 1
    assert f.gvf.shape == (2, *f.grid.shape)
    assert len(f.snake_history_m) >= 2
    assert len(c.entropy_holes) + len(c.gap_holes) > 0
    # The first snake is the bounding box of the edge structure, the last the contour.
    first = shapely.Polygon(f.snake_history_m[0])
    assert first.contains(c.polygon.buffer(-1.0))


def test_edge_structure_links_neighbouring_boundary_points_only():
    pts = np.array([[0, 0], [5, 0], [10, 0], [100, 0]], dtype=float)
    edges = edge_structure(pts, max_edge_m=12.0, edge_neighbours=5, edge_joints=1, max_joint_m=20.0)
    assert {tuple(e) for e in edges} == {(0, 1), (0, 2), (1, 2)}
    grid = Grid.covering((0, -5, 10, 5), 0.5, 4)
    f = synthesize_edge_map(grid, pts[:3], edges)
    assert f.max() == pytest.approx(1.0)
    row = int(round(grid.xy_to_rc(np.array([[5.0, 0.0]]))[0, 0]))
    assert f[row].max() > 0.5 and f[0].max() < 0.05
