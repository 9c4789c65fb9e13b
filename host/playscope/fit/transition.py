"""The smooth transition after the play (docs/method.md, "Transition model"): Prandtl-Ishlinskii operators on the
play centre z, their classical inverse, and the in-situ fit with its model choice.

Direct model per sample k (docs/method.md, "Transition"):
  z[k]   = play of width B(q) (eq. 3, model.play_operator; B measured from onsets, eq. 1)
  p_i[k] = min(z[k] + r_i, max(z[k] - r_i, p_i[k-1]))      classical play operators
  y[k]   = sum_i w_i p_i[k]      0 = r_0 < r_1 < ... , w_0 > 0, w_i >= 0, sum w_i = 1
  c[k]   = f(y[k])               f = f_remain (eq. 9), strictly monotone
The paper's pure play is n = 1 (r_0 = 0, w_0 = 1, y = z).

Inverse (Krejci & Kuhnen 2001, IEE Proc. Control Theory Appl. 148(3); Kuhnen 2003, Eur. J.
Control 9(4)): the inverse of a PI operator with w_0 > 0 is again a PI operator, with
  r'_i = sum_{j<=i} w_j (r_i - r_j),  w'_0 = 1/w_0,
  w'_i = -w_i / (W_i W_{i-1}),  W_i = sum_{j<=i} w_j,
and initial states p'_i = sum_{j<=i} w_j p_i + sum_{j>i} w_j p_j (inverse_params, inverse_state).

Fit (fit_weights): c ~ f(P w) by variable projection: for given weights f is linear in its
spline coefficients and solved exactly inside; the weights are found by the bounded
scipy.optimize.least_squares on the projected residual (w >= 0, w_0 > 0, sum 1); the final f
is the inner P-spline at the solution (the f the weights were fitted with and the
cross-validation scored), or the monotone robust spline of c on y (bspline.robust_spline) when
that P-spline is not strictly monotone (the table needs f^-1, eq. 9).

Settings, all from the calibration data by rules fixed a priori (choose_model, docs/method.md):
  b_scale     the play width of the model, one of B_SCALES = {1, 1/2} x the onset-measured B:
              an onset detector fires once the tip has moved by its threshold, so when the
              transition starts with a slow creep the measured B already includes part of it;
              the operators can only widen the play, so a narrower anchor lets them model the
              creep (1 for the paper's play);
  thresholds  N_OPS = PST_MAX_OPS operators, r_i = r_span (i / N_OPS)^2, r_span = E, E the largest
              excursion of the play centre z between reversals in the calibration record: an
              operator of threshold r closes a loop only on a stroke longer than 2 r, so the
              ones above E/2 move only on the record's first loading (the virgin curve, which
              a running board holds in its state): they let the fit take that curve without
              bending the loop weights. Quadratic spacing puts half the operators below E/4,
              where every stroke shows the transition after the play; the non-negative
              weights prune the count;
  f_ctrl      f's control points, one of F_CTRL = {4 (a single cubic), 14 (f_remain's)};
  thresholds  constant, or proportional to the onset width B(z) (ThresholdMap: the classical
              PI on u = g(z), g' = b_ref / B), the latter offered only when B's shape is
              measured (threshold_kinds: >= 2 onset samples per B control point);
  choice      cross-validation on a rolling origin (rolling_origins: fit on the calibration
              frames before each of KFOLD origins, score the next block, the operators run from
              the record's start), then the one-standard-error rule: the fewest operators, then
              b_scale closest to 1, then the stiffest f, within one standard error of the best.
Units: q, z, y, r in actuator units (mm or deg of command), c in deg, t in s.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from scipy.linalg import cho_factor, cho_solve
from threadpoolctl import ThreadpoolController

from .bspline import SplineFn, clamped_knots, design_dense, robust_spline
from .reversals import detect_reversals
from . import model
from ..base import kernels, native

B_SCALES = (1.0, 0.5)                  # play width candidates, x onset-measured B
SPAN_EXCURSION = 1.0                   # r_span = the largest excursion of z between reversals
F_CTRL = (4, 14)                       # f's control points: 4 = one cubic, 14 = f_remain's spline
KFOLD = 4                              # CV origins (rolling_origins)
CONSTANT_ONLY = (False,)               # threshold kinds: constant only (the classical PI)
BOTH_KINDS = (False, True)             # constant, then B-proportional (ThresholdMap)
MAP_SAMPLES_PER_CTRL = 2               # B samples per B-spline control point to offer the map
B_FLOOR = 0.1                          # the map's B is floored at B_FLOOR x b_ref (g' <= 1/B_FLOOR)
MAP_POINTS = 129                       # grid points of the threshold map (host float model)
V_MAX = 1e3                            # v_i <= 1000 v_0: w_0 >= 1/(1 + 1000 (n-1)) > 0 (inverse needs 1/w_0)


# --------------------------------------------------------------------------- operators
def play_ops(x: np.ndarray, r: np.ndarray, p0: np.ndarray | float | None = None) -> np.ndarray:
    """Classical play operators of thresholds r over the input x (the transition model, docs/method.md).

    p_i[k] = min(x[k] + r_i, max(x[k] - r_i, p_i[k-1])), p_i[-1] = p0 (default x[0]: every
    operator centred). x: (N,), r: (n,) >= 0. Returns P (N, n) in the unit of x."""
    x = np.asarray(x, float).ravel()
    r = np.asarray(r, float).ravel()
    p = np.array(np.broadcast_to(x[0] if p0 is None else p0, r.shape), float)
    if kernels.available():  # the same recursion in C, bit for bit (base/kernels.c, dk_play_ops)
        return kernels.play_ops(x, r, p)
    return _play_ops_numpy(x, r, p)


def _play_ops_numpy(x: np.ndarray, r: np.ndarray, p: np.ndarray) -> np.ndarray:
    """play_ops' recursion in numpy (the reference of kernels.play_ops): x (N,), r (n,), p (n,)
    the state before x[0], overwritten. Returns P (N, n)."""
    P = np.empty((x.size, r.size))
    lo, hi = x[:, None] - r[None, :], x[:, None] + r[None, :]
    for k in range(x.size):  # sequential by nature; vectorised over the operators
        np.minimum(hi[k], np.maximum(lo[k], p, out=p), out=p)
        P[k] = p
    return P


def __getattr__(name: str) -> int:
    # N_OPS: operators of the PI candidates, the most a table holds (PST_MAX_OPS), read from the
    # C on first use so that importing this module does not compile the core.
    if name == "N_OPS":
        return native.MAX_OPS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def thresholds(n: int, r_span: float) -> np.ndarray:
    """r_i = r_span (i / n)^2, i = 0..n-1 (r_0 = 0): nested for n = 2, 4, 8, 16, dense at
    small thresholds (the transition just after the play, seen on every stroke) and sparse at
    wide ones (seen only on the longest strokes and the record's first loading)."""
    return float(r_span) * (np.arange(n) / n) ** 2


def inverse_params(r: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Thresholds and weights (r', w') of the inverse PI operator (Krejci & Kuhnen 2001).

    r: (n,) increasing with r_0 = 0; w: (n,), w_0 > 0, w_i >= 0. Returns (r' (n,), w' (n,)):
    z = sum_i w'_i p'_i(y) with p'_i plays of threshold r'_i. Errors: ValueError for w_0 <= 0."""
    r, w = np.asarray(r, float), np.asarray(w, float)
    if w[0] <= 0:
        raise ValueError("w_0 must be > 0 for the PI operator to be invertible")
    W = np.cumsum(w)
    r_inv = np.array([np.sum(w[: i + 1] * (r[i] - r[: i + 1])) for i in range(r.size)])
    w_inv = np.empty_like(w)
    w_inv[0] = 1.0 / w[0]
    w_inv[1:] = -w[1:] / (W[1:] * W[:-1])
    return r_inv, w_inv


def inverse_state(w: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Initial states of the inverse operators from the direct ones (Kuhnen 2003):
    p'_i = sum_{j<=i} w_j p_i + sum_{j>i} w_j p_j. w, p: (n,). Returns (n,)."""
    w, p = np.asarray(w, float), np.asarray(p, float)
    W = np.cumsum(w)
    tail = np.cumsum((w * p)[::-1])[::-1]  # sum_{j>=i} w_j p_j
    return W * p + np.r_[tail[1:], 0.0]




def _interp_linear_ends(x, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolation of (xp, fp), xp increasing, continued beyond the ends
    with the end segments' slopes (np.interp would clamp)."""
    x = np.asarray(x, float)
    out = np.interp(x, xp, fp)
    lo, hi = x < xp[0], x > xp[-1]
    if np.any(lo):
        out[lo] = fp[0] + (x[lo] - xp[0]) * (fp[1] - fp[0]) / (xp[1] - xp[0])
    if np.any(hi):
        out[hi] = fp[-1] + (x[hi] - xp[-1]) * (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
    return out


@dataclass
class ThresholdMap:
    """The map g that makes the operators' thresholds proportional to the onset width B(z)
    (a generalized PI with position-dependent thresholds, docs/method.md "B-proportional
    thresholds"): u = g(z) = z_0 + integral_{z_0}^{z} b_ref / B(s) ds, so a threshold r in u is
    r B(z) / b_ref in z, to first order in the change of B over one threshold. g is strictly
    increasing (B floored at B_FLOOR b_ref), so the classical PI on u keeps its exact inverse
    (Krejci & Kuhnen 2001) and the model's inverse is g^-1 after it.

    z, u: (m,) grid, both strictly increasing, actuator units; linear beyond the grid."""

    z: np.ndarray
    u: np.ndarray

    def __post_init__(self):
        self.z = np.asarray(self.z, float).ravel()
        self.u = np.asarray(self.u, float).ravel()
        if self.z.size < 2 or self.z.size != self.u.size:
            raise ValueError("threshold map: z and u must have the same length >= 2")
        if np.any(np.diff(self.z) <= 0) or np.any(np.diff(self.u) <= 0):
            raise ValueError("threshold map: z and u must increase strictly")

    @classmethod
    def from_backlash(cls, B, z_lo: float, z_hi: float, m: int = MAP_POINTS) -> "ThresholdMap":
        """g from the onset width B (callable, actuator units) over [z_lo, z_hi]: trapezoidal
        integral of b_ref / max(B, B_FLOOR b_ref) on m points, b_ref the median of B there (so
        that g' is 1 on average and u stays in the unit of z), g(z_lo) = z_lo."""
        z = np.linspace(float(z_lo), float(z_hi), int(m))
        b = np.asarray(B(z), float)
        b_ref = float(np.median(b))
        if not np.isfinite(b_ref) or b_ref <= 0:
            raise ValueError("threshold map: the onset width B must be positive")
        slope = b_ref / np.maximum(b, B_FLOOR * b_ref)
        u = z[0] + np.r_[0.0, np.cumsum(0.5 * (slope[1:] + slope[:-1]) * np.diff(z))]
        return cls(z, u)

    def fwd(self, z):
        """u = g(z): z any shape, actuator units -> u, same shape and unit."""
        return _interp_linear_ends(z, self.z, self.u)

    def inv(self, u):
        """z = g^-1(u): u any shape, actuator units -> z, same shape and unit."""
        return _interp_linear_ends(u, self.u, self.z)

    def to_json(self) -> dict:
        """{"z": [m], "u": [m]} (docs/calibration-format.md, transition.threshold_map)."""
        return {"z": self.z.tolist(), "u": self.u.tolist()}

    @classmethod
    def from_json(cls, d: dict) -> "ThresholdMap":
        return cls(np.asarray(d["z"], float), np.asarray(d["u"], float))


@dataclass
class Transition:
    """The PI part: thresholds r (n,) actuator units, weights w (n,) summing to 1, and b_scale,
    the play width of the model as a fraction of the onset-measured B (1: B itself)."""

    r: np.ndarray
    w: np.ndarray
    b_scale: float = 1.0
    tmap: ThresholdMap | None = None  # B-proportional thresholds: the operators run on g(z)

    def __post_init__(self):
        self.r = np.asarray(self.r, float).ravel()
        self.w = np.asarray(self.w, float).ravel()
        if self.r.size != self.w.size or self.r.size == 0:
            raise ValueError("r and w must be non-empty and of the same length")
        if self.r[0] != 0 or np.any(np.diff(self.r) <= 0):
            raise ValueError("thresholds must start at 0 and increase strictly")
        if self.w[0] <= 0 or np.any(self.w < 0) or abs(self.w.sum() - 1) > 1e-9:
            raise ValueError("weights must be >= 0 with w_0 > 0 and sum 1")
        if not 0 < self.b_scale <= 1:
            raise ValueError("b_scale must be in (0, 1]")

    @classmethod
    def play(cls) -> "Transition":
        """n = 1: y = z, the paper's pure play."""
        return cls(np.zeros(1), np.ones(1))

    @property
    def n(self) -> int:
        return int(self.r.size)

    @property
    def is_play(self) -> bool:
        """The paper's pure play: no operator and the onset width as measured."""
        return self.n == 1 and self.b_scale == 1.0

    def play_width(self, B):
        """The model's play width b_scale x B(q) (callable on arrays)."""
        if self.b_scale == 1.0:
            return B
        k = self.b_scale
        return lambda q: k * np.asarray(B(q), float)

    def to_ops(self, z: np.ndarray) -> np.ndarray:
        """The operators' input: z, or u = g(z) with B-proportional thresholds (ThresholdMap).
        z: any shape, actuator units; returns the same shape and unit."""
        return z if self.tmap is None else self.tmap.fwd(z)

    def from_ops(self, u: np.ndarray) -> np.ndarray:
        """The inverse of to_ops: u (any shape, actuator units) -> z, same shape."""
        return u if self.tmap is None else self.tmap.inv(u)

    def direct(self, z: np.ndarray, p0=None) -> np.ndarray:
        """y = sum w_i p_i(x), x = z or g(z) (the transition model, docs/method.md). z: (N,); returns y (N,) in
        the unit of x."""
        return play_ops(self.to_ops(np.asarray(z, float)), self.r, p0) @ self.w

    def inverse(self, y: np.ndarray, p0=None) -> np.ndarray:
        """z = PI^-1(y) by the inverse PI operator. p0: states of the direct operators at
        the start (default: all at y[0], i.e. z[0] = y[0]). y: (N,); returns z (N,)."""
        r_inv, w_inv = inverse_params(self.r, self.w)
        y = np.asarray(y, float).ravel()
        p = np.full(self.n, y[0]) if p0 is None else np.asarray(p0, float)
        return self.from_ops(play_ops(y, r_inv, inverse_state(self.w, p)) @ w_inv)

    def to_json(self) -> dict:
        d = {"r": self.r.tolist(), "w": self.w.tolist(), "b_scale": float(self.b_scale)}
        if self.tmap is not None:
            d["threshold_map"] = self.tmap.to_json()
        return d

    @classmethod
    def from_json(cls, d: dict) -> "Transition":
        tm = d.get("threshold_map")
        return cls(np.asarray(d["r"], float), np.asarray(d["w"], float), float(d.get("b_scale", 1.0)),
                   ThresholdMap.from_json(tm) if tm else None)


# --------------------------------------------------------------------------- float chain
def direct_chain(q: np.ndarray, B, tr: Transition, f, z0: float | None = None) -> np.ndarray:
    """c = f(PI(play(q; B))) from the record's start (the transition model's direct model, docs/method.md). q: (N,); B: the
    model's play width (tr.play_width(B_onset))."""
    z = model.play_operator(q, B, z0)
    return f(tr.direct(z))


def compensate_chain(c_ref: np.ndarray, B, tr: Transition, f_inv, f_sign: int) -> np.ndarray:
    """q* for a reference c* (the transition model's inverse, docs/method.md), B the model's play width: y* = f^-1(c*), z* = PI^-1(y*), then
    q* = z* + dir B(z*)/2 with dir the direction of z* (= f_sign x direction of c*, eqs. 4/5/9),
    held while z* is still, 0 before it first moves. c_ref: (N,) deg; returns q* (N,)."""
    y = f_inv(np.asarray(c_ref, float).ravel())
    z = tr.inverse(y)
    d = np.sign(np.diff(z, prepend=z[:1]))
    idx = np.where(d != 0, np.arange(d.size), 0)
    np.maximum.accumulate(idx, out=idx)
    dirs = np.where(idx > 0, d[idx], 0.0)
    return z + dirs * 0.5 * B(z)


def f_inverse(f, lo: float, hi: float, n: int = 20001):
    """Numeric inverse of a strictly monotone f on [lo, hi] (linear ends beyond): c -> y."""
    g = np.linspace(lo, hi, n)
    fg = f(g)
    o = np.argsort(fg)
    return lambda c: np.interp(c, fg[o], g[o])


# --------------------------------------------------------------------------- fit
def turning_points(x: np.ndarray) -> np.ndarray:
    """Indices of x's first and last samples and of every sample where its direction of
    motion reverses (flat stretches skipped). Play operators are rate-independent and between
    two such points x is monotone, so their outputs only depend on these samples."""
    x = np.asarray(x, float)
    nz = np.flatnonzero(np.diff(x))
    if nz.size < 2:
        return np.array([0, x.size - 1])
    s = np.sign(np.diff(x)[nz])
    turns = nz[1:][s[1:] != s[:-1]]
    return np.unique(np.r_[0, turns, x.size - 1])


@dataclass
class FitData:
    """One session prepared for the fit: the encoder record (for the play centre from the
    record's start) and the frames (acquisition times already shifted by t_delay) with their c.

    t_enc, q_enc: (N,) s, actuator units; B: onset width callable (eq. 1); t_frame, c: (F,)
    s, deg; b_med: median onset width over the travel."""

    t_enc: np.ndarray
    q_enc: np.ndarray
    B: object
    t_frame: np.ndarray
    c: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_session(cls, t_enc, q, B, t_f, c_f, t_delay_s: float) -> "FitData":
        """Encoder t_enc (N,) s and q (N,) actuator units, B(q), frames t_f (F,) s and angles
        c_f (F,) deg (NaN rows dropped), frame times moved back by the acquisition delay (s)."""
        ok = np.isfinite(c_f)
        return cls(np.asarray(t_enc, float), np.asarray(q, float), B, np.asarray(t_f, float)[ok] - t_delay_s,
                   np.asarray(c_f, float)[ok])

    def with_B(self, B) -> "FitData":
        """The same session with another onset width B(q): shares the reduced path (_reduced:
        q's turning points and the frames' q, which do not depend on B), so the B alternatives
        of the calibration (calibration.choose_b_and_model) compute it once."""
        out = FitData(self.t_enc, self.q_enc, B, self.t_frame, self.c)
        self._reduced()
        out._cache["red"] = self._cache["red"]
        return out

    @property
    def b_med(self) -> float:
        """Median of B over the travelled q range (actuator units)."""
        return float(np.median(self.B(np.linspace(self.q_enc.min(), self.q_enc.max(), 201))))

    def z_enc(self, b_scale: float = 1.0) -> np.ndarray:
        """Play centre (eq. 3) of width b_scale x B(q) at the encoder rate, from the record's start."""
        key = ("z", round(b_scale, 12))
        if key not in self._cache:
            B = self.B
            self._cache[key] = model.play_operator(self.q_enc, lambda x: b_scale * B(x))
        return self._cache[key]

    def _reduced(self) -> tuple[np.ndarray, np.ndarray]:
        """The encoder path reduced to what rate-independent operators depend on: q at its
        turning points (turning_points) and at the frames' acquisition times, in time order
        (frames after an encoder sample of the same time). Returns (order of the reduced
        samples, q there); the frames are the last F entries before ordering."""
        if "red" not in self._cache:
            k = turning_points(self.q_enc)
            t = np.r_[self.t_enc[k], self.t_frame]
            x = np.r_[self.q_enc[k], np.interp(self.t_frame, self.t_enc, self.q_enc)]
            order = np.argsort(t, kind="stable")
            self._cache["red"] = (order, x[order])
        return self._cache["red"]

    def z_reduced(self, b_scale: float = 1.0) -> np.ndarray:
        """Play centre (eq. 3) of width b_scale x B(q) on the reduced path (_reduced), from the
        record's start: the same values as z_enc at q's turning points (the play is
        rate-independent and monotone between them), and the play of q at the frame times."""
        key = ("zr", round(b_scale, 12))
        if key not in self._cache:
            B = self.B
            _, x = self._reduced()
            self._cache[key] = model.play_operator(x, lambda v: b_scale * B(v), float(self.q_enc[0]))
        return self._cache[key]

    def threshold_map(self) -> ThresholdMap:
        """The B-proportional thresholds' map g (ThresholdMap) of this record's onset width,
        over the travelled q range widened by the largest B on each side (z stays within
        half a play of q)."""
        if "tmap" not in self._cache:
            q0, q1 = float(self.q_enc.min()), float(self.q_enc.max())
            pad = float(np.max(self.B(np.linspace(q0, q1, 201))))
            self._cache["tmap"] = ThresholdMap.from_backlash(self.B, q0 - pad, q1 + pad)
        return self._cache["tmap"]

    def ops_input_reduced(self, b_scale: float = 1.0, scaled: bool = False) -> np.ndarray:
        """The operators' input on the reduced path: the play centre z, or u = g(z) for
        B-proportional thresholds (threshold_map)."""
        z = self.z_reduced(b_scale)
        return self.threshold_map().fwd(z) if scaled else z

    def ops_at_frames(self, r: np.ndarray, b_scale: float = 1.0, scaled: bool = False) -> np.ndarray:
        """P (F, n): the operators run over the whole record from its start (the state a
        running board holds), read at the frames' acquisition times. Run on the reduced path
        (exact at q's turning points: see turning_points). scaled: the operators run on
        u = g(z) (B-proportional thresholds, ThresholdMap)."""
        key = ("P", round(b_scale, 12), tuple(np.round(r, 12)), bool(scaled))
        if key not in self._cache:
            order, _ = self._reduced()
            z = self.ops_input_reduced(b_scale, scaled)
            P = play_ops(z, r, z[0])
            out = np.empty((z.size, r.size))
            out[order] = P
            self._cache[key] = out[z.size - self.t_frame.size:]
        return self._cache[key]


def fit_f(y, c, n_ctrl, smooth=1e-3, sign=None, min_slope: float = 0.0):
    """f: monotone robust cubic spline of c on y over y's range, linear ends (as f_remain).
    y, c: (F,) operator output (actuator units) and angle (deg) at the frames; min_slope:
    |f'| >= min_slope, deg per actuator unit (bspline.robust_spline). Returns (SplineFn, sign)."""
    sign = sign or (1 if np.corrcoef(y, c)[0, 1] >= 0 else -1)
    lo, hi = float(y.min()), float(y.max())
    spl, _ = robust_spline(y, c, n_ctrl, lo, hi, smooth, monotone=sign, min_slope=min_slope)
    return SplineFn(spl, lo, hi, linear_ends=True), sign


class _SplineProjection:
    """P-spline least squares of c on y (the inner solve of fit_weights) and its residual's
    Jacobian in the weights by Kaufman's variable-projection approximation (Golub & Pereyra
    2003, Inverse Problems 19(2)): J = (I - Pi) diag(f'(y)) dy/dv, Pi the fit's projection."""

    def __init__(self, P: np.ndarray, c: np.ndarray, n_ctrl: int, smooth: float):
        self.P, self.c, self.n_ctrl, self.smooth = P, c, n_ctrl, smooth
        # dy/dv as one contiguous block: the Jacobian scales it by f'(y) at every step, and the
        # strided view P[:, 1:] took twice as long for the same products.
        self.dy_dv = np.ascontiguousarray(P[:, 1:])
        D = np.diff(np.eye(n_ctrl), 2, axis=0)
        self.DtD = D.T @ D
        self._key, self._val = None, None

    def _solve(self, x: np.ndarray):
        key = x.tobytes()
        if key != self._key:
            y = self.P[:, 0] + self.P[:, 1:] @ x
            lo, hi = float(y.min()), float(y.max())
            hi = max(hi, lo + 1e-9)
            t = clamped_knots(lo, hi, self.n_ctrl)
            yc = np.clip(y, lo, hi)
            A = design_dense(yc, t, self.n_ctrl)
            AtA = A.T @ A
            lam = self.smooth * np.trace(AtA) / self.n_ctrl
            # Normal equations of the penalised fit (n_ctrl x n_ctrl, well conditioned by the
            # penalty): the projection of any G is A (N^-1 A^T G).
            N = AtA + lam * self.DtD
            cho = cho_factor(N)
            coef = cho_solve(cho, A.T @ self.c)
            self._key, self._val = key, (A, cho, coef, t, yc)
        return self._val

    def resid(self, x):
        A, _, coef, _, _ = self._solve(x)
        return A @ coef - self.c

    def jac(self, x, out: np.ndarray | None = None):
        """J (F, n-1) at x; into out (F, n-1), any strides, when given (the same values)."""
        from scipy.interpolate import BSpline

        # f'(y) here, not in _solve: a caller that needs only the residual does not pay for it
        # (fit_weights' _CompressedProjection needs both at every trial point).
        A, cho, coef, t, yc = self._solve(x)
        der = BSpline(t, coef, 3).derivative()
        slope = der(yc)
        G = np.multiply(slope[:, None], self.dy_dv, out=out)
        # cho_solve returns a Fortran-ordered (n_ctrl, n-1) block, and numpy's A @ X does not
        # reach BLAS for that layout (~50x slower at F = 3000 frames: it was half of calibrate).
        return np.subtract(G, A @ np.ascontiguousarray(cho_solve(cho, A.T @ G)), out=G)


# Rows of the first level's blocks in tall_skinny_r: a block of 512 x 16 doubles (64 KiB) stays
# in cache while its Householder reflectors sweep it.
TSQR_BLOCK = 512


def tall_skinny_r(H: np.ndarray, block: int = TSQR_BLOCK) -> np.ndarray:
    """R of H = Q R (Householder QR, Q never formed) for a tall-thin H (m, n), m >> n: each block of
    rows is reduced to its n x n R, then the stacked R's (and the rows left over) once more
    (Demmel et al. 2012, "Communication-optimal parallel and sequential QR", SIAM J. Sci.
    Comput. 34(1): the tall-skinny QR). R^T R = H^T H as a QR of the whole H gives it, to
    rounding, with a QR's backward stability (no Gram matrix is formed); R's rows may differ in
    sign from another QR's. LAPACK's unblocked QR of a 38,000 x 16 matrix sweeps it from memory
    once per column: this is 2-3 times faster. Returns R (min(m, n), n), upper triangular."""
    H = np.asarray(H, float)
    m, n = H.shape
    k = m // block
    if k < 2 or block <= n:
        return np.linalg.qr(H, mode="r")
    R1 = np.linalg.qr(H[: k * block].reshape(k, block, n), mode="r")  # (k, n, n), one per block
    return np.linalg.qr(np.concatenate([R1.reshape(k * n, n), H[k * block:]]), mode="r")


class _CompressedProjection:
    """The variable-projection problem of _SplineProjection handed to the trust region in n + 1
    rows instead of F (F frames, n weights): at each x, R = tall_skinny_r([J f]) (J (F, n) the
    Jacobian, f (F,) the residual) gives r = R[:, n] and K = R[:, :n] with
    K^T K = J^T J, K^T r = J^T f and r^T r = f^T f. Every quantity scipy's bounded trust region
    ("trf", tr_solver "exact") computes from (f, J) is one of these (the cost, the gradient,
    the SVD's singular values, right vectors and U^T f, the predicted reduction |J p|^2 +
    2 g^T p), so its steps and its stopping are those of the F-row problem, in exact arithmetic;
    in floating point they differ by rounding. What it saves: the SVD of the F x n Jacobian per
    step (half of a fit's time at F = 20,000-40,000 frames) becomes a QR of F x (n + 1) and an
    SVD of (n + 1) x n. The price: J is computed at every trial point, rejected ones too
    (under a tenth of them on the 1-hour log's fits)."""

    def __init__(self, vp: _SplineProjection):
        self.vp = vp
        self._key, self._val = None, None

    def _eval(self, x: np.ndarray):
        key = x.tobytes()
        if key != self._key:
            H = np.empty((self.vp.c.size, self.vp.dy_dv.shape[1] + 1))
            self.vp.jac(x, out=H[:, :-1])
            H[:, -1] = self.vp.resid(x)
            R = tall_skinny_r(H)
            self._key, self._val = key, (np.ascontiguousarray(R[:, -1]), np.ascontiguousarray(R[:, :-1]))
        return self._val

    def resid(self, x):
        return self._eval(x)[0]

    def jac(self, x):
        return self._eval(x)[1]


def fit_weights(P: np.ndarray, c: np.ndarray, n_ctrl: int = 14, smooth: float = 1e-3, robust_f: bool = True,
                v0: np.ndarray | None = None, v_max: float = V_MAX):
    """Weights w and f for c ~ f(P w) (the transition model, docs/method.md), by variable projection.

    P: (F, n) operator outputs at the frames, c: (F,) deg. For given weights f is linear in
    its spline coefficients, so it is solved exactly inside (P-spline least squares, N =
    n_ctrl); the weights are v = (1, v_1..v_{n-1}), v_i in [0, v_max], found by
    scipy.optimize.least_squares (bounded trust region) on the projected residual and
    normalised, w = v / sum v (f absorbs the scale; w_0 = 1/sum v > 0 by construction).
    The final f is the inner P-spline at the solution (the f the weights were optimised
    with and the cross-validation scored); with robust_f=True (the table's f) and that
    P-spline not strictly monotone on y's range, the monotone robust spline of c on y = P w
    instead (bspline.robust_spline, as f_remain), since eq. 9 needs f^-1. v0: (n-1,)
    starting point of v_1.. (a warm start: the previous fold's solution in the
    cross-validation), default all equal. v_max: bound of v_i (choose_model: v_max_for_table).
    Returns (w (n,), f SplineFn, sign of
    f', rms deg on these frames); the solution v is kept as fit_weights.last_v."""
    from scipy.optimize import least_squares

    n = P.shape[1]
    v = np.ones(n)
    v[1:] = 0.0  # v_max 0: the table cannot carry any operator within its precision ceiling
    if n > 1 and v_max > 0:
        vp = _SplineProjection(P, c, n_ctrl, smooth)
        x0 = np.full(n - 1, min(1.0, v_max) / (n - 1)) if v0 is None else np.clip(v0, 0.0, v_max)
        # ftol 1e-6, xtol 1e-5: the CV compares RMSEs to about 1 %, far coarser than the
        # defaults (1e-8). Measured on bench_host's session (its 111 fits, captured): xtol 1e-5
        # takes 12.8 instead of 16.5 evaluations per fit, and with lsmr it moved no fit's RMSE
        # by more than 1.3e-6 (relative). tr_solver "exact" (an SVD of the F x (n-1) Jacobian per
        # step): "lsmr"'s inexact steps stalled short of the optimum on some folds (RMSE up to
        # 60 % above exact's); exact took 3.1 s CPU for the 111 fits against lsmr's 4.9, on one
        # BLAS thread. Threaded (2 cores, both busy) the same fits took 6.9 s wall. The exact
        # solver's SVD is of the (n) x (n-1) compressed problem (_CompressedProjection), not of
        # the F x (n-1) Jacobian.
        with _blas_controller().limit(limits=1, user_api="blas"):
            cp = _CompressedProjection(vp)
            v[1:] = least_squares(cp.resid, x0, jac=cp.jac, bounds=(0.0, v_max), ftol=1e-6, xtol=1e-5,
                                  max_nfev=60, tr_solver="exact").x
    fit_weights.last_v = v[1:].copy()
    w = v / v.sum()
    y = P @ w
    from scipy.interpolate import BSpline

    # f of the projection: the P-spline the weights were optimised with (and that the
    # cross-validation scored). Refitting another f on y afterwards would leave the joint
    # least-squares optimum for weights chosen under a different f.
    vp = _SplineProjection(y[:, None], c, n_ctrl, smooth)
    _, _, coef, _, _ = vp._solve(np.zeros(0))
    lo, hi = float(y.min()), max(float(y.max()), float(y.min()) + 1e-9)
    f = SplineFn(BSpline(clamped_knots(lo, hi, n_ctrl), coef, 3, extrapolate=False), lo, hi, linear_ends=True)
    sign = 1 if f.s_lo + f.s_hi >= 0 else -1
    if robust_f and not _strictly_monotone(f, lo, hi, sign):
        # The table needs f strictly monotone (eq. 9's f^-1): only then the constrained fit.
        f, sign = fit_f(y, c, n_ctrl, smooth)
    return w, f, sign, float(np.sqrt(np.mean((f(y) - c) ** 2)))


@functools.cache
def _blas_controller() -> ThreadpoolController:
    """One threadpoolctl controller for the process: building one scans every loaded library
    (2 ms, 0.3 s over a calibration's fits); its limit() is then a few microseconds."""
    return ThreadpoolController()


def _strictly_monotone(f, lo: float, hi: float, sign: int, n: int = 2001) -> bool:
    """f strictly monotone with direction sign on [lo, hi], sampled on n points, and its
    linear ends (SplineFn linear_ends) going the same way."""
    d = np.diff(f(np.linspace(lo, hi, n)))
    return bool(np.all(sign * d > 0) and sign * f.s_lo > 0 and sign * f.s_hi > 0)


def rolling_origins(data: "FitData", k: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Evaluation on a rolling forecasting origin (Hyndman & Athanasopoulos, "Forecasting:
    Principles and Practice", 3rd ed., sec. 5.10): k (train, test) frame masks, origin j at
    the fraction 1/2 + j/(2k) of the calibration frames (in time order), train = every frame
    before it, test = the next 1/(2k) of the frames. Each test block is scored with the
    operators run from the record's start, exactly as the in-situ evaluation and a running
    board use the model: fitted on what came before, predicting what comes after (the
    virgin loading curve of the record's start is always in the training part, never judged)."""
    F = data.t_frame.size
    order = np.argsort(data.t_frame, kind="stable")
    out = []
    for j in range(k):
        a = int(round(F * (0.5 + j / (2 * k))))
        b = int(round(F * (0.5 + (j + 1) / (2 * k))))
        tr_m, te_m = np.zeros(F, bool), np.zeros(F, bool)
        tr_m[order[:a]], te_m[order[a:b]] = True, True
        out.append((tr_m, te_m))
    return out


def largest_excursion(x: np.ndarray, hysteresis_frac: float = 0.01) -> float:
    """Largest travel of x between consecutive reversals (hysteresis hysteresis_frac of the
    span; the first and last samples count as turning points). x: (N,). Returns its unit."""
    x = np.asarray(x, float)
    span = float(np.ptp(x))
    _, x1, _ = detect_reversals(np.arange(x.size, dtype=float), x, hysteresis_frac * span + 1e-12)
    turns = np.r_[x[0], x1, x[-1]]
    return float(np.max(np.abs(np.diff(turns)))) if turns.size > 1 else span


def v_max_for_table(data: "FitData", b_scale: float, n: int, scaled: bool = False) -> float:
    """Bound of v_i = w_i / w_0 that keeps the table loadable: the inverse PI's worst-case
    error is about 1/w_0 Q16 units (pi_build: 1/2 + 1/2 sum|w'_i|, sum|w'_i| = 2/w_0 - 1), and
    calib_load refuses a table whose error exceeds calib_precision_ceiling_q16(B_max) (1/16 of
    the largest play width). With sum v = 1/w_0 <= ceiling/2 (a factor 2 for the other terms)
    the fitted table always loads: v_i <= (ceiling/2 - 1)/(n - 1), at most V_MAX. B_max: the
    model's play width b_scale x B over the recorded q range. scaled (a threshold map, layout
    3): the loader holds the inverse's error times the map's Lipschitz constant L = max dz/du
    (docs/firmware.md), so the ceiling is divided by L."""
    from ..base.native import core

    _, lib = core()
    q = np.linspace(float(data.q_enc.min()), float(data.q_enc.max()), 201)
    b_max_q16 = int(round(b_scale * float(np.max(data.B(q))) * lib.PS_Q16_ONE))
    ceiling = float(lib.calib_precision_ceiling_q16(min(max(b_max_q16, 0), 2**31 - 1)))
    if scaled:
        tm = data.threshold_map()
        ceiling /= float(np.max(np.diff(tm.z) / np.diff(tm.u)))
    return float(min(V_MAX, max(0.5 * ceiling - 1.0, 0.0) / max(n - 1, 1)))


def threshold_kinds(b_kind: str, b_samples: int, b_ctrl: int) -> tuple[bool, ...]:
    """Which threshold kinds the model choice may offer, from the B fit (rule fixed a priori,
    docs/method.md "B-proportional thresholds"): the map g is the shape of B(q), so it is
    offered only when that shape is measured, not interpolated: a B spline (not a constant)
    with at least MAP_SAMPLES_PER_CTRL onset samples per control point. With fewer (the
    spline has as many coefficients as samples, N = min(14, M)), B between the samples is
    the spline's interpolation of their scatter, and thresholds tied to it would follow that
    scatter. b_kind: BacklashFit.kind; b_samples: onset samples M; b_ctrl: B's control points N."""
    ok = b_kind == "spline" and b_samples >= MAP_SAMPLES_PER_CTRL * max(int(b_ctrl), 1)
    return BOTH_KINDS if ok else CONSTANT_ONLY


def candidates(data: FitData, model_kind: str = "auto", n_ctrl: int = 14,
               kinds: tuple[bool, ...] | None = None) -> list[tuple[float, int, float, int, bool]]:
    """(b_scale, n, r_span, f_ctrl, scaled) tuples tried, fixed a priori (module docstring):
    (1, 1, 0, n_ctrl, False) for the paper's play; for the PI, b_scale in B_SCALES x f_ctrl in
    F_CTRL x thresholds constant or B-proportional (scaled, ThresholdMap), each with N_OPS
    operators at thresholds(N_OPS, r_span), r_span = SPAN_EXCURSION x the largest excursion of
    the operators' input (z, or g(z)) between reversals in the calibration record."""
    out = [(1.0, 1, 0.0, int(n_ctrl), False)] if model_kind in ("auto", "play") else []
    if model_kind in ("auto", "pi"):
        for scaled in (CONSTANT_ONLY if kinds is None else kinds):
            for kb in B_SCALES:
                span = SPAN_EXCURSION * largest_excursion(data.ops_input_reduced(kb, scaled))
                if span > 0:
                    out += [(kb, native.MAX_OPS, span, nc, scaled) for nc in F_CTRL]
    return out


class _CandidateCV:
    """One candidate's rolling-origin CV, run one fold at a time so that it can stop early
    (ModelChoice) and resume later with bit-identical results: fold j starts from fold j-1's
    weights (the folds share most frames), and nothing else carries over between folds."""

    def __init__(self, data: FitData, splits, kb: float, n: int, span: float, nc: int, scaled: bool = False):
        self.kb, self.n, self.span, self.nc, self.scaled = kb, n, float(span), int(nc), bool(scaled)
        self.data, self.splits = data, splits
        self.r = thresholds(n, span) if n > 1 else np.zeros(1)
        self.key = (self.kb, self.n, self.span, self.nc, self.scaled)
        self.errs: list[float] = []
        self._next, self._v, self._P, self._vm = 0, None, None, None
        self._folds: list[tuple] = []  # the FitData cache keys of the folds' weights it stored

    @property
    def done(self) -> bool:
        return self._next >= len(self.splits)

    def step(self) -> None:
        """Fit and score the next scored fold (rolling_origins' folds with too few frames are
        skipped, as choose_model always did)."""
        if self._P is None:  # the operators at the frames and the table's bound, once
            self._P = self.data.ops_at_frames(self.r, self.kb, self.scaled)
            self._vm = v_max_for_table(self.data, self.kb, self.n, self.scaled)
        while not self.done:
            tr_m, te_m = self.splits[self._next]
            self._next += 1
            if te_m.sum() < 3 or tr_m.sum() < 10:
                continue
            P, c = self._P, self.data.c
            w, f, _, _ = fit_weights(P[tr_m], c[tr_m], self.nc, robust_f=False, v0=self._v, v_max=self._vm)
            self._v = fit_weights.last_v  # warm start of the next fold
            self._folds.append(_fold_key(self.key, tr_m))
            self.data._cache[self._folds[-1]] = self._v  # and of the same fit elsewhere (cv_start)
            self.errs.append(float(np.sqrt(np.mean((f(P[te_m] @ w) - c[te_m]) ** 2))))
            return

    def complete(self) -> "_CandidateCV":
        while not self.done:
            self.step()
        return self

    def state(self) -> dict:
        """What the folds so far left: their errors, the next fold, the last weights and the folds'
        weights stored for cv_start ({cache key: (n-1,)}); small, for a pipe (ModelChoice.complete_all)."""
        return {"errs": list(self.errs), "next": self._next, "v": self._v,
                "folds": {k: self.data._cache[k] for k in self._folds}}

    def resume(self, st: dict) -> None:
        """Take up state() of the same candidate on the same data, computed in another process: the
        numbers are those of the folds run here (each fold depends only on this candidate's
        earlier ones), and the folds' weights join this data's cache as if fitted here."""
        self.errs, self._next, self._v = list(st["errs"]), st["next"], st["v"]
        self.data._cache.update(st["folds"])
        self._folds = list(st["folds"])

    def lower_bound(self, k_scored: int) -> float:
        """A lower bound of the final CV RMSE from the folds scored so far: the folds still to
        come add >= 0 to the sum of squares over the k_scored folds."""
        return float(np.sqrt(np.sum(np.square(self.errs)) / max(k_scored, 1)))

    def row(self) -> dict:
        """The choice's candidate row (complete() first)."""
        errs = np.array(self.errs)
        return {"b_scale": self.kb, "n": self.n, "r_span": self.span, "n_ctrl": self.nc, "scaled": self.scaled,
                "cv_rmse_deg": float(np.sqrt(np.mean(errs ** 2))),
                "cv_se_deg": float(np.std(errs, ddof=1) / np.sqrt(errs.size)) if errs.size > 1 else 0.0}


def _fold_key(cand: tuple, train: np.ndarray) -> tuple:
    """FitData cache key of a candidate's weights fitted on the frames train (F,) bool."""
    import hashlib

    return ("cv_v", cand, hashlib.blake2b(np.packbits(train).tobytes(), digest_size=16).digest())


def cv_start(data: FitData, cand: tuple, train: np.ndarray) -> np.ndarray | None:
    """The weights v_1.. (n-1,) that the model choice's cross-validation fitted for candidate
    cand = (b_scale, n, r_span, n_ctrl, scaled) on exactly the frames train (F,) bool, or None
    (not fitted there). A fit of the same candidate on the same frames elsewhere (the family
    choice's onset_transition folds) starts from them: the same least-squares problem, so the
    trust region starts at its solution and only confirms it (or goes on where the
    cross-validation's fit stopped at its evaluation limit) instead of repeating the search."""
    return data._cache.get(_fold_key(cand, np.asarray(train, bool)))


def _preference(d) -> tuple:
    """The one-standard-error rule's order (simplest first): fewest operators, then the onset
    width closest to as measured, then the stiffest f, then constant before B-proportional
    thresholds (the classical PI before its generalisation)."""
    return d["n"], -d["b_scale"], d["n_ctrl"], bool(d.get("scaled", False))


class ModelChoice:
    """choose_model's rule, computed lazily (the calibration runs it once per B(q) alternative,
    calibration.choose_b_and_model, and needs every candidate's CV only for the alternative it
    keeps).

    pick() finds the rule's choice exactly while fitting as few folds as it can prove
    irrelevant: (1) the best CV (it sets the limit best + its SE) is found by scoring folds
    best-first (the open candidate with the lowest lower bound of its CV from the folds scored
    so far, _CandidateCV.lower_bound) and stopping a candidate once that bound exceeds the
    lowest complete CV: it cannot be the best, whatever its remaining folds; (2) the pick is the first candidate in the rule's order
    within the limit: a stopped candidate whose lower bound already exceeds the limit is not,
    any other one is completed and tested. What cannot be skipped: the candidates that could
    still be the best (their SE is part of the limit) and the ones the order reaches before a
    pick. result() completes every candidate (the choice dict lists them all) and gives exactly
    what choose_model gives. Stopping never changes a number: each candidate's folds are the
    same fits in the same order whether run at once or resumed."""

    def __init__(self, data: FitData, model_kind: str = "auto", n_ctrl: int = 14, k: int = KFOLD,
                 kinds: tuple[bool, ...] | None = None):
        if model_kind not in ("auto", "play", "pi"):
            raise ValueError(f"model must be play, pi or auto, not {model_kind!r}")
        self.data, self.model_kind, self.k = data, model_kind, k
        self.kinds = CONSTANT_ONLY if kinds is None else tuple(kinds)
        splits = rolling_origins(data, k)
        self.k_scored = sum(1 for tr_m, te_m in splits if te_m.sum() >= 3 and tr_m.sum() >= 10)
        self.cands = [_CandidateCV(data, splits, *cand) for cand in candidates(data, model_kind, n_ctrl, kinds)]
        self._pick, self._refit = None, None

    # A relative margin for comparing the lower bound (a sum over folds) with a CV RMSE (a mean):
    # the two round differently, and a stop must never rest on a rounding difference.
    _MARGIN = 1e-9

    def _exceeds(self, c: _CandidateCV, level: float) -> bool:
        return c.lower_bound(self.k_scored) > level * (1 + self._MARGIN) + 1e-300

    def pick(self) -> dict:
        """The chosen candidate's row ({"b_scale", "n", "r_span", "n_ctrl", "cv_rmse_deg",
        "cv_se_deg"}), by choose_model's rule."""
        if self._pick is not None:
            return self._pick
        # (1) Best first: always score the next fold of the open candidate with the lowest lower
        # bound (an unscored one has 0), until every open one is above the lowest complete CV.
        # The order of the fits does not change any of them (_CandidateCV).
        while True:
            done = [c for c in self.cands if c.done]
            best_cv = min((c.row()["cv_rmse_deg"] for c in done), default=None)
            open_ = [c for c in self.cands if not c.done
                     and (best_cv is None or not self._exceeds(c, best_cv))]
            if not open_:
                break
            min(open_, key=lambda c: c.lower_bound(self.k_scored)).step()
        rows = [c.row() for c in self.cands if c.done]
        best = min(rows, key=lambda d: d["cv_rmse_deg"])  # the first of equal ones, as choose_model
        limit = best["cv_rmse_deg"] + best["cv_se_deg"]
        for c in sorted(self.cands, key=lambda c: _preference({"n": c.n, "b_scale": c.kb, "n_ctrl": c.nc, "scaled": c.scaled})):
            if not c.done and self._exceeds(c, limit):
                continue  # its CV is above the limit whatever its remaining folds
            row = c.complete().row()
            if row["cv_rmse_deg"] <= limit:
                self._pick = row
                return row
        # Only without any scored fold (every CV NaN; choose_model never had a pick there either).
        raise ValueError("no candidate of the model choice has a cross-validation score (too few frames per fold)")

    def refit(self) -> tuple[Transition, "SplineFn", int, float]:
        """The pick refitted on all the calibration frames: (Transition without its zero-weight
        operators, f, sign of f', fit RMSE deg)."""
        if self._refit is None:
            p = self.pick()
            kb, n, span, nc, sc = p["b_scale"], p["n"], p["r_span"], p["n_ctrl"], p["scaled"]
            r = thresholds(n, span) if n > 1 else np.zeros(1)
            # Started from the candidate's last fold (its weights on the first 7/8 of these
            # frames), as each fold starts from the one before: the closest solution at hand.
            # From the default start the 38,000-frame refit of the 1-hour log ran into its
            # evaluation limit well short of the optimum.
            cand = next(c for c in self.cands if c.key == (kb, n, float(span), int(nc), bool(sc)))
            w, f, sign, rms = fit_weights(self.data.ops_at_frames(r, kb, sc), self.data.c, nc, v0=cand._v,
                                          v_max=v_max_for_table(self.data, kb, n, sc))
            keep = (w > 0) | (np.arange(n) == 0)  # operators with zero weight are dropped from the table
            tmap = self.data.threshold_map() if sc and n > 1 else None
            self._refit = (Transition(r[keep], w[keep] / w[keep].sum(), kb, tmap), f, sign, rms)
        return self._refit

    def complete_all(self) -> None:
        """Every candidate's CV completed, the open candidates shared with a forked child
        (base.forkmap), the most operators first: a candidate's folds are the same fits in the same
        order in either process, and one that the child completed comes back as its state
        (_CandidateCV.state) with the folds' weights it stored, so the choice is the same bit for bit
        whichever process completed what (tests: test_the_model_choice_is_the_same_through_the_pipe).
        Errors: a fit's own error when it raised here; RuntimeError with the child's traceback when it
        raised there (base.forkmap)."""
        from ..base.forkmap import fork_map  # looked up at the call: the tests stand in for it

        todo = [c for c in self.cands if not c.done]
        for c, st in zip(todo, fork_map(lambda c: c.complete().state(), todo, cost=lambda c: float(c.n))):
            c.resume(st)

    def result(self) -> tuple[Transition, "SplineFn", int, dict]:
        """choose_model's return value: every candidate's CV complete (complete_all)."""
        self.complete_all()
        p = self.pick()
        tr, f, sign, rms = self.refit()
        choice = {"model": "play" if tr.is_play else "pi", "n": int(tr.n), "n_tried": int(p["n"]),
                  "b_scale": p["b_scale"], "r_span": float(p["r_span"]), "n_ctrl": int(p["n_ctrl"]),
                  "thresholds": "B-proportional" if p["scaled"] else "constant",
                  "thresholds_offered": ["B-proportional" if k else "constant" for k in self.kinds],
                  "fit_rmse_deg": rms,
                  "rule": "CV on a rolling origin (fit before, score the next block), one-standard-error rule",
                  "folds": int(self.k), "b_median": self.data.b_med, "candidates": [c.row() for c in self.cands]}
        return tr, f, sign, choice


def picked_candidate(choice: dict) -> dict | None:
    """The row of choice["candidates"] that the model choice picked (choose_model's choice
    dict, as stored in the calibration JSON), matched on b_scale, operators tried, r_span,
    f's control points and threshold kind; None when no row matches (a hand-edited file)."""
    key = (choice.get("b_scale"), choice.get("n_tried"), choice.get("r_span"), choice.get("n_ctrl"),
           choice.get("thresholds") == "B-proportional")
    return next((c for c in choice.get("candidates", [])
                 if (c["b_scale"], c["n"], c["r_span"], c.get("n_ctrl"), c.get("scaled", False)) == key), None)


def choose_model(data: FitData, model_kind: str = "auto", n_ctrl: int = 14, k: int = KFOLD,
                 kinds: tuple[bool, ...] | None = None) -> tuple[Transition, "SplineFn", int, dict]:
    """Pick play vs PI, the play width and f's stiffness by cross-validation on the
    calibration frames, then refit the choice on all of them (module docstring for the rule;
    ModelChoice computes it).

    model_kind: "play" (the paper's pure play only), "pi" (operators only) or "auto" (both);
    n_ctrl: f's control points for the pure play (f_remain's N).
    Returns (Transition, f, sign of f', choice dict: {"model", "n", "n_tried", "b_scale",
    "r_span", "n_ctrl", "fit_rmse_deg", "rule", "folds", "b_median", "candidates": [{"b_scale",
    "n", "r_span", "n_ctrl", "cv_rmse_deg", "cv_se_deg"}]}). Errors: ValueError for an
    unknown model_kind."""
    return ModelChoice(data, model_kind, n_ctrl, k, kinds).result()
