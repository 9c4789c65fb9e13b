"""Write-then-rename helpers, so an error never leaves a half-written file or folder, and the
output guard every write goes through, so a command never replaces its own inputs.

The guard (issue 14) is armed by the CLI for the length of one command (``output_guard``):
``atomic_path`` then refuses, before anything is written, a destination that is an input
of the command, a file of an input session folder, or a folder holding an input, whatever
--force says; and without --force it refuses to replace any existing output. Library calls
outside a command (tests, scripts) run unguarded, as before.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterable, Iterator

from .errors import InputError

# Files of a session folder that commands derive and may replace (--force): `track` writes
# marker.csv. Everything else in an input folder (the recording) is never replaced.
DERIVED_SESSION_FILES = frozenset({"marker.csv", ".tracked"})

_guard: dict | None = None  # {"inputs": [Path], "files": {Path: input named}, "force": bool} while armed


def _resolve(p: str | os.PathLike) -> Path:
    return Path(os.path.abspath(os.path.realpath(os.fspath(p))))


@contextlib.contextmanager
def output_guard(inputs: Iterable[str | os.PathLike], force: bool = False) -> Iterator[None]:
    """Arm the output guard for one command: inputs are the files and folders it reads;
    force allows replacing an existing output (never an input)."""
    global _guard
    ins, files = [], {}
    for p in inputs:
        if p is None or not os.path.exists(p):
            continue
        r = _resolve(p)
        ins.append(r)
        if r.is_dir():
            try:
                for q in r.rglob("*"):
                    if q.is_file() and q.name not in DERIVED_SESSION_FILES:
                        files[_resolve(q)] = os.fspath(p)
            except OSError:
                pass  # an unreadable folder: the command itself reports it
        else:
            files[r] = os.fspath(p)
    prev, _guard = _guard, {"inputs": ins, "files": files, "force": force}
    try:
        yield
    finally:
        _guard = prev


def check_output(dest: str | os.PathLike) -> None:
    """Refuse dest (InputError naming it) when the armed guard forbids writing it; no-op unarmed."""
    if _guard is None:
        return
    d = _resolve(dest)
    for inp in _guard["inputs"]:
        if d == inp or inp.is_relative_to(d):
            raise InputError(dest, f"is {'an input' if d == inp else 'a folder holding the input ' + str(inp)} "
                             "of this command; write the output elsewhere")
    if d in _guard["files"]:
        raise InputError(dest, f"is a file of the input {_guard['files'][d]}; write the output elsewhere")
    if os.path.lexists(dest) and not _guard["force"]:
        raise InputError(dest, "exists; pass --force to replace it")


@contextlib.contextmanager
def atomic_path(dest: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``dest``; on normal exit rename it onto ``dest``.

    Works for a file or a folder (create whichever at the yielded path). On an exception
    the temporary is removed and ``dest`` is untouched. Same directory, so the final
    ``os.replace`` is atomic for files; a folder replacing an existing folder is swapped
    through a second rename (old one deleted only after the new one is in place).
    """
    check_output(dest)
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=suffix + ".tmp", dir=dest.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    tmp.unlink()  # caller decides whether it becomes a file or a folder
    try:
        yield tmp
        if tmp.is_dir() and dest.exists():
            old = dest.with_name(f".{dest.name}.old.{os.getpid()}")
            os.replace(dest, old)
            os.replace(tmp, dest)
            shutil.rmtree(old) if old.is_dir() else old.unlink()
        else:
            os.replace(tmp, dest)
    finally:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        elif tmp.exists():
            tmp.unlink()


def write_text_atomic(dest: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``dest`` through a temporary file and a rename."""
    with atomic_path(dest) as tmp:
        tmp.write_text(text)


def write_bytes_atomic(dest: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``dest`` through a temporary file and a rename."""
    with atomic_path(dest) as tmp:
        tmp.write_bytes(data)
