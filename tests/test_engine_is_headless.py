"""The engine never imports Qt or a renderer: only the viewer does."""

import subprocess
import sys

CORE_MODULES = [
    "core.io.blastholes",
    "core.synthetic.blobs",
    "core.synthetic.scenarios",
    "core.model.scoring",
    "core.extraction.contours",
    "core.correspondence.pair",
    "core.morph.levelset",
    "core.morph.trajectories",
    "core.morph.backtracking",
    "core.model.prediction",
    "core.model.surfaces",
    "core.io.export",
    "core.model.evaluation",
    "core.model.pipeline",
    "core.model.parameters",
    "core.model.session",
    "core.io.cache",
    "core.model.build",
    "core.io.project",
    "core.cli",
]


def test_core_imports_no_gui_or_renderer():
    code = (
        "import sys\n"
        + "".join(f"import {m}\n" for m in CORE_MODULES)
        + "bad = [m for m in sys.modules if m.split('.')[0] in ('PySide6', 'qtpy', 'pyvista', 'pyvistaqt', 'vtk', 'vtkmodules', 'bgm_viewer')]\n"
        + "print(','.join(sorted(set(b.split('.')[0] for b in bad))))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"core imported {out}"
