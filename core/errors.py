"""Errors the engine raises for bad input.

Every problem a user can cause (a missing column, NaN coordinates, a single
bench...) is raised as :class:`BGMInputError` with a sentence that names the
problem; the command line prints that sentence and exits non-zero instead of
showing a traceback.
"""


class BGMInputError(ValueError):
    """Input the engine cannot work with, described in one clear sentence."""
