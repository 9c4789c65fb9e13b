"""`playscope calibrate`: session -> calibration JSON (B(q) spline, f_remain)."""

from __future__ import annotations

import sys

import numpy as np

from .. import argtypes as T
from ..calibration import calibrate
from .common import load_session_noted, add_json_arg, dump_json


def add_parser(sub) -> None:
    p = sub.add_parser("calibrate", help="estimate B(q) and f_remain from a session",
                       description="Paper Fig. 4: reversals -> motion onsets (the firmware's C detector, eq. 1; image sessions: "
                       "refined on the host by a joint ML model, t_delay measured from the record) "
                       "-> B(q) robust cubic B-spline (N control points) -> f_remain (play-consistent least "
                       "squares, or the paper's morphological median line) -> calibration JSON "
                       "(docs/calibration-format.md). Example: playscope calibrate sessions/d21 -o d21.cal.json")
    p.add_argument("session", help="session folder (playscope-session/1)")
    p.add_argument("-o", "--out", required=True, type=T.file_path, help="calibration JSON to write")
    p.add_argument("-N", "--control-points", type=T.CONTROL_POINTS, default=14, help="B-spline control points (paper: 14)")
    p.add_argument("--f-method", choices=["lsq", "morph"], default="lsq",
                   help="f_remain estimator: lsq (default, play-consistent) or morph (paper, section IV)")
    p.add_argument("--model", choices=["play", "pi", "auto"], default="auto",
                   help="play: the paper's pure play; pi: play + Prandtl-Ishlinskii transition operators; "
                   "auto (default): play or PI, the play width and f's stiffness by rolling-origin "
                   "cross-validation on this session (docs/method.md, 'Transition'); the choice and its CV "
                   "errors go into the JSON")
    p.add_argument("--fps", type=T.FPS, help="frame rate for angle sessions (default: ~125 frames per stroke, 10-50 Hz)")
    p.add_argument("--t-delay", type=T.T_DELAY_S, help="configured image delay t_delay in s (default: session.json); "
                   "image sessions check it against the record's own delay")
    p.add_argument("--t-delay-from", choices=["data", "config"], default="data",
                   help="image sessions: use the delay measured from the record (data, default) or the configured "
                   "one (config); a gap over one frame period is warned about either way")
    p.add_argument("--hysteresis", type=T.HYSTERESIS, help="reversal detection hysteresis, actuator units (default 1%% of travel)")
    p.add_argument("--threshold", type=T.THRESHOLD, help="onset threshold T per frame (px or deg); default automatic")
    add_json_arg(p, "calibration (path), reversals, b_samples, onset_reasons {name: count}, t_delay_s, "
                 "fps_frames, B_range [min,max], t_delay {configured_s, record_s, used_s, ...} and ringing "
                 "{freq_hz, damping_ratio, ...} (image sessions, else null), b_inconsistent (count), warnings, model (play|pi), operators (count)")
    p.set_defaults(func=run)


def run(a) -> int:
    s = load_session_noted(a.session)
    ov = {"threshold": a.threshold} if a.threshold is not None else None
    cal = calibrate(s, a.control_points, a.f_method, a.fps, a.t_delay, a.hysteresis, ov,
                    t_delay_from=a.t_delay_from, model_kind=a.model)
    cal.save(a.out)
    d = cal.doc
    for w in d.get("warnings", []):
        print(f"playscope: warning: {w}", file=sys.stderr)
    g = np.linspace(*d["q_range"], 200)
    b = cal.B(g)
    print(f"{a.out}: {len(d['b_samples']['b'])} B samples from {d['reversals']} reversals "
          f"({', '.join(f'{k} {v}' for k, v in d['onset']['reasons'].items() if v)}); "
          f"B {b.min():.3g}..{b.max():.3g} {d['actuator_unit']}, t_delay {d['t_delay_s']:.3f} s; "
          f"model {_model_text(cal)}")
    dump_json(a.json, {"calibration": a.out, "reversals": d["reversals"], "b_samples": len(d["b_samples"]["b"]),
                       "onset_reasons": d["onset"]["reasons"], "t_delay_s": d["t_delay_s"],
                       "fps_frames": d["fps_frames"], "B_range": [float(b.min()), float(b.max())],
                       "t_delay": (d["onset"].get("refine") or {}).get("t_delay"),
                       "ringing": (d["onset"].get("refine") or {}).get("ringing"),
                       "b_inconsistent": len(d.get("b_inconsistent", [])), "warnings": d.get("warnings", []),
                       "model": "play" if cal.transition.is_play else "pi", "operators": cal.transition.n})
    return 0


def _model_text(cal) -> str:
    """'play' or 'PI, n operators (r up to ... )', with the CV error of the choice when made."""
    tr, ch = cal.transition, cal.model_choice
    txt = "play" if tr.is_play else (f"play ({tr.b_scale:g} B) + PI, {tr.n} operators (r <= {tr.r[-1]:.3g})")
    if ch:
        pick = next(c for c in ch["candidates"] if (c["b_scale"], c["n"], c["r_span"], c.get("n_ctrl")) ==
                    (ch["b_scale"], ch["n_tried"], ch["r_span"], ch.get("n_ctrl")))
        play = next((c for c in ch["candidates"] if c["n"] == 1), None)
        txt += f", CV RMSE {pick['cv_rmse_deg']:.3g} deg"
        if play and pick is not play:
            txt += f" (play {play['cv_rmse_deg']:.3g})"
    return txt
