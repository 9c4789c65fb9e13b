"""Eq. 1 from the actuator's own trajectory: B samples and t_delay that hold when the play is
taken up within a frame.

Around a reversal (t1, q1) the play operator (eq. 3) gives the tip's drive z exactly, for a
width b, from the actuator record alone: on the old branch z = q - s b/2 (s = +1 when q rose
to q1), then z holds until q has come back by b, then z = q + s b/2. Up to the constant
-s b/2 (taken up by the image offset) that is

    w(t; b) = q(t)                           t <= t1
            = q1 - s max(D(t) - b, 0)         t > t1,  D(t) = max over [t1, t] of s (q1 - q)

and the marker of frame k (stamped t_k, captured at t_k - t_delay) is, near the reversal,

    p_k = G(z_k) + A + K w_k                    the image of z: the record's image curve G
                                                (fit/image_curve.py) once B(q) has a first fit,
                                                before that a cubic in w free per reversal
          + S [k >= j]                          optional: a registration / channel jump at the
                                                onset's first or second frame (j)
          + ringing (optional, the record's frequency and decay): a free-phase ring carried
            over from the previous reversal, and the tip mode's response to the drive w itself
            (the drive through the mode's low-pass: one column, _Rev._ring_drive)

p (2,) px; A, K, K2, S and the ring amplitudes are 2-vectors, linear given (b, j, t_delay), so
each candidate is one least-squares solve. With Gaussian noise of unknown variance the profile
likelihood is RSS^(-N/2) (N = 2 x frames); the onset's own time is not a parameter: the frames
see the whole shape of q (a constant-speed leg, a raised-cosine swing, a sine) through w, so a
play taken up between two frames is still measured by where the new branch lies, not by a
"still" frame. b's posterior under a flat prior on a grid gives each B sample and its
sigma; when a jump at the onset and b cannot be told apart (no frame inside the dead band),
the posterior spreads over the frame interval and sigma_b says so (about the travel of one
frame period / sqrt(12)).

t_delay: the same model on up to 24 reversals spread over the record, on a grid of delays
(1/16 frame) around a first guess, each reversal's likelihood marginalised over b and the jump;
their sum (independent reversals) is the record's likelihood of t_delay. The estimate is its
posterior mean, the interval its 2.5-97.5 % points, widened by the grid step.

Units: t s, q actuator units, image px. Source: eq. 1 and eq. 3 of the paper; Schwarz (1978)
for the BIC penalties of the optional parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .image_curve import fit_image_curve

SUB = 16                              # delay grid points per frame period
DELAY_SPAN = 3.0                      # the delay grid reaches +- this many frames from the guess
HOLD_BACK = 0.2                       # a ringing record's window ends when q comes back this share of b_max
FAR_RING = 1.2                        # ... and the new branch may reach b_max + this x b_max (a whole swing)
RING_LASTS = 1.0                      # ... when the ring lasts: decay (1/s) <= this x frequency (Hz), zeta <~ 0.16
PRE_S, POST_S = 1.0, 3.5              # window around t1 (s, scene clock)
NB = 160                              # b grid points
RING_HZ = np.arange(1.5, 7.01, 0.5)   # ringing searched (Hz) when the record rings
RING_ALPHA = np.array([0.5, 1.5, 3.0, 6.0, 12.0])
RING_GAIN = np.arange(0.0, 4.0001, 0.1)  # the tip mode's gain g searched (drive z + g (y - z)); g >= 0: a tip driven through its base lags it
DELAY_REVERSALS = 24
CURVE_PASSES = 2                      # B(q) and the image curve again from the curve's own samples (fit)
JUMP_T = 4.0                          # signed-jump mean / standard error for a record's jump
GAIN_TOP = 3.0                        # the joint (delay, gain) profile searches g up to this (`_gain_settle`)
JUMP_AGREE = 0.5                      # the image curve's offset reaches this share of the onsets' jump along it
SAFE_REACH = 1.5                      # the previous reversal's play is taken up once q has gone this x B(q)
FINE, FINE_SPAN = 8, 1.5              # the delay's fine pass: FINE points per grid step, +- FINE_SPAN steps


@dataclass
class PlayFit:
    """Per reversal (M,): b (posterior mean, actuator units), sigma_b, t2_s (image clock onset
    for that b: q back by b from q1, plus t_delay), ok; and the record's t_delay_s with its
    95 % interval (lo, hi), the choice of steps / ringing and the b grid's top b_max."""

    b: np.ndarray
    sigma_b: np.ndarray
    t2_s: np.ndarray
    ok: np.ndarray
    t_delay_s: float
    t_delay_ci_s: tuple
    t_delay_sd_s: float
    steps: bool
    ring: tuple
    b_max: float


