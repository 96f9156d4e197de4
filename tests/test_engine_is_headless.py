"""The engine never imports Qt or a renderer: only the viewer does."""

import subprocess
import sys

CORE_MODULES = [
    "core.blastholes", "core.synthetic", "core.extraction", "core.correspondence", "core.morph",
    "core.trajectories", "core.backtracking", "core.prediction", "core.surfaces", "core.export",
    "core.evaluation", "core.pipeline", "core.build", "core.project", "core.cli",
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
