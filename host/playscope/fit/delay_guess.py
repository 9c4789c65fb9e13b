"""First guesses of timing from the record, before any model: when the actuator reached each
reversal's extremum (`motor_stop_times`) and a coarse image delay from the correlation of
commanded and observed motion around those stops (`coarse_delay`, and every delay the
correlation could mean, `coarse_delay_peaks`). The record model
(onset_model) starts from these; calibrate's command-lag figure for angle sessions uses them too.

Units: t in s, q in actuator units, image points in px.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

SUB = 8               # coarse_delay's lag grid points per frame period
SLOW_PER_DELAY = 6.0  # coarse_delay's slow travel: averages over this many times its longest lag
SLOW_R2_MIN = 0.9     # ... which must follow q that closely to give the image direction of q


def motor_stop_times(t: np.ndarray, q: np.ndarray, t1: np.ndarray, q1: np.ndarray, tol: float) -> np.ndarray:
    """When the actuator reached each reversal's extremum: the first sample of the run within
    ``tol`` of q1 that ends at t1 (t1 itself without a hold at the turn). t, q: (N,);
    t1, q1: (M,). Returns (M,) s. The tip stops there (the play opens at once)."""
    i1 = np.clip(np.searchsorted(t, t1), 0, t.size - 1)
    out = np.empty(t1.size)
    for r, (i, qq) in enumerate(zip(i1, q1)):  # one short backward walk per reversal
        k = i
        while k > 0 and abs(q[k - 1] - qq) <= tol:
            k -= 1
        out[r] = t[k]
    return out


def image_direction_of_q(t_f: np.ndarray, obs: np.ndarray, t_enc: np.ndarray, q: np.ndarray, t_at: np.ndarray,
                         window_s: float) -> np.ndarray | None:
    """The image direction in which the marker moves as q grows, at the motor positions q(t_at):
    d/dq of a cubic fitted, per image coordinate, to the record's slow travel (image positions
    and q(t), each a moving average over window_s). The average moves by delay / window_s of
    the travel inside the window when the image lags the motor, so a delay well under window_s
    leaves the direction's sign right, whatever the swings do. t_f (F,) s, obs (F, 2) px, all
    finite; t_enc, q (N,); t_at (M,) s. Returns (M, 2), not normalised (px / unit of q), or None
    when the slow travel does not determine it: the cubic explains under SLOW_R2_MIN of the
    slow image motion (no ramp, no travel) or there are fewer than 8 frames."""
    if t_f.size < 8:
        return None
    n = max(3, int(round(window_s / float(np.median(np.diff(t_f))))))
    pb = uniform_filter1d(obs, n, axis=0, mode="nearest")
    qb = uniform_filter1d(np.interp(t_f, t_enc, q), n, mode="nearest")
    if not np.ptp(qb) > 0.0:
        return None
    fit = [np.polynomial.Polynomial.fit(qb, pb[:, j], 3) for j in range(pb.shape[1])]
    res = pb - np.column_stack([f(qb) for f in fit])
    ss = float(np.sum((pb - pb.mean(axis=0)) ** 2))
    if not ss > 0.0 or 1.0 - float(np.sum(res ** 2)) / ss < SLOW_R2_MIN:
        return None
    q_at = np.interp(t_at, t_enc, q)
    return np.column_stack([f.deriv()(q_at) for f in fit])


def coarse_delay(t_f: np.ndarray, obs: np.ndarray, t_stop: np.ndarray, t_enc: np.ndarray, q: np.ndarray,
                 period: float, max_delay: float = 0.5) -> float:
    """First guess of t_delay (s): the highest peak of `delay_score` (its arguments). Returns s, on
    the scan's grid in [0, max_delay] (period / SUB steps)."""
    lags, score = delay_score(t_f, obs, t_stop, t_enc, q, period, max_delay)
    return float(lags[int(np.argmax(score))])


