"""Host refinement of the motion onsets (section III-A, eq. 1) by maximum likelihood.

The board keeps its simple detector (firmware/core/onset.c); the host refines each of its
onsets with a joint model of the marker around a reversal, fitted to the frames:

    Q(t) = a + v0 min(t - tau0, 0)                       old motion, stops at tau0
             + r e^(-alpha (t - tau0)) sin(w (t - tau0))  ringing after the stop (optional)
             + s [t >= t_j]                               a step: registration / channel jump (optional)
             + p [frame j - 1]                            its part frame: an exposure that caught the
                                                          step part-way (optional, on a registration record)
             + e^(-alpha t) (c1 sin(w t) + c2 cos(w t))   the ringing an earlier onset left, any phase
                                                          (with the record's ringing)
             + v1 max(t - tau, 0)                         new motion from the onset tau
             + r1 e^(-alpha (t - tau)) sin(w (t - tau))   ringing the onset excites (with the record's
                                                          ringing, when the record says so: onset_ring_evidence)

Q is the 2-D marker (px); a, v0, r, s, p, c1, c2, v1 are 2-vectors, linear given the change points
(tau0, tau, frame j) and the ringing (w, alpha), so each candidate is one linear least-squares
solve and the change points are found on grids (coordinate ascent: stop and ringing, then onset
and step, then stop again). Gaussian noise of unknown variance gives the profile likelihood
RSS^(-N/2); optional parts are kept by BIC (Schwarz 1978). The onset t2 is the posterior mean
of tau under a flat prior on the grid, its uncertainty the posterior standard deviation: a
step in the frame interval of the onset makes tau unidentifiable inside that interval, and the
estimate is then its middle with sigma = T/sqrt(12), instead of the early crossing that a line
through the jump gives.

The stop tau0 is seen where the motor stopped plus the image delay, whatever the backlash, so
the stop times give t_delay from the record (median of tau0 - motor stop), independent of the
configured value.

Units: t in s, image points in px. Arrays per reversal are (M,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .delay_guess import coarse_delay, image_direction_of_q, motor_stop_times  # noqa: F401 (re-exported)
from .onsets import RobustOnsets
from .pacing import pacing

# Ringing grid: 1.5-7 Hz (below Nyquist at 25 fps with margin; the 2-5 Hz of the bench renderings inside) and
# decay rates 0.5-12 /s (damping ratio ~0.01-0.8 at 3 Hz).
RING_HZ = np.arange(1.5, 7.01, 0.5)
RING_ALPHA = np.array([0.5, 1.5, 3.0, 6.0, 12.0])
SUB = 8          # onset / stop grid points per frame period
PRE_FRAMES = 3   # frames of old motion kept before the earliest stop searched
FAST_FRAMES = 4.0  # below: the actuator-shape model (onset_play) gives the B samples and t_delay
FOOLED_LATE = 4.0  # refined onsets this many times later than the actuator's figure are fooled late
RING_DELAY_SHARE = 0.5  # a ringing record's approach delay: its interval widened by this share of the ring's period
DELAY_SHAPE_SPAN = 3.0  # frames searched either side of the guess by delay_from_shape
RING_ZETA_MAX = 0.5  # a fitted ringing more damped than this does not ring (overshoot under 16 %)
POST_FRAMES = 6  # frames of new motion kept after the onset (a straight line holds over ~0.25 s)
POST_RING_SHARE = 0.5  # with an onset that rings, at least this share of the ring's period kept after it
MIN_REFINED = 4  # refined onsets needed for their frames-to-take-up figure (as for a delay from the stops)
MIN_REFINED_SHARE = 0.5  # ... and at least this share of the reversals (`refined_frames`)


@dataclass
class Refined:
    """Per reversal (M,): refined onset t2_s and its sigma_t2_s (s), stop time tau0_s (image
    clock), step_px (|s|, 0 without a step), ring_hz / ring_alpha (0 without ringing) and
    ring_px (|r|), ok (fit done); step_vec (M, 2) the step s itself (px, 0 without one)."""

    t2_s: np.ndarray
    sigma_t2_s: np.ndarray
    tau0_s: np.ndarray
    step_px: np.ndarray
    ring_hz: np.ndarray
    ring_alpha: np.ndarray
    ring_px: np.ndarray
    ok: np.ndarray
    step_vec: np.ndarray | None = None


def _project(F: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The shared part of `_solve` for F (n, f) and Y (n, 2): an orthonormal basis Qf (n, r) of
    F's span (rank-aware: absent parts are zero columns), Y with F projected out (n, 2) and its
    sum of squares. Depends on F and Y only, so an episode computes it once for all the
    candidates (and Nelder-Mead steps) that share F."""
    U, sv, _ = np.linalg.svd(F, full_matrices=False)
    Qf = U[:, sv > 1e-9 * sv.max()]
    Yr = Y - Qf @ (Qf.T @ Y)
    return Qf, Yr, float(np.sum(Yr * Yr))


def _solve(F: np.ndarray, V: np.ndarray, Y: np.ndarray, proj=None) -> tuple[np.ndarray, np.ndarray]:
    """Batched least squares Y ~ [F, V_g]: F (n, f) columns shared by every candidate, V
    (G, n, p) the candidate's own columns, Y (n, 2). F is projected out first (Frisch-Waugh-
    Lovell), so each candidate is a p x p solve. proj: `_project(F, Y)` when already computed
    (same numbers, computed once). Returns (RSS (G,), coef of V (G, p, 2)).
    Columns that are identically zero (a part absent from a candidate) get a tiny ridge so the
    solve stays regular without changing the fit."""
    return _solve_t(np.ascontiguousarray(V.transpose(0, 2, 1)), _project(F, Y) if proj is None else proj)


_EYE = {p: np.eye(p) for p in (1, 2, 3)}


def _solve_t(Vt: np.ndarray, proj) -> tuple[np.ndarray, np.ndarray]:
    """`_solve` with the candidates' columns as rows, Vt (G, p, n) C-contiguous, and F given by
    proj = `_project(F, Y)`."""
    Qf, Yr, yy = proj
    G, p, n = Vt.shape
    Vt = Vt.reshape(G * p, n)  # 2-D products: BLAS, not stacks
    Vt = (Vt - (Vt @ Qf) @ Qf.T).reshape(G, p, n)
    A = Vt @ Vt.transpose(0, 2, 1)
    scale = np.maximum(np.diagonal(A, axis1=1, axis2=2).max(axis=1), 1.0)
    A += (1e-10 * scale)[:, None, None] * (_EYE[p] if p in _EYE else np.eye(p))[None]
    rhs = (Vt.reshape(G * p, n) @ Yr).reshape(G, p, 2)
    coef = np.linalg.solve(A, rhs)
    rss = yy - (coef * rhs).sum(axis=(1, 2))
    return np.maximum(rss, 1e-12 * max(yy, 1e-300)), coef


def _col_old(tk, tau0):
    """Old motion, stopping at tau0: min(t - tau0, 0). tau0 (G,) -> (G, n)."""
    return np.minimum(tk[None, :] - np.asarray(tau0, float)[:, None], 0.0)


def _col_ring(tk, tau0, om, al):
    """Ringing from the stop: e^(-al d) sin(om d), d = t - tau0 > 0 (0 before). (G, n).
    The grids repeat few distinct tau0, om and al, so exp and sin are taken once per distinct
    (tau0, al) and (tau0, om) pair and multiplied per candidate (the same numbers as per
    candidate); no ringing (om 0 everywhere) is a zero column."""
    tau0, om, al = (np.asarray(x, float).ravel() for x in (tau0, om, al))
    if not np.any(om):
        return np.zeros((tau0.size, tk.size))
    if np.all(om == om[0]) and np.all(al == al[0]):  # one ringing (the record's, a polishing step)
        d = np.maximum(tk[None, :] - tau0[:, None], 0.0)
        return np.exp(-al[0] * d) * np.sin(om[0] * d)
    ut, ti = np.unique(tau0, return_inverse=True)
    uo, oi = np.unique(om, return_inverse=True)
    ua, ai = np.unique(al, return_inverse=True)
    d = np.maximum(tk[None, :] - ut[:, None], 0.0)  # (T, n)
    S = np.sin(uo[:, None, None] * d[None])  # (O, T, n)
    E = np.exp(-ua[:, None, None] * d[None])  # (A, T, n)
    return E[ai, ti] * S[oi, ti]


def _col_step(k_idx, j):
    """Step at frame j (applies from frame j on); j < 0: none. (G, n)."""
    j = np.asarray(j, float)[:, None]
    return ((k_idx[None, :] >= j) & (j >= 0)).astype(float)


def _logw(rss: np.ndarray, n_obs: int, n_extra: np.ndarray) -> np.ndarray:
    """Profile log-likelihood of a Gaussian fit with unknown variance, less the BIC penalty of
    the optional parameters: -N/2 log RSS - k/2 log N."""
    return -0.5 * n_obs * np.log(np.maximum(rss, 1e-300)) - 0.5 * n_extra * np.log(n_obs)


def _posterior(x: np.ndarray, lw: np.ndarray, step: float) -> tuple[float, float]:
    """Mean and standard deviation of x under weights exp(lw) (flat prior on a grid of
    spacing ``step``); the sd is at least step/sqrt(12), the grid's own resolution."""
    w = np.exp(lw - lw.max())
    w /= w.sum()
    m = float(np.sum(w * x))
    sd = float(np.sqrt(max(np.sum(w * (x - m) ** 2), 0.0) + step * step / 12.0))
    return m, sd


