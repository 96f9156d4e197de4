"""Reading labelled blasthole tables: columns, benches, units and a local frame.

The paper's input (section 1.2) is a set of blastholes per horizontal
cross-section (bench), each with x, y and a geozone label. This module turns a
CSV or Parquet table into :class:`Blastholes`:

* columns are found by name, case-insensitively (or named explicitly), and
  only those columns are parsed (see :mod:`core.io.tables` for file formats);
* numbers may use decimal commas or thousands separators; geozone labels that
  spell one number two ways (``3310``, ``3310.0``) are merged, with a warning,
  and an integral number written with a zero fraction is its plain spelling
  (``3310.0`` is ``3310``, as a float column read from Parquet gives it);
  labels with leading zeros (``010``) are codes, never merged with ``10``;
* coordinates in degrees of latitude and longitude are refused;
* benches are found by clustering elevations, at the levels as measured
  (uneven bench heights are fine); z that does not form benches is refused;
  holes far above or below every bench (elevations missing as 0 or -9999, or
  mistyped) are left out, named in a warning, or refused when they are many;
* z is an elevation (positive up): benches that widen with depth as read, where an open pit
  narrows, are warned about, as depths read as elevations give them;
* lengths are converted to metres in a local frame centred on the data, so
  mine-grid coordinates (x ~ 650,000, y ~ 7,400,000) keep full precision and
  feet data works with the same metre-based defaults; everything reported goes
  back to the input's own coordinates and units through :class:`LocalFrame`.

Bad input raises :class:`core.errors.BGMInputError` with one clear sentence.
"""

from __future__ import annotations

import re
import unicodedata
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from core.errors import BGMInputError, BGMWarning, listing, quoted
from core.io.tables import data_lines

COLUMN_ALIASES: dict[str, tuple[str, ...]] = {
    "x": ("x", "east", "easting", "mid_x"),
    "y": ("y", "north", "northing", "mid_y"),
    "z": ("z", "rl", "elevation", "elev", "mid_z"),
    "geozone": ("geozone", "domain", "lookup_domain", "label", "zone"),
}
#: A length unit ending a column name (``Easting (m)``, ``RL [ft]``, ``NORTHING_M``): not part of the name's role.
UNIT_SUFFIX = re.compile(r"\s*(?:[(\[]\s*(?:m|ft|metres?|meters?|feet)\s*[)\]]|_(?:m|ft))$", re.IGNORECASE)
#: The command-line option naming each role's column (``--geozone`` selects geozones, not a column).
COLUMN_OPTIONS = {"x": "--x", "y": "--y", "z": "--z", "geozone": "--geozone-column"}
FEET_TO_METRES = 0.3048
#: Holes farther than this fraction of the bench height from every bench
#: level are not assigned to a bench (they sit between benches).
OFF_BENCH_FRACTION = 0.3
#: Holes closer than this (metres) on one bench are the same hole.
COINCIDENT_M = 1e-3
#: Smallest bench height (input units, metres or feet) recognised when benches
#: are given at exact levels with no scatter (see :func:`detect_benches`).
MIN_BENCH_GAP = 2.0
#: Blastholes closer than this (metres, the median across benches) are no drilling pattern: the unit is not feet.
MIN_HOLE_SPACING_M = 2.5
#: Blasthole spacings (metres, the median across benches) outside this range are a unit mistake (mm, cm, km...).
PLAUSIBLE_SPACING_M = (0.5, 50.0)
#: Metric benches are at most this high (input units); up to 25 units a bench is taken to be metres, unsure.
METRIC_BENCH_MAX = 20.0
#: Coordinates larger than this (input units) are rejected as not coordinates.
MAX_COORDINATE = 1e12
#: More holes than this share between bench levels: z does not form benches.
MAX_OFF_BENCH_SHARE = 0.25
#: A hole farther than this many hole spacings from every other hole of its bench is on no pattern (x, y missing
#: as 0, or mistyped); the most on Kennecott's and the demo's benches is 3.0.
FAR_HOLE_SPACINGS = 20.0
#: A group of holes at the top or bottom of the elevations, more than this many bench heights from every bench, is
#: no bench of the pit (elevations missing or mistyped): a pit does not leave ten benches unsampled between two of its own.
FAR_LEVEL_BENCHES = 10.0
#: Elevations that spell a missing value when a whole group of holes sits exactly on one of them (z exported as 0 or
#: -9999 where it was missing) ...
MISSING_ELEVATIONS = frozenset({0.0, -99.0, -999.0, -9999.0, -99999.0})
#: ... and lies more than this many bench heights from every bench (a real bench at RL 0 next to the others stays).
MISSING_ELEVATION_BENCHES = 3.0
#: ... or, beside a single bench (no bench height to measure by), more than this many of its hole spacings from it: a
#: bench is drilled on a pattern of about its height (1.8 hole spacings on the demo, 2.2 on Kennecott, 1.0-2.9 on the
#: synthetic drillings), so this is three benches of 3.3 spacings (Kennecott's floor is 11.9 spacings above 0).
MISSING_ELEVATION_SPACINGS = 10.0
#: A small group of holes at any elevation, beside one bench (or two) and more than this many of its hole spacings from
#: it, is no bench (mistyped: RL 150 or 15000 for 1500): ten benches (:data:`FAR_LEVEL_BENCHES`) of the same 3.3
#: spacings, the rule for groups beside several benches measured by the pattern (:data:`MISSING_ELEVATION_SPACINGS`).
FAR_GROUP_SPACINGS = FAR_LEVEL_BENCHES * MISSING_ELEVATION_SPACINGS / MISSING_ELEVATION_BENCHES
#: A single cluster of elevations thicker than this many hole spacings is not one bench.
MAX_BENCH_THICKNESS_SPACINGS = 5.0
#: A group of holes too few for a bench of their own, beside a single bench, is a sparsely drilled bench when
#: their hole spacing is within this factor of the bench's (its pattern; see ``_sparse_benches_beside_one``).
SPARSE_BENCH_SPACING_RATIO = 1.5
#: A given bench height may differ from the collars' own (median level gap) by this fraction of it.
BENCH_HEIGHT_TOLERANCE = 0.03
#: Elevations where holes are this many times sparser than at the median hole are between benches, when a few holes
#: there bridge every gap (:func:`_dense_levels`): benches 10 m apart whose holes scatter by 1.2-1.5 m (a standard
#: deviation) leave a few holes half-way between them, and were refused as elevations "spread continuously".
SPARSE_ELEVATION_FACTOR = 10.0
#: Elevations whose density's autocorrelation comes back to this share of its value at no lag repeat by bench
#: (:func:`_repeating_height`): 0.5-0.8 for benches 10 m apart scattered by 2-2.5 m; evenly spread ones 0.0-0.1.
REPEAT_CORRELATION = 0.3
#: Elevations the repeating height is refined on, at most (:func:`_repeating_height`).
REPEAT_SAMPLE = 50_000
#: More benches than this from an explicit bench height is a unit mistake.
MAX_BENCHES = 10_000
#: x and y both spanning less than this many units (and within +-180, +-90) are degrees.
MAX_DEGREES_SPREAD = 1.0
#: More than this share of the holes with a label of their own: the geozone column is an identifier.
MAX_OWN_LABEL_SHARE = 0.5
#: Fewer holes than this are too few to tell geozones from identifiers.
MIN_HOLES_FOR_ID_CHECK = 20
#: Geozone labels (any case) that spell a missing value in common exports (R, SQL, Excel, no-data codes).
MISSING_LABELS = frozenset({"na", "n/a", "#n/a", "nan", "null", "none", "-99", "-999", "-9999"})
#: Column names taken as the hole identifier, compared by :func:`is_hole_id_column` (any case, spaces,
#: underscores, hyphens and dots ignored): ``Hole ID``, ``HOLE_ID``, ``hole-id``, Datamine's ``BHID``.
HOLE_ID_NAMES = ("holeid", "hole_id", "hole", "id", "bhid", "holename", "holeno", "holenumber", "blastholeid")
#: What :func:`is_hole_id_column` leaves out of a name before comparing it.
_NAME_SEPARATORS = re.compile(r"[\s_.\-]+")
#: :data:`HOLE_ID_NAMES` as :func:`is_hole_id_column` compares them.
_HOLE_ID_KEYS = frozenset(_NAME_SEPARATORS.sub("", n) for n in HOLE_ID_NAMES)
#: A geozone label that spells a number (compared as numbers by :func:`merge_number_spellings`).
NUMBER_LABEL = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d{1,3})?")
#: A label whose integer part has leading zeros (``010``, ``-007.5``): a code, not a number.
LEADING_ZEROS = re.compile(r"[+-]?0\d")
#: An integer written with a zero fraction, as a float column is written to CSV (``3310.0``).
ZERO_FRACTION = re.compile(r"-?\d+\.0+")
#: A z column named like this (any case) holds depths, positive down: ``depth``, ``Depth_m``, ``from``, ``to (m)``.
DEPTH_NAME = re.compile(r"(?:.*depth.*|(?:from|to)(?:[_\s(].*)?)", re.IGNORECASE)
#: Benches with fewer holes than this share of the median bench's are left out of the pit's shape (see
#: :func:`widening_with_depth`): a bench only partly in the table, or being opened, says nothing of the pit's width
#: there (Kennecott's top bench: 20 holes, the others 1,900-2,850).
PIT_SHAPE_MIN_HOLES_SHARE = 0.25
#: Benches whose deepest third spans this many times the area of their top third widen with depth: an open pit
#: narrows, so z is very likely read upside down. Right way up, the synthetic families' 7 benches give 0.39-0.66
#: (0.81 for 3), the demo 0.51, Kennecott 0.74; upside down 1.52-2.58 (1.23 for 3), 1.98 and 1.36.
UPSIDE_DOWN_AREA_RATIO = 1.25
#: Fewer benches than this (of :data:`PIT_SHAPE_MIN_HOLES_SHARE`) tell too little of the pit's shape.
PIT_SHAPE_MIN_BENCHES = 4
#: Numbers with decimal commas, and with thousands separators.
DECIMAL_COMMA = r"[+-]?\d*,\d+(?:[eE][+-]?\d+)?"
THOUSANDS = r"[+-]?\d{1,3}(?:,\d{3})+(?:\.\d*)?(?:[eE][+-]?\d+)?"
#: Decimal commas with dots grouping thousands, as European spreadsheets write them (``7.400.517,77``).
DOTS_DECIMAL_COMMA = r"[+-]?\d{1,3}(?:\.\d{3})+,\d*(?:[eE][+-]?\d+)?"

