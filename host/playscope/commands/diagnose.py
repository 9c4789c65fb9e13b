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
    from ..diagnose.run import clean, diagnose_data
    from .common import dump_json
    from ..io.importer import load_recording
    from ..diagnose.fitmodel import from_session

    if args.selftest:
        from ..diagnose import selftest
        nulls = selftest.REPORTED_NULLS if args.full else 2
        sc = selftest.run("both" if args.full else "strong", nulls, True, workers=args.workers,
                          log=lambda s: print(s, file=sys.stderr, flush=True))
        print(selftest.format_report(sc))
        dump_json(args.json, {"selftest": sc})
        return 0
    from .common import load_session_noted  # prints what loading repaired

    items = [(str(s), lambda s=s: load_session_noted(s)) for s in args.sessions]
    if args.catheter:
        from ..io.importer import import_catheter
        items += [(Path(f).stem, lambda f=f: import_catheter(f)) for f in args.catheter]
    if not items:
        print("playscope diagnose: give session folders, --catheter files, or --selftest", file=sys.stderr)
        return 2
    if not 0.2 <= args.split <= 0.9:
        print(f"playscope diagnose: --split {args.split} outside [0.2, 0.9]", file=sys.stderr)
        return 2
    test_data = None
    if args.test or args.test_catheter:
        if len(items) != 1:
            print("playscope diagnose: --test takes exactly one calibration record", file=sys.stderr)
            return 2
        if args.test:
            test_data = from_session(load_recording(args.test))
        else:
            from ..io.importer import import_catheter
            test_data = from_session(import_catheter(args.test_catheter))
    out, figs_all = {}, []
    for name, load in items:
        session = load()
        data = from_session(session)
        res = diagnose_data(data, args.split, session=session, test_data=test_data)
        data = res.pop("_data")
        r, t = res["final"], res["test"]
        where = "separate test record" if t["separate_record"] else "test part"
        print(f"{name}: noise floor {res['noise_floor_deg']:.3f} deg ({res['noise_method']}); split {res['split']['method']}; "
              f"validation RMSE {res['base']['rmse_heldout_deg']:.3f} -> {r['rmse_heldout_deg']:.3f} deg; "
              f"{where} {t['rmse_base_deg']:.3f} -> {t['rmse_final_deg']:.3f} deg; verdict {res['verdict']}")
        if res.get("hint"):
            print(f"  closest library effect (a hint, not a verdict): {res['hint']['effect']} -- {res['hint']['why']}")
        for n in res["record_notes"]:
            print(f"  warning: {n}")
        for k in res["kept"]:
            ps = ", ".join(f"{n.split('.', 1)[1]}={v[0]:.3g}±{v[1]:.2g}" for n, v in k["params"].items())
            ind = f"; cannot tell apart from {', '.join(k['indistinguishable_from'])}" if k["indistinguishable_from"] else ""
            ab = "".join(f"; {n} at its {b} bound" for n, b in k.get("at_bounds", {}).items())
            print(f"  + {k['effect']} ({ps}): {k['rmse_before_deg']:.3f} -> {k['rmse_after_deg']:.3f} deg, "
                  f"{100 * k['share_of_excess_removed']:.0f} % of the excess over the noise floor{ind}{ab}")
        for g in res.get("geometry", {}).get("screen", []):
            if g["kept"]:
                print(f"  + {g['effect']} ({g['param']}={g['value']:.3g}): path residual "
                      f"{res['geometry']['base_px']['heldout']:.3f} -> {g['heldout_px']:.3f} px (held out)")
        if args.html:
            from ..diagnose.diagnosis_report import figures
            figs_all += [(f"{name}: {t}", img) for t, img in figures(data, res, res["atlas_before"], res["atlas_after"])]
        res.pop("_models", None)
        out[name] = clean(res)
    dump_json(args.json, {"sessions": out})
    if args.html:
        from ..base.atomic import write_text_atomic
        from ..diagnose.diagnosis_report import html_page
        write_text_atomic(args.html, html_page("playscope diagnose", out, figs_all))
    return 0
