"""Warnings silenced for one piece of work (a viewer run), not for the whole process.

``warnings.catch_warnings`` changes the process's filters (Python's warnings filters are
process-global before 3.14): a viewer run that silenced the engine's warnings with it, in
its worker thread, silenced every thread's while it ran. A warning the window's thread gave
meanwhile (a project's override dropped, said as the run's result is drawn) never reached
stderr; and two runs overlapping (one cancelled, the next started) each put back the filters
it found, which could leave the process silenced for good.

Here one filter, kept first in the process's list, ignores every warning given in a silenced
context (:mod:`contextvars`) and matches none elsewhere: the work's warnings, and those of the
threads it starts through :func:`core.threads.on_threads` (which run in its context), are
dropped before any other filter sees them (neither counted as shown nor raised by ``-W error``);
every other thread's go on as before.

Opening a file is the converse: the window's thread keeps the engine's warnings it gives
(:func:`noted`) to show them in a dialog. ``catch_warnings(record=True)`` did that by taking
every thread's warnings meanwhile: a run's silenced ones, which its filter went before, and a
plain thread's, as if the file had said them. Here the notes are kept in the context that
opens the file (and the threads it starts), by a ``showwarning`` that only reads the context.
Plain Python: no Qt.
"""

from __future__ import annotations

import contextlib
import contextvars
import warnings
from collections.abc import Callable, Iterator
from typing import TypeVar, cast

from core.errors import BGMWarning

Item = TypeVar("Item")
Result = TypeVar("Result")

#: True in the context of work whose warnings are silenced (see :func:`silenced`).
_SILENCED = contextvars.ContextVar("bgm_viewer_warnings_silenced", default=False)


class _InSilencedContext:
    """A warnings filter's message pattern matching any message given in a silenced context, and none elsewhere.

    ``warnings.filters`` holds compiled patterns and calls their ``match(message)`` (the C and
    the Python implementations alike, 3.11 to 3.14): this one asks the context, not the text.
    """

    def match(self, message: str) -> bool:
        return _SILENCED.get()

    def __repr__(self) -> str:
        return "<any message in a context bgm_viewer.silence.silenced>"


#: Ignore a warning of any category, from any module and line, given in a silenced context.
SILENCED_FILTER = ("ignore", _InSilencedContext(), Warning, None, 0)


def _filter_first() -> None:
    """Put :data:`SILENCED_FILTER` first in the process's filters, again if it is not there.

    A filter added since goes before it (``simplefilter``), and a ``catch_warnings`` on
    another thread puts back a list it is not in: taken again at each step of the work.
    """
    filters = cast(list, warnings.filters)  # a list (typeshed says a Sequence: not to be changed but by the API)
    if filters and filters[0] is SILENCED_FILTER:
        return
    with contextlib.suppress(ValueError):
        filters.remove(SILENCED_FILTER)
    filters.insert(0, SILENCED_FILTER)


def silenced(steps: Iterator[Item]) -> Iterator[Item]:
    """``steps``' items, each computed with the warnings it gives silenced, and only those.

    Every step of ``steps`` runs in one context of its own, marked silenced (whatever thread
    takes it): a warning another thread gives meanwhile is filtered and shown as usual.
    """
    context = contextvars.copy_context()
    context.run(_SILENCED.set, True)
    try:
        while True:
            _filter_first()
            try:
                item = context.run(next, steps)
            except StopIteration:
                return
            yield item
    finally:
        close = getattr(steps, "close", None)
        if close is not None:  # its clean-up, stopped early, is silenced too
            context.run(close)


#: The messages of the engine's warnings given in a context that keeps them (see :func:`noted`); None elsewhere.
_NOTES: contextvars.ContextVar[list[str] | None] = contextvars.ContextVar("bgm_viewer_warnings_noted", default=None)


class _InNotingContext:
    """A warnings filter's message pattern matching any message given in a noting context, and none elsewhere."""

    def match(self, message: str) -> bool:
        return _NOTES.get() is not None

    def __repr__(self) -> str:
        return "<any message in a context bgm_viewer.silence.noted>"


#: Show every engine warning given in a noting context, one given before at the same place too (a file opened again).
NOTED_FILTER = ("always", _InNotingContext(), BGMWarning, None, 0)


class _NotingShow:
    """A ``warnings.showwarning`` keeping an engine warning's message in its context's notes, then showing it as before."""

    def __init__(self, show: Callable) -> None:
        self.show = show

    def __call__(self, message, category, filename, lineno, file=None, line=None) -> None:
        notes = _NOTES.get()
        if notes is not None and issubclass(category, BGMWarning):
            notes.append(str(message))
        self.show(message, category, filename, lineno, file, line)


def _noting() -> None:
    """Install :class:`_NotingShow` and :data:`NOTED_FILTER`, again if a ``catch_warnings`` put back what it found."""
    if not isinstance(warnings.showwarning, _NotingShow):
        warnings.showwarning = _NotingShow(warnings.showwarning)
    filters = cast(list, warnings.filters)
    with contextlib.suppress(ValueError):
        filters.remove(NOTED_FILTER)
    # A filter added the public way makes the process forget where warnings were shown, so that a file opened again
    # says its notes again; it is then made the noting context's.
    warnings.filterwarnings("always", category=BGMWarning)
    filters[filters.index(("always", None, BGMWarning, None, 0))] = NOTED_FILTER


def noted(fn: Callable[[], Result]) -> tuple[Result, list[str]]:
    """``(fn(), messages)``: the messages of the :class:`~core.errors.BGMWarning` ``fn`` gave, which go on stderr too.

    Only ``fn``'s (and those of the threads it starts through :func:`core.threads.on_threads`): another thread's
    warnings meanwhile, a run's silenced ones among them, are neither kept nor changed. Other warnings pass on as
    usual.
    """
    notes: list[str] = []
    context = contextvars.copy_context()
    context.run(_NOTES.set, notes)
    _noting()
    return context.run(fn), notes
