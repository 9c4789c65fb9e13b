#!/usr/bin/env python3
"""Blind self-test of `playscope diagnose` at full size, then the real catheter recordings.

Part 1: simulated sessions (STRAS preset, parameters perturbed), one library effect at two
strengths each, 4 nulls, 2 out-of-library cases; identity hidden. Prints the confusion matrix,
top-1 accuracy (target >= 90 %), false discoveries on nulls (<= 10 %), recovered vs true shrink.
Part 2: the catheter recordings in ../shared/data/real/catheter (read in place, never copied;
skipped when absent): in situ (fit on the first half, judge on the second) with the effects the
diagnosis keeps, and across files (fit on data_2_1 with those effects, judge on the others).

Usage: .venv/bin/python bench/diagnose_selftest.py [--quick] [--workers 2] [--json out.json]
       (~10 min at full size on 2 cores; --real-only for part 2, ~2 min)
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

# One BLAS thread per process (set before numpy loads): the fits are small and 2 workers on
# 2 cores with threaded BLAS ran an order of magnitude slower.
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

from playscope.diagnose import selftest
from playscope.diagnose.realdata import CATHETER_DIR, catheter_table, format_catheter


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="one strength, 2 nulls, 1 out-of-library case")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--real-only", action="store_true")
    ap.add_argument("--json", help="write all results as JSON")
    a = ap.parse_args(argv)
    out = {}
    if not a.real_only:
        sc = selftest.run(*((1, 2, 1) if a.quick else (2, 4, 2)), workers=a.workers, log=lambda s: print(s, flush=True))
        print(selftest.format_report(sc))
        out["selftest"] = sc
    files = sorted(Path(CATHETER_DIR).glob("data_2_*.txt"))
    if files:
        tab = catheter_table(files, log=lambda s: print(s, flush=True))
        print(format_catheter(tab))
        out["catheter"] = tab
    else:
        print(f"catheter recordings not found in {CATHETER_DIR}: part 2 skipped")
    if a.json:
        from playscope.commands.common import dump_json
        dump_json(a.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
