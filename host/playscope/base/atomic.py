"""Write-then-rename helpers, so an error never leaves a half-written file or folder, and the
output guard every write goes through, so a command never replaces its own inputs nor
anything playscope did not write.

The guard is armed by the CLI for the length of one command (``output_guard``):
``atomic_path`` then refuses, before anything is written and again at the rename, a
destination that is an input of the command, a file of an input session folder, a folder
holding an input, a symbolic link, a named pipe, a device or a socket (``refuse_special``:
lstat only, never opened), whatever --force says; and without --force any existing output.
With --force it replaces only what playscope wrote, by content (``owned_file``: a table's
magic, a JSON's "written_by" key or a calibration's format, an HTML generator line, the
exact header of a CSV it writes; a folder by its ``MANIFEST`` of SHA-256s, checked at any
depth, ``folder_not_owned``), and only by the same kind (``same_kind``: a table by a table).
Outputs are renamed into place in the target's folder (``os.replace`` of a temporary beside
it). The virtual board's flash file is checked by ``check_flash_file`` (an image by its slot
headers, not its size). Library calls outside a command (tests, scripts) run unguarded.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
from pathlib import Path
from typing import Iterable, Iterator

from .errors import InputError

# Files of a session folder that commands derive and may replace (--force): `track` writes
# marker.csv. Everything else in an input folder (the recording) is never replaced.
DERIVED_SESSION_FILES = frozenset({"marker.csv", ".tracked"})

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
    """Refuse dest (InputError naming it) when the armed guard forbids writing it; no-op unarmed.
    Whatever --force says: a link, pipe, device or socket (never opened), an input; with
    --force an existing file is replaced only when its content says playscope wrote it
    (owned_file; an empty file holds nothing to lose), a folder only when everything in it is
    playscope's (folder_not_owned)."""
    if _guard is None:
        return
    st = refuse_special(dest)
    d = _refuse_inputs(dest, "write the output elsewhere")
    if st is not None and not _guard["force"]:
        raise InputError(dest, "exists; pass --force to replace it")
    parent = d.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not os.access(parent, os.W_OK | os.X_OK):  # before any work, not after it
        raise InputError(dest, f"cannot write into {parent}: permission denied; choose another folder")
    if st is None:
        return
    if stat.S_ISDIR(st.st_mode):
        _check_folder_replaceable(Path(dest))
    elif st.st_size and not owned_file(dest):
        raise InputError(dest, "holds a file playscope did not write (by its content); not replaced, even with "
                         "--force: write the output elsewhere")


def _check_folder_replaceable(folder: Path) -> None:
    """Refuse (InputError) replacing folder unless playscope_owned says every thing in it,
    at any depth, is playscope's own."""
    why = folder_not_owned(folder)
    if why:
        raise InputError(folder, f"{why}; replacing the folder would delete it, even with --force: "
                         "write the output to a new folder")


def _table_magic() -> int:
    # The table's magic number as the C defines it (PST_MAGIC, the bytes "PSTB").
    from .native import constant

    return constant("PST_MAGIC")


# ---------------------------------------------------------------- what playscope wrote, by content
# A JSON playscope writes carries this key (jsonio.write_json), a calibration its "format", an
# HTML page this generator line, a folder this manifest (file -> SHA-256 of what was written).
WRITTEN_BY = "playscope"
HTML_GENERATOR = '<meta name="generator" content="playscope">'
MANIFEST = ".playscope"
# The stand-alone CSVs a command writes (marker.csv of `track`, b_samples.csv of run-insitu),
# by their exact header line; ".tracked" by its exact text (evaluate-real).
OWNED_CSV_HEADERS = frozenset({"t_s,u_px,v_px", "reason,reason_code,t1_s,t2_s,q1,q2,q_mean,b"})
TRACKED_TEXT = b"marker.csv comes from tracking video.avi\n"
# A PNG playscope writes carries this text chunk (matplotlib's savefig metadata=).
PNG_METADATA = {"Software": "playscope"}
_PNG_MARK = b"Software\0playscope"
_OWNED_JSON_FORMATS = ("playscope-calibration/",)
_MAX_OWNED_JSON = 1 << 28


def _kind_of_mode(m: int) -> str:
    return ("a symbolic link" if stat.S_ISLNK(m) else "a named pipe (FIFO)" if stat.S_ISFIFO(m)
            else "a device" if stat.S_ISCHR(m) or stat.S_ISBLK(m) else "a socket" if stat.S_ISSOCK(m)
            else "a folder" if stat.S_ISDIR(m) else "a regular file" if stat.S_ISREG(m) else "not a regular file")


