"""`playscope run-insitu`: the paper's in-situ procedure (section III) end to end on a board.

1. The board runs its excitation trajectory (mode EXCITATION, section III-B) and streams its
   encoder samples (t_us, q) on the board clock (PSP_MSG_ENC_STREAM, 1 kHz).
2. Frames come from a camera or a video (OpenCV VideoCapture), or, with ``--sim-plant``, from
   a SIMULATED instrument (playscope.sim.plant.SimPlant) driven in closed loop by the board's
   streamed q.
   playscope.io.marker_track.MarkerTracker finds the marker (u, v) px in each frame.
3. Every frame goes to the board as PSP_MSG_MARKER_OBS stamped on the board clock (the
   acquisition delay is not removed: the board's detector subtracts t_delay, eq. 1), and the
   board's onset detector answers B samples (psp_b_sample_t) when a reversal's onset is found.
4. The host fits B(q) to the board's samples (robust B-spline, backlash.fit_backlash, N = 14),
   f_remain from the recorded characteristic (pose estimation eqs. 6-8, play-consistent least
   squares; calibration.calibrate with the board's onsets), builds the fixed-point tables and
   flashes them (upload, commit, read back, compensator bit for bit: device.flash.flash).

Board clock. With --sim-plant, frames are rendered exactly at board times k / fps once the
encoder stream has passed them (so the board's clock drives the simulation, whatever its
speed), and the virtual board runs in lock-step (ps_vboard --lockstep-ms SIM_LOCKSTEP_MS,
sim_vboard_args): it waits for the host's observations, so a loaded machine slows the run down
instead of delivering frames after the board's encoder history has moved on. With a camera or a video, a frame is stamped when it is read: board time = host time +
offset, where offset is the largest (t_last_sample - host receive time) over encoder batches,
i.e. that of the least delayed batch (the board sends a batch the tick it fills).
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base import native



# --------------------------------------------------------------------------- board clock
# --sim-plant: board time the virtual board may run past the last marker observation. Above a
# few frame periods (40 ms at the simulated 25 fps) so the board never waits for a frame the host
# cannot render yet, and well inside the onset detector's encoder history (ENC_HIST_LEN = 512
# ticks, 512 ms at 1 kHz) so every observation still finds q(t2 - t_delay) there.
SIM_LOCKSTEP_MS = 250


def sim_vboard_args(time_scale: float) -> list[str]:
    """ps_vboard options for a closed-loop run through a simulated instrument: its clock at most
    time_scale x the wall clock (dimensionless, > 0), in lock-step with the host's observations
    (the board waits for a host that lags, so a loaded machine slows the run instead of moving
    the board's onsets)."""
    return ["--time-scale", f"{time_scale:g}", "--lockstep-ms", str(SIM_LOCKSTEP_MS)]


class BoardClock:
    """Board time (us) from host time, learnt from encoder batches (module docstring).
    Assumes the board and host clocks run at the same rate (no --time-scale)."""

    def __init__(self):
        self.offset_us: float | None = None

    def batch(self, t_last_us: int, host_s: float) -> None:
        off = t_last_us - host_s * 1e6
        self.offset_us = off if self.offset_us is None else max(self.offset_us, off)

    def now_us(self, host_s: float) -> int | None:
        return None if self.offset_us is None else int(host_s * 1e6 + self.offset_us)


# --------------------------------------------------------------------------- frame sources
class VideoSource:
    """Frames from cv2.VideoCapture, the same code for a camera and a file.

    A camera index is read as fast as it delivers; each frame is stamped when read (host time,
    turned into board time by BoardClock). A file has no link to the robot, so it is played as
    the camera of the board's excitation: its frame k shows the instrument k / fps after the
    excitation first moved the actuator (t0, taken from the encoder stream), and it is stamped
    t0 + k / fps on the board clock and delivered once the board's clock has passed that time.
    Host delays then never shift a stamp against the picture (as with a live camera, whose
    picture is the robot's own state). Raises OSError when it cannot be opened."""

    def __init__(self, spec: str):
        import cv2

        self.live = spec.isdigit()
        self.cap = cv2.VideoCapture(int(spec) if self.live else spec)
        if not self.cap.isOpened():
            raise OSError(f"cannot open video {spec!r}")
        fps = self.cap.get(cv2.CAP_PROP_FPS)
        self.period_us = 1e6 / fps if fps and fps > 0 else 40000.0
        self.t0_us: int | None = None  # file: board time of frame 0
        self.k = 0

    def start(self, t0_us: int) -> None:
        """File: frame 0 is at board time t0_us (when the excitation first moved q)."""
        if self.t0_us is None:
            self.t0_us = int(t0_us)

    def due_us(self) -> int | None:
        """File: board time of the next frame (None before start())."""
        return None if self.t0_us is None else int(self.t0_us + self.k * self.period_us)

    def read(self):
        """The next frame (BGR) or None at the end of the video."""
        ok, img = self.cap.read()
        self.k += 1
        return img if ok else None

    def close(self) -> None:
        self.cap.release()


# --------------------------------------------------------------------------- the run
@dataclass
class InsituRun:
    """What one run recorded: encoder (t_s, q) from the stream, marker (t_s, u_px, v_px) as
    sent to the board (NaN = lost), the board's B samples (dicts of psp_b_sample_t, q/b in
    actuator units), counts of their reasons, board seconds and wall seconds."""

    enc_t_s: list = field(default_factory=list)
    enc_q: list = field(default_factory=list)
    mk_t_s: list = field(default_factory=list)
    mk_u: list = field(default_factory=list)
    mk_v: list = field(default_factory=list)
    samples: list = field(default_factory=list)
    board_s: float = 0.0
    wall_s: float = 0.0
    ended: str = ""

    def valid(self) -> list:
        return [s for s in self.samples if s["reason_code"] <= 1]  # ONSET_OK, ONSET_OK_COARSE


def _b_dict(b: dict) -> dict:
    from ..fit.onsets import onset_reason_names

    return {"reason": onset_reason_names().get(b["reason"], str(b["reason"])), "reason_code": b["reason"],
            "t1_s": b["t1_us"] / 1e6, "t2_s": b["t2_us"] / 1e6, "q1": b["q1_q16"] / native.Q16_ONE,
            "q2": b["q2_q16"] / native.Q16_ONE, "q_mean": b["q_mean_q16"] / native.Q16_ONE, "b": b["b_q16"] / native.Q16_ONE}


def run_loop(link, source, max_board_s: float = 600.0, progress=None, tracker=None) -> InsituRun:
    """Steps 1-3 of the module docstring. source: VideoSource, or a simulated plant (anything
    with push(t_us, q) and frames(t_board_us), e.g. playscope.sim.plant.SimPlant). Ends when the
    board's excitation ends (the board returns to idle), the video ends, or after
    max_board_s of board time. progress(board_s, n_samples) is called about twice a second."""
    from ..io.marker_track import MarkerTracker

    tracker = tracker or MarkerTracker()
    run = InsituRun()
    clock = BoardClock()
    sim = hasattr(source, "push")  # a simulated plant follows the encoder stream; a video does not
    t_wall0 = time.monotonic()
    t_hi, t_prev = 0, None  # unwrap the board's 32-bit us clock
    t_board = 0
    link.set_mode("idle")
    link.stream(True, 1)
    link.set_mode("excitation")
    next_check = time.monotonic() + 0.5
    try:
        while True:
            now = time.monotonic()
            for kind, ev in link.poll_events(0.002):
                if kind == "b":
                    run.samples.append(_b_dict(ev))
                elif kind == "enc" and ev:
                    t = []
                    for tu, _ in ev:
                        if t_prev is not None and tu < t_prev:
                            t_hi += 1 << 32
                        t_prev = tu
                        t.append(t_hi + tu)
                    q = np.array([qq for _, qq in ev], float) / native.Q16_ONE
                    run.enc_t_s += [x / 1e6 for x in t]
                    run.enc_q += q.tolist()
                    t_board = t[-1]
                    clock.batch(t_board, now)
                    if sim:
                        source.push(np.array(t), q)
                    elif not source.live and source.t0_us is None:
                        # A file plays from the excitation's first move (VideoSource): look for
                        # it in this batch only, against the first sample of the stream.
                        moved = np.flatnonzero(q != run.enc_q[0])
                        if moved.size:
                            source.start(t[int(moved[0])])
            if sim:
                frames = list(source.frames(t_board))
            elif source.live:
                t_now = clock.now_us(now)  # None until the first encoder batch: no board time yet
                frames = []
                if t_now is not None:
                    img = source.read()
                    if img is None:
                        run.ended = "end of video"
                        break
                    frames = [(t_now, img)]
            else:
                frames = []
                while source.due_us() is not None and source.due_us() <= t_board:
                    t_f = source.due_us()
                    img = source.read()
                    if img is None:
                        run.ended = "end of video"
                        break
                    frames.append((t_f, img))
                if run.ended:
                    break
            for t_f, img in frames:
                d = tracker.track(img)
                ok = not math.isnan(d.u)
                b = link.marker(t_f, int(round(d.u * native.Q16_ONE)) if ok else 0, int(round(d.v * native.Q16_ONE)) if ok else 0,
                                valid=ok)
                run.mk_t_s.append(t_f / 1e6)
                run.mk_u.append(d.u)
                run.mk_v.append(d.v)
                if b:
                    run.samples.append(_b_dict(b))
            run.board_s = t_board / 1e6
            if now >= next_check:
                next_check = now + 0.5
                if progress:
                    progress(run.board_s, len(run.valid()))
                if link.info()["mode"] == "idle":
                    run.ended = "excitation done"
                    break
            if run.board_s > max_board_s:
                run.ended = f"stopped after {max_board_s:g} s of board time"
                break
    finally:
        link.set_mode("idle")
        link.stream(False)
        run.wall_s = time.monotonic() - t_wall0
    for kind, ev in link.poll_events(0.05):  # a last event still in flight
        if kind == "b":
            run.samples.append(_b_dict(ev))
    return run


def session_of(run: InsituRun, robot, camera, hand_eye, t_delay_s: float):
    """The run as a playscope session (image kind): encoder from the board's stream, marker as
    tracked; so it can be recalibrated offline (`playscope calibrate`)."""
    from ..io.session import Session

    enc = {"t_s": np.array(run.enc_t_s), "q": np.array(run.enc_q)}
    mk = {"t_s": np.array(run.mk_t_s), "u_px": np.array(run.mk_u, float), "v_px": np.array(run.mk_v, float)}
    return Session(actuator_unit="mm", distal_kind="image", robot=robot, encoder=enc, camera=camera,
                   hand_eye=hand_eye, t_delay_s=t_delay_s, marker=mk, meta={"source": "playscope run-insitu"})


def calibrate_run(run: InsituRun, session, n_ctrl: int = 14):
    """Step 4: B from the board's samples, f_remain from the characteristic. Returns a
    calibration.Calibration. Errors: InputError with too few valid B samples."""
    from ..fit.onsets import Onsets
    from ..fit.calibration import calibrate

    v = run.valid()
    reasons: dict[str, int] = {}
    for s in run.samples:
        reasons[s["reason"]] = reasons.get(s["reason"], 0) + 1
    col = lambda k: np.array([s[k] for s in v], float)  # noqa: E731
    on = Onsets(col("t1_s"), col("t2_s"), col("q1"), col("q2"), col("q_mean"), col("b"), reasons)
    return calibrate(session, n_ctrl=n_ctrl, onsets=on, source="board onset detector (run-insitu)")


def write_samples_csv(path, samples: list) -> None:
    """The B samples of a run (dicts with reason, reason_code, t1_s, t2_s (s), q1, q2, q_mean,
    b (actuator units)) as one CSV row each at path. Errors: OSError from the file system."""
    import io

    from ..base.atomic import write_text_atomic

    keys = ["reason", "reason_code", "t1_s", "t2_s", "q1", "q2", "q_mean", "b"]
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=keys)
    w.writeheader()
    w.writerows(samples)
    write_text_atomic(path, buf.getvalue())  # through the output guard, like every write of a command


