"""The whole model for every geozone: what ``bgm build`` and ``bgm demo`` write.

For each geozone: contours, correspondence, trajectories, predictions for one
bench below the deepest bench, a closed surface exported in every format, the
paper's precision/recall evaluation against three references, and a
``report.md`` that summarises it all with the figures embedded.
"""

from __future__ import annotations

import contextlib
import gc
import hashlib
import json
import os
import re
import shutil
import signal
import sys
import threading
import time
import warnings
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import shapely
from shapely.geometry import shape

from core.errors import BGMInputError, BGMWarning, listing, quoted
from core.extraction.contours import Contour
from core.geometry.grid import as_multipolygon
from core.io.atomic import atomic_write_text, check_output, replaced_folder
from core.io.blastholes import Blastholes
from core.io.export import SURFACE_FORMATS
from core.io.reporting import (
    CHOSEN_WORDS,
    carried_json,
    carried_words,
    containment_summary,
    contour_feature,
    prediction_feature,
)
from core.model.pipeline import (
    GeozoneModel,
    ModelParameters,
    correspondence_json,
    morph_json,
    pair_coverage,
)
from core.model.prediction import predict_geozone
from core.model.progress import CONTOURS_STAGE, FIELDS_STEP, GeozoneSteps, geozone_stage
from core.model.session import (  # noqa: F401 - the surface build's steps, long imported from here
    SURFACE_STEPS_PER_BENCH,
    ModelSession,
    StageStore,
    surface_cell_size,
    surface_sections,
)
from core.threads import available_cores

#: Depths below the deepest bench at which predictions are written, in bench heights.
PREDICTION_FRACTIONS = tuple(k / 8 for k in range(1, 9))
#: What ``bgm build`` writes at the top of its folder (besides one folder per geozone).
TOP_LEVEL_FILES = (
    "contours.dxf",
    "contours.geojson",
    "evaluation.csv",
    "evaluation_rows.csv",
    "precision_recall.png",
    "report.md",
    "summary.json",
)
#: What ``bgm build`` writes in a geozone's folder, in any run: replaced by each build, never carried over.
#: :func:`build_geozone` writes the JSON files and predictions, :func:`write_sampling` the uncertainty,
#: suggestions and map, :func:`_write_surface` the surface in every format the build can write (a stale
#: ``surface.omf`` of a build with more formats is not kept by one with fewer) and the STL's offset beside it.
GEOZONE_FILES = frozenset(
    {
        "correspondence.json",
        "morph.json",
        "prediction.geojson",
        "prediction.dxf",
        "uncertainty.geojson",
        "p_inside.npz",
        "suggestions.csv",
        "where_to_sample.png",
        *(f"surface.{fmt}" for fmt in SURFACE_FORMATS),
        "surface.stl.json",  # core.io.export._record_stl_offset
    }
)
#: Longest geozone folder name (characters), before its distinguishing suffix.
MAX_FOLDER_CHARS = 48
#: Folder names Windows reserves whatever the extension.
_RESERVED = re.compile(r"(con|prn|aux|nul|com\d|lpt\d)(\..*)?", re.IGNORECASE)


def truth_sidecar(path: Path) -> Path:
    """Where a synthetic table's truth description lives (``name.truth.json``)."""
    return path.with_name(path.stem + ".truth.json")


def load_truth(path: Path, holes: Blastholes):
    """The true sections of a synthetic table, if its generator left a sidecar; else None.

    The sidecar names the generator and its arguments:
    ``{"generator": "core.synthetic.demo_dataset", "seed": 2019}``,
    ``{"generator": "core.synthetic.make_mine", "kwargs": {...}}`` or
    ``{"generator": "core.synthetic.scenario", "family": "strips", "seed": 7}``
    (optionally with ``n_benches``, ``bench_height_m`` and ``units``, see
    :func:`core.synthetic.scenarios.scenario`) or
    ``{"generator": "core.synthetic.shape_scenario", "shape": "ring", "seed": 7}``
    (the same options, :func:`core.synthetic.shapes.make_shape`).
    Returns a callable ``truth(geozone, z_m)`` in the engine's local frame.
    """
    side = truth_sidecar(Path(path))
    if not side.exists():
        return None
    from core.model.evaluation import truth_from_mine
    from core.synthetic.blobs import demo_dataset, make_mine
    from core.synthetic.scenarios import make_family
    from core.synthetic.shapes import make_shape

    try:
        spec = json.loads(side.read_text())
        if spec.get("generator") == "core.synthetic.demo_dataset":
            mine, _ = demo_dataset(int(spec["seed"]))
        elif spec.get("generator") == "core.synthetic.make_mine":
            mine = make_mine(**spec["kwargs"])
        elif spec.get("generator") == "core.synthetic.scenario":
            layout = {k: spec[k] for k in ("n_benches", "bench_height_m", "units") if k in spec}
            mine = make_family(spec["family"], spec["seed"], **layout)
        elif spec.get("generator") == "core.synthetic.shape_scenario":
            layout = {k: spec[k] for k in ("n_benches", "bench_height_m", "units") if k in spec}
            mine = make_shape(spec["shape"], spec["seed"], **layout)
        else:
            raise ValueError(f"unknown generator {spec.get('generator')!r}")
    except (ValueError, KeyError, TypeError) as exc:
        raise BGMInputError(f"truth file {side} is not usable: {exc}") from None
    truth = truth_from_mine(mine, holes.frame)
    _check_truth_describes(truth, holes, side, path)
    return truth


#: Fewer of a table's holes than this inside their own geozone's true section: its truth file describes another table.
MIN_TRUTH_AGREEMENT = 0.5


def truth_agreement(truth, holes: Blastholes) -> float:
    """The share of the holes that lie inside their own geozone's true section on their bench."""
    inside = 0
    for k in range(holes.n_benches):
        for g in holes.geozones:
            idx = holes.on_bench(k, g)
            if len(idx):
                try:
                    region = truth(g, float(holes.bench_levels_m[k]))
                except (KeyError, ValueError):  # a geozone the generator does not know
                    continue
                inside += int(np.sum(shapely.contains_xy(region, holes.xy[idx, 0], holes.xy[idx, 1])))
    return inside / max(len(holes.xy), 1)


def _check_truth_describes(truth, holes: Blastholes, side: Path, path: Path) -> None:
    """Refuse a truth file that does not describe the table beside it (moved, relabelled or replaced since).

    A generated table's holes lie in their true sections but for label
    noise (97-99% of them); scored against another table's truth, every
    figure of an evaluation would be meaningless, or it would fail with a
    message about contours.
    """
    share = truth_agreement(truth, holes)
    if share < MIN_TRUTH_AGREEMENT:
        raise BGMInputError(
            f"truth file {side} does not describe {path}: only {share:.0%} of its holes lie in their geozone's true "
            f"section (a generated table: 97-99%); the table was changed since it was generated: delete or rename "
            f"{side.name} to score against the holes of the next bench"
        )


