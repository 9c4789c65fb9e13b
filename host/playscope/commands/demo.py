"""`playscope demo`: the main job end to end on the built-in simulated instrument
(playscope.mainjob holds the job; this module only parses, runs and prints)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .. import mainjob
from ..mainjob import DEFAULT_OUT, format_summary, run
from .common import dump_json, progress


def cmd_demo(args) -> int:
    bar = progress(total=8, desc="playscope demo", unit="step")

    def log(line: str) -> None:  # a step starts: its name above the bar, the bar one step on
        bar.write(line, file=sys.stdout)
        sys.stdout.flush()
        bar.update(1)

    try:
        with bar:
            s = run(Path(args.out), args.duration, args.seed, args.device, log=log)
    except RuntimeError as e:
        print(f"playscope: error: {e}", file=sys.stderr)
        return 1
    print(format_summary(s))
    dump_json(args.json, s)
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", help="the main job on the built-in simulated instrument, end to end",
        description=mainjob.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  playscope demo\n  playscope demo --out out/main --duration 40 --device virtual "
               "--json summary.json\n")
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    p.add_argument("--duration", type=float, default=90.0, help="length of each simulated session, s (default 90)")
    p.add_argument("--seed", type=int, default=1, help="random seed of the excitation session (test uses seed+1)")
    p.add_argument("--device", choices=["usb", "virtual", "qemu"], default="usb",
                   help="board to flash: usb = virtual board behind the emulated USB device (default)")
    p.add_argument("--json", metavar="PATH", help="also write the summary (keys of out/summary.json) to PATH "
                   "('-': stdout)")
    p.set_defaults(func=cmd_demo, own_progress=True)
