"""Property-based tests (hypothesis) over random labelled point sets and random shapes.

* extraction always returns valid, closed, non-empty polygons, and every
  contour of 15 or more holes holds at least 90% of them;
* alignment never shifts a source outside the padded frame;
* the morph never produces NaN (``arrival_time`` is nan only where the
  documentation says: cells the front never had to cross);
* trajectories never cross;
* exported meshes are watertight and re-read with the same faces;
* a length in hole spacings over cells in hole spacings is the same whole number of
  cells whatever the spacing;
* a polygon's cells are those scikit-image draws;
* a point's distance to a region's boundary is GEOS's to the whole boundary, holes included;
* a Gaussian filtered over the box of an array's non-zero cells is the whole array's, to the bit;
* reading: geozone labels merge exactly when they spell one number (codes with leading
  zeros never), columns are found whatever their case, spaces and order, two candidates
  for one role are refused, decimal commas and thousands separators read as numbers.

Example counts keep the whole file well under 90 s (about 20 s here).
"""

from __future__ import annotations

import math
import warnings
from decimal import Decimal

import numpy as np
import pandas as pd
import pytest
import shapely
import trimesh
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy import ndimage
from shapely import affinity
from shapely.geometry import MultiPolygon, Polygon

from core.correspondence.pair import correspond_pair, fft_translation
from core.errors import BGMInputError
from core.extraction.contours import extract_contours
from core.geometry.grid import cells_covering, local_gaussian_filter
from core.geometry.sdf import boundary_distance, signed_distance
from core.io.blastholes import (
    COLUMN_ALIASES,
    ZERO_FRACTION,
    BGMWarning,
    _without_digit_grouping,
    blastholes_from_table,
    find_column,
    label_number,
    merge_number_spellings,
    number_label,
    table_columns,
)
from core.io.export import export_surface
from core.io.reporting import containment, to_input_geometry
from core.model.surfaces import surface_from_sections
from core.morph.levelset import morph_regions
from core.morph.trajectories import crossing_pairs

SETTINGS = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large]}


