"""Reading blasthole tables: columns, benches, units, frames and bad input."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pandas as pd
import pytest
from conftest import DEMO_CSV, synthetic

from core.errors import BGMInputError
from core.io.blastholes import BGMWarning, detect_benches, median_hole_spacing, read_blastholes
from core.synthetic.scenarios import scenario


def small_table(n_per_bench: int = 40, benches=(100.0, 90.0, 80.0), seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    rows = []
    for z in benches:
        gx, gy = np.meshgrid(np.arange(8) * 6.0, np.arange(n_per_bench // 8) * 6.0)
        for x, y in zip(gx.ravel(), gy.ravel()):
            rows.append(
                (x + rng.normal(0, 0.3), y + rng.normal(0, 0.3), z + rng.uniform(-1, 1), "3310" if x < 20 else "2210")
            )
    return pd.DataFrame(rows, columns=["EAST", "NORTH", "RL", "lookup_domain"])


def write(tmp_path, table: pd.DataFrame, name="holes.csv", **kw) -> str:
    path = tmp_path / name
    table.to_csv(path, index=False, **kw)
    return str(path)


def test_columns_found_by_name_and_labels_stay_strings(tmp_path):
    holes = read_blastholes(write(tmp_path, small_table()))
    assert holes.geozones == ["2210", "3310"]
    assert holes.n_benches == 3
    assert np.allclose(holes.bench_levels_m, [100.0, 90.0, 80.0], atol=0.5)  # holes scatter +-1 m
    assert holes.bench_height_m == pytest.approx(10.0)
    assert 5.0 < holes.hole_spacing_m < 6.5


@pytest.mark.parametrize("pattern", ["staggered", "square"])
def test_holes_collared_off_their_pattern_read_at_its_spacing(pattern):
    """Every length of the engine is in hole spacings: scatter off the pattern must not shrink the spacing.

    Holes collared 0.3 of a spacing off a 6 m pattern (standard deviation each
    way) bring their nearest neighbour to 3.6 m (median) on either pattern.
    """
    rng = np.random.default_rng(0)
    i, j = np.meshgrid(np.arange(40.0), np.arange(40.0))
    if pattern == "staggered":
        xy = np.column_stack([(i + (j % 2) / 2).ravel(), (j * np.sqrt(3) / 2).ravel()]) * 6.0
    else:
        xy = np.column_stack([i.ravel(), j.ravel()]) * 6.0
    bench = np.zeros(len(xy), int)
    assert median_hole_spacing(xy, bench) == pytest.approx(6.0)
    scattered = xy + rng.normal(0.0, 0.3 * 6.0, xy.shape)
    assert median_hole_spacing(scattered, bench) == pytest.approx(6.0, rel=0.1)


@pytest.mark.parametrize("rows", [1, 2])
def test_a_bench_drilled_in_rows_reads_at_its_step(rows):
    """One row (a trench, a ramp): its third-nearest hole is two steps away; two staggered rows are a pattern."""
    rng = np.random.default_rng(1)
    step = np.arange(30.0) * 6.0
    xy = np.vstack([np.column_stack([step + 3.0 * r, np.full(30, 5.2 * r)]) for r in range(rows)])
    xy = xy @ np.array([[0.8, 0.6], [-0.6, 0.8]]) + rng.normal(0.0, 0.1, xy.shape)
    assert median_hole_spacing(xy, np.zeros(len(xy), int)) == pytest.approx(6.0, rel=0.05)


def pattern_bench(spacing_m: float, z_m: float, rng, n: int = 30) -> pd.DataFrame:
    """A bench of ``n`` x ``n`` holes on a staggered pattern, collared 0.08 of a spacing off it (the synthetic's)."""
    i, j = np.meshgrid(np.arange(float(n)), np.arange(float(n)))
    xy = np.column_stack([(i + (j % 2) / 2).ravel(), (j * np.sqrt(3) / 2).ravel()]) * spacing_m
    xy += rng.normal(0.0, 0.08 * spacing_m, xy.shape)
    return pd.DataFrame({"x": xy[:, 0], "y": xy[:, 1], "z": z_m, "geozone": np.where(xy[:, 0] < 80, "a", "b")})


@pytest.mark.parametrize("kept", [0.05, 0.15, 0.4])
def test_a_new_benchs_first_holes_leave_the_tables_spacing(kept):
    """A bench is drilled over weeks: its first patterns must not move the spacing every length is measured in.

    Benches are drilled on patterns a few percent apart (here 5.8, 6.0 and 6.1
    m, the new bench 6.3), and a partly drilled bench is mostly edge, whose
    holes' neighbours lie farther off. Pooled over every hole, the median moved
    by 0.1-0.6% with the new bench's first 5-40% (a strip), and the grid's
    cells with it, so predictions far from those holes changed.
    """
    from core.io.blastholes import blastholes_from_table

    rng = np.random.default_rng(3)
    above = pd.concat([pattern_bench(s, z, rng) for s, z in ((5.8, 100.0), (6.0, 90.0), (6.1, 80.0))])
    new = pattern_bench(6.3, 70.0, rng)
    first = new[new.y <= new.y.quantile(kept)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        before = blastholes_from_table(above, length_unit="m").hole_spacing_m
        after = blastholes_from_table(pd.concat([above, first]), length_unit="m").hole_spacing_m
    assert after == pytest.approx(before, rel=1e-4)


def test_explicit_columns_and_other_delimiters(tmp_path):
    t = small_table().rename(columns={"EAST": "e1", "NORTH": "n1", "RL": "level", "lookup_domain": "code"})
    path = write(tmp_path, t, sep=";")
    holes = read_blastholes(path, x="e1", y="n1", z="level", geozone="code")
    assert len(holes.xy) == len(t)
    with pytest.raises(BGMInputError, match="no x column"):
        read_blastholes(path)


def test_parquet_labels_from_integers(tmp_path):
    t = small_table()
    t["lookup_domain"] = t["lookup_domain"].astype(int)
    path = tmp_path / "holes.parquet"
    t.to_parquet(path)
    assert read_blastholes(path).geozones == ["2210", "3310"]


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda t: t.assign(x=1.0), "ambiguous x column"),
        (lambda t: t.drop(columns=["lookup_domain"]), "no geozone column"),
        (lambda t: t.assign(RL=t.RL.astype(object).where(t.index != 5, "abc")), r"RL.*data line\(s\) 7"),
        (lambda t: t.assign(EAST=t.EAST.where(t.index != 3, np.nan)), r"EAST.*line\(s\) 5"),
        (lambda t: t.assign(NORTH=t.NORTH.where(t.index != 0, np.inf)), "infinite"),
        (lambda t: t.iloc[:0], "no rows"),
        (lambda t: t.assign(lookup_domain=t.lookup_domain.where(t.index != 2, "")), "geozone.*empty"),
    ],
)
def test_bad_tables_get_one_clear_message(tmp_path, mutate, message):
    path = write(tmp_path, mutate(small_table()))
    with pytest.raises(BGMInputError, match=message):
        read_blastholes(path)


