"""Autosaves of the viewer's unsaved work, so a crash or a killed session loses seconds, not an hour.

An autosave is a project file (:mod:`core.io.project`: parameters, the view,
alignment overrides and the options the table was read with) with one more
member naming what it was made for::

    "autosave": {"project": "/pit/p.bgm.json", "input": "/pit/holes.csv"}

Its input is named by absolute path, so it is found wherever it lies. It lies

* beside the project, as ``<project name>.autosave`` (``p.bgm.json.autosave``), for a
  project saved at least once;
* for a table whose project was never saved, under the user's state folder
  (``$BGM_AUTOSAVE_DIR``, else ``~/.local/state/bgm/autosave`` on Linux), named after the
  table and a digest of its absolute path: one autosave per table, whichever folder the
  viewer was started in.

It is written atomically (:mod:`core.io.atomic`), never through a link (a link named
like the autosave and pointing at the project would overwrite the project), and never
read by the command line: ``bgm build --project p.bgm.json`` reads ``p.bgm.json`` alone.

An autosave records the viewer that wrote it (its process id, the machine, when the
process started). A viewer that finds the autosave of another viewer running now on
this machine (two viewers on one project) neither offers it nor overwrites it: it
autosaves to a name of its own, ``p.bgm.json.autosave-<pid>`` (:func:`own_autosave_path`),
which a later opening offers once no viewer runs that writes it.

An autosave whose restore failed (the table changed, so an override no longer fits) is
renamed aside, ``p.bgm.json.autosave.failed-20261205-110812`` (:func:`set_aside`): kept,
and no longer offered at every opening.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import socket
import time
from dataclasses import dataclass
from pathlib import Path

from core.errors import BGMInputError
from core.io.atomic import atomic_write_text
from core.io.project import Project, load_project

#: Appended to a project's name for its autosave.
SUFFIX = ".autosave"
#: Where autosaves of never-saved projects go instead of the user's state folder (tests set it).
AUTOSAVE_ENV = "BGM_AUTOSAVE_DIR"
#: The member of an autosave naming the project and table it was made for.
MEMBER = "autosave"
#: Between an autosave's name and the time its restore failed, in the name it is set aside under.
FAILED_TAG = ".failed-"


@dataclass
class AutosaveOffer:
    """An autosave to offer for restoring: where it is, its work and when it was written.

    Attributes
    ----------
    path : Path
        The autosave file.
    project : Project
        Its work; ``input_path`` absolute, ``reading`` how the table was read.
    written : float
        When it was written (seconds since the epoch, the file's modification time).
    """

    path: Path
    project: Project
    written: float


def autosave_dir() -> Path:
    """``$BGM_AUTOSAVE_DIR`` if set, else ``autosave`` in the user's state folder for bgm."""
    env = os.environ.get(AUTOSAVE_ENV)
    if env:
        return Path(env).expanduser()
    import platformdirs

    return Path(platformdirs.user_state_dir("bgm", appauthor=False)) / "autosave"


def autosave_path(project_path: str | os.PathLike | None, input_path: str | os.PathLike | None) -> Path | None:
    """Where the autosave of a session goes: beside its project, else one per table (``None``: nowhere).

    Parameters
    ----------
    project_path : path or None
        The project file the session was last saved to or opened from.
    input_path : path or None
        The table the session shows; without a project, only a file on disk has an autosave
        (standard input or the bundled demo cannot be read again to restore it).
    """
    if project_path is not None:
        project = Path(project_path).absolute()
        return project.with_name(project.name + SUFFIX)
    if input_path is None or not Path(input_path).is_file():
        return None
    table = Path(input_path).resolve()
    digest = hashlib.sha256(str(table).encode("utf-8", "surrogatepass")).hexdigest()[:16]
    stem = re.sub(r"[^\w.-]", "_", table.stem)[:40]  # a name the user can recognise, on every file system
    return autosave_dir() / f"{stem}-{digest}.json"


def write_autosave(
    project: Project, path: str | os.PathLike, project_path: str | os.PathLike | None, input_path
) -> None:
    """Write ``project`` as the autosave at ``path``, atomically.

    ``project.input_path`` is written absolute (the autosave may lie far from the table).

    Raises
    ------
    BGMInputError
        If ``path`` is a link (written through, it could overwrite the project), the
        project cannot be written as JSON, or the folder is not writable.
    """
    path = Path(path)
    if path.is_symlink():
        raise BGMInputError(f"autosave {path} is a link; it is not written through it (it could be the project)")
    data = project.to_dict()
    table = Path(input_path).resolve() if input_path is not None and Path(input_path).is_file() else None
    data["input_path"] = str(table) if table is not None else project.input_path
    data[MEMBER] = {
        "project": None if project_path is None else str(Path(project_path).absolute()),
        "input": None if table is None else str(table),
        "writer": this_writer(),
    }
    try:
        text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise BGMInputError(f"autosave cannot be written as JSON: {exc}.") from None
    atomic_write_text(path, text)


def pending_autosave(
    path: Path | None, project_path: str | os.PathLike | None, input_path
) -> tuple[AutosaveOffer | None, str | None]:
    """The autosave at ``path`` if it holds work the saved project lacks, and what to say of one ignored.

    An autosave is offered when it exists and is at least as new as the project
    file (a project saved after it, by another viewer, has the later work), or
    when there is no project file. One made for another table (named in its
    ``autosave`` member) is not this session's and is passed over in silence.
    One that cannot be read (half written by a full disk, edited by hand) is
    ignored, with a sentence saying so: never a traceback.

    Returns
    -------
    offer : AutosaveOffer or None
    note : str or None
        Why an autosave there was ignored (``None``: nothing to say).
    """
    if path is None or not path.is_file():
        return None, None
    try:
        written = path.stat().st_mtime
        if project_path is not None and Path(project_path).is_file():
            if written < Path(project_path).stat().st_mtime:
                return None, None  # the project was saved after it
        project = load_project(path)
        member = json.loads(path.read_text(encoding="utf-8-sig")).get(MEMBER)
    except (BGMInputError, OSError, ValueError) as exc:
        return None, f"the autosave {path} cannot be restored and was ignored: {_reason(exc, path)}"
    if not isinstance(member, dict):
        return None, f"the autosave {path} cannot be restored and was ignored: it names no table"
    if project_path is None and input_path is not None and member.get("input") != str(Path(input_path).resolve()):
        return None, None  # another table's (the digest of its path is the same): not this session's
    return AutosaveOffer(path, project, written), None


def _reason(exc: Exception, path: Path) -> str:
    """An exception's message without the autosave's path, which the caller names already."""
    text = str(exc).rstrip(".").replace(f"project file {path}", "it").replace(str(path), "it")
    return text or type(exc).__name__


def remove_autosave(path: Path | None) -> None:
    """Delete the autosave at ``path`` if there is one (a link is removed, not what it points at)."""
    if path is None:
        return
    try:
        path.unlink()
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise BGMInputError(f"cannot remove the autosave {path}: {exc.strerror or exc}") from None


def set_aside(path: Path, now: float | None = None) -> Path:
    """Rename the autosave at ``path`` to ``<name>.failed-<local time>`` beside it; returns the new path.

    For an autosave whose restore failed: kept (nothing the user did is lost, and
    the name says what it is), but no longer offered at every opening. Renamed,
    not copied: a rename within a folder is atomic, so the autosave is under one
    name or the other, never half of each. A name taken already (two failures in
    one second) is never overwritten: the next free ``-1``, ``-2`` is used.

    Raises
    ------
    BGMInputError
        If it cannot be renamed (the folder is not writable, the file went).
    """
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(now))
    for n in range(1000):
        aside = path.with_name(f"{path.name}{FAILED_TAG}{stamp}{f'-{n}' if n else ''}")
        if aside.exists() or aside.is_symlink():
            continue
        try:
            os.rename(path, aside)
        except OSError as exc:
            raise BGMInputError(f"cannot set the autosave {path} aside: {exc.strerror or exc}") from None
        return aside
    raise BGMInputError(f"cannot set the autosave {path} aside: every name for {stamp} is taken")


