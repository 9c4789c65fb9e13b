"""Fixed-point calibration tables (common/ps_table.h): the one host module that makes, stamps,
loads and runs them.

Layout is never written here: every blob comes from the firmware's own writer
``table_write()`` (firmware/core/table_write.c, reached through cffi), so host and board cannot
drift. A table is loaded with the firmware's ``calib_load()`` and run with its ``playop_step()``
(direct model) and ``comp_step()`` (compensator) by the one wrapper ``CalibTable``; every
refusal is a ``TableError`` carrying the loader's reason (``calib_status_str``).

Layout 2 carries the smooth transition (thresholds r, weights w of the PI operators,
docs/method.md, "Transition model") after the B and f grids; a pure play (n = 1 or no transition) writes no operator.
Layout 3 adds the threshold map u = g(z) (transition.ThresholdMap: thresholds proportional to
B) on its own grid after the operators, layout 4 the travel-domain relaxation. Every table the
host writes is layout 5 (table_write_inst): the layout-4 content plus the instrument block
(common/ps_table.h pst_instrument_t: the instrument's id, the angle range it can reach, its
largest play, the largest slopes of f and f^-1), stamped by the C pst_instrument_derive, so a
board refuses it for another instrument or beyond its own limits. The plausibility rules are
the C ones (common/ps_plaus.h, through calib_load_guarded); ``refusal`` only words their numbers.
"""

from __future__ import annotations

import math

import numpy as np

from . import model
from ..base.errors import InputError
from ..base import native
from ..base.native import core, from_q16, to_q16

# f's slope floors tried, in order, when a table of the fitted f is refused for precision
# (loadable_f): fractions of f's mean slope over its fitted range. At 1 the floor is the mean
# slope itself, which only a straight line meets: its inverse is exact, so the last one loads.
F_SLOPE_FLOORS = (1 / 32, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0)


class TableError(InputError):
    """A table that cannot be written, stamped or loaded (one line: source and reason).
    status: the loader's calib_status_t when calib_load refused it, else None."""

    status: int | None = None


# --------------------------------------------------------------------------- writing
def grid_for(q_min: float, q_max: float, n_max: int) -> tuple[int, int, int]:
    """Uniform grid over [q_min, q_max] with a power-of-two step (raw Q16 units) and at
    most n_max entries: returns (x0_q16, step_q16, n)."""
    x0 = int(to_q16(q_min))
    span = int(to_q16(q_max)) - x0
    step = 1 << max(0, int(np.ceil(np.log2(max(span, 1) / (n_max - 1)))))
    n = int(np.ceil(span / step)) + 1
    return x0, step, max(n, 2)


