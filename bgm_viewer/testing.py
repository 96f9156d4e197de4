"""Small, fast inputs for the viewer's tests and benchmarks (no Qt)."""

from __future__ import annotations

import functools
import warnings


@functools.lru_cache(maxsize=4)
def small_holes(seed: int = 3, unit: str = "m"):
    """A 3-bench synthetic mine of about 900 holes (extraction takes about a second).

    ``unit="ft"``: the same mine with its coordinates written in feet.
    """
    from core.io.blastholes import FEET_TO_METRES, blastholes_from_table
    from core.synthetic.blobs import make_mine, sample_blastholes

    mine = make_mine(seed=seed, n_benches=3, extent_m=(140.0, 100.0), n_pods=1)
    table = sample_blastholes(mine, seed=seed + 1)
    if unit == "ft":
        for c in ("x", "y", "z"):
            table[c] = table[c] / FEET_TO_METRES
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return blastholes_from_table(table, length_unit=unit, source=f"small mine {seed} ({unit})")


@functools.lru_cache(maxsize=1)
def two_bodies_holes():
    """:func:`small_holes` with a second body of g1, a few holes in a corner of the top two benches.

    g1's top bench pair then has two source components: the main body (0) and the corner one (1).
    """
    from core.io.blastholes import blastholes_from_table
    from core.synthetic.blobs import make_mine, sample_blastholes

    table = sample_blastholes(make_mine(seed=3, n_benches=3, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    corner = (table.x - table.x.min() - 12) ** 2 + (table.y - table.y.min() - 12) ** 2 < 9**2
    table.loc[corner, "geozone"] = "g1"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return blastholes_from_table(table, length_unit="m", source="small mine with two g1 bodies")


def small_model(seed: int = 3, until: str = "surface"):
    """A :class:`~bgm_viewer.model.ViewerModel` of :func:`small_holes` with the pipeline run."""
    from .model import ViewerModel

    model = ViewerModel(small_holes(seed))
    model.select("g1", 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until=until)
    return model