def predictor_from_model(model: GeozoneModel, holes: Blastholes, params: ModelParameters):
    """Model predictor for the evaluation protocol, reusing an already built model.

    Each bench pair is modelled from its two benches only, so the pair
    ``(k-1, k)`` of the full model is what a model built on benches ``0..k``
    would have: no withheld label leaks in. But the hole spacing (and so the
    grids) is the whole table's, not that of benches ``0..k``; against ``bgm predict`` run on the
    table cut at bench ``k`` (strips and folds, held-out seed 7001, every
    bench, 40 predictions) the F1 differs by -1.3 to +3.4 points a case and
    +0.1 on average.
    """

    def predict(known: Blastholes, geozone: str, z_targets_m: list[float]):
        k = int(known.bench.max())
        pairs = [p for p in model.pairs if p.lower <= k]
        partial = GeozoneModel(
            model.geozone,
            [c for c in model.contours if c.bench <= k],
            pairs,
            model.minor,
            fields=None if model.fields is None else model.fields.through(float(holes.bench_levels_m[k])),
        )
        return predict_geozone(partial, list(z_targets_m), holes.hole_spacing_m, params, holes=known)

    return predict


@dataclass
class GeozoneSummary:
    geozone: str
    components: int
    bench_pairs: int
    coverage_before: float
    coverage_after: float
    volume: float | None  #: the whole surface's, down to a bench below the deepest
    area: float | None
    watertight: bool | None
    #: The part of ``volume`` between the top and the deepest bench: the rest is predicted below the deepest.
    volume_drilled: float | None = None
    files: dict = field(default_factory=dict)
    seconds: float = 0.0
    note: str = ""
    folder: str = ""  #: where its files are, under the build folder (see :func:`geozone_folders`)
    #: Per surface format: ``watertight`` as written (STL read back), and the STL's local-frame ``offset``.
    formats: dict = field(default_factory=dict)
    #: Where to sample next (see :func:`write_sampling`): calibration, band width, suggested holes, map.
    sampling: dict = field(default_factory=dict)
    #: How the depth trend carries the benches' movement on below the deepest bench (:func:`carried_json`).
    carried: dict | None = None


def build(
    holes: Blastholes,
    out_dir: Path,
    *,
    geozones: list[str] | None = None,
    params: ModelParameters | None = None,
    project=None,
    truth=None,
    formats=None,
    progress: Callable[[str, int, int], None] | None = None,
    evaluate: bool = True,
    workers: int | None = None,
    scheduler: str | None = None,
    cache=None,
) -> dict:
    """Run the whole pipeline and write every output under ``out_dir``.

    Benches (for contours) and geozones (for everything else) are
    independent: they run in parallel on ``workers`` local processes (all
    cores by default), or on a dask.distributed cluster when ``scheduler``
    gives its address, with identical results. Every stage runs through a
    :class:`~core.model.session.ModelSession`, the viewer's pipeline; with a
    :class:`~core.io.cache.StageCache` as ``cache`` its results are kept on
    disk for the next run. Surfaces are written in ``formats``
    (:func:`core.io.export.build_formats` by default: OMF too where its package is installed).

    ``progress(stage, done, total)`` is told the benches traced (stage
    ``"contours"``), the steps of each geozone's work (``"surface of geozone
    3310"``), reported by the worker processes as they go, and each geozone
    done (``"geozone 3310"``); :func:`core.model.progress.stage_unit` says
    what each counts.

    ``out_dir`` is replaced whole, but for what a geologist put in a previous
    model's geozone folders (:func:`user_files`): carried over into the same
    geozone's folder in the new model (by its label, whatever the folder is
    named this time, see :func:`carried_places`), geozone built this time or
    not, with a :class:`~core.errors.BGMWarning` naming them and where they went.

    Returns the summary that ``report.md`` and ``summary.json`` hold.
    """
    from core.io.export import build_formats, dxf_layer_names

    params = (params or ModelParameters()).validate()
    out_dir = check_output(out_dir, [holes.source], folder=True)
    check_model_folder(out_dir)
    wanted = holes.check_geozones(geozones)
    folders = geozone_folders(wanted)
    carried = user_files(out_dir)
    previous = previous_geozones(out_dir)
    places = carried_places(carried, previous, folders)
    with replaced_folder(out_dir) as staging:
        ctx = BuildContext(
            ModelSession(holes, params, project, StageStore(cache)),
            [],
            truth,
            staging,
            tuple(formats or build_formats()),
            evaluate,
            folders,
            dxf_layer_names(holes.geozones),  # a geozone's layer whichever geozones are built
            kept_folders(places, previous, folders),
        )
        summary = _build_into(ctx, wanted, progress, workers, scheduler)
        # Into the staging folder, before the swap: an interrupted build leaves them in the previous model.
        carry_over(out_dir, staging, places)
    if carried:
        warnings.warn(
            f"kept {len(carried)} file{'s' if len(carried) > 1 else ''} of yours that bgm build does not write, "
            f"carried over into the new model in {str(out_dir)!r}: {listing(p.as_posix() for p in carried)}"
            + _moved_folders(places, previous),
            BGMWarning,
            stacklevel=2,
        )
    return summary


def _moved_folders(places: dict[Path, Path], previous: dict[str, str]) -> str:
    """Where carried files went when their geozone's folder is named differently in this build ("" if nowhere)."""
    moves = sorted(
        {(rel.parts[0], target.parts[0]) for rel, target in places.items() if rel.parts[0] != target.parts[0]}
    )
    return "".join(
        f"; those of {old}/ went into {new}/, the folder of geozone {quoted(previous[old])} in this build"
        for old, new in moves
    )


def write_section_dxf(features: list[dict], z_key: str, path: Path, layers: dict | None = None) -> None:
    """Write the rings of GeoJSON-like section features as 3D polylines at their elevation ``z_key``.

    ``layers`` maps geozones to their DXF layers (see :func:`core.io.export.write_polylines_dxf`).
    """
    from core.io.export import polygon_rings, write_polylines_dxf

    rings = [
        (str(f["properties"]["geozone"]), float(f["properties"][z_key]), ring)
        for f in features
        for ring in polygon_rings(shape(f["geometry"]) if isinstance(f["geometry"], dict) else f["geometry"])
    ]
    write_polylines_dxf(rings, path, layers)