def coarse_delay_peaks(t_f: np.ndarray, obs: np.ndarray, t_stop: np.ndarray, t_enc: np.ndarray, q: np.ndarray,
                       period: float, max_delay: float = 0.5) -> np.ndarray:
    """Every delay `delay_score` (its arguments) could mean: its highest point (`coarse_delay`'s
    guess) first, then its other local maxima where the score is positive, highest first, each
    more than one frame period from every one kept before it. Why more than one: an excitation
    that repeats (a triangle, regular swings) repeats the score with its period, so an alias one
    period late scores as high as the delay (on a 60 fps triangle of 0.29 s period, 1.000 against
    1.000 to three digits, the alias first), and only a model of the whole record tells them apart
    (a fit from each, onset_search._fitted_start). Why a frame apart: the frames time a lag no finer than one
    frame before any model, so maxima closer than that are the score's ripple about one lag.
    Returns (K,) s, K >= 1."""
    lags, score = delay_score(t_f, obs, t_stop, t_enc, q, period, max_delay)
    i0 = int(np.argmax(score))
    inner = np.arange(1, lags.size - 1)
    peak = inner[(score[inner] >= score[inner - 1]) & (score[inner] > score[inner + 1]) & (score[inner] > 0.0)]
    kept = [lags[i0]]
    for i in peak[np.argsort(-score[peak], kind="stable")]:
        if np.all(np.abs(lags[i] - np.array(kept)) > period):
            kept.append(lags[i])
    return np.array(kept, float)


def delay_score(t_f: np.ndarray, obs: np.ndarray, t_stop: np.ndarray, t_enc: np.ndarray, q: np.ndarray,
                period: float, max_delay: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The cross-correlation of commanded and observed motion around the motor stops, over the
    lags a delay may take. For each reversal the image velocity along the old motion's image
    direction is multiplied by the sign of the motor's velocity at t - lag (+1 on, -1 back,
    0 held), over 8 frame periods before t_stop + lag and 4 after; the sum over reversals peaks
    at the delay (earlier lags meet the tip still going while the motor is back; later ones meet
    the dead band). The old motion's image direction is the motor's direction at the stop times
    the image direction of increasing q (`image_direction_of_q`, from the record's slow travel,
    which no delay in the scan moves); without slow travel, the image displacement over the
    half second before the motor stop, whose sign is wrong when that half second reaches back
    into the leg before (legs under 0.5 s plus the delay). A ringing tip keeps going for up to a
    quarter period after the stop, so the guess may be late by that; velocities are clipped at
    3 median so a jump does not count. t_f (F,) s, obs (F, 2) px (rows with NaN, lost frames, are skipped); t_stop (M,)
    s (`motor_stop_times`); t_enc, q (N,) s and actuator units; period, max_delay s. Returns
    (lags (L,) s, the scan's grid in [0, max_delay] in period / SUB steps; score (L,), px of image
    velocity along the motion, summed)."""
    ok = np.all(np.isfinite(obs), axis=1)
    tf, o = t_f[ok], obs[ok]
    P = lambda tt: np.stack([np.interp(tt, tf, o[:, 0]), np.interp(tt, tf, o[:, 1])], axis=-1)  # noqa: E731
    sgn = np.sign(np.interp(t_stop, t_enc, q) - np.interp(t_stop - 0.1, t_enc, q))
    u = image_direction_of_q(tf, o, t_enc, q, t_stop, SLOW_PER_DELAY * max_delay)
    e = P(t_stop) - P(t_stop - 0.5) if u is None else u * sgn[:, None]
    e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-12)
    dq = np.diff(q)
    tm = 0.5 * (t_enc[1:] + t_enc[:-1])
    ks = np.arange(-8, 4) + 0.5
    lags = np.arange(0.0, max_delay + 1e-9, period / SUB)
    score = np.empty(lags.size)
    for i, lag in enumerate(lags):
        tc = t_stop[:, None] + lag + ks[None, :] * period  # (M, 12) velocity sample times
        vi = np.einsum("mkc,mc->mk", P(tc + period / 2) - P(tc - period / 2), e)
        vm = np.sign(np.interp(tc - lag, tm, dq)) * sgn[:, None]
        lim = 3.0 * np.median(np.abs(vi)) + 1e-12  # a jump is one huge velocity sample: clip it
        score[i] = np.sum(np.clip(vi, -lim, lim) * vm)
    return lags, score
