"""Project files: model parameters, the viewer's view and manual alignment overrides.

A project file is JSON::

    {
      "format": "bgm-project",
      "version": 1,
      "input_path": "blastholes.csv",
      "reading_options": {"units": "ft", "geozone_column": "DOMAIN"},
      "parameters": {"search_radius_m": 9.5, "viewer": {"geozone": "ore", "bench": 2}},
      "overrides": [
        {"geozone": "ore", "source_z": 1210.0, "source": 2,
         "translation": [3.5, -1.0], "associate": {"0": true, "4": false}}
      ]
    }

An override concerns one source component (index ``source``) of one
geozone on the bench at elevation ``source_z`` (the upper bench of a bench
pair, paper section 3 "source"): ``translation`` locks its translation
(input units; translations do not depend on the local frame's origin) and
``associate`` forces (``true``) or forbids (``false``) its association with
target components by index. ``parameters`` sets the model's parameters by
name (``bgm parameters`` lists them; every command with ``--project`` and the
viewer apply them) and, under ``viewer``, the viewer's selection, vertical
exaggeration, whose surfaces it builds, its body filter, which layers it shows
(``layers``: layer name -> true/false) and its camera (``camera``, see
:func:`check_camera`; projects before these two have neither, and open with the
viewer's defaults). ``reading_options``
(optional) are the options the input was read with, by their command-line
names without dashes (:data:`READING_OPTIONS`): every command with
``--project`` and the viewer read the input with them, so a table read in
feet is not read in metres again. A project that records
reading options is written as version 2, which BGMs older than the option
refuse instead of ignoring them; one without them stays version 1. Files are
written atomically (core.io.atomic).
"""

from __future__ import annotations

import json
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from core.errors import BGMInputError, Range, listing, quoted
from core.io.atomic import atomic_write_text

FORMAT = "bgm-project"
#: Newest version read; a project is written as version 1 unless it records reading options.
VERSION = 2
#: Options the input table was read with, by command-line name (``--units`` is ``units``) ->
#: the keyword of :func:`core.io.blastholes.read_blastholes` taking it.
READING_OPTIONS = {
    "x": "x",
    "y": "y",
    "z": "z",
    "geozone_column": "geozone",
    "bench_height": "bench_height",
    "units": "length_unit",
}
#: Relative tolerance when matching bench elevations (with a floor of 1 unit,
#: so elevation 0 still matches within 1e-6).
Z_RELATIVE_TOLERANCE = 1e-6


@dataclass
class AlignmentOverride:
    """Manual correction of one source component's correspondence.

    Attributes
    ----------
    geozone : str
        Geozone label.
    source_z : float
        Elevation of the source (upper) bench, input units.
    source : int
        Source component index on that bench.
    translation : (float, float) or None
        Locked translation ``(dx, dy)`` in input units; ``None`` = automatic.
    associate : dict of int to bool
        Target index -> ``True`` (force association) / ``False`` (forbid).
    """

    geozone: str
    source_z: float
    source: int
    translation: tuple[float, float] | None = None
    associate: dict[int, bool] = field(default_factory=dict)

    def to_dict(self) -> dict:
        out: dict = {"geozone": self.geozone, "source_z": self.source_z, "source": self.source}
        if self.translation is not None:
            out["translation"] = [float(self.translation[0]), float(self.translation[1])]
        if self.associate:
            out["associate"] = {str(k): bool(v) for k, v in sorted(self.associate.items())}
        return out


@dataclass
class Project:
    """Parameters, overrides, the input path and the options it was read with, of one modelling project.

    Attributes
    ----------
    reading : dict
        Options the input was read with, by command-line name
        (:data:`READING_OPTIONS`); those not given are left out.
    """

    parameters: dict = field(default_factory=dict)
    overrides: list[AlignmentOverride] = field(default_factory=list)
    input_path: str | None = None
    reading: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        out = {
            "format": FORMAT,
            # version 1 when it can be: a BGM without reading options opens it exactly as before
            "version": VERSION if self.reading else 1,
            "input_path": self.input_path,
            "parameters": self.parameters,
            "overrides": [o.to_dict() for o in self.overrides],
        }
        if self.reading:
            out["reading_options"] = dict(self.reading)
        return out

    def read_keywords(self) -> dict:
        """The reading options as :func:`core.io.blastholes.read_blastholes` takes them."""
        return {READING_OPTIONS[k]: v for k, v in self.reading.items()}