class _Rev:
    """One reversal's data: encoder window, direction, frames (fixed set), the b grid."""

    def __init__(self, t_enc, q, t1, q1, s, t_start, t_end, t_f, obs, d_lo, d_hi, b_max, period, b_of_q=None,
                 t_safe=None):
        # Encoder samples for every frame's scene time under every delay of the grid.
        i0 = max(np.searchsorted(t_enc, t_start - (d_hi - d_lo)) - 1, 0)
        i1 = min(np.searchsorted(t_enc, t_end + (d_hi - d_lo)) + 1, t_enc.size)
        self.te, self.qe = t_enc[i0:i1], q[i0:i1]
        self.t1, self.q1, self.s = t1, q1, s
        after = self.te > t1
        back = np.where(after, s * (q1 - self.qe), 0.0)
        self.D = np.maximum.accumulate(np.maximum(back, 0.0))  # travel back from q1 (nondecreasing)
        # One frame set for the whole delay grid (so that the likelihoods compare): frames after
        # the window's start for some delay of the grid and before its end for some delay (the
        # start is where q has gone b_max from the previous reversal, the end the next reversal
        # or the new branch's reach; z holds or the branch goes on past the end, so the model
        # stays right there), and past t_safe (when given) for every delay: before it the
        # previous reversal's play may not be taken up yet, where the model is wrong. Without that
        # condition, on fast swings the grid's larger delays took in 1-2 frames of the previous
        # dead band, which pulled the delay (seventh set-aside, a wrong configured delay on fast
        # swings: the record's delay 2.5 ms late with its interval past the truth, B 13.8 %).
        # Requiring the whole grid inside the start instead lost the swing's frames that pin a
        # registration jump (dev-reg-swings25 6.2 -> 15.2 %).
        t_safe = -np.inf if t_safe is None else t_safe
        sel = ((t_f - d_lo >= t_start) & (t_f - d_hi >= t_safe) & (t_f - d_hi <= t_end)
               & np.all(np.isfinite(obs), axis=1))
        self.n = int(sel.sum())
        self.ymean = obs[sel].mean(axis=0) if self.n else np.zeros(2)
        self.tf, self.Y = t_f[sel], obs[sel] - self.ymean
        d_end = float(self.D[-1])
        self.b_grid = np.linspace(0.0, min(b_max, 0.95 * d_end), NB) if d_end > 0 else np.zeros(0)
        self.period = period
        self.b_of_q = b_of_q
        self.jump = None  # the record's jump vector J (px), the jump being s J; None: free
        self.curve = None  # the record's image curve G(z) (image_curve.ImageCurve); None: a cubic of z here

    def onset_scene(self, b: np.ndarray) -> np.ndarray:
        """Scene time at which q has come back by b from q1 (first encoder sample)."""
        i = np.clip(np.searchsorted(self.D, b, side="left"), 0, self.te.size - 1)
        return self.te[i]

    def logw(self, d: float, b: np.ndarray, steps: bool, ring) -> tuple[np.ndarray, np.ndarray]:
        """Log weight (profile likelihood less BIC penalties) of each candidate (b, jump frame);
        returns (lw (nb, J), b) with J = 1 (no jump) or 2 (a jump from the onset's first frame,
        from the next)."""
        X, w, ts, t_on = self._design(d, b, ring)
        Y0 = self._target(w, b)
        N = 2 * self.n
        # A record with jumps (chosen over the record) has one at every reversal: the no-jump
        # candidate would otherwise win where b and the jump cannot be told apart (no frame in
        # the dead band), and b would take the jump in; with the jump, b spreads over the frame
        # interval instead, and sigma_b says so.
        outs = [] if steps else [self._rss(X, Y0)]
        pen = [] if steps else [0.0]
        if steps:
            first = np.cumsum(ts[None, :] > t_on[:, None], axis=1)        # 1 at the onset's first frame
            for m in (1, 2):
                # The jump from frame m on: the record's jump vector (s J, known) when given,
                # else a free level; a rotation being a change of view, it also scales the
                # image curve a little (a slope from frame m on, 0 at the onset).
                st = (first >= m).astype(float)
                if self.jump is not None:
                    Yg = Y0 - st[..., None] * (self.s * self.jump)[None, None, :]
                    outs.append(self._rss(np.concatenate([X, (st * w)[..., None]], axis=-1), Yg))
                else:
                    outs.append(self._rss(np.concatenate([X, st[..., None], (st * w)[..., None]], axis=-1), Y0))
                pen.append(0.0)
        rss = np.stack(outs, axis=1)                                      # (nb, J)
        pen_steps = 2 * np.log(N) if steps else 0.0                       # 4 parameters: (4/2) log N
        return -0.5 * N * np.log(np.maximum(rss, 1e-300)) - np.array(pen)[None, :] - pen_steps, b

    def _design(self, d: float, b: np.ndarray, ring):
        """The shared columns of each candidate b at delay d: (X (nb, n, p), w (nb, n) the
        scaled drive, ts (n,) scene times, t_on (nb,) onsets on the scene clock)."""
        ts = self.tf - d
        qk = np.interp(ts, self.te, self.qe)
        Dk = np.interp(ts, self.te, self.D)
        post = ts > self.t1
        scale = max(float(np.max(self.D)), 1e-9)
        w = np.where(post[None, :], self.q1 - self.s * np.maximum(Dk[None, :] - b[:, None], 0.0), qk[None, :])
        if self.b_of_q is not None:
            # B changes with q: z = q - s B(q)/2 on the old branch, q + s B(q)/2 on the new one,
            # so each branch drifts from "q plus a constant" by half the change of B (the
            # record's first-pass B(q)); relative to the stop and to the onset respectively.
            bq = self.b_of_q(qk)
            q_on = self.q1 - self.s * b
            w = w + np.where(post[None, :], np.where(Dk[None, :] > b[:, None],
                                                     0.5 * self.s * (bq[None, :] - self.b_of_q(q_on)[:, None]), 0.0),
                             -0.5 * self.s * (bq - float(self.b_of_q(np.array([self.q1]))[0]))[None, :])
        w = (w - self.q1) / scale                                         # (nb, n)
        t_on = self.onset_scene(b)                                        # (nb,)
        ring_cols = []
        if ring is not None and ring[0] > 0:
            om, al = 2 * np.pi * ring[0], ring[1]
            tau = ts - ts[0]
            e = np.exp(-al * tau)
            ring_cols = [np.broadcast_to(e * np.sin(om * tau), w.shape), np.broadcast_to(e * np.cos(om * tau), w.shape)]
            y = (self._ring_drive(b, ring[:2], ts) - self.q1) / scale
            if len(ring) > 2:  # the record's gain g: the tip's drive is z + g (y - z)
                w = w + ring[2] * (y - w)
            else:  # g free (choosing the ringing): y is a column of its own
                ring_cols.append(y)
        # With the record's image curve the shape of Q(z) is known (_target takes it off); an
        # offset and a slope stay free here, so only G's shape is relied on (image_curve).
        poly = [np.ones_like(w), w] if self.curve is not None else [np.ones_like(w), w, w * w, w * w * w]
        return np.stack(poly + ring_cols, axis=-1), w, ts, t_on

    def _target(self, w: np.ndarray, b: np.ndarray) -> np.ndarray:
        """What the columns fit, per candidate b: the centred frames Y (1, n, 2) when the image
        curve is free here, or Y less G(z) (nb, n, 2) with the record's curve, z = the drive w in
        actuator units less s b / 2 (the play's centre, eq. 3; its constant part is the offset's)."""
        if self.curve is None:
            return self.Y[None]
        scale = max(float(np.max(self.D)), 1e-9)
        z = w * scale + self.q1 - 0.5 * self.s * b[:, None]
        return (self.Y + self.ymean)[None] - self.curve(z)

    def _ring_drive(self, b: np.ndarray, ring: tuple, ts: np.ndarray) -> np.ndarray:
        """The tip mode's response to the drive for each b, at scene times ts: (nb, n).

        A tip mode x'' + 2 alpha x' + w0^2 x = -g z'' (base excitation by the drive z, w0^2 =
        w^2 + alpha^2) adds g x to the drive; x = y - z with y the drive through the low-pass
        (2 alpha s + w0^2) / (s^2 + 2 alpha s + w0^2), so the image of z + g x is a combination
        of z and y: one more column, y, whose coefficient carries g. The ringing after the stop
        and after the onset both come from z's own shape (b sets where the new branch starts),
        so the onset is where the motion starts, not where the ring swings. Bilinear
        discretisation at the encoder rate (from rest at the window's start; a ring carried
        over from before has its own free-phase columns). Cached per (b grid, ring)."""
        from scipy.signal import bilinear, lfilter

        key = (tuple(ring), b.size, float(b[0]), float(b[-1]))
        cache = self.__dict__.setdefault("_ring_cache", {})
        if key not in cache:
            if len(cache) >= 2:  # a ring grid passes once; the delay profile reuses one ring
                cache.clear()
            om, al = 2 * np.pi * ring[0], ring[1]
            w0 = om * om + al * al
            fs = 1.0 / float(np.median(np.diff(self.te))) if self.te.size > 1 else 1000.0
            bz, az = bilinear([2 * al, w0], [1.0, 2 * al, w0], fs=fs)
            after = self.te > self.t1
            z = np.where(after[None, :], self.q1 - self.s * np.maximum(self.D[None, :] - b[:, None], 0.0),
                         self.qe[None, :])
            y = lfilter(bz, az, z - z[:, :1], axis=1) + z[:, :1]
            cache[key] = y
        y = cache[key]
        i = np.clip(np.searchsorted(self.te, ts), 1, self.te.size - 1)
        f = np.clip((ts - self.te[i - 1]) / np.maximum(self.te[i] - self.te[i - 1], 1e-12), 0.0, 1.0)
        return y[:, i - 1] * (1 - f)[None, :] + y[:, i] * f[None, :]

    def jump_px(self, d: float, b: np.ndarray, ring=None) -> np.ndarray:
        """The free jump's image vector (px, (2,)) of the best jump candidate at delay d over b
        (with the ringing ``ring`` in the model, or none)."""
        keep, self.jump = self.jump, None
        lw, _ = self.logw(d, b, True, ring)
        self.jump = keep
        i, m = np.unravel_index(int(np.argmax(lw)), lw.shape)
        X, w, ts, t_on = self._design(d, b[i:i + 1], ring)
        st = (np.cumsum(ts > t_on[0]) >= m + 1).astype(float)
        Xj = np.column_stack([X[0], st, st * w[0]])
        coef, *_ = np.linalg.lstsq(Xj, self._target(w, b[i:i + 1])[0], rcond=None)
        return coef[X.shape[2]]

    def slope_px(self, d: float, b: float, m: int, ring=None) -> np.ndarray:
        """The image's slope along the drive (px per unit of the scaled drive, (2,)) of the fit
        at delay d and width b with a free jump from the onset's frame m (1 or 2; the jump
        columns of `logw`): the w column's coefficient, the sign saying which way the marker
        moves as z does. With the jump in the fit, a registration step against the motion is not
        read as the marker moving backwards."""
        X, w, ts, t_on = self._design(d, np.array([b]), ring)
        st = (np.cumsum(ts > t_on[0]) >= m).astype(float)
        Xj = np.column_stack([X[0], st, st * w[0]])
        coef, *_ = np.linalg.lstsq(Xj, self._target(w, np.array([b]))[0], rcond=None)
        return coef[1]

    def _rss(self, X: np.ndarray, Yg: np.ndarray) -> np.ndarray:
        """Residual sum of squares of the targets Yg ((1, n, 2): one for every candidate, or
        (G, n, 2): each candidate's own) on each candidate's columns X (G, n, p)."""
        A = np.einsum("gnp,gnq->gpq", X, X)
        A += 1e-9 * np.maximum(np.einsum("gpp->g", A), 1.0)[:, None, None] * np.eye(X.shape[2])[None]
        if Yg.shape[0] == 1:
            r = np.einsum("gnp,nc->gpc", X, Yg[0])
            yy = float(np.sum(Yg[0] * Yg[0]))
        else:
            r = np.einsum("gnp,gnc->gpc", X, Yg)
            yy = np.einsum("gnc,gnc->g", Yg, Yg)
        coef = np.linalg.solve(A, r)
        return np.maximum(yy - np.einsum("gpc,gpc->g", coef, r), 1e-12)


