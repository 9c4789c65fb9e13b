"""The one loader for the firmware's C on the host: the core, the frame codec, the desktop boards.

Host and board must agree bit for bit, so the host runs the same C sources:
- ``core()``: firmware/core and common/ (tables, play operator, compensator, onset detector,
  frame codec, CRC) compiled into one cffi extension module (API mode) on first use and
  cached under $PLAYSCOPE_CACHE (default ~/.cache/playscope/native-<hash>), keyed by a hash
  of every source and header, so an edit rebuilds it. The cdef is the headers themselves, run
  through ``gcc -E -P -DPS_CDEF`` (PS_CDEF empties PS_PACKED, hence ``cdef(packed=True)`` for
  the packed wire and table structs): no struct, enum or constant is retyped in Python.
  ``frame_codec()`` is the same module (kept as a name for the link code that only needs it).
- ``executable(target)``: a desktop program of the CMake build (``ps_vboard``, ``ps_usbemu``).
  CMake is the one list of their sources: the program is taken from build/desktop-release or
  build/desktop after an incremental ``cmake --build --target``, or built in a private build
  folder in the cache when the checkout has no build yet.

- Constants (CONSTANTS): ``native.Q16_ONE``, ``native.MAX_OPS``, ``native.USB_VID``, ... and
  ``constant("PST_...")``, read from the compiled C on first access; the only place the host
  names them (tests/python/host/test_constants_from_c.py fails on a literal copy elsewhere).

Usage:  from playscope.base.native import core;  ffi, lib = core()
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

# The C sources live in the repository beside host/ (editable install) or where
# $PLAYSCOPE_SRC points (any checkout of the same revision).
REPO = Path(os.environ.get("PLAYSCOPE_SRC", Path(__file__).resolve().parents[3]))
COMMON = REPO / "common"
CORE = REPO / "firmware" / "core"
CDEF_HEADERS = [COMMON / n for n in ("ps_fixed.h", "ps_table.h", "ps_proto.h", "ps_frame.h", "ps_plaus.h")] + [
    CORE / f"{n}.h" for n in ("lut", "calib", "playop", "comp", "enc_hist", "onset", "exc", "table_write", "b_online", "f_online")]
# The USB ids live with the USB device core (firmware/link/usb); only these names are taken from it
# (its functions belong to the board, not to the host's module). A name cdef'd as "#define NAME ..."
# gets its value from the C compiler, never from Python.
USB = REPO / "firmware" / "link" / "usb"
USB_HEADER = USB / "psu_device.h"
VALUE_ONLY = {"PSU_VID": USB_HEADER, "PSU_PID": USB_HEADER, "PSU_EP_OUT": USB_HEADER, "PSU_EP_IN": USB_HEADER,
              "CALIB_DERIVED_MAX": CORE / "calib.h"}
# Constants the host reads from the C, by their Python name: ``native.Q16_ONE`` etc. (attribute
# access compiles the core on first use; importing this module does not).
CONSTANTS = {
    "Q16_ONE": "PS_Q16_ONE",              # Q16.16 scale: value = raw / Q16_ONE
    "FRAC_BITS": "PS_FRAC_BITS",
    "MAX_OPS": "PST_MAX_OPS",             # play operators of the transition
    "MAX_ENTRIES": "PST_MAX_ENTRIES",     # entries per grid the loader accepts
    "MIN_ENTRIES": "PST_MIN_ENTRIES",
    "MAX_TABLE_SIZE": "PST_MAX_TABLE_SIZE",
    "CALIB_DERIVED_MAX": "CALIB_DERIVED_MAX",  # entries of each table the loader derives (f^-1, z)
    "USB_VID": "PSU_VID",                 # the board's USB vendor and product id
    "USB_PID": "PSU_PID",
    "USB_EP_OUT": "PSU_EP_OUT",           # bulk endpoints: host -> board frames, board -> host
    "USB_EP_IN": "PSU_EP_IN",
}
# Headers whose structs are runtime state, not wire or table layout: cdef'd unpacked.
UNPACKED_COMMON = {"ps_frame.h", "ps_plaus.h"}
MODULE = "_playscope_native"
# Environment overrides for the desktop programs (a build elsewhere, a sanitizer build, ...).
EXE_ENV = {"ps_vboard": "PLAYSCOPE_VBOARD", "ps_usbemu": "PLAYSCOPE_USBEMU"}

_lock = threading.Lock()
_cached = None


class NativeBuildError(RuntimeError):
    """The C could not be preprocessed, compiled or built (message carries the tool output)."""


def cache_root() -> Path:
    return Path(os.environ.get("PLAYSCOPE_CACHE", Path.home() / ".cache" / "playscope"))


def _sources() -> list[Path]:
    """Every C file of the core and common/: the rule is "all of them", so no list to keep."""
    return sorted(CORE.glob("*.c")) + sorted(COMMON.glob("*.c"))


def _fingerprint() -> str:
    h = hashlib.sha256(sys.version.encode())
    for p in _sources() + sorted(CORE.glob("*.h")) + sorted(COMMON.glob("*.h")) + sorted(USB.glob("*.h")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    h.update(Path(__file__).read_bytes())
    return h.hexdigest()[:16]


def cdef_text() -> tuple[str, str]:
    """The headers preprocessed for cffi, split by layout: (packed text, unpacked text).

    common/'s wire and table structs are packed (cdef'd with packed=True); the core's runtime
    structs and the frame parser's state are not. System headers are replaced by empty stubs
    (cffi knows int32_t, bool, size_t itself); gcc's line markers tell which header each line
    came from. Errors: NativeBuildError when gcc fails."""
    with tempfile.TemporaryDirectory() as stub:
        for name in ("stdint.h", "stdbool.h", "stddef.h", "string.h"):
            Path(stub, name).write_text("")
        src = "".join(f'#include "{h}"\n' for h in CDEF_HEADERS)
        try:
            out = subprocess.run(
                ["gcc", "-E", "-DPS_CDEF", "-nostdinc", "-I", stub, "-I", str(COMMON), "-I", str(CORE), "-"],
                input=src, capture_output=True, text=True, check=True)
        except (OSError, subprocess.CalledProcessError) as e:
            raise NativeBuildError(f"gcc -E over the C headers failed: {getattr(e, 'stderr', e)}") from None
    packed, plain = [], []
    dest = None
    for line in out.stdout.splitlines():
        if line.startswith("# "):  # line marker: # <n> "<file>" <flags>
            f = Path(line.split('"')[1]) if '"' in line else Path("<none>")
            if f.parent == COMMON:
                dest = plain if f.name in UNPACKED_COMMON else packed
            else:
                dest = plain if f.parent == CORE else None
            continue
        # Empty statements are left where PS_STATIC_ASSERT(...); expanded to nothing.
        if dest is not None and line.strip() and line.strip() != ";":
            dest.append(line)
    return "\n".join(packed), "\n".join(plain)


def _build(target_dir: Path) -> None:
    import cffi

    ffi = cffi.FFI()
    packed, plain = cdef_text()
    ffi.cdef(packed, packed=True)
    ffi.cdef(plain)
    ffi.cdef("uint32_t ps_crc32_update(uint32_t crc, const void *buf, size_t len);")
    ffi.cdef("".join(f"#define {n} ...\n" for n in VALUE_ONLY))
    extra = sorted({h.name for h in VALUE_ONLY.values()} - {h.name for h in CDEF_HEADERS})
    includes = "".join(f'#include "{h}"\n' for h in [h.name for h in CDEF_HEADERS] + extra) + '#include "ps_crc32.h"\n'
    ffi.set_source(MODULE, includes, sources=[str(p) for p in _sources()],
                   # firmware/ too: the link headers include each other with their folder
                   # ("link/usb/psu_usb.h")
                   include_dirs=[str(COMMON), str(CORE), str(USB), str(REPO / "firmware")],
                   extra_compile_args=["-std=c11", "-O2", "-Wno-address-of-packed-member"])
    target_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target_dir) as tmp:
        try:
            so = ffi.compile(tmpdir=tmp, verbose=False)
        except Exception as e:  # distutils/setuptools raise several types
            raise NativeBuildError(f"compiling the C core failed: {e}") from None
        # Rename into place so a concurrent process never imports a half-written file.
        os.replace(so, target_dir / Path(so).name)


def _load(target: Path) -> tuple:
    """(ffi, lib) of the core's extension in folder target, building it first when absent."""
    return load_extension(target, MODULE, _build)


