"""``bgm view``: the viewer's command, added to the engine's command line as a plug-in.

``core.cli`` never imports the viewer: it loads the entry points of the group
``bgm.commands`` (see :func:`core.cli.load_plugins`), and this package's
pyproject entry ``view = "bgm_viewer.cli_hooks:register"`` adds the command.
Nothing here imports Qt or PyVista until the command runs, so ``bgm`` works
without them and ``bgm view`` says in one line what to install.

``view_command(input, project, screenshot, layers, camera)``:

* with ``screenshot``: render the scene off-screen to that picture (PNG, JPEG,
  BMP or TIFF by its extension; no Qt, no display needed) and return 0;
* otherwise: open the Qt window (``run_viewer``) and return its exit code.

Every option is checked before anything is loaded or drawn: an unknown layer
or camera, a geozone or bench that is not in the input, a vertical
exaggeration that is not a positive number, all raise
:class:`core.errors.BGMInputError` naming the option, as do errors in the
input or project; the CLI reports them in one line.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from core.errors import BGMInputError, quoted

from .layer_names import DEFAULT_VISIBLE, LAYER_NAMES, SCREENSHOT_FORMATS, parse_layers

if TYPE_CHECKING:
    from core.io.blastholes import Blastholes

#: Largest vertical exaggeration a picture can use.
MAX_EXAGGERATION = 100.0
#: A camera direction closer than this (degrees) to vertical has no "up" to draw: use ``top``.
MIN_CAMERA_TILT_DEG = 1.0
#: Qt platforms that draw through a display server (X or Wayland); any other one the user names
#: (offscreen, minimal, linuxfb, eglfs, vnc, ...) needs none.
DISPLAY_PLATFORMS = ("xcb", "wayland")
NO_DISPLAY = "no display to open a window on (DISPLAY is not set); use --screenshot FILE to render offscreen"
#: What --bench selects: the stage layers (edge map, GVF, snake, wavefront, trajectories) show one bench pair.
BENCH_HELP = (
    "Bench pair to select, by the index of its upper bench: 0 = the top bench and the one below it, "
    "up to the number of benches minus 2 (default: the pair where the geozone has the most holes)."
)
QT_MISSING = "the viewer needs Qt and PyVista ({}); install them with: pip install -e '.[viewer]'"


def register(app: typer.Typer) -> None:
    """Add ``bgm view`` to the engine's typer app, with the table options every reading command takes."""
    from core.cli import reads_table

    command = reads_table(view)
    command.preflight = check_display  # what ``bgm demo --view`` checks before building
    app.command("view")(command)


def view(
    input: Annotated[
        Path | None,
        typer.Argument(help="Blasthole table (default: the bundled demo; - for standard input).", show_default=False),
    ] = None,
    project: Annotated[
        Path | None, typer.Option("--project", help="Project file with parameters and manual alignment overrides.")
    ] = None,
    screenshot: Annotated[
        Path | None,
        typer.Option(
            "--screenshot",
            help=f"Render off-screen to this picture ({', '.join(SCREENSHOT_FORMATS)}) instead of opening the window.",
        ),
    ] = None,
    layers: Annotated[
        str | None,
        typer.Option(
            help=f"Layers to show, comma-separated (any case, - or _ for a space): {', '.join(LAYER_NAMES)} "
            f"(default: those the project saved, else {', '.join(DEFAULT_VISIBLE)})."
        ),
    ] = None,
    camera: Annotated[
        str | None,
        typer.Option(
            help="iso, top, front, side, or a view direction x,y,z (default: the camera the project saved, else iso)."
        ),
    ] = None,
    geozone: Annotated[list[str] | None, typer.Option("--geozone", help="Geozone to select.")] = None,
    bench: Annotated[int | None, typer.Option(help=BENCH_HELP)] = None,
    exaggeration: Annotated[float | None, typer.Option(help="Vertical exaggeration.")] = None,
    no_cache: Annotated[
        bool, typer.Option("--no-cache", help="Compute every stage afresh instead of reusing earlier runs' results.")
    ] = False,
    *,
    table=None,
) -> None:
    """Open the 3D viewer (or render a screenshot with no display)."""
    from core.cli import DEMO_CSV, _given_once, _outputs  # the engine's checks of every output

    selected = None if geozone is None else _given_once(geozone, "bgm view")  # typer kept the last one alone

    if input is not None and str(input) != "-" and not Path(input).exists():
        raise BGMInputError(f"input file {str(input)!r} does not exist")
    if screenshot is not None:
        _outputs(screenshot, input if input is not None else DEMO_CSV, project)
        check_screenshot_name(screenshot)
    else:
        check_display()  # before the table is read: Qt would abort the process, not raise
    source = input
    if table is not None and table.given():
        if input is None and project is not None:
            from core.io.project import load_project, saved_input

            input = saved_input(load_project(project), project)  # read as the project was made (its options)
        if input is None:
            raise BGMInputError("--x, --y, --z, --geozone-column, --bench-height and --units need an input table")
        source = table.read(input)  # columns, bench height or units named on the command line
    with screenshot_progress() if screenshot else contextlib.nullcontext() as progress:
        code = view_command(
            source,
            project,
            screenshot,
            layers,
            camera,
            geozone=selected,
            bench=bench,
            vertical_exaggeration=exaggeration,
            cache=not no_cache,
            progress=progress,
        )
    if screenshot:
        typer.echo(f"wrote {screenshot}", err=True)
    raise typer.Exit(code or 0)