class _Episode:
    """The frames of one reversal in frame-period units and the current estimate."""

    def __init__(self, tk, Y, k_idx, tau0, tau):
        self.tk, self.Y, self.k = tk, Y, k_idx
        self.tau0, self.tau, self.j, self.om, self.al = tau0, tau, -1, 0.0, 0.0
        self.n_obs = 2 * tk.size
        self.stop_back = 5.0  # frames searched before the stop guess (ringing makes it late)
        self.fixed_ring = None  # (om, al) per frame period: the record's ringing, not searched
        self.onset_ring = False  # with fixed_ring: the ringing the onset excites is a column too
        self.carry_ring = False  # with fixed_ring: the ringing an earlier event left, any phase
        self.part = False  # the step's first frame caught it part-way (its own level: `_col_part`)
        self.allow_part = False  # whether steps with a part frame are candidates (the record's registration)

    def _proj(self, key, cols):
        """`_project` of the shared columns F = [ones, *cols()] and Y, once per key (the held
        parameters) for this episode's frames: the grids and polishing steps that hold the
        same parameters share it."""
        cache = self.__dict__.setdefault("_proj_cache", {})
        if key not in cache:
            cache[key] = _project(np.column_stack([np.ones(self.tk.size), *cols()]), self.Y)
        return cache[key]

    def _col_part(self, j, part):
        """The frame before the step's first frame j, when the step was caught part-way through
        its exposure (part): a level of its own, whatever share of the step it shows. (G, n).
        A registration that flips with the tip's direction, or any jump, lands inside an
        exposure now and then; the frame then shows part of it, which no onset or step fits,
        and the fit put the onset a few frames early to take it in (eleventh-registration-
        sine25-noisy: the 10 samples 0.05-0.09 mm short were each such a split flip)."""
        j = np.asarray(j, float)[:, None]
        part = np.asarray(part, bool)[:, None]
        return ((self.k[None, :] == j - 1) & part & (j >= 0)).astype(float)

    def _solve_stop(self, tau0, om, al, j):
        """Candidates (tau0, ringing, step frame j) with the onset held: (RSS, coef of [old,
        ring, step, the step's part frame])."""
        return _solve_t(self._stop_columns(tau0, om, al, j), self._stop_proj())

    def _stop_proj(self):
        """`_project` of the stop fits' shared columns [ones, new motion from the held onset,
        ringing from the held onset (the record's ringing only, see `_solve_onset`)]."""
        om, al = self.fixed_ring if self.onset_ring else (0.0, 0.0)
        return self._proj(("stop", self.tau, om, al),
                          lambda: [np.maximum(self.tk - float(self.tau), 0.0),
                                   _col_ring(self.tk, [self.tau], [om], [al])[0], *self._carry_cols()])

    def _carry_cols(self) -> list:
        """The ringing the last onset left in the window: the record's mode (held) with any phase
        and amplitude, e^(-al t) (sin, cos)(om t) over every frame; none unless carry_ring (set in
        the second pass where onsets excite the mode: `robust_samples`). A lightly damped mode still rings
        a few px at the next reversal; at 60 fps the window spans under a ring period and that
        ring passed for the onset (eleventh-ringing-sine60-noisy: 44 of 100 B samples 0.05-0.24
        mm off without these columns)."""
        if not (self.carry_ring and self.fixed_ring is not None and self.fixed_ring[0] > 0):
            return []
        om, al = self.fixed_ring
        e = np.exp(-al * (self.tk - self.tk[0]))
        return [e * np.sin(om * self.tk), e * np.cos(om * self.tk)]

    def _stop_columns(self, tau0, om, al, j):
        """The stop candidates' own columns [old, ring, step, the step's part frame (with
        self.part held)] as rows: (G, 4, n)."""
        tau0 = np.asarray(tau0, float)
        Vt = np.empty((tau0.size, 4, self.tk.size))
        np.minimum(self.tk[None, :] - tau0[:, None], 0.0, out=Vt[:, 0])  # old motion: _col_old
        Vt[:, 1] = _col_ring(self.tk, tau0, om, al)
        Vt[:, 2] = _col_step(self.k, j)
        Vt[:, 3] = self._col_part(np.broadcast_to(j, tau0.shape), np.full(tau0.size, self.part))
        return Vt

    def _solve_onset(self, tau, j, part=None):
        """Candidates (onset, step frame, part: the frame before it caught the step part-way)
        with the stop and ringing held: (RSS, coef of [new, step, ringing from the onset, the
        part frame])."""
        proj = self._proj(("onset", self.tau0, self.om, self.al),
                          lambda: [_col_old(self.tk, [self.tau0])[0],
                                   _col_ring(self.tk, [self.tau0], [self.om], [self.al])[0],
                                   *self._carry_cols()])
        tau = np.asarray(tau, float)
        Vt = np.empty((tau.size, 4, self.tk.size))
        np.maximum(self.tk[None, :] - tau[:, None], 0.0, out=Vt[:, 0])  # new motion: max(t - tau, 0)
        Vt[:, 3] = self._col_part(j, np.zeros(tau.size, bool) if part is None else part)
        Vt[:, 1] = _col_step(self.k, j)
        # The onset is a step in the carrier's velocity: it excites the tip mode as the stop does
        # (a tip driven through its base starts with its own ringing, here even against the
        # motion: dev-ring5-sine30 put the onsets ~300 ms late without it, 1.5 ring periods).
        # Only with the record's ringing (the second pass): searched per reversal in the first
        # pass, the extra freedom moved the stops of a 60 fps triangle that rings between every
        # two reversals (sa-ring4-tri60: the record's delay 0.26 s against 0.08 s).
        Vt[:, 2] = (_col_ring(self.tk, tau, np.full(tau.size, self.om), np.full(tau.size, self.al))
                    if self.onset_ring else 0.0)
        return _solve_t(Vt, proj)

    def fit_stop(self):
        """Stop tau0, ringing (w, alpha) and a step near the stop (a registration flipping at
        the motor reversal), onset held. Half-frame grid of tau0 with every ringing (step
        held), then with every step near the stop (ringing held); the ringing is then polished
        by Nelder-Mead on the profile RSS (the grid is too coarse for a 10 px ring), and an
        eighth-frame grid around the best gives tau0's posterior, marginalised over the step."""
        from scipy.optimize import minimize

        lo = max(-self.stop_back, self.tk[0] + 0.5)  # around the first guess (t = 0): no drift
        hi = min(3.0, self.tau - 1.0)
        if hi <= lo:
            hi = lo + 0.5
        g0 = np.arange(lo, hi + 1e-9, 0.5)
        om = np.r_[0.0, np.repeat(2 * np.pi * RING_HZ, RING_ALPHA.size)] * self.period_s  # rad / frame
        al = np.r_[0.0, np.tile(RING_ALPHA, RING_HZ.size)] * self.period_s
        if self.fixed_ring is not None:  # the record's ringing (second pass): nothing to choose
            self.om, self.al = float(self.fixed_ring[0]), float(self.fixed_ring[1])
        else:
            T0, R_ = np.repeat(g0, om.size), np.tile(np.arange(om.size), g0.size)
            J = np.full(T0.size, float(self.j))
            rss, _ = self._solve_stop(T0, om[R_], al[R_], J)
            lw = _logw(rss, self.n_obs, 4.0 * (om[R_] > 0) + (3.0 + 2.0 * self.part) * (J >= 0))
            b = int(np.argmax(lw))
            self.om, self.al = float(om[R_[b]]), float(al[R_[b]])
        js = np.unique(np.concatenate(([-1, self.j], self.k[(self.tk >= lo - 1) & (self.tk <= hi + 1)]))).astype(float)
        T0, J = np.repeat(g0, js.size), np.tile(js, g0.size)
        rss, _ = self._solve_stop(T0, np.full(T0.size, self.om), np.full(T0.size, self.al), J)
        lw = _logw(rss, self.n_obs, (3.0 + 2.0 * self.part) * (J >= 0))
        b = int(np.argmax(lw))
        self.j, t0b = int(J[b]), float(T0[b])
        if self.om > 0 and self.fixed_ring is None:
            Vt, proj = self._stop_columns([t0b], [self.om], [self.al], [self.j]), self._stop_proj()

            def f(p):  # the profile RSS of one ringing: only the ring column changes
                Vt[:, 1] = _col_ring(self.tk, [t0b], [abs(p[0])], [abs(p[1])])
                return _solve_t(Vt, proj)[0][0]
            p = minimize(f, [self.om, self.al], method="Nelder-Mead",
                         options={"xatol": 1e-4, "fatol": 1e-9, "maxiter": 200}).x
            self.om, self.al = float(abs(p[0])), float(abs(p[1]))
        gf = np.arange(max(t0b - 1.0, lo), min(t0b + 1.0, hi) + 1e-9, 0.5 / SUB)
        js = np.unique([-1, self.j]).astype(float)
        TT, JJ = np.repeat(gf, js.size), np.tile(js, gf.size)
        rss, coef = self._solve_stop(TT, np.full(TT.size, self.om), np.full(TT.size, self.al), JJ)
        lw = _logw(rss, self.n_obs, (3.0 + 2.0 * self.part) * (JJ >= 0))
        b = int(np.argmax(lw))
        self.j = int(JJ[b])
        self.ring_px = float(np.linalg.norm(coef[b, 1])) if self.om > 0 else 0.0
        self.v0 = coef[b, 0]  # old velocity, px per frame period
        lw2 = lw.reshape(gf.size, js.size)
        m = lw2.max()
        self.tau0, self.sd0 = _posterior(gf, m + np.log(np.exp(lw2 - m).sum(axis=1)), 0.5 / SUB)

    def score(self) -> float:
        """This window's log-weight under the fitted model: the onset's (its 3 parameters v1, tau
        charged as in `fit_onset`'s test) when one was found, else the best still model's."""
        on = self.lw_best - 1.5 * np.log(self.n_obs) if self.found else -np.inf
        return float(max(on, self.null_lw))

    def _back(self, coef: np.ndarray) -> np.ndarray:
        """0 for onset candidates whose new motion goes back along the old one (after a reversal
        the tip retraces its path at the actuator's speed: velocity 3 frames after the onset
        within 45 deg of -v0 and between 0.3 and 3 |v0|; a ringing tip's swing back is faster),
        -inf for the others. No constraint when the old motion is not
        seen (|v0| below 0.05 px per frame)."""
        v0 = getattr(self, "v0", np.zeros(2))
        n0 = float(np.linalg.norm(v0))
        if n0 < 0.05:
            return np.zeros(coef.shape[0])
        vel = coef[:, 0, :]
        along = -(vel @ v0) / n0
        ok = (along > 0.3 * n0) & (along < 3.0 * n0) & (along > 0.7071 * np.linalg.norm(vel, axis=1))
        return np.where(ok, 0.0, -np.inf)

    def _order(self, tau: np.ndarray, j: np.ndarray, part: np.ndarray | None = None) -> np.ndarray:
        """0, or -inf for a step seen from a frame less than 1.5 periods before the onset (its
        part frame, when it has one). A
        registration or channel jump comes with the reversal (at the stop, many frames
        earlier) or with the onset (in its frame interval or after); a jump just before the
        onset would leave that frame free of the line, and the fit would take it for any
        curvature of the first moving frames, putting the onset late."""
        jf = j - (0.0 if part is None else np.asarray(part, float))
        tj = np.where(j >= 0, self.tk[np.clip(np.searchsorted(self.k, jf), 0, self.k.size - 1)], -np.inf)
        return np.where((tau - tj > 0) & (tau - tj < 1.5), -np.inf, 0.0)

    def fit_onset(self, final: bool):
        """Onset tau and step frame j, stop and ringing held: a half-frame grid of tau, a step
        at any frame after the stop (or none), then an eighth-frame grid around the best with
        the steps near it. final: t2 and its sd are the posterior of tau, marginalised
        over the step's frame; otherwise the best tau."""
        lo = self.tau0 + 0.25
        hi = self.tk[-1] - 2.0
        if hi <= lo:
            self.ok = False
            return
        # the stop's ringing (amplitude 2-D, w, alpha) and, with the record's ringing, the onset's (2-D)
        pen_ring = (4.0 + 2.0 * self.onset_ring) * (self.om > 0)
        # Coarse: tau on a half-frame grid; the step none, the current one (a step at the stop
        # comes from fit_stop) or at a frame within 2 periods of tau (the onset's jump).
        gt = np.arange(lo, hi + 1e-9, 0.5)
        ks = self.k[self.tk > self.tau0 - 1.0]
        tks = self.tk[self.tk > self.tau0 - 1.0]
        band = np.abs(tks[None, :] - gt[:, None]) <= 2.0
        ti, ki = np.nonzero(band)
        TT = np.concatenate((gt, gt, gt[ti]))
        JJ = np.concatenate((np.full(gt.size, -1.0), np.full(gt.size, float(self.j)), ks[ki].astype(float)))
        PP = np.zeros(TT.size, bool)
        if self.allow_part:  # every step candidate also with its part frame (`_col_part`: 2 more parameters)
            st = JJ >= 0
            TT, JJ, PP = np.r_[TT, TT[st]], np.r_[JJ, JJ[st]], np.r_[PP, np.ones(int(st.sum()), bool)]
        rss, coef = self._solve_onset(TT, JJ, PP)
        lw = _logw(rss, self.n_obs, 3.0 * (JJ >= 0) + 2.0 * PP + pen_ring) + self._back(coef) + \
            self._order(TT, JJ, PP)
        b = int(np.argmax(lw))
        tb, self.j, self.part = float(TT[b]), int(JJ[b]), bool(PP[b])
        # No onset in the window unless new motion beats the best still model (level, old
        # motion, ringing, and a step anywhere or none) by BIC: its 3 parameters (v1, tau).
        jn = np.concatenate(([-1], ks, ks if self.allow_part else [])).astype(float)
        pn = np.r_[False, np.zeros(ks.size, bool), np.ones(ks.size if self.allow_part else 0, bool)]
        rn, _ = self._solve_onset(np.full(jn.size, 1e9), jn, pn)
        null = float(np.max(_logw(rn, self.n_obs, 3.0 * (jn >= 0) + 2.0 * pn + pen_ring)))
        self.found = lw[b] - 1.5 * np.log(self.n_obs) > null
        self.null_lw = null  # the best still model's log-weight (`score`)
        gf = np.arange(max(tb - 1.5, lo), min(tb + 1.5, hi) + 1e-9, 1.0 / SUB)
        near = self.k[np.abs(self.tk - tb) <= 2.5]
        js = np.unique(np.concatenate(([-1, self.j], near))).astype(float)
        ps = np.zeros(js.size, bool)
        if self.allow_part:  # each step also with its part frame
            ps, js = np.r_[ps, np.ones(js.size - 1, bool)], np.r_[js, js[1:]]
        TT, JJ, PP = np.repeat(gf, js.size), np.tile(js, gf.size), np.tile(ps, gf.size)
        rss, coef = self._solve_onset(TT, JJ, PP)
        lw = _logw(rss, self.n_obs, 3.0 * (JJ >= 0) + 2.0 * PP + pen_ring) + self._back(coef) + \
            self._order(TT, JJ, PP)
        b = int(np.argmax(lw))
        self.j, self.part = int(JJ[b]), bool(PP[b])
        self.lw_best = float(lw[b])  # the best onset candidate's log-weight (`score`)
        self.step_px = float(np.linalg.norm(coef[b, 1])) if self.j >= 0 else 0.0
        self.step_vec = np.array(coef[b, 1], float) if self.j >= 0 else np.zeros(2)
        if not np.isfinite(lw[b]):  # no candidate moves back along the old motion
            self.found = False
        if final and self.found:
            lw2 = lw.reshape(gf.size, js.size)
            m = lw2.max()
            with np.errstate(divide="ignore"):  # onsets the direction rule excludes have weight 0
                marg = m + np.log(np.exp(lw2 - m).sum(axis=1))
            self.tau, self.sd = _posterior(gf, marg, 1.0 / SUB)
        else:
            self.tau = float(TT[b])
        self.ok = True