__all__ = ["BGMWarning", "Blastholes", "LocalFrame", "blastholes_from_table", "detect_benches", "read_blastholes"]


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
        The table's pattern spacing (:func:`table_hole_spacing`: the middle
        bench's median distance from a hole to its third-nearest neighbour on
        the bench); every length default of the engine is a multiple of it.
    bench_height_m : float
        Vertical distance between successive benches (nan for a single bench).
    frame : LocalFrame
        How to report results in the input's own coordinates.
    hole_id : (n,) object or None
    source : str
        Where the table came from.
    notes : list of str
        Repairs made while reading (deduplication, off-bench holes...).
    unit_guess : str
        How the length unit was guessed when it was not given and is not
        metres, or metres are only assumed (a single bench, or benches higher
        than metric ones and lower than imperial ones); said in the command
        line's summary of the input and the viewer's title; else empty.
    read_options : dict
        The options :func:`read_blastholes` was given (keyword -> value, those
        not given left out): a project saves them to read the table the same way.
    lost_geozones : dict
        Labels the table holds none of whose holes were kept (label -> why: all
        left out, or all merged into another geozone's coincident holes), so a
        request for one is told why it is missing, not that it is not in the table.
    data_line : (n,) int or None
        The file line each hole was read from, as warnings name them; None for
        holes not read from a file. What names a hole where the table has no id
        column (:func:`core.io.reporting.hole_ids`): a hole's place among the kept
        holes is not its row once holes are left out or merged.
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
    unit_guess: str = ""
    read_options: dict = field(default_factory=dict)
    lost_geozones: dict = field(default_factory=dict)
    data_line: np.ndarray | None = None
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

    def below_deepest_m(self, fraction: float = 1.0) -> float:
        """The elevation ``fraction`` of a bench height below the deepest bench (local metres); 1: the next bench.

        One height for every "next bench" (the build's and the viewer's predictions, the surfaces' ends, the
        band and the suggestions): :attr:`bench_height_m`, the median gap between benches or the one given. The
        deepest pair's own gap put Kennecott's predictions 47.6 ft down and its suggestions 49.65 ft down, two
        "next benches" 2 ft apart in one build.
        """
        return float(self.bench_levels_m[-1] - fraction * self.bench_height_m)

    def on_bench(self, k: int, geozone: str | None = None) -> np.ndarray:
        """Indices of the holes on bench ``k`` (optionally of one geozone)."""
        sel = self.bench == k
        if geozone is not None:
            sel &= self.geozone == geozone
        return np.flatnonzero(sel)

    def check_geozones(self, requested: list[str] | None) -> list[str]:
        """Validate requested geozones; all of them when ``requested`` is empty.

        A request that spells a present label's number another way (``3310.0``
        for ``3310``) is that label.
        """
        present = self.geozones
        if not requested:
            return present
        by_number = {label_number(g): g for g in present if label_number(g) is not None}
        # As labels are read (stripped): bgm predict --geozone " 3310" was refused where bgm build took it.
        requested = [unicodedata.normalize("NFC", str(g)).strip() for g in requested]
        found = [g if g in present else by_number.get(label_number(g)) for g in requested]
        missing = [g for g, f in zip(requested, found) if f is None]
        lost = [g for g in missing if g in self.lost_geozones]
        if lost:
            # "not in the file" of a label the file holds sent the geologist looking for a typo.
            raise BGMInputError(
                f"geozone {quoted(lost[0])} is in {self.source or 'the input'}, but none of its holes is left: "
                f"{self.lost_geozones[lost[0]]}; geozones present: {listing(present)}"
            )
        if missing:
            raise BGMInputError(
                f"geozone {', '.join(map(quoted, missing[:5]))} is not in {self.source or 'the input'}; "
                f"geozones present: {listing(present)}"
            )
        return list(dict.fromkeys(f for f in found if f is not None))

    def check_one_geozone(self, value: str, command: str) -> str:
        """The one geozone ``value`` names for ``command`` (``bgm predict``, ...), validated.

        ``bgm contours`` and ``bgm build`` take several geozones separated by
        commas; the commands that model one refused ``3320,3310`` as a label
        "not in" the table, and the geologist looked for a typo. A value that
        is no label but several (separated by commas or semicolons, or by
        spaces where each part is a label) is refused naming them.

        Parameters
        ----------
        value : str
            The ``--geozone`` as given.
        command : str
            The command, as the message names it (``bgm predict``).

        Returns
        -------
        str
            The label as the table writes it.
        """
        try:
            return self.check_geozones([value])[0]
        except BGMInputError:
            several = [] if str(value).strip() in self.lost_geozones else self._several_geozones(value)
            if not several:
                raise
        missing = [g for g in several if not self._is_geozone(g)]
        absent = f"; {listing(map(quoted, missing))} not in {self.source or 'the input'}" if missing else ""
        raise BGMInputError(
            f"{command} takes one geozone; --geozone {quoted(value)} names {len(several)}: "
            f"{listing(several)}{absent} (run {command} once for each)"
        )

    def _is_geozone(self, value: str) -> bool:
        try:
            self.check_geozones([value])
        except BGMInputError:
            return False
        return True

    def _several_geozones(self, value: str) -> list[str]:
        """The geozones a value that is no label lists, or none when it lists fewer than two."""
        text = unicodedata.normalize("NFC", str(value)).strip()
        if re.search(r"[,;]", text):
            parts = [g.strip() for g in re.split(r"[,;]", text) if g.strip()]
            return parts if len(parts) > 1 else []
        parts = text.split()
        # Spaces only when every part is a label: a label may hold spaces ("ore oxide").
        return parts if len(parts) > 1 and all(self._is_geozone(g) for g in parts) else []

    def drilled_area(self, k: int):
        """Area drilled on bench ``k`` (see :func:`drilled_area`), computed once per bench."""
        if k not in self._drilled:
            self._drilled[k] = drilled_area(self.xy[self.bench == k], self.hole_spacing_m)
        return self._drilled[k]

    def as_table(self) -> pd.DataFrame:
        """The holes as an input table: x, y, z and geozone in the input's coordinates and units.

        Read again (:func:`blastholes_from_table`), a part of it finds its benches from its own holes, where
        :meth:`subset` keeps the whole table's levels (an empty one among them).
        """
        xy = self.frame.to_input(self.xy)
        return pd.DataFrame({"x": xy[:, 0], "y": xy[:, 1], "z": self.frame.z_to_input(self.z), "geozone": self.geozone})

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
            unit_guess=self.unit_guess,
            read_options=dict(self.read_options),
            lost_geozones=dict(self.lost_geozones),
            data_line=None if self.data_line is None else self.data_line[keep],
        )


# ---------------------------------------------------------------------------
# Reading tables


def find_column(columns: list[str], role: str, explicit: str | None = None) -> str:
    """The column playing ``role`` (x, y, z or geozone), found by name case-insensitively.

    Names are compared with surrounding spaces and a length unit ending them
    removed (``Easting (m)``, ``RL_ft``, see :func:`column_key`); an explicit
    name is matched exactly first, then ignoring case and spaces.
    """
    if explicit:
        key = explicit.strip().lower()
        matches = [c for c in columns if c == explicit] or [c for c in columns if str(c).strip().lower() == key]
        if not matches:
            raise BGMInputError(
                f"column {quoted(explicit)} given for {role} is not in the table; columns are: {listing(columns)}"
            )
        _refuse_one_name_twice(columns, matches[0], role)
        return matches[0]
    aliases = COLUMN_ALIASES[role]
    matches = [c for c in columns if column_key(c) in aliases]
    if not matches:
        raise BGMInputError(
            f"no {role} column: looked for {', '.join(aliases)} (any case); columns are: "
            f"{listing(columns)}; name it with {COLUMN_OPTIONS[role]} COLUMN"
        )
    _refuse_one_name_twice(columns, matches[0], role)
    if len(matches) > 1:
        raise BGMInputError(
            f"ambiguous {role} column: {listing(map(repr, matches))} could all be {role}; choose one with {COLUMN_OPTIONS[role]} COLUMN"
        )
    return matches[0]


def _refuse_one_name_twice(columns: list[str], name: str, role: str) -> None:
    """Refuse a table with two columns of the name ``role`` is read from (a collar's and a toe's ``X``).

    No option can choose between them (``--x X`` names both), and the first was read without
    a word: the message says to rename one, not to name it with an option.

    Raises
    ------
    BGMInputError
        ``name`` heads more than one column.
    """
    at = [i + 1 for i, c in enumerate(columns) if c == name]
    if len(at) > 1:
        raise BGMInputError(
            f"the table has {len(at)} columns named {quoted(name)} (columns {listing(map(str, at))}), "
            f"which could all be {role}: rename them so that one is {role}"
        )


def column_key(name: str) -> str:
    """A column name as compared with :data:`COLUMN_ALIASES`: trimmed, lower case, a length unit ending it dropped."""
    return UNIT_SUFFIX.sub("", str(name).strip()).lower()


def is_hole_id_column(name: str) -> bool:
    """Whether a column named ``name`` holds the hole identifiers (:data:`HOLE_ID_NAMES`).

    Mine software writes the name many ways (``Hole ID``, ``HOLE_ID``, ``HoleID``,
    ``BHID``): compared with the separators left out, so that none of them is
    missed and the holes named by row number instead, with nothing saying so.
    """
    key = _NAME_SEPARATORS.sub("", str(name).strip().lower())
    return key in _HOLE_ID_KEYS


def table_columns(columns: list[str], x=None, y=None, z=None, geozone=None) -> dict[str, str]:
    """Column of each role (x, y, z, geozone and, when present, hole_id)."""
    columns = [str(c) for c in columns]
    cols = {
        "x": find_column(columns, "x", x),
        "y": find_column(columns, "y", y),
        "z": find_column(columns, "z", z),
        "geozone": find_column(columns, "geozone", geozone),
    }
    if len(set(cols.values())) < 4:
        raise BGMInputError(f"one column is used for two roles: {cols}")
    hole = next((c for c in columns if is_hole_id_column(c) and c not in cols.values()), None)
    if hole is not None:
        cols["hole_id"] = hole
    return cols


def _label_strings(values: pd.Series) -> np.ndarray:
    """Geozone labels as strings; integral floats from Parquet lose their '.0'."""
    if pd.api.types.is_float_dtype(values):
        v = values.to_numpy()
        ok = np.isfinite(v)
        if ok.all() and np.all(v == np.round(v)):
            return np.array([str(int(a)) for a in v], dtype=object)
    return np.array([("" if pd.isna(a) else str(a).strip()) for a in values], dtype=object)


def label_number(label: str) -> Decimal | None:
    """The number a geozone label spells (``3310``, ``3310.0``, ``3.31e3``...), exactly; None if none.

    A label with leading zeros (``010``, ``0010``) is a code and spells no
    number: ``010`` and ``10`` are distinct codes, and no program writing a
    float column pads it with zeros.
    """
    if len(label) > 40 or not NUMBER_LABEL.fullmatch(label) or LEADING_ZEROS.match(label):
        return None
    return Decimal(label)


def number_label(value: Decimal) -> str:
    """Plain spelling of a number: ``3310``, ``0.5``, ``-12.25`` (no exponent, no trailing zeros)."""
    return "0" if value == 0 else format(value.normalize(), "f")


def merge_number_spellings(labels: np.ndarray) -> tuple[np.ndarray, dict[str, str]]:
    """Make labels that spell the same number differently one label.

    ``3310`` and ``3310.0`` in one file are one geozone written by two
    programs, not two geozones. An integer written with a zero fraction
    (``3310.0``) is its plain spelling even alone: a float column gives it
    in CSV, and the same column read from Parquet gives ``3310``. Other
    labels that spell a number no other label spells stay as written, and
    labels with leading zeros (codes, see :func:`label_number`) always do.

    Returns
    -------
    labels : (n,) object
    renamed : dict
        Spelling -> the plain spelling it was merged into (empty when nothing
        merged); lone zero fractions made plain are not listed.
    """
    by_value: dict[Decimal, list[str]] = {}
    for label in pd.unique(np.asarray(labels, dtype=object)):
        value = label_number(label)
        if value is not None:
            by_value.setdefault(value, []).append(label)
    renamed = {s: number_label(v) for v, spellings in by_value.items() if len(spellings) > 1 for s in spellings}
    renamed = {s: t for s, t in renamed.items() if s != t}
    plain = {s: number_label(v) for v, (s, *more) in by_value.items() if not more and ZERO_FRACTION.fullmatch(s)}
    if not renamed and not plain:
        return np.asarray(labels, dtype=object), {}
    merged = pd.Series(labels, dtype=object).replace(renamed | plain).to_numpy(dtype=object)
    return merged, renamed


