"""Render the viewer's scene to a PNG with no display and no Qt.

Plain ``pyvista.Plotter(off_screen=True)``; with no ``DISPLAY`` VTK is told to
use EGL (see :mod:`bgm_viewer._vtkenv`). Anti-aliasing is off (software
rendering). This module never imports Qt.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pyvista as pv

from core.errors import BGMInputError
from core.io.atomic import atomic_path

from . import _vtkenv  # noqa: F401  (before pyvista)
from .builders import build_scene, empty_layer_reasons, parse_layers
from .model import STEPS, ViewerModel
from .scene import Scene, SceneRenderer

DEFAULT_SIZE = (1280, 960)

#: The last step of the pipeline each layer needs (to skip work a screenshot does not show).
_NEEDS = {
    "blastholes": "contours",
    "contours": "contours",
    "edge map": "contours",
    "GVF": "contours",
    "snake": "contours",
    "wavefront": "morph",
    "trajectories": "morph",
    "predicted contours": "prediction",
    "surfaces": "surface",
    "selected components": "morph",
    # The next bench's band and suggested holes are drawn from the geozone's whole model, built with the prediction.
    "uncertainty": "prediction",
    "suggested holes": "prediction",
}


def no_aa_theme():
    """The global PyVista theme without multi-sampling or anti-aliasing (software rendering)."""
    import copy

    theme = copy.deepcopy(pv.global_theme)
    theme.multi_samples = 0
    theme.anti_aliasing = None
    return theme


def plotter_for(
    scene: Scene, *, window_size=DEFAULT_SIZE, camera: str | None = "iso", legend: bool = True, bearings: bool = True
):
    """An off-screen plotter with ``scene`` drawn (with axes grid and scale bar unless ``bearings`` is false)."""
    plotter = pv.Plotter(off_screen=True, window_size=[int(v) for v in window_size], theme=no_aa_theme())
    renderer = SceneRenderer(plotter, scene, legend=legend, bearings=bearings)
    renderer.set_camera(camera)
    return plotter, renderer


def scene_image(
    scene: Scene, *, window_size=DEFAULT_SIZE, camera: str | None = "iso", legend: bool = True
) -> np.ndarray:
    """``(rows, cols, 3)`` uint8 image of ``scene``."""
    plotter, _ = plotter_for(scene, window_size=window_size, camera=camera, legend=legend)
    try:
        return np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy()
    finally:
        plotter.close()


def shown_layers(model: ViewerModel, layers=None) -> list[str]:
    """The layers ``layers`` names, else those ``model`` shows (a project's saved layers, else the default ones)."""
    if layers is not None:
        return parse_layers(layers)
    return [name for name, shown in model.layer_visibility.items() if shown]


def model_scene(model: ViewerModel, layers=None, *, run: bool = True, progress=None) -> Scene:
    """Run what the requested layers need and build their scene.

    ``layers``: see :func:`shown_layers`. ``progress(message, fraction)`` is told each step of the run
    (:func:`bgm_viewer.model.compute`'s).
    """
    names = shown_layers(model, layers)
    if run and names:
        until = STEPS[max(STEPS.index(_NEEDS[n]) for n in names)]
        model.run(until=until, progress=progress)
    return build_scene(
        model.holes, model.result, model.selection, visible=names, vertical_exaggeration=model.vertical_exaggeration
    )


def render_screenshot(
    holes_or_path=None,
    out_png: str | Path = "bgm.png",
    layers=None,
    camera: str | None = None,
    *,
    project=None,
    geozone: str | None = None,
    bench: int | None = None,
    component: int | None = None,
    vertical_exaggeration: float | None = None,
    window_size=DEFAULT_SIZE,
    legend: bool = True,
    model: ViewerModel | None = None,
    cache: bool = True,
    progress=None,
) -> Path:
    """Render the viewer scene of ``holes_or_path`` to ``out_png``; returns the path.

    Parameters
    ----------
    holes_or_path : Blastholes, path, or None
        The input (``None``: the bundled demo). Ignored when ``model`` is given.
    out_png : path
    layers : list of str or "a,b,c", optional
        Layers to show (see :data:`bgm_viewer.builders.LAYER_NAMES`); default: those the project
        saved, else blastholes, contours, snake, trajectories, surfaces and the selected components.
    camera : "iso", "top", "front", "side" or "x,y,z", optional
        Default: the camera the project saved (:attr:`ViewerModel.camera`), else ``iso``.
    project : path, optional
        Project file whose parameters, selection, overrides and view (layers, camera, exaggeration)
        are applied; ``layers``, ``camera`` and the other options given win over its view.
    geozone, bench, component : selection of the stage layers (bench = upper bench of the pair).
    vertical_exaggeration : float, optional
    cache : bool
        Reuse (and keep) stage results on disk (see :mod:`core.io.cache`).
    progress : callable, optional
        ``progress(message, fraction)``, told each step of the pipeline run for the layers (the
        surfaces of every geozone take a minute on a large table; see :func:`model_scene`).
    """
    if model is None:
        model = ViewerModel(holes_or_path, cache=cache)
        if project:
            model.load_project(project)
        if geozone is not None or bench is not None or component is not None:
            model.select(geozone, bench, component)
        if vertical_exaggeration:
            model.vertical_exaggeration = float(vertical_exaggeration)
        scene = model_scene(model, layers, progress=progress)
    else:
        scene = build_scene(
            model.holes,
            model.result,
            model.selection,
            visible=shown_layers(model, layers),
            vertical_exaggeration=vertical_exaggeration or model.vertical_exaggeration,
        )
    if not any(layer.visible for layer in scene.layers):
        raise BGMInputError("the picture would be blank: the project shows no layer; name the layers with --layers")
    reasons = empty_layer_reasons(scene, model.holes, model.result, model.selection)
    if all(not layer.visible or layer.name in reasons for layer in scene.layers):
        why = "; ".join(f"{name}: {text}" for name, text in reasons.items())
        raise BGMInputError(f"the picture would be blank: the chosen layers hold nothing for this selection ({why})")
    for name, text in reasons.items():
        print(f"bgm: note: layer {name!r} is empty: {text}", file=sys.stderr)
    out_png = Path(out_png)
    plotter, renderer = plotter_for(scene, window_size=window_size, camera=camera, legend=legend)
    try:
        if camera is None and model.camera is not None:
            renderer.set_camera_state(model.camera)  # the view the geologist saved, not the default one
        # PyVista picks the format by a lower-case extension only: picture.PNG is written through picture.png's.
        with atomic_path(out_png, suffix=out_png.suffix.lower()) as tmp:
            image = np.asarray(plotter.screenshot(str(tmp), return_img=True))
            if image.size == 0 or np.ptp(image[..., :3]) == 0:  # a render failure leaves one colour
                raise BGMInputError(f"the picture came out blank (one colour); {out_png} was not written")
    finally:
        plotter.close()
    return out_png