def _fit_window(tf, o, kf, t0, end, period_s, state, final=False, stop=True, ring=None, stop_back=5.0,
                onset_ring=False, part=False, carry=False):
    """Fit the frames in [t0 - (PRE_FRAMES + 5) periods, end] starting from ``state`` (tau0,
    om, al, j, tau; in periods from t0, tau = inf when no onset is known): stop, onset, stop,
    onset (the last one final when asked; stop=False: the stop held from ``state``, onset only,
    while the window grows). ring: the record's ringing (Hz, 1/s), held; onset_ring: with it,
    the ringing the onset excites is a column too (`onset_ring_evidence` decides). Returns the
    _Episode or None (too few frames)."""
    sel = (tf >= t0 - (PRE_FRAMES + 5) * period_s) & (tf <= end)
    if sel.sum() < 8:
        return None
    tk = (tf[sel] - t0) / period_s
    ep = _Episode(tk, o[sel] - o[sel].mean(axis=0), kf[sel], state[0], 1e9)
    ep.period_s = period_s
    ep.om, ep.al, ep.j = state[1], state[2], state[3]
    ep.stop_back = stop_back
    ep.allow_part = bool(part)
    if ring is not None:
        ep.fixed_ring = (2 * np.pi * ring[0] * period_s, ring[1] * period_s)
        ep.onset_ring = bool(onset_ring) and ring[0] > 0
        ep.carry_ring = bool(carry) and ring[0] > 0
    if np.isfinite(state[4]):
        ep.tau = min(max(state[4], state[0] + 1.0), tk[-1] - 2.0)
    if stop or len(state) < 6:
        ep.fit_stop()
    else:
        ep.v0, ep.ring_px = state[5], state[6]
    ep.fit_onset(final=False)
    if not ep.ok:
        return None
    if ep.found and stop:
        ep.fit_stop()
        ep.fit_onset(final=final)
        if not ep.ok:
            return None
    return ep


def post_frames(ring: tuple | None, period_s: float) -> float:
    """Frames of new motion the onset's window keeps after the onset: POST_FRAMES, or, where the
    onset excites the record's ringing (ring (Hz, 1/s), None or 0 Hz: it does not), at least
    POST_RING_SHARE of the ring's period. The onset's ring column r1 e^(-alpha t) sin(w t) (module
    doc) is a ramp over a quarter period or less, the new motion's own shape, so only a window
    that reaches the ring's turn tells the two apart. POST_FRAMES was set at 25 fps, where a
    2-5 Hz ring's half period is 2.5-6 frames; at 60 fps a 2.5 Hz ring's is 12, and the 6-frame
    window (0.1 s) traded the onset for its ring: refined onsets 30-38 frames early on 10 of
    34 reversals of fourteenth-ringing-sine60-noisy (a slow sine, the play taken up over
    23-34 frames; B 46 % off). Returns frames (float)."""
    if ring is None or not ring[0] > 0:
        return float(POST_FRAMES)
    return max(float(POST_FRAMES), POST_RING_SHARE / (ring[0] * period_s))


def _refine_one(tf, o, kf, t0, t_lim, t2_guess, period_s, ring, stop_back, onset_ring, part=False, carry=False):
    """One reversal's episode (`refine`): frames tf (s), o (px), kf (frame numbers) with the
    lost ones left out; t0 the stop guess and t_lim the episode's end (s, image clock); t2_guess
    the board's candidate (NaN: none). Returns (the final _Episode or None, its window's end s)."""
    guess = t2_guess if np.isfinite(t2_guess) else -np.inf
    # The first window ends 4 frames after the stop (the stop and ringing are fitted
    # there, before any onset); the next one reaches past the board's candidate.
    end = min(t0 + 4 * period_s, t_lim)
    state = (0.0, 0.0, 0.0, -1, np.inf)  # tau0, om, al, j, tau (inf: no onset known yet)
    kw = dict(ring=ring, stop_back=stop_back, onset_ring=onset_ring, part=part, carry=carry)
    post = post_frames(ring if onset_ring else None, period_s)
    for _ in range(40):  # grow the window until an onset sits well inside it, then trim to it
        ep = _fit_window(tf, o, kf, t0, end, period_s, state, stop=len(state) < 6, **kw)
        if ep is None:
            # No onset can be fitted in the frames so far: a longer window, up to the episode's
            # end. The carried ring's columns (`_Episode._carry_cols`) need more frames than the
            # first window's 4 past the stop (returning there left 63 of 100 reversals of
            # fifth-ringing-sine30-noisy to the board, 2.9 -> 24.6 %), and so does a stop guessed
            # early, whose fit sits at its search's far end with no room left for an onset
            # (fifteenth-delay-sine60: 33 of 54 reversals left to the board, 15.9 % off).
            if end >= t_lim:
                return None, end
            end = min(end + period_s, t_lim)
            continue
        state = (ep.tau0, ep.om, ep.al, ep.j, ep.tau if ep.found else np.inf, ep.v0, ep.ring_px)
        if ep.found and ep.tau * period_s + t0 < end - (post - 1.5) * period_s:
            trim = min(ep.tau * period_s + t0 + post * period_s, t_lim)
            e2 = _fit_window(tf, o, kf, t0, trim, period_s, state, final=True, **kw)
            if e2 is not None and e2.found and abs(e2.tau - ep.tau) < 2.0:
                return e2, trim
        if end >= t_lim:
            return None, end
        # Never shrink: an onset the longer window no longer supports was a jump or a swing.
        if ep.found:
            end = min(max(end + period_s, ep.tau * period_s + t0 + post * period_s), t_lim)
        else:
            end = min(max(end, guess) + post * period_s, t_lim)
        guess = -np.inf
    return ep, end


