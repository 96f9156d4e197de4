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


@functools.lru_cache(maxsize=1)
def bodies_that_start_and_end_holes():
    """A 4-bench mine whose g1 has, besides its main body (component 0): on the top bench a body A
    that ends below it (component 1) and a small body (component 2) that continues as body B, the
    second component of the bench below."""
    from core.io.blastholes import blastholes_from_table
    from core.synthetic.blobs import make_mine, sample_blastholes

    table = sample_blastholes(make_mine(seed=3, n_benches=4, extent_m=(140.0, 100.0), n_pods=1), seed=4)
    bench_z = table.z.round(-1)
    levels = sorted(bench_z.unique())[::-1]
    x0, y0, x1, y1 = table.x.min(), table.y.min(), table.x.max(), table.y.max()
    a = ((table.x - x0 - 20) ** 2 + (table.y - y0 - 20) ** 2 < 14**2) & (bench_z == levels[0])
    b = ((table.x - x1 + 20) ** 2 + (table.y - y1 + 20) ** 2 < 14**2) & bench_z.isin(levels[1:3])
    table.loc[a | b, "geozone"] = "g1"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return blastholes_from_table(table, length_unit="m", source="g1 bodies that start and end")


def small_model(seed: int = 3, until: str = "surface"):
    """A :class:`~bgm_viewer.model.ViewerModel` of :func:`small_holes` with the pipeline run."""
    from .model import ViewerModel

    model = ViewerModel(small_holes(seed))
    model.select("g1", 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until=until)
    return model
