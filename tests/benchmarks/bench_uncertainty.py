"""Calibration of the uncertainty band, and the value of suggested holes, on every synthetic family and on Kennecott.

    python tests/benchmarks/bench_uncertainty.py [--seeds 8] [--tuning] [--workers 2] [--no-kennecott] [--between]

Calibration (:mod:`core.model.uncertainty`): for every non-host geozone and
every bench ``k + 1`` with at least two benches above it, the benches down to
``k`` are known (each bench's contours are extracted from its own holes only,
so nothing below ``k`` leaks in) and the section at ``k + 1`` is predicted
with its 90% band, calibrated on the known benches' own backtest (pooled with
the other geozones' when too short). Coverage is the share of points of the
true boundary at ``k + 1`` (the generator's exact section, inside the bench's
drilled area; on Kennecott the boundary of the contours extracted from the
bench's holes) that fall inside the band; the target is 85-95%. "Of the holes'
boundary" is the same share for the boundary of the contours extracted from
bench ``k + 1``'s holes, the boundary the band is calibrated on (it is what
backtests can measure) and, on real data, the only one there is. Band width is
the median width across the predicted boundary inside the drilled area.

Value of suggestions (:mod:`core.model.sampling`): the deepest two benches are
hidden in turn. Their holes are the planned pattern; ``N`` of them (5, 10 and
20% of the bench's holes) are revealed, chosen by ``suggest_holes`` (all
non-host geozones sharing the budget), at random (mean of three draws) or on a
regular sub-grid. The bench is then estimated from the benches above plus the
revealed labels (:func:`core.model.sampling.revealed_field`, the same
estimator for every strategy) and scored by IoU against the truth inside the
bench's drilled area (pooled over geozones: summed intersections over summed
unions). ``0%`` is the prediction alone.

``--between`` adds the band half-way between benches (synthetic only): the
section of the paper's trajectories, its band combined from the extrapolations
from above and from below, each calibrated on its own direction's backtest,
scored against the true section there inside both benches' drilled areas.

Seeds: the first ``--seeds`` held-out seeds of each family
(:data:`core.synthetic.scenarios.HELD_OUT_SEEDS`, all eight by default: with two, a family's
coverage rests on 20-30 sections and moved by up to 3 points from one change to the next);
``--tuning`` uses tuning seeds.
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
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from kennecott_data import KENNECOTT  # noqa: E402

from core.io.blastholes import BGMWarning, blastholes_from_table, read_blastholes  # noqa: E402
from core.model.sampling import revealed_field, suggest_holes  # noqa: E402
from core.model.session import ModelSession  # noqa: E402
from core.model.uncertainty import (  # noqa: E402
    backtest,
    band_width_m,
    boundary_points,
    noise_ring_area_m2,
    section_uncertainty,
)
from core.synthetic.blobs import HOST  # noqa: E402
from core.synthetic.scenarios import FAMILIES, HELD_OUT_SEEDS, TUNING_SEEDS, scenario  # noqa: E402

PROBABILITY = 0.9
BUDGETS = (0.05, 0.10, 0.20)
RANDOM_DRAWS = 3


def true_boundary_points(region, drilled_area, step_m: float) -> np.ndarray:
    """Points every ``step_m`` along a true section's boundary, inside the drilled area, ``(n, 2)``."""
    lines = region.boundary
    if lines.is_empty:
        return np.zeros((0, 2))
    parts = getattr(lines, "geoms", [lines])
    out = []
    for line in parts:
        k = max(int(line.length / step_m), 1)
        pts = shapely.line_interpolate_point(line, np.linspace(0, line.length, k, endpoint=False))
        out.append(shapely.get_coordinates(pts))
    xy = np.concatenate(out) if out else np.zeros((0, 2))
    inner = drilled_area.buffer(-step_m)
    return xy[shapely.contains_xy(inner, xy[:, 0], xy[:, 1])]


