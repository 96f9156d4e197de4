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
every other thread's go on as before. Plain Python: no Qt.
"""

from __future__ import annotations

import contextlib
import contextvars
import warnings
from collections.abc import Iterator
from typing import TypeVar, cast

Item = TypeVar("Item")

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
