"""Sequential kernels in C (kernels.c): the play operator (the onsets' record model and the
diagnosis use it), the record model's grid passes (the play with its drags, the band at the input,
the two in one pass, the play's gradient, the onsets' first moves, the tip mode's filter and its B gradient's drive) and the diagnosis' recursions, loaded through
cffi like the firmware core
(playscope.base.native): compiled on first use into $PLAYSCOPE_CACHE/diagkernels-<hash of the C, the
header and this file>, so an edit rebuilds it and a stale build is never loaded.

Why: the play operator, the viscous play, the registration switch and the Karnopp carrier are
recursions over time that numpy cannot vectorise; in Python they took about half of a diagnosis'
time (cProfile of a 275-s record, docs/diagnosis.md section 5). The record model's passes run over
a 1 kHz grid several times per evaluation; fused in C they took its Jacobian with the tip mode
from 147 to 19 ms on the 3-minute bench record. The C is a line-for-line
translation of the Python references in fitmodel.py, fit/model.py and fit/onset_model.py (the
tip mode: scipy.signal.lfilter's transposed direct form, in its order of operations) and agrees
with them bit for bit (tests/python/sim/test_diagnose_kernels.py). When no C compiler is available the callers
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


def first_moves(z, start, stop) -> np.ndarray:
    """onset_model._first_moves_ref in C: for each span j, the first grid sample k in [start[j],
    stop[j]) at which z moves (z[k] != z[k - 1], k >= 1), else -1; (M,) int64. z (N,); start, stop
    (M,) int grid indices (a span past the grid finds none). Why: the reference compares all N
    samples per call to find M onsets; a span's scan ends at its first move. Errors: ValueError
    when start and stop differ in shape."""
    ffi, lib = _load()
    zz = _arr(z)
    a, b = np.ascontiguousarray(start, dtype=np.int64), np.ascontiguousarray(stop, dtype=np.int64)
    if a.shape != b.shape:
        raise ValueError("first_moves: start and stop must have one shape")
    out = np.empty(a.size, np.int64)
    lib.dk_first_moves(ffi.from_buffer("double[]", zz), zz.size, ffi.from_buffer("long[]", a),
                       ffi.from_buffer("long[]", b), a.size, ffi.from_buffer("long[]", out))
    return out


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


def band_play_drags(q, idx, val, c, f: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """`band_input` then `play_drags` in one pass, from z0 = lo[0] + f (hi[0] - lo[0]): (z (N,), last
    (N,) int64, side (N,), lo[0], hi[0]), the same bits as the two (kernels.h); q (N,) actuator units,
    idx, val (N, w), c (n_b,), f in [0, 1]. Why: every gradient reads the band at its first sample
    only, so its two grid arrays need not be built. No errors of its own (the taps are the model's)."""
    ffi, lib = _load()
    qq, vv, cc = _arr(q), _arr(val), _arr(c)
    ii = np.ascontiguousarray(idx, dtype=np.int32)
    z, side = np.empty(qq.size), np.empty(qq.size)
    last = np.empty(qq.size, np.int64)
    band0 = np.empty(2)
    lib.dk_band_play_drags(ffi.from_buffer("double[]", qq), ffi.from_buffer("int[]", ii), ffi.from_buffer("double[]", vv),
                           qq.size, ii.shape[1], ffi.from_buffer("double[]", cc), float(f), ffi.from_buffer("double[]", z),
                           ffi.from_buffer("long[]", last), ffi.from_buffer("double[]", side), ffi.from_buffer("double[]", band0))
    return z, last, side, float(band0[0]), float(band0[1])


def drag_gradient(cols, vals, last, side, nb: int) -> np.ndarray:
    """The play's gradient over B's nb coefficients at K grid samples (K, nb) (kernels.h): row i is
    the design's row at last[i] (its taps cols (N, w) int, vals (N, w)) times side[i], or zeros
    where last[i] < 0. Bit for bit onset_model's numpy rows (their zeros' signs included). Why:
    z_gradient built these rows by fancy indexing and a boolean mask, 72 % of its time on the bench
    record (under a line profiler). Errors: ValueError for a last past the table or a tap past nb."""
    ffi, lib = _load()
    cc = np.ascontiguousarray(cols, dtype=np.int32)
    vv, ss = _arr(vals), _arr(side)
    ll = np.ascontiguousarray(last, dtype=np.int64)
    if ll.shape != ss.shape or cc.shape != vv.shape or cc.ndim != 2:
        raise ValueError("drag_gradient: last and side of one shape, cols and vals (N, w) alike")
    if ll.size and ll.max() >= cc.shape[0]:
        raise ValueError("drag_gradient: a sample past the taps' table")
    used = cc[ll[ll >= 0]]  # the rows read (not the whole table: it is the grid's, N x w)
    if used.size and (used.min() < 0 or used.max() >= nb):
        raise ValueError("drag_gradient: a tap past nb")
    out = np.empty((ll.size, int(nb)))
    lib.dk_drag_gradient(ffi.from_buffer("int[]", cc), ffi.from_buffer("double[]", vv), cc.shape[1],
                         ffi.from_buffer("long[]", ll), ffi.from_buffer("double[]", ss), ll.size, int(nb),
                         ffi.from_buffer("double[]", out))
    return out


def tip_mode(u, b1: float, a1: float, a2: float) -> np.ndarray:
    """scipy.signal.lfilter([0, b1], [1, a1, a2], u) in C, bit for bit (kernels.h)."""
    ffi, lib = _load()
    uu = _arr(u)
    y = np.empty(uu.size)
    lib.dk_tip_mode(ffi.from_buffer("double[]", uu), uu.size, float(b1), float(a1), float(a2), ffi.from_buffer("double[]", y))
    return y


def tip_mode_edges(cols, vals, src, scale, pre, wd, b1: float, a1: float, a2: float, i0, w_lo, w_hi) -> np.ndarray:
    """The tip mode's filter driven by the second differences of an edge gradient on the grid,
    for each of its R coefficients, read at F sorted positions: (F, R) (kernels.h). cols (K, w) int,
    vals (K, w) a table of rows; src (n,) int the table row of each grid sample (-1: pre (R,)),
    scale (n,) its multiplier; wd (n - 2,); i0 (F,) int sorted, w_lo, w_hi (F,). Bit for bit the
    numpy and lfilter pipeline on the dense (R, n) gradient. Errors: ValueError for positions
    unsorted or past the output."""
    ffi, lib = _load()
    cc = np.ascontiguousarray(cols, dtype=np.int32)
    vv, ss, sc, pp, ww = _arr(vals), np.ascontiguousarray(src, dtype=np.int64), _arr(scale), _arr(pre), _arr(wd)
    ii = np.ascontiguousarray(i0, dtype=np.int64)
    n, R = ss.size, pp.size
    if ii.size and (ii[0] < 0 or ii[-1] + 1 >= n - 2 or np.any(np.diff(ii) < 0)):
        raise ValueError("tip_mode_edges: positions must be sorted and within the output")
    out = np.zeros((ii.size, R))
    scratch = np.empty(7 * R)
    lib.dk_tip_mode_edges(ffi.from_buffer("int[]", cc), ffi.from_buffer("double[]", vv), cc.shape[1],
                          ffi.from_buffer("long[]", ss), ffi.from_buffer("double[]", sc), n, ffi.from_buffer("double[]", pp),
                          R, ffi.from_buffer("double[]", ww), float(b1), float(a1), float(a2), ffi.from_buffer("long[]", ii),
                          ffi.from_buffer("double[]", _arr(w_lo)), ffi.from_buffer("double[]", _arr(w_hi)), ii.size,
                          ffi.from_buffer("double[]", scratch), ffi.from_buffer("double[]", out))
    return out
