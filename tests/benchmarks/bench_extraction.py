"""Benchmark of boundary extraction (prints figures; not a timed test).

    python tests/benchmarks/bench_extraction.py [--seeds held-out|tuning] [--limit N] [--workers 2]
        [--drilling "label noise 6-10%"]

* every synthetic family of :mod:`core.synthetic.scenarios` at the held-out
  seeds (the only ones reported; ``--seeds tuning`` runs the tuning seeds
  instead), through the real pipeline (``extract_contours``, then
  ``model_geozone`` for the morphs), scored by :mod:`core.model.scoring`
  for every non-host geozone and bench:

  - median bench IoU of the geozone's contours against its true section, both
    clipped to the bench's drilled footprint (target >= 0.90);
  - median share of the geozone's true holes inside its contours (>= 95%);
  - median share of the holes inside its contours whose true label is
    another geozone (<= 5%);
  - min and median target-boundary coverage over bench pairs (min >= 0.99);

* ``--drilling``: the same families drilled one of the other ways of
  ``bench_robustness.DRILLING`` (9-12 m or 3-4 m patterns, 6-10% label noise,
  ...) instead of the default;
* the same on the real Kennecott benches (``BGM_KENNECOTT`` or
  ../shared/data), where the file's labels stand in for the true labels and
  there is no IoU, and the containment summary of the bundled demo;
* the GVF on a 256 x 256 grid: sparse steady-state solve against 200
  explicit iterations, with how far from steady state each ends.

Scenarios run in parallel on ``--workers`` processes; the wall time is printed.
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_robustness import DRILLING  # noqa: E402
from kennecott_data import KENNECOTT  # noqa: E402

from core.extraction.contours import extract_contours  # noqa: E402
from core.extraction.gvf import gvf_explicit, gvf_residual, gvf_steady_state  # noqa: E402
from core.io.blastholes import BGMWarning, blastholes_from_table, read_blastholes  # noqa: E402
from core.io.reporting import containment_summary  # noqa: E402
from core.model.evaluation import truth_from_mine  # noqa: E402
from core.model.pipeline import ModelParameters, model_geozone  # noqa: E402
from core.model.scoring import (  # noqa: E402
    coverage_by_pair,
    coverage_summary,
    extraction_scores,
    labels_by_hole,
)
from core.synthetic.blobs import HOST  # noqa: E402
from core.synthetic.scenarios import FAMILIES, HELD_OUT_SEEDS, TUNING_SEEDS, scenario  # noqa: E402


def bench_file(path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        holes = read_blastholes(path)
        t1 = time.perf_counter()
        contours = extract_contours(holes)
        t2 = time.perf_counter()
    s = containment_summary(contours, holes)
    print(
        f"{path.name}: {len(holes.xy)} holes, {holes.n_benches} benches, {len(holes.geozones)} geozones -> "
        f"{len(contours)} contours; read {t1 - t0:.2f} s, extraction {t2 - t1:.2f} s"
    )
    print(
        f"  contours >= 15 holes: {s['contours']}, holes inside median {s['holes_inside_median']:.3f} "
        f"(min {s['holes_inside_min']:.3f}, {s['contours_with_95pct_inside']:.0%} at >= 95%), other-geozone holes "
        f"inside median {s['other_holes_inside_median']:.3f} ({s['contours_with_at_most_5pct_other']:.0%} at <= 5%)"
    )


def bench_gvf(size: int = 256) -> None:
    yy, xx = np.mgrid[:size, :size]
    r = np.hypot(xx - size / 2, yy - size / 2)
    theta = np.arctan2(yy - size / 2, xx - size / 2)
    outline = 80 + 25 * np.cos(3 * theta)  # a concave three-lobed shape
    f = ndimage.gaussian_filter((np.abs(r - outline) < 0.8).astype(float), 1.5)
    f /= f.max()
    t0 = time.perf_counter()
    steady = gvf_steady_state(f, 0.2)
    t1 = time.perf_counter()
    explicit = gvf_explicit(f, 0.2, iterations=200)
    t2 = time.perf_counter()
    print(f"GVF {size}x{size}: sparse steady-state solve {t1 - t0:.3f} s, residual {gvf_residual(f, steady):.1e}")
    print(f"GVF {size}x{size}: 200 explicit iterations   {t2 - t1:.3f} s, residual {gvf_residual(f, explicit):.1e}")
    centre = (size // 2, size // 2)
    print(
        "  field magnitude at the shape's centre: steady "
        f"{np.hypot(*steady[:, centre[0], centre[1]]):.2e}, explicit {np.hypot(*explicit[:, centre[0], centre[1]]):.2e}"
    )


def score_holes(holes, labels, geozones, truth=None, footprint=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Extraction scores per (geozone, bench) and coverage per (geozone, bench pair), with the real pipeline."""
    params = ModelParameters()
    contours = extract_contours(holes, params=params.extraction)
    scores = extraction_scores(holes, contours, labels, truth, footprint, geozones=geozones)
    models = [model_geozone(holes, g, contours=contours, params=params) for g in geozones]
    return scores, coverage_by_pair(models)


