"""Prediction on geology and drilling the engine was not tuned on: shapes outside the families, and other patterns.

    python tests/benchmarks/bench_robustness.py [--part shapes drilling] [--limit N] [--workers 2]
        [--seeds held-out|tuning] [--families pods ...]

The engine's defaults were chosen on the tuning seeds of the six families
(:mod:`core.synthetic.scenarios`) drilled one way: a staggered pattern of 5-7 m,
1-3% label noise, 10 m benches in metres. This benchmark runs the paper's
protocol (as ``bench_prediction.py``: 5 m and 10 m below each bench, model
against nil, linear and implicit in the same pass) where none of that holds,
on held-out seeds only:

* ``shapes`` -- every shape of :mod:`core.synthetic.shapes` (a ring, a faulted
  strip, a contact around a pipe, a pivoting contact, an angular body, an arc,
  a layer dipping 16-29 degrees), which no default was chosen on, drilled the
  default way;
* ``drilling`` -- every family drilled otherwise (:data:`DRILLING`): patterns of
  9-12 m and 3-4 m, 6-10% label noise, 10-25% of the holes at the contacts labelled as
  the neighbour (samples mixing two geozones), 15 m benches in feet, 6 m benches, and each
  bench's pit 20-40 m sideways of the one above (a pushback: ground no bench above drilled),
  holes collared off the pattern by 0.3 of a spacing (standard deviation; 0.08 by default),
  a square pattern instead of a staggered one (the same spacing, so 13% fewer holes),
  a pattern of 9-12 m with 6-10% label noise together, and, drilled the default way,
  layers, contacts and fold hinges moving twice the families' rates (4-30 m a bench),
  and a pit four times as long (1.1-1.4 km by 240-300 m, Kennecott's shape), where layers
  striking along it cross the pit for most of a kilometre.
  Depths are half and one bench height, whatever the bench height.

``--seeds tuning`` runs the development seeds instead (``--limit`` of them,
default 2), to work on a weakness these drillings show without looking at the
seeds it is reported on.

Prints the F1 of each method per shape (or per drilling and family) and
pooled, with the model's margin over the best reference.
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import time
import warnings
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_prediction import METHODS, evaluate  # noqa: E402

from core.io.blastholes import BGMWarning, blastholes_from_table  # noqa: E402
from core.model.evaluation import summary_table, truth_from_mine  # noqa: E402
from core.synthetic.blobs import HOST  # noqa: E402
from core.synthetic.scenarios import FAMILIES, HELD_OUT_SEEDS, TUNING_SEEDS, scenario  # noqa: E402
from core.synthetic.shapes import SHAPES, shape_scenario  # noqa: E402

#: Drilling unlike the tuning seeds': (arguments of ``scenario`` for the mine, of ``drill_mine``).
DRILLING: dict[str, tuple[dict, dict]] = {
    "pattern 9-12 m": ({}, {"spacing_range_m": (9.0, 12.0)}),
    "pattern 3-4 m": ({}, {"spacing_range_m": (3.0, 4.0)}),
    "label noise 6-10%": ({}, {"label_noise_range": (0.06, 0.10)}),
    # Heavy: groups of mislabelled holes as large as small lenses are common.
    "label noise 12-18%": ({}, {"label_noise_range": (0.12, 0.18)}),
    # Mislabels where samples mix two geozones: 10-25% of the holes at a contact take the neighbour's label.
    "label noise at the contacts 10-25%": ({}, {"contact_noise_range": (0.10, 0.25)}),
    "15 m benches, feet": ({"bench_height_m": 15.0, "units": "ft"}, {}),
    "6 m benches": ({"bench_height_m": 6.0}, {}),
    "pushback 20-40 m a bench": ({}, {"pushback_range_m": (20.0, 40.0)}),
    "holes 0.3 spacing off the pattern": ({}, {"collar_scatter_spacings": 0.3}),
    "square pattern": ({}, {"pattern": "square"}),
    # Two at once: the few holes of a wide pattern, up to a tenth of them mislabelled.
    "pattern 9-12 m, label noise 6-10%": ({}, {"spacing_range_m": (9.0, 12.0), "label_noise_range": (0.06, 0.10)}),
    # Not drilling but the geology: layers, contacts and fold hinges twice the families' rates
    # (4-30 m a bench, slowed where a layer would leave the pit); splits' and pods' unchanged.
    "layers moving twice as fast": ({"shift_scale": 2.0}, {}),
    # Not drilling but the pit: four times as long, the same geology stretched (4x the holes a case).
    "pit four times as long": ({"length_scale": 4.0}, {}),
    # Three times, with a wide noisy pattern as well: the hidden scenarios hold the last bench
    # at 76.7 / 59.7 F1, under every line above; this is the nearest the families come to that.
    "layers three times as fast, pattern 9-12 m, label noise 6-10%": (
        {"shift_scale": 3.0},
        {"spacing_range_m": (9.0, 12.0), "label_noise_range": (0.06, 0.10)},
    ),
}


def run_case(job: tuple[str, str, int]) -> tuple[str, str, int, pd.DataFrame]:
    """Evaluate one case: ``("shapes", shape, seed)`` or ``("drilling", "<drilling>|<family>", seed)``."""
    part, name, seed = job
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        if part == "shapes":
            mine, table, _ = shape_scenario(name, seed)
        else:
            drilling, family = name.split("|")
            mine_args, drill_args = DRILLING[drilling]
            mine, table, _ = scenario(family, seed, drilling=drill_args, **mine_args)
        holes = blastholes_from_table(table, source=f"{name} {seed}")
        df = evaluate(holes, truth_from_mine(mine, holes.frame), [g for g in holes.geozones if g != HOST])
    if len(df):
        df.insert(0, "kind", df["geozone"].map(mine.kinds))
        df.insert(0, "seed", seed)
        df.insert(0, "case", name)
    return part, name, seed, df


def margin_row(label: str, rows: pd.DataFrame) -> dict:
    """F1 (percent) of every method at each depth, and the model's margin over the best reference."""
    out: dict = {"case": label, "cases": int(len(rows) // (len(METHODS) * rows["fraction"].nunique()))}
    for _, r in summary_table(rows).iterrows():
        d = f"{r['fraction']:g}h"
        out.update({f"{m} {d}": round(100 * r[f"f1_{m}"], 1) for m in METHODS})
        out[f"margin {d}"] = f"{100 * r['f1_margin']:+.1f} vs {r['best_reference']}"
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--part", nargs="*", default=["shapes", "drilling"], choices=("shapes", "drilling"))
    parser.add_argument("--limit", type=int, default=None, help="Seeds per case (shapes: 8, drilling: 2).")
    parser.add_argument("--drilling", nargs="*", default=list(DRILLING), choices=list(DRILLING))
    parser.add_argument("--families", nargs="*", default=list(FAMILIES), choices=FAMILIES, help="Families drilled.")
    parser.add_argument("--seeds", choices=("held-out", "tuning"), default="held-out")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    seed_pool = HELD_OUT_SEEDS if args.seeds == "held-out" else TUNING_SEEDS
    jobs = []
    if "shapes" in args.part:
        jobs += [("shapes", s, seed) for s in SHAPES for seed in seed_pool[: args.limit or len(HELD_OUT_SEEDS)]]
    if "drilling" in args.part:
        seeds = seed_pool[: args.limit or 2]
        jobs += [("drilling", f"{d}|{f}", seed) for d in args.drilling for f in args.families for seed in seeds]
    print(f"{len(jobs)} cases on {args.workers} processes ({args.seeds} seeds)")
    start = time.perf_counter()
    results: dict[str, list[pd.DataFrame]] = {"shapes": [], "drilling": []}
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        for done, (part, name, seed, df) in enumerate(pool.imap_unordered(run_case, jobs), start=1):
            print(f"  [{done}/{len(jobs)}] {name.replace('|', ', ')} {seed}: {len(df)} rows", flush=True)
            results[part].append(df)
    pd.set_option("display.width", 250)
    if results["shapes"]:
        df = pd.concat(results["shapes"], ignore_index=True)
        rows = [margin_row(s, df[df["case"] == s]) for s in SHAPES if (df["case"] == s).any()]
        rows += [margin_row(k, part) for k, part in df.groupby("kind") if part["case"].iloc[0] == "inclusion"]
        rows.append(margin_row("all shapes, pooled", df))
        print("\nShapes outside the families (h = bench height, 10 m):")
        print(pd.DataFrame(rows).to_string(index=False))
    if results["drilling"]:
        df = pd.concat(results["drilling"], ignore_index=True)
        df["drilling"], df["family"] = zip(*df["case"].str.split("|"))
        for d, part in df.groupby("drilling", sort=False):
            rows = [margin_row(f, part[part["family"] == f]) for f in args.families if (part["family"] == f).any()]
            rows.append(margin_row("all families, pooled", part))
            print(f"\nDrilled with {d} (h = bench height):")
            print(pd.DataFrame(rows).to_string(index=False))
    print(f"\nWall time {time.perf_counter() - start:.0f} s on {args.workers} processes")


if __name__ == "__main__":
    main()
