"""Correspondence and metamorphosis over whole files: time per bench pair and coverage.

    python tests/benchmarks/bench_pipeline.py

For every geozone and bench pair of the demo and (when present) the Kennecott
file: the time of correspondence and of the morph per pair, and the
distribution of target-boundary coverage before and after curvelet
backtracking over all morph instances. Targets: < 0.2 s per typical pair for
correspondence; < 0.5 s per morph instance.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from kennecott_data import KENNECOTT  # noqa: E402

from core.extraction.contours import extract_contours  # noqa: E402
from core.io.blastholes import read_blastholes  # noqa: E402
from core.model.pipeline import ModelParameters, bench_pairs, correspond, morph  # noqa: E402


def run(path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        holes = read_blastholes(path)
        contours = extract_contours(holes)
    params = ModelParameters()
    t_corr, t_morph, n_instances = [], [], 0
    before, after = [], []
    for g in holes.geozones:
        for pair in bench_pairs(holes, contours, g, params.min_component_holes):
            t0 = time.perf_counter()
            correspond(pair, holes, params)
            t1 = time.perf_counter()
            morph(pair, params, hole_spacing_m=holes.hole_spacing_m)
            t2 = time.perf_counter()
            t_corr.append(t1 - t0)
            t_morph.append(t2 - t1)
            for step in pair.morphs:
                n_instances += 1
                if step.instance.source_ids and step.instance.target_ids:
                    before.append(step.result.coverage_before_backtracking)
                    after.append(step.result.target_boundary_coverage)

    def q(a):
        return " / ".join(f"{v:.3f}" for v in np.percentile(a, [5, 25, 50, 75, 95]))

    print(f"{path.name}: {len(t_corr)} bench pairs over {len(holes.geozones)} geozones, {n_instances} morph instances")
    print(
        f"  correspondence per pair: median {np.median(t_corr):.3f} s, 90th pct {np.percentile(t_corr, 90):.3f} s, total {sum(t_corr):.1f} s"
    )
    print(
        f"  morph per pair:          median {np.median(t_morph):.3f} s, 90th pct {np.percentile(t_morph, 90):.3f} s, "
        f"total {sum(t_morph):.1f} s ({sum(t_morph) / max(n_instances, 1):.3f} s per instance)"
    )
    print(f"  coverage before backtracking (5/25/50/75/95 pct): {q(before)}")
    print(
        f"  coverage after backtracking  (5/25/50/75/95 pct): {q(after)}  "
        f"({np.mean(np.array(after) >= 0.99):.0%} of instances at >= 0.99)"
    )


if __name__ == "__main__":
    run(ROOT / "assets" / "demo_blastholes.csv")
    if KENNECOTT.exists():
        run(KENNECOTT)
    else:
        print(f"Kennecott data not found at {KENNECOTT}; skipped")
