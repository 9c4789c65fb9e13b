"""Command-line entry point `playscope`: one argparse subcommand per module.

Each command module exposes ``add_parser(subparsers)``, which adds its subparser and sets
``func=<callable(args) -> int>`` on it. All command modules live in playscope.commands;
those of optional subpackages (sim, diagnose, board) are skipped when the package is absent. Bad input prints one line
``playscope: error: <file>:<row>: <message>`` and exits with status 2: an InputError, an
OSError, a UnicodeDecodeError, a JSON or any other ValueError escaping a command, and a bad
command-line value (argparse types in playscope.commands.argtypes). PLAYSCOPE_DEBUG=1 re-raises them
with the traceback, for bug reports.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import io
import json
import os
import sys

from . import __version__
from .base.atomic import check_flash_file, check_output, output_guard
from .base.errors import InputError
from .io.inputfile import check_input_file

# Argument dests that name what a command writes; every other path-valued argument that
# exists is an input the output guard protects (atomic.output_guard). Not inputs either:
# the virtual board's flash file, work folders and device addresses.
OUTPUT_ARGS = ("out", "output", "json", "html")
NOT_INPUT_ARGS = frozenset(OUTPUT_ARGS + ("flash_file", "elf", "address", "device", "command",
                                          "device_command", "func"))
# Per command, arguments naming a work folder or file the command manages itself (reuses or
# replaces by design): neither an input nor an output the guard checks.
WORK_ARGS = {"evaluate-real": ("reimage",), "demo": ("out", "json")}
# Per command, inputs that may be a device (a camera): every other input must be a regular
# file or a folder (io.inputfile.check_input_file).
DEVICE_ARGS = {"run-insitu": ("video",)}

# Command modules in help order (all in playscope.commands, the one command-line home), each
# with the subpackage it needs: a command whose package is absent from an install is skipped.
COMMAND_MODULES = [
    ("playscope.commands.import_cmd", None),
    ("playscope.commands.track", None),
    ("playscope.commands.calibrate", None),
    ("playscope.commands.tables", None),
    ("playscope.commands.evaluate", None),
    ("playscope.commands.report", None),
    ("playscope.commands.evaluate_real", None),
    ("playscope.commands.evaluate_insitu", None),
    ("playscope.commands.evaluate_transfer", None),
    ("playscope.commands.simulate", "playscope.sim"),
    ("playscope.commands.diagnose", "playscope.diagnose"),
    ("playscope.commands.device", "playscope.board"),
    ("playscope.commands.demo", None),
]

# Each command's name, module and one-line help, so `playscope --help`, `--version` and an
# unknown command answer without importing any command module (numpy, OpenCV, the native
# core: about 1 s); a command imports only its own module. tests/python/host/test_cli_examples.py
# checks each line equals the help its module declares.
COMMANDS = {
    "import": ("playscope.commands.import_cmd", "bring a CSV recording or a ROS bag into a session folder"),
    "track": ("playscope.commands.track", "find the coloured marker in a session's video -> marker.csv"),
    "calibrate": ("playscope.commands.calibrate", "estimate B(q) and f_remain from a session"),
    "tables": ("playscope.commands.tables", "write the firmware's fixed-point lookup tables"),
    "evaluate": ("playscope.commands.evaluate", "prediction (Table I) and compensation errors on a test session"),
    "report": ("playscope.commands.report", "HTML report with the paper's figures"),
    "evaluate-real": ("playscope.commands.evaluate_real",
                      "in situ and across-session RMSE tables on the catheter recordings"),
    "evaluate-insitu": ("playscope.commands.evaluate_insitu", "in-situ RMSE of every model on one session split in time"),
    "evaluate-transfer": ("playscope.commands.evaluate_transfer",
                          "calibration of one record run on other sessions or configurations"),
    "simulate": ("playscope.commands.simulate",
                 "simulated session (robot with B(q) + f_remain, effects, endoscope camera)"),
    "diagnose": ("playscope.commands.diagnose",
                 "sim-to-real gap: held-out gap, localisation, attribution to library effects"),
    "flash": ("playscope.commands.device", "upload a table, commit, read back and check bit for bit"),
    "device": ("playscope.commands.device", "board information"),
    "run-insitu": ("playscope.commands.device", "in-situ calibration on the board: excitation, marker from a "
                   "camera/video, B samples from the board's onset detector, fit, tables, flash"),
    "demo": ("playscope.commands.demo", "the main job on the built-in simulated instrument, end to end"),
}
NEEDS = dict(COMMAND_MODULES)

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


class Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line (no usage block), exit status 2; the
    subcommand parsers inherit it."""

    def error(self, message: str):
        where = self.prog.partition(" ")[2]  # "playscope calibrate" -> "calibrate"
        self.exit(2, f"playscope: error: {where + ': ' if where else ''}{message}; see `{self.prog} --help`\n")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The full parser (every command module imported), or with only="flash" etc. the one
    module holding that command, the others as stubs that only name themselves (enough for
    the top-level --help and for refusing an unknown command); only="" imports none."""
    p = Parser(prog="playscope", description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"playscope {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    want = None if only is None else (COMMANDS[only][0] if only in COMMANDS else "")
    done = set()
    for name, (module, help_) in COMMANDS.items():
        needs = NEEDS[module]
        # Only a missing optional package is silent; a broken one still fails loudly.
        if needs is not None and importlib.util.find_spec(needs) is None:
            continue
        if want is None or module == want:
            if module not in done:
                importlib.import_module(module).add_parser(sub)
                done.add(module)
        else:
            sub.add_parser(name, help=help_)
    for sp in _all_subparsers(sub):
        if "--force" not in sp._option_string_actions:
            sp.add_argument("--force", action="store_true",
                            help="replace existing outputs (never an input of the command)")
        if sp.get_default("func") is not None and "--quiet" not in sp._option_string_actions:
            sp.add_argument("-q", "--quiet", action="store_true",
                            help="print no summary on stdout (warnings and errors still go to stderr; "
                            "--json - implies it)")
    return p


def _all_subparsers(sub) -> list:
    out = []
    for sp in set(sub.choices.values()):
        out.append(sp)
        for a in sp._actions:
            if isinstance(a, argparse._SubParsersAction):
                out += _all_subparsers(a)
    return out


def _paths(args) -> tuple[list[str], list[str]]:
    """(inputs, outputs) named on the command line: see OUTPUT_ARGS / NOT_INPUT_ARGS."""
    ins, outs = [], []
    work = WORK_ARGS.get(getattr(args, "command", None), ())
    for k, v in vars(args).items():
        if k in work:
            continue
        for x in (v if isinstance(v, list) else [v]):
            if not isinstance(x, str) or not x:
                continue
            if k in OUTPUT_ARGS:
                outs.append(x)
            elif k not in NOT_INPUT_ARGS and os.path.exists(x):
                ins.append(x)
    return ins, outs


def _command_word(argv: list[str]) -> str:
    """The subcommand named in argv (the first word not starting with '-'), or ""."""
    for a in argv:
        if not a.startswith("-"):
            return a
        if a == "--":
            break
    return ""


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command_word(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help, --version, or a refused value (one line already printed)
        return e.code if isinstance(e.code, int) else 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        ins, outs = _paths(args)
        live = [getattr(args, k, None) for k in DEVICE_ARGS.get(args.command, ())]
        for x in ins:  # a pipe or a device named as an input is refused before anything opens it
            if not os.path.isdir(x) and x not in live:
                check_input_file(x, "regular file")
        force = bool(getattr(args, "force", False))
        _sigterm_as_interrupt()
        with output_guard(ins, force):
            for o in outs:  # before any work: a refused output costs nothing
                check_output(o)
            check_flash_file(getattr(args, "flash_file", None))
            return _run_command(args)
    except KeyboardInterrupt:
        print("playscope: interrupted (nothing half-written is left under an output's name)", file=sys.stderr)
        return 130
    except (InputError, OSError, ValueError, OverflowError, RecursionError,
            KeyError, TypeError, AttributeError, IndexError) as e:
        # The last four: a malformed field of a file no loader check caught (a missing key, a
        # value of another type); still one line, never a traceback.
        if os.environ.get("PLAYSCOPE_DEBUG"):
            raise
        print(f"playscope: error: {_one_line(e, args)}", file=sys.stderr)
        return 2


def _sigterm_as_interrupt():
    """SIGTERM raises KeyboardInterrupt, as SIGINT does, so a killed command removes its
    temporaries (atomic.atomic_path, io.videofile) instead of leaving a partial output."""
    import signal

    def handler(signum, frame):
        raise KeyboardInterrupt

    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (a library caller): leave the process's handler alone
        return None


def _run_command(args) -> int:
    """args.func(args), its stdout silenced under --quiet or --json - (the JSON itself still
    reaches stdout: jsonio.STDOUT), under a busy line (commands.common.busy) unless the command
    shows progress of its own (own_progress)."""
    from .base import jsonio
    from .commands.common import busy

    bar = contextlib.nullcontext() if getattr(args, "own_progress", False) else busy(f"playscope {args.command}")
    if not (getattr(args, "quiet", False) or getattr(args, "json", None) == "-"):
        with bar:
            return int(args.func(args) or 0)
    jsonio.STDOUT.append(sys.stdout)
    try:
        with contextlib.redirect_stdout(io.StringIO()), bar:
            return int(args.func(args) or 0)
    finally:
        jsonio.STDOUT.pop()


def _one_line(e: BaseException, args) -> str:
    """FILE[:ROW]: what, for an error that escaped a command (InputError already is that)."""
    if isinstance(e, InputError):
        msg = str(e)
    elif isinstance(e, json.JSONDecodeError):
        msg = f"<input>:{e.lineno}: invalid JSON: {e.msg}; check the file"
    elif isinstance(e, UnicodeDecodeError):
        msg = f"<input>: not UTF-8 text (byte {e.start}); a text file was expected"
    elif isinstance(e, OSError) and e.filename is not None:
        msg = f"{e.filename}: {e.strerror or e}; check the path and its permissions"
    elif isinstance(e, OSError):
        msg = f"{e}"  # a board or transport failure (TransportError) says what and where itself
    elif isinstance(e, (KeyError, TypeError, AttributeError, IndexError)):
        cmd = " ".join(x for x in (getattr(args, "command", None), getattr(args, "device_command", None)) if x)
        what = f"key {e.args[0]!r} missing" if isinstance(e, KeyError) and e.args else str(e)
        msg = (f"{cmd or 'playscope'}: a malformed field in an input file ({type(e).__name__}: {what}); check the "
               "files against docs/session-format.md and docs/calibration-format.md (PLAYSCOPE_DEBUG=1 for details)")
    else:
        cmd = " ".join(x for x in (getattr(args, "command", None), getattr(args, "device_command", None)) if x)
        msg = f"{cmd or 'playscope'}: {e}; check the inputs and options (PLAYSCOPE_DEBUG=1 for details)"
    return " ".join(msg.split())  # one line, whatever the message held


if __name__ == "__main__":
    sys.exit(main())