def read_geometry(path: str):
    """Robot, camera, hand-eye and t_delay from a session.json (playscope-session/1)."""
    from ..base.errors import InputError
    from ..io.session import parse_meta, read_json

    p = Path(path)
    if not p.is_file():
        raise InputError(p, "no such session.json")
    d = read_json(p, "session.json")
    if not isinstance(d, dict):
        raise InputError(p, "a session.json is a JSON object (robot, camera, hand_eye)")
    m = parse_meta(d, p)
    if m.get("camera") is None or m.get("hand_eye") is None:
        raise InputError(p, "needs camera and hand_eye to estimate c from the marker (eqs. 6-8)")
    return m["robot"], m["camera"], m["hand_eye"], m.get("t_delay_s") or 0.08


def exc_duration_s(exc: str) -> float:
    """Board seconds of an excitation "Q0:Q1:AMP:ADV:V" (turning points as firmware/core/exc.h:
    up AMP, down to the next base ADV higher until the up-turn would pass Q1, then the mirror
    sweep back down to Q0)."""
    q0, q1, amp, adv, v = (float(x) for x in exc.split(":"))
    pts, low = [q0], q0
    while low + amp <= q1 + 1e-9:
        pts += [low + amp, low + adv]
        low += adv
    high = pts[-2]
    while high - amp >= q0 - 1e-9:
        pts += [high - amp, high - adv]
        high -= adv
    return float(np.sum(np.abs(np.diff(pts)))) / v
