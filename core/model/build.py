"""The whole model for every geozone: what ``bgm build`` and ``bgm demo`` write.

For each geozone: contours, correspondence, trajectories, predictions for one
bench below the deepest bench, a closed surface exported in every format, the
paper's precision/recall evaluation against three references, and a
``report.md`` that summarises it all with the figures embedded.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import shapely

from core.errors import BGMInputError
from core.extraction.contours import Contour
from core.io.atomic import atomic_write_text
from core.io.blastholes import Blastholes
from core.io.reporting import containment_summary, contour_feature, to_input_geometry
from core.model.pipeline import (
    GeozoneModel,
    ModelParameters,
    correspondence_json,
    morph_json,
    pair_coverage,
)
from core.model.prediction import predict_geozone
from core.model.session import (  # noqa: F401 - the surface build's steps, long imported from here
    SURFACE_STEPS_PER_BENCH,
    ModelSession,
    StageStore,
    surface_cell_size,
    surface_sections,
)

#: Depths below the deepest bench at which predictions are written, in bench heights.
PREDICTION_FRACTIONS = tuple(k / 8 for k in range(1, 9))


def truth_sidecar(path: Path) -> Path:
    """Where a synthetic table's truth description lives (``name.truth.json``)."""
    return path.with_name(path.stem + ".truth.json")


def load_truth(path: Path, holes: Blastholes):
    """The true sections of a synthetic table, if its generator left a sidecar; else None.

    The sidecar names the generator and its arguments, either
    ``{"generator": "core.synthetic.demo_dataset", "seed": 2019}`` or
    ``{"generator": "core.synthetic.make_mine", "kwargs": {...}}``.
    Returns a callable ``truth(geozone, z_m)`` in the engine's local frame.
    """
    side = truth_sidecar(Path(path))
    if not side.exists():
        return None
    from core.model.evaluation import truth_from_mine
    from core.synthetic.blobs import demo_dataset, make_mine

    try:
        spec = json.loads(side.read_text())
        if spec.get("generator") == "core.synthetic.demo_dataset":
            mine, _ = demo_dataset(int(spec["seed"]))
        elif spec.get("generator") == "core.synthetic.make_mine":
            mine = make_mine(**spec["kwargs"])
        else:
            raise ValueError(f"unknown generator {spec.get('generator')!r}")
    except (ValueError, KeyError, TypeError) as exc:
        raise BGMInputError(f"truth file {side} is not usable: {exc}") from None
    return truth_from_mine(mine, holes.frame)


def predictor_from_model(model: GeozoneModel, holes: Blastholes, params: ModelParameters):
    """Model predictor for the evaluation protocol, reusing an already built model.

    Each bench pair is modelled from its two benches only, so the pair
    ``(k-1, k)`` of the full model is exactly what a model built on benches
    ``0..k`` would have: nothing withheld leaks in.
    """

    def predict(known: Blastholes, geozone: str, z_targets_m: list[float]):
        k = int(known.bench.max())
        pairs = [p for p in model.pairs if p.lower <= k]
        if not pairs or pairs[-1].lower != k:
            return {z: shapely.MultiPolygon() for z in z_targets_m}
        partial = GeozoneModel(
            model.geozone,
            [c for c in model.contours if c.bench <= k],
            pairs,
            model.minor,
            frontiers=model.frontiers,
            beyond_frontier=model.beyond_frontier,
        )
        return predict_geozone(partial, list(z_targets_m), holes.hole_spacing_m, params)

    return predict


@dataclass
class GeozoneSummary:
    geozone: str
    components: int
    bench_pairs: int
    coverage_before: float
    coverage_after: float
    volume: float | None
    area: float | None
    watertight: bool | None
    files: dict = field(default_factory=dict)
    seconds: float = 0.0
    note: str = ""


