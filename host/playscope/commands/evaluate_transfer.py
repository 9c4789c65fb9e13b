"""`playscope evaluate-transfer`: a calibration made on one record run on others (another session
or sheath configuration), with and without each on-line update (playscope.evaluate.transfer)."""

from __future__ import annotations

from .argtypes import file_path, float_range
from ..evaluate.transfer import JSON_KEYS, WARMUP
from .common import add_command, add_json_arg, dump_json, progress

DESCRIPTION = f"""\
Calibrates the pure play and ours with the transition on the whole of CAL, runs each SESSION with
them from its first sample and scores it after the warm-up: in situ (each record calibrated on its
own warm-up part, the reference), transferred as is, transferred with each on-line update (the
board's RLS on B, the host's offset refresh, both, the host's offset and gain refresh, the board's
offset and gain learner), and the textbook peers fitted on CAL (constant play + poly5, generalized
and modified Prandtl-Ishlinskii and their invertible forms) as is and with the same updates; the
lines under the table say whether ours is at or below every peer given the same update. Records: catheter CSV files (data_2_*.txt) or endoscope files (headerless,
q = commanded angle). One Markdown table (bending-angle RMSE, deg); --plot writes RMSE against the
configuration angle. Default warm-up {WARMUP}: the first half, the only split leaving every endoscope
record two reversals to calibrate on in situ.
"""


def add_parser(sub) -> None:
    p = add_command(sub, "evaluate-transfer", "calibration of one record run on other sessions or configurations",
                    DESCRIPTION, examples=["playscope evaluate-transfer ../shared/data/real/catheter/data_2_1.txt "
                                           "../shared/data/real/catheter/data_2_2.txt --plot transfer.png"])
    p.add_argument("cal", help="the calibration record (CSV file)")
    p.add_argument("sessions", nargs="+", help="the records to run it on (CSV files)")
    p.add_argument("--warmup", type=float_range(0.0, 1.0, lo_open=True, hi_open=True), default=WARMUP,
                   help=f"fraction of each record's duration before scoring starts (default {WARMUP})")
    p.add_argument("--refresh", type=float_range(0.0, None, lo_open=True), default=1.0,
                   help="host offset refresh period, s; also the board learner's publish period (default 1)")
    p.add_argument("--plot", metavar="PNG", type=file_path, help="write RMSE against configuration angle here")
    add_json_arg(p, JSON_KEYS)
    p.set_defaults(func=run, own_progress=True)


def run(a) -> int:
    from ..pipeline import transfer_records

    res = transfer_records(a.cal, a.sessions, a.warmup, a.refresh, a.plot, progress=progress)
    print(res.text)
    dump_json(a.json, res.to_json())
    return 0
