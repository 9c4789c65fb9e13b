#!/usr/bin/env python3
"""B(q) and t_delay of `playscope calibrate` on fast-swing sessions from bench/swing_render.py.

One row per rendering of the chosen group (bench/swing_cases.py: "development", on which the
rules are settled, or "set-aside", run once and spent; "fresh", "third", ... "eighteenth", further set-aside groups, each run once; swing_cases.GROUPS), then one row per category with the
worst rendering beside the mean. Figures: B mean absolute error over the sampled q range in %
of the mean true B; t_delay used and its error in frame periods (acceptance: within 1/8); the
delay the record gives and its interval; refusals count as failures.

Usage: PYTHONPATH=host .venv/bin/python bench/swing_bench.py [--group development|set-aside|fresh|third|...|eighteenth]
       [--only NAME ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import b_score  # noqa: E402
import swing_cases  # noqa: E402
import swing_render as SR  # noqa: E402


def run(r: SR.Rendering) -> dict:
    """Render, write, calibrate (b_score.score); errors against the truth."""
    sc = b_score.score(lambda d: SR.write(r, d), r.B)
    if "refused" in sc:
        return sc
    cal = sc["cal"]
    ref = cal.onset_refine or {}
    td = ref.get("t_delay", {})
    return {"err_pct": sc["err_pct"], "t_delay": cal.t_delay_s, "td_err_frames": (cal.t_delay_s - r.delay_s) * r.fps,
            "record_s": td.get("record_s"), "record_ci_s": td.get("record_ci95_s"),
            "samples": cal.n_b_samples, "reversals": cal.reversals, "warnings": len(cal.warnings),
            "wall_s": sc["wall_s"], "reasons": (cal.doc.get("onset") or {}).get("reasons")}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--group", choices=tuple(swing_cases.GROUPS), default="development")
    ap.add_argument("--only", nargs="*", help="rendering names to run (default: all of the group)")
    a = ap.parse_args(argv)
    cases = swing_cases.GROUPS[a.group]
    if a.only:
        cases = [c for c in cases if c[2].name in a.only]
    print(f"group {a.group}: {len(cases)} renderings (bench/swing_render.py)")
    print("| category | rendering | shape, fps, noise px | true / cfg delay (s) | B error % | limit | "
          "t_delay used (s), error (frames) | record delay (s) [95 %] | samples / reversals | reasons | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    by_cat: dict[str, list] = {}
    fails = 0
    for cat, limit, r in cases:
        res = run(r)
        cfg = "none" if r.delay_cfg_s is None else f"{r.delay_cfg_s:g}"
        head = f"| {cat} | {r.name} | {r.shape}, {r.fps:g}, {r.noise_px:g} | {r.delay_s:g} / {cfg} |"
        if "refused" in res:
            print(f"{head} REFUSED | <= {limit:g} | | | | {res['refused'][:90]} | |")
            by_cat.setdefault(cat, []).append((np.inf, np.inf))
            fails += 1
            continue
        ok = res["err_pct"] <= limit and abs(res["td_err_frames"]) <= 0.125
        fails += not ok
        ci = res["record_ci_s"]
        ci_s = f" [{ci[0]:.4f}, {ci[1]:.4f}]" if ci else ""
        rec = f"{res['record_s']:.4f}{ci_s}" if res["record_s"] is not None else ""
        print(f"{head} {res['err_pct']:.2f} | <= {limit:g} | {res['t_delay']:.4f}, {res['td_err_frames']:+.3f} | "
              f"{rec} | {res['samples']} / {res['reversals']} | {res['reasons']} | {res['wall_s']:.0f} |", flush=True)
        by_cat.setdefault(cat, []).append((res["err_pct"], abs(res["td_err_frames"])))
    print("\n| category | renderings | B error % mean (worst) | |t_delay error| frames mean (worst) |")
    print("|---|---|---|---|")
    for cat, v in by_cat.items():
        e = np.array(v)
        print(f"| {cat} | {len(v)} | {np.mean(e[:, 0]):.2f} ({np.max(e[:, 0]):.2f}) | "
              f"{np.mean(e[:, 1]):.3f} ({np.max(e[:, 1]):.3f}) |")
    print(f"renderings failing (B over limit, |t_delay error| > 1/8 frame, or refused): {fails} of {len(cases)}")
    return 0 if fails == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
