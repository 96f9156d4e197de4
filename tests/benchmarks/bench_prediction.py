"""Predictive value of the model against the references, on every synthetic family and on Kennecott.

    python tests/benchmarks/bench_prediction.py [--seeds held-out|tuning] [--limit N] [--workers 2] [--benches 7]

Synthetic: every family of :mod:`core.synthetic.scenarios` at the held-out
seeds (the only ones reported; ``--seeds tuning`` runs the tuning seeds
instead). For every non-host geozone, the paper's protocol
(:func:`core.model.evaluation.evaluate_geozone`): each bench with a bench
below it and a bench above it is the deepest known, everything below is
withheld, and the geozone is predicted 5 m and 10 m below it (half and one
bench height) and scored against the generator's true section inside the
drilled area of the next bench. Model, nil (hold the last bench), linear
(signed distance through the last two benches) and implicit (RBF) run in the
same pass. Precision and recall are area-weighted (pooled over benches,
geozones and seeds), F1 is their harmonic mean; tables per family and pooled,
with the model's F1 margin over the best reference, per kind of geozone and per
deepest known bench. Beside them, as a yardstick no method has, the linear
extrapolation of the *true* sections of the last two known benches
(``true sections, linear``; issue 12 puts its target against it): it is in
every table, and no margin counts it. ``--benches`` drills each synthetic mine on that many benches
(7 by default; rates are per metre of depth, and layers slow down to stay in the
deeper pit, so more benches also means slower layers).

Kennecott (``BGM_KENNECOTT`` or ../shared/data, when present): the next bench withheld, scored against the region
extracted from its holes, F1 per method.

Scenarios run in parallel on ``--workers`` processes; the wall time is printed.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from kennecott_data import KENNECOTT  # noqa: E402

import core.model.evaluation as evaluation  # noqa: E402
from core.extraction.contours import extract_contours  # noqa: E402
from core.io.blastholes import BGMWarning, blastholes_from_table, read_blastholes  # noqa: E402
from core.model.build import predictor_from_model  # noqa: E402
from core.model.evaluation import LinearSDF, evaluate_geozone, summary_table, truth_from_mine  # noqa: E402
from core.model.pipeline import ModelParameters, model_geozone  # noqa: E402
from core.synthetic.blobs import HOST  # noqa: E402
from core.synthetic.scenarios import FAMILIES, HELD_OUT_SEEDS, TUNING_SEEDS, scenario  # noqa: E402

METHODS = ("model", "nil", "linear", "implicit")
REFERENCES = ("nil", "linear", "implicit")
#: The linear extrapolation of the true sections of the last two known benches: a yardstick, not a reference.
TRUE_LINEAR = "true sections, linear"
#: Prediction depths below the deepest known bench, as fractions of the bench height (5 and 10 m at 10 m).
FRACTIONS = (0.5, 1.0)


def evaluate(holes, truth=None, geozones=None, fractions=FRACTIONS) -> pd.DataFrame:
    """The protocol for every geozone of ``holes`` (or ``geozones``), with the real pipeline."""
    params = ModelParameters()
    contours = extract_contours(holes, params=params.extraction)
    rows = []
    for g in geozones if geozones is not None else holes.geozones:
        model = model_geozone(holes, g, contours=contours, params=params)
        if not model.pairs:
            continue
        df = evaluate_geozone(
            holes,
            g,
            predictor_from_model(model, holes, params),
            truth=truth,
            contours=contours,
            fractions=fractions,
            references=REFERENCES,
        )
        df.insert(0, "geozone", g)
        rows.append(df)
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()


@contextlib.contextmanager
def with_true_linear(truth):
    """Score :data:`TRUE_LINEAR` beside the methods, from ``truth(geozone, z_m)``, in this process meanwhile."""
    predictors = evaluation._predictors

    def also_true_linear(holes, geozone, k, regions, z_targets, model, references, grid):
        methods = predictors(holes, geozone, k, regions, z_targets, model, references, grid)
        last_two = sorted(regions)[:2]  # elevations fall with depth: the two deepest known
        methods[TRUE_LINEAR] = LinearSDF({z: truth(geozone, z) for z in last_two}, grid).region
        return methods

    evaluation._predictors = also_true_linear
    try:
        yield
    finally:
        evaluation._predictors = predictors


def without_true_linear(df: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``df``'s rows of the methods, and those of :data:`TRUE_LINEAR` (no margin may count it)."""
    yardstick = df["method"] == TRUE_LINEAR
    return df[~yardstick], df[yardstick]


def run_scenario(job: tuple[str, int, int]) -> tuple[str, int, pd.DataFrame, float]:
    """Evaluate one scenario ``(family, seed, benches)`` (or Kennecott, ``("kennecott", 0, 0)``); rows and CPU seconds."""
    family, seed, n_benches = job
    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        if family == "kennecott":
            holes = read_blastholes(KENNECOTT)
            df = evaluate(holes, fractions=(1.0,))
        else:
            mine, table, _ = scenario(family, seed, n_benches=n_benches)
            holes = blastholes_from_table(table, source=f"{family} {seed}")
            geozones = [g for g in holes.geozones if g != HOST]
            truth = truth_from_mine(mine, holes.frame)
            with with_true_linear(truth):
                df = evaluate(holes, truth, geozones)
    if len(df):
        df.insert(0, "kind", "real" if family == "kennecott" else df["geozone"].map(mine.kinds))
        df.insert(0, "seed", seed)
        df.insert(0, "family", family)
    return family, seed, df, time.process_time() - start