def _lse(x: np.ndarray, axis=None) -> np.ndarray:
    m = np.max(x, axis=axis, keepdims=True)
    return np.squeeze(m, axis=axis) + np.log(np.sum(np.exp(x - m), axis=axis))


def _reversals(t_enc, q, rt, rq, t_f, obs, d_lo, d_hi, b_max, period, b_of_q=None, hold=False, curve=None,
               safe=True) -> list:
    """A _Rev per reversal (None where the old branch is not known to be engaged: the first
    reversal, or q not moved by b_max since the previous one); curve: the record's image curve
    (image_curve.ImageCurve) each takes, or None (a cubic of the drive per reversal, and the
    window's new branch cut where it leaves the old branch's reach; also cut with hold).

    safe (with b_of_q): over a delay grid, only frames past the previous reversal's take-up for
    every delay of the grid (`_Rev`, t_safe); False keeps the frames inside the window's start
    for the grid's smallest delay.

    hold (a ringing record): the window runs over the whole new motion and the hold after it,
    past the next reversal until q has come back from it by HOLD_BACK b_max (the play stays
    engaged on the new side: z holds), instead of ending at the next reversal and where the new
    branch leaves the old one's reach. A tip that rings hides the few moving frames of a fast
    swing, but the ring that the onset's velocity step excites lasts the whole hold, and its
    phase and amplitude follow where z started (the tip mode's drive, `_Rev._ring_drive`): on a
    3 Hz ringing record at 25 fps the short windows put b near 0 on the fast swings' reversals,
    the long ones within a few % (development renderings). Not used without ringing: a
    registration flip makes the image curve differ by direction, and a long branch then costs
    (dev-reg-swings25 7.8 -> 14.1 %)."""
    out = []
    for r in range(rt.size):
        if r == 0:
            out.append(None)
            continue
        s = 1.0 if rq[r] > rq[r - 1] else -1.0
        i0, i1 = np.searchsorted(t_enc, [rt[r - 1], rt[r]])
        moved = np.nonzero(np.abs(q[i0:i1] - rq[r - 1]) > b_max)[0]
        if moved.size == 0:
            out.append(None)
            continue
        t_start = max(t_enc[i0 + moved[0]], rt[r] - PRE_S)
        t_safe = None
        if b_of_q is not None and safe:
            # Where the previous reversal's play is surely taken up: q gone SAFE_REACH x the first
            # B(q) from it (b_max, the window's start, is the swing's reach and comes later).
            # reach <= b_max, so q gets there no later than the start (`moved`); min() keeps b_max
            # for a NaN B(q).
            reach = min(b_max, SAFE_REACH * float(b_of_q(np.array([rq[r - 1]]))[0]))
            far_prev = np.nonzero(np.abs(q[i0:i1] - rq[r - 1]) > reach)[0]
            t_safe = max(t_enc[i0 + far_prev[0]], rt[r] - PRE_S)
        t_end = min(rt[r + 1] if r + 1 < rt.size else t_enc[-1], rt[r] + POST_S)
        if hold and r + 1 < rt.size:
            k1 = np.searchsorted(t_enc, rt[r + 1])
            k2 = np.searchsorted(t_enc, rt[r] + POST_S)
            back = np.nonzero(np.abs(q[k1:k2] - rq[r + 1]) > HOLD_BACK * b_max)[0]
            t_end = min(t_enc[k1 + back[0]] if back.size else t_enc[min(k2, t_enc.size - 1)], rt[r] + POST_S)
        # Without the record's image curve (a cubic of the drive per reversal): the new branch no
        # further from q1 than b_max plus the old branch's reach, so both branches see the same
        # stretch of the curve. With it the curve is known over the travel and the window runs
        # to the next reversal: after a fast reversal the cut left one or two frames of the new
        # branch, too few to tell a registration jump at the onset's frame from one a frame
        # later (which moves b by a frame's travel); the whole swing's frames tell them apart
        # (eighth-registration-swings25-fast: B 16.8 -> 5.1 %; development renderings). A ringing
        # record's long windows (hold) keep their own reach (FAR_RING), as before. The longer
        # windows first cost third- and fifth-ringing-swings25 7.4 -> 31.3 % and 9.1 -> 58.8 %;
        # the cause was the ringing gain chosen apart from the delay (`_gain_settle`), with which
        # they are at 5.3 and 7.6 %.
        if curve is None or hold:
            span = float(np.ptp(q[np.searchsorted(t_enc, t_start):i1 + 1]))
            j1 = np.searchsorted(t_enc, rt[r])
            j2 = np.searchsorted(t_enc, t_end)
            far = np.nonzero(s * (rq[r] - q[j1:j2]) > b_max + (max(span, FAR_RING * b_max) if hold else span))[0]
            if far.size:
                t_end = min(t_end, t_enc[j1 + far[0]])
        rv = _Rev(t_enc, q, rt[r], rq[r], s, t_start, t_end, t_f, obs, d_lo, d_hi, b_max, period, b_of_q, t_safe)
        rv.curve = curve
        out.append(rv if rv.n >= 8 and rv.b_grid.size else None)
    return out