def test_missing_empty_directory_and_binary_inputs(tmp_path):
    with pytest.raises(BGMInputError, match="does not exist"):
        read_blastholes(tmp_path / "nope.csv")
    with pytest.raises(BGMInputError, match="directory"):
        read_blastholes(tmp_path)
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(BGMInputError, match="empty"):
        read_blastholes(tmp_path / "empty.csv")
    (tmp_path / "bin.csv").write_bytes(b"\x00\x01\x02garbage" * 10)
    with pytest.raises(BGMInputError):
        read_blastholes(tmp_path / "bin.csv")
    (tmp_path / "bad.parquet").write_text("not parquet")
    with pytest.warns(BGMWarning, match="named .parquet but is not Parquet"), pytest.raises(BGMInputError):
        read_blastholes(tmp_path / "bad.parquet")


def test_unknown_geozone_lists_the_present_ones(tmp_path):
    holes = read_blastholes(write(tmp_path, small_table()))
    with pytest.raises(BGMInputError, match="present: 2210, 3310"):
        holes.check_geozones(["9999"])


def test_duplicates_are_merged_with_a_warning(tmp_path):
    t = small_table()
    t = pd.concat([t, t.iloc[1:4], t.iloc[[0]].assign(lookup_domain="2210")], ignore_index=True)
    with pytest.warns(BGMWarning, match="4 duplicate hole.*conflicting"):
        holes = read_blastholes(write(tmp_path, t))
    assert len(holes.xy) == len(t) - 4


@pytest.mark.parametrize("how", ["merged", "left out"])
def test_a_geozone_whose_every_hole_was_merged_or_left_out_is_not_said_to_be_absent_from_the_table(tmp_path, how):
    """A geozone whose every hole coincides with another geozone's (merged, first row kept), or lies off the
    benches, was "not in holes.csv": the geologist looked for a typo in a label the file holds."""
    t = small_table()
    if how == "merged":
        lost = t[t["lookup_domain"] == "3310"].iloc[:5].assign(lookup_domain="4410")
    else:
        lost = t.iloc[:2].assign(lookup_domain="4410", RL=-9999.0)
    with pytest.warns(BGMWarning):
        holes = read_blastholes(write(tmp_path, pd.concat([t, lost], ignore_index=True)))
    assert "4410" not in holes.geozones
    with pytest.raises(BGMInputError, match="none of its holes is left") as refused:
        holes.check_geozones(["4410"])
    assert "is in" in str(refused.value) and ("merged" in str(refused.value)) == (how == "merged")
    with pytest.raises(BGMInputError, match="is not in"):  # a label the table does not hold is still that
        holes.check_geozones(["9999"])


def test_off_bench_holes_are_reported_and_left_out(tmp_path):
    t = small_table()
    t.loc[0, "RL"] = 95.0  # between the 100 and 90 benches
    with pytest.warns(BGMWarning, match="1 hole"):
        holes = read_blastholes(write(tmp_path, t))
    assert len(holes.xy) == len(t) - 1


@pytest.mark.parametrize("typos", [[0.0], [-9999.0], [6849.3], [0.0, 68.49, -9999.0, 6849.3]])
def test_a_hole_with_its_elevation_mistyped_is_left_out_not_the_table_refused(tmp_path, typos):
    """One hole with RL 0, -9999 or 6849.3 (for 684.93; one in the demo's 11,211) made the widest gap between elevations,
    next to which no bench gap was wide: the table was refused, 'z does not form benches: elevations spread
    continuously over 60.06 units'."""
    t = small_table()
    t.loc[: len(typos) - 1, "RL"] = typos
    with pytest.warns(BGMWarning, match=f"{len(typos)} hole"):
        holes = read_blastholes(write(tmp_path, t))
    assert len(holes.xy) == len(t) - len(typos)
    assert holes.n_benches == read_blastholes(write(tmp_path, small_table())).n_benches


@pytest.mark.parametrize("missing", ["0", "-9999"])
def test_many_holes_with_their_elevation_missing_are_left_out_not_the_benches_merged(tmp_path, missing):
    """300 of the demo's 11,211 holes with z written as 0 (or -9999) where it was missing were a cluster of their own,
    whose gap hid every gap between benches: the seven benches were read as one at 664.8 m, with only a units
    warning ('benches 664.8 units high would be feet')."""
    demo = pd.read_csv(DEMO_CSV, dtype=str)
    rows = np.sort(np.random.default_rng(0).choice(len(demo), 300, replace=False))
    demo.loc[rows, "z"] = missing
    with pytest.warns(BGMWarning, match=rf"300 hole\(s\) lie more than a bench height .* at z {missing} ") as caught:
        holes = read_blastholes(write(tmp_path, demo))
    clean = read_blastholes(DEMO_CSV)
    assert holes.n_benches == 7 and np.array_equal(holes.bench_levels_m, clean.bench_levels_m)
    assert holes.bench_height_m == clean.bench_height_m == 10.0 and holes.frame.length_unit == "m"
    assert set(holes.hole_id) == set(clean.hole_id) - set(demo.hole_id[rows])
    named = f"data line(s) {', '.join(str(r + 2) for r in rows[:10])} and 290 more"  # line 1 is the header
    assert any(named in str(w.message) for w in caught)


