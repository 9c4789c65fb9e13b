"""The estimation chain of Fig. 4: reversals, motion onsets (C detector), B(q) spline,
f_remain (paper's morphological median line, or play-consistent least squares).

Units: t in s, q and B in actuator units, c in deg, image points in px.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline
from scipy.optimize import lsq_linear

from . import model
from .errors import InputError
from . import native
from .native import core, enum_names, from_q16, to_q16


def onset_reason_names() -> dict[int, str]:
    """{value: name} of onset_reason_t (firmware/core/onset.h), read from the C enum:
    0 -> "ok", 1 -> "ok_coarse", 2 -> "marker_lost", ... (ONSET_ and ERR_ dropped)."""
    return {k: v.removeprefix("err_") for k, v in enum_names("onset_reason_t", "ONSET_").items()}


# --------------------------------------------------------------------------- reversals
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


# --------------------------------------------------------------------------- onsets (C)
# onset_config_t.jump_ratio_q8 is Q8 (onset.h), the one field not in Q16.16; the C names no
# constant for its scale.
JUMP_RATIO_SCALE = 1 << 8


@dataclass
class OnsetConfig:
    """Host view of onset_config_t (firmware/core/onset.h); units s, and px or deg per frame.

    None keeps the C default (onset_default_config()), so the firmware's defaults are
    defined once, in C. threshold 0 = automatic from the measured still noise (T = k *
    rms frame-to-frame motion while still), bounded by threshold_floor and threshold_max.
    """

    t_delay_s: float = 0.08
    fps: float = 25.0
    threshold: float | None = None
    threshold_floor: float | None = None
    threshold_max: float | None = None
    noise_k: float | None = None
    settle_frames: int | None = None
    max_lost_frames: int | None = None
    jump_ratio: float | None = None
    timeout_s: float | None = None

    def to_c(self, ffi, lib):
        """onset_config_t with the overrides applied (fields the header lacks are skipped)."""
        c = lib.onset_default_config()
        fields = {f for f, _ in ffi.typeof("onset_config_t").fields}
        conv = {
            "t_delay_us": (self.t_delay_s, lambda x: int(round(x * 1e6))),
            "frame_period_us": (self.fps, lambda x: max(1, int(round(1e6 / x)))),
            "threshold_q16": (self.threshold, lambda x: int(to_q16(x))),
            "threshold_floor_q16": (self.threshold_floor, lambda x: int(to_q16(x))),
            "threshold_max_q16": (self.threshold_max, lambda x: int(to_q16(x))),
            "noise_k2_q16": (self.noise_k, lambda x: int(round(x * x * lib.PS_Q16_ONE))),
            "settle_frames": (self.settle_frames, int),
            "max_lost_frames": (self.max_lost_frames, int),
            "jump_ratio_q8": (self.jump_ratio, lambda x: int(round(x * JUMP_RATIO_SCALE))),
            "timeout_us": (self.timeout_s, lambda x: int(round(x * 1e6))),
        }
        for name, (val, fn) in conv.items():
            if val is not None and name in fields:
                setattr(c, name, fn(val))
        return c

    def effective(self) -> dict:
        """The configuration the C detector runs with, in host units (for the calibration file)."""
        ffi, lib = core()
        c = self.to_c(ffi, lib)
        out = {}
        for f, _ in ffi.typeof("onset_config_t").fields:
            v = getattr(c, f)
            if f.endswith("_q16") and f != "noise_k2_q16":
                out[f[:-4]] = v / lib.PS_Q16_ONE
            elif f.endswith("_us"):
                out[f[:-3] + "_s"] = v / 1e6
            elif f == "noise_k2_q16":
                out["noise_k"] = float(np.sqrt(v / lib.PS_Q16_ONE))
            else:
                out[f] = int(v)
        return out


@dataclass
class Onsets:
    """B samples of eq. 1 from the C detector. Arrays (M,), one per reversal that ended
    with a sample; ``reasons`` counts every reversal's outcome by name."""

    t1_s: np.ndarray
    t2_s: np.ndarray
    q1: np.ndarray
    q2: np.ndarray
    q_mean: np.ndarray
    b: np.ndarray
    reasons: dict[str, int] = field(default_factory=dict)
    sigma_b: np.ndarray | None = None  # (M,) standard error of each b (host refinement), None: unknown


