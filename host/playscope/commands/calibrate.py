"""`playscope calibrate`: session -> calibration JSON (B(q) spline, f_remain)."""

from __future__ import annotations

import sys

from . import argtypes as T
from ..pipeline import calibrate_session
from .common import add_command, add_json_arg, emit, progress


DESCRIPTION = """\
Paper Fig. 4: reversals -> motion onsets (eq. 1; image sessions: read off one model of the
whole record, the play, the delay and the camera's effects fitted jointly from the firmware's C
detector's onsets, t_delay measured from the record, docs/host.md) -> B(q) robust cubic
B-spline (N control points) -> f_remain (play-consistent least squares, or the paper's
morphological median line) -> calibration JSON (docs/calibration-format.md).
"""


def add_parser(sub) -> None:
    p = add_command(sub, "calibrate", "estimate B(q) and f_remain from a session", DESCRIPTION,
                    examples=["playscope calibrate sessions/d21 -o d21.cal.json"])
    p.add_argument("session", help="session folder (playscope-session/1), or a recording file read in place "
                   "(the catheter's CSV with a header, the endoscope's headerless CSV)")
    p.add_argument("-o", "--out", required=True, type=T.file_path, help="calibration JSON to write")
    p.add_argument("-N", "--control-points", type=T.CONTROL_POINTS, default=14, help="most control points of the B(q) spline, and those of the paper's morphological f_remain (paper: 14); the least-squares f_remain takes its own by cross-validation (calibration file: f_fit)")
    p.add_argument("--f-method", choices=["lsq", "morph"], default="lsq",
                   help="f_remain estimator: lsq (default, play-consistent) or morph (paper, section IV)")
    p.add_argument("--model", choices=["play", "pi", "auto"], default="auto",
                   help="play: the paper's pure play; pi: play + Prandtl-Ishlinskii transition operators; "
                   "auto (default): play or PI, the play width, f's stiffness and the thresholds' kind "
                   "(constant, or proportional to B(q) when B's shape is measured: >= 2 onset samples per B "
                   "control point) by cross-validation on this session (docs/method.md, 'Transition' and "
                   "'B-proportional thresholds'); the choice and its CV errors go into the JSON")
    p.add_argument("--fps", type=T.FPS, help="frame rate for angle sessions (default: ~125 frames per stroke, 10-50 Hz)")
    p.add_argument("--t-delay", type=T.T_DELAY_S, help="configured image delay t_delay in s (default: session.json); "
                   "image sessions check it against the record's own delay")
    p.add_argument("--t-delay-from", choices=["data", "config"], default="data",
                   help="image sessions: use the delay measured from the record (data, default) or the configured "
                   "one (config); a gap over one frame period is warned about either way")
    p.add_argument("--hysteresis", type=T.HYSTERESIS, help="reversal detection hysteresis, actuator units (default 1%% of travel)")
    p.add_argument("--threshold", type=T.THRESHOLD, help="onset threshold T per frame (px or deg); default: from this record's still noise and a "
                   "false-alarm rate of 0.01 onsets per reversal (docs/method.md 'Settings from the record', "
                   "docs/robustness.md), recorded in the JSON")
    add_json_arg(p, "calibration (path), reversals, b_samples, onset_reasons {name: count}, t_delay_s, "
                 "fps_frames, B_range [min,max], t_delay {configured_s, record_s, used_s, ...} and ringing "
                 "{freq_hz, damping_ratio, ...} (image sessions, else null), b_inconsistent (count), warnings, model (play|pi), operators (count)")
    p.set_defaults(func=run)


def run(a) -> int:
    res = calibrate_session(a.session, a.out, a.control_points, a.f_method, a.fps, a.t_delay, a.t_delay_from,
                            a.hysteresis, a.threshold, a.model, progress=progress)
    for w in res.warnings:
        print(f"playscope: warning: {w}", file=sys.stderr)
    return emit(a, res)