def _rows(idx: np.ndarray, lines: np.ndarray, limit: int = 10) -> str:
    """The file lines of data rows ``idx``, ``lines`` being each row's (see :func:`core.io.tables.data_lines`)."""
    shown = ", ".join(str(int(lines[i])) for i in idx[:limit])
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
        CSV (comma, semicolon, tab or pipe separated; plain or compressed) or
        Parquet file, or ``-`` for standard input (see :mod:`core.io.tables`).
    x, y, z, geozone : str, optional
        Column names; by default found among :data:`COLUMN_ALIASES`.
    bench_height : float, optional
        Bench height in the input's units; detected from z when omitted.
    length_unit : {"m", "ft"}, optional
        Units of the input's coordinates; guessed from the bench height when
        omitted (benches of 25 units or more are taken to be feet: metric
        benches are 5-20 m, imperial ones 30-60 ft), unless their holes would
        then be under :data:`MIN_HOLE_SPACING_M` apart.

    Returns
    -------
    Blastholes
    """
    from core.io.tables import read_table

    cols: dict[str, str] = {}

    def choose(header: list[str]) -> list[int]:
        cols.update(table_columns(header, x, y, z, geozone))
        return [header.index(c) for c in cols.values()]

    table = read_table(path, choose)
    holes = blastholes_from_table(
        table,
        x=cols["x"],
        y=cols["y"],
        z=cols["z"],
        geozone=cols["geozone"],
        bench_height=bench_height,
        length_unit=length_unit,
        source="standard input" if str(path) == "-" else str(path),
    )
    given = {"x": x, "y": y, "z": z, "geozone": geozone, "bench_height": bench_height, "length_unit": length_unit}
    holes.read_options = {k: v for k, v in given.items() if v is not None}
    return holes


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
    """:func:`read_blastholes` on a table already in memory.

    In steps: the columns and coordinates (:func:`_table_coordinates`), the labels, the benches and the holes
    left out off them or far from their bench (each named in a warning), the unit and the local frame
    (:func:`_kept_holes`), then duplicates merged and the hole spacing measured (:func:`_measure_spacing`).
    Warnings are given here (their ``stacklevel`` counts from this function).
    """
    if len(table) == 0:
        raise BGMInputError(f"{source or 'the input'} has a header but no rows")
    lines = data_lines(table)
    table, cols, coords = _table_coordinates(table, x, y, z, geozone, lines, source)
    notes: list[str] = []
    _warn_depth_column(cols["z"], notes)
    _warn_single_precision(table, cols, notes)
    labels = _geozone_labels(table[cols["geozone"]], cols["geozone"], lines, notes)
    hole_id = table[cols["hole_id"]].astype(str).to_numpy(dtype=object) if "hole_id" in cols else None

    if len(labels) < 3:
        raise BGMInputError(f"{source or 'the input'} has only {len(labels)} hole(s); BGM needs at least 3")

    zin = coords["z"]
    xy_in = np.column_stack([coords["x"], coords["y"]])
    levels_in, bench, height_in, off = detect_benches(zin, bench_height, xy=xy_in)
    sparse = None if bench_height is not None else sparse_bench_note(bench, levels_in)
    if sparse:
        _note(notes, sparse, stacklevel=3)
    _note_missing_elevations(zin, notes)
    # A single bench's far groups lie beyond FAR_GROUP_SPACINGS of its own pattern (see _far_beside_one_bench).
    reach = FAR_GROUP_SPACINGS * median_hole_spacing(xy_in[~off]) if len(levels_in) == 1 and off.any() else np.inf
    _left_out_off_bench(notes, zin, off, levels_in, height_in, lines, given=bench_height is not None, reach=reach)
    far = _far_holes(xy_in, bench, ~off)
    where = f"lie more than {FAR_HOLE_SPACINGS:g} hole spacings from every other hole of their bench"
    _left_out(notes, far, lines, where, "x, y missing or mistyped")

    named = unit_in_names(cols, length_unit, notes)
    unit = _guess_unit(
        height_in,
        length_unit or named,
        lambda: median_hole_spacing(xy_in[~off], bench[~off]),
    )
    keep = ~off & ~far
    holes = _kept_holes(coords, labels, hole_id, bench, levels_in, height_in, keep, unit, source, notes)
    holes.data_line = np.asarray(lines, dtype=np.int64)[keep]
    holes = _deduplicate(holes, lines[keep])
    holes.lost_geozones = _lost_geozones(labels, labels[keep], holes.geozone)
    _measure_spacing(holes, source)
    _check_spacing(holes, given=bool(length_unit))
    _warn_upside_down(holes, cols["z"])
    holes.unit_guess = _unit_guess_note(unit, length_unit or named, height_in)
    return holes


def unit_in_names(cols: dict[str, str], length_unit: str | None = None, notes: list[str] | None = None) -> str | None:
    """The length unit the x, y and z columns' names state (``Easting (ft)``, ``RL_ft``), None where none does.

    A table whose columns say feet is in feet, whatever its bench height: 20 ft benches
    with holes 18 ft apart read as metres by the bench height alone (:func:`_guess_unit`),
    and every area, volume and file came out labelled metres. ``length_unit`` (``--units``)
    given overrides the names, with a warning (in ``notes``) where they say otherwise.

    Raises
    ------
    BGMInputError
        The names state different units (``X (m)`` and ``RL (ft)``) and no ``--units`` is given.
    """
    said = {}
    for role in ("x", "y", "z"):
        found = UNIT_SUFFIX.search(str(cols[role]).strip())
        if found:
            letters = re.sub(r"[^a-z]", "", found.group(0).lower())
            said[role] = "ft" if letters in ("ft", "feet") else "m"
    units = set(said.values())
    named = ", ".join(f"{quoted(cols[r])} in {u}" for r, u in said.items())
    if length_unit:
        if units - {unit_name(length_unit)}:
            _note(
                notes if notes is not None else [],
                f"--units {length_unit} given, but the columns are named {named}: "
                f"read in {unit_name(length_unit)} as given",
                stacklevel=4,
            )
        return None
    if len(units) > 1:
        raise BGMInputError(
            f"the columns are named in different length units ({named}); x, y and z must be in one unit: "
            "convert them, or give --units if the names are wrong"
        )
    return units.pop() if units else None


def _table_coordinates(
    table: pd.DataFrame,
    x: str | None,
    y: str | None,
    z: str | None,
    geozone: str | None,
    lines: np.ndarray,
    source: str,
) -> tuple[pd.DataFrame, dict[str, str], dict[str, np.ndarray]]:
    """The table's columns BGM reads (by role, see :func:`table_columns`), those columns alone, and x, y, z as
    numbers (input units); refused when x, y are degrees (see :func:`_refuse_degrees`)."""
    delimiter = table.attrs.get("delimiter")
    cols = table_columns(list(table.columns), x, y, z, geozone)
    table = table[list(cols.values())].copy()
    table.columns = list(cols.values())
    coords = {role: _coordinates(table[cols[role]], cols[role], role, delimiter, lines) for role in ("x", "y", "z")}
    _refuse_degrees(coords["x"], coords["y"], source)
    return table, cols, coords


def _kept_holes(
    coords: dict[str, np.ndarray],
    labels: np.ndarray,
    hole_id: np.ndarray | None,
    bench: np.ndarray,
    levels_in: np.ndarray,
    height_in: float,
    keep: np.ndarray,
    unit: str,
    source: str,
    notes: list[str],
) -> Blastholes:
    """The holes ``keep`` (on a bench, near the others of theirs) in a local frame in metres, centred on their
    median position (rounded to a whole unit); the hole spacing not measured yet (NaN)."""
    mpu = FEET_TO_METRES if unit == "ft" else 1.0
    frame = LocalFrame(
        origin_x=float(np.round(np.median(coords["x"][keep]))),
        origin_y=float(np.round(np.median(coords["y"][keep]))),
        metres_per_unit=mpu,
        length_unit=unit,
    )
    xy = frame.to_local(coords["x"], coords["y"])
    return Blastholes(
        xy=xy[keep],
        z=frame.z_to_local(coords["z"])[keep],
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


def _measure_spacing(holes: Blastholes, source: str) -> None:
    """Set the holes' spacing (see :func:`table_hole_spacing`); refused when no bench has two distinct holes."""
    holes.hole_spacing_m = table_hole_spacing(holes.xy, holes.bench)
    if not np.isfinite(holes.hole_spacing_m) or holes.hole_spacing_m <= 0:
        raise BGMInputError(
            f"cannot measure the hole spacing of {source or 'the input'}: no bench has two distinct holes"
        )


def _unit_guess_note(unit: str, length_unit: str | None, height_in: float) -> str:
    """What :attr:`Blastholes.unit_guess` says of a unit not given (``""`` when given, or beyond doubt)."""
    if unit == "ft" and not length_unit:
        return f"feet guessed from the {height_in:.4g}-unit bench height: give --units m if not"
    if not length_unit and not np.isfinite(height_in):  # nothing to tell metres from feet by: say so
        return "metres assumed: a single bench has no bench height to tell feet by: give --units ft if not"
    if not length_unit and METRIC_BENCH_MAX < height_in < 25.0:
        return (
            f"metres guessed from the {height_in:.4g}-unit bench height, above metric benches (5-20 m) "
            "and below imperial ones (30-60 ft): give --units ft if not"
        )
    return ""


def _left_out_off_bench(
    notes: list[str],
    z: np.ndarray,
    off: np.ndarray,
    levels: np.ndarray,
    height: float,
    lines: np.ndarray,
    given: bool,
    reach: float = np.inf,
) -> None:
    """Warn of the off-bench holes left out: those far above or below every bench (elevations missing or
    mistyped), then the strays between or beside the benches.

    Beside several benches the far ones lie more than a bench height beyond the top or the bottom one. A
    single bench has no bench height: its far ones sit exactly at 0 or -9999 (:data:`MISSING_ELEVATIONS`) or
    more than ``reach`` from it (mistyped: 150 for 1500), the others off the elevations of its holes. 300 holes at 0 beside one bench at 685 were said to lie
    "more than 30% of a bench height from every bench level", a height it does not have. When ten or more
    far ones sit at one elevation they may be a bench of their own, which a bench height keeps: said, unless
    one was ``given``.

    Parameters
    ----------
    notes : list of str
        The holes' notes, appended to.
    z : (n,) float
        Elevations, input units.
    off : (n,) bool
        Holes on no bench.
    levels : (b,) float
        Bench levels, input units.
    height : float
        Bench height, input units (nan for a single bench).
    lines : (n,) int
        Each hole's data line.
    given : bool
        Whether the bench height was given.
    reach : float
        Beside a single bench, how far (input units) a group at any elevation lies to be no bench (see
        :data:`FAR_GROUP_SPACINGS`).
    """
    if len(levels) >= 2:
        outside = off & ((z < levels.min() - height) | (z > levels.max() + height))
        where = f"lie more than a bench height above or below every bench, at z {_far_values(z[outside])}"
        strays = f"lie more than {OFF_BENCH_FRACTION:.0%} of a bench height from every bench level"
    else:
        outside = off & (np.isin(z, list(MISSING_ELEVATIONS)) | (np.abs(z - levels[0]) > reach))
        where = f"lie far above or below the only bench (at z {levels[0]:g}), at z {_far_values(z[outside])}"
        on = z[~off]
        strays = (
            f"lie off the only bench's elevations ({on.min():g} to {on.max():g}), at z {_far_values(z[off & ~outside])}"
        )
    one_level = outside.sum() >= 10 and np.ptp(z[outside]) == 0 and len(levels) == 1 and not given
    then = "; if they are a bench of their own, give --bench-height" if one_level else ""
    _left_out(
        notes, outside, lines, where, "elevations missing (written as 0 or -9999) or mistyped", then, stacklevel=5
    )
    _left_out(notes, off & ~outside, lines, strays, stacklevel=5)


def _note_missing_elevations(z: np.ndarray, notes: list[str]) -> None:
    """Say so when every hole sits at 0 (or -9999): one bench, a plan, unless the table's elevations are missing.

    A table without elevations (a plan of one bench, z written as 0) reads as one bench, as it should; but a
    table of several benches whose z column was exported empty reads so too, its benches' holes stacked on one
    plan (their positions merged, their labels in conflict) with nothing saying why.
    """
    if np.ptp(z) == 0 and float(z[0]) in MISSING_ELEVATIONS:
        msg = (
            f"every hole's elevation is {z[0]:g}: read as one bench (a plan); if the holes come from several "
            "benches, their elevations are missing and the benches cannot be told apart: fill them in"
        )
        _note(notes, msg, stacklevel=4)


def _lost_geozones(read: np.ndarray, kept: np.ndarray, merged: np.ndarray) -> dict[str, str]:
    """Labels of the table none of whose holes is left, and why: label -> reason.

    Parameters
    ----------
    read : ndarray of str
        Every row's label as read.
    kept : ndarray of str
        The labels of the holes kept on the benches (none far off every bench or every other hole).
    merged : ndarray of str
        The labels left once coincident holes were merged (first row kept).
    """
    kept_labels, merged_labels = set(kept.tolist()), set(merged.tolist())
    lost = {}
    for label in sorted(set(read.tolist()) - merged_labels):
        lost[label] = (
            "every one of its holes lies where another geozone's hole is, on the same bench, and was merged "
            "into it (the first row kept, as warned)"
            if label in kept_labels
            else "every one of its holes was left out, off the benches or far from every other hole (as warned)"
        )
    return lost


def _far_holes(xy: np.ndarray, bench: np.ndarray, on: np.ndarray) -> np.ndarray:
    """Holes of ``on`` more than :data:`FAR_HOLE_SPACINGS` hole spacings from every other position of their bench.

    One such hole (x, y written as 0 where they were missing) drew every extent around itself: a surface of
    1.7e12 m³ for the demo's 4.0e6, no suggestions and no evaluation, without a word. Only a few of a bench's
    holes are: a bench whose holes are mostly that far apart is sparse, not mistyped.
    """
    far = np.zeros(len(xy), bool)
    spacing = median_hole_spacing(xy[on], bench[on])
    if not np.isfinite(spacing) or spacing <= 0:
        return far
    for k in np.unique(bench[on]):
        idx = np.flatnonzero(on & (bench == k))
        points, which = np.unique(xy[idx], axis=0, return_inverse=True)  # holes listed twice are one position
        if len(points) < 2:
            continue
        alone = cKDTree(points).query(points, k=2)[0][:, 1] > FAR_HOLE_SPACINGS * spacing
        if alone.sum() <= 0.1 * len(points):
            far[idx] = alone[which.ravel()]
    return far


