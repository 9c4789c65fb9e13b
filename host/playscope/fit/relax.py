"""Travel-domain relaxation (rate-independent creep) of the transmission, in double precision:
its direct model, its exact inverse, its fit given the rest of the product's model, and the
table fields the board reads (common/ps_table.h, layout 4; firmware/core/relax.c).

Model (a Dahl / Duhem-type relaxation: the state relaxes towards the input over a constant of
*travelled* input, not of time; P. R. Dahl, "Solid friction damping of mechanical vibrations",
AIAA J. 14(12), 1976; the Duhem class of rate-independent hysteresis operators, A. Visintin,
"Differential Models of Hysteresis", Springer 1994, ch. III): with input x (actuator units) at
samples k = 0..N-1,

    v[k] = x[k] + kappa (r[k-1] - x[k])                                 output
    r[k] = r[k-1] + g[k] (x[k] - r[k-1]),  g[k] = min(|v[k] - v[k-1]| / lambda, 1 - kappa)

r[-1] = v[-1] = x[0] (at rest). kappa in [0, kappa_max()] is the share of the output that creeps,
lambda > 0 (actuator units) the travel over which it relaxes (dr/ds = (x - r) / lambda in the
travel s; the explicit step is that ODE's Euler step, exact to O(|dx| / lambda) per sample).
Rate independence: a time-rescaled input gives the time-rescaled output (only the path of x
enters). The output reads the relaxed state *before* this sample's update so that the inverse
is explicit, with no divide (the board's per-tick recursion, firmware/core/relax.h):

    x[k] = v[k] + m (v[k] - r[k-1]),  m = kappa / (1 - kappa)           inverse
    then the same update of r from x[k].

The gain reads the travel of the output v (Duhem's class allows the rate of either
variable), which the inverse is given: with g from |dx| the inverse's errors obey
e[k] = (1 - m) e[k-1] + m e[k-2] (roots 1 and -m) and diverge for kappa >= 1/2 (measured on the
board's recursion: 4348 raw after 20000 ticks at kappa 0.5); from |dv| they contract by
1 - g / (1 - kappa) per sample. In steady motion dv = dx, so lambda keeps its meaning. The cap
1 - kappa keeps that factor >= 0; it acts only on a sample that travels more than
(1 - kappa) lambda.

In steady motion r trails x by lambda, so the output trails the input by kappa lambda: a
rounded extra play of half-width kappa lambda, taken up over a travel of a few lambda after each
reversal, at any speed. A time-domain lag (the diagnosis' cable_elongation) instead trails by
kappa tau |dx/dt|: the two differ exactly in how they scale with speed.

Where it acts in the product's chain (docs/method.md, "Travel-domain relaxation"): on the
transition's output y, before f_remain, c = f(R[PI[g(z)]]); the compensator runs R^-1 on
y* = f^-1(c*) before PI^-1. Chosen on the catheter recordings (docs/method.md gives the figures).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

LAMBDA_MIN_FRAC = 1e-3     # lambda >= 1e-3 x the travel range: below, a step (the plain play) is as good
LAMBDA_MAX_FRAC = 2.0      # lambda <= 2 x the travel range: beyond, r barely moves over the record


def kappa_max_q16() -> int:
    """The largest creeping share the board's table loader accepts, Q16.16 raw:
    PST_RELAX_KAPPA_MAX_Q16 (common/ps_table.h; 0.9, so the inverse's gain 1/(1 - kappa) on the
    output's rounding stays <= 10), read from the C through the native module."""
    from ..base import native

    return native.constant("PST_RELAX_KAPPA_MAX_Q16")


def kappa_max() -> float:
    """kappa_max_q16() as a double (dimensionless): the fit's upper bound on kappa."""
    from ..base import native

    return kappa_max_q16() / native.Q16_ONE


@dataclass
class Relaxation:
    """kappa (dimensionless, 0..kappa_max(): judged in the table's Q16.16 steps) and lam
    (actuator units, > 0). kappa = 0: identity."""

    kappa: float
    lam: float

    def __post_init__(self):
        self.kappa, self.lam = float(self.kappa), float(self.lam)
        if not 0.0 <= self.kappa < 1.0:
            raise ValueError(f"relaxation kappa must be in [0, {kappa_max():.6g}], not {self.kappa}")
        if self.kappa > 0.0:  # the loader's bound in its own units (0.9 rounds onto it)
            from ..base import native

            if round(self.kappa * native.Q16_ONE) > kappa_max_q16():
                raise ValueError(f"relaxation kappa must be in [0, {kappa_max():.6g}], not {self.kappa}")
        if not (np.isfinite(self.lam) and self.lam > 0.0):
            raise ValueError(f"relaxation lambda must be a positive length, not {self.lam}")

    @property
    def is_identity(self) -> bool:
        return self.kappa == 0.0

    def direct(self, x: np.ndarray, r0: float | None = None) -> np.ndarray:
        """v (N,) for input x (N,), actuator units; r0: state at rest before x[0] (default x[0])."""
        return _run(np.asarray(x, float).ravel(), self.kappa, self.lam, r0, inverse=False)

    def inverse(self, v: np.ndarray, r0: float | None = None, clip: tuple[float, float] | None = None) -> np.ndarray:
        """x (N,) with direct(x) = v (N,) exactly (in exact arithmetic); r0 as in direct (default
        v[0], which is x[0] for a record that starts at rest). clip: (lo, hi) actuator units, x
        held there before the state update, as the board's inverse holds it to its table's input
        range (relax_params_t x_min, x_max)."""
        return _run(np.asarray(v, float).ravel(), self.kappa, self.lam, r0, inverse=True, clip=clip)

    def to_json(self) -> dict:
        return {"kappa": self.kappa, "lambda": self.lam}

    @classmethod
    def from_json(cls, d: dict) -> "Relaxation":
        return cls(float(d["kappa"]), float(d["lambda"]))


def _run(s: np.ndarray, kappa: float, lam: float, r0, inverse: bool, clip=None) -> np.ndarray:
    """The recursion of the module doc over s (the input x, or with inverse=True the output v)."""
    out = np.empty(s.size)
    if s.size == 0:
        return out
    inv_lam = 1.0 / lam
    m = kappa / (1.0 - kappa)
    cap = 1.0 - kappa
    r = float(s[0]) if r0 is None else float(r0)
    vp = None
    for k, sk in enumerate(s.tolist()):
        if inverse:
            v = sk
            x = v + m * (v - r)
            if clip is not None:
                x = min(max(x, clip[0]), clip[1])
            out[k] = x
        else:
            x = sk
            v = x + kappa * (r - x)
            out[k] = v
        if vp is None:
            vp = v  # at rest: no travel on the first sample
        g = abs(v - vp) * inv_lam
        r += (cap if g > cap else g) * (x - r)
        vp = v
    return out


# --------------------------------------------------------------------------- fit
@dataclass
class RelaxFit:
    """Result of fit(): the relaxation, f refitted on its output, and the fit's figures."""

    relax: Relaxation
    f: object
    sign: int
    rmse_deg: float
    rmse_without_deg: float
    nfev: int
    f_without: object = None     # f fitted the same way on the unrelaxed output (the control)
    sign_without: int = 0

    def to_json(self) -> dict:
        return {**self.relax.to_json(), "rmse_deg": self.rmse_deg, "rmse_without_deg": self.rmse_without_deg,
                "nfev": self.nfev}


def at_frames(y_enc: np.ndarray, t_enc: np.ndarray, t_frame: np.ndarray, rl: Relaxation) -> np.ndarray:
    """The relaxation's output of y_enc (N,) (the transition's output at the encoder samples,
    from the record's start), read at the frames' acquisition times t_frame (F,) s."""
    return np.interp(t_frame, t_enc, rl.direct(y_enc))


def fit(y_enc: np.ndarray, t_enc: np.ndarray, t_frame: np.ndarray, c: np.ndarray, fit_f, x0=(0.3, 0.1),
        max_nfev: int = 60, fit_f_search=None, starts=(None, 0.02)) -> RelaxFit:
    """(kappa, lambda) by scipy.optimize.least_squares, given the rest of the model.

    y_enc (N,): the transition's output (actuator units) at the encoder times t_enc (N,) s, run
    from the record's start (onset play, transition, threshold map as calibrated); t_frame (F,)
    s, c (F,) deg: the calibration frames (acquisition times, NaN-free); fit_f(v (F,), c (F,))
    -> (f, sign): the product's own f_remain fit on the relaxed output (refitted at each
    evaluation: kappa moves the output's scale, which f absorbs). x0: (kappa, lambda as a
    fraction of y's range). Parameters: kappa in [0, kappa_max()], log lambda within
    [LAMBDA_MIN_FRAC, LAMBDA_MAX_FRAC] x y's range. Returns RelaxFit (rmse_without_deg: the
    same f fit with kappa = 0, whose f is f_without). fit_f_search: a cheaper f fit of the same
    signature used while (kappa, lambda) are searched (f is then fitted once more by fit_f at
    the best point); starts: the lambda starts as fractions of y's range (None: x0's).
    Errors: ValueError when y has no range."""
    y_enc, t_enc = np.asarray(y_enc, float), np.asarray(t_enc, float)
    t_frame, c = np.asarray(t_frame, float), np.asarray(c, float)
    span = float(np.ptp(y_enc))
    if not span > 0:
        raise ValueError("the transition's output does not move: no relaxation to fit")
    lo = np.array([0.0, np.log(LAMBDA_MIN_FRAC * span)])
    hi = np.array([kappa_max(), np.log(LAMBDA_MAX_FRAC * span)])
    y_f = np.interp(t_frame, t_enc, y_enc)
    f0, s0 = fit_f(y_f, c)
    base = float(np.sqrt(np.mean((f0(y_f) - c) ** 2)))
    cache = {}

    def resid(p):
        key = (round(p[0], 12), round(p[1], 12))
        if key not in cache:
            rl = Relaxation(min(max(p[0], 0.0), hi[0]), float(np.exp(p[1])))
            v = at_frames(y_enc, t_enc, t_frame, rl)
            f, sg = (fit_f_search or fit_f)(v, c)
            cache[key] = (f(v) - c, f, sg, rl)
        return cache[key][0]

    best = None
    # Two starts in lambda (short and long creep): the residual is not convex in log lambda.
    for lam_frac in (x0[1] if st is None else st for st in starts):
        p0 = np.clip([x0[0], np.log(lam_frac * span)], lo + 1e-9, hi - 1e-9)
        res = least_squares(resid, p0, bounds=(lo, hi), x_scale=[0.1, 0.5], diff_step=1e-3, max_nfev=max_nfev)
        if best is None or res.cost < best.cost:
            best = res
    e, f, sg, rl = cache[(round(best.x[0], 12), round(best.x[1], 12))]
    if fit_f_search is not None:
        v = at_frames(y_enc, t_enc, t_frame, rl)
        f, sg = fit_f(v, c)
        e = f(v) - c
    rm = float(np.sqrt(np.mean(e ** 2)))
    if rm >= base:  # never worse than the model without it (kappa = 0 is in the family)
        return RelaxFit(Relaxation(0.0, rl.lam), f0, s0, base, base, len(cache), f0, s0)
    return RelaxFit(rl, f, sg, rm, base, len(cache), f0, s0)


# --------------------------------------------------------------------------- table fields

def table_fields(rl: Relaxation | None) -> tuple[int, int]:
    """(kappa_q16, lambda_q16) for pst_relax_t (common/ps_table.h, layout 4): kappa in
    Q16.16 (0..kappa_max_q16()), lambda in actuator units Q16.16 (>= 1 raw). (0, 0): no relaxation.
    Errors: ValueError when lambda does not fit Q16.16."""
    if rl is None or rl.is_identity:
        return 0, 0
    from ..base import native

    k = int(round(rl.kappa * native.Q16_ONE))
    lam = int(round(rl.lam * native.Q16_ONE))
    if not 1 <= lam < 2 ** 31:
        raise ValueError(f"relaxation lambda {rl.lam} does not fit the table's Q16.16")
    return k, lam


def from_table_fields(kappa_q16: int, lambda_q16: int) -> Relaxation | None:
    """The double model of a table's stored fields (what the board runs, before its rounding)."""
    if kappa_q16 == 0:
        return None
    from ..base import native

    return Relaxation(kappa_q16 / native.Q16_ONE, lambda_q16 / native.Q16_ONE)


# --------------------------------------------------------------------------- on a calibration
def transition_output(q: np.ndarray, B, tr, z0: float | None = None) -> np.ndarray:
    """y (N,) = PI[g(play(q))], the transition's output the relaxation acts on: q (N,) actuator
    units from the record's start, B the onset width callable, tr a transition.Transition
    (its own play width and threshold map applied)."""
    from . import model

    return tr.direct(model.play_operator(np.asarray(q, float), tr.play_width(B), z0))


def fit_on_calibration(t_enc: np.ndarray, q: np.ndarray, B, tr, t_frame: np.ndarray, c: np.ndarray,
                       n_ctrl: int, sign: int | None = None) -> RelaxFit:
    """The relaxation of a calibration: (kappa, lambda) and f refitted on the relaxed output by
    the transition's own f fit (transition.fit_f: monotone robust spline, n_ctrl control points,
    f's sign kept), given the onset play B, the transition tr (b_scale, operators, map) as the
    calibration chose them. t_enc, q: (N,) the calibration part's encoder record (s, actuator
    units); t_frame, c: (F,) frame acquisition times (s, delay already removed) and angles (deg),
    NaN rows dropped here. Returns RelaxFit (kappa 0 when the relaxation does not lower the
    calibration part's residual). Errors: ValueError when the transition's output does not move."""
    from . import transition as T

    ok = np.isfinite(c)
    t_frame, c = np.asarray(t_frame, float)[ok], np.asarray(c, float)[ok]
    y = transition_output(q, B, tr)
    return fit(y, np.asarray(t_enc, float), t_frame, c, lambda v, cc: T.fit_f(v, cc, n_ctrl, sign=sign))