def run_onsets(t_enc: np.ndarray, q: np.ndarray, rev_t: np.ndarray, rev_q: np.ndarray,
               t_f: np.ndarray, obs: np.ndarray, kind: str, cfg: OnsetConfig) -> Onsets:
    """Feed a session through the firmware's onset detector in time order.

    Per encoder sample onset_tick(), at each reversal onset_reversal(), per frame
    onset_observe_px() / onset_observe_deg() (kind "image" / "angle"), exactly as the
    board does on-line. obs: (F, 2) px, or deg in column 0; NaN = lost. Every encoder
    sample goes in, as on the board: the detector's history keeps one per
    onset_history_span_us() / ENC_HIST_LEN whatever the rate (firmware/core/enc_hist.h).
    Times become uint32 microseconds from the first sample.
    """
    ffi, lib = core()
    t_enc = np.asarray(t_enc, float)
    t0 = min(t_enc[0], t_f[0] if t_f.size else t_enc[0]) - 1e-3
    us = lambda x: np.round((np.asarray(x, float) - t0) * 1e6).astype(np.int64)
    te_us, tr_us, tf_us = us(t_enc), us(rev_t), us(t_f)
    if max(te_us[-1], tf_us[-1] if tf_us.size else 0) >= 2**32:
        raise InputError(None, "session longer than 71 min: split it (uint32 microsecond clock)")
    q_raw = to_q16(q)
    rq_raw = to_q16(rev_q)
    ok = np.all(np.isfinite(obs), axis=1)
    o_raw = to_q16(np.where(np.isfinite(obs), obs, 0.0))
    # Merge: at equal times tick, then reversal, then frame.
    times = np.concatenate([te_us, tr_us, tf_us])
    kinds = np.concatenate([np.zeros(te_us.size, np.int8), np.ones(tr_us.size, np.int8), np.full(tf_us.size, 2, np.int8)])
    idx = np.concatenate([np.arange(te_us.size), np.arange(tr_us.size), np.arange(tf_us.size)])
    order = np.lexsort((kinds, times))
    o = ffi.new("onset_t *")
    lib.onset_init(o, ffi.new("onset_config_t *", cfg.to_c(ffi, lib)))
    ev = ffi.new("onset_event_t *")
    out = []
    names = onset_reason_names()
    reasons = {names[k]: 0 for k in sorted(names)}
    tick, rev = lib.onset_tick, lib.onset_reversal
    obs_px, obs_deg = lib.onset_observe_px, lib.onset_observe_deg
    times_l, kinds_l, idx_l = times[order].tolist(), kinds[order].tolist(), idx[order].tolist()
    q_l, rq_l = q_raw.tolist(), rq_raw.tolist()
    u_l, v_l, ok_l = o_raw[:, 0].tolist(), o_raw[:, 1].tolist(), ok.tolist()
    angle = kind == "angle"
    for tt, k, i in zip(times_l, kinds_l, idx_l):
        if k == 0:
            hit = tick(o, tt, q_l[i], ev)
        elif k == 1:
            hit = rev(o, tt, rq_l[i], ev)
        elif angle:
            hit = obs_deg(o, tt, u_l[i], ok_l[i], ev)
        else:
            hit = obs_px(o, tt, u_l[i], v_l[i], ok_l[i], ev)
        if hit:
            reasons[names[ev.reason]] += 1
            if ev.reason in (lib.ONSET_OK, lib.ONSET_OK_COARSE):
                out.append((ev.t1_us, ev.t2_us, ev.q1_q16, ev.q2_q16, ev.q_mean_q16, ev.b_q16))
    a = np.array(out, dtype=np.int64).reshape(-1, 6)
    ts = lambda x: x.astype(float) / 1e6 + t0
    return Onsets(ts(a[:, 0]), ts(a[:, 1]), from_q16(a[:, 2]), from_q16(a[:, 3]), from_q16(a[:, 4]),
                  from_q16(a[:, 5]), reasons)


# --------------------------------------------------------------------------- onset settings from the record
# The angle-sensor detector's frame rate and threshold come from the record by
# these rules (docs/method.md, "Settings from the record"); nothing here was set on a file.
FALSE_ONSETS_PER_REVERSAL = 0.01  # alpha: one false onset in a hundred reversals (the robust B fit absorbs it)
# Frames the detector needs inside a dead band: settle_frames (1) + ONSET_NOISE_LEARN_PAIRS (8)
# still pairs for its own noise estimate + the first moving frame.
DEAD_BAND_FRAMES = 10
MIN_STILL_PAIRS = ONSET_NOISE_LEARN_PAIRS = 8  # still pairs a noise estimate needs (the C detector's count)


def onset_noise_k(n_frames: float, dims: int = 1, alpha: float = FALSE_ONSETS_PER_REVERSAL) -> float:
    """Threshold factor k (T = k x rms still frame difference) from a false-alarm rate.

    A still frame difference d crosses T with probability p = 2 (1 - Phi(k)) for a 1-D
    Gaussian d (angle sensor), exp(-k^2) for 2-D (image: |d|^2 / sigma^2 ~ chi^2_2 with
    mean |d|^2 = 2 sigma^2). Over the n_frames a reversal's detector watches, the union
    bound n p <= alpha gives k = Phi^-1(1 - alpha / (2 n)) (1-D), sqrt(ln(n / alpha)) (2-D).
    n_frames >= 1. Returns k (dimensionless)."""
    from scipy.stats import norm

    n = max(float(n_frames), 1.0)
    return float(norm.isf(alpha / (2.0 * n))) if dims == 1 else float(np.sqrt(np.log(n / alpha)))


def still_diffs(t_f: np.ndarray, c_f: np.ndarray, t_a: np.ndarray, t_b: np.ndarray) -> np.ndarray:
    """Frame-to-frame differences of consecutive valid frames inside the same still segment
    [t_a[i], t_b[i]) (s). t_f, c_f: (F,) frames; t_a, t_b: (S,) sorted by t_a. Returns (P,)."""
    t_f, c_f = np.asarray(t_f, float), np.asarray(c_f, float)
    seg = np.searchsorted(t_a, t_f, side="right") - 1
    inside = (seg >= 0) & np.isfinite(c_f)
    inside[inside] &= t_f[inside] < np.asarray(t_b)[seg[inside]]
    pair = inside[1:] & inside[:-1] & (seg[1:] == seg[:-1])
    return np.diff(c_f)[pair]


def still_noise(t_f: np.ndarray, c_f: np.ndarray, t_a: np.ndarray, t_b: np.ndarray) -> tuple[float, int]:
    """Robust rms of frame-to-frame differences on still segments [t_a[i], t_b[i]) (s).

    Pairs of consecutive valid frames inside the same segment (still_diffs); sigma = 1.4826 x
    MAD of their differences (the MAD about the median takes out a slow creep and ignores a
    frame of motion at a segment's end). t_f, c_f: (F,) frames; t_a, t_b: (S,) sorted by t_a.
    Returns (sigma (deg per frame), pairs used); (nan, 0) without a pair."""
    d = still_diffs(t_f, c_f, t_a, t_b)
    if d.size == 0:
        return float("nan"), 0
    return float(1.4826 * np.median(np.abs(d - np.median(d)))), int(d.size)


def diff2_noise(c: np.ndarray) -> float:
    """Upper bound of the rms frame difference of still frames, from the whole record: the
    second difference removes any constant-speed motion, so 1.4826 MAD(d2c) / sqrt(6) is the
    per-frame noise (white) plus what curvature of the motion is left, times sqrt(2) for a
    first difference. c: (F,), NaN ignored. Returns deg per frame (nan with < 3 frames)."""
    d2 = np.diff(np.asarray(c, float), 2)
    d2 = d2[np.isfinite(d2)]
    if d2.size == 0:
        return float("nan")
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(3.0))