def _ring_lasts(ring) -> bool:
    """A ringing (Hz, decay 1/s[, gain]) that lasts: at most RING_LASTS e-folds of decay per
    second per hertz, so it is still there after a swing (the long windows of `_reversals`).
    None or a zero frequency: no."""
    return ring is not None and ring[0] > 0 and ring[1] <= RING_LASTS * ring[0]


def _curve_agrees(jump: np.ndarray, curve) -> bool:
    """Whether the image curve sees the onsets' jump J (px, (2,)): its own direction-following
    offset (`image_curve`, fitted on the frames away from the reversals), -2 J_curve in the onset
    model's convention (the image moves by s J at a reversal whose old direction is s, and by
    -2 s J_curve there), reaches JUMP_AGREE x |J| along J. True without a curve.

    Why: the onsets' jump is one offset from the few frames around each reversal, where b and a
    jump trade along the motion, so a misfit there (a ringing tip's phase over a swing) comes out
    as a consistent "jump": third- and fifth-ringing-swings25 (no registration rendered) chose
    -3.6 and -5.1 px where the curve saw +4.7 and +7.7, B 31 and 59 %. On the registration
    renderings the two agree within 1.2 px of 24-32 (dev-, sixth-, eighth-registration-
    swings25-fast; development renderings)."""
    if curve is None:
        return True
    norm = float(np.linalg.norm(jump))
    return float((-2.0 * np.asarray(curve.jump_px, float)) @ (np.asarray(jump, float) / max(norm, 1e-12))) \
        >= JUMP_AGREE * norm


def _set_jump(revs: list, jump) -> None:
    """The record's jump vector (px, (2,), or None: free) on every reversal of revs (None kept)."""
    for rv in revs:
        if rv is not None:
            rv.jump = jump


def _delay_posterior(L: np.ndarray, grid: np.ndarray, T: float, step: float | None = None) -> tuple[float, float, float, float]:
    """The delay's posterior from its log-likelihood L (grid,) on grid (s) under a flat prior: mean,
    sd (with the grid step's own step / sqrt(12)) and the 2.5-97.5 % points widened by half a
    grid step (s); step defaults to T / SUB. Returns (mean, sd, lo, hi)."""
    h = T / SUB if step is None else step
    w = np.exp(L - L.max())
    w /= w.sum()
    d = float(np.sum(w * grid))
    sd = float(np.sqrt(np.sum(w * (grid - d) ** 2) + h ** 2 / 12))
    cw = np.cumsum(w)
    lo = float(grid[min(np.searchsorted(cw, 0.025), grid.size - 1)]) - 0.5 * h
    hi = float(grid[min(np.searchsorted(cw, 0.975), grid.size - 1)]) + 0.5 * h
    return d, sd, lo, hi


def _fine_delay(revs, grid: np.ndarray, est: tuple, steps: bool, ring, T: float) -> tuple[float, float, float, float]:
    """The delay's posterior again on a grid FINE times finer, +- FINE_SPAN coarse steps around the
    coarse estimate est (mean, sd, lo, hi), each reversal marginal over its full b grid, when the
    coarse posterior sits within about one step (sd under a step); else est unchanged.

    Why: on fast swings the likelihood is sharper than the 1/16-frame grid, so the coarse
    posterior collapses onto one grid point, up to half a step (1.25 ms at 25 fps) from the
    truth, and B inherits the error at the swing's speed (~8 mm/s: 0.01 mm, 5 % of a 0.2 mm
    play). The coarse profile's b grid (every 4th point, ~0.014 mm) is also coarser than b's
    posterior there (~0.003 mm); the fine pass takes every point. Measured by ablation on the
    five development fast-swing records that use the record's delay: B 3.05 % mean with it,
    4.33 % without (one, sixth-delay-swings25-fast, better without: 1.15 against 3.33 %). The
    window of each reversal is the coarse grid's (its frames fixed), so the fine grid is kept
    inside it. Returns (mean, sd, lo, hi) s."""
    h = T / SUB
    if not revs or est[1] >= h:
        return est
    fg = est[0] + np.arange(-FINE_SPAN * FINE, FINE_SPAN * FINE + 1) * h / FINE
    fg = fg[(fg >= grid[0]) & (fg <= grid[-1])]
    if fg.size < 3:
        return est
    L = np.zeros(fg.size)
    for rv in revs:
        L += np.array([_lse(rv.logw(x, rv.b_grid, steps, ring)[0]) for x in fg])
    return _delay_posterior(L, fg, T, h / FINE)


def _delay_profile(revs, grid, steps, ring) -> np.ndarray:
    """Sum over reversals of log p(frames | t_delay), marginal over b and the jump. (grid,)"""
    L = np.zeros(grid.size)
    for rv in revs:
        L += np.array([_lse(rv.logw(d, rv.b_grid[::4], steps, ring)[0]) for d in grid])
    return L