def _left_out(
    notes: list[str],
    left: np.ndarray,
    lines: np.ndarray,
    where: str,
    guess: str = "",
    then: str = "",
    stacklevel: int = 4,
) -> None:
    """Warn of the holes ``left`` out: how many, where they lie, their data lines, if any a likely cause, and
    ``then`` what to do if they should not have been."""
    if not left.any():
        return
    said = f"{int(left.sum())} hole(s) {where} (data line(s) {_rows(np.flatnonzero(left), lines)})"
    msg = f"{said}: {guess}? they were left out" if guess else f"{said} and were left out"
    _note(notes, msg + then, stacklevel=stacklevel)


def _note(notes: list[str], msg: str, stacklevel: int) -> None:
    """A repair or doubt about the input: kept in the holes' ``notes`` and warned about."""
    notes.append(msg)
    warnings.warn(msg, BGMWarning, stacklevel=stacklevel)


#: A coordinate stored with a coarser step than this (input units) at its largest value is warned about:
#: finer steps are within a collar survey's own error (a few centimetres), coarser ones move holes visibly.
COORDINATE_STEP_MAX = 0.1


def _warn_single_precision(table: pd.DataFrame, cols: dict[str, str], notes: list[str]) -> None:
    """Warn of x, y or z stored as 32-bit floats (a Parquet ``float``) too coarse at their magnitude.

    A float32 holds 24 bits: mine-grid northings near 7,445,000 are then stored in steps
    of 0.5 units, every hole moved by up to a quarter of a unit before BGM reads it (the
    demo's top benches read a hole spacing of 5.51 m, not 5.46 m), with nothing saying so. Nothing can be
    recovered from the file: the warning says to write it as 64-bit floats.
    """
    for role in ("x", "y", "z"):
        column = table[cols[role]]
        if not (pd.api.types.is_float_dtype(column) and column.dtype.itemsize < 8 and len(column)):
            continue
        largest = float(np.nanmax(np.abs(column.to_numpy(dtype=float))))
        step = float(np.spacing(column.dtype.type(largest)))
        if step > COORDINATE_STEP_MAX:
            _note(
                notes,
                f"column {quoted(cols[role])} ({role}) is stored as {8 * column.dtype.itemsize}-bit floats, which "
                f"near {largest:,.0f} hold positions only in steps of {step:g} units: write it as 64-bit floats "
                "(double) for holes where they were drilled",
                stacklevel=4,
            )


def _warn_depth_column(column: str, notes: list[str]) -> None:
    """Warn when z is read from a column named as a depth: positive down, it turns the benches upside down.

    Not flipped: a name is no proof, and an elevation needs the collar's, which the table may not hold.
    """
    if DEPTH_NAME.fullmatch(column.strip()):
        msg = (
            f"column {quoted(column)} given for z is named like a depth (positive down), but z must be an "
            "elevation (positive up): read as one, the deepest bench is the top; give an elevation column "
            "with --z, or convert first (elevation = collar elevation - depth)"
        )
        _note(notes, msg, stacklevel=4)


def widening_with_depth(xy: np.ndarray, bench: np.ndarray, n_benches: int, hole_spacing_m: float) -> float | None:
    """How many times the top third of the benches' area their deepest third spans, when the benches widen with depth.

    An open pit is widest at its top and narrows bench by bench. Each bench's area is its holes' convex hull; the
    median bench of the deepest third is compared with that of the top third, benches with few holes
    (:data:`PIT_SHAPE_MIN_HOLES_SHARE`) left out, so that a bench partly drilled at either end does not decide.

    Parameters
    ----------
    xy : (n, 2) float
        Hole positions.
    bench : (n,) int
        Each hole's bench, 0 the top one (-1 off the benches).
    n_benches : int

    Returns
    -------
    float or None
        The ratio of the two areas when it is at least :data:`UPSIDE_DOWN_AREA_RATIO` and more benches widen
        than narrow downwards (their rank correlation with depth is positive); None otherwise, or with fewer
        than :data:`PIT_SHAPE_MIN_BENCHES` benches to tell by.
    """
    counts = np.bincount(bench[bench >= 0], minlength=n_benches)
    full = np.flatnonzero(counts >= PIT_SHAPE_MIN_HOLES_SHARE * np.median(counts[counts > 0]))
    if len(full) < PIT_SHAPE_MIN_BENCHES:
        return None
    area = np.array([_pattern_hull_area(xy[bench == k], hole_spacing_m) for k in full])
    third = len(full) // 3
    top, deep = float(np.median(area[:third])), float(np.median(area[-third:]))
    if not (top > 0 and deep >= UPSIDE_DOWN_AREA_RATIO * top):
        return None
    widening = np.corrcoef(np.arange(len(full)), np.argsort(np.argsort(area)))[0, 1]  # Spearman's, top first
    return deep / top if widening > 0 else None


#: A hole counts in a bench's extent (:func:`_pattern_hull_area`) with at least this many holes within
#: :data:`PATTERN_REACH_SPACINGS` of it: inside a blast pattern (about 30 on a staggered one), not a few holes
#: far off (a constructed table's 4-hole patch 300 m out made its bench's hull 2.3 times the top bench's).
PATTERN_NEIGHBOURS = 12
PATTERN_REACH_SPACINGS = 3.0


def _pattern_hull_area(xy: np.ndarray, hole_spacing_m: float) -> float:
    """The area of the convex hull of a bench's holes that lie in a blast pattern (:data:`PATTERN_NEIGHBOURS`)."""
    import shapely
    from scipy.spatial import cKDTree

    if len(xy) < PATTERN_NEIGHBOURS:
        return 0.0
    near = cKDTree(xy).query_ball_point(xy, PATTERN_REACH_SPACINGS * hole_spacing_m, return_length=True)
    return float(shapely.MultiPoint(xy[near >= PATTERN_NEIGHBOURS]).convex_hull.area)


def _warn_upside_down(holes: Blastholes, column: str) -> None:
    """Warn when the benches widen with depth as z reads them (:func:`widening_with_depth`): depths read as elevations.

    Depths below a datum (positive down) in a column named ``z`` or ``RL`` turn the benches upside down without a
    word: every prediction "below the deepest bench" lies above the top one. A column named like a depth is
    warned of by its name (:func:`_warn_depth_column`). Not refused: a pit drilled out of order, or pushed back,
    may widen downwards.
    """
    if DEPTH_NAME.fullmatch(column.strip()):
        return
    ratio = widening_with_depth(holes.xy, holes.bench, holes.n_benches, holes.hole_spacing_m)
    if ratio is None:
        return
    msg = (
        f"the benches widen with depth as column {quoted(column)} (z) reads them: the deepest third's holes "
        f"span {ratio:.1f} times the area of the top third's (z {holes.bench_z_input(0):g} down to "
        f"{holes.bench_z_input(holes.n_benches - 1):g}), where an open pit narrows with depth; if {quoted(column)} "
        "holds depths (positive down), the benches are upside down and every prediction below the deepest bench "
        "lies above the top one: give elevations instead (elevation = collar elevation - depth)"
    )
    _note(holes.notes, msg, stacklevel=4)


def _geozone_labels(raw: pd.Series, column: str, lines: np.ndarray, notes: list[str]) -> np.ndarray:
    """Labels as strings, none blank, spellings of one number merged (said in ``notes`` and a warning)."""
    labels = _label_strings(raw)
    blank = np.flatnonzero(labels == "")
    if len(blank):
        raise BGMInputError(
            f"column {quoted(column)} (geozone) is empty on {len(blank)} row(s): data line(s) {_rows(blank, lines)}"
        )
    labels = _merge_unicode_forms(labels, column, notes)
    labels, renamed = merge_number_spellings(labels)
    if renamed:
        msg = (
            f"geozone labels {listing(sorted(renamed), 5)} spell the same number as other labels and were merged "
            f"into {listing(sorted(set(renamed.values())), 5)}"
        )
        _note(notes, msg, stacklevel=5)
    _warn_case_twins(labels, column, notes)
    _warn_missing_labels(labels, column, lines, notes)
    _warn_identifier_labels(labels, column, notes)
    return labels


def _merge_unicode_forms(labels: np.ndarray, column: str, notes: list[str]) -> np.ndarray:
    """Labels in Unicode's composed form (NFC): one text written in two forms is one geozone, said in a note.

    ``minério`` typed with ``é`` as one character and pasted from elsewhere
    as ``e`` and a combining accent looks the same everywhere and is the same
    text (canonically equivalent), but compares unequal: read as written,
    the two were two geozones, each on the benches of its own rows, without
    a word; and a label in the decomposed form alone was not found by a
    ``--geozone`` typed in the usual composed one.
    """
    forms = {str(g): unicodedata.normalize("NFC", str(g)) for g in pd.unique(labels)}
    renamed = {g: nfc for g, nfc in forms.items() if g != nfc}
    if not renamed:
        return labels
    merged = pd.Series(labels, dtype=object).replace(renamed).to_numpy(dtype=object)
    twins = sorted({nfc for nfc in renamed.values() if nfc in forms})
    if twins:
        msg = (
            f"geozone labels {listing(map(quoted, twins), 5)} in column {quoted(column)} are written in two "
            "Unicode forms (an accent as part of its letter, or as a character of its own): each is one geozone"
        )
        _note(notes, msg, stacklevel=5)
    return merged


def _warn_identifier_labels(labels: np.ndarray, column: str, notes: list[str]) -> None:
    """Warn when most holes have a label of their own: the column is a hole identifier, not geozones.

    A geozone holds many holes; more than :data:`MAX_OWN_LABEL_SHARE` of the
    holes alone in theirs (of at least :data:`MIN_HOLES_FOR_ID_CHECK`) is an
    identifier column read as geozones, which would make a geozone per hole.
    """
    if len(labels) < MIN_HOLES_FOR_ID_CHECK:
        return
    counts = pd.Series(labels, dtype=object).value_counts().to_numpy()  # no fixed-width copy: a label may be 50 MB
    alone = int((counts == 1).sum())
    if alone > MAX_OWN_LABEL_SHARE * len(labels):
        msg = (
            f"column {quoted(column)} (geozone) gives {len(counts)} geozones to {len(labels)} holes, {alone} of them "
            "a label of their own: it looks like an identifier, not geozone labels; name the geozone column "
            "with --geozone-column"
        )
        _note(notes, msg, stacklevel=5)


def _warn_missing_labels(labels: np.ndarray, column: str, lines: np.ndarray, notes: list[str]) -> None:
    """Warn about labels that spell a missing value (``NA``, ``NULL``, ``-99``...): modelled as a geozone of their own.

    A blank label is refused; these are not refused, since a code may be a
    real geozone, but unlabelled holes outlined as a geozone reshape their
    neighbours' boundaries, so the warning names them and their rows.
    """
    found = sorted(str(g) for g in pd.unique(labels) if str(g).casefold() in MISSING_LABELS)
    if not found:
        return
    missing = pd.Series(labels, dtype=object).isin(found).to_numpy()
    msg = (
        f"geozone label(s) {listing(map(quoted, found), 5)} in column {quoted(column)} look like missing values "
        f"({int(missing.sum())} hole(s), data line(s) {_rows(np.flatnonzero(missing), lines)}): they are modelled "
        "as a geozone of their own; drop those rows or give them their geozone if they are unlabelled"
    )
    _note(notes, msg, stacklevel=5)


def _warn_case_twins(labels: np.ndarray, column: str, notes: list[str]) -> None:
    """Warn about labels differing only by case (``G0``, ``g0``): kept distinct, but often one code typed twice."""
    by_fold: dict[str, list[str]] = {}
    for label in pd.unique(labels):
        by_fold.setdefault(str(label).casefold(), []).append(str(label))
    twins = [sorted(group) for group in by_fold.values() if len(group) > 1]
    if twins:
        more = f" ({len(twins) - 1} more such group(s))" if len(twins) > 1 else ""
        msg = (
            f"geozone labels {' and '.join(quoted(t) for t in twins[0][:5])}{more} in column {quoted(column)} "
            "differ only by case: they are kept as distinct geozones"
        )
        _note(notes, msg, stacklevel=5)


def _is_numeric(raw: pd.Series) -> bool:
    return pd.api.types.is_numeric_dtype(raw) and not pd.api.types.is_bool_dtype(raw)


def coordinate_values(raw: pd.Series, delimiter: str | None) -> np.ndarray:
    """A coordinate column as the reader takes it (decimal commas, thousands separators); NaN where not a number."""
    if _is_numeric(raw):
        return raw.to_numpy(dtype=float)
    text = _without_digit_grouping(raw.astype(str).str.strip(), delimiter)
    return pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)


