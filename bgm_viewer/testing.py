"""Small, fast inputs for the viewer's tests and benchmarks (no Qt)."""

from __future__ import annotations

import functools
import warnings


@functools.lru_cache(maxsize=2)
def small_holes(seed: int = 3):
    """A 3-bench synthetic mine of about 900 holes (extraction takes about a second)."""
    from core.io.blastholes import blastholes_from_table
    from core.synthetic.blobs import make_mine, sample_blastholes

    mine = make_mine(seed=seed, n_benches=3, extent_m=(140.0, 100.0), n_pods=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return blastholes_from_table(sample_blastholes(mine, seed=seed + 1), source=f"small mine {seed}")


def small_model(seed: int = 3, until: str = "surface"):
    """A :class:`~bgm_viewer.model.ViewerModel` of :func:`small_holes` with the pipeline run."""
    from .model import ViewerModel

    model = ViewerModel(small_holes(seed))
    model.select("g1", 0, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.run(until=until)
    return model
