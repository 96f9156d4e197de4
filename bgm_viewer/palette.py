"""Fixed colours: a qualitative palette for geozones and one colour per layer kind.

Colours are RGB tuples of ints 0-255. Geozones take the palette in sorted
label order, so the same project always looks the same. The layer colours are
chosen away from the geozone palette so tests (and people) can tell an arrow
from a hole.
"""

from __future__ import annotations

from collections.abc import Iterable

#: Tableau-10-like qualitative palette (colour-blind friendlier order).
GEOZONE_PALETTE: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180),  # blue
    (255, 127, 14),  # orange
    (44, 160, 44),  # green
    (214, 39, 40),  # red
    (148, 103, 189),  # purple
    (140, 86, 75),  # brown
    (227, 119, 194),  # pink
    (127, 127, 127),  # grey
    (188, 189, 34),  # olive
    (23, 190, 207),  # teal
)

BACKGROUND = (24, 26, 32)
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
