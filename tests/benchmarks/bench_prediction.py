"""Predictive value of the model against the references, on fresh synthetic mines and on Kennecott.

    python tests/benchmarks/bench_prediction.py [SEED ...]

Synthetic mines (default seeds 2019 = the demo, 31, 47, 53): the paper's
protocol at 1/8..8/8 of a bench below every bench with two known benches
above it, scored against the generator's true sections; all geozones
area-weighted, then per geozone at 10 m. Kennecott (when present): the next
bench withheld, scored against its holes, F1 per method. Also prints the
movement persistence the model learnt for each geozone
(:func:`core.model.prediction.persistence_coefficient`).
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
KENNECOTT = ROOT.parent / "shared" / "data" / "kennecott-blastholes" / "blastholes_tagged.csv"

from core.extraction.contours import extract_contours  # noqa: E402
from core.io.blastholes import BGMWarning, blastholes_from_table, read_blastholes  # noqa: E402
from core.model.build import predictor_from_model  # noqa: E402
from core.model.evaluation import evaluate_geozone, format_table, summary_table, truth_from_mine  # noqa: E402
from core.model.pipeline import ModelParameters, model_geozone  # noqa: E402
from core.model.prediction import persistence_coefficient  # noqa: E402
from core.synthetic.blobs import demo_dataset, make_mine, sample_blastholes  # noqa: E402


def evaluate(holes, truth=None, references=("nil", "linear", "implicit")) -> tuple[pd.DataFrame, dict]:
    params = ModelParameters()
    contours = extract_contours(holes, params=params.extraction)
    rows, learnt = [], {}
    for g in holes.geozones:
        model = model_geozone(holes, g, contours=contours, params=params)
        if not model.pairs:
            continue
        learnt[g] = round(persistence_coefficient(model.pairs, holes.hole_spacing_m), 2)
        df = evaluate_geozone(
            holes, g, predictor_from_model(model, holes, params), truth=truth, contours=contours, references=references
        )
        df.insert(0, "geozone", g)
        rows.append(df)
    return pd.concat(rows, ignore_index=True), learnt


def f1(p: float, r: float) -> float:
    return 2 * p * r / (p + r) if p + r > 0 else 0.0


def synthetic(seeds: list[int]) -> None:
    frames = []
    for seed in seeds:
        if seed == 2019:
            mine, table = demo_dataset(seed)
        else:
            mine = make_mine(seed=seed, origin=(650_000.0 + seed, 7_400_000.0 - seed))
            table = sample_blastholes(mine, seed=seed + 1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", BGMWarning)
            holes = blastholes_from_table(table, source=f"seed {seed}")
        t = time.perf_counter()
        df, learnt = evaluate(holes, truth_from_mine(mine, holes.frame))
        print(f"seed {seed}: evaluated in {time.perf_counter() - t:.1f} s; persistence learnt {learnt}")
        df.insert(0, "seed", seed)
        frames.append(df)
    df = pd.concat(frames, ignore_index=True)
    print(f"\nSynthetic seeds {seeds}, all geozones (percent):")
    print(format_table(summary_table(df)))
    print("\nPer geozone at one bench below (percent):")
    for g, part in df.groupby("geozone"):
        r = summary_table(part).set_index("fraction").loc[1.0]
        cells = "  ".join(
            f"{m} P {100 * r[f'precision_{m}']:.1f} R {100 * r[f'recall_{m}']:.1f}"
            for m in ("model", "nil", "linear", "implicit")
        )
        print(f"  {g}: {cells}")


def kennecott() -> None:
    if not KENNECOTT.exists():
        print(f"\nKennecott data not found at {KENNECOTT}; skipped")
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = read_blastholes(KENNECOTT)
    t = time.perf_counter()
    df, learnt = evaluate(holes)
    print(f"\nKennecott, next bench withheld ({time.perf_counter() - t:.1f} s); persistence learnt {learnt}")
    r = summary_table(df).iloc[0]
    for m in ("model", "nil", "linear", "implicit"):
        p, rec = r[f"precision_{m}"], r[f"recall_{m}"]
        print(f"  {m:9s} precision {100 * p:5.1f}  recall {100 * rec:5.1f}  F1 {f1(p, rec):.3f}")


if __name__ == "__main__":
    synthetic([int(a) for a in sys.argv[1:]] or [2019, 31, 47, 53])
    kennecott()
