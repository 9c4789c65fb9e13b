"""`playscope report`: calibration + test session -> single-file HTML report with the paper's figures."""

from __future__ import annotations

import json
from pathlib import Path

from .. import argtypes as T
from ..errors import InputError
from ..evaluate import evaluate, format_table
from ..report import write_report
from .common import load_session_noted, add_json_arg, dump_json, load_calibration


def add_parser(sub) -> None:
    p = sub.add_parser("report", help="HTML report with the paper's figures",
                       description="One HTML file (PNG figures embedded): characteristic with envelopes "
                       "(Figs. 6, 9), B(q) samples/spline/knots (Fig. 8), predictions vs measurement (Figs. 10, 11), "
                       "compensation (Fig. 12), and Table I. Example: playscope report cal.json sim_test -o report.html")
    p.add_argument("calibration", help="calibration JSON")
    p.add_argument("session", help="test session folder")
    p.add_argument("-o", "--out", required=True, type=T.file_path, help="HTML file to write")
    p.add_argument("--eval", metavar="JSON", help="`playscope evaluate --json` output whose tables to show "
                   "(default: computed here; the figures are always computed from the inputs)")
    add_json_arg(p, "report (path), figures [names], bytes")
    p.set_defaults(func=run)


def run(a) -> int:
    cal = load_calibration(a.calibration)
    s = load_session_noted(a.session)
    ev = evaluate(cal, s, source=a.session)
    ev.summary["calibration"] = a.calibration
    summary = ev.summary
    if a.eval:
        path = Path(a.eval)
        if not path.is_file():
            raise InputError(path, "file not found")
        try:
            summary = json.loads(path.read_text())
            md = format_table(summary)
        except (json.JSONDecodeError, KeyError, TypeError) as e:
            raise InputError(path, f"not an `evaluate --json` file: {e}") from None
    else:
        md = format_table(summary)
    write_report(a.out, cal, ev, md)
    n = Path(a.out).stat().st_size
    print(f"{a.out}: {n} bytes, 4 figures")
    dump_json(a.json, {"report": a.out, "figures": ["characteristic", "backlash", "prediction", "compensation"],
                       "bytes": n})
    return 0
