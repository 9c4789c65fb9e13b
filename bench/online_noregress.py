"""No regression when nothing drifts: the board's on-line offset and gain of f (firmware/core/
f_online.c through cffi) switched on where the calibration is the right one. Prints one table:

- Main job: the open-loop compensation test of `playscope demo` (its separate test motion through
  the simulator's truth model, fixed-point table with the transition, RMSE after the first second),
  the table as flashed against the same table with the learner on, closed loop (each frame's
  angle learnt against f(f^-1(c*)), each publish rewriting f^-1 before the next sample:
  online.compensate_learning).
- Every catheter file in situ (each calibrated on its own first half, run from its first sample,
  scored on the second half: the in-situ row of evaluate-transfer), without and with the learner
  replayed on its frames (online.board_f_refreshed).
Settings by online.f_config_from from each calibration record (refresh period 1 s).
Target: every figure with the learner <= 1.02 x without.

Usage: .venv/bin/python bench/online_noregress.py [DATA_REAL] [--main DIR]
  --main DIR: a `playscope demo --out DIR` folder (default: the demo is run into a temporary
  folder first, about 60 s). The recordings are read in place. (About 40 s after the demo.)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

DEFAULT = Path(__file__).resolve().parents[1] / ".." / ".." / "shared" / "data" / "real"


def main_job_rows(main_dir: Path) -> list[tuple[str, float, float]]:
    """[(case, RMSE off, RMSE on)] in deg: the main job's open-loop compensation test from a
    `playscope demo --out` folder, its table as flashed and with the board's learner closed loop."""
    from playscope.board import online as O
    from playscope.evaluate.prediction import reference_trajectory
    from playscope.fit.calibration_check import load_calibration
    from playscope.fit.table_build import CalibTable
    from playscope.io.importer import load_recording
    from playscope.sim.plant import session_plant

    cal = load_calibration(main_dir / "calibration.json")
    s_test = load_recording(main_dir / "session_test")
    s_cal = load_recording(main_dir / "session_excitation")
    blob = (main_dir / "tables.pstb").read_bytes()
    plant, _ = session_plant(s_test)
    rate = float(1.0 / np.median(np.diff(s_test.encoder["t_s"])))
    t, c_ref = reference_trajectory(cal, 60.0, rate)  # evaluate's compensation test
    fps = 1.0 / cal.onset_config["frame_period_s"]
    cfg = O.f_config_from(s_cal, cal, 1.0)
    skip = t >= 1.0
    e = lambda q: float(np.sqrt(np.mean((np.asarray(plant(t, q)) - c_ref)[skip] ** 2)))  # noqa: E731
    static = e(CalibTable(blob).compensate(c_ref))
    q, end = O.compensate_learning(blob, t, c_ref, plant, fps, cfg)
    return [(f"main job: open-loop compensation, transition, fixed point (learnt a {end['a_deg']:+.3f} deg, "
             f"g {end['g']:.4f}, {end['publishes']} publishes)", static, e(q))]


def catheter_rows(folder: Path) -> list[tuple[str, float, float]]:
    """[(case, RMSE off, RMSE on)] in deg: every catheter file of folder in situ (calibrated on
    its first half, scored on the second), without and with the board's learner replayed."""
    from playscope.board import online as O
    from playscope.evaluate.transfer import WARMUP, _in_situ
    from playscope.io.importer import read_record

    rows = []
    for p in sorted(folder.glob("data_2_*.txt")):
        s = read_record(p)
        t, q = s.encoder["t_s"], s.encoder["q"]
        t_split = float(t[0] + WARMUP * (t[-1] - t[0]))
        # The learner's settings from the part the record was calibrated on (its own first half).
        c_hat, _, cal, s_cal = _in_situ(s, t_split, str(p))
        fps = 1.0 / cal.onset_config["frame_period_s"]
        cfg = O.f_config_from(s_cal, cal, 1.0)
        c_true = np.interp(t, s.distal["t_s"], s.distal["c_deg"])
        mask = t >= t_split
        c_fix, _ = O.board_f_refreshed(s, c_hat, fps, cfg, (float(np.nanmin(s_cal.distal["c_deg"])),
                                                            float(np.nanmax(s_cal.distal["c_deg"]))))
        rows.append((f"catheter in situ, {p.stem}", O.rmse((c_hat - c_true)[mask]), O.rmse((c_fix - c_true)[mask])))
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("real", nargs="?", default=str(DEFAULT if DEFAULT.is_dir() else Path("/work/shared/data/real")))
    p.add_argument("--main", help="a `playscope demo --out DIR` folder (default: run the demo first)")
    a = p.parse_args(argv)
    cath = Path(a.real) / "catheter"
    if not cath.is_dir():
        print(f"online_noregress: no catheter/ under {a.real}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        main_dir = Path(a.main) if a.main else Path(tmp) / "main"
        if not a.main:
            from playscope import mainjob

            mainjob.run(main_dir, log=lambda s: None)
        rows = main_job_rows(main_dir)
    rows += catheter_rows(cath)
    cat = [r for r in rows if r[0].startswith("catheter")]
    rows.append(("catheter in situ, mean of the files", float(np.mean([r[1] for r in cat])),
                 float(np.mean([r[2] for r in cat]))))
    print("**The board's offset and gain learner where nothing drifts (bending-angle RMSE, deg)**\n")
    print("| case | as calibrated | learner on | change |")
    print("|---|---|---|---|")
    for name, off, on in rows:
        print(f"| {name} | {off:.4f} | {on:.4f} | {100 * (on / off - 1):+.1f} % |")
    worst = max(on / off for _, off, on in rows)
    print(f"\nTarget (learner on <= 1.02 x as calibrated, every case): {'met' if worst <= 1.02 else 'NOT met'} "
          f"(worst {100 * (worst - 1):+.1f} %)\n")
    print(f"({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