def load_extension(target: Path, module: str, build) -> tuple:
    """(ffi, lib) of the cffi extension `module` in folder target, calling build(target) first
    when no compiled file is there (the folder name carries a hash of the sources, so a stale
    build is never loaded). Shared by the core and the diagnosis' kernels. Errors: whatever
    build raises; ImportError for a compiled file that does not load."""
    found = sorted(target.glob(f"{module}*.so")) if target.is_dir() else []
    if not found:
        build(target)
        found = sorted(target.glob(f"{module}*.so"))
    spec = importlib.util.spec_from_file_location(module, found[0])
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.ffi, mod.lib


def core():
    """Return (ffi, lib) of the compiled core and frame codec, building it on first use.

    Errors: NativeBuildError when gcc or the sources are missing or do not compile.
    """
    global _cached
    with _lock:
        if _cached is not None:
            return _cached
        if not CORE.is_dir():
            raise NativeBuildError(f"{CORE}: firmware sources not found (set PLAYSCOPE_SRC)")
        _cached = _load(cache_root() / f"native-{_fingerprint()}")
        return _cached


@functools.lru_cache(maxsize=None)  # fixed for the process: one compiled core per run
def constant(c_name: str) -> int:
    """The integer constant `c_name` of the C headers (an enum value or a VALUE_ONLY macro),
    e.g. constant("PST_MAX_ENTRIES") -> 256. Errors: AttributeError for an unknown name."""
    return int(getattr(core()[1], c_name))


