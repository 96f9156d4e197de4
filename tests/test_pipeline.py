"""The stages chained per geozone: correspondence recovers known movement, morphs reach targets."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import synthetic

from core.io.blastholes import BGMWarning, blastholes_from_table
from core.model.pipeline import model_geozone
from core.synthetic.blobs import demo_dataset


@pytest.mark.parametrize("source", ["demo", 31])
def test_translations_match_the_dipping_body_movement_within_a_hole_spacing(source):
    if source == "demo":
        mine, table = demo_dataset()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", BGMWarning)
            holes = blastholes_from_table(table)
    else:
        mine, _, holes = synthetic(source)
    model = model_geozone(holes, "g1", stages=("correspond",))
    true_shift = np.array(mine.geozones["g1"][0].velocity) * holes.bench_height_m
    assert len(model.pairs) == holes.n_benches - 1
    for pair in model.pairs:
        body = int(np.argmax([len(c.holes) for c in pair.sources]))
        error = np.hypot(*(pair.correspondence.translations[body] - true_shift))
        assert error < holes.hole_spacing_m, (pair.upper, pair.correspondence.translations[body], true_shift)


def test_split_body_is_associated_with_both_lobes_and_morphs_into_them():
    mine, table = demo_dataset()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BGMWarning)
        holes = blastholes_from_table(table)
    model = model_geozone(holes, "g2")
    # Somewhere down the pit one source becomes two targets (the lobes separate).
    splits = [p for p in model.pairs if (p.correspondence.association.sum(axis=1) >= 2).any()]
    assert splits, [p.correspondence.association.tolist() for p in model.pairs]
    coverage = []
    for pair in model.pairs:
        for step in pair.morphs:
            if step.instance.source_ids and step.instance.target_ids:
                assert step.result.iou >= 0.95
                assert step.result.target_boundary_coverage >= step.result.coverage_before_backtracking - 1e-9
                coverage.append(step.result.target_boundary_coverage)
    # Backtracking covers the target boundary almost everywhere; one lobe of the demo
    # keeps about a fifth of its boundary uncovered (a known shortfall, see the README).
    assert np.median(coverage) >= 0.99 and min(coverage) >= 0.75, coverage
