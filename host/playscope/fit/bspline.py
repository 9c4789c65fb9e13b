"""Robust cubic B-splines on an interval: clamped knots, the penalised (optionally monotone)
least-squares fit with Huber weights, and SplineFn, the evaluable curve every fit returns
(B(q), f_remain, the calibration file's splines).

Units: those of the data fitted (x: actuator units).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline
from scipy.optimize import lsq_linear


def clamped_knots(lo: float, hi: float, n_ctrl: int, degree: int = 3) -> np.ndarray:
    """Knot vector of a clamped B-spline with n_ctrl control points spread evenly over
    [lo, hi]: degree+1 repeated knots at each end and n_ctrl-degree-1 interior ones."""
    inner = np.linspace(lo, hi, n_ctrl - degree + 1)
    return np.concatenate([[lo] * degree, inner, [hi] * degree])


def design_dense(x: np.ndarray, t: np.ndarray, n_ctrl: int) -> np.ndarray:
    """Dense cubic B-spline design matrix (x.size, n_ctrl) on knots t, x within [t[3], t[-4]]:
    the spline with the identity as coefficients evaluated at x. The same basis values as
    BSpline.design_matrix(x, t, 3).toarray() (bit for bit: each column is one basis function
    times 1), without building the sparse matrix first: 2-3x faster on 20,000-40,000 points
    (4-20 coefficients). scipy's own evaluation, not a copy of its recurrence: a vectorised de
    Boor written here was measured 10-20 % faster on 30,000 points (8 and 16 coefficients), too
    little to keep a second spline code beside scipy's."""
    return BSpline(t, np.eye(n_ctrl), 3)(x)


def _diff_penalty(n: int, order: int = 2) -> np.ndarray:
    return np.diff(np.eye(n), order, axis=0)


def _slope_matrix(t: np.ndarray, n_ctrl: int, degree: int = 3) -> np.ndarray:
    """G (n_ctrl-1, n_ctrl): the coefficients of s' (a degree-1 lower B-spline on the same
    knots) are G @ coef, d_i = k (c_(i+1) - c_i) / (t_(i+k+1) - t_(i+1)) (de Boor, A Practical
    Guide to Splines, ch. X). |d_i| <= m bounds |s'| <= m everywhere, since s' is a convex
    combination of its coefficients."""
    G = np.zeros((n_ctrl - 1, n_ctrl))
    for i in range(n_ctrl - 1):
        h = t[i + degree + 1] - t[i + 1]
        G[i, i], G[i, i + 1] = -degree / h, degree / h
    return G


