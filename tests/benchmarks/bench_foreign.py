"""Prediction on geology the synthetic families do not make: travelling waves, drifting bodies, faulted layers.

    python tests/benchmarks/bench_foreign.py [--seeds 24] [--speed 1.0] [--noise 0.03] [--drift LO HI | --faults]
                                             [--workers 2]

Every default of the engine was chosen on :mod:`core.synthetic.families`, whose
geozones are built from layers, folds, lobes and lenses that move as wholes.
This benchmark draws its geology from a different generator, written here and
used for nothing else: each of two geozones is where a sum of six plane waves
exceeds its 70th percentile, and each wave travels across the pit with depth at
its own rate (``--speed`` times 1-10 m per 10 m bench, either way). Bodies
therefore change shape, split, merge, appear and vanish from bench to bench
without any of them moving as a whole, as real alteration and lithology
contacts do. With ``--drift LO HI`` the waves stand still and each geozone's
whole pattern translates with depth instead, LO-HI metres per metre in a
direction of its own: bodies of any shape dipping steadily, where linear
extrapolation of the true sections is near exact. With ``--faults`` the
geology is two parallel layers dipping steadily and offset across a steep
fault (:func:`faulted_layers`): sections that jog where the fault crosses a
bench, the jog moving along the layers with depth. Holes on a staggered
pattern (7 m, jittered 0.4 m), benches of 10 m, the pit narrowing 4 m a side
per bench, ``--noise`` of the labels drawn at random. The protocol is :mod:`bench_prediction`'s (each bench with one below it
is the deepest known; 5 and 10 m below it scored by area against the true
section inside the next bench's drilled area), and besides the three
references it scores the linear extrapolation of the *true* sections of the
last two benches, which no method has: how much a first-order trend could give
with perfect boundaries.

No default is tuned on it, so every seed is unseen.
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from shapely import affinity

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_prediction import METHODS, REFERENCES, TRUE_LINEAR, evaluate, f1, with_true_linear  # noqa: E402

from core.geometry.grid import Grid  # noqa: E402
from core.io.blastholes import BGMWarning, blastholes_from_table  # noqa: E402
from core.model.evaluation import summary_table  # noqa: E402

SIDE_M, BENCH_M, BENCHES, WAVES = 240.0, 10.0, 7, 6


@dataclass
class Waves:
    """Plane waves ``a cos(2 pi (u . xy - c z) / wavelength + phase)`` travelling ``c`` metres per metre of depth."""

    direction: np.ndarray  #: (k, 2) unit vectors
    wavelength_m: np.ndarray
    speed: np.ndarray
    phase: np.ndarray
    amplitude: np.ndarray
    drift: np.ndarray  #: (2,) metres the whole pattern moves per metre of depth

    @classmethod
    def draw(cls, rng: np.random.Generator, speed: float, drift: tuple[float, float] | None = None) -> Waves:
        angle = rng.uniform(0, 2 * np.pi, WAVES)
        waves = cls(
            np.column_stack([np.cos(angle), np.sin(angle)]),
            rng.uniform(70.0, 220.0, WAVES),
            (0.0 if drift else speed) * rng.uniform(0.1, 1.0, WAVES) * rng.choice([-1.0, 1.0], WAVES),
            rng.uniform(0, 2 * np.pi, WAVES),
            rng.uniform(0.5, 1.0, WAVES),
            np.zeros(2),
        )
        if drift:  # drawn after the waves, so a seed's waves are the same with or without it
            heading, rate = rng.uniform(0, 2 * np.pi), rng.uniform(*drift)
            waves.drift = rate * np.array([np.cos(heading), np.sin(heading)])
        return waves

    def __call__(self, x, y, z):
        x, y = x + self.drift[0] * z, y + self.drift[1] * z  # z falls with depth
        total = 0.0
        for u, lam, c, phi, a in zip(self.direction, self.wavelength_m, self.speed, self.phase, self.amplitude):
            total = total + a * np.cos(2 * np.pi * (u[0] * x + u[1] * y - c * z) / lam + phi)
        return total


def foreign_mine(
    seed: int, speed: float, noise: float, spacing_m: float = 7.0, drift: tuple[float, float] | None = None
):
    """The holes table and ``{geozone: f(x, y, z)}``, positive inside (g2 is where g1 is not)."""
    rng = np.random.default_rng(seed)
    waves1, waves2 = Waves.draw(rng, speed, drift), Waves.draw(rng, speed, drift)
    X, Y = np.meshgrid(np.linspace(0, SIDE_M, 121), np.linspace(0, SIDE_M, 121))
    t1, t2 = np.quantile(waves1(X, Y, 0.0), 0.70), np.quantile(waves2(X, Y, 0.0), 0.72)

    def g1(x, y, z):
        return waves1(x, y, z) - t1

    def g2(x, y, z):
        return np.minimum(waves2(x, y, z) - t2, -g1(x, y, z))

    return drilled(rng, g1, g2, noise, spacing_m), {"g1": g1, "g2": g2}


def faulted_layers(seed: int, speed: float, noise: float, spacing_m: float = 7.0):
    """Two parallel layers dipping steadily, offset across a steep fault: the table and ``{geozone: f}``.

    The layers are 15-35 m wide, 10-40 m apart, and move ``speed`` times 3-12 m
    across their strike a 10 m bench; the fault strikes 45-135 degrees off
    them, dips 60-85 degrees (its trace moves 1-6 m a bench) and throws them
    15-40 m along their normal, so each bench's sections jog where it crosses.
    """
    rng = np.random.default_rng(seed)
    strike = rng.uniform(0, np.pi)
    normal = np.array([-np.sin(strike), np.cos(strike)])
    rate = speed * rng.uniform(0.3, 1.2) * rng.choice([-1.0, 1.0])  # metres across the strike per metre of depth
    fault_strike = strike + rng.uniform(np.pi / 4, 3 * np.pi / 4)
    fault_normal = np.array([-np.sin(fault_strike), np.cos(fault_strike)])
    fault_rate = rng.choice([-1.0, 1.0]) / np.tan(np.radians(rng.uniform(60.0, 85.0)))
    throw = rng.uniform(15.0, 40.0) * rng.choice([-1.0, 1.0])
    widths, gap, offset = rng.uniform(15.0, 35.0, 2), rng.uniform(10.0, 40.0), rng.uniform(-40.0, 40.0)
    centre = SIDE_M / 2

    def across(x, y, z):
        side = np.sign((x - centre) * fault_normal[0] + (y - centre) * fault_normal[1] - fault_rate * z)
        return (x - centre) * normal[0] + (y - centre) * normal[1] - rate * z - side * throw / 2 - offset

    def g1(x, y, z):
        return widths[0] / 2 - np.abs(across(x, y, z))

    def g2(x, y, z):
        return widths[1] / 2 - np.abs(across(x, y, z) - (widths[0] / 2 + gap + widths[1] / 2))

    return drilled(rng, g1, g2, noise, spacing_m), {"g1": g1, "g2": g2}


def drilled(rng: np.random.Generator, g1, g2, noise: float, spacing_m: float) -> pd.DataFrame:
    """Holes of the narrowing pit labelled by ``g1`` and ``g2`` (positive inside), ``noise`` of them at random."""
    rows = []
    for b in range(BENCHES):
        inset = 4.0 * b
        for r, y in enumerate(np.arange(inset, SIDE_M - inset, spacing_m * np.sqrt(3) / 2)):
            for x in np.arange(inset + (spacing_m / 2 if r % 2 else 0.0), SIDE_M - inset, spacing_m):
                rows.append((x, y, -b * BENCH_M))
    xyz = np.asarray(rows)
    xyz[:, :2] += rng.normal(0.0, 0.4, (len(xyz), 2))
    label = np.where(g1(*xyz.T) > 0, "g1", np.where(g2(*xyz.T) > 0, "g2", "host"))
    flip = rng.random(len(xyz)) < noise
    label[flip] = rng.choice(["g1", "g2", "host"], int(flip.sum()))
    xyz[:, 2] += rng.uniform(-0.5, 0.5, len(xyz))
    table = pd.DataFrame({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "geozone": label})
    table["hole_id"] = [f"H{i:06d}" for i in range(len(table))]
    return table


def run_seed(job: tuple[int, float, float, tuple[float, float] | None, bool]) -> pd.DataFrame:
    """Evaluate one seed: ``(seed, speed, noise, drift, faults)``."""
    seed, speed, noise, drift, faults = job
    table, fields = faulted_layers(seed, speed, noise) if faults else foreign_mine(seed, speed, noise, drift=drift)
    fine = Grid(0.0, 0.0, 1.0, (int(SIDE_M) + 1, int(SIDE_M) + 1))
    X, Y = fine.cell_centres()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = blastholes_from_table(table, source=f"foreign {seed}")
    frame = holes.frame

    def truth(geozone: str, z_m: float):
        section = fine.polygons_from_field(fields[geozone](X, Y, z_m), 0.0)
        return affinity.translate(section, -frame.origin_x, -frame.origin_y)

    with with_true_linear(truth), warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        df = evaluate(holes, truth, ["g1", "g2"])
    df.insert(0, "seed", seed)
    return df


def print_table(df: pd.DataFrame) -> None:
    summary = summary_table(df)
    for _, r in summary.iterrows():
        scores = {m: f1(r[f"precision_{m}"], r[f"recall_{m}"]) for m in (*METHODS, TRUE_LINEAR)}
        best = max(REFERENCES, key=lambda m: scores[m])
        cases = len(df[df["fraction"] == r["fraction"]]) // len(scores)
        print(f"\n{r['depth_m']:.0f} m below the deepest bench ({cases} cases):")
        for m in (*METHODS, TRUE_LINEAR):
            p, rec = r[f"precision_{m}"], r[f"recall_{m}"]
            print(f"  {m:22s} precision {100 * p:5.1f}  recall {100 * rec:5.1f}  F1 {100 * scores[m]:5.1f}")
        print(f"  model F1 margin over the best reference ({best}): {100 * (scores['model'] - scores[best]):+.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=24)
    parser.add_argument("--speed", type=float, default=1.0, help="Scale of the waves' movement with depth.")
    parser.add_argument("--noise", type=float, default=0.03, help="Share of labels drawn at random.")
    parser.add_argument(
        "--drift",
        type=float,
        nargs=2,
        metavar=("LO", "HI"),
        help="Waves stand still; each geozone's pattern moves LO-HI m per m of depth (e.g. 0.3 1.2).",
    )
    parser.add_argument(
        "--faults",
        action="store_true",
        help="Two dipping layers offset across a steep fault instead of waves (--speed scales their movement).",
    )
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    if args.faults and args.drift:
        parser.error("--faults and --drift are two different geologies: choose one")
    start = time.perf_counter()
    drift = tuple(args.drift) if args.drift else None
    jobs = [(s, args.speed, args.noise, drift, args.faults) for s in range(args.seeds)]
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        df = pd.concat(pool.map(run_seed, jobs), ignore_index=True)
    movement = f"drift {drift[0]:g}-{drift[1]:g} m per m of depth" if drift else f"speed {args.speed}"
    geology = "faulted layers" if args.faults else "waves"
    print(f"Foreign geology ({geology}): {args.seeds} seeds, {movement}, label noise {args.noise:.0%}")
    print_table(df)
    print(f"\nWall time {time.perf_counter() - start:.0f} s on {args.workers} processes")


if __name__ == "__main__":
    main()
