"""Benchmark of core.correspondence.pair.correspond_pair on typical synthetic bench pairs.

Run: ``python tests/benchmarks/bench_correspondence.py [--repeats N] [--profile]``.
Prints the median wall time per bench pair (target: < 0.2 s per pair).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from shapely import affinity
from shapely.geometry import Point, Polygon

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from core.correspondence.pair import correspond_pair

HOLE_SPACING_M = 6.0


def blob(cx: float, cy: float, ax: float, ay: float, rng: np.random.Generator) -> Polygon:
    """A ``2ax x 2ay`` m ellipse with a random low-order wobble of its radius."""
    th = np.linspace(0, 2 * np.pi, 160, endpoint=False)
    r = 1 + sum(rng.uniform(-0.08, 0.08) * np.cos(k * th + rng.uniform(0, 6.3)) for k in (2, 3, 4))
    return Polygon(np.column_stack([cx + ax * r * np.cos(th), cy + ay * r * np.sin(th)]))


def pairs(rng: np.random.Generator) -> dict[str, tuple[list[Polygon], list[Polygon]]]:
    """Bench pairs of 100 x 60 m components, three per bench unless noted."""
    out = {}
    # 3 x one-to-one, each drifting by a few metres.
    srcs = [blob(x, y, 50, 30, rng) for x, y in [(0, 0), (150, 40), (60, 140)]]
    tgts = [affinity.translate(s, *rng.uniform(-8, 8, 2)) for s in srcs]
    out["3x one-to-one"] = (srcs, tgts)
    # merge (2 -> 1) + one-to-one + new pod.
    s0, s1 = blob(-52, 0, 50, 30, rng), blob(52, 5, 50, 30, rng)
    s2 = blob(40, 130, 50, 30, rng)
    merged = affinity.translate(s0.union(s1).buffer(5).buffer(-5), 6, -4)
    out["merge + 1:1 + pod"] = (
        [s0, s1, s2],
        [merged, affinity.translate(s2, -5, 3), Point(220, -90).buffer(12)],
    )
    # split (1 -> 2) + two one-to-one.
    big = blob(0, 0, 90, 30, rng)
    t0, t1 = blob(-45, 4, 40, 26, rng), blob(48, 4, 40, 26, rng)
    a, b = blob(0, 120, 50, 30, rng), blob(170, 60, 50, 30, rng)
    out["split + 2x 1:1"] = ([big, a, b], [t0, t1, affinity.translate(a, 4, 4), affinity.translate(b, -6, 2)])
    # many-to-many: s0+s1 -> t0, s1+s2 -> t1 (chain).
    s = [blob(x, 0, 50, 30, rng) for x in (-110, 0, 110)]
    t = [blob(-55, 6, 100, 32, rng), blob(60, 6, 90, 32, rng)]
    out["many-to-many 3->2"] = (s, t)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    rng = np.random.default_rng(42)
    cases = pairs(rng)
    correspond_pair(*cases["3x one-to-one"], hole_spacing_m=HOLE_SPACING_M)  # warm-up
    times = []
    for name, (srcs, tgts) in cases.items():
        runs = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            res = correspond_pair(srcs, tgts, hole_spacing_m=HOLE_SPACING_M)
            runs.append(time.perf_counter() - t0)
        med = statistics.median(runs)
        times.append(med)
        print(
            f"{name:22s} {len(srcs)}x{len(tgts)}  grid {res.grid.shape[0]}x{res.grid.shape[1]} "
            f"cell {res.cell_size_m:.2f} m  {med * 1000:7.1f} ms/pair  instances "
            f"{[(m.target_ids, m.source_ids) for m in res.instances]}"
        )
    print(f"mean {statistics.mean(times) * 1000:.1f} ms/pair, worst {max(times) * 1000:.1f} ms/pair (target < 200 ms)")
    if args.profile:
        prof = cProfile.Profile()
        prof.enable()
        for srcs, tgts in cases.values():
            correspond_pair(srcs, tgts, hole_spacing_m=HOLE_SPACING_M)
        prof.disable()
        pstats.Stats(prof).sort_stats("cumulative").print_stats(20)


if __name__ == "__main__":
    main()