def onset_ring_evidence(t_f: np.ndarray, obs: np.ndarray, t_stop: np.ndarray, t_next_stop: np.ndarray,
                        t2_guess: np.ndarray, t_delay_s: float, period_s: float, ring: tuple,
                        stop_back: float = 1.5) -> dict:
    """Whether the onset excites the record's ringing: the model with the onset's ring column
    (r1, module doc) against the one without, by BIC summed over the given reversals.

    A tip mode driven through its base (x'' + 2 zeta w x' + w^2 x = -g c'') rings wherever the
    carrier's velocity steps: at the stop and again at the onset, where it starts against the
    new motion and makes the onset look late (fifth-ringing-sine30-noisy: 99 % off without the
    column). A tip that only overshoots at the stop (the Fig. 7 replica's renderer) has no onset
    ring, and there the column trades with the new motion's ramp (2 Hz ring at 25 fps: 5.5 ->
    12 %). The mode is the record's, shared by every reversal, so the record decides, not each
    reversal: per reversal both models are refined (`refine`), then fitted again on the same
    frames (to the later end of the windows that found an onset) and their log-weights compared
    (`_Episode.score`: -N/2 log RSS less half the BIC penalty, the column's 2 parameters
    included, Schwarz 1978; a model that finds no onset there scores its best still model, so a
    reversal only one of them can explain counts for it: fourth-ringing-swings25 found onsets on
    10 of 24 reversals with the column, 1 without). The column is used when the sum is positive.
    Arrays as `refine` (M,) for the reversals to use; ring (Hz, 1/s) the record's ringing.
    Returns {"reversals": compared, "delta_log_weight": sum, "share_for": share of reversals
    favouring the column, "used": bool}."""
    ok_f = np.all(np.isfinite(obs), axis=1)
    tf, o = t_f[ok_f], obs[ok_f]
    kf = np.nonzero(ok_f)[0]
    d = []
    for r in range(t_stop.size):
        t0 = t_stop[r] + t_delay_s
        t_lim = t_next_stop[r] + t_delay_s - 2 * period_s
        fits = [_refine_one(tf, o, kf, t0, t_lim, t2_guess[r], period_s, ring, stop_back, on) for on in (False, True)]
        found = [ep for ep, _ in fits if ep is not None and ep.found]
        if not found:
            continue
        end = max(e for ep, e in fits if ep is not None and ep.found)
        lw = []
        for on, (ep, _) in zip((False, True), fits):
            src = ep if ep is not None and ep.found else found[0]  # start from an onset one of them found
            state = (src.tau0, src.om, src.al, src.j, src.tau, src.v0, src.ring_px)
            e2 = _fit_window(tf, o, kf, t0, end, period_s, state, final=True, ring=ring, stop_back=stop_back,
                             onset_ring=on)
            lw.append(e2.score() if e2 is not None else np.nan)
        if np.all(np.isfinite(lw)):
            d.append(lw[1] - lw[0])
    d = np.asarray(d, float)
    total = float(d.sum()) if d.size else 0.0
    return {"reversals": int(d.size), "delta_log_weight": total,
            "share_for": float(np.mean(d > 0)) if d.size else 0.0, "used": bool(d.size and total > 0)}


def refine(t_f: np.ndarray, obs: np.ndarray, t_stop: np.ndarray, t_next_stop: np.ndarray,
           t2_guess: np.ndarray, t_delay_s: float, period_s: float, ring: tuple | None = None,
           stop_back: float = 5.0, onset_ring: bool = False, part: bool = False, carry: bool = False) -> Refined:
    """Refine every reversal's onset with the joint model (module doc).

    t_f (F,), obs (F, 2) px (NaN = lost) on the image clock; t_stop (M,) motor stops (s,
    encoder clock); t_next_stop (M,) the next reversal's motor stop (bounds the episode);
    t2_guess (M,) the board's onset candidates (NaN: none, e.g. ONSET_ERR_NO_STILL when the tip
    rings); t_delay_s the current delay (its error may be a few frames: the stop is searched
    from stop_back frames before t_stop + t_delay_s to 3 after); period_s the frame period;
    ring (hz, alpha 1/s) fixes the ringing (hz 0: none) instead of searching it; onset_ring
    (with it) fits the ringing the onset excites too (`onset_ring_evidence`); part: a step may
    come with a part frame (`_Episode._col_part`; the record's registration decides, `robust_samples`);
    carry (with ring): the ring an earlier onset left is fitted too (`_Episode._carry_cols`). The window is grown
    until the onset lies POST_FRAMES before its end, so a candidate fired by ringing or by a
    jump is only a start. Returns Refined; ok False where no onset fits before the next stop.
    """
    ok_f = np.all(np.isfinite(obs), axis=1)
    tf, o = t_f[ok_f], obs[ok_f]
    kf = np.nonzero(ok_f)[0]
    M = t_stop.size
    res = {k: np.full(M, np.nan) for k in ("t2", "sd", "tau0", "step", "hz", "al", "ring")}
    okm = np.zeros(M, bool)
    stepv = np.zeros((M, 2))
    for r in range(M):  # episodes are independent; each is a handful of batched solves
        t0 = t_stop[r] + t_delay_s
        t_lim = t_next_stop[r] + t_delay_s - 2 * period_s  # the next episode's old motion stays out
        ep, _ = _refine_one(tf, o, kf, t0, t_lim, t2_guess[r], period_s, ring, stop_back, onset_ring, part, carry)
        if ep is None or not ep.found or not hasattr(ep, "sd"):
            continue
        okm[r] = True
        res["t2"][r] = t0 + ep.tau * period_s
        res["sd"][r] = ep.sd * period_s
        res["tau0"][r] = t0 + ep.tau0 * period_s
        res["step"][r] = ep.step_px
        stepv[r] = getattr(ep, "step_vec", np.zeros(2))
        res["hz"][r] = ep.om / period_s / (2 * np.pi)
        res["al"][r] = ep.al / period_s
        res["ring"][r] = ep.ring_px
    return Refined(res["t2"], res["sd"], res["tau0"], res["step"], res["hz"], res["al"], res["ring"], okm, stepv)


def delay_from_stops(tau0_s: np.ndarray, t_stop: np.ndarray) -> tuple[float, float, int]:
    """t_delay from the record: median over reversals of (image stop - motor stop), its
    standard error (1.2533 MAD-sd / sqrt(n), for the median of a normal sample) and the count.
    NaN entries (no fit) are left out. Returns (t_delay_s, se_s, n)."""
    d = tau0_s - t_stop
    d = d[np.isfinite(d)]
    if d.size == 0:
        return float("nan"), float("nan"), 0
    med = float(np.median(d))
    sd = 1.4826 * float(np.median(np.abs(d - med)))
    sd = max(sd, 0.0025 / np.sqrt(12))  # the stops are on a grid of 1/16 frame
    return med, 1.2533 * sd / np.sqrt(d.size), int(d.size)


def delay_from_shape(t_enc: np.ndarray, q: np.ndarray, rt: np.ndarray, rq: np.ndarray, t_f: np.ndarray,
                     obs: np.ndarray, t2_img: np.ndarray, d_guess: float, period_s: float,
                     span_frames: float = 3.0, ring: tuple = (0.0, 0.0)) -> tuple[float, float, int]:
    """t_delay from the approach to each reversal, with the actuator's own shape.

    Until the play is taken up the tip's drive is z = q(min(t, t1)) - q1 + const (eq. 3: on the
    old branch z follows q, after the reversal it holds), so the frames between the old motion
    and the refined onset are p_k = A + K h_k + K2 h_k^2, h_k = q(min(t_k - d, t1)) - q1 (the
    image of z, locally quadratic; A, K, K2 2-vectors). The delay d enters through h only. A
    constant-speed approach makes h a kink (what the change-point stop sees); a sine or a
    raised-cosine swing slows down gradually, and a kink fitted there comes early by a
    good part of the deceleration (measured -2.6 frames on a 3 s sine at 30 fps), the shape
    does not. A registration that flips with the motor's reversal is a step at the stop: a
    step from the stop's first or second frame is a candidate too (kept by BIC, Schwarz 1978).
    Per reversal: d on a 1/16-frame grid d_guess +- span_frames frames, the least
    criterion (N log RSS + the step's penalty) over the frames from 0.5 s (or the previous onset plus a frame) before the stop to half
    a frame before the refined onset t2_img (image clock), refined by a parabola through the
    best three; then the median over reversals, its standard error as in `delay_from_stops`.
    t_enc, q (N,); rt, rq (M,) reversals; t_f (F,), obs (F, 2) px (NaN = lost); t2_img (M,)
    refined onsets (NaN: none; those reversals are left out); ring (Hz, 1/s) the record's
    ringing after the stop (Hz 0: none), one more column. Returns (t_delay_s, se_s, n)."""
    ok_f = np.all(np.isfinite(obs), axis=1)
    tf, o = t_f[ok_f], obs[ok_f]
    step = period_s / 16.0
    grid = d_guess + np.arange(-16 * span_frames, 16 * span_frames + 1) * step
    grid = grid[grid >= 0.0]
    if grid.size < 3:
        return float("nan"), float("nan"), 0
    best = []
    for r in range(1, rt.size):
        if not np.isfinite(t2_img[r]):
            continue
        start = rt[r] + d_guess - 0.5
        if np.isfinite(t2_img[r - 1]):
            start = max(start, t2_img[r - 1] + period_s)
        sel = (tf >= start) & (tf <= t2_img[r] - 0.5 * period_s)
        if sel.sum() < 8 or np.sum(tf[sel] < rt[r] + d_guess) < 3:
            continue
        tk, Y = tf[sel], o[sel] - o[sel].mean(axis=0)
        h = np.interp(np.minimum(tk[None, :] - grid[:, None], rt[r]), t_enc, q) - rq[r]  # (G, n)
        sc = max(float(np.max(np.abs(h))), 1e-12)
        h = h / sc
        n_obs = 2 * tk.size
        crit = np.full(grid.size, np.inf)
        first = np.cumsum(tk[None, :] > rt[r] + grid[:, None], axis=1)  # 1 at the stop's first frame
        ring_cols = []
        if ring[0] > 0:
            # The record's ringing, started at the stop: a velocity step there (a constant-speed
            # approach) starts it in sine phase, an acceleration step (a sine's or a swing's
            # deceleration ends at the stop) as 1 - cosine (continuous, zero velocity).
            tau = np.maximum(tk[None, :] - rt[r] - grid[:, None], 0.0)
            e = np.exp(-ring[1] * tau)
            ring_cols = [e * np.sin(2 * np.pi * ring[0] * tau), 1.0 - e * np.cos(2 * np.pi * ring[0] * tau)]
            # and a ring carried over from before the window (the previous onset's), free phase
            tw = tk - tk[0]
            ew = np.exp(-ring[1] * tw)
            ring_cols += [np.broadcast_to(ew * np.sin(2 * np.pi * ring[0] * tw), h.shape),
                          np.broadcast_to(ew * np.cos(2 * np.pi * ring[0] * tw), h.shape)]
        for m in (0, 1, 2):  # no step, or one from the stop's first or second frame
            cols = [np.ones_like(h), h, h * h] + ring_cols + ([(first >= m).astype(float)] if m else [])
            X = np.stack(cols, axis=-1)  # (G, n, p)
            p = X.shape[2]
            A = np.einsum("gnp,gnq->gpq", X, X) + 1e-9 * np.eye(p)[None]
            rhs = np.einsum("gnp,nc->gpc", X, Y)
            coef = np.linalg.solve(A, rhs)
            rss = np.maximum(float(np.sum(Y * Y)) - np.einsum("gpc,gpc->g", coef, rhs), 1e-12)
            crit = np.minimum(crit, n_obs * np.log(rss) + (2 * np.log(n_obs) if m else 0.0))
        rss = crit
        i = int(np.argmin(rss))
        if i == 0 or i == grid.size - 1:
            continue  # the best delay at the grid's edge: not bracketed
        y0, y1, y2 = rss[i - 1], rss[i], rss[i + 1]
        den = y0 - 2 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den > 0 else 0.0
        best.append(grid[i] + float(np.clip(off, -1.0, 1.0)) * step)
    if not best:
        return float("nan"), float("nan"), 0
    d = np.array(best)
    med = float(np.median(d))
    sd = max(1.4826 * float(np.median(np.abs(d - med))), step / np.sqrt(12))
    return med, 1.2533 * sd / np.sqrt(d.size), int(d.size)


