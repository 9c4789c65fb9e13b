"""The excitation's pacing rule on the host: the swing speed that takes up the smallest expected
play over several camera frames, computed by the board's own C (firmware/core/exc.h,
exc_pace_speed) through the native module, so host and board pick the same speed to the bit.

Rule: v = b_low x fps / EXC_PACE_FRAMES (actuator units/s): at that speed the play b_low is
taken up over EXC_PACE_FRAMES frame periods after each reversal, so the onset is timed by
several frames instead of falling between two (a faster swing leaves B timed only to the
travel of one frame period). The board works in Q16 units, an integer frame period in us and
Q32.32 units per control tick, rounded down; the host passes the same integers.

Used by `playscope simulate` (the default excitation speed), `playscope run-insitu` (the
virtual board's --exc speed when none is given) and calibrate's "a slower swing would measure
B better" advice (`pacing`).
"""

from __future__ import annotations

import math

import numpy as np

from ..base import native

TICK_HZ = 1000  # the board's control tick (encoder stream 1 kHz); the speed in units/s barely depends on it


def _lib():
    from ..base.native import core

    return core()


def pace_frames() -> int:
    """EXC_PACE_FRAMES from firmware/core/exc.h: frames over which the smallest play is taken up."""
    return int(_lib()[1].EXC_PACE_FRAMES)


def frame_period_us(fps: float) -> int:
    """Camera period in whole us, as the board's onset detector holds it (frame_period_us)."""
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise ValueError(f"frame rate must be a positive number of frames/s, got {fps!r}")
    return int(round(1e6 / fps))


def pace_v_q32(b_low: float, b_high: float, fps: float, tick_hz: int = TICK_HZ) -> int:
    """The board's speed for this camera and play range: actuator units per tick, Q32.32 (int).

    b_low, b_high: expected play range, actuator units (0 < b_low <= b_high); fps: camera frame
    rate (1..1000 frames/s); tick_hz: control rate. Errors: ValueError naming what the board
    refuses (frame rate or B range invalid, speed below one LSB or too large)."""
    ffi, lib = _lib()
    b_low_q16, b_high_q16 = _play_q16("b_low", b_low), _play_q16("b_high", b_high)
    period_us = frame_period_us(fps)
    v = ffi.new("int64_t *")
    st = lib.exc_pace_speed(b_low_q16, b_high_q16, period_us, int(tick_hz), v)
    if st == lib.EXC_ERR_PACE:
        raise ValueError(f"pacing refused: need 0 < b_low <= b_high (got {b_low:g}, {b_high:g}), a frame rate "
                         f"of 1..1000 frames/s (got {fps:g}) and a tick rate of 1..1000000 Hz (got {tick_hz})")
    if st != lib.EXC_OK:
        raise ValueError(f"pacing refused: the speed for b_low {b_low:g} at {fps:g} frames/s is below one "
                         f"Q32.32 step per tick or beyond any trajectory")
    return int(v[0])


def _play_q16(name: str, x) -> int:
    """A play width (actuator units) as the board's Q16.16 raw value (native.to_q16's rounding).
    Errors: ValueError naming the argument when it is not a finite number the Q format holds."""
    if not isinstance(x, (int, float)) or not math.isfinite(x):
        raise ValueError(f"{name} must be a finite number of actuator units, got {x!r}")
    try:
        return int(native.to_q16(x))
    except OverflowError:
        raise ValueError(f"{name} = {x:g} actuator units is beyond the board's Q16.16 range (+-32768)") from None


def swing_speed(b_low: float, b_high: float, fps: float, tick_hz: int = TICK_HZ) -> float:
    """The pacing rule's swing speed, actuator units/s, exactly the board's (pace_v_q32 x tick_hz / 2^32).
    Errors as pace_v_q32."""
    return pace_v_q32(b_low, b_high, fps, tick_hz) * tick_hz / 2.0**32


def paced_exc(exc4: str, b_low: float, b_high: float, fps: float, tick_hz: int = TICK_HZ) -> str:
    """The board's excitation "Q0:Q1:AMP:ADV" (actuator units) with its paced speed appended:
    "Q0:Q1:AMP:ADV:V", V units/s, as the board's exc_pace_config sets it (the same checks: the
    down leg AMP - ADV must exceed b_high, the trajectory must pass exc_init). Errors: ValueError
    naming what is refused."""
    ffi, lib = _lib()
    try:
        q0, q1, amp, adv = (float(x) for x in exc4.split(":"))
    except ValueError:
        raise ValueError(f"excitation {exc4!r} is not Q0:Q1:AMP:ADV (4 numbers separated by ':')") from None
    pace_v_q32(b_low, b_high, fps, tick_hz)  # frame rate and B range first, with their own message
    cfg = ffi.new("exc_config_t *")
    cfg.q_start_q16, cfg.q_end_q16 = int(q0 * native.Q16_ONE), int(q1 * native.Q16_ONE)
    cfg.amplitude_q16, cfg.advance_q16 = int(amp * native.Q16_ONE), int(adv * native.Q16_ONE)
    cfg.return_sweep = True
    st = lib.exc_pace_config(cfg, _play_q16("b_low", b_low), _play_q16("b_high", b_high), frame_period_us(fps),
                             int(tick_hz))
    if st == lib.EXC_ERR_PACE:
        raise ValueError(f"excitation {exc4!r}: its down leg AMP - ADV = {amp - adv:g} must exceed the widest "
                         f"play expected ({b_high:g}), or the tip never moves on it")
    if st != lib.EXC_OK:
        raise ValueError(f"excitation {exc4!r} refused by the board (need Q1 > Q0, AMP > ADV > 0, and one tick "
                         f"shorter than a leg at the paced speed)")
    return f"{exc4}:{cfg.v_q32 * tick_hz / 2.0**32:.9g}"


def pacing(t_enc: np.ndarray, q: np.ndarray, on, fps: float, t_delay_s: float) -> dict:
    """How many frames the play takes to take up at the excitation's speed, and the swing speed
    that would spread it over EXC_PACE_FRAMES frames (the board's pacing rule, playscope.fit.pacing):
    speed = B_low fps / EXC_PACE_FRAMES,
    B_low the 10th percentile of the B samples. The actuator speed at each onset is |dq/dt| at
    t2 - t_delay, in actuator units/s. Returns a JSON-ready dict; frames_to_take_up inf without
    samples."""
    frames = pace_frames()
    if on.b.size == 0:
        return {"frames_to_take_up": float("inf"), "speed_to_use": float("nan"), "sigma_frame_travel": float("nan"),
                "frames_wanted": frames}
    v = np.abs(np.interp(on.t2_s - t_delay_s, t_enc, np.gradient(q, t_enc)))
    travel = np.maximum(v / fps, 1e-12)  # actuator travel in one frame period at the onset
    b_low = float(np.percentile(on.b, 10))
    return {"frames_to_take_up": float(np.median(on.b / travel)), "speed_at_onset_median": float(np.median(v)),
            "sigma_frame_travel": float(np.median(travel) / np.sqrt(12)), "b_low": b_low,
            "speed_to_use": b_low * fps / frames, "frames_wanted": frames}
