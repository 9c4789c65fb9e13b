"""Fixed-point calibration tables (common/ps_table.h, layout v1) written through the C types.

The header is a cffi pst_header_t filled field by field and the CRC comes from the C
calib_table_crc(), so the host cannot drift from the firmware's layout; every table
written is loaded back with the firmware's calib_load() before it is returned.
"""

from __future__ import annotations

import numpy as np

from . import model
from .errors import InputError
from .native import core, from_q16, to_q16


def grid_for(q_min: float, q_max: float, n_max: int) -> tuple[int, int, int]:
    """Uniform grid over [q_min, q_max] with a power-of-two step (raw Q16 units) and at
    most n_max entries: returns (x0_q16, step_q16, n)."""
    x0 = int(to_q16(q_min))
    span = int(to_q16(q_max)) - x0
    step = 1 << max(0, int(np.ceil(np.log2(max(span, 1) / (n_max - 1)))))
    n = int(np.ceil(span / step)) + 1
    return x0, step, max(n, 2)


class CalibTable:
    """A table blob and its loaded C calib_t (kept alive together: entries are read in place)."""

    def __init__(self, blob: bytes, source=None):
        ffi, lib = core()
        self.blob = bytes(blob)
        self._buf = ffi.new("uint8_t[]", self.blob)  # malloc'd, so 4-aligned as calib_load needs
        self.cal = ffi.new("calib_t *")
        st = lib.calib_load(self.cal, self._buf, len(self.blob))
        if st != lib.CALIB_OK:
            raise InputError(source, f"table refused by calib_load: {ffi.string(lib.calib_status_str(st)).decode()}")

    def predict(self, q: np.ndarray, z0: float | None = None) -> np.ndarray:
        """Direct model by the firmware's playop_step() (eq. 3, fixed point): c (N,) deg."""
        ffi, lib = core()
        p = ffi.new("playop_t *")
        qr = to_q16(q).tolist()
        lib.playop_reset(p, self.cal, int(to_q16(q[0] if z0 is None else z0)))
        step = lib.playop_step
        return from_q16(np.array([step(p, x) for x in qr], np.int64))

    def compensate(self, c_ref: np.ndarray) -> np.ndarray:
        """Inverse model by the firmware's comp_step() (eq. 4 with 5/9, no smoothing): q* (N,)."""
        ffi, lib = core()
        cp = ffi.new("comp_t *")
        cr = to_q16(c_ref).tolist()
        lib.comp_reset(cp, self.cal, ffi.NULL, cr[0])
        step = lib.comp_step
        return from_q16(np.array([step(cp, x) for x in cr], np.int64))


def build_table(B, f, q_min: float, q_max: float, unit: str, f_kind: str = "remain", generation: int = 1,
                n_max: int | None = None, source=None) -> CalibTable:
    """Sample B and f on power-of-two grids over the travel and pack a v1 table.

    B: widths floored at 0; f made strictly monotone in raw units (a flat stretch of the
    float f would otherwise have no inverse). Errors: InputError when the loader refuses
    the table (e.g. |dB/dq| >= 2), OverflowError beyond the Q16.16 range."""
    ffi, lib = core()
    n_max = n_max or lib.PST_MAX_ENTRIES
    x0, step, n = grid_for(q_min, q_max, n_max)
    xs = from_q16(x0 + step * np.arange(n, dtype=np.int64))
    b_raw = np.maximum(to_q16(np.maximum(B(xs), 0.0)), 0).astype(np.int64)
    f_raw = to_q16(f(xs)).astype(np.int64)
    sgn = 1 if f_raw[-1] >= f_raw[0] else -1
    g = sgn * f_raw
    for i in range(1, n):  # strictly monotone by at least one LSB
        g[i] = max(g[i], g[i - 1] + 1)
    f_raw = sgn * g
    hsize = ffi.sizeof("pst_header_t")
    total = hsize + 8 * n
    buf = ffi.new("uint8_t[]", total)
    h = ffi.cast("pst_header_t *", buf)
    h.magic, h.layout_version, h.header_size = lib.PST_MAGIC, lib.PST_LAYOUT_VERSION, hsize
    h.total_size, h.crc32, h.generation = total, 0, generation
    h.q_frac_bits = h.c_frac_bits = lib.PS_FRAC_BITS
    h.q_unit = lib.PST_Q_UNIT_MM if unit == "mm" else lib.PST_Q_UNIT_DEG
    h.f_kind = lib.PST_F_REMAIN if f_kind == "remain" else lib.PST_F_COARSE
    h.q_min_q16, h.q_max_q16 = int(to_q16(q_min)), int(to_q16(q_max))
    for grid, off in ((h.b, hsize), (h.f, hsize + 4 * n)):
        grid.x0_q16, grid.step_q16, grid.n, grid.offset = x0, step, n, off
    h.pi.n, h.pi.offset = 0, 0  # no transition operators: the pure play (v2 with n = 0)
    entries = ffi.cast("int32_t *", buf + hsize)
    for i in range(n):
        entries[i] = int(b_raw[i])
        entries[n + i] = int(f_raw[i])
    h.crc32 = lib.calib_table_crc(buf, total)
    return CalibTable(bytes(ffi.buffer(buf, total)), source)


def table_errors(tab: CalibTable, B, f, q_min: float, q_max: float) -> dict:
    """Measured worst-case errors of the fixed-point model against the float one.

    direct_c_deg: |playop_step - direct_model| over a sweep with reversals every 1/8 of
    the travel; comp_q: |comp_step - compensator| on a sine reference; plus the loader's
    own bounds f_inv_err and z_err. All over the table's travel."""
    span = q_max - q_min
    turns = q_min + span * np.array([0, 1, 0.25, 0.875, 0.5, 0.625, 0.125, 1, 0.0])
    q = np.concatenate([np.linspace(a, b, 400) for a, b in zip(turns[:-1], turns[1:])])
    c_fix = tab.predict(q)
    c_flt = model.direct_model(q, B, f)
    fx = f(np.linspace(q_min, q_max, 64))
    lo, hi = float(min(fx)), float(max(fx))
    c_ref = lo + (hi - lo) * (0.5 + 0.45 * np.sin(np.linspace(0, 6 * np.pi, 3000)))
    sign = 1 if f(np.array([q_max]))[0] > f(np.array([q_min]))[0] else -1
    gq = np.linspace(q_min - span, q_max + span, 20001)
    fg = f(gq)
    order = np.argsort(fg)
    f_inv = lambda c: np.interp(c, fg[order], gq[order])
    q_flt = np.clip(model.compensator(c_ref, B, f_inv, sign), q_min, q_max)
    q_fix = tab.compensate(c_ref)
    return {"direct_c_deg_max": float(np.max(np.abs(c_fix - c_flt))),
            "comp_q_max": float(np.max(np.abs(q_fix - q_flt)[1:])),
            "f_inv_err": float(tab.cal.f_inv_err_q16) / 65536, "z_err": float(tab.cal.z_err_q16) / 65536}
