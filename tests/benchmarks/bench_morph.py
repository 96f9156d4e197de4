"""Time one contour morph (level set + trajectories + backtracking) on a 256 x 256 grid.

Run: ``.venv/bin/python tests/benchmarks/bench_morph.py [--profile]``.
Target: under 0.5 s per instance. Prints, per instance, the grid shape, the
number of level-set steps and trajectories, coverage before/after
backtracking, and the best / median wall time of a few repeats.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import time

from shapely import affinity
from shapely.geometry import Point, Polygon, box
from shapely.ops import unary_union

from core.morph.levelset import morph_regions


def ellipse(cx, cy, rx, ry):
    return affinity.scale(Point(cx, cy).buffer(1.0, quad_segs=32), rx, ry)


INSTANCES = {
    "translated disc": (Point(0, 0).buffer(30), Point(4, 3).buffer(30)),
    "scaled disc": (Point(0, 0).buffer(20), Point(0, 0).buffer(35)),
    "merge 2 discs -> ellipse": ([Point(-25, 0).buffer(18), Point(25, 0).buffer(18)], ellipse(0, 0, 48, 22)),
    "split ellipse -> 2 discs": (ellipse(0, 0, 48, 22), [Point(-25, 0).buffer(18), Point(25, 0).buffer(18)]),
    "branching disc -> cross": (Point(0, 0).buffer(12), unary_union([box(-60, -4, 60, 4), box(-4, -60, 4, 60)])),
    "pod appearing": ([], ellipse(0, 0, 40, 30)),
    "pod beside the source": (Point(-30, 0).buffer(15), [Point(-28, 0).buffer(15), Point(30, 0).buffer(10)]),
    "host pod appearing inside": (Point(0, 0).buffer(35), Point(0, 0).buffer(35).difference(Point(5, 0).buffer(10))),
    "C shape from a disc": (
        Point(10, 0).buffer(25),
        Point(0, 0).buffer(40).difference(Point(0, 0).buffer(20)).difference(Polygon([(0, 0), (60, -25), (60, 25)])),
    ),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--profile", action="store_true", help="cProfile the branching instance")
    args = parser.parse_args()
    morph_regions(*INSTANCES["translated disc"], max_cells=64)  # warm-up (imports, caches)
    print(
        f"{'instance':28s} {'grid':>10s} {'steps':>5s} {'traj':>5s} {'cov0':>6s} {'cov':>6s} {'iou':>6s} {'best s':>7s} {'median s':>8s} {'best cpu':>8s}"
    )
    for name, (src, tgt) in INSTANCES.items():
        times, cpu = [], []
        for _ in range(args.repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            res = morph_regions(src, tgt, max_cells=256)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        shape = "x".join(map(str, res.grid.shape))
        print(
            f"{name:28s} {shape:>10s} {res.n_steps:5d} {len(res.trajectories):5d} "
            f"{res.coverage_before_backtracking:6.3f} {res.target_boundary_coverage:6.3f} {res.iou:6.4f} "
            f"{min(times):7.3f} {statistics.median(times):8.3f} {min(cpu):8.3f}"
        )
    if args.profile:
        src, tgt = INSTANCES["branching disc -> cross"]
        prof = cProfile.Profile()
        prof.enable()
        morph_regions(src, tgt)
        prof.disable()
        pstats.Stats(prof).sort_stats("cumulative").print_stats(20)


if __name__ == "__main__":
    main()
