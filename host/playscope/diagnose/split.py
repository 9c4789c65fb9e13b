"""How a record is split for the diagnosis (paper protocol): fit / validation / test.

The paper calibrates on an excitation and judges on a separate test motion; `diagnose` accepts
exactly that (a calibration record and a test record). In a single record the judged parts must
stay inside the q range the fit saw, otherwise the "held-out" error is extrapolation (a record
whose excitation ramps over the range, split in time, fits one half of the range and judges the
other). Rule, in order:
  1. time-ordered: fit on the first `fractions[0]`, select on the next `fractions[1]`, test on
     the rest -- used when both judged parts lie inside the fitted q range;
  2. interleaved blocks: the record is cut into 12 equal-time blocks assigned F V F T F F V F T F V T
     (6 fit, 3 validation, 3 test) -- used when (1) fails and (2) passes;
  3. by range: (2) with the judged rows outside the fitted q range dropped, with a warning.
"Inside" = at most 1 % of the judged rows farther than 2 % of the span outside [min, max] of the
fitted q. Also says what a short or thin record cannot decide (few reversals, repeated samples).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .fitmodel import Data

PATTERN = "FVFTFFVFTFVT"
OUTSIDE_TOL = 0.02      # of the q span
OUTSIDE_MAX = 0.01      # share of judged rows allowed outside


@dataclass
class Split:
    """Row masks (Nm,) of one record and how they were chosen."""

    fit: np.ndarray
    val: np.ndarray
    test: np.ndarray
    method: str
    warnings: list = field(default_factory=list)

    def summary(self) -> dict:
        return {"method": self.method, "rows": {"fit": int(self.fit.sum()), "validation": int(self.val.sum()),
                                                 "test": int(self.test.sum())}, "warnings": list(self.warnings)}


def q_at_rows(data: Data) -> np.ndarray:
    """Actuator position (mm) at each measurement row (Nm,)."""
    return np.interp(data.t_m - data.t_delay_s, data.t_int, data.q_int)


def outside_share(data: Data, fit: np.ndarray, judged: np.ndarray) -> tuple[float, np.ndarray]:
    """(share of judged rows outside the fitted q range, bool mask of those rows)."""
    q = q_at_rows(data)
    if not judged.any():
        return 0.0, judged.copy()
    if not fit.any():
        return 1.0, judged.copy()
    lo, hi = q[fit].min(), q[fit].max()
    tol = OUTSIDE_TOL * max(data.q_hi - data.q_lo, 1e-9)
    out = judged & ((q < lo - tol) | (q > hi + tol))
    return float(out.sum() / judged.sum()), out


def _time_ordered(data: Data, fractions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = data.t_m
    a = t[0] + fractions[0] * (t[-1] - t[0])
    b = t[0] + (fractions[0] + fractions[1]) * (t[-1] - t[0])
    return t < a, (t >= a) & (t < b), t >= b


def _blocks(data: Data) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = data.t_m
    k = np.clip(((t - t[0]) / max(t[-1] - t[0], 1e-9) * len(PATTERN)).astype(int), 0, len(PATTERN) - 1)
    lab = np.array(list(PATTERN))[k]
    return lab == "F", lab == "V", lab == "T"


def choose_split(data: Data, fractions=(0.5, 0.25, 0.25)) -> Split:
    """Split one record into fit / validation / test (module doc). fractions (fit, validation,
    test) of the duration for the time-ordered split; test 0 when a separate test record judges
    (then the blocks are fit / validation only). Returns a Split."""
    if fractions[2] <= 0:
        f, v, te = _time_ordered(data, fractions)
        sv, ov = outside_share(data, f, v)
        if sv <= OUTSIDE_MAX:
            return Split(f, v, te, "time-ordered")
        f, v, te = _blocks(data)
        v, f = v | te, f
        te = np.zeros_like(f)
        sv, ov = outside_share(data, f, v)
        if sv <= OUTSIDE_MAX:
            return Split(f, v, te, "interleaved blocks",
                         ["a time-ordered split would judge q outside the fitted range: interleaved blocks used"])
        return Split(f, v & ~ov, te, "by range",
                     [f"{100 * sv:.0f} % of the validation rows lie outside the fitted q range: dropped"])
    f, v, te = _time_ordered(data, fractions)
    sv, _ = outside_share(data, f, v)
    st, _ = outside_share(data, f, te)
    if sv <= OUTSIDE_MAX and st <= OUTSIDE_MAX:
        return Split(f, v, te, "time-ordered")
    f, v, te = _blocks(data)
    sv, ov = outside_share(data, f, v)
    st, ot = outside_share(data, f, te)
    if sv <= OUTSIDE_MAX and st <= OUTSIDE_MAX:
        return Split(f, v, te, "interleaved blocks",
                     ["a time-ordered split would judge q outside the fitted range: interleaved blocks used"])
    w = (f"interleaved blocks still judge outside the fitted q range ({100 * sv:.0f} % of validation, "
         f"{100 * st:.0f} % of test rows): those rows are dropped (judged by range only)")
    return Split(f, v & ~ov, te & ~ot, "by range", [w])


def count_reversals(data: Data, frac: float = 0.05) -> int:
    """Direction reversals of q larger than frac of the q span (a turn counts once q has come
    back by that much from its extreme since the last turn)."""
    q = data.q_int
    thr = frac * max(data.q_hi - data.q_lo, 1e-9)
    n, d = 0, 0
    hi = lo = float(q[0])
    for v in q.tolist():
        hi, lo = max(hi, v), min(lo, v)
        if d != -1 and hi - v > thr:
            n += d == 1
            d, lo = -1, v
        elif d != 1 and v - lo > thr:
            n += d == -1
            d, hi = 1, v
    return int(n)


def thin_record(data: Data) -> tuple[Data, list[str]]:
    """Short and thin records: drop repeated sensor samples (a sensor slower than the log repeats
    its last value; keeping the repeats would weight stale values and fake a delay) and say what
    cannot be decided. Returns (data with repeats removed, list of statements)."""
    notes = []
    y = data.y_m
    rep = np.r_[False, y[1:] == y[:-1]] & np.isfinite(y)
    if rep.mean() > 0.3:
        keep = ~rep
        dt = float(np.median(np.diff(data.t_m[keep]))) if keep.sum() > 2 else float("nan")
        notes.append(f"{100 * rep.mean():.0f} % of the sensor samples repeat the previous one: kept the "
                     f"{int(keep.sum())} fresh ones (effective rate {1 / dt:.1f} Hz); a delay or lag "
                     f"shorter than ~{dt / 2:.3f} s cannot be decided")
        data = replace(data, t_m=data.t_m[keep], y_m=y[keep])
    n = count_reversals(data)
    if n < 5:
        notes.append(f"only {n} reversals: B(q) is sampled at {n} positions; effects that act after each "
                     "reversal (smooth_transition, asymmetric_backlash, viscous_hysteresis, handeye_direction) "
                     "cannot be told apart, and a kept one is indicative only")
    if data.t_m[-1] - data.t_m[0] < 30.0:
        notes.append(f"record of {data.t_m[-1] - data.t_m[0]:.0f} s: drift (a trend over minutes) cannot be decided")
    return data, notes