def write_blob(x0_q16: int, step_q16: int, b_q16, f_q16, q_min: float, q_max: float, unit: str = "mm",
               f_kind: str = "remain", generation: int = 1, pi_r=None, pi_w=None, source=None,
               f_grid: tuple[int, int] | None = None, tmap: tuple[int, int, list] | None = None,
               relax: tuple[int, int] | None = None, instrument: int | None = None) -> bytes:
    """Lay out and seal one layout-5 table by the C table_write_inst() (common/ps_table.h).

    b_q16, f_q16: int Q16.16 entries on the grid x0 + i step (same grid for both unless f_grid =
    (x0_q16, step_q16) gives f its own); q_min, q_max: actuator travel (units); unit "mm" | "deg";
    f_kind "remain" | "coarse"; pi_r, pi_w: operator thresholds (actuator units) and weights
    (floats, n <= PST_MAX_OPS), or None for the pure play; tmap: (x0_q16, step_q16, u_q16) the
    threshold map's grid and entries (layout 3), or None (layout 2); relax: (kappa_q16,
    lambda_q16) of the travel-domain relaxation (layout 4; playscope.fit.relax.table_fields), or None
    / kappa 0 for none; instrument: the id of the instrument calibrated (default PST_INSTRUMENT_DEFAULT),
    its block's figures derived from the entries by the C pst_instrument_derive. Returns the blob. Errors:
    TableError when the writer refuses it (too many entries, operators or map entries)."""
    ffi, lib = core()
    b = [int(v) for v in b_q16]
    f = [int(v) for v in f_q16]
    n_ops = 0 if pi_r is None else len(pi_r)
    hd = ffi.new("pst_header_t *")
    hd.generation = generation
    hd.q_unit = lib.PST_Q_UNIT_MM if unit == "mm" else lib.PST_Q_UNIT_DEG
    hd.f_kind = lib.PST_F_REMAIN if f_kind == "remain" else lib.PST_F_COARSE
    hd.q_min_q16, hd.q_max_q16 = int(to_q16(q_min)), int(to_q16(q_max))
    for g, n in ((hd.b, len(b)), (hd.f, len(f))):
        g.x0_q16, g.step_q16, g.n = x0_q16, step_q16, n
    if f_grid is not None:
        hd.f.x0_q16, hd.f.step_q16 = f_grid
    n_map = 0 if tmap is None else len(tmap[2])
    cap = ffi.sizeof("pst_header_v5_t") + 4 * (len(b) + len(f) + 2 * n_ops + n_map) + 16
    hd.pi.n = n_ops
    r = ffi.new("int32_t[]", [int(v) for v in to_q16(pi_r)]) if n_ops else ffi.NULL
    w = ffi.new("int32_t[]", [int(v) for v in to_q16(pi_w)]) if n_ops else ffi.NULL
    grid, g = ffi.new("pst_grid_t *"), ffi.NULL  # grid n = 0: no map
    if tmap is not None:
        grid.x0_q16, grid.step_q16, grid.n = int(tmap[0]), int(tmap[1]), n_map
        g = ffi.new("int32_t[]", [int(v) for v in tmap[2]])
    rx = ffi.new("pst_relax_t *")  # kappa 0: no relaxation
    if relax is not None and int(relax[0]) != 0:
        rx.kappa_q16, rx.lambda_q16 = int(relax[0]), int(relax[1])
    bq, fq = ffi.new("int32_t[]", b), ffi.new("int32_t[]", f)
    inst = ffi.new("pst_instrument_t *")
    lib.pst_instrument_derive(hd, bq, fq, lib.PST_INSTRUMENT_DEFAULT if instrument is None else int(instrument), inst)
    buf = ffi.new("uint8_t[]", cap)
    size = lib.table_write_inst(buf, cap, hd, bq, fq, r, w, grid, g, rx, inst)
    if size == 0:
        raise TableError(source, f"table_write refused the table ({len(b)} entries, {n_ops} operators, "
                         f"{n_map} map entries)")
    return bytes(ffi.buffer(buf, size))


def header(blob: bytes, source=None):
    """The blob's pst_header_t (a cffi copy). Errors: TableError if shorter than a header."""
    ffi, _ = core()
    if len(blob) < ffi.sizeof("pst_header_t"):
        raise TableError(source, f"table of {len(blob)} bytes is shorter than its header")
    hd = ffi.new("pst_header_t *")
    ffi.memmove(hd, blob, ffi.sizeof("pst_header_t"))
    return hd


def set_generation(blob: bytes, generation: int, source=None) -> bytes:
    """Return blob with pst_header_t.generation set and the CRC resealed (calib_table_crc).

    The blob's own CRC is checked first: bytes that were corrupted are never resealed into a
    valid-looking table. Errors: TableError (short blob, size mismatch, CRC mismatch)."""
    ffi, lib = core()
    hd = header(blob, source)
    if hd.total_size != len(blob):
        raise TableError(source, f"header says {hd.total_size} bytes, blob has {len(blob)}")
    if lib.calib_table_crc(blob, len(blob)) != hd.crc32:
        raise TableError(source, "CRC mismatch: the table is corrupted, not resealing it")
    hd.generation = generation
    b = bytearray(blob)
    b[: ffi.sizeof("pst_header_t")] = bytes(ffi.buffer(hd))
    crc = lib.calib_table_crc(bytes(b), len(b))
    off = ffi.offsetof("pst_header_t", "crc32")
    b[off:off + 4] = int(crc).to_bytes(4, "little")
    return bytes(b)


