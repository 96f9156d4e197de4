"""Kennecott as it stood at other moments: the table cut at a hole number, scored on the holes drilled after.

    python tests/benchmarks/bench_periods.py [--cuts 0.3 0.4 ... 0.9] [--kennecott PATH] [--save rows.csv]
                                             [--workers 1] [--next-bench]

A mine drills several benches at once, each over weeks, so the table a
geologist hands BGM has its deepest benches partly drilled.
:mod:`bench_partial_bench` cuts one bench along random directions; here the
table is cut in time. Kennecott's ``HOLEID`` is, for most holes, a 6-digit
number that grows with drilling time; the others (7-16 character codes such
as ``0202231031-17929``) are of unknown time, left out of the known tables and
of the scoring (their number is printed). For each cut at a quantile of the
numeric ids:

* known: the holes with id <= cut, read afresh as an input table (its own
  benches, spacing and grid: what ``bgm predict`` would see; what the reader
  made of them is printed);
* held back: the holes with id > cut, each on a bench level of the full table.
  Scored are those on (a) a level the known table has (a partly drilled bench:
  its undrilled rest, or a hole between its drilled ones) and (b) the first
  level below the known table's deepest bench. Holes on other levels (deeper,
  or a level the reader did not make a bench of) are counted, not scored.

Every geozone's section at such a level is predicted by the model
(``ModelSession(known).predict``) and by two references:

* nil, a hold: at each place, the contours of the deepest known bench at or
  above the level that drilled there (for (a) the bench's own contours where
  it drilled, the benches above's elsewhere; for (b) the same carried below
  the deepest bench). A hold of the bench's own contours alone would predict
  nothing in its undrilled rest, and one of the deepest complete bench alone
  would ignore the bench's own holes: each holds what the nearest drilling
  above said, as a geologist would;
* implicit: the implicit model of the known holes
  (:func:`core.model.new_ground.implicit_model`, as the evaluation's
  reference), evaluated over the held-back holes' drilled area.

Scores are the held-back holes' pooled F1 (holes inside a geozone's section
and carrying its label, pooled over geozones, as
:func:`bench_partial_bench.hole_f1`), per cut and kind, and overall.
``--save`` writes the per-geozone counts.
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
import shapely

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_partial_bench import read  # noqa: E402
from kennecott_data import KENNECOTT  # noqa: E402

from core.errors import BGMWarning  # noqa: E402
from core.io.blastholes import Blastholes, drilled_area  # noqa: E402
from core.model.evaluation import bench_regions, reference_grid  # noqa: E402
from core.model.new_ground import implicit_model, known_holes  # noqa: E402
from core.model.session import ModelSession  # noqa: E402

METHODS = ("model", "nil", "implicit")
#: Quantiles of the numeric hole ids the table is cut at: from 0.3 every cut leaves the two benches under the top
#: bench's 20 holes well drilled (514.7 ft 85%, 464.5 ft 46%, over 1,100 holes each, at 0.3; at 0.2 the second
#: held 678).
DEFAULT_CUTS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)


def hole_table(path: Path) -> tuple[pd.DataFrame, int]:
    """The holes as an input table (``x, y, z, geozone``) with their numeric id (NaN: of unknown time)."""
    raw = pd.read_csv(path, dtype={"HOLEID": str})
    numeric = raw["HOLEID"].str.fullmatch(r"\d{6}").fillna(False).to_numpy(bool)
    table = pd.DataFrame(
        {
            "x": raw["EAST"].to_numpy(float),
            "y": raw["NORTH"].to_numpy(float),
            "z": raw["RL"].to_numpy(float),
            "geozone": raw["lookup_domain"].astype(str).to_numpy(),
            "id": np.where(numeric, pd.to_numeric(raw["HOLEID"].where(numeric), errors="coerce"), np.nan),
        }
    )
    return table, int((~numeric).sum())


def full_levels(table: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, float]:
    """Each row's bench level in the whole table (input units; NaN off every bench), the levels, the bench height."""
    full = read(table[["x", "y", "z", "geozone"]], None)
    levels_in = full.frame.z_to_input(full.bench_levels_m)
    level = np.full(len(table), np.nan)
    row = np.asarray(full.data_line) - 2  # data_lines count the header as line 1
    on = full.bench >= 0
    level[row[on]] = levels_in[full.bench[on]]
    return level, levels_in, float(full.frame.z_to_input(full.bench_height_m))


def hold(regions: dict[int, shapely.MultiPolygon], drilled: dict[int, shapely.MultiPolygon], k: int):
    """At each place, the region of the deepest bench ``<= k`` that drilled there (nil for a partly drilled bench)."""
    held = regions[0]
    for j in range(1, k + 1):
        held = shapely.union(regions[j], shapely.difference(held, drilled[j]))
    return held


