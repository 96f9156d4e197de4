"""The stages of a long command's ``progress(stage, done, total)``, and a geozone's work as steps.

``bgm build`` and ``bgm suggest`` report through one callback: the benches
traced (stage ``"contours"``), the steps of each geozone's work (``"surface
of geozone 3310"``: its bench pairs corresponded and morphed one by one, then
what follows), and each geozone done (``"geozone 3310"``). A geozone's work
took 10-25 s on Kennecott with nothing said, and a log could not tell it from
a hang; its steps take a few seconds each. The engine only calls the
callback: the command line says it (``core.cli.progress_bar``).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

#: The stage of the benches' contours, counted in benches.
CONTOURS_STAGE = "contours"
#: Longest geozone label in a stage (characters): a line of a log, not the label's whole text.
MAX_LABEL_CHARS = 40
#: The steps of a geozone's model before the steps that follow it: each bench pair, then its bench fields.
PAIR_STEP, FIELDS_STEP = "correspondence and morph", "bench fields"

Progress = Callable[[str, int, int], None]


def geozone_stage(geozone: str) -> str:
    """The stage that says a geozone is done: ``"geozone 3310"`` (counted in geozones)."""
    return f"geozone {geozone[:MAX_LABEL_CHARS]}"


def stage_unit(stage: str) -> str:
    """What ``done`` and ``total`` count in ``stage``: benches, geozones, or the steps of one geozone.

    Parameters
    ----------
    stage : str
        A stage given to a ``progress(stage, done, total)`` callback (this module's docstring).

    Returns
    -------
    str
        ``"benches"``, ``"geozones"`` or ``"steps"``.
    """
    if stage == CONTOURS_STAGE:
        return "benches"
    # Steps begin with their own name ("surface of geozone 3310"), never with "geozone ".
    return "geozones" if stage.startswith("geozone ") else "steps"


def one_at_a_time(progress: Progress | None) -> Progress:
    """``progress`` for work on several threads: one call at a time (a line is said whole), nothing if None.

    Parameters
    ----------
    progress : callable or None
        ``progress(stage, done, total)``.

    Returns
    -------
    callable
        The same, behind a lock.
    """
    lock = threading.Lock()

    def say(stage: str, done: int, total: int) -> None:
        if progress is not None:
            with lock:
                progress(stage, done, total)

    return say


def stage_run(stage: str) -> str:
    """Which series of steps ``stage`` belongs to: one geozone's (``"geozone 3310"``), else its unit's.

    A build's workers report two geozones' steps at once, interleaved: each
    geozone's are a series of their own, thinned apart from the other's.
    """
    unit = stage_unit(stage)
    # Step names hold no " of ": what follows the first is the geozone's stage, whatever its label.
    return stage.partition(" of ")[2] if unit == "steps" else unit


@dataclass
class GeozoneSteps:
    """One geozone's work as steps, said to ``progress``: each bench pair, its bench fields, then ``after``.

    The bench pairs are known only once its contours are paired (their
    number is the ``total`` of :meth:`ModelSession.geozone_model
    <core.model.session.ModelSession.geozone_model>`'s own progress, given to
    :meth:`pair`); each step says what was just done.

    Parameters
    ----------
    progress : callable or None
        ``progress(stage, done, total)``; None says nothing.
    geozone : str
    after : tuple of str
        The steps after the bench fields, in order (``"predictions"``, ``"surface"``).
    """

    progress: Progress | None
    geozone: str
    after: tuple[str, ...] = ()
    pairs: int = 0
    done: int = 0

    def pair(self, done: int, total: int) -> None:
        """A bench pair corresponded and morphed (``done`` of the geozone's ``total``): the model's ``progress``."""
        self.pairs = total
        self.step(PAIR_STEP)

    def step(self, name: str) -> None:
        """Step ``name`` is done."""
        self.done += 1
        if self.progress is not None:
            total = max(self.pairs + 1 + len(self.after), self.done)
            self.progress(f"{name} of {geozone_stage(self.geozone)}", self.done, total)


class Stages:
    """One ``progress(done, total)`` told over several stages, each its own share, never going back.

    A surface is made in stages (the geozone's model, its sections, the mesh), and each
    stage counted its own steps into the same callback: its sections 9 of 9, then the
    mesh's 0 of 2, the prediction's elevations 1 of 4 between its depth trend's
    backtests 5 of 6: a bar on it went back and forth. Here stage ``k`` of ``n`` is told
    as ``k/n`` of the whole plus its own fraction of ``1/n``, and nothing told is less
    than what was told before (a stage whose own steps start again, as a depth trend's
    backtests do for each dip, holds the bar where it was). Every call is passed on,
    so a :class:`core.threads.Cancelled` raised by ``progress`` still stops each step.

    Parameters
    ----------
    progress : callable or None
        ``progress(done, total)``; None says nothing.
    stages : int
        How many stages share it.
    """

    #: Steps of each stage in what is told (``done`` and ``total`` stay whole numbers).
    STEPS_PER_STAGE = 1000

    def __init__(self, progress: Callable[[int, int], None] | None, stages: int):
        self.progress, self.stages, self.told = progress, max(int(stages), 1), 0

    def stage(self, k: int) -> Callable[[int, int], None] | None:
        """The ``progress(done, total)`` of stage ``k`` (from 0); None when there is nothing to tell."""
        if self.progress is None:
            return None
        return lambda done, total: self._tell(k, done, total)

    def _tell(self, k: int, done: int, total: int) -> None:
        own = min(max(done / total, 0.0), 1.0) if total > 0 else 1.0
        whole = self.STEPS_PER_STAGE * self.stages
        self.told = max(self.told, min(round(self.STEPS_PER_STAGE * (k + own)), whole))
        assert self.progress is not None  # stage() hands out no callback without one
        self.progress(self.told, whole)