def test_too_many_holes_with_their_elevation_missing_are_refused_by_name(tmp_path):
    """More than a quarter of the holes at RL 0 are no typos to leave out: the table is refused, saying why."""
    t = small_table()
    t.loc[: len(t) // 3, "RL"] = 0.0
    with pytest.raises(BGMInputError, match=r"41 of 120 holes \(34%\) have elevations far off the benches \(at 0;"):
        read_blastholes(write(tmp_path, t))


@pytest.mark.parametrize("below", [1, 3, 8])
def test_a_sump_of_holes_benches_below_the_pit_is_a_bench_of_its_own(tmp_path, below):
    """Real benches lie a bench height or a few apart: a sump of 32 holes 3 benches below the pit's five made the
    widest gap, and the table was refused (its holes 'between the bench levels found (85.1, 30)'); 8 benches
    below, the five were read as one at 80 m."""
    pit = small_table(benches=(100.0, 90.0, 80.0, 70.0, 60.0))
    sump = small_table(n_per_bench=32, benches=(60.0 - 10.0 * below,), seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)  # nothing left out
        holes = read_blastholes(write(tmp_path, pd.concat([pit, sump])))
    assert np.allclose(holes.bench_levels_m, [100.0, 90.0, 80.0, 70.0, 60.0, 60.0 - 10.0 * below], atol=0.5)
    assert len(holes.xy) == len(pit) + len(sump)


def test_a_group_of_holes_more_than_ten_benches_off_the_others_is_left_out_by_name(tmp_path):
    """No pit leaves ten benches unsampled between two of its own: 32 holes 15 benches below are set apart."""
    pit = small_table(benches=(300.0, 290.0, 280.0, 270.0))
    far = small_table(n_per_bench=32, benches=(120.0,), seed=1)
    with pytest.warns(BGMWarning, match=r"32 hole\(s\) lie more than a bench height above or below every bench"):
        holes = read_blastholes(write(tmp_path, pd.concat([pit, far])))
    assert np.allclose(holes.bench_levels_m, [300.0, 290.0, 280.0, 270.0], atol=0.5) and len(holes.xy) == len(pit)


def test_kennecott_with_300_holes_at_rl_0_reads_as_without_them(kennecott_csv, tmp_path):
    """Kennecott's floor is 5.4 benches above 0: 300 holes at RL 0 read as two benches, at 366.1 and 0 ft, and 1,888
    holes were left out as between them. A group all at exactly 0 (or -9999) a few benches off is no bench."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        clean = read_blastholes(kennecott_csv)
    levels = [564.4, 514.7, 464.5, 414.9, 365.0, 315.4, 267.8]  # as read before and after the change
    assert clean.n_benches == 7 and len(clean.xy) == 14709
    assert np.allclose(clean.frame.z_to_input(clean.bench_levels_m), levels)
    table = pd.read_csv(kennecott_csv, dtype=str, keep_default_na=False)
    rows = np.random.default_rng(0).choice(len(table), 300, replace=False)
    table.loc[rows, "RL"] = "0"
    with pytest.warns(BGMWarning) as caught:  # with Kennecott's own ('-99' labels, 2 holes between benches)
        holes = read_blastholes(write(tmp_path, table))
    assert any("300 hole(s) lie more than a bench height above or below" in str(w.message) for w in caught)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        without = read_blastholes(write(tmp_path, table.drop(index=rows), name="without.csv"))
    assert np.array_equal(holes.bench_levels_m, without.bench_levels_m) and holes.n_benches == 7
    assert np.array_equal(holes.hole_id, without.hole_id) and np.array_equal(holes.bench, without.bench)


def demo_bench(level: float = 685.0) -> pd.DataFrame:
    """One bench of the demo, as written (strings), its holes within half a bench of ``level``."""
    demo = pd.read_csv(DEMO_CSV, dtype=str)
    return demo[np.abs(demo.z.astype(float) - level) < 5.0].reset_index(drop=True)


@pytest.mark.parametrize(("level", "missing"), [(685.0, "0"), (685.0, "-9999"), (0.0, "-9999")])
def test_holes_with_their_elevation_missing_beside_a_single_bench_are_no_second_bench(tmp_path, level, missing):
    """One bench and 300 holes with z written as 0 (or -9999) where it was missing read as two benches 685 apart,
    with only a unit warning ('benches 685 units high would be feet ... read as metres'), and the model was built
    between the bench and a made-up one. A plan at 0 with 300 holes at -9999 likewise."""
    bench = demo_bench()
    bench["z"] = (bench.z.astype(float) - 685.0 + level).map("{:.2f}".format) if level else "0"
    rows = np.sort(np.random.default_rng(0).choice(len(bench), 300, replace=False))
    table = bench.copy()
    table.loc[rows, "z"] = missing
    with pytest.warns(BGMWarning) as caught:
        holes = read_blastholes(write(tmp_path, table))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        alone = read_blastholes(write(tmp_path, bench.drop(index=rows), name="alone.csv"))
    assert holes.n_benches == 1 and np.array_equal(holes.bench_levels_m, alone.bench_levels_m)
    assert np.array_equal(holes.hole_id, alone.hole_id) and np.isnan(holes.bench_height_m)
    said = rf"300 hole\(s\) lie far above or below the only bench \(at z {level:g}[.\d]*\), at z {missing} \(data line"
    assert any(re.match(said, str(w.message)) for w in caught), [str(w.message) for w in caught]
    assert any(str(w.message).endswith("if they are a bench of their own, give --bench-height") for w in caught)


def test_a_single_bench_with_more_than_a_quarter_of_its_holes_at_rl_0_is_refused_by_name(tmp_path):
    """900 of a bench's 2,147 holes at RL 0 read as two benches; now refused, naming the group and the way out."""
    table = demo_bench()
    table.loc[np.random.default_rng(1).choice(len(table), 900, replace=False), "z"] = "0"
    with pytest.raises(
        BGMInputError,
        match=r"900 of 2147 holes \(42%\) have elevations far off the benches \(at 0; the others from 684.5 to 685.5\)"
        r".*if they are a bench of their own, give --bench-height$",
    ):
        read_blastholes(write(tmp_path, table))


def test_kennecotts_floor_bench_with_300_holes_at_rl_0_reads_as_without_them(kennecott_csv, tmp_path):
    """Kennecott's floor (267.8 ft) is 11.9 hole spacings above 0, its benches 2.2 high: alone with 300 holes at RL 0,
    it read as two benches 267.8 ft apart ('feet guessed from the 267.8-unit bench height')."""
    table = pd.read_csv(kennecott_csv, dtype=str, keep_default_na=False)
    floor = table[np.abs(table.RL.astype(float) - 267.8) < 25.0].reset_index(drop=True)
    rows = np.random.default_rng(0).choice(len(floor), 300, replace=False)
    missing = floor.copy()
    missing.loc[rows, "RL"] = "0"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = read_blastholes(write(tmp_path, missing))
        alone = read_blastholes(write(tmp_path, floor.drop(index=rows), name="alone.csv"))
    assert holes.n_benches == 1 and np.array_equal(holes.bench_levels_m, alone.bench_levels_m)
    assert np.array_equal(holes.hole_id, alone.hole_id)
    assert any("300 hole(s) lie far above or below the only bench (at z 267.78), at z 0" in n for n in holes.notes)


@pytest.mark.parametrize("levels", [(0.0, -10.0), (0.0, -10.0, -20.0), (10.0, 0.0)])
@pytest.mark.parametrize("scatter", [True, False])
def test_real_benches_at_rl_0_on_a_local_datum_stay_benches(tmp_path, levels, scatter):
    """A mine grid with its datum at a bench (0, -10, -20): the bench at exactly 0 is a bench, nothing left out."""
    table = small_table(benches=levels)
    if not scatter:
        table["RL"] = np.round(table.RL / 10.0) * 10.0  # benches given at their levels: every hole at exactly 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)
        holes = read_blastholes(write(tmp_path, table))
    assert np.allclose(holes.bench_levels_m, levels, atol=0.5) and len(holes.xy) == len(table)
    assert holes.bench_height_m == pytest.approx(10.0, abs=0.5)  # holes scatter +-1 m


def test_a_bench_at_rl_0_far_below_the_only_other_is_kept_by_giving_the_bench_height(tmp_path):
    """Two benches 80 m apart on a 6 m pattern (14 hole spacings), the lower at exactly 0: no pit drills a bench
    that high, so the one at 0 is taken for missing elevations; the refusal (or warning) says how to keep it."""
    table = small_table(benches=(80.0, 0.0))
    table.loc[table.RL.abs() < 5.0, "RL"] = 0.0
    with pytest.raises(BGMInputError, match=r"40 of 80 holes \(50%\) .* \(at 0; .*give --bench-height$"):
        read_blastholes(write(tmp_path, table))
    fewer = table.drop(index=table.index[table.RL == 0.0][:28])
    with pytest.warns(BGMWarning, match=r"12 hole\(s\) lie far .* at z 0 .*give --bench-height$"):
        assert read_blastholes(write(tmp_path, fewer)).n_benches == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)
        holes = read_blastholes(write(tmp_path, table), bench_height=80.0, length_unit="m")
    assert np.allclose(holes.bench_levels_m, [80.0, 0.0], atol=0.5) and len(holes.xy) == len(table)