def save_project(project: Project, path: str | os.PathLike) -> None:
    """Write ``project`` to ``path`` as JSON, atomically (old file kept on failure)."""
    try:
        text = json.dumps(project.to_dict(), indent=2, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise BGMInputError(f"project cannot be saved as JSON: {exc}.") from None
    atomic_write_text(path, text)


def load_project(path: str | os.PathLike) -> Project:
    """Read a project file.

    Raises
    ------
    BGMInputError
        If the file is missing or unreadable, is not valid JSON ("corrupt"),
        is not a BGM project, comes from a newer BGM version, or holds a
        malformed override.
    """
    path = Path(path)
    if path.is_dir():  # "does not exist" would mislead
        raise BGMInputError(f"project file {path} is a directory, not a project file.")
    if not path.is_file():
        raise BGMInputError(f"project file {path} does not exist.")
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte order mark (Windows PowerShell 5) is no error
    except (OSError, UnicodeDecodeError) as exc:
        raise BGMInputError(f"project file {path} cannot be read: {exc}.") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise BGMInputError(
            f"project file {path} is corrupt (not valid JSON: {exc.msg} at line {exc.lineno})."
        ) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise BGMInputError(f'{path} is not a BGM project file (expected "format": "{FORMAT}").')
    version = data.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise BGMInputError(f"project file {path} has an invalid version {version!r}.")
    if version > VERSION:
        raise BGMInputError(
            f"project file {path} has version {version}, newer than version {VERSION} "
            "supported by this BGM; please upgrade BGM."
        )
    parameters = data.get("parameters", {})
    if not isinstance(parameters, dict):
        raise BGMInputError(f'project file {path}: "parameters" must be an object.')
    _check_parameters(path, parameters)
    input_path = data.get("input_path")
    if input_path is not None and not isinstance(input_path, str):
        raise BGMInputError(f'project file {path}: "input_path" must be a string.')
    raw = data.get("overrides", [])
    if not isinstance(raw, list):
        raise BGMInputError(f'project file {path}: "overrides" must be a list.')
    overrides = [_parse_override(path, i, o) for i, o in enumerate(raw)]
    reading = _parse_reading(path, data.get("reading_options", {}))
    return Project(parameters=parameters, overrides=overrides, input_path=input_path, reading=reading)


def _parse_reading(path: Path, raw) -> dict:
    """The reading options of a project file, checked: column names and units are strings, the bench height a length."""
    from core.io.blastholes import unit_name

    where = f'project file {path}: "reading_options"'
    if not isinstance(raw, dict):
        raise BGMInputError(f"{where} must be an object.")
    unknown = sorted(set(raw) - set(READING_OPTIONS))
    if unknown:
        raise BGMInputError(
            f"{where} has unknown option(s) {listing(map(quoted, unknown))}; known: {listing(READING_OPTIONS)}."
        )
    reading = {k: v for k, v in raw.items() if v is not None}
    for name, value in reading.items():
        if name == "bench_height":
            if not (_is_number(value) and value > 0):
                raise BGMInputError(f"{where}: bench_height must be a positive number, got {value!r}.")
        elif not isinstance(value, str) or not value.strip():
            raise BGMInputError(f"{where}: {name} must be a non-empty string, got {value!r}.")
    if "units" in reading:
        reading["units"] = unit_name(reading["units"])  # refuses a unit that is neither m nor ft
    return reading


def reading_of(read_keywords: dict) -> dict:
    """Options given to :func:`core.io.blastholes.read_blastholes` (``Blastholes.read_options``) by command-line name."""
    names = {v: k for k, v in READING_OPTIONS.items()}
    return {names[k]: v for k, v in read_keywords.items() if k in names and v is not None}


def comparable_reading(reading: dict) -> dict:
    """Reading options by command-line name, those given only, the unit by its one name (``feet`` is ``ft``):
    two readings of a table are the same reading when these are equal."""
    from core.io.blastholes import unit_name

    return {k: unit_name(v) if k == "units" else v for k, v in reading.items() if v is not None}


def merge_reading(project: Project, project_path, given: dict) -> tuple[dict, list[str]]:
    """The options to read the input with: the project's, and those given on the command line.

    An option given that the project records with another value is refused: the
    project's overrides (elevations, translations in input units, geozone labels)
    and parameters were made on the table read its way, and read another way
    (feet as metres, another geozone column) it is other data. Options the
    project does not record are taken as given.

    Parameters
    ----------
    project : Project
    project_path : str or Path
        Names the project in messages.
    given : dict
        Options given on the command line, by command-line name (``None``: not given).

    Returns
    -------
    options : dict
        Every option, by command-line name (``None`` where neither gives it).
    used : list of str
        The project's options used (``"--units ft"``), for the command to say.

    Raises
    ------
    BGMInputError
        Naming the option, both values and how to resolve it.
    """
    options = dict(given)
    used = []
    for name, saved in project.reading.items():
        flag = f"--{name.replace('_', '-')}"
        value = given.get(name)
        if value is None:
            options[name] = saved
            used.append(f"{flag} {saved}")
            continue
        if comparable_reading({name: value}) != comparable_reading({name: saved}):
            raise BGMInputError(
                f"{flag} {value} conflicts with project file {project_path}, made reading the input with "
                f"{flag} {saved}: read otherwise it is other data than its overrides and view were made on; "
                f"leave {flag} out, or save a new project"
            )
    return options, used


def saved_input(project: Project, project_path: str | os.PathLike) -> Path | None:
    """The input file the project was saved for, resolved against the project's folder (None if it names none)."""
    if not project.input_path:
        return None
    path = Path(project.input_path)
    return path if path.is_absolute() else Path(project_path).resolve().parent / path


def check_project_input(project: Project, project_path: str | os.PathLike, input_file: str | os.PathLike) -> None:
    """Warn when a project with alignment overrides is applied to another input file than it was saved for.

    Overrides name components by number (:class:`AlignmentOverride`): in another
    table the same numbers may be other bodies, and nothing else would say so.
    """
    from core.errors import BGMWarning

    saved, given = saved_input(project, project_path), Path(input_file)
    if not project.overrides or saved is None or not given.is_file():
        return
    try:
        same = saved.samefile(given)
    except OSError:  # the file it was saved for is gone or unreadable
        same = False
    if not same:
        warnings.warn(
            f"project file {project_path} was saved for {project.input_path}, not {input_file}: its "
            f"{len(project.overrides)} alignment override(s) name components by number, which in this input "
            "may be other bodies; check them (bgm correspond lists the components)",
            BGMWarning,
            stacklevel=2,
        )


def _parse_override(path: Path, i: int, o) -> AlignmentOverride:
    where = f"project file {path}, override {i}"
    if not isinstance(o, dict):
        raise BGMInputError(f"{where} must be an object.")
    try:
        geozone = o["geozone"]
        source_z = o["source_z"]
        source = o["source"]
    except KeyError as exc:
        raise BGMInputError(f"{where} lacks the field {exc.args[0]!r}.") from None
    if not isinstance(geozone, str):
        raise BGMInputError(f"{where}: geozone must be a string.")
    if not _is_number(source_z):
        raise BGMInputError(f"{where}: source_z must be a finite number.")
    if not isinstance(source, int) or isinstance(source, bool) or source < 0:
        raise BGMInputError(f"{where}: source must be a non-negative integer.")
    translation = o.get("translation")
    if translation is not None:
        if not (isinstance(translation, list) and len(translation) == 2 and all(map(_is_number, translation))):
            raise BGMInputError(f"{where}: translation must be two finite numbers or null.")
        translation = (float(translation[0]), float(translation[1]))
    raw_assoc = o.get("associate", {})
    if not isinstance(raw_assoc, dict):
        raise BGMInputError(f"{where}: associate must be an object of target index -> true/false.")
    associate: dict[int, bool] = {}
    for k, v in raw_assoc.items():
        try:
            t = int(k)
        except ValueError:
            raise BGMInputError(f"{where}: associate key {k!r} is not a target index.") from None
        if t < 0 or not isinstance(v, bool):
            raise BGMInputError(f"{where}: associate must map target indices to true/false.")
        associate[t] = v
    return AlignmentOverride(geozone, float(source_z), source, translation, associate)


def _check_parameters(path: Path, parameters: dict) -> None:
    """Every parameter is a finite number (a flag true or false); those the engine knows by name are in their range.

    Names the engine does not know are left unused, and said so by
    :func:`check_project`.
    """
    from core.extraction.contours import EXTRACTION_RANGES
    from core.model.parameters import MODEL_RANGES, PARAMETER

    ranges = {**EXTRACTION_RANGES, **MODEL_RANGES}
    for name, value in parameters.items():
        if name == "viewer":
            if value is not None and not isinstance(value, dict):
                raise BGMInputError(f'project file {path}: "viewer" must be an object.')
            _check_viewer(path, value or {})
            continue
        if name in PARAMETER and PARAMETER[name].kind == "flag":
            if not isinstance(value, bool):
                raise BGMInputError(f"project file {path}: parameter {name} must be true or false, got {value!r}.")
            continue
        if name in ranges and not ranges[name].holds(value):
            raise BGMInputError(
                f"project file {path}: parameter {name} must be {ranges[name].describe()}, got {value!r}."
            )
        if name not in ranges and not _is_number(value):
            raise BGMInputError(
                f"project file {path}: parameter {quoted(name)} must be a finite number, got {value!r}."
            )


#: The viewer's saved view: what each setting may hold.
VIEWER_RANGES = {
    "bench": Range(0, integer=True, optional=True),
    "component": Range(0, integer=True, optional=True),
    "vertical_exaggeration": Range(0, 100, low_open=True, optional=True),
    "min_body_volume_m3": Range(0, optional=True),
    "min_body_holes": Range(0, integer=True, optional=True),
}
#: Whose surfaces the viewer builds (viewer setting ``surfaces``): all but a host rock, all, the
#: geozones ticked (``surface_geozones``) or the selected one. Projects before it have none: "bodies".
SURFACE_SCOPES = ("bodies", "all", "ticked", "selected")


def _check_viewer(path: Path, viewer: dict) -> None:
    for name, valid in VIEWER_RANGES.items():
        if name in viewer and not valid.holds(viewer[name]):
            raise BGMInputError(
                f"project file {path}: viewer setting {name} must be {valid.describe()}, got {viewer[name]!r}."
            )
    if viewer.get("geozone") is not None and not isinstance(viewer["geozone"], str):
        raise BGMInputError(f"project file {path}: viewer setting geozone must be a string.")
    if viewer.get("surfaces") is not None and viewer["surfaces"] not in SURFACE_SCOPES:
        raise BGMInputError(
            f"project file {path}: viewer setting surfaces must be one of {', '.join(SURFACE_SCOPES)},"
            f" got {viewer['surfaces']!r}."
        )
    zones = viewer.get("surface_geozones")
    if zones is not None and not (isinstance(zones, list) and all(isinstance(z, str) for z in zones)):
        raise BGMInputError(f"project file {path}: viewer setting surface_geozones must be a list of geozones.")
    layers = viewer.get("layers")
    if layers is not None and not (
        isinstance(layers, dict) and all(isinstance(k, str) and isinstance(v, bool) for k, v in layers.items())
    ):
        raise BGMInputError(
            f"project file {path}: viewer setting layers must be an object of layer name -> true/false, got {layers!r}."
        )
    if viewer.get("camera") is not None:
        problem = check_camera(viewer["camera"])
        if problem:
            raise BGMInputError(f"project file {path}: viewer setting camera {problem}.")


#: The viewer's camera (viewer setting ``camera``): points and the up direction as three numbers each.
CAMERA_VECTORS = ("position", "focal_point", "view_up")


def check_camera(camera) -> str | None:
    """What is wrong with a saved camera (``None``: nothing), as the end of a sentence naming it.

    A camera is an object: ``position`` (where the view is from) and ``focal_point`` (what it looks
    at), in the input's coordinates and units, elevations not exaggerated; ``view_up``, the direction
    that is up in the picture, three numbers each; ``parallel_scale``, for a view without perspective,
    half the height the picture shows (input units), else null or absent; ``window_center``, where the
    picture's centre is moved to (two numbers, -1 to 1 across it), absent for none.

    >>> check_camera({"position": [0, 0, 10], "focal_point": [0, 0, 10], "view_up": [0, 1, 0]})
    'looks from its focal point (position and focal_point are the same point)'
    """
    if not isinstance(camera, dict):
        return f"must be an object with {listing(CAMERA_VECTORS)}, got {camera!r}"
    unknown = sorted(set(camera) - {*CAMERA_VECTORS, "parallel_scale", "window_center"})
    if unknown:
        return f"has unknown key(s) {listing(map(quoted, unknown))}"
    for name in CAMERA_VECTORS:
        value = camera.get(name)
        if not (isinstance(value, list) and len(value) == 3 and all(map(_is_number, value))):
            return f"{name} must be three finite numbers, got {value!r}"
    if camera["position"] == camera["focal_point"]:
        return "looks from its focal point (position and focal_point are the same point)"
    sight = [f - p for f, p in zip(camera["focal_point"], camera["position"])]
    up = camera["view_up"]
    across = (
        sight[1] * up[2] - sight[2] * up[1],
        sight[2] * up[0] - sight[0] * up[2],
        sight[0] * up[1] - sight[1] * up[0],
    )
    if math.hypot(*across) <= 1e-9 * math.hypot(*sight) * math.hypot(*up):
        return "view_up must be a direction across the line of sight (not zero, nor along it)"
    scale = camera.get("parallel_scale")
    if scale is not None and not (_is_number(scale) and scale > 0):
        return f"parallel_scale must be a positive number or null, got {scale!r}"
    centre = camera.get("window_center")
    if centre is not None and not (isinstance(centre, list) and len(centre) == 2 and all(map(_is_number, centre))):
        return f"window_center must be two finite numbers, got {centre!r}"
    return None


def check_project(
    project: Project,
    holes,
    geozones: list[str] | None = None,
    command: str = "this command",
    uses_parameters: bool = False,
) -> None:
    """Refuse overrides the input cannot honour, and warn about every one left unused.

    An override is unused when its geozone is not in the input (or not among
    ``geozones``, the ones being modelled), or no bench pair has its upper
    bench at ``source_z``. A locked translation longer than the whole input
    is refused: it cannot be a correction. Project parameters the command
    does not apply (any, unless ``uses_parameters``; else those that are no
    parameter of the model) are said to be unused too.

    Parameters
    ----------
    project : Project
    holes : core.io.blastholes.Blastholes
    geozones : list of str, optional
        Geozones the command models (default: all in the input).
    command : str
        How the warnings name the command.
    uses_parameters : bool
        The command applies the project's parameters (every command with
        ``--project`` and the viewer do).
    """
    from core.errors import BGMWarning

    extent = input_extent(holes)
    unit = holes.frame.length_unit  # elevations and translations are the input's
    uppers = [holes.bench_z_input(k) for k in range(holes.n_benches - 1)]
    modelled = set(geozones if geozones is not None else holes.geozones)
    for i, o in enumerate(project.overrides):
        where = f"project override {i} ({quoted(o.geozone)} at {o.source_z:g} {unit}, source {o.source})"
        if o.translation is not None and not translation_fits(o.translation, extent):
            raise BGMInputError(
                f"{where} moves its component by ({o.translation[0]:.6g}, {o.translation[1]:.6g}) {unit}, more than "
                f"the whole input spans ({extent:.6g} {unit}); fix or remove it"
            )
        reason = None
        if o.geozone not in holes.geozones:
            reason = f"geozone {quoted(o.geozone)} is not in the input"
        elif o.geozone not in modelled:
            reason = f"{command} does not model geozone {quoted(o.geozone)}"
        elif not any(same_elevation(o.source_z, z) for z in uppers):
            reason = f"no bench pair has its upper bench at {o.source_z:g} {unit} (upper benches in {unit}: {listing(uppers, 8)})"
        if reason:
            warnings.warn(f"{where} is not used: {reason}", BGMWarning, stacklevel=2)
    from core.model.parameters import PARAMETER

    settings = sorted(k for k in project.parameters if k != "viewer")
    if settings and not uses_parameters:
        warnings.warn(
            f"project parameters {listing(settings, 8)} are viewer settings; {command} does not use them",
            BGMWarning,
            stacklevel=2,
        )
    unknown = [k for k in settings if k not in PARAMETER]
    if unknown and uses_parameters:
        warnings.warn(
            f"project parameters {listing(unknown, 8)} are not parameters of the model "
            f"(see bgm parameters); {command} does not use them",
            BGMWarning,
            stacklevel=2,
        )
    if uses_parameters:
        for note in _lengths_out_of_range(project.parameters, holes.hole_spacing_m):
            warnings.warn(note, BGMWarning, stacklevel=2)


def _lengths_out_of_range(parameters: dict, hole_spacing_m: float) -> list[str]:
    """A sentence per length parameter outside its typical range in hole spacings (a length in feet, say)."""
    from core.model.parameters import PARAMETER

    notes = []
    for name, value in parameters.items():
        spec = PARAMETER.get(name)
        if spec is None or spec.kind != "length" or not isinstance(value, int | float) or isinstance(value, bool):
            continue
        lo, hi = spec.limits(hole_spacing_m)
        if not lo <= value <= hi:
            notes.append(
                f"project parameter {name} = {value:g} m is {value / hole_spacing_m:.3g} hole spacings "
                f"({hole_spacing_m:.3g} m); its typical range is {spec.minimum:g}-{spec.maximum:g} spacings "
                f"({lo:.3g}-{hi:.3g} m). Lengths are in metres, whatever the input's unit"
            )
    return notes


def input_extent(holes) -> float:
    """How far the input spans along its longer horizontal axis, in input units (0 without holes)."""
    import numpy as np

    return float(holes.frame.length_to_input(np.ptp(holes.xy, axis=0).max())) if len(holes.xy) else 0.0


def translation_fits(translation: tuple[float, float], extent: float) -> bool:
    """Whether a locked translation (input units) can be a correction: finite, and not longer than the input spans.

    A longer one moves its component off the input altogether; :func:`check_project`
    refuses it, so the viewer refuses to set it (a project it saved would not open).
    """
    dx, dy = (float(v) for v in translation)
    return math.isfinite(dx) and math.isfinite(dy) and max(abs(dx), abs(dy)) <= max(extent, 1.0)


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def same_elevation(a: float, b: float) -> bool:
    """Whether two bench elevations (input units) are the same bench: equal within :data:`Z_RELATIVE_TOLERANCE`."""
    return abs(a - b) <= Z_RELATIVE_TOLERANCE * max(1.0, abs(a), abs(b))


def check_override_components(
    overrides: tuple[dict[int, tuple[float, float]], set[tuple[int, int]], set[tuple[int, int]]],
    n_sources: int,
    n_targets: int,
    where: str,
) -> None:
    """Refuse overrides of a bench pair that name a source or target component the pair does not have.

    Parameters
    ----------
    overrides : (locked_translations, forced, forbidden)
        One bench pair's overrides, as :func:`overrides_for` returns them.
    n_sources, n_targets : int
        Components of the upper (source) and lower (target) bench the pair links.
    where : str
        Names the geozone and the bench pair in the message
        (``"geozone 'ore', benches 1210 and 1195 m"``).

    Raises
    ------
    BGMInputError
        Naming the override's component and what the bench has: a project
        written for other data or other parameters (``min_component_holes``
        changes which components a bench pair links) would otherwise fail deep
        in the correspondence with a message naming no project.
    """
    locked, forced, forbidden = overrides
    pairs = sorted(forced | forbidden)
    for s in sorted({*locked, *(s for s, _ in pairs)}):
        if not 0 <= s < n_sources:
            raise BGMInputError(
                f"project override of {where} names source component {s}, but the upper bench has "
                f"{_components(n_sources)}; fix or remove the override"
            )
    for _, t in pairs:
        if not 0 <= t < n_targets:
            raise BGMInputError(
                f"project override of {where} associates target component {t}, but the lower bench has "
                f"{_components(n_targets)}; fix or remove the override"
            )


def _components(n: int) -> str:
    """``"2 components (0 to 1)"``: what a bench pair's side has, as overrides index it."""
    if n == 0:
        return "no component"
    return f"{n} component{'s' if n > 1 else ''} ({'0' if n == 1 else f'0 to {n - 1}'})"


def overrides_for(
    project: Project, geozone: str, source_z: float
) -> tuple[dict[int, tuple[float, float]], set[tuple[int, int]], set[tuple[int, int]]]:
    """Overrides of one bench pair in the form :func:`core.correspondence.pair.correspond_pair` takes.

    Parameters
    ----------
    project : Project
    geozone : str
    source_z : float
        Elevation of the source bench; matched with relative tolerance
        ``1e-6`` (floor of one unit).

    Returns
    -------
    locked_translations : dict
        ``{source: (dx, dy)}`` (input units).
    forced, forbidden : set of (source, target)
        Later overrides win over earlier ones for the same pair.
    """
    locked: dict[int, tuple[float, float]] = {}
    assoc: dict[tuple[int, int], bool] = {}
    for o in project.overrides:
        if o.geozone != geozone or not same_elevation(o.source_z, source_z):
            continue
        if o.translation is not None:
            locked[o.source] = (float(o.translation[0]), float(o.translation[1]))
        for t, flag in o.associate.items():
            assoc[(o.source, int(t))] = bool(flag)
    forced = {k for k, v in assoc.items() if v}
    forbidden = {k for k, v in assoc.items() if not v}
    return locked, forced, forbidden