@contextlib.contextmanager
def screenshot_progress():
    """``progress(message, fraction)`` for a screenshot's run, said as every command says its steps.

    A screenshot of the surfaces runs the whole pipeline (16 s on the demo, minutes on a
    large table) and said nothing until ``wrote``: in batch it looked hung. Its steps go
    through :func:`core.cli.progress_bar` (a bar on a terminal, a line a step otherwise) in
    percent of the run, which never goes back (the viewer's fractions order the selected
    items first, not always rising).
    """
    from core.cli import progress_bar

    with progress_bar("screenshot", "percent") as update:
        furthest = [0]

        def progress(message: str, fraction: float) -> None:
            # 100 is the run's end alone ("done"): its last surface, at 100 too, said the same twice.
            furthest[0] = max(furthest[0], min(100 if message == "done" else 99, round(100 * fraction)))
            update(furthest[0], 100, message)

        yield progress


def view_command(
    input: str | Path | Blastholes | None = None,
    project: str | Path | None = None,
    screenshot: str | Path | None = None,
    layers: str | list[str] | None = None,
    camera: str | None = None,
    *,
    geozone: str | None = None,
    bench: int | None = None,
    vertical_exaggeration: float | None = None,
    cache: bool = True,
    progress=None,
) -> int:
    """Render ``screenshot`` off-screen (no Qt, no display) and return 0, or open the window and return its exit code.

    ``progress(message, fraction)`` is told the screenshot's steps (:func:`screenshot_progress`).

    Errors in the options, input or project are :class:`core.errors.BGMInputError`, for the CLI to report.
    """
    try:
        from .model import load_holes, project_input, project_read_options

        if screenshot:
            from .screenshot import render_screenshot
        else:
            check_display()
            from .app import run_viewer
    except ImportError as exc:
        raise BGMInputError(QT_MISSING.format(exc)) from None
    check_view_options(layers, camera, vertical_exaggeration)
    if input is None and project is not None:
        input = project_input(project)
    elif project is not None and isinstance(input, str | Path):
        from core.io.project import check_project_input, load_project

        check_project_input(load_project(project), project, input)
    if project is not None and isinstance(input, str | Path) and project_read_options(project):
        input = load_holes(input, project_read_options(project))  # read as the project was made: feet stay feet
    if screenshot:
        holes = _checked_holes(input, geozone, bench)
        render_screenshot(
            holes,
            screenshot,
            layers=layers,
            camera=camera,  # None: the project's saved camera, else iso
            project=project,
            geozone=geozone if geozone is None else holes.check_one_geozone(geozone, "bgm view"),
            bench=bench,
            vertical_exaggeration=vertical_exaggeration,
            cache=cache,
            progress=progress,
        )
        return 0
    if geozone is not None or bench is not None:
        input = _checked_holes(input, geozone, bench)  # read once: the window opens on these holes
        geozone = geozone if geozone is None else input.check_one_geozone(geozone, "bgm view")
    view = {"geozone": geozone, "bench": bench, "layers": layers, "camera": camera}
    view["vertical_exaggeration"] = vertical_exaggeration
    return run_viewer(input, project, cache=cache, **{k: v for k, v in view.items() if v is not None})


