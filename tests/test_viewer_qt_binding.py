"""The Qt binding the viewer is installed with keeps a long session alive (no display needed)."""

from __future__ import annotations

import sys

import pytest


def test_qt_calls_returning_nothing_keep_none_alive():
    """PySide6 6.12.0 on Python 3.11 drops a reference to ``None`` at every call of a method that
    returns nothing (``setInterval``, ``showMessage``, ``update``...). ``None`` is not immortal
    before Python 3.12: after some ten minutes of turning the view (about two such calls a mouse
    move) its count reached zero and the viewer aborted with "Fatal Python error: none_dealloc".
    """
    QtCore = pytest.importorskip("PySide6.QtCore")
    timer = QtCore.QTimer()
    before = sys.getrefcount(None)
    for _ in range(1000):
        timer.setInterval(5)
    assert sys.getrefcount(None) >= before - 50