def refuse_special(path: str | os.PathLike, role: str = "output") -> os.stat_result | None:
    """lstat path without opening it; InputError naming it when it is a symbolic link, a named
    pipe, a device or a socket (a write would go through the link, block on the pipe or
    replace the device node). Returns the stat, or None when nothing is there."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    except OSError as e:
        raise InputError(path, f"cannot inspect the {role}: {e.strerror or e}") from None
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode)):
        raise InputError(path, f"is {_kind_of_mode(st.st_mode)}; playscope writes its {role} only as a regular "
                         "file or folder of its own, never through a link or over a pipe or device: "
                         "give a new path")
    return st


def _flash_image_ok(head_a: bytes, head_b: bytes) -> bool:
    """A slot of a board flash image begins with the store's record magic (PSSL), or is erased
    (0xFF) up to the data, whose start is then erased too or a table's magic (a commit cut
    between data and header)."""
    pssl, pstb = (0x4C535350).to_bytes(4, "little"), _table_magic().to_bytes(4, "little")
    for h in (head_a, head_b):
        if h[:4] == pssl:
            continue
        if h[:32] == b"\xff" * 32 and h[32:36] in (b"\xff" * 4, pstb):
            continue
        return False
    return True


def is_flash_image(path: str | os.PathLike) -> bool:
    """True when path is a regular file of FLASH_IMAGE_BYTES whose two slots look as the board's
    store leaves them (_flash_image_ok), checked from its first bytes; never opens a non-file."""
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size != FLASH_IMAGE_BYTES:
            return False
        with open(path, "rb") as fh:
            a = fh.read(64)
            fh.seek(FLASH_IMAGE_BYTES // 2)
            b = fh.read(64)
    except OSError:
        return False
    return _flash_image_ok(a, b)


def _sha256(path) -> str:
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def owned_file(path: str | os.PathLike) -> bool:
    """True when the regular file path says by its content that playscope wrote it: a table
    (PSTB magic), a board flash image, a JSON object with "written_by": "playscope" or a
    calibration's format, an HTML page with playscope's generator line, a CSV with the exact
    header of one playscope writes, or the .tracked note. Never opens a non-regular file."""
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode):
            return False
        if is_flash_image(path):
            return True
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    if len(head) >= 4 and int.from_bytes(head[:4], "little") == _table_magic():
        return True
    if head == TRACKED_TEXT:
        return True
    if head.startswith(b"\x89PNG") and _PNG_MARK in head:
        return True
    text = head.decode("utf-8", "ignore")
    if text.lstrip().startswith("{"):
        if st.st_size > _MAX_OWNED_JSON:
            return False
        import json

        try:
            d = json.loads(Path(path).read_bytes())
        except (ValueError, OSError, RecursionError):
            return False
        return isinstance(d, dict) and (d.get("written_by") == WRITTEN_BY or
                                         (isinstance(d.get("format"), str) and d["format"].startswith(_OWNED_JSON_FORMATS)))
    if text.lstrip().startswith("<"):
        return HTML_GENERATOR in text
    return text.partition("\n")[0].rstrip("\r") in OWNED_CSV_HEADERS


def write_manifest(folder: Path) -> None:
    """Record in folder/MANIFEST the SHA-256 of every regular file under folder (written just
    before the folder is renamed into place), so --force can later tell it is playscope's."""
    import json

    files = {}
    for dirpath, dirs, names in os.walk(folder):
        dirs.sort()
        for n in sorted(names):
            p = Path(dirpath) / n
            rel = p.relative_to(folder).as_posix()
            if rel != MANIFEST and stat.S_ISREG(os.lstat(p).st_mode):
                files[rel] = _sha256(p)
    (folder / MANIFEST).write_text(json.dumps({"written_by": WRITTEN_BY, "files": files}, indent=1) + "\n")


