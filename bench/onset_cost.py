"""Where the onset stage's time goes: on the 3-minute bench session (bench/bench_session.py, the one
bench/bench_host.py times `calibrate` on), the record model's evaluations
(`onset_model.RecordModel.evaluate`) and Jacobians (`RecordModel.jacobian`) counted per step of the
search (`onset_search`), with each step's wall time.

Why counts: `calibrate`'s time on that session is mostly the onset stage's model evaluations, and
their number is set by the search alone (the same on any machine and under any load), where the
wall time is not. The steps are the search's own functions; each row's counts include the steps
nested in it (a step is named by its path, e.g. `_search/_fit_distinct`), and "the rest of
`_search`" is what `_search` spends outside its nested steps (the chains that choose B's size and
where it is read, and the full fit after each term enters, `fit_model`). The seconds include the
counters' own overhead (a clock read per counted call). The fits run in this one process (base.forkmap's second core turned off, whose results
are the same bit for bit, docs/host.md "Speed"), so the wall times add up to the stage's time on one
core; they depend on the machine's load, the counts do not. A second table splits the same counts
by the terms of the model evaluated (the plain model, each term's trial models), with the time spent
inside those calls.

Usage: .venv/bin/python bench/onset_cost.py   (about a minute; prints two Markdown tables)
"""

from __future__ import annotations

import functools
import time

from bench_session import loaded_session

from playscope.base.native import core
from playscope.fit import onset_model, onset_search
from playscope.fit.calibration import calibrate

STEPS = ("fit_record", "_coarse_starts", "_search", "_start", "_fitted_start", "_ring_scan", "_ring_profiled_starts",
         "_slide_starts", "_fit_distinct", "_resize", "_trade_profile")  # onset_search's steps, as named there
COUNTED = ("evaluate", "jacobian")  # RecordModel's methods counted


def instrument() -> tuple[dict, dict, dict]:
    """Patch the search for counting: fork_map serial, COUNTED wrapped with counters, each of STEPS
    wrapped to add its calls, counts and wall time under its path of nested steps. Returns (the
    running counts {method: n}, the table {path: [calls, evaluations, Jacobians, seconds]}, and
    {the model's terms: [evaluations, Jacobians, seconds in them]})."""
    count = dict.fromkeys(COUNTED, 0)
    table: dict[str, list] = {}
    stack: list[str] = []
    from playscope.base import forkmap

    forkmap.can_fork = lambda: False  # every map in this process, in turn (no lockstep child either)
    by_terms: dict[str, list] = {}
    for k, name in enumerate(COUNTED):
        def counted(self, *a, _f=getattr(onset_model.RecordModel, name), _n=name, _k=k):
            count[_n] += 1
            row = by_terms.setdefault(" + ".join(self.terms.names()) or "(plain)", [0, 0, 0.0])
            t0 = time.perf_counter()
            try:
                return _f(self, *a)
            finally:
                row[_k] += 1
                row[2] += time.perf_counter() - t0
        setattr(onset_model.RecordModel, name, counted)
    for name in STEPS:
        f = getattr(onset_search, name)

        @functools.wraps(f)
        def step(*a, _f=f, _n=name, **kw):
            before, t0 = dict(count), time.perf_counter()
            stack.append(_n)
            row = table.setdefault("/".join(stack), [0, 0, 0, 0.0])  # rows in the order the steps first run
            try:
                return _f(*a, **kw)
            finally:
                stack.pop()
                row[0] += 1
                row[1] += count["evaluate"] - before["evaluate"]
                row[2] += count["jacobian"] - before["jacobian"]
                row[3] += time.perf_counter() - t0
        setattr(onset_search, name, step)
    return count, table, by_terms


def main() -> None:
    core()
    s = loaded_session()
    count, table, by_terms = instrument()
    t0 = time.perf_counter()
    calibrate(s)
    total = time.perf_counter() - t0
    search = table.get("fit_record/_search")
    print("| step of the onset search (onset_search) | calls | evaluations | Jacobians | wall s (this run, one core) |")
    print("|---|---|---|---|---|")
    for path, (n, ev, jac, sec) in table.items():
        print(f"| `{path}` | {n} | {ev:,} | {jac:,} | {sec:.2f} |")
    if search:
        nested = [r for p, r in table.items() if p.startswith("fit_record/_search/") and p.count("/") == 2]
        rest = [search[k] - sum(r[k] for r in nested) for k in (1, 2, 3)]
        print(f"| the rest of `_search` (B's size chains; the full fit after a term enters) | | {rest[0]:,} | {rest[1]:,} "
              f"| {rest[2]:.2f} |")
    stage = table.get("fit_record", [0, 0, 0, 0.0])
    print(f"| `calibrate` outside the onset stage | | {count['evaluate'] - stage[1]:,} | {count['jacobian'] - stage[2]:,} "
          f"| {total - stage[3]:.2f} |")
    print(f"| all of `calibrate` | 1 | {count['evaluate']:,} | {count['jacobian']:,} | {total:.2f} |")
    print("\n| the model's terms (`RecordModel.terms`) | evaluations | Jacobians | wall s in them |\n|---|---|---|---|")
    for terms, (ev, jac, sec) in sorted(by_terms.items(), key=lambda kv: -kv[1][2]):
        print(f"| {terms} | {ev:,} | {jac:,} | {sec:.2f} |")


if __name__ == "__main__":
    main()