def blob(cx: float, cy: float, radius: float, harmonics=(), n: int = 96) -> Polygon:
    """Star-shaped polygon ``R (1 + sum a_k cos(k theta + phase_k))`` (valid for sum |a_k| < 1)."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = np.ones_like(th)
    for k, a, ph in harmonics:
        r += a * np.cos(k * th + ph)
    r *= radius
    return Polygon(np.column_stack([cx + r * np.cos(th), cy + r * np.sin(th)]))


harmonics = st.lists(
    st.tuples(st.integers(2, 4), st.floats(-0.15, 0.15), st.floats(0, 2 * np.pi)), min_size=0, max_size=2
)


@st.composite
def blobs(draw, centre=20.0, r_min=8.0, r_max=25.0):
    return blob(
        draw(st.floats(-centre, centre)),
        draw(st.floats(-centre, centre)),
        draw(st.floats(r_min, r_max)),
        draw(harmonics),
    )


# ---------------------------------------------------------------------------
# Extraction on random labelled point sets


@st.composite
def labelled_holes(draw):
    """A jittered drill pattern (spacing 3-10 m) labelled by random blobs, with label noise."""
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    spacing = draw(st.floats(3.0, 10.0))
    nx, ny = draw(st.integers(8, 22)), draw(st.integers(8, 22))
    stagger = draw(st.booleans())
    gx, gy = np.meshgrid(np.arange(nx, dtype=float), np.arange(ny, dtype=float))
    if stagger:
        gx = gx + 0.5 * (gy % 2)
        gy = gy * math.sqrt(3) / 2
    xy = np.column_stack([gx.ravel(), gy.ravel()]) * spacing
    xy += rng.normal(0.0, draw(st.floats(0.0, 0.15)) * spacing, xy.shape)
    labels = np.full(len(xy), "host", dtype=object)
    w, h = xy.max(axis=0)
    for g in range(draw(st.integers(1, 3))):
        shape = blob(
            rng.uniform(0, w),
            rng.uniform(0, h),
            rng.uniform(1.5, 6.0) * spacing,
            [(int(rng.integers(2, 5)), rng.uniform(-0.2, 0.2), rng.uniform(0, 2 * np.pi))],
        )
        labels[shapely.contains_xy(shape, xy[:, 0], xy[:, 1])] = f"g{g}"
    noise = draw(st.floats(0.0, 0.05))
    flip = rng.random(len(xy)) < noise
    present = sorted(set(labels.tolist()))
    if len(present) > 1:
        labels[flip] = [rng.choice([p for p in present if p != lab]) for lab in labels[flip]]
    origin = draw(st.sampled_from([(0.0, 0.0), (650_000.0, 7_400_000.0)]))
    table = pd.DataFrame(
        {
            "x": xy[:, 0] + origin[0],
            "y": xy[:, 1] + origin[1],
            "z": 100.0 + rng.uniform(-0.5, 0.5, len(xy)),
            "geozone": labels,
        }
    )
    return table


@settings(max_examples=300, **SETTINGS)
@given(st.floats(0.5, 50.0), st.integers(1, 12), st.sampled_from([0.1, 0.25, 0.3, 0.5]))
def test_lengths_in_spacings_cover_the_same_cells_whatever_the_spacing(spacing_m, spacings, cell_spacings):
    """A bare ceiling of 3 s / (0.25 s) gave 12 or 13 cells by the last bit of ``s`` (feet against metres)."""
    whole = spacings / cell_spacings
    expected = math.ceil(round(whole, 6))
    assert cells_covering(spacings * spacing_m, cell_spacings * spacing_m) == expected


@settings(max_examples=100, **SETTINGS)
@given(
    st.lists(blobs(), min_size=1, max_size=4), st.lists(blobs(r_min=2.0, r_max=8.0), max_size=2), st.integers(0, 999)
)
def test_a_points_distance_to_a_regions_boundary_is_the_distance_to_all_of_it(parts, holes, seed):
    """:func:`boundary_distance` (nearest segments through a tree) equals ``shapely.distance`` to the whole boundary."""
    region = shapely.union_all(parts).difference(shapely.union_all(holes))
    assume(not region.is_empty)
    xy = np.random.default_rng(seed).uniform(-60.0, 60.0, (500, 2))
    expected = shapely.distance(region.boundary, shapely.points(xy))
    assert np.array_equal(boundary_distance(region, xy[:, 0], xy[:, 1]), expected)


@settings(max_examples=200, **SETTINGS)
@given(
    st.tuples(st.integers(1, 90), st.integers(1, 90)),
    st.tuples(st.integers(0, 89), st.integers(0, 89), st.integers(1, 30), st.integers(1, 30)),
    st.floats(0.3, 15.0),
    st.integers(0, 999),
)
def test_a_gaussian_over_the_nonzero_box_is_the_whole_arrays(shape, box, sigma_cells, seed):
    """:func:`local_gaussian_filter` filters only the non-zero box and the kernel's reach: the result must not change."""
    values = np.zeros(shape)
    r0, c0, h, w = box
    block = values[r0 : r0 + h, c0 : c0 + w]  # clipped at the edges, where the reflection is the whole array's
    rng = np.random.default_rng(seed)
    block[...] = rng.normal(size=block.shape) * (rng.random(block.shape) < 0.7)
    assert np.array_equal(local_gaussian_filter(values, sigma_cells), ndimage.gaussian_filter(values, sigma_cells))


@settings(max_examples=300, **SETTINGS)
@given(
    st.integers(3, 40),
    st.tuples(st.integers(4, 60), st.integers(4, 60)),
    st.sampled_from([1.0, 0.5, 0.0]),
    st.integers(0, 2**31),
)
def test_a_ring_covers_the_cells_skimage_draws(n, shape, snap, seed):
    """:func:`Grid.rasterize`'s row-by-row fill is the per-cell test of :func:`skimage.draw.polygon`, to the cell.

    Vertices snapped to whole (or half) cells put centres on vertices and edges, where the two could differ.
    """
    from skimage import draw

    from core.geometry.grid import ring_cells

    rng = np.random.default_rng(seed)
    rc = rng.uniform(-5, max(shape) + 5, (n, 2))
    if snap:
        rc = np.round(rc / snap) * snap
    drawn = np.zeros(shape, bool)
    rr, cc = draw.polygon(rc[:, 0], rc[:, 1], shape=shape)
    drawn[rr, cc] = True
    assert np.array_equal(ring_cells(rc, shape), drawn)


