"""Benchmark of `bgm build`: time and peak memory on the demo and the Kennecott file.

    python tests/benchmarks/bench_build.py

Target: the whole Kennecott build under 60 s and 2 GB on 2 cores.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _measure import run_measured  # noqa: E402

KENNECOTT = ROOT.parent / "shared" / "data" / "kennecott-blastholes" / "blastholes_tagged.csv"
BGM = [sys.executable, "-c", "from core.cli import main; main()"]


def bench(name: str, path: Path) -> None:
    with tempfile.TemporaryDirectory() as out:
        r = run_measured([*BGM, "build", str(path), "--out", out])
        status = "ok" if r["returncode"] == 0 else f"FAILED ({r['returncode']}): {r['stderr'][-300:]}"
        print(f"{name}: bgm build {r['seconds']:.1f} s, peak memory {r['peak_gb']:.2f} GB (all processes) - {status}")


if __name__ == "__main__":
    bench("demo", ROOT / "assets" / "demo_blastholes.csv")
    if KENNECOTT.exists():
        bench("kennecott", KENNECOTT)
    else:
        print(f"Kennecott data not found at {KENNECOTT}; skipped")
