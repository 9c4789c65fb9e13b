"""`playscope diagnose`: sim-to-real gap diagnosis of sessions, and the blind self-test.

Registered by playscope.cli through add_parser(subparsers).
"""

from __future__ import annotations

import sys
from pathlib import Path

from .common import add_command

JSON_KEYS = ("sessions.<name>: noise_floor_deg, noise_method, base{rmse_fit_deg, rmse_heldout_deg, bic}, "
             "screen[{effect, rmse_heldout_deg, delta_rmse_deg, delta_bic, promising, params}], "
             "kept[{effect, params{name: [value, sd]}, rmse_before_deg, rmse_after_deg, share_of_excess_removed, "
             "indistinguishable_from}], final{effects, rmse_heldout_deg, excess_after_deg, share_of_excess_removed}, "
             "verdict, hint{effect, why} (unexplained verdicts), stick_slip_signature, atlas_before, atlas_after, geometry{base_px, screen, kept} (image sessions); selftest: confusion, "
             "top1, false_discovery_nulls, n_false_discoveries, false_discovery_ci95, n_false_discoveries_first, cases")


DESCRIPTION = """\
Fit the paper's model (play of width B(q) then f_remain) on the first part of each session,
judge it on the rest, localise the residuals and attribute the gap to effects of the simulator's
library (docs/diagnosis.md).
"""


def add_parser(sub) -> None:
    from . import argtypes  # range-checked values

    p = add_command(sub, "diagnose", "sim-to-real gap: held-out gap, localisation, attribution to library effects", DESCRIPTION,
                    examples=["playscope diagnose sessions/d21 --html diag.html --json diag.json",
                              "playscope diagnose --catheter ../shared/data/real/catheter/data_2_1.txt --split 0.5",
                              "playscope diagnose --selftest --workers 2"])
    p.add_argument("sessions", nargs="*", help="session folders (playscope-session/1)")
    p.add_argument("--catheter", metavar="FILE", nargs="+", default=[],
                   help="catheter CSV recordings (data_2_*.txt) read in place through playscope.io.importer")
    p.add_argument("--test", metavar="SESSION", help="separate test record (the paper's test motion): the calibration "
                   "record is split fit / validation, this record only judges (one calibration session)")
    p.add_argument("--test-catheter", metavar="FILE", help="as --test, a catheter CSV")
    p.add_argument("--split", type=argtypes.float_range(0.0, 1.0, lo_open=True, hi_open=True), default=0.5, help="fraction of each record used to fit (default 0.5); the "
                   "rest is validation then test in equal parts, or validation only with --test")
    p.add_argument("--html", metavar="PATH", help="write an HTML page with the plots")
    p.add_argument("--json", metavar="PATH", help=f"write results as JSON. Keys: {JSON_KEYS}")
    p.add_argument("--selftest", action="store_true", help="run the blind self-test instead (simulated cases)")
    p.add_argument("--full", action="store_true", help="self-test at full size (2 strengths, 20 nulls, 2 out-of-library)")
    p.add_argument("--workers", type=argtypes.int_range(1, 64), default=2, help="self-test processes (default 2)")
    p.set_defaults(func=run)


def run(args) -> int:
    from .common import dump_json, warn

    if args.selftest:
        from ..diagnose import selftest
        nulls = selftest.REPORTED_NULLS if args.full else 2
        sc = selftest.run("both" if args.full else "strong", nulls, True, workers=args.workers,
                          log=lambda s: print(s, file=sys.stderr, flush=True))
        print(selftest.format_report(sc))
        dump_json(args.json, {"selftest": sc})
        return 0
    from ..pipeline import diagnose_records

    records = [(str(s), s, "session") for s in args.sessions]
    records += [(Path(f).stem, f, "catheter") for f in args.catheter or ()]
    if not records:
        print("playscope diagnose: give session folders, --catheter files, or --selftest", file=sys.stderr)
        return 2
    if not 0.2 <= args.split <= 0.9:
        print(f"playscope diagnose: --split {args.split} outside [0.2, 0.9]", file=sys.stderr)
        return 2
    test = None
    if args.test or args.test_catheter:
        if len(records) != 1:
            print("playscope diagnose: --test takes exactly one calibration record", file=sys.stderr)
            return 2
        test = (args.test, "session") if args.test else (args.test_catheter, "catheter")
    res = diagnose_records(records, args.split, test, args.html)
    warn(res.warnings)
    for name in res.records:
        for line in res.lines[name]:
            print(line)
    dump_json(args.json, res.to_json())
    return 0