def ring_summary(ref: Refined) -> dict:
    """The record's post-reversal ringing for the diagnosis: share of reversals where a ringing
    was kept (BIC), and over those the median frequency (Hz), decay rate alpha (1/s), damping
    ratio zeta = alpha / sqrt(alpha^2 + w^2) and amplitude (px)."""
    ok = ref.ok & np.isfinite(ref.ring_hz)
    has = ok & (ref.ring_hz > 0)
    out = {"reversals_fitted": int(ok.sum()), "reversals_ringing": int(has.sum()),
           "share": float(has.sum() / max(ok.sum(), 1))}
    if has.any():
        hz, al = np.median(ref.ring_hz[has]), np.median(ref.ring_alpha[has])
        w = 2 * np.pi * hz
        out.update({"freq_hz": float(hz), "decay_per_s": float(al), "damping_ratio": float(al / np.hypot(al, w)),
                    "amplitude_px": float(np.median(ref.ring_px[has]))})
    return out


def tip_mode(summary: dict, min_share: float = 0.5) -> tuple:
    """The record's tip mode that rings, from pass 1's `ring_summary`: (Hz, decay 1/s), or
    (0.0, 0.0) where none rings. Kept where over min_share of the fitted reversals ring (half by
    default; 0: any, for `robust_samples`' record-level test of a minority ringing), the damping
    ratio is under RING_ZETA_MAX and the frequency within the band searched (RING_HZ). summary:
    dict with "share", and where over 0, "freq_hz", "decay_per_s", "damping_ratio".

    A heavily damped "ringing" is the change-point model bending its kink to a sine's gradual stop
    (fourth-delay-sine30: 2.5 Hz, zeta 0.74; eleventh-delay-sine60: 3.8 Hz, 0.60; the rendered rings
    were 0.03-0.1): kept in the change-point model, where it takes that curvature up (without it
    eleventh-delay-sine60 was 19 % off, 1 % with), and in the delay interval's widening
    (`robust_samples`; the approach's figure is as uncertain there: 1.3 frames off on
    seventh-none-sine60-noisy, which the widening leaves to its right configured delay), but not a
    column of the delay's approach fit, where it took the approach's curvature for itself
    (eleventh-delay-sine60: +0.23 -> +0.07 frame). Nor is one below the band searched (RING_HZ; its
    polish walked out of it): that is the approach's own curvature (tenth-delay-triangle60-noisy:
    0.74 Hz, 33 px, on a triangle).
    """
    if not (summary["share"] > min_share and summary["damping_ratio"] < RING_ZETA_MAX
            and summary["freq_hz"] >= RING_HZ[0]):
        return (0.0, 0.0)
    return (summary["freq_hz"], summary["decay_per_s"])


def direction_jump(ref: Refined, rq: np.ndarray, shape_doc: dict | None = None) -> dict:
    """Whether the image jumps at the onsets with the direction of motion (a registration or
    channel error: the jump's sign follows the distal direction). The refined onsets' step
    vectors, each signed by its reversal's direction (+1 when q rose to q1), averaged: found
    when the mean lies over onset_play.JUMP_T standard errors from 0 with steps at half the
    fitted reversals or more (a jump fitted to noise or ringing comes and goes, and averages
    out). When the actuator-shape model's B samples are used (shape_doc), its own record-wide
    choice decides (its jump_px). Returns {"found", "jump_px" (2,) or None, "ratio", "from"}.
    ref: refine()'s result; rq (M,) reversal positions."""
    from .onset_play import JUMP_T

    if shape_doc is not None:
        j = (shape_doc.get("choice") or {}).get("jump_px")
        return {"found": j is not None, "jump_px": j, "ratio": (shape_doc.get("choice") or {}).get("jump_ratio"),
                "from": "actuator-shape model"}
    s = np.sign(np.r_[0.0, np.diff(rq)])
    sv = ref.step_vec if ref.step_vec is not None else np.zeros((rq.size, 2))
    k = ref.ok & (ref.step_px > 0) & (s != 0)
    if k.sum() < 4 or k.sum() < 0.5 * ref.ok.sum():
        return {"found": False, "jump_px": None, "ratio": None, "from": "refined onsets' steps"}
    J = s[k, None] * sv[k]
    m = J.mean(axis=0)
    se = J.std(axis=0, ddof=1) / np.sqrt(len(J))
    ratio = float(np.linalg.norm(m) / max(float(np.linalg.norm(se)), 1e-12))
    found = ratio > JUMP_T
    return {"found": bool(found), "jump_px": [float(x) for x in m] if found else None, "ratio": ratio,
            "from": "refined onsets' steps"}


def board_width(b: np.ndarray) -> float:
    """The board's median eq. 1 width (actuator units) over its onsets with a width (b > 0), the
    width `actuator_frames` checks the refined onsets against; NaN with fewer than MIN_REFINED of
    them, as for the refined onsets' own figure. One width is no check: a configured delay 0.1 s
    short left the board one onset on fifteenth-delay-swings25-fast (fast swings, no still
    frame), its width 37 frames of travel, which passed 5 refined onsets with invented 36 px steps
    (28 frames) and kept the actuator-shape model off (58 % off; 2.2 % with the model). b (K,)."""
    b = np.asarray(b, float)
    b = b[np.isfinite(b) & (b > 0)]
    return float(np.median(b)) if b.size >= MIN_REFINED else float("nan")


def actuator_frames(t_enc: np.ndarray, q: np.ndarray, rt: np.ndarray, rq: np.ndarray, b: float,
                    period_s: float) -> float:
    """Frames the actuator takes to come back by b (actuator units) from each reversal q1, lower
    quartile over the reversals (NaN for no b or no reversal that comes back that far before
    the next). t_enc, q (N,) s and units; rt, rq (M,) reversals; period_s the frame period."""
    if not (np.isfinite(b) and b > 0) or rt.size < 2:
        return float("nan")
    out = []
    for r in range(1, rt.size):
        s = 1.0 if rq[r] > rq[r - 1] else -1.0
        i0 = np.searchsorted(t_enc, rt[r])
        i1 = np.searchsorted(t_enc, rt[r + 1]) if r + 1 < rt.size else t_enc.size
        back = np.nonzero(s * (rq[r] - q[i0:i1]) >= b)[0]
        if back.size:
            out.append((t_enc[i0 + back[0]] - rt[r]) / period_s)
    return float(np.percentile(out, 25)) if out else float("nan")


def frames_to_take_up(b: np.ndarray, t_drive_s: np.ndarray, t_enc: np.ndarray, v: np.ndarray, fps: float) -> float:
    """Frames the play takes to take up: each b (K,) over the actuator's travel in one frame
    period at its drive time t_drive_s (K,) s (t2 - t_delay), lower quartile (a swing that is
    fast on one side only, the paper's square-ish swings: fast out, slow back, still leaves a
    quarter or more within a frame). t_enc, v (N,) s and units/s; fps frames/s. Frames; the
    refined onsets' (`refined_frames`) and the actuator-shape model's figure alike. K >= 1."""
    return float(np.percentile(b / np.maximum(np.abs(np.interp(t_drive_s, t_enc, v)) / fps, 1e-12), 25))


def refined_frames(ref: Refined, t_enc: np.ndarray, q: np.ndarray, v: np.ndarray, rq: np.ndarray,
                   t_delay_s: float, fps: float) -> float:
    """Frames the refined onsets take to take up the play (`frames_to_take_up` of their
    b = |q(t2 - t_delay) - q1| at t2 - t_delay, over the refined reversals). ref: `refine`'s (M,); t_enc, q,
    v (N,) s, units, units/s; rq (M,) q1; fps frames/s. NaN with fewer than MIN_REFINED refined
    onsets, or fewer than MIN_REFINED_SHARE of the reversals: a quartile of so few says nothing
    about the record (then the actuator-shape model is fitted and its own figure decides, as
    `gate_frames` does where nothing can be trusted). The share: a registration that flips at
    the onset itself on fast swings (the flip's lag 0) left 6 of 81 reversals refined, each on
    a step it could not tell from the take-up; their 5.1 frames (the actuator's, for the board's
    width: 1.3) kept the model off, and B came from the board, 69 % off.
    Found on fourth-ringing-swings25: its first pass fitted none of 24 reversals at a coarse
    delay 1.6 frames late, 3 of 99 were refined, each a 25 px "step" put at the next swing, and
    their 31.8 frames kept the model off a record whose play is taken up within about two
    frames (77.6 % off; with the model, 98 samples)."""
    if ref.ok.sum() < max(MIN_REFINED, MIN_REFINED_SHARE * ref.ok.size):
        return float("nan")
    t2r = ref.t2_s[ref.ok] - t_delay_s
    return frames_to_take_up(np.abs(np.interp(t2r, t_enc, q) - rq[ref.ok]), t2r, t_enc, v, fps)


def gate_frames(ref_frames: float, act_frames: float, invented: bool) -> float:
    """The frames-to-take-up figure the model gate (FAST_FRAMES) reads: the refined onsets'
    (ref_frames, NaN without them), or the actuator's for the board's median width (act_frames,
    `actuator_frames`) when it is smaller and the refined onsets are fooled late: they invent
    steps (``invented``: a step on most reversals that does not follow the direction), or they
    look over FOOLED_LATE times later than the actuator says. Frames (lower quartiles).
    Invented steps with no board width to check them against (the board found no onset: its
    configured delay 0.1 s off on third-delay-swings25-fast, 99 reversals without a still frame)
    leave no figure to trust: NaN, so the model is fitted and its own figure decides (74 % off
    on that rendering with the refined onsets' 31 frames, 3.0 % with the model)."""
    if invented and not np.isfinite(act_frames):
        return float("nan")
    if not (np.isfinite(act_frames) and np.isfinite(ref_frames)) or act_frames >= ref_frames:
        return ref_frames
    return act_frames if invented or ref_frames > FOOLED_LATE * act_frames else ref_frames


