"""`playscope evaluate`: Table I (prediction errors) and the compensation test on a test session."""

from __future__ import annotations

from . import argtypes as T
from ..pipeline import evaluate_session
from .common import add_command, add_json_arg, emit


DESCRIPTION = """\
Direct models f_coarse, f_coarse+B, f_remain+B (float, eqs. 2-3) and f_remain+B through the
firmware's playop_step on Q16.16 tables, projected with h(g(c)) (eq. 6) and compared with the
marker (|Qx|, |Qy|, distance: mean ± std, max) or with the angle sensor (RMSE); then an open-
loop reference through f_coarse^-1, eq. 4+5, eq. 4+9 and comp_step, run on the simulator's truth
model when the session records it.
"""


def add_parser(sub) -> None:
    p = add_command(sub, "evaluate", "prediction (Table I) and compensation errors on a test session", DESCRIPTION,
                    examples=["playscope evaluate sim_test cal.json --json eval.json"])
    p.add_argument("session", help="test session folder, or a recording file read in place (not the one "
                   "calibrated on, for a fair test)")
    p.add_argument("calibration", help="calibration JSON from `playscope calibrate`")
    p.add_argument("--table", type=T.existing_file, help="table blob from `playscope tables` for the fixed-point rows "
                   "(default: built from the calibration)")
    # At least 2 s: the reference's first second is not scored (the plant's play starts centred).
    p.add_argument("--comp-duration", type=T.float_range(2.0, 3600.0), default=60.0,
                   help="length of the compensation reference, s, 2..3600 (default 60; its first second is not scored)")
    add_json_arg(p, "format, session, calibration, distal_kind, t_delay_s, frames_scored, table, "
                 "prediction {model: {Qx_px|Qy_px|dist_px|c_deg: {mean,std,max}, c_rmse_deg, c_rmse_truth_deg}}, "
                 "compensation {plant, note, reference {duration_s, rate_hz, c_min_deg, c_max_deg}, "
                 "methods {method: {c_rmse_deg, c_max_deg, dist_px {mean,std,max}}}}, notes "
                 "(docs/calibration-format.md)")
    p.set_defaults(func=run)


def run(a) -> int:
    return emit(a, evaluate_session(a.session, a.calibration, a.table, a.comp_duration))
