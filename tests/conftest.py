"""Shared fixtures: synthetic mines with known truth, and the real Kennecott data when present."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
import shapely

from core.io.blastholes import BGMWarning, blastholes_from_table
from core.synthetic.blobs import make_mine, sample_blastholes

ROOT = Path(__file__).resolve().parent.parent
DEMO_CSV = ROOT / "assets" / "demo_blastholes.csv"
KENNECOTT_CSV = Path(
    os.environ.get("BGM_KENNECOTT", ROOT.parent / "shared" / "data" / "kennecott-blastholes" / "blastholes_tagged.csv")
)

os.environ.setdefault("QT_API", "pyside6")
# Stage results are cached on disk (core.io.cache): the suite never reads or fills the user's
# cache, and each test gets a cache of its own (fixture below); commands started by a test inherit it.
os.environ["BGM_CACHE_DIR"] = tempfile.mkdtemp(prefix="bgm-test-cache-")
atexit.register(shutil.rmtree, os.environ["BGM_CACHE_DIR"], ignore_errors=True)
# Likewise the viewer's autosaves of never-saved projects (core.io.autosave) never go to the user's state folder.
os.environ["BGM_AUTOSAVE_DIR"] = tempfile.mkdtemp(prefix="bgm-test-autosave-")
atexit.register(shutil.rmtree, os.environ["BGM_AUTOSAVE_DIR"], ignore_errors=True)


@pytest.fixture(autouse=True)
def own_stage_cache(tmp_path_factory, monkeypatch) -> Path:
    """A fresh, empty stage cache for every test (see :mod:`core.io.cache`)."""
    path = tmp_path_factory.mktemp("bgm-cache")
    monkeypatch.setenv("BGM_CACHE_DIR", str(path))
    return path


@pytest.fixture(autouse=True)
def own_autosave_dir(tmp_path_factory, monkeypatch) -> Path:
    """A fresh, empty folder for every test's autosaves of never-saved projects (see :mod:`core.io.autosave`)."""
    path = tmp_path_factory.mktemp("bgm-autosave")
    monkeypatch.setenv("BGM_AUTOSAVE_DIR", str(path))
    return path


@pytest.fixture(scope="session")
def kennecott_csv() -> Path:
    if not KENNECOTT_CSV.exists():
        pytest.skip(f"real Kennecott data not found at {KENNECOTT_CSV}")
    return KENNECOTT_CSV


def synthetic(seed: int, **mine_kwargs):
    """A fresh synthetic mine, its blasthole table and the holes read into the engine."""
    mine = make_mine(seed=seed, origin=(650_000.0 + seed, 7_400_000.0 - seed), **mine_kwargs)
    table = sample_blastholes(mine, seed=seed + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = blastholes_from_table(table, source=f"synthetic seed {seed}")
    return mine, table, holes


def component_truth(mine, holes, contour):
    """True region of a contour's component inside the drilled area, in the engine's frame.

    The parts of the true section (clipped to the bench's drilled area) that
    hold at least one of the component's holes.
    """
    z = holes.bench_levels_m[contour.bench]
    footprint = mine.footprint_in(holes.frame, z)
    truth = mine.section_in(holes.frame, contour.geozone, z).intersection(footprint)
    xy = holes.xy[contour.holes]
    parts = [g for g in getattr(truth, "geoms", [truth]) if shapely.contains_xy(g, xy[:, 0], xy[:, 1]).any()]
    return shapely.union_all(parts) if parts else shapely.Polygon(), footprint


def iou(a, b) -> float:
    union = a.union(b).area
    return float(a.intersection(b).area / union) if union > 0 else float("nan")


@pytest.fixture(scope="session")
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def hex_grid(nx: int, ny: int, spacing: float = 6.0) -> np.ndarray:
    """A staggered pattern of ``ny`` rows of ``nx`` holes (metres, origin at the first hole)."""
    rows = np.arange(ny) * spacing * np.sqrt(3) / 2
    pts = [(i * spacing + (j % 2) * spacing / 2, y) for j, y in enumerate(rows) for i in range(nx)]
    return np.array(pts, dtype=float)


CONSTRUCTED_ORIGIN = np.array([650_000.0, 7_400_000.0])


def constructed_bench(xy: np.ndarray, labels: np.ndarray):
    """Holes of one labelled bench read into the engine (mine-grid origin, two benches alike)."""
    import pandas as pd

    table = pd.DataFrame(
        {"x": xy[:, 0] + CONSTRUCTED_ORIGIN[0], "y": xy[:, 1] + CONSTRUCTED_ORIGIN[1], "geozone": labels}
    )
    return blastholes_from_table(pd.concat([table.assign(z=500.0), table.assign(z=490.0)]), source="constructed")


def constructed_offset(holes) -> np.ndarray:
    """What to add to the engine's local metres to get a constructed bench's own (pre-offset) coordinates."""
    return holes.frame.to_input(np.zeros((1, 2)))[0] - CONSTRUCTED_ORIGIN


def straight_contacts(seed: int, n: int, spacing: float = 6.0, contact_noise: float = 0.0) -> list[tuple]:
    """``n`` straight contacts at random offsets and headings through a staggered pattern (holes 0.08 of a
    spacing off it), each extracted: ``(holes, contour of "a", offsets)``, the contour's signed distances
    to the true line in spacings, away from the drilling's edge. With ``contact_noise``, that share of the
    holes within a spacing of the line carry the other side's label."""
    from core.extraction.contours import extract_bench

    rng = np.random.default_rng(seed)
    pattern = hex_grid(30, 34, spacing)
    out = []
    for _ in range(n):
        xy = pattern - [90.0, 88.0] + rng.normal(0, 0.08 * spacing, pattern.shape)
        heading = rng.uniform(0, np.pi)
        normal, at = np.array([np.cos(heading), np.sin(heading)]), rng.uniform(-spacing, spacing)
        labels = np.where(xy @ normal > at, "a", "b")
        flip = (np.abs(xy @ normal - at) < spacing) & (rng.random(len(xy)) < contact_noise)
        labels[flip] = np.where(labels[flip] == "a", "b", "a")
        holes = constructed_bench(xy, labels)
        contour = max(extract_bench(holes, 0, ["a"]), key=lambda c: c.polygon.area)
        ring = np.asarray(contour.polygon.exterior.coords) + constructed_offset(holes)
        inner = np.abs(ring).max(axis=1) < 50.0  # away from the drilling's edge
        out.append((holes, contour, (ring[inner] @ normal - at) / spacing))
    return out


def constructed_local(holes, geometry):
    """A geometry given in a constructed bench's own (pre-offset) coordinates, in the engine's frame."""
    o = constructed_offset(holes)
    return shapely.affinity.translate(geometry, -o[0], -o[1])


def narrowing_pit(n_benches: int = 5, spacing: float = 6.0, gone: bool = True):
    """A pit narrowing 22 m a bench (radius 120 m at the top, 10 m benches), holes on a staggered pattern.

    ``wall`` is a vertical cylinder (22 m radius) at its edge, x = 58-102 m: the top two benches drilled all of
    it, the third part of it, the lower two none. ``gone`` is a cylinder (18 m radius) in the middle on the top
    three benches only: the two below drilled its ground and found the host.
    """
    import pandas as pd

    from core.io.blastholes import blastholes_from_table

    frames = []
    for k in range(n_benches):
        radius = 120.0 - 22.0 * k
        rows = np.arange(-radius, radius, spacing * np.sqrt(3) / 2)
        xy = np.array(
            [(x + (i % 2) * spacing / 2, y) for i, y in enumerate(rows) for x in np.arange(-radius, radius, spacing)]
        )
        xy = xy[np.hypot(*xy.T) < radius]
        label = np.where(np.hypot(xy[:, 0] - 80.0, xy[:, 1]) < 22.0, "wall", "host")
        label = np.where((np.hypot(xy[:, 0] + 10.0, xy[:, 1] - 10.0) < 18.0) & (k <= 2) & gone, "gone", label)
        frames.append(
            pd.DataFrame({"x": xy[:, 0] + 650_000, "y": xy[:, 1] + 7_400_000, "z": 500.0 - 10 * k, "geozone": label})
        )
    return blastholes_from_table(pd.concat(frames, ignore_index=True), source="constructed")
