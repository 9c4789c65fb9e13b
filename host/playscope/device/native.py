"""The C frame codec (common/ps_frame.c) and the virtual board, built from the repository's sources.

The host never retypes the wire format: common/ps_frame.h and ps_proto.h are run through
``gcc -E -DPS_CDEF`` for cffi's cdef (packed structs from ps_proto.h, the unpacked parser
state from ps_frame.h), and ps_frame.c is compiled into an extension module cached like
playscope.native (keyed by a hash of the sources).

The virtual board (firmware/boards/desktop/vboard.c) is found as $PLAYSCOPE_VBOARD or in
build/desktop-release or build/desktop, and otherwise compiled straight from the sources
into the same cache, so ``--device virtual`` works without the CMake build.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from ..native import REPO, NativeBuildError, load_extension

COMMON = REPO / "common"
CORE = REPO / "firmware" / "core"
APP = REPO / "firmware" / "app"
LINK = REPO / "firmware" / "link"
STORAGE = REPO / "firmware" / "storage"
DESKTOP = REPO / "firmware" / "boards" / "desktop"
MODULE = "_playscope_frame"
PACKED_HEADERS = {"ps_proto.h", "ps_defs.h"}

_lock = threading.Lock()
_cached = None


def _cache_dir(kind: str, files: list[Path]) -> Path:
    h = hashlib.sha256(sys.version.encode())
    for p in sorted(files):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    h.update(Path(__file__).read_bytes())
    base = Path(os.environ.get("PLAYSCOPE_CACHE", Path.home() / ".cache" / "playscope"))
    return base / f"{kind}-{h.hexdigest()[:16]}"


def _cdef() -> tuple[str, str]:
    """(packed part, unpacked part) of ps_frame.h and what it includes, preprocessed."""
    with tempfile.TemporaryDirectory() as stub:
        for name in ("stdint.h", "stdbool.h", "stddef.h"):
            Path(stub, name).write_text("")
        try:
            out = subprocess.run(["gcc", "-E", "-DPS_CDEF", "-nostdinc", "-I", stub, "-I", str(COMMON), "-"],
                                 input='#include "ps_frame.h"\n', capture_output=True, text=True, check=True)
        except (OSError, subprocess.CalledProcessError) as e:
            raise NativeBuildError(f"gcc -E over ps_frame.h failed: {getattr(e, 'stderr', e)}") from None
    packed, plain, origin = [], [], None
    for line in out.stdout.splitlines():
        if line.startswith("# "):
            origin = Path(line.split('"')[1]).name if '"' in line else None
            continue
        if not line.strip() or line.strip() == ";" or origin is None or origin.startswith("<"):
            continue
        (packed if origin in PACKED_HEADERS else plain).append(line)
    return "\n".join(packed), "\n".join(plain)


def _build(target: Path) -> None:
    import cffi

    ffi = cffi.FFI()
    packed, plain = _cdef()
    ffi.cdef(packed, packed=True)
    ffi.cdef(plain)
    ffi.cdef("uint32_t ps_crc32_update(uint32_t crc, const void *buf, size_t len);")
    ffi.set_source(MODULE, '#include "ps_frame.h"\n#include "ps_crc32.h"\n',
                   sources=[str(COMMON / "ps_frame.c"), str(COMMON / "ps_crc32.c")],
                   include_dirs=[str(COMMON)], extra_compile_args=["-std=c11", "-O2", "-Wno-address-of-packed-member"])
    target.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target) as tmp:
        try:
            so = ffi.compile(tmpdir=tmp, verbose=False)
        except Exception as e:
            raise NativeBuildError(f"compiling the frame codec failed: {e}") from None
        os.replace(so, target / Path(so).name)


def frame_codec():
    """(ffi, lib) of common/ps_frame.c; built on first use. Errors: NativeBuildError."""
    global _cached
    with _lock:
        if _cached is None:
            files = [COMMON / n for n in ("ps_frame.c", "ps_frame.h", "ps_proto.h", "ps_defs.h",
                                          "ps_crc32.c", "ps_crc32.h")]
            _cached = load_extension(_cache_dir("frame", files), MODULE, _build)
        return _cached


def vboard_sources() -> list[Path]:
    return (sorted(COMMON.glob("*.c")) + sorted(CORE.glob("*.c")) + [APP / "psa_loop.c", LINK / "psl_link.c"]
            + [STORAGE / n for n in ("pss_store.c", "pss_flash_sim.c", "pss_flash_file.c")]
            + [DESKTOP / "vboard.c"])


def vboard_path() -> Path:
    """Path of the virtual board executable, compiling it if no build has one."""
    env = os.environ.get("PLAYSCOPE_VBOARD")
    if env:
        return Path(env)
    for preset in ("desktop-release", "desktop"):
        p = REPO / "build" / preset / "link-desktop-board" / "ps_vboard"
        if p.is_file() and all(p.stat().st_mtime >= s.stat().st_mtime for s in vboard_sources()):
            return p
    headers = [p for d in (COMMON, CORE, APP, LINK, STORAGE) for p in d.glob("*.h")]
    target = _cache_dir("vboard", vboard_sources() + headers)
    exe = target / "ps_vboard"
    with _lock:
        if not exe.is_file():
            target.mkdir(parents=True, exist_ok=True)
            cc = os.environ.get("CC") or shutil.which("cc") or "gcc"
            tmp = target / f"ps_vboard.{os.getpid()}"
            cmd = [cc, "-std=c11", "-O2", "-Wall", *[f"-I{d}" for d in (COMMON, CORE, APP, LINK, STORAGE)],
                   *map(str, vboard_sources()), "-o", str(tmp)]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                raise NativeBuildError(f"compiling the virtual board failed:\n{r.stderr}")
            os.replace(tmp, exe)
    return exe
