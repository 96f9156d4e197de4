"""The model's parameters, what each one means, and which stage of the pipeline it acts on.

:class:`ModelParameters` holds every tunable value of the pipeline (boundary
extraction's in :class:`core.extraction.contours.ExtractionParameters`).
:data:`PARAMETERS` describes each of them once, for the command line, project
files and the viewer's sliders alike: a label and a help text in a
geologist's words with the paper's symbol, a typical range, the kind of
quantity (length, angle, count or ratio) and the stage it belongs to. A
changed parameter invalidates its stage and every stage after it in
:data:`STAGES` (see :class:`core.model.session.ModelSession`).

Lengths are metres in the engine's local frame; a length left ``None`` is
derived from the data (a multiple of the hole spacing, or of a grid cell).
:meth:`ModelParameters.validate` refuses values outside :data:`MODEL_RANGES`
(and extraction's :data:`~core.extraction.contours.EXTRACTION_RANGES`): the
specs' ranges are what is typical, those are what the engine can work with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

from core.errors import BGMInputError, Range, check_ranges
from core.extraction.contours import ExtractionParameters

#: Pipeline stages in order; a parameter change re-runs its stage and the ones after it.
STAGES = ("contours", "correspondence", "morph", "prediction", "surface")
#: Kinds of quantity: how a value is shown and checked (a flag is on or off).
KINDS = ("length", "angle", "count", "ratio", "flag")


@dataclass(frozen=True)
class ModelParameters:
    """Parameters of the whole model; ``None`` lengths scale with the hole spacing."""

    extraction: ExtractionParameters = field(default_factory=ExtractionParameters)
    mu_lower_m: float | None = None  #: lower limit of the association radius (eq. 8)
    correspondence_cell_size_m: float | None = None
    morph_max_cells: int = 256  #: level-set grid size along the longer side
    #: Components with fewer holes are left out between benches: on real
    #: benches a lone hole of another domain is far more often a mislabelled
    #: assay than a body, and it would drag alignments around.
    min_component_holes: int = 3
    speed_clamp_m: float | None = None  #: |gamma_t| clamp of the morph speed
    #: How far past a bench's drilled area its evidence is carried, in hole
    #: spacings (and never further than the drilled patch is wide); see
    #: :mod:`core.model.extrapolation`.
    frontier_reach_spacings: float = 10.0
    #: The surface grid is half a hole spacing, coarsened to hold under this many cells squared.
    surface_max_cells: int = 300

    def validate(self) -> ModelParameters:
        """Raise :class:`core.errors.BGMInputError` naming the first parameter out of range; returns self."""
        self.extraction.validate()
        check_ranges(self, MODEL_RANGES)
        return self


#: Valid values of each :class:`ModelParameters` field.
MODEL_RANGES = {
    "mu_lower_m": Range(0, low_open=True, optional=True),
    "correspondence_cell_size_m": Range(0, low_open=True, optional=True),
    "morph_max_cells": Range(16, 4096, integer=True),
    "min_component_holes": Range(1, integer=True),
    "speed_clamp_m": Range(0, low_open=True, optional=True),
    "frontier_reach_spacings": Range(0),
    "surface_max_cells": Range(1, integer=True),
}


@dataclass(frozen=True)
class ParameterSpec:
    """What one parameter means and where it acts.

    Attributes
    ----------
    name : str
        Field name in :class:`ModelParameters` or :class:`ExtractionParameters`.
    stage : str
        First stage of :data:`STAGES` its value changes.
    section : str
        Step of the method it tunes (groups the viewer's sliders): ``boundary``
        (connected components, entropy, gap closure), ``snake`` (edge map,
        GVF, active contour), ``correspondence``, ``morph``, ``prediction``, ``surface``.
    label, symbol, help : str
        Short name, the paper's symbol, and what it does in a geologist's words.
    kind : str
        ``length`` (metres), ``angle`` (radians), ``count`` (integer), ``ratio``
        or ``flag`` (true or false).
    minimum, maximum : float
        Typical range (the viewer's slider; 0 and 1 for a flag). For lengths, in hole spacings.
    auto : str
        How a ``None`` default is derived from the data ("" when the default is a number).
    auto_spacings : float or None
        The ``None`` default as a multiple of the hole spacing, where it is one.
    """

    name: str
    stage: str
    section: str
    label: str
    symbol: str
    kind: str
    minimum: float
    maximum: float
    help: str
    auto: str = ""
    auto_spacings: float | None = None

    @property
    def integer(self) -> bool:
        return self.kind == "count"

    @property
    def default(self):
        """The default value (``None``: derived from the data, see ``auto``)."""
        return parameter_value(ModelParameters(), self.name)

    def limits(self, hole_spacing_m: float) -> tuple[float, float]:
        """Typical range in engine units (lengths scaled by the hole spacing)."""
        scale = hole_spacing_m if self.kind == "length" else 1.0
        return self.minimum * scale, self.maximum * scale

    def resolved(self, value, hole_spacing_m: float) -> float | None:
        """``value``, or the derived default it stands for when ``None`` (``None`` if not known ahead)."""
        if value is not None:
            return value
        return None if self.auto_spacings is None else self.auto_spacings * hole_spacing_m


def _spec(name, stage, section, label, symbol, kind, lo, hi, text, auto="", auto_spacings=None) -> ParameterSpec:
    return ParameterSpec(name, stage, section, label, symbol, kind, lo, hi, text, auto, auto_spacings)


PARAMETERS: tuple[ParameterSpec, ...] = (
    # -- boundary extraction (paper section 2) -------------------------------------------------
    _spec(
        "search_radius_m", "contours", "boundary", "search radius", "r", "length", 1.0, 4.0,
        "Two holes of a geozone closer than this belong to the same body, and the mix of labels "
        "around a hole is measured within it (r, sections 2.1-2.2). Larger joins bodies across gaps.",
        "1.6 x hole spacing", 1.6,
    ),
    _spec(
        "entropy_threshold", "contours", "boundary", "entropy threshold", "T_entropy", "ratio", 0.0, 1.5,
        "A hole is a boundary hole when the labels around it are this mixed (local entropy, bits; "
        "T_entropy, section 2.2). Lower marks more holes as boundary.",
    ),
    _spec(
        "gap_angle_rad", "contours", "boundary", "gap-closure angle", "T_orient", "angle", math.radians(60),
        math.radians(180),
        "A hole whose neighbours leave an empty sector wider than this is on the edge of the drilled "
        "area, and the boundary is closed there (T_orient, section 2.3).",
    ),
    _spec(
        "gap_neighbours", "contours", "boundary", "gap-closure neighbours", "K_orient", "count", 4, 24,
        "Neighbours looked at to find empty sectors around a hole (K_orient, section 2.3).",
    ),
    _spec(
        "smoothing_spacings", "contours", "boundary", "transition smoothing", "", "ratio", 0.0, 3.0,
        "Hole spacings over which the line half-way between holes of different geozones is smoothed "
        "before the snake settles on it (sections 2.2-2.4): larger irons out the drilling pattern's "
        "zig-zag, smaller follows the holes more closely.",
    ),
    _spec(
        "keep_isolated_holes", "contours", "boundary", "keep isolated holes", "", "flag", 0, 1,
        "Keep components of one or two holes surrounded by other geozones as bodies; by default they "
        "are taken as mislabelled assays (label noise) and reported, not contoured (section 2.1).",
    ),
    # -- edge map, GVF and snake (sections 2.4-2.5) ---------------------------------------------
    _spec(
        "edge_map_cells", "contours", "snake", "edge-map grid size", "n_x", "count", 80, 400,
        "Cells across the edge map of a component (n_x ~ n_y, Fig. 4): finer follows the boundary "
        "more closely and costs more.",
    ),
    _spec(
        "gvf_mu", "contours", "snake", "GVF smoothness", "mu", "ratio", 0.01, 0.5,
        "How far the boundary's pull reaches into open ground (gradient vector flow regularisation mu, "
        "section 2.5): larger draws the snake in from further away and smooths it.",
    ),
    _spec(
        "snake_alpha", "contours", "snake", "snake elasticity", "alpha", "ratio", 0.0, 0.5,
        "How strongly the contour resists stretching (alpha, section 2.5): larger gives a shorter, tighter contour.",
    ),
    _spec(
        "snake_beta", "contours", "snake", "snake rigidity", "beta", "ratio", 0.0, 0.5,
        "How strongly the contour resists bending (beta, section 2.5): larger rounds off sharp corners.",
    ),
    _spec(
        "snake_step", "contours", "snake", "snake step", "", "ratio", 0.1, 3.0,
        "Cells the contour moves per iteration at full pull (section 2.5).",
    ),
    _spec(
        "snake_max_iterations", "contours", "snake", "snake iterations", "", "count", 10, 1500,
        "Most iterations of the active contour before it is taken as converged (section 2.5).",
    ),
    # -- spatial correspondence (section 3) ------------------------------------------------------
    _spec(
        "min_component_holes", "correspondence", "correspondence", "smallest modelled component", "",
        "count", 1, 20,
        "Components with fewer holes are shown but left out between benches: a lone hole of another "
        "domain is more often a mislabelled assay than a body.",
    ),
    _spec(
        "mu_lower_m", "correspondence", "correspondence", "association radius floor", "mu_lower", "length",
        0.25, 5.0,
        "Components on successive benches at least this close are candidates to be one body, however "
        "small they are (lower limit of mu, eq. 8).",
        "1.5 x hole spacing", 1.5,
    ),
    _spec(
        "correspondence_cell_size_m", "correspondence", "correspondence", "alignment cell size", "",
        "length", 0.1, 2.0,
        "Cell of the grid on which a source is slid over its targets to find its translation (section 3.2).",
        "a quarter hole spacing (coarser for very large benches)",
    ),
    # -- contour metamorphosis (section 4) -------------------------------------------------------
    _spec(
        "morph_max_cells", "morph", "morph", "morph grid size", "", "count", 64, 512,
        "Cells along the longer side of the level-set grid on which a bench's regions grow into the next "
        "bench's (section 4); never finer than a quarter hole spacing.",
    ),
    _spec(
        "speed_clamp_m", "morph", "morph", "morph speed clamp", "c", "length", 0.1, 5.0,
        "Largest distance the front moves per unit time, so far parts of the boundary do not race ahead "
        "(c in clip(gamma_t, -c, c), section 4).",
        "3 morph grid cells",
    ),
    # -- prediction --------------------------------------------------------------------------------
    _spec(
        "frontier_reach_spacings", "prediction", "prediction", "reach past the drilling", "", "ratio",
        0.0, 30.0,
        "How far, in hole spacings, a bench's evidence of the boundary is carried past the edge of its "
        "drilled area when predicting below and above the benches (never further than the drilled patch "
        "is wide).",
    ),
    # -- surface -----------------------------------------------------------------------------------
    _spec(
        "surface_max_cells", "surface", "surface", "surface grid size", "", "count", 40, 600,
        "The grid the surface is built on holds at most this many cells squared (half a hole spacing when the "
        "geozone is small or long).",
    ),
)  # fmt: skip
PARAMETER: dict[str, ParameterSpec] = {p.name: p for p in PARAMETERS}
_EXTRACTION_FIELDS = {f.name for f in fields(ExtractionParameters)}


def _check_covered() -> None:
    """Every field of the parameter dataclasses has exactly one spec (so every one has a stage)."""
    names = _EXTRACTION_FIELDS | {f.name for f in fields(ModelParameters)} - {"extraction"}
    if names != set(PARAMETER) or len(PARAMETER) != len(PARAMETERS):
        raise AssertionError(f"parameter specs do not match the dataclasses: {sorted(names ^ set(PARAMETER))}")


_check_covered()


def parameter_value(params: ModelParameters, name: str):
    """The value of parameter ``name`` (see :data:`PARAMETER`)."""
    spec = PARAMETER[name]  # KeyError for an unknown name
    return getattr(params.extraction if spec.name in _EXTRACTION_FIELDS else params, name)


def with_values(params: ModelParameters, **values) -> ModelParameters:
    """A copy of ``params`` with the named parameters set (``None`` = derived from the data)."""
    extraction = {k: v for k, v in values.items() if k in _EXTRACTION_FIELDS}
    model = {k: v for k, v in values.items() if k not in _EXTRACTION_FIELDS}
    for k in model:
        PARAMETER[k]  # KeyError for an unknown name
    if extraction:
        model["extraction"] = replace(params.extraction, **extraction)
    return replace(params, **model)


def stage_values(params: ModelParameters, stage: str) -> dict:
    """The parameters of one stage, by name (what a stage's results depend on besides its inputs)."""
    if stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r}; stages are {', '.join(STAGES)}")
    return {p.name: parameter_value(params, p.name) for p in PARAMETERS if p.stage == stage}


def first_changed_stage(old: ModelParameters, new: ModelParameters) -> str | None:
    """The earliest stage whose parameters differ (``None`` if none do)."""
    return next((s for s in STAGES if stage_values(old, s) != stage_values(new, s)), None)


def parameters_to_dict(params: ModelParameters) -> dict:
    """The parameters that differ from the defaults, by name (engine units), for project files."""
    default = ModelParameters()
    return {
        p.name: parameter_value(params, p.name)
        for p in PARAMETERS
        if parameter_value(params, p.name) != parameter_value(default, p.name)
    }


def parameters_from_dict(values: dict, base: ModelParameters | None = None) -> ModelParameters:
    """Parameters from a project file's ``parameters`` object; other keys are left alone.

    Raises
    ------
    BGMInputError
        A known parameter with a value of the wrong kind (a count that is not a
        whole number, a length or angle that is not positive, a non-finite number,
        a flag that is not true or false), or out of its range (see
        :meth:`ModelParameters.validate`).
    """
    known = {k: v for k, v in values.items() if k in PARAMETER}
    params = with_values(base or ModelParameters(), **{k: _checked(PARAMETER[k], v) for k, v in known.items()})
    return params.validate()


def _checked(spec: ParameterSpec, value):
    if value is None and spec.default is None:
        return None
    if spec.kind == "flag":
        if not isinstance(value, bool):
            raise BGMInputError(f"parameter {spec.name} must be true or false, got {value!r}.")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise BGMInputError(f"parameter {spec.name} must be a finite number, got {value!r}.")
    if spec.integer:
        if value != int(value) or value < 0:
            raise BGMInputError(f"parameter {spec.name} must be a whole number of {spec.label}, got {value!r}.")
        return int(value)
    if spec.kind in ("length", "angle") and value <= 0:
        raise BGMInputError(f"parameter {spec.name} must be positive, got {value!r}.")
    return float(value)