def _choose(revs, d, ring_grid=True, allow_jump=True) -> tuple[np.ndarray | None, tuple | None, dict]:
    """The record's jump and ringing at delay d.

    Jump: each reversal's best free jump, signed by its direction (a registration or channel
    error follows the direction of motion); the record has one when their mean is over
    JUMP_T standard errors from 0 (a jump that comes and goes, or fits noise, averages out).
    It is then one vector J (`_jump_profile`: the record's likelihood along the mean), the
    same at every reversal up to the sign (s J), so b and the jump are no longer confounded
    when no frame falls in the dead band. Ringing: a (Hz, 1/s) from the grid when it beats
    none by BIC, summed over the reversals. A ringing tip makes free jumps look consistent
    and an unmodelled jump looks like ringing, so both orders are tried (jump then ringing;
    ringing then jump) and the one with the higher penalised likelihood kept. allow_jump False:
    no jump (the image curve does not see the one found, `_curve_agrees`).
    Returns (J (2,) px or None, ring or None, doc)."""
    n_p = 3 * 2 * len(revs)  # 3 ring columns x 2 image axes per reversal
    pen = 0.5 * n_p * np.log(np.mean([2 * rv.n for rv in revs]))

    def set_jump(jump):
        _set_jump(revs, jump)

    def find_jump(ring):
        set_jump(None)
        J = np.array([rv.s * rv.jump_px(d, rv.b_grid[::4], ring) for rv in revs])
        m = J.mean(axis=0)
        se = J.std(axis=0, ddof=1) / np.sqrt(len(J))
        ratio = float(np.linalg.norm(m) / max(np.linalg.norm(se), 1e-12))
        jump, doc_j = (None, {})
        if ratio > JUMP_T and allow_jump:
            jump, doc_j = _jump_profile(revs, d, m, ring)
        set_jump(jump)
        return jump, {"jump_px": None if jump is None else [float(x) for x in jump],
                      "jump_mean_px": [float(x) for x in m], "jump_se_px": [float(x) for x in se],
                      "jump_ratio": ratio, **doc_j}

    def score(ring, steps):
        return float(sum(np.max(rv.logw(d, rv.b_grid[::4], steps, ring)[0]) for rv in revs)) - (pen if ring else 0.0)

    def light(hz, al):
        """A ringing is lightly damped (decay rate <= half the angular frequency, damping
        ratio <= 0.45); a heavier one is a transient that fits the window's first frames."""
        return al <= 0.5 * 2 * np.pi * hz

    def best_ring(steps):
        best, ring = score(None, steps), None
        if ring_grid:
            for hz in RING_HZ:
                for al in RING_ALPHA[light(hz, RING_ALPHA)]:
                    sc = score((float(hz), float(al)), steps)
                    if sc > best:
                        best, ring = sc, (float(hz), float(al))
        if ring is not None:
            # The grid is coarse for a ring that lasts several periods: the frequency on a
            # 0.1 Hz grid +- 0.4 Hz, then the decay on a geometric grid between its neighbours.
            for hz in ring[0] + np.arange(-0.4, 0.41, 0.1):
                if not light(hz, ring[1]):
                    continue
                sc = score((float(hz), ring[1]), steps)
                if sc > best:
                    best, ring = sc, (float(hz), ring[1])
            for al in ring[1] * np.geomspace(1 / 3, 3, 11):
                if not light(ring[0], al):
                    continue
                sc = score((ring[0], float(al)), steps)
                if sc > best:
                    best, ring = sc, (ring[0], float(al))
        return best, ring

    def with_gain(ring, steps):
        """ring (hz, alpha) -> (hz, alpha, g): g one figure for the record (a property of the
        tip), by its profile likelihood summed over the reversals on RING_GAIN, the best
        refined by a parabola (each reversal's own g scatters too much: its y column trades
        with where the new branch starts); None when the best g is 0."""
        if ring is None:
            return None
        L = np.array([sum(float(np.max(rv.logw(d, rv.b_grid[::4], steps, (ring[0], ring[1], g))[0])) for rv in revs)
                      for g in RING_GAIN])
        i = int(np.argmax(L))
        if i == 0:
            # The motion does not drive it (g = 0): not a tip mode, only the free-phase columns of
            # a ring carried over from before each window, which soak up the window's first frames
            # (2 Hz, 6 /s and 7.4 Hz, 23 /s on ringless 25 fps fast-swing renderings: B 1.2 -> 8.1 %
            # and 2.2 -> 6.2 %). No ringing.
            return None
        g = float(RING_GAIN[i])
        if 0 < i < RING_GAIN.size - 1:
            den = L[i - 1] - 2 * L[i] + L[i + 1]
            if den < 0:
                g += float(np.clip(0.5 * (L[i - 1] - L[i + 1]) / den, -1.0, 1.0)) * float(RING_GAIN[1] - RING_GAIN[0])
        return (ring[0], ring[1], g)

    def kept(ring, steps):
        """The ringing with its gain fixed against none, by BIC (its columns: the free-phase
        pair per reversal, and 3 for the record): (score, ring or None)."""
        none = score(None, steps)
        if ring is None:
            return none, None
        sc = score(ring, steps) + pen - pen_fixed
        return (sc, ring) if sc > none else (none, None)

    n_fixed = 2 * 2 * len(revs) + 3  # 2 free-phase columns x 2 axes per reversal; hz, alpha, g
    pen_fixed = 0.5 * n_fixed * np.log(np.mean([2 * rv.n for rv in revs]))
    jump_a, doc_a = find_jump(None)
    score_a, ring_a = best_ring(jump_a is not None)
    score_a, ring_a = kept(with_gain(ring_a, jump_a is not None), jump_a is not None)
    doc = {**doc_a, "ring_penalty": float(pen), "score_jump_first": score_a}
    if ring_grid:
        set_jump(None)
        _, ring_b = best_ring(False)
        if ring_b is not None:
            jump_b, doc_b = find_jump(ring_b)
            score_b, ring_b = kept(with_gain(ring_b, jump_b is not None), jump_b is not None)
            doc["score_ring_first"] = score_b
            if score_b > score_a:
                doc.update(doc_b)
                doc["order"] = "ringing first"
                return jump_b, ring_b, doc
    set_jump(jump_a)
    doc["order"] = "jump first"
    return jump_a, ring_a, doc


def _gain_settle(revs, grid, steps, ring) -> tuple[tuple | None, np.ndarray]:
    """The ringing's gain g and the delay together: the record's likelihood on (delay, g), each
    reversal marginal over b, on every other point of the delay grid (s) and RING_GAIN up to
    GAIN_TOP; g at the best pair (a parabola through its neighbours), the delay's profile
    (`_delay_profile`) again at that g. revs the reversals (`_Rev`), ring (Hz, 1/s, g) or None,
    grid (G,) delays (s).

    Why: g and the delay trade (a stronger tip mode moves the new branch's first frames as a
    later delay does), so choosing g at the current delay and then the delay at that g settles
    wherever it starts: 0.140 s and g 1.07 on third-ringing-swings25 (true 0.127 s, the
    renderer's g 0.74), B 21.6 % low; the joint best is 0.130 s, g 0.8 (B 5.3 %).
    Returns (ring with that g, the delay's profile (G,) at it); the ring unchanged without a
    ringing gain or when the best g is 0."""
    if ring is None or len(ring) < 3:
        return ring, _delay_profile(revs, grid, steps, ring)
    gs = RING_GAIN[RING_GAIN <= GAIN_TOP]
    ds = grid[::2]
    J = np.array([[sum(float(_lse(rv.logw(x, rv.b_grid[::4], steps, (ring[0], ring[1], float(g)))[0])) for rv in revs)
                   for g in gs] for x in ds])
    i, k = np.unravel_index(int(np.argmax(J)), J.shape)
    g = float(gs[k])
    if 0 < k < gs.size - 1:
        den = J[i, k - 1] - 2 * J[i, k] + J[i, k + 1]
        if den < 0:
            g += float(np.clip(0.5 * (J[i, k - 1] - J[i, k + 1]) / den, -1.0, 1.0)) * float(gs[1] - gs[0])
    if g > 0:
        ring = (ring[0], ring[1], g)
    return ring, _delay_profile(revs, grid, steps, ring)


def _choose_settled(t_enc, q, rt, rq, t_f, obs, b_max, T, pick, grid, revs, L, jump, ring, bq, curve):
    """The jump and ringing chosen again once the delay has settled (`fit` step 3): B samples at
    the delay's posterior mean (L on grid) with the current choice, B(q) and the image curve
    refitted from them, the choice (`_choose`) on the grid's windows with them, and a jump the
    refitted curve does not see (`_curve_agrees`) refused. Arguments as in `fit`; revs the
    grid's windows, jump / ring / bq / curve the current choice and first-pass fits.

    Why: the first choices run at the scan's delay, 2-3 frames late on fast swings (0.21-0.22 s
    against 0.13-0.14 s), on a curve fitted there, and a ringing record kept a jump chosen on
    them (third- and fifth-ringing-swings25: -2.3 and -4.2 px beside the ring where the
    refitted curve sees +4.3 and +7.1 px; no registration rendered).
    Returns (jump, ring, doc, B(q), curve) when the choice differs (a jump or ringing gained or
    lost), else None (the current choice stands)."""
    if curve is None:
        return None
    M = rt.size
    nanv = lambda: np.full(M, np.nan)  # noqa: E731
    d = _delay_posterior(L, grid, T)[0]
    pf = samples(PlayFit(nanv(), nanv(), nanv(), np.zeros(M, bool), d, (d, d), T, jump is not None,
                         ring or (0.0, 0.0), b_max), revs, d)
    if pf.ok.sum() < 4:
        return None
    bq2 = _b_of_q(rq, pf)
    curve2 = fit_image_curve(t_enc, q, t_f, obs, d, bq2, T)
    if curve2 is None:
        return None
    cur = _reversals(t_enc, q, rt, rq, t_f, obs, float(grid[0]), float(grid[-1]), b_max, T, bq2, curve=curve2, safe=False)
    cs = [cur[k] for k in pick if cur[k] is not None]
    j2, r2, doc = _choose(cs, d)
    if j2 is not None and not _curve_agrees(j2, curve2):
        refused = {"jump_px": doc.get("jump_px"), "curve_jump_px": [float(x) for x in -2.0 * curve2.jump_px]}
        j2, r2, doc = _choose(cs, d, allow_jump=False)
        doc = {**doc, "jump_refused": refused}
    if (j2 is None) == (jump is None) and (r2 is None) == (ring is None):
        return None
    return j2, r2, {**doc, "rechosen_at_s": d}, bq2, curve2


