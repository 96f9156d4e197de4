"""Atomic file writing: a crash or Ctrl-C while saving leaves the old file intact.

Everything the engine saves goes through :func:`atomic_path`: the content is
written to a temporary file in the destination folder, flushed to disk, and
renamed over the destination in one step (``os.replace`` is atomic on POSIX
and Windows when both paths are on one file system).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from core.errors import BGMInputError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it over ``path`` on success.

    Use it for libraries that insist on writing a file themselves::

        with atomic_path("surface.stl") as tmp:
            mesh.export(tmp)

    If the block raises (or is interrupted), the temporary file is removed and
    ``path`` is untouched. ``suffix`` defaults to the destination's suffix so
    that writers choosing a format by extension still work.
    """
    path = Path(path)
    # An output path that is a folder, or a folder that cannot be created or
    # written to, is the user's to fix: say so in one line (BGMInputError)
    # instead of an internal error from os.replace / mkstemp.
    if path.is_dir():
        raise BGMInputError(f"cannot write {str(path)!r}: it is a directory; give a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(
            dir=path.parent, prefix=f".{path.name}.", suffix=suffix if suffix is not None else path.suffix
        )
    except OSError as exc:
        raise BGMInputError(f"cannot write {str(path)!r}: {exc.strerror or exc}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, _mode_for(path))
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def _mode_for(path: Path) -> int:
    """Keep an existing file's permissions; new files get the usual umask default."""
    try:
        return path.stat().st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask
