"""The ``bgm`` command line: the engine for batch use.

Every command reads a blasthole table (CSV or Parquet), finds its columns and
benches, and writes results in the input's own coordinates. Bad input ends in
one line naming the problem and exit status 2, never a traceback.
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from core.errors import BGMInputError

app = typer.Typer(
    name="bgm",
    help="Boundary Geometry Modeler: geozone boundaries, surfaces and slope predictions from labelled blastholes.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)

ASSETS = Path(__file__).resolve().parent.parent / "assets"
DEMO_CSV = ASSETS / "demo_blastholes.csv"

# Options shared by every command that reads blastholes.
XOpt = Annotated[str | None, typer.Option("--x", help="Column holding x (default: x/east/easting, any case).")]
YOpt = Annotated[str | None, typer.Option("--y", help="Column holding y (default: y/north/northing).")]
ZOpt = Annotated[str | None, typer.Option("--z", help="Column holding elevation (default: z/rl/elevation/elev/mid_z).")]
GeozoneColOpt = Annotated[
    str | None,
    typer.Option(
        "--geozone-column", help="Column holding the geozone label (default: geozone/domain/lookup_domain/label/zone)."
    ),
]
BenchHeightOpt = Annotated[
    float | None, typer.Option("--bench-height", help="Bench height in input units (default: detected from z).")
]
UnitsOpt = Annotated[
    str | None,
    typer.Option("--units", help="Length unit of the input, m or ft (default: guessed from the bench height)."),
]
InputArg = Annotated[Path, typer.Argument(help="Blasthole table (CSV or Parquet).", show_default=False)]
NoCacheOpt = Annotated[
    bool,
    typer.Option(
        "--no-cache", help="Compute every stage afresh instead of reusing results kept from earlier runs on this input."
    ),
]


def _say(message: str) -> None:
    typer.echo(message, err=True)


def _load(input: Path, x, y, z, geozone_column, bench_height, units):
    from core.io.blastholes import read_blastholes

    holes = read_blastholes(input, x=x, y=y, z=z, geozone=geozone_column, bench_height=bench_height, length_unit=units)
    unit = holes.frame.length_unit
    spacing = f"hole spacing {holes.frame.length_to_input(holes.hole_spacing_m):.2f} {unit}"
    if holes.n_benches == 1:
        benches = f"1 bench at {holes.bench_z_input(0)} {unit}"
    else:
        height = holes.frame.length_to_input(holes.bench_height_m)
        benches = (
            f"{holes.n_benches} benches ({holes.bench_z_input(0)} to {holes.bench_z_input(holes.n_benches - 1)} {unit}, "
            f"bench height {height:.1f} {unit})"
        )
    _say(f"{input}: {len(holes.xy)} holes, {len(holes.geozones)} geozones, {benches}, {spacing}")
    return holes


def _progress(description: str, total: int):
    """A rich progress bar on stderr; returns (callback, context manager)."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    progress = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=False,
        disable=not sys.stderr.isatty() and os.environ.get("BGM_PROGRESS") != "1",
    )
    task = progress.add_task(description, total=total)

    def advance(done: int, total_: int) -> None:
        progress.update(task, completed=done, total=total_)

    return advance, progress


