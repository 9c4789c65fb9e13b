"""Parametric model of the bending DOF used by the diagnosis: play of width B(q) (eq. 3) then
f_remain, plus any subset of the effect library, fitted by least squares on part of a session.

The fitted quantity is the configuration c in deg (measured by an angle sensor, or estimated
per frame from the marker by eq. 8 with the session's nominal camera and hand-eye). Linear
parts are solved exactly for each value of the nonlinear ones (variable projection):
  c(t) = sum_j a_j P_j(x(t)) + r_drift (t - t_mid)/60 + delta s(t)
where P_j are cubic B-splines (12 interior knots) of the normalised play output after the play-stage
and distal effects, x = (z' - q_mid)/q_half, s(t) = direction of distal motion (held sign of
dz/dt), with an elongation low-pass and the extra delay applied to the basis columns.
Nonlinear parameters: B at 9 knots (natural cubic spline) (mm, piecewise linear in q) and those of the effects on.

Units: q, z, B in actuator units (mm); c in deg; t in s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares
from scipy.signal import lfilter

from ..fit.bspline import design_dense
from ..fit.model import play_edges
from ..base import kernels

N_KNOTS = 9
N_FKNOTS = 12  # interior knots of the cubic B-spline f_remain
INTERNAL_HZ = 50.0
PROFILE_NFEV = 8  # iterations of a dead band's own parameters per start (Model._profile_dead_zone)

# Nonlinear parameters of each effect in the diagnostic model: (name, init, lo, hi); the scales
# that depend on the data (q range) are filled by Data.bounds(). Linear ones are listed apart.
NONLIN = {
    "asymmetric_backlash": [("alpha", 0.0, -0.8, 0.8)],
    # Widths B exp(sigma u) / mean, u in [-1, 1]: any spread with positive widths (the former
    # linear 1 + spread u needed spread < 1 and sat at 0.95 on the catheter).
    "smooth_transition": [("log_spread", 0.5, 0.0, 3.0)],
    # Dead band of half-width w around z0, its corners rounded over corner_frac * w on each side of
    # an edge (_dead_band; 0 is the hard band): a joint's or a routing's slack is taken up gradually.
    "dead_zone": [("w_q", None, 0.0, None), ("z0_q", None, None, None), ("corner_frac", 0.3, 0.0, 1.0)],
    # Stiction of the carrier in the transmission, Karnopp (1985): a carrier of unit mass tied to
    # the play output by a spring (natural frequency fn), viscous damping zeta, Coulomb friction with
    # a static level (breakaway lag static_q, mm of play output) and a kinetic level (kin_ratio of
    # it), and Karnopp's zero-velocity band (stuck while |v| is inside it and the spring force stays
    # under the static level). See _karnopp_carrier.
    "stick_slip": [("static_q", None, 0.0, None), ("kin_ratio", 0.5, 0.0, 1.0),
                   ("log_fn", np.log(20.0), np.log(8.0), np.log(60.0)), ("zeta", 0.5, 0.05, 1.0)],
    "cable_elongation": [("kappa", 0.3, 0.0, 0.95), ("log_tau", 0.0, np.log(0.05), np.log(10.0))],
    # The same creep over the travel instead of time (rate-independent, Dahl / Duhem type;
    # playscope.fit.relax): the carrier relaxes towards the play output over a travel lambda (q
    # units; log, bounds from the q span in Model), kappa of it creeping. A lag whose fitted tau
    # scales with each record's period is this effect; kept apart from cable_elongation so
    # records at several speeds tell them apart (tau moves with speed, lambda does not).
    "travel_relaxation": [("kappa", 0.3, 0.0, 0.9), ("log_lambda_q", None, None, None)],
    "camera_delay": [("delay_s", 0.0, -0.2, 0.5)],
    # Rate-dependent play, two physical routes to a lag that grows with speed: (1) an extra
    # half-width beta * |dq/dt| (speed low-passed with tau_v; sheath friction with a viscous part:
    # the band itself widens with speed); (2) a viscous contact, the play output relaxing towards
    # the band with time constant tau_c instead of being carried by it (a lag only while an edge
    # pushes, frozen as soon as the edge leaves: unlike a low-pass after the play, i.e. an
    # elongation, it does not creep on through the reversal). log_tau_c at its lower bound
    # (2 ms, a tenth of an internal sample) is the plain play.
    "viscous_hysteresis": [("beta_s", 0.05, 0.0, 2.0), ("log_tau_v", np.log(0.1), np.log(0.02), np.log(3.0)),
                           ("log_tau_c", np.log(0.002), np.log(0.002), np.log(2.0))],
    # The registration offset switches sign with the direction of distal motion over a travel of
    # the play output (a seat that slides over its gap, an instrument dragged in its channel);
    # log of the travel as a fraction of the q span; the smallest is an instant switch.
    "handeye_direction": [("log_travel", np.log(0.002), np.log(0.002), np.log(0.5))],
    "drift": [],
}
LINEAR = {"handeye_direction": "delta_deg", "drift": "rate_deg_per_min"}
C_LIBRARY = list(NONLIN)  # effects visible in a record of c
DEAD_ZONE_SIDES = ("actuator", "distal")


def _dead_band(u: np.ndarray, w: float, r: float) -> np.ndarray:
    """Output of a dead band of half-width w (mm) for an input u (mm, (N,)) measured from its
    centre: sign(u) g(|u| - w), with g(a) = max(a, 0) (the hard band) when r = 0, else g the
    quadratically smoothed hinge -- 0 for a <= -r, (a + r)^2 / (4 r) for |a| < r, a for a >= r --
    whose slope rises linearly from 0 to 1 over [-r, r] around each edge (C1; a two-sided form of
    the quadratically smoothed hinge of Rennie & Srebro, IJCAI 2005 workshop, whose quadratic sits
    on one side of the kink). r <= w keeps the output 0 at the centre and monotone. Returns (N,) mm.
    Why rounded: a slack taken up gradually (a joint, a routing) has no kink, and the hard band
    recovered half or less of a rounded one's shrink on the blind generator's development seeds
    3000-3500 (docs/diagnosis.md section 3 item 1)."""
    a = np.abs(u) - w
    if r <= 0.0:
        return np.sign(u) * np.maximum(a, 0.0)
    g = np.where(a <= -r, 0.0, np.where(a >= r, a, (a + r) ** 2 / (4.0 * r)))
    return np.sign(u) * g


# Largest stretch of a side of the distal band (_distal_stretch): a band that takes nearly all of
# one side leaves a short output there, stretched at most this much.
STRETCH_MAX = 4.0


def _distal_stretch(v: np.ndarray, zc: float, w: float, ends: tuple[float, float]) -> np.ndarray:
    """The distal band's output v = _dead_band(z - zc, ...) (mm, (N,)) stretched on each side so it
    spans the range of z again: v (zc - lo) / (zc - lo - w) below the centre, v (hi - zc) /
    (hi - zc - w) above (each capped at STRETCH_MAX); ends = (lo, hi), the range of z (_z_ends).
    Why: f_remain is a spline on fixed knots over the range of z; the band shortens its input by w
    at each end, so without the stretch the outer basis splines see only the tails of their
    support and take wild coefficients (213 on a 0.4-mm band of the second generator's spent
    seed 6151), and validation rows 2 % past the fitted range then missed by up to 0.7 deg
    (validation RMSE 0.22 deg against 0.07 without the band). f_remain of a stretched output is
    the same model class (a linear map on each side of the flat band), with the knots covering
    the data as in the model without the band. Returns (N,) mm, measured from zc."""
    lo, hi = ends
    s_lo = (zc - lo) / max(zc - lo - w, (zc - lo) / STRETCH_MAX, 1e-12)
    s_hi = (hi - zc) / max(hi - zc - w, (hi - zc) / STRETCH_MAX, 1e-12)
    return v * np.where(v < 0.0, s_lo, s_hi)


def lowpass(x: np.ndarray, tau_s: float, rate_hz: float) -> np.ndarray:
    """First-order low-pass tau dy/dt = x - y of a uniformly sampled (N,) signal, y[0] = x[0]
    (the diagnosis' own filter; the simulators keep theirs). x may also be (N, M): each column
    filtered alone."""
    a = np.exp(-1.0 / (tau_s * rate_hz))
    if np.ndim(x) == 2:
        # every column of an (N, M) array at once, each as the 1-D call would filter it
        y, _ = lfilter([1 - a], [1, -a], x, axis=0, zi=a * x[:1])
        return y
    y, _ = lfilter([1 - a], [1, -a], x, zi=[a * x[0]])
    return y


@dataclass
class Data:
    """A session reduced to what the model needs.

    t_int, q_int: (Ni,) actuator log resampled at INTERNAL_HZ; t_m, y_m: (Nm,) measurement
    times (s, stamped) and c (deg); t_delay_s: declared acquisition delay; extra: per-frame
    image data (u, v, reprojection residual) for image sessions.
    """

    t_int: np.ndarray
    q_int: np.ndarray
    t_m: np.ndarray
    y_m: np.ndarray
    t_delay_s: float = 0.0
    name: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def q_lo(self):
        return float(np.min(self.q_int))

    @property
    def q_hi(self):
        return float(np.max(self.q_int))


def knots(data: Data, n: int = N_KNOTS) -> np.ndarray:
    """The n knots of B (q units, (n,)): evenly over the record's actuator range."""
    return np.linspace(data.q_lo, data.q_hi, n)


@dataclass
class Fit:
    """Result of fitting one model (a set of effects) on the rows ``fit_mask`` of a Data."""

    effects: tuple
    theta: np.ndarray          # nonlinear parameters (B knots, then effects in NONLIN order)
    names: list
    coef: np.ndarray           # linear coefficients (B-spline f_remain, then drift/handeye columns)
    coef_names: list
    pred: np.ndarray           # (Nm,) predicted c, deg, on every row
    rss: float
    n_fit: int
    n_eff: float
    k: int
    cov_theta: np.ndarray | None = None
    cov_coef: np.ndarray | None = None
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None

    def at_bounds(self) -> dict[str, str]:
        """{effect parameter: "lower"|"upper"} for effect parameters within 0.1 % of the span of
        a bound (a fitted value at a bound is not an estimate: reported, and the bound widened)."""
        out = {}
        if self.lo is None:
            return out
        for n, v, l, h in zip(self.names, self.theta, self.lo, self.hi):
            if "." not in n:
                continue
            tol = 1e-3 * (h - l)
            if v >= h - tol:
                out[n] = "upper"
            elif v <= l + tol:
                out[n] = "lower"
        return out

    @property
    def bic(self) -> float:
        """Bayesian information criterion on the fit rows with the effective sample size (the
        residuals are autocorrelated, so n_eff < n keeps the penalty honest)."""
        return self.n_eff * np.log(self.rss / self.n_fit) + self.k * np.log(self.n_eff)

    def rmse(self, y: np.ndarray, mask: np.ndarray) -> float:
        r = (y - self.pred)[mask]
        r = r[np.isfinite(r)]
        return float(np.sqrt(np.mean(r * r))) if r.size else float("nan")

    def params(self) -> dict[str, tuple[float, float]]:
        """{name: (value, 1-sigma)} for every parameter (nonlinear and named linear ones)."""
        out = {}
        sd = np.sqrt(np.diag(self.cov_theta)) if self.cov_theta is not None else np.full(len(self.theta), np.nan)
        for n, v, s in zip(self.names, self.theta, sd):
            out[n] = (float(v), float(s))
        sdc = np.sqrt(np.diag(self.cov_coef)) if self.cov_coef is not None else np.full(len(self.coef), np.nan)
        for n, v, s in zip(self.coef_names, self.coef, sdc):
            if not n.startswith("P"):
                out[n] = (float(v), float(s))
        return out


KARNOPP_SUBSTEPS = 8  # integration steps per internal sample (2.5 ms; stable for fn <= 60 Hz)


def _karnopp_carrier(z: np.ndarray, rate_hz: float, static: float, kin_ratio: float, fn_hz: float,
                     zeta: float, substeps: int = KARNOPP_SUBSTEPS, native: bool = True) -> np.ndarray:
    """Stick-slip of a carrier driven through a spring by z (Karnopp 1985, "Computer simulation of
    stick-slip friction in mechanical dynamic systems", J. Dyn. Sys. Meas. Control 107:100-103).
    Per unit mass: p'' = wn^2 (z - p) - 2 zeta wn p' - F_f, with
      |p'| outside the band D:  F_f = Fc sign(p')                        (Coulomb, kinetic)
      |p'| inside the band D:   F_f = F_app if |F_app| <= Fs (stuck: p'' = 0, p' set to 0),
                                else Fs sign(F_app)                          (breakaway)
    F_app = wn^2 (z - p) the spring force, Fs = wn^2 static (a spring stretched by ``static`` mm
    holds the carrier), Fc = kin_ratio Fs. D = 0.01 h Fs, a hundredth of the velocity one step of
    the static force gives (a wider band, h Fs, was tried first: it stuck the carrier between
    slips that the unit test's generator lets through); a velocity that changes sign within a step
    while the spring force is under Fs also sticks. Semi-implicit Euler (damping implicit) with
    step h = 1 / (rate_hz substeps), z linear between samples; a stuck carrier whose spring force
    stays under Fs over a whole sample is skipped. Starts stuck at p = z[0].
    z: (N,) mm sampled at rate_hz; returns p (N,) mm at the same samples. native: the C kernel
    (kernels.karnopp, the same arithmetic) when it is compiled; False runs this Python reference."""
    wn = 2.0 * np.pi * fn_hz
    w2, c2 = wn * wn, 2.0 * zeta * wn
    Fs = w2 * max(static, 0.0)
    Fc = kin_ratio * Fs
    h = 1.0 / (rate_hz * substeps)
    band = 0.01 * h * Fs
    if native and kernels.available():
        return kernels.karnopp(z, w2, c2, Fs, Fc, h, band, substeps)
    zl = np.asarray(z, float).tolist()
    out = [0.0] * len(zl)
    p, v = zl[0], 0.0
    zp = zl[0]
    for k, zk in enumerate(zl):
        if v == 0.0 and abs(w2 * (zk - p)) <= Fs and abs(w2 * (zp - p)) <= Fs:
            out[k] = p
            zp = zk
            continue
        for j in range(1, substeps + 1):
            zj = zp + (zk - zp) * j / substeps
            F = w2 * (zj - p)
            if -band < v < band:
                if -Fs <= F <= Fs:
                    v = 0.0
                    continue
                vn = v + h * (F - (Fs if F > 0 else -Fs))
            else:
                # damping taken implicitly (stable for any zeta at this step)
                vn = (v + h * (F - (Fc if v > 0 else -Fc))) / (1.0 + h * c2)
            if v != 0.0 and vn * v <= 0.0 and abs(F) <= Fs:
                vn = 0.0  # the velocity crossed the band within the step: stuck
            v = vn
            p += h * v
        out[k] = p
        zp = zk
    return np.asarray(out)


def _switch(z: list, travel: float, native: bool = True) -> np.ndarray:
    """Direction state that goes from -1 to +1 over a travel ``travel`` of z (a play of width
    travel on z, normalised): s += 2 dz / travel, clipped to [-1, 1]; starts at +1. native: the
    C kernel when compiled (same arithmetic); False runs this Python reference."""
    g = 2.0 / max(travel, 1e-12)
    if native and kernels.available() and len(z):
        return kernels.switch(z, g)
    z = np.asarray(z, float).tolist()
    out = [0.0] * len(z)
    st = 1.0
    for k in range(1, len(z)):
        st += g * (z[k] - z[k - 1])
        st = 1.0 if st > 1.0 else (-1.0 if st < -1.0 else st)
        out[k] = st
    out[0] = out[1] if len(z) > 1 else 1.0
    return np.asarray(out)


def _viscous_play(z_lo: np.ndarray, z_hi: np.ndarray, z0: float, a: float, native: bool = True) -> np.ndarray:
    """Play whose output relaxes towards its band instead of being carried by it (a viscous
    contact): p[k] = p[k-1] + a (clip(p[k-1], z_lo[k], z_hi[k]) - p[k-1]), a = 1 - exp(-dt/tau_c).
    a = 1 is the play operator of eq. 3; a < 1 lags while an edge pushes, by ~ speed x tau_c, and
    holds still once the edge has left (the band contains p). z_lo, z_hi: (N,); returns p (N,).
    native: the C kernel when compiled (same arithmetic); False runs this Python reference."""
    if native and kernels.available():
        return kernels.viscous_play(z_lo, z_hi, z0, a)
    lo = np.asarray(z_lo, float).tolist()
    hi = np.asarray(z_hi, float).tolist()
    out = [0.0] * len(lo)
    p = float(z0)
    for k in range(len(lo)):
        c = lo[k] if p < lo[k] else (hi[k] if p > hi[k] else p)
        p += a * (c - p)
        out[k] = p
    return np.asarray(out)


def _direction(z: np.ndarray) -> np.ndarray:
    from ..fit.model import held_direction

    return held_direction(z, 1e-12)


class Model:
    """The diagnostic model for one Data and one set of effects (names from C_LIBRARY)."""

    def __init__(self, data: Data, effects=(), frame: "Model | None" = None, dead_zone_side: str | None = None,
                 spline_knots: tuple[int, int] | None = None):
        """frame: another Model whose knots and normalisation are reused, so a fit made on one
        session can be evaluated on another (across-session protocol). dead_zone_side: where the
        dead band acts, "actuator" (on q, before the play; default) or "distal" (on the play
        output z, before f_remain; see design()); a frame's side is kept. spline_knots: (knots of
        B, interior knots of f_remain), default (N_KNOTS, N_FKNOTS) or the frame's (a richer class
        for the self-test's trace check, selftest.base_trace)."""
        self.d = data
        self.effects = tuple(e for e in C_LIBRARY if e in effects)
        side = dead_zone_side or (frame.dead_zone_side if frame is not None else "actuator")
        if side not in DEAD_ZONE_SIDES:
            raise ValueError(f"dead_zone_side must be one of {DEAD_ZONE_SIDES}, not {side!r}")
        self.dead_zone_side = side
        self.frame = frame
        if spline_knots is None:
            spline_knots = (frame.n_b, frame.n_f) if frame is not None else (N_KNOTS, N_FKNOTS)
        self.n_b, self.n_f = int(spline_knots[0]), int(spline_knots[1])
        ref = frame.d if frame is not None else data
        span = ref.q_hi - ref.q_lo
        self.q_mid = 0.5 * (ref.q_hi + ref.q_lo)
        self.q_range = (ref.q_lo, ref.q_hi)
        self.q_half = max(0.5 * span, 1e-9)
        self.kn = knots(ref, self.n_b)
        self.zg = np.r_[self.kn[0] - 10 * span - 1, np.linspace(self.kn[0], self.kn[-1], 600), self.kn[-1] + 10 * span + 1]
        names, init, lo, hi = [], [], [], []
        for i in range(self.n_b):
            names.append(f"B{i}_q")
            init.append(0.1 * span)
            lo.append(0.0)
            hi.append(0.6 * span)
        for e in self.effects:
            for (n, v0, l, h) in NONLIN[e]:
                if n == "w_q":
                    v0, h = 0.03 * span, 0.3 * span
                elif n == "z0_q":
                    v0, l, h = data.q_lo + 0.2 * span, data.q_lo - 0.1 * span, data.q_hi + 0.1 * span
                elif n == "static_q":
                    v0, h = 0.01 * span, 0.1 * span
                elif n == "log_lambda_q":
                    v0, l, h = np.log(0.1 * span), np.log(0.002 * span), np.log(2.0 * span)
                names.append(f"{e}.{n}")
                init.append(v0)
                lo.append(l)
                hi.append(h)
        self.names, self.init = names, np.array(init, float)
        self.lo, self.hi = np.array(lo, float), np.array(hi, float)
        inner = np.linspace(-1, 1, self.n_f + 2)
        self.ftk = np.r_[[-1.5] * 4, inner[1:-1], [1.5] * 4]
        self.coef_names = [f"P{j}" for j in range(self.ftk.size - 4)]
        if "drift" in self.effects:
            self.coef_names.append("drift.rate_deg_per_min")
        if "handeye_direction" in self.effects:
            self.coef_names.append("handeye_direction.delta_deg")

    @staticmethod
    def _edge(zk: np.ndarray, half: np.ndarray):
        """(xp, fp) for np.interp inverting q = z + half(z) (half sampled on the grid zk); xp is
        made non-decreasing so an over-steep B cannot break np.interp."""
        xp = np.maximum.accumulate(zk + half)
        return xp, zk

    def _get(self, theta, e, n):
        return float(theta[self.names.index(f"{e}.{n}")])

    def _corner(self, theta) -> float:
        """Corner half-width of the dead band as a fraction of its half-width (see _dead_band)."""
        return self._get(theta, "dead_zone", "corner_frac")

    def _band(self, theta, ends: tuple[float, float]) -> tuple[float, float]:
        """Dead band (centre z0, half-width w), mm, with w capped at the centre's distance to the
        nearer end of the range ``ends`` (mm) of the variable the band acts on. Why: a band that
        reaches past that range has an edge that no sample shows; inside the data it is then a flat
        at the end of the range that f_remain would otherwise have to bend into, and beyond the
        data it predicts c frozen. Such a band fitted an end of the range on development seed 2000
        (soft distal dead zone 8 deg: centre 2.86 mm, band to 3.03 mm against a fitted range to
        2.91 mm) and put 0.68 deg of error on the test rows that went 0.05 mm further. A band at
        the edge is the base model.
        ends: the actuator side acts on q, so its range is q's (``q_range``); the distal side acts
        on the play output z, whose range is q's narrowed by half the play at each end
        (``_z_ends``). Both are the commanded input over the whole record (that of the frame's
        record when one is given), pushed through the model's own play for z: never a reading of
        the validation or test rows. theta: (n_params,) in self.names order. Returns (z0_mm, w_mm)."""
        zc = self._get(theta, "dead_zone", "z0_q")
        w = self._get(theta, "dead_zone", "w_q")
        lo, hi = ends
        return zc, min(w, max(zc - lo, 0.0), max(hi - zc, 0.0))

    def _z_ends(self, theta, z: np.ndarray) -> tuple[float, float]:
        """Range (mm) of the play output z over the whole record for the distal band's cap
        (``_band``); z: (N_int,) this model's play output at theta. With a frame the frame's
        record's z is used, so a band fitted on one record keeps its width on another.
        Why not q's range (the rule before): the distal band acts on z, which stops half a play
        short of q at each end. Capped by q's range, a band could still end where z ends and act
        as a saturation: on development seed 4000 (soft distal dead zone 8 deg, hard band) one sat
        at z0 = 2.73 mm, w = 0.07 mm, its upper edge at the end of z (q to 2.95 mm, half the play
        about 0.15 mm), and held c at 33 deg where the test rows reached 34 deg: test RMSE
        0.057 -> 0.166 deg. Capped by z's range the fit finds the band near straight (z0 -0.12 mm,
        w 0.36 mm) and the test RMSE goes 0.057 -> 0.050 (rounded band: z0 -0.13 mm, 0.050)."""
        if self.frame is not None:
            z = self.frame._play_output(theta)[0]
        return float(np.min(z)), float(np.max(z))

    def _play_output(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The carrier: play output z (N_int,) mm on the internal grid (self.d.t_int) and the held
        direction of its motion (N_int,) +-1, for nonlinear parameters theta: the actuator-side
        band, the play operator(s) with the transition / asymmetry / viscous lag, the registration
        switch and the stick-slip carrier: everything design() computes before the distal band
        and f_remain. For a model with a frame this is also run on the frame's record by
        ``_z_ends`` at each design() call (one carrier more; such models are only evaluated)."""
        d = self.d
        q = d.q_int
        if "dead_zone" in self.effects and self.dead_zone_side == "actuator":
            # Dead band on the actuator side, before the play: the cable does not move while q
            # crosses [z0 - w, z0 + w].
            zc, w = self._band(theta, self.q_range)
            q = zc + _dead_band(q - zc, w, self._corner(theta) * w)
        Bk = np.maximum(theta[:self.n_b], 0.0)
        alpha = self._get(theta, "asymmetric_backlash", "alpha") if "asymmetric_backlash" in self.effects else 0.0
        z0 = float(q[0])
        widths = [1.0]
        if "smooth_transition" in self.effects:
            s = self._get(theta, "smooth_transition", "log_spread")
            r = np.exp(s * np.linspace(-1, 1, 5))
            widths = list(r / r.mean())
        vh = np.zeros_like(q)
        a_c = 1.0
        if "viscous_hysteresis" in self.effects:
            beta = self._get(theta, "viscous_hysteresis", "beta_s")
            tau_v = np.exp(self._get(theta, "viscous_hysteresis", "log_tau_v"))
            vh = beta * lowpass(np.abs(np.gradient(q, 1.0 / INTERNAL_HZ)), tau_v, INTERNAL_HZ)
            ltc = self._get(theta, "viscous_hysteresis", "log_tau_c")
            lo_tc = NONLIN["viscous_hysteresis"][2][2]
            a_c = 1.0 if ltc <= lo_tc + 1e-9 else -np.expm1(-1.0 / (np.exp(ltc) * INTERNAL_HZ))
        # B(z): natural cubic spline through the knots, held beyond them, on a fine z grid.
        Bg = np.maximum(CubicSpline(self.kn, Bk, bc_type="natural")(np.clip(self.zg, self.kn[0], self.kn[-1])), 0.0)
        zs = []
        for r in widths:
            # Band edges as in playscope.fit.model (z + B(z)/2 = q going up, z - B(z)/2 = q going
            # down), inverted on the z grid by np.interp (z + B(z)/2 is increasing for |B'| < 2).
            zu = np.interp(q - vh, *self._edge(self.zg, (1 + alpha) * r * Bg / 2))
            zd = np.interp(q + vh, *self._edge(self.zg, -(1 - alpha) * r * Bg / 2))
            zs.append(play_edges(zu, zd, z0) if a_c >= 1.0 else _viscous_play(zu, zd, z0, a_c))
        z = zs[0] if len(zs) == 1 else np.mean(zs, axis=0)
        sdir = _direction(z)
        if "handeye_direction" in self.effects:
            w = np.exp(self._get(theta, "handeye_direction", "log_travel")) * 2 * self.q_half
            sdir = _switch(z, w)
        if "stick_slip" in self.effects:
            # The carrier sticks and slips behind the play output (stiction in the transmission,
            # before f_remain: the prediction stays linear in f_remain's coefficients).
            z = _karnopp_carrier(z, INTERNAL_HZ, self._get(theta, "stick_slip", "static_q"),
                                 self._get(theta, "stick_slip", "kin_ratio"),
                                 np.exp(self._get(theta, "stick_slip", "log_fn")),
                                 self._get(theta, "stick_slip", "zeta"))
        if "travel_relaxation" in self.effects:
            # After the play and the carrier, before the distal band and f_remain: where the
            # product's board runs it (c = f(R[y]), playscope.fit.relax).
            from ..fit.relax import Relaxation
            z = Relaxation(self._get(theta, "travel_relaxation", "kappa"),
                           float(np.exp(self._get(theta, "travel_relaxation", "log_lambda_q")))).direct(z)
        return z, sdir

    def design(self, theta: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Design matrix (Nm, n_coef) at the measurement rows for nonlinear parameters theta; with
        ``rows`` (bool (Nm,)) only those rows, (rows.sum(), n_coef), the same values. Why rows: a
        fit needs its own rows only (half of a record), and the basis is then built only up to
        the last internal sample they reach (everything before it is causal: the play, the
        elongation's low-pass), which halves the cost of each of a fit's evaluations."""
        d = self.d
        z, sdir = self._play_output(theta)
        if "dead_zone" in self.effects and self.dead_zone_side == "distal":
            # Dead band on the distal side: the bend does not follow the play output while z
            # crosses [z0 - w, z0 + w] (a joint that is slack near one configuration). It is a static
            # map of z, but with kinks f_remain's 12 knots cannot follow; same parameters (q units).
            ends = self._z_ends(theta, z)
            zc, w = self._band(theta, ends)
            z = zc + _distal_stretch(_dead_band(z - zc, w, self._corner(theta) * w), zc, w, ends)
        delay = d.t_delay_s + (self._get(theta, "camera_delay", "delay_s") if "camera_delay" in self.effects else 0.0)
        tq = d.t_m - delay
        t_m = d.t_m
        n_int = d.t_int.size
        if rows is not None:
            tq, t_m = tq[rows], t_m[rows]
            # internal samples up to the first one past the last row (np.interp's bracket)
            n_int = min(int(np.searchsorted(d.t_int, tq.max(), side="right")) + 1, n_int) if tq.size else 2
        t_int = d.t_int[:n_int]
        x = np.clip((z[:n_int] - self.q_mid) / self.q_half, -1.5, 1.5)
        Phi = design_dense(x, self.ftk, self.ftk.size - 4)
        if "cable_elongation" in self.effects:
            kappa = self._get(theta, "cable_elongation", "kappa")
            tau = np.exp(self._get(theta, "cable_elongation", "log_tau"))
            Phi = Phi + kappa * (lowpass(Phi, tau, INTERNAL_HZ) - Phi)
        extra = []
        if "drift" in self.effects:
            extra.append((t_m - 0.5 * (d.t_m[0] + d.t_m[-1])) / 60.0)
        if "handeye_direction" in self.effects:
            idx = np.clip(np.searchsorted(d.t_int, tq) - 1, 0, d.t_int.size - 1)
            extra.append(sdir[idx])
        nb = Phi.shape[1]
        A = np.empty((tq.size, nb + len(extra)))
        PT = np.ascontiguousarray(Phi.T)
        for j in range(nb):
            A[:, j] = np.interp(tq, t_int, PT[j])
        for j, c in enumerate(extra):
            A[:, nb + j] = c
        return A

    def _solve(self, theta, mask):
        """(A_m, coef, m): the design at the rows m = mask & finite y only, and f_remain's (and the
        other linear) coefficients solved on them."""
        y = self.d.y_m
        m = mask & np.isfinite(y)
        Am = self.design(theta, m)
        # Normal equations: ~14 well-conditioned columns (B-spline basis), 6x cheaper than lstsq's
        # SVD in the inner loop; lstsq only when the system is singular (e.g. a dead column).
        try:
            G = Am.T @ Am
            G[np.diag_indices_from(G)] += 1e-10 * np.trace(G) / G.shape[0]  # basis splines without data
            coef = np.linalg.solve(G, Am.T @ y[m])
        except np.linalg.LinAlgError:
            coef, *_ = np.linalg.lstsq(Am, y[m], rcond=None)
        return Am, coef, m

    def predict(self, theta: np.ndarray, coef: np.ndarray) -> np.ndarray:
        """c (Nm,) deg predicted with given nonlinear parameters and linear coefficients."""
        return self.design(theta) @ coef

    def residual(self, theta, mask):
        Am, coef, m = self._solve(theta, mask)
        return self.d.y_m[m] - Am @ coef

    def fit(self, mask: np.ndarray, theta0: np.ndarray | None = None, grid: bool = True,
            uncertainty: bool = True) -> Fit:
        """Least-squares fit on rows ``mask`` (bool (Nm,)). theta0: start (default: init, with a
        small grid over the effect parameters that have several local minima)."""
        th = self.init.copy() if theta0 is None else np.clip(np.asarray(theta0, float), self.lo, self.hi)
        starts = self._grid(th) if grid else [th]
        best = None
        for s in starts:
            if grid and "dead_zone" in self.effects:
                s = self._profile_dead_zone(s, mask)
            c = float(np.sum(self.residual(s, mask) ** 2))
            if best is None or c < best[0]:
                best = (c, s)
        th = best[1]
        free = np.ones(th.size, bool)
        def fun(p):
            full = th.copy()
            full[free] = p
            return self.residual(full, mask)
        lo, hi = self.lo[free], self.hi[free]
        p0 = np.clip(th[free], lo + 1e-12, hi - 1e-12)
        res = least_squares(fun, p0, bounds=(lo, hi), diff_step=1e-3, x_scale="jac", max_nfev=40,
                            ftol=1e-6, xtol=1e-6)
        th = th.copy()
        th[free] = res.x
        Am, coef, m = self._solve(th, mask)
        A = self.design(th)
        r = self.d.y_m[m] - Am @ coef
        n = int(m.sum())
        rho = float(np.corrcoef(r[:-1], r[1:])[0, 1]) if n > 3 else 0.0
        # Correlation beyond 0.9 is model misfit rather than noise: it is not allowed to shrink the
        # effective sample below n/19 (else a gross misfit would make every criterion blind).
        rho = min(max(rho, 0.0), 0.9)
        n_eff = max(n * (1 - rho) / (1 + rho), 10.0)
        rss = float(np.sum(r * r))
        k = int(free.sum()) + A.shape[1]
        pred = A @ coef
        fit = Fit(self.effects, th, list(self.names), coef, list(self.coef_names), pred, rss, n, n_eff, k,
                  lo=self.lo.copy(), hi=self.hi.copy())
        if uncertainty:
            s2 = rss / max(n - k, 1) * n / n_eff  # inflate for autocorrelated residuals
            J = res.jac
            cov_free = np.full((free.sum(), free.sum()), np.nan)
            try:
                cov_free = np.linalg.pinv(J.T @ J) * s2
            except np.linalg.LinAlgError:
                pass
            cov = np.full((th.size, th.size), np.nan)
            cov[np.ix_(free, free)] = cov_free
            fit.cov_theta = cov
            try:
                fit.cov_coef = np.linalg.pinv(Am.T @ Am) * s2
            except np.linalg.LinAlgError:
                pass
        return fit

    def _profile_dead_zone(self, th: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """A dead-band start refined in its own two parameters (centre, half-width), the rest held,
        before the starts are compared. Why: the band's centre is a location parameter with a
        plateau -- a band that sits where the data does not reach (or outside the travel) is a
        constant shift that f_remain absorbs, so such a start costs what the base costs, while a
        start near the true band but of the wrong width costs more until the width has moved.
        Compared unrefined, the plateau wins and the full fit stays on it (blind self-test, dev
        seed 2000: the soft distal band near straight, found from the centre start when refined,
        was missed; the band went to the edge of the travel). PROFILE_NFEV iterations of two
        parameters cost about 3 PROFILE_NFEV model evaluations a start (at most 24; its share of
        the self-test's wall time was not measured apart).
        th: (n_params,) start; mask: bool (Nm,) fit rows. Returns a new (n_params,) start with w_q
        and z0_q refined inside their bounds."""
        idx = [self.names.index("dead_zone.w_q"), self.names.index("dead_zone.z0_q")]
        lo, hi = self.lo[idx], self.hi[idx]

        def fun(p):
            full = th.copy()
            full[idx] = p
            return self.residual(full, mask)
        p0 = np.clip(th[idx], lo + 1e-12, hi - 1e-12)
        res = least_squares(fun, p0, bounds=(lo, hi), diff_step=1e-3, x_scale="jac", max_nfev=PROFILE_NFEV,
                            ftol=1e-4, xtol=1e-4)
        out = th.copy()
        out[idx] = res.x
        return out

    def _grid(self, th: np.ndarray) -> list[np.ndarray]:
        """Starting points: th plus a small grid over multi-modal effect parameters."""
        starts = [th]
        span = self.d.q_hi - self.d.q_lo
        for e in self.effects:
            new = []
            for s in starts:
                if e == "dead_zone":
                    for zc in np.linspace(self.d.q_lo + 0.05 * span, self.d.q_hi - 0.05 * span, 7):
                        for w in (0.03 * span, 0.08 * span):
                            x = s.copy()
                            x[self.names.index("dead_zone.z0_q")] = zc
                            x[self.names.index("dead_zone.w_q")] = w
                            new.append(x)
                elif e == "stick_slip":
                    # breakaway lag x kinetic ratio x natural frequency (the slips' size and
                    # their ring are not found from one start)
                    # (the first start, a stiff well-damped carrier with a tiny breakaway lag, is
                    # the base model to within a few ms of lag: the fit starts from it)
                    combos = [(1e-4, 0.5, 60.0, 1.0)] + [(st, kr, fn, 0.5) for st in (0.003, 0.008, 0.02)
                                                           for kr in (0.3, 0.7) for fn in (12.0, 30.0)]
                    for st, kr, fn, zt in combos:
                        x = s.copy()
                        x[self.names.index("stick_slip.static_q")] = st * span
                        x[self.names.index("stick_slip.kin_ratio")] = kr
                        x[self.names.index("stick_slip.log_fn")] = np.log(fn)
                        x[self.names.index("stick_slip.zeta")] = zt
                        new.append(x)
                elif e == "cable_elongation":
                    for lt in np.log([0.2, 1.0, 4.0]):
                        x = s.copy()
                        x[self.names.index("cable_elongation.log_tau")] = lt
                        new.append(x)
                elif e == "travel_relaxation":
                    for lf in (0.02, 0.1, 0.4):
                        x = s.copy()
                        x[self.names.index("travel_relaxation.log_lambda_q")] = np.log(lf * span)
                        new.append(x)
                elif e == "smooth_transition":
                    for sp in (0.3, 0.8, 1.5):
                        x = s.copy()
                        x[self.names.index("smooth_transition.log_spread")] = sp
                        new.append(x)
                elif e == "viscous_hysteresis":
                    # speed-widened band (tau_c at its plain-play bound), then viscous contacts
                    for b, tv, tc in ((0.05, 0.05, 0.002), (0.2, 0.3, 0.002), (0.0, 0.1, 0.1), (0.0, 0.1, 0.3)):
                        x = s.copy()
                        x[self.names.index("viscous_hysteresis.beta_s")] = b
                        x[self.names.index("viscous_hysteresis.log_tau_v")] = np.log(tv)
                        x[self.names.index("viscous_hysteresis.log_tau_c")] = np.log(tc)
                        new.append(x)
                elif e == "handeye_direction":
                    for lt in np.log([0.002, 0.05, 0.2]):
                        x = s.copy()
                        x[self.names.index("handeye_direction.log_travel")] = lt
                        new.append(x)
                elif e == "camera_delay":
                    for dl in (-0.04, 0.04, 0.1):
                        x = s.copy()
                        x[self.names.index("camera_delay.delay_s")] = dl
                        new.append(x)
                else:
                    new.append(s)
            starts = new if new else starts
        return starts


def from_session(session, max_rate_hz: float = 50.0) -> Data:
    """Reduce a playscope Session to Data: c measured (angle) or estimated per frame (eq. 8 with
    the nominal camera and hand-eye, started from f_coarse(q)). Angle records faster than
    max_rate_hz are block-averaged down (the fit needs shape, not rate)."""
    from ..fit.model import ImageModel, f_coarse

    enc = session.encoder
    t, q = enc["t_s"], enc["q"]
    t_int = np.arange(t[0], t[-1], 1.0 / INTERNAL_HZ)
    q_int = np.interp(t_int, t, q)
    delay = float(session.t_delay_s or 0.0)
    extra = {}
    if session.distal_kind == "angle":
        tm, y = session.distal["t_s"], session.distal["c_deg"]
        rate = (tm.size - 1) / max(tm[-1] - tm[0], 1e-9)
        k = int(rate // max_rate_hz)
        if k > 1:
            n = (tm.size // k) * k
            tm = tm[:n].reshape(-1, k).mean(1)
            y = y[:n].reshape(-1, k).mean(1)
        extra["raw"] = (session.distal["t_s"], session.distal["c_deg"])
    else:
        tm = session.marker["t_s"]
        Q = np.column_stack([session.marker["u_px"], session.marker["v_px"]])
        im = ImageModel(session.robot, session.camera, session.hand_eye)
        c0 = f_coarse(np.interp(tm - delay, t, q), session.robot.q_per_rad)
        # Start from a coarse grid search so a poor f_coarse cannot send LM to a wrong branch.
        grid = np.linspace(-150, 150, 601)
        G = im(grid)
        ok = np.all(np.isfinite(G), 1)
        d2 = ((Q[:, None, :] - G[None, ok, :]) ** 2).sum(-1)
        c0 = np.where(np.all(np.isfinite(Q), 1), grid[ok][np.argmin(np.nan_to_num(d2, nan=1e18), 1)], c0)
        y, res = im.estimate_c(Q, c0)
        extra.update({"u": Q[:, 0], "v": Q[:, 1], "reproj_px": res, "J": im.jacobian(np.nan_to_num(y))})
    return Data(t_int, q_int, tm, y, delay, str(session.path or ""), extra)
