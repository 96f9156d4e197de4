"""``bgm view``: the viewer's command, added to the engine's command line as a plug-in.

``core.cli`` never imports the viewer: it loads the entry points of the group
``bgm.commands`` (see :func:`core.cli.load_plugins`), and this package's
pyproject entry ``view = "bgm_viewer.cli_hooks:register"`` adds the command.
Nothing here imports Qt or PyVista until the command runs, so ``bgm`` works
without them and ``bgm view`` says in one line what to install.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from core.errors import BGMInputError

QT_MISSING = "the viewer needs Qt and PyVista ({}); install them with: pip install -e '.[viewer]'"


def register(app: typer.Typer) -> None:
    """Add ``bgm view`` to the engine's typer app."""
    app.command("view")(view)


def view(
    input: Annotated[
        Path | None, typer.Argument(help="Blasthole table (default: the bundled demo).", show_default=False)
    ] = None,
    project: Annotated[
        Path | None, typer.Option("--project", help="Project file with parameters and manual alignment overrides.")
    ] = None,
    screenshot: Annotated[
        Path | None,
        typer.Option("--screenshot", help="Render off-screen to this PNG instead of opening the window."),
    ] = None,
    layers: Annotated[
        str | None,
        typer.Option(
            help="Layers to show, comma-separated: blastholes, contours, edge-map, gvf, snake, wavefront, trajectories, predicted, surfaces."
        ),
    ] = None,
    camera: Annotated[str | None, typer.Option(help="iso, top, front, side, or a view direction x,y,z.")] = None,
    geozone: Annotated[str | None, typer.Option("--geozone", help="Geozone to select.")] = None,
    bench: Annotated[int | None, typer.Option(help="Bench index to select (0 = top).")] = None,
    exaggeration: Annotated[float | None, typer.Option(help="Vertical exaggeration.")] = None,
    no_cache: Annotated[
        bool, typer.Option("--no-cache", help="Compute every stage afresh instead of reusing earlier runs' results.")
    ] = False,
) -> None:
    """Open the 3D viewer (or render a screenshot with no display)."""
    if input is not None and not Path(input).exists():
        raise BGMInputError(f"input file {str(input)!r} does not exist")
    code = view_command(
        input,
        project,
        screenshot,
        layers,
        camera,
        geozone=geozone,
        bench=bench,
        vertical_exaggeration=exaggeration,
        cache=not no_cache,
    )
    if screenshot:
        typer.echo(f"wrote {screenshot}", err=True)
    raise typer.Exit(code or 0)


def view_command(
    input: str | Path | None = None,
    project: str | Path | None = None,
    screenshot: str | Path | None = None,
    layers: str | list[str] | None = None,
    camera: str | None = None,
    *,
    geozone: str | None = None,
    bench: int | None = None,
    vertical_exaggeration: float | None = None,
    cache: bool = True,
) -> int:
    """Render ``screenshot`` off-screen (no Qt, no display) and return 0, or open the window and return its exit code.

    Errors in the input or project are :class:`core.errors.BGMInputError`, for the CLI to report.
    """
    try:
        from .model import project_input

        if screenshot:
            from .screenshot import render_screenshot
        else:
            from .app import run_viewer
    except ImportError as exc:
        raise BGMInputError(QT_MISSING.format(exc)) from None
    if input is None and project is not None:
        input = project_input(project)
    if screenshot:
        render_screenshot(
            input,
            screenshot,
            layers=layers,
            camera=camera or "iso",
            project=project,
            geozone=geozone,
            bench=bench,
            vertical_exaggeration=vertical_exaggeration,
            cache=cache,
        )
        return 0
    return run_viewer(input, project, cache=cache)
