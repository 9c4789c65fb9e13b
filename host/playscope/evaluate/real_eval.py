"""Acceptance on the real catheter recordings: in situ and across-session RMSE tables.

In situ (each file alone): playscope.evaluate.insitu_split.evaluate_insitu with the split at half the
duration, so every row of insitu.ROWS (linear, constant play, the paper's method, onset B +
least-squares f_remain, generalized PI, Bouc-Wen, ours) is fitted on the first half, run
from the file's first sample (state carried) and judged on the second half; the rows the
board runs go through the fixed-point tables.

Across sessions (fit on data_2_1, judged on the whole of each other file), float models:
  linear      c = a q + b, least squares, no backlash (baseline)
  const_play  constant-width play + degree-5 polynomial, both least squares (baseline)
  ours        onset-based B(q) spline + f_remain (play-consistent least squares)
  paper       onset-based B(q) spline + f_remain by the paper's morphological median line
All judged by the bending-angle RMSE (deg) on the judged samples (500 Hz).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fit.baselines import fit_constant_play, fit_linear
from ..fit.f_remain import characteristic
from ..fit.reversals import frames_from_angle
from . import insitu_split as insitu
from ..fit import model
from ..fit.calibration import calibrate
from ..io.importer import import_catheter
from ..base.metrics import rmse  # noqa: F401  (real_eval.rmse: the in-situ tables' figure)

MODELS = ["linear", "const_play", "ours", "paper"]


def fit_models(s) -> dict:
    """All four models fitted on session s. Returns {name: (B callable, f callable)}."""
    cal = calibrate(s, f_method="lsq", model_kind="play")  # the paper's play rows
    alt = cal.f_alt
    # Baselines see the same frames as the chain (block averages at the chain's frame rate).
    t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], cal.fps_frames)
    q_c, c_c = characteristic(s.encoder["t_s"], s.encoder["q"], t_f, c_f, 0.0)
    w, fp, Bc = fit_constant_play(q_c, c_c)
    return {"linear": (model.constant(0.0), fit_linear(q_c, c_c)), "const_play": (Bc, fp),
            "ours": (cal.B, cal.f), "paper": (cal.B, alt), "_cal": cal, "_w": w}


def fit_models_image(s) -> dict:
    """The same four models on an image session (a re-imaged recording): the chain as
    `calibrate` runs it (onsets in the image, f_remain on LM pose estimates, eqs. 6-8), the
    baselines fitted on the same LM estimates of c. Returns {name: (B, f)}."""
    cal = calibrate(s, f_method="lsq", model_kind="play")  # the paper's play rows
    alt = cal.f_alt
    t_f, obs = s.observations()
    td = cal.t_delay_s
    im = model.ImageModel(s.robot, s.camera, s.hand_eye)
    q_f = np.interp(t_f - td, s.encoder["t_s"], s.encoder["q"])
    c_f, _ = im.estimate_c(obs, model.f_coarse(q_f, s.robot.q_per_rad))
    q_c, c_c = characteristic(s.encoder["t_s"], s.encoder["q"], t_f, c_f, td)
    w, fp, Bc = fit_constant_play(q_c, c_c)
    return {"linear": (model.constant(0.0), fit_linear(q_c, c_c)), "const_play": (Bc, fp),
            "ours": (cal.B, cal.f), "paper": (cal.B, alt), "_cal": cal, "_w": w}


def reimage_and_track(src: Path, work: Path) -> "object":
    """Render src (a catheter CSV) through the simulator's virtual endoscope into
    work/<stem>/ (video + frames.csv, truth.csv with the measured angle), track the marker
    in that video, and load the session. Reuses a folder already tracked."""
    import sys

    from ..base.atomic import output_guard
    from ..io.marker_track import track_session
    from ..io.session import load_session
    from ..sim.record import sim_config, write_simulated

    folder = work / src.stem
    if not (folder / "marker.csv").is_file() or not (folder / ".tracked").is_file():
        # The simulator's default preset (stras) images the recording (`playscope simulate --reimage`);
        # the work folder is this function's own, replaced at will, the recording is an input.
        with output_guard((src,), force=True):
            print(write_simulated(sim_config(), folder, video=True, reimage_src=str(src), overwrite=True).summary_line(),
                  file=sys.stderr)
            res = track_session(folder, overwrite=True)
        if res.warning:
            print(f"playscope: warning: {res.warning}", file=sys.stderr)
        print(res.line())
        (folder / ".tracked").write_text("marker.csv comes from tracking video.avi\n")
    return load_session(folder)


def evaluate_real_reimaged(folder, work, progress=lambda it, **kw: it) -> dict:
    """Both protocols of evaluate_real() on the recordings re-imaged through a virtual
    endoscope, so that the image pipeline (render, track, onsets in the image, LM pose
    estimation) runs on real kinematics; judged against the measured angle (truth.csv).
    Same result layout as evaluate_real()."""
    files = sorted(Path(folder).glob("data_2_*.txt"))
    if not files:
        from ..base.errors import InputError

        raise InputError(folder, "no data_2_*.txt recordings here")
    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    out = _empty()
    sessions = {f.stem: reimage_and_track(f, work) for f in progress(files, desc="re-image + track")}

    def judge(s, fit, mask):
        c_true = np.interp(s.encoder["t_s"], s.truth["t_s"], s.truth["c_deg"])
        return {m: rmse(model.direct_model(s.encoder["q"], *fit[m])[mask] - c_true[mask]) for m in MODELS}

    for name, s in progress(sessions.items(), desc="in situ", total=len(sessions)):
        _in_situ(out, name, s, str(work / name))
    ref_name = files[0].stem
    fit = fit_models_image(sessions[ref_name])
    for name, s in progress(sessions.items(), desc="across", total=len(sessions)):
        if name != ref_name:
            out["across"][name] = judge(s, fit, np.ones(s.encoder["t_s"].size, bool))
    return out


def _empty() -> dict:
    return {"in_situ": {}, "in_situ_max": {}, "in_situ_rows": insitu.ROWS, "across": {}, "b_samples": {}}


def _in_situ(out: dict, name: str, s, source: str) -> None:
    """evaluate_insitu at half the duration, filed under name in out."""
    doc = insitu.evaluate_insitu(s, 0.5, source=source)
    out["in_situ"][name] = {k: r["rmse_deg"] for k, r in doc["rows"].items()}
    out["in_situ_max"][name] = {k: r["max_deg"] for k, r in doc["rows"].items()}
    out["b_samples"][name] = doc["rows"]["onset_lsq"]["params"]["b_samples"]


def evaluate_real(folder, progress=lambda it, **kw: it, across: bool = True) -> dict:
    """Both protocols on data_2_*.txt in folder. Returns {"in_situ": {file: {row: rmse}},
    "in_situ_max": {file: {row: max |error|}}, "in_situ_rows": [row], "across": {file:
    {model: rmse}}, "b_samples": {file: onset samples in the first half}} (deg); rows:
    insitu.ROWS, models: MODELS. across=False leaves the across-sessions protocol out."""
    files = sorted(Path(folder).glob("data_2_*.txt"))
    if not files:
        from ..base.errors import InputError

        raise InputError(folder, "no data_2_*.txt recordings here")
    out = _empty()
    sessions = {f.stem: import_catheter(f) for f in files}
    for name, s in progress(sessions.items(), desc="in situ", total=len(sessions)):
        _in_situ(out, name, s, str(Path(folder) / f"{name}.txt"))
    if not across:
        return out
    ref_name = files[0].stem
    fit = fit_models(sessions[ref_name])
    for name, s in progress(sessions.items(), desc="across", total=len(sessions)):
        if name == ref_name:
            continue
        out["across"][name] = {m: rmse(model.direct_model(s.encoder["q"], *fit[m]) - s.distal["c_deg"])
                               for m in MODELS}
    return out


def format_in_situ(res: dict) -> str:
    """The in-situ table of evaluate_real()'s result: one row per model, one column per file,
    then the mean and the worst file (RMSE, deg; every file in the mean). A row refused on a
    file (its table refused by the loader, evaluate_insitu's "refused") reads "refused" there,
    and its mean is not given."""
    files = list(res["in_situ"])
    rows = res.get("in_situ_rows", insitu.ROWS)
    lines = ["**In situ, state carried: fit on the first half of each file, judged on the second "
             "(bending-angle RMSE, deg)**", "",
             "| model | " + " | ".join(files) + " | mean | worst |", "|---" * (len(files) + 3) + "|"]
    for m in rows:
        v = [res["in_situ"][f][m] for f in files]
        ok = [x for x in v if x is not None]  # None: the row's table was refused on that file
        tail = f" | {np.mean(ok):.2f} | {np.max(ok):.2f} |" if len(ok) == len(v) else \
            f" | {len(v) - len(ok)} refused | {max(ok):.2f} |" if ok else " | refused | refused |"
        lines.append(f"| {insitu.LABELS[m]} | " + " | ".join("refused" if x is None else f"{x:.2f}" for x in v) + tail)
    return "\n".join(lines + [""])


def format_tables(res: dict) -> str:
    """Markdown tables of evaluate_real()'s result: in situ (format_in_situ), then across
    sessions with a mean row."""
    lines = [format_in_situ(res)] if res["in_situ"] else []
    for key, title in (("across", "Across sessions: fit on data_2_1, judged on each other file (RMSE, deg)"),):
        rows = res[key]
        lines += [f"**{title}**", "", "| file | " + " | ".join(MODELS) + " |", "|---" * (len(MODELS) + 1) + "|"]
        for name, r in rows.items():
            lines.append(f"| {name} | " + " | ".join(f"{r[m]:.2f}" for m in MODELS) + " |")
        if rows:
            lines.append("| mean | " + " | ".join(f"{np.mean([r[m] for r in rows.values()]):.2f}" for m in MODELS) + " |")
        lines.append("")
    return "\n".join(lines)