def build(
    holes: Blastholes,
    out_dir: Path,
    *,
    geozones: list[str] | None = None,
    params: ModelParameters | None = None,
    project=None,
    truth=None,
    formats=None,
    progress: Callable[[str, int, int], None] | None = None,
    evaluate: bool = True,
    workers: int | None = None,
    scheduler: str | None = None,
    cache=None,
) -> dict:
    """Run the whole pipeline and write every output under ``out_dir``.

    Benches (for contours) and geozones (for everything else) are
    independent: they run in parallel on ``workers`` local processes (all
    cores by default), or on a dask.distributed cluster when ``scheduler``
    gives its address, with identical results. Every stage runs through a
    :class:`~core.model.session.ModelSession`, the viewer's pipeline; with a
    :class:`~core.io.cache.StageCache` as ``cache`` its results are kept on
    disk for the next run.

    Returns the summary that ``report.md`` and ``summary.json`` hold.
    """
    from core.io.export import DEFAULT_FORMATS, write_geojson
    from core.model.evaluation import plot_precision_recall, summary_table

    params = params or ModelParameters()
    formats = formats or DEFAULT_FORMATS
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    wanted = holes.check_geozones(geozones)
    unit = holes.frame.length_unit
    t0 = time.perf_counter()

    session = ModelSession(holes, params, project, StageStore(cache))
    contours = extract_all_benches(session, workers, scheduler, progress)
    write_geojson([contour_feature(c, holes) for c in contours if c.geozone in wanted], out_dir / "contours.geojson")
    containment = containment_summary([c for c in contours if c.geozone in wanted], holes)
    t_contours = time.perf_counter() - t0

    for k in range(holes.n_benches):
        holes.drilled_area(k)  # once, before the workers fork, so they all share it
    ctx = BuildContext(session, contours, truth, out_dir, tuple(formats), evaluate)
    summaries: list[GeozoneSummary] = []
    evaluations = []
    for done, (summary, rows) in enumerate(_map_geozones(ctx, wanted, workers, scheduler), start=1):
        summaries.append(summary)
        if rows is not None and len(rows):
            evaluations.append(rows)
        if progress:
            progress(f"geozone {summary.geozone}", done, len(wanted))
    summaries.sort(key=lambda s: wanted.index(s.geozone))
    table = None
    if evaluations:
        results = pd.concat(evaluations, ignore_index=True)
        results.to_csv(out_dir / "evaluation_rows.csv", index=False)
        table = summary_table(results)
        _write_csv(table, out_dir / "evaluation.csv")
        plot_precision_recall(table, out_dir / "precision_recall.png", title=f"{holes.source}: all geozones")

    summary = {
        "input": holes.source,
        "holes": int(len(holes.xy)),
        "benches": [holes.bench_z_input(k) for k in range(holes.n_benches)],
        "units": unit,
        "hole_spacing": float(holes.frame.length_to_input(holes.hole_spacing_m)),
        "truth": "synthetic generator" if truth is not None else "next bench's holes",
        "contours_seconds": round(t_contours, 2),
        "seconds": round(time.perf_counter() - t0, 2),
        "containment": containment,
        "geozones": [s.__dict__ for s in summaries],
        "evaluation": None if table is None else table.round(4).to_dict(orient="records"),
    }
    atomic_write_text(out_dir / "summary.json", json.dumps(summary, indent=1, default=_json_default))
    atomic_write_text(out_dir / "report.md", report_markdown(summary, table))
    return summary


@dataclass
class BuildContext:
    """What every geozone job needs (shared with worker processes by fork)."""

    session: ModelSession
    contours: list[Contour]
    truth: Callable | None
    out_dir: Path
    formats: tuple
    evaluate: bool


_WORKER_CONTEXT: object = None  # set once per worker process by _init_worker


def _init_worker(ctx) -> None:
    global _WORKER_CONTEXT
    _WORKER_CONTEXT = ctx


def _map_geozones(ctx: BuildContext, geozones: list[str], workers: int | None, scheduler: str | None = None):
    """Yield ``build_geozone`` results as they finish, in parallel where it pays."""
    # Largest geozones first so the last job to start is a short one.
    order = sorted(geozones, key=lambda g: -int(np.sum(ctx.session.holes.geozone == g)))
    yield from _parallel_map(build_geozone, ctx, order, workers, scheduler)


def _parallel_map(func, ctx, items: list, workers: int | None, scheduler: str | None):
    """``func(ctx, item)`` for every item: serially, on local processes, or on a dask cluster."""
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor, as_completed

    if scheduler:
        yield from _dask_map(func, ctx, items, scheduler)
        return
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers <= 1 or len(items) <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        for item in items:
            yield func(ctx, item)
        return
    with ProcessPoolExecutor(
        max_workers=min(workers, len(items)),
        mp_context=multiprocessing.get_context("fork"),
        initializer=_init_worker,
        initargs=(ctx,),
    ) as pool:
        futures = [pool.submit(_call_in_worker, func, item) for item in items]
        for fut in as_completed(futures):
            yield fut.result()