def _shape_fit_needed(ref_frames: float) -> bool:
    """Whether the actuator-shape model (onset_play.fit) is fitted, given the gate's figure
    (`gate_frames`: the refined onsets' frames to take up the play, or the actuator's where they
    are fooled late; lower quartile, NaN without refined onsets). Not when it is FAST_FRAMES or
    more: this gate, not the model's own figure, keeps the model off slow records (the Fig. 7
    replica's and the main job's, where the change-point model does better and where the model is
    most of the onset path's cost). A model fitted anyway would also be used if its own figure
    came out below FAST_FRAMES (robust_samples reads either figure once fitted)."""
    return not ref_frames >= FAST_FRAMES


def delay_below_zero(d_data: float, ci_hi_s: float, period_s: float) -> bool:
    """Whether a record's delay d_data (s; NaN: none) is no delay at all: its 95 % interval's top
    ci_hi_s (s), widened by half a frame period (period_s / 2, the quantisation allowance of
    `choose_delay`), lies below zero. No tip moves before its motor, so such a figure says the
    estimator does not describe the record; `choose_delay` does not use it."""
    return bool(np.isfinite(d_data) and ci_hi_s + period_s / 2.0 < 0.0)


def choose_delay(d_data: float, ci_s: tuple[float, float], how: str, t_delay_cfg: float | None, period_s: float,
                 t_delay_from: str = "data") -> tuple[float, str, bool | None, float]:
    """Which t_delay to use: the record's d_data (s; NaN when the record gives none), its 95 %
    interval ci_s (s) found by `how`, or the configured t_delay_cfg (s, None: not configured).

    Frame quantisation: an onset seen between two frames is placed within that frame interval,
    and an effect shared by every reversal (where within the interval the motion shows, a
    registration flip some fraction of a frame after the tip reverses, the exposure) shifts all
    of them alike, which the interval's scatter term cannot see. So the configured delay is
    replaced only when it lies beyond ci_s widened by half a frame period (period_s / 2) on each
    side, the largest shift that placing an onset within its frame interval leaves. (A correct
    configured delay was replaced on a registration rendering whose record delay came 0.46 frame
    early with an interval of 0.03 frame.) t_delay_from "config" keeps the configured delay.
    A record delay whose interval, so widened, lies wholly below zero is no delay at all (no tip
    moves before its motor): the estimator is biased on this record, and what it says cannot
    arbitrate. Its figure is reported, the configured delay kept (agrees None), and without one
    0 s is used. (A ringing 25 fps sine's stops said -0.039 s, 95 % -0.047..-0.030 s, clipped to
    0 s and replacing a right configured 0.069 s: B 124.7 %, seventeenth-ringing-sine25-noisy.)
    Returns (t_delay_s, source text, agrees (None when there is nothing to compare), allowance_s).
    """
    allow = period_s / 2.0
    have = bool(np.isfinite(d_data))
    agree = None
    if delay_below_zero(d_data, ci_s[1], period_s):
        if t_delay_cfg is not None:
            return t_delay_cfg, "configured (the record's delay lies below zero beyond its interval and half a frame: " \
                                "not a delay)", None, allow
        return 0.0, f"estimated from the record ({how}) below zero beyond its interval and half a frame; 0 s used", \
            None, allow
    if t_delay_cfg is not None and have:
        agree = bool(ci_s[0] - allow <= t_delay_cfg <= ci_s[1] + allow)
    if t_delay_cfg is None:
        return d_data, f"estimated from the record ({how})", agree, allow
    if t_delay_from == "config":
        return t_delay_cfg, "configured (--t-delay-from config)", agree, allow
    if agree is False:
        return (d_data, "estimated from the record: the configured value lies outside its 95 % interval widened by "
                "half a frame period", agree, allow)
    return t_delay_cfg, "configured (the record agrees within its 95 % interval, widened by half a frame period)", agree, allow