def _build_into(ctx: BuildContext, wanted: list[str], progress, workers, scheduler) -> dict:
    """Everything :func:`build` writes, into ``ctx.out_dir`` (its staging folder)."""
    from core.io.export import FORMAT_NOTES, json_default, write_geojson
    from core.model.evaluation import plot_precision_recall, rows_as_written, summary_as_written, summary_table

    holes, out_dir = ctx.session.holes, ctx.out_dir
    t0 = time.perf_counter()
    ctx.contours = extract_all_benches(ctx.session, workers, scheduler, progress)
    mine = [c for c in ctx.contours if c.geozone in wanted]
    features = [contour_feature(c, holes) for c in mine]
    write_geojson(features, out_dir / "contours.geojson", units=holes.frame.length_unit)
    write_section_dxf(features, "bench", out_dir / "contours.dxf", ctx.layers)
    containment = containment_summary(mine, holes)
    t_contours = time.perf_counter() - t0

    for k in range(holes.n_benches):
        holes.drilled_area(k)  # once, before the workers fork, so they all share it
    summaries: list[GeozoneSummary] = []
    evaluations = []
    for done, (summary, rows) in enumerate(_map_geozones(ctx, wanted, workers, scheduler, progress), start=1):
        summaries.append(summary)
        if rows is not None and len(rows):
            evaluations.append(rows)
        if progress:
            progress(geozone_stage(summary.geozone), done, len(wanted))
    summaries.sort(key=lambda s: wanted.index(s.geozone))
    evaluations.sort(key=lambda rows: wanted.index(rows["geozone"].iloc[0]))  # the same file whatever finished first
    table = None
    if evaluations:
        results = pd.concat(evaluations, ignore_index=True)
        _write_csv(rows_as_written(results, holes), out_dir / "evaluation_rows.csv")
        table = summary_as_written(summary_table(results), holes)  # depths in the input's units too (depth_ft)
        _write_csv(table, out_dir / "evaluation.csv")
        plot_precision_recall(
            table, out_dir / "precision_recall.png", title=f"{holes.source}: all geozones", unit=holes.frame.length_unit
        )

    # Said in the report and by bgm build: a build with no evaluation.csv and no word of why left one guessing.
    note = "" if table is not None else no_evaluation_note(holes.n_benches, ctx.evaluate)
    summary = {
        "input": holes.source,
        "holes": int(len(holes.xy)),
        "benches": [holes.bench_z_input(k) for k in range(holes.n_benches)],
        "units": holes.frame.length_unit,
        "hole_spacing": float(holes.frame.length_to_input(holes.hole_spacing_m)),
        "truth": "synthetic generator" if ctx.truth is not None else "next bench's holes",
        "contours_seconds": round(t_contours, 2),
        "seconds": round(time.perf_counter() - t0, 2),
        "containment": containment,
        "geozones": [s.__dict__ for s in summaries],
        "evaluation": None if table is None else table.round(4).to_dict(orient="records"),
        "evaluation_note": note,
        "formats": {f: FORMAT_NOTES[f] for f in ctx.formats},
        # Folders of geozones not built this time that hold the geologist's files: the next build's to keep,
        # with their geozones, by which the next build carries the files into each geozone's folder.
        "kept_folders": sorted(ctx.kept_folders),
        "kept_geozones": {f: g for f, g in sorted(ctx.kept_folders.items()) if g is not None},
    }
    text = json.dumps(_finite(summary), indent=1, default=json_default, allow_nan=False)
    atomic_write_text(out_dir / "summary.json", text)
    atomic_write_text(out_dir / "report.md", report_markdown(summary, table))
    return summary


def no_evaluation_note(n_benches: int, evaluated: bool) -> str:
    """Why a build has no evaluation (``evaluation_note`` of ``summary.json``, said in ``report.md``)."""
    if not evaluated:
        return "not evaluated: the evaluation was not asked for"
    if n_benches < 3:
        return (
            f"not evaluated: the protocol predicts a bench withheld below two known benches, so it needs three or "
            f"more benches; this input has {n_benches}"
        )
    return "not evaluated: no geozone built lies on a withheld bench below two known benches of its own to score"


#: Files a file browser leaves in any folder it shows (macOS Finder, Windows Explorer): nothing to lose.
FOLDER_METADATA = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})


def check_model_folder(out_dir: Path) -> None:
    """Refuse an output folder that holds anything ``bgm build`` did not write.

    The build replaces its folder whole; a folder that is new, empty, or a
    previous model (with nothing added at its top but a file browser's
    :data:`FOLDER_METADATA`) can be replaced without loss. Files added in a
    previous model's geozone folders are carried over (:func:`user_files`).
    """
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return
    entries = sorted(e.name for e in out_dir.iterdir() if e.name not in FOLDER_METADATA)
    if not entries:
        return
    known = _model_entries(out_dir)
    if known is None:
        raise BGMInputError(
            f"{str(out_dir)!r} is a folder holding other files ({listing(map(quoted, entries), 3)}), not a BGM "
            "model; the build replaces its output folder whole, so give a new or empty folder"
        )
    foreign = [e for e in entries if e not in known]
    if foreign:
        raise BGMInputError(
            f"{str(out_dir)!r} holds {listing(map(quoted, foreign), 3)}, which bgm build did not write; the "
            "build replaces the folder whole, so move that out or choose another folder"
        )


