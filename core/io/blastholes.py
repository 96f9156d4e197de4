"""Reading labelled blasthole tables: columns, benches, units and a local frame.

The paper's input (section 1.2) is a set of blastholes per horizontal
cross-section (bench), each with x, y and a geozone label. This module turns a
CSV or Parquet table into :class:`Blastholes`:

* columns are found by name, case-insensitively (or named explicitly);
* benches are found by clustering elevations, and the bench height detected;
* lengths are converted to metres in a local frame centred on the data, so
  mine-grid coordinates (x ~ 650,000, y ~ 7,400,000) keep full precision and
  feet data works with the same metre-based defaults; everything reported goes
  back to the input's own coordinates and units through :class:`LocalFrame`.

Bad input raises :class:`core.errors.BGMInputError` with one clear sentence.
"""

from __future__ import annotations

import csv
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from core.errors import BGMInputError

COLUMN_ALIASES: dict[str, tuple[str, ...]] = {
    "x": ("x", "east", "easting"),
    "y": ("y", "north", "northing"),
    "z": ("z", "rl", "elevation", "elev", "mid_z"),
    "geozone": ("geozone", "domain", "lookup_domain", "label", "zone"),
}
FEET_TO_METRES = 0.3048
#: Holes farther than this fraction of the bench height from every bench
#: level are not assigned to a bench (they sit between benches).
OFF_BENCH_FRACTION = 0.3
#: Holes closer than this (metres) on one bench are the same hole.
COINCIDENT_M = 1e-3
#: Smallest bench height (input units, metres or feet) recognised when benches
#: are given at exact levels with no scatter (see :func:`detect_benches`).
MIN_BENCH_GAP = 2.0
#: Coordinates larger than this (input units) are rejected as not coordinates.
MAX_COORDINATE = 1e12


class BGMWarning(UserWarning):
    """Something in the input was repaired; the message says what."""