# --------------------------------------------------------------------------- refusals
# How each plausibility rule's numbers read (common/ps_plaus.h): the quantity's unit, by the
# rule's name; the rules themselves are only in C.
_RULE_UNITS = {"TRAVEL": "q", "B_TRAVEL": "q", "C_RANGE": "deg", "C_SPAN": "deg", "F_SLOPE": "deg/q",
               "TRAVEL_UNIT": "q", "INST_C_RANGE": "deg", "INST_B_MAX": "q", "INST_F_SLOPE": "deg/q",
               "INST_F_INV_SLOPE": "q/deg", "B_INST": "q", "C_INST": "deg", "F_SLOPE_INST": "deg/q",
               "F_INV_SLOPE_INST": "q/deg", "UNBOUND": "layout", "BOARD_INSTRUMENT": "id", "BOARD_UNIT": "unit",
               "BOARD_TRAVEL": "q", "BOARD_ANGLE": "deg", "BOARD_B": "q"}


def refusal(status: int, rep, blob: bytes | None = None) -> str:
    """One line for calib_load_guarded's refusal `status` (calib_status_t) with its report `rep`
    (pst_plaus_report_t *): the code's name, the loader's reason and, for a plausibility rule,
    what the table has against what the rule allows, in the table's units (blob: the table,
    for its unit and the entry's q)."""
    ffi, lib = core()
    names = native.enum_names("calib_status_t", "", lower=False)
    name = names.get(int(status), str(int(status)))
    msg = f"{name}: {ffi.string(lib.calib_status_str(status)).decode()}"
    if rep is None or int(rep.rule) == lib.PST_RULE_OK:
        return msg
    rule = native.enum_names("pst_rule_t", "PST_RULE_", lower=False).get(int(rep.rule), "")
    kind = _RULE_UNITS.get(rule, "")
    hd = header(blob) if blob is not None and len(blob) >= ffi.sizeof("pst_header_t") else None
    qu = ("deg" if hd is not None and hd.q_unit == lib.PST_Q_UNIT_DEG else "mm") if hd is not None else "units"
    units = {v: k for k, v in {"mm": lib.PST_Q_UNIT_MM, "deg": lib.PST_Q_UNIT_DEG}.items()}
    if kind in ("layout", "id"):
        what = f"{int(rep.value)} (allowed: {int(rep.limit)})"
    elif kind == "unit":
        what = f"{units.get(int(rep.value), rep.value)} (the board's: {units.get(int(rep.limit), rep.limit)})"
    else:
        u = {"q": qu, "deg": "deg", "deg/q": f"deg/{qu}", "q/deg": f"{qu}/deg"}[kind]
        what = f"{int(rep.value) / native.Q16_ONE:.6g} {u} against the limit {int(rep.limit) / native.Q16_ONE:.6g} {u}"
    where = ""
    if int(rep.index) >= 0 and hd is not None:
        g = hd.b if rule in ("B_TRAVEL", "B_INST") else hd.f
        seg = "segment" if "SLOPE" in rule else "entry"
        where = f" at {seg} {int(rep.index)} (q = {(g.x0_q16 + int(rep.index) * g.step_q16) / native.Q16_ONE:.6g} {qu})"
    return f"{msg}: {what}{where}"