def bootstrap_fps(t1: np.ndarray, fps_max: float = 50.0, fps_min: float = 10.0) -> float:
    """First-pass frame rate: about 125 frames per stroke (median time between reversals),
    10-50 Hz. Only used to find the still segments the rules then measure."""
    if t1.size < 2:
        return 25.0
    return float(np.clip(125.0 / np.median(np.diff(t1)), fps_min, fps_max))


def angle_onset_settings(t_enc: np.ndarray, q: np.ndarray, rev_t: np.ndarray, rev_q: np.ndarray,
                         t_s: np.ndarray, c_deg: np.ndarray, t_delay_s: float, fps: float | None = None):
    """Frame rate and threshold of the angle-sensor onset detector, from the record itself.

    1. Bootstrap: frames at bootstrap_fps (capped at half the sensor's own rate of valid
       readings), the C detector with T = k diff2_noise (an upper bound of the still noise
       from the whole record; k from onset_noise_k); each onset gives a still segment
       [t1 + t_delay, t2).
    2. Frame rate: DEAD_BAND_FRAMES frames in the median still segment (the lowest rate the
       detector can work at, so each frame averages the most samples), between
       DEAD_BAND_FRAMES per median stroke and half the sensor's rate; ``fps`` overrides it.
    3. Threshold T = k sigma_d: sigma_d the robust still frame-difference noise at that rate
       on the bootstrap's still segments (``still_noise``, one segment margin of one frame
       at each end), k = onset_noise_k(fps x median stroke duration) (false onsets per
       reversal <= FALSE_ONSETS_PER_REVERSAL).
    With fewer than MIN_STILL_PAIRS still pairs sigma_d is diff2_noise at that rate (an upper
    bound); without a bootstrap onset, the bootstrap's rate and threshold stay. t_enc, q: encoder (N,); rev_t, rev_q: reversals (M,); t_s, c_deg: the
    sensor (K,), NaN = lost. Returns (fps, OnsetConfig overrides dict, doc dict).
    """
    t_s, c_deg = np.asarray(t_s, float), np.asarray(c_deg, float)
    ok = np.isfinite(c_deg)
    span = max(float(t_s[ok][-1] - t_s[ok][0]) if ok.sum() > 1 else 0.0, 1e-9)
    rate = max(int(ok.sum()) - 1, 1) / span
    stroke = float(np.median(np.diff(rev_t))) if rev_t.size >= 2 else float(t_enc[-1] - t_enc[0]) / max(rev_t.size + 1, 1)
    fps0 = min(bootstrap_fps(rev_t), 0.5 * rate) if fps is None else fps
    k0 = onset_noise_k(fps0 * stroke)
    doc = {"sensor_rate_hz": rate, "stroke_s": stroke, "bootstrap_fps": fps0, "alpha": FALSE_ONSETS_PER_REVERSAL}
    tf0, cf0 = frames_from_angle(t_s, c_deg, fps0)
    T0 = k0 * diff2_noise(cf0)
    doc["bootstrap_threshold_deg"] = T0
    boot = {"threshold": max(T0, 2.0 / native.Q16_ONE)} if np.isfinite(T0) else {"noise_k": k0}
    on0 = run_onsets(t_enc, q, rev_t, rev_q, tf0, np.column_stack([cf0, np.zeros_like(cf0)]), "angle",
                     OnsetConfig(t_delay_s=t_delay_s, fps=fps0, jump_ratio=0.0, **boot))
    doc["bootstrap_onsets"] = int(on0.b.size)
    if on0.b.size == 0:
        doc.update(rule="T = k x diff2_noise (no bootstrap onset)", fps=fps0, noise_k=k0)
        return fps0, {"jump_ratio": 0.0, **boot}, doc
    dead = np.maximum(on0.t2_s - on0.t1_s - t_delay_s, 0.0)
    if fps is None:
        fr = DEAD_BAND_FRAMES / max(float(np.median(dead)), 1e-6)
        fps = float(np.clip(fr, min(DEAD_BAND_FRAMES / max(stroke, 1e-6), 0.5 * rate), 0.5 * rate))
    k = onset_noise_k(fps * stroke)
    tf, cf = frames_from_angle(t_s, c_deg, fps)
    order = np.argsort(on0.t1_s)
    a = on0.t1_s[order] + t_delay_s + 1.0 / fps
    b = on0.t2_s[order] - 1.0 / fps
    sig, pairs = still_noise(tf, cf, a, b)
    doc.update(fps=fps, dead_band_s_median=float(np.median(dead)), noise_k=k, still_pairs=pairs,
               still_noise_deg=sig)
    if pairs >= MIN_STILL_PAIRS and sig > 0:
        doc["rule"] = "T = k x still noise"
    else:  # too few still frames to trust their MAD: the whole record's upper bound
        sig = diff2_noise(cf)
        doc["rule"] = "T = k x diff2_noise (too few still frame pairs)"
    if not np.isfinite(sig):
        doc["rule"] = "automatic T (no noise estimate)"
        return fps, {"jump_ratio": 0.0, "noise_k": k}, doc
    T = max(k * sig, 2.0 / native.Q16_ONE)  # a fixed threshold of 0 would mean "automatic" to the C detector
    doc["threshold_deg"] = T
    return fps, {"jump_ratio": 0.0, "threshold": T}, doc


def _axis_noise(d: np.ndarray) -> float:
    """rms of still frame differences d (one image axis): 1.4826 MAD (still_noise's robust
    figure), or, when over half of them are exactly equal (a tracker that returns the same
    sub-pixel position for a still marker: MAD 0), their rms about the median, which counts the
    rare jitter the MAD cannot see. nan without a difference."""
    if d.size == 0:
        return float("nan")
    r = d - np.median(d)
    mad = float(np.median(np.abs(r)))
    return 1.4826 * mad if mad > 0 else float(np.sqrt(np.mean(r * r)))


def _rms2(su: float, sv: float) -> float:
    """rms of a 2-D frame difference |d| from the per-axis rms of its components."""
    return float(np.sqrt(su * su + sv * sv))


