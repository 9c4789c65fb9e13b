#!/usr/bin/env python3
"""The onset scoreboard: `playscope calibrate`'s B(q) and t_delay over many renderings
of several renderers written apart, judged as a failure rate with its exact 95 % interval
(Clopper-Pearson), never row by row.

Groups:
  fresh        bench/onset_cases.py FRESH_300: 100 renderings from each of marker_render,
               swing_render and render_c, drawn and committed before the record model's code.
               A failure: B error over its limit (5 % none / registration, 10 % wrong or absent
               delay / ringing), or, where the configured delay is right, |t_delay error| over
               1/8 frame, or a refusal. Run once (stop 47); development data since.
  setaside     bench/onset_cases.py SETASIDE_150: 50 more renderings from each renderer (new
               seeds), drawn and committed before the record model's second round of terms,
               judged as fresh. Run once (stop 54); development data since.
  lockbox      bench/onset_cases.py LOCKBOX_300: 100 more renderings from each renderer (new
               seeds), drawn and committed at stop 55 before any of its code, judged as fresh.
  lockbox_a    its every third row (100), the part stop 55 runs; the other 200 stay sealed.
  lockbox_b    every other row of those 200 (100), the part stop 56 runs.
  lockbox_c    the last 100 of LOCKBOX_300, the part stop 57 runs.
  lockbox4     bench/onset_cases.py LOCKBOX4_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at stop 57, sealed for a later stop's code.
  lockbox4_a   its every third row (100), the part stop 58 runs; the other 200 stay sealed.
  lockbox4_b   every third row of those 200 (67), the part stop 59 runs; 133 stay sealed.
  lockbox4_c   the other 133 of those 200, the part stop 60 runs on lockbox4_b's onset code.
  lockbox5     bench/onset_cases.py LOCKBOX5_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 60, sealed for a later code.
  lockbox5_a   its every fifth row (60), the part stop 61 runs; the other 240 stay sealed.
  lockbox5_b   every third row of those 240 (80), the part stop 62 runs; 160 stay sealed.
  lockbox5_c   every other row of those 160 (80), the part stop 65 runs; 80 stay sealed.
  lockbox5_d   the last 80, the part stop 66 runs.
  lockbox6     bench/onset_cases.py LOCKBOX6_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at stop 66, sealed for a later code (the issue's acceptance run).
  lockbox7     bench/onset_cases.py LOCKBOX7_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 68, sealed for a later code.
  lockbox8     bench/onset_cases.py LOCKBOX8_300: 100 more renderings from each renderer (new seeds),
               drawn and committed during stop 70, sealed for a later code.
  lockbox9     bench/onset_cases.py LOCKBOX9_300: 100 more renderings from each renderer (new seeds),
               drawn and committed during stop 71, sealed for a later code.
  lockbox10    bench/onset_cases.py LOCKBOX10_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 74, sealed for a later code.
  lockbox11    bench/onset_cases.py LOCKBOX11_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 75, sealed for 5ae768c's onset code.
  lockbox12    bench/onset_cases.py LOCKBOX12_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 76, sealed for 221fffb's onset code.
  lockbox13    bench/onset_cases.py LOCKBOX13_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 77, sealed for 1f06283's onset code.
  lockbox14    bench/onset_cases.py LOCKBOX14_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 78, run on 1f06283's onset code (as lockbox13).
  lockbox15    bench/onset_cases.py LOCKBOX15_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 79, run on c2cc458's onset code.
  lockbox16    bench/onset_cases.py LOCKBOX16_300: 100 more renderings from each renderer (new seeds),
               drawn and committed during stop 79 (after c2cc458's onset code), run on 835a9a4's.
  lockbox17    bench/onset_cases.py LOCKBOX17_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 80, run on 46c09cb's onset code.
  lockbox18    bench/onset_cases.py LOCKBOX18_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 81, run on ae31109's onset code.
  lockbox19    bench/onset_cases.py LOCKBOX19_300: 100 more renderings from each renderer (new seeds),
               drawn and committed during stop 82, run on 3cf5173's onset code (0 / 300).
  lockbox20    bench/onset_cases.py LOCKBOX20_300: 100 more renderings from each renderer (new seeds),
               drawn and committed during stop 83, run on a2fe723's calibration code (1 / 300).
  lockbox21    bench/onset_cases.py LOCKBOX21_300: 100 more renderings from each renderer (new seeds),
               drawn and committed at the start of stop 85, run on dcd538d's onset code (1 / 300).
  lockbox22    bench/onset_cases.py LOCKBOX22_300: 100 more renderings from each renderer (new seeds),
               drawn and committed during stop 86, sealed for an onset code after stop 86's.
  exposure     bench/onset_cases.py EXPOSURE_30: 15 renderings each of marker_render and swing_render
               with the exposure 0.25-1 frame period (the other groups' renderers expose 2-8 ms),
               judged as fresh (category "exposure", B <= 5 %).
  transition_dev
               bench/onset_cases.py TRANSITION_DEV_40: 20 renderings each of swing_render and render_c
               with a smooth transition after each reversal (a spread of play widths, 0.2-0.7), no camera
               effect, the delay configured right: category "transition", B against the centre width
               <= 10 %. Development data.
  transition_lockbox
               bench/onset_cases.py TRANSITION_LOCKBOX_100: 50 more of each (new seeds), drawn and
               committed with it, sealed for the onset code that models the transition; run once.
  development  every group of bench/swing_cases.py (208 renderings of swing_render, the rules of
               the old onset stage were settled on them): judged as bench/swing_bench.py did
               (B over its limit, |t_delay error| over 1/8 frame on every row, or a refusal).

B error: mean |B_fit - B_true| over the q range the B samples cover, in % of the mean true B
(bench/b_score.py). Each row is written as one JSON line to build/onset_scoreboard/<group>.jsonl
as it finishes (a rerun skips rows already there; --fresh-start removes them), then the tables:
per category and per renderer, failures / n, the rate and its interval, the median and 95th
percentile of the B error, the worst row.

Usage: PYTHONPATH=host:bench .venv/bin/python bench/onset_scoreboard.py --group GROUP (one of the groups above)
       [--jobs 2] [--only NAME ...] [--fresh-start] [--markdown FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
OUT = HERE.parent / "build" / "onset_scoreboard"


# The groups drawn in bench/onset_cases.py, judged alike.
FROM_CASES = {"fresh": lambda c: c.FRESH_300, "setaside": lambda c: c.SETASIDE_150,
              "lockbox": lambda c: c.LOCKBOX_300,
              "lockbox_a": lambda c: c.LOCKBOX_A, "lockbox_b": lambda c: c.LOCKBOX_B,
              "lockbox_c": lambda c: c.LOCKBOX_C, "lockbox4": lambda c: c.LOCKBOX4_300,
              "lockbox4_a": lambda c: c.LOCKBOX4_A, "lockbox4_b": lambda c: c.LOCKBOX4_B,
              "lockbox4_c": lambda c: c.LOCKBOX4_C, "lockbox5": lambda c: c.LOCKBOX5_300,
              "lockbox5_a": lambda c: c.LOCKBOX5_A, "lockbox5_b": lambda c: c.LOCKBOX5_B,
              "lockbox5_c": lambda c: c.LOCKBOX5_C, "lockbox5_d": lambda c: c.LOCKBOX5_D,
              "lockbox6": lambda c: c.LOCKBOX6_300,
              "lockbox7": lambda c: c.LOCKBOX7_300, "lockbox8": lambda c: c.LOCKBOX8_300, "lockbox9": lambda c: c.LOCKBOX9_300,
              "lockbox10": lambda c: c.LOCKBOX10_300, "lockbox11": lambda c: c.LOCKBOX11_300,
              "lockbox12": lambda c: c.LOCKBOX12_300, "lockbox13": lambda c: c.LOCKBOX13_300,
              "lockbox14": lambda c: c.LOCKBOX14_300, "lockbox15": lambda c: c.LOCKBOX15_300,
              "lockbox16": lambda c: c.LOCKBOX16_300, "lockbox17": lambda c: c.LOCKBOX17_300,
              "lockbox18": lambda c: c.LOCKBOX18_300, "lockbox19": lambda c: c.LOCKBOX19_300,
              "lockbox20": lambda c: c.LOCKBOX20_300,
              "lockbox21": lambda c: c.LOCKBOX21_300,
              "lockbox22": lambda c: c.LOCKBOX22_300,
              "lockbox23": lambda c: c.LOCKBOX23_300, "lockbox24": lambda c: c.LOCKBOX24_300,
              "exposure": lambda c: c.EXPOSURE_30, "transition_dev": lambda c: c.TRANSITION_DEV_40,
              "transition_lockbox": lambda c: c.TRANSITION_LOCKBOX_100}


def _rows(group: str) -> list:
    """(renderer, name, category, limit %, delay status, params or Rendering) for the group."""
    if group in FROM_CASES:
        import onset_cases

        return list(FROM_CASES[group](onset_cases))
    import swing_cases

    out = []
    for g, cases in swing_cases.GROUPS.items():
        for cat, limit, r in cases:
            status = "absent" if r.delay_cfg_s is None else ("right" if abs(r.delay_cfg_s - r.delay_s) < 1e-9 else "wrong")
            out.append(("swing", r.name, cat, limit, status, r))
    return out


def row_objects(group: str, row: tuple) -> tuple:
    """A row's renderer object and truth: (obj, write(obj, folder), true_B(q) callable (actuator
    units), true delay s, configured delay s or None)."""
    if group in FROM_CASES:
        import onset_cases

        return onset_cases.make(row)
    import swing_render

    kw = row[5]
    return kw, swing_render.write, kw.B, kw.delay_s, kw.delay_cfg_s


def true_mean_lag(renderer: str, obj, d_true: float) -> float:
    """The image's true mean lag behind the encoder, s: marker_render averages each frame over the
    exposure that ends at its capture instant (so its delay is to the exposure's end, the mean lag
    e / 2 longer); swing_render and render_c centre the exposure on it."""
    return d_true + (0.5 * obj.exposure if renderer == "marker" else 0.0)


def run_row(args) -> dict:
    """Render, write, calibrate one row; its figures (a JSON-ready dict)."""
    group, row = args
    import b_score

    renderer, name, cat, limit, status, kw = row
    obj, write, true_B, d_true, d_cfg = row_objects(group, row)
    fps = float(getattr(obj, "fps"))
    t0 = time.time()
    sc = b_score.score(lambda d: write(obj, d), true_B)
    out = {"name": name, "renderer": renderer, "category": cat, "limit_pct": limit, "delay_status": status,
           "fps": fps, "delay_true_s": d_true, "delay_cfg_s": d_cfg, "total_s": None}
    if "refused" in sc:
        out.update(refused=sc["refused"], fail=True)
    else:
        cal = sc["cal"]
        td_err = (cal.t_delay_s - d_true) * fps
        ref = cal.onset_refine or {}
        check_td = status == "right" if group in FROM_CASES else True
        fail = bool(sc["err_pct"] > limit or (check_td and abs(td_err) > 0.125))
        # The image's mean lag behind the encoder, against the renderer's (`true_mean_lag`). Not a
        # failure criterion (fixed before): with a right configured delay, t_delay is the configured
        # one wherever the record's mean lag allows it, so this column is what the record measured.
        lag_true = true_mean_lag(renderer, obj, d_true)
        lag = ref.get("image_mean_lag_s")
        out.update(lag_err_frames=None if lag is None else (lag - lag_true) * fps)
        out.update(err_pct=sc["err_pct"], t_delay_s=cal.t_delay_s, td_err_frames=td_err, td_checked=check_td,
                   samples=cal.n_b_samples, reversals=cal.reversals, calibrate_s=sc["wall_s"],
                   terms=(ref.get("terms") or {}).get("chosen"), fail=fail)
    out["total_s"] = time.time() - t0
    return out


def clopper_pearson(k: int, n: int, conf: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval for k failures in n (Clopper & Pearson 1934)."""
    from scipy.stats import beta

    a = 1.0 - conf
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def table(res: list[dict], key: str) -> list[str]:
    lines = [f"| {key} | failures / n | rate [exact 95 %] | B error % median | P95 | worst (row) |",
             "|---|---|---|---|---|---|"]
    groups: dict[str, list] = {}
    for r in res:
        groups.setdefault(r[key], []).append(r)
    groups["all"] = res
    for g, rs in groups.items():
        k, n = sum(r["fail"] for r in rs), len(rs)
        lo, hi = clopper_pearson(k, n)
        e = np.array([r.get("err_pct", np.inf) for r in rs])
        w = rs[int(np.argmax(e))]
        lines.append(f"| {g} | {k} / {n} | {100 * k / n:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] | "
                     f"{np.median(e):.2f} | {np.percentile(e, 95):.2f} | {np.max(e):.2f} ({w['name']}) |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--group", choices=(*FROM_CASES, "development"),
                    default="development")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--only", nargs="*", help="row names to run (default: all of the group)")
    ap.add_argument("--fresh-start", action="store_true", help="forget the rows already run")
    ap.add_argument("--tag", default="", help="suffix of the rows' file (a development run beside the recorded one)")
    ap.add_argument("--markdown", help="also write the tables and the failing rows to this file")
    a = ap.parse_args(argv)
    rows = _rows(a.group)
    if a.only:
        rows = [r for r in rows if r[1] in a.only]
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / (a.group + a.tag + ".jsonl")
    if a.fresh_start and path.exists():
        path.unlink()
    done = {}
    if path.exists():
        for line in path.read_text().splitlines():
            d = json.loads(line)
            done[d["name"]] = d
    todo = [r for r in rows if r[1] not in done]
    print(f"group {a.group}: {len(rows)} renderings, {len(todo)} to run, {a.jobs} jobs; rows to {path}", flush=True)
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # each row written as it finishes, not in the group's order: a run stopped part way keeps every
    # row that finished (the tables below are in the group's order whatever the file's)
    with ProcessPoolExecutor(a.jobs) as ex, open(path, "a") as f:
        futures = [ex.submit(run_row, (a.group, r)) for r in todo]
        for i, fut in enumerate(as_completed(futures)):
            d = fut.result()
            f.write(json.dumps(d) + "\n")
            f.flush()
            done[d["name"]] = d
            tag = "FAIL" if d["fail"] else "ok"
            fig = d.get("refused", "")[:80] if "refused" in d else \
                f"B {d['err_pct']:.2f} % (<= {d['limit_pct']:g}), t_delay {d['td_err_frames']:+.3f} frame, {d['terms']}"
            print(f"[{i + 1}/{len(todo)}] {tag:4s} {d['name']}: {fig}, {d['total_s']:.0f} s", flush=True)
    res = [done[r[1]] for r in rows if r[1] in done]
    out = [f"## Onset scoreboard, group {a.group}: {len(res)} renderings", ""]
    out += table(res, "category") + [""] + table(res, "renderer") + [""]
    fails = [r for r in res if r["fail"]]
    out.append(f"Failing rows ({len(fails)}):")
    for r in fails:
        fig = "refused: " + r["refused"][:120] if "refused" in r else \
            f"B {r['err_pct']:.2f} % (limit {r['limit_pct']:g}), t_delay error {r['td_err_frames']:+.3f} frame" \
            f"{'' if r['td_checked'] else ' (not judged)'}, terms {r['terms']}"
        out.append(f"- {r['name']} ({r['category']}, delay {r['delay_status']}, {r['fps']:g} fps): {fig}")
    lag = np.array([abs(r["lag_err_frames"]) for r in res if r.get("lag_err_frames") is not None])
    if lag.size:
        out.append(f"\nThe image's mean lag against the renderer's ({lag.size} rows), |error| in frames: median "
                   f"{np.median(lag):.3f}, P95 {np.percentile(lag, 95):.3f}, worst {lag.max():.3f}")
    cs = np.array([r["calibrate_s"] for r in res if "calibrate_s" in r])
    if cs.size:
        out.append(f"\n`calibrate` wall time over the rows (two processes on a 2-core machine): median {np.median(cs):.1f} s, "
                   f"worst {cs.max():.1f} s")
    text = "\n".join(out)
    print(text)
    if a.markdown:
        Path(a.markdown).write_text(text + "\n")
    return 0 if not fails else 1


if __name__ == "__main__":
    sys.exit(main())
