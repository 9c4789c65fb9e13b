"""Peak memory and time of `playscope calibrate` on a long high-rate encoder log: a simulated
angle session (preset stras, excitation trajectory) with its encoder at 5 kHz for 27 minutes
(8.1 million rows, about 240 MB of CSV), as a user's long bench recording would be. The
session loader thins encoder logs above session.ENCODER_MAX_HZ (500 Hz) by travel at load; this bench
prints one row per command: wall time and peak RSS (the child's ru_maxrss).

    PYTHONPATH=host python bench/bench_large_log.py [WORKDIR] [--minutes 27] [--hz 5000]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path


def run(argv: list[str], env: dict) -> tuple[float, float, int]:
    """(wall s, peak RSS MiB, exit status) of one playscope command, measured by GNU time
    (/usr/bin/time -f %M: the child's maximum resident set)."""
    t0 = time.perf_counter()
    r = subprocess.run(["/usr/bin/time", "-f", "@@%M", sys.executable, "-m", "playscope.cli", *argv], env=env,
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    lines = r.stderr.strip().splitlines()
    peak_kb = float(lines[-1][2:]) if lines and lines[-1].startswith("@@") else float("nan")
    if r.returncode:
        print("\n".join(lines[-5:]), file=sys.stderr)
    return wall, peak_kb / 1024.0, r.returncode


def add_noise(src: Path, dst: Path, noise_um: float) -> Path:
    """A copy of session src whose encoder q carries Gaussian noise of noise_um and 1 um counts,
    as a real encoder's log does (a noise-free q has few turning points, which hides the cost
    of a dense log). Made once."""
    import shutil

    import numpy as np

    if dst.exists():
        return dst
    dst.mkdir()
    for name in ("session.json", "distal.csv"):
        shutil.copy(src / name, dst / name)
    d = np.loadtxt(src / "encoder.csv", delimiter=",", skiprows=1)
    q = np.round((d[:, 1] + np.random.default_rng(0).normal(0, noise_um * 1e-3, d.shape[0])) * 1000) / 1000
    with open(dst / "encoder.csv", "w") as f:
        f.write("t_s,q\n")
        np.savetxt(f, np.column_stack([d[:, 0], q]), fmt=["%.4f", "%.3f"], delimiter=",")
    return dst


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("work", nargs="?", default="bench_large_log.work")
    ap.add_argument("--minutes", type=float, default=27.0)
    ap.add_argument("--hz", type=float, default=5000.0)
    ap.add_argument("--noise-um", type=float, default=2.0,
                    help="encoder noise added to the simulated q (um, then rounded to 1 um counts); 0: noise-free")
    a = ap.parse_args()
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "host"))
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    sess = work / "long"
    rows = []
    if not sess.exists():
        (work / "c.json").write_text(json.dumps({"encoder_hz": a.hz}))
        rows.append(("simulate", *run(["simulate", str(sess), "--kind", "angle", "--config", str(work / "c.json"),
                                       "--trajectory", "excitation", "--duration", str(a.minutes * 60)], env)))
    truth = sess / "truth.csv"
    if truth.exists():  # simulator-only ground truth (471 MB here): a user's log has none
        truth.unlink()
    if a.noise_um > 0:
        sess = add_noise(sess, work / f"noisy{a.noise_um:g}um", a.noise_um)
    size_mb = (sess / "encoder.csv").stat().st_size / 2**20
    rows.append(("calibrate", *run(["calibrate", str(sess), "-o", str(work / "cal.json"), "--force"], env)))
    print(f"encoder.csv: {size_mb:.0f} MiB, {a.hz:g} Hz, {a.minutes:g} min, noise {a.noise_um:g} um")
    print(f"{'command':12s} {'wall s':>8s} {'peak RSS MiB':>13s} {'status':>7s}")
    for name, wall, rss, rc in rows:
        print(f"{name:12s} {wall:8.1f} {rss:13.0f} {rc:7d}")


if __name__ == "__main__":
    main()