# --------------------------------------------------------------------------- loading and running
class CalibTable:
    """A table blob and its loaded C calib_t (kept alive together: entries are read in place).

    Errors: TableError with calib_load()'s reason when the loader refuses the blob."""

    def __init__(self, blob: bytes, source=None):
        ffi, lib = core()
        self.ffi, self.lib = ffi, lib
        self.blob = bytes(blob)
        self._buf = ffi.new("uint8_t[]", self.blob)  # malloc'd, so 4-aligned as calib_load needs
        self.cal = ffi.new("calib_t *")
        rep = ffi.new("pst_plaus_report_t *")
        st = lib.calib_load_guarded(self.cal, self._buf, len(self.blob), ffi.NULL, rep)
        if st != lib.CALIB_OK:
            err = TableError(source, f"table refused by calib_load: {refusal(st, rep, self.blob)}")
            err.status = int(st)  # calib_status_t, for callers that can mend one reason (calibration.loadable_f)
            raise err

    @property
    def has_map(self) -> bool:
        """True for a layout-3 table carrying a threshold map (the operators run on u = g(z))."""
        return int(self.cal.tmap.n) != 0

    @property
    def n_ops(self) -> int:
        """Transition operators carried (0: pure play or a layout-1 table)."""
        hd = header(self.blob)
        return int(hd.pi.n) if hasattr(hd, "pi") else 0

    def predict(self, q: np.ndarray, z0: float | None = None) -> np.ndarray:
        """Direct model by the firmware's playop_step() (eq. 3 and the PI part, fixed point):
        q (N,) actuator units -> c (N,) deg, state run from q[0] (or z0)."""
        p = self.ffi.new("playop_t *")
        qr = to_q16(q).tolist()
        self.lib.playop_reset(p, self.cal, int(to_q16(q[0] if z0 is None else z0)))
        step = self.lib.playop_step
        return from_q16(np.array([step(p, x) for x in qr], np.int64))

    def comp_run(self, c_q16: list[int]) -> list[int]:
        """comp_reset at c[0], then comp_step over c (raw Q16): what the board does in
        compensation mode, no smoothing. Returns q* raw Q16 (list)."""
        cp = self.ffi.new("comp_t *")
        self.lib.comp_reset(cp, self.cal, self.ffi.NULL, c_q16[0])
        step = self.lib.comp_step
        return [step(cp, c) for c in c_q16]

    def compensate(self, c_ref: np.ndarray) -> np.ndarray:
        """Inverse model by the firmware's comp_step() (eqs. 4 with 5/9 and the PI inverse):
        c* (N,) deg -> q* (N,) actuator units."""
        return from_q16(np.array(self.comp_run(to_q16(c_ref).tolist()), np.int64))

    def c_range_q16(self) -> tuple[int, int]:
        """Range of f over the travel, raw Q16 deg."""
        a = self.lib.lut_eval(self.ffi.addressof(self.cal.f), self.cal.q_min_q16)
        b = self.lib.lut_eval(self.ffi.addressof(self.cal.f), self.cal.q_max_q16)
        return min(a, b), max(a, b)


# --------------------------------------------------------------------------- building
def build_table(B, f, q_min: float, q_max: float, unit: str, f_kind: str = "remain", generation: int = 1,
                n_max: int | None = None, source=None, transition=None, relax=None,
                instrument: int | None = None) -> CalibTable:
    """Sample B and f on power-of-two grids over the travel and write a table by table_write().

    B: widths floored at 0; f made strictly monotone in raw units (a flat stretch of the
    float f would otherwise have no inverse); relax: a playscope.fit.relax.Relaxation on the
    transition's output before f (layout 4), or None; transition: a transition.Transition (None or
    n = 1: the pure play, no operator written). A transition with a threshold map
    (transition.tmap) writes layout 3: g sampled on its own grid over the play centre's range
    (B's grid widened by max B/2 on each side, as many entries as the other grids), and f's
    grid widened to cover y = g(z) there too (f then acts on u). Errors: TableError when the
    writer or the loader refuses the table (e.g. |dB/dq| >= 2), OverflowError beyond the
    Q16.16 range."""
    _, lib = core()
    n_max = n_max or lib.PST_MAX_ENTRIES
    x0, step, n = grid_for(q_min, q_max, n_max)
    xs = from_q16(x0 + step * np.arange(n, dtype=np.int64))
    b_raw = np.maximum(to_q16(np.maximum(B(xs), 0.0)), 0).astype(np.int64)
    tm = None if transition is None else transition.tmap
    f_grid = tmap = None
    fx = xs
    if tm is not None:
        half = float(from_q16(int(b_raw.max()))) / 2
        z_lo, z_hi = float(xs[0]) - half, float(xs[-1]) + half
        mx0, mstep, mn = grid_for(z_lo, z_hi, n_max)
        u_raw = _strictly_increasing(to_q16(tm.fwd(from_q16(mx0 + mstep * np.arange(mn, dtype=np.int64))))
                                     .astype(np.int64), 1)
        tmap = (mx0, mstep, u_raw.tolist())
        # y = PI[g(z)] stays within g's values over B's grid (where z lives): f must cover them.
        u_b = tm.fwd(xs[[0, -1]])
        fx0, fstep, fn = grid_for(min(q_min, float(u_b[0])), max(float(xs[-1]), float(u_b[1])), n_max)
        f_grid = (fx0, fstep)
        fx = from_q16(fx0 + fstep * np.arange(fn, dtype=np.int64))
    f_raw = to_q16(f(fx)).astype(np.int64)
    f_raw = _strictly_increasing(f_raw, 1 if f_raw[-1] >= f_raw[0] else -1)
    ops = transition is not None and not transition.is_play
    r, w = (transition.r, _weights_q16_sum_one(transition.w)) if ops else (None, None)
    from .relax import table_fields

    blob = write_blob(x0, step, b_raw, f_raw, q_min, q_max, unit, f_kind, generation, r, w, source,
                      f_grid=f_grid, tmap=tmap, relax=table_fields(relax) if relax is not None else None,
                      instrument=instrument)
    return CalibTable(blob, source)