def this_writer() -> dict:
    """Who writes an autosave: this process's id, the machine's name and when the process started."""
    return {"pid": os.getpid(), "host": socket.gethostname(), "started": _process_start(os.getpid())}


def live_writer(path: Path | None) -> dict | None:
    """The writer of the autosave at ``path`` when it is another viewer running now on this machine, else ``None``.

    Two viewers on one project shared its autosave, and the last to write won:
    each overwrote the other's work. A process id is only alive on its own
    machine, and may be reused after the viewer ended: a writer whose process
    started at another time than recorded is another program, not a viewer.
    Anything unreadable is no live writer (the autosave is offered, or said
    unreadable, as before).
    """
    if path is None or not path.is_file():
        return None
    try:
        member = json.loads(path.read_text(encoding="utf-8-sig")).get(MEMBER)
        writer = member.get("writer") if isinstance(member, dict) else None
        if not isinstance(writer, dict):
            return None  # written before autosaves named their writer, or by hand
        pid, host = int(writer["pid"]), str(writer["host"])
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None
    if host != socket.gethostname() or pid == os.getpid() or pid <= 0 or not _alive(pid):
        return None
    started = writer.get("started")
    if started is not None and _process_start(pid) not in (None, started):
        return None  # the id of a viewer that ended, reused by another process
    return writer


def own_autosave_path(path: Path, pid: int | None = None) -> Path:
    """The autosave of this viewer beside ``path``, which another running viewer writes: ``<name>-<pid>``.

    ``p.bgm.json.autosave`` -> ``p.bgm.json.autosave-4242``; ``holes-<digest>.json`` ->
    ``holes-<digest>-4242.json``.
    """
    pid = os.getpid() if pid is None else pid
    if path.name.endswith(".json"):
        return path.with_name(f"{path.name[: -len('.json')]}-{pid}.json")
    return path.with_name(f"{path.name}-{pid}")


def other_viewers_autosaves(path: Path) -> list[Path]:
    """The autosaves other viewers wrote beside ``path`` under names of their own (:func:`own_autosave_path`), newest first."""
    stem, json_suffix = (path.name[: -len(".json")], ".json") if path.name.endswith(".json") else (path.name, "")
    pattern = re.compile(re.escape(stem) + r"-\d+" + re.escape(json_suffix))
    try:
        found = [p for p in path.parent.iterdir() if pattern.fullmatch(p.name) and p.is_file()]
    except OSError:
        return []
    return sorted(found, key=lambda p: p.stat().st_mtime, reverse=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process: alive
    except OSError:
        return False
    return True


def _process_start(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot, Linux's ``/proc``), or ``None`` where it cannot be told."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
        return int(text.rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None
