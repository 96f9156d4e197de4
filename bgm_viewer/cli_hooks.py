"""What ``bgm view`` calls (the lead wires it into ``core.cli``; core never imports this).

``view_command(input, project, screenshot, layers, camera)``:

* with ``screenshot``: render the scene off-screen to that PNG (no Qt, no display
  needed) and return 0;
* otherwise: open the Qt window (``run_viewer``) and return its exit code.

Errors in the input or project are :class:`core.errors.BGMInputError` and are
left for the CLI to report.
"""

from __future__ import annotations

from pathlib import Path


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
) -> int:
    """Entry point of ``bgm view [INPUT] [--project P] [--screenshot out.png] [--layers a,b] [--camera iso]``."""
    if input is None and project is not None:
        input = _project_input(project)
    if screenshot:
        from .screenshot import render_screenshot

        render_screenshot(
            input,
            screenshot,
            layers=layers,
            camera=camera or "iso",
            project=project,
            geozone=geozone,
            bench=bench,
            vertical_exaggeration=vertical_exaggeration,
        )
        return 0
    from .app import run_viewer

    return run_viewer(input, project)


def _project_input(project) -> str | None:
    """The input named by a project file (relative to the project's folder)."""
    from core.io.project import load_project

    p = load_project(project).input_path
    if not p:
        return None
    path = Path(p)
    if not path.is_absolute():
        path = Path(project).resolve().parent / path
    return str(path)