def f_inverse_error(B, f, q_min: float, q_max: float, n_max: int | None = None) -> dict:
    """The loader's own figures for a pure-play table's f^-1, computed by the firmware's
    lut_inverse_error() on the f grid build_table() writes (no transition, no map): {"f_inv_err"
    (actuator units, exact worst case of the f^-1 table against the exact inverse of the f
    table), "ceiling" (calib_precision_ceiling_q16 of the largest play, units), "ratio",
    "entries"}. Used to name by how much a table misses the precision ceiling."""
    ffi, lib = core()
    n_max = n_max or lib.PST_MAX_ENTRIES
    x0, step, n = grid_for(q_min, q_max, n_max)
    xs = from_q16(x0 + step * np.arange(n, dtype=np.int64))
    b_raw = np.maximum(to_q16(np.maximum(B(xs), 0.0)), 0).astype(np.int64)
    f_raw = to_q16(f(xs)).astype(np.int64)
    f_raw = _strictly_increasing(f_raw, 1 if f_raw[-1] >= f_raw[0] else -1)
    buf = ffi.new("int32_t[]", [int(v) for v in f_raw])
    lut = ffi.new("lut_t *")
    if lib.lut_init(lut, buf, int(n), int(x0), int(step)) != 0:
        raise TableError(None, "f's grid is not a valid table")
    err = ffi.new("int32_t *")
    if lib.lut_inverse_error(lut, lib.CALIB_DERIVED_MAX, err) != 0:
        raise TableError(None, "f is not strictly monotone on the table's grid")
    ceiling = int(lib.calib_precision_ceiling_q16(int(min(b_raw.max(), 2**31 - 1))))
    return {"f_inv_err": float(err[0]) / lib.PS_Q16_ONE, "ceiling": ceiling / lib.PS_Q16_ONE, "ratio": float(err[0]) / ceiling,
            "entries": int(n)}


def _strictly_increasing(raw: np.ndarray, sgn: int) -> np.ndarray:
    """raw made strictly monotone in direction sgn (+1 / -1) by at least one LSB per entry."""
    g = sgn * np.asarray(raw, np.int64).copy()
    for i in range(1, g.size):
        g[i] = max(g[i], g[i - 1] + 1)
    return sgn * g


