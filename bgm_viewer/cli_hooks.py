"""What ``bgm view`` calls (the lead wires it into ``core.cli``; core never imports this).

``view_command(input, project, screenshot, layers, camera)``:

* with ``screenshot``: render the scene off-screen to that PNG (no Qt, no display
  needed) and return 0;
* otherwise: open the Qt window (``run_viewer``) and return its exit code.

Every option is checked before anything is loaded or drawn: an unknown layer
or camera, a geozone or bench that is not in the input, a vertical
exaggeration that is not a positive number, all raise
:class:`core.errors.BGMInputError` naming the option, as do errors in the
input or project; the CLI reports them in one line.
"""

from __future__ import annotations

import math
from pathlib import Path

from core.errors import BGMInputError, quoted

#: Largest vertical exaggeration a picture can use.
MAX_EXAGGERATION = 100.0
#: A camera direction closer than this (degrees) to vertical has no "up" to draw: use ``top``.
MIN_CAMERA_TILT_DEG = 1.0


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
    check_view_options(layers, camera, vertical_exaggeration)
    if input is None and project is not None:
        input = _project_input(project)
    holes = None
    if screenshot or geozone is not None or bench is not None or project is not None:
        holes = _checked_holes(input, project, geozone, bench)
    if screenshot:
        from .screenshot import render_screenshot

        render_screenshot(
            holes,
            screenshot,
            layers=layers,
            camera=camera or "iso",
            project=project,
            geozone=geozone if geozone is None else holes.check_geozones([geozone])[0],
            bench=bench,
            vertical_exaggeration=vertical_exaggeration,
        )
        return 0
    from .app import run_viewer

    return run_viewer(input, project)


def check_view_options(layers=None, camera: str | None = None, vertical_exaggeration: float | None = None) -> None:
    """Refuse layers, cameras and exaggerations that cannot make a picture (one sentence each)."""
    from .builders import LAYER_NAMES, parse_layers
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


def _checked_holes(input, project, geozone: str | None, bench: int | None):
    """The input's blastholes, with the selection and the project checked against them."""
    from core.io.project import check_project, load_project

    from .model import load_holes

    holes = load_holes(input)
    if geozone is not None:
        holes.check_geozones([geozone])
    if bench is not None and not 0 <= bench < max(holes.n_benches - 1, 1):
        raise BGMInputError(
            f"--bench {bench} is out of range: bench pairs of {holes.source or 'the input'} are numbered 0 "
            f"(top) to {max(holes.n_benches - 2, 0)}"
        )
    if project is not None:
        check_project(load_project(project), holes, command="bgm view", uses_parameters=True)
    return holes


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
