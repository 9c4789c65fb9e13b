"""Host speed: `calibrate` on a 3-minute 25 Hz image session (1 kHz encoder). Prints a table.

Usage: .venv/bin/python bench/bench_host.py
"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
from host.synth import ROBOT, excitation, image_model_parts, true_B, true_f  # noqa: E402

from playscope import model  # noqa: E402
from playscope.calibration import calibrate  # noqa: E402
from playscope.native import core  # noqa: E402
from playscope.session import Session, load_session, write_session  # noqa: E402


def image_session(duration_s=180.0):
    t, q, _ = excitation(v=0.4, rate_hz=1000.0)
    t, q = t[t < duration_s], q[t < duration_s]
    cam, he = image_model_parts()
    c = model.direct_model(q, true_B, true_f)
    tf = np.arange(0.0, t[-1], 1 / 25.0)
    im = model.ImageModel(ROBOT, cam, he)
    Q = im(np.interp(tf - 0.08, t, c)) + np.random.default_rng(0).normal(0, 0.05, (tf.size, 2))
    return Session("mm", "image", ROBOT, {"t_s": t, "q": q}, cam, he, 0.08,
                   marker={"t_s": tf, "u_px": Q[:, 0], "v_px": Q[:, 1]})


core()
rows = []
with tempfile.TemporaryDirectory() as d:
    write_session(image_session(), Path(d) / "s")
    t0 = time.perf_counter()
    s = load_session(Path(d) / "s")
    t1 = time.perf_counter()
    cal = calibrate(s)
    t2 = time.perf_counter()
    rows.append(("load 3-min session (1 kHz encoder, 25 Hz marker)", t1 - t0))
    rows.append((f"calibrate ({len(cal.doc['b_samples']['b'])} B samples, LM on {s.marker['t_s'].size} frames)", t2 - t1))
    rows.append(("load + calibrate (target < 3 s)", t2 - t0))
print("| step | time (s) |\n|---|---|")
for name, sec in rows:
    print(f"| {name} | {sec:.2f} |")