def _coordinates(raw: pd.Series, column: str, role: str, delimiter: str | None, lines: np.ndarray) -> np.ndarray:
    """A coordinate column as finite floats, or one sentence naming the rows that are not."""
    values = coordinate_values(raw, delimiter)
    bad = np.flatnonzero(~np.isfinite(values))
    if len(bad):
        text = not _is_numeric(raw)
        example = f" (e.g. {quoted(raw.iloc[bad[0]], 30)})" if text else ""
        hint = ""
        if text and raw.iloc[bad].astype(str).str.contains(",", regex=False).any():
            hint = "; commas there are neither all decimal commas nor all thousands separators"
        raise BGMInputError(
            f"column {quoted(column)} ({role}) has {len(bad)} missing, non-numeric or infinite "
            f"value(s), on data line(s) {_rows(bad, lines)}{example}{hint}"
        )
    # Finite but absurd magnitudes (1e300) overflow distance computations
    # (kD-tree) deep in the engine; no mine grid comes near 1e12 units, and
    # past it float64 cannot hold sub-millimetre positions anyway.
    huge = np.flatnonzero(np.abs(values) > MAX_COORDINATE)
    if len(huge):
        raise BGMInputError(
            f"column {quoted(column)} ({role}) has {len(huge)} value(s) beyond {MAX_COORDINATE:.0e} in "
            f"magnitude, too large to be coordinates, on data line(s) {_rows(huge, lines)}"
        )
    return values


def _without_digit_grouping(text: pd.Series, delimiter: str | None) -> pd.Series:
    """Numbers written with decimal commas (``650053,80``, ``650.053,80``) or thousands separators (``650,053.80``)
    in plain form.

    Decided per column: commas that can only be decimal commas, or only
    thousands separators, are read as such; where every comma could be either
    (``1,234``), a semicolon- or tab-separated file is taken to use decimal
    commas and a comma-separated one (quoted fields) thousands separators.
    A column mixing both is left alone and reported as non-numeric.
    """
    comma = text.str.contains(",", regex=False)
    if not comma.any():
        return text
    dots = text.str.fullmatch(DOTS_DECIMAL_COMMA)
    decimal = text.str.fullmatch(DECIMAL_COMMA) | dots
    grouped = text.str.fullmatch(THOUSANDS)
    if (comma & ~decimal & ~grouped).any():
        return text
    decimal_only = (comma & decimal & ~grouped).any()
    grouped_only = (comma & grouped & ~decimal).any()
    if decimal_only and grouped_only:
        return text
    use_decimal = decimal_only or (not grouped_only and delimiter not in (",", None))
    if use_decimal and dots.any():  # dots group thousands in this column, in whole numbers too (7.400.517)
        dots |= ~comma & text.str.fullmatch(r"[+-]?\d{1,3}(?:\.\d{3})+")
        text = text.where(~dots, text.str.replace(".", "", regex=False))
    return text.str.replace(",", "." if use_decimal else "", regex=False)


def _refuse_degrees(x: np.ndarray, y: np.ndarray, source: str) -> None:
    """Refuse longitudes and latitudes: BGM needs lengths (metres or feet) on a projected grid.

    Holes in degrees span a few thousandths of a unit, so nearly all of them
    would be merged as duplicates and a meaningless model built from the rest.
    """
    spread = max(float(np.ptp(x)), float(np.ptp(y)))
    if not 0 < spread < MAX_DEGREES_SPREAD:
        return
    for lon, lat in ((x, y), (y, x)):
        if np.abs(lon).max() <= 180 and np.abs(lat).max() <= 90:
            raise BGMInputError(
                f"x and y of {source or 'the input'} look like degrees of longitude and latitude "
                f"(x {x.min():.6g} to {x.max():.6g}, y {y.min():.6g} to {y.max():.6g}: all holes within "
                f"{spread:.3g} units); BGM needs projected coordinates in metres or feet (a mine grid or UTM)"
            )


def _check_spacing(holes: Blastholes, given: bool) -> None:
    """Refuse a hole spacing no blasthole pattern has (outside :data:`PLAUSIBLE_SPACING_M`): a unit mistake.

    A table in millimetres reads as benches 10,000 feet high with holes 5,500
    feet apart. With ``--units`` given (``given``) the user vouches for the
    unit, and the odd spacing is only warned about.
    """
    low, high = PLAUSIBLE_SPACING_M
    spacing = holes.hole_spacing_m
    if low <= spacing <= high:
        return
    unit = holes.frame.length_unit
    said = f"{holes.frame.length_to_input(spacing):.4g} {unit} ({spacing:.4g} m)" if unit != "m" else f"{spacing:.4g} m"
    msg = (
        f"the median hole spacing of {holes.source or 'the input'} is {said}, where blastholes are {low:g} "
        f"to {high:g} m apart: the table's length unit is likely neither metres nor feet "
        f"(millimetres, centimetres, kilometres?); convert it to metres or feet"
    )
    if given:
        warnings.warn(msg, BGMWarning, stacklevel=3)
    else:
        raise BGMInputError(f"{msg}, or give --units m or ft if it is one")


def unit_name(length_unit: str) -> str:
    """``"m"`` or ``"ft"`` for a length unit as a user writes it (``metres``, ``Feet``...).

    Raises
    ------
    BGMInputError
        For any other unit.
    """
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
    unit = str(length_unit).strip().lower()
    if unit not in aliases:
        raise BGMInputError(f"unknown length unit {length_unit!r}: use m or ft")
    return aliases[unit]


def _guess_unit(bench_height: float, length_unit: str | None, spacing=lambda: float("nan")) -> str:
    """The input's length unit: ``length_unit``, else feet for benches of 25 units or more.

    Unless their holes would then lie closer than :data:`MIN_HOLE_SPACING_M` (``spacing()``, input units):
    30-unit benches with holes 5.5 units apart are metres (a 9 m bench drilled every 1.7 m is no pattern).
    """
    if length_unit:
        return unit_name(length_unit)
    if np.isfinite(bench_height) and bench_height >= 25.0:
        apart_m = spacing() * FEET_TO_METRES
        if apart_m < MIN_HOLE_SPACING_M:
            warnings.warn(
                f"benches {bench_height:g} units high would be feet, but their holes would then lie "
                f"{apart_m:.2g} m apart: read as metres (give --units ft if they are feet)",
                BGMWarning,
                stacklevel=3,
            )
            return "m"
        return "ft"
    return "m"