def test_a_single_bench_at_rl_0_reads_as_a_bench_without_a_word_on_missing_elevations(tmp_path):
    """A local datum at the only bench: its holes scatter around 0, which is no missing elevation."""
    with pytest.warns(BGMWarning) as caught:  # none expected, but a single bench's unit is assumed: not a warning
        warnings.warn("sentinel", BGMWarning, stacklevel=1)
        holes = read_blastholes(write(tmp_path, small_table(benches=(0.0,))))
    assert [str(w.message) for w in caught] == ["sentinel"]
    assert holes.n_benches == 1 and abs(holes.bench_levels_m[0]) < 0.5 and len(holes.xy) == 40


def test_a_plan_with_every_elevation_0_reads_as_one_bench_and_says_so(tmp_path):
    """A 2D table (z all 0) is one bench; if its holes came from several benches their elevations are missing, and
    nothing said so: the benches' holes were stacked on one plan."""
    table = small_table()
    table["RL"] = 0.0
    with pytest.warns(BGMWarning, match=r"every hole's elevation is 0: read as one bench \(a plan\); if the holes "):
        holes = read_blastholes(write(tmp_path, table))
    assert holes.n_benches == 1 and holes.bench_levels_m[0] == 0.0


def test_a_few_holes_at_rl_0_beside_a_single_bench_are_named_as_missing_elevations(tmp_path):
    """5 of a bench's 40 holes at RL 0 had the table refused ('elevations spread continuously over 686 units');
    among more holes they were said to lie 'more than 30% of a bench height from every bench level', a height a
    single bench does not have. Its strays are said to lie off the bench's elevations."""
    table = small_table(benches=(685.0,))
    table.loc[[0, 1, 2, 3, 4], "RL"] = 0.0
    table.loc[5, "RL"] = 693.0
    with pytest.warns(BGMWarning) as caught:
        holes = read_blastholes(write(tmp_path, table))
    said = [str(w.message) for w in caught]
    assert any(
        m.startswith("5 hole(s) lie far above or below the only bench (at z 685")
        and "at z 0 (data line(s) 2, 3, 4, 5, 6): elevations missing (written as 0 or -9999)" in m
        for m in said
    ), said
    assert any(
        m.startswith("1 hole(s) lie off the only bench's elevations (") and "at z 693 (data line(s) 7)" in m
        for m in said
    )
    assert not any("bench height from every" in m or "--bench-height" in m for m in said)
    assert len(holes.xy) == 34


@pytest.mark.parametrize("typed", [150.0, 15000.0])
@pytest.mark.parametrize("n_per_bench", [24, 40])
@pytest.mark.parametrize("units", ["m", "ft"])
def test_a_small_group_mistyped_far_from_a_single_bench_is_left_out_and_named(tmp_path, typed, n_per_bench, units):
    """A bench at RL 1500 with 6 holes typed at RL 150 or 15000 (neither 0 nor -9999) read as two benches 1350 units
    apart, or had the table refused as elevations 'spread continuously'; in feet too (pattern and levels / 0.3048)."""
    table = small_table(n_per_bench=n_per_bench, benches=(1500.0,))
    if units == "ft":
        table[["EAST", "NORTH", "RL"]] /= 0.3048
    alone = table.iloc[6:]
    table.loc[:5, "RL"] = typed / (0.3048 if units == "ft" else 1.0)
    with pytest.warns(BGMWarning) as caught:
        holes = read_blastholes(write(tmp_path, table))
    expected = read_blastholes(write(tmp_path, alone, name="alone.csv"))
    assert holes.n_benches == 1 and np.array_equal(holes.bench_levels_m, expected.bench_levels_m)
    assert np.array_equal(holes.xy, expected.xy) and len(holes.xy) == n_per_bench - 6
    said = [str(w.message) for w in caught]
    assert any(
        m.startswith("6 hole(s) lie far above or below the only bench (at z ")
        and "(data line(s) 2, 3, 4, 5, 6, 7): elevations missing (written as 0 or -9999) or mistyped?" in m
        for m in said
    ), said


def test_a_small_group_mistyped_far_from_two_benches_is_no_third_bench(tmp_path):
    """Two benches and 6 holes typed at RL 150 read as three benches (the group was a bench being opened)."""
    table = small_table(benches=(1500.0, 1490.0))
    table.loc[:5, "RL"] = 150.0
    with pytest.warns(
        BGMWarning, match=r"6 hole\(s\) lie more than a bench height above or below every bench, at z 150"
    ):
        holes = read_blastholes(write(tmp_path, table))
    assert np.allclose(holes.bench_levels_m, [1500.0, 1490.0], atol=0.5) and len(holes.xy) == 74


@pytest.mark.parametrize("levels", [(1500.0, 1200.0), (1500.0, 1460.0)])
def test_a_real_bench_far_below_or_a_few_benches_below_stays_a_bench(tmp_path, levels):
    """Real benches are no far group: two benches of a deep pit 300 m apart (as many holes each), or a small bench
    four bench heights below the only other (12 holes of 52, 7 hole spacings) read as two benches, nothing left out."""
    table = small_table(benches=levels)
    if levels[1] == 1460.0:
        table = table.drop(index=table.index[table.RL < 1470.0][12:])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)  # the unit is guessed from the bench height
        holes = read_blastholes(write(tmp_path, table))
    assert np.allclose(holes.bench_levels_m, levels, atol=0.5) and len(holes.xy) == len(table)


def test_a_hole_far_from_every_other_of_its_bench_is_left_out(tmp_path):
    """A hole with x, y written as 0 (missing) on the mine grid was modelled: the demo's g0 surface grew from
    4.0e6 to 1.7e12 m³, and the build suggested no hole and evaluated nothing, without a word."""
    t = small_table()
    t[["EAST", "NORTH"]] += [482000.0, 7445000.0]
    t.loc[[0, 1], ["EAST", "NORTH"]] = 0.0  # twice on the first bench, once with the second's on it
    t.loc[len(t) - 1, ["EAST", "NORTH"]] = 0.0
    with pytest.warns(BGMWarning, match=r"3 hole\(s\) lie more than 20 hole spacings.*data line\(s\) 2, 3, 121"):
        holes = read_blastholes(write(tmp_path, t))
    assert len(holes.xy) == len(t) - 3
    assert np.ptp(holes.xy, axis=0).max() < 50.0


def test_a_geozone_asked_for_with_spaces_around_is_the_label(tmp_path):
    """Labels are read stripped, but bgm predict/evaluate --geozone " 3310" was refused ("not in ..."), where
    bgm build --geozone " 3310" took it."""
    holes = read_blastholes(write(tmp_path, small_table()))
    assert holes.check_geozones([" 3310", "2210 "]) == ["3310", "2210"]


