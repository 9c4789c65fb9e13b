#!/usr/bin/env python3
"""The product's `ours` with and without the travel-domain relaxation on the catheter files,
through the fixed-point tables, in situ (playscope.evaluate.insitu_split: fit on t < t_split only, every model
run from the record's first sample, scored on t >= t_split against the angle sensor).

Per file and split: the rows of `evaluate-insitu` (playscope.evaluate.insitu_split.fit_rows / score_rows), plus
`ours+relax`: ours's onset B, transition and threshold map as calibrated, (kappa, lambda) and f
refitted on the relaxed output by playscope.fit.relax.fit_on_calibration on the calibration part's
frames only, written as a layout-4 table and run by the firmware's playop_step (cffi); and its
control `ours_refit`: the same f fit on the unrelaxed output (kappa = 0), so the difference
between the two is the relaxation's alone.

Usage: .venv/bin/python bench/relax_insitu.py [--catheter DIR] [--splits 0.5,0.75] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "host"))

from playscope.fit.reversals import frames_from_angle  # noqa: E402
from playscope.fit import relax as R  # noqa: E402
from playscope.diagnose.realdata import catheter_dir  # noqa: E402
from playscope.io.importer import import_catheter  # noqa: E402
from playscope.evaluate.insitu_split import fit_rows, score_rows, split_time, Row  # noqa: E402
from playscope.fit.table_build import build_table  # noqa: E402


def relaxed_row(s, t_split, cal) -> Row:
    cal_s = s.slice_time(-np.inf, t_split)
    t_f, c_f = frames_from_angle(cal_s.distal["t_s"], cal_s.distal["c_deg"], cal.fps_frames)
    tr = cal.transition
    nc = int((cal.model_choice or {}).get("n_ctrl") or 14)
    sign = int(np.sign(cal.f(np.array([cal.q_range[1]]))[0] - cal.f(np.array([cal.q_range[0]]))[0])) or None
    rf = R.fit_on_calibration(cal_s.encoder["t_s"], cal_s.encoder["q"], cal.B_model, tr, t_f - cal.t_delay_s,
                              c_f, nc, sign)
    q0, q1 = cal.q_range
    tab = build_table(cal.B_model, rf.f, q0, q1, cal.actuator_unit, "remain", transition=tr,
                      relax=None if rf.relax.is_identity else rf.relax)
    ctl = build_table(cal.B_model, rf.f_without, q0, q1, cal.actuator_unit, "remain", transition=tr)
    return (Row("ours+relax", True, tab.predict, {**rf.to_json(), "layout": 4 if not rf.relax.is_identity else 2}),
            Row("ours_refit", True, ctl.predict, {}))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--catheter", default=None)
    ap.add_argument("--splits", default="0.5,0.75")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    d = catheter_dir(a.catheter, HERE.parent.parent / "shared" / "data" / "real" / "catheter")
    files = sorted(Path(d).glob("data_2_*.txt"))
    out = {}
    for sp in [float(x) for x in a.splits.split(",")]:
        print(f"\nsplit {sp}: test RMSE [deg] (fixed point for ours, ours+relax)\n")
        print("| file | ours | ours, f refitted without relaxation (control) | ours+relax | kappa | lambda [mm] | "
              "cal RMSE without -> with | gpi | onset_lsq | const_play |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for fn in files:
            s = import_catheter(fn)
            ts = split_time(s.encoder["t_s"], sp)
            rows = fit_rows(s, ts, source=str(fn))
            # the chain's calibration (fit_rows keeps it on no row): recompute as fit_rows did
            from playscope.fit.calibration import calibrate
            cal = calibrate(s.slice_time(-np.inf, ts), f_method="lsq", source=str(fn), model_kind="auto")
            rows["ours+relax"], rows["ours_refit"] = relaxed_row(s, ts, cal)
            td = float(s.t_delay_s) if s.t_delay_s is not None else float(rows["onset_lsq"].params["t_delay_s"])
            rm, _, _, _, _ = score_rows(rows, s, ts, td)
            p = rows["ours+relax"].params
            out.setdefault(str(sp), {})[fn.stem] = {"rmse_deg": rm, "relax": p}
            print(f"| {fn.stem} | {rm['ours']:.3f} | {rm['ours_refit']:.3f} | {rm['ours+relax']:.3f} | {p['kappa']:.3f} | {p['lambda']:.3g} | "
                  f"{p['rmse_without_deg']:.3f} -> {p['rmse_deg']:.3f} | {rm['gpi']:.3f} | {rm['onset_lsq']:.3f} | "
                  f"{rm['const_play']:.3f} |", flush=True)
        r = out[str(sp)]
        g = np.exp(np.mean([np.log(v["rmse_deg"]["ours+relax"] / v["rmse_deg"]["ours"]) for v in r.values()]))
        g2 = np.exp(np.mean([np.log(v["rmse_deg"]["ours+relax"] / v["rmse_deg"]["ours_refit"]) for v in r.values()]))
        print(f"\ngeometric mean at split {sp}: (ours+relax) / ours {g:.3f}; (ours+relax) / control {g2:.3f}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
