"""Named synthetic scenarios: every family at fixed seeds, split into tuning and held-out seeds.

A scenario is a family of :mod:`core.synthetic.families` at a seed, drilled by
:func:`core.synthetic.drilling.drill_mine`. Benchmarks and accuracy tests run
on every family in :data:`FAMILIES`.

Seeds come in two disjoint sets:

* :data:`TUNING_SEEDS` -- for developing the engine: try changes and choose
  defaults on these.
* :data:`HELD_OUT_SEEDS` -- the only seeds whose figures are reported. No
  default, threshold or parameter of the engine may ever be chosen by looking
  at results on them; otherwise they stop measuring how the engine does on
  geology it has not seen.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from typing import Any

import pandas as pd

from core.synthetic.blobs import SyntheticMine
from core.synthetic.drilling import drill_mine
from core.synthetic.families import PLANS, compose

#: Family names, in the order reports list them (that of :data:`~core.synthetic.families.PLANS`).
FAMILIES: tuple[str, ...] = tuple(PLANS)
#: Seeds to develop and tune on.
TUNING_SEEDS: tuple[int, ...] = tuple(range(0, 20))
#: Seeds to report on, never to tune on (see the module docstring).
HELD_OUT_SEEDS: tuple[int, ...] = (7001, 7002, 7003, 7004, 7005, 7006, 7007, 7008)


def make_family(
    family: str,
    seed: int,
    *,
    n_benches: int = 7,
    bench_height_m: float = 10.0,
    units: str = "m",
    shift_scale: float = 1.0,
    length_scale: float = 1.0,
) -> SyntheticMine:
    """The mine of ``family`` at ``seed`` (not drilled yet); raises ValueError for an unknown family or seed."""
    if family not in PLANS:
        raise ValueError(f"unknown family {family!r}; families: {', '.join(FAMILIES)}")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be a whole number >= 0, got {seed!r}")
    for name, scale in (("shift_scale", shift_scale), ("length_scale", length_scale)):
        if not scale > 0:
            raise ValueError(f"{name} must be positive, got {scale!r}")
    return compose(family, int(seed), PLANS[family], n_benches, bench_height_m, units, shift_scale, length_scale)


def scenario(
    family: str,
    seed: int,
    *,
    n_benches: int = 7,
    bench_height_m: float = 10.0,
    units: str = "m",
    drilling: Mapping[str, Any] | None = None,
    shift_scale: float = 1.0,
    length_scale: float = 1.0,
) -> tuple[SyntheticMine, pd.DataFrame, pd.Series]:
    """The mine of ``family`` at ``seed``, drilled.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    seed : int
        Whole number >= 0; the same seed always gives the same scenario.
    n_benches, bench_height_m : int, float
        Benches to drill and their height (metres).
    units : {"m", "ft"}
        Units of the table (the geometry is the same; feet coordinates are
        metres / 0.3048).
    drilling : mapping, optional
        Keyword arguments of :func:`~core.synthetic.drilling.drill_mine`
        other than the seed (hole spacing, label noise, ...): the defaults
        otherwise.
    shift_scale : float
        Times the families' rates at which dipping layers, contacts and fold
        hinges move sideways with depth (1: 2-15 m per 10 m of depth).
    length_scale : float
        Times as long in x as the families' mines (280-360 m): 4 makes a pit
        of Kennecott's shape, 1.1-1.4 km by 240-300 m.

    Returns
    -------
    mine : SyntheticMine
        With ``footprints`` filled in by drilling.
    table : DataFrame
        What the engine reads: ``x, y, z, geozone, hole_id`` (labels with noise).
    true_labels : Series
        True geozone of every hole, indexed by ``hole_id``; never give it to the engine.
    """
    mine = make_family(
        family,
        seed,
        n_benches=n_benches,
        bench_height_m=bench_height_m,
        units=units,
        shift_scale=shift_scale,
        length_scale=length_scale,
    )
    table, true_labels = drill_mine(mine, seed=[int(seed), zlib.crc32(family.encode()), 1], **(drilling or {}))
    return mine, table, true_labels
