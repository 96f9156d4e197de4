"""Fixed colours: a qualitative palette for geozones and one colour per layer kind.

Colours are RGB tuples of ints 0-255. Geozones take the palette in sorted
label order, so a geozone has one colour in every layer, the legend and every
run on the same input. The layer colours are
chosen away from the geozone palette so tests (and people) can tell an arrow
from a hole.
"""

from __future__ import annotations

from collections.abc import Iterable

#: Glasbey categorical palette (colorcet's ``glasbey_bw_minc_20_minl_30``, fixed here so the
#: viewer does not depend on colorcet), without the colours too dark on the dark background
#: or too near a layer colour: 32 geozones get distinct colours before any repeats.
GEOZONE_HEX = (
    "#028800", "#06acc6", "#98ff00", "#ffa530", "#ff8fc8", "#b0a5ff", "#94ad84", "#9a6900",
    "#c86f66", "#9ee3ff", "#00c946", "#a977ad", "#b8bb02", "#009f7d", "#ff6200", "#56652b",
    "#963f1f", "#91318f", "#ff3465", "#a0e492", "#8d9bb2", "#829126", "#78c7bb", "#bc9258",
    "#e58fff", "#72b9ff", "#ad577d", "#ff4ab1", "#c25703", "#c244bd", "#007540", "#ba6ffe",
)  # fmt: skip
GEOZONE_PALETTE: tuple[tuple[int, int, int], ...] = tuple(
    (int(h[1:3], 16), int(h[3:5], 16), int(h[5:7], 16)) for h in GEOZONE_HEX
)

BACKGROUND = (24, 26, 32)
#: Axes grid, labels, scale bar and orientation widget.
BEARINGS = (205, 210, 220)
#: Colours of the layers that are not coloured by geozone.
LAYER_COLOURS: dict[str, tuple[int, int, int]] = {
    "gvf": (255, 255, 0),  # arrows: pure yellow, in no geozone colour
    "snake": (255, 255, 255),
    "snake_start": (110, 110, 110),
    "trajectories": (0, 255, 255),
    "backtracked": (255, 0, 255),
    "wavefront": (255, 220, 120),
    "predicted": (240, 240, 240),
    "edge_map": (200, 200, 200),
    "selected_source": (255, 255, 255),
    "selected_target": (255, 250, 170),
}


def geozone_colours(labels: Iterable[str]) -> dict[str, tuple[int, int, int]]:
    """``{label: rgb}`` for the sorted unique labels, cycling through the palette."""
    return {g: GEOZONE_PALETTE[i % len(GEOZONE_PALETTE)] for i, g in enumerate(sorted(set(map(str, labels))))}


def to_float(rgb: tuple[int, int, int]) -> tuple[float, float, float]:
    """RGB 0-255 to 0-1 floats (what VTK takes)."""
    return tuple(c / 255.0 for c in rgb)  # type: ignore[return-value]


def lighten(rgb: tuple[int, int, int], amount: float = 0.5) -> tuple[int, int, int]:
    """Mix ``rgb`` with white."""
    return tuple(int(round(c + (255 - c) * amount)) for c in rgb)  # type: ignore[return-value]
