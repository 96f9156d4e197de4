"""Errors the engine raises for bad input, and how user text appears in messages.

Every problem a user can cause (a missing column, NaN coordinates, a single
bench...) is raised as :class:`BGMInputError` with a sentence that names the
problem; the command line prints that sentence on one line and exits with
status 2 instead of showing a traceback.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

#: Longest piece of user-supplied text (a label, a column name) quoted in a message.
MAX_QUOTED_CHARS = 60


class BGMInputError(ValueError):
    """Input the engine cannot work with, described in one clear sentence."""


def quoted(text, limit: int = MAX_QUOTED_CHARS) -> str:
    """``repr`` of user text for a message, cut to ``limit`` characters.

    A label or column name can be megabytes long (a broken export); a message
    names it, it does not echo it.
    """
    text = str(text)
    if len(text) <= limit:
        return repr(text)
    return repr(text[:limit]) + f"... ({len(text)} characters)"


def listing(items, limit: int = 20) -> str:
    """Comma-separated, shortened items: at most ``limit`` of them, then how many more."""
    items = [str(i) for i in items]
    shown = ", ".join(i if len(i) <= MAX_QUOTED_CHARS and i.isprintable() else quoted(i) for i in items[:limit])
    return shown + (f" and {len(items) - limit} more" if len(items) > limit else "")


class BGMWarning(UserWarning):
    """Something in the input was repaired or left unused; the message says what."""


@dataclass(frozen=True)
class Range:
    """Valid values of one numeric parameter (see :func:`check_ranges`)."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False  #: the low end itself is not allowed
    integer: bool = False
    optional: bool = False  #: None allowed (a default derived from the data)

    def describe(self) -> str:
        kind = "an integer" if self.integer else "a finite number"
        bounds = []
        if math.isfinite(self.low):
            bounds.append(f"{'>' if self.low_open else '>='} {_number(self.low)}")
        if math.isfinite(self.high):
            bounds.append(f"<= {_number(self.high)}")
        return f"{kind} {' and '.join(bounds)}".strip()

    def holds(self, value) -> bool:
        if value is None:
            return self.optional
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            return False
        value = float(value)
        if self.integer and value != int(value):
            return False
        above = value > self.low if self.low_open else value >= self.low
        return above and value <= self.high


def check_ranges(params, ranges: dict[str, Range], prefix: str = "parameter ") -> None:
    """Raise :class:`BGMInputError` naming the first attribute of ``params`` outside its range."""
    for name, valid in ranges.items():
        value = getattr(params, name)
        if not valid.holds(value):
            raise BGMInputError(f"{prefix}{name} must be {valid.describe()}, got {quoted(value, 30)[1:-1]}")


def _number(v: float) -> str:
    return str(int(v)) if v == int(v) and abs(v) < 1e15 else f"{v:.6g}"
