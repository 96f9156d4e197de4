"""How the cost of `bgm build` grows with the size of the mine.

    python tests/benchmarks/bench_scale.py [10000 100000 1000000]

Synthetic mines of growing extent (more holes per bench) and more benches,
built with `bgm build` on all local cores; prints time and peak memory
(whole process tree) per size and the growth exponent between sizes.
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measure import run_measured

from core.synthetic.blobs import make_mine, sample_blastholes

BGM = [sys.executable, "-c", "from core.cli import main; main()"]
HOLE_AREA_M2 = 6.0 * 6.0 * math.sqrt(3) / 2  # one hole per cell of a 6 m staggered pattern


def synthetic_table(n_holes: int, seed: int = 7):
    n_benches = int(min(max(round(math.log10(n_holes) * 4 - 8), 4), 16))
    # The pit shrinks with depth and benches are drilled in part (see core.synthetic.blobs):
    # size the top bench from a first guess, then rescale once to the count it gave.
    per_bench = n_holes / n_benches / 0.75
    side = math.sqrt(per_bench * HOLE_AREA_M2 / 0.75)
    for _ in range(3):
        mine = make_mine(seed=seed, n_benches=n_benches, extent_m=(side / 0.75**0.5, side * 0.75**0.5), n_pods=6)
        table = sample_blastholes(mine, seed=seed + 1)
        side *= math.sqrt(n_holes / len(table))
    return table, n_benches


def main(sizes: list[int]) -> None:
    previous = None
    for n in sizes:
        table, n_benches = synthetic_table(n)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "mine.csv"
            table.to_csv(path, index=False)
            r = run_measured([*BGM, "build", str(path), "--out", str(Path(tmp) / "out"), "--no-cache"])
        status = "ok" if r["returncode"] == 0 else f"FAILED: {r['stderr'][-400:]}"
        line = f"{len(table):>9,d} holes, {n_benches:2d} benches: {r['seconds']:7.1f} s, peak {r['peak_gb']:5.2f} GB - {status}"
        if previous is not None:
            k = math.log(r["seconds"] / previous[1]) / math.log(len(table) / previous[0])
            line += f"  (time grows as n^{k:.2f})"
        print(line, flush=True)
        previous = (len(table), r["seconds"])


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [10_000, 100_000, 1_000_000])
