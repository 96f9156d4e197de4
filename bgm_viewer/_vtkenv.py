"""Pick a VTK render window that works before pyvista/vtk is imported.

With no ``DISPLAY`` (a server, CI) VTK first tries X, warns, and then falls
back to EGL; telling it to use ``vtkEGLRenderWindow`` straight away skips the
failed attempt. OSMesa is not installed on these machines, EGL is (through
the GPU-less Mesa ``llvmpipe`` driver). A value the user already set wins.

Import this module before anything that imports :mod:`pyvista` or :mod:`vtk`
(every module of :mod:`bgm_viewer` that renders does).
"""

from __future__ import annotations

import os
import sys


def configure_offscreen() -> str | None:
    """Set ``VTK_DEFAULT_OPENGL_WINDOW`` for head-less rendering; return what is in force."""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY") and sys.platform.startswith("linux"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    return os.environ.get("VTK_DEFAULT_OPENGL_WINDOW")


configure_offscreen()
