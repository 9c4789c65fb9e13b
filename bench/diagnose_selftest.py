#!/usr/bin/env python3
"""Blind self-test of `playscope diagnose`, then the real catheter recordings (three-way split).

Part 1: records from the withheld-effect generator (host/playscope/sim/withheld: own plant, at
least two physically different implementations of every library effect, each at two strengths),
20 nulls (the first 4 drawn where the case list always drew them; selftest.score says why 20),
2 out-of-library effects (tip vibration, ratcheting backlash); identity hidden. Every
planted case counts. Prints the per-effect table with "identifiable in situ?" (the generator's own
effect-free oracle) and "recoverable in situ?" (its oracle that knows the planted effect's form and
fits the rest in situ, sim/withheld/recover.py), the confusion matrix, top-1, false discoveries,
and the recovered shrink against the generator's truth on the test part, over the identifiable
and over the recoverable cases.
Part 2: the catheter recordings (read in place, never copied; skipped when absent): fit on the
first half, select effects on the next quarter, report on the last quarter (test), per file.

Catheter folder: --catheter DIR, else $PLAYSCOPE_CATHETER_DIR, else $PLAYSCOPE_REAL_DATA/catheter,
else ../shared/data/real/catheter next to the repository.

Usage: .venv/bin/python bench/diagnose_selftest.py [--quick] [--workers 2] [--json out.json]
       [--real-only] [--catheter DIR] [--effects a,b] [--nulls N] [--no-ool] [--seed S]
       [--selftest-only] [--no-recover] [--second | --second-only] [--second-nulls N]
       [--second-seed S]
       (a subset while developing, e.g. --effects viscous_hysteresis,cable_elongation --nulls 0
       --no-ool --seed 1000 --selftest-only; the reported figures are the REPORTED_SEED_* seeds with every case)
       (full, reported seeds, on 2 cores shared with other jobs (load 4-7): second generator 41 cases
       in 450 s (seeds 47211 / 82900: 307 s at load 2-3 / 313 s at load 4-6); first generator 58
       cases in 1987 s with the recoverability oracle (seed 47552: 1470 s at load 6-7; 723 s
       without it, --no-recover, two rounds before); over the 10-min CI budget together, so this is a
       nightly-style bench that prints its wall time, not a CI job; --quick: strong strength only,
       2 nulls; --real-only ~2 min)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# One BLAS thread per process (set before numpy loads): the fits are small and 2 workers on
# 2 cores with threaded BLAS ran an order of magnitude slower.
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

from playscope.diagnose import selftest
from playscope.diagnose.realdata import catheter_dir, catheter_table, format_catheter

ROOT = Path(__file__).resolve().parent.parent

# The reported seeds, one per generator. Fixed (and committed) before any rule they judge was
# changed in this round of changes: each reported seed is run once, at full size, at the end of the
# round; rules are never settled on it. Seeds already run once are spent and are development seeds
# now: seed 0 of both generators, 1000-4000 of the first, and the previous reported seeds 7919
# (first) and 6151, 40093, 47211 (second; 47211 was the first reported seed of its asymmetric play
# that the base model cannot absorb, turn_set_slack). 47552 and 82900 were drawn before the
# noise floor's ringing rule was written (attribute.still_periods_ring).
REPORTED_SEED_FIRST = 47552
REPORTED_SEED_SECOND = 82900
SPENT_SEEDS_FIRST = (0, 1000, 2000, 3000, 4000, 7919, 52711)
SPENT_SEEDS_SECOND = (0, 6151, 40093, 47211)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="strong strength only, 2 nulls (22 cases)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--real-only", action="store_true")
    ap.add_argument("--selftest-only", action="store_true", help="skip the catheter part")
    ap.add_argument("--catheter", help="folder of data_2_*.txt (see module doc for the default)")
    ap.add_argument("--json", help="write all results as JSON")
    ap.add_argument("--effects", help="comma-separated library effects to plant, in either generator (a subset "
                    "while developing; the reported figure is the full list)")
    ap.add_argument("--nulls", type=int, help=f"number of null cases (default {selftest.REPORTED_NULLS}, --quick 2)")
    ap.add_argument("--no-ool", action="store_true", help="leave out the out-of-library cases")
    ap.add_argument("--seed", type=int, default=REPORTED_SEED_FIRST,
                    help=f"case seed of the first generator (default: the reported {REPORTED_SEED_FIRST}; develop on others)")
    ap.add_argument("--second-seed", type=int, default=REPORTED_SEED_SECOND,
                    help=f"case seed of the second generator (default: the reported {REPORTED_SEED_SECOND}; develop on others)")
    ap.add_argument("--second", action="store_true",
                    help="also run the self-test on the second, independent generator (sim/withheld_b), reported apart")
    ap.add_argument("--second-only", action="store_true", help="only the second generator's self-test")
    ap.add_argument("--second-nulls", type=int, default=selftest.REPORTED_NULLS,
                    help=f"nulls of the second generator (default {selftest.REPORTED_NULLS})")
    ap.add_argument("--no-recover", action="store_true",
                    help="skip the recoverability oracle (no 'recoverable' column; about a third faster)")
    a = ap.parse_args(argv)
    out = {}
    t_start = time.monotonic()
    effects = selftest.LIB_EFFECTS
    if a.effects:
        effects = tuple(e.strip() for e in a.effects.split(",") if e.strip())
        bad = [e for e in effects if e not in selftest.LIB_EFFECTS]
        if bad:
            ap.error(f"unknown effect(s) {', '.join(bad)}; choose from {', '.join(selftest.LIB_EFFECTS)}")
    if a.second or a.second_only:
        sc2 = selftest.run_second(a.second_seed, a.second_nulls, not a.no_ool, workers=a.workers,
                                  effects=effects if a.effects else None,
                                  strengths="strong" if a.quick else "both", log=lambda s: print(s, flush=True))
        print(f"second generator (sim/withheld_b), seed {a.second_seed}, wall time {time.monotonic() - t_start:.0f} s:")
        print(selftest.format_report(sc2))
        out["selftest_second"] = sc2
        if a.second_only:
            a.real_only = True
            a.selftest_only = True
    t_second = time.monotonic() - t_start
    if not a.real_only:
        nulls = a.nulls if a.nulls is not None else (2 if a.quick else selftest.REPORTED_NULLS)
        sc = selftest.run("strong" if a.quick else "both", nulls, not a.no_ool, seed=a.seed, workers=a.workers,
                          effects=effects, log=lambda s: print(s, flush=True), recover=not a.no_recover)
        print(f"first generator (sim/withheld), seed {a.seed}, wall time {time.monotonic() - t_start - t_second:.0f} s:")
        print(selftest.format_report(sc))
        out["selftest"] = sc
    folder = catheter_dir(a.catheter, default=ROOT.parent / "shared" / "data" / "real" / "catheter")
    files = sorted(folder.glob("data_2_*.txt")) if folder and not a.selftest_only else []
    if files:
        tab = catheter_table(files, log=lambda s: print(s, flush=True))
        print(format_catheter(tab))
        out["catheter"] = tab
    elif not a.selftest_only:
        print(f"catheter recordings not found ({folder}): part 2 skipped")
    print(f"total wall time {time.monotonic() - t_start:.0f} s")
    if a.json:
        from playscope.commands.common import dump_json
        dump_json(a.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
