"""Several pieces of work at once on threads (:mod:`core.threads`)."""

from __future__ import annotations

import threading
import time

import pytest

from core.threads import Cancelled, on_threads


def test_no_item_begins_after_an_item_was_cancelled():
    """A stop stops the queue: once an item raised ``Cancelled``, the worker that ran it takes no other.

    The caller is busy with an earlier result when the item raises (as the viewer is, drawing a
    geozone), so only ``on_threads`` itself can keep the next queued item from beginning.
    """
    events: list[tuple[str, str]] = []
    lock = threading.Lock()

    def work(item: str) -> str:
        with lock:
            events.append(("began", item))
        if item == "quick":
            return item
        if item == "stopped":
            time.sleep(0.1)
            with lock:
                events.append(("raised", item))
            raise Cancelled()
        time.sleep(0.3)
        return item

    items = ["quick", "stopped", "slow", "a", "b", "c"]
    with pytest.raises(Cancelled):
        for _item, _result in on_threads(work, items, threads=2):
            time.sleep(0.4)  # the caller at work on a result while "stopped" raises
    raised_at = events.index(("raised", "stopped"))
    assert [e for e in events[raised_at:] if e[0] == "began"] == []


def test_an_error_reaches_the_caller_and_no_item_begins_after_it():
    """An error is the caller's (not an item left out), and nothing queued begins after it."""
    began: list[int] = []

    def work(item: int) -> int:
        began.append(item)
        if item == 1:
            time.sleep(0.1)
            raise ValueError("bench 1 is broken")
        time.sleep(0.0 if item == 0 else 0.3)
        return item

    with pytest.raises(ValueError, match="bench 1 is broken"):
        for _ in on_threads(work, range(8), threads=2):
            time.sleep(0.4)
    assert sorted(began) == [0, 1, 2]  # 2 began on the other worker before 1 raised, 3 never


def test_every_item_once_when_nothing_stops():
    done = dict(on_threads(lambda k: k * k, range(20), threads=2))
    assert done == {k: k * k for k in range(20)}


def test_each_item_runs_in_the_callers_context_on_whatever_thread():
    """The viewer silences a run's warnings in the run's context (bgm_viewer.silence): the items its steps put on
    threads ran in each thread's own, empty context, and their warnings went on stderr."""
    import contextvars

    marked = contextvars.ContextVar("marked", default="not set")

    def seen(item):
        time.sleep(0.01)  # several at once, on several threads
        return marked.get(), threading.current_thread().name

    marked.set("the caller's")
    try:
        done = dict(on_threads(seen, range(6), threads=3))
    finally:
        marked.set("not set")
    assert {value for value, _ in done.values()} == {"the caller's"}
    assert any(thread != threading.current_thread().name for _, thread in done.values())
