"""Reversals of the actuator (section III-A: t1 and q1 of eq. 1) and the frame view of an
angle record: the first step of the calibration path, before any onset is searched.

Units: t in s, q in actuator units, c in deg.
"""

from __future__ import annotations

import numpy as np


def detect_reversals(t: np.ndarray, q: np.ndarray, hysteresis: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Direction changes of q with hysteresis (section III-A, t1 and q1 of eq. 1).

    A reversal is the last extremum of q before q has moved back from it by more than
    ``hysteresis`` (actuator units), so encoder noise and dwell do not count. t, q: (N,).
    Returns (t1 (M,), q1 (M,), new_dir (M,) of +1/-1). Uses q_cmd when given it instead of q.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float)
    t1, q1, dirs = [], [], []
    d = 0
    ext_i = 0
    for i in range(1, q.size):  # one pass; run once per session
        if d == 0:
            if q[i] - q[0] > hysteresis:
                d, ext_i = 1, i
            elif q[0] - q[i] > hysteresis:
                d, ext_i = -1, i
            continue
        if d > 0:
            if q[i] >= q[ext_i]:
                ext_i = i
            elif q[ext_i] - q[i] > hysteresis:
                t1.append(t[ext_i]); q1.append(q[ext_i]); dirs.append(-1)
                d, ext_i = -1, i
        else:
            if q[i] <= q[ext_i]:
                ext_i = i
            elif q[i] - q[ext_i] > hysteresis:
                t1.append(t[ext_i]); q1.append(q[ext_i]); dirs.append(1)
                d, ext_i = 1, i
    return np.array(t1), np.array(q1), np.array(dirs, int)


def q_looks_commanded(q: np.ndarray) -> tuple[bool, float]:
    """Does q look like a commanded position rather than an encoder reading?

    A reading carries quantisation and noise, so its third difference is of the order of
    one step |dq| wherever it moves; a command computed in floating point (ramp, spline,
    sine) is smooth to rounding. Rule: median |d3q| / median |dq| over moving samples
    (|dq| > 0) below 1e-3. q: (N,). Returns (looks commanded, the ratio)."""
    q = np.asarray(q, float)
    if q.size < 8:
        return False, float("nan")
    d1 = np.abs(np.diff(q))
    d3 = np.abs(np.diff(q, 3))
    mv = d1[:-2] > 0
    if mv.sum() < 4:
        return False, float("nan")
    ratio = float(np.median(d3[mv]) / np.median(d1[:-2][mv]))
    return ratio < 1e-3, ratio


# --------------------------------------------------------------------------- frames
def frames_from_angle(t: np.ndarray, c: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Decimate a high-rate angle log into camera-like frames by block averaging.

    At ~500 Hz the motion per sample is below the sensor noise, so a per-frame threshold
    needs frames of 25-50 Hz; the average over each frame period (like an exposure) also
    lowers the noise by sqrt(samples per frame). Time of a frame = mean time of its block.
    NaN samples are ignored; a block with none valid is a lost frame. Returns (t_f, c_f).
    """
    t = np.asarray(t, float)
    idx = np.floor((t - t[0]) * fps).astype(np.int64)
    n = int(idx[-1]) + 1
    ok = np.isfinite(c)
    cnt = np.bincount(idx[ok], minlength=n).astype(float)
    s_c = np.bincount(idx[ok], weights=c[ok], minlength=n)
    s_t = np.bincount(idx, weights=t, minlength=n)
    cnt_t = np.bincount(idx, minlength=n)
    keep = cnt_t > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        tf = s_t[keep] / cnt_t[keep]
        cf = np.where(cnt[keep] > 0, s_c[keep] / np.maximum(cnt[keep], 1), np.nan)
    return tf, cf
