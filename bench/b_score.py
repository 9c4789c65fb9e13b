"""The B(q) score the onset benches share (bench/swing_bench.py, bench/fig7_replica.py): a rendered
session written to a folder, loaded and calibrated as a user's would be, then the fitted B(q)
against the renderer's true B over the q range the B samples cover.

The renderers (bench/marker_render.py, bench/swing_render.py) stay apart from this and from each
other: they only write the session folder and give the true B; this module is the judging side.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Callable

import numpy as np

from playscope.base.errors import InputError
from playscope.fit.calibration import calibrate
from playscope.io.session import load_session

GRID = 400  # points of the q grid the error is averaged over


def score(write: Callable[[Path], object], true_B: Callable[[np.ndarray], np.ndarray], **calibrate_kw) -> dict:
    """Write a session with write(folder), load it, calibrate it (calibrate_kw passed on) and
    compare B. Returns, when calibrate refuses: {"refused": its message (str)}; otherwise
    {"cal": the Calibration, "session": the loaded Session, "grid": q grid (GRID,) over
    [min, max] of the B samples' mean q, actuator units, "err_mm": mean |B_fit - B_true| over
    the grid (actuator units), "err_pct": that in % of the mean true B over the grid,
    "wall_s": calibrate's wall time (s)}. The folder is temporary; the session is read in full
    before it goes."""
    with tempfile.TemporaryDirectory() as d:
        write(Path(d))
        s = load_session(d)
        t0 = time.time()
        try:
            cal = calibrate(s, **calibrate_kw)
        except InputError as e:
            return {"refused": str(e)}
        wall = time.time() - t0
    qm = np.asarray(cal.b_samples["q_mean"], float)
    g = np.linspace(qm.min(), qm.max(), GRID)
    true = np.asarray(true_B(g), float)
    err_mm = float(np.mean(np.abs(cal.B(g) - true)))
    return {"cal": cal, "session": s, "grid": g, "err_mm": err_mm, "err_pct": 100 * err_mm / float(np.mean(true)),
            "wall_s": wall}