def image_onset_settings(t_enc: np.ndarray, q: np.ndarray, rev_t: np.ndarray, rev_q: np.ndarray,
                         t_f: np.ndarray, obs: np.ndarray, t_delay_s: float, fps: float):
    """Onset threshold of the image (marker, px) detector from the record: the angle rule
    (angle_onset_settings) in 2-D, at the camera's own frame rate. Used by `calibrate` on every
    image session (onset_refine.robust_samples) unless a threshold is given. On the demo's
    STRAS-like preset, whose tip creeps through the dead band, it fires earlier on the creep
    than the C detector's automatic threshold did, closer to the first motion: with constant
    transition thresholds that made the compensation worse (0.41 against 0.33 deg); with the
    B-proportional thresholds (transition.ThresholdMap), whose map wants B's shape, it is
    0.21 / 0.26 / 0.29 deg on seeds 1-3 (docs/robustness.md).

    1. Bootstrap: the C detector with the fixed T0 = k rms|d|, rms|d| from diff2_noise of u and
       v (an upper bound of the still noise from the whole record), k = onset_noise_k(fps x
       median stroke, dims=2) = sqrt(ln(n / alpha)); each onset gives a still segment
       [t1 + t_delay, t2).
    2. T = k sigma_d: sigma_d = rms of the 2-D still frame difference, from still_noise on u
       and v over the bootstrap's still segments (one frame of margin at each end), or the
       diff2 bound when that is smaller (both bound the still noise from above: the segments
       hold motion when the onsets come late, because the marker moves less per frame than
       T0); with fewer than MIN_STILL_PAIRS pairs, the diff2 bound. Per axis the MAD figure, or
       the rms when the MAD is 0 (a tracker that repeats the same position: _axis_noise). A fixed T replaces the C detector's
       automatic one (k = 3 and its 0.05 / 1 px floor and ceiling, constants).
    t_enc, q: encoder (N,); rev_t, rev_q: reversals (M,); t_f (F,) s, obs (F, 2) px, NaN = lost;
    t_delay_s: acquisition delay (s); fps: camera rate (Hz). Returns (OnsetConfig overrides
    dict, doc dict); ({}, doc) when no noise figure can be had (the C defaults then stay)."""
    t_f, obs = np.asarray(t_f, float), np.asarray(obs, float)
    stroke = float(np.median(np.diff(rev_t))) if rev_t.size >= 2 else float(t_enc[-1] - t_enc[0]) / max(rev_t.size + 1, 1)
    k = onset_noise_k(fps * stroke, dims=2)
    doc = {"stroke_s": stroke, "fps": fps, "alpha": FALSE_ONSETS_PER_REVERSAL, "noise_k": k}
    s0 = _rms2(diff2_noise(obs[:, 0]), diff2_noise(obs[:, 1]))
    if not np.isfinite(s0) or s0 <= 0:
        doc["rule"] = "C defaults (no noise estimate)"
        return {}, doc
    T0 = max(k * s0, 2.0 / native.Q16_ONE)
    doc["bootstrap_threshold_px"] = T0
    on0 = run_onsets(t_enc, q, rev_t, rev_q, t_f, obs, "image", OnsetConfig(t_delay_s=t_delay_s, fps=fps, threshold=T0))
    doc["bootstrap_onsets"] = int(on0.b.size)
    sig, pairs = float("nan"), 0
    if on0.b.size:
        order = np.argsort(on0.t1_s)
        a = on0.t1_s[order] + t_delay_s + 1.0 / fps
        b = on0.t2_s[order] - 1.0 / fps
        du, dv = still_diffs(t_f, obs[:, 0], a, b), still_diffs(t_f, obs[:, 1], a, b)
        sig, pairs = _rms2(_axis_noise(du), _axis_noise(dv)), min(du.size, dv.size)
    doc.update(still_pairs=pairs, still_noise_px=sig, diff2_noise_px=s0)
    if pairs >= MIN_STILL_PAIRS and sig > 0:
        # Both figures bound the same still noise from above (the segments may hold motion when
        # onsets are found late; diff2 holds the motion's curvature): the smaller is kept.
        doc["rule"] = "T = k x min(still noise, diff2_noise) (2-D)"
        sig = min(sig, s0)
    else:
        sig = s0
        doc["rule"] = "T = k x diff2_noise (2-D; too few still frame pairs)"
    T = max(k * sig, 2.0 / native.Q16_ONE)
    doc["threshold_px"] = T
    return {"threshold": T}, doc


# --------------------------------------------------------------------------- B spline
def clamped_knots(lo: float, hi: float, n_ctrl: int, degree: int = 3) -> np.ndarray:
    """Knot vector of a clamped B-spline with n_ctrl control points spread evenly over
    [lo, hi]: degree+1 repeated knots at each end and n_ctrl-degree-1 interior ones."""
    inner = np.linspace(lo, hi, n_ctrl - degree + 1)
    return np.concatenate([[lo] * degree, inner, [hi] * degree])


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
    A = BSpline.design_matrix(np.clip(x, lo, hi), t, 3).toarray()
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


@dataclass
class BacklashFit:
    """B(q) spline and what the fit made of each sample (M,): weight (normalised to max 1),
    z the standardised residual (residual / its standard deviation: the sample's sigma and
    the scatter between samples), and inconsistent = |z| > 3.5 (modified z-score rule of
    Iglewicz & Hoaglin 1993), samples the fit disagrees with rather than averages."""

    B: "SplineFn"
    weight: np.ndarray
    z: np.ndarray
    inconsistent: np.ndarray
    scatter: float
    kind: str = "spline"              # "spline" (B(q)) or "constant" (too few samples for a shape)
    n_ctrl: int = 0                   # control points used (4 for a constant)
    smooth: float | None = None       # difference-penalty weight (chosen by cross-validation)
    ci95: tuple[float, float] | None = None  # constant B: 95 % confidence interval, None if unknown
    cv: dict | None = None            # the stiffness choice: candidates and their CV scores


Z_INCONSISTENT = 3.5


