"""The ``bgm`` command line: the engine for batch use.

Every command reads a blasthole table (CSV or Parquet, a file or ``-`` for
standard input), finds its columns and benches, and writes results in the
input's own coordinates. Exit status: 0 done; 2 for any problem with the
input, options or output paths, told in one line (``bgm: error: ...``); 130
when interrupted (Ctrl-C) and 143 when terminated (SIGTERM: ``kill``, ``timeout``,
a job scheduler), also one line; 3 only for a bug in BGM. Outputs
never replace an input, a device or anything outside ``--out``, and every file
is written atomically.
"""

# ruff: noqa: E402  (Ctrl-C is held before the imports below)
from __future__ import annotations

import contextlib
import os
import signal

_INTERRUPTS: list[int] = []  # Ctrl-Cs this process received while the command line ran
#: The process whose command the handlers below serve (a process forked from it inherits them).
_COMMAND_PID = os.getpid()


def _remember_ctrl_c(signum, frame):
    _INTERRUPTS.append(signum)


def _on_ctrl_c(signum, frame):
    if os.getpid() != _COMMAND_PID:
        # A build's worker stopped (by its parent's SIGTERM) before it set its own handlers:
        # it ends at once and quietly, as it would have with them, not with a traceback.
        os._exit(128 + signum)
    # Remembered as well as raised: some libraries catch BaseException (trimesh's
    # import guards), and an interrupt they swallow must still end the command.
    _INTERRUPTS.append(signum)
    raise KeyboardInterrupt


def _interrupt_again(unraisable) -> None:
    """``sys.unraisablehook`` while a command runs: an interrupt raised where Python can only print it.

    A signal lands between any two bytecodes, also in a fork hook or a finalizer
    (logging's lock release as a build forks its workers), where the interrupt
    cannot propagate: Python printed "Exception ignored" and a traceback, and
    the command went on. It is raised again in the main thread a moment later,
    from a thread: raised from here, it would land in this hook, as unraisable.
    The thread waits until this hook is past starting it: a timer counted from
    its own start, and on a loaded machine fired while ``start()`` still waited
    for it, inside this hook, and the interrupt was lost again.
    """
    import _thread
    import threading

    if isinstance(unraisable.exc_value, KeyboardInterrupt) and _INTERRUPTS:
        started = threading.Event()

        def interrupt_later() -> None:
            started.wait()
            time.sleep(0.01)  # for this hook to return
            _thread.interrupt_main(signal.SIGINT)

        threading.Thread(target=interrupt_later, daemon=True).start()
        started.set()
        return
    sys.__unraisablehook__(unraisable)


@contextlib.contextmanager
def _ctrl_c_held():
    """Ctrl-C inside is remembered, not raised (imports that must not be cut in half)."""
    try:
        previous = signal.signal(signal.SIGINT, _remember_ctrl_c)
    except ValueError:  # not the main thread
        previous = None
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


# Ctrl-C while this module loads ends the command with one line (see main), not a traceback.
_LOADING = _ctrl_c_held()
_LOADING.__enter__()

import functools
import inspect
import json
import math
import re
import sys
import time
import warnings
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from core.errors import BGMInputError, listing, quoted

#: What an option's value is, in the words of the help (``--x <column>``), by the option's name; an
#: option not named here shows its own name (``--geozone <geozone>``), or ``<path>`` for a file or folder.
_PLACEHOLDERS = {
    "x": "<column>",
    "y": "<column>",
    "z": "<column>",
    "geozone_column": "<column>",
    "units": "<m|ft>",
    "bench_height": "<height>",
    "search_radius": "<radius>",
    "band_probability": "<probability>",
    "workers": "<count>",
    "budget": "<holes>",
    "scheduler": "<address>",
    "camera": "<view>",
    "bench": "<index>",
    "exaggeration": "<factor>",
}


def placeholder(option: typer.core.TyperOption) -> str:
    """The placeholder ``--help`` shows after an option that takes a value, in a geologist's words.

    typer 0.29 shows the option's Python type (``--geozone <list[str]>``, ``--x <str>``): a
    repeatable option read as a list to type, a column name as a "str". An option an add-on
    gave a placeholder of its own keeps it.
    """
    if option.metavar is not None:
        return option.metavar
    name = option.name or ""
    if name in _PLACEHOLDERS:
        return _PLACEHOLDERS[name]
    if option.type_descriptor.is_path:
        return "<path>"
    return f"<{name.replace('_', '-')}>"


class _PlainArgument(typer.core.TyperArgument):
    """A command's argument as click writes it: ``INPUT`` (required) or ``[INPUT]``, without a type.

    typer 0.29 wrote a required argument ``{input}`` in the usage line (``Usage: bgm build
    [OPTIONS] {input}``), which reads as a literal to type, and ``input <path>`` below it.
    """

    def get_usage_pieces(self, ctx):
        name = (self.name or "").upper()
        return [(name if self.required else f"[{name}]") + ("..." if self.nargs != 1 else "")]

    def display_type_rich(self, ctx):
        return None  # the argument's help says what it is (a table, a folder)


class _PlainHelpGroup(typer.core.TyperGroup):
    """The ``bgm`` group: every command's help in plain words, add-ons' commands too (see :func:`plain_help`)."""

    def __init__(self, **attrs):
        super().__init__(**attrs)
        for command in self.commands.values():
            plain_help(command)


def plain_help(command) -> None:
    """Give ``command``'s arguments and options the usage line and placeholders a geologist reads.

    In one place for every command (the engine's and add-ons', which typer builds into the
    ``bgm`` group): arguments as ``INPUT`` (:class:`_PlainArgument`), options' values as
    :func:`placeholder` says.
    """
    for param in command.params:
        if type(param) is typer.core.TyperArgument:
            param.__class__ = _PlainArgument  # same fields; only how its help is written differs
            param.metavar = (param.name or "").upper()  # and click's messages: "Missing argument 'INPUT'"
        elif isinstance(param, typer.core.TyperOption) and not (param.is_flag or param.count):
            param.metavar = placeholder(param)


app = typer.Typer(
    cls=_PlainHelpGroup,
    name="bgm",
    help="Boundary Geometry Modeler: geozone boundaries, surfaces and predictions below the deepest bench from labelled blastholes.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    # Help in the plain layout: typer 0.29's Rich layout prints a value placeholder after every flag
    # (--no-cache <bool>, --help <bool>), and a geologist who typed --keep-isolated true got "unexpected
    # extra argument (true)". The plain layout shows a flag as it is typed (no value) and every other
    # option's placeholder, for every command, add-ons' too; it also reads no markup in the help texts.
    rich_markup_mode=None,
)

ASSETS = Path(__file__).resolve().parent.parent / "assets"
DEMO_CSV = ASSETS / "demo_blastholes.csv"
#: ``predict`` refuses elevations farther than this many bench heights outside the benches (unless --force).
MAX_PREDICTION_BENCHES = 3.0

