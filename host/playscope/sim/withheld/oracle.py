"""Identifiable in situ? An effect-free reference fit written apart from the diagnosis.

A planted effect can only be found by a gap-based diagnosis if the paper's model, refitted in situ
(its B(q) and its f_remain free), cannot absorb it. This oracle answers that question with its
own, flexible, effect-free model and its own fitter (nothing shared with playscope.diagnose):
  clearance half-width h(q) piecewise linear at 9 knots over the q range (evaluated at q),
  c = Chebyshev series of degree 15 in the normalised carrier position (linear least squares),
  the 9 knots by scipy.optimize.least_squares (soft-l1 free, bounded 0..0.6 span).
The effect is called identifiable when this model's judged RMSE r stands out of the noise-only RMSE
n (measured minus the generator's noise-free reading) by what the protocol counts as a gap: r - n
at least the practical margin max(8 % of r, 0.05 deg), r > 1.5 n, and an excess sqrt(r^2 - n^2) of
at least 0.1 deg (the thresholds of docs/diagnosis.md, restated here as numbers, not imported).
Otherwise refitting B and f absorbs the effect, or what is left is below what the protocol calls a
gap. Measured on nulls: r - n = 0.016-0.031 deg (the oracle's own misfit).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev
from scipy.optimize import least_squares

N_HALF_KNOTS = 9
CHEB_DEG = 15
ORACLE_HZ = 100.0


def _carrier(q: np.ndarray, half: np.ndarray) -> np.ndarray:
    x = float(q[0])
    out = np.empty(q.size)
    for k, (qk, hk) in enumerate(zip(q.tolist(), half.tolist())):
        if x < qk - hk:
            x = qk - hk
        elif x > qk + hk:
            x = qk + hk
        out[k] = x
    return out


def oracle_grid(t_q: np.ndarray, q: np.ndarray, hz: float = ORACLE_HZ) -> tuple[np.ndarray, np.ndarray]:
    """The oracle's time grid: hz plus every sharp turning point of q (the clearance output depends
    on the extremes of q, which a plain decimation would clip when q turns without a hold).
    t_q, q: actuator log (s, mm). Returns (tg, qg)."""
    dq = np.sign(np.diff(q))
    turns = np.flatnonzero(dq[1:] * dq[:-1] < 0) + 1
    tg = np.union1d(np.arange(t_q[0], t_q[-1], 1 / hz), t_q[turns])
    return tg, np.interp(tg, t_q, q)


def half_width_knots(lo: float, hi: float) -> np.ndarray:
    """q positions (mm) of the clearance half-width's N_HALF_KNOTS knots over [lo, hi]."""
    return np.linspace(lo, hi, N_HALF_KNOTS)


def _normalised(x, lo: float, hi: float):
    span = max(hi - lo, 1e-9)
    return np.clip((x - 0.5 * (lo + hi)) / (0.5 * span + 1e-9), -1.2, 1.2) / 1.2


def map_columns(x: np.ndarray, lo: float, hi: float, inside: tuple[float, float] | None = None) -> np.ndarray:
    """Design matrix (N, CHEB_DEG + 1) of the bending map: Chebyshev columns of the carrier
    position x (mm) normalised over the q range [lo, hi] (clipped at 1.2 of the half span).
    inside: None (the effect-free oracle's map), or the carrier range (x_lo, x_hi) the map was
    fitted on, beyond which the columns continue along their tangent at the edge (a degree-15 series
    is not extrapolated: 0.05 mm beyond its data it was measured 0.4-0.9 deg off)."""
    u = _normalised(x, lo, hi)
    A = chebyshev.chebvander(u, CHEB_DEG)
    if inside is not None:
        ue = _normalised(np.asarray(inside, float), lo, hi)
        D = np.zeros((CHEB_DEG + 1, CHEB_DEG + 1))   # column j: Chebyshev coefficients of T_j'
        for j in range(1, CHEB_DEG + 1):
            d = chebyshev.chebder(np.eye(CHEB_DEG + 1)[j])
            D[:d.size, j] = d
        for e, out in ((ue[0], u < ue[0]), (ue[1], u > ue[1])):
            if out.any():
                Ve = chebyshev.chebvander(np.array([e]), CHEB_DEG)
                A[out] = Ve + (u[out] - e)[:, None] * (Ve @ D)
    return A