def test_single_bench_reads_with_nan_bench_height(tmp_path):
    holes = read_blastholes(write(tmp_path, small_table(benches=(50.0,))))
    assert holes.n_benches == 1 and np.isnan(holes.bench_height_m)


def test_bench_height_override_and_detection_in_feet():
    rng = np.random.default_rng(1)
    z = np.concatenate([lvl + rng.uniform(-8, 8, 500) for lvl in (515.0, 465.0, 415.0, 365.0)])
    levels, bench, height, off = detect_benches(z)
    assert height == pytest.approx(50.0, abs=0.5)
    assert np.allclose(levels, [515, 465, 415, 365], atol=1.0)
    assert not off.any()
    levels, _, height, _ = detect_benches(z, bench_height=50.0)
    assert height == 50.0 and len(levels) == 4


def test_feet_are_recognised_and_reported_back_in_feet(tmp_path):
    t = small_table(benches=(500.0, 450.0, 400.0))
    t[["EAST", "NORTH"]] *= 3.28084
    holes = read_blastholes(write(tmp_path, t))
    assert holes.frame.length_unit == "ft"
    assert 5.0 < holes.hole_spacing_m < 6.5  # spacing in metres whatever the input unit
    assert holes.bench_z_input(0) == pytest.approx(500.0, abs=0.5)
    back = holes.frame.to_input(holes.xy)
    assert np.allclose(np.sort(back[:, 0]), np.sort(t.EAST.to_numpy()), atol=1e-9)


def test_a_part_of_a_table_in_feet_read_again_from_as_table_finds_its_own_benches(tmp_path):
    """``as_table`` gives the input's coordinates and units back: read again, the holes are where they were, and a
    part without the middle bench has two benches, not an empty level between them (as :meth:`subset` keeps)."""
    from core.io.blastholes import blastholes_from_table

    t = small_table(benches=(500.0, 450.0, 400.0))
    t[["EAST", "NORTH"]] *= 3.28084
    holes = read_blastholes(write(tmp_path, t))
    again = blastholes_from_table(holes.as_table())
    assert again.frame.length_unit == "ft" and again.n_benches == 3
    np.testing.assert_allclose(again.frame.to_input(again.xy), holes.frame.to_input(holes.xy), atol=1e-6)
    np.testing.assert_allclose(again.z, holes.z, atol=1e-6)
    assert list(again.geozone) == list(holes.geozone)
    part = blastholes_from_table(holes.as_table()[holes.bench != 1])
    assert part.n_benches == 2 and holes.subset(holes.bench != 1).n_benches == 3
    assert [part.bench_z_input(k) for k in range(2)] == pytest.approx([500.0, 400.0], abs=0.5)


def test_mine_grid_coordinates_keep_full_precision():
    _, table, holes = synthetic(3, n_benches=3)
    assert table.y.min() > 7_399_000
    assert np.abs(holes.xy).max() < 1000  # local frame near the origin
    back = holes.frame.to_input(holes.xy)
    original = table[["x", "y"]].to_numpy()
    # Every hole maps back to a table row to well below a millimetre.
    from scipy.spatial import cKDTree

    d, _ = cKDTree(original).query(back)
    assert d.max() < 1e-6


def test_a_missing_column_message_names_the_option_that_names_it(tmp_path):
    """``--geozone`` selects geozones: the hint for an unfound geozone column is ``--geozone-column``."""
    path = write(tmp_path, small_table().rename(columns={"lookup_domain": "rocktype"}))
    with pytest.raises(BGMInputError, match="name it with --geozone-column COLUMN"):
        read_blastholes(path)
    path = write(tmp_path, small_table().assign(zone="a"), name="two.csv")
    with pytest.raises(BGMInputError, match="choose one with --geozone-column COLUMN"):
        read_blastholes(path)
    assert read_blastholes(path, geozone="zone").geozones == ["a"]


def test_mid_point_columns_are_found_for_x_and_y_as_for_z(tmp_path):
    """A table of mid-points (``MID_X, MID_Y, MID_Z``, as mine databases export them) reads as found."""
    mid = small_table().rename(columns={"EAST": "MID_X", "NORTH": "MID_Y", "RL": "MID_Z"})
    holes = read_blastholes(write(tmp_path, mid))
    assert holes.n_benches == 3 and holes.geozones == ["2210", "3310"]


@pytest.mark.parametrize("sep", [";", ",", "\t"])
def test_an_excel_sep_line_names_the_delimiter(tmp_path, sep):
    """Excel writes (and reads) ``sep=;`` before the header: it names the delimiter and is no header."""
    path = tmp_path / "holes.csv"
    text = small_table().assign(lookup_domain="ore, oxide").to_csv(index=False, sep=sep, lineterminator="\r\n")
    path.write_text(f"sep={sep}\r\n{text}")
    holes = read_blastholes(path)
    assert holes.n_benches == 3 and holes.geozones == ["ore, oxide"] and len(holes.xy) == 120


def test_a_huge_bench_height_is_said_to_merge_the_levels_there_are():
    """``--bench-height 1e9`` on 10 m benches merges the 3 levels there are, not "100000000 levels"."""
    with pytest.raises(BGMInputError, match="the holes of all 3 levels on one bench") as refused:
        detect_benches(small_table()["RL"].to_numpy(), 1e9)
    assert "100000000" not in str(refused.value)


@pytest.mark.parametrize("missing", ["NA", "NULL", "-99"])
def test_labels_spelling_a_missing_value_are_warned_about(tmp_path, missing):
    """R writes a missing label ``NA``, SQL ``NULL``, mine databases ``-99``: a geozone of unlabelled holes, said so."""
    table = small_table()
    table.loc[[3, 50], "lookup_domain"] = missing
    with pytest.warns(
        BGMWarning, match=rf"'{missing}'.*look like missing values \(2 hole\(s\), data line\(s\) 5, 52\)"
    ):
        holes = read_blastholes(write(tmp_path, table))
    assert missing in holes.geozones  # kept: a code may be a real geozone


@pytest.mark.parametrize(
    "names", [("Easting (m)", "Northing (m)", "RL (m)"), ("EAST_M", "NORTH_M", "RL_M"), ("x [ft]", "y [ft]", "z [ft]")]
)
def test_columns_named_with_their_unit_are_found(tmp_path, names):
    """``Easting (m)``, ``RL_M``: a length unit ending a column's name does not hide its role."""
    table = small_table().rename(columns=dict(zip(["EAST", "NORTH", "RL"], names)))
    holes = read_blastholes(write(tmp_path, table))
    assert holes.n_benches == 3 and holes.geozones == ["2210", "3310"]


