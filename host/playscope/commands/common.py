"""Helpers shared by the subcommands: one way to declare a command (add_command), the common
options (--json PATH, --out, --quiet; docs/host.md "Common options"), --json output and
progress bars."""

from __future__ import annotations

import contextlib
import sys

from ..fit.calibration_check import load_calibration  # noqa: F401 (the commands' name for it)
from ..base.jsonio import write_json


def add_command(sub, name: str, help: str, description: str, examples=(), epilog: str = ""):
    """Add subcommand name to the subparsers sub and return its parser: description wrapped,
    then an "examples:" block (each a command line, run or parsed by
    tests/python/host/test_cli_examples.py), then epilog as written."""
    import argparse
    import textwrap

    ex = "examples:\n" + "".join(f"  {e}\n" for e in examples) if examples else ""
    return sub.add_parser(name, help=help, description="\n".join(textwrap.wrap(" ".join(description.split()), 92)),
                          epilog=(ex + epilog) or None, formatter_class=argparse.RawDescriptionHelpFormatter)


def add_json_arg(p, keys_doc: str) -> None:
    """Add --json PATH; keys_doc lists the keys written, shown in --help."""
    from .argtypes import file_path

    p.add_argument("--json", metavar="PATH", type=file_path,
                   help=f"also write machine-readable results to PATH ('-': stdout). Keys: {keys_doc}")


def load_session_noted(folder):
    """A session folder or a recording file read in place (importer.load_recording), printing
    what loading repaired (session.notes: repeated or backward time stamps, a held sensor) as one
    `playscope: warning:` line each on stderr."""
    from ..io.importer import load_recording

    s = load_recording(folder, progress)
    warn(s.notes)
    return s


def warn(lines) -> None:
    """Each line as `playscope: warning: <line>` on stderr."""
    for line in lines:
        print(f"playscope: warning: {line}", file=sys.stderr)


def dump_json(path: str | None, obj: dict) -> None:
    """Write obj as JSON (NaN -> null, numpy -> lists) atomically to path, or to stdout for "-";
    no-op when path is None (jsonio.write_json)."""
    write_json(path, obj)


def emit(a, res) -> int:
    """Print a pipeline result's summary line and write its --json document; exit status 0."""
    print(res.line())
    dump_json(a.json, res.to_json())
    return 0


@contextlib.contextmanager
def busy(desc: str):
    """A tqdm line on stderr with the elapsed time while a step without progress of its own
    runs (cli.main wraps every command that sets no own_progress in it), refreshed twice a
    second by a thread, naming the step the computation reports (base.stage); silent when
    stderr is not a terminal. Yields the bar (bar.write prints above it)."""
    import threading

    bar = progress(total=None, desc=desc, bar_format="{desc}: {elapsed}")
    stop = threading.Event()
    th = None
    if not bar.disable:
        def tick():
            while not stop.wait(0.5):
                bar.refresh()
        th = threading.Thread(target=tick, daemon=True)
        th.start()
    from ..base.stage import stage_sink

    try:
        with stage_sink(lambda name: bar.set_description_str(f"{desc}: {name}", refresh=False)):
            yield bar
    finally:
        stop.set()
        if th is not None:
            th.join()
        bar.close()


def progress(iterable=None, **kw):
    """tqdm on stderr, silent when stderr is not a terminal (logs, tests)."""
    from tqdm import tqdm

    kw.setdefault("disable", not sys.stderr.isatty())
    kw.setdefault("leave", False)
    return tqdm(iterable, file=sys.stderr, **kw)