@settings(max_examples=60, **SETTINGS)  # each example traces a whole bench: 100 took 30 s of the suite
@given(labelled_holes())
def test_extraction_returns_valid_closed_polygons_holding_their_holes(table):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = blastholes_from_table(table)
    contours = extract_contours(holes)
    assert contours
    # Every hole of every geozone belongs to exactly one contour's component, or
    # is label noise reported by exactly one contour.
    counted = np.concatenate([np.r_[c.holes, c.isolated_holes] for c in contours])
    assert len(counted) == len(holes.xy) and len(np.unique(counted)) == len(holes.xy)
    for c in contours:
        p = c.polygon
        assert isinstance(p, Polygon), type(p)
        assert not p.is_empty and p.is_valid and p.area > 0
        ring = np.asarray(p.exterior.coords)
        assert len(ring) >= 4 and np.array_equal(ring[0], ring[-1])
        assert np.isfinite(ring).all()
        # In the input's coordinates too (mine-grid offsets must not break validity).
        q = to_input_geometry(p, holes)
        assert q.geom_type == "Polygon" and q.is_valid and not q.is_empty
        if len(c.holes) >= 15:
            assert containment(c, holes)["holes_inside"] >= 0.9, (c.geozone, len(c.holes), c.method)


# ---------------------------------------------------------------------------
# Alignment stays inside the padded frame