def _dask_map(func, ctx, items: list, scheduler: str):
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise BGMInputError("--scheduler needs dask.distributed: pip install -e '.[dask]'") from None
    try:
        client = Client(scheduler, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise BGMInputError(f"cannot reach the dask scheduler at {scheduler}: {exc}") from None
    try:
        shared = client.scatter(ctx, broadcast=True)
        futures = [client.submit(func, shared, item, pure=False) for item in items]
        for fut in as_completed(futures):
            yield fut.result()
    finally:
        client.close()


def _call_in_worker(func, item):
    return func(_WORKER_CONTEXT, item)


def extract_all_benches(session: ModelSession, workers=None, scheduler=None, progress=None) -> list[Contour]:
    """Contours of every bench, benches in parallel; in bench order whatever order they finish in."""
    holes = session.holes
    by_bench = {}
    for done, (k, contours) in enumerate(
        _parallel_map(_extract_one_bench, session, list(range(holes.n_benches)), workers, scheduler), start=1
    ):
        by_bench[k] = contours
        if progress:
            progress("contours", done, holes.n_benches)
    for k, contours in by_bench.items():  # from worker processes: remembered here (they cached them on disk)
        session.store.put("contours", session._contours_key(k), contours, disk=False)
    return [c for k in sorted(by_bench) for c in by_bench[k]]


def _extract_one_bench(session: ModelSession, k: int):
    return k, session.bench_contours(k)


def build_geozone(ctx: BuildContext, g: str) -> tuple[GeozoneSummary, pd.DataFrame | None]:
    """Everything ``bgm build`` writes for one geozone, under ``out_dir/<geozone>/``."""
    from core.io.export import export_all, write_geojson
    from core.model.evaluation import evaluate_geozone
    from core.model.surfaces import mesh_summary, to_input_frame

    session, out_dir = ctx.session, ctx.out_dir
    holes, params = session.holes, session.params
    mpu = holes.frame.metres_per_unit
    tg = time.perf_counter()
    model = session.geozone_model(g, contours=ctx.contours)
    gdir = out_dir / _safe(g)
    gdir.mkdir(exist_ok=True)
    atomic_write_text(gdir / "correspondence.json", json.dumps(correspondence_json(model, holes), indent=1))
    atomic_write_text(gdir / "morph.json", json.dumps(morph_json(model, holes)))
    cov = [pair_coverage(p) for p in model.pairs if p.morphs]
    after = [a for a, _ in cov if np.isfinite(a)]
    before = [b for _, b in cov if np.isfinite(b)]
    summary = GeozoneSummary(
        geozone=g,
        components=len(model.contours),
        bench_pairs=len(model.pairs),
        coverage_before=float(np.median(before)) if before else float("nan"),
        coverage_after=float(np.median(after)) if after else float("nan"),
        volume=None,
        area=None,
        watertight=None,
    )
    rows = None
    if not model.pairs:
        summary.note = "on one bench only: no bench pair to model"
        summary.seconds = time.perf_counter() - tg
        return summary, rows
    deepest = model.pairs[-1]
    height = deepest.source_z_m - deepest.target_z_m
    zs = [deepest.target_z_m - f * height for f in PREDICTION_FRACTIONS]
    predictions = session.predict(g, zs, model)
    features = [
        {
            "geometry": to_input_geometry(region, holes),
            "properties": {"geozone": g, "z": round(float(holes.frame.z_to_input(z)), 3), "fraction_below": f},
        }
        for (z, region), f in zip(predictions.items(), PREDICTION_FRACTIONS)
        if not region.is_empty
    ]
    write_geojson(features, gdir / "prediction.geojson")
    try:
        mesh = session.surface(g, model)
        info = mesh_summary(mesh)
        exported = export_all(
            to_input_frame(mesh, (holes.frame.origin_x, holes.frame.origin_y), mpu), gdir, "surface", ctx.formats
        )
        summary.volume = info["volume_m3"] / mpu**3
        summary.area = info["area_m2"] / mpu**2
        summary.watertight = bool(info["watertight"])
        summary.files = {k: str(Path(v).relative_to(out_dir)) for k, v in exported.items()}
    except (BGMInputError, RuntimeError) as exc:
        # e.g. every section empty, or a mesh that would not close even after repair: the
        # geozone's other outputs stand, and the report says why it has no surface.
        summary.note = f"no surface: {exc}"
    if ctx.evaluate and holes.n_benches >= 3:
        rows = evaluate_geozone(
            holes, g, predictor_from_model(model, holes, params), truth=ctx.truth, contours=ctx.contours
        )
        if len(rows):
            rows.insert(0, "geozone", g)
    summary.seconds = time.perf_counter() - tg
    return summary, rows


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name) or "geozone"