class Case:
    """One input: its holes, every geozone's bench fields, and the truth of a bench (synthetic or extracted)."""

    def __init__(self, holes, mine=None):
        self.holes, self.mine = holes, mine
        self.session = session = ModelSession(holes)
        contours = session.contours()
        self.geozones = [g for g in holes.geozones if g != HOST] if mine is not None else list(holes.geozones)
        self.fields = {
            g: session.bench_fields(g, [c for c in contours if c.geozone == g]) for g in holes.geozones if g != HOST
        }
        self.spacing = float(holes.hole_spacing_m)

    def truth(self, g: str, k: int):
        """True section of ``g`` on bench ``k`` (local metres), clipped to the bench's drilled area."""
        area = self.holes.drilled_area(k)
        z = float(self.holes.bench_levels_m[k])
        if self.mine is not None:
            return self.mine.section_in(self.holes.frame, g, z).intersection(area)
        f = self.fields[g]
        j = int(np.argmin(np.abs(f.z_m - z)))
        region = f.grid.polygons_from_field(f.distance[j], 0.0) if (f.distance[j] > 0).any() else shapely.Polygon()
        return region.intersection(area)

    def section(self, g: str, k: int):
        """The section of ``g`` on bench ``k + 1`` predicted from benches down to ``k``, with its band."""
        z_known = float(self.holes.bench_levels_m[k])
        known = self.fields[g].through(z_known)
        height = float(np.median(-np.diff(known.z_m)))

        def pooled():
            return [backtest(self.fields[o].through(z_known), height, self.spacing) for o in self.fields if o != g]

        return section_uncertainty(known, float(self.holes.bench_levels_m[k + 1]), self.spacing, PROBABILITY, pooled)


def calibration_rows(case: Case) -> list[dict]:
    rows = []
    holes = case.holes
    for g in case.geozones:
        for k in range(1, holes.n_benches - 1):
            section = case.section(g, k)
            if section is None:
                continue
            area = holes.drilled_area(k + 1)
            # The boundary the next bench's holes show (its extracted contours): what the band is
            # calibrated on, and the only truth real data has.
            f = case.fields[g]
            seen = boundary_points(f.distance[k + 1], f.drilled[k + 1], f.grid, noise_ring_area_m2(case.spacing))
            if case.mine is not None:
                pts = true_boundary_points(case.truth(g, k + 1), area, section.grid.cell_size_m)
            else:
                pts = seen
            if not len(pts):
                continue
            rows.append(
                {
                    "geozone": g,
                    "bench": k + 1,
                    "points": len(pts),
                    "inside": int(section.in_band(pts).sum()),
                    "seen_points": len(seen),
                    "seen_inside": int(section.in_band(seen).sum()) if len(seen) else 0,
                    "width_m": band_width_m(section, area),
                    "source": section.scale.source,
                }
            )
    return rows


def between_rows(case: Case) -> list[dict]:
    """Coverage of the band half-way between benches (synthetic only; ``--between``).

    There the section comes from the paper's trajectories and the band combines
    the extrapolations from the bench above and the bench below, each
    calibrated on its own direction's backtest (what ``bgm build`` writes).
    """
    holes, rows = case.holes, []
    height = float(np.median(-np.diff(holes.bench_levels_m)))
    for g in case.geozones:
        model = case.session.geozone_model(g)
        for k in range(holes.n_benches - 1):
            z = float(holes.bench_levels_m[k]) - height / 2
            region = case.session.predict(g, [z], model)[z]
            section = section_uncertainty(model.fields, z, case.spacing, PROBABILITY, region=region)
            area = holes.drilled_area(k).intersection(holes.drilled_area(k + 1))
            truth = case.mine.section_in(holes.frame, g, z).intersection(area)
            pts = true_boundary_points(truth, area, section.grid.cell_size_m) if section is not None else []
            if len(pts):
                inside = int(section.in_band(pts).sum())
                rows.append(
                    {
                        "geozone": g,
                        "bench": k,
                        "points": len(pts),
                        "inside": inside,
                        "width_m": band_width_m(section, area),
                    }
                )
    return rows