def check_physical(B, f, q_min: float, q_max: float, source=None, n: int = 2001) -> None:
    """Refuse a calibration that is not a physical play model before it becomes a table: the
    float B and f sampled on n points over [q_min, q_max] must be finite, B >= 0 (one Q16 LSB
    of rounding allowed; the loader's CALIB_ERR_B_NEGATIVE), B not zero over the whole travel
    (no play measured), and f strictly monotone (eq. 9 needs f^-1; CALIB_ERR_F_NOT_MONOTONE):
    it may not turn back by more than one LSB. build_table() itself floors B and forces f
    monotone by one LSB, so without this check such a calibration would load and run with an
    error of tens of degrees. Errors: TableError naming the rule and where it breaks."""
    lsb = 1.0 / native.Q16_ONE
    q = np.linspace(q_min, q_max, n)
    b = np.asarray(B(q), float)
    c = np.asarray(f(q), float)
    if not (np.all(np.isfinite(b)) and np.all(np.isfinite(c))):
        raise TableError(source, "B or f_remain is not finite over the q range: not a table")
    if b.min() < -lsb:
        k = int(np.argmin(b))
        raise TableError(source, f"B(q) = {b[k]:.4g} < 0 at q = {q[k]:.4g} (CALIB_ERR_B_NEGATIVE): a backlash "
                         "width cannot be negative; recalibrate (the B fit is constrained to B >= 0)")
    if b.max() <= lsb:
        raise TableError(source, "B(q) is zero over the whole q range: no play was measured; check the onsets")
    d = np.diff(c)
    sgn = 1.0 if c[-1] >= c[0] else -1.0
    bad = np.flatnonzero(sgn * d < -lsb)
    if c[-1] == c[0] or bad.size:
        k = int(bad[0]) if bad.size else 0
        raise TableError(source, f"f_remain is not strictly monotone over the q range (turns back at q = "
                         f"{q[k]:.4g}; CALIB_ERR_F_NOT_MONOTONE): eq. 9 has no inverse; refit f_remain")


def _weights_q16_sum_one(w: np.ndarray) -> np.ndarray:
    """Weights rounded to Q16.16 with the rounding remainder put on w_0, so that the raw sum
    is exactly 1.0 (the loader allows 2^-8; exact keeps y on the centre line)."""
    raw = to_q16(w).astype(np.int64)
    raw[0] += native.Q16_ONE - int(raw.sum())
    return from_q16(raw)


def table_errors(tab: CalibTable, B, f, q_min: float, q_max: float, transition=None, relax=None) -> dict:
    """Measured worst-case errors of the fixed-point model against the float one.

    direct_c_deg: |playop_step - float direct model| over a sweep with reversals every 1/8 of
    the travel; comp_q: |comp_step - float compensator| on a sine reference; plus the loader's
    own bounds f_inv_err and z_err. All over the table's travel. transition: the float PI part
    (transition.Transition) the table carries, None for the pure play; relax: its travel-domain
    relaxation (relax.Relaxation) between the transition and f, or None."""
    from . import transition as T

    span = q_max - q_min
    turns = q_min + span * np.array([0, 1, 0.25, 0.875, 0.5, 0.625, 0.125, 1, 0.0])
    q = np.concatenate([np.linspace(a, b, 400) for a, b in zip(turns[:-1], turns[1:])])
    tr = transition if transition is not None else T.Transition.play()
    c_fix = tab.predict(q)
    if relax is not None and not relax.is_identity:  # c = f(R[PI(play(q))]); the compensator runs R^-1 on f^-1(c*)
        c_flt = f(relax.direct(tr.direct(model.play_operator(q, B))))
    else:
        c_flt = T.direct_chain(q, B, tr, f)
    fx = f(np.linspace(q_min, q_max, 64))
    lo, hi = float(min(fx)), float(max(fx))
    c_ref = lo + (hi - lo) * (0.5 + 0.45 * np.sin(np.linspace(0, 6 * np.pi, 3000)))
    sign = 1 if f(np.array([q_max]))[0] > f(np.array([q_min]))[0] else -1
    f_inv = T.f_inverse(f, q_min - span, q_max + span)
    if relax is not None and not relax.is_identity:
        f_inv0 = f_inv
        rx = (float(tab.cal.relax.x_min_q16) / native.Q16_ONE, float(tab.cal.relax.x_max_q16) / native.Q16_ONE)  # the board's clamp
        f_inv = lambda c: relax.inverse(f_inv0(c), clip=rx)  # noqa: E731
    if tr.is_play and tr.tmap is None and (relax is None or relax.is_identity):
        q_flt = model.compensator(c_ref, B, f_inv, sign)
    else:
        q_flt = T.compensate_chain(c_ref, B, tr, f_inv, sign)
    q_flt = np.clip(q_flt, q_min, q_max)
    q_fix = tab.compensate(c_ref)
    dq = np.abs(q_fix - q_flt)
    if relax is not None and not relax.is_identity:
        # At a reversal of z* the B/2 step may fall one tick apart: R^-1's output turns where the
        # float and the board's (within 1 raw) differ in sign of a hair. Compared within a tick.
        dq[1:-1] = np.minimum(dq[1:-1], np.minimum(np.abs(q_fix[1:-1] - q_flt[:-2]), np.abs(q_fix[1:-1] - q_flt[2:])))
    return {"direct_c_deg_max": float(np.max(np.abs(c_fix - c_flt))),
            "comp_q_max": float(np.max(dq[1:])),
            "f_inv_err": float(tab.cal.f_inv_err_q16) / native.Q16_ONE,
            "z_err": float(tab.cal.z_err_q16) / native.Q16_ONE}


