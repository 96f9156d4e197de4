"""The viewer keeps the warnings of opening a file, and only those (bgm_viewer.silence.noted): no Qt needed."""

from __future__ import annotations

import threading
import warnings

from bgm_viewer.silence import noted, silenced
from core.errors import BGMWarning


def test_opening_a_file_keeps_its_own_notes_not_those_other_threads_give_meanwhile(recwarn):
    """``catch_warnings(record=True)`` on the window's thread took every thread's warnings while a file opened: a
    run's, which it should have silenced, and another thread's, shown in the file's dialog as if the file said them.
    """
    go = threading.Event()

    def run_steps():
        go.wait(60)
        warnings.warn("the run's warning", BGMWarning, stacklevel=1)
        yield 1

    run = threading.Thread(target=lambda: list(silenced(run_steps())), name="run")
    run.start()

    def open_file() -> str:
        warnings.warn("the file's note", BGMWarning, stacklevel=1)
        go.set()  # the run warns while the file is still opening
        run.join(60)
        other = threading.Thread(target=lambda: warnings.warn("another thread's warning", BGMWarning, stacklevel=1))
        other.start()
        other.join(60)
        warnings.warn("not the engine's", UserWarning, stacklevel=1)
        return "opened"

    try:
        opened, notes = noted(open_file)
    finally:
        go.set()
        run.join(60)
    assert opened == "opened"
    assert notes == ["the file's note"]
    shown = sorted(str(w.message) for w in recwarn)
    assert shown == ["another thread's warning", "not the engine's", "the file's note"]  # on stderr, the run's not


def test_a_file_opened_again_says_its_notes_again(recwarn):
    """The process remembers where a warning was shown once (the default): a table read before, from the command
    line's session or a first opening, says its notes again when the viewer opens it."""

    def read_the_file() -> None:
        warnings.warn("guessed feet", BGMWarning, stacklevel=1)

    with warnings.catch_warnings():
        warnings.simplefilter("default")  # a warning once per place, as a process starts
        read_the_file()
        said = [noted(read_the_file)[1] for _ in range(2)]
    assert said == [["guessed feet"], ["guessed feet"]]
    assert [str(w.message) for w in recwarn] == ["guessed feet"] * 3  # and on stderr each time