def detect_benches(
    z: np.ndarray, bench_height: float | None = None, xy: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Group sample elevations into benches, at the levels the holes were drilled.

    Holes of one bench scatter by a few units around its level; a few sit far
    off any level. Elevations are split into clusters at gaps wider than a
    third of the widest gap; clusters holding at least 1% of the holes (or 10
    holes) are benches, at their median elevation (shown to 0.1 unit when the
    holes scatter). Benches need not be evenly spaced (10 m, then 15 m): levels
    are taken as measured, and put on a regular ladder only where the medians
    themselves say the benches are regular (see :func:`_bench_levels`). A
    cluster too thick for one bench is split into the benches it holds (see
    :func:`_split_hidden_benches`). Groups of holes far above or below the
    benches (see :func:`_far_off_elevations`) are no benches: the benches are
    found without them, and they are off-bench holes.

    Parameters
    ----------
    z : (n,) float
        Elevations, input units.
    bench_height : float, optional
        Known bench height (input units). Where the collars form benches by
        themselves their levels stand, and a height more than
        :data:`BENCH_HEIGHT_TOLERANCE` off the median gap between them is
        refused; where they spread continuously, a regular ladder of that
        height groups them.
    xy : (n, 2) float, optional
        Hole positions (input units), to tell one bench from elevations spread
        continuously (which is refused).

    Returns
    -------
    levels : (b,) float
        Bench levels, descending.
    bench : (n,) int
        Bench index of each hole (-1 for off-bench holes).
    height : float
        Bench height: the median distance between successive levels (nan for a
        single bench).
    off : (n,) bool
        Holes farther than ``OFF_BENCH_FRACTION`` of the distance to the next
        level from their nearest level.

    Raises
    ------
    BGMInputError
        When z does not form benches: one elevation cluster far thicker than
        the hole spacing, or more than ``MAX_OFF_BENCH_SHARE`` of the holes
        between levels or far off the benches; or when ``bench_height``
        disagrees with the levels.
    """
    z = np.asarray(z, float)
    if bench_height is not None and not (np.isfinite(bench_height) and bench_height > 0):
        raise BGMInputError(f"bench height must be a positive number, got {bench_height}")
    zs = np.sort(z)
    if zs[-1] == zs[0]:
        return np.array([zs[0]]), np.zeros(len(z), int), np.nan, np.zeros(len(z), bool)
    min_count = min_bench_holes(len(z))
    clusters = _split_hidden_benches(_bench_clusters(zs, min_count), min_count, z, xy)
    apart = _far_off_holes(z, zs, clusters, min_count, bench_height, xy)
    if apart.any():
        return _benches_without(z, apart, bench_height, xy)
    big = [c for c in clusters if len(c) >= min_count]
    if bench_height is None:
        _refuse_tiny_levels(zs, clusters)
        if len(big) < 2:
            small = [c for c in clusters if 3 <= len(c) < min_count]
            sparse = _sparse_benches_beside_one(z, big, small, xy)
            return _on_levels(z, sparse, None, xy) if sparse is not None else _single_or_dense(z, zs, xy, big, small)
    levels = _levels_of(z, zs, big, [c for c in clusters if 3 <= len(c) < min_count], bench_height)
    return _on_levels(z, levels, bench_height, xy)


def min_bench_holes(n_holes: int) -> int:
    """Holes a cluster of elevations needs to be a bench on its own, among ``n_holes``: 1% of them, or 10.

    Fewer holes on a level are a bench only beside benches that measure a bench height (see
    :func:`_bench_levels`), or beside a single bench as :func:`_sparse_benches_beside_one` says.
    """
    return min(max(10, int(0.01 * n_holes)), max(3, n_holes // 4))


def _sparse_benches_beside_one(
    z: np.ndarray, big: list[np.ndarray], small: list[np.ndarray], xy: np.ndarray | None
) -> np.ndarray | None:
    """The levels of one bench and the sparsely drilled benches beside it (ascending), or None when there are none.

    A bench of 40 holes and 8 holes 40 m below it, on the same pattern, was refused as elevations "spread
    continuously ... with no gap between benches": 8 holes are under the 10 a level needs to be a bench on its
    own (:func:`min_bench_holes`), and beside one bench no bench height says how far a bench lies (see
    :func:`_bench_levels`). Such a group is a bench opened or sampled sparsely when it sits on a level of its
    own (no thicker than a bench may be, :data:`MAX_BENCH_THICKNESS_SPACINGS` hole spacings), farther from the
    bench than the bench's holes may spread, and its holes are drilled on the bench's pattern (their spacing
    within :data:`SPARSE_BENCH_SPACING_RATIO` of it). Only tables read otherwise as elevations spread
    continuously are read so: a few holes within a bench's spread stay off-bench holes of that bench.
    """
    if xy is None or len(big) != 1 or not small:
        return None
    on = (z >= big[0][0]) & (z <= big[0][-1])
    spacing = _collar_spacing(xy[on])
    thickness = float(np.percentile(z, 95) - np.percentile(z, 5))
    if not spacing > 0 or thickness <= MAX_BENCH_THICKNESS_SPACINGS * spacing:
        return None  # one bench reads as it did (:func:`_single_bench`)
    reach = MAX_BENCH_THICKNESS_SPACINGS * spacing
    levels = [_level(big[0])]
    for c in small:
        holes = (z >= c[0]) & (z <= c[-1])
        own = _collar_spacing(xy[holes])
        if (
            np.ptp(c) > reach
            or abs(float(np.median(c)) - float(np.median(big[0]))) <= reach
            or not (own > 0 and 1 / SPARSE_BENCH_SPACING_RATIO <= own / spacing <= SPARSE_BENCH_SPACING_RATIO)
        ):
            return None  # not a bench on the pattern: refused as before, with what to do
        levels.append(_level(c))
    return np.sort(np.array(levels))


def sparse_bench_note(bench: np.ndarray, levels: np.ndarray) -> str | None:
    """What to say of benches read with fewer holes than a bench needs on its own, beside a single full one.

    Said whenever :func:`_sparse_benches_beside_one` read them (so never of a table read otherwise):
    the geologist learns that those few holes carry a whole bench of the model.

    Parameters
    ----------
    bench : (n,) int
        Each hole's bench (-1 off the benches).
    levels : (b,) float
        The benches' levels (input units), as :func:`detect_benches` returns them.

    Returns
    -------
    str or None
        The warning, or None when no bench is so sparse.
    """
    counts = np.bincount(bench[bench >= 0], minlength=len(levels))
    needed = min_bench_holes(int(np.sum(bench >= 0)))
    sparse = [k for k in range(len(levels)) if counts[k] < needed]
    if len(levels) < 2 or int(np.sum(counts >= needed)) != 1 or not sparse:
        return None
    said = ", ".join(f"{counts[k]} at z {levels[k]:g}" for k in sparse)
    return (
        f"{'a bench' if len(sparse) == 1 else 'benches'} of few holes read beside the bench at z "
        f"{levels[int(np.argmax(counts))]:g} ({int(counts.max())} holes): {said}, on its hole pattern; "
        "the model takes each as a whole bench (drop those rows if they are no bench)"
    )


def _bench_clusters(zs: np.ndarray, min_count: int) -> list[np.ndarray]:
    """Sorted elevations split into clusters at the gaps between benches, ascending (see :func:`_elevation_clusters`).

    A few holes far off the rest (a typo: RL 0, -9999, 6849.3 for 684.93) made the widest gap, next to which no gap
    between benches was wide: while only one cluster holds ``min_count`` holes, it is split on its own gaps (the
    few stay clusters of their own, off-bench holes).
    """
    clusters = _elevation_clusters(zs)
    big = [c for c in clusters if len(c) >= min_count]
    while len(big) == 1 and len(clusters) > 1:
        i = next(i for i, c in enumerate(clusters) if len(c) >= min_count)
        inner = _elevation_clusters(clusters[i])
        if len(inner) == 1:
            break
        clusters = [*clusters[:i], *inner, *clusters[i + 1 :]]
        big = [c for c in clusters if len(c) >= min_count]
    return clusters


def _far_off_holes(
    z: np.ndarray,
    zs: np.ndarray,
    clusters: list[np.ndarray],
    min_count: int,
    bench_height: float | None,
    xy: np.ndarray | None,
) -> np.ndarray:
    """The holes of the groups far above or below the benches (see :func:`_far_off_elevations`), (n,) bool.

    ``zs`` is ``z`` sorted, ``clusters`` its clusters; ``xy`` measures a cluster's hole spacing (none without).
    """
    spacing = None if xy is None else (lambda part: median_hole_spacing(xy[(z >= part[0]) & (z <= part[-1])]))
    return np.isin(z, _far_off_elevations(clusters, min_count, zs[len(zs) // 2], bench_height, spacing))


def _benches_without(
    z: np.ndarray, apart: np.ndarray, bench_height: float | None, xy: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """:func:`detect_benches` of the holes not ``apart``, those apart off-bench; refused when they are too many.

    Many holes far off (300 of the demo's 11,211 at RL 0) are a cluster of their own, whose gap hid every gap
    between the benches: all seven were read as one at 664.8 m. The benches are found without them.
    """
    if apart.mean() > MAX_OFF_BENCH_SHARE:
        # Without a bench height the far-off group was judged by the hole spacing, or against the others' own
        # height: one given says how far apart the benches are drilled, and keeps a real bench that far off.
        hint = "; if they are a bench of their own, give --bench-height" if bench_height is None else ""
        raise BGMInputError(
            f"z does not form benches: {int(apart.sum())} of {len(z)} holes ({apart.mean():.0%}) have elevations "
            f"far off the benches (at {_far_values(z[apart])}; the others from {np.min(z[~apart]):g} to "
            f"{np.max(z[~apart]):g}): too many to leave out as missing (written as 0 or -9999) "
            f"or mistyped; fill in their elevations or drop those rows{hint}"
        )
    levels, found, height, off = detect_benches(z[~apart], bench_height, None if xy is None else xy[~apart])
    bench, off_all = np.full(len(z), -1), apart.copy()
    bench[~apart], off_all[~apart] = found, off
    return levels, bench, height, off_all


def _single_or_dense(
    z: np.ndarray, zs: np.ndarray, xy: np.ndarray | None, big: list[np.ndarray], small: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """One bench (:func:`_single_bench`); where that is refused as too thick, the benches of its dense bands
    (:func:`_dense_levels`), if it has two or more. A bench of two sub-levels (685 and 687 m) stays one bench."""
    try:
        return _single_bench(z, xy, small if big else [])
    except BGMInputError as refused:
        levels = _dense_levels(zs, min_bench_holes(len(z)), z, xy)
        if levels is not None:
            return _on_levels(z, levels, None, xy)
        height = _repeating_height(zs)
        if height is None:
            raise
        said = f"{float(f'{height:.2g}'):g}"  # two figures, never as an exponent (150, not 1.5e+02)
        raise BGMInputError(
            f"{refused}; but how densely the holes lie repeats about every {said} units of z: if the benches "
            f"are that far apart and their holes scatter into each other, give their height, as --bench-height {said}"
        ) from None


def _repeating_height(zs: np.ndarray) -> float | None:
    """The step at which the elevations' density repeats, where it clearly does; None otherwise.

    Benches whose holes scatter into each other (2 m on 10 m benches) leave no sparse band between them, but their
    elevations still pile up every bench height: the histogram's autocorrelation (bins of a thousandth of the
    range) peaks there at :data:`REPEAT_CORRELATION` or more of its value at no lag. Elevations spread evenly peak
    nowhere near it (a few hundredths). A step under :data:`MIN_BENCH_GAP` units is no bench height. Over six
    benches it is good to about 1% (10.0-10.2 for 10 m benches), so it is said to two figures.
    """
    counts, edges = np.histogram(zs, bins=1000)
    step = float(edges[1] - edges[0])
    c = counts - counts.mean()
    r = np.fft.irfft(np.abs(np.fft.rfft(c, 2 * len(c))) ** 2)[: len(c)]
    if not r[0] > 0:
        return None
    r = r / r[0]
    below = np.flatnonzero(r < 0)  # past the central peak
    if not len(below):
        return None
    lag = int(below[0] + np.argmax(r[below[0] : len(r) // 2]))
    if r[lag] < REPEAT_CORRELATION or lag * step < MIN_BENCH_GAP:
        return None
    # The lag is a bin's width coarse and pulled by the benches' envelope: refined to the step at which the
    # elevations' phases agree best (the Rayleigh statistic), within 10% of it.
    # One candidate at a time over at most REPEAT_SAMPLE elevations (every k-th of the sorted ones): all 201 at
    # once over a million holes held 3 GB.
    z = (zs - zs[0])[:: max(1, len(zs) // REPEAT_SAMPLE)]
    steps = lag * step * np.linspace(0.9, 1.1, 201)
    agreement = [abs(np.exp(2j * np.pi * z / s).mean()) for s in steps]
    return float(steps[int(np.argmax(agreement))])


def _dense_levels(zs: np.ndarray, min_count: int, z: np.ndarray, xy: np.ndarray | None) -> np.ndarray | None:
    """The bench levels (ascending) of elevations that scatter so far that a few holes bridge every gap, or None.

    Benches are the dense bands of the elevations: a hole where holes are :data:`SPARSE_ELEVATION_FACTOR` times
    sparser than at the median hole (the span of its ``k`` nearest elevations that many times the median span)
    lies between benches; the rest are clustered as :func:`detect_benches` clusters any elevations. Two or more
    benches of ``min_count`` holes are the levels (each hole is then put on its nearest, those far from every
    level left out and said). Elevations spread evenly have no sparse band, and stay refused.
    """
    n, k = len(zs), max(5, len(zs) // 1000)
    if n <= 2 * k:
        return None
    # The span of the 2k elevations around each hole (fewer at either end, scaled up to 2k: an end's tail is sparse too).
    lo, hi = np.maximum(np.arange(n) - k, 0), np.minimum(np.arange(n) + k, n - 1)
    span = (zs[hi] - zs[lo]) * (2 * k) / (hi - lo)
    dense = span <= SPARSE_ELEVATION_FACTOR * max(float(np.median(span)), 1e-12)
    if dense.all():
        return None
    clusters = _split_hidden_benches(_bench_clusters(zs[dense], min_count), min_count, z, xy)
    big = [c for c in clusters if len(c) >= min_count]
    if len(big) < 2:
        return None
    # A bench drilled sparsely (opened at the pit's floor: a few dozen holes) is as sparse as the ground between two
    # benches; the holes far from every dense bench's level are clustered again, and a cluster far enough from every
    # bench is one too (:func:`_bench_levels`).
    levels = _bench_levels(big, [])
    height = typical_bench_height(levels)
    far = np.abs(zs[:, None] - levels[None, :]).min(axis=1) > OFF_BENCH_FRACTION * height
    small = [c for c in _elevation_clusters(zs[far]) if len(c) >= 3] if far.sum() >= 3 else []
    # Each about its densest slice: the tails of the dense bench beside it are in its cluster too.
    small = [c[np.abs(c - _densest_elevation(c, height)) <= OFF_BENCH_FRACTION * height] for c in small]
    return _bench_levels(big, [c for c in small if len(c) >= 3])


def _refuse_tiny_levels(zs: np.ndarray, clusters: list[np.ndarray]) -> None:
    """Refuse elevations on several levels of fewer than 3 holes each: no bench BGM can model."""
    if len(clusters) >= 2 and max(len(c) for c in clusters) < 3:
        raise BGMInputError(
            f"z falls on {len(clusters)} levels ({zs[-1]:g} to {zs[0]:g}) of at most "
            f"{max(len(c) for c in clusters)} hole(s) each; BGM needs at least 3 holes a bench"
        )


def _levels_of(
    z: np.ndarray, zs: np.ndarray, big: list[np.ndarray], small: list[np.ndarray], bench_height: float | None
) -> np.ndarray:
    """The bench levels (ascending): the clusters' (``big`` ones, and ``small`` ones far enough from them, see
    :func:`_bench_levels`), or a ladder of the given height over one continuous spread of elevations."""
    if bench_height is None or len(big) >= 2:
        # The collars form benches by themselves: their levels stand, and a
        # given height only has to agree with them (a grid of it from the top
        # would move every level the height is off, and drop holes).
        levels = _bench_levels(big, small)
        if bench_height is not None:
            _refuse_disagreeing_height(levels, float(bench_height))
        return levels
    # One continuous spread of elevations: the given height groups it into benches.
    if np.ptp(zs) / bench_height > MAX_BENCHES:
        raise BGMInputError(
            f"bench height {bench_height:g} would cut the elevations ({zs[0]:g} to {zs[-1]:g}) into more "
            f"than {MAX_BENCHES} benches; give the bench height in the input's units"
        )
    return _ladder(zs, _densest_elevation(z, float(bench_height)), float(bench_height))


def _on_levels(
    z: np.ndarray, levels: np.ndarray, bench_height: float | None, xy: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Each hole on its level (see :func:`detect_benches`' returns); refused when too many lie between levels."""
    levels, bench, off = _assign_levels(z, levels)
    if bench_height is not None and xy is not None:
        _refuse_merged_benches(z, bench, levels, xy, float(bench_height))
    if off.mean() > MAX_OFF_BENCH_SHARE:
        raise BGMInputError(
            f"z does not form benches: {int(off.sum())} of {len(z)} holes lie between the bench levels found "
            f"({', '.join(f'{v:g}' for v in levels[:8])}{'...' if len(levels) > 8 else ''}); "
            "BGM needs samples grouped by bench"
        )
    height = float(bench_height) if bench_height is not None else typical_bench_height(levels)
    return levels, bench, (height if len(levels) >= 2 else np.nan), off