@app.command()
def contours(
    input: InputArg,
    out: Annotated[Path, typer.Option("--out", help="GeoJSON file to write.")] = Path("contours.geojson"),
    geozone: Annotated[
        list[str] | None, typer.Option("--geozone", help="Geozone to extract (repeat for several; default all).")
    ] = None,
    search_radius: Annotated[
        float | None, typer.Option(help="Region-growing radius r in input units (default 1.6 x hole spacing).")
    ] = None,
    x: XOpt = None,
    y: YOpt = None,
    z: ZOpt = None,
    geozone_column: GeozoneColOpt = None,
    bench_height: BenchHeightOpt = None,
    units: UnitsOpt = None,
    no_cache: NoCacheOpt = False,
) -> None:
    """Extract closed geozone contours on every bench (paper section 2).

    Writes one Polygon feature per bench, geozone and component with
    properties geozone, bench (elevation), component and containment figures.
    """
    from core.io.export import write_geojson
    from core.io.reporting import containment_summary, contour_feature
    from core.model.parameters import with_values

    holes = _load(input, x, y, z, geozone_column, bench_height, units)
    wanted = holes.check_geozones(geozone)
    session = _session(holes, None, no_cache)
    if search_radius is not None:
        radius_m = float(holes.frame.length_to_local(search_radius))
        session = session.updated(params=with_values(session.params, search_radius_m=radius_m))
    start = time.perf_counter()
    advance, bar = _progress("extracting contours", holes.n_benches)
    with bar:
        result = [c for c in session.contours(progress=advance) if c.geozone in wanted]
    elapsed = time.perf_counter() - start
    features = [contour_feature(c, holes) for c in result]
    write_geojson(features, out)
    summary = containment_summary(result, holes)
    summary.update({"features": len(features), "seconds": round(elapsed, 2), "out": str(out)})
    typer.echo(json.dumps(summary, indent=2))


GeozoneOpt = Annotated[str, typer.Option("--geozone", help="Geozone to model (as written in the input, e.g. 3310).")]
ProjectOpt = Annotated[
    Path | None,
    typer.Option(
        "--project", help="Project file (JSON) with parameters (see bgm parameters) and manual alignment overrides."
    ),
]


def _session(holes, project: Path | None, no_cache: bool):
    """The pipeline on ``holes`` with the project's parameters and overrides, on the disk cache unless ``no_cache``."""
    from core.io.project import load_project
    from core.model.parameters import parameters_from_dict
    from core.model.session import ModelSession

    proj = load_project(project) if project is not None else None
    params = parameters_from_dict(proj.parameters) if proj is not None else None
    return ModelSession.open(holes, params, proj, cache=not no_cache)


def _model(input, geozone, project, stages, x, y, z, geozone_column, bench_height, units, no_cache=False):
    holes = _load(input, x, y, z, geozone_column, bench_height, units)
    holes.check_geozones([geozone])
    if holes.n_benches < 2:
        raise BGMInputError(
            f"{input} has a single bench ({holes.bench_z_input(0)}); correspondence needs two or more benches"
        )
    session = _session(holes, project, no_cache)
    start = time.perf_counter()
    advance, bar = _progress(f"{stages[-1]} {geozone}", holes.n_benches - 1)
    with bar:
        model = session.geozone_model(geozone, stages=stages, progress=advance)
    return session, model, time.perf_counter() - start


@app.command()
def correspond(
    input: InputArg,
    geozone: GeozoneOpt,
    out: Annotated[Path, typer.Option("--out", help="JSON file to write.")] = Path("correspondence.json"),
    project: ProjectOpt = None,
    x: XOpt = None,
    y: YOpt = None,
    z: ZOpt = None,
    geozone_column: GeozoneColOpt = None,
    bench_height: BenchHeightOpt = None,
    units: UnitsOpt = None,
    no_cache: NoCacheOpt = False,
) -> None:
    """Associate components between successive benches and estimate their translations (paper section 3)."""
    from core.io.atomic import atomic_write_text
    from core.model.pipeline import correspondence_json

    session, model, elapsed = _model(
        input, geozone, project, ("correspond",), x, y, z, geozone_column, bench_height, units, no_cache
    )
    data = correspondence_json(model, session.holes)
    atomic_write_text(out, json.dumps(data, indent=1))
    typer.echo(
        json.dumps({"geozone": geozone, "pairs": len(data["pairs"]), "seconds": round(elapsed, 2), "out": str(out)})
    )


