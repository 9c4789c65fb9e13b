"""`playscope simulate`: write a simulated session (with truth.csv, optionally video), or re-image a
recording that has a measured tip angle through a virtual endoscope camera.

Registered by playscope.cli through add_parser(subparsers); the work is playscope.sim.record.
"""

from __future__ import annotations

import sys

from .common import add_command, add_json_arg, dump_json


DESCRIPTION = """\
Simulate the bending DOF (play of width B(q), f_remain, constant curvature) seen by an endoscope
camera, and write a session folder (docs/simulator.md).
"""


def add_parser(sub) -> None:
    from . import argtypes  # range-checked values

    from ..sim.core import PRESETS
    from ..sim.effects import EFFECTS
    from ..sim.record import TRAJ_DEFAULTS

    eff_help = "; ".join(f"{e.name}: " + ",".join(f"{p.name}[{p.unit}]" for p in e.params) for e in EFFECTS.values())
    p = add_command(sub, "simulate", "simulated session (robot with B(q) + f_remain, effects, endoscope camera)", DESCRIPTION,
                    examples=["playscope simulate sim_cal --preset stras --trajectory excitation --duration 120 --seed 1 --video",
                              "playscope simulate sim_test --preset stras --trajectory test --duration 60 --seed 2",
                              "playscope simulate reimaged --reimage ../shared/data/real/catheter/data_2_1.txt --video"])
    p.add_argument("out", help="session folder to write")
    p.add_argument("--preset", default="stras", choices=sorted(PRESETS), help="named configuration (default stras)")
    p.add_argument("--config", metavar="JSON", help="SimConfig as JSON (overrides the preset's keys)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME[:p=v,...]",
                   help=f"switch an effect on (repeatable). Known: {eff_help}")
    p.add_argument("--no-preset-effects", action="store_true", help="drop the preset's own effects")
    p.add_argument("--trajectory", choices=list(TRAJ_DEFAULTS), help="trajectory kind")
    # At least 0.1 s: a shorter record has fewer than the two encoder samples a session needs.
    p.add_argument("--duration", type=argtypes.float_range(0.1, 86_400.0), help="duration in s, 0.1..86400")
    p.add_argument("--seed", type=argtypes.SEED, help="random seed")
    p.add_argument("--kind", choices=["image", "angle"], help="distal measurement (default image)")
    p.add_argument("--video", action="store_true", help="also render video.avi (MJPG) + frames.csv")
    p.add_argument("--blind", action="store_true", help="leave the effect list out of session.json")
    p.add_argument("--reimage", metavar="SRC", help="re-image a recording with a measured angle instead: a session "
                                                     "folder (distal.kind angle) or a catheter CSV (data_2_*.txt)")
    p.add_argument("--force", "--overwrite", dest="force", action="store_true",
                   help="replace an existing session folder (only one holding nothing but session files)")
    add_json_arg(p, "session (path), encoder_rows, frames (null for an angle session), video (path or null)")
    p.set_defaults(func=run)


def build_config(args):
    """The SimConfig the command line asks for (sim.record.sim_config)."""
    from ..sim.record import sim_config

    return sim_config(args.preset, args.config, args.effect, args.no_preset_effects, args.trajectory,
                      args.duration, args.seed, args.kind)


def run(args) -> int:
    from ..sim.record import write_simulated

    res = write_simulated(build_config(args), args.out, args.video, args.blind, args.reimage, args.force)
    print(res.summary_line(), file=sys.stderr)
    dump_json(args.json, res.to_json())
    return 0