InputArg = Annotated[
    Path, typer.Argument(help="Blasthole table (CSV or Parquet; - for standard input).", show_default=False)
]
# A list, so that a repeated --geozone is refused (_given_once), not silently the last one given.
GeozoneOpt = Annotated[
    list[str],
    typer.Option("--geozone", help="Geozone to model (as written in the input, e.g. 3310).", show_default=False),
]
ProjectOpt = Annotated[
    Path | None,
    typer.Option(
        "--project", help="Project file (JSON) with parameters (see bgm parameters) and manual alignment overrides."
    ),
]
BandProbabilityOpt = Annotated[
    float,
    typer.Option("--band-probability", help="Probability that the uncertainty band holds the true boundary."),
]
NoCacheOpt = Annotated[
    bool,
    typer.Option(
        "--no-cache", help="Compute every stage afresh instead of reusing results kept from earlier runs on this input."
    ),
]


# --------------------------------------------------------------------------- options shared by every reading command


@dataclass(frozen=True)
class TableOptions:
    """How to read the blasthole table: the options every command that reads one takes."""

    x: Annotated[
        str | None, typer.Option("--x", help="Column holding x (default: x/east/easting/mid_x, any case).")
    ] = None
    y: Annotated[str | None, typer.Option("--y", help="Column holding y (default: y/north/northing/mid_y).")] = None
    z: Annotated[
        str | None, typer.Option("--z", help="Column holding elevation (default: z/rl/elevation/elev/mid_z).")
    ] = None
    geozone_column: Annotated[
        str | None,
        typer.Option(
            "--geozone-column",
            help="Column holding the geozone label (default: geozone/domain/lookup_domain/label/zone).",
        ),
    ] = None
    bench_height: Annotated[
        float | None,
        typer.Option(
            "--bench-height",
            help="Bench height in input units (default: detected from z); benches stay at the collars' levels.",
        ),
    ] = None
    units: Annotated[
        str | None,
        typer.Option(
            "--units",
            help="Length unit of the input, m or ft (default: guessed from the bench height and hole spacing).",
        ),
    ] = None

    def with_project(self, project: Path) -> TableOptions:
        """These options with those the project was made with (its ``reading_options``), said on stderr.

        An option given here that the project records with another value is
        refused (:func:`core.io.project.merge_reading`): read otherwise, the
        table is other data than the project's overrides were made on.
        """
        from core.io.project import load_project, merge_reading

        options, used = merge_reading(load_project(project), project, asdict(self))
        if used:
            _say(f"reading the input as project {project} was made: {', '.join(used)}")
        return TableOptions(**options)

    def given(self) -> bool:
        """Whether any option was given (else the table is read as found)."""
        return any(getattr(self, f.name) is not None for f in fields(self))

    def read(self, input: Path):
        """Read ``input`` with these options and say in one line what was found."""
        from core.io.blastholes import read_blastholes

        holes = read_blastholes(
            input,
            x=self.x,
            y=self.y,
            z=self.z,
            geozone=self.geozone_column,
            bench_height=self.bench_height,
            length_unit=self.units,
        )
        guess = f" ({holes.unit_guess})" if holes.unit_guess else ""
        geozones = f"{len(holes.geozones)} geozone{'s' if len(holes.geozones) != 1 else ''}"
        _say(f"{holes.source}: {len(holes.xy)} holes, {geozones}, {_benches(holes)}{guess}")
        return holes


def reads_table(command):
    """Give ``command`` the :class:`TableOptions` options, passed to it as one ``table`` argument.

    The options are defined once (the fields of :class:`TableOptions`) and
    appear last in every command's ``--help``, as they always have.
    """
    signature = inspect.signature(command, eval_str=True)
    own = [p for p in signature.parameters.values() if p.name != "table"]
    names = [f.name for f in fields(TableOptions)]
    types = inspect.get_annotations(TableOptions, eval_str=True)
    added = [inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY, default=None, annotation=types[n]) for n in names]

    @functools.wraps(command)
    def run(*args, **kwargs):
        # Called by another command (demo --view) rather than by typer, it is given none of them.
        table = TableOptions(**{n: kwargs.pop(n, None) for n in names})
        if kwargs.get("project") is not None:
            table = table.with_project(kwargs["project"])
        return command(*args, table=table, **kwargs)

    run.__signature__ = signature.replace(parameters=[*own, *added])  # what typer reads
    run.__annotations__ = {p.name: p.annotation for p in [*own, *added]}
    return run


def _benches(holes) -> str:
    unit = holes.frame.length_unit
    spacing = f"hole spacing {holes.frame.length_to_input(holes.hole_spacing_m):.2f} {unit}"
    if holes.n_benches == 1:
        return f"1 bench at {holes.bench_z_input(0)} {unit}, {spacing}"
    heights = -np.diff(holes.frame.z_to_input(holes.bench_levels_m))
    height = f"bench height {heights[0]:.1f} {unit}"
    if np.ptp(heights) > 0.01 * heights.max():
        height = f"bench heights {heights.min():.1f} to {heights.max():.1f} {unit}"
    return (
        f"{holes.n_benches} benches ({holes.bench_z_input(0)} to {holes.bench_z_input(holes.n_benches - 1)} "
        f"{unit}, {height}), {spacing}"
    )


# --------------------------------------------------------------------------- helpers


def _say(message: str) -> None:
    typer.echo(message, err=True)


#: What ``BGM_PROGRESS`` may force on stderr; unset, a bar on a terminal and lines otherwise.
PROGRESS_MODES = ("bar", "lines", "off")

#: Batch progress lines a stage at most: every step up to this many steps, then every 1/this of them.
PROGRESS_LINES = 20


def _progress_mode() -> str:
    """How progress is shown: ``BGM_PROGRESS`` (bar, lines or off), else a bar on a terminal and lines otherwise."""
    mode = os.environ.get("BGM_PROGRESS", "").strip().lower()
    if mode == "1":  # its old, undocumented spelling: the bar even off a terminal
        return "bar"
    if mode in PROGRESS_MODES:
        return mode
    if mode:
        _say(f"bgm: note: BGM_PROGRESS={quoted(mode)} is none of {', '.join(PROGRESS_MODES)}; ignored")
    return "bar" if sys.stderr.isatty() else "lines"