@app.command()
def morph(
    input: InputArg,
    geozone: GeozoneOpt,
    out: Annotated[Path, typer.Option("--out", help="JSON file to write.")] = Path("morph.json"),
    project: ProjectOpt = None,
    x: XOpt = None,
    y: YOpt = None,
    z: ZOpt = None,
    geozone_column: GeozoneColOpt = None,
    bench_height: BenchHeightOpt = None,
    units: UnitsOpt = None,
    no_cache: NoCacheOpt = False,
) -> None:
    """Morph each bench's regions into the next bench's and trace the boundary's trajectories (paper section 4)."""
    from core.io.atomic import atomic_write_text
    from core.model.pipeline import morph_json

    session, model, elapsed = _model(
        input, geozone, project, ("correspond", "morph"), x, y, z, geozone_column, bench_height, units, no_cache
    )
    data = morph_json(model, session.holes)
    atomic_write_text(out, json.dumps(data))
    cov = [p["target_boundary_coverage"] for p in data["pairs"] if p["target_boundary_coverage"] is not None]
    before = [p["coverage_before_backtracking"] for p in data["pairs"] if p["coverage_before_backtracking"] is not None]
    typer.echo(
        json.dumps(
            {
                "geozone": geozone,
                "pairs": len(data["pairs"]),
                "coverage_min": min(cov) if cov else None,
                "coverage_median": float(np.median(cov)) if cov else None,
                "coverage_before_backtracking_median": float(np.median(before)) if before else None,
                "trajectories": sum(len(p["trajectories"]) for p in data["pairs"]),
                "seconds": round(elapsed, 2),
                "out": str(out),
            }
        )
    )


@app.command()
def predict(
    input: InputArg,
    geozone: GeozoneOpt,
    elevations: Annotated[
        str,
        typer.Option(
            "--elevations", help="Comma-separated elevations in input units (above, between or below the benches)."
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="GeoJSON file to write.")] = Path("prediction.geojson"),
    project: ProjectOpt = None,
    x: XOpt = None,
    y: YOpt = None,
    z: ZOpt = None,
    geozone_column: GeozoneColOpt = None,
    bench_height: BenchHeightOpt = None,
    units: UnitsOpt = None,
    no_cache: NoCacheOpt = False,
) -> None:
    """Predict the geozone's region at any elevation (paper: contour prediction)."""
    from core.io.export import write_geojson
    from core.io.reporting import to_input_geometry

    try:
        levels = [float(v) for v in elevations.replace(";", ",").split(",") if v.strip()]
    except ValueError:
        raise BGMInputError(f"--elevations must be numbers separated by commas, got {elevations!r}") from None
    if not levels or not all(np.isfinite(levels)):
        raise BGMInputError(f"--elevations needs at least one finite number, got {elevations!r}")
    session, model, elapsed = _model(
        input, geozone, project, ("correspond", "morph"), x, y, z, geozone_column, bench_height, units, no_cache
    )
    holes = session.holes
    z_m = [float(holes.frame.z_to_local(v)) for v in levels]
    regions = session.predict(geozone, z_m, model)
    features = []
    for level, zm in zip(levels, z_m):
        region = regions[zm]
        geometry = to_input_geometry(region, holes)
        if len(region.geoms) == 1:
            geometry = geometry.geoms[0]
        features.append(
            {
                "geometry": geometry,
                "properties": {
                    "geozone": geozone,
                    "z": level,
                    f"area_{holes.frame.length_unit}2": round(geometry.area, 3),
                },
            }
        )
    write_geojson([f for f in features if not f["geometry"].is_empty], out)
    empty = [f["properties"]["z"] for f in features if f["geometry"].is_empty]
    if empty:
        _say(f"bgm: note: {geozone} is predicted absent at {', '.join(map(str, empty))}")
    typer.echo(
        json.dumps({"geozone": geozone, "elevations": levels, "features": len(features) - len(empty), "out": str(out)})
    )


@app.command()
def evaluate(
    input: InputArg,
    geozone: GeozoneOpt,
    out: Annotated[Path, typer.Option("--out", help="Folder for the table (CSV) and plot (PNG).")] = Path("evaluation"),
    x: XOpt = None,
    y: YOpt = None,
    z: ZOpt = None,
    geozone_column: GeozoneColOpt = None,
    bench_height: BenchHeightOpt = None,
    units: UnitsOpt = None,
    no_cache: NoCacheOpt = False,
) -> None:
    """Precision and recall of predictions below withheld benches, against nil, linear and implicit references."""
    from core.model.build import load_truth, predictor_from_model
    from core.model.evaluation import evaluate_geozone, format_table, plot_precision_recall, summary_table

    holes = _load(input, x, y, z, geozone_column, bench_height, units)
    holes.check_geozones([geozone])
    if holes.n_benches < 3:
        raise BGMInputError(f"{input} has {holes.n_benches} bench(es); evaluation needs at least three")
    truth = load_truth(input, holes)
    session = _session(holes, None, no_cache)
    start = time.perf_counter()
    contours = session.contours()
    model = session.geozone_model(geozone, contours=contours)
    predictor = predictor_from_model(model, holes, session.params)
    rows = evaluate_geozone(holes, geozone, predictor, truth=truth, contours=contours)
    if rows.empty:
        raise BGMInputError(f"geozone {geozone} has no bench with two known benches above it and holes below")
    table = summary_table(rows)
    out.mkdir(parents=True, exist_ok=True)
    from core.io.atomic import atomic_write_text

    atomic_write_text(out / "evaluation_rows.csv", rows.to_csv(index=False))
    atomic_write_text(out / "evaluation.csv", table.to_csv(index=False))
    plot_precision_recall(table, out / "precision_recall.png", title=f"{geozone}: model vs references")
    _say(
        f"truth: {'synthetic generator' if truth is not None else 'next bench holes'}; {time.perf_counter() - start:.1f} s"
    )
    typer.echo(format_table(table))


def _run_build(holes, out, geozone, project, truth, workers=None, scheduler=None, no_cache=False) -> dict:
    from core.model.build import build

    session = _session(holes, project, no_cache)
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        disable=not sys.stderr.isatty() and os.environ.get("BGM_PROGRESS") != "1",
    )
    task = bar.add_task("building", total=1)

    def progress(stage: str, done: int, total: int) -> None:
        bar.update(task, description=stage, completed=done, total=max(total, 1))

    with bar:
        summary = build(
            holes,
            out,
            geozones=geozone,
            params=session.params,
            project=session.project,
            truth=truth,
            progress=progress,
            workers=workers,
            scheduler=scheduler,
            cache=session.store.cache,
        )
    _say(f"wrote {out}/report.md ({summary['seconds']:.1f} s)")
    return summary


@app.command()
def build(
    input: InputArg,
    out: Annotated[Path, typer.Option("--out", help="Folder to write everything into.")] = Path("bgm-out"),
    geozone: Annotated[list[str] | None, typer.Option("--geozone", help="Geozones to model (default all).")] = None,
    project: ProjectOpt = None,
    workers: Annotated[int | None, typer.Option(help="Local processes (default: all cores).")] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Address of a dask.distributed scheduler to run on instead.")
    ] = None,
    x: XOpt = None,
    y: YOpt = None,
    z: ZOpt = None,
    geozone_column: GeozoneColOpt = None,
    bench_height: BenchHeightOpt = None,
    units: UnitsOpt = None,
    no_cache: NoCacheOpt = False,
) -> None:
    """The whole pipeline for every geozone: contours, correspondence, trajectories, predictions, surfaces, evaluation, report."""
    from core.model.build import load_truth

    holes = _load(input, x, y, z, geozone_column, bench_height, units)
    if holes.n_benches < 2:
        raise BGMInputError(f"{input} has a single bench; building a model needs two or more benches")
    summary = _run_build(holes, out, geozone, project, load_truth(input, holes), workers, scheduler, no_cache)
    typer.echo(json.dumps({k: summary[k] for k in ("holes", "seconds")} | {"out": str(out)}))


@app.command()
def demo(
    out: Annotated[Path, typer.Option("--out", help="Folder to write everything into.")] = Path("bgm-demo"),
    view: Annotated[bool, typer.Option(help="Open the 3D viewer on the result when a display is available.")] = False,
    no_cache: NoCacheOpt = False,
) -> None:
    """Build the whole model on the bundled synthetic demo data (assets/demo_blastholes.csv)."""
    from core.io.blastholes import read_blastholes
    from core.model.build import load_truth

    holes = read_blastholes(DEMO_CSV)
    _run_build(holes, out, None, None, load_truth(DEMO_CSV, holes), no_cache=no_cache)
    typer.echo((out / "report.md").read_text())
    if not view:
        _say("open it in 3D with: bgm view")
        return
    viewer = next((c.callback for c in app.registered_commands if c.name == "view" and c.callback), None)
    if viewer is None:
        raise BGMInputError("the 3D viewer is not installed: pip install -e '.[viewer]'")
    viewer(DEMO_CSV)