def _split_hidden_benches(
    clusters: list[np.ndarray], min_count: int, z: np.ndarray, xy: np.ndarray | None
) -> list[np.ndarray]:
    """Split clusters too thick for one bench into the benches they hold.

    Benches are cut at gaps a third as wide as the widest: a sump 30 or 80 m below benches 10 m apart made the
    widest gap, and the five benches above it were read as one (or refused, their holes between the two levels).
    A bench's holes (5th to 95th percentile) are thinner than the gap to the next bench, and than
    :data:`MAX_BENCH_THICKNESS_SPACINGS` hole spacings; a cluster thicker than either is split, where it splits
    into two or more clusters of at least ``min_count`` holes. Sub-levels of one bench (685 and 687 m, the next
    bench 10 m down) are thinner than both: they stay one bench.

    Parameters
    ----------
    clusters : list of (k,) float
        Sorted elevations split into clusters (see :func:`_elevation_clusters`), ascending.
    min_count : int
        Holes a cluster needs to be a bench on its own.
    z : (n,) float
        Every hole's elevation, to find a cluster's holes in ``xy``.
    xy : (n, 2) float, optional
        Hole positions; without them only the gaps tell.

    Returns
    -------
    list of (k,) float
        The clusters, those holding several benches split into them.
    """
    out: list[np.ndarray] = []
    for i, c in enumerate(clusters):
        gaps = [clusters[i + 1][0] - c[-1]] if i + 1 < len(clusters) else []
        gaps += [c[0] - clusters[i - 1][-1]] if i > 0 else []
        thick = float(np.percentile(c, 95) - np.percentile(c, 5)) if len(c) >= min_count else 0.0
        inner = _elevation_clusters(c) if thick > 0 else [c]
        pieces = [p for p in inner if len(p) >= min_count]
        too_thick = bool(gaps) and thick > min(gaps)
        if len(pieces) >= 2 and not too_thick and xy is not None:
            # The hole spacing on each piece: sub-levels of one bench sample the same collars.
            spacing = np.median([_collar_spacing(xy[(z >= p[0]) & (z <= p[-1])]) for p in pieces])
            too_thick = thick > MAX_BENCH_THICKNESS_SPACINGS * spacing
        if len(pieces) >= 2 and too_thick:
            out.extend(_split_hidden_benches(inner, min_count, z, xy))
        else:
            out.append(c)
    return out


def _far_off_elevations(
    clusters: list[np.ndarray],
    min_count: int,
    median: float,
    bench_height: float | None,
    spacing: Callable[[np.ndarray], float] | None = None,
) -> np.ndarray:
    """Elevations of the groups of holes above or below the benches that are no bench: missing (0, -9999) or mistyped.

    Walking up and down from the median elevation's cluster, everything beyond a step of more than
    :data:`FAR_LEVEL_BENCHES` bench heights between neighbouring clusters is set apart; so is a cluster at
    either end whose holes all sit exactly on one value of :data:`MISSING_ELEVATIONS` (0, -9999) more than
    :data:`MISSING_ELEVATION_BENCHES` bench heights from every other bench (Kennecott's floor is 5.4 bench
    heights above 0). The bench height is the one given, else the median step between the benches with the
    widest left out. Real benches lie a bench height or a few apart, within the pit's span: a sump of holes
    one or several benches below the pit floor is a bench and stays (whatever its size), as does a level at
    RL 0 next to the others. A group more than ten bench heights from the others (a second pit in the same
    table) is set apart too: its holes are then named in a warning, or the table refused when they are many.
    With no bench height to measure by (one bench and a group at 0, two clusters in all), the group at 0 or
    -9999 is judged by the bench's hole spacing (see :func:`_missing_beside_one_bench`), and so is a small group
    at any other elevation (see :func:`_far_beside_one_bench`).

    Parameters
    ----------
    clusters : list of (k,) float
        Sorted elevations split into clusters (see :func:`_elevation_clusters`), ascending.
    min_count : int
        Holes a cluster needs to be a bench on its own.
    median : float
        The median elevation: its bench is never set apart.
    bench_height : float, optional
        Given bench height; else the median distance between the other benches.
    spacing : callable, optional
        A cluster's elevations -> the hole spacing of its holes (input units); without it, one bench and a
        group at 0 read as two benches.

    Returns
    -------
    (m,) float
        The elevations set apart (empty when none).
    """
    # One huge gap (0 to 625 m) hides the gaps between benches: split the clusters down to the benches to measure.
    parts: list[np.ndarray] = []
    todo = list(clusters)
    while todo:
        c = todo.pop(0)
        inner = _elevation_clusters(c) if len(c) >= min_count and np.ptp(c) > 0 else [c]
        if sum(len(i) >= min_count for i in inner) >= 2:
            todo[:0] = inner
        else:
            parts.append(c)
    apart: list[np.ndarray] = []
    while True:
        centres = np.array([float(np.median(p)) for p in parts])
        gaps = np.diff(centres[[len(p) >= min_count for p in parts]])
        if bench_height is None and len(gaps) < 2:
            if spacing is not None:
                apart += _missing_beside_one_bench(parts, min_count, spacing)
                apart += _far_beside_one_bench(parts, median, spacing)
            break
        # The widest gap left out: it may be the one to the group being judged (two benches, 300 holes at 0).
        height = bench_height or float(np.median(np.sort(gaps)[:-1]))
        home = next(k for k, p in enumerate(parts) if p[0] <= median <= p[-1])  # the parts hold every elevation
        steps = np.diff(centres) > FAR_LEVEL_BENCHES * height
        low = max([k + 1 for k in np.flatnonzero(steps) if k < home], default=0)
        high = min([k for k in np.flatnonzero(steps) if k >= home], default=len(parts) - 1)
        for k in (low, high):  # a group at exactly 0 or -9999 a few benches off
            p = parts[k]
            others = [centres[i] for i in range(low, high + 1) if i != k and len(parts[i]) >= min_count]
            missing = p[0] == p[-1] and float(p[0]) in MISSING_ELEVATIONS and k != home and bool(others)
            if missing and np.abs(np.array(others) - centres[k]).min() > MISSING_ELEVATION_BENCHES * height:
                low, high = (low + 1, high) if k == low else (low, high - 1)
                break
        if low == 0 and high == len(parts) - 1:
            break
        apart += parts[:low] + parts[high + 1 :]
        parts = parts[low : high + 1]
    return np.concatenate(apart) if apart else np.array([])


def _missing_beside_one_bench(
    parts: list[np.ndarray], min_count: int, spacing: Callable[[np.ndarray], float]
) -> list[np.ndarray]:
    """Groups of holes all at 0 or -9999 beside the only bench and far from it (``[]`` when there are none).

    One bench and 300 holes whose elevation was written as 0 where it was missing read as two benches 685
    units apart, with only a warning on the unit, and the model was built between a real bench and a made-up
    one; 5 such holes among a bench's 40 had the table refused as elevations "spread continuously". With one
    bench there is no bench height to measure the gap by, but its drilling pattern says how high it is (see
    :data:`MISSING_ELEVATION_SPACINGS`): a group exactly on a value of :data:`MISSING_ELEVATIONS` more than
    that many of the bench's hole spacings from it is no bench. A real bench at RL 0 beside another (a local
    datum: 0 and -10) lies a bench height from it, a few spacings, and stays; so does any pair of benches when
    neither sits exactly on such a value. When both do, the smaller is judged (the larger is the bench).

    Parameters
    ----------
    parts : list of (k,) float
        Sorted elevations, one cluster per bench (ascending).
    min_count : int
        Holes a cluster needs to be a bench on its own: one or two such clusters make the bench and the group.
    spacing : callable
        A cluster's elevations -> the hole spacing of its holes (input units, NaN when not measurable).

    Returns
    -------
    list of (k,) float
        The groups' elevations, or nothing.
    """
    on_code = [len(p) > 0 and p[0] == p[-1] and float(p[0]) in MISSING_ELEVATIONS for p in parts]
    big = [k for k, p in enumerate(parts) if len(p) >= min_count]
    benches = [k for k in big if not on_code[k]]
    if not benches and big:  # every large group on a code (a plan at 0, a group at -9999): the largest is the bench
        benches = [max(big, key=lambda k: len(parts[k]))]
    groups = [k for k in range(len(parts)) if on_code[k] and k not in benches]
    if len(benches) != 1 or not groups:
        return []
    bench = parts[benches[0]]
    holes_apart = spacing(bench)
    if not (np.isfinite(holes_apart) and holes_apart > 0):
        return []
    reach = MISSING_ELEVATION_SPACINGS * holes_apart
    return [parts[k] for k in groups if abs(float(np.median(bench)) - float(parts[k][0])) > reach]


def _far_beside_one_bench(
    parts: list[np.ndarray], median: float, spacing: Callable[[np.ndarray], float]
) -> list[np.ndarray]:
    """Small groups of holes at any elevation far above or below the bench (or two) beside them (``[]`` when none).

    One bench at RL 1500 and 6 holes typed at RL 150 or 15000 read as two benches 1350 units apart (with a
    warning on the unit only), or had the table refused as elevations "spread continuously"; two benches and
    such a group read as three. Beside several benches their own gaps measure how far a group is (see
    :func:`_far_off_elevations`); beside one or two there is no bench height to trust (the one gap may be the
    group's), but the bench's drilling pattern says how high a bench is. Walking up and down from the median
    elevation's bench, the groups beyond a step of more than :data:`FAR_GROUP_SPACINGS` of its hole spacings
    (ten benches of 3.3 spacings) are no bench when they hold at most :data:`MAX_OFF_BENCH_SHARE` of the holes
    on their side: a bench a few benches below is a bench height or a few away, and a larger group far off (two
    benches exported from a deep pit) stays the bench it may be.

    Parameters
    ----------
    parts : list of (k,) float
        Sorted elevations, one cluster per bench or group (ascending).
    median : float
        The median elevation: its bench is never set apart, and its hole spacing measures the reach.
    spacing : callable
        A cluster's elevations -> the hole spacing of its holes (input units, NaN when not measurable).

    Returns
    -------
    list of (k,) float
        The groups' elevations, or nothing.
    """
    home = next(k for k, p in enumerate(parts) if p[0] <= median <= p[-1])  # the parts hold every elevation
    holes_apart = spacing(parts[home])
    if not (np.isfinite(holes_apart) and holes_apart > 0):
        return []
    centres = np.array([float(np.median(p)) for p in parts])
    steps = np.flatnonzero(np.diff(centres) > FAR_GROUP_SPACINGS * holes_apart)
    low = max([k + 1 for k in steps if k < home], default=0)
    high = min([k for k in steps if k >= home], default=len(parts) - 1)
    n_holes = sum(len(p) for p in parts)
    sides = [parts[:low], parts[high + 1 :]]
    return [p for side in sides if sum(len(p) for p in side) <= MAX_OFF_BENCH_SHARE * n_holes for p in side]


def _far_values(z: np.ndarray) -> str:
    """The elevations of holes set apart, shortened: ``0``, ``-9999 and 6849.3``, ``-3.2 to 4.1``."""
    values = np.unique(z)
    return listing([f"{v:g}" for v in values], 4) if len(values) <= 6 else f"{values[0]:g} to {values[-1]:g}"


def typical_bench_height(levels: np.ndarray) -> float:
    """The step between successive bench levels, counting a gap of whole benches not drilled as that many steps.

    The median gap between levels, unless it matches no gap while one gap divides every other into whole
    steps: two benches 10 m apart and a bench 40 m below them (three benches between not drilled) have gaps
    10 and 40, whose median, 25, is no bench height of theirs (and read as a feet table's); 10 divides both.
    Irregular benches (10 m, then 15 m) keep the median, as do regular ones.

    Parameters
    ----------
    levels : (b,) float
        The bench levels, in either order (input units).

    Returns
    -------
    float
        The bench height (input units; NaN for fewer than two levels).
    """
    gaps = np.abs(np.diff(np.asarray(levels, float)))
    if not len(gaps):
        return float("nan")
    median = float(np.median(gaps))
    tolerance = BENCH_HEIGHT_TOLERANCE
    if np.any(np.abs(gaps - median) <= tolerance * gaps):
        return median
    for step in np.sort(gaps):
        whole = np.round(gaps / step)
        if step > 0 and np.all(np.abs(gaps - whole * step) <= tolerance * whole * step):
            return float(np.median(gaps / whole))
    return median


def _refuse_disagreeing_height(levels: np.ndarray, bench_height: float) -> None:
    """Refuse a given bench height other than the one between the collars' own levels (ascending ``levels``).

    The measured height is :func:`typical_bench_height` of the levels (a gap of
    benches not drilled counting as that many steps); it agrees within :data:`BENCH_HEIGHT_TOLERANCE` of the given height.
    """
    measured = typical_bench_height(levels)
    if abs(measured - bench_height) <= BENCH_HEIGHT_TOLERANCE * bench_height:
        return
    # A height several times the levels' gap would merge benches: say so, as _refuse_merged_benches does.
    merges = bench_height > 1.5 * measured
    merged = bench_height / measured
    count = f"all {len(levels)}" if merged >= len(levels) else f"{merged:.0f}"
    grouping = f", so it would put the holes of {count} levels on one bench" if merges else ""
    raise BGMInputError(
        f"a bench height of {bench_height:g} disagrees with the holes' own benches: their collars lie on "
        f"{len(levels)} levels ({levels[-1]:g} to {levels[0]:g}) {measured:.4g} apart{grouping}; "
        f"leave --bench-height out to use the levels as drilled, or give {measured:.4g}"
    )