def linear_map(A: np.ndarray, y: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """Chebyshev coefficients (CHEB_DEG + 1,) of the map by linear least squares on rows sel
    (bool, finite y only)."""
    m = sel & np.isfinite(y)
    coef, *_ = np.linalg.lstsq(A[m], y[m], rcond=None)
    return coef


def fit_half_widths(res, starts, span: float, max_nfev: int = 60, extra_bounds=(), ftol: float = 1e-8):
    """The half-width knots (mm) by scipy.optimize.least_squares of the residual function res
    (knots -> residual vector), bounded 0..0.6 span, from each start in turn; the lowest cost wins.
    extra_bounds: (lo, hi) of parameters appended after the knots (each start then carries them);
    ftol: least_squares' relative cost tolerance."""
    lb = [0.0] * N_HALF_KNOTS + [b[0] for b in extra_bounds]
    ub = [0.6 * span] * N_HALF_KNOTS + [b[1] for b in extra_bounds]
    best = None
    for h0 in starts:
        r = least_squares(res, h0, bounds=(lb, ub) if extra_bounds else (0.0, 0.6 * span), diff_step=1e-3,
                          max_nfev=max_nfev, ftol=ftol)
        if best is None or r.cost < best.cost:
            best = r
    return best


def effect_free_fit(t_q: np.ndarray, q: np.ndarray, t_y: np.ndarray, y: np.ndarray, fit_sel: np.ndarray,
                    judge_sel: np.ndarray) -> dict:
    """Fit the effect-free model on samples fit_sel of (t_y, y), judge on judge_sel.
    t_q, q: actuator log (mm); t_y, y: sensor samples (deg); *_sel: bool (Ny,).
    Returns {"rmse_fit_deg", "rmse_judged_deg", "half_knots_mm"}."""
    tg, qg = oracle_grid(t_q, q)
    lo, hi = float(qg.min()), float(qg.max())
    span = max(hi - lo, 1e-9)
    kn = half_width_knots(lo, hi)
    ok = np.isfinite(y)

    def columns(h):
        x = _carrier(qg, np.interp(qg, kn, h))
        return map_columns(np.interp(t_y, tg, x), lo, hi)

    def solve(h, sel):
        A = columns(h)
        return A @ linear_map(A, y, sel)

    def res(h):
        return (y - solve(h, fit_sel))[fit_sel & ok]

    best = fit_half_widths(res, [np.full(N_HALF_KNOTS, h0 * span) for h0 in (0.06, 0.2)], span)
    pred = solve(best.x, fit_sel)

    def rms(sel):
        e = (y - pred)[sel & ok]
        return float(np.sqrt(np.mean(e * e))) if e.size else float("nan")

    return {"rmse_fit_deg": rms(fit_sel), "rmse_judged_deg": rms(judge_sel), "half_knots_mm": best.x.tolist()}


def noise_only_rmse(session, judge_sel: np.ndarray) -> float:
    """RMSE (deg) of the measurement noise alone on judge_sel: the record minus the generator's
    noise-free reading (session.meta["clean_reading_deg"])."""
    e = (session.distal["c_deg"] - session.meta["clean_reading_deg"])[judge_sel]
    return float(np.sqrt(np.mean(e * e)))


def identifiable(session, fit_sel: np.ndarray, judge_sel: np.ndarray, margin_frac: float = 0.08,
                 margin_abs: float = 0.05, ratio: float = 1.5, excess_min: float = 0.1,
                 free: dict | None = None) -> dict:
    """Is the planted effect of a generator session identifiable in situ? fit_sel/judge_sel: bool
    over the session's sensor samples; free: effect_free_fit's result on the same selections, when
    already computed. Returns {"identifiable", "rmse_effect_free_deg", "rmse_noise_only_deg"}."""
    t_y, y = session.distal["t_s"], session.distal["c_deg"]
    f = free if free is not None else effect_free_fit(session.encoder["t_s"], session.encoder["q"], t_y, y,
                                                      fit_sel, judge_sel)
    noise = noise_only_rmse(session, judge_sel)
    r = f["rmse_judged_deg"]
    gap = (r - noise >= max(margin_frac * r, margin_abs) and r > ratio * noise
           and np.sqrt(max(r * r - noise * noise, 0.0)) >= excess_min)
    return {"identifiable": bool(gap),
            "rmse_effect_free_deg": r, "rmse_noise_only_deg": noise}
