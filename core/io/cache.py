"""On-disk cache of pipeline stage results, so repeated commands on the same input are fast.

A result is stored under a key that hashes everything it depends on: the
input's content (hole positions, labels, bench levels), the stage's
parameters and manual overrides, and the engine's own source code
(:func:`engine_fingerprint`, with the Python and numerical libraries it runs
on), so a changed file, parameter or program is never served a stale result. Entries are pickles written atomically
(:mod:`core.io.atomic`) under ``$BGM_CACHE_DIR`` or the user's cache folder
(``~/.cache/bgm`` on Linux); an unreadable entry is deleted and recomputed,
and the least recently used entries are removed beyond a size limit
(``$BGM_CACHE_MAX_MB``, 2048 by default). The cache holds only what this
user's own runs wrote: pickles are not a format to exchange.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import math
import os
import pickle
import sys
from pathlib import Path

import numpy as np

from core.io.atomic import atomic_write_bytes

CACHE_ENV = "BGM_CACHE_DIR"
MAX_MB_ENV = "BGM_CACHE_MAX_MB"
DEFAULT_MAX_MB = 2048
#: The cache is pruned after this many stores in one process (and after the first).
PRUNE_EVERY_STORES = 200
MISSING = object()


def default_cache_dir() -> Path:
    """``$BGM_CACHE_DIR`` if set, else the user's cache folder for bgm."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    import platformdirs

    return Path(platformdirs.user_cache_dir("bgm", appauthor=False))


#: Distributions whose versions change what the stages compute (geometry, grids, meshes).
NUMERICAL_DISTRIBUTIONS = ("numpy", "scipy", "scikit-image", "shapely", "pandas", "trimesh")


@functools.cache
def engine_fingerprint() -> str:
    """Hash of the engine's source code (every ``core/**/*.py``) and of what it runs on.

    A code change invalidates the cache; so does another Python, GEOS or
    version of a :data:`NUMERICAL_DISTRIBUTIONS` package: the cache folder is
    the user's, shared by every environment that runs bgm, and a contour from
    another GEOS is not this one's.
    """
    return content_key(source_fingerprint(Path(__file__).resolve().parents[1]), runtime_versions())


def runtime_versions() -> dict[str, str]:
    """Versions of Python, GEOS and the :data:`NUMERICAL_DISTRIBUTIONS` (``"-"`` for one not installed)."""
    from importlib import metadata

    import shapely

    versions = {"python": sys.version, "geos": shapely.geos_version_string}
    for name in NUMERICAL_DISTRIBUTIONS:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "-"
    return versions


def source_fingerprint(root: Path) -> str:
    """Hash of the names and contents of the Python files under ``root``."""
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def content_key(*parts) -> str:
    """Hex digest of ``parts``: numbers, strings, arrays, geometries, dataclasses, and containers of them."""
    h = hashlib.sha256()
    _feed(h, parts)
    return h.hexdigest()


def _feed(h, obj) -> None:
    import shapely

    if obj is None or isinstance(obj, (bool, int, float, str)):
        h.update(f"{type(obj).__name__}:{obj!r};".encode())
    elif isinstance(obj, bytes):
        h.update(b"bytes:%d;" % len(obj) + obj)
    elif isinstance(obj, np.ndarray):
        arr = np.ascontiguousarray(obj)
        if arr.dtype == object:
            _feed(h, ("object-array", arr.shape, "\x1f".join(map(str, arr.ravel().tolist()))))
        else:
            h.update(f"array:{arr.dtype.str}:{arr.shape};".encode())
            h.update(arr.tobytes())
    elif isinstance(obj, np.generic):
        _feed(h, obj.item())
    elif isinstance(obj, shapely.Geometry):
        _feed(h, shapely.to_wkb(obj))
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        _feed(h, (type(obj).__name__, [(f.name, getattr(obj, f.name)) for f in dataclasses.fields(obj)]))
    elif isinstance(obj, dict):
        h.update(b"dict;")
        for k in sorted(obj, key=repr):
            _feed(h, (k, obj[k]))
    elif isinstance(obj, (list, tuple, set, frozenset)):
        items = sorted(obj, key=repr) if isinstance(obj, (set, frozenset)) else obj
        h.update(f"{type(obj).__name__}:{len(items)}[".encode())
        for item in items:
            _feed(h, item)
        h.update(b"]")
    else:
        raise TypeError(f"cannot make a cache key of a {type(obj).__name__}")


def max_bytes_from_env() -> int:
    """The cache's size limit: ``$BGM_CACHE_MAX_MB`` megabytes (:data:`DEFAULT_MAX_MB` when unset).

    Raises
    ------
    BGMInputError
        A value that is not a number of megabytes, 0 or more (``abc``, ``nan``, ``-5``): it ended
        every command as an internal error (``abc``), or kept nothing (``-5``), without a word.
    """
    from core.errors import BGMInputError

    text = os.environ.get(MAX_MB_ENV, "").strip()
    if not text:
        return int(DEFAULT_MAX_MB * 1e6)
    try:
        mb = float(text)
    except ValueError:
        mb = float("nan")
    if not (math.isfinite(mb) and mb >= 0):
        raise BGMInputError(f"${MAX_MB_ENV} must be the cache's size limit in megabytes (0 or more), got {text!r}")
    return int(mb * 1e6)


class StageCache:
    """Pickled stage results in a folder, one file per ``(stage, key)``.

    Never raises for the cache's own sake: a folder that cannot be written
    only means results are not kept.
    """

    def __init__(self, directory: str | os.PathLike | None = None, max_bytes: int | None = None):
        self.directory = Path(directory) if directory is not None else default_cache_dir()
        self.max_bytes = max_bytes if max_bytes is not None else max_bytes_from_env()
        self._stores = 0

    def path(self, stage: str, key: str) -> Path:
        return self.directory / stage / key[:2] / f"{key}.pkl"

    def load(self, stage: str, key: str):
        """The stored value, or :data:`MISSING` (also for an entry that cannot be read, which is removed)."""
        path = self.path(stage, key)
        try:
            data = path.read_bytes()
        except OSError:
            return MISSING
        try:
            value = pickle.loads(data)
        except Exception:  # truncated, corrupt or from classes that changed: recompute
            with contextlib.suppress(OSError):
                path.unlink()
            return MISSING
        with contextlib.suppress(OSError):
            os.utime(path)  # recently used: pruned last
        return value

    def store(self, stage: str, key: str, value) -> None:
        """Keep ``value`` (atomically: a reader never sees half an entry)."""
        path = self.path(stage, key)
        if path.exists():  # keys name contents: another process stored the same result
            with contextlib.suppress(OSError):
                os.utime(path)
            return
        try:
            atomic_write_bytes(path, pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL))
        except Exception:  # full disk, read-only folder, unpicklable value: run uncached
            return
        self._stores += 1
        if self._stores % PRUNE_EVERY_STORES == 1:
            self.prune()

    def prune(self) -> None:
        """Remove the least recently used entries until the cache is under its size limit."""
        entries = []
        for path in self.directory.glob("*/*/*.pkl"):
            with contextlib.suppress(OSError):
                st = path.stat()
                entries.append((st.st_mtime, st.st_size, path))
        total = sum(size for _, size, _ in entries)
        for _, size, path in sorted(entries, key=lambda e: e[0]):
            if total <= self.max_bytes:
                break
            with contextlib.suppress(OSError):
                path.unlink()
                total -= size

    def __repr__(self) -> str:
        return f"StageCache({str(self.directory)!r})"