@settings(max_examples=200, **SETTINGS)
@given(
    rows=st.integers(12, 70),
    cols=st.integers(12, 70),
    seed=st.integers(0, 2**31 - 1),
    kind=st.sampled_from(["noise", "disc", "ramp"]),
    obstacles=st.booleans(),
    subpixel=st.booleans(),
)
def test_fft_translation_never_leaves_the_frame(rows, cols, seed, kind, obstacles, subpixel):
    rng = np.random.default_rng(seed)
    u = np.zeros((rows, cols), bool)
    h, w = rng.integers(1, rows // 2 + 1), rng.integers(1, cols // 2 + 1)
    r0, c0 = rng.integers(0, rows - h + 1), rng.integers(0, cols - w + 1)
    u[r0 : r0 + h, c0 : c0 + w] = rng.random((h, w)) < 0.8
    assume(u.any())
    rr, cc = np.mgrid[0:rows, 0:cols]
    if kind == "noise":
        v = rng.normal(size=(rows, cols))
    elif kind == "disc":  # an SDF-like bump anywhere, possibly at the frame's edge
        v = rng.uniform(2, 15) - np.hypot(rr - rng.uniform(0, rows), cc - rng.uniform(0, cols))
    else:  # a ramp rising towards a corner: the maximum pulls the source off the frame
        v = rng.choice([-1, 1]) * rr * 3.0 + rng.choice([-1, 1]) * cc * 2.0
    obstacle = (rng.random((rows, cols)) < 0.05) if obstacles else None
    d_row, d_col = fft_translation(u, v, obstacle_mask=obstacle, subpixel=subpixel)
    assert np.isfinite([d_row, d_col]).all()
    used_r = np.flatnonzero(u.any(axis=1))
    used_c = np.flatnonzero(u.any(axis=0))
    # The whole shifted source stays in the frame (half a cell of sub-cell refinement allowed).
    slack = 0.5 if subpixel else 0.0
    assert used_r[0] + d_row >= -slack and used_r[-1] + d_row <= rows - 1 + slack
    assert used_c[0] + d_col >= -slack and used_c[-1] + d_col <= cols - 1 + slack


@settings(max_examples=50, **SETTINGS)
@given(
    src=blobs(),
    extra=st.one_of(st.none(), blobs(centre=40.0, r_min=5.0, r_max=12.0)),
    shift=st.tuples(st.floats(-60.0, 60.0), st.floats(-60.0, 60.0)),
    spacing=st.floats(3.0, 10.0),
)
def test_correspond_pair_keeps_translated_sources_in_the_frame(src, extra, shift, spacing):
    tgt = affinity.translate(src, *shift)
    sources = [src] + ([extra] if extra is not None and not extra.intersects(src) else [])
    res = correspond_pair(sources, [tgt], hole_spacing_m=spacing)
    assert res.translations.shape == (len(sources), 2) and np.isfinite(res.translations).all()
    if res.grid is None:
        return
    xmin, ymin, xmax, ymax = res.grid.bounds
    tol = res.grid.cell_size_m
    for s, t in zip(sources, res.translations):
        bx0, by0, bx1, by1 = affinity.translate(s, *t).bounds
        assert bx0 >= xmin - tol and by0 >= ymin - tol, (t, res.grid)
        assert bx1 <= xmax + tol and by1 <= ymax + tol, (t, res.grid)


# ---------------------------------------------------------------------------
# Morphs: no NaN, trajectories that never cross


@st.composite
def region_pairs(draw):
    """A source and a target region: overlapping blobs, a split, a merge, or a pod appearing / pinching out."""
    kind = draw(st.sampled_from(["one-one", "one-one", "split", "merge", "appear", "vanish"]))
    a = draw(blobs(centre=8.0, r_min=10.0, r_max=22.0))
    shift = draw(st.tuples(st.floats(-8.0, 8.0), st.floats(-8.0, 8.0)))
    b = affinity.translate(draw(blobs(centre=4.0, r_min=10.0, r_max=22.0)), *shift)
    if kind == "one-one":
        return a, b
    if kind in ("split", "merge"):
        gap = draw(st.floats(4.0, 14.0))
        r = draw(st.floats(7.0, 11.0))
        two = MultiPolygon([blob(-r - gap / 2, 0, r, draw(harmonics)), blob(r + gap / 2, 0, r, draw(harmonics))])
        one = blob(0, 0, draw(st.floats(r + gap / 2, 2 * r + gap / 2)), draw(harmonics))
        return (one, two) if kind == "split" else (two, one)
    if kind == "appear":
        return Polygon(), b
    return a, Polygon()


def _morph(pair):
    return morph_regions(*pair, max_cells=96)


@settings(max_examples=30, **SETTINGS)
@given(region_pairs())
def test_morph_never_produces_nan(pair):
    res = _morph(pair)
    assert np.isfinite(res.phi_final).all()
    assert np.isfinite(res.target_sdf).all()
    assert not np.isinf(res.arrival_time).any()
    assert np.isfinite(res.times).all() and np.isfinite(res.iou) and 0.0 <= res.iou <= 1.0
    for value in (res.coverage_before_backtracking, res.target_boundary_coverage):
        assert np.isfinite(value) and 0.0 <= value <= 1.0
    # nan only where documented: cells inside both regions or outside both, i.e.
    # the front never had to cross them. Cells the morph had to sweep (inside
    # exactly one of source and target, away from the rasterised contours) got a time.
    src = res.grid.rasterize(res.source)
    tgt = res.grid.rasterize(res.target)
    h = res.grid.cell_size_m
    d_src = np.abs(signed_distance(src, h))
    swept = (src != tgt) & (d_src > 1.5 * h) & (np.abs(res.target_sdf) > 1.5 * h)
    if res.iou >= 0.98:
        assert np.isfinite(res.arrival_time[swept]).all()


@settings(max_examples=30, **SETTINGS)
@given(region_pairs())
def test_trajectories_never_cross(pair):
    res = _morph(pair)
    assert res.trajectories
    for tr in res.trajectories:
        assert np.isfinite(tr.xy).all() and np.isfinite(tr.t).all() and np.all(np.diff(tr.t) >= 0)
    assert len(crossing_pairs(res.trajectories)) == 0


# ---------------------------------------------------------------------------
# Surfaces: watertight after export and re-reading


@st.composite
def section_stacks(draw):
    n = draw(st.integers(2, 4))
    z = 0.0
    sections = []
    for k in range(n):
        kind = draw(st.sampled_from(["blob", "blob", "two", "empty"])) if 0 < k < n - 1 else "blob"
        if kind == "blob":
            region = draw(blobs(centre=15.0, r_min=8.0, r_max=25.0))
        elif kind == "two":
            region = MultiPolygon(
                [
                    blob(-22, 0, draw(st.floats(6, 12)), draw(harmonics)),
                    blob(22, 0, draw(st.floats(6, 12)), draw(harmonics)),
                ]
            )
        else:
            region = Polygon()
        sections.append((z, region))
        z -= draw(st.floats(3.0, 15.0))
    return sections


@settings(max_examples=20, **SETTINGS)
@given(section_stacks(), st.sampled_from(["ply", "obj"]))
def test_exported_meshes_are_watertight(tmp_path_factory, sections, fmt):
    mesh = surface_from_sections(sections, cell_size_m=2.5)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    path = tmp_path_factory.mktemp("mesh") / f"surface.{fmt}"
    export_surface(mesh, path)
    back = trimesh.load(path, process=False, force="mesh")
    assert len(back.faces) == len(mesh.faces)
    back.merge_vertices()  # OBJ/PLY may split vertices per face; topology is what counts
    assert back.is_watertight and back.is_winding_consistent
    assert back.volume == pytest.approx(mesh.volume, rel=1e-6)
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]  # no temporary files left


