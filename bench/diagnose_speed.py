#!/usr/bin/env python3
"""Wall time of one diagnosis (`playscope diagnose`'s work: record checks, split, attribution,
atlas) on a 275-s record of the withheld-effect generator, repeated; prints a table with the
median and the worst run beside it, and the C kernels' state.

The record: a perturbed plant of the blind generator (host/playscope/sim/withheld) with a
quasi-static stick-slip (the first stick-slip case of development seed 1000, strong), 275 s of the
paper's excitation, an angle sensor at the generator's rate. Target: median <= 20 s on 2 cores.
Timings on a machine shared with other jobs are noisy: the load average is printed with them.

Usage: .venv/bin/python bench/diagnose_speed.py [--runs 5] [--duration 275] [--case null|stick_slip]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--duration", type=float, default=275.0, help="record length, s (default 275)")
    ap.add_argument("--case", choices=("stick_slip", "null"), default="stick_slip")
    a = ap.parse_args(argv)
    from playscope.diagnose import selftest
    try:
        from playscope.diagnose import kernels
        native = "on" if kernels.available() else "OFF (Python references)"
    except ImportError:  # a checkout from before the C kernels (to time it the same way)
        native = "absent (this checkout predates them)"
    from playscope.diagnose.fitmodel import from_session
    from playscope.diagnose.run import diagnose_data

    if a.case == "null":
        case = next(c for c in selftest.cases("strong", 1, False, seed=1000, effects=()) if c["effect"] is None)
    else:
        case = selftest.cases("strong", 0, False, seed=1000, effects=("stick_slip",))[0]
    data = from_session(selftest.make_session(case, a.duration))
    print(f"record: {a.case} ({case.get('variant') or '-'}), {a.duration:.0f} s, {data.t_m.size} rows; "
          f"C kernels {native}; {os.cpu_count()} cpus")
    times, verdicts = [], set()
    print(f"{'run':>4s} {'seconds':>8s} {'load 1 min':>10s}  verdict")
    for i in range(a.runs):
        t0 = time.perf_counter()
        res = diagnose_data(data)
        dt = time.perf_counter() - t0
        times.append(dt)
        verdicts.add(res["verdict"])
        print(f"{i + 1:>4d} {dt:>8.1f} {os.getloadavg()[0]:>10.2f}  {res['verdict']}", flush=True)
    print(f"median {statistics.median(times):.1f} s   worst {max(times):.1f} s   best {min(times):.1f} s   "
          f"(target: median <= 20 s)   verdicts {sorted(verdicts)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
