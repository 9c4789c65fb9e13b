#!/usr/bin/env python3
"""Does a planted asymmetric play leave a trace in the data? The base-model trace check.

For each planted case of the two withheld-effect generators' asymmetric plays (first generator:
edge_ratio, antagonist_load; second: its current form and the retired loaded_side_slack), and for
null records of both, the diagnosis' base model (play of width B(q) then f_remain, NO effect: no
selection, no attribution) is fitted on the record's fit part and judged on its test part
(selftest.base_trace), on the noisy record and on the generator's noise-free reading, with the
diagnosis' spline classes and with richer ones (about twice the knots). Printed per case: the
noise-only RMSE, and the excess (base RMSE minus noise-only) on the noisy record and the base RMSE
on the noise-free one, per class. The nulls give the base model's own misfit (its spread is what a
trace must clear).

A play whose edges each depend on q alone is the base model under a relabelling (z the edges'
mean, B their difference, f_remain re-parameterised): its trace is zero in principle and what is
left comes from the classes' limits, so it shrinks with the richer classes.

Usage: .venv/bin/python bench/diagnose_trace.py [--seed-first S] [--seed-second S] [--nulls N]
       [--duration 120] [--json out.json]
       (the case seeds come from the generators' case lists at those seeds: defaults are the spent
       reported seeds 52711 / 40093, so the rows are the reported records; ~4 min on 2 shared cores)
"""

from __future__ import annotations

import argparse
import os
import sys
import time

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np

from playscope.diagnose import selftest
from playscope.sim.withheld_b import generator as gen_b


def _cases(seed_first: int, seed_second: int, nulls: int) -> list[tuple[str, dict, object]]:
    """(generator, case, session maker) for the asymmetric cases and the first `nulls` nulls."""
    out = []
    for c in selftest.cases("both", nulls, False, seed_first, ("asymmetric_backlash",)):
        out.append(("first", c, lambda c, d: selftest.make_session(c, d)))
    cb = gen_b.cases(seed_second, ("asymmetric_backlash",), nulls, False)
    for c in cb:
        out.append(("second", c, lambda c, d: gen_b.session(c, d)))
        if c["effect"] is not None:   # the retired form on the same record seed
            old = {**c, "variant": "loaded_side_slack", "strength": gen_b.RETIRED["loaded_side_slack"][1][
                gen_b.LIBRARY["asymmetric_backlash"][1].index(c["strength"])]}
            if old["variant"] != c["variant"]:
                out.append(("second", old, lambda c, d: gen_b.session(c, d)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed-first", type=int, default=52711)
    ap.add_argument("--seed-second", type=int, default=40093)
    ap.add_argument("--nulls", type=int, default=4)
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    t0 = time.monotonic()
    rows = []
    cfg = (("diagnosis", 0.0), ("diagnosis", 10.0), ("rich", 10.0))
    head = " | ".join(f"{f'{c} classes, fit from {k:g} s':^27s}" for c, k in cfg)
    print(f"{'generator':<9s} {'case':<52s} {'noise':>6s} | {head}")
    print(f"{'':<9s} {'':<52s} {'only':>6s} | " + " | ".join(f"{'excess noisy':>13s} {'clean':>13s}" for _ in cfg))
    for g, c, make in _cases(a.seed_first, a.seed_second, a.nulls):
        r = selftest.base_trace(make(c, a.duration), cfg)
        what = f"{c['effect'] or 'null'}/{c['variant'] or '-'}@{c['strength']:g} (seed {c['seed']})"
        print(f"{g:<9s} {what:<52s} {r['noise_only_deg']:6.3f} | "
              + " | ".join(f"{f['excess_deg']:13.4f} {f['clean_deg']:13.4f}" for f in r["fits"]), flush=True)
        rows.append({"generator": g, "case": c, **r})
    for g in ("first", "second"):
        nl = [r for r in rows if r["generator"] == g and r["case"]["effect"] is None]
        for i, (cls, skip) in enumerate(cfg):
            if not nl:
                break
            ex = np.array([r["fits"][i]["excess_deg"] for r in nl])
            cl = np.array([r["fits"][i]["clean_deg"] for r in nl])
            print(f"{g} generator nulls ({len(nl)}), {cls} classes, fit from {skip:g} s: excess noisy mean "
                  f"{ex.mean():.4f} max {ex.max():.4f} sd {ex.std(ddof=1) if ex.size > 1 else float('nan'):.4f}; "
                  f"clean mean {cl.mean():.4f} max {cl.max():.4f}")
    print(f"wall time {time.monotonic() - t0:.0f} s")
    if a.json:
        from playscope.commands.common import dump_json
        dump_json(a.json, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