def fit_backlash_samples(q_mean: np.ndarray, b: np.ndarray, n_ctrl: int = 14, smooth: float = 1e-3,
                         q_range: tuple[float, float] | None = None, source: str | None = None,
                         max_slope: float = 1.5, sigma: np.ndarray | None = None) -> BacklashFit:
    """B(q) from onset samples (section III-B): robust cubic B-spline, N control points,
    constrained to B >= 0 and |B'| <= max_slope, each sample weighted by its uncertainty.

    N = 14 is the paper's setting; with fewer samples than control points the difference
    penalty carries the fit (shape between samples is then the smoothest one). |B'| < 2 is
    physical (eq. 2: the envelopes would fold back) and the firmware's loader refuses steeper
    tables, so max_slope = 1.5 keeps a margin. q_mean, b, sigma: (M,) actuator units (sigma
    None: equal weights). Errors: InputError (naming ``source``) with fewer than 4 samples.
    """
    if q_mean.size < 4:
        raise InputError(source, f"only {q_mean.size} valid backlash samples (need >= 4 reversals with a "
                         f"detected onset); record a longer excitation")
    lo, hi = (float(np.min(q_mean)), float(np.max(q_mean))) if q_range is None else q_range
    if hi - lo <= 0:
        raise InputError(source, "all backlash samples at the same actuator position")
    spl, w = robust_spline(q_mean, b, n_ctrl, lo, hi, smooth, sigma=sigma, lower=0.0, max_slope=max_slope)
    r = b - spl(np.clip(q_mean, lo, np.nextafter(hi, -np.inf)))
    s = 1.4826 * float(np.median(np.abs(r - np.median(r)))) + 1e-12
    if sigma is None:
        z = r / s
        scatter = s
    else:
        sig2 = np.asarray(sigma, float) ** 2
        scatter = float(np.sqrt(max(s * s - float(np.median(sig2)), 0.0)))
        z = r / np.sqrt(sig2 + max(scatter * scatter, 1e-6 * s * s))
    return BacklashFit(SplineFn(spl, lo, hi, linear_ends=False, floor=0.0), w, z, np.abs(z) > Z_INCONSISTENT, scatter)


def fit_backlash(q_mean: np.ndarray, b: np.ndarray, n_ctrl: int = 14, smooth: float = 1e-3,
                 q_range: tuple[float, float] | None = None, source: str | None = None, max_slope: float = 1.5,
                 sigma: np.ndarray | None = None):
    """fit_backlash_samples, returning (SplineFn, weights (M,)) only."""
    f = fit_backlash_samples(q_mean, b, n_ctrl, smooth, q_range, source, max_slope, sigma)
    return f.B, f.weight


# --------------------------------------------------------------------------- B from few or many samples
MIN_SPLINE_SAMPLES = 4  # a cubic needs 4 coefficients: fewer samples give a constant B


def _constant_spline(value: float, lo: float, hi: float) -> SplineFn:
    """A B(q) SplineFn equal to value everywhere (clamped cubic, 4 equal coefficients), so
    tables and the model read a constant B like any other."""
    if not hi > lo:
        lo, hi = lo - 0.5, hi + 0.5
    t = clamped_knots(lo, hi, 4)
    return SplineFn(BSpline(t, np.full(4, float(value)), 3, extrapolate=False), lo, hi, linear_ends=False, floor=0.0)


def constant_backlash(b: np.ndarray, sigma: np.ndarray | None = None,
                      q_range: tuple[float, float] = (0.0, 1.0)) -> tuple[float, tuple[float, float] | None]:
    """Constant B from M >= 1 onset samples b (M,) and its 95 % confidence interval.

    Weighted mean with weights 1 / sigma^2 (equal without sigma). Interval: Student t with
    M - 1 degrees of freedom on the samples' own scatter (M >= 2), widened to the sigmas'
    standard error when that is larger; one sample: +-1.96 sigma, or None without sigma.
    Returns (B, (lo, hi) or None). Units: actuator units."""
    # The Student t quantile straight from scipy.special (what scipy.stats.t.ppf evaluates, the
    # same bits): importing scipy.stats costs ~0.5 s of the first calibration in a process.
    from scipy.special import stdtrit

    b = np.asarray(b, float)
    m = b.size
    w = np.ones(m) if sigma is None else 1.0 / np.maximum(np.asarray(sigma, float) ** 2, 1e-24)
    b0 = float(np.sum(w * b) / np.sum(w))
    se_sig = None if sigma is None else float(np.sqrt(1.0 / np.sum(w)))
    if m >= 2:
        se = float(np.sqrt(np.sum(w * (b - b0) ** 2) / ((m - 1) * np.sum(w))))
        se = max(se, se_sig or 0.0)
        h = float(stdtrit(m - 1, 0.975)) * se
    elif se_sig is not None:
        h = 1.96 * se_sig
    else:
        return b0, None
    return b0, (max(b0 - h, 0.0), b0 + h)


def _cv_folds(q: np.ndarray, k: int) -> np.ndarray:
    """Fold of each sample: samples sorted by q dealt round-robin, so every fold spans the range."""
    f = np.empty(q.size, int)
    f[np.argsort(q, kind="stable")] = np.arange(q.size) % k
    return f


SMOOTH_GRID = tuple(10.0 ** np.arange(-4, 3))  # penalty weights tried, relative to the data term