def check_view_options(layers=None, camera: str | None = None, vertical_exaggeration: float | None = None) -> None:
    """Refuse layers, cameras and exaggerations that cannot make a picture (one sentence each)."""
    from .scene import CAMERAS

    try:
        names = parse_layers(layers)
    except (KeyError, ValueError) as exc:
        raise BGMInputError(f"--layers: {exc.args[0] if exc.args else exc}") from None
    if layers is not None and not names:
        raise BGMInputError(f"--layers names no layer; layers are: {', '.join(LAYER_NAMES)}")
    if camera is not None and camera not in CAMERAS:
        _check_direction(camera, CAMERAS)
    if vertical_exaggeration is not None and not (
        math.isfinite(vertical_exaggeration) and 0 < vertical_exaggeration <= MAX_EXAGGERATION
    ):
        raise BGMInputError(
            f"--exaggeration must be a number above 0 and at most {MAX_EXAGGERATION:g}, got {vertical_exaggeration}"
        )


def check_display() -> None:
    """Refuse to open a window where Qt would find no display server (it aborts the process instead).

    Only X11/Wayland systems (Linux, the BSDs) have one to miss; macOS and
    Windows always have their own. A ``QT_QPA_PLATFORM`` that needs no display
    (offscreen, minimal, a frame buffer) is left to Qt.
    """
    if sys.platform.startswith(("darwin", "win", "cygwin", "msys")):
        return
    wanted = os.environ.get("QT_QPA_PLATFORM", "").strip()
    # "name:options", or a ';'-separated list Qt tries in turn
    platforms = [p.split(":")[0].strip().lower() for p in wanted.split(";") if p.strip()]
    if any(not p.startswith(DISPLAY_PLATFORMS) for p in platforms):
        return
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise BGMInputError(NO_DISPLAY)


def check_screenshot_name(screenshot: str | Path) -> None:
    """Refuse a picture name whose extension is not one of :data:`SCREENSHOT_FORMATS` (any case)."""
    suffix = Path(screenshot).suffix
    if suffix.lower() not in SCREENSHOT_FORMATS:
        what = f"bgm writes no {quoted(suffix)} pictures" if suffix else "a picture needs an extension"
        raise BGMInputError(
            f"--screenshot {quoted(Path(screenshot).name)}: {what}; use one of {', '.join(SCREENSHOT_FORMATS)}"
        )


def _check_direction(camera: str, names) -> None:
    try:
        vec = [float(v) for v in camera.split(",")]
    except ValueError:
        raise BGMInputError(
            f"--camera {quoted(camera)} is not a camera: use one of {', '.join(names)} or a view direction x,y,z"
        ) from None
    if len(vec) != 3 or not all(map(math.isfinite, vec)):
        raise BGMInputError(f"--camera direction needs three finite numbers x,y,z, got {quoted(camera)}")
    norm = math.sqrt(sum(v * v for v in vec))
    if norm == 0:
        raise BGMInputError(f"--camera direction {quoted(camera)} has no length: it points nowhere")
    if math.degrees(math.acos(min(1.0, abs(vec[2]) / norm))) < MIN_CAMERA_TILT_DEG:
        raise BGMInputError(f"--camera direction {quoted(camera)} is vertical; use --camera top for a plan view")


def _checked_holes(input, geozone: str | None, bench: int | None):
    """The input's blastholes, with the selection checked against them (the project is checked as it is applied)."""
    from .model import load_holes

    holes = load_holes(input)
    if geozone is not None:
        holes.check_one_geozone(geozone, "bgm view")
    last = max(holes.n_benches - 2, 0)  # a single bench still has its own contours to show, as pair 0
    if bench is not None and not 0 <= bench <= last:
        raise BGMInputError(
            f"--bench {bench} is out of range: it selects a bench pair by its upper bench, and "
            f"{holes.source or 'the input'} has {holes.n_benches} bench(es), so --bench must be 0 to {last}"
        )
    return holes
