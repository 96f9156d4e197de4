"""The extrapolation below the deepest bench on exact sections: what it loses with no holes at all.

    python tests/benchmarks/bench_exact_fields.py

Each case is a known section on five benches 10 m apart (a disc, an ellipse, a
ring, folds and a wedge, moving, growing, shrinking or elongating steadily),
given to :func:`core.model.extrapolation.depth_trend` as its exact signed
distances on a 3 m grid, with no holes, contours or drilling frontier in
between. The predicted section 5, 10 and 20 m below the deepest bench is
scored against the true one (F1 in percent, and its area as a share of the
true area). Whatever falls short of 100 here is the extrapolation's own; the
rest of the gap to perfect in ``bench_prediction.py`` is the contours', placed
between holes.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString, Point

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.geometry.grid import Grid  # noqa: E402
from core.geometry.sdf import region_signed_distance  # noqa: E402
from core.model.extrapolation import depth_trend  # noqa: E402
from core.model.fields import BenchFields  # noqa: E402

CELL_M = 3.0
CELLS = 140
BENCHES = 5
BENCH_HEIGHT_M = 10.0
HOLE_SPACING_M = 6.0  # sets the transport's neighbourhood and the cap, as a 6 m pattern would
CAP_M = 48.0
DEPTHS_M = (5.0, 10.0, 20.0)

_X = np.linspace(-50.0, 470.0, 300)


def _fold(offset_m: float, along_m: float, amplitude_m: float, wavelength_m: float, width_m: float):
    y = 210.0 + offset_m + amplitude_m * np.sin(2 * np.pi * (_X - along_m) / wavelength_m)
    return LineString(np.column_stack([_X, y])).buffer(width_m / 2, cap_style="flat")


#: Section of each case on bench ``k`` (fractional ``k`` between and below the benches).
CASES: dict[str, Callable[[float], shapely.Geometry]] = {
    "disc 25 m moving 10 m a bench": lambda k: Point(150 + 10 * k, 210).buffer(25),
    "disc 15 m moving 6 m a bench": lambda k: Point(150 + 6 * k, 210).buffer(15),
    "ellipse moving 8.5 m a bench diagonally": lambda k: affinity.rotate(
        affinity.scale(Point(150 + 6 * k, 150 + 6 * k).buffer(20), 2.0, 1.0), 30
    ),
    "ring moving 6 m a bench": lambda k: (
        Point(150 + 6 * k, 210).buffer(40).difference(Point(150 + 6 * k, 210).buffer(20))
    ),
    "disc growing 4 m a bench": lambda k: Point(210, 210).buffer(20 + 4 * k),
    "disc shrinking 4 m a bench": lambda k: Point(210, 210).buffer(50 - 4 * k),
    "ellipse elongating": lambda k: affinity.scale(Point(210, 210).buffer(20), 1 + 0.15 * k, 1.0),
    "fold moving 8 m a bench across": lambda k: _fold(8 * k, 0.0, 40, 200, 30),
    "fold moving 8 m a bench along its axis": lambda k: _fold(0.0, 8 * k, 40, 200, 30),
    "tight fold moving 6 m a bench along": lambda k: _fold(0.0, 6 * k, 50, 120, 24),
    "wedge thinning 8 m a bench": lambda k: shapely.Polygon(
        [(100, 150), (330, 150 + 4 * k), (330, 270 - 4 * k), (100, 270)]
    ),
}


def signed_distance(section, grid: Grid) -> np.ndarray:
    """Exact signed distance to ``section``'s boundary (positive inside) on ``grid``, capped."""
    return np.clip(region_signed_distance(grid, section, band_cells=np.inf), -CAP_M, CAP_M)


def score(section_at: Callable[[float], shapely.Geometry]) -> list[tuple[float, float, float]]:
    """``(depth_m, F1 %, predicted / true area)`` below the deepest of :data:`BENCHES` exact benches."""
    grid = Grid.covering((0, 0, CELLS * CELL_M, CELLS * CELL_M), CELL_M, margin_cells=0)
    x = grid.cell_centres()[0]
    z = 500.0 - BENCH_HEIGHT_M * np.arange(BENCHES)
    distance = np.array([signed_distance(section_at(k), grid) for k in range(BENCHES)])
    fields = BenchFields(grid, z, distance, np.ones_like(distance), np.ones(distance.shape, bool))
    trend = depth_trend(fields, BENCH_HEIGHT_M, HOLE_SPACING_M)
    scored = (x > 30) & (x < CELLS * CELL_M - 30)  # away from the grid's edge, where the folds are cut
    rows = []
    for depth in DEPTHS_M:
        predicted = (trend.field(z[-1] - depth) > 0) & scored
        truth = (signed_distance(section_at(BENCHES - 1 + depth / BENCH_HEIGHT_M), grid) > 0) & scored
        both = float(np.sum(predicted & truth))
        f1 = 200 * both / (predicted.sum() + truth.sum())
        rows.append((depth, f1, predicted.sum() / truth.sum()))
    return rows


def main() -> None:
    start = time.perf_counter()
    header = "".join(f"  {d:>4.0f} m F1 (area)" for d in DEPTHS_M)
    print(f"{'case':42s}{header}")
    for name, section_at in CASES.items():
        cells = "".join(f"  {f1:6.1f} ({area:5.3f})" for _, f1, area in score(section_at))
        print(f"{name:42s}{cells}")
    print(f"\nWall time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