@pytest.mark.parametrize("name", ["hole_id", "Hole ID", "HOLE-ID", "HoleID", "BHID", "Hole Name"])
def test_hole_identifiers_are_found_however_the_column_is_written(tmp_path, name):
    """``Hole ID`` (Vulcan, Excel), ``BHID`` (Datamine): the holes keep their names, not row numbers.

    Missed, every hole named in a message or a file (``isolated_hole_ids``, a
    planned pattern's ``pattern_hole``) was a row number a geologist could take for an identifier.
    """
    from core.io.uncertainty_export import read_pattern

    table = small_table()
    ids = [f"P{i:04d}" for i in range(len(table))]
    holes = read_blastholes(write(tmp_path, table.assign(**{name: ids})))
    assert holes.hole_id is not None and list(holes.hole_id) == ids
    pattern = table[table.RL < 85][["EAST", "NORTH"]].assign(**{name: ids[: int((table.RL < 85).sum())]})
    _, labels, _ = read_pattern(write(tmp_path, pattern, "pattern.csv"), holes)
    assert labels == list(pattern[name])


def _feet_table_of_20_ft_benches(names) -> pd.DataFrame:
    """Holes 18 ft apart on benches 20 ft high: by the bench height alone, metres (5-20 m benches)."""
    table = small_table(benches=(5000.0, 4980.0, 4960.0)).assign(EAST=lambda t: t.EAST * 3, NORTH=lambda t: t.NORTH * 3)
    return table.rename(columns=dict(zip(["EAST", "NORTH", "RL"], names)))


@pytest.mark.parametrize("names", [("Easting (ft)", "Northing (ft)", "RL (ft)"), ("X_FT", "Y_FT", "Z_FT")])
def test_a_unit_the_columns_are_named_in_is_the_tables_unit(tmp_path, names):
    """``Easting (ft)``: the table says it is in feet, and is read in feet, whatever its bench height.

    Read as metres, its areas (``area_m2``), volumes and files were labelled metres, 3.28 times off.
    """
    path = write(tmp_path, _feet_table_of_20_ft_benches(names))
    holes = read_blastholes(path)
    assert holes.frame.length_unit == "ft" and not holes.unit_guess
    assert holes.bench_height_m == pytest.approx(20 * 0.3048, rel=0.02)
    # --units overrides the names, with a word that they say otherwise.
    with pytest.warns(BGMWarning, match="named .* in ft: read in m as given"):
        assert read_blastholes(path, length_unit="m").frame.length_unit == "m"


def test_columns_named_in_different_units_are_refused(tmp_path):
    path = write(tmp_path, _feet_table_of_20_ft_benches(("X (ft)", "Y (ft)", "RL (m)")))
    with pytest.raises(BGMInputError, match=r"named in different length units .*'RL \(m\)' in m"):
        read_blastholes(path)


@pytest.mark.parametrize("given", [None, "EAST"])
def test_two_columns_of_one_name_are_refused_not_the_first_read(tmp_path, given):
    """A collar's and a toe's ``EAST`` joined into one export: the first was read without a word.

    The message said to choose one with ``--x``, which names both; it says to rename them now.
    """
    table = small_table()
    text = table.assign(TOE=table.EAST + 3.0).to_csv(index=False).replace("TOE", "EAST", 1)
    path = tmp_path / "twice.csv"
    path.write_text(text)
    with pytest.raises(BGMInputError, match=r"2 columns named 'EAST' \(columns 1, 5\).*rename"):
        read_blastholes(path, x=given)


def test_mine_grid_coordinates_stored_as_32_bit_floats_are_warned_about(tmp_path):
    """A Parquet file of float32 northings near 7,400,000 holds them in 0.5-unit steps: said, not read silently.

    Local coordinates in float32 (steps of a thousandth of a unit) are read without a word.
    """
    table = small_table().assign(NORTH=lambda t: (t.NORTH + 7_400_000.0).astype("float32"))
    table.to_parquet(tmp_path / "grid.parquet")
    with pytest.warns(BGMWarning, match=r"'NORTH' \(y\) is stored as 32-bit floats.*steps of 0\.5 units"):
        read_blastholes(tmp_path / "grid.parquet")
    small_table().astype({"EAST": "float32", "NORTH": "float32"}).to_parquet(tmp_path / "local.parquet")
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)
        read_blastholes(tmp_path / "local.parquet")


def test_decimal_commas_with_dots_grouping_thousands(tmp_path):
    """European spreadsheets write mine-grid coordinates ``7.400.517,77``: read as 7400517.77, not refused."""
    table = small_table()
    table["EAST"] += 650_000.0
    table["NORTH"] += 7_400_000.0
    expected = read_blastholes(write(tmp_path, table, name="plain.csv"))

    def european(v: float) -> str:
        return f"{v:,.2f}".replace(",", " ").replace(".", ",").replace(" ", ".")

    styled = table.assign(EAST=table["EAST"].map(european), NORTH=table["NORTH"].map(european))
    styled.loc[0, "EAST"] = f"{round(table.loc[0, 'EAST']):,}".replace(",", ".")  # a whole number: dots only
    styled["RL"] = styled["RL"].map(lambda v: f"{v:.2f}".replace(".", ","))
    holes = read_blastholes(write(tmp_path, styled, name="european.csv", sep=";"))
    np.testing.assert_allclose(holes.frame.to_input(holes.xy)[1:], expected.frame.to_input(expected.xy)[1:], atol=0.006)
    assert holes.frame.to_input(holes.xy)[0, 0] == round(table.loc[0, "EAST"])


def test_one_label_in_two_unicode_forms_is_one_geozone(tmp_path):
    """ "minério" with "é" as one character on one bench and as "e" and an accent on the next looked the same
    everywhere but were two geozones, each on one bench, without a word."""
    import unicodedata

    table = small_table()
    composed, decomposed = unicodedata.normalize("NFC", "minério"), unicodedata.normalize("NFD", "minério")
    ore = table["lookup_domain"] == "3310"
    table.loc[ore, "lookup_domain"] = np.where(table.loc[ore, "RL"] > 95, composed, decomposed)
    with pytest.warns(BGMWarning, match="two Unicode forms"):
        holes = read_blastholes(write(tmp_path, table))
    assert holes.geozones == ["2210", composed]
    assert sorted(set(holes.bench[holes.geozone == composed].tolist())) == [0, 1, 2]
    assert holes.check_geozones([decomposed]) == [composed]


@pytest.mark.parametrize("benches", [(100.0,), (100.0, 78.0, 56.0)])
def test_a_unit_nothing_tells_is_said_to_be_assumed(tmp_path, benches):
    """A single bench (no bench height), or benches 22 units high (above metric 5-20 m, below imperial
    30-60 ft), were read as metres with nothing said: a table in feet gave a silently wrong model."""
    path = write(tmp_path, small_table(benches=benches))
    holes = read_blastholes(path)
    assert holes.frame.length_unit == "m" and "metres" in holes.unit_guess and "--units ft" in holes.unit_guess
    assert read_blastholes(path, length_unit="m").unit_guess == ""
    assert read_blastholes(path, length_unit="ft").read_options == {"length_unit": "ft"}  # what a project saves