def choose_stiffness(q: np.ndarray, b: np.ndarray, n_ctrl: int, lo: float, hi: float,
                     sigma: np.ndarray | None = None, grid=SMOOTH_GRID) -> dict:
    """Spline stiffness of B(q) by k-fold cross-validation on the B samples themselves.

    Candidates: a constant B, and the penalised spline (robust_spline) for each penalty in
    grid. Folds: k = min(M, 5), the samples sorted by q dealt round-robin. Score: mean over
    held-out samples of the squared prediction error, each clipped at (3 s)^2, s the robust
    scatter of the samples about their median (a false onset must not pick the model), and
    weighted 1 / sigma^2 when the samples carry one. Choice: the stiffest candidate (constant
    first, then the largest penalty) within one standard error of the best (the one-standard-
    error rule, as transition.choose_model). Returns {"choice": "constant" | smooth (float),
    "candidates": [{"smooth": None | float, "cv": float, "se": float}]}.
    """
    q, b = np.asarray(q, float), np.asarray(b, float)
    m = b.size
    k = min(m, 5)
    folds = _cv_folds(q, k)
    s = 1.4826 * float(np.median(np.abs(b - np.median(b)))) + 1e-9 * (1 + float(np.max(np.abs(b))))
    wt = np.ones(m) if sigma is None else 1.0 / np.maximum(np.asarray(sigma, float) ** 2 + np.median(np.asarray(sigma) ** 2), 1e-24)
    wt = wt / wt.mean()
    cands = [None] + [float(g) for g in grid]
    out = []
    for sm in cands:
        pred = np.empty(m)
        for j in range(k):
            tr, te = folds != j, folds == j
            sg = None if sigma is None else np.asarray(sigma, float)[tr]
            if sm is None or tr.sum() < MIN_SPLINE_SAMPLES:
                pred[te] = constant_backlash(b[tr], sg)[0]
            else:
                spl, _ = robust_spline(q[tr], b[tr], n_ctrl, lo, hi, sm, sigma=sg)
                pred[te] = spl(np.clip(q[te], lo, np.nextafter(hi, -np.inf)))
        loss = wt * np.minimum((pred - b) ** 2, (3 * s) ** 2)
        out.append({"smooth": sm, "cv": float(loss.mean()), "se": float(loss.std(ddof=1) / np.sqrt(m))})
    best = min(range(len(out)), key=lambda i: out[i]["cv"])
    limit = out[best]["cv"] + out[best]["se"]
    # Stiffest first: the constant, then the spline penalties from the largest down.
    order = [0] + sorted(range(1, len(out)), key=lambda i: -out[i]["smooth"])
    pick = next(i for i in order if out[i]["cv"] <= limit)
    return {"choice": "constant" if out[pick]["smooth"] is None else out[pick]["smooth"], "candidates": out}


def fit_backlash_auto(q_mean: np.ndarray, b: np.ndarray, n_max: int = 14, q_range: tuple[float, float] | None = None,
                      source: str | None = None, max_slope: float = 1.5, sigma: np.ndarray | None = None) -> BacklashFit:
    """B from whatever number of onset samples the record holds.

    - M = 0: InputError naming ``source`` (nothing to fit).
    - 1 <= M < 4: constant B (weighted mean) with its 95 % confidence interval
      (``constant_backlash``); kind "constant".
    - M >= 4: a B(q) spline with N = min(n_max, M) control points (no more coefficients than
      samples; N = 14 is the paper's setting, reached from 14 samples on) and its stiffness,
      or a constant, chosen by cross-validation on the samples (``choose_stiffness``); then
      fitted by fit_backlash_samples (B >= 0, |B'| <= max_slope, robust, sigma-weighted).
    q_mean, b, sigma: (M,) actuator units. Returns a BacklashFit.
    """
    q_mean, b = np.asarray(q_mean, float), np.asarray(b, float)
    m = b.size
    if m == 0:
        raise InputError(source, "no B sample: no reversal ended with a detected onset")
    lo, hi = (float(np.min(q_mean)), float(np.max(q_mean))) if q_range is None else q_range
    cv = None
    if m >= MIN_SPLINE_SAMPLES and hi > lo:
        n_ctrl = int(min(n_max, m))
        cv = choose_stiffness(q_mean, b, n_ctrl, lo, hi, sigma)
        if cv["choice"] != "constant":
            f = fit_backlash_samples(q_mean, b, n_ctrl, cv["choice"], (lo, hi), source, max_slope, sigma)
            f.kind, f.n_ctrl, f.smooth, f.cv = "spline", n_ctrl, float(cv["choice"]), cv
            return f
    b0, ci = constant_backlash(b, sigma)
    r = b - b0
    s = 1.4826 * float(np.median(np.abs(r - np.median(r)))) + 1e-12 if m >= 3 else 0.0
    z = r / s if s > 0 else np.zeros(m)
    return BacklashFit(_constant_spline(b0, lo, hi), np.ones(m), z, np.abs(z) > Z_INCONSISTENT, s,
                       "constant", 4, None, ci, cv)


def backlash_alternatives(q_mean: np.ndarray, b: np.ndarray, bfit: BacklashFit, source: str | None = None,
                          max_slope: float = 1.5, sigma: np.ndarray | None = None) -> list[tuple[float, BacklashFit]]:
    """The B(q) splines of every penalty choose_stiffness tried (bfit.cv), stiffest first, for a
    choice of the stiffness by a downstream criterion (calibration: the model's own cross-
    validation on c). Splines that differ from a stiffer kept one by less than the samples'
    median standard error (sigma) everywhere on the range are the same B to the data and are
    dropped. bfit: fit_backlash_auto's result for the same samples (kind "spline"; a constant
    or a fit without cv gives [(bfit.smooth, bfit)]). q_mean, b, sigma: (M,) actuator units.
    Returns [(penalty, BacklashFit)], bfit's own penalty included (its fit object)."""
    if bfit.kind != "spline" or not bfit.cv:
        return [(bfit.smooth, bfit)]
    q_mean, b = np.asarray(q_mean, float), np.asarray(b, float)
    lo, hi = float(np.min(q_mean)), float(np.max(q_mean))
    tol = float(np.median(sigma)) if sigma is not None and np.size(sigma) else 0.0
    grid = np.linspace(lo, hi, 201)
    out: list[tuple[float, BacklashFit]] = [(float(bfit.smooth), bfit)]  # the B-sample CV's own pick
    for sm in sorted((c["smooth"] for c in bfit.cv["candidates"] if c["smooth"] is not None), reverse=True):
        if sm == bfit.smooth:
            continue
        f = fit_backlash_samples(q_mean, b, bfit.n_ctrl, sm, (lo, hi), source, max_slope, sigma)
        f.kind, f.n_ctrl, f.smooth, f.cv = "spline", bfit.n_ctrl, float(sm), bfit.cv
        Bg = f.B(grid)
        if all(np.max(np.abs(Bg - g.B(grid))) > tol for _, g in out):
            out.append((float(sm), f))
    out.sort(key=lambda p: -p[0])
    return out


