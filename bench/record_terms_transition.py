#!/usr/bin/env python3
"""The record model's camera terms on plants with a smooth transition and no camera effect.

The main job's plant (the simulator's "stras" preset) has a smooth transition after each reversal
(a Prandtl-Ishlinskii spread of play widths, effect smooth_transition) and no camera effect: no
registration switch, no tip mode, no slide, no exposure. The record model of the onset stage
(fit.onset_model) has no term for a spread of widths: it is a single play. This bench measures
what its term search does there: sessions of the simulator's "stras" preset at several spreads
(0: a pure play; the main job's 0.5; 0.8) and seeds, the marker projected with the preset's noise
(no video: the tracker is not what is measured), each calibrated twice:

- as `calibrate` does (the terms chosen by the BIC, onset_search);
- with the record model held plain (no term offered: `onset_model.Terms.offered` stood in for).

Per session and mode: the terms chosen, `calibrate`'s wall time, B against the simulator's centre
width (mainjob.b_error_vs_truth: mean |error| mm and the mean ratio B_est / B_true), and the
lowest cross-validated RMSE of the model choice on c (`B_fit.model_cv`, deg: what the product's
own criterion says of the calibration). The simulator is the product's own (playscope.sim), not
one of the scoreboard's renderers, so this is development data, not a check.

Usage: .venv/bin/python bench/record_terms_transition.py [--spreads 0,0.5,0.8] [--seeds 1,2]
       [--duration 60]        (about 1-2 min per session with the terms on)
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from playscope import mainjob
from playscope.fit import onset_model as OM
from playscope.fit.calibration import calibrate
from playscope.io.session import load_session
from playscope.sim.record import sim_config, write_simulated


def one(session_dir: Path, plain: bool) -> dict:
    """calibrate on the session, the record model's terms offered or not: a dict of the figures."""
    offered = OM.Terms.offered
    if plain:
        OM.Terms.offered = lambda self: []
    try:
        s = load_session(session_dir)
        t0 = time.perf_counter()
        cal = calibrate(s)
        sec = time.perf_counter() - t0
    finally:
        OM.Terms.offered = offered
    path = session_dir / ("cal_plain.json" if plain else "cal_terms.json")
    cal.save(path)
    b = mainjob.b_error_vs_truth(path, session_dir)
    cv = cal.doc["B_fit"].get("model_cv") or []
    return {"terms": cal.doc["onset"]["refine"]["terms"]["chosen"], "s": sec, "b_mean_mm": b["mean"],
            "ratio": b["ratio_mean"], "cv_deg": min((r["cv_rmse_deg"] for r in cv), default=float("nan"))}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--spreads", default="0,0.5,0.8", help="smooth_transition spreads (default 0,0.5,0.8)")
    p.add_argument("--seeds", default="1,2", help="simulator seeds (default 1,2)")
    p.add_argument("--duration", type=float, default=60.0, help="excitation length, s (default 60)")
    a = p.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for spread in (float(x) for x in a.spreads.split(",")):
            for seed in (int(x) for x in a.seeds.split(",")):
                out = Path(d) / f"s{spread}-{seed}"
                cfg = sim_config("stras", effects=[f"smooth_transition:spread={spread}"] if spread > 0 else [],
                                 no_preset_effects=True, trajectory="excitation", duration_s=a.duration, seed=seed)
                write_simulated(cfg, out)
                for plain in (False, True):
                    r = one(out, plain)
                    rows.append((spread, seed, "plain" if plain else "terms by BIC", r))
                    print(f"spread {spread} seed {seed} {rows[-1][2]}: {r}", flush=True)
    print("\n| spread | seed | record model | terms chosen | calibrate s | B mean error mm | B_est / B_true | "
          "model CV on c, deg |\n|---|---|---|---|---|---|---|---|")
    for spread, seed, mode, r in rows:
        print(f"| {spread:g} | {seed} | {mode} | {', '.join(r['terms']) or '(none)'} | {r['s']:.1f} | "
              f"{r['b_mean_mm']:.3f} | {r['ratio']:.2f} | {r['cv_deg']:.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
