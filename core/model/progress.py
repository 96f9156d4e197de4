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