# --------------------------------------------------------------------------- f_remain
def characteristic(t_enc, q, t_f, c_f, t_delay_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (q, c) of the characteristic (Fig. 9): each valid frame with the actuator
    position at its acquisition time t - t_delay. Returns (q (F,), c (F,))."""
    ok = np.isfinite(c_f)
    return np.interp(t_f[ok] - t_delay_s, t_enc, q), c_f[ok]


def f_remain_lsq(q_c: np.ndarray, c: np.ndarray, B, n_ctrl: int = 14, smooth: float = 1e-3,
                 z_range: tuple[float, float] | None = None, z: np.ndarray | None = None,
                 min_slope: float = 0.0):
    """f_remain by play-consistent least squares (our estimator).

    With B fixed from the onsets, the play operator gives the centre z[k] from q alone
    (eq. 3), and the model says c[k] = f(z[k]); f is then a monotone robust spline
    regression of c on z, using every frame (transitions included) instead of the loop's
    outline only. q_c, c: (F,) in time order; z: the play centre if the caller has it
    (model.play_operator(q_c, B)); min_slope: |f'| >= min_slope, deg per actuator unit
    (robust_spline). Returns (SplineFn, sign of f', z (F,)).
    """
    z = model.play_operator(q_c, B) if z is None else np.asarray(z, float)
    sign = 1 if np.corrcoef(z, c)[0, 1] >= 0 else -1
    lo, hi = (float(z.min()), float(z.max())) if z_range is None else z_range
    spl, _ = robust_spline(z, c, n_ctrl, lo, hi, smooth, monotone=sign, min_slope=min_slope)
    return SplineFn(spl, lo, hi, linear_ends=True), sign, z


# f_remain's stiffness: its number of control points, chosen by cross-validation on
# the calibration frames. Candidates fixed a priori: a single cubic (4) up to 2x the paper's 14.
F_CTRL_GRID = (4, 6, 8, 10, 14, 20, 28)
F_FRAMES_PER_CTRL = 10  # a candidate needs >= 10 training frames per coefficient in every fold


def _monotone_pspline(x: np.ndarray, y: np.ndarray, n_ctrl: int, lo: float, hi: float, smooth: float,
                      sign: int) -> SplineFn:
    """robust_spline's first (unweighted) iteration, monotone, solved on its normal equations:
    with N = A'A + lam D'D = R'R (Cholesky) the F-row problem equals ||R c - R^-T A'y||^2 + const,
    an n_ctrl-row bounded least squares (bvls), so a fit costs one design matrix and an n x n
    solve. For the cross-validation's many fits (the final fit is the robust one). Returns the
    SplineFn with linear ends over [lo, hi], as f_remain_lsq's."""
    from scipy.linalg import cho_factor, solve_triangular

    t = clamped_knots(lo, hi, n_ctrl)
    A = BSpline.design_matrix(np.clip(x, lo, hi), t, 3).toarray()
    D = _diff_penalty(n_ctrl)
    AtA = A.T @ A
    lam = smooth * max(np.trace(AtA) / n_ctrl, 1e-12)
    N = AtA + lam * (D.T @ D) + 1e-12 * np.eye(n_ctrl) * max(np.trace(AtA), 1.0)
    R, _ = cho_factor(N, lower=False)
    R = np.triu(R)
    rhs = solve_triangular(R, A.T @ y, trans="T", lower=False)
    Tm = np.tril(np.ones((n_ctrl, n_ctrl))) * np.where(np.arange(n_ctrl) == 0, 1.0, float(sign))[None, :]
    lb = np.r_[-np.inf, np.zeros(n_ctrl - 1)]
    th = lsq_linear(R @ Tm, rhs, bounds=(lb, np.full(n_ctrl, np.inf)), method="bvls").x
    return SplineFn(BSpline(t, Tm @ th, 3, extrapolate=False), lo, hi, linear_ends=True)


def choose_f_ctrl(z: np.ndarray, c: np.ndarray, splits, grid=F_CTRL_GRID, smooth: float = 1e-3) -> dict:
    """f_remain's stiffness (control points N) by cross-validation on the calibration frames.

    z, c: (F,) play centre (eq. 3, actuator units) and angle (deg) at the calibration frames, in
    time order. splits: [(train mask (F,), test mask (F,))], the rolling origins of the
    transition's model choice (transition.rolling_origins: fit on the frames before each origin,
    score the next block), so f is judged as the board uses it: fitted on the past, predicting
    frames that come after, whose z may reach beyond the trained range (linear ends, as the
    tables). Each candidate N of ``grid`` (at most one per F_FRAMES_PER_CTRL frames of the
    smallest training part; 4, a single cubic, always) is fitted on each training part by the
    monotone P-spline (_monotone_pspline, the penalty ``smooth`` relative to the data term as in
    robust_spline), scored by the held-out RMSE per fold; cv = rms over folds, se = their standard
    error. Choice: the lowest CV RMSE. The one-standard-error rule (Hastie, Tibshirani & Friedman,
    ESL 2nd ed., 7.10) was the first rule; its stiffer picks generalised worse (an effect-free
    simulated record: 0.31 against 0.13 deg on the judged part; the catheter's least-squares
    f_remain row: 1.20 against 0.83 deg mean), and f is already regularised by its penalty, so
    the choice is the CV's minimum (docs/robustness.md). Returns {"n_ctrl": N,
    "rule": str, "candidates": [{"n_ctrl", "cv_rmse_deg", "cv_se_deg"}]}; n_ctrl is None when no
    fold has frames to judge (the caller keeps its default). Errors: none (bad folds are skipped).
    """
    z, c = np.asarray(z, float), np.asarray(c, float)
    folds = [(tr, te) for tr, te in splits if te.sum() >= 3 and tr.sum() >= 4 * F_FRAMES_PER_CTRL]
    rule = "CV on a rolling origin (fit before, score the next block), the lowest CV RMSE"
    if not folds:
        return {"n_ctrl": None, "rule": rule + " (no fold with frames to judge)", "candidates": []}
    n_max = min(int(tr.sum()) for tr, _ in folds) // F_FRAMES_PER_CTRL
    grid = [int(n) for n in grid if n <= n_max] or [4]
    sign = 1 if np.corrcoef(z, c)[0, 1] >= 0 else -1
    rows = []
    for n in grid:
        errs = []
        for tr, te in folds:
            lo, hi = float(z[tr].min()), float(z[tr].max())
            if hi <= lo:
                continue
            f = _monotone_pspline(z[tr], c[tr], n, lo, hi, smooth, sign)
            errs.append(float(np.sqrt(np.mean((f(z[te]) - c[te]) ** 2))))
        if not errs:
            continue
        e = np.array(errs)
        rows.append({"n_ctrl": n, "cv_rmse_deg": float(np.sqrt(np.mean(e ** 2))),
                     "cv_se_deg": float(np.std(e, ddof=1) / np.sqrt(e.size)) if e.size > 1 else 0.0})
    if not rows:
        return {"n_ctrl": None, "rule": rule + " (no fold with a z range)", "candidates": []}
    # The argmin, not the one-standard-error rule: f is a penalised spline (already regularised),
    # and on an effect-free simulated record the one-SE rule's stiffer pick (N = 8, CV 0.242
    # against 0.208 for N = 14, within one SE) gave 0.31 deg on the judged part against 0.13.
    pick = min(rows, key=lambda d: d["cv_rmse_deg"])
    return {"n_ctrl": int(pick["n_ctrl"]), "rule": rule, "candidates": rows}


def f_remain_morph(q_c: np.ndarray, c: np.ndarray, n_ctrl: int = 14, size: int = 512, close_px: int = 7,
                   smooth: float = 1e-3, min_slope: float = 0.0):
    """f_remain by the paper's method (section IV): the characteristic drawn as an image,
    holes filled by morphology, then for each row (a value of c) the middle between the
    leftmost and rightmost filled pixels (extremal horizontal values), then a spline.

    The polyline through consecutive (q, c) pairs is drawn at size x size px, closed with
    a close_px elliptic kernel (joins the loop's outline where samples are sparse), and
    the inside of each loop filled by flood-filling the background from the border.
    Returns (SplineFn, sign of f', (q_mid, c_row) samples).
    """
    import cv2

    qlo, qhi = float(q_c.min()), float(q_c.max())
    clo, chi = float(c.min()), float(c.max())
    sx = (size - 1) / max(qhi - qlo, 1e-12)
    sy = (size - 1) / max(chi - clo, 1e-12)
    pts = np.column_stack([(q_c - qlo) * sx, (chi - c) * sy])  # row 0 = largest c
    # A free margin wider than the kernel keeps the background ring connected, so the
    # flood fill from a corner reaches every outside pixel.
    m = close_px + 2
    img = np.zeros((size + 2 * m, size + 2 * m), np.uint8)
    cv2.polylines(img, [np.round(pts + m).astype(np.int32).reshape(-1, 1, 2)], False, 255, 1)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (close_px, close_px))
    img = cv2.morphologyEx(img, cv2.MORPH_CLOSE, k)
    flood = img.copy()
    mask = np.zeros((img.shape[0] + 2, img.shape[1] + 2), np.uint8)
    cv2.floodFill(flood, mask, (0, 0), 255)
    filled = img | cv2.bitwise_not(flood)
    rows = np.nonzero(filled.any(axis=1))[0]
    q_mid, c_row = [], []
    for r in rows:
        cols = np.nonzero(filled[r])[0]
        q_mid.append(0.5 * (cols[0] + cols[-1] - 2 * m) / sx + qlo)
        c_row.append(chi - (r - m) / sy)
    q_mid, c_row = np.array(q_mid), np.array(c_row)
    sign = 1 if np.corrcoef(q_c, c)[0, 1] >= 0 else -1
    spl, _ = robust_spline(q_mid, c_row, n_ctrl, qlo, qhi, smooth, monotone=sign, min_slope=min_slope)
    return SplineFn(spl, qlo, qhi, linear_ends=True), sign, (q_mid, c_row)


# --------------------------------------------------------------------------- baselines
def fit_linear(q: np.ndarray, c: np.ndarray):
    """Baseline: c = a q + b by least squares, no backlash. Returns a callable q -> c."""
    a, b = np.polyfit(q, c, 1)
    return lambda x: a * np.asarray(x, float) + b


def fit_constant_play(q_c: np.ndarray, c: np.ndarray, degree: int = 5, w_max: float | None = None):
    """Baseline: constant-width play operator + degree-5 polynomial, both by least squares.

    For a width w the centre z(q; w) is known (eq. 3), the polynomial is then linear least
    squares; w minimises the residual (bounded scalar search, after a coarse grid so a
    local minimum is not taken). q_c, c: (F,) in time order. Returns (w, f, B callable).
    """
    from scipy.optimize import minimize_scalar

    span = float(q_c.max() - q_c.min())
    w_max = 0.5 * span if w_max is None else w_max
    zsc = max(span, 1e-12)

    def fit(w):
        z = model.play_operator(q_c, model.constant(w), b_max=w)
        V = np.vander((z - q_c.min()) / zsc, degree + 1)
        coef, *_ = np.linalg.lstsq(V, c, rcond=None)
        return float(np.sum((V @ coef - c) ** 2)), coef

    grid = np.linspace(0, w_max, 41)
    costs = [fit(w)[0] for w in grid]
    i = int(np.argmin(costs))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    w = float(minimize_scalar(lambda w: fit(w)[0], bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-6 * max(span, 1)}).x) if hi > lo else float(grid[i])
    coef = fit(w)[1]
    q0 = float(q_c.min())
    return w, (lambda x: np.polyval(coef, (np.asarray(x, float) - q0) / zsc)), model.constant(w)
