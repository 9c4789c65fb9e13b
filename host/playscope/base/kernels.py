"""Sequential kernels in C (kernels.c): the play operator (the onsets' record model and the
diagnosis use it) and the diagnosis' recursions, loaded through cffi like the firmware core
(playscope.base.native): compiled on first use into $PLAYSCOPE_CACHE/diagkernels-<hash of the C, the
header and this file>, so an edit rebuilds it and a stale build is never loaded.

Why: the play operator, the viscous play, the registration switch and the Karnopp carrier are
recursions over time that numpy cannot vectorise; in Python they took about half of a diagnosis'
time (cProfile of a 275-s record, docs/diagnosis.md section 5). The C is a line-for-line
translation of the Python references in fitmodel.py and fit/model.py and agrees with them bit for
bit (tests/python/sim/test_diagnose_kernels.py). When no C compiler is available the callers
fall back to the Python references (``available()`` is False; the same results, slower).

Functions take and return float64 numpy arrays of one length N (mm); shapes (N,).
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import threading
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SOURCES = (HERE / "kernels.c", HERE / "kernels.h")
MODULE = "_playscope_diagkernels"

_lock = threading.Lock()
_lib = None       # (ffi, lib) once loaded
_failed = False   # a build failed once: use the Python references for the rest of the process


def _fingerprint() -> str:
    h = hashlib.sha256(sys.version.encode())
    for p in SOURCES + (Path(__file__),):
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def _cdef() -> str:
    """kernels.h without its preprocessor lines (cffi's cdef takes declarations only)."""
    return "\n".join(l for l in SOURCES[1].read_text().splitlines() if not l.lstrip().startswith("#"))


def _build(target: Path) -> None:
    import cffi

    ffi = cffi.FFI()
    ffi.cdef(_cdef())
    ffi.set_source(MODULE, '#include "kernels.h"\n', sources=[str(SOURCES[0])], include_dirs=[str(HERE)],
                   # no contraction into fused multiply-adds: the C must round as Python does
                   extra_compile_args=["-std=c11", "-O2", "-ffp-contract=off", "-fno-fast-math"],
                   libraries=["m"])
    target.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target) as tmp:
        so = ffi.compile(tmpdir=tmp, verbose=False)
        os.replace(so, target / Path(so).name)  # never a half-written file for another process


def _load():
    """(ffi, lib), building on first use; None when the build fails (warned once)."""
    global _lib, _failed
    if _lib is not None or _failed:
        return _lib
    with _lock:
        if _lib is not None or _failed:
            return _lib
        from ..base.native import cache_root, load_extension
        try:
            _lib = load_extension(cache_root() / f"diagkernels-{_fingerprint()}", MODULE, _build)
        except Exception as e:  # no compiler, no cffi, unwritable cache: the Python references run
            _failed = True
            warnings.warn(f"diagnosis kernels not compiled ({e}); using the slower Python references",
                          RuntimeWarning, stacklevel=3)
        return _lib


def available() -> bool:
    """True when the C kernels are loaded (else the callers use the Python references)."""
    return _load() is not None


def _arr(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.float64)


def play_on_edges(z_lo, z_hi, z0: float) -> np.ndarray:
    """model.play_on_edges in C: z[k] = min(z_hi[k], max(z_lo[k], z[k-1])), z[-1] = z0."""
    ffi, lib = _load()
    lo, hi = _arr(z_lo), _arr(z_hi)
    out = np.empty(lo.size)
    lib.dk_play_on_edges(ffi.from_buffer("double[]", lo), ffi.from_buffer("double[]", hi), lo.size, float(z0),
                         ffi.from_buffer("double[]", out))
    return out


def play_ops(x, r, p0) -> np.ndarray:
    """transition.play_ops in C: P (N, n), P[k, i] = min(x[k] + r_i, max(x[k] - r_i, P[k-1, i])),
    P[-1] = p0 (n,), with numpy's tie rule (bit for bit the numpy loop, signed zeros included)."""
    ffi, lib = _load()
    xx, rr, pp = _arr(x), _arr(r), _arr(p0)
    out = np.empty((xx.size, rr.size))
    lib.dk_play_ops(ffi.from_buffer("double[]", xx), xx.size, ffi.from_buffer("double[]", rr), rr.size,
                    ffi.from_buffer("double[]", pp), ffi.from_buffer("double[]", out))
    return out


def viscous_play(z_lo, z_hi, z0: float, a: float) -> np.ndarray:
    """fitmodel._viscous_play in C: p[k] = p[k-1] + a (clip(p[k-1], z_lo[k], z_hi[k]) - p[k-1])."""
    ffi, lib = _load()
    lo, hi = _arr(z_lo), _arr(z_hi)
    out = np.empty(lo.size)
    lib.dk_viscous_play(ffi.from_buffer("double[]", lo), ffi.from_buffer("double[]", hi), lo.size, float(z0),
                        float(a), ffi.from_buffer("double[]", out))
    return out


def switch(z, g: float) -> np.ndarray:
    """fitmodel._switch's recursion in C with gain g = 2 / travel (1/mm)."""
    ffi, lib = _load()
    zz = _arr(z)
    out = np.empty(zz.size)
    lib.dk_switch(ffi.from_buffer("double[]", zz), zz.size, float(g), ffi.from_buffer("double[]", out))
    return out


def karnopp(z, w2: float, c2: float, Fs: float, Fc: float, h: float, band: float, substeps: int) -> np.ndarray:
    """fitmodel._karnopp_carrier's recursion in C, its constants computed by the caller."""
    ffi, lib = _load()
    zz = _arr(z)
    out = np.empty(zz.size)
    lib.dk_karnopp(ffi.from_buffer("double[]", zz), zz.size, float(w2), float(c2), float(Fs), float(Fc),
                   float(h), float(band), int(substeps), ffi.from_buffer("double[]", out))
    return out


def play_drags(z_lo, z_hi, z0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """onset_model.play_drags in C: (z (N,), last (N,) int64, side (N,)) (kernels.h)."""
    ffi, lib = _load()
    lo, hi = _arr(z_lo), _arr(z_hi)
    z, side = np.empty(lo.size), np.empty(lo.size)
    last = np.empty(lo.size, np.int64)
    lib.dk_play_drags(ffi.from_buffer("double[]", lo), ffi.from_buffer("double[]", hi), lo.size, float(z0),
                      ffi.from_buffer("double[]", z), ffi.from_buffer("long[]", last), ffi.from_buffer("double[]", side))
    return z, last, side


def band_input(q, idx, val, c) -> tuple[np.ndarray, np.ndarray]:
    """onset_model's band at the input in C: (lo, hi) (N,) = q -+ max(B, 0) / 2, B[k] = sum_j
    val[k, j] c[idx[k, j]] (idx (N, w) int32, val (N, w)), summed as scipy's csr_matvec does."""
    ffi, lib = _load()
    qq, vv, cc = _arr(q), _arr(val), _arr(c)
    ii = np.ascontiguousarray(idx, dtype=np.int32)
    lo, hi = np.empty(qq.size), np.empty(qq.size)
    lib.dk_band_input(ffi.from_buffer("double[]", qq), ffi.from_buffer("int[]", ii), ffi.from_buffer("double[]", vv),
                      qq.size, ii.shape[1], ffi.from_buffer("double[]", cc), ffi.from_buffer("double[]", lo),
                      ffi.from_buffer("double[]", hi))
    return lo, hi
