"""The onset detector's settings from the record itself (docs/method.md, "Settings from the
record"): frame rate, still noise and the threshold T from a false-alarm rate, for angle and
image records. Nothing here was set on a file.

Units: t in s, q in actuator units, c in px or deg.
"""

from __future__ import annotations

import numpy as np

from .onsets import OnsetConfig, run_onsets
from .reversals import frames_from_angle
from ..base import native

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
    image session (onset_stage.record_samples) unless a threshold is given. On the demo's
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


def board_onsets(t_enc: np.ndarray, q: np.ndarray, rt: np.ndarray, rq: np.ndarray, t_f: np.ndarray,
                 obs: np.ndarray, fps: float, t_delay_s: float, onset_cfg: dict | None) -> tuple[Onsets, dict]:
    """The board's plain eq. 1 onsets of an image record at the delay t_delay_s (s): the C
    detector with its threshold from this record's still noise and false-alarm rate
    (onset_settings.image_onset_settings; not the detector's automatic k = 3 with its constant
    0.05 / 1 px floor and ceiling) unless onset_cfg gives one. Shapes as in run_onsets. Returns
    (Onsets, the threshold's rule as a JSON-ready dict)."""
    over = dict(onset_cfg or {})
    if "threshold" not in over:
        auto, rule = image_onset_settings(t_enc, q, rt, rq, t_f, obs, t_delay_s, fps)
        over.update(auto)
    else:
        rule = {"rule": "given", "threshold_px": float(over["threshold"])}
    cfg = OnsetConfig(t_delay_s=t_delay_s, fps=fps, **over)
    return run_onsets(t_enc, q, rt, rq, t_f, obs, "image", cfg), rule
