"""Short renderings of bench/swing_render.py (a renderer written apart from the estimator) as the
onset stage takes them, and B's error against their truth: the onset tests' shared helper."""

import importlib.util
import sys
from pathlib import Path

import numpy as np

from playscope.fit.reversals import detect_reversals

ROOT = Path(__file__).resolve().parents[3]


def bench_module(name: str):
    """bench/<name>.py, a renderer written apart from the estimator, as a module."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "bench" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look the module up by name
    spec.loader.exec_module(mod)
    return mod


SR = bench_module("swing_render")


def record(**kw):
    """A 40 s rendering (the ramp over half the travel) as the stage takes it."""
    r = SR.Rendering(kw.pop("name", "t"), kw.pop("seed", 7), duration_s=kw.pop("duration_s", 40.0), **kw)
    d = SR.render(r)
    t, q = d["t_enc"], d["q"]
    hyst = 0.01 * np.ptp(q)
    rt, rq, _ = detect_reversals(t, q, hyst)
    return r, d, t, q, rt, rq, np.column_stack([d["u"], d["v"]]), hyst


def b_error_pct(r, on):
    """Mean |B_model - B_true| at the samples' own q, % of the mean true B: each sample of eq. 1 is
    |q2 - q1|, the width at take-up, so it is judged against the true width between q1 and q2."""
    true = 0.5 * (r.B(on.q1) + r.B(on.q2))
    return 100 * float(np.mean(np.abs(on.b - true)) / np.mean(true))