def regular_subset(xy: np.ndarray, n: int, area, rng) -> np.ndarray:
    """About ``n`` holes on a regular sub-grid: the holes nearest to a square lattice of ``sqrt(area / n)``."""
    step = np.sqrt(area.area / max(n, 1))
    x0, y0, x1, y1 = area.bounds
    gx, gy = np.meshgrid(np.arange(x0 + step / 2, x1, step), np.arange(y0 + step / 2, y1, step))
    nodes = np.column_stack([gx.ravel(), gy.ravel()])
    nodes = nodes[shapely.contains_xy(area, nodes[:, 0], nodes[:, 1])]
    picked = np.unique(cKDTree(xy).query(nodes)[1]) if len(nodes) else np.zeros(0, int)
    if len(picked) > n:
        picked = rng.choice(picked, n, replace=False)
    elif len(picked) < n:
        rest = np.setdiff1d(np.arange(len(xy)), picked)
        picked = np.concatenate([picked, rng.choice(rest, n - len(picked), replace=False)])
    return picked


def value_rows(case: Case, hidden: int) -> list[dict]:
    """IoU of the hidden bench for each strategy and budget (see the module docstring)."""
    holes = case.holes
    k = hidden - 1
    on = holes.on_bench(hidden)
    xy, labels = holes.xy[on], holes.geozone[on]
    area = holes.drilled_area(hidden)
    sections = {g: s for g in case.geozones if (s := case.section(g, k)) is not None}
    if not sections or len(xy) < 20:
        return []
    grid = next(iter(sections.values())).grid
    drilled = grid.rasterize(area)
    truth = {g: grid.rasterize(case.truth(g, hidden)) & drilled for g in sections}
    if not any(t.any() for t in truth.values()):
        return []
    rng = np.random.default_rng(hidden)

    def iou(chosen: np.ndarray) -> float:
        inter = union = 0
        for g, s in sections.items():
            est = (revealed_field(s, xy[chosen], labels[chosen] == g, case.spacing) > 0) & drilled
            inter += int(np.sum(est & truth[g]))
            union += int(np.sum(est | truth[g]))
        return inter / union if union else float("nan")

    rows = [{"hidden": hidden, "budget": 0.0, "strategy": s, "iou": iou(np.zeros(0, int))} for s in STRATEGIES]
    for share in BUDGETS:
        n = max(int(round(share * len(xy))), 1)
        suggested = np.array([s.candidate for s in suggest_holes(sections, xy, n, case.spacing)], int)
        random = np.mean([iou(rng.choice(len(xy), n, replace=False)) for _ in range(RANDOM_DRAWS)])
        rows += [
            {"hidden": hidden, "budget": share, "strategy": "suggested", "iou": iou(suggested)},
            {"hidden": hidden, "budget": share, "strategy": "random", "iou": float(random)},
            {"hidden": hidden, "budget": share, "strategy": "sub-grid", "iou": iou(regular_subset(xy, n, area, rng))},
        ]
    return rows


STRATEGIES = ("suggested", "random", "sub-grid")


def run(job: tuple[str, int, bool]) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, float]:
    family, seed, between = job
    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        if family == "kennecott":
            case = Case(read_blastholes(KENNECOTT))
        else:
            mine, table, _ = scenario(family, seed)
            case = Case(blastholes_from_table(table, source=f"{family} {seed}"), mine)
        calibration = pd.DataFrame(calibration_rows(case))
        n = case.holes.n_benches
        value = pd.DataFrame([r for hidden in (n - 2, n - 1) for r in value_rows(case, hidden)])
        halfway = pd.DataFrame(between_rows(case) if between and case.mine is not None else [])
    for df in (calibration, value, halfway):
        df.insert(0, "seed", seed)
        df.insert(0, "family", family)
    return calibration, value, halfway, time.process_time() - start


def calibration_table(df: pd.DataFrame) -> pd.DataFrame:
    out = []
    for family, part in df.groupby("family", sort=False):
        out.append(
            {
                "family": family,
                "sections": len(part),
                "boundary points": int(part["points"].sum()),
                "coverage %": round(100 * part["inside"].sum() / part["points"].sum(), 1),
                "of the holes' boundary %": round(
                    100 * part["seen_inside"].sum() / max(part["seen_points"].sum(), 1), 1
                ),
                "median band width m": round(float(np.nanmedian(part["width_m"])), 1),
                "own calibration %": round(100 * float(np.mean(part["source"] == "own backtest")), 0),
            }
        )
    return pd.DataFrame(out)