def __getattr__(name: str) -> int:
    # Module attributes read from the C on first access (PEP 562), so `import playscope.base.native`
    # stays cheap and the CLI's --help never compiles the core.
    if name in CONSTANTS:
        return constant(CONSTANTS[name])
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def enum_names(ctype: str, prefix: str, lower: bool = True) -> dict[int, str]:
    """{value: name} of a C enum, names without `prefix` (lower-cased unless lower=False),
    read from the compiled headers so Python never retypes them: e.g.
    enum_names("enum psp_mode", "PSP_MODE_") -> {0: "idle", 1: "excitation", ...}."""
    ffi, _ = core()
    out = {}
    for value, name in ffi.typeof(ctype).elements.items():
        if name.startswith(prefix):
            name = name[len(prefix):]
            out[value] = name.lower() if lower else name
    return out


def frame_codec():
    """(ffi, lib) holding common/ps_frame.c's codec: the same module as core()."""
    return core()


def _cmake_build(build_dir: Path, target: str) -> None:
    # Serialised across processes (tests start boards in parallel): two ninja runs in one
    # build folder may both rebuild the same outputs.
    import fcntl

    with open(build_dir / ".playscope-build.lock", "w") as lk:
        fcntl.flock(lk, fcntl.LOCK_EX)
        r = subprocess.run(["cmake", "--build", str(build_dir), "--target", target],
                           capture_output=True, text=True)
    if r.returncode != 0:
        raise NativeBuildError(f"cmake --build {build_dir} --target {target} failed:\n{r.stdout[-2000:]}{r.stderr[-2000:]}")


def executable(target: str) -> Path:
    """Path of the desktop program `target` (a CMake target of firmware/boards/desktop, e.g.
    "ps_vboard", "ps_usbemu"), brought up to date first.

    Order: $PLAYSCOPE_VBOARD / $PLAYSCOPE_USBEMU as given; the checkout's build/desktop-release
    or build/desktop (incremental build, a no-op when current); else a private release build
    configured in the cache. Errors: NativeBuildError when cmake is missing or the build fails
    (ps_usbemu also needs libumockdev-dev and pkg-config)."""
    env = os.environ.get(EXE_ENV.get(target, ""), "")
    if env:
        return Path(env)
    with _lock:
        for preset in ("desktop-release", "desktop"):
            build = REPO / "build" / preset
            if (build / "CMakeCache.txt").is_file():
                _cmake_build(build, target)
                exe = build / "link-desktop-board" / target
                if exe.is_file():
                    return exe
        if not shutil.which("cmake"):
            raise NativeBuildError(f"{target}: no build of the firmware and no cmake to make one "
                                   "(run tools/setup.sh)")
        # One private build per checkout: a CMake build folder is tied to its source folder,
        # so two checkouts (or a moved one) sharing it would fail to configure.
        build = cache_root() / f"cmake-desktop-{hashlib.sha256(str(REPO.resolve()).encode()).hexdigest()[:12]}"
        build.mkdir(parents=True, exist_ok=True)
        if not (build / "CMakeCache.txt").is_file():
            gen = ["-G", "Ninja"] if shutil.which("ninja") else []
            r = subprocess.run(["cmake", "-S", str(REPO), "-B", str(build), *gen, "-DCMAKE_BUILD_TYPE=Release",
                                "-DPS_BUILD_TESTS=OFF"], capture_output=True, text=True)
            if r.returncode != 0:
                raise NativeBuildError(f"cmake configure failed:\n{r.stderr[-2000:]}")
        _cmake_build(build, target)
        exe = build / "link-desktop-board" / target
        if not exe.is_file():
            raise NativeBuildError(f"{target}: not built (missing dependency? see cmake output in {build})")
        return exe


# --------------------------------------------------------------------------- Q16.16
def to_q16(x) -> "np.ndarray":
    """Round to the nearest Q16.16 raw value (int32), half away from zero.

    Errors: OverflowError naming the first value outside int32 (as Klipper refuses to send
    an out-of-range fixed-point value)."""
    import numpy as np

    a = np.asarray(x, float) * float(constant("PS_Q16_ONE"))
    r = np.sign(a) * np.floor(np.abs(a) + 0.5)
    if np.any(~np.isfinite(r)) or np.any(np.abs(r) > 2**31 - 1):
        bad = np.asarray(x, float).ravel()[np.argmax((~np.isfinite(r) | (np.abs(r) > 2**31 - 1)).ravel())]
        raise OverflowError(f"Fixed point Q16.16 overflow: {bad!r}")
    return r.astype(np.int32)


def from_q16(raw) -> "np.ndarray":
    """Raw Q16.16 int32 -> float64 value."""
    import numpy as np

    return np.asarray(raw, np.int64).astype(float) / float(constant("PS_Q16_ONE"))
