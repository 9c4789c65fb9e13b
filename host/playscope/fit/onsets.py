"""Motion onsets after each reversal (section III-A, eq. 1) found by the firmware's own C
detector (firmware/core/onset.c) through the native module: the host view of onset_config_t
and the onset list the B(q) fit reads.

Units: t in s, q in actuator units, c in px or deg per frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..base.errors import InputError
from ..base.native import core, enum_names, from_q16, to_q16

def onset_reason_names() -> dict[int, str]:
    """{value: name} of onset_reason_t (firmware/core/onset.h), read from the C enum:
    0 -> "ok", 1 -> "ok_coarse", 2 -> "marker_lost", ... (ONSET_ and ERR_ dropped)."""
    return {k: v.removeprefix("err_") for k, v in enum_names("onset_reason_t", "ONSET_").items()}

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
    # (M,) standard error of each b, actuator units: given only by the record model (onset_stage), whose
    # samples therefore keep their own stiffness in calibration.choose_b_and_model; None: a detector's
    # samples (the board's or run_onsets'), their error unknown
    sigma_b: np.ndarray | None = None


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


@dataclass
class RobustOnsets:
    """What an image session's onset stage (onset_stage.record_samples) gives calibrate: the B samples (Onsets with sigma_b), the delay used (s) and where it came
    from, the record's diagnosis (a JSON-ready dict) and warnings (one line each)."""

    onsets: Onsets
    t_delay_s: float
    t_delay_source: str
    report: dict
    warnings: list