def _elevation_clusters(zs: np.ndarray) -> list[np.ndarray]:
    """Sorted elevations split at the gaps between benches."""
    gaps = np.diff(zs)
    if not (gaps > 0).any():  # one exact level (a bench's RL): nothing to split, and no typical step to measure
        return [zs]
    # A gap between benches is wide next to the widest gap and far wider than
    # the typical step between sorted elevations (which rounding can make
    # all equal on a single bench).
    typical = np.median(gaps[gaps > 0])
    cut = (gaps > gaps.max() / 3.0) & (gaps > 20.0 * typical)
    # Benches given at exact levels (z is the bench RL, no scatter): the only
    # positive gaps are then the bench gaps themselves, so ``typical`` is a
    # bench gap and nothing was cut. A wide gap of at least MIN_BENCH_GAP units
    # is a bench break too; rounding steps are smaller, and splits inside a
    # scattered bench are merged back just below.
    cut |= (gaps > gaps.max() / 3.0) & (gaps >= MIN_BENCH_GAP)
    labels = _merge_scatter_splits(zs, np.concatenate([[0], np.cumsum(cut)]))
    return np.split(zs, np.flatnonzero(np.diff(labels)) + 1)


def _bench_levels(big: list[np.ndarray], small: list[np.ndarray]) -> np.ndarray:
    """Levels of the benches (ascending): each at its measured level, or on a ladder where one fits.

    A bench's measured level is the median elevation of its holes. When
    three or more benches lie on a regular ladder to within three standard
    errors of their medians, the differences are sampling noise and the
    ladder's rungs are the levels (regular benches read as 685, 675, 665, not
    685.0, 675.1, 664.9); otherwise (10 m, then 15 m) the medians are. A
    cluster too small to be a bench on its own (a bench being opened, or
    sparsely sampled) is one when it lies at least ``1 - OFF_BENCH_FRACTION``
    of a typical bench height from every bench; nearer, it is stray holes.
    """
    centres = np.array([float(np.median(c)) for c in big])
    height = typical_bench_height(centres)
    levels = np.array([_level(c) for c in big])
    k = np.round((centres - centres[0]) / height)
    if len(big) >= 3 and len(np.unique(k)) == len(k):
        noise = np.array([1.2533 * np.std(c) / np.sqrt(len(c)) for c in big])  # standard error of a median
        slope, z0 = np.polyfit(k, centres, 1, w=1 / (noise + 1e-9 * height))
        rungs = z0 + k * slope
        if np.all(np.abs(centres - rungs) <= 3 * noise + 1e-9 * height):
            levels = np.where([np.ptp(c) <= 0.1 for c in big], centres, np.round(rungs, 1 if slope >= 1 else 6))
    extra = [_level(c) for c in small if np.abs(centres - np.median(c)).min() >= (1 - OFF_BENCH_FRACTION) * height]
    return np.sort(np.concatenate([levels, extra]))


def _level(members: np.ndarray) -> float:
    """A cluster's elevation: its median, shown to 0.1 unit unless the holes sit at one exact level."""
    m = float(np.median(members))
    return m if np.ptp(members) <= 0.1 else round(m, 1)


def _densest_elevation(z: np.ndarray, height: float) -> float:
    """Median elevation of the densest slice of ``height / 10``: a level of a known-height ladder."""
    bins = np.arange(z.min(), z.max() + height / 10, height / 10)
    if len(bins) < 2:
        bins = np.array([z.min() - 0.5, z.max() + 0.5])
    hist, edges = np.histogram(z, bins=bins)
    k = int(np.argmax(hist))
    return float(np.median(z[(z >= edges[k]) & (z <= edges[k + 1])]))


def _ladder(z: np.ndarray, anchor: float, height: float) -> np.ndarray:
    """Every rung ``anchor + k height`` from below the lowest to above the highest elevation (ascending)."""
    anchor = round(anchor, 1) if height >= 1 else anchor
    k = np.arange(np.floor((z.min() - anchor) / height) - 1, np.ceil((z.max() - anchor) / height) + 2)
    return anchor + k * height


def _assign_levels(z: np.ndarray, levels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each hole's nearest level; holes too far from it are off-bench; levels with under 3 holes are dropped.

    A hole is off-bench beyond ``OFF_BENCH_FRACTION`` of the distance from
    its level to the nearest other level (of the levels first given).

    Returns the kept levels (descending), each hole's bench index in them (-1 off) and the off mask.
    """
    levels = np.sort(np.asarray(levels, float))
    gaps = np.diff(levels)
    reach = OFF_BENCH_FRACTION * np.minimum(np.r_[np.inf, gaps], np.r_[gaps, np.inf])
    while True:
        nearest = _nearest(z, levels)
        off = np.abs(z - levels[nearest]) > reach[nearest]
        keep = np.bincount(nearest[~off], minlength=len(levels)) >= 3
        if keep.all() or not keep.any():
            break
        levels, reach = levels[keep], reach[keep]
    if not keep.any():
        return np.array([]), np.full(len(z), -1), np.ones(len(z), bool)
    bench = np.where(off, -1, len(levels) - 1 - nearest)
    return levels[::-1], bench, off


def _nearest(z: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Index of the nearest of the ascending ``levels`` for each elevation."""
    i = np.clip(np.searchsorted(levels, z), 1, max(len(levels) - 1, 1))
    if len(levels) == 1:
        return np.zeros(len(z), int)
    return np.where(np.abs(z - levels[i - 1]) <= np.abs(levels[i] - z), i - 1, i)


def _collar_spacing(xy: np.ndarray) -> float:
    """Median distance to the nearest other collar (coincident collars skipped; 0 where every collar repeats)."""
    if len(xy) < 2:
        return 0.0
    d = cKDTree(xy).query(xy, k=2)[0][:, 1]
    return float(np.median(d[d > 0])) if (d > 0).any() else 0.0


def _refuse_merged_benches(z, bench, levels, xy, bench_height: float) -> None:
    """Refuse a given bench height that puts holes of several benches on one (their elevations spread too far)."""
    for k, level in enumerate(levels):
        on = bench == k
        if on.sum() < 3:
            continue
        thickness = float(np.percentile(z[on], 95) - np.percentile(z[on], 5))
        spacing = _collar_spacing(xy[on])
        if thickness > MAX_BENCH_THICKNESS_SPACINGS * spacing:
            raise BGMInputError(
                f"a bench height of {bench_height:g} puts holes from {np.min(z[on]):g} to {np.max(z[on]):g} on one bench "
                f"(at {level:g}), {thickness:.4g} units thick (5th to 95th percentile) where the holes are "
                f"{spacing:.3g} apart: give the bench height in the input's units, or leave it out to detect it"
            )


def _single_bench(
    z: np.ndarray, xy: np.ndarray | None, groups: Sequence[np.ndarray] = ()
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """One bench at the median elevation; refused when the elevations are spread far thicker than a bench.

    ``groups``: the levels beside the bench too few holes to be benches of their own, and not on its pattern
    (:func:`_sparse_benches_beside_one`): a refusal names them and what to do, not a spread "with no gap".
    """
    level = float(np.median(z))
    thickness = float(np.percentile(z, 95) - np.percentile(z, 5))
    if xy is not None and len(xy) >= 2:
        spacing = _collar_spacing(xy)
        if thickness > MAX_BENCH_THICKNESS_SPACINGS * spacing and groups:
            said = ", ".join(f"{len(g)} hole(s) at z {_level(g):g}" for g in groups)
            raise BGMInputError(
                f"z does not form benches: one level holds enough holes for a bench, and beside it {said}, "
                "too few for a bench of their own and not drilled on its hole pattern; give "
                "--bench-height if they are benches, or drop those rows if their elevations are mistyped"
            )
        if thickness > MAX_BENCH_THICKNESS_SPACINGS * spacing:
            spacings = f"{thickness / spacing:.0f} hole spacings" if spacing > 0 else "every collar repeated"
            raise BGMInputError(
                f"z does not form benches: elevations spread continuously over {thickness:.4g} units "
                f"(5th to 95th percentile), {spacings}, with no gap "
                "between benches; BGM needs samples grouped by bench (give --bench-height if they are)"
            )
    spread = float(np.percentile(np.abs(z - level), 95))
    return np.array([level]), np.zeros(len(z), int), np.nan, np.abs(z - level) > max(spread, 1e-9) * 3


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


def _deduplicate(holes: Blastholes, lines: np.ndarray) -> Blastholes:
    """Merge holes at the same position on the same bench, warning about it (``lines``: each hole's file line)."""
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
        msg += (
            f"; {len(conflicting)} of those positions carry conflicting geozone labels "
            f"(e.g. data lines {_rows(np.flatnonzero(inverse == g), lines, 4)}: {listing(sorted(set(holes.geozone[inverse == g].tolist())), 5)})"
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


#: The neighbour whose distance is a hole's spacing: on a staggered or a square pattern its three
#: nearest neighbours are a spacing away, and holes collared off the pattern bring the nearest closer.
SPACING_NEIGHBOUR = 3


def _one_row(pts: np.ndarray, nearest: np.ndarray) -> bool:
    """Holes along one line (a trench, a ramp), whose third-nearest neighbour is two steps away, not one.

    Their spread across the line is under a quarter of their ``nearest`` spacing (two staggered rows: about half).
    """
    across = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)[-1] / np.sqrt(len(pts))
    return bool(across < 0.25 * np.median(nearest))


def _bench_spacings(xy: np.ndarray, bench: np.ndarray | None, neighbour: int) -> list[np.ndarray]:
    """Each bench's holes' distances to their ``neighbour``-th nearest collar of the bench (benches of two or more)."""
    bench = np.zeros(len(xy), int) if bench is None else bench
    distances = []
    for k in np.unique(bench):
        pts = np.unique(xy[bench == k], axis=0)  # coincident holes are one collar
        if len(pts) < 2:
            continue
        d, _ = cKDTree(pts).query(pts, k=min(neighbour, len(pts) - 1) + 1)
        nth = neighbour if len(pts) > neighbour and not _one_row(pts, d[:, 1]) else 1  # a few holes, or a row: nearest
        distances.append(d[:, nth])
    return distances


def median_hole_spacing(xy: np.ndarray, bench: np.ndarray | None = None, neighbour: int = SPACING_NEIGHBOUR) -> float:
    """Median distance from a hole to its third-nearest neighbour on the same bench (metres; one bench by default).

    ``neighbour``: which neighbour to measure instead (1: the nearest).

    The nearest neighbour is the spacing of a regular pattern only: holes
    collared off a staggered 6 m pattern by 0.3 of a spacing (standard
    deviation) put its median at 3.6 m, the third-nearest's at 5.9 m (square
    pattern: 3.9 and 6.4 m); 5.2 and 5.9 m at 0.08, the synthetic drilling's.
    Every length of the engine is in spacings: on the tuning seeds drilled
    0.3 off, widening, splits and folds were predicted at 86.8, 84.8 and 91.0
    F1 at 5 m with the nearest neighbour's, 95.1, 93.3 and 95.8 with this.
    """
    distances = _bench_spacings(xy, bench, neighbour)
    if not distances:
        return float("nan")
    return float(np.median(np.concatenate(distances)))


def table_hole_spacing(xy: np.ndarray, bench: np.ndarray) -> float:
    """The spacing of a table's pattern: the middle bench's own (:func:`median_hole_spacing`), weighted by its holes.

    Benches are drilled on patterns a few percent apart (the synthetic
    drillings' deepest benches 0.1-1.5% off the benches above's). Pooled
    over every hole, the median moved as soon as a new bench's first holes
    were added (they are drilled on their own pattern, and are mostly edge,
    whose holes' neighbours lie farther off): on the families' tuning seeds
    0-2 and Kennecott's benches 3-5 with 5-40% of the deepest bench kept by
    0.18% on average, up to 0.61%, and since every length and the grid's
    cells are in spacings, predictions far from those holes moved with it.
    Here each bench's holes give its own spacing, the benches are ordered by
    it and the table takes the one at the middle of their holes: a few holes
    of a new bench move it only when they tip which bench is the middle one
    (6 of those 105 cuts, all with 15% or more kept, none of the pods').
    Leaving out the edge holes alone (those with a gap wider than 135
    degrees between their six nearest neighbours) left 0.16% of the 0.18%.
    """
    spacings = _bench_spacings(xy, bench, SPACING_NEIGHBOUR)
    if not spacings:
        return float("nan")
    own = np.array([np.median(d) for d in spacings])
    holes = np.array([len(d) for d in spacings], float)
    order = np.argsort(own, kind="stable")
    below = np.cumsum(holes[order])  # holes on benches of this spacing or closer
    return float(own[order][np.searchsorted(below, below[-1] / 2)])  # the first bench reaching half the holes