def robust_samples(t_enc: np.ndarray, q: np.ndarray, q_rev: np.ndarray, rt: np.ndarray, rq: np.ndarray,
                   t_f: np.ndarray, obs: np.ndarray, fps: float, t_delay_cfg: float | None,
                   t_delay_from: str = "data", board=None, onset_cfg: dict | None = None,
                   hysteresis: float = 0.0) -> RobustOnsets:
    """B samples of eq. 1 for an image session: the board's detector, then the host refinement.

    1. Motor stops (``motor_stop_times`` on q_rev, the signal the reversals came from) and a
       coarse delay (``coarse_delay``).
    2. Candidates: ``board`` (onsets.Onsets the board measured, e.g. run-insitu) or the
       firmware's detector run here through cffi (onsets.run_onsets) with the configured
       delay, as the board would have run it (the coarse one when none is configured), and
       its threshold from the record (onset_settings.image_onset_settings) unless onset_cfg gives
       one; the rule and its figures are in report["board_threshold"].
    3. ``refine`` every reversal (the record's ringing from a first pass on up to 24: kept where
       over half its reversals ring, or, a tip mode on at least MIN_REFINED, where the onset's
       ring column wins on the record, ``onset_ring_evidence``; report["ringing"]["ring_from"]);
       t_delay from the approach to each stop with the actuator's
       shape (``delay_from_shape``; the stop times, ``delay_from_stops``, without 4 reversals
       to fit), or the actuator-shape model's when its B samples are used.
    4. ``choose_delay``: t_delay_from "data" (default): the configured delay unless the record
       disagrees beyond its 95 % interval widened by half a frame period (on a ringing record
       also by RING_DELAY_SHARE of the ring's period), then the record's; a record's delay
       wholly below zero (``delay_below_zero``) is reported, never used;
       "config": the configured one. A disagreement is a warning either way. A configured
       delay is never needed: without one the record's delay is used.
    5. b = |q(t2 - t_delay) - q1| with sigma_b = |dq/dt| sigma_t2. A reversal the refinement
       could not fit, or whose refined onset comes before t1 + t_delay (not an onset), keeps the
       board's sample (when that one comes after it), timed to a frame period or to the board's
       median distance from the refined onsets, whichever is larger.
    t_enc, q, q_rev (N,); rt, rq (M,) reversals; t_f (F,), obs (F, 2) px. Returns RobustOnsets.
    Errors: ValueError for an unknown t_delay_from.
    """
    from .onsets import Onsets, board_onsets

    if t_delay_from not in ("data", "config"):
        raise ValueError(f"t_delay_from must be 'data' or 'config', not {t_delay_from!r}")
    period = 1.0 / fps
    tol = max(0.02 * hysteresis, 1e-9 * max(float(np.ptp(q_rev)), 1.0))
    t_stop = motor_stop_times(t_enc, q_rev, rt, rq, tol)
    d0 = coarse_delay(t_f, obs, t_stop, t_enc, q_rev, period)
    threshold_rule = None
    if board is None:
        board, threshold_rule = board_onsets(t_enc, q, rt, rq, t_f, obs, fps,
                                             d0 if t_delay_cfg is None else t_delay_cfg, onset_cfg)
    # The board's candidates by reversal (its t1 is the commanded reversal, up to rounding).
    guess = np.full(rt.size, np.nan)
    bidx = np.full(rt.size, -1)
    if board.t1_s.size:
        i = np.argmin(np.abs(rt[:, None] - board.t1_s[None, :]), axis=0)
        near = np.abs(rt[i] - board.t1_s) < 0.5 * period
        guess[i[near]] = board.t2_s[near]
        bidx[i[near]] = np.nonzero(near)[0]
    t_next = np.r_[t_stop[1:], t_enc[-1] + 1.0]
    # Pass 1 on up to 24 reversals spread over the record: the record's delay and ringing
    # (searched per reversal); pass 2 on all with those, the stop searched +-1.5 frames.
    sub = np.unique(np.linspace(0, rt.size - 1, min(rt.size, 24)).round().astype(int))
    ref1 = refine(t_f, obs, t_stop[sub], t_next[sub], guess[sub], d0, period)
    d1, _, n1 = delay_from_stops(ref1.tau0_s, t_stop[sub])
    d1 = d1 if n1 >= 4 else d0
    rs = ring_summary(ref1)
    ring = (rs["freq_hz"], rs["decay_per_s"]) if rs["share"] > 0.5 else (0.0, 0.0)
    # ring: any ringing pass 1 kept (the change-point model's columns, the delay interval's
    # widening); ring_mode: only a tip mode that rings (`tip_mode`: light, in the band searched).
    ring_mode = tip_mode(rs)
    # Whether the onset rings too: the record decides on pass 1's reversals (onset_ring_evidence).
    onset_ring = onset_ring_evidence(t_f, obs, t_stop[sub], t_next[sub], guess[sub], d1, period, ring) \
        if ring[0] > 0 else None
    ring_from = "pass 1, over half the reversals" if ring[0] > 0 else None
    if ring[0] == 0 and rs["reversals_ringing"] >= MIN_REFINED and tip_mode(rs, min_share=0.0)[0] > 0:
        # A mode the onset excites rings after the onset, not after the stop, where a sine or a
        # swing decelerates gradually; pass 1's windows end soon after the onset, so the ring shows
        # on a minority of them, and there the refined onsets took it for a step (15 px on every
        # reversal) and came late: seventeenth-ringing-sine25-noisy, 8 of 17 ringing (4.49 Hz; 4.19
        # rendered), B 101 %. The record decides, as for the onset's column: pass 1's ringing, a
        # tip mode on at least MIN_REFINED reversals, is kept where the onset's ring column wins
        # on the record (`onset_ring_evidence`, its sum positive) and on most of its reversals.
        cand = (rs["freq_hz"], rs["decay_per_s"])
        ev = onset_ring_evidence(t_f, obs, t_stop[sub], t_next[sub], guess[sub], d1, period, cand)
        if ev["used"] and ev["share_for"] > 0.5:
            ring, ring_mode, onset_ring = cand, cand, ev
            ring_from = "pass 1's minority, the onset's ring column on the record"
    # Where the onset excites the mode, the ring the last onset left is still there at the next
    # reversal: its columns too (`_Episode._carry_cols`). The evidence above is taken without
    # them (with them in the onset's model only, it also counted the ring the last stop left,
    # and took the onset's column in where only the stop rings: the Fig. 7 replica's 2 Hz ring).
    kw_ref = dict(ring=ring, stop_back=1.5, onset_ring=bool(onset_ring and onset_ring["used"]),
                  carry=bool(onset_ring and onset_ring["used"]) and ring_mode[0] > 0)
    ref = refine(t_f, obs, t_stop, t_next, guess, d1, period, **kw_ref)
    # A registration that flips with the direction (the refined onsets' steps follow it,
    # `direction_jump`): an exposure then catches its step part-way now and then, so every
    # reversal is refined again with steps that may come with a part frame (`_Episode._col_part`;
    # eleventh-registration-sine25-noisy: 5.4 -> 4.1 %). Not on a ringing record (a mode that
    # rings, `ring_mode`): the ring the onset excites starts against the motion at every
    # reversal, so its steps follow the direction too (ratio 5.6-5.9 on two development ringing
    # sines after the second pass, 6-17 on four after the first), and there the part frame took
    # in the first moving frame and put the onsets early (fresh-ringing-sine30: 1.6 -> 4.7 %;
    # dev-ring5-sine30 with part frames on every record: b 0.007 mm short at the median).
    part = ring_mode[0] == 0 and direction_jump(ref, rq)["found"]
    if part:
        ref = refine(t_f, obs, t_stop, t_next, guess, d1, period, part=True, **kw_ref)
    d_stops, d_stops_se, n_d = delay_from_stops(ref.tau0_s, t_stop)
    # The actuator-shape model (playscope.fit.onset_play): the delay's likelihood over the record
    # and a B sample per reversal that needs no "still" frame.
    from . import onset_play as P

    warnings = []
    d_shape, d_shape_se, n_shape = float("nan"), float("nan"), 0
    # Which model: the actuator-shape one where the play is taken up in fewer than FAST_FRAMES
    # frames on a quarter of the reversals (a still frame between stop and onset is then rare, and the change-point model
    # invents steps); from there on the change-point refinement, which the Fig. 7 replica's
    # records (10-25 frames, ringing included) were checked on, and where the actuator-shape
    # model did worse on development (2 Hz ringing, sine excitation, docs/host.md).
    v = np.gradient(q, t_enc)
    # The refined onsets' figure (or the actuator's, `gate_frames`) decides whether the model is
    # fitted; once fitted, either figure below FAST_FRAMES uses it (below).
    ref_frames = refined_frames(ref, t_enc, q, v, rq, d_stops if n_d >= 4 else d1, fps)
    amp = np.abs(np.diff(rq))
    b_max = 0.6 * float(np.median(amp)) if amp.size else float(np.ptp(q))
    M = rt.size
    # The same figure from the actuator alone, for the board's median eq. 1 width: the refined
    # onsets can be fooled late (a "step" fitted to noise when no frame is still after a fast
    # reversal makes the play look taken up over tens of frames), the actuator's trajectory
    # cannot. The smaller of the two decides whether the play is taken up fast.
    act_frames = actuator_frames(t_enc, q, rt, rq, board_width(board.b), period)
    # Only when the refined onsets show that symptom: a step on most reversals that does not
    # follow the direction (no registration to explain it). Otherwise they stand: on a ringing
    # record the board's onsets come early and its width would call a slow take-up fast.
    # Or when they look many times later than the actuator says (FOOLED_LATE): a ringing tip
    # or a registration jump after a fast reversal fools them just as late, with steps that do
    # follow the direction (dev-ring3-swings25: 28.1 frames against the actuator's 2.4;
    # fourth-registration-swings25-fast: 17.2 against 1.25). The slow records where the
    # refined onsets are right stay within a small factor of the board's early width (Fig. 7
    # replica, every case, ringing included, seeds 0 and 1: 2.4 at most, its 3.5 Hz ring).
    ref_frames_raw = ref_frames
    stepped = ref.ok & (ref.step_px > 0)
    invented = stepped.sum() >= max(4, 0.5 * ref.ok.sum()) and not direction_jump(ref, rq)["found"]
    ref_frames = gate_frames(ref_frames, act_frames, invented)
    if not _shape_fit_needed(ref_frames):
        pf = P.PlayFit(np.full(M, np.nan), np.full(M, np.nan), np.full(M, np.nan), np.zeros(M, bool),
                       float("nan"), (float("nan"), float("nan")), float("nan"), False, (0.0, 0.0), b_max)
        pdoc = {"fitted": False, "why": f"refined onsets (and the actuator, for the board's median b) take the "
                                        f"play up over {ref_frames:.1f} frames (lower quartile) >= {FAST_FRAMES:g}"}
    else:
        pf, pdoc = P.fit(t_enc, q, rt, rq, t_f, obs, period, b_max)
        pdoc["fitted"] = True
    def model_frames(pf) -> float:
        """The actuator-shape model's own frames to take up the play (lower quartile)."""
        if not pf.ok.any():
            return float("nan")
        return frames_to_take_up(pf.b[pf.ok], pf.t2_s[pf.ok] - pf.t_delay_s, t_enc, v, fps)

    shape_frames = model_frames(pf)
    # Once fitted (the refined onsets, or the actuator where they invent steps, call the take-up
    # fast), the model stands when either figure is below FAST_FRAMES. (The larger deciding
    # turned it down on a 60 fps triangle whose figures were 4.2 (model) and 2.8 (refined):
    # the refined onsets' delay then came from the stops a leg off, 0.47 s for a true 0.149 s,
    # B 47 %, where the model's delay was 0.150 s; fifth-delay-triangle60-noisy.)
    fast_frames = float(np.nanmin([shape_frames, ref_frames])) if np.isfinite([shape_frames, ref_frames]).any() \
        else float("nan")
    use_shape = bool(pdoc["fitted"] and np.isfinite(pf.t_delay_s) and fast_frames < FAST_FRAMES)
    d_stop_ref = d_stops
    # Only where the image stops were found on most reversals (so the refined onsets are there to
    # fall back on): a record whose stops are not found says nothing against the model's delay.
    # On a periodic excitation the delay is ambiguous by a leg (0.47 s from the stops against
    # 0.151 s, true, from the model on a 0.32 s triangle; 0.48 s from the model against 0.08 s,
    # true, from the stops on a 0.4 s one): a configured delay that one of the two matches
    # (within its 95 % interval and half a frame, as choose_delay) settles it.
    # Without a configured delay nothing arbitrates and the model stands (the stops may be the
    # ones a leg off: a 0.25 s triangle without one had the stops at 0.51 s, the model right).
    stops_match_cfg = t_delay_cfg is not None and n_d >= max(4, 0.5 * M) and \
        abs(t_delay_cfg - d_stop_ref) <= 1.96 * d_stops_se + period / 2
    if use_shape and abs(pf.t_delay_s - d_stop_ref) > P.DELAY_SPAN * period and stops_match_cfg:
        # The model's delay search walked beyond its own span from where the image stops and the
        # configured delay agree: most often the leg a periodic excitation leaves open (its wide
        # scan found the next leg). Fitted again with the scan confined to +- DELAY_SPAN frames of
        # the stops' delay; when it still strays, the model does not describe this record and the
        # refined onsets do.
        pdoc["strayed_delay_s"] = pf.t_delay_s
        pf2, pdoc2 = P.fit(t_enc, q, rt, rq, t_f, obs, period, b_max, d_guess=d_stop_ref)
        if np.isfinite(pf2.t_delay_s) and abs(pf2.t_delay_s - d_stop_ref) <= P.DELAY_SPAN * period:
            warnings.append(f"onsets: the actuator-shape model's delay {pf.t_delay_s:.4f} s lay over {P.DELAY_SPAN:g} "
                            f"frames from the image stops' {d_stop_ref:.4f} s, which the configured delay matches; "
                            f"fitted again near them ({pf2.t_delay_s:.4f} s)")
            pf, pdoc = pf2, {**pdoc2, "fitted": True, "strayed_delay_s": pf.t_delay_s, "refitted_near_s": d_stop_ref}
            shape_frames = model_frames(pf)  # reported; the gate was read on the first fit
        else:
            warnings.append(f"onsets: the actuator-shape model's delay {pf.t_delay_s:.4f} s lies over {P.DELAY_SPAN:g} "
                            f"frames from the image stops' {d_stop_ref:.4f} s; its B samples are not used")
            use_shape = False
    if use_shape:
        d_data, (ci_lo, ci_hi), d_se = pf.t_delay_s, pf.t_delay_ci_s, pf.t_delay_sd_s
        how = "actuator-shape model, posterior mean"
    else:
        # The delay from the approach to each stop with the actuator's shape (the kink of the
        # stop fit comes early on a gradual deceleration); it needs the refined onsets, so only
        # here, where they are used; recentred while it lands near its grid's edge.
        t2_img = np.where(ref.ok, ref.t2_s, np.nan)
        guess_d = d_stops if n_d >= 4 else d1
        # A delay cannot be negative; the stops can say so on a ringing sine (a half-cycle of
        # the ring looks like the approach's end: -0.12 s on eighth-ringing-sine25-noisy), and a
        # grid centred there held no delay >= 0 (the stops' figure, clipped to 0, then replaced a
        # right configured delay). A figure under DELAY_SHAPE_SPAN frames puts the grid's start
        # at 0 (its span 0 to twice DELAY_SHAPE_SPAN frames).
        guess_d = max(guess_d, DELAY_SHAPE_SPAN * period)
        for _ in range(3):
            d_shape, d_shape_se, n_shape = delay_from_shape(t_enc, q, rt, rq, t_f, obs, t2_img, guess_d, period,
                                                            span_frames=DELAY_SHAPE_SPAN, ring=ring_mode)
            if not (n_shape >= 4 and abs(d_shape - guess_d) > 2.0 * period):
                break
            guess_d = d_shape
        if n_shape >= 4:
            d_data, d_se, how = d_shape, d_shape_se, "approach to the stop with the actuator's shape, median"
        else:
            d_data = d_stops if n_d >= 4 else d1
            d_se = d_stops_se if n_d >= 4 else period
            how = "image stop - motor stop, median"
        ci_lo, ci_hi = d_data - 1.96 * d_se, d_data + 1.96 * d_se
        if ring[0] > 0:
            # A ringing record (the change-point model's ringing on most reversals of its first
            # pass), whichever of the delays above is used: the tip's ring after the stop and the
            # stop's own time trade within about half the ring's period (a half-cycle of the ring
            # looks like the approach's end), alike at every reversal, which the interval's scatter
            # term cannot see. The interval is widened by RING_DELAY_SHARE of the period, so a
            # configured delay within it stands. Development ringing sines: the record's delay came
            # 0.055-0.058 s early on two (replacing a right configured one; kept out by this) and
            # 0.24 s early on a third with a 2.5 Hz ring (beyond half its period: still replaced).
            # The price: a configured delay wrong by less than this is kept on a ringing record.
            widen = RING_DELAY_SHARE / ring[0]
            ci_lo, ci_hi = ci_lo - widen, ci_hi + widen
            how += f", interval widened by {RING_DELAY_SHARE:g} of the ring's period"
    # A delay cannot be negative (the stops can say so on a sine): clipped to 0 s where its
    # interval and half a frame reach zero; one that lies wholly below is left as it is, reported
    # and not used (choose_delay).
    admissible = not delay_below_zero(d_data, ci_hi, period)
    if np.isfinite(d_data) and d_data < 0 and admissible:
        d_data, ci_lo, ci_hi = 0.0, max(ci_lo, 0.0), max(ci_hi, 0.0)
    if not use_shape:
        pf.ok[:] = False
    td, src, agree, allow = choose_delay(d_data, (ci_lo, ci_hi), how, t_delay_cfg, period, t_delay_from)
    if not admissible:
        warnings.append(f"t_delay: the record says {d_data:.4f} s (95 % {ci_lo:.4f}..{ci_hi:.4f}, +-{allow:.4f} s for "
                        f"the frame period), below zero: its estimator does not describe this record; using "
                        f"{td:.4f} s ({src})")
    if t_delay_cfg is not None and agree is False:
        warnings.append(f"t_delay: the record says {d_data:.4f} s (95 % {ci_lo:.4f}..{ci_hi:.4f}, +-{allow:.4f} s for the "
                        f"frame period), the configuration "
                        f"{t_delay_cfg:.4f} s; using {'the configured' if t_delay_from == 'config' else 'the record'}'s "
                        f"({'--t-delay-from data' if t_delay_from == 'config' else '--t-delay-from config'} to change)")
    # The samples again at the delay used whenever it is not the model's own, however close: on
    # a fast swing (~10 mm/s at the take-up) half a millisecond moves every fast frame's drive by
    # 0.005 mm and b with it. A skip under 1/32 frame left the heavy-noise fast-swing rendering of
    # the seventh set-aside group at 5.64 % (configured 0.147 s, the model's 0.1475 s); 2.27 % with
    # this change alone.
    if use_shape and td != pf.t_delay_s:
        pf = P.refit_at(pf, t_enc, q, rt, rq, t_f, obs, period, td)
    # B samples (eq. 1): the actuator-shape model's; the refined onset's, then the board's, where it has none.
    rows, row_r = [], []
    n_play = n_ref = n_board = n_lost_before = 0
    # Eq. 1 needs t2 - t_delay after t1: an onset before the direction change is not one.
    # A sine's gradual stop is fitted early, and its true end, a ring's half-cycle later,
    # can fall into the onset's search (twelfth-ringing-sine60-noisy: 6 of 68 refined
    # onsets, each b ~ 0 with sigma_b near 0, where the actuator barely moves). Such a
    # reversal keeps the board's onset, when that one comes after t1 (NaN onsets compare False).
    ref_after = ref.ok & (ref.t2_s - td >= rt)
    board_after = (bidx >= 0) & (board.t2_s[np.maximum(bidx, 0)] - td >= rt) if board.t2_s.size \
        else np.zeros(rt.size, bool)
    n_before = int(np.sum(ref.ok & ~ref_after & ~pf.ok))  # where the actuator-shape samples are not used
    # The board's onset where the refinement has none: its timing uncertainty is a frame period,
    # or, where it is larger, how far the board's onsets lie from the refined ones on the
    # reversals that have both (median |difference|): on a ringing record the board fires early
    # or late by several frames (twelfth-ringing-sine60-noisy: 7-10 frames late), and a sample
    # weighted as if timed to a frame pulled B(q) up.
    both = ref_after & (bidx >= 0)  # refined onsets that are onsets (after t1)
    board_sd = period
    if both.sum() >= 4:
        board_sd = max(period, float(np.median(np.abs(board.t2_s[bidx[both]] - ref.t2_s[both]))))
    for r in range(rt.size):
        row_r.append(r)
        if pf.ok[r]:
            b, sb = pf.b[r], pf.sigma_b[r]
            t2 = pf.t2_s[r]
            q2 = rq[r] - np.sign(rq[r] - (rq[r - 1] if r else q[0])) * b
            rows.append((rt[r], t2, rq[r], q2, 0.5 * (rq[r] + q2), b, sb))
            n_play += 1
            continue
        if ref_after[r]:
            t2, sd = ref.t2_s[r], ref.sigma_t2_s[r]
            n_ref += 1
        elif board_after[r]:
            t2, sd = board.t2_s[bidx[r]], board_sd
            n_board += 1
        else:
            n_lost_before += bool(ref.ok[r] or bidx[r] >= 0)  # it had an onset, only before t1
            row_r.pop()
            continue
        q2 = float(np.interp(t2 - td, t_enc, q))
        sb = abs(float(np.interp(t2 - td, t_enc, v))) * sd
        rows.append((rt[r], t2, rq[r], q2, 0.5 * (rq[r] + q2), abs(q2 - rq[r]), sb))
    if n_lost_before >= max(4, 0.5 * (n_lost_before + n_ref + n_board)):
        # Most reversals lost because their onsets lie before t1: the delay used, not the onsets,
        # is the suspect (a delay at the edge of the coarse scan, 0.5 s against 0.178 s true on a
        # 90 s rendering of tenth-delay-triangle60-noisy, put every onset there).
        warnings.append(f"onsets: {n_lost_before} reversals give no B sample because their onsets lie before the "
                        f"reversal at the t_delay used, {td:.4f} s ({src}); the delay is likely wrong: check "
                        f"session.json's t_delay, or keep it with --t-delay-from config")
    a = np.array(rows, float).reshape(-1, 7)
    row_r = np.array(row_r, int)
    reasons = {"actuator_shape": n_play, "refined": n_ref, "board_only": n_board,
               "none": int(rt.size - n_play - n_ref - n_board)}
    on = Onsets(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], a[:, 5], reasons, sigma_b=a[:, 6])
    pace = pacing(t_enc, q, on, fps, td)
    if pace["frames_to_take_up"] < pace["frames_wanted"]:
        warnings.append(f"the play is taken up in {pace['frames_to_take_up']:.1f} frame(s) (median): B is timed to "
                        f"about {pace['sigma_frame_travel']:.3g} per sample by the frame period; a swing at "
                        f"<= {pace['speed_to_use']:.3g} units/s would take it up over {pace['frames_wanted']} frames")
    guard = guard_rail(on, row_r, board, bidx, period, t_enc, q, td)
    if guard["warn"]:
        warnings.append(f"onsets: the actuator-shape B samples and the board's plain eq. 1 onsets disagree beyond "
                        f"their combined uncertainty on {guard['disagree']} of {guard['compared']} reversals; "
                        f"both B curves are in onset.refine.guard")
    steps = ref.ok & (ref.step_px > 0)
    registration = direction_jump(ref, rq, pdoc if use_shape else None)
    report = {
        "method": "joint ML change-point model per reversal (playscope.fit.onset_refine)",
        "board_reasons": board.reasons,
        "board_threshold": threshold_rule,
        "t_delay": {"configured_s": t_delay_cfg, "record_s": d_data, "record_se_s": d_se,
                    "record_ci95_s": [ci_lo, ci_hi], "record_admissible": admissible, "agrees_with_configured": agree,
                    "frame_allowance_s": allow, "used_s": td, "used": "configured" if td == t_delay_cfg else "record",
                    "from": t_delay_from, "source": src, "stops_s": d_stops, "stops_fitted": n_d, "shape_s": d_shape, "shape_se_s": d_shape_se,
                    "shape_reversals": n_shape,
                    "coarse_s": d0, "first_pass_s": d1},
        "actuator_shape": {**pdoc, "samples": int(pf.ok.sum()), "used": use_shape,
                           "frames_to_take_up": fast_frames, "model_frames": shape_frames, "fast_frames": FAST_FRAMES,
                           "actuator_frames_board_b": act_frames, "refined_frames": ref_frames_raw},
        "pacing": pace,
        "guard": guard,
        "ringing": {**ring_summary(ref), "onset_ring": onset_ring, "ring_from": ring_from},
        "steps": {"reversals_with_step": int(steps.sum()),
                  "median_step_px": float(np.median(ref.step_px[steps])) if steps.any() else 0.0},
        "registration": registration,
        "sigma_t2_s_median": float(np.nanmedian(ref.sigma_t2_s)) if ref.ok.any() else None,
        "refined_before_reversal": n_before,
        "lost_before_reversal": n_lost_before,
        "board_sigma_t2_s": board_sd,
    }
    return RobustOnsets(on, float(td), src, report, warnings)


