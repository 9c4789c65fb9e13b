"""`playscope report`: calibration + test session -> single-file HTML report with the paper's figures."""

from __future__ import annotations

from . import argtypes as T
from ..pipeline import write_report_file
from .common import add_command, add_json_arg, emit


DESCRIPTION = """\
One HTML file (PNG figures embedded): characteristic with envelopes (Figs. 6, 9), B(q)
samples/spline/knots (Fig. 8), predictions vs measurement (Figs. 10, 11), compensation (Fig.
12), and Table I.
"""


def add_parser(sub) -> None:
    p = add_command(sub, "report", "HTML report with the paper's figures", DESCRIPTION,
                    examples=["playscope report cal.json sim_test -o report.html"])
    p.add_argument("calibration", help="calibration JSON")
    p.add_argument("session", help="test session folder")
    p.add_argument("-o", "--out", required=True, type=T.file_path, help="HTML file to write")
    p.add_argument("--eval", metavar="JSON", help="`playscope evaluate --json` output whose tables to show "
                   "(default: computed here; the figures are always computed from the inputs)")
    add_json_arg(p, "report (path), figures [names], bytes")
    p.set_defaults(func=run)


def run(a) -> int:
    return emit(a, write_report_file(a.calibration, a.session, a.out, a.eval))
