"""Benchmark of `bgm build` and of one geozone's `bgm predict`: time and peak memory on the demo and Kennecott.

    python tests/benchmarks/bench_build.py

Target: the whole Kennecott build under 60 s and 2 GB on 2 cores. A single
geozone's prediction, on a fresh cache, traces only that geozone's contours.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measure import run_measured  # noqa: E402
from kennecott_data import KENNECOTT  # noqa: E402

BGM = [sys.executable, "-c", "from core.cli import main; main()"]


def _status(r: dict) -> str:
    return "ok" if r["returncode"] == 0 else f"FAILED ({r['returncode']}): {r['stderr'][-300:]}"


def bench(name: str, path: Path) -> None:
    # A fresh stage cache (core.io.cache): the first build computes everything, the second reuses it.
    with tempfile.TemporaryDirectory() as out, tempfile.TemporaryDirectory() as cache:
        os.environ["BGM_CACHE_DIR"] = cache
        for run in ("", ", again on its cache"):
            r = run_measured([*BGM, "build", str(path), "--out", out])
            print(
                f"{name}: bgm build{run} {r['seconds']:.1f} s, peak memory {r['peak_gb']:.2f} GB (all processes)"
                f" - {_status(r)}"
            )


def bench_predict(name: str, path: Path, geozone: str, elevations: str) -> None:
    """One geozone's ``bgm predict`` on a fresh stage cache (what a script calling it per geozone pays)."""
    with tempfile.TemporaryDirectory() as out, tempfile.TemporaryDirectory() as cache:
        os.environ["BGM_CACHE_DIR"] = cache
        args = ["predict", str(path), "--geozone", geozone, "--elevations", elevations, "--out", f"{out}/p.geojson"]
        r = run_measured([*BGM, *args])
        print(
            f"{name}: bgm predict --geozone {geozone} {r['seconds']:.1f} s, peak {r['peak_gb']:.2f} GB - {_status(r)}"
        )


if __name__ == "__main__":
    bench("demo", ROOT / "assets" / "demo_blastholes.csv")
    bench_predict("demo", ROOT / "assets" / "demo_blastholes.csv", "g1", "620,615")
    if KENNECOTT.exists():
        bench("kennecott", KENNECOTT)
        bench_predict("kennecott", KENNECOTT, "3310", "243,218")
    else:
        print(f"Kennecott data not found at {KENNECOTT}; skipped")