# ---------------------------------------------------------------------------
# Reading: column and label normalisation (issue 15)


@st.composite
def number_spelling(draw, value: Decimal) -> str:
    """One of the ways programs write ``value``: 3310, 3310.0, 3310.00, 03310, +3310, 3.31e3, 33100e-1."""
    sign = "-" if value < 0 else draw(st.sampled_from(["", "+"]))
    v = abs(value)
    text = format(v.normalize(), "f") if v != 0 else "0"
    form = draw(st.integers(0, 4))
    if form == 1:
        text += ("" if "." in text else ".") + "0" * draw(st.integers(1, 3))
    elif form == 2:
        text = "0" * draw(st.integers(1, 3)) + text
    elif form == 3 and v != 0:
        mantissa, exponent = f"{v:e}".split("e")
        text = f"{Decimal(mantissa).normalize()}e{int(exponent)}"
    elif form == 4:
        shift = draw(st.integers(1, 3))
        text = f"{format((v * 10**shift).normalize(), 'f')}e-{shift}"
    return sign + text


@st.composite
def labelled_codes(draw):
    """Labels of a table: domain codes written several ways, and words that are not numbers."""
    values = draw(
        st.lists(
            st.one_of(
                st.decimals(min_value=-99999, max_value=99999, places=draw(st.integers(0, 2)), allow_nan=False),
                st.integers(10**15, 10**20).map(Decimal),  # hole-id-like codes past float precision
            ),
            min_size=1,
            max_size=5,
            unique_by=lambda d: d.normalize(),
        )
    )
    words = draw(st.lists(st.text("abcxyz_-/. ", min_size=1, max_size=6).map(str.strip).filter(bool), max_size=3))
    words = [w for w in words if label_number(w) is None]
    labels = []
    for v in values:
        labels += [draw(number_spelling(v)) for _ in range(draw(st.integers(1, 3)))]
    labels += words
    return draw(st.permutations(labels)), values, words


@settings(max_examples=200, **SETTINGS)
@given(labelled_codes())
def test_labels_merge_exactly_when_they_spell_one_number(case):
    labels, values, words = case
    merged, renamed = merge_number_spellings(np.array(labels, dtype=object))
    assert len(merged) == len(labels)
    for a, ma in zip(labels, merged):
        for b, mb in zip(labels, merged):
            na, nb = label_number(a), label_number(b)
            same_number = na is not None and nb is not None and na == nb
            assert (ma == mb) == (a == b or same_number), (a, b, ma, mb)
    # Words and codes with leading zeros are never touched; a number written one way only keeps its
    # spelling, unless it is an integer with a zero fraction (what a float column writes): that is made plain.
    for a, ma in zip(labels, merged):
        if label_number(a) is None:
            assert ma == a
        elif len({b for b in labels if label_number(b) == label_number(a)}) == 1:
            assert ma == (number_label(label_number(a)) if ZERO_FRACTION.fullmatch(a) else a)
        else:
            assert ma == number_label(label_number(a)) and renamed.get(a, a) == ma
    # Merging again changes nothing.
    again, renamed_again = merge_number_spellings(merged)
    assert list(again) == list(merged) and not renamed_again


