"""The transition model on the shared catheter recordings, in situ with state carried, on the
fixed-point tables (the full comparison with textbook peers is
`playscope evaluate` / evaluate-real on branch insitu-eval).

Per file: `calibrate(first half, model_kind=...)` (onset B, f_remain, transition chosen by
cross-validation on the first half only), `tables.build_table` (layout 2, the firmware's
table_write/calib_load), then the firmware's playop_step over the whole record from its first
sample; RMSE of the bending angle on the second half. Rows: the paper's pure play (auto's
alternative, --model play) and ours (--model auto) on the tables; ours in the float chain
(`Calibration.predict`, the same model in double precision: what the tables cost); the
generalized-PI peer (`peers.GeneralizedPI` on the chain's calibration frames,
`insitu.calibration_frames`, run in double precision from the first sample). Prints a Markdown
table.

Usage: .venv/bin/python bench/transition_catheter.py [folder]   (default $PLAYSCOPE_REAL_DATA/catheter; ~10 s)
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from playscope.fit.calibration import calibrate
from playscope.io.importer import import_catheter
from playscope.evaluate.insitu_split import calibration_frames
from playscope.fit.peers import GeneralizedPI
from playscope.fit.table_build import build_table

# As tests/python/conftest.py: $PLAYSCOPE_REAL_DATA, else ../shared/data/real beside the checkout.
DEFAULT = Path(os.environ.get("PLAYSCOPE_REAL_DATA", Path(__file__).resolve().parents[2] / "shared" / "data" / "real")) / "catheter"


def in_situ(path: Path, model_kind: str) -> tuple[dict, str]:
    """{row: RMSE deg on the second half} for one file and one model_kind, and the choice."""
    s = import_catheter(path)
    t = s.encoder["t_s"]
    half = t[0] + 0.5 * (t[-1] - t[0])
    cal_s = s.slice_time(-np.inf, half)
    cal = calibrate(cal_s, model_kind=model_kind)
    q0, q1 = cal.q_range
    # The table covers the travel seen in calibration; the board saturates beyond it.
    tab = build_table(cal.B_model, cal.f, q0, q1, "mm", transition=cal.transition)
    q = np.clip(s.encoder["q"], q0, q1)
    j = s.distal["t_s"] >= half
    rmse = lambda c_hat: float(np.sqrt(np.mean((c_hat[j] - s.distal["c_deg"][j]) ** 2)))
    out = {"fixed": rmse(tab.predict(q)), "float": rmse(cal.predict(q))}
    if model_kind == "auto":
        out["gpi"] = rmse(GeneralizedPI.fit(*calibration_frames(cal_s, cal)).predict(s.encoder["q"]))
    tr = cal.transition
    ch = cal.model_choice or {}
    what = "play" if tr.is_play else f"{tr.n} ops, {tr.b_scale:g}B, r<={tr.r[-1]:.2f}, f N={ch.get('n_ctrl')}"
    return out, what


def main(folder: Path) -> int:
    files = sorted(folder.glob("data_2_*.txt"))
    if not files:
        print(f"no data_2_*.txt in {folder}", file=sys.stderr)
        return 2
    rows = {f.stem: (in_situ(f, "play"), in_situ(f, "auto")) for f in files}
    print("| in situ, RMSE (deg) | " + " | ".join(rows) + " | mean | worst |")
    print("|---" * (len(rows) + 3) + "|")
    for i, key, name in ((0, "fixed", "paper's play (onset B + f_remain), fixed-point table"),
                         (1, "fixed", "ours, --model auto, fixed-point table"),
                         (1, "float", "ours, --model auto, float chain"),
                         (1, "gpi", "generalized PI peer (float)")):
        v = [r[i][0][key] for r in rows.values()]
        print(f"| {name} | " + " | ".join(f"{x:.3f}" for x in v) + f" | {np.mean(v):.3f} | {np.max(v):.3f} |")
    print("| ours: model chosen | " + " | ".join(r[1][1] for r in rows.values()) + " | | |")
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT))
