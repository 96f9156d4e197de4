"""Several pieces of work at once on threads.

The heavy steps of the engine (scipy's sparse factorisations, distance
transforms and filters, shapely's vectorised predicates, numpy's array
arithmetic) release the GIL, so independent benches or geozones run side by
side on threads with no copy of the data: a bench's contours depend on its
own holes, a geozone's model on its own contours. ``bgm build`` uses worker
processes instead (:func:`core.model.build.build`), which share nothing.
"""

from __future__ import annotations

import contextvars
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor, as_completed
from typing import Any, TypeVar

Item = TypeVar("Item")
Result = TypeVar("Result")
#: ``progress(done, total)``: told as each step of a piece of work is done; it may raise :class:`Cancelled`.
Progress = Callable[[int, int], None]


class Cancelled(Exception):
    """Work whoever asked for it no longer wants: raised from its ``progress`` callback, it stops at that step."""


def cancelling(cancelled: Callable[[], bool], progress: Progress | None = None) -> Progress:
    """A ``progress(done, total)`` that raises :class:`Cancelled` once ``cancelled()`` is true.

    Until then the counts go on to ``progress`` (if any). What a thread cannot
    be told by a signal, it is told at its next step: the engine calls
    ``progress`` between steps, so the work stops there.
    """

    def told(done: int, total: int) -> None:
        if cancelled():
            raise Cancelled()
        if progress is not None:
            progress(done, total)

    return told


def available_cores() -> int:
    """Cores this process may run on (its affinity where the platform tells it, as ``taskset`` or a container sets it)."""
    affinity = getattr(os, "sched_getaffinity", None)
    return len(affinity(0)) if affinity else (os.cpu_count() or 1)


def on_threads(
    func: Callable[[Item], Result], items: Iterable[Item], threads: int | None = None
) -> Iterator[tuple[Item, Result]]:
    """``(item, func(item))`` for every item, several at once, in the order they finish.

    On ``threads`` threads (default: one per available core); one after
    another, in order, with one item or one core. A caller that stops early
    (an error, a cancelled viewer run) waits for the items begun and drops
    the others: items that take seconds should stop at their next step too,
    by the caller's ``progress`` raising :class:`Cancelled` in them. Once an
    item has raised (:class:`Cancelled` or an error), no other item begins:
    the caller gets that item's exception. Each item runs in a copy of the
    caller's :mod:`contextvars` context, as it would on the caller's thread.
    """
    todo = list(items)
    threads = min(len(todo), threads or available_cores())
    if threads <= 1:
        for item in todo:
            yield item, func(item)
        return
    stopped = threading.Event()
    with ThreadPoolExecutor(threads, thread_name_prefix="bgm") as pool:
        # each item in a copy of the caller's context, as on the caller's thread (the viewer's silenced warnings)
        jobs = {
            pool.submit(contextvars.copy_context().run, _unless_stopped, func, item, stopped): item for item in todo
        }
        try:
            for job in as_completed(jobs):
                result = job.result()
                if result is not _NOT_BEGUN:
                    yield jobs[job], result
        finally:
            for job in jobs:
                job.cancel()


#: What :func:`_unless_stopped` returns for an item it did not begin (never a result of ``func``).
_NOT_BEGUN: Any = object()


def _unless_stopped(func: Callable[[Item], Result], item: Item, stopped: threading.Event) -> Result:
    """``func(item)``, unless an item has raised already (``stopped`` set): then :data:`_NOT_BEGUN`.

    A worker thread takes the next queued item the moment its item raises,
    before the caller, woken by that exception, can cancel the queue: without
    this a stopped viewer run began another geozone's first bench pair
    (0.3-1 s on Kennecott) after the stop. ``stopped`` is set before the
    exception leaves the worker, so no item queued behind it begins.
    """
    if stopped.is_set():
        return _NOT_BEGUN
    try:
        return func(item)
    except BaseException:
        stopped.set()
        raise