def guard_rail(on, row_r: np.ndarray, board, bidx: np.ndarray, period: float, t_enc: np.ndarray,
               q: np.ndarray, t_delay_s: float) -> dict:
    """Compare each B sample with the board's plain eq. 1 sample of the same reversal: they
    disagree when |b - b_board| > 2 sqrt(sigma_b^2 + sigma_board^2), sigma_board the travel of
    one frame period at the board's onset / sqrt(3) (its onset lies anywhere in the frame
    interval, and its threshold adds up to about as much). warn: more than half of at least 4
    compared reversals disagree. Both B curves (fit_backlash_samples of each set, at 9 q) are
    reported. Returns a JSON-ready dict."""
    from .backlash import fit_backlash_samples

    v = np.gradient(q, t_enc)
    k = bidx[row_r] if row_r.size else np.zeros(0, int)
    has = k >= 0
    out = {"compared": int(has.sum()), "disagree": 0, "warn": False}
    if not has.any():
        return out
    bb = board.b[k[has]]
    sb = np.abs(np.interp(board.t2_s[k[has]] - t_delay_s, t_enc, v)) * period / np.sqrt(3)
    sa = on.sigma_b[has]
    dis = np.abs(on.b[has] - bb) > 2 * np.sqrt(sa ** 2 + sb ** 2)
    out["disagree"] = int(dis.sum())
    out["warn"] = bool(has.sum() >= 4 and dis.sum() > 0.5 * has.sum())
    qg = np.linspace(float(np.min(on.q_mean)), float(np.max(on.q_mean)), 9)
    curves = {"q": qg}
    for name, (qm, b) in {"samples": (on.q_mean, on.b), "board": (board.q_mean, board.b)}.items():
        try:
            curves[name] = fit_backlash_samples(qm, b).B(qg)
        except Exception as e:  # a curve that cannot be fitted is reported, not fatal
            curves[name] = f"not fitted: {e}"
    out["B_curves"] = curves
    return out