@contextlib.contextmanager
def progress_bar(description: str, unit: str = "steps"):
    """Progress on stderr: a bar on a terminal, a line a step otherwise (``BGM_PROGRESS``: :func:`_progress_mode`).

    Off a terminal (a job scheduler, CI, ``2> log``, a pipe) the bar drew
    nothing until the end, and a long build looked hung: there each step
    prints ``bgm: progress: 3/13 geozones (geozone 3310, 12.4 s)``, flushed
    at once, at most :data:`PROGRESS_LINES` a stage.

    Parameters
    ----------
    description : str
        What is being done, shown before the bar and in each line.
    unit : str, optional
        What the steps count ("benches", "geozones"), said in the lines.

    Yields
    ------
    callable
        ``update(done, total, description=None, unit=None, run=None)`` (a
        new unit begins a new stage of lines), which also ends the command at
        its next step after a Ctrl-C that a library caught and swallowed.
        ``run`` names a series of steps that others interleave with (the
        steps of one geozone, while another worker reports its own): each
        run is thinned to :data:`PROGRESS_LINES` apart (default: its unit).
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    mode = _progress_mode()
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=False,
        disable=mode != "bar",
    )
    task = bar.add_task(description, total=1)
    start = time.perf_counter()
    # The last unit and description, and the last step said of each run (by default a unit's steps are one:
    # benches, then geozones; two geozones' steps on two workers are two runs, each thinned on its own).
    said_unit, said, now = unit, dict[str, int](), description

    def say_line(done: int, total: int, unit: str, run: str) -> None:
        last = said.get(run, 0)
        if done < last:  # the run begun again
            last = said[run] = 0
        # Every step of a short stage; of a long one (hundreds of benches) every 1/PROGRESS_LINES: not a flood.
        if done < total and done * PROGRESS_LINES // total == last * PROGRESS_LINES // total:
            return
        said[run] = done
        _say(f"bgm: progress: {done}/{total} {unit} ({now}, {time.perf_counter() - start:.1f} s)")
        sys.stderr.flush()  # as it happens, to a log file or a pipe too

    def update(
        done: int, total: int, description: str | None = None, unit: str | None = None, run: str | None = None
    ) -> None:
        nonlocal now, said_unit
        if _INTERRUPTS:
            raise KeyboardInterrupt
        now = now if description is None else description
        bar.update(task, completed=done, total=max(total, 1), description=now)
        said_unit = unit or said_unit
        if mode == "lines" and total > 0:
            say_line(done, total, said_unit, run or said_unit)

    with bar:
        yield update


def _staged(update):
    """A core ``progress(stage, done, total)`` said through :func:`progress_bar`'s ``update``.

    The stages ("contours", "surface of geozone 3310", "geozone 3310") are the
    description; what their steps count (benches, steps, geozones) is the
    unit, and a geozone's steps are a run of their own
    (:func:`core.model.progress.stage_unit` and ``stage_run``).
    """
    from core.model.progress import stage_run, stage_unit

    return lambda stage, done, total: update(done, total, stage, stage_unit(stage), stage_run(stage))


def _positive(option: str, value: float | None) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise BGMInputError(f"{option} must be a positive number, got {value}")


def _outputs(out: Path, input: Path, *others, folder: bool = False, what: str = "--out") -> None:
    """Refuse an output that is an input, a device or (for a folder) holds an input, before any work."""
    from core.io.atomic import check_output
    from core.model.build import truth_sidecar

    # An input with no file name ("/", ".", or an empty argument, which typer reads as ".") is a folder, said
    # so by the reader; it has no sidecar beside it (pathlib refuses to name one: an internal error).
    sidecar = None if str(input) == "-" or not Path(input).name else truth_sidecar(Path(input))
    check_output(out, [input, sidecar, *others], folder=folder, what=what)


def _wanted(holes, given: list[str] | None) -> list[str]:
    """The geozones ``--geozone`` asks for, repeated or separated by commas; all of them when not given.

    A value that is a label of the table is taken whole: a label may hold a comma ("ore, oxide").
    """
    labels = set(holes.geozones)
    parts = [[v] if v in labels else [g.strip() for g in v.split(",") if g.strip()] for v in given or []]
    return holes.check_geozones([g for part in parts for g in part])


def _load_project(project: Path | None, holes, geozones: list[str], command: str):
    from core.io.project import check_project, check_project_input, load_project

    if project is None:
        return None
    proj = load_project(project)
    check_project(proj, holes, geozones, command=f"bgm {command}", uses_parameters=True)
    check_project_input(proj, project, holes.source)
    return proj


def _session(holes, project: Path | None, geozones: list[str], command: str, no_cache: bool):
    """The pipeline on ``holes`` with the project's parameters and overrides, on the disk cache unless ``no_cache``."""
    from core.model.parameters import parameters_from_dict
    from core.model.session import ModelSession

    proj = _load_project(project, holes, geozones, command)
    params = parameters_from_dict(proj.parameters) if proj is not None else None
    return ModelSession.open(holes, params, proj, cache=not no_cache)


# --------------------------------------------------------------------------- commands


@app.command()
@reads_table
def contours(
    input: InputArg,
    out: Annotated[Path, typer.Option("--out", help="GeoJSON file to write.")] = Path("contours.geojson"),
    geozone: Annotated[
        list[str] | None,
        typer.Option("--geozone", help="Geozone(s) to extract (repeat, or separate with commas; default all)."),
    ] = None,
    search_radius: Annotated[
        float | None, typer.Option(help="Region-growing radius r in input units (default 1.6 x hole spacing).")
    ] = None,
    keep_isolated: Annotated[
        bool,
        typer.Option(
            "--keep-isolated",
            help="Keep components of one or two holes surrounded by other geozones as contours, and the "
            "labels of holes at noisy contacts (by default both are taken as label noise and reported "
            "as isolated_holes).",
        ),
    ] = False,
    no_cache: NoCacheOpt = False,
    *,
    table: TableOptions,
) -> None:
    """Extract closed geozone contours on every bench (paper section 2).

    Writes one Polygon feature per bench, geozone and component with
    properties geozone, bench (elevation), component and containment figures.
    """
    from core.io.export import write_geojson
    from core.io.reporting import containment_summary, contour_feature
    from core.model.parameters import with_values

    _positive("--search-radius", search_radius)
    _outputs(out, input)
    holes = table.read(input)
    wanted = _wanted(holes, geozone)
    session = _session(holes, None, wanted, "contours", no_cache)
    radius_m = None if search_radius is None else float(holes.frame.length_to_local(search_radius))
    params = with_values(session.params, search_radius_m=radius_m, keep_isolated_holes=keep_isolated)
    session = session.updated(params=params.validate())
    start = time.perf_counter()
    with progress_bar("extracting contours", "benches") as update:
        result = [c for c in session.contours(progress=update) if c.geozone in wanted]
    elapsed = time.perf_counter() - start
    features = [contour_feature(c, holes) for c in result]
    write_geojson(features, out, units=holes.frame.length_unit)
    summary = containment_summary(result, holes)
    isolated = sum(len(c.isolated_holes) for c in result)
    summary.update(
        {"features": len(features), "isolated_holes": isolated, "seconds": round(elapsed, 2), "out": str(out)}
    )
    typer.echo(json.dumps(summary, indent=2))


def _given_once(given: list[str], command: str) -> str:
    """The one ``--geozone`` of a command that models one geozone; refused when the option is repeated.

    Typer keeps the last of a repeated single-valued option: ``bgm correspond
    --geozone 3320 --geozone 3310`` modelled 3310 alone, with nothing said.
    """
    if len(given) != 1:
        raise BGMInputError(
            f"{command} takes one geozone; --geozone is given {len(given)} times: "
            f"{listing(map(quoted, given))} (run {command} once for each)"
        )
    return given[0]


def _model(input, geozone, project, stages, table: TableOptions, command: str, no_cache: bool):
    """Read the input and model one geozone up to ``stages``; returns (session, label, model, seconds)."""
    geozone = _given_once(geozone, f"bgm {command}")
    holes = table.read(input)
    geozone = holes.check_one_geozone(geozone, f"bgm {command}")
    if holes.n_benches < 2:
        raise BGMInputError(
            f"{input} has a single bench ({holes.bench_z_input(0)}); correspondence needs two or more benches"
        )
    session = _session(holes, project, [geozone], command, no_cache)
    start = time.perf_counter()
    with progress_bar(f"{stages[-1]} {geozone[:40]}", "bench pairs") as update:
        model = session.geozone_model(geozone, stages=stages, progress=update)
    _say_no_pair(session, geozone, model)  # else "pairs": 0 alone, and the user left to guess why
    return session, geozone, model, time.perf_counter() - start