def counts(region, xy: np.ndarray, labels: np.ndarray, g: str) -> tuple[int, int, int]:
    """Holes ``xy`` (local metres) inside ``region``, of them labelled ``g``, and labelled ``g`` in all."""
    ins = shapely.contains_xy(region, xy[:, 0], xy[:, 1]) if not region.is_empty else np.zeros(len(xy), bool)
    return int(ins.sum()), int((ins & (labels == g)).sum()), int((labels == g).sum())


def targets(known: Blastholes, level: np.ndarray, levels_in: np.ndarray, height_in: float, held: np.ndarray):
    """``(kind, z_m, bench index or None, rows)`` of the held-back holes scored, and the count left unscored.

    (a) on a level of the known table (its bench index), (b) on the first full-table level below its deepest.
    """
    known_in = known.frame.z_to_input(known.bench_levels_m)
    out, scored = [], np.zeros(len(level), bool)
    for j, z_in in enumerate(known_in):
        rows = np.flatnonzero(held & (np.abs(level - z_in) < 0.3 * height_in))
        if len(rows):
            out.append(("a", float(known.bench_levels_m[j]), j, rows))
            scored[rows] = True
    below = levels_in[levels_in < known_in.min() - 0.3 * height_in]
    if len(below):
        rows = np.flatnonzero(held & np.isclose(level, below.max()))
        if len(rows):
            out.append(("b", float(known.frame.z_to_local(below.max())), None, rows))
            scored[rows] = True
    return out, int((held & ~scored).sum())


def run_cut(table: pd.DataFrame, q: float, level, levels_in, height_in) -> tuple[dict, list[dict]]:
    """The summary and per-geozone rows of one cut at quantile ``q`` of the numeric ids."""
    t0 = time.perf_counter()
    ids = table["id"].to_numpy(float)
    cut = float(np.nanquantile(ids, q))
    is_known, held = ids <= cut, ids > cut  # NaN (unknown time) is neither
    known = read(table.loc[is_known, ["x", "y", "z", "geozone"]], None)
    per_bench = np.bincount(known.bench[known.bench >= 0], minlength=known.n_benches)
    info = {
        "cut": q,
        "id": int(cut),
        "known": int(is_known.sum()),
        "read": len(known.xy),
        "unit": known.frame.length_unit,
        "benches": " ".join(f"{known.bench_z_input(j):g}:{n}" for j, n in enumerate(per_bench)),
        "held back": int(held.sum()),
    }
    todo, info["unscored"] = targets(known, level, levels_in, height_in, held)
    session = ModelSession(known)
    grid = reference_grid(
        np.vstack([known.xy, known.frame.to_local(table["x"][held], table["y"][held])]), known.hole_spacing_m
    )
    geozones = sorted(set(table["geozone"][held]) | set(known.geozones))
    drilled = {j: session.drilled_area(j) for j in range(known.n_benches)}
    rows = []
    for g in geozones:
        present = g in known.geozones
        z_all = sorted({z for _, z, _, _ in todo})
        model = session.predict(g, z_all) if present else {}
        regions = bench_regions(known, g, session.geozone_contours(g)) if present else {}
        rbf = implicit_model(known_holes(known, g)) if present else None
        for kind, z, j, r in todo:
            xy = known.frame.to_local(table["x"].to_numpy()[r], table["y"].to_numpy()[r])
            labels = table["geozone"].to_numpy()[r]
            empty = shapely.MultiPolygon()
            sections = {
                "model": model.get(z, empty),
                "nil": hold(regions, drilled, known.n_benches - 1 if j is None else j) if present else empty,
                "implicit": rbf.region(z, grid=grid, where=drilled_area(xy, known.hole_spacing_m)) if rbf else empty,
            }
            for method, region in sections.items():
                inside, hits, labelled = counts(region, xy, labels, g)
                rows.append(
                    {
                        "cut": q,
                        "kind": kind,
                        "bench_z": round(float(known.frame.z_to_input(z)), 1),
                        "deepest": j is None or j == known.n_benches - 1,
                        "bench_holes": int(per_bench[j]) if j is not None else 0,
                        "geozone": g,
                        "in_known": present,
                        "method": method,
                        "area_m2": float(region.area),
                        "inside": inside,
                        "hits": hits,
                        "labelled": labelled,
                    }
                )
    info["seconds"] = time.perf_counter() - t0
    print(f"  cut {q:g} (id {int(cut)}): {info['seconds']:.0f} s", flush=True)
    return info, rows


def pooled_f1(rows: pd.DataFrame) -> float:
    """F1 (percent) of the pooled counts: ``2 hits / (inside + labelled)``, as ``hole_f1`` pools them."""
    denominator = rows["inside"].sum() + rows["labelled"].sum()
    return 200.0 * rows["hits"].sum() / denominator if denominator else float("nan")