def value_table(df: pd.DataFrame) -> pd.DataFrame:
    table = df.groupby(["budget", "strategy"])["iou"].mean().unstack("strategy")[list(STRATEGIES)]
    table.index = [f"{100 * b:.0f}%" for b in table.index]
    return (100 * table).round(1)


def half_budget_verdict(table: pd.DataFrame) -> list[str]:
    """Does the suggested set reach the best other strategy's IoU with half the budget?"""
    lines = []
    for low, high in (("5%", "10%"), ("10%", "20%")):
        if low in table.index and high in table.index:
            best = max(table.loc[high, "random"], table.loc[high, "sub-grid"])
            ours = table.loc[low, "suggested"]
            lines.append(
                f"  suggested at {low}: {ours:.1f}  vs best of random / sub-grid at {high}: {best:.1f}  "
                f"-> {'reached' if ours >= best else 'not reached'}"
            )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--seeds", type=int, default=len(HELD_OUT_SEEDS), help="seeds per family (default: all held out)"
    )
    parser.add_argument("--tuning", action="store_true", help="run on tuning seeds instead of the held-out ones")
    parser.add_argument("--families", default=",".join(FAMILIES))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--no-kennecott", action="store_true")
    parser.add_argument(
        "--between", action="store_true", help="also the band half-way between benches (runs the whole pipeline)"
    )
    args = parser.parse_args()
    seeds = (TUNING_SEEDS if args.tuning else HELD_OUT_SEEDS)[: args.seeds]
    families = [f for f in args.families.split(",") if f]
    jobs = [(f, s, args.between) for f in families for s in seeds]
    if not args.no_kennecott and KENNECOTT.exists():
        jobs.insert(0, ("kennecott", 0, False))
    elif not args.no_kennecott:
        print(f"Kennecott data not found at {KENNECOTT}: skipped")
    start = time.perf_counter()
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        results = pool.map(run, jobs, chunksize=1)
    calibration = pd.concat([r[0] for r in results], ignore_index=True)
    value = pd.concat([r[1] for r in results], ignore_index=True)
    print(f"Seeds: {'tuning' if args.tuning else 'held-out'} {list(seeds)}; band probability {PROBABILITY:.0%}")
    print("\nCalibration (target coverage 85-95%):")
    table = calibration_table(calibration)
    synthetic = calibration[calibration["family"] != "kennecott"]
    if len(synthetic):
        pooled = calibration_table(synthetic.assign(family="all synthetic"))
        table = pd.concat([table, pooled], ignore_index=True)
    print(table.to_string(index=False))
    halfway = pd.concat([r[2] for r in results], ignore_index=True)
    if len(halfway):
        print("\nCalibration half-way between benches (the band from both sides):")
        rows = [("all synthetic", halfway), *halfway.groupby("family", sort=False)]
        for family, part in rows:
            coverage = 100 * part["inside"].sum() / part["points"].sum()
            width = float(np.nanmedian(part["width_m"]))
            print(f"  {family:13s} {len(part):4d} sections  coverage {coverage:5.1f}%  median width {width:.1f} m")
    for family, part in (
        ("all synthetic", value[value["family"] != "kennecott"]),
        ("kennecott", value[value["family"] == "kennecott"]),
    ):
        if part.empty:
            continue
        print(
            f"\nValue of suggestions, {family} (IoU %, hidden bench estimated from the benches above + revealed holes):"
        )
        t = value_table(part)
        print(t.to_string())
        print("\n".join(half_budget_verdict(t)))
    if len(value):
        print("\nPer family (IoU %, suggested / random / sub-grid):")
        for family, part in value[value["family"] != "kennecott"].groupby("family", sort=False):
            t = value_table(part)
            cells = [f"{i}: {r['suggested']:.1f}/{r['random']:.1f}/{r['sub-grid']:.1f}" for i, r in t.iterrows()]
            print(f"  {family:9s} " + "  ".join(cells))
    cpu = sum(r[3] for r in results)
    print(f"\nWall {time.perf_counter() - start:.0f} s, CPU {cpu:.0f} s on {args.workers} workers, {len(jobs)} inputs.")


if __name__ == "__main__":
    main()