def _pattern(nx: int, ny: int, z: float, spacing: float = 6.0) -> pd.DataFrame:
    """A bench of ``nx`` by ``ny`` holes ``spacing`` apart at elevation ``z``, two geozones side by side."""
    xs, ys = np.meshgrid(spacing * np.arange(nx), spacing * np.arange(ny))
    xs, ys = xs.ravel(), ys.ravel()
    return pd.DataFrame({"x": xs, "y": ys, "z": z, "geozone": np.where(xs < spacing * nx / 2, "a", "b")})


def test_a_bench_far_below_two_others_leaves_the_bench_height_theirs():
    """Two benches 10 m apart and a sparse bench 40 m below them: the bench height was the median gap, 25, no
    gap of theirs, and said to look like feet. The 40 m gap is four benches of 10; irregular benches keep the
    median gap."""
    from core.io.blastholes import blastholes_from_table

    table = pd.concat([_pattern(8, 5, 100.0), _pattern(8, 5, 90.0), _pattern(4, 2, 50.0)], ignore_index=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BGMWarning)  # nothing to say: metres, three benches on a 10 m ladder
        holes = blastholes_from_table(table, source="t.csv")
    assert holes.bench_height_m == pytest.approx(10.0)
    assert [holes.bench_z_input(k) for k in range(holes.n_benches)] == [100.0, 90.0, 50.0]
    from core.io.blastholes import typical_bench_height

    assert typical_bench_height(np.array([100.0, 90.0, 75.0])) == pytest.approx(12.5)  # 10 then 15: the median
    assert typical_bench_height(np.array([0.0, 15.1, 30.3, 45.3])) == pytest.approx(15.1)  # regular: the median


def test_the_models_bench_height_is_the_readers_beside_a_bench_not_drilled():
    """The model's fields measured their own bench height as the median gap: 25 for levels 100, 90 and 50, where
    the reader says 10; how far a boundary may move a bench and every trend's keys rest on it."""
    from core.geometry.grid import Grid
    from core.model.fields import BenchFields

    shape = (1, 2)
    fields = BenchFields(
        Grid(0.0, 0.0, 1.0, shape),
        np.array([100.0, 90.0, 50.0]),
        np.zeros((3, *shape)),
        np.ones((3, *shape)),
        np.ones((3, *shape), bool),
    )
    assert fields.bench_height_m == pytest.approx(10.0)


