"""Seeded synthetic mines with analytic true sections, drilled and labelled as a mine would be."""

from core.synthetic.blobs import (
    HOST,
    Blob,
    SyntheticMine,
    bench_footprint,
    demo_dataset,
    drill_pattern,
    make_mine,
    sample_blastholes,
)

__all__ = [
    "HOST",
    "Blob",
    "SyntheticMine",
    "bench_footprint",
    "demo_dataset",
    "drill_pattern",
    "make_mine",
    "sample_blastholes",
]