def robust_spline(x: np.ndarray, y: np.ndarray, n_ctrl: int, lo: float, hi: float, smooth: float = 1e-3,
                  monotone: int = 0, iters: int = 15, huber_k: float = 1.345, sigma: np.ndarray | None = None,
                  lower: float | None = None, max_slope: float | None = None, min_slope: float = 0.0):
    """Robust cubic B-spline fit y ~ s(x) with n_ctrl control points on [lo, hi].

    Least squares with a small second-difference penalty on the coefficients (P-spline,
    Eilers & Marx) so that sparse samples (few reversals) still give a well-posed fit,
    and iteratively reweighted with Huber weights on a MAD scale so that a spurious onset
    does not bend the curve. sigma (M,): each sample's own standard error; the weights are
    then 1 / (sigma^2 + s^2), s^2 the scatter the sigmas do not explain (MAD of the residuals
    less the median sigma^2, a random-effects weighting), times the Huber weight of the
    standardised residual. monotone=+1/-1 constrains the coefficients to be
    non-decreasing/non-increasing (sufficient for a monotone spline), solved by
    scipy.optimize.lsq_linear; min_slope >= 0 (y per x) then holds |s'| >= min_slope on [lo, hi]:
    s' is the quadratic spline with coefficients 3 (c_{j+1} - c_j) / (t_{j+4} - t_{j+1}) (de Boor,
    "A Practical Guide to Splines", X (12)), a convex combination of them at every x, so
    bounding each difference by min_slope (t_{j+4} - t_{j+1}) / 3 bounds s' (the tables' f^-1
    needs f's slope away from 0: calibration.loadable_f). lower / max_slope: coefficients >= lower (so s >= lower) and
    |s'| <= max_slope (through the derivative's coefficients, _slope_matrix), a quadratic
    programme solved by scipy.optimize.minimize (SLSQP) from the unconstrained solution.
    x, y: (M,). Returns (BSpline, weights (M,) normalised to max 1).
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    t = clamped_knots(lo, hi, n_ctrl)
    A = design_dense(np.clip(x, lo, hi), t, n_ctrl)
    D = _diff_penalty(n_ctrl)
    sig2 = None if sigma is None else np.asarray(sigma, float) ** 2
    base = np.ones(x.size) if sig2 is None else 1.0 / np.maximum(sig2 + np.median(sig2), 1e-300)
    base = base / base.mean()
    scale_A = np.trace(A.T @ (A * base[:, None])) / n_ctrl
    lam = smooth * max(scale_A, 1e-12)
    w = base.copy()
    # Monotone: coef = T @ theta with theta[1:] >= 0 (sign-adjusted cumulative sum).
    if monotone:
        T = np.tril(np.ones((n_ctrl, n_ctrl))) * np.where(np.arange(n_ctrl) == 0, 1.0, float(monotone))[None, :]
        lb = np.r_[-np.inf, float(min_slope) * (t[4:n_ctrl + 3] - t[1:n_ctrl]) / 3.0]
    constrained = lower is not None or max_slope is not None
    if constrained:
        from scipy.optimize import LinearConstraint, minimize

        cons = [LinearConstraint(_slope_matrix(t, n_ctrl), -max_slope, max_slope)] if max_slope is not None else []
        bounds = [(lower, None)] * n_ctrl if lower is not None else None
    coef = None
    for _ in range(iters):
        sw = np.sqrt(w)
        M = np.vstack([A * sw[:, None], np.sqrt(lam) * D])
        rhs = np.r_[y * sw, np.zeros(D.shape[0])]
        if monotone:
            th = lsq_linear(M @ T, rhs, bounds=(lb, np.full(n_ctrl, np.inf)), method="bvls").x
            new = T @ th
        else:
            new = np.linalg.lstsq(M, rhs, rcond=None)[0]
            if constrained:
                H, g = M.T @ M, M.T @ rhs
                x0 = np.maximum(new, lower) if lower is not None else new
                new = minimize(lambda c: 0.5 * c @ H @ c - g @ c, x0, jac=lambda c: H @ c - g, method="SLSQP",
                               bounds=bounds, constraints=cons, options={"maxiter": 200, "ftol": 1e-12}).x
        r = y - A @ new
        s = 1.4826 * np.median(np.abs(r - np.median(r))) + 1e-12
        if sig2 is None:
            w = np.minimum(1.0, huber_k * s / np.maximum(np.abs(r), 1e-300))
        else:
            var = sig2 + max(s * s - float(np.median(sig2)), 1e-6 * s * s)
            z = np.abs(r) / np.sqrt(var)
            w = np.minimum(1.0, huber_k / np.maximum(z, 1e-300)) / var
            w = w / w.max()
        if coef is not None and np.max(np.abs(new - coef)) < 1e-10 * (1 + np.max(np.abs(new))):
            coef = new
            break
        coef = new
    return BSpline(t, coef, 3, extrapolate=False), w


class SplineFn:
    """A spline held constant beyond [lo, hi] (B) or continued linearly with its end
    slopes (f, so it stays strictly monotone for tables and inverses). Callable on arrays."""

    def __init__(self, spl: BSpline, lo: float, hi: float, linear_ends: bool = False, floor: float | None = None):
        self.spl, self.lo, self.hi, self.linear_ends, self.floor = spl, lo, hi, linear_ends, floor
        d = spl.derivative()
        self.s_lo, self.s_hi = float(d(lo)), float(d(hi - 1e-12 * max(1, abs(hi))))
        self.y_lo, self.y_hi = float(spl(lo)), float(spl(hi - 1e-12 * max(1, abs(hi))))

    def __call__(self, x):
        x = np.asarray(x, float)
        y = self.spl(np.clip(x, self.lo, np.nextafter(self.hi, -np.inf)))
        if self.linear_ends:
            y = np.where(x < self.lo, self.y_lo + self.s_lo * (x - self.lo), y)
            y = np.where(x > self.hi, self.y_hi + self.s_hi * (x - self.hi), y)
        if self.floor is not None:
            y = np.maximum(y, self.floor)
        return y

    def to_json(self) -> dict:
        return {"kind": "bspline", "degree": 3, "knots": self.spl.t.tolist(), "coef": self.spl.c.tolist(),
                "range": [self.lo, self.hi], "ends": "linear" if self.linear_ends else "hold",
                "floor": self.floor}

    @classmethod
    def from_json(cls, d: dict) -> "SplineFn":
        spl = BSpline(np.asarray(d["knots"], float), np.asarray(d["coef"], float), int(d["degree"]), extrapolate=False)
        return cls(spl, d["range"][0], d["range"][1], d.get("ends") == "linear", d.get("floor"))
