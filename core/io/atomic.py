"""Atomic file writing: a crash or Ctrl-C while saving leaves the old file intact.

Everything the engine and the viewer save goes through this module (a test
fails when a module writes a user-visible file any other way):

* :func:`atomic_path` for one file: the content is written to a temporary
  file in the destination folder, flushed to disk, and renamed over the
  destination in one step (``os.replace`` is atomic on POSIX and Windows when
  both paths are on one file system);
* :func:`replaced_folder` for a whole folder (``bgm build``): everything is
  written into a staging folder next to it, which is swapped in whole at the
  end, so an interrupted build leaves the previous folder untouched;
* :func:`replaced_files` for a set of files in one folder that belong together
  (``bgm predict``'s prediction and its two uncertainty files, ``bgm evaluate``'s
  tables and plot): all are written into a staging folder first and moved in
  only once every one is complete, so a failure leaves the previous set as it was;
* :func:`check_output` before any work starts: an output is never one of the
  inputs, a device or a folder where a file is expected.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import shutil
import signal
import stat
import sys
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from core.errors import BGMInputError

#: Marks the staging and retired folders of :func:`replaced_folder` (``.<name>.bgm-staging-<pid>-<random>``).
STAGING_TAG = ".bgm-staging-"
RETIRED_TAG = ".bgm-old-"
#: A write that failed for want of room or rights where it goes (a full disk, a quota, a file system
#: gone read-only, a failing disk): the user's to fix, said in one line, not reported as a bug in BGM.
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG, errno.EACCES, errno.EPERM})


class OutputError(BGMInputError):
    """A file that could not be written where it goes, for a reason of the storage (:data:`STORAGE_ERRNOS`).

    Parameters
    ----------
    path : Path
        The file that was being written.
    reason : str
        The system's words for it (``No space left on device``).
    """

    def __init__(self, path: Path, reason: str, aside: str = ""):
        super().__init__(f"cannot write {str(path)!r}: {reason}{aside}")
        self.path, self.reason = path, reason


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it over ``path`` on success.

    Use it for libraries that insist on writing a file themselves::

        with atomic_path("surface.stl") as tmp:
            mesh.export(tmp)

    If the block raises (or is interrupted), the temporary file is removed and
    ``path`` is untouched. ``suffix`` defaults to the destination's suffix so
    that writers choosing a format by extension still work. A symbolic link is
    written through (the link stays, its target gets the new content); a
    device, pipe or folder is refused with :class:`BGMInputError`.
    """
    path = _writable_file(Path(path))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(
            dir=path.parent, prefix=f".{path.name[:64]}.", suffix=suffix if suffix is not None else path.suffix
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
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS:  # the disk filled up while writing
            raise OutputError(path, exc.strerror or str(exc)) from None
        raise


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def check_output(
    path: str | os.PathLike, inputs: Iterable[str | os.PathLike | None] = (), *, folder: bool = False, what="--out"
) -> Path:
    """Refuse an output path that would destroy input or cannot hold the output.

    Parameters
    ----------
    path : path-like
        Where a command will write: a file, or a folder when ``folder``.
    inputs : paths
        Files the command reads (``None`` and ``-`` for stdin are skipped). A
        file output may not be one of them (also through a link); a folder
        output may not hold one of them, since it is replaced whole.
    what : str
        How the message names the output (an option name).

    Returns
    -------
    Path
    """
    if str(path) == "-":  # standard input as an input, but no command writes its output to standard output
        raise BGMInputError(
            f"{what} - would write a {'folder' if folder else 'file'} named '-', not standard output; give a "
            f"{'folder' if folder else 'file'} name"
        )
    if str(path).startswith("--"):
        # `--out --no-cache`: the option took the next one as its value, wrote into "--no-cache" and the flag
        # was dropped without a word. A path meant so can be given as ./--name.
        raise BGMInputError(
            f"{what} {str(path)!r} looks like an option: was {what}'s value left out? "
            f"(a name starting with -- can be given as ./{path})"
        )
    path = Path(path)
    if folder:
        if path.exists() and not path.is_dir():
            raise BGMInputError(f"{what} {str(path)!r} is a file; give a folder to write into")
        # As for a file: a folder that cannot be made (/proc/x) was refused only once the table was read.
        _creatable_in(path, f"cannot write the folder {str(path)!r}:", probe="folder")
    else:
        _creatable_in(_writable_file(path).parent, f"cannot write {str(path)!r}:")
    for source in inputs:
        if source is None or str(source) == "-" or not Path(source).exists():
            continue
        source = Path(source)
        if folder and _inside(source, path):
            raise BGMInputError(
                f"{what} {str(path)!r} holds the input {str(source)!r} and would be replaced whole; "
                "write the output to another folder"
            )
        if not folder and _same_file(path, source):
            raise BGMInputError(f"{what} {str(path)!r} is the input {str(source)!r}; it would be overwritten")
    return path


def make_folder(folder: str | os.PathLike) -> Path:
    """Create ``folder`` (and its parents) or say in one sentence why it cannot be."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BGMInputError(f"cannot write the folder {str(folder)!r}: {exc.strerror or exc}") from None
    return folder


@contextlib.contextmanager
def replaced_folder(out_dir: str | os.PathLike) -> Iterator[Path]:
    """Yield a staging folder that replaces ``out_dir`` whole when the block succeeds.

    The staging folder sits next to ``out_dir`` (same file system). On success
    it is swapped with ``out_dir`` in one step (``renameat2(RENAME_EXCHANGE)``
    on Linux; elsewhere two renames a moment apart) and the previous folder is
    deleted. If the block raises or is interrupted, the staging folder is
    deleted and ``out_dir`` is as it was. Staging folders left by a killed
    process (its pid no longer runs) are removed on the next call.
    """
    out = Path(out_dir)
    if out.is_symlink():  # replace what the link points to; the link stays
        out = out.resolve()
    if out.exists() and not out.is_dir():
        raise BGMInputError(f"cannot write a folder at {str(out)!r}: it is a file")
    parent = out.absolute().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        _remove_stale(parent, out.name)
        staging = Path(tempfile.mkdtemp(prefix=f".{out.name[:64]}{STAGING_TAG}{os.getpid()}-", dir=parent))
    except OSError as exc:
        raise BGMInputError(f"cannot write the folder {str(out)!r}: {exc.strerror or exc}") from None
    try:
        os.chmod(staging, out.stat().st_mode & 0o7777 if out.is_dir() else 0o777 & ~_umask())
        yield staging
        _swap_in(staging, out)
    except BaseException as exc:
        shutil.rmtree(staging, ignore_errors=True)
        if isinstance(exc, OutputError | OSError):
            _raise_storage_error(exc, staging, out)
        raise


@contextlib.contextmanager
def replaced_files(paths: Iterable[str | os.PathLike]) -> Iterator[list[Path]]:
    """Yield where to write a set of files; move them all in when the block succeeds.

    Parameters
    ----------
    paths : paths
        The files of the set, usually of one folder (which need not exist yet).

    Yields
    ------
    list of Path
        One path per file, of the same name, in a staging folder beside the
        files (on their file system). Write each there, through any writer.

    Notes
    -----
    Written one by one, the files of a set could end up mixed: ``bgm evaluate``
    interrupted after its plot left a new plot beside the previous tables, and
    a new folder holding only the plot (an empty one on a full disk). Here
    nothing is moved in until the block has written them all; if it raises (a
    writer's error, a full disk, Ctrl-C), the staging folder is deleted and the
    previous files are as they were. A folder that does not exist yet is
    staged whole and renamed into place in one step; into an existing folder
    the files are renamed one after another, a moment apart, with Ctrl-C and
    SIGTERM held until the last is in (they are raised then). Other files of
    the folder are left alone (:func:`replaced_folder` replaces a whole folder).
    """
    dests = [_writable_file(Path(p)) for p in paths]  # a link's target: written through, as atomic_path does
    stages: list[_Staging] = []
    try:
        for folder in dict.fromkeys(d.absolute().parent for d in dests):
            stages.append(_Staging.beside(folder, next(d.name for d in dests if d.absolute().parent == folder)))
    except OSError as exc:
        for stage in stages:
            shutil.rmtree(stage.staging, ignore_errors=True)
        raise BGMInputError(f"cannot write {str(dests[0])!r}: {exc.strerror or exc}") from None
    inner = {stage.folder: stage.inner for stage in stages}
    staged = [inner[d.absolute().parent] / d.name for d in dests]
    try:
        yield staged
        missing = [d for d, f in zip(dests, staged) if not f.is_file()]
        if missing:
            raise RuntimeError(f"replaced_files: {', '.join(map(str, missing))} not written")
        for dest, f in zip(dests, staged):
            os.chmod(f, _mode_for(dest))
        with _interrupts_held():
            for stage in stages:
                stage.move_in([(f, d) for f, d in zip(staged, dests) if d.absolute().parent == stage.folder])
        for stage in stages:
            _fsync_dir(stage.existing)
    except BaseException as exc:
        for stage in stages:
            shutil.rmtree(stage.staging, ignore_errors=True)
        if isinstance(exc, OutputError | OSError):
            where = getattr(exc, "path", None) or getattr(exc, "filename", None) or ""
            stage = next((t for t in stages if Path(where).absolute().is_relative_to(t.inner)), stages[0])
            _raise_storage_error(exc, stage.inner, stage.folder)
        raise


@dataclass
class _Staging:
    """Where :func:`replaced_files` stages the files of one ``folder``.

    In the folder itself when it exists; else (``whole``) in its nearest existing ancestor ``existing``, as
    the first folder of the path to be made (``top``), renamed into place whole with the folders under it.
    """

    folder: Path
    existing: Path
    top: Path
    staging: Path
    inner: Path

    @property
    def whole(self) -> bool:
        return self.existing != self.folder

    @classmethod
    def beside(cls, folder: Path, first_name: str) -> _Staging:
        existing = folder
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        top = folder if existing == folder else existing / folder.relative_to(existing).parts[0]
        name = first_name if existing == folder else top.name
        _remove_stale(existing, name)
        staging = Path(tempfile.mkdtemp(prefix=f".{name[:64]}{STAGING_TAG}{os.getpid()}-", dir=existing))
        inner = staging if existing == folder else staging / folder.relative_to(top)
        inner.mkdir(parents=True, exist_ok=True)
        return cls(folder, existing, top, staging, inner)

    def move_in(self, files: list[tuple[Path, Path]]) -> None:
        """Rename the staged files over their destinations, or the staged folder into place."""
        if self.whole:
            os.chmod(self.staging, 0o777 & ~_umask())
            os.rename(self.staging, self.top)
        else:
            for staged, dest in files:
                os.replace(staged, dest)
            self.staging.rmdir()


#: What :func:`_interrupts_held` holds: Ctrl-C, and ``kill`` (``timeout``, a job scheduler), which by default
#: ends the process on the spot and, under ``bgm``, is raised as Ctrl-C is.
HELD_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def _interrupts_held() -> Iterator[None]:
    """Ctrl-C or SIGTERM inside is raised when the block is done, not in the middle of it (the renames of one set).

    Held only SIGINT: a ``kill`` between two renames of ``bgm predict``'s three files left a new prediction
    beside the previous uncertainty files.
    """
    received: list[int] = []
    previous = {}
    with contextlib.suppress(ValueError):  # not the main thread: no signal lands here
        for signum in HELD_SIGNALS:
            previous[signum] = signal.signal(signum, lambda got, frame: received.append(got))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            if handler is not None:  # None: a handler not set from Python, left as it was
                signal.signal(signum, handler)
    for signum in dict.fromkeys(received):
        signal.raise_signal(signum)  # to the handler the block held it from (SIGTERM's default: the process ends)


def _raise_storage_error(exc: OSError | OutputError, staging: Path, out: Path) -> None:
    """Raise :class:`OutputError` for a folder's file the storage refused, named where it was going.

    The staging folder is BGM's own and gone by now: the message names the file in ``out``,
    and says that ``out`` is as it was. Returns (for the caller to raise ``exc``) otherwise.
    """
    if isinstance(exc, OutputError):
        where, reason = exc.path, exc.reason
    elif exc.errno in STORAGE_ERRNOS:
        where, reason = Path(exc.filename) if exc.filename else staging, exc.strerror or str(exc)
    else:
        return
    with contextlib.suppress(ValueError):
        where = out / Path(where).absolute().relative_to(staging.absolute())
    kept = "the folder was left as it was" if out.exists() else "nothing was written"
    raise OutputError(where, reason, f" ({kept})") from None


# --------------------------------------------------------------------------- helpers


def _writable_file(path: Path) -> Path:
    """``path`` (a link's target for a link) if a regular file may be written there."""
    lead = f"cannot write {str(path)!r}:"
    if path.is_symlink():
        path = path.resolve()
    if path.is_dir():
        raise BGMInputError(f"{lead} it is a directory; give a file name")
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return path
    except OSError as exc:
        raise BGMInputError(f"{lead} {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        raise BGMInputError(f"{lead} it is a device, pipe or socket, not a regular file")
    return path


def _creatable_in(folder: Path, lead: str, probe: str = "file") -> None:
    """Refuse, before any work, a folder no file can be created in (the nearest existing one, if it is to be made).

    Permissions alone do not tell (root may write anywhere, yet not in /proc): a file is made and removed,
    or with ``probe="folder"`` a folder (what a folder output makes first; no file is opened outside it).
    """
    existing = folder.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise BGMInputError(f"{lead} {str(existing)!r} is a file, not a folder")
    try:
        if probe == "folder":
            os.rmdir(tempfile.mkdtemp(dir=existing, prefix=".bgm-probe-"))
        else:
            with tempfile.TemporaryFile(dir=existing):
                pass
    except OSError as exc:
        raise BGMInputError(f"{lead} {exc.strerror or exc}") from None


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return a.resolve() == b.resolve()


def _inside(item: Path, folder: Path) -> bool:
    return item.resolve().is_relative_to(folder.resolve())


def _swap_in(staging: Path, out: Path) -> None:
    """Put ``staging`` where ``out`` is, in one step where the system allows; delete the old ``out``."""
    if not out.exists():
        os.rename(staging, out)
    elif _exchange(staging, out):
        shutil.rmtree(staging, ignore_errors=True)  # now the previous folder
    else:
        retired = Path(tempfile.mkdtemp(prefix=f".{out.name[:64]}{RETIRED_TAG}{os.getpid()}-", dir=staging.parent))
        os.rename(out, retired / out.name)
        os.rename(staging, out)
        shutil.rmtree(retired, ignore_errors=True)
    _fsync_dir(out.absolute().parent)


def _exchange(a: Path, b: Path) -> bool:
    """Atomically exchange two paths (Linux ``renameat2``); False where unsupported."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        return False  # a file system without exchange: fall back to two renames
    raise OSError(err, os.strerror(err), str(b))


def _remove_stale(parent: Path, name: str) -> None:
    """Delete staging and retired folders of ``name`` whose process no longer runs."""
    for tag in (STAGING_TAG, RETIRED_TAG):
        for entry in parent.glob(f".{glob_escape(name[:64])}{tag}*"):
            pid = entry.name[len(name[:64]) + 1 + len(tag) :].split("-", 1)[0]
            if pid.isdigit() and not _running(int(pid)):
                shutil.rmtree(entry, ignore_errors=True)


def glob_escape(text: str) -> str:
    """``text`` with glob wildcards escaped."""
    return "".join(f"[{c}]" if c in "*?[]" else c for c in text)


def _running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def _mode_for(path: Path) -> int:
    """Keep an existing file's permissions; new files get the usual umask default."""
    try:
        return path.stat().st_mode & 0o777
    except FileNotFoundError:
        return 0o666 & ~_umask()