@dataclass(frozen=True)
class LocalFrame:
    """Mapping between the input's coordinates and the engine's local metres.

    ``local = (input - origin) * metres_per_unit`` for x and y and
    ``local_z = input_z * metres_per_unit``.
    """

    origin_x: float
    origin_y: float
    metres_per_unit: float = 1.0
    length_unit: str = "m"

    def to_local(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Input x, y to local ``(n, 2)`` metres."""
        return np.column_stack(
            [
                (np.asarray(x, float) - self.origin_x) * self.metres_per_unit,
                (np.asarray(y, float) - self.origin_y) * self.metres_per_unit,
            ]
        )

    def to_input(self, xy_m: np.ndarray) -> np.ndarray:
        """Local ``(..., 2)`` metres to input x, y."""
        xy_m = np.asarray(xy_m, float)
        out = np.empty_like(xy_m)
        out[..., 0] = xy_m[..., 0] / self.metres_per_unit + self.origin_x
        out[..., 1] = xy_m[..., 1] / self.metres_per_unit + self.origin_y
        return out

    def z_to_input(self, z_m):
        """Local elevation (metres) to input units."""
        return np.asarray(z_m, float) / self.metres_per_unit

    def z_to_local(self, z):
        """Input elevation to local metres."""
        return np.asarray(z, float) * self.metres_per_unit

    def length_to_local(self, length):
        """A length or vector in input units to metres."""
        return np.asarray(length, float) * self.metres_per_unit

    def length_to_input(self, length_m):
        """A length or vector in metres to input units (no origin shift)."""
        return np.asarray(length_m, float) / self.metres_per_unit


@dataclass
class Blastholes:
    """Labelled blastholes grouped into benches, in a local metric frame.

    Attributes
    ----------
    xy : (n, 2) float
        Hole positions, local metres.
    z : (n,) float
        Sample elevations, metres.
    geozone : (n,) object
        Geozone labels as strings (domain codes like ``"3310"`` stay as written).
    bench : (n,) int
        Index of each hole's bench in ``bench_levels_m`` (top bench is 0).
    bench_levels_m : (b,) float
        Bench elevations in metres, descending (top first).
    hole_spacing_m : float
        Median distance from a hole to its nearest neighbour on the same bench;
        every length default of the engine is a multiple of it.
    bench_height_m : float
        Vertical distance between successive benches (nan for a single bench).
    frame : LocalFrame
        How to report results in the input's own coordinates.
    hole_id : (n,) object or None
    source : str
        Where the table came from.
    notes : list of str
        Repairs made while reading (deduplication, off-bench holes...).
    """

    xy: np.ndarray
    z: np.ndarray
    geozone: np.ndarray
    bench: np.ndarray
    bench_levels_m: np.ndarray
    hole_spacing_m: float
    bench_height_m: float
    frame: LocalFrame
    hole_id: np.ndarray | None = None
    source: str = ""
    notes: list[str] = field(default_factory=list)
    _drilled: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def geozones(self) -> list[str]:
        """Geozone labels present, sorted."""
        return sorted(set(self.geozone.tolist()))

    @property
    def n_benches(self) -> int:
        return len(self.bench_levels_m)

    def bench_z_input(self, k: int) -> float:
        """Elevation of bench ``k`` in the input's units, rounded for display."""
        return round(float(self.frame.z_to_input(self.bench_levels_m[k])), 3)

    def on_bench(self, k: int, geozone: str | None = None) -> np.ndarray:
        """Indices of the holes on bench ``k`` (optionally of one geozone)."""
        sel = self.bench == k
        if geozone is not None:
            sel &= self.geozone == geozone
        return np.flatnonzero(sel)

    def check_geozones(self, requested: list[str] | None) -> list[str]:
        """Validate requested geozones; all of them when ``requested`` is empty."""
        present = self.geozones
        if not requested:
            return present
        missing = [g for g in requested if g not in present]
        if missing:
            raise BGMInputError(
                f"geozone {', '.join(map(repr, missing))} is not in {self.source or 'the input'}; "
                f"geozones present: {', '.join(present)}"
            )
        return list(requested)

    def drilled_area(self, k: int):
        """Area drilled on bench ``k`` (see :func:`drilled_area`), computed once per bench."""
        if k not in self._drilled:
            self._drilled[k] = drilled_area(self.xy[self.bench == k], self.hole_spacing_m)
        return self._drilled[k]

    def subset(self, keep: np.ndarray) -> Blastholes:
        """The same table restricted to the holes ``keep`` (bool mask or indices).

        Bench levels are kept as they are so bench indices stay comparable.
        """
        return Blastholes(
            xy=self.xy[keep],
            z=self.z[keep],
            geozone=self.geozone[keep],
            bench=self.bench[keep],
            bench_levels_m=self.bench_levels_m,
            hole_spacing_m=self.hole_spacing_m,
            bench_height_m=self.bench_height_m,
            frame=self.frame,
            hole_id=None if self.hole_id is None else self.hole_id[keep],
            source=self.source,
            notes=list(self.notes),
        )


# ---------------------------------------------------------------------------
# Reading tables


def read_table(path: str | Path) -> pd.DataFrame:
    """Read a CSV (any common delimiter) or Parquet file into a DataFrame of strings/numbers."""
    path = Path(path)
    if not path.exists():
        raise BGMInputError(f"input file {str(path)!r} does not exist")
    if path.is_dir():
        raise BGMInputError(f"input {str(path)!r} is a directory, not a CSV or Parquet file")
    if path.stat().st_size == 0:
        raise BGMInputError(f"input file {str(path)!r} is empty")
    suffix = path.suffix.lower()
    try:
        if suffix in (".parquet", ".pq"):
            return pd.read_parquet(path)
        with open(path, encoding="utf-8-sig", errors="strict") as fh:
            head = fh.read(64 * 1024)
        if "\x00" in head:
            raise BGMInputError(
                f"cannot read {str(path)!r}: it looks binary; BGM reads CSV and Parquet (.parquet) tables"
            )
        try:
            sep = csv.Sniffer().sniff(head.splitlines()[0] if head else "", delimiters=",;\t|").delimiter
        except csv.Error:
            sep = ","
        return pd.read_csv(path, sep=sep, dtype=str, keep_default_na=False, encoding="utf-8-sig")
    except BGMInputError:
        raise
    except UnicodeDecodeError:
        raise BGMInputError(
            f"cannot read {str(path)!r}: it is not UTF-8 text; BGM reads CSV and Parquet tables"
        ) from None
    except Exception as exc:  # pandas/pyarrow raise many types for unreadable files
        kind = "Parquet" if suffix in (".parquet", ".pq") else "CSV"
        raise BGMInputError(f"cannot read {str(path)!r} as {kind}: {exc}") from None


def find_column(columns: list[str], role: str, explicit: str | None = None) -> str:
    """The column playing ``role`` (x, y, z or geozone), found by name case-insensitively."""
    if explicit:
        matches = [c for c in columns if c == explicit] or [c for c in columns if str(c).lower() == explicit.lower()]
        if not matches:
            raise BGMInputError(
                f"column {explicit!r} given for {role} is not in the table; columns are: {', '.join(map(str, columns))}"
            )
        return matches[0]
    aliases = COLUMN_ALIASES[role]
    matches = [c for c in columns if str(c).strip().lower() in aliases]
    if not matches:
        raise BGMInputError(
            f"no {role} column: looked for {', '.join(aliases)} (any case); columns are: "
            f"{', '.join(map(str, columns))}; name it with --{role} COLUMN"
        )
    if len(matches) > 1:
        raise BGMInputError(
            f"ambiguous {role} column: {', '.join(map(repr, matches))} could all be {role}; "
            f"choose one with --{role} COLUMN"
        )
    return matches[0]


def _label_strings(values: pd.Series) -> np.ndarray:
    """Geozone labels as strings; integral floats from Parquet lose their '.0'."""
    if pd.api.types.is_float_dtype(values):
        v = values.to_numpy()
        ok = np.isfinite(v)
        if ok.all() and np.all(v == np.round(v)):
            return np.array([str(int(a)) for a in v], dtype=object)
    return np.array([("" if pd.isna(a) else str(a).strip()) for a in values], dtype=object)


def _rows(idx: np.ndarray, limit: int = 10) -> str:
    """Data row numbers as a file shows them (header is line 1, first row is 2)."""
    shown = ", ".join(str(int(i) + 2) for i in idx[:limit])
    more = f" and {len(idx) - limit} more" if len(idx) > limit else ""
    return f"{shown}{more}"


def read_blastholes(
    path: str | Path,
    *,
    x: str | None = None,
    y: str | None = None,
    z: str | None = None,
    geozone: str | None = None,
    bench_height: float | None = None,
    length_unit: str | None = None,
) -> Blastholes:
    """Read a labelled blasthole table and group it into benches.

    Parameters
    ----------
    path : str or Path
        CSV (comma, semicolon, tab or pipe separated) or Parquet file.
    x, y, z, geozone : str, optional
        Column names; by default found among :data:`COLUMN_ALIASES`.
    bench_height : float, optional
        Bench height in the input's units; detected from z when omitted.
    length_unit : {"m", "ft"}, optional
        Units of the input's coordinates; guessed from the bench height when
        omitted (benches of 25 units or more are taken to be feet: metric
        benches are 5-20 m, imperial ones 30-60 ft).

    Returns
    -------
    Blastholes
    """
    table = read_table(path)
    return blastholes_from_table(
        table,
        x=x,
        y=y,
        z=z,
        geozone=geozone,
        bench_height=bench_height,
        length_unit=length_unit,
        source=str(path),
    )


def blastholes_from_table(
    table: pd.DataFrame,
    *,
    x: str | None = None,
    y: str | None = None,
    z: str | None = None,
    geozone: str | None = None,
    bench_height: float | None = None,
    length_unit: str | None = None,
    source: str = "",
) -> Blastholes:
    """:func:`read_blastholes` on a table already in memory."""
    if len(table) == 0:
        raise BGMInputError(f"{source or 'the input'} has a header but no rows")
    columns = [str(c) for c in table.columns]
    table = table.copy()
    table.columns = columns
    cols = {
        "x": find_column(columns, "x", x),
        "y": find_column(columns, "y", y),
        "z": find_column(columns, "z", z),
        "geozone": find_column(columns, "geozone", geozone),
    }
    used = list(cols.values())
    if len(set(used)) < 4:
        raise BGMInputError(f"one column is used for two roles: {cols}")

    coords = {}
    for role in ("x", "y", "z"):
        raw = table[cols[role]]
        if raw.dtype == object:
            raw = raw.astype(str).str.strip().str.replace(",", "", regex=False)
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise BGMInputError(
                f"column {cols[role]!r} ({role}) has {len(bad)} missing, non-numeric or infinite "
                f"value(s), on data line(s) {_rows(bad)}"
            )
        # Finite but absurd magnitudes (1e300) overflow distance computations
        # (kD-tree) deep in the engine; no mine grid comes near 1e12 units, and
        # past it float64 cannot hold sub-millimetre positions anyway.
        huge = np.flatnonzero(np.abs(values) > MAX_COORDINATE)
        if len(huge):
            raise BGMInputError(
                f"column {cols[role]!r} ({role}) has {len(huge)} value(s) beyond {MAX_COORDINATE:.0e} in "
                f"magnitude, too large to be coordinates, on data line(s) {_rows(huge)}"
            )
        coords[role] = values
    labels = _label_strings(table[cols["geozone"]])
    blank = np.flatnonzero(labels == "")
    if len(blank):
        raise BGMInputError(
            f"column {cols['geozone']!r} (geozone) is empty on {len(blank)} row(s): data line(s) {_rows(blank)}"
        )
    hole_col = next((c for c in columns if c.lower() in ("holeid", "hole_id", "hole", "id")), None)
    hole_id = table[hole_col].astype(str).to_numpy(dtype=object) if hole_col else None

    if len(labels) < 3:
        raise BGMInputError(f"{source or 'the input'} has only {len(labels)} hole(s); BGM needs at least 3")

    notes: list[str] = []
    zin = coords["z"]
    levels_in, bench, height_in, off = detect_benches(zin, bench_height)
    if off.any():
        msg = (
            f"{int(off.sum())} hole(s) lie more than {OFF_BENCH_FRACTION:.0%} of a bench height from "
            f"every bench level (data line(s) {_rows(np.flatnonzero(off))}) and were left out"
        )
        notes.append(msg)
        warnings.warn(msg, BGMWarning, stacklevel=2)

    unit = _guess_unit(height_in, length_unit)
    mpu = FEET_TO_METRES if unit == "ft" else 1.0
    keep = ~off
    frame = LocalFrame(
        origin_x=float(np.round(np.median(coords["x"][keep]))),
        origin_y=float(np.round(np.median(coords["y"][keep]))),
        metres_per_unit=mpu,
        length_unit=unit,
    )
    xy = frame.to_local(coords["x"], coords["y"])
    holes = Blastholes(
        xy=xy[keep],
        z=frame.z_to_local(zin)[keep],
        geozone=labels[keep],
        bench=bench[keep],
        bench_levels_m=frame.z_to_local(levels_in),
        hole_spacing_m=np.nan,
        bench_height_m=float(height_in * mpu) if np.isfinite(height_in) else np.nan,
        frame=frame,
        hole_id=None if hole_id is None else hole_id[keep],
        source=source,
        notes=notes,
    )
    holes = _deduplicate(holes, np.flatnonzero(keep))
    holes.hole_spacing_m = median_hole_spacing(holes.xy, holes.bench)
    if not np.isfinite(holes.hole_spacing_m) or holes.hole_spacing_m <= 0:
        raise BGMInputError(
            f"cannot measure the hole spacing of {source or 'the input'}: no bench has two distinct holes"
        )
    return holes


def _guess_unit(bench_height: float, length_unit: str | None) -> str:
    if length_unit:
        unit = length_unit.strip().lower()
        aliases = {
            "m": "m",
            "metre": "m",
            "metres": "m",
            "meter": "m",
            "meters": "m",
            "ft": "ft",
            "feet": "ft",
            "foot": "ft",
        }
        if unit not in aliases:
            raise BGMInputError(f"unknown length unit {length_unit!r}: use m or ft")
        return aliases[unit]
    if np.isfinite(bench_height) and bench_height >= 25.0:
        return "ft"
    return "m"


def detect_benches(
    z: np.ndarray, bench_height: float | None = None
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Group sample elevations into benches.

    Holes of one bench scatter by a few units around its level; a few sit far
    off any level. Elevations are split into clusters at gaps wider than a
    third of the widest gap; clusters holding at least 1% of the holes (or 10
    holes) define bench levels (their medians), the bench height is the median
    spacing of successive levels, and a regular ladder of levels is fitted to
    them so benches with few holes still get a level on the ladder.

    Parameters
    ----------
    z : (n,) float
        Elevations, input units.
    bench_height : float, optional
        Known bench height (input units); skips its detection.

    Returns
    -------
    levels : (b,) float
        Bench levels, descending.
    bench : (n,) int
        Bench index of each hole (-1 for off-bench holes).
    height : float
        Bench height (nan when there is a single bench).
    off : (n,) bool
        Holes farther than ``OFF_BENCH_FRACTION * height`` from every level.
    """
    z = np.asarray(z, float)
    if bench_height is not None and not (np.isfinite(bench_height) and bench_height > 0):
        raise BGMInputError(f"bench height must be a positive number, got {bench_height}")
    zs = np.sort(z)
    gaps = np.diff(zs)
    if len(gaps) == 0 or gaps.max() == 0:
        return np.array([float(np.median(z))]), np.zeros(len(z), int), np.nan, np.zeros(len(z), bool)

    min_count = max(10, int(0.01 * len(z)))
    if bench_height is None:
        # A gap between benches is wide next to the widest gap and far wider than
        # the typical step between sorted elevations (which rounding can make
        # all equal on a single bench).
        typical = np.median(gaps[gaps > 0])
        cut = (gaps > gaps.max() / 3.0) & (gaps > 20.0 * typical)
        # Benches given at exact levels (z is the bench RL, no scatter): the only
        # positive gaps are then the bench gaps themselves, so ``typical`` is a
        # bench gap and nothing was cut (all benches merged into one and their
        # holes into "duplicates"). A wide gap of at least MIN_BENCH_GAP units is
        # a bench break too; rounding steps are smaller, and splits inside a
        # scattered bench are merged back just below.
        cut |= (gaps > gaps.max() / 3.0) & (gaps >= MIN_BENCH_GAP)
        labels = _merge_scatter_splits(zs, np.concatenate([[0], np.cumsum(cut)]))
        centres = []
        for k in range(labels[-1] + 1):
            members = zs[labels == k]
            if len(members) >= min(min_count, max(3, len(z) // 4)):
                centres.append(float(np.median(members)))
        centres = np.array(sorted(centres))
        if len(centres) < 2:
            level = float(np.median(z))
            spread = float(np.percentile(np.abs(z - level), 95))
            return np.array([level]), np.zeros(len(z), int), np.nan, np.abs(z - level) > max(spread, 1e-9) * 3
        height = float(np.median(np.diff(centres)))
        anchor = centres
    else:
        height = float(bench_height)
        # Anchor the ladder on the densest elevation: the mode of z in bins of height/10.
        bins = np.arange(zs[0], zs[-1] + height / 10, height / 10)
        if len(bins) < 2:
            bins = np.array([zs[0] - 0.5, zs[-1] + 0.5])
        hist, edges = np.histogram(z, bins=bins)
        k = int(np.argmax(hist))
        anchor = np.array([float(np.median(z[(z >= edges[k]) & (z <= edges[k + 1])]))])

    # Fit a regular ladder z0 + k * height through the anchors; levels are shown
    # to 0.1 unit, finer than any bench scatter.
    k_anchor = np.round((anchor - anchor[0]) / height)
    if bench_height is None and len(np.unique(k_anchor)) >= 2:
        height = float(np.polyfit(k_anchor, anchor, 1)[0])
        height = round(height, 1) if height >= 1 else height
    z0 = float(np.median(anchor - k_anchor * height))
    z0 = round(z0, 1) if height >= 1 else z0
    k_hole = np.round((z - z0) / height)
    residual = z - (z0 + k_hole * height)
    off = np.abs(residual) > OFF_BENCH_FRACTION * height
    ks = np.unique(k_hole[~off])
    # Drop ladder rungs with too few holes to be a bench (isolated stray holes).
    counts = np.array([(k_hole[~off] == k).sum() for k in ks])
    sparse = ks[counts < 3]
    off |= np.isin(k_hole, sparse)
    ks = np.unique(k_hole[~off])[::-1]
    levels = z0 + ks * height
    index = {k: i for i, k in enumerate(ks)}
    bench = np.array([index.get(k, -1) for k in k_hole], dtype=int)
    bench[off] = -1
    if len(levels) < 2:
        height = np.nan
    return levels, bench, height, off


def _merge_scatter_splits(zs: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Merge neighbouring elevation clusters whose gap is small next to their own scatter.

    On a single bench the widest gap is itself scatter, so cutting at a third
    of it splits the bench; a real gap between benches is at least half as
    wide as the holes' spread (5th-95th percentile) on either side of it.
    """
    while labels[-1] > 0:
        groups = [zs[labels == k] for k in range(labels[-1] + 1)]
        spread = [np.percentile(g, 95) - np.percentile(g, 5) for g in groups]
        merged = False
        for k in range(len(groups) - 1):
            gap = groups[k + 1][0] - groups[k][-1]
            if gap < 0.5 * max(spread[k], spread[k + 1]):
                labels = np.where(labels > k, labels - 1, labels)
                merged = True
                break
        if not merged:
            break
    return labels


def _deduplicate(holes: Blastholes, rows: np.ndarray) -> Blastholes:
    """Merge holes at the same position on the same bench, warning about it."""
    key = np.column_stack([holes.bench, np.round(holes.xy / COINCIDENT_M).astype(np.int64)])
    _, first, inverse, counts = np.unique(key, axis=0, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    if len(first) == len(key):
        return holes
    dup_groups = np.flatnonzero(counts > 1)
    conflicting = [g for g in dup_groups if len(set(holes.geozone[inverse == g].tolist())) > 1]
    n_removed = len(key) - len(first)
    msg = f"{n_removed} duplicate hole(s) at the same position on the same bench were merged (first row kept)"
    if conflicting:
        g = conflicting[0]
        lines = rows[np.flatnonzero(inverse == g)]
        msg += (
            f"; {len(conflicting)} of those positions carry conflicting geozone labels "
            f"(e.g. data lines {_rows(lines, 4)}: {sorted(set(holes.geozone[inverse == g].tolist()))})"
        )
    warnings.warn(msg, BGMWarning, stacklevel=3)
    keep = np.sort(first)
    out = holes.subset(keep)
    out.notes.append(msg)
    return out


def drilled_area(xy: np.ndarray, spacing_m: float, radius_spacings: float = 0.75):
    """Area drilled by holes ``xy``: union of discs of ``radius_spacings`` spacings, closed over one spacing."""
    import shapely
    from shapely.geometry import MultiPoint

    from core.geometry.grid import as_multipolygon

    if len(xy) == 0:
        return shapely.MultiPolygon()
    discs = shapely.buffer(MultiPoint(np.asarray(xy, float)), radius_spacings * spacing_m, quad_segs=6)
    return as_multipolygon(discs.buffer(spacing_m, quad_segs=6).buffer(-spacing_m, quad_segs=6))


def median_hole_spacing(xy: np.ndarray, bench: np.ndarray) -> float:
    """Median nearest-neighbour distance between holes of the same bench (metres)."""
    distances = []
    for k in np.unique(bench):
        pts = xy[bench == k]
        if len(pts) < 2:
            continue
        d, _ = cKDTree(pts).query(pts, k=2)
        distances.append(d[:, 1][d[:, 1] > 0])
    if not distances:
        return float("nan")
    alld = np.concatenate(distances)
    return float(np.median(alld)) if len(alld) else float("nan")
