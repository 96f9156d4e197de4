"""Regenerate the representative screenshots (no Qt, no display needed).

    python -m bgm_viewer.gallery [OUT_DIR]     # default assets/screenshots

Writes demo_overview.png, gvf_snake.png, wavefront_trajectories.png and
surfaces.png (every geozone's surface) of the bundled demo (geozone g1, top
bench pair), and kennecott_overview.png (holes, contours and every geozone's
surface, in feet) when the Kennecott table is found (``BGM_KENNECOTT`` or
``../shared/data`` beside the repository).
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

SHOTS = (
    ("demo_overview.png", "blastholes,contours", "iso"),
    ("gvf_snake.png", "edge map,GVF,snake", "top"),
    ("wavefront_trajectories.png", "wavefront,trajectories,contours,selected components", "iso"),
    ("surfaces.png", "surfaces,contours", "iso"),
)
KENNECOTT = Path(
    os.environ.get(
        "BGM_KENNECOTT",
        Path(__file__).resolve().parents[2] / "shared" / "data" / "kennecott-blastholes" / "blastholes_tagged.csv",
    )
)


def make_gallery(out_dir: str | Path = "assets/screenshots", geozone: str = "g1") -> list[Path]:
    from .model import ViewerModel
    from .screenshot import render_screenshot

    model = ViewerModel(None)
    model.select(geozone, 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run()
    out = []
    for name, layers, camera in SHOTS:
        out.append(render_screenshot(out_png=Path(out_dir) / name, layers=layers, camera=camera, model=model))
    if KENNECOTT.exists():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = ViewerModel(str(KENNECOTT))
            model.run()
        shot = Path(out_dir) / "kennecott_overview.png"
        out.append(render_screenshot(out_png=shot, layers="blastholes,contours,surfaces", model=model))
    return out


if __name__ == "__main__":
    for p in make_gallery(sys.argv[1] if len(sys.argv) > 1 else "assets/screenshots"):
        print(p)