def test_a_sparse_bench_below_a_single_bench_is_read_as_a_bench_with_a_warning():
    """8 holes 40 m below a bench of 40, on its pattern, were refused as elevations "spread continuously ...
    with no gap between benches": too few for a bench of their own (10), and no bench height beside one bench.
    They are a bench opened or sampled sparsely: read as one, and said."""
    from core.io.blastholes import blastholes_from_table

    table = pd.concat([_pattern(8, 5, 100.0), _pattern(4, 2, 60.0)], ignore_index=True)
    # Two warnings: this one, and that 40 m benches might be feet (read as metres): both are due here.
    with pytest.warns(BGMWarning) as said:
        holes = blastholes_from_table(table, source="t.csv")
    assert any("few holes" in str(w.message) and "8 at z 60" in str(w.message) for w in said), said.list
    assert [holes.bench_z_input(k) for k in range(holes.n_benches)] == [100.0, 60.0]
    assert np.bincount(holes.bench).tolist() == [40, 8]
    assert any("8 at z 60" in note for note in holes.notes)
    # On another pattern (30 m apart against the bench's 6) they are no bench it drilled: refused, saying what to do.
    other = pd.concat([_pattern(8, 5, 100.0), _pattern(4, 2, 60.0, spacing=30.0)], ignore_index=True)
    with pytest.raises(BGMInputError, match=r"8 hole\(s\) at z 60.*not drilled on its hole pattern.*--bench-height"):
        blastholes_from_table(other, source="t.csv")
    given = blastholes_from_table(other, source="t.csv", bench_height=10.0)  # as the message says
    assert [given.bench_z_input(k) for k in range(given.n_benches)] == [100.0, 60.0]
    # Within a bench's spread a few holes stay off-bench holes of that bench, as before.
    near = pd.concat([_pattern(20, 10, 100.0), _pattern(3, 2, 97.0)], ignore_index=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        assert blastholes_from_table(near, source="t.csv").n_benches == 1


@pytest.mark.parametrize("scatter_m", [1.2, 1.5])
def test_benches_whose_holes_scatter_until_a_few_bridge_every_gap_are_found_at_their_levels(scatter_m):
    """Benches 10 m apart whose holes' elevations scatter by 1.2-1.5 m (a standard deviation) leave a few holes
    half-way between two benches: the gaps left are narrower than a bench's own scatter, and the table was refused
    as elevations "spread continuously". The benches are the dense bands of the elevations, and a bench being
    opened (a tenth of a bench's holes, as sparse as the ground between benches) one of them; holes further than 30%
    of a bench from every level are left out and said, as with a given bench height. Elevations spread evenly are
    still refused."""
    from core.io.blastholes import OFF_BENCH_FRACTION, blastholes_from_table

    rng = np.random.default_rng(3)
    levels = np.arange(100.0, 30.0, -10.0)
    # The deepest bench being opened: a tenth of a bench's holes, as sparse as the ground between two benches.
    opened = _pattern(40, 40, levels[-1]).sample(160, random_state=0)
    table = pd.concat([*(_pattern(40, 40, z) for z in levels[:-1]), opened], ignore_index=True)
    table["z"] += rng.normal(0.0, scatter_m, len(table))
    inner = np.sort(table["z"][(table["z"] > levels.min()) & (table["z"] < levels.max())].to_numpy())
    assert np.diff(inner).max() < 3.0 * scatter_m  # every gap between benches narrower than a bench's own scatter
    with pytest.warns(BGMWarning, match="from every bench level"):
        holes = blastholes_from_table(table, source="t.csv")
    assert np.allclose(holes.bench_levels_m, levels, atol=0.5)
    assert holes.bench_height_m == pytest.approx(10.0, abs=0.1)
    off = np.abs(table["z"].to_numpy()[:, None] - holes.bench_levels_m[None, :]) > OFF_BENCH_FRACTION * 10.0
    # Every hole within 3 m of a level kept (3 m: 30% of the gap to the next level, 10.3 m below the lowest found)
    assert abs(len(holes.xy) - (len(table) - off.all(axis=1).sum())) <= 2
    assert (np.abs(holes.z - holes.bench_levels_m[holes.bench]) <= OFF_BENCH_FRACTION * 10.5).all()
    spread = table.assign(z=rng.uniform(30.0, 100.0, len(table)))
    with pytest.raises(BGMInputError, match="spread continuously"):
        blastholes_from_table(spread, source="t.csv")


def test_benches_scattered_into_each_other_are_refused_with_the_bench_height_their_holes_repeat_at():
    """Scattered by 2 m, benches 10 m apart leave no sparse band between them: refused, as they were, but the
    refusal says the height at which the holes' density repeats, and that height reads them. Elevations spread
    evenly are refused without a height to give."""
    from core.io.blastholes import blastholes_from_table

    rng = np.random.default_rng(4)
    levels = np.arange(100.0, 30.0, -10.0)
    table = pd.concat([_pattern(40, 40, z) for z in levels], ignore_index=True)
    table["z"] += rng.normal(0.0, 2.0, len(table))
    with pytest.raises(BGMInputError, match=r"repeats about every 10 units of z.*--bench-height 10$"):
        blastholes_from_table(table, source="t.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = blastholes_from_table(table, source="t.csv", bench_height=10.0)  # as the message says
    assert np.allclose(holes.bench_levels_m, levels, atol=0.5)
    spread = table.assign(z=rng.uniform(30.0, 100.0, len(table)))
    with pytest.raises(BGMInputError, match="spread continuously") as refused:
        blastholes_from_table(spread, source="t.csv")
    assert "repeats" not in str(refused.value)


def test_holes_of_a_table_without_ids_are_named_by_the_file_line_they_were_read_from(tmp_path):
    # Without an id column a hole was named by its place among the kept holes (plus one), which is not its row
    # once a hole is left out or merged above it: the contours' isolated holes and the viewer pointed at the
    # wrong rows. Here a duplicate (line 3) and a hole far off every bench (line 4) come first.
    from core.io.reporting import hole_ids, hole_name

    xs, ys = np.meshgrid(np.arange(0.0, 60.0, 6.0), np.arange(0.0, 60.0, 6.0))
    grid = np.column_stack([xs.ravel(), ys.ravel()])
    rows = [(x, y, z, "a" if x < 30 else "b") for z in (100.0, 90.0, 80.0) for x, y in grid]
    rows = [rows[0], rows[0], (0.0, 0.0, 300.0, "a"), *rows[1:]]
    path = tmp_path / "holes.csv"
    pd.DataFrame(rows, columns=["x", "y", "z", "geozone"]).to_csv(path, index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = read_blastholes(path)
    assert holes.hole_id is None and len(holes.xy) == len(rows) - 2
    table = pd.read_csv(path)
    for k in (0, 1, 57, len(holes.xy) - 1):
        x, y = holes.frame.to_input(holes.xy[k : k + 1])[0]
        z = holes.frame.z_to_input(holes.z[k])
        first = np.flatnonzero(np.isclose(table.x, x) & np.isclose(table.y, y) & np.isclose(table.z, z))[0]
        assert hole_ids(holes, np.array([k])) == [first + 2]  # the header is line 1
        assert hole_name(holes, k) == f"line {first + 2}"


def depths_below_a_datum(table: pd.DataFrame, column: str) -> pd.DataFrame:
    """``table`` with ``column``'s elevations written as depths below a datum above its top bench (positive down)."""
    z = table[column].astype(float)
    return table.assign(**{column: np.round(float(np.ceil(z.max())) + 10.0 - z, 2)})


def said_upside_down(path, **kw) -> list[str]:
    """The warnings reading ``path`` gives that the benches widen with depth."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", BGMWarning)
        read_blastholes(path, **kw)
    return [str(w.message) for w in caught if "widen with depth" in str(w.message)]


@pytest.mark.parametrize(
    ("family", "seed", "name"), [("strips", 0, "z"), ("folds", 1, "RL"), ("pods", 2, "Z"), ("mix", 3, "elevation")]
)
def test_depths_in_an_elevation_column_are_said_to_read_upside_down(tmp_path, family, seed, name):
    """Depths below a datum in a column named ``z``, ``RL`` or ``elevation`` were read as elevations without a word:
    the benches in reverse order, every prediction below the deepest bench above the top one. An open pit narrows
    with depth: benches that widen with depth as read are said to, naming the column and what to do."""
    _, table, _ = scenario(family, seed)
    table = table.rename(columns={"z": name})
    assert not said_upside_down(write(tmp_path, table))
    said = said_upside_down(write(tmp_path, depths_below_a_datum(table, name), name="depths.csv"))
    assert len(said) == 1 and repr(name) in said[0] and "depths (positive down)" in said[0], said
    assert re.search(r"span \d\.\d times the area of the top third", said[0]) and "give elevations" in said[0]


@pytest.mark.parametrize("source", ["demo", "kennecott"])
def test_the_demo_and_kennecott_read_right_way_up_without_a_word(request, tmp_path, source):
    """Kennecott's top bench holds 20 holes (a bench partly in the table): it does not decide the pit's shape.

    Upside down, the demo's pit widens with depth and is said to. Kennecott's benches of this period hardly
    narrow once a few stray holes are left out of their extent (the top two spanning 0.94 times the area of the
    deepest two; with its stray holes, bench 2's extent was half as large again): upside down they are 1.07,
    under the ratio, so nothing is said either way, rather than a warning resting on a few holes."""
    path = DEMO_CSV if source == "demo" else request.getfixturevalue("kennecott_csv")
    assert not said_upside_down(path)
    if source == "demo":
        table = pd.read_csv(path, dtype=str, keep_default_na=False)
        assert len(said_upside_down(write(tmp_path, depths_below_a_datum(table, "z")))) == 1


def test_a_few_holes_far_off_on_the_deepest_bench_do_not_make_the_pit_widen(tmp_path):
    """A bench's extent is its blast patterns' (holes with a dozen others within three spacings), not the convex
    hull of every hole: four holes 300 m off on one bench made its hull the largest. Upside down, that bench
    on top hid the pit widening with depth (nothing said); on a table whose benches span the same ground it
    made them read upside down (the pinched-out body of test_prediction: 2.3 times the top bench's area)."""
    rng = np.random.default_rng(3)
    frames = []
    for k, half in enumerate((100.0, 90.0, 80.0, 70.0, 60.0)):
        x, y = np.meshgrid(np.arange(-half, half, 6.0), np.arange(-half, half, 5.2))
        xy = np.c_[x.ravel() + (np.round(y.ravel() / 5.2) % 2) * 3.0, y.ravel()]
        if k == 4:
            xy = np.vstack([xy, [[400.0, 400.0], [406.0, 400.0], [403.0, 405.0], [409.0, 405.0]]])
        label = np.where(rng.random(len(xy)) < 0.3, "ore", "waste")
        frames.append(pd.DataFrame({"x": xy[:, 0], "y": xy[:, 1], "z": 500.0 - 10.0 * k, "geozone": label}))
    table = pd.concat(frames, ignore_index=True)
    assert not said_upside_down(write(tmp_path, table))
    flipped = table.assign(z=1000.0 - table["z"])
    assert len(said_upside_down(write(tmp_path, flipped, name="flipped.csv"))) == 1


def test_a_repeating_height_of_a_hundred_units_or_more_is_said_as_a_number_to_give():
    """Two figures of 152 were said as "1.5e+02", not a height a geologist would type: now "150"."""
    from core.io.blastholes import blastholes_from_table

    rng = np.random.default_rng(4)
    table = pd.concat([_pattern(40, 40, z) for z in np.arange(1500.0, 450.0, -150.0)], ignore_index=True)
    table["z"] += rng.normal(0.0, 30.0, len(table))
    with pytest.raises(BGMInputError, match=r"repeats about every 150 units of z.*--bench-height 150$"):
        blastholes_from_table(table, source="t.csv")