def _jump_profile(revs, d, m, ring=None) -> tuple[np.ndarray, dict]:
    """The record's jump vector J (px) by its profile likelihood along the mean's direction.

    Along the motion's image direction a jump and b are confounded but for the timing (the
    jump is a step, b's motion follows q), so each reversal's own best jump scatters by several
    px (28 px sd measured on a 31 px registration jump at 25 fps), and an error of J moves
    every b by |J error| / (image px per actuator unit). J = m + x m/|m|, x on a 0.5 px grid
    over +- max(|m| / 2, 4) px: the sum over reversals of each one's likelihood marginal over
    b and the jump's frame, the best x refined by a parabola. Returns (J (2,), doc)."""
    norm = float(np.linalg.norm(m))
    u = m / max(norm, 1e-12)
    half = max(0.5 * norm, 4.0)
    xs = np.arange(-half, half + 1e-9, 0.5)
    L = np.zeros(xs.size)
    for i, x in enumerate(xs):
        J = m + x * u
        for rv in revs:
            rv.jump = J
            L[i] += float(_lse(rv.logw(d, rv.b_grid[::4], True, ring)[0]))
    i = int(np.argmax(L))
    x = float(xs[i])
    if 0 < i < xs.size - 1:
        den = L[i - 1] - 2 * L[i] + L[i + 1]
        if den < 0:
            x += float(np.clip(0.5 * (L[i - 1] - L[i + 1]) / den, -1.0, 1.0)) * 0.5
    J = m + x * u
    return J, {"jump_profile_shift_px": x, "jump_profile_edge": bool(i in (0, xs.size - 1))}


def _wide_delay(t_enc, q, rt, rq, t_f, obs, T, b_max, d_max, pick, ring=None,
                grid=None) -> tuple[np.ndarray, np.ndarray]:
    """Coarse delay scan 0..d_max on a quarter-frame grid (or the given grid): per delay its
    own frame windows (a window common to the whole scan would leave the short strokes no
    frames), the score the per-observation mean of -0.5 log(RSS / N) over the reversals (jumps
    free, best b; ringing ``ring`` (hz, alpha) with its gain free, or none), since the frame
    sets differ between delays. Returns (grid, score).

    A delay at which most reversals see the marker move against the record's own direction (the
    slope of the image along q over the whole record, `_image_direction`) is the mirror image,
    not the motion, and scores -inf: each reversal's cubic of the drive is free, sign included,
    so on a constant-speed triangle a delay a leg off (the next leg running the other way) fits
    about as well (seventh set-aside, a 60 fps triangle with legs of 0.278 s and a wrong
    configured delay: -2.2450 at 0.4125 s against -2.2575 at the true 0.1375 s)."""
    if grid is None:
        grid = np.arange(0.0, d_max + 1e-9, T / 4)
    score = np.full(grid.size, -np.inf)
    g_dir = _image_direction(t_enc, q, t_f, obs)
    for i, d in enumerate(grid):
        revs = _reversals(t_enc, q, rt, rq, t_f, obs, d, d, b_max, T)
        revs = [revs[k] for k in pick if revs[k] is not None]
        if len(revs) < 2:
            continue
        tot, along = 0.0, 0
        for rv in revs:
            lw, b = rv.logw(d, rv.b_grid[::4], True, ring)
            tot += float(np.max(lw)) / (2 * rv.n) - 0.5 * np.log(2 * rv.n)
            ib, m = np.unravel_index(int(np.argmax(lw)), lw.shape)
            along += int(rv.slope_px(d, float(b[ib]), int(m) + 1, ring) @ g_dir > 0)
        if g_dir.any() and along < 0.5 * len(revs):
            continue
        score[i] = tot / len(revs)
    return grid, score


def _image_direction(t_enc, q, t_f, obs) -> np.ndarray:
    """The marker's image direction per unit q over the whole record: unit 2-vector of the least-
    squares slope of the frames against q at their stamps (the travel's ramp dominates it, and a
    delay of a fraction of a second moves it little); zeros when q does not vary."""
    ok = np.all(np.isfinite(obs), axis=1)
    qk = np.interp(np.asarray(t_f, float)[ok], t_enc, q)
    if ok.sum() < 3 or np.ptp(qk) <= 0:
        return np.zeros(2)
    A = np.column_stack([np.ones(qk.size), qk])
    slope = np.linalg.lstsq(A, np.asarray(obs, float)[ok], rcond=None)[0][1]
    n = float(np.linalg.norm(slope))
    return slope / n if n > 0 else np.zeros(2)


