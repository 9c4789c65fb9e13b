#!/usr/bin/env python3
"""Does the angle lag the actuator? A diagnosis on the catheter's development files.

The chain takes an angle sensor on the encoder's clock as having no delay (`calibrate`: t_delay 0,
"angle sensor on the encoder clock"). A tip whose angle follows the tendon with a lag breaks the
rate-independent model in a rate-dependent way: eq. 1's onset comes late by the lag, so B reads
wider on faster records, and the loops of a fast half of a record differ from those of a slow one.

Per file and split, for each trial lag tau (s): the protocol of playscope.evaluate.insitu_split with
the session's delay set to tau (every row, the peers too, fitted and judged on the frames at their
acquisition time t - tau: the same state handling), and beside it ours' own cross-validation on the
calibration part (the chosen family's CV RMSE, deg), the only figure a rule choosing tau could read.
Printed: ours' CV on the calibration part, ours judged, the best peer row judged and its name.

Development files only. A diagnosis, not a rule: no setting of the product is read from it.

Usage: .venv/bin/python bench/angle_lag.py [--files data_1_1,data_1_2] [--taus 0,0.04,0.08,0.12,0.16]
       [--splits 0.5,0.75]     (~3 s per file, split and tau)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from playscope.evaluate.insitu_split import evaluate_insitu
from playscope.io.importer import import_catheter

ROOT = Path(__file__).resolve().parent.parent
REAL = Path(os.environ.get("PLAYSCOPE_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))


def one(s, path: Path, split: float, tau: float) -> tuple[float, float, float, str]:
    """For the session s (read from path; its t_delay_s is set to tau, s, and left so) at the split
    fraction: (ours' CV on the calibration part, ours judged, the lowest other row judged, that
    row's name), RMSE in deg. Errors: InputError from evaluate_insitu (a part it cannot calibrate)."""
    s.t_delay_s = tau
    d = evaluate_insitu(s, split, source=str(path))
    rows = d["rows"]
    p = rows["ours"]["params"]
    cv = next(r["cv_rmse_deg"] for r in p["family_cv"] if r["family"] == p["family"])
    peer = min((r["rmse_deg"], k) for k, r in rows.items() if k != "ours" and r["rmse_deg"] is not None)
    return cv, rows["ours"]["rmse_deg"], peer[0], peer[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", default="data_1_1,data_1_2,data_2_1", help="catheter development files (stems)")
    ap.add_argument("--taus", default="0,0.04,0.08,0.12,0.16", help="trial lags, s")
    ap.add_argument("--splits", default="0.5,0.75", help="split fractions")
    ap.add_argument("--catheter", default=str(REAL / "catheter"), help="folder of the catheter files (read in place)")
    a = ap.parse_args(argv)
    taus = [float(x) for x in a.taus.split(",")]
    t0 = time.time()
    print("| file | split | tau (s) | ours' CV, calibration part | ours judged | best peer judged |")
    print("|---|---|---|---|---|---|")
    for stem in a.files.split(","):
        path = Path(a.catheter) / f"{stem}.txt"
        if not path.exists():
            print(f"{path}: not found (set --catheter or PLAYSCOPE_REAL_DATA)", file=sys.stderr)
            return 2
        s = import_catheter(path)  # read once: evaluate_insitu reads the session, never changes it
        for split in (float(x) for x in a.splits.split(",")):
            for tau in taus:
                cv, ours, peer, name = one(s, path, split, tau)
                print(f"| {stem} | {split:g} | {tau:.2f} | {cv:.3f} | {ours:.3f} | {peer:.3f} ({name}) |", flush=True)
    print(f"\n({time.time() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