def folder_not_owned(folder: str | os.PathLike, _manifest: dict | None = None, _prefix: str = "") -> str | None:
    """None when everything under folder, at any depth, is playscope's own: each regular file
    listed in the folder's MANIFEST with the same SHA-256, or owned_file by its content; each
    sub-folder the same (under its own manifest, or the enclosing one). Else what is not, as a
    phrase naming it (a user's file, a folder, a link, a pipe, a device, a changed file)."""
    import json

    folder = Path(folder)
    man = _manifest
    if (folder / MANIFEST).is_file() and not os.path.islink(folder / MANIFEST):
        try:
            d = json.loads((folder / MANIFEST).read_text())
            man, _prefix = (d.get("files") if isinstance(d, dict) and isinstance(d.get("files"), dict) else {}), ""
        except (ValueError, OSError):
            man = {}
    try:
        names = sorted(os.listdir(folder))
    except OSError as e:
        return f"cannot list {folder}: {e.strerror or e}"
    for n in names:
        p = folder / n
        rel = _prefix + n
        if n == MANIFEST and _prefix == "":
            continue
        st = os.lstat(p)
        if stat.S_ISDIR(st.st_mode):
            why = folder_not_owned(p, man, rel + "/")
            if why:
                return why
            continue
        if not stat.S_ISREG(st.st_mode):
            return f"holds {n!r}, {_kind_of_mode(st.st_mode)}"
        if owned_file(p):  # playscope's by its content (marker.csv that `track` rewrote, a table, ...)
            continue
        if man is not None and rel in man:
            if man[rel] == _sha256(p):
                continue
            return f"holds {rel!r}, changed since playscope wrote it"
        return f"holds {rel!r}, not a file playscope wrote"
    return None


def sniff_kind(path: str | os.PathLike) -> str:
    """What a file holds, from its first bytes: "folder", "table" (PSTB magic), "flash image"
    (a board flash image, is_flash_image), "json", "html", "text" (UTF-8 without NUL), else
    "binary"; a link, pipe or device is named as such and never opened."""
    try:
        st = os.lstat(path)
    except OSError:
        return "unreadable"
    if stat.S_ISDIR(st.st_mode):
        return "folder"
    if not stat.S_ISREG(st.st_mode):
        return "special"
    p = Path(path)
    try:
        with open(p, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return "unreadable"
    if len(head) >= 4 and int.from_bytes(head[:4], "little") == _table_magic():
        return "table"
    if is_flash_image(p):
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
              "empty": "nothing", "special": "a link, pipe or device"}


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
    command, a link, pipe, device or folder, or an existing file that is not a board flash
    image by its content (is_flash_image: size and both slots' headers): the board opens it
    read-write and would turn any other file into an image. A new path is fine (the board
    creates it). No-op for None."""
    if path is None:
        return
    st = refuse_special(path, "board flash image")
    if _guard is not None:
        _refuse_inputs(path, "give the board's flash image its own file")
    if st is None:
        return
    if stat.S_ISDIR(st.st_mode):
        raise InputError(path, "is a folder; --flash-file takes a board flash image file (a new path creates one)")
    if st.st_size != FLASH_IMAGE_BYTES:
        raise InputError(path, f"is not a board flash image ({st.st_size} bytes, an image has {FLASH_IMAGE_BYTES}); "
                         "the board would overwrite it: give --flash-file a new path")
    if not is_flash_image(path):
        raise InputError(path, "is not a board flash image (its slots hold neither a store record nor erased "
                         "flash), though of an image's size; the board would overwrite it: give --flash-file a new path")


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
        try:
            yield tmp
        except InputError as e:  # name the output the user gave, not the temporary it was written as
            if e.file and (e.file == str(tmp) or e.file.startswith(str(tmp) + os.sep)):
                raise InputError(str(dest) + e.file[len(str(tmp)):], e.message, e.row) from None
            raise
        if tmp.is_dir() and not tmp.is_symlink():
            write_manifest(tmp)
        check_output(dest)  # again at the write: nothing swapped in meanwhile (a link, a pipe, a user's file)
        same_kind(tmp, dest)
        if tmp.is_dir() and os.path.lexists(dest):
            old = dest.with_name(f".{dest.name}.old.{os.getpid()}")
            os.replace(dest, old)
            os.replace(tmp, dest)
            shutil.rmtree(old) if old.is_dir() else old.unlink()
        else:
            os.replace(tmp, dest)
    finally:
        if tmp.is_dir() and not tmp.is_symlink():
            shutil.rmtree(tmp, ignore_errors=True)
        elif os.path.lexists(tmp):
            tmp.unlink()


def write_text_atomic(dest: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``dest`` through a temporary file and a rename."""
    with atomic_path(dest) as tmp:
        tmp.write_text(text)


def write_bytes_atomic(dest: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``dest`` through a temporary file and a rename."""
    with atomic_path(dest) as tmp:
        tmp.write_bytes(data)