def check_precision(tab: CalibTable, errors: dict, f, q_min: float, q_max: float, source=None) -> None:
    """Refuse a table whose measured fixed-point error is above the loader's precision ceiling
    (calib.h, CALIB_ERR_PRECISION; docs/firmware.md "Precision ceiling"): the compensator's
    |q*_fixed - q*_float| and the direct model's |c_fixed - c_float| / max|f'| (the q that
    error corresponds to) must each stay within calib_precision_ceiling_q16(B_max), i.e. 1/16
    of the largest play, never below 16 raw. The loader holds its exactly computed errors of
    the derived tables to the same figure; this check adds what only the host can see, the
    sampling of the float model on the grids. errors: table_errors()'s dict. Errors:
    TableError naming the figure and what to do."""
    ceiling = float(tab.cal.precision_ceiling_q16) / native.Q16_ONE
    qq = np.linspace(q_min, q_max, 2001)
    slope = float(np.max(np.abs(np.diff(np.asarray(f(qq), float)) / np.diff(qq))))
    checks = [("|q*_fixed - q*_float|", errors["comp_q_max"], ceiling, ""),
              ("|c_fixed - c_float|", errors["direct_c_deg_max"], ceiling * slope,
               f" (the ceiling times max|f'| = {slope:.4g} deg per unit)")]
    for name, got, lim, why in checks:
        if not got <= lim:  # NaN fails too
            raise TableError(source, f"fixed-point error {name} = {got:.3g} is above the precision ceiling "
                             f"{lim:.3g}{why}, 1/16 of the largest play (CALIB_ERR_PRECISION): the table would "
                             "add an error comparable to the play it corrects; use more --entries or a "
                             "smoother f_remain (recalibrate)")


# --------------------------------------------------------------------------- test tables
def test_vector(tab: CalibTable, n: int = 200) -> list[int]:
    """c* reference (raw Q16): two sine periods with reversals of varying amplitude over 90 %
    of f's range, for the board-versus-host compensator check of `playscope flash`."""
    lo, hi = tab.c_range_q16()
    mid, amp = (lo + hi) / 2, 0.45 * (hi - lo)
    return [int(mid + amp * math.sin(2 * math.pi * 2 * k / n) * (0.6 + 0.4 * math.cos(7.0 * k / n)))
            for k in range(n)]


def builtin_table(n: int | None = None, q0: float = -4.0, step_log2: int = 11, generation: int = 1) -> bytes:
    """A valid table of n entries per grid (default PST_MAX_ENTRIES; B bump, cubic f_remain),
    no transition: for tests, benches and a first flash before any calibration. Laid out by
    table_write()."""
    one = native.Q16_ONE
    n = native.MAX_ENTRIES if n is None else n
    step = 2 ** step_log2
    x0 = int(q0 * one)
    qs = [(x0 + i * step) / one for i in range(n)]
    b = [int(round((0.4 + 0.3 * math.exp(-q * q / 2)) * one)) for q in qs]
    f = [int(round((10 * q + 0.3 * q ** 3) * one)) for q in qs]
    return write_blob(x0, step, b, f, q0, (x0 + (n - 1) * step) / one, "mm", "remain", generation)
