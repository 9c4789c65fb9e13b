"""Write-then-rename helpers, so an error never leaves a half-written file or folder, and the
output guard every write goes through, so a command never replaces its own inputs.

The guard is armed by the CLI for the length of one command (``output_guard``):
``atomic_path`` then refuses, before anything is written, a destination that is an input
of the command, a file of an input session folder, or a folder holding an input, whatever
--force says; and without --force it refuses to replace any existing output. With --force
it still replaces only a thing of the same kind (``same_kind``): a file by a file whose
content sniffs alike (a table by a table, JSON by JSON, text by text, ...), a folder by a
folder holding nothing but files playscope writes (``PRODUCT_FILES``), so an unrelated file
a user keeps in a folder is never deleted. The virtual board's flash file is checked by
``check_flash_file``. Library calls outside a command (tests, scripts) run unguarded.
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

# Every file name a playscope command writes into a folder it owns (a session folder from
# import/simulate/run-insitu): a folder holding anything else is not replaced, even with
# --force, since replacing the folder would delete that file.
PRODUCT_FILES = frozenset({"session.json", "encoder.csv", "distal.csv", "marker.csv", "truth.csv", "frames.csv",
                           "video.avi", ".tracked", "b_samples.csv", "calibration.json", "table.bin",
                           "result.json", "session"})

# The virtual board's file-backed flash: two slots of 128 KiB (firmware/boards/desktop/vboard.c,
# VB_SLOT_SIZE). An existing file of any other size is not a board image and is never opened.
FLASH_IMAGE_BYTES = 2 * 128 * 1024

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


def _refuse_inputs(dest: str | os.PathLike, advice: str) -> Path:
    """dest resolved; InputError naming it, ending with advice, when it is an input of the armed
    guard, a folder holding one, or a file of an input folder. Call only with the guard armed."""
    d = _resolve(dest)
    for inp in _guard["inputs"]:
        if d == inp or inp.is_relative_to(d):
            raise InputError(dest, f"is {'an input' if d == inp else 'a folder holding the input ' + str(inp)} "
                             f"of this command; {advice}")
    if d in _guard["files"]:
        raise InputError(dest, f"is a file of the input {_guard['files'][d]}; {advice}")
    return d


def check_output(dest: str | os.PathLike) -> None:
    """Refuse dest (InputError naming it) when the armed guard forbids writing it; no-op unarmed."""
    if _guard is None:
        return
    d = _refuse_inputs(dest, "write the output elsewhere")
    if os.path.lexists(dest) and not _guard["force"]:
        raise InputError(dest, "exists; pass --force to replace it")
    parent = d.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not os.access(parent, os.W_OK | os.X_OK):  # before any work, not after it
        raise InputError(dest, f"cannot write into {parent}: permission denied; choose another folder")
    if os.path.isdir(dest):
        _check_folder_replaceable(Path(dest))


def _check_folder_replaceable(folder: Path) -> None:
    """Refuse (InputError) replacing folder when it holds a file playscope does not write."""
    try:
        names = sorted(os.listdir(folder))
    except OSError as e:
        raise InputError(folder, f"cannot list the folder to replace: {e.strerror or e}") from None
    for n in names:
        if n not in PRODUCT_FILES:
            raise InputError(folder, f"holds {n!r}, not a file playscope writes; replacing the folder would delete "
                             "it: write the output to a new folder")


def _table_magic() -> int:
    # The table's magic number as the C defines it (PST_MAGIC, the bytes "PSTB").
    from .native import constant

    return constant("PST_MAGIC")


def sniff_kind(path: str | os.PathLike) -> str:
    """What a file holds, from its first bytes: "folder", "table" (PSTB magic), "flash image"
    (FLASH_IMAGE_BYTES long), "json", "html", "text" (UTF-8 without NUL), else "binary"."""
    p = Path(path)
    if p.is_dir():
        return "folder"
    try:
        size = p.stat().st_size
        with open(p, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return "unreadable"
    if len(head) >= 4 and int.from_bytes(head[:4], "little") == _table_magic():
        return "table"
    if size == FLASH_IMAGE_BYTES:
        return "flash image"
    if not head:
        return "empty"
    if b"\0" in head:
        return "binary"
    try:
        text = head.decode("utf-8").lstrip()
    except UnicodeDecodeError:
        if len(head) < 4096:
            return "binary"
        text = head[:4000].decode("utf-8", "ignore").lstrip()
    if text[:1] in ("{", "["):
        return "json"
    if text[:1] == "<":
        return "html"
    return "text"


_KIND_TEXT = {"folder": "a folder", "table": "a table", "flash image": "a board flash image", "json": "JSON",
              "html": "HTML", "text": "text", "binary": "binary data", "unreadable": "something unreadable",
              "empty": "nothing"}


def same_kind(new: str | os.PathLike, old: str | os.PathLike) -> None:
    """Refuse (InputError naming old) replacing old by new unless both are the same kind of
    thing (sniff_kind); an empty old file may be replaced by anything."""
    if _guard is None or not os.path.lexists(old):
        return
    k_new, k_old = sniff_kind(new), sniff_kind(old)
    if k_old not in (k_new, "empty"):
        raise InputError(old, f"holds {_KIND_TEXT.get(k_old, k_old)} and this command writes {_KIND_TEXT.get(k_new, k_new)}: "
                         "not replaced, even with --force; write the output elsewhere")


def check_flash_file(path: str | os.PathLike | None) -> None:
    """Refuse (InputError naming it) a virtual board's --flash-file that is an input of the
    command, or an existing thing other than a board flash image (FLASH_IMAGE_BYTES, a regular
    file): the board opens it read-write and would turn any other file into an image. A new
    path is fine (the board creates it). No-op for None."""
    if path is None:
        return
    if _guard is not None:
        _refuse_inputs(path, "give the board's flash image its own file")
    if not os.path.lexists(path):
        return
    import stat

    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        what = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise InputError(path, f"is {what}; --flash-file takes a board flash image file (a new path creates one)")
    if st.st_size != FLASH_IMAGE_BYTES:
        raise InputError(path, f"is not a board flash image ({st.st_size} bytes, an image has {FLASH_IMAGE_BYTES}); "
                         "the board would overwrite it: give --flash-file a new path")


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
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=suffix + ".tmp", dir=dest.parent)
    except OSError as e:  # name the output the user gave, not the temporary beside it
        raise InputError(dest, f"cannot write here: {e.strerror or e}; check the folder's permissions") from None
    os.close(fd)
    tmp = Path(tmp_name)
    tmp.unlink()  # caller decides whether it becomes a file or a folder
    try:
        yield tmp
        same_kind(tmp, dest)
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