def _say_no_pair(session, geozone: str, model, consequence: str = "") -> None:
    """Say why ``geozone`` has no bench pair (as ``bgm build``'s report does), when ``model`` has none."""
    if not model.pairs:
        from core.model.build import no_pair_note

        why = no_pair_note(session.holes, geozone, session.params.min_component_holes)
        _say(f"bgm: note: geozone {geozone} is {why}{consequence}")


@app.command()
@reads_table
def correspond(
    input: InputArg,
    geozone: GeozoneOpt,
    out: Annotated[Path, typer.Option("--out", help="JSON file to write.")] = Path("correspondence.json"),
    project: ProjectOpt = None,
    no_cache: NoCacheOpt = False,
    *,
    table: TableOptions,
) -> None:
    """Associate components between successive benches and estimate their translations (paper section 3)."""
    from core.io.atomic import atomic_write_text
    from core.model.pipeline import correspondence_json

    _outputs(out, input, project)
    session, geozone, model, elapsed = _model(input, geozone, project, ("correspond",), table, "correspond", no_cache)
    data = correspondence_json(model, session.holes)
    atomic_write_text(out, json.dumps(data, indent=1))
    typer.echo(
        json.dumps({"geozone": geozone, "pairs": len(data["pairs"]), "seconds": round(elapsed, 2), "out": str(out)})
    )


