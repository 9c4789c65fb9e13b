"""`playscope evaluate-insitu`: one session split in time, every model fitted on the part before
and scored on the part after, state carried from the record's start (playscope.evaluate.insitu_split)."""

from __future__ import annotations

from ..evaluate.insitu_split import JSON_KEYS
from .common import add_command, add_json_arg, dump_json, load_session_noted, progress


DESCRIPTION = """\
Fits, on the part of SESSION before the split only: linear, constant play + poly5, the paper's
method (onset B + morphological f_remain), onset B + least-squares f_remain, generalized
Prandtl-Ishlinskii (16 play operators, weights >= 0, + cubic in q) and the same with its cubic held
increasing, Bouc-Wen, modified Prandtl-Ishlinskii (16 play operators + output spline) and the same
with its output monotone (the two invertible forms), and ours (the model family chosen by
cross-validation through the tables). Every model then runs over the whole record from its first sample (a board that has
been running all along) and is scored on the part after the split: bending-angle RMSE and max
(deg), one Markdown table. Rows the board runs go through the firmware's fixed-point tables.
"""


def add_parser(sub) -> None:
    from . import argtypes

    p = add_command(sub, "evaluate-insitu", "in-situ RMSE of every model on one session split in time", DESCRIPTION,
                    examples=["playscope evaluate-insitu sessions/d21 --split 0.5 --json insitu.json",
                              "playscope evaluate-insitu ../shared/data/real/endoscope/30.txt --split 0.75"])
    p.add_argument("session", help="session folder (an angle session, or an image session: scored against "
                   "truth.csv when present, else the per-frame pose estimate), or a recording file read in "
                   "place: the catheter's CSV with a header, or the endoscope's headerless CSV")
    p.add_argument("--split", default="0.5", type=argtypes.split_spec, help="fraction of the duration in (0, 1), or a time from the "
                   "first sample with an s suffix, e.g. 30s (default 0.5)")
    add_json_arg(p, JSON_KEYS + ". rmse_deg/max_deg over the samples with t >= t_split; fixed_point true when "
                 "the row is scored through the firmware's playop_step on a Q16.16 table")
    p.set_defaults(func=run, own_progress=True)


def run(a) -> int:
    from ..pipeline import evaluate_insitu_record

    s = load_session_noted(a.session)  # its repairs as warnings, before the long run
    res = evaluate_insitu_record(a.session, a.split, progress=progress, loaded=s)
    print(res.text())
    dump_json(a.json, res.to_json())
    return 0
