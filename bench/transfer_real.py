"""A calibration made on one record used on others, on the real recordings (read in place):
prints the transfer tables and the table of what drifts (docs/online.md, "Calibrated once,
used elsewhere").

- Catheter: calibrated on data_2_1, run on data_2_2..5 (the zero-baseline set), and calibrated on
  data_1_1, run on data_1_2 (the non-zero-baseline set): ours and the textbook peers (generalized
  and modified PI and their invertible forms) calibrated on the same record, each as is and with
  the same refresh and the same board learner.
- Endoscope development files only (30, 60, 120 deg and conf0_60): calibrated on 60.txt (the
  middle of the short records' configurations), run on each other. The other endoscope files
  are set aside and never read here.
- Endoscope, every development file as the calibration one in turn (a compact table), and the
  ratio of ours (transition + the board's offset and gain learner) to the in-situ figure.
- Endoscope, what learning the drifting terms could reach at best: the offset, gain and B level
  chosen on the scored samples themselves (an oracle), against the in-situ figure.
- Endoscope, what learning f's shape (hat functions on the model's pre-f output), a correction
  per branch of the loop, or the transition's weights could reach: oracle (on the scored
  samples), fitted once on the warm-up, and causal RLS from the record's start, per pair; and
  the weights beside the per-branch correction; and the same learners on each record's in-situ
  model (endoscope development files and catheter files), where nothing drifts.
- What drifts: every record calibrated in situ on its whole length, compared with the
  calibration record.

Usage: .venv/bin/python bench/transfer_real.py [DATA_REAL] [--warmup F] [--json OUT] [--plot-dir DIR] [--tables-only]
(about 4 min; --tables-only: the three transfer tables alone, about 1 min)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from playscope.evaluate.transfer import (WARMUP, drift, evaluate_transfer, format_ceiling, format_drift, format_noregress,
                                        format_shape, format_transfer, learnable_ceiling, plot_transfer, shape_ceiling,
                                        shape_noregress)

DEFAULT = Path(__file__).resolve().parents[1] / ".." / ".." / "shared" / "data" / "real"
ENDOSCOPE_DEV = ["30", "60", "120", "conf0_60"]  # development files; the others are set aside
ENDOSCOPE_CAL = "60"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("real", nargs="?", default=str(DEFAULT if DEFAULT.is_dir() else Path("/work/shared/data/real")))
    p.add_argument("--warmup", type=float, default=WARMUP, help=f"fraction before scoring (default {WARMUP})")
    p.add_argument("--json", help="also write every result here")
    p.add_argument("--plot-dir", help="write transfer_catheter.png, transfer_catheter_1.png and transfer_endoscope.png here")
    p.add_argument("--tables-only", action="store_true", help="only the transfer tables (catheter both sets, endoscope)")
    a = p.parse_args(argv)
    cath, endo = Path(a.real) / "catheter", Path(a.real) / "endoscope"
    if not cath.is_dir() or not endo.is_dir():
        print(f"transfer_real: no catheter/ and endoscope/ under {a.real}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    cf = sorted(cath.glob("data_2_*.txt"))
    cf1 = sorted(cath.glob("data_1_*.txt"))
    ef = [endo / f"{n}.txt" for n in ENDOSCOPE_DEV]
    ecal = endo / f"{ENDOSCOPE_CAL}.txt"
    out = {"catheter": evaluate_transfer(cf[0], cf[1:], a.warmup)}
    if len(cf1) > 1:
        out["catheter_1"] = evaluate_transfer(cf1[0], cf1[1:], a.warmup)
    out["endoscope"] = evaluate_transfer(ecal, [f for f in ef if f != ecal], a.warmup)
    for k in ("catheter", "catheter_1", "endoscope"):
        if k not in out:
            continue
        print(format_transfer(out[k]))
        if a.plot_dir:
            Path(a.plot_dir).mkdir(parents=True, exist_ok=True)
            plot_transfer(out[k], Path(a.plot_dir) / f"transfer_{k}.png")
    if a.tables_only:
        print(f"({time.perf_counter() - t0:.1f} s)")
        if a.json:
            Path(a.json).write_text(json.dumps(out, indent=1, default=float))
        return 0
    # Every development configuration as the calibration one (the table above takes 60 deg).
    pairs = {c.stem: evaluate_transfer(c, [f for f in ef if f != c], a.warmup) for c in ef}
    out["endoscope_pairs"] = pairs
    keys = ("in_situ", "online", "transition_offset", "transition_affine", "transition_board", "const_play_ref_offset",
            "const_play_ref_affine", "const_play_ref_board")
    print("**Endoscope, every development record as the calibration one (RMSE after the warm-up, deg)**\n")
    print("| calibrated on | run on | " + " | ".join(pairs[ENDOSCOPE_CAL]["labels"][k] for k in keys) + " |")
    print("|---|---" + "|---" * len(keys) + "|")
    for c, doc in pairs.items():
        for n, f in doc["files"].items():
            print(f"| {c} | {n} | " + " | ".join(f"{f['rmse_deg'][k]:.2f}" for k in keys) + " |")
    # Ours with the board's learner against the in-situ reference, per pair (target: within 1.5 x).
    ratios = [f["rmse_deg"]["transition_board"] / f["rmse_deg"]["in_situ"] for doc in pairs.values()
              for f in doc["files"].values()]
    print(f"\nEndoscope, transferred with transition + the board's offset and gain learner / in situ: "
          f"{min(ratios):.1f} .. {max(ratios):.1f} x over {len(ratios)} pairs; within 1.5 x on "
          f"{sum(r <= 1.5 for r in ratios)} (target: every pair)")
    print()
    # What learning offset, gain and B level could reach at best (oracle), every development pair.
    cache: dict = {}
    out["ceiling_endoscope"] = [learnable_ceiling(c, [f for f in ef if f != c], a.warmup, cache) for c in ef]
    print(format_ceiling(out["ceiling_endoscope"]))
    out["shape_endoscope"] = [shape_ceiling(c, [f for f in ef if f != c], a.warmup, in_situ_cache=cache) for c in ef]
    print(format_shape(out["shape_endoscope"]))
    for k in ("shape_8", "branch_8", "weights", "wbranch_4", "wbranch_8"):
        r = [f[f"{k}_rls"] / f["in_situ"] for d in out["shape_endoscope"] for f in d["files"].values()]
        print(f"Endoscope, {k} learnt by causal RLS / in situ: {min(r):.1f} .. {max(r):.1f} x over {len(r)} pairs; "
              f"within 1.5 x on {sum(v <= 1.5 for v in r)}")
    print()
    # The same learners where nothing drifts (each record's in-situ model): they must not make it worse.
    out["shape_noregress"] = {"endoscope": shape_noregress(ef, a.warmup), "catheter": shape_noregress(cf, a.warmup)}
    for k in ("endoscope", "catheter"):  # the instrument in the heading: one generated block each
        print(format_noregress(out["shape_noregress"][k]).replace("**Where nothing drifts:", f"**Where nothing drifts ({k}):", 1))
    out["drift_catheter"] = drift(cf, cf[0])
    out["drift_endoscope"] = drift(ef, ecal)
    print(format_drift(out["drift_catheter"]))
    print(format_drift(out["drift_endoscope"]))
    print(f"({time.perf_counter() - t0:.1f} s)")
    if a.json:
        for k in ("drift_catheter", "drift_endoscope"):
            for d in out[k]["files"].values():
                d.pop("cal", None)
        Path(a.json).write_text(json.dumps(out, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