def fit(t_enc: np.ndarray, q: np.ndarray, rt: np.ndarray, rq: np.ndarray, t_f: np.ndarray, obs: np.ndarray,
        period_s: float, b_max: float, d_max: float = 0.5, d_guess: float | None = None) -> tuple[PlayFit, dict]:
    """B samples and t_delay from the record (module doc). t_enc, q (N,) encoder; rt, rq (M,)
    reversals; t_f (F,), obs (F, 2) px (NaN = lost); period_s the frame period; b_max the
    largest play considered (actuator units); d_max the largest delay searched (s); d_guess
    (s, or None) confines the first scan to +- DELAY_SPAN frames of it (a periodic excitation's
    delay is ambiguous by a leg: the caller's independent delay picks the leg).

    1. Delay scan 0..d_max (quarter frame; or around d_guess) on up to 24 reversals spread over
       the record.
    2. B samples there without jumps or ringing; a first B(q) (cubic) from them (the b grid
       keeps b_max).
    3. With that B(q): the record's jumps and ringing (BIC, summed over the 24; `_choose`);
       when a ringing is found, the scan (+-3 frames) and the first B samples are redone with
       it; then the delay's likelihood on a 1/16-frame grid +-1.5 frames around the scan's best
       (the choice again while the delay moves by a grid step or more); a jump kept only if the
       record with it beats the record without, each at its own best delay; once the delay has
       settled, a ringing's gain found with the delay (`_gain_settle`), and the choice made again
       on B(q) and the image curve refitted there (`_choose_settled`: a jump the curve does not
       see is refused); the posterior again on a grid 8 times finer when it sits within a grid
       step (`_fine_delay`).
    4. Every reversal's B sample at the delay's posterior mean.
    Returns (PlayFit, doc with the choices and the delay figures)."""
    T = period_s
    M = rt.size
    nanv = lambda: np.full(M, np.nan)  # noqa: E731
    revs0 = _reversals(t_enc, q, rt, rq, t_f, obs, 0.0, 0.0, b_max, T)
    usable = [i for i, rv in enumerate(revs0) if rv is not None]
    empty = PlayFit(nanv(), nanv(), nanv(), np.zeros(M, bool), float("nan"), (float("nan"), float("nan")),
                    float("nan"), False, (0.0, 0.0), b_max)
    if len(usable) < 4:
        return empty, {"usable_reversals": len(usable)}
    pick = [usable[i] for i in np.unique(np.linspace(0, len(usable) - 1, min(len(usable), DELAY_REVERSALS))
                                         .round().astype(int))]
    near = None if d_guess is None else d_guess + np.arange(-4 * DELAY_SPAN, 4 * DELAY_SPAN + 1) * T / 4
    wg, ws = _wide_delay(t_enc, q, rt, rq, t_f, obs, T, b_max, d_max, pick,
                         grid=None if near is None else near[near >= 0.0])
    d0 = float(wg[int(np.argmax(ws))])
    revs = _reversals(t_enc, q, rt, rq, t_f, obs, d0, d0, b_max, T)
    first = samples(PlayFit(nanv(), nanv(), nanv(), np.zeros(M, bool), d0, (d0, d0), T, False, (0.0, 0.0), b_max),
                    revs, d0)
    if first.ok.sum() < 4:
        return empty, {"usable_reversals": len(usable), "scan_s": d0}
    # The b grid keeps its full reach (b_max) throughout: a top taken from these first samples
    # (twice their 90th percentile) cut it below the truth where they come out low, and the
    # reversals whose b lay beyond it lost their samples (fifth-none-swings25-fast-noisy: a top
    # of 0.119 mm against a true 0.12-0.30 mm, 35 of 98 samples left, B 64 %).
    bq = _b_of_q(rq, first)
    # From here on the record's image curve (image_curve) in place of a cubic per reversal: z
    # from the first B(q) at the scan's delay; each reversal keeps a free offset and slope.
    curve = fit_image_curve(t_enc, q, t_f, obs, d0, bq, T)
    dc = d0
    for it in range(4):  # the jump and ringing are chosen at the current delay: again if it moved
        grid = dc + np.arange(-1.5 * SUB, 1.5 * SUB + 1) * T / SUB
        grid = grid[grid >= 0.0]
        d_lo, d_hi = float(grid[0]), float(grid[-1])
        revs = _reversals(t_enc, q, rt, rq, t_f, obs, d_lo, d_hi, b_max, T, bq, curve=curve)
        sub = [revs[k] for k in pick if revs[k] is not None]
        # The jump and ringing are chosen on the grid's windows without the take-up condition
        # (`_reversals` safe=False: the frames inside the start for the grid's smallest delay):
        # with it, the frames of the swing before the start, where a registration jump shows,
        # were gone at dc too (fifth-registration-swings25-fast lost its jump, 14.1 -> 27.5 %;
        # fourth-ringing-swings25 gained a false one, 4.1 -> 18.9 %); on windows for dc alone,
        # a ringing replaced the first one's jump (157 %).
        cur = _reversals(t_enc, q, rt, rq, t_f, obs, d_lo, d_hi, b_max, T, bq, curve=curve, safe=False)
        jump, ring, choice = _choose([cur[k] for k in pick if cur[k] is not None], dc)
        if ring is not None and it == 0:
            # The scan and the first B samples ran without ringing, which a ringing tip fools
            # (the first B(q) comes from them): scan again near the delay
            # with the ringing found, take the first samples again there with it, and choose
            # again.
            rg, rs = _wide_delay(t_enc, q, rt, rq, t_f, obs, T, b_max, d_max, pick, ring[:2],
                                 dc + np.arange(-12, 13) * T / 4)
            rg, rs = rg[rg >= 0.0], rs[rg >= 0.0]
            dc = float(rg[int(np.argmax(rs))])
            revs = _reversals(t_enc, q, rt, rq, t_f, obs, dc, dc, b_max, T, curve=curve)
            _set_jump(revs, jump)
            again = samples(PlayFit(nanv(), nanv(), nanv(), np.zeros(M, bool), dc, (dc, dc), T, jump is not None,
                                    ring, b_max), revs, dc)
            if again.ok.sum() >= 4:
                bq = _b_of_q(rq, again)
            continue
        steps = jump is not None
        _set_jump(revs, jump)
        L = _delay_profile(sub, grid, steps, ring)
        d = _delay_posterior(L, grid, T)[0]
        # Chosen again unless the delay stayed within a grid step: a jump chosen a quarter frame
        # off (the scan's grid) takes up the delay error on fast swings (seventh set-aside, a
        # wrong configured delay: -9.3 px at a scan 10 ms late, none at the delay found).
        if abs(d - dc) < T / SUB:
            break
        dc = float(grid[int(np.argmax(L))])
    if steps:
        # The jump was chosen at a delay (the free jumps' t-test, `_choose`), and a delay error
        # makes every reversal's free jump lean the same way on a fast swing (the new branch's
        # frames land early or late), so a record with no jump can get one; with it fixed, the
        # delay settles where it suits the jump. The record decides once more, each model at
        # its own best delay: the jump stays when the record's likelihood with it beats the
        # one without by more than J's BIC share (its 2 coordinates: log N). Written against
        # the false jump that the delay grid's frame set turned out to cause (`_Rev`); since that
        # fix it acts on none of the 87 development renderings (ablation), and no test makes it
        # act: a guard, kept so the code is the one the eighth set-aside group was run on.
        L0 = _delay_profile(sub, grid, False, ring)
        if L0.max() >= L.max() - np.log(np.mean([2 * rv.n for rv in sub])):
            jump, steps, L = None, False, L0
            _set_jump(revs, None)
            choice = {**choice, "jump_px": None, "jump_dropped": "no better than none at each one's best delay"}
    # Once the delay has settled: the ringing's gain with the delay (`_gain_settle`), then the
    # choice again on the curve refitted there (`_choose_settled`), and the gain again if it changed.
    if ring is not None:
        ring, L = _gain_settle(sub, grid, steps, ring)
    rechoice = _choose_settled(t_enc, q, rt, rq, t_f, obs, b_max, T, pick, grid, revs, L, jump, ring, bq, curve)
    if rechoice is not None:
        jump, ring, choice2, bq, curve = rechoice
        choice = {**choice2, "first_choice": choice}
        steps = jump is not None
        revs = _reversals(t_enc, q, rt, rq, t_f, obs, d_lo, d_hi, b_max, T, bq, curve=curve)
        _set_jump(revs, jump)
        sub = [revs[k] for k in pick if revs[k] is not None]
        ring, L = _gain_settle(sub, grid, steps, ring)
    d, sd, lo, hi = _delay_posterior(L, grid, T)
    if _ring_lasts(ring):
        # A ringing record: the long windows (`_reversals` hold), when the ring lasts (at most
        # one e-fold per period: it is still there after the swing). A heavily damped "ring"
        # (sa-delay150-cfg50, no ringing rendered: 3.9 Hz, 12 /s) is the model soaking up
        # something else, and the long windows made that record worse (12.7 -> 18.9 %).
        # The first B(q) came from short windows, which such a ring fools: once more from the long
        # windows' samples at the delay found, then the windows again with it, and the delay's
        # likelihood on them.
        # The frequency again on the long windows: it was chosen on short ones to 0.1 Hz, and over a
        # hold of a second or more the phase of a ring that far off drifts by a good part of a
        # cycle (third-ringing-swings25: 4.8 Hz chosen for a 4.68 Hz mode put b near 0 and
        # calibrate refused at the tables). 0.02 Hz grid +- 0.2 Hz, summed over the subset.
        long_ = _reversals(t_enc, q, rt, rq, t_f, obs, d, d, b_max, T, bq, hold=True, curve=curve)
        _set_jump(long_, jump)
        lsub = [long_[k] for k in pick if long_[k] is not None]
        if lsub:
            hzs = ring[0] + np.arange(-0.2, 0.2001, 0.02)
            Lh = [sum(float(np.max(rv.logw(d, rv.b_grid[::4], steps, (float(h), ring[1], ring[2]))[0])) for rv in lsub)
                  for h in hzs]
            ring = (float(hzs[int(np.argmax(Lh))]), ring[1], ring[2])
        mid = samples(PlayFit(nanv(), nanv(), nanv(), np.zeros(M, bool), d, (lo, hi), sd, steps, ring, b_max),
                      _reversals(t_enc, q, rt, rq, t_f, obs, d_lo, d_hi, b_max, T, bq, hold=True, curve=curve), d)
        if mid.ok.sum() >= 4:
            bq = _b_of_q(rq, mid)
        revs = _reversals(t_enc, q, rt, rq, t_f, obs, d_lo, d_hi, b_max, T, bq, hold=True, curve=curve)
        _set_jump(revs, jump)
        sub = [revs[k] for k in pick if revs[k] is not None]
        # The gain with the delay again on the long windows (fifth-ringing-swings25: g 0.98 from the
        # short windows, 0.82 here against the renderer's 0.78; B 16.0 -> 7.6 %).
        ring, L = _gain_settle(sub, grid, steps, ring)
        d, sd, lo, hi = _delay_posterior(L, grid, T)
    d, sd, lo, hi = _fine_delay(sub, grid, (d, sd, lo, hi), steps, ring, T)
    out = samples(PlayFit(nanv(), nanv(), nanv(), np.zeros(M, bool), d, (lo, hi), sd, steps, ring or (0.0, 0.0), b_max),
                  revs, d)
    for _ in range(CURVE_PASSES if curve is not None else 0):
        # z, and so the image curve, came from the first B(q) (a cubic per reversal, biased on fast
        # swings); the samples on the curve come from the timing: B(q) and the curve again from
        # them, then the samples (fourth-none-swings25-fast: the first curve's residual 0.57 px
        # against 0.13 px of noise, B(q) 9.9 %).
        if out.ok.sum() < 4:
            break
        bq = _b_of_q(rq, out)
        curve = fit_image_curve(t_enc, q, t_f, obs, d, bq, T) or curve
        revs = _reversals(t_enc, q, rt, rq, t_f, obs, d, d, b_max, T, bq, hold=_ring_lasts(ring), curve=curve)
        _set_jump(revs, jump)
        out = samples(PlayFit(nanv(), nanv(), nanv(), np.zeros(M, bool), d, (lo, hi), sd, steps, ring or (0.0, 0.0),
                              b_max), revs, d)
    out.b_of_q = bq
    out.jump = jump
    out.curve = curve
    doc = {"usable_reversals": len(usable), "delay_reversals": len(sub), "delay_grid_step_s": T / SUB,
           "scan_s": d0, "iterations": it + 1, "choice": choice, "b_max": b_max, "steps": steps,
           "ring": None if ring is None else {"hz": ring[0], "decay_per_s": ring[1], "gain": ring[2]},
           "image_curve": None if curve is None else curve.doc()}
    return out, doc


