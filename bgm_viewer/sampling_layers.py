"""Where to sample next, as two layers: the uncertainty of the next bench and the holes suggested there.

Both draw one :class:`NextBench`, computed by ``core`` (:mod:`core.model.uncertainty`,
:mod:`core.model.sampling`) the first time either layer is drawn, so a
scene rebuilt without showing them costs nothing. The window defers it
(``deferred``): its layers draw nothing until the window's worker thread has
run :meth:`NextBench.compute` (1-3.5 s on Kennecott, a frozen window on its
own thread), then are told their data changed. A newer request cancels that
computation through its ``progress`` (:func:`core.threads.cancelling`): it
stops at core's next step and leaves the next bench pending, not half computed:

* :class:`UncertaintyLayer` -- P(inside) as a colour map on the next bench's
  plane where it is uncertain (blue outside, red inside, white at one half),
  and the outline of the band;
* :class:`SuggestedHolesLayer` -- the suggested holes, most informative
  first; its ``frame`` is the budget (``frame + 1`` holes shown), so the
  window's frame slider is the budget slider.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import pyvista as pv

from core.threads import Progress

from . import _vtkenv  # noqa: F401  (must precede pyvista)
from .layers import Layer, MeshItem, _colormap, _line_style, _xyz, polygon_rings, polylines

#: Cells shown by the uncertainty layer: P(inside) strictly between these (the rest is sure).
SHOWN_PROBABILITY = (0.02, 0.98)
#: Most holes the budget slider offers.
MAX_BUDGET = 200
SUGGESTED_COLOUR = (255, 40, 40)
BAND_COLOUR = (255, 190, 120)


class NextBench:
    """The selected geozone's predicted section one bench below the deepest, its band and suggested holes.

    Parameters
    ----------
    holes : core.io.blastholes.Blastholes
    model : core.model.pipeline.GeozoneModel or None
    probability : float
        The band's probability of holding the true boundary.
    session : core.model.session.ModelSession, optional
        The session ``model`` was computed with: the band is then calibrated as ``bgm build``
        calibrates the one it writes, on the other geozones' backtests too where the geozone's
        own is too short (without it, on the geozone's own only).
    deferred : bool
        Computed by :meth:`compute` (in the window's worker thread), not when first drawn: until then
        the layers draw nothing (:attr:`pending`).
    """

    def __init__(self, holes, model, probability: float = 0.9, session=None, deferred: bool = False):
        self.holes, self.model, self.probability = holes, model, float(probability)
        self.session = session
        self.deferred = bool(deferred)
        #: Why :meth:`compute` failed (its layers then stay empty), else ``None``.
        self.error: str | None = None

    @property
    def computed(self) -> bool:
        """Whether the band and the suggestions are computed (the suggestions come last)."""
        return "suggestions_m" in vars(self)

    @property
    def pending(self) -> bool:
        """Deferred and not computed yet: the layers draw nothing (computing would freeze the window)."""
        return self.deferred and not self.computed

    def compute(self, progress: Progress | None = None) -> NextBench:
        """Compute the band and the suggestions (what the window runs off its thread); returns itself.

        Parameters
        ----------
        progress : callable, optional
            ``progress(done, total)`` of each of core's steps (see
            :func:`core.model.uncertainty.geozone_uncertainty`). Raising
            :class:`core.threads.Cancelled` there (a superseded request, the window
            closing) stops the computation at that step; the next bench then stays
            :attr:`pending`, and a later ``compute`` starts again.
        """
        if self.computed:
            return self
        section = self._section(progress)
        suggestions = self._suggestions(section, progress)
        if progress:  # the last step: a request cancelled meanwhile keeps nothing
            progress(1, 1)
        vars(self).update(section=section, suggestions_m=suggestions)  # what the cached properties would hold
        return self

    @property
    def z_m(self) -> float:
        return self.holes.below_deepest_m() if self.holes.n_benches > 1 else float(self.holes.bench_levels_m[-1])

    @cached_property
    def section(self):
        """:class:`core.model.uncertainty.SectionUncertainty` on the next bench (None without a model)."""
        return self._section()

    @cached_property
    def suggestions_m(self) -> np.ndarray:
        """Suggested holes, most informative first, ``(n, 2)`` local metres (up to :data:`MAX_BUDGET`)."""
        return self._suggestions(self.section)

    def _section(self, progress: Progress | None = None):
        from core.model.uncertainty import geozone_uncertainty, section_uncertainty

        fields = getattr(self.model, "fields", None)
        if fields is None or len(fields.z_m) < 2:
            return None
        if self.session is not None:  # as core.model.build.write_sampling: a band drawn as it is written
            sections = geozone_uncertainty(
                self.session, self.model.geozone, [self.z_m], self.model, self.probability, progress
            )
            return sections[self.z_m]
        return section_uncertainty(fields, self.z_m, self.holes.hole_spacing_m, self.probability, progress=progress)

    def _suggestions(self, section, progress: Progress | None = None) -> np.ndarray:
        from core.model.sampling import next_bench_candidates, suggest_holes

        if section is None:
            return np.zeros((0, 2))
        try:
            candidates = next_bench_candidates(self.holes)
        except ValueError:
            return np.zeros((0, 2))
        budget = min(int(section.in_band(candidates).sum()), MAX_BUDGET) if len(candidates) else 0
        spacing = self.holes.hole_spacing_m
        chosen = suggest_holes({self.model.geozone: section}, candidates, budget, spacing, progress)
        return np.array([s.xy_m for s in chosen], float).reshape(-1, 2)


class UncertaintyLayer(Layer):
    """P(inside) on the next bench's plane where it is uncertain, and the outline of the band (see the module)."""

    kind = "uncertainty"

    def __init__(self, next_bench: NextBench | None = None, *, name="uncertainty", opacity=0.7, **kw):
        kw.setdefault("color", BAND_COLOUR)
        super().__init__(name, opacity=opacity, **kw)
        self.next_bench = next_bench

    def _build(self, view):
        nb = self.next_bench
        section = None if nb is None or nb.pending or nb.error else nb.section
        if section is None:
            return []
        g, z = section.grid, float(view.z(section.z_m))
        rows, cols = section.field.shape
        image = pv.ImageData(
            dimensions=(cols, rows, 1), spacing=(g.cell_size_m, g.cell_size_m, 1.0), origin=(g.x0, g.y0, z)
        )
        image.point_data["p"] = section.inside_probability.ravel()  # rows = y: C order is x fastest
        shown = image.threshold(SHOWN_PROBABILITY, scalars="p", all_scalars=True).extract_surface(algorithm=None)
        items = []
        if shown.n_points:
            shown.point_data["rgb"] = _colormap(np.asarray(shown.point_data["p"]), "coolwarm")
            style = {"scalars": "rgb", "rgb": True, "lighting": False, "show_scalar_bar": False}
            items.append(MeshItem(shown, style))
        rings = [_xyz(r, z + 0.1) for r in polygon_rings(section.band)]
        items.append(MeshItem(polylines(rings), _line_style(1.5, rgb=False, color=self.color)))
        return items

    def legend(self):
        p = int(round(100 * self.next_bench.probability)) if self.next_bench is not None else 90
        return [(f"{p}% band of the boundary, next bench", self.color)]


class SuggestedHolesLayer(Layer):
    """The holes suggested on the next bench; ``frame + 1`` of them shown (the budget)."""

    kind = "suggested holes"

    def __init__(self, next_bench: NextBench | None = None, *, name="suggested holes", point_size=12.0, **kw):
        kw.setdefault("color", SUGGESTED_COLOUR)
        super().__init__(name, **kw)
        self.next_bench = next_bench
        self.point_size = point_size
        self._budget: int | None = None

    @property
    def n_frames(self) -> int:
        return max(len(self._holes()), 1)

    @property
    def frame(self) -> int:
        return self.n_frames - 1 if self._budget is None else min(self._budget, self.n_frames) - 1

    @frame.setter
    def frame(self, value: int) -> None:
        value = int(np.clip(value if value >= 0 else value + self.n_frames, 0, self.n_frames - 1))
        if value != self.frame:
            self._budget = value + 1
            self._emit("frame")

    @property
    def budget(self) -> int:
        """How many suggested holes are shown."""
        return min(self.frame + 1, len(self._holes()))

    @budget.setter
    def budget(self, value: int) -> None:
        self.frame = int(value) - 1

    def _holes(self) -> np.ndarray:
        nb = self.next_bench
        return np.zeros((0, 2)) if nb is None or nb.pending or nb.error else nb.suggestions_m

    def _build(self, view):
        xy = self._holes()[: self.budget]
        if not len(xy):
            return []
        mesh = pv.PolyData(_xyz(xy, float(view.z(self.next_bench.z_m)) + 0.2))
        style = {"color": self.color, "point_size": self.point_size, "render_points_as_spheres": True}
        return [MeshItem(mesh, {**style, "lighting": False, "show_scalar_bar": False})]