@app.command()
def parameters() -> None:
    """The model's parameters, by stage: what a project file's "parameters" may set, with defaults and ranges.

    Lengths are metres (ranges in hole spacings), angles radians; a default of
    "auto" is derived from the data as the last column says.
    """
    from rich.console import Console
    from rich.table import Table

    from core.model.parameters import PARAMETERS

    table = Table("name", "stage", "symbol", "default", "typical range", "what it does", show_lines=False)
    for p in PARAMETERS:
        scale = " x spacing" if p.kind == "length" else ""
        default = "auto: " + p.auto if p.default is None else f"{p.default:g}"
        table.add_row(p.name, p.stage, p.symbol, default, f"{p.minimum:g} - {p.maximum:g}{scale}", p.help)
    Console(width=200).print(table)


@app.command("make-demo-data")
def make_demo_data(
    out: Annotated[Path, typer.Option("--out", help="CSV to write.")] = DEMO_CSV,
    seed: Annotated[int, typer.Option(help="Random seed of the synthetic mine.")] = 2019,
) -> None:
    """Regenerate the bundled synthetic demo blastholes (assets/demo_blastholes.csv)."""
    from core.io.atomic import atomic_path, atomic_write_text
    from core.model.build import truth_sidecar
    from core.synthetic.blobs import demo_dataset

    _, table = demo_dataset(seed)
    with atomic_path(out) as tmp:
        table.to_csv(tmp, index=False)
    # The generator knows the true sections: record how to regenerate them for evaluation.
    atomic_write_text(truth_sidecar(out), json.dumps({"generator": "core.synthetic.demo_dataset", "seed": seed}))
    _say(f"wrote {len(table)} holes to {out} (truth in {truth_sidecar(out).name})")


def _show_warning(message, category, filename, lineno, file=None, line=None):
    _say(f"bgm: warning: {message}")


#: Entry-point group through which other packages add commands (the viewer adds ``bgm view``):
#: each entry point names a function ``register(app)`` that adds its commands to the typer app.
PLUGIN_GROUP = "bgm.commands"


def load_plugins(target: typer.Typer = app) -> list[str]:
    """Let installed packages add their commands (entry points of :data:`PLUGIN_GROUP`); returns their names.

    The engine knows no viewer: a package that adds one registers it here, so
    ``bgm`` works with or without it installed.
    """
    from importlib.metadata import entry_points

    present = {c.name for c in target.registered_commands}
    loaded = []
    for ep in entry_points(group=PLUGIN_GROUP):
        if ep.name in present:
            continue
        try:
            ep.load()(target)
        except Exception as exc:  # a broken add-on must not take the engine's commands with it
            _say(f"bgm: warning: the {ep.name!r} command could not be loaded ({type(exc).__name__}: {exc})")
            continue
        loaded.append(ep.name)
    return loaded


def main() -> None:
    """Entry point of the ``bgm`` console script."""
    from core.io.blastholes import BGMWarning

    load_plugins()

    # Users see the engine's own warnings (repairs to their data), not library chatter.
    warnings.showwarning = _show_warning
    warnings.filterwarnings("ignore")
    warnings.filterwarnings("always", category=BGMWarning)
    try:
        app(prog_name="bgm")
    except BGMInputError as exc:
        _say(f"bgm: error: {exc}")
        sys.exit(2)
    except KeyboardInterrupt:
        _say("bgm: interrupted; files being written were left as they were")
        sys.exit(130)
    except MemoryError:
        _say("bgm: error: out of memory; try fewer geozones or benches at a time")
        sys.exit(3)
    except Exception as exc:  # a bug: say so plainly, traceback only on request
        if os.environ.get("BGM_DEBUG"):
            raise
        _say(f"bgm: internal error: {type(exc).__name__}: {exc} (set BGM_DEBUG=1 for the traceback)")
        sys.exit(3)


if __name__ == "__main__":
    main()