def _model_entries(out_dir: Path) -> set[str] | None:
    """Names a previous build wrote at the top of ``out_dir`` (None if it is not a BGM model)."""
    try:
        summary = json.loads((out_dir / "summary.json").read_text(encoding="utf-8"))
        geozones = summary["geozones"]
        summary["input"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    known = set(TOP_LEVEL_FILES)
    for g in geozones if isinstance(geozones, list) else []:
        if not isinstance(g, dict):
            continue
        if isinstance(g.get("folder"), str):
            known.add(g["folder"])
        for f in (g.get("files") or {}).values():
            known.add(Path(str(f)).parts[0])
        if isinstance(g.get("geozone"), str):  # builds before folders were recorded
            known.add(_legacy_folder(g["geozone"]))
    kept = summary.get("kept_folders")
    known.update(f for f in (kept if isinstance(kept, list) else []) if isinstance(f, str))
    return known


def user_files(out_dir: Path) -> list[Path]:
    """What a geologist put in a previous model's geozone folders: entries no build writes there.

    Paths relative to ``out_dir``, sorted; a folder put there is one entry
    (carried whole). Empty when ``out_dir`` is not a previous model. The
    build's own files (:data:`GEOZONE_FILES`) and a file browser's
    :data:`FOLDER_METADATA` are not among them.
    """
    out_dir = Path(out_dir)
    known = (_model_entries(out_dir) if out_dir.is_dir() else None) or set()
    found: list[Path] = []
    # The folder's own entries, not summary.json's names: a name there ("..", "/") is never a path to follow.
    for folder in sorted(out_dir.iterdir() if known else [], key=lambda e: e.name):
        if folder.name not in known or folder.name in TOP_LEVEL_FILES or folder.is_symlink() or not folder.is_dir():
            continue  # a linked folder's target is not deleted by the build
        found += [
            Path(folder.name, e.name)
            for e in sorted(folder.iterdir(), key=lambda e: e.name)
            if e.name not in GEOZONE_FILES and e.name not in FOLDER_METADATA
        ]
    return found


def previous_geozones(out_dir: Path) -> dict[str, str]:
    """The geozone label of each folder of the previous model in ``out_dir``, as its ``summary.json`` records them.

    Built geozones' folders (``folder``, or the name builds before folders were recorded gave a ``geozone``),
    and the folders kept for geozones not built (``kept_geozones``). Empty when ``out_dir`` holds no model.
    """
    try:
        summary = json.loads((Path(out_dir) / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(summary, dict):
        return {}
    labels: dict[str, str] = {}
    geozones = summary.get("geozones")
    for g in geozones if isinstance(geozones, list) else []:
        if isinstance(g, dict) and isinstance(g.get("geozone"), str):
            folder = g.get("folder")
            labels[folder if isinstance(folder, str) and folder else _legacy_folder(g["geozone"])] = g["geozone"]
    kept = summary.get("kept_geozones")
    for folder, label in (kept if isinstance(kept, dict) else {}).items():
        if isinstance(label, str):
            labels.setdefault(folder, label)
    return labels


def carried_places(carried: list[Path], previous: dict[str, str], folders: dict[str, str]) -> dict[Path, Path]:
    """Where each ``carried`` entry goes in the new model (paths relative to the model): into its geozone's folder.

    A folder is named for a label among the labels built (:func:`geozone_folders`): ``ox`` alone is ``ox/``,
    beside ``OX`` it is ``ox-<hash>/``, and a build of ``ox`` alone after one of both names it ``ox/`` again. Carried
    by folder name, the geologist's ``notes.txt`` of ``ox`` landed in a folder of no geozone beside the new one.
    Carried by the label the previous model recorded for the folder (``previous``, see :func:`previous_geozones`),
    it goes into that geozone's folder of this build (``folders``); a geozone not built keeps its folder, renamed
    as :func:`geozone_folders` distinguishes labels when a built geozone's folder now has its name but for case
    (the two would be one folder on a case-insensitive disk). Two entries sent to one place stay where they were.
    """
    built = {f.casefold() for f in folders.values()}
    places: dict[Path, Path] = {}
    for rel in carried:
        folder = rel.parts[0]
        label = previous.get(folder)
        if label is not None and label in folders:
            folder = folders[label]
        elif label is not None and folder.casefold() in built:
            folder = _hashed_folder(label)
        places[rel] = Path(folder, *rel.parts[1:])
    sent = Counter(places.values())
    return {rel: rel if sent[target] > 1 else target for rel, target in places.items()}


def kept_folders(places: dict[Path, Path], previous: dict[str, str], folders: dict[str, str]) -> dict[str, str | None]:
    """The folders carried entries go to that no geozone of this build writes, with their geozone (None: unknown).

    See :func:`carried_places`; ``previous`` maps the previous model's folders to their labels.
    """
    kept: dict[str, str | None] = {}
    for rel, target in places.items():
        if target.parts[0] not in folders.values():
            kept[target.parts[0]] = previous.get(rel.parts[0])
    return kept


def carry_over(out_dir: Path, staging: Path, places: dict[Path, Path]) -> None:
    """Copy each entry of ``out_dir`` in ``places`` to its place under ``staging``, byte for byte.

    Links are copied as links, and modification times kept, so the files are as the geologist left them.
    """
    for rel, place in places.items():
        source, target = Path(out_dir) / rel, Path(staging) / place
        target.parent.mkdir(exist_ok=True)
        try:
            if source.is_dir() and not source.is_symlink():
                shutil.copytree(source, target, symlinks=True)
            else:
                shutil.copy2(source, target, follow_symlinks=False)
        except OSError as exc:
            raise BGMInputError(
                f"cannot carry {rel.as_posix()!r} over into the new model: {exc.strerror or exc}; the previous "
                f"model in {str(out_dir)!r} is untouched"
            ) from None


def geozone_folders(labels: list[str]) -> dict[str, str]:
    """A safe, unique folder name for each geozone label.

    Labels are free text (``..``, ``a/b``, 300 characters, ``CON``). A folder
    name keeps letters, digits, ``-`` and ``_`` (and inner dots), at most
    ``MAX_FOLDER_CHARS`` of them; a label changed on the way, or whose name
    would collide with another's (``A`` and ``a`` on a case-insensitive disk)
    or with a file of the build, gets the first 8 hex digits of its SHA-1, so
    distinct labels never share a folder. ``summary.json`` and ``report.md``
    map the folders back to the labels.
    """
    bases = {g: _folder_base(g) for g in labels}
    clean = Counter(g.casefold() for g, base in bases.items() if base == g)
    taken = {f.casefold() for f in TOP_LEVEL_FILES}
    folders = {}
    for g, base in bases.items():
        kept = base == g and clean[g.casefold()] == 1 and g.casefold() not in taken and not _RESERVED.fullmatch(g)
        folders[g] = base if kept else _hashed_folder(g)
    if len({f.casefold() for f in folders.values()}) < len(folders):  # 8 hex digits clashed: use them all
        folders = {g: f"{bases[g]}-{hashlib.sha1(g.encode()).hexdigest()}" for g in labels}
    return folders


def _hashed_folder(label: str) -> str:
    """The folder of a label told apart from its look-alikes: its base, then 8 hex digits of its SHA-1 (``ox-1a2b3c4d``).

    One rule for :func:`geozone_folders` and :func:`carried_places`: a kept folder renamed by the one is the
    folder the other gives the label.
    """
    return f"{_folder_base(label)}-{hashlib.sha1(label.encode()).hexdigest()[:8]}"


def _folder_base(label: str) -> str:
    name = "".join(ch if (ch.isascii() and ch.isalnum()) or ch in "-_." else "_" for ch in label)
    name = name[:MAX_FOLDER_CHARS].strip(".") or "geozone"  # no "..", no hidden folders, no trailing dot
    return name


def _legacy_folder(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name) or "geozone"


def _finite(obj):
    """``obj`` with every non-finite float replaced by None (JSON has no NaN)."""
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, np.floating):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


@dataclass
class BuildContext:
    """What every geozone job needs (shared with worker processes by fork)."""

    session: ModelSession  #: the input, parameters, project overrides and stage store
    contours: list[Contour]
    truth: Callable[[str, float], shapely.MultiPolygon] | None
    out_dir: Path
    formats: tuple
    evaluate: bool
    folders: dict = field(default_factory=dict)  #: geozone label -> its folder (see :func:`geozone_folders`)
    #: Geozone label -> its layer in every DXF of the build (:func:`core.io.export.dxf_layer_names` of the input's).
    layers: dict = field(default_factory=dict)
    #: Folders of geozones not built this time kept for the geologist's files in them, with their geozone
    #: (:func:`kept_folders`).
    kept_folders: dict = field(default_factory=dict)


#: Set once per worker process by _init_worker: a build's context, or the session whose benches are extracted.
_WORKER_CONTEXT: BuildContext | ModelSession | None = None
#: Set with it: the queue a job's steps go to, read by the parent (None: its jobs report none).
_WORKER_STEPS = None


def _init_worker(ctx: BuildContext | ModelSession, parent: int, steps=None) -> None:
    # Ctrl-C reaches every process of the terminal's group: the parent alone
    # handles it (one line, exit 130) and stops the workers, by SIGTERM, which
    # must end them (the parent's handler, inherited by fork, would not).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    _end_with_parent(parent)
    global _WORKER_CONTEXT, _WORKER_STEPS
    _WORKER_CONTEXT, _WORKER_STEPS = ctx, steps


#: ``prctl`` option: the signal this process gets when the thread that forked it ends (Linux).
PR_SET_PDEATHSIG = 1


def _end_with_parent(parent: int) -> None:
    """End this worker when its parent (pid ``parent``) dies, even by SIGKILL, where the system allows (Linux).

    Else a worker whose parent was killed finishes its job into a folder no
    one will read, then waits for work forever.
    """
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:  # it died before the line above
        os._exit(1)


def _map_geozones(
    ctx: BuildContext, geozones: list[str], workers: int | None, scheduler: str | None = None, steps=None
):
    """Yield ``build_geozone`` results as they finish, in parallel where it pays; their steps said to ``steps``."""
    # Largest geozones first so the last job to start is a short one.
    order = sorted(geozones, key=lambda g: -int(np.sum(ctx.session.holes.geozone == g)))
    yield from _parallel_map(build_geozone, ctx, order, workers, scheduler, steps)


#: How often the parent says the steps its workers reported while it waits for their results (seconds).
STEPS_POLL_S = 0.2


def _parallel_map(func, ctx, items: list, workers: int | None, scheduler: str | None, steps=None):
    """``func(ctx, item)`` for every item: serially, on local processes, or on a dask cluster.

    Local workers ignore Ctrl-C; when the caller stops early (an error, an
    interrupt) they are terminated rather than left to finish their jobs.

    With ``steps`` (a ``progress(stage, done, total)``), ``func`` is called
    as ``func(ctx, item, progress)`` and what it reports is said to
    ``steps`` in this process, as it happens and before the item's result:
    the workers put it on a queue the parent reads while it waits. A dask
    cluster has no such channel: there ``func`` is given no progress.
    """
    import multiprocessing

    if scheduler:
        yield from _dask_map(func, ctx, items, scheduler)
        return
    workers = available_cores() if workers is None else workers
    if workers <= 1 or len(items) <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        for item in items:
            yield func(ctx, item) if steps is None else func(ctx, item, steps)
        return
    context = multiprocessing.get_context("fork")
    # A SimpleQueue's put writes to its pipe at once (a Queue's feeder thread may lag): a job's steps are
    # in the pipe before its result is sent, so the parent, reading the pipe first, says them first.
    queue = None if steps is None else context.SimpleQueue()
    yield from _pool_map(func, ctx, items, workers, context, queue, steps)


def _pool_map(func, ctx, items: list, workers: int, context, queue, steps):
    """:func:`_parallel_map` on local worker processes (``queue``: their steps, said to ``steps``)."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    pool = ProcessPoolExecutor(
        max_workers=min(workers, len(items)),
        mp_context=context,
        initializer=_init_worker,
        initargs=(ctx, os.getpid(), queue),
    )
    try:
        # Workers are forked on the first submit: with SIGINT blocked they are
        # born ignoring it, and a Ctrl-C meanwhile reaches the parent just after.
        with _sigint_blocked():
            pending = {pool.submit(_call_in_worker, func, item) for item in items}
        while pending:
            finished, pending = wait(pending, timeout=STEPS_POLL_S if queue else None, return_when=FIRST_COMPLETED)
            while queue is not None and not queue.empty():
                steps(*queue.get())
            for fut in finished:
                yield fut.result()
        # Inside the try: a Ctrl-C cutting this short would leave idle workers waiting for work forever.
        pool.shutdown(wait=True)
    except BaseException:
        _stop_workers(pool)
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    finally:
        if queue is not None:
            queue.close()


@contextlib.contextmanager
def _sigint_blocked():
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _stop_workers(pool) -> None:
    """Terminate a process pool's workers now (``ProcessPoolExecutor.terminate_workers`` from Python 3.14)."""
    stop = getattr(pool, "terminate_workers", None)
    if stop is not None:
        stop()
        return
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        with contextlib.suppress(Exception):
            process.terminate()


#: How long a build waits for a dask scheduler to answer before saying it cannot reach it (seconds).
SCHEDULER_TIMEOUT_S = 10.0


def _dask_map(func, ctx, items: list, scheduler: str):
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise BGMInputError("--scheduler needs dask.distributed: pip install -e '.[dask]'") from None
    try:
        client = Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S:g}s")
    except Exception as exc:  # a bad address raises ValueError, TypeError, OSError... all the user's to fix
        reason = " ".join(str(exc).split())[:200]
    else:
        reason = None
    if reason is not None:
        # The half-made client lingers in a reference cycle, and its finaliser takes the lock every client's start
        # holds: run by a garbage collection in the thread the next client started, it deadlocked that start (a
        # test process that tried two bad addresses hung). Collected here, where no client is starting.
        gc.collect()
        raise BGMInputError(f"cannot reach the dask scheduler at {quoted(scheduler)}: {reason}")
    try:
        shared = client.scatter(ctx, broadcast=True)
        futures = [client.submit(func, shared, item, pure=False) for item in items]
        for fut in as_completed(futures):
            yield fut.result()
    finally:
        client.close()


#: Stages whose results every job of a worker reads (made before the workers fork): kept between jobs.
SHARED_STAGES = ("contours", "drilled")


def _call_in_worker(func, item):
    queue = _WORKER_STEPS
    try:
        if queue is None:
            return func(_WORKER_CONTEXT, item)
        return func(_WORKER_CONTEXT, item, lambda stage, done, total: queue.put((stage, done, total)))
    finally:
        # A worker's next job is another geozone or bench: what this one computed is never asked for again
        # there (its results went back to the parent), and held it grew each worker by ~100 MB a geozone.
        session = _WORKER_CONTEXT.session if isinstance(_WORKER_CONTEXT, BuildContext) else _WORKER_CONTEXT
        if session is not None:
            session.store.forget(keep=SHARED_STAGES)


def extract_all_benches(session: ModelSession, workers=None, scheduler=None, progress=None) -> list[Contour]:
    """Contours of every bench, benches in parallel; in bench order whatever order they finish in."""
    holes = session.holes
    by_bench = {}
    for done, (k, contours) in enumerate(
        _parallel_map(_extract_one_bench, session, list(range(holes.n_benches)), workers, scheduler), start=1
    ):
        by_bench[k] = contours
        if progress:
            progress(CONTOURS_STAGE, done, holes.n_benches)
    for k, contours in by_bench.items():  # from worker processes: remembered here (they cached them on disk)
        session.store.put("contours", session._contours_key(k), contours, disk=False)
    return [c for k in sorted(by_bench) for c in by_bench[k]]


def _extract_one_bench(session: ModelSession, k: int):
    return k, session.bench_contours(k)


def build_geozone(ctx: BuildContext, g: str, progress=None) -> tuple[GeozoneSummary, pd.DataFrame | None]:
    """Everything ``bgm build`` writes for one geozone, under ``out_dir/<geozone>/``.

    ``progress(stage, done, total)`` is told each step as it is done (its
    bench pairs, bench fields, predictions, uncertainty, surface and
    evaluation: :class:`core.model.progress.GeozoneSteps`).
    """
    from core.io.export import write_geojson
    from core.model.evaluation import evaluate_geozone

    session, out_dir = ctx.session, ctx.out_dir
    holes, params = session.holes, session.params
    tg = time.perf_counter()
    evaluated = ctx.evaluate and holes.n_benches >= 3
    after = ("predictions", "uncertainty", "surface", *(("evaluation",) if evaluated else ()))
    steps = GeozoneSteps(progress, g, after)
    model = session.geozone_model(g, contours=ctx.contours, progress=steps.pair)
    gdir = out_dir / (ctx.folders.get(g) or geozone_folders([g])[g])
    gdir.mkdir(exist_ok=True)
    folder = gdir.name
    atomic_write_text(gdir / "correspondence.json", json.dumps(correspondence_json(model, holes), indent=1))
    atomic_write_text(gdir / "morph.json", json.dumps(morph_json(model, holes)))
    cov = [pair_coverage(p) for p in model.pairs if p.morphs]
    after = [a for a, _ in cov if np.isfinite(a)]
    before = [b for _, b in cov if np.isfinite(b)]
    summary = GeozoneSummary(
        geozone=g,
        components=len(model.contours),
        bench_pairs=len(model.pairs),
        coverage_before=float(np.median(before)) if before else float("nan"),
        coverage_after=float(np.median(after)) if after else float("nan"),
        volume=None,
        area=None,
        watertight=None,
        folder=folder,
    )
    rows = None
    if not model.pairs:
        summary.note = no_pair_note(holes, g, params.min_component_holes)
        summary.seconds = time.perf_counter() - tg
        return summary, rows
    steps.step(FIELDS_STEP)  # made by geozone_model after its last pair
    # Below the table's deepest bench, by its deepest pair's height, whichever bench the geozone's pairs end on:
    # a geozone whose pairs end higher up was predicted between two known benches, where no pair of it is and
    # so always absent, while the depth trend may carry it on below the deepest (`bgm predict` there).
    zs = [holes.below_deepest_m(f) for f in PREDICTION_FRACTIONS]
    predictions = session.predict(g, zs, model)
    features = [
        prediction_feature(region, holes, g, round(float(holes.frame.z_to_input(z)), 3))
        for z, region in predictions.items()
    ]
    for feature, f in zip(features, PREDICTION_FRACTIONS):
        feature["properties"]["fraction_below"] = f
    features = [f for f in features if not f["geometry"].is_empty]
    write_geojson(features, gdir / "prediction.geojson", units=holes.frame.length_unit)
    write_section_dxf(features, "z", gdir / "prediction.dxf", ctx.layers)
    summary.carried = carried_json(session.carried_movement(g, model), holes)
    steps.step("predictions")
    summary.sampling = write_sampling(ctx.session, model, predictions, gdir, ctx.out_dir)
    steps.step("uncertainty")
    summary.note = undrilled_below_note(session, model)
    _write_surface(summary, model, ctx, gdir)
    steps.step("surface")
    if evaluated:
        rows = evaluate_geozone(
            holes, g, predictor_from_model(model, holes, params), truth=ctx.truth, contours=ctx.contours
        )
        if len(rows):
            rows.insert(0, "geozone", g)
        steps.step("evaluation")
    summary.seconds = time.perf_counter() - tg
    return summary, rows


#: Share of the next bench's candidate holes in a geozone's band that the build suggests sampling.
SUGGESTION_SHARE = 0.1


def write_sampling(session: ModelSession, model: GeozoneModel, predictions: dict, gdir: Path, out_dir: Path) -> dict:
    """The uncertainty of the geozone's predictions and the holes to sample on the next bench, under ``gdir``.

    Writes ``uncertainty.geojson`` (90% band, inner and outer polygons of
    every predicted section), ``p_inside.npz`` (P(inside) grids),
    ``suggestions.csv`` (:data:`SUGGESTION_SHARE` of the next bench's
    candidate holes that lie in the band, one bench below the deepest, laid
    out on the deepest bench's pattern) and ``where_to_sample.png`` (its
    map, when matplotlib is there). Returns what the report says of it.
    """
    from core.io.export import write_geojson
    from core.io.uncertainty_export import (
        band_features,
        plot_sampling_map,
        probability_grid,
        suggestions_table,
        write_probability_grid,
        write_suggestions,
    )
    from core.model.sampling import next_bench_candidates, plan_sampling
    from core.model.uncertainty import DEFAULT_PROBABILITY, band_width_m, geozone_uncertainty

    holes, g = session.holes, model.geozone
    z_next = holes.below_deepest_m()
    # The next bench the suggestions are for has its band in the files too, predicted level or not.
    at = [z for z in predictions if np.isclose(z, z_next)]
    z_next = at[0] if at else z_next
    sections = geozone_uncertainty(session, g, sorted({*predictions, z_next}, reverse=True), model, DEFAULT_PROBABILITY)
    write_geojson(band_features(sections, holes, g), gdir / "uncertainty.geojson", units=holes.frame.length_unit)
    write_probability_grid(gdir / "p_inside.npz", probability_grid(sections, holes, g))
    try:
        candidates = next_bench_candidates(holes)
    except ValueError as exc:
        return {"note": f"no suggestions: {exc}"}
    section = sections[z_next]
    if section is None:
        return {"note": "no suggestions: no predicted boundary on the next bench"}
    # Predicted absent, the geozone has no contact for its band's holes to be near (see suggest_holes).
    in_band = int(section.in_band(candidates).sum()) if len(candidates) and section.has_contact else 0
    budget = max(int(round(SUGGESTION_SHARE * in_band)), 1) if in_band else 0
    plan = plan_sampling(session, [g], budget, z_next, candidates, sections={g: section})
    write_suggestions(gdir / "suggestions.csv", suggestions_table(plan.suggestions, holes, z_next, plan.probability))
    picture = plot_sampling_map(plan, holes, gdir / "where_to_sample.png", f"{g}: next bench")
    width = band_width_m(section, holes.drilled_area(holes.n_benches - 1))
    return {
        "z": round(float(holes.frame.z_to_input(z_next)), 3),
        "probability": plan.probability,
        "calibration": section.scale.source,
        "band_width": None if not np.isfinite(width) else float(holes.frame.length_to_input(width)),
        "candidates_in_band": in_band,
        "suggested": len(plan.suggestions),
        "map": None if picture is None else str(picture.relative_to(out_dir)),
    }


def _write_surface(summary: GeozoneSummary, model: GeozoneModel, ctx: BuildContext, gdir: Path) -> None:
    """The geozone's closed surface in every format; its figures (or why there is none) go into ``summary``."""
    from core.io.export import export_all
    from core.model.surfaces import mesh_summary, surface_as_written, volume_above

    holes = ctx.session.holes
    mpu = holes.frame.metres_per_unit
    try:
        mesh = ctx.session.surface(model.geozone, model)
        info = mesh_summary(mesh)
        surface = surface_as_written(mesh, holes)
        exported = export_all(
            surface,
            gdir,
            "surface",
            ctx.formats,
            name=model.geozone,
            layer=ctx.layers.get(model.geozone),
            units=holes.frame.length_unit,
        )
        summary.volume = info["volume_m3"] / mpu**3
        if info["watertight"]:  # a volume only a closed surface has
            summary.volume_drilled = volume_above(mesh, float(holes.bench_levels_m[-1])) / mpu**3
        summary.area = info["area_m2"] / mpu**2
        summary.watertight = bool(info["watertight"])
        summary.files = {k: str(Path(v).relative_to(ctx.out_dir)) for k, v in exported.items()}
        summary.formats = written_formats(exported, surface, summary.watertight)
    except (BGMInputError, RuntimeError) as exc:
        # e.g. every section empty, or a mesh that would not close even after repair: the
        # geozone's other outputs stand, and the report says why it has no surface.
        summary.note = "; ".join(n for n in (summary.note, f"no surface: {exc}") if n)


def undrilled_below_note(session: ModelSession, model: GeozoneModel) -> str:
    """What the report says of a geozone whose last bench is above the deepest and the bench below it drilled
    less than half of it there: its body ends for want of drilling, not of the geozone, and below that bench
    its surface and predictions are its depth trend (:func:`core.model.prediction.undrilled_extension`).

    Empty otherwise: a geozone the bench below drilled and did not find closes above it
    (a pit narrowing with depth leaves parts of most bodies undrilled below; only where the whole end is
    undrilled is it said).
    """
    holes = session.holes
    on = [c.bench for c in model.contours if not c.polygon.is_empty]
    last = max(on, default=holes.n_benches - 1)
    if last >= holes.n_benches - 1:
        return ""
    body = as_multipolygon(model.region_at_bench(last))
    drilled = body.intersection(session.drilled_area(last + 1)).area / body.area if body.area > 0 else 1.0
    if drilled >= 0.5:
        return ""
    return (
        f"last on bench {holes.bench_z_input(last):g} {holes.frame.length_unit}, of which the bench below drilled "
        f"{100 * drilled:.0f}%: below it the surface and predictions are the depth trend, not drilled ground"
    )


def written_formats(exported: dict, surface, watertight: bool) -> dict:
    """What each surface file holds: closed as written, and for STL the offset of its local frame.

    The float64 formats hold the mesh exactly, so they are as closed as it is;
    the STL is read back (its float32 vertices merged as every reader merges
    them) and checked.
    """
    import trimesh

    from core.io.export import stl_offset

    formats: dict[str, dict] = {}
    for fmt, path in exported.items():
        formats[fmt] = {"watertight": watertight}
        if fmt == "stl":
            formats[fmt]["watertight"] = bool(trimesh.load(path, force="mesh").is_watertight)  # type: ignore[attr-defined]  # a Trimesh with force="mesh"
            formats[fmt]["offset"] = [float(v) for v in stl_offset(surface.vertices)]
    return formats


def _write_csv(df: pd.DataFrame, path: Path) -> None:
    atomic_write_text(path, df.to_csv(index=False))


def report_markdown(summary: dict, table: pd.DataFrame | None) -> str:
    """``report.md``: what was built, how well contours separate geozones, and how well the model predicts."""
    unit = summary["units"]
    lines = [
        "# BGM build report",
        "",
        f"Input: `{summary['input']}`: {summary['holes']} holes on {len(summary['benches'])} benches "
        f"({summary['benches'][0]} to {summary['benches'][-1]} {unit}), hole spacing {summary['hole_spacing']:.2f} {unit}.",
        f"Built in {summary['seconds']:.1f} s (contours {summary['contours_seconds']:.1f} s).",
        "",
        "## Contours",
        "",
    ]
    c = summary["containment"]
    if c.get("contours"):
        lines += [
            f"{c['contours']} contours of {c['min_holes']} or more holes: median {c['holes_inside_median']:.1%} of "
            f"their own holes inside ({c['contours_with_95pct_inside']:.0%} of contours hold at least 95%), median "
            f"{c['other_holes_inside_median']:.1%} other-geozone holes inside "
            f"({c['contours_with_at_most_5pct_other']:.0%} of contours at most 5%).",
            "",
        ]
    lines += (
        _geozone_table(summary) + _surfaces_section(summary) + _carried_section(summary) + _sampling_section(summary)
    )
    if table is not None:
        lines += [
            "## Predictive value",
            "",
            f"Protocol of the paper's Table: for each bench with two known benches above it, everything below is withheld "
            f"and the geozone is predicted at fractions of a bench below it. Truth: {summary['truth']}. Precision and "
            "recall are area-weighted over all geozones and benches (%), F1 their harmonic mean; `f1_margin` is the "
            "model's F1 less the best reference's (`f1_holes_`: scored on the withheld benches' holes, real data).",
            "",
            "![precision and recall](precision_recall.png)",
            "",
            _markdown_table(table),
            "",
        ]
    elif summary.get("evaluation_note"):
        note = summary["evaluation_note"]
        lines += ["## Predictive value", "", f"{note[0].upper()}{note[1:]}.", ""]
    return "\n".join(lines)


def _geozone_table(summary: dict) -> list[str]:
    """The geozones section of ``report.md``: one row per geozone, with the folder holding its files."""
    unit = summary["units"]
    lines = [
        "## Geozones",
        "",
        "Each surface runs from the top bench to one bench below the deepest, that last bench predicted; its "
        "volume down to the deepest bench is the known benches' part. Where a bench did not drill ground that "
        "the benches above it did (a pit narrowing with depth), the surface holds the depth trend there, as "
        "below the deepest bench, until that evidence has likely run out; it does not end at the drilling edge.",
        "",
        f"| geozone | components | bench pairs | coverage before / after backtracking | volume ({unit}³) "
        f"| of it down to the deepest bench ({unit}³) | area ({unit}²) | watertight | time (s) | note | folder |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for g in summary["geozones"]:
        vol = "" if g["volume"] is None else f"{g['volume']:.4g}"
        drilled = "" if g.get("volume_drilled") is None else f"{g['volume_drilled']:.4g}"
        area = "" if g["area"] is None else f"{g['area']:.4g}"
        cov = f"{_pct(g['coverage_before'])} / {_pct(g['coverage_after'])}"
        open_in = [f for f, w in g.get("formats", {}).items() if w["watertight"] != g["watertight"]]
        closed = "" if g["watertight"] is None else str(g["watertight"])
        if open_in:
            closed += f" ({', '.join(open_in)}: {not g['watertight']})"
        lines.append(
            f"| {_cell(g['geozone'])} | {g['components']} | {g['bench_pairs']} | {cov} | {vol} | {drilled} | {area} | "
            f"{closed} | {g['seconds']:.1f} | {_cell(g['note'], 200)} | `{g.get('folder', '')}` |"
        )
    return lines


def _surfaces_section(summary: dict) -> list[str]:
    """Where the surfaces are and what each format holds, STL's local frame included."""
    formats = summary.get("formats", {})
    lines = [
        "",
        f"Surfaces: `<folder>/surface.{{{','.join(formats)}}}`; trajectories: `<folder>/morph.json`. "
        "Watertight: as written to every format.",
        "",
    ]
    lines += [f"- {fmt}: {note}" for fmt, note in formats.items()]
    offsets = {tuple(g["formats"]["stl"]["offset"]) for g in summary["geozones"] if "stl" in g.get("formats", {})} - {
        (0.0, 0.0, 0.0)
    }
    for offset in sorted(offsets):
        lines.append(f"  STL offset: add ({', '.join(f'{v:.0f}' for v in offset)}) {summary['units']} to x, y, z.")
    return [*lines, ""]


def _carried_section(summary: dict) -> list[str]:
    """Below the deepest bench: how much of each geozone's movement its depth trend carries on, and what chose it."""
    unit = summary["units"]
    rows = [g for g in summary["geozones"] if g.get("carried")]
    if not rows:
        return []
    lines = [
        "## Below the deepest bench",
        "",
        "Each geozone's boundary moves on below the deepest bench as its benches moved, as far as they show it "
        "(trajectories give the movement, the geozone's own benches how much of it goes on: each bench predicted "
        "from the benches above it each way, the way with the least area on the wrong side taken). Movement: how "
        "far the deepest section's boundary moves a bench down (median / 90th percentile). Gaps filled: the "
        "deepest section's gaps and embayments narrower than this are filled a bench below, where the benches "
        "showed such gaps filling (the same backtest, with and without).",
        "",
        f"| geozone | movement carried | chosen by | persistence (outlines / finer) | movement a bench ({unit}) "
        f"| backtest: area wrong, agreement / all / none ({unit}²) | gaps filled under ({unit}) |",
        "|---|---|---|---|---|---|---|",
    ]
    for g in rows:
        c = g["carried"]
        moved = c[f"movement_per_bench_{unit}"]
        wrong = c[f"backtest_wrong_area_{unit}2"]
        gaps = c[f"gaps_filled_narrower_than_{unit}"]
        lines.append(
            f"| {_cell(g['geozone'])} | {carried_words(c)} | {CHOSEN_WORDS[c['chosen_by']]} | "
            f"{c['persistence'][0]:.2f} / {c['persistence'][1]:.2f} | "
            f"{'' if moved is None else f'{moved[0]:.1f} / {moved[1]:.1f}'} | "
            f"{'' if wrong is None else ' / '.join(f'{wrong[w]:.0f}' for w in ('agreement', 'all', 'none'))} | "
            f"{'' if gaps is None else f'{gaps:.1f}'} |"
        )
    return [*lines, ""]


def _sampling_section(summary: dict) -> list[str]:
    """Where to sample next: each geozone's band on the next bench and the holes suggested there, with its map."""
    unit = summary["units"]
    rows = [g for g in summary["geozones"] if g.get("sampling")]
    if not rows:
        return []
    lines = [
        "## Where to sample next",
        "",
        "The band holds the true boundary with the stated probability, calibrated by predicting each known bench "
        "from the benches above it (the input's other geozones pooled when a geozone has too few). Suggested holes, "
        f"{SUGGESTION_SHARE:.0%} of the next bench's holes in the band (laid out on the deepest bench's pattern), are "
        "those whose labels would most narrow it: `<folder>/suggestions.csv`; bands in `<folder>/uncertainty.geojson`, "
        "P(inside) grids in `<folder>/p_inside.npz`. `bgm suggest` chooses any number of holes, or from a planned pattern.",
        "",
        f"| geozone | next bench ({unit}) | band | calibration | median band width ({unit}) | holes in band | suggested |",
        "|---|---|---|---|---|---|---|",
    ]
    for g in rows:
        s = g["sampling"]
        if "note" in s:
            lines.append(f"| {_cell(g['geozone'])} | | | | | | {_cell(s['note'], 200)} |")
            continue
        width = "" if s["band_width"] is None else f"{s['band_width']:.1f}"
        lines.append(
            f"| {_cell(g['geozone'])} | {s['z']:g} | {s['probability']:.0%} | {s['calibration']} | {width} | "
            f"{s['candidates_in_band']} | {s['suggested']} |"
        )
    lines.append("")
    for g in rows:
        if g["sampling"].get("map"):
            lines += [f"![{_cell(g['geozone'])}: where to sample next]({g['sampling']['map']})", ""]
    return lines


def _cell(text, limit: int = 60) -> str:
    """User text in a markdown table cell: one line, no column breaks, shortened."""
    text = " ".join(str(text).split()).replace("|", "\\|")
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _pct(v) -> str:
    return "" if v is None or not np.isfinite(v) else f"{v:.1%}"


def _markdown_table(table: pd.DataFrame) -> str:
    """The evaluation in percent, its depths first: in metres, and in the input's units as well (``depth_ft``)."""
    cols = [c for c in table.columns if c.startswith("depth")]
    cols += [c for c in table.columns if c.startswith(("precision", "recall", "f1_"))]
    head = "| " + " | ".join(cols) + " |"
    rule = "|" + "---|" * len(cols)
    rows = []
    for _, r in table.iterrows():
        cells = []
        for c in cols:
            v = r[c]
            if c.startswith("depth"):
                cells.append(f"{v:.2f}")
            else:
                cells.append("" if not np.isfinite(v) else f"{100 * v:.1f}")
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join([head, rule, *rows])


def no_pair_note(holes, geozone: str, min_component_holes: int) -> str:
    """Why a geozone has no bench pair to model: ``on 3 benches, never in a component of 3 or more holes: ...``.

    Said by ``bgm build`` (the report's note) and by the commands that model one geozone,
    which wrote ``"pairs": []`` with no word of why.
    """
    benches = len(set(holes.bench[holes.geozone == geozone].tolist()))
    return (
        f"on {'one bench' if benches == 1 else f'{benches} benches'}, never in a component of "
        f"{min_component_holes} or more holes: no bench pair to model"
    )
