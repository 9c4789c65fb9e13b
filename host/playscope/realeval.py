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
    cal = calibrate(s, f_method="lsq", model_kind="play")  # the paper's play rows
    alt = E.SplineFn.from_json(cal.doc["f_remain_alt"])
    # Baselines see the same frames as the chain (block averages at the chain's frame rate).
    t_f, c_f = E.frames_from_angle(s.distal["t_s"], s.distal["c_deg"], cal.doc["fps_frames"])
    q_c, c_c = E.characteristic(s.encoder["t_s"], s.encoder["q"], t_f, c_f, 0.0)
    w, fp, Bc = E.fit_constant_play(q_c, c_c)
    return {"linear": (model.constant(0.0), E.fit_linear(q_c, c_c)), "const_play": (Bc, fp),
            "ours": (cal.B, cal.f), "paper": (cal.B, alt), "_cal": cal, "_w": w}


def fit_models_image(s) -> dict:
    """The same four models on an image session (a re-imaged recording): the chain as
    `calibrate` runs it (onsets in the image, f_remain on LM pose estimates, eqs. 6-8), the
    baselines fitted on the same LM estimates of c. Returns {name: (B, f)}."""
    cal = calibrate(s, f_method="lsq", model_kind="play")  # the paper's play rows
    alt = E.SplineFn.from_json(cal.doc["f_remain_alt"])
    t_f, obs = s.observations()
    td = cal.doc["t_delay_s"]
    im = model.ImageModel(s.robot, s.camera, s.hand_eye)
    q_f = np.interp(t_f - td, s.encoder["t_s"], s.encoder["q"])
    c_f, _ = im.estimate_c(obs, model.f_coarse(q_f, s.robot.q_per_rad))
    q_c, c_c = E.characteristic(s.encoder["t_s"], s.encoder["q"], t_f, c_f, td)
    w, fp, Bc = E.fit_constant_play(q_c, c_c)
    return {"linear": (model.constant(0.0), E.fit_linear(q_c, c_c)), "const_play": (Bc, fp),
            "ours": (cal.B, cal.f), "paper": (cal.B, alt), "_cal": cal, "_w": w}


def reimage_and_track(src: Path, work: Path) -> "object":
    """Render src (a catheter CSV) through the simulator's virtual endoscope into
    work/<stem>/ (video + frames.csv, truth.csv with the measured angle), track the marker
    in that video, and load the session. Reuses a folder already tracked."""
    from . import cli
    from .session import load_session

    folder = work / src.stem
    if not (folder / "marker.csv").is_file() or not (folder / ".tracked").is_file():
        for argv in (["simulate", str(folder), "--reimage", str(src), "--video", "--overwrite"],
                     ["track", str(folder), "--overwrite"]):
            if cli.main(argv) != 0:
                raise RuntimeError(f"`playscope {' '.join(argv)}` failed")
        (folder / ".tracked").write_text("marker.csv comes from tracking video.avi\n")
    return load_session(folder)


def evaluate_real_reimaged(folder, work, progress=lambda it, **kw: it) -> dict:
    """Both protocols of evaluate_real() on the recordings re-imaged through a virtual
    endoscope, so that the image pipeline (render, track, onsets in the image, LM pose
    estimation) runs on real kinematics; judged against the measured angle (truth.csv).
    Same result layout as evaluate_real()."""
    files = sorted(Path(folder).glob("data_2_*.txt"))
    if not files:
        from .errors import InputError

        raise InputError(folder, "no data_2_*.txt recordings here")
    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    out = {"in_situ": {}, "across": {}, "b_samples": {}}
    sessions = {f.stem: reimage_and_track(f, work) for f in progress(files, desc="re-image + track")}

    def judge(s, fit, mask):
        c_true = np.interp(s.encoder["t_s"], s.truth["t_s"], s.truth["c_deg"])
        return {m: rmse(model.direct_model(s.encoder["q"], *fit[m])[mask] - c_true[mask]) for m in MODELS}

    for name, s in progress(sessions.items(), desc="in situ", total=len(sessions)):
        t = s.encoder["t_s"]
        half = t[0] + 0.5 * (t[-1] - t[0])
        fit = fit_models_image(s.slice_time(-np.inf, half))
        out["b_samples"][name] = len(fit["_cal"].doc["b_samples"]["b"])
        out["in_situ"][name] = judge(s, fit, t >= half)
    ref_name = files[0].stem
    fit = fit_models_image(sessions[ref_name])
    for name, s in progress(sessions.items(), desc="across", total=len(sessions)):
        if name != ref_name:
            out["across"][name] = judge(s, fit, np.ones(s.encoder["t_s"].size, bool))
    return out


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