def run_job(job: tuple[str, int, str]) -> tuple[str, int, pd.DataFrame, pd.DataFrame, float]:
    """Score one scenario drilled one way (or Kennecott, ``("kennecott", 0, "")``); returns its tables and CPU seconds."""
    family, seed, drilling = job
    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        if family == "kennecott":
            holes = read_blastholes(KENNECOTT)
            scores, coverage = score_holes(holes, holes.geozone, holes.geozones)
        else:
            mine_args, drill_args = DRILLING.get(drilling, ({}, {}))
            mine, table, true_labels = scenario(family, seed, drilling=drill_args, **mine_args)
            holes = blastholes_from_table(table, source=f"{family} {seed}")
            geozones = [g for g in mine.labels if g != HOST]

            def footprint(k: int):
                return mine.footprint_in(holes.frame, float(holes.bench_levels_m[k]))

            scores, coverage = score_holes(
                holes, labels_by_hole(holes, true_labels), geozones, truth_from_mine(mine, holes.frame), footprint
            )
    for df in (scores, coverage):
        df.insert(0, "kind", "real" if family == "kennecott" else df["geozone"].map(mine.kinds))
        df.insert(0, "seed", seed)
        df.insert(0, "family", family)
    return family, seed, scores, coverage, time.process_time() - start


def summary_row(name: str, scores: pd.DataFrame, coverage: pd.DataFrame) -> dict:
    iou = scores["iou"].dropna()
    own = scores.loc[scores["own_holes"] > 0, "own_inside"]
    other = scores.loc[scores["holes_inside"] > 0, "other_inside"]
    cov_min, cov_median = coverage_summary(coverage["coverage"])
    return {
        "": name,
        "cells": len(scores),
        "IoU med": round(float(iou.median()), 3) if len(iou) else np.nan,
        "IoU p10": round(float(iou.quantile(0.1)), 3) if len(iou) else np.nan,
        "own in med": round(float(own.median()), 3),
        "other in med": round(float(other.median()), 3),
        "other in p90": round(float(other.quantile(0.9)), 3),
        "pairs": len(coverage),
        "cov min": round(cov_min, 3),
        "cov med": round(cov_median, 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", choices=("held-out", "tuning"), default="held-out")
    parser.add_argument("--limit", type=int, default=None, help="Seeds per family (default: as many as held out).")
    parser.add_argument("--families", nargs="*", default=list(FAMILIES), choices=FAMILIES)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-kennecott", action="store_true")
    parser.add_argument("--save", type=Path, default=None, help="Also write every row scored to this CSV.")
    parser.add_argument("--drilling", choices=list(DRILLING), default=None, help="Drill the families this way.")
    args = parser.parse_args()

    bench_gvf()
    bench_file(ROOT / "assets" / "demo_blastholes.csv")

    seeds = list(HELD_OUT_SEEDS if args.seeds == "held-out" else TUNING_SEEDS)[: args.limit or len(HELD_OUT_SEEDS)]
    jobs = [(f, s, args.drilling or "") for f in args.families for s in seeds]
    if not args.no_kennecott and KENNECOTT.exists():
        jobs.insert(0, ("kennecott", 0, ""))  # the longest job first, so it is not the tail
    drilled = f", drilled: {args.drilling}" if args.drilling else ""
    print(f"\nExtraction on {args.seeds} seeds {seeds}{drilled}: {len(jobs)} jobs on {args.workers} processes")
    start = time.perf_counter()
    results = []
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        for family, seed, scores, coverage, cpu in pool.imap_unordered(run_job, jobs):
            print(
                f"  {family} {seed}: {len(scores)} geozone-benches, {len(coverage)} pairs, {cpu:.0f} s CPU", flush=True
            )
            results.append((family, scores, coverage))
    wall = time.perf_counter() - start

    synthetic = [r for r in results if r[0] != "kennecott"]
    scores = pd.concat([s for _, s, _ in synthetic], ignore_index=True)
    coverage = pd.concat([c for _, _, c in synthetic], ignore_index=True)
    rows = [summary_row(f, scores[scores["family"] == f], coverage[coverage["family"] == f]) for f in args.families]
    rows.append(summary_row("all families", scores, coverage))
    if args.save:
        pd.concat([s for _, s, _ in results], ignore_index=True).to_csv(args.save, index=False)
        coverage_path = args.save.with_name(args.save.stem + "_coverage.csv")
        pd.concat([c for _, _, c in results], ignore_index=True).to_csv(coverage_path, index=False)
    kennecott = [r for r in results if r[0] == "kennecott"]
    if kennecott:
        rows.append(summary_row("Kennecott (file labels)", kennecott[0][1], kennecott[0][2]))
    elif not args.no_kennecott:
        print(f"Kennecott data not found at {KENNECOTT}; skipped")
    print(
        "\nPer (non-host geozone, bench): IoU vs the true section in the drilled footprint (target >= 0.90), share of "
        "own true holes inside (>= 0.95), share of holes inside that are another geozone's (<= 0.05); per bench "
        "pair: target-boundary coverage after backtracking (min >= 0.99)."
    )
    print(pd.DataFrame(rows).to_string(index=False))
    print("\nPer kind of geozone, all families:")
    kinds = [
        summary_row(k, scores[scores["kind"] == k], coverage[coverage["kind"] == k])
        for k in sorted(set(scores["kind"]))
    ]
    print(pd.DataFrame(kinds).to_string(index=False))
    print(f"\nWall time {wall:.0f} s on {args.workers} processes")


if __name__ == "__main__":
    main()
