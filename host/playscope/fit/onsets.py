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
    board does on-line (the merged stream in one C call, `feed`). obs: (F, 2) px, or deg
    in column 0; NaN = lost. Every encoder sample goes in, as on the board: the detector's
    history keeps one per onset_history_span_us() / ENC_HIST_LEN whatever the rate
    (firmware/core/enc_hist.h).
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
    order = np.lexsort((kinds, times))
    o = ffi.new("onset_t *")
    lib.onset_init(o, ffi.new("onset_config_t *", cfg.to_c(ffi, lib)))
    # the stream's columns, in the order of times and kinds above, then sorted with them
    head = te_us.size + tr_us.size
    stream = (times[order].astype(np.uint32), kinds[order].astype(np.uint8),
              np.concatenate([q_raw, rq_raw, o_raw[:, 0]])[order].astype(np.int32),
              np.concatenate([np.zeros(head, np.int32), o_raw[:, 1]])[order].astype(np.int32),
              np.concatenate([np.ones(head, np.uint8), ok.astype(np.uint8)])[order])
    events = feed(o, stream, lib.ONSET_INPUT_DEG if kind == "angle" else lib.ONSET_INPUT_PX, cap=tr_us.size + 1)
    names = onset_reason_names()
    reasons = {names[k]: 0 for k in sorted(names)}
    out = []
    for ev in events:
        reasons[names[ev[0]]] += 1
        if ev[0] in (lib.ONSET_OK, lib.ONSET_OK_COARSE):
            out.append(ev[1:])
    a = np.array(out, dtype=np.int64).reshape(-1, 6)
    ts = lambda x: x.astype(float) / 1e6 + t0
    return Onsets(ts(a[:, 0]), ts(a[:, 1]), from_q16(a[:, 2]), from_q16(a[:, 3]), from_q16(a[:, 4]),
                  from_q16(a[:, 5]), reasons)


EVENT_FIELDS = ("reason", "t1_us", "t2_us", "q1_q16", "q2_q16", "q_mean_q16", "b_q16")  # onset_event_t's, in order


def feed(o, stream: tuple, input_kind: int, cap: int = 64) -> list[tuple]:
    """The firmware's detector o (an initialised cffi onset_t *) fed a recorded stream in its order in
    one C call (onset.h: onset_feed): stream = (t_us (n,) uint32, kind (n,) uint8 (ONSET_FEED_TICK,
    _REVERSAL, _FRAME), a (n,) int32 Q16 (q, q1, u or c), b (n,) int32 Q16 (v), valid (n,) uint8);
    input_kind ONSET_INPUT_PX or ONSET_INPUT_DEG. Returns the outcomes in order, each a tuple of
    EVENT_FIELDS. cap: the room first given for outcomes; a stream with more is fed again from o's
    state on entry, with room for all (the same calls, so the same outcomes). Errors: TypeError for
    columns of other dtypes, ValueError for columns not 1-D or of different lengths."""
    ffi, lib = core()
    t, k, a, b, v = (np.ascontiguousarray(x) for x in stream)
    if not (t.dtype == np.uint32 and k.dtype == v.dtype == np.uint8 and a.dtype == b.dtype == np.int32):
        raise TypeError("feed: stream columns must be uint32, uint8, int32, int32, uint8")
    if not t.shape == k.shape == a.shape == b.shape == v.shape or t.ndim != 1:
        raise ValueError("feed: stream columns must be 1-D and of one length")
    start = ffi.new("onset_t *", o[0])  # the state on entry, for a second pass

    def run(room: int):
        out = ffi.new("onset_event_t[]", room)
        n_out = lib.onset_feed(o, ffi.from_buffer("uint32_t[]", t), ffi.from_buffer("uint8_t[]", k),
                               ffi.from_buffer("int32_t[]", a), ffi.from_buffer("int32_t[]", b),
                               ffi.from_buffer("uint8_t[]", v), t.size, input_kind, out, room)
        return n_out, [tuple(getattr(out[i], f) for f in EVENT_FIELDS) for i in range(min(n_out, room))]

    room = max(int(cap), 1)
    n_out, events = run(room)
    if n_out > room:
        o[0] = start[0]
        n_out, events = run(n_out)
    return events


def _feed_ref(o, stream: tuple, input_kind: int) -> list[tuple]:
    """`feed` one call per entry from Python: its reference, and what it replaced (0.06 s a run on the
    3-minute bench record)."""
    ffi, lib = core()
    ev = ffi.new("onset_event_t *")
    out = []
    for t, k, a, b, v in zip(*(np.asarray(x).tolist() for x in stream)):
        if k == lib.ONSET_FEED_TICK:
            hit = lib.onset_tick(o, t, a, ev)
        elif k == lib.ONSET_FEED_REVERSAL:
            hit = lib.onset_reversal(o, t, a, ev)
        elif input_kind == lib.ONSET_INPUT_DEG:
            hit = lib.onset_observe_deg(o, t, a, bool(v), ev)
        else:
            hit = lib.onset_observe_px(o, t, a, b, bool(v), ev)
        if hit:
            out.append(tuple(getattr(ev, f) for f in EVENT_FIELDS))
    return out


@dataclass
class RobustOnsets:
    """What an image session's onset stage (onset_stage.record_samples) gives calibrate: the B samples (Onsets with sigma_b), the delay used (s) and where it came
    from, the record's diagnosis (a JSON-ready dict) and warnings (one line each)."""

    onsets: Onsets
    t_delay_s: float
    t_delay_source: str
    report: dict
    warnings: list