def f1(p: float, r: float) -> float:
    return 2 * p * r / (p + r) if np.isfinite(p) and np.isfinite(r) and p + r > 0 else float("nan")


def depth_table(df: pd.DataFrame) -> pd.DataFrame:
    """Precision, recall and F1 (percent) per depth and method, the model's F1 margin over the best reference,
    and :data:`TRUE_LINEAR`'s F1 where it was scored."""
    rows, yardstick = without_true_linear(df)
    summary = summary_table(rows)
    lines = _yardstick_f1(yardstick)
    out = []
    for _, r in summary.iterrows():
        line = {
            "depth_m": round(float(r["depth_m"]), 2),
            "cases": int(len(rows[rows["fraction"] == r["fraction"]]) // len(METHODS)),
        }
        for m in METHODS:
            p, rec = r.get(f"precision_{m}", np.nan), r.get(f"recall_{m}", np.nan)
            line[f"{m} P/R/F1"] = f"{100 * p:5.1f} / {100 * rec:5.1f} / {100 * r.get(f'f1_{m}', np.nan):5.1f}"
        line["margin"] = f"{100 * r['f1_margin']:+5.1f} vs {r['best_reference']}"
        if lines:
            line[f"{TRUE_LINEAR} F1"] = round(100 * lines[r["fraction"]], 1)
        out.append(line)
    return pd.DataFrame(out)


def _yardstick_f1(yardstick: pd.DataFrame) -> dict[float, float]:
    """:data:`TRUE_LINEAR`'s F1 per fraction of a bench (none where it was not scored)."""
    if yardstick.empty:
        return {}
    return {float(r["fraction"]): float(r[f"f1_{TRUE_LINEAR}"]) for _, r in summary_table(yardstick).iterrows()}


def print_tables(df: pd.DataFrame, families: list[str]) -> None:
    for family in families:
        part = df[df["family"] == family]
        if part.empty:
            print(f"\n{family}: no case")
            continue
        print(
            f"\n{family} (seeds {sorted(int(s) for s in part['seed'].unique())}, {part['geozone'].nunique()} geozone labels):"
        )
        print(depth_table(part).to_string(index=False))
    print("\nAll families pooled (area-weighted):")
    print(depth_table(df).to_string(index=False))
    print("\nPer kind of geozone, all families (F1, percent):")
    print(margin_rows(df, "kind").to_string(index=False))
    print("\nPer deepest known bench (0 the top), all families (F1, percent):")
    print(margin_rows(df, "bench").to_string(index=False))


def margin_rows(df: pd.DataFrame, by: str) -> pd.DataFrame:
    """Every method's F1 at each depth, and the model's margin over the best reference, per value of ``by``."""
    rows = []
    for value, whole in df.groupby(by):
        part, yardstick = without_true_linear(whole)
        summary = summary_table(part)
        lines = _yardstick_f1(yardstick)
        row = {by: value, "cases": len(part) // (len(METHODS) * len(summary))}
        for _, r in summary.iterrows():
            d = f"{r['depth_m']:.0f} m"
            row.update({f"{m} {d}": round(100 * r[f"f1_{m}"], 1) for m in METHODS})
            row[f"margin {d}"] = round(100 * r["f1_margin"], 1)
            if lines:
                row[f"true linear {d}"] = round(100 * lines[r["fraction"]], 1)
        rows.append(row)
    return pd.DataFrame(rows)


def print_kennecott(df: pd.DataFrame) -> None:
    if df.empty:
        return
    r = summary_table(df).iloc[0]
    print(f"\nKennecott, next bench withheld ({df['geozone'].nunique()} geozones, {len(df) // len(METHODS)} cases):")
    for m in METHODS:
        p, rec = r[f"precision_{m}"], r[f"recall_{m}"]
        print(f"  {m:9s} precision {100 * p:5.1f}  recall {100 * rec:5.1f}  F1 {100 * f1(p, rec):5.1f}")
    print(f"  model F1 margin over the best reference ({r['best_reference']}): {100 * r['f1_margin']:+.1f}")
    if "holes_in" not in df:
        return
    print("  scored on the withheld bench's holes:")
    scores = hole_scores(df)
    for m in METHODS:
        p, rec = scores[m]
        print(f"  {m:9s} precision {100 * p:5.1f}  recall {100 * rec:5.1f}  F1 {100 * f1(p, rec):5.1f}")
    print(f"  model F1 margin over the best reference ({r['best_holes_reference']}): {100 * r['f1_holes_margin']:+.1f}")
    print_kennecott_by_depth(df)


def hole_scores(part: pd.DataFrame, ground: str = "all") -> dict[str, tuple[float, float]]:
    """Per method, precision and recall on the withheld benches' holes in ``ground`` (:func:`ground_counts`)."""
    scores = {}
    for m, rows in part.groupby("method"):
        hit, inside, labelled = ground_counts(rows, ground)
        scores[m] = (hit / inside if inside else np.nan, hit / labelled if labelled else np.nan)
    return scores


def ground_counts(rows: pd.DataFrame, ground: str = "all") -> np.ndarray:
    """The withheld benches' holes inside and of the geozone, inside, and of the geozone, pooled over ``rows``.

    ``ground``: ``"all"`` the holes, ``"drilled"`` those in ground the last known bench drilled, ``"new"`` the rest.
    """
    columns = ["holes_in_geozone", "holes_in", "holes_geozone"]
    counts = rows[columns].sum().to_numpy()
    if ground == "all":
        return counts
    drilled = rows[[f"drilled_{c}" for c in columns]].sum().to_numpy()
    return drilled if ground == "drilled" else counts - drilled


def print_kennecott_by_depth(df: pd.DataFrame) -> None:
    """Hole-scored F1 by how many benches are known: the deepest cases are the nearest to the benches held out below.

    With more benches known the pit has narrowed, the next bench is drilled mostly where the last
    one was, and holding the last bench is a harder reference to beat. So each line is also told
    apart by ground: the holes under the last known bench's drilling, and those beyond it.
    """
    grounds = ("all", "drilled", "new") if "drilled_holes_in" in df else ("all",)
    for ground in grounds:
        where = {"all": "", "drilled": " in ground the last bench drilled", "new": " in ground it did not"}[ground]
        print(f"  by the deepest known bench (F1 on the withheld bench's holes{where}; cases, holes):")
        for first in sorted(df["bench"].unique()):
            part = df[df["bench"] >= first]
            scores = {m: 100 * f1(*pr) for m, pr in hole_scores(part, ground).items()}
            best = max(REFERENCES, key=lambda m: scores[m] if np.isfinite(scores[m]) else -1)
            cases = len(part) // len(METHODS)
            holes = int(ground_counts(part[part["method"] == "model"], ground)[2])
            line = "  ".join(f"{m} {scores[m]:5.1f}" for m in METHODS)
            margin = scores["model"] - scores[best]
            print(f"    bench {first} and deeper ({cases:2d}, {holes:5d}): {line}  margin {margin:+.1f} vs {best}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", choices=("held-out", "tuning"), default="held-out")
    parser.add_argument("--limit", type=int, default=None, help="Seeds per family (default: all held-out seeds).")
    parser.add_argument(
        "--first-seed",
        type=int,
        default=None,
        help="Seeds from this one on (--limit of them, 8 by default) instead of --seeds: a batch no figure was read from.",
    )
    parser.add_argument("--families", nargs="*", default=list(FAMILIES), choices=FAMILIES)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-kennecott", action="store_true")
    parser.add_argument("--save", type=Path, default=None, help="Also write every row scored to this CSV.")
    parser.add_argument("--benches", type=int, default=7, help="Benches drilled in each synthetic mine.")
    args = parser.parse_args()
    seeds = list(HELD_OUT_SEEDS if args.seeds == "held-out" else TUNING_SEEDS)
    seeds = seeds[: args.limit or (len(HELD_OUT_SEEDS) if args.seeds == "tuning" else len(seeds))]
    if args.first_seed is not None:
        seeds = list(range(args.first_seed, args.first_seed + (args.limit or len(HELD_OUT_SEEDS))))
    if args.benches < 3:
        parser.error("--benches must be 3 or more (a deepest known bench with one above it and one below)")
    jobs = [(f, s, args.benches) for f in args.families for s in seeds]
    if not args.no_kennecott and KENNECOTT.exists():
        jobs.insert(0, ("kennecott", 0, 0))  # the longest job first, so it is not the tail
    pool = "fresh" if args.first_seed is not None else args.seeds
    print(f"{pool} seeds {seeds}; {len(jobs)} jobs on {args.workers} processes")
    start = time.perf_counter()
    results = []
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(args.workers) as pool:
        for family, seed, df, cpu in pool.imap_unordered(run_scenario, jobs):
            print(f"  {family} {seed}: {len(df)} rows, {cpu:.0f} s CPU", flush=True)
            results.append((family, df))
    wall = time.perf_counter() - start
    synthetic = [df for f, df in results if f != "kennecott" and len(df)]
    if args.save:
        pd.concat([df for _, df in results if len(df)], ignore_index=True).to_csv(args.save, index=False)
    if synthetic:  # none with `--families` and no family named: Kennecott only
        print_tables(pd.concat(synthetic, ignore_index=True), args.families)
    kennecott = [df for f, df in results if f == "kennecott"]
    if kennecott:
        print_kennecott(kennecott[0])
    elif not args.no_kennecott:
        print(f"\nKennecott data not found at {KENNECOTT}; skipped")
    print(f"\nWall time {wall:.0f} s on {args.workers} processes")


if __name__ == "__main__":
    main()
