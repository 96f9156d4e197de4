"""Running ``bgm`` the way users do, and checking what it did, for the robustness tests.

:func:`bgm` runs the command line in this process through ``core.cli.main``
(exit status, one-line messages, warnings as users see them) and is fast;
:func:`bgm_process` runs it in a fresh interpreter, for what needs one
(signals, standard input as a pipe). :func:`snapshot` records every file
under a folder so a test can assert that nothing that existed changed.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import signal
import subprocess
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

#: ``bgm`` with the viewer's command registered, as its installed entry point does (see test_plugins.py).
BGM = [
    sys.executable,
    "-c",
    "from core.cli import app, main; from bgm_viewer.cli_hooks import register; register(app); main()",
]


@dataclass
class Run:
    returncode: int
    stdout: str
    stderr: str


class _Stdin(io.TextIOWrapper):
    def isatty(self) -> bool:
        return False


def bgm(*args, stdin: bytes | None = None) -> Run:
    """``bgm ARGS`` in this process: its exit status, stdout and stderr."""
    from bgm_viewer.cli_hooks import register
    from core import cli

    if "view" not in {c.name for c in cli.app.registered_commands}:
        register(cli.app)  # as its installed entry point does
    out, err = io.StringIO(), io.StringIO()
    saved = sys.argv, sys.stdin, os.environ.pop("BGM_DEBUG", None), signal.getsignal(signal.SIGINT)
    sys.argv = ["bgm", *map(str, args)]
    if stdin is not None:
        sys.stdin = _Stdin(io.BytesIO(stdin))
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                cli.main()
                code = 0
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        sys.argv, sys.stdin = saved[0], saved[1]
        if saved[2] is not None:
            os.environ["BGM_DEBUG"] = saved[2]
        signal.signal(signal.SIGINT, saved[3])  # main() leaves Ctrl-C to its own process's exit
    return Run(code, out.getvalue(), err.getvalue())


def bgm_process(*args, stdin=None, timeout: float = 300, **popen) -> subprocess.CompletedProcess:
    """``bgm ARGS`` in a fresh interpreter (this worktree's code)."""
    env = dict(os.environ)
    env.pop("BGM_DEBUG", None)
    env["PYTHONPATH"] = str(Path(__file__).resolve().parent.parent)
    return subprocess.run([*BGM, *map(str, args)], capture_output=True, timeout=timeout, env=env, stdin=stdin, **popen)


def no_traceback(proc) -> None:
    stderr = proc.stderr if isinstance(proc.stderr, str) else proc.stderr.decode(errors="replace")
    assert "Traceback" not in stderr, stderr
    assert "internal error" not in stderr, stderr
    assert proc.returncode not in (1, 3), (proc.returncode, stderr)


def error_line(proc, *phrases: str) -> str:
    """Exit 2 with exactly one stderr line, ``bgm: error: ...``, naming the problem; returns it.

    Warnings about the input (``bgm: warning:``) and progress lines of the work
    done before the problem (``bgm: progress:``) may come before it; nothing
    else may be printed on stderr.
    """
    no_traceback(proc)
    stderr = proc.stderr if isinstance(proc.stderr, str) else proc.stderr.decode(errors="replace")
    assert proc.returncode == 2, (proc.returncode, stderr)
    lines = [line for line in stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("bgm: error:")]
    assert len(errors) == 1, stderr
    others = [line for line in lines if is_message(line) and not line.startswith(("bgm: error:", "bgm: warning:"))]
    assert all(": " in line and "holes" in line for line in others), stderr  # only the one-line input summary
    assert len(errors[0]) < 1200, errors[0][:300]
    for phrase in phrases:
        assert phrase.lower() in errors[0].lower(), (phrase, errors[0])
    return errors[0]


def is_message(line: str) -> bool:
    """Whether a stderr line is a message (``bgm: ...``, the input summary), not a batch progress line."""
    return not line.startswith("bgm: progress: ")


def succeeds(proc):
    no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    return proc


def warnings_of(proc) -> list[str]:
    return [line for line in proc.stderr.splitlines() if line.startswith("bgm: warning:")]


def snapshot(*roots: Path) -> dict[str, tuple]:
    """Every file and folder under ``roots``: kind, mode and content hash (devices by their type)."""
    seen: dict[str, tuple] = {}
    for root in roots:
        root = Path(root)
        entries = [root, *root.rglob("*")] if root.is_dir() else [root]
        for p in entries:
            st = p.lstat() if (p.exists() or p.is_symlink()) else None
            if st is None:
                continue
            if p.is_symlink():
                seen[str(p)] = ("link", os.readlink(p))
            elif p.is_file():
                seen[str(p)] = ("file", st.st_mode, hashlib.sha1(p.read_bytes()).hexdigest())
            elif p.is_dir():
                seen[str(p)] = ("dir", st.st_mode)
            else:
                seen[str(p)] = ("other", st.st_mode, st.st_rdev)
    return seen


def unchanged(before: dict, after: dict, allow_new=()) -> None:
    """Everything in ``before`` is in ``after`` as it was; new entries only under ``allow_new``."""
    changed = [k for k, v in before.items() if after.get(k) != v]
    assert not changed, changed[:5]
    new = [k for k in after if k not in before and not any(k.startswith(str(a)) for a in allow_new)]
    assert not new, new[:5]
