"""`playscope simulate`: write a simulated session (with truth.csv, optionally video), or re-image a
recording that has a measured tip angle through a virtual endoscope camera.

Registered by playscope.cli through add_parser(subparsers).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def add_parser(sub) -> None:
    from .. import argtypes  # range-checked values (issue 14)

    from .core import PRESETS
    from .effects import EFFECTS

    eff_help = "; ".join(f"{e.name}: " + ",".join(f"{p.name}[{p.unit}]" for p in e.params) for e in EFFECTS.values())
    p = sub.add_parser("simulate", help="simulated session (robot with B(q) + f_remain, effects, endoscope camera)",
                       description="Simulate the bending DOF (play of width B(q), f_remain, constant curvature) seen by an "
                                   "endoscope camera, and write a session folder (docs/simulator.md).")
    p.add_argument("out", help="session folder to write")
    p.add_argument("--preset", default="stras", choices=sorted(PRESETS), help="named configuration (default stras)")
    p.add_argument("--config", metavar="JSON", help="SimConfig as JSON (overrides the preset's keys)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME[:p=v,...]",
                   help=f"switch an effect on (repeatable). Known: {eff_help}")
    p.add_argument("--no-preset-effects", action="store_true", help="drop the preset's own effects")
    p.add_argument("--trajectory", choices=["excitation", "test", "ellipse", "random_walk"], help="trajectory kind")
    p.add_argument("--duration", type=argtypes.float_range(0.0, 86_400.0, lo_open=True), help="duration in s")
    p.add_argument("--seed", type=argtypes.SEED, help="random seed")
    p.add_argument("--kind", choices=["image", "angle"], help="distal measurement (default image)")
    p.add_argument("--video", action="store_true", help="also render video.avi (MJPG) + frames.csv")
    p.add_argument("--blind", action="store_true", help="leave the effect list out of session.json")
    p.add_argument("--reimage", metavar="SRC", help="re-image a recording with a measured angle instead: a session "
                                                     "folder (distal.kind angle) or a catheter CSV (data_2_*.txt)")
    p.add_argument("--overwrite", action="store_true")
    p.set_defaults(func=run)


TRAJ_DEFAULTS = {
    "excitation": {"kind": "excitation", "q_lo": -3.0, "q_hi": 3.0, "amp": 1.4, "speed": 0.8, "duration_s": 120.0, "cycles": 2},
    "test": {"kind": "test", "q_lo": -3.0, "q_hi": 3.0, "amp": 1.6, "speed": 1.0, "duration_s": 200.0, "hold_s": 1.0},
    "ellipse": {"kind": "ellipse", "a_mm": 8.0, "b_mm": 3.0, "period_s": 20.0, "cycles": 3},
    "random_walk": {"kind": "random_walk", "q_lo": -3.0, "q_hi": 3.0, "speed": 0.8, "duration_s": 120.0},
}


def build_config(args):
    from .core import SimConfig, preset
    from .effects import parse_effect

    cfg = preset(args.preset)
    if args.config:
        d = cfg.to_json()
        d.update(json.loads(Path(args.config).read_text()))
        cfg = SimConfig.from_json(d)
    if args.no_preset_effects:
        cfg.effects = {}
    for spec in args.effect:
        name, params = parse_effect(spec)
        cfg.effects[name] = params
    if args.trajectory:
        cfg.trajectory = dict(TRAJ_DEFAULTS[args.trajectory])
    if args.duration:
        if cfg.trajectory["kind"] == "ellipse":
            cfg.trajectory["cycles"] = args.duration / cfg.trajectory.get("period_s", 20.0)
        else:
            cfg.trajectory["duration_s"] = args.duration
    if args.seed is not None:
        cfg.seed = args.seed
    if args.kind:
        cfg.distal_kind = args.kind
    return cfg


def reimage(src: str, cfg, seed: int = 0):
    """Session whose marker is the measured tip angle of ``src`` seen by cfg's camera (nominal
    hand-eye, distortion, delay t_delay_s, marker noise). Returns (session, c_frames, t_frames)."""
    from ..session import Session, load_session
    from .core import observe_image

    p = Path(src)
    if p.is_dir():
        rec = load_session(p)
    else:
        from ..importer import import_catheter
        rec = import_catheter(p)
    if rec.distal is None:
        raise ValueError(f"{src}: no measured angle (distal.csv) to re-image")
    cfg.q_per_rad = rec.robot.q_per_rad
    truth = {"t_s": rec.distal["t_s"], "c_deg": rec.distal["c_deg"]}
    from .core import distal_direction
    from .effects import EffectSet
    truth["dir"] = distal_direction(truth["c_deg"], tol=0.02)
    rng = np.random.default_rng(seed)
    obs = observe_image(cfg, truth, EffectSet(dict(cfg.effects)), rng)
    s = Session(actuator_unit=rec.actuator_unit, distal_kind="image", robot=cfg.robot(), encoder=dict(rec.encoder),
                camera=cfg.camera(), hand_eye=cfg.hand_eye(), t_delay_s=cfg.t_delay_s,
                marker={k: obs[k] for k in ("t_s", "u_px", "v_px")}, truth=truth,
                meta={"source": {"reimaged_from": str(src)}, "simulator": cfg.to_json()})
    return s, obs["c_deg"], obs["t_s"]


def run(args) -> int:
    from ..session import write_session
    from .core import observe_image, simulate
    from .effects import EffectSet

    cfg = build_config(args)
    out = Path(args.out)
    if args.reimage:
        s, c_frames, t_frames = reimage(args.reimage, cfg, cfg.seed)
    else:
        s = simulate(cfg, blind=args.blind)
    write_session(s, out, overwrite=args.overwrite)
    msg = f"wrote {out}: {s.encoder['t_s'].size} encoder rows"
    if s.marker is not None:
        msg += f", {s.marker['t_s'].size} frames"
    if args.video:
        from .render import write_video
        if not args.reimage:
            obs = observe_image(cfg, s.truth, EffectSet(dict(cfg.effects)), np.random.default_rng(cfg.seed), with_noise=False)
            c_frames, t_frames = obs["c_deg"], obs["t_s"]
            cap = obs["t_capture_s"]
        else:
            cap = t_frames - cfg.t_delay_s
        dirs = np.interp(cap, s.truth["t_s"], s.truth["dir"]) if "dir" in s.truth else None
        tr = np.interp(cap, s.truth["t_s"], s.truth["translation_mm"]) if "translation_mm" in s.truth else None
        v = write_video(cfg, c_frames, t_frames, out, dirs, tr, cfg.effects)
        msg += f", video {v.name}"
    print(msg, file=sys.stderr)
    return 0
