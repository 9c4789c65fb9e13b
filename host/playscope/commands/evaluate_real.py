"""`playscope evaluate-real`: acceptance tables on the real catheter recordings."""

from __future__ import annotations

from .common import add_command, add_json_arg, dump_json, progress


DESCRIPTION = """\
Two Markdown tables of bending-angle RMSE (deg). In situ: each file split at half its duration
and run through `playscope evaluate-insitu` (every model fitted on the first half, run from the
file's start with its state carried, judged on the second half; the board's models on fixed-
point tables). Across sessions: linear, constant play + degree-5 polynomial, ours (onset B(q) +
play-consistent f_remain) and paper (onset B(q) + morphological f_remain) fitted on data_2_1,
judged on each other file. The recordings are read in place.
"""


def add_parser(sub) -> None:
    p = add_command(sub, "evaluate-real", "in situ and across-session RMSE tables on the catheter recordings", DESCRIPTION,
                    examples=["playscope evaluate-real ../shared/data/real/catheter"])
    p.add_argument("folder", help="folder holding data_2_*.txt")
    p.add_argument("--reimage", metavar="WORKDIR",
                   help="render each recording through a virtual endoscope into WORKDIR first (video, "
                   "then marker tracking), and run the chain on the images, judged against the measured "
                   "angle (about 20 s per file; tracked folders are reused)")
    p.add_argument("--online", action="store_true",
                   help="instead: the on-line update protocol (docs/online.md): calibrate on data_2_1, run each other "
                   "file from its start with the board's B update and the host's offset refresh, score after its first "
                   "20 %%, beside the same model without update and a constant play refitted in situ (--json: that "
                   "result, files {file: {rmse_deg: {row: deg}, b_samples, ...}})")
    add_json_arg(p, "in_situ {file: {row: rmse_deg}}, in_situ_max {file: {row: max_abs_deg}}, in_situ_rows "
                 "[row] (linear, const_play, paper, onset_lsq, gpi, bouc_wen, ours: see evaluate-insitu), "
                 "across {file: {model: rmse_deg}} (linear, const_play, ours, paper), b_samples {file: n}")
    p.set_defaults(func=run, own_progress=True)


def run(a) -> int:
    from ..pipeline import evaluate_real_data

    res = evaluate_real_data(a.folder, a.reimage, a.online, progress=lambda it, **kw: progress(it, **kw))
    print(res.text)
    dump_json(a.json, res.to_json())
    return 0
