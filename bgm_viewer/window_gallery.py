"""Pictures of the whole viewer window, docks included, for the README (needs a display).

    xvfb-run -a -s "-screen 0 1920x1080x24" python -m bgm_viewer.window_gallery [OUT_DIR]

Writes window_demo.png (the bundled demo: holes, contours, trajectories and
every geozone's surface; the host rock's holes unticked) and, when the Kennecott table is found (as for
:mod:`bgm_viewer.gallery`), window_kennecott.png (holes, contours and every
geozone's surface, in feet). Each picture is what a geologist sees after
opening the file with ``bgm view``: the same window, pipeline and defaults.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

from .gallery import KENNECOTT

#: (file name, input, layers shown besides the defaults)
WINDOWS = (
    ("window_demo.png", None, ("blastholes", "contours", "trajectories", "surfaces")),
    ("window_kennecott.png", KENNECOTT, ("blastholes", "contours", "surfaces")),
)
WINDOW_SIZE = (1600, 1000)


def window_picture(source, layers, out_png: Path, timeout_s: float = 900.0) -> Path:
    """Open the window on ``source``, wait for the whole pipeline, show ``layers`` and save the window.

    ``source``: what :class:`~bgm_viewer.model.ViewerModel` opens (a path, blastholes, or
    ``None`` for the demo).
    """
    from qtpy import QtWidgets

    from core.io.atomic import atomic_path

    from .app import MainWindow
    from .builders import LAYER_NAMES
    from .model import ViewerModel

    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication([])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ViewerModel(str(source) if isinstance(source, str | Path) else source)
        # no one answers a restore question here: it blocked the gallery for good when the table had an autosave
        win = MainWindow(model, debounce_ms=0, restore=False)
        win.resize(*WINDOW_SIZE)
        win.show()
        if not win.wait_idle(timeout_s):
            raise RuntimeError(f"the pipeline on {source or 'the demo'} did not finish in {timeout_s:.0f} s")
    for name in LAYER_NAMES:
        win.set_layer_visible(name, name in layers)
    if win.model.surface_geozones is not None:  # the host rock's holes would hide the bodies' surfaces
        win.legend.set_shown(win.model.surface_geozones)
        win.wait_idle(timeout_s)
    win.fit_view()
    _settle(app)
    picture = _window_with_view(win)
    with atomic_path(out_png) as tmp:
        if not picture.save(str(tmp), "PNG"):
            raise RuntimeError(f"could not write {out_png}")
    win.model.dirty = False  # nothing to save: no prompt on close
    win.close()
    return out_png


def _window_with_view(win):
    """The window's widgets (``QWidget.grab``) with the 3D view's own rendering painted in.

    A widget grab leaves the OpenGL view black, and grabbing the screen
    takes whatever window lies on top; VTK's render of the view is exact.
    """
    import numpy as np
    from qtpy import QtCore, QtGui

    picture = win.grab()
    view = win.plotter.interactor
    rgb = np.ascontiguousarray(np.asarray(win.plotter.screenshot(None, return_img=True))[..., :3])
    image = QtGui.QImage(rgb.data, rgb.shape[1], rgb.shape[0], 3 * rgb.shape[1], QtGui.QImage.Format.Format_RGB888)
    painter = QtGui.QPainter(picture)
    painter.drawImage(QtCore.QRect(view.mapTo(win, QtCore.QPoint(0, 0)), view.size()), image)
    painter.end()
    return picture


def _settle(app, seconds: float = 1.0) -> None:
    """Let Qt lay out, paint and flush for ``seconds``."""
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        app.processEvents()
        time.sleep(0.02)


def make_window_gallery(out_dir: str | Path = "assets/screenshots") -> list[Path]:
    out = []
    for name, source, layers in WINDOWS:
        if source is None or Path(source).exists():
            out.append(window_picture(source, layers, Path(out_dir) / name))
    return out


if __name__ == "__main__":
    for p in make_window_gallery(sys.argv[1] if len(sys.argv) > 1 else "assets/screenshots"):
        print(p)
    sys.stdout.flush()
