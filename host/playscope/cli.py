"""Command-line entry point `playscope`: one argparse subcommand per module.

Each command module exposes ``add_parser(subparsers)``, which adds its subparser and sets
``func=<callable(args) -> int>`` on it. Optional subpackages (sim, diagnose, device) register
themselves the same way when they are importable. Bad input (playscope.errors.InputError)
prints one line ``playscope: error: <file>:<row>: <message>`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from . import __version__
from .errors import InputError

# Command modules in help order; optional ones are skipped when their package is absent.
COMMAND_MODULES = [
    ("playscope.commands.import_cmd", False),
    ("playscope.commands.track", False),
    ("playscope.commands.calibrate", False),
    ("playscope.commands.tables", False),
    ("playscope.commands.evaluate", False),
    ("playscope.commands.report", False),
    ("playscope.commands.evaluate_real", False),
    ("playscope.commands.evaluate_insitu", False),
    ("playscope.sim.cli", True),
    ("playscope.diagnose.cli", True),
    ("playscope.device.cli", True),
    ("playscope.mainjob", False),
]

DESCRIPTION = """\
In situ backlash estimation for tendon-driven continuum robots (Fig. 4 of the paper):
  import      bring a foreign CSV recording (e.g. the EM-tracked catheter) into a session
  track       find the coloured marker in a session's video -> marker.csv
  calibrate   B(q) from motion onsets + f_remain -> calibration JSON
  tables      calibration JSON -> fixed-point table blob for the firmware (common/ps_table.h)
  evaluate    prediction (Table I) and compensation errors on a test session
  evaluate-insitu  every model fitted before a split of one session, scored after it, state carried
  report      HTML report with the paper's figures
  demo        the main job end to end on a simulated instrument (what tools/run-main.sh runs)
Typical run:  playscope calibrate S -o cal.json && playscope tables cal.json -o cal.pstb
"""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="playscope", description=DESCRIPTION,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"playscope {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name, optional in COMMAND_MODULES:
        try:
            mod = importlib.import_module(name)
        except ImportError as e:
            # Only a missing optional package is silent; a broken one still fails loudly.
            if optional and e.name is not None and name.startswith(e.name):
                continue
            raise
        mod.add_parser(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except InputError as e:
        print(f"playscope: error: {e}", file=sys.stderr)
        return 2
    except FileExistsError as e:
        print(f"playscope: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