def f1_table(rows: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Pooled F1 of each method, and the held-back holes scored, per group of ``by``."""
    out = rows.groupby([*by, "method"]).apply(pooled_f1, include_groups=False).unstack("method")[list(METHODS)]
    holes = rows[rows["method"] == "model"].groupby(by)["labelled"].sum()
    return out.round(1).assign(holes=holes)


def _run(job):
    return run_cut(*job)


def next_bench_rows(job: tuple[pd.DataFrame, float]) -> pd.DataFrame:
    """The paper's protocol on the table of one moment (``--next-bench``): :func:`bench_prediction.evaluate`."""
    from bench_prediction import evaluate

    table, q = job
    ids = table["id"].to_numpy(float)
    known = read(table.loc[ids <= np.nanquantile(ids, q), ["x", "y", "z", "geozone"]], None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        rows = evaluate(known, fractions=(1.0,))
    rows.insert(0, "cut", q)
    return rows


def print_next_bench(rows: pd.DataFrame) -> None:
    """Hole-scored F1 per cut and per deepest known bench, as ``bench_prediction.py`` prints Kennecott's."""
    from bench_prediction import METHODS as ALL_METHODS
    from bench_prediction import f1, hole_scores

    def line(part: pd.DataFrame) -> str:
        scores = {m: 100 * f1(*pr) for m, pr in hole_scores(part).items()}
        return "  ".join(f"{m} {scores[m]:5.1f}" for m in ALL_METHODS) + f"  ({len(part) // len(ALL_METHODS)} cases)"

    print("\nThe paper's protocol on each moment's table (next bench withheld, F1 on its holes):")
    for q, part in rows.groupby("cut"):
        print(f"  cut {q:g}: {line(part)}")
        for k in sorted(part["bench"].unique()):
            print(f"      deepest known bench {k}: {line(part[part['bench'] == k])}")
    print(f"  every cut: {line(rows)}")
    for k in sorted(rows["bench"].unique()):
        print(f"      deepest known bench {k}: {line(rows[rows['bench'] == k])}")


def main(argv=None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cuts", type=float, nargs="+", default=list(DEFAULT_CUTS), help="Quantiles of the ids.")
    ap.add_argument("--kennecott", type=Path, default=KENNECOTT)
    ap.add_argument("--save", type=Path)
    ap.add_argument("--workers", type=int, default=1, help="Cuts run at once (fork).")
    ap.add_argument(
        "--next-bench",
        action="store_true",
        help="Instead, the paper's protocol on each moment's table: each bench in turn the deepest known, the next "
        "withheld and scored on its holes (the hidden evaluation's protocol, on tables whose deepest benches are "
        "partly drilled).",
    )
    args = ap.parse_args(argv)
    if not args.kennecott.exists():
        print(f"Kennecott skipped: {args.kennecott} not found")
        return pd.DataFrame()
    t0 = time.perf_counter()
    table, unknown = hole_table(args.kennecott)
    level, levels_in, height_in = full_levels(table)
    print(f"{len(table)} holes, {unknown} of unknown time (id not 6 digits): left out of every table and score")
    if args.next_bench:
        with multiprocessing.get_context("fork").Pool(args.workers) as pool:
            rows = pd.concat(pool.map(next_bench_rows, [(table, q) for q in args.cuts]), ignore_index=True)
        if args.save:
            rows.to_csv(args.save, index=False)
        print_next_bench(rows)
        print(f"Wall time {time.perf_counter() - t0:.0f} s")
        return rows
    jobs = [(table, q, level, levels_in, height_in) for q in args.cuts]
    if args.workers > 1:
        with multiprocessing.get_context("fork").Pool(args.workers) as pool:
            results = pool.map(_run, jobs)
    else:
        results = [_run(j) for j in jobs]
    rows = pd.DataFrame([r for _, rs in results for r in rs])
    if args.save:
        rows.to_csv(args.save, index=False)
    info = pd.DataFrame([i for i, _ in results]).set_index("cut")
    pd.set_option("display.width", 200)
    print("\nThe known tables (bench level ft: holes read on it):")
    print(info[["id", "known", "read", "unit", "benches", "held back", "unscored"]].to_string())
    print("\nPooled F1 on the held-back holes, percent ((a) a level the known table has, (b) the first below):")
    print(f1_table(rows, ["cut", "kind"]).to_string())
    print("\nBy kind, every cut:")
    print(f1_table(rows, ["kind"]).to_string())
    print(f"\nOverall: {f1_table(rows.assign(all='all'), ['all']).to_string(header=False)}")
    print(f"Wall time {time.perf_counter() - t0:.0f} s")
    return rows


if __name__ == "__main__":
    main()