def _b_of_q(rq: np.ndarray, pf: PlayFit):
    """A smooth first-pass B(q): cubic least squares of the samples against their mid q, each
    weighted by 1 / sigma_b^2 (sigma_b floored at the samples' median, so that a few sharp ones do
    not carry the fit), held constant beyond the sampled range. Returns a callable q -> B.

    Weighted because a reversal with no frame inside its dead band has a posterior spread over the
    frame interval and its mean sits mid-grid: on the 150-s heavy-noise fast-swing rendering of the
    seventh set-aside group, 14 of 98 samples had sigma_b ~0.11 mm and lay 0.11-0.17 mm above the
    truth; unweighted, they pulled this B(q), and through it the image curve (B 2.27 -> 1.96 %)."""
    ok = pf.ok
    s = np.sign(np.r_[0.0, np.diff(rq)])
    qm = rq[ok] - s[ok] * pf.b[ok] / 2
    lo, hi = float(qm.min()), float(qm.max())
    deg = 3 if ok.sum() >= 12 else 0
    sb = pf.sigma_b[ok]
    sb = np.where(np.isfinite(sb) & (sb > 0), sb, np.inf)
    floor = float(np.median(sb[np.isfinite(sb)])) if np.isfinite(sb).any() else 1.0
    c = np.polyfit(qm, pf.b[ok], deg, w=1.0 / np.maximum(sb, floor))
    return lambda x: np.polyval(c, np.clip(x, lo, hi))


def samples(pf: PlayFit, revs: list, d: float) -> PlayFit:
    """Fill pf's per-reversal b, sigma_b, t2_s at delay d (every usable reversal)."""
    ring = pf.ring if pf.ring[0] > 0 else None
    for r, rv in enumerate(revs):
        if rv is None:
            continue
        lw, b = rv.logw(d, rv.b_grid, pf.steps, ring)
        m = _lse(lw, axis=1)
        wb = np.exp(m - m.max())
        wb /= wb.sum()
        mean = float(np.sum(wb * b))
        step = float(b[1] - b[0]) if b.size > 1 else 0.0
        sd = float(np.sqrt(np.sum(wb * (b - mean) ** 2) + step * step / 12))
        if mean >= 0.97 * b[-1]:  # the onset is not inside the window: no sample
            continue
        pf.b[r], pf.sigma_b[r], pf.ok[r] = mean, sd, True
        pf.t2_s[r] = float(rv.onset_scene(np.array([mean]))[0]) + d
    return pf


def refit_at(pf: PlayFit, t_enc, q, rt, rq, t_f, obs, period_s: float, d: float) -> PlayFit:
    """pf's B samples again at delay d (a configured delay that stands), with pf's choices.
    Returns a new PlayFit (the delay figures kept)."""
    M = rt.size
    revs = _reversals(t_enc, q, rt, rq, t_f, obs, d, d, pf.b_max, period_s, getattr(pf, "b_of_q", None),
                      hold=_ring_lasts(pf.ring), curve=getattr(pf, "curve", None))
    _set_jump(revs, getattr(pf, "jump", None))
    out = PlayFit(np.full(M, np.nan), np.full(M, np.nan), np.full(M, np.nan), np.zeros(M, bool), pf.t_delay_s,
                  pf.t_delay_ci_s, pf.t_delay_sd_s, pf.steps, pf.ring, pf.b_max)
    return samples(out, revs, d)
