"""A deepest bench drilled over part of the pit: does its rest come out better, or no worse, for its first holes?

    python tests/benchmarks/bench_partial_bench.py [--kennecott-benches 3 4 5] [--families pods folds ...]

``--families`` alone names none: Kennecott only, as the figures quoted with it are.
                                                   [--seeds 1] [--save rows.csv]

A bench is drilled over weeks, so a geologist often runs BGM when the deepest
bench of the table holds only its first blast patterns. For each case the
deepest bench ``k`` is cut: its holes whose projection on a random direction is
lowest (5%, 15%, 40% of them) or a strip from one end along the pit's long axis
(15%, 40%) are kept, the rest held back. Every geozone's section at bench
``k``'s level is predicted (a) from benches ``0..k-1`` alone (one bench below
the deepest known) and (b) from them with the kept part of bench ``k`` (its
contours where drilled, the depth trend in the rest), and both are scored on
the held-back holes' labels, pooled over geozones (F1 of holes inside a
geozone's predicted section that carry its label), as :mod:`bench_prediction`
scores Kennecott. (b) should be at least (a): the first holes add evidence.

Kennecott benches (``--kennecott-benches``; read from ``BGM_KENNECOTT`` or ``../shared/data`` beside
the repository, skipped when absent) and the synthetic families' last bench on
tuning seeds (``--families``, ``--seeds`` each; the host is not scored).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import shapely

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from kennecott_data import KENNECOTT  # noqa: E402

from core.errors import BGMWarning  # noqa: E402
from core.io.blastholes import Blastholes, blastholes_from_table, read_blastholes  # noqa: E402
from core.model.session import ModelSession  # noqa: E402
from core.synthetic.blobs import HOST  # noqa: E402
from core.synthetic.scenarios import TUNING_SEEDS, scenario  # noqa: E402

FAMILIES = ("strips", "widening", "folds", "splits", "pods", "mix")


def first_holes(xy: np.ndarray, rng: np.random.Generator) -> list[tuple[str, np.ndarray]]:
    """``(name, kept)`` cuts of a bench's holes: a random direction's lowest 5/15/40%, a strip from one end."""
    angle = rng.uniform(0.0, 2.0 * np.pi)
    along = xy @ np.array([np.cos(angle), np.sin(angle)])
    cuts = [
        (f"{int(f * 100)}% from {int(np.degrees(angle))} deg", along <= np.quantile(along, f))
        for f in (0.05, 0.15, 0.4)
    ]
    centred = xy - xy.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    length = centred @ axis
    return cuts + [(f"strip {int(f * 100)}%", length <= np.quantile(length, f)) for f in (0.15, 0.4)]


def sections(holes: Blastholes, geozones: list[str], z_m: float) -> dict[str, shapely.MultiPolygon]:
    """Every geozone's predicted section at ``z_m`` (empty for a geozone the table does not hold)."""
    session = ModelSession(holes)
    return {g: session.predict(g, [z_m])[z_m] if g in holes.geozones else shapely.MultiPolygon() for g in geozones}


def hole_f1(regions: dict, holes: Blastholes, xy_input: np.ndarray, labels: np.ndarray) -> float:
    """F1 (percent) of the held-back holes inside each geozone's section and carrying its label, pooled (NaN: none)."""
    xy = holes.frame.to_local(xy_input[:, 0], xy_input[:, 1])
    hits = inside = labelled = 0
    for g, region in regions.items():
        ins = shapely.contains_xy(region, xy[:, 0], xy[:, 1]) if not region.is_empty else np.zeros(len(xy), bool)
        hits += int((ins & (labels == g)).sum())
        inside += int(ins.sum())
        labelled += int((labels == g).sum())
    if labelled == 0 and inside == 0:
        return float("nan")  # every held-back hole is host, which is not scored
    p, r = hits / max(inside, 1), hits / max(labelled, 1)
    return 200.0 * p * r / (p + r) if p + r > 0 else 0.0


def read(table: pd.DataFrame, unit: str) -> Blastholes:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        return blastholes_from_table(table, source="partial bench", length_unit=unit)


def cases(full: Blastholes, k: int, geozones: list[str], label: str, unit: str, rng) -> list[dict]:
    """Rows of (a) and (b) for bench ``k`` of ``full`` cut every way :func:`first_holes` cuts it."""
    table = full.as_table()
    above = read(table[full.bench < k], unit)
    z_k = float(full.bench_levels_m[k])
    on_k = np.flatnonzero(full.bench == k)
    xy_input, labels = table[["x", "y"]].to_numpy()[on_k], full.geozone[on_k]
    from_above = sections(above, geozones, z_k)
    rows = []
    for name, kept in first_holes(full.xy[on_k], rng):
        partly = read(pd.concat([table[full.bench < k], table.iloc[on_k[kept]]]), unit)
        z_new = float(partly.bench_levels_m[-1])
        with_first = sections(partly, geozones, z_new)
        held = ~kept
        rows.append(
            {
                "case": label,
                "bench": k,
                "first holes": name,
                "kept": int(kept.sum()),
                "held back": int(held.sum()),
                "benches above alone": hole_f1(from_above, above, xy_input[held], labels[held]),
                "with the first holes": hole_f1(with_first, partly, xy_input[held], labels[held]),
            }
        )
        print(
            f"  {label} bench {k}, {name}: {rows[-1]['benches above alone']:.1f} -> {rows[-1]['with the first holes']:.1f}",
            flush=True,
        )
    return rows


def main(argv=None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kennecott-benches", type=int, nargs="*", default=[3, 4, 5])
    ap.add_argument(
        "--families", nargs="*", default=list(FAMILIES), choices=FAMILIES, help="Families (the flag alone: none)."
    )
    ap.add_argument("--seeds", type=int, default=1, help="Tuning seeds per family.")
    ap.add_argument("--save", type=Path)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(12)
    t0 = time.perf_counter()
    rows: list[dict] = []
    if KENNECOTT.exists() and args.kennecott_benches:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", BGMWarning)
            full = read_blastholes(KENNECOTT)
        for k in args.kennecott_benches:
            rows += cases(full, k, list(full.geozones), "kennecott", full.frame.length_unit, rng)
    elif args.kennecott_benches:
        print(f"Kennecott skipped: {KENNECOTT} not found")
    for family in args.families:
        for seed in TUNING_SEEDS[: args.seeds]:
            _, table, _ = scenario(family, seed)
            full = read(table, "m")
            geozones = [g for g in full.geozones if g != HOST]
            rows += cases(full, full.n_benches - 1, geozones, f"{family} {seed}", "m", rng)
    out = pd.DataFrame(rows)
    if args.save:
        out.to_csv(args.save, index=False)
    if len(out):
        out["gain"] = out["with the first holes"] - out["benches above alone"]
        print("\nF1 on the held-back holes of the deepest bench, percent:")
        print(out.groupby("case")[["benches above alone", "with the first holes", "gain"]].mean().round(1).to_string())
        print(f"\n{len(out)} cuts, the first holes worse by more than a point in {(out.gain < -1).sum()}")
    print(f"Wall time {time.perf_counter() - t0:.0f} s")
    return out


if __name__ == "__main__":
    main()