def _write_csv(df: pd.DataFrame, path: Path) -> None:
    atomic_write_text(path, df.to_csv(index=False))


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, float) and not np.isfinite(o):
        return None
    return str(o)


def report_markdown(summary: dict, table: pd.DataFrame | None) -> str:
    """``report.md``: what was built, how well contours separate geozones, and how well the model predicts."""
    unit = summary["units"]
    lines = [
        "# BGM build report",
        "",
        f"Input: `{summary['input']}`: {summary['holes']} holes on {len(summary['benches'])} benches "
        f"({summary['benches'][0]} to {summary['benches'][-1]} {unit}), hole spacing {summary['hole_spacing']:.2f} {unit}.",
        f"Built in {summary['seconds']:.1f} s (contours {summary['contours_seconds']:.1f} s).",
        "",
        "## Contours",
        "",
    ]
    c = summary["containment"]
    if c.get("contours"):
        lines += [
            f"{c['contours']} contours of {c['min_holes']} or more holes: median {c['holes_inside_median']:.1%} of "
            f"their own holes inside ({c['contours_with_95pct_inside']:.0%} of contours hold at least 95%), median "
            f"{c['other_holes_inside_median']:.1%} other-geozone holes inside "
            f"({c['contours_with_at_most_5pct_other']:.0%} of contours at most 5%).",
            "",
        ]
    lines += [
        "## Geozones",
        "",
        f"| geozone | components | bench pairs | coverage before / after backtracking | volume ({unit}³) | area ({unit}²) | watertight | time (s) | note |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for g in summary["geozones"]:
        vol = "" if g["volume"] is None else f"{g['volume']:.4g}"
        area = "" if g["area"] is None else f"{g['area']:.4g}"
        cov = f"{_pct(g['coverage_before'])} / {_pct(g['coverage_after'])}"
        lines.append(
            f"| {g['geozone']} | {g['components']} | {g['bench_pairs']} | {cov} | {vol} | {area} | "
            f"{'' if g['watertight'] is None else g['watertight']} | {g['seconds']:.1f} | {g['note']} |"
        )
    lines += ["", "Surfaces: `<geozone>/surface.{obj,ply,stl,vtp,dxf}`; trajectories: `<geozone>/morph.json`.", ""]
    if table is not None:
        lines += [
            "## Predictive value",
            "",
            f"Protocol of the paper's Table: for each bench with two known benches above it, everything below is withheld "
            f"and the geozone is predicted at fractions of a bench below it. Truth: {summary['truth']}. Precision and "
            "recall are area-weighted over all geozones and benches (%).",
            "",
            "![precision and recall](precision_recall.png)",
            "",
            _markdown_table(table),
            "",
        ]
    return "\n".join(lines)


def _pct(v) -> str:
    return "" if v is None or not np.isfinite(v) else f"{v:.1%}"


def _markdown_table(table: pd.DataFrame) -> str:
    cols = [c for c in table.columns if c.startswith(("depth", "precision", "recall"))]
    head = "| " + " | ".join(cols) + " |"
    rule = "|" + "---|" * len(cols)
    rows = []
    for _, r in table.iterrows():
        cells = []
        for c in cols:
            v = r[c]
            if c.startswith("depth"):
                cells.append(f"{v:.2f}")
            else:
                cells.append("" if not np.isfinite(v) else f"{100 * v:.1f}")
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join([head, rule, *rows])
