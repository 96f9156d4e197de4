"""Seeded synthetic mines with analytic true sections, drilled and labelled as a mine would be.

:mod:`~core.synthetic.blobs` is the bundled demo's mine; :mod:`~core.synthetic.families`
the families benchmarks run on, :mod:`~core.synthetic.scenarios` their named
seeds (tuning and held-out) and :mod:`~core.synthetic.drilling` how they are drilled.
"""

from core.synthetic.blobs import (
    HOST,
    Blob,
    Solid,
    SyntheticMine,
    bench_footprint,
    demo_dataset,
    drill_pattern,
    make_mine,
    sample_blastholes,
)
from core.synthetic.drilling import drill_mine
from core.synthetic.scenarios import FAMILIES, HELD_OUT_SEEDS, TUNING_SEEDS, make_family, scenario

__all__ = [
    "FAMILIES",
    "HELD_OUT_SEEDS",
    "HOST",
    "TUNING_SEEDS",
    "Blob",
    "Solid",
    "SyntheticMine",
    "bench_footprint",
    "demo_dataset",
    "drill_mine",
    "drill_pattern",
    "make_family",
    "make_mine",
    "sample_blastholes",
    "scenario",
]