@app.command()
@reads_table
def morph(
    input: InputArg,
    geozone: GeozoneOpt,
    out: Annotated[Path, typer.Option("--out", help="JSON file to write.")] = Path("morph.json"),
    project: ProjectOpt = None,
    no_cache: NoCacheOpt = False,
    *,
    table: TableOptions,
) -> None:
    """Morph each bench's regions into the next bench's and trace the boundary's trajectories (paper section 4)."""
    from core.io.atomic import atomic_write_text
    from core.model.pipeline import morph_json

    _outputs(out, input, project)
    session, geozone, model, elapsed = _model(
        input, geozone, project, ("correspond", "morph"), table, "morph", no_cache
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


#: Elevations given closer than this (input units) are one level: the files give z to three decimals.
SAME_LEVEL = 5e-4


def _elevations(text: str) -> list[float]:
    """The distinct elevations of ``--elevations`` (input units), in the order given.

    An elevation given again (``615,615``, or ``615,615.0000001``: within
    :data:`SAME_LEVEL`) is one level, the first as given, with a note: kept
    twice, the prediction had two identical features where the uncertainty
    file and ``p_inside.npz`` had one level, or two the files could not tell apart.
    """
    try:
        given = [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
    except ValueError:
        raise BGMInputError(f"--elevations must be numbers separated by commas, got {quoted(text)}") from None
    if not given or not all(np.isfinite(given)):
        raise BGMInputError(f"--elevations needs at least one finite number, got {quoted(text)}")
    levels: list[float] = []
    for v in given:
        if all(abs(v - kept) > SAME_LEVEL for kept in levels):
            levels.append(v)
    if len(levels) < len(given):
        again = [f"{kept:g}" for kept in levels if sum(abs(v - kept) <= SAME_LEVEL for v in given) > 1]
        _say(
            f"bgm: note: --elevations gives {', '.join(again)} more than once (to within {SAME_LEVEL:g}); "
            "each level is predicted once"
        )
    return levels


def decimal_comma_splits(text: str, far: list[float]) -> list[tuple[str, str]]:
    """``(whole, decimals)`` of the items of ``--elevations`` that read as one number written with a decimal comma.

    An integer, a comma and a short integer (``647,5``: 1 to 3 digits) whose second part is among the ``far``
    elevations refused: split at the comma, the decimals became an elevation hundreds of metres from any bench
    and were refused with no word of why. Items joined by ``;`` or by a comma and a space are not one number.
    """
    # A lookahead, so that the pairs overlap: in 660,652,25 both 660,652 and 652,25 are looked at.
    found = re.findall(r"(?<![\d.])(?=([+-]?\d+),(\d{1,3})(?![\d.]))", text)
    return [(whole, decimals) for whole, decimals in found if any(abs(float(decimals) - v) <= SAME_LEVEL for v in far)]


def _check_reach(levels: list[float], holes, text: str = "") -> None:
    """Refuse elevations more than ``MAX_PREDICTION_BENCHES`` bench heights above or below the benches.

    ``text`` is the option as given: a refused elevation that is the decimals of a number written with a
    decimal comma (:func:`decimal_comma_splits`) is said to be so, not to need ``--force``.
    """
    top, bottom = holes.bench_z_input(0), holes.bench_z_input(holes.n_benches - 1)
    height = float(np.min(-np.diff(holes.frame.z_to_input(holes.bench_levels_m))))
    reach = MAX_PREDICTION_BENCHES * height
    far = [v for v in levels if v > top + reach or v < bottom - reach]
    if not far:
        return
    where = (
        f"{'is' if len(far) == 1 else 'are'} more than {MAX_PREDICTION_BENCHES:g} bench heights "
        f"({reach:.4g} {holes.frame.length_unit}) outside the benches ({bottom:g} to {top:g})"
    )
    refused = f"--elevations {', '.join(f'{v:g}' for v in far[:5])} {where}"
    splits = decimal_comma_splits(text, far)
    if splits:
        read = "; ".join(f"{w},{d} is read as {w} and {d}" for w, d in splits[:3])
        w, d = splits[0]
        raise BGMInputError(
            f"{refused}: elevations are separated by commas ({read}); write decimals with a point ({w}.{d})"
        )
    raise BGMInputError(f"{refused}; a prediction that far is a guess: pass --force to make it anyway")


@app.command()
@reads_table
def predict(
    input: InputArg,
    geozone: GeozoneOpt,
    elevations: Annotated[
        str,
        typer.Option(
            "--elevations",
            help="Comma-separated elevations in input units, decimals with a point: 647.5,637.5 (above, between or "
            "below the benches).",
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="GeoJSON file to write.")] = Path("prediction.geojson"),
    project: ProjectOpt = None,
    force: Annotated[
        bool,
        typer.Option(
            "--force",
            help=f"Predict even more than {MAX_PREDICTION_BENCHES:g} bench heights above or below the benches.",
        ),
    ] = False,
    no_cache: NoCacheOpt = False,
    band_probability: BandProbabilityOpt = 0.9,
    *,
    table: TableOptions,
) -> None:
    """Predict the geozone's region at any elevation (paper: contour prediction).

    Beside --out it writes the uncertainty of every section off the benches:
    OUT.uncertainty.geojson (inner, outer and band polygons holding the true
    boundary with --band-probability) and OUT.p_inside.npz (probability of
    being inside the geozone on a grid).
    """
    from core.io.atomic import replaced_files
    from core.io.export import write_geojson
    from core.io.uncertainty_export import write_probability_grid

    given = _given_once(geozone, "bgm predict")
    levels = _elevations(elevations)
    _band_probability(band_probability)
    sidecars = uncertainty_sidecars(out)
    _outputs(out, input, project)
    for sidecar in sidecars:  # written too: none may be an input, a folder or a device
        _outputs(sidecar, input, project, what="the uncertainty file beside --out")
    holes = table.read(input)
    geozone = holes.check_one_geozone(given, "bgm predict")
    if holes.n_benches < 2:
        raise BGMInputError(
            f"{input} has a single bench ({holes.bench_z_input(0)}); correspondence needs two or more benches"
        )
    if not force:
        _check_reach(levels, holes, elevations)
    session = _session(holes, project, [geozone], "predict", no_cache)
    with progress_bar(f"morph {geozone[:40]}", "bench pairs") as update:
        model = session.geozone_model(geozone, stages=("correspond", "morph"), progress=update)
    # predicted nowhere, as bgm build and the viewer have it (ModelSession.predict): said why
    _say_no_pair(session, geozone, model, ", and so no prediction (bgm build and the viewer make none)")
    features = _prediction_features(session, geozone, levels, model)
    bands, grid = _uncertainty(session, geozone, levels, model, band_probability)
    # Written as one set once all is computed: an interrupt or a failure, during the work or while the three are
    # written, leaves the previous three as they were, never a new prediction beside old uncertainty files.
    unit = holes.frame.length_unit
    with replaced_files([out, *sidecars]) as (staged_out, staged_bands, staged_grid):
        write_geojson([f for f in features if not f["geometry"].is_empty], staged_out, units=unit)
        write_geojson(bands, staged_bands, units=unit)
        write_probability_grid(staged_grid, grid)
    empty = [f["properties"]["z"] for f in features if f["geometry"].is_empty]
    if empty and model.pairs:
        _say(f"bgm: note: {geozone} is predicted absent at {', '.join(map(str, empty))}")
    said = {"geozone": geozone, "elevations": levels, "features": len(features) - len(empty), "out": str(out)}
    # Below the deepest bench the sections are the depth trend's: how much of the benches' movement it carries on.
    if any(float(holes.frame.z_to_local(v)) < holes.bench_levels_m[-1] for v in levels) and model.pairs:
        from core.io.reporting import carried_json

        said["carried"] = carried_json(session.carried_movement(geozone, model), holes)
    typer.echo(json.dumps(said))


def uncertainty_sidecars(out: Path) -> tuple[Path, Path]:
    """Where ``bgm predict --out OUT`` writes the bands and the P(inside) grid."""
    stem = out.name[: -len(out.suffix)] if out.suffix else out.name
    return out.with_name(f"{stem}.uncertainty.geojson"), out.with_name(f"{stem}.p_inside.npz")


def _band_probability(value: float) -> None:
    if not (math.isfinite(value) and 0.5 <= value < 1):
        raise BGMInputError(f"--band-probability must lie in [0.5, 1), got {value}")


def _uncertainty(session, geozone: str, levels: list[float], model, probability: float) -> tuple[list, dict]:
    """The band features and P(inside) grid arrays of the predicted sections (see :mod:`core.io.uncertainty_export`)."""
    from core.io.uncertainty_export import band_features, probability_grid
    from core.model.uncertainty import geozone_uncertainty

    z_m = [float(session.holes.frame.z_to_local(v)) for v in levels]
    sections = geozone_uncertainty(session, geozone, z_m, model, probability)
    at_benches = [v for v, z in zip(levels, z_m) if sections[z] is None]
    if at_benches and model.pairs:  # with no pair there is no section anywhere (said by predict)
        _say(f"bgm: note: no uncertainty at bench levels {', '.join(map(str, at_benches))} (the bench's own contours)")
    return band_features(sections, session.holes, geozone), probability_grid(sections, session.holes, geozone)


def _prediction_features(session, geozone: str, levels: list[float], model) -> list[dict]:
    """One feature per elevation (input units), empty geometry where the geozone is predicted absent."""
    from core.io.reporting import prediction_feature

    holes = session.holes
    z_m = [float(holes.frame.z_to_local(v)) for v in levels]
    regions = session.predict(geozone, z_m, model)
    return [prediction_feature(regions[zm], holes, geozone, level) for level, zm in zip(levels, z_m)]


@app.command()
@reads_table
def evaluate(
    input: InputArg,
    geozone: GeozoneOpt,
    out: Annotated[Path, typer.Option("--out", help="Folder for the table (CSV) and plot (PNG).")] = Path("evaluation"),
    project: ProjectOpt = None,
    no_cache: NoCacheOpt = False,
    *,
    table: TableOptions,
) -> None:
    """Precision and recall of predictions below withheld benches, against nil, linear and implicit references.

    With --project the model scored is the one the project makes (its
    parameters and manual alignment overrides), as bgm build --project
    evaluates it. The references take nothing from the overrides or the
    model's parameters; parameters of the contours stage change the contours
    every method starts from and is scored on.
    """
    from core.io.atomic import atomic_write_text, check_output, replaced_files
    from core.model.build import load_truth, predictor_from_model
    from core.model.evaluation import (
        evaluate_geozone,
        format_table,
        margin_lines,
        plot_precision_recall,
        rows_as_written,
        summary_as_written,
        summary_table,
    )

    given = _given_once(geozone, "bgm evaluate")
    names = ("evaluation_rows.csv", "evaluation.csv", "precision_recall.png")
    check_output(out, folder=True)
    for name in names:
        _outputs(out / name, input, project)  # nor the project file
    holes = table.read(input)
    geozone = holes.check_one_geozone(given, "bgm evaluate")
    if holes.n_benches < 3:
        raise BGMInputError(f"{input} has {holes.n_benches} bench(es); evaluation needs at least three")
    truth = load_truth(input, holes)
    session = _session(holes, project, [geozone], "evaluate", no_cache)
    start = time.perf_counter()
    contours = session.geozone_contours(geozone)
    with progress_bar(f"model {geozone[:40]}", "bench pairs") as update:
        model = session.geozone_model(geozone, contours=contours, progress=update)
        predictor = predictor_from_model(model, holes, session.params)
        rows = evaluate_geozone(
            holes,
            geozone,
            predictor,
            truth=truth,
            contours=contours,
            progress=lambda done, total: update(done, total, f"evaluate {geozone[:40]}", "withheld benches"),
        )
    if rows.empty:
        raise BGMInputError(f"geozone {geozone} has no bench with two known benches above it and holes below")
    _refuse_empty_scores(rows, holes, geozone)
    rows.insert(0, "geozone", geozone)  # as a build's rows say it: the folder may hold another geozone's before
    summary = summary_as_written(summary_table(rows), holes)
    # The three as one set, the folder made with them: an input refused (unreadable, too few benches, nothing to
    # score) left an empty folder, and a failure or Ctrl-C after the plot a new plot beside the previous tables
    # (or a new folder holding only the plot). A folder that cannot be made was refused before any work
    # (_outputs above tries a file in it).
    unit = holes.frame.length_unit
    with replaced_files([out / name for name in names]) as (staged_rows, staged_summary, staged_plot):
        plot_precision_recall(summary, staged_plot, title=f"{geozone}: model vs references", unit=unit)
        atomic_write_text(staged_rows, rows_as_written(rows, holes).to_csv(index=False))
        atomic_write_text(staged_summary, summary.to_csv(index=False))
    _say(
        f"truth: {'synthetic generator' if truth is not None else 'next bench holes'}; {time.perf_counter() - start:.1f} s"
    )
    typer.echo(format_table(summary, unit))
    for line in margin_lines(summary, unit):
        typer.echo(line)


def _refuse_empty_scores(rows, holes, geozone: str) -> None:
    """Refuse an evaluation whose every score is 0 / 0: the geozone on no bench scored, outlined on none, or predicted nowhere."""
    if rows["g_area"].any() and rows["p_area"].any():
        return
    benches_on = set(holes.bench[holes.geozone == geozone].tolist())
    benches_scored = {int(k) + 1 for k in rows["bench"]}
    on, scored = _benches_at(holes, benches_on), _benches_at(holes, benches_scored)
    if not benches_on & benches_scored:
        # Said as label noise, a body of fifty holes on the top bench alone read as if it were two stray holes.
        why = f"has no hole on any bench it could be scored on ({scored}, those with two benches above): its holes are on {on}"
    elif not rows["g_area"].any():
        why = (
            f"has no contour on any bench it could be scored on ({scored}): its holes are on {on}, "
            "and one or two holes alone are taken as label noise"
        )
    else:
        why = (
            f"is predicted by no method on the benches scored ({scored}): "
            f"the benches above do not show it there (its holes are on {on})"
        )
    raise BGMInputError(f"geozone {geozone} {why}; nothing to evaluate")


def _benches_at(holes, benches: set[int]) -> str:
    """The benches' elevations in the input's units, top first: "the benches at 675, 665 m"."""
    levels = ", ".join(f"{holes.bench_z_input(k):g}" for k in sorted(benches))
    return f"the bench{'es' if len(benches) > 1 else ''} at {levels} {holes.frame.length_unit}"


def _run_build(holes, out, geozone, project, truth, workers=None, scheduler=None, no_cache=False) -> dict:
    from core.model.build import build

    wanted = _wanted(holes, geozone)
    session = _session(holes, project, wanted, "build", no_cache)
    with progress_bar("building") as update:
        summary = build(
            holes,
            out,
            geozones=wanted,
            params=session.params,
            project=session.project,
            truth=truth,
            progress=_staged(update),
            workers=workers,
            scheduler=scheduler,
            cache=session.store.cache,
        )
    if summary.get("evaluation_note"):
        _say(f"bgm: note: {summary['evaluation_note']}")
    _say(f"wrote {out}/report.md ({summary['seconds']:.1f} s)")
    return summary


@app.command()
@reads_table
def build(
    input: InputArg,
    out: Annotated[Path, typer.Option("--out", help="Folder for the results.")] = Path("bgm-out"),
    geozone: Annotated[
        list[str] | None,
        typer.Option("--geozone", help="Geozones to model (repeat, or separate with commas; default all)."),
    ] = None,
    project: ProjectOpt = None,
    workers: Annotated[int | None, typer.Option(help="Local processes (default: one per usable core).")] = None,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", help="Address of a dask.distributed scheduler to run on instead.")
    ] = None,
    no_cache: NoCacheOpt = False,
    *,
    table: TableOptions,
) -> None:
    """The whole pipeline for every geozone: contours, correspondence, trajectories, predictions, surfaces, evaluation, report."""
    from core.model.build import check_model_folder, load_truth

    if workers is not None and workers < 1:
        raise BGMInputError(f"--workers must be 1 or more, got {workers}")
    _outputs(out, input, project, folder=True)
    check_model_folder(out)
    holes = table.read(input)
    if holes.n_benches < 2:
        raise BGMInputError(f"{input} has a single bench; building a model needs two or more benches")
    summary = _run_build(holes, out, geozone, project, load_truth(input, holes), workers, scheduler, no_cache)
    typer.echo(json.dumps({k: summary[k] for k in ("holes", "seconds")} | {"out": str(out)}))


@app.command()
def demo(
    out: Annotated[Path, typer.Option("--out", help="Folder for the results.")] = Path("bgm-demo"),
    view: Annotated[
        bool, typer.Option(help="Open the 3D viewer on the result (needs the viewer installed and a display).")
    ] = False,
    no_cache: NoCacheOpt = False,
) -> None:
    """Build the whole model on the bundled synthetic demo data (assets/demo_blastholes.csv)."""
    from core.io.blastholes import read_blastholes
    from core.model.build import check_model_folder, load_truth

    viewer = _viewer_command() if view else None
    _outputs(out, DEMO_CSV, folder=True)
    check_model_folder(out)
    holes = read_blastholes(DEMO_CSV)
    _run_build(holes, out, None, None, load_truth(DEMO_CSV, holes), no_cache=no_cache)
    typer.echo((out / "report.md").read_text())
    if viewer is None:
        _say("open it in 3D with: bgm view")
        return
    with contextlib.suppress(ValueError):  # the window closes on SIGTERM, as a window does (see main)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    viewer(DEMO_CSV, no_cache=no_cache)  # the stages just built, from the cache (unless --no-cache)


def _viewer_command():
    """The ``view`` command's callback, refused before any work if it is not installed or cannot open a window.

    A viewer plug-in may give its callback a ``preflight()`` that raises
    :class:`BGMInputError` when no window can be opened (no display).
    """
    viewer = next((c.callback for c in app.registered_commands if c.name == "view" and c.callback), None)
    if viewer is None:
        raise BGMInputError("the 3D viewer is not installed: pip install -e '.[viewer]'")
    getattr(viewer, "preflight", lambda: None)()
    return viewer


@app.command()
def parameters() -> None:
    """The model's parameters, by stage: what a project file's "parameters" may set, with defaults and ranges.

    Lengths are metres (ranges in hole spacings), angles radians, flags true or
    false; a default of "auto" is derived from the data as the last column says.
    """
    from rich.console import Console
    from rich.table import Table

    from core.model.parameters import PARAMETERS

    table = Table("name", "stage", "symbol", "default", "typical range", "what it does", show_lines=False)
    for p in PARAMETERS:
        scale = " x spacing" if p.kind == "length" else ""
        if p.kind == "flag":
            default, typical = str(p.default).lower(), "true or false"
        else:
            default = "auto: " + p.auto if p.default is None else f"{p.default:g}"
            typical = f"{p.minimum:g} - {p.maximum:g}{scale}"
        table.add_row(p.name, p.stage, p.symbol, default, typical, p.help)
    Console(width=200).print(table)


@app.command()
@reads_table
def suggest(
    input: InputArg,
    geozone: Annotated[
        list[str],
        typer.Option(
            "--geozone", help="Geozone(s) to pin down (repeat, or separate with commas); they share the budget."
        ),
    ],
    budget: Annotated[int, typer.Option("--budget", help="Number of holes to suggest, for all the geozones together.")],
    out: Annotated[Path, typer.Option("--out", help="CSV file to write.")] = Path("suggestions.csv"),
    pattern: Annotated[
        Path | None,
        typer.Option(
            "--pattern", help="Planned blast pattern (CSV with x, y; optional z, hole_id): choose among its holes."
        ),
    ] = None,
    elevation: Annotated[
        float | None,
        typer.Option(
            "--elevation", help="Elevation of the bench to sample (default: the pattern's, else the next bench)."
        ),
    ] = None,
    project: ProjectOpt = None,
    band_probability: BandProbabilityOpt = 0.9,
    no_cache: NoCacheOpt = False,
    *,
    table: TableOptions,
) -> None:
    """Holes on the next bench whose labels would most reduce the uncertainty of the geozones' boundaries.

    Without --pattern the holes are laid out on the deepest bench's spacing
    and orientation over its drilled area; with it, they are a subset of the
    planned holes. Each row gives x, y, z, the geozone it informs, the
    predicted probability of being inside it and a short reason.
    """
    from core.io.uncertainty_export import read_pattern, suggestions_table, write_suggestions
    from core.model.sampling import next_bench_candidates, plan_sampling

    if budget < 1:
        raise BGMInputError(f"--budget must be 1 or more holes, got {budget}")
    _band_probability(band_probability)
    _outputs(out, input, project, pattern)
    holes = table.read(input)
    wanted = _wanted(holes, geozone)
    if holes.n_benches < 2:
        raise BGMInputError(f"{input} has a single bench; predicting the next one needs two or more benches")
    session = _session(holes, project, wanted, "suggest", no_cache)
    labels, z_pattern, candidates = None, None, None
    if pattern is not None:
        # How far the predictions reach past the drilling is the project's if it sets it, not the default.
        candidates, labels, z_pattern = read_pattern(pattern, holes, session.params.frontier_reach_spacings)
    level = _next_level(holes, elevation if elevation is not None else z_pattern)
    if candidates is None:
        try:
            candidates = next_bench_candidates(holes)
        except ValueError as exc:
            raise BGMInputError(f"{exc}; give the holes with --pattern") from None
    with progress_bar("uncertainty", "geozones") as update:
        plan = plan_sampling(session, wanted, budget, level, candidates, band_probability, progress=_staged(update))
    if not plan.sections:
        raise BGMInputError(f"no geozone of {', '.join(wanted)} has a predicted boundary to sample at that elevation")
    in_band = int(sum(s.in_band for s in plan.suggestions))
    if not in_band:
        _say(_outside_band_note(plan, wanted))
    if plan.suggestions and budget > len(candidates):
        _say(f"bgm: note: only {len(candidates)} candidate holes; all of them are suggested")
    data = suggestions_table(plan.suggestions, holes, level, band_probability, labels)
    write_suggestions(out, data)
    typer.echo(
        json.dumps(
            {
                "geozones": wanted,
                "z": round(float(holes.frame.z_to_input(level)), 3),
                "candidates": int(len(candidates)),
                "suggested": int(len(data)),
                "in_band": in_band,
                "out": str(out),
            }
        )
    )


def _outside_band_note(plan, wanted: list[str]) -> str:
    """The note of a suggestion with no hole in the band: why, judged on the band each row's ``in_band`` reports.

    Holes are chosen on the wider band of the boundary their labels will show
    (:meth:`~core.model.uncertainty.SectionUncertainty.as_observed`), but a
    suggestion's ``in_band`` and the count printed are the written band's
    (``uncertainty.geojson``): judged on the wider one, holes all beyond the
    written band were suggested with ``"in_band": 0`` and no word.
    """
    # A geozone predicted absent has a band but no contact in it: it takes no part in suggestions.
    contacts = [g for g in wanted if g in plan.sections and plan.sections[g].has_contact]
    band = f"the {plan.probability:.0%} band of {', '.join(contacts or wanted)}'s predicted boundary"
    if not plan.suggestions:
        return (
            f"bgm: note: no candidate hole lies in {band} (predicted absent there, or certain): nothing to pin "
            "down, none suggested"
        )
    n = len(plan.suggestions)
    beyond = "beyond it, where the boundary the holes' labels will show is still unsure (their reason says so)"
    if not any(plan.sections[g].in_band(plan.candidates_m).any() for g in contacts):
        return f"bgm: note: no candidate hole lies in {band}; the {n} suggested lie {beyond}"
    return f"bgm: note: none of the {n} suggested holes lies in {band}; they lie {beyond}"


def _next_level(holes, elevation: float | None) -> float:
    """The elevation to sample (local metres): ``elevation`` (input units), else one bench below the deepest.

    It must lie below the deepest bench, within :data:`MAX_PREDICTION_BENCHES` bench heights.
    """
    levels = holes.bench_levels_m
    if elevation is None:
        return holes.below_deepest_m()
    if not math.isfinite(elevation):
        raise BGMInputError(f"--elevation must be a finite number, got {elevation}")
    from core.model.prediction import bench_at

    z = float(holes.frame.z_to_local(elevation))
    bottom = holes.bench_z_input(holes.n_benches - 1)
    unit = holes.frame.length_unit
    if z >= levels[-1] - 1e-6:
        raise BGMInputError(
            f"elevation {elevation:g} is not below the deepest bench ({bottom:g} {unit}); "
            "suggestions are for the next bench down"
        )
    # Just below it (624.99999 under 625 m) the model takes the elevation as the bench's level, whose section
    # is its own contours with no band: accepted here, it failed later saying no geozone had a boundary there.
    if bench_at(levels, z) is not None:
        raise BGMInputError(
            f"elevation {elevation:.10g} is the deepest bench's level ({bottom:g} {unit}) to the model's precision, "
            "where the section is the bench's own contours with no uncertainty to sample; suggestions are for "
            "the next bench down: give an elevation further below it"
        )
    if z < holes.below_deepest_m(MAX_PREDICTION_BENCHES):
        raise BGMInputError(
            f"elevation {elevation:g} is more than {MAX_PREDICTION_BENCHES:g} bench heights below the deepest bench "
            f"({bottom:g} {holes.frame.length_unit}); a prediction that far is a guess"
        )
    return z


@app.command("make-demo-data")
def make_demo_data(
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="CSV to write (default: demo_blastholes.csv, or FAMILY_SEED.csv / SHAPE_SEED.csv, in the current "
            "folder; the bundled demo is never replaced unless named here).",
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Random seed of the synthetic mine.")] = 2019,
    family: Annotated[
        str | None,
        typer.Option(help="Synthetic family instead of the demo: strips, widening, folds, splits, pods or mix."),
    ] = None,
    shape: Annotated[
        str | None,
        typer.Option(
            help="A shape outside the families instead (no default was tuned on them): ring, "
            "'faulted strip', inclusion, 'pivoting contact', 'angular body', arc or 'shallow layer'."
        ),
    ] = None,
) -> None:
    """Write the synthetic demo blastholes (as bundled in assets/demo_blastholes.csv), or a synthetic family's or shape's."""
    from core.io.atomic import atomic_write_text, check_output
    from core.model.build import truth_sidecar
    from core.synthetic.blobs import demo_dataset
    from core.synthetic.scenarios import scenario
    from core.synthetic.shapes import shape_scenario

    if seed < 0:
        raise BGMInputError(f"--seed must be 0 or more, got {seed}")
    if family is not None and shape is not None:
        raise BGMInputError("give --family or --shape, not both")
    if out is None:  # in the working folder: the bundled demo, which `bgm demo` builds, stays as shipped
        name = family or shape
        out = Path(f"{name.replace(' ', '_')}_{seed}.csv" if name else DEMO_CSV.name)
    check_output(out)
    check_output(truth_sidecar(out))
    try:
        if family is not None:
            _, table, _ = scenario(family, seed)
            spec = {"generator": "core.synthetic.scenario", "family": family, "seed": seed}
        elif shape is not None:
            _, table, _ = shape_scenario(shape, seed)
            spec = {"generator": "core.synthetic.shape_scenario", "shape": shape, "seed": seed}
        else:
            _, table = demo_dataset(seed)
            spec = {"generator": "core.synthetic.demo_dataset", "seed": seed}
    except ValueError as exc:
        raise BGMInputError(str(exc)) from None
    atomic_write_text(out, table.to_csv(index=False))
    # The generator knows the true sections: record how to regenerate them for evaluation.
    atomic_write_text(truth_sidecar(out), json.dumps(spec))
    _say(f"wrote {len(table)} holes to {out} (truth in {truth_sidecar(out).name})")


# --------------------------------------------------------------------------- entry point


def _show_warning(message, category, filename, lineno, file=None, line=None):
    _say(f"bgm: warning: {_one_line(message)}")


def _one_line(message, limit: int = 1000) -> str:
    """A message on one line, cut to ``limit`` characters (user text in it can be megabytes)."""
    text = " ".join(str(message).split())
    return text if len(text) <= limit else text[:limit] + f"... ({len(text)} characters)"


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
            _say(
                f"bgm: warning: the {ep.name!r} command could not be loaded ({type(exc).__name__}: {_one_line(exc, 300)})"
            )
            continue
        loaded.append(ep.name)
    return loaded


#: The engine's commands that never write surfaces, so never load trimesh (most of a second to import).
_WITHOUT_SURFACES = frozenset(
    {"contours", "correspond", "morph", "predict", "evaluate", "parameters", "suggest", "make-demo-data"}
)


#: The engine's own commands (add-ons such as ``view`` are not among them).
_ENGINE_COMMANDS = _WITHOUT_SURFACES | {"build", "demo"}


def _command(argv: list[str]) -> str | None:
    """The command ``bgm ARGV`` runs: its first argument that is not an option."""
    return next((a for a in argv if not a.startswith("-")), None)


def _stop_on_sigterm(argv: list[str]) -> None:
    """Make SIGTERM (kill, timeout, a job scheduler) stop the engine's commands as Ctrl-C does.

    By default Python dies on the spot, leaving its staging folder and a
    build's workers behind. Not an add-on's command (``view``): a Qt event
    loop runs no Python handler until an event comes, and a window that
    ignored SIGTERM would stay open.
    """
    if _command(argv) in _ENGINE_COMMANDS:
        signal.signal(signal.SIGTERM, _on_ctrl_c)


def _import_uninterrupted(argv: list[str]) -> None:
    """Import the libraries that swallow Ctrl-C during their own import, with Ctrl-C held until done.

    Only for commands that may load them: ``build``, ``demo`` and add-ons.
    """
    if _command(argv) in _WITHOUT_SURFACES:
        return
    with _ctrl_c_held():
        import trimesh  # noqa: F401  (its optional-import guards catch BaseException)


def _stopped_status(code: int) -> tuple[int, str | None]:
    """The exit status and line of a command stopped by a signal (Ctrl-C or SIGTERM); ``code`` and None if not."""
    if code != 130 and not (_INTERRUPTS and code != 0):  # typer turns Ctrl-C into exit status 130 without a word
        return code, None
    if _INTERRUPTS and _INTERRUPTS[0] == signal.SIGTERM:
        return 128 + signal.SIGTERM, "bgm: terminated; files being written were left as they were"
    return 130, "bgm: interrupted; files being written were left as they were"


def main() -> None:
    """Entry point of the ``bgm`` console script: run the command, print at most one line, exit."""
    global _COMMAND_PID
    _COMMAND_PID = os.getpid()
    on_sigterm = signal.getsignal(signal.SIGTERM)
    with contextlib.suppress(ValueError):  # not the main thread: Python's default handling
        signal.signal(signal.SIGINT, _on_ctrl_c)
        _stop_on_sigterm(sys.argv[1:])
    sys.unraisablehook = _interrupt_again
    try:
        code, line = _stopped_status(_run())
    finally:
        sys.unraisablehook = sys.__unraisablehook__
    if line is not None:
        _say(line)
    # The work is done (or abandoned): a Ctrl-C while the interpreter shuts down changes
    # nothing. Ignored, not handled: Python resets its own handlers to the default
    # (die by SIGINT) while it shuts down.
    with contextlib.suppress(ValueError):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        # SIGTERM as it was: ignored, it would be inherited by whatever this process forks next when
        # main() runs inside another program (the tests), and a terminated worker would live on.
        if on_sigterm is not None:
            signal.signal(signal.SIGTERM, on_sigterm)
    if _INTERRUPTS and line is not None:
        # Every file is closed and every staging folder gone; the interpreter's own
        # shutdown, with worker-pool threads cut short, can crash ("Fatal Python
        # error") and would add a second message: leave now, without a worker process
        # (they ignore Ctrl-C and share the terminal's pipes) left waiting for work.
        _stop_worker_processes()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _stop_worker_processes() -> None:
    """Terminate this process's live worker processes (local build pools), if any were started."""
    import multiprocessing

    for child in multiprocessing.active_children():
        child.terminate()


def _run() -> int:
    """Run the command line; returns the exit status after printing any error in one line."""
    from core.errors import BGMWarning

    try:  # typer 0.2x carries its own copy of click
        from typer._click import exceptions as click
    except ImportError:
        from click import exceptions as click  # type: ignore[no-redef]  # older typer uses click itself

    # Users see the engine's own warnings (repairs to their data), not library chatter.
    warnings.showwarning = _show_warning
    warnings.filterwarnings("ignore")
    warnings.filterwarnings("always", category=BGMWarning)
    try:
        _import_uninterrupted(sys.argv[1:])
        load_plugins()
        return 130 if _INTERRUPTS else (app(prog_name="bgm", standalone_mode=False) or 0)
    except click.NoArgsIsHelpError:
        app(["--help"], prog_name="bgm", standalone_mode=False)
        return 2
    except click.UsageError as exc:  # a missing or malformed option
        where = f" (see {exc.ctx.command_path} --help)" if exc.ctx is not None else ""
        _say(f"bgm: error: {_one_line(exc.format_message())}{where}")
        return 2
    except typer.Abort:  # end of input while prompting
        _say("bgm: error: input ended unexpectedly")
        return 2
    except KeyboardInterrupt:
        return 130
    except BGMInputError as exc:
        if _INTERRUPTS:
            return 130
        _say(f"bgm: error: {_one_line(exc)}")
        return 2
    except MemoryError:
        _say("bgm: error: out of memory; try fewer geozones or benches at a time")
        return 3
    except Exception as exc:  # a bug: say so plainly, traceback only on request
        if _INTERRUPTS:  # a library left broken by a Ctrl-C it swallowed
            return 130
        if os.environ.get("BGM_DEBUG"):
            raise
        _say(f"bgm: internal error: {type(exc).__name__}: {_one_line(exc, 300)} (set BGM_DEBUG=1 for the traceback)")
        return 3


_LOADING.__exit__(None, None, None)

if __name__ == "__main__":
    main()
