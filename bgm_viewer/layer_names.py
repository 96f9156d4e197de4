"""The standard scene's layer names, and the spellings ``--layers`` and the layer panel accept.

Plain Python (no PyVista, no Qt): ``bgm view --help`` lists these names
without importing a renderer, and the same list validates ``--layers``.
"""

from __future__ import annotations

#: Every layer of the standard scene, as shown in the layer panel.
LAYER_NAMES = (
    "blastholes",
    "contours",
    "edge map",
    "GVF",
    "snake",
    "wavefront",
    "trajectories",
    "predicted contours",
    "surfaces",
    "selected components",
    "uncertainty",
    "suggested holes",
)
#: Shown when nothing else is asked for.
DEFAULT_VISIBLE = ("blastholes", "contours", "snake", "trajectories", "surfaces", "selected components")


def _alias(name: str) -> str:
    key = name.strip().lower().replace("_", " ").replace("-", " ")
    aliases = {
        "holes": "blastholes",
        "edges": "edge map",
        "edgemap": "edge map",
        "gvf": "GVF",
        "arrows": "GVF",
        "front": "wavefront",
        "fronts": "wavefront",
        "tracks": "trajectories",
        "predicted": "predicted contours",
        "prediction": "predicted contours",
        "surface": "surfaces",
        "band": "uncertainty",
        "suggestions": "suggested holes",
        "suggested": "suggested holes",
        "selection": "selected components",
        "selected": "selected components",
    }
    key = aliases.get(key, key)
    for n in LAYER_NAMES:
        if n.lower() == key.lower():
            return n
    raise KeyError(f"unknown layer {name!r}; layers are: {', '.join(LAYER_NAMES)}")


def parse_layers(layers) -> list[str]:
    """``"blastholes,contours"`` or a list of names (aliases allowed) to canonical layer names."""
    if layers is None:
        return list(DEFAULT_VISIBLE)
    if isinstance(layers, str):
        layers = [p for p in layers.split(",") if p.strip()]
    out = []
    for part in layers:
        for p in str(part).split(","):
            if p.strip():
                n = _alias(p)
                if n not in out:
                    out.append(n)
    return out


#: Picture formats ``--screenshot`` and File > Export screenshot write: those of ``pyvista.Plotter.screenshot``
#: (its ``SUPPORTED_FORMATS``), named here so a wrong name is refused before PyVista is imported or the table read.
SCREENSHOT_FORMATS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
