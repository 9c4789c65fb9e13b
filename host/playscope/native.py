"""The firmware's own C core (firmware/core, common/) compiled for the host through cffi.

Host and board must agree bit for bit, so the host runs the same C sources: they are
compiled into an extension module (cffi API mode) on first use and cached under
$PLAYSCOPE_CACHE (default ~/.cache/playscope/native-<hash>), keyed by a hash of every
source and header, so an edit of firmware/core rebuilds it. The cdef is the headers
themselves, run through ``gcc -E -P -DPS_CDEF`` (PS_CDEF empties PS_PACKED, hence
``cdef(packed=True)``): no struct, enum or constant is retyped here.

Usage:  from playscope.native import core;  ffi, lib = core()
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

# The C sources live in the repository beside host/ (editable install) or where
# $PLAYSCOPE_SRC points (any checkout of the same revision).
REPO = Path(os.environ.get("PLAYSCOPE_SRC", Path(__file__).resolve().parents[2]))
COMMON = REPO / "common"
CORE = REPO / "firmware" / "core"
CDEF_HEADERS = [COMMON / "ps_fixed.h", COMMON / "ps_table.h", COMMON / "ps_proto.h"] + [
    CORE / f"{n}.h" for n in ("lut", "calib", "playop", "comp", "enc_hist", "onset", "exc", "table_write")]
MODULE = "_playscope_core"

_lock = threading.Lock()
_cached = None


class NativeBuildError(RuntimeError):
    """The C core could not be preprocessed or compiled (message carries the compiler output)."""


def _sources() -> list[Path]:
    return sorted(CORE.glob("*.c")) + sorted(COMMON.glob("*.c"))


def _fingerprint() -> str:
    h = hashlib.sha256(sys.version.encode())
    for p in _sources() + sorted(CORE.glob("*.h")) + sorted(COMMON.glob("*.h")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    h.update(Path(__file__).read_bytes())
    return h.hexdigest()[:16]


def cdef_text() -> tuple[str, str]:
    """The headers preprocessed for cffi, split by origin: (common/ text, firmware/core text).

    common/ structs are packed on the wire and in tables (cdef'd with packed=True); the
    core's runtime structs are not, so they go through a second, unpacked cdef. System
    headers are replaced by empty stubs (cffi knows int32_t, bool, size_t itself); gcc's
    line markers tell which header each line came from."""
    with tempfile.TemporaryDirectory() as stub:
        for name in ("stdint.h", "stdbool.h", "stddef.h", "string.h"):
            Path(stub, name).write_text("")
        src = "".join(f'#include "{h}"\n' for h in CDEF_HEADERS)
        try:
            out = subprocess.run(
                ["gcc", "-E", "-DPS_CDEF", "-nostdinc", "-I", stub, "-I", str(COMMON), "-I", str(CORE), "-"],
                input=src, capture_output=True, text=True, check=True)
        except (OSError, subprocess.CalledProcessError) as e:
            raise NativeBuildError(f"gcc -E over the core headers failed: {getattr(e, 'stderr', e)}") from None
    parts = {"common": [], "core": []}
    origin = None
    for line in out.stdout.splitlines():
        if line.startswith("# "):  # line marker: # <n> "<file>" <flags>
            f = line.split('"')[1] if '"' in line else ""
            origin = "common" if Path(f).parent == COMMON else "core" if Path(f).parent == CORE else None
            continue
        # Empty statements left where PS_STATIC_ASSERT(...); expanded to nothing.
        if origin and line.strip() and line.strip() != ";":
            parts[origin].append(line)
    return "\n".join(parts["common"]), "\n".join(parts["core"])


def _build(target_dir: Path) -> None:
    import cffi

    ffi = cffi.FFI()
    common_text, core_text = cdef_text()
    ffi.cdef(common_text, packed=True)
    ffi.cdef(core_text)
    includes = "".join(f'#include "{h.name}"\n' for h in CDEF_HEADERS) + '#include "ps_crc32.h"\n'
    ffi.cdef("uint32_t ps_crc32_update(uint32_t crc, const void *buf, size_t len);")
    ffi.set_source(MODULE, includes, sources=[str(p) for p in _sources()],
                   include_dirs=[str(COMMON), str(CORE)],
                   extra_compile_args=["-std=c11", "-O2", "-Wno-address-of-packed-member"])
    target_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target_dir) as tmp:
        try:
            so = ffi.compile(tmpdir=tmp, verbose=False)
        except Exception as e:  # distutils/setuptools raise several types
            raise NativeBuildError(f"compiling the C core failed: {e}") from None
        # Rename into place so a concurrent process never imports a half-written file.
        os.replace(so, target_dir / Path(so).name)


def core():
    """Return (ffi, lib) of the compiled core, building it on first use.

    Errors: NativeBuildError when gcc or the sources are missing or do not compile.
    """
    global _cached
    with _lock:
        if _cached is not None:
            return _cached
        if not CORE.is_dir():
            raise NativeBuildError(f"{CORE}: firmware sources not found (set PLAYSCOPE_SRC)")
        base = Path(os.environ.get("PLAYSCOPE_CACHE", Path.home() / ".cache" / "playscope"))
        _cached = load_extension(base / f"native-{_fingerprint()}", MODULE, _build)
        return _cached


def load_extension(target: Path, module: str, build) -> tuple:
    """(ffi, lib) of the cffi extension `module` compiled into folder target, calling
    build(target) first when no build is there yet (the folder name carries a hash of the
    sources, so a stale build is never loaded)."""
    found = sorted(target.glob(f"{module}*.so")) if target.is_dir() else []
    if not found:
        build(target)
        found = sorted(target.glob(f"{module}*.so"))
    spec = importlib.util.spec_from_file_location(module, found[0])
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.ffi, mod.lib


# --------------------------------------------------------------------------- Q16.16
def to_q16(x) -> "np.ndarray":
    """Round to the nearest Q16.16 raw value (int32), half away from zero.

    Errors: OverflowError naming the first value outside int32 (as Klipper refuses to send
    an out-of-range fixed-point value)."""
    import numpy as np

    a = np.asarray(x, float) * 65536.0
    r = np.sign(a) * np.floor(np.abs(a) + 0.5)
    if np.any(~np.isfinite(r)) or np.any(np.abs(r) > 2**31 - 1):
        bad = np.asarray(x, float).ravel()[np.argmax((~np.isfinite(r) | (np.abs(r) > 2**31 - 1)).ravel())]
        raise OverflowError(f"Fixed point Q16.16 overflow: {bad!r}")
    return r.astype(np.int32)


def from_q16(raw) -> "np.ndarray":
    """Raw Q16.16 int32 -> float64 value."""
    import numpy as np

    return np.asarray(raw, np.int64).astype(float) / 65536.0
