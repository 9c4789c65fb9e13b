"""Acceptance on the real catheter recordings: in situ and across-session RMSE tables.

Models, all judged by the bending-angle RMSE (deg) on the judged samples (500 Hz):
  linear      c = a q + b, least squares, no backlash (baseline)
  const_play  constant-width play + degree-5 polynomial, both least squares (baseline)
  ours        onset-based B(q) spline + f_remain (play-consistent least squares)
  paper       onset-based B(q) spline + f_remain by the paper's morphological median line
Every model runs over the whole file (the play state needs the past of q) and is scored
on the judged part only: the second half (in situ) or the whole file (across sessions).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import estimate as E
from . import model
from .calibration import calibrate
from .importer import import_catheter

MODELS = ["linear", "const_play", "ours", "paper"]


def fit_models(s) -> dict:
    """All four models fitted on session s. Returns {name: (B callable, f callable)}."""
    cal = calibrate(s, f_method="lsq")
    alt = E.SplineFn.from_json(cal.doc["f_remain_alt"])
    # Baselines see the same frames as the chain (block averages at the chain's frame rate).
    t_f, c_f = E.frames_from_angle(s.distal["t_s"], s.distal["c_deg"], cal.doc["fps_frames"])
    q_c, c_c = E.characteristic(s.encoder["t_s"], s.encoder["q"], t_f, c_f, 0.0)
    w, fp, Bc = E.fit_constant_play(q_c, c_c)
    return {"linear": (model.constant(0.0), E.fit_linear(q_c, c_c)), "const_play": (Bc, fp),
            "ours": (cal.B, cal.f), "paper": (cal.B, alt), "_cal": cal, "_w": w}


def rmse(e) -> float:
    return float(np.sqrt(np.mean(np.square(e))))


def evaluate_real(folder, progress=lambda it, **kw: it) -> dict:
    """Both protocols on data_2_*.txt in folder. Returns {"in_situ": {file: {model: rmse}},
    "across": {file: {model: rmse}}, "b_samples": {file: count}} (deg)."""
    files = sorted(Path(folder).glob("data_2_*.txt"))
    if not files:
        from .errors import InputError

        raise InputError(folder, "no data_2_*.txt recordings here")
    out = {"in_situ": {}, "across": {}, "b_samples": {}}
    sessions = {f.stem: import_catheter(f) for f in files}
    for name, s in progress(sessions.items(), desc="in situ", total=len(sessions)):
        t = s.encoder["t_s"]
        half = t[0] + 0.5 * (t[-1] - t[0])
        fit = fit_models(s.slice_time(-np.inf, half))
        out["b_samples"][name] = len(fit["_cal"].doc["b_samples"]["b"])
        judged = s.distal["t_s"] >= half
        row = {}
        for m in MODELS:
            B, f = fit[m]
            c_hat = model.direct_model(s.encoder["q"], B, f)
            row[m] = rmse(c_hat[judged] - s.distal["c_deg"][judged])
        out["in_situ"][name] = row
    ref_name = files[0].stem
    fit = fit_models(sessions[ref_name])
    for name, s in progress(sessions.items(), desc="across", total=len(sessions)):
        if name == ref_name:
            continue
        out["across"][name] = {m: rmse(model.direct_model(s.encoder["q"], *fit[m]) - s.distal["c_deg"])
                               for m in MODELS}
    return out


def format_tables(res: dict) -> str:
    """Markdown tables of evaluate_real()'s result, with a mean row."""
    lines = []
    for key, title in (("in_situ", "In situ: fit on the first half, judged on the second (RMSE, deg)"),
                       ("across", "Across sessions: fit on data_2_1, judged on each other file (RMSE, deg)")):
        rows = res[key]
        lines += [f"**{title}**", "", "| file | " + " | ".join(MODELS) + " |", "|---" * (len(MODELS) + 1) + "|"]
        for name, r in rows.items():
            lines.append(f"| {name} | " + " | ".join(f"{r[m]:.2f}" for m in MODELS) + " |")
        if rows:
            lines.append("| mean | " + " | ".join(f"{np.mean([r[m] for r in rows.values()]):.2f}" for m in MODELS) + " |")
        lines.append("")
    return "\n".join(lines)