@settings(max_examples=40, **SETTINGS)
@given(labelled_codes())
def test_a_table_has_one_geozone_per_number_and_any_spelling_selects_it(case):
    labels, values, words = case
    n = 3 * len(labels)
    table = pd.DataFrame(
        {
            "x": np.tile(np.arange(n, dtype=float) * 5.0, 2),
            "y": np.repeat([0.0, 5.0], n),
            "z": 100.0,
            "geozone": np.tile(np.array(labels * 3, dtype=object), 2),
        }
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = blastholes_from_table(table)
    # One geozone per number, and one per code with leading zeros (010 is not 10).
    assert len(holes.geozones) == len({label_number(a) if label_number(a) is not None else a for a in labels})
    for a in labels:
        (found,) = holes.check_geozones([a])
        for b in labels:
            if label_number(a) is not None and label_number(a) == label_number(b):
                assert holes.check_geozones([b]) == [found]  # any spelling selects the one geozone


role_names = st.sampled_from([(role, alias) for role, aliases in COLUMN_ALIASES.items() for alias in aliases])


@st.composite
def header(draw):
    """A header naming each role once (any alias, any case, stray spaces) among unrelated columns."""
    names = {}
    for role, aliases in COLUMN_ALIASES.items():
        alias = draw(st.sampled_from(aliases))
        cased = "".join(c.upper() if draw(st.booleans()) else c for c in alias)
        names[role] = draw(st.sampled_from(["", " "])) + cased + draw(st.sampled_from(["", " ", "  "]))
    taken = {a for aliases in COLUMN_ALIASES.values() for a in aliases} | {"holeid", "hole_id", "hole", "id"}
    others = draw(
        st.lists(
            st.text("ABCdefq0123_ ", min_size=1, max_size=8).filter(lambda s: s.strip().lower() not in taken),
            max_size=6,
            unique=True,
        )
    )
    return names, draw(st.permutations([*names.values(), *others]))


@settings(max_examples=200, **SETTINGS)
@given(header())
def test_columns_are_found_by_name_whatever_the_case_spaces_and_order(case):
    names, columns = case
    assert table_columns(columns) == names
    # Named explicitly, in any case and with spaces around, a column is found too.
    for role, name in names.items():
        assert find_column(columns, role, f" {name.strip().swapcase()} ") == name


@settings(max_examples=100, **SETTINGS)
@given(header(), st.sampled_from(list(COLUMN_ALIASES)), st.data())
def test_two_candidates_for_one_role_are_refused_naming_both(case, role, data):
    names, columns = case
    spare = [a for a in COLUMN_ALIASES[role] if a != names[role].strip().lower()]
    assume(spare)
    second = data.draw(st.sampled_from(spare)).upper()
    with pytest.raises(BGMInputError, match=f"ambiguous {role} column") as info:
        table_columns([*columns, second])
    assert names[role] in str(info.value) and second in str(info.value)


@settings(max_examples=200, **SETTINGS)
@given(
    st.lists(st.floats(-1e7, 1e7, allow_nan=False).map(lambda v: round(v, 3)), min_size=1, max_size=20),
    st.sampled_from([";", "\t"]),
    st.integers(1, 3),
)
def test_decimal_commas_read_as_the_numbers_they_spell(values, sep, places):
    written = [float(f"{v:.{places}f}") for v in values]
    text = pd.Series([f"{v:.{places}f}".replace(".", ",") for v in values])
    parsed = pd.to_numeric(_without_digit_grouping(text, sep), errors="coerce").to_numpy()
    assert np.array_equal(parsed, written)
    # Thousands separators (quoted in a comma-separated file) read as the same numbers.
    grouped = pd.Series([f"{v:,.{places}f}" for v in values])
    parsed = pd.to_numeric(_without_digit_grouping(grouped, ","), errors="coerce").to_numpy()
    assert np.array_equal(parsed, written)
