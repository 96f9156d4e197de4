"""Benchmark of the stage cache: a repeated command on the same input (prints figures).

    python tests/benchmarks/bench_cache.py [--geozone 3310] [INPUT]

Runs ``bgm predict`` for one geozone three times on a fresh, empty cache: the
first call computes and stores every stage, the second reads them back, the
third runs with ``--no-cache``. Then ``bgm correspond`` and ``bgm morph`` on
the warm cache. Default input: the Kennecott table (or the demo without it).

Target (issue 13): on Kennecott, the second ``bgm predict`` of one geozone
under 2 s; the first no slower than without a cache.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measure import run_measured  # noqa: E402
from kennecott_data import KENNECOTT  # noqa: E402

BGM = [sys.executable, "-c", "from core.cli import main; main()"]


def bench(path: Path, geozone: str, elevations: str) -> None:
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        os.environ["BGM_CACHE_DIR"] = cache
        predict = [*BGM, "predict", str(path), "--geozone", geozone, "--elevations", elevations]
        runs = {
            "predict, first call (empty cache)": predict + ["--out", f"{out}/1.geojson"],
            "predict, second call": predict + ["--out", f"{out}/2.geojson"],
            "predict --no-cache": predict + ["--out", f"{out}/3.geojson", "--no-cache"],
            "correspond after predict": [*BGM, "correspond", str(path), "--geozone", geozone, "--out", f"{out}/c.json"],
            "morph after predict": [*BGM, "morph", str(path), "--geozone", geozone, "--out", f"{out}/m.json"],
        }
        for name, cmd in runs.items():
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            r = run_measured(cmd)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
            status = "ok" if r["returncode"] == 0 else f"FAILED ({r['returncode']}): {r['stderr'][-300:]}"
            print(f"{path.name}, geozone {geozone}: bgm {name}: {r['seconds']:.2f} s ({cpu:.2f} s CPU) - {status}")
        print(f"  load average while measuring: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        same = Path(f"{out}/1.geojson").read_bytes() == Path(f"{out}/2.geojson").read_bytes()
        same &= Path(f"{out}/1.geojson").read_bytes() == Path(f"{out}/3.geojson").read_bytes()
        size = sum(p.stat().st_size for p in Path(cache).rglob("*.pkl")) / 1e6
        print(f"  outputs identical: {same}; cache holds {size:.1f} MB")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("input", nargs="?", type=Path)
    ap.add_argument("--geozone", default=None)
    ap.add_argument("--elevations", default=None, help="input units (default: one and two benches below the deepest)")
    args = ap.parse_args()
    path = args.input or (KENNECOTT if KENNECOTT.exists() else ROOT / "assets" / "demo_blastholes.csv")
    kennecott = path == KENNECOTT
    geozone = args.geozone or ("3310" if kennecott else "g2")
    elevations = args.elevations or ("250,240,230" if kennecott else "620,615")
    bench(path, geozone, elevations)
