"""Textbook hysteresis models a user would pick instead of ours: the peers of the in-situ
evaluation (playscope.evaluate.insitu_split). Fitted by scipy, run in double precision from the record's start.

Units: q in actuator units (mm of cable or deg of command), c in deg. Every model here is
rate-independent: its output depends on the path of q only, so it can be fitted on frames
decimated from the calibration part and run on the full-rate record.

Both models normalise the input with the calibration part's range, x = (q - q_mid) / q_half
(q_mid, q_half = middle and half-span of q over the calibration samples), so that the fit is
well conditioned whatever the actuator unit; the parameters are reported in raw units.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import exp, expm1, log1p

import numpy as np
from scipy.optimize import least_squares, lsq_linear

GPI_OPERATORS = 16
GPI_POLY_DEGREE = 3


# --------------------------------------------------------------------------- play operators
# The classical play operators are the project's one kernel (transition.play_ops: Krasnosel'skii
# & Pokrovskii 1989; Brokate & Sprekels 1996, eq. 2.1): the peer and ours run the same operator,
# so the comparison is of the models, not of two implementations.
from .transition import largest_excursion  # noqa: E402  (one rule for both models' threshold spans)
from .transition import play_ops as play_operators  # noqa: E402


def gpi_thresholds(q_cal: np.ndarray, n: int = GPI_OPERATORS) -> np.ndarray:
    """The threshold rule of the generalized PI peer, the same for every record: the
    midpoints of n equal bins of [0, E/2], E = the largest excursion of q between reversals
    in the calibration samples (largest_excursion). A play operator of threshold r only
    closes a loop on a stroke longer than 2 r, so the weight of a wider one cannot be told
    from the polynomial's linear term on these data (on a ramp excitation of short strokes
    such operators just follow q -+ r and the fit breaks on the return sweep). On a record
    whose strokes span the whole travel (the catheter files) E is the span of q.
    Returns (n,) increasing, actuator units."""
    return (np.arange(n) + 0.5) / n * 0.5 * largest_excursion(q_cal)


def _norm(q_cal: np.ndarray) -> tuple[float, float]:
    lo, hi = float(np.min(q_cal)), float(np.max(q_cal))
    return 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-12)


# --------------------------------------------------------------------------- generalized PI
def _gpi_columns(q: np.ndarray, n_ops: int):
    """What both generalized PI fits regress on, for a path q (F,) in actuator units: (q_mid,
    q_half (the path's centre and half span), r (n_ops,) thresholds (gpi_thresholds), P (F, n_ops)
    the play operators' outputs centred and scaled by the half span, so their weights come out
    in deg per half span, x (F,) = (q - q_mid) / q_half)."""
    q_mid, q_half = _norm(q)
    r = gpi_thresholds(q, n_ops)
    return q_mid, q_half, r, (play_operators(q, r) - q_mid) / q_half, (q - q_mid) / q_half


@dataclass
class GeneralizedPI:
    """Generalized Prandtl-Ishlinskii model with a polynomial input function:

        c[k] = sum_{i=0}^{n-1} w_i F_{r_i}[q][k] + a_0 + a_1 x + a_2 x^2 + a_3 x^3,   w_i >= 0,

    F_r the classical play operator (play_operators), x = (q - q_mid)/q_half. The memoryless
    polynomial makes the loops asymmetric and the centre line curved (the "generalized" and
    "modified" PI models: Al Janaideh, Rakheja & Su, IEEE/ASME Trans. Mechatronics 16(4)
    734-744, 2011; Gu, Zhu & Su, IEEE Trans. Ind. Electron. 61(3) 1583-1595, 2014, whose
    polynomial input function this is). Thresholds by gpi_thresholds(); weights and
    coefficients by bounded linear least squares (scipy.optimize.lsq_linear), the weights
    held >= 0 so the operator sum stays monotone in each branch.

    r: (n,) thresholds, actuator units; w: (n,) deg per actuator unit; poly: (4,) deg,
    coefficients of 1, x, x^2, x^3.
    """

    r: np.ndarray
    w: np.ndarray
    poly: np.ndarray
    q_mid: float
    q_half: float

    @classmethod
    def fit(cls, q: np.ndarray, c: np.ndarray, n_ops: int = GPI_OPERATORS) -> "GeneralizedPI":
        """Fit on one calibration path (q, c): (F,) each, in time order, finite."""
        q, c = np.asarray(q, float), np.asarray(c, float)
        q_mid, q_half, r, P, x = _gpi_columns(q, n_ops)
        A = np.column_stack([P, np.vander(x, GPI_POLY_DEGREE + 1, increasing=True)])
        lb = np.r_[np.zeros(n_ops), np.full(GPI_POLY_DEGREE + 1, -np.inf)]
        sol = lsq_linear(A, c, bounds=(lb, np.inf), method="bvls")
        th = sol.x
        w = np.maximum(th[:n_ops], 0.0) / q_half
        poly = th[n_ops:].copy()
        poly[0] -= float(np.sum(w * q_mid))  # the operators enter raw, the offset absorbs q_mid
        return cls(r, w, poly, q_mid, q_half)

    def predict(self, q: np.ndarray) -> np.ndarray:
        """c (N,) deg over the path q (N,), every operator centred at q[0]."""
        q = np.asarray(q, float)
        x = (q - self.q_mid) / self.q_half
        return play_operators(q, self.r) @ self.w + np.vander(x, GPI_POLY_DEGREE + 1, increasing=True) @ self.poly

    def params(self) -> dict:
        """The fitted parameters as a JSON-ready dict (thresholds in actuator units, weights and
        coefficients in deg)."""
        return {"thresholds": self.r.tolist(), "weights_deg_per_unit": self.w.tolist(),
                "poly_deg": self.poly.tolist(), "poly_variable": "x = (q - q_mid)/q_half",
                "q_mid": self.q_mid, "q_half": self.q_half,
                "active_operators": int(np.sum(self.w > 0))}


# --------------------------------------------------------------------------- generalized PI, increasing
GPI_INC_EPS = 1e-3  # m' floor: this fraction of c's half span per unit x (x spans 2)


def _bernstein_int(x: np.ndarray) -> np.ndarray:
    """(N, 3): integrals from -1 to x of the quadratic Bernstein basis on [-1, 1]; with
    non-negative coefficients their sum is a cubic whose slope is >= 0 on [-1, 1]."""
    t = (np.asarray(x, float) + 1.0) / 2.0
    B3 = np.column_stack([t ** 3, 3 * t ** 2 * (1 - t), 3 * t * (1 - t) ** 2, (1 - t) ** 3][::-1])
    return np.column_stack([2.0 / 3.0 * B3[:, k + 1:].sum(axis=1) for k in range(3)])


@dataclass
class IncreasingGPI:
    """The generalized PI (GeneralizedPI) with its memoryless cubic held increasing, so that the
    whole model is strictly increasing in q for every play state and has an inverse:

        c = sum_i w_i F_{r_i}[q] + m(x),   w_i >= 0,   m(x) = a_0 + sum_k beta_k I_k(x),   beta_k >= eps,

    I_k the integrals of the quadratic Bernstein basis on [-1, 1] (a sufficient condition for
    m' > 0 there), m continued linearly with its end slopes beyond [-1, 1] (so it stays
    increasing on a record with a wider travel). One bounded linear least squares (lsq_linear).
    The fitted peer's cubic is not increasing on any development record (right after a
    reversal every play of r > 0 is stuck and only the cubic moves), so the peer itself has no
    inverse; this is its invertible form in its own structure. The board's table layout
    (c = f(PI[play(q)])) cannot carry an additive m(q); its invertible form there is the
    modified PI with a monotone output (ModifiedPI(monotone=True), the pi_const family)."""

    r: np.ndarray
    w: np.ndarray
    m: np.ndarray  # (4,): a_0, beta_0..2 (deg)
    q_mid: float
    q_half: float

    @classmethod
    def fit(cls, q: np.ndarray, c: np.ndarray, n_ops: int = GPI_OPERATORS) -> "IncreasingGPI":
        """Fit on one calibration path (q, c): (F,) each, in time order, finite."""
        q, c = np.asarray(q, float), np.asarray(c, float)
        q_mid, q_half, r, P, x = _gpi_columns(q, n_ops)
        eps = GPI_INC_EPS * 0.5 * max(float(np.ptp(c)), 1e-12)
        A = np.column_stack([P, np.ones_like(x), _bernstein_int(x)])
        lb = np.r_[np.zeros(n_ops), -np.inf, np.full(3, eps)]
        th = lsq_linear(A, c, bounds=(lb, np.inf), method="bvls").x
        w = np.maximum(th[:n_ops], 0.0) / q_half
        m = th[n_ops:].copy()
        m[0] -= float(np.sum(w * q_mid))
        return cls(r, w, m, q_mid, q_half)

    def memoryless(self, x: np.ndarray) -> np.ndarray:
        """m(x) deg, linear with the end slopes beyond [-1, 1]."""
        x = np.asarray(x, float)
        xc = np.clip(x, -1.0, 1.0)
        y = self.m[0] + _bernstein_int(xc) @ self.m[1:]
        b = self.m[1:]
        return y + np.where(x < -1, b[0] * (x + 1), 0.0) + np.where(x > 1, b[2] * (x - 1), 0.0)

    def predict(self, q: np.ndarray) -> np.ndarray:
        """c (N,) deg over the path q (N,), every operator centred at q[0]."""
        q = np.asarray(q, float)
        return play_operators(q, self.r) @ self.w + self.memoryless((q - self.q_mid) / self.q_half)

    def params(self) -> dict:
        """The fitted parameters as a JSON-ready dict (thresholds in actuator units, weights and
        coefficients in deg)."""
        return {"thresholds": self.r.tolist(), "weights_deg_per_unit": self.w.tolist(),
                "m_bernstein_deg": self.m.tolist(), "m_variable": "x = (q - q_mid)/q_half",
                "q_mid": self.q_mid, "q_half": self.q_half, "active_operators": int(np.sum(self.w > 0))}


# --------------------------------------------------------------------------- modified PI
MPI_F_CTRL = 8  # control points of the output nonlinearity (a continuous superposition of dead zones)


@dataclass
class ModifiedPI:
    """Modified Prandtl-Ishlinskii model: a PI operator followed by a memoryless monotone output
    nonlinearity,

        y[k] = sum_i w_i F_{r_i}[q][k],   w_i >= 0, w_0 > 0, sum w = 1;   c[k] = g(y[k]),

    (Kuhnen, Eur. J. Control 9(4) 407-418, 2003: the superposition operator S of one-sided dead
    zones after the PI; here S is its continuous limit, a cubic spline of MPI_F_CTRL control
    points). Thresholds by gpi_thresholds(); weights and g jointly by variable projection
    (transition.fit_weights, double precision, no table bound), g the unconstrained P-spline.

    r: (n,) thresholds, actuator units; w: (n,) dimensionless; g: callable y -> c (deg).
    """

    r: np.ndarray
    w: np.ndarray
    g: object

    @classmethod
    def fit(cls, q: np.ndarray, c: np.ndarray, n_ops: int = GPI_OPERATORS, monotone: bool = False) -> "ModifiedPI":
        """Fit on one calibration path (q, c): (F,) each, in time order, finite. monotone: g made
        strictly monotone where the P-spline is not (transition.fit_weights' robust_f): with
        w_0 > 0 the model is then invertible, the double-precision form of the pi_const family
        (its narrowest play the table's constant B, the others on its centre)."""
        from .transition import fit_weights

        q, c = np.asarray(q, float), np.asarray(c, float)
        r = gpi_thresholds(q, n_ops)
        w, g, _, _ = fit_weights(play_operators(q, r), c, MPI_F_CTRL, robust_f=monotone)
        return cls(r, w, g)

    def predict(self, q: np.ndarray) -> np.ndarray:
        """c (N,) deg over the path q (N,), every operator centred at q[0]."""
        return self.g(play_operators(np.asarray(q, float), self.r) @ self.w)

    def params(self) -> dict:
        """The fitted parameters as a JSON-ready dict (thresholds in actuator units, the operators'
        weights in actuator units per actuator unit before the output spline g, g's size)."""
        return {"thresholds": self.r.tolist(), "weights": self.w.tolist(), "g_ctrl": MPI_F_CTRL,
                "active_operators": int(np.sum(self.w > 0))}


# --------------------------------------------------------------------------- Bouc-Wen
def bouc_wen_h(x: np.ndarray, beta: float, gamma: float, h0: float = 0.0) -> np.ndarray:
    """Hysteretic state of the Bouc-Wen model with A = 1, n = 1, driven by the path x:

        dh = A dx - beta |dx| |h|^(n-1) h - gamma dx |h|^n        (Ismail, Ikhouane & Rodellar,
                                                                    Arch. Comput. Methods Eng. 16, 2009, eq. 3)

    Rate-independent, so it is integrated in x, exactly: with g = h sign(dx) the state obeys
    dg/d|x| = 1 - u g (g >= 0) or 1 - v g (g < 0), u = beta + gamma, v = beta - gamma, a
    linear ODE in each region with the crossing of g = 0 in closed form. Needs u > 0 and
    v >= 0 (bounded, passive: class I of the survey). x: (N,); returns h (N,), h[-1] = h0.
    """
    u, v = beta + gamma, beta - gamma
    if not (u > 0 and v >= 0):
        raise ValueError("Bouc-Wen needs beta + gamma > 0 and beta >= gamma")
    xs = np.asarray(x, float).ravel().tolist()
    out = [0.0] * len(xs)
    h, prev = float(h0), xs[0]
    for k, xk in enumerate(xs):  # one scalar recursion per sample; plain floats are fastest
        dx = xk - prev
        prev = xk
        if dx != 0.0:
            s = 1.0 if dx > 0 else -1.0
            g, d = h * s, abs(dx)
            if g < 0.0:
                d0 = log1p(-v * g) / v if v > 0 else -g  # |x| travelled to reach g = 0
                if d < d0:
                    e = -expm1(-v * d) / v if v > 0 else d
                    g = g * exp(-v * d) + e
                    d = 0.0
                else:
                    g, d = 0.0, d - d0
            if d > 0.0:
                g = g * exp(-u * d) - expm1(-u * d) / u
            h = g * s
        out[k] = h
    return np.array(out)


@dataclass
class BoucWen:
    """Bouc-Wen hysteresis (Bouc 1967, Wen 1976; survey: Ismail, Ikhouane & Rodellar,
    "The hysteresis Bouc-Wen model, a survey", Arch. Comput. Methods Eng. 16:161-188, 2009):

        c = a x + b h + d,   dh = dx - beta |dx| h - gamma dx |h|   (A = 1, n = 1),

    x = (q - q_mid)/q_half. A = 1 because b absorbs the scale of h (the model is otherwise
    not identifiable); n = 1, the sharpest transition of the family and the choice of most
    actuator papers (e.g. Low & Guo, J. Microelectromech. Syst. 4(4), 1995). beta, gamma
    by scipy.optimize.least_squares (trust region reflective, bounds u = beta + gamma > 0,
    v = beta - gamma >= 0) from the best of a small start grid; a, b, d solved exactly for
    each (beta, gamma) (variable projection). Parameters in the normalised x; params()
    gives them per actuator unit.
    """

    a: float
    b: float
    d: float
    beta: float
    gamma: float
    q_mid: float
    q_half: float

    @staticmethod
    def _linear(x, h, c):
        A = np.column_stack([x, h, np.ones_like(x)])
        coef, *_ = np.linalg.lstsq(A, c, rcond=None)
        return coef, A @ coef - c

    @classmethod
    def fit(cls, q: np.ndarray, c: np.ndarray) -> "BoucWen":
        """Fit on one calibration path (q, c): (F,) each, in time order, finite."""
        q, c = np.asarray(q, float), np.asarray(c, float)
        q_mid, q_half = _norm(q)
        x = (q - q_mid) / q_half

        def resid(p):
            u, v = p
            return cls._linear(x, bouc_wen_h(x, 0.5 * (u + v), 0.5 * (u - v)), c)[1]

        # h saturates at 1/u after a travel of ~3/u: start from saturation within 1/30 to
        # 3x the normalised span, each with symmetric (v = u) and sharp-return (v = 0) shapes.
        starts = [(u, f * u) for u in (0.3, 1.0, 3.0, 10.0, 30.0, 100.0) for f in (0.0, 0.5, 1.0)]
        best = min(starts, key=lambda p: float(np.sum(resid(p) ** 2)))
        sol = least_squares(resid, best, bounds=([1e-6, 0.0], [1e4, 1e4]), method="trf", x_scale="jac")
        u, v = sol.x
        beta, gamma = 0.5 * (u + v), 0.5 * (u - v)
        (a, b, d), _ = cls._linear(x, bouc_wen_h(x, beta, gamma), c)
        return cls(float(a), float(b), float(d), float(beta), float(gamma), q_mid, q_half)

    def predict(self, q: np.ndarray) -> np.ndarray:
        """c (N,) deg over the path q (N,), h = 0 at q[0]."""
        x = (np.asarray(q, float) - self.q_mid) / self.q_half
        return self.a * x + self.b * bouc_wen_h(x, self.beta, self.gamma) + self.d

    def params(self) -> dict:
        """In actuator units (A = 1 kept): h in actuator units, beta/gamma per unit,
        a and b deg per unit, d deg: c = a q + b h + d."""
        s = self.q_half
        return {"A": 1.0, "n": 1, "beta_per_unit": self.beta / s, "gamma_per_unit": self.gamma / s,
                "a_deg_per_unit": self.a / s, "b_deg_per_unit": self.b / s,
                "d_deg": self.d - self.a * self.q_mid / s}
