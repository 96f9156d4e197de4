"""Benchmark of boundary extraction (prints figures; not a timed test).

    python tests/benchmarks/bench_extraction.py

* the whole extraction of the Kennecott file (all geozones, all benches),
  when ../shared/data is present, and of the bundled demo;
* the GVF on a 256 x 256 grid: sparse steady-state solve against 200
  explicit iterations, with how far from steady state each ends.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.extraction.contours import extract_contours  # noqa: E402
from core.extraction.gvf import gvf_explicit, gvf_residual, gvf_steady_state  # noqa: E402
from core.io.blastholes import read_blastholes  # noqa: E402
from core.io.reporting import containment_summary  # noqa: E402

KENNECOTT = ROOT.parent / "shared" / "data" / "kennecott-blastholes" / "blastholes_tagged.csv"


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


if __name__ == "__main__":
    bench_gvf()
    bench_file(ROOT / "assets" / "demo_blastholes.csv")
    if KENNECOTT.exists():
        bench_file(KENNECOTT)
    else:
        print(f"Kennecott data not found at {KENNECOTT}; skipped")
