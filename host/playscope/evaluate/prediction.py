"""Evaluation of a calibration on a test session: the paper's Table I and compensation test.

Prediction (section V-F, Table I, Figs. 10-11): the direct model runs over the session's
whole encoder log (the play state needs the past of q), is read at each frame's
acquisition time t - t_delay, and is compared with the measurement:
  f_coarse          c = f_coarse(q)                         (no backlash)
  f_coarse+B        c = f_coarse(z), z = play(q; B)         (eqs. 2-3)
  f_remain+B        c = f_remain(z)                         (eqs. 2-3, the paper's full model)
  f_remain+B+PI     c = f_remain(PI(z))                     (with the smooth transition, docs/method.md;
                                                             only when the calibration carries one)
  <row>_fixed       the table's model through the firmware's playop_step() on Q16.16 tables
                    (f_remain+B_fixed for a pure-play table, f_remain+B+PI_fixed with operators)
Image sessions: Q_hat = h(g(c)) (eq. 6, session camera and hand-eye) against marker.csv,
errors |Qx|, |Qy| and distance in px (mean, std, max). Angle sessions: c against
distal.csv. When truth.csv is there (simulated), the bending-angle RMSE against the true
c is given too.

Compensation (section V-G, Fig. 12): a reference c*(t) is turned into actuator commands by
  f_coarse_inv      q = f_coarse^-1(c*)                     (no compensation)
  f_coarse+B        eq. 4 with eq. 5 (B, f_coarse)
  f_remain+B        eq. 4 with eq. 9 (B, f_remain)
  f_remain+B+PI     f_remain^-1, the inverse PI operator, then eq. 4 (the transition model's inverse, docs/method.md)
  <row>_fixed       the firmware's comp_step() on the Q16.16 table
and each command runs open loop through a plant: the simulator's truth model when the
session records its parameters (session.json "simulator"), or a callable given by the
caller. Without a plant only the commands are computed and the result says so.

Units: q in actuator units, c in deg, image in px, t in s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..fit import model
from ..fit import transition as T
from ..fit.calibration import Calibration
from ..base.errors import InputError
from ..base.metrics import rmse_finite as rmse  # noqa: F401  (over the finite residuals: a reference may leave f^-1 undefined)
from ..io.session import Session
from ..sim.plant import NO_PLANT  # the note for a real recording, beside the simulator it names

PRED_MODELS = ["f_coarse", "f_coarse+B", "f_remain+B", "f_remain+B+PI", "f_remain+B_fixed", "f_remain+B+PI_fixed"]
COMP_METHODS = ["f_coarse_inv", "f_coarse+B", "f_remain+B", "f_remain+B+PI", "f_remain+B_fixed", "f_remain+B+PI_fixed"]


def stats(x: np.ndarray) -> dict:
    """{"mean", "std", "max"} of |x| over finite entries (NaN when none)."""
    a = np.abs(np.asarray(x, float))
    a = a[np.isfinite(a)]
    if a.size == 0:
        return {"mean": float("nan"), "std": float("nan"), "max": float("nan")}
    return {"mean": float(a.mean()), "std": float(a.std()), "max": float(a.max())}


def inverse_of(f, lo: float, hi: float, n: int = 20001):
    """Numerical inverse of a strictly monotone f on [lo - span, hi + span] by interpolation
    on n samples (f_remain's ends are linear, so the widened grid covers references slightly
    beyond the calibrated range). Returns a callable c -> q."""
    span = hi - lo
    g = np.linspace(lo - span, hi + span, n)
    fg = f(g)
    order = np.argsort(fg)
    return lambda c: np.interp(c, fg[order], g[order])


def reference_trajectory(cal: Calibration, duration_s: float = 60.0, rate_hz: float = 500.0,
                         margin: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Pseudo-periodic open-loop reference c*(t) (like the paper's Fig. 10 test motion):
    two incommensurate sines spanning the middle (1 - 2 margin) of f_remain's range over the
    calibrated travel, so reversals happen at many positions and amplitudes.
    Returns (t (N,) s, c* (N,) deg)."""
    q0, q1 = cal.q_range
    fc = cal.f_play(np.linspace(q0, q1, 257))
    lo, hi = float(fc.min()), float(fc.max())
    mid, amp = 0.5 * (lo + hi), 0.5 * (hi - lo) * (1 - 2 * margin)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    x = 0.65 * np.sin(2 * np.pi * t / 8.0) + 0.35 * np.sin(2 * np.pi * t / 2.9 + 0.7)
    return t, mid + amp * x


@dataclass
class Evaluation:
    """evaluate()'s result: ``summary`` is the JSON document (docs/calibration-format.md,
    `evaluate --json`); ``series`` holds the time series the report plots:
    t_f, Q (F, 2) measured px or None, c_meas (F,) deg, q_f (F,), pred {model: c (F,)},
    pred_Q {model: (F, 2)}, comp_t, comp_ref, comp_q {method: q}, comp_c {method: c} or {}."""

    summary: dict
    series: dict = field(default_factory=dict)


def evaluate(cal: Calibration, s: Session, table=None, plant=None, plant_note: str | None = None,
             comp_duration_s: float = 60.0, source: str | None = None) -> Evaluation:
    """Table I and the compensation test of ``cal`` on test session ``s``.

    table: a playscope.fit.table_build.CalibTable for the fixed-point rows (built from ``cal`` when
    None; skipped when the C core is unavailable); plant: callable (t (N,), q (N,)) -> c (N,)
    deg, or None (no compensation rows: a real recording has no plant; the pipeline passes
    sim.plant.session_plant(s) for a simulated session). Errors: InputError (naming ``source``) when the session
    has no valid frame or its actuator unit differs from the calibration's.
    """
    src = source or (str(s.path) if s.path else None)
    if s.actuator_unit != cal.actuator_unit:
        raise InputError(src, f"actuator unit {s.actuator_unit!r} differs from the calibration's "
                         f"{cal.actuator_unit!r}")
    t_enc, q = s.encoder["t_s"], s.encoder["q"]
    td = float(s.t_delay_s if s.t_delay_s is not None else cal.t_delay_s)
    t_f, obs = s.observations()
    ok = np.all(np.isfinite(obs), axis=1) & (t_f - td >= t_enc[0]) & (t_f - td <= t_enc[-1])
    if not ok.any():
        raise InputError(src, "no valid frame inside the encoder log's time span")
    t_f, obs = t_f[ok], obs[ok]
    fc = lambda x: model.f_coarse(x, cal.q_per_rad)

    # Table for the fixed-point rows (the same blob `playscope tables` writes).
    notes = []
    if table is None:
        try:
            from ..fit.table_build import build_table

            q0, q1 = cal.q_range
            table = build_table(cal.B_model, cal.f, q0, q1, cal.actuator_unit, "remain",
                                transition=cal.transition, relax=cal.relax)
            table_src = "built from the calibration"
        except Exception as e:  # no compiler / C core: float rows only
            table, table_src = None, None
            notes.append(f"fixed-point rows skipped: {e}")
    else:
        table_src = "given"

    # Direct models over the whole encoder log, then read at acquisition times (eqs. 2-3).
    z = model.play_operator(q, cal.B)
    c_enc = {"f_coarse": fc(q), "f_coarse+B": fc(z), "f_remain+B": cal.f_play(z)}
    if not cal.transition.is_play or cal.relax is not None:
        c_enc["f_remain+B+PI"] = cal.predict(q)
    fixed = None if table is None else ("f_remain+B+PI_fixed" if table.n_ops else "f_remain+B_fixed")
    if table is not None:
        c_enc[fixed] = table.predict(q)
    t_acq = t_f - td
    pred = {m: np.interp(t_acq, t_enc, c) for m, c in c_enc.items()}
    q_f = np.interp(t_acq, t_enc, q)

    table_i: dict = {}
    pred_Q: dict = {}
    Q = None
    if s.distal_kind == "image":
        im = model.ImageModel(s.robot, s.camera, s.hand_eye)
        Q = obs
        for m, c in pred.items():
            Qh = im(c)
            e = Qh - Q
            pred_Q[m] = Qh
            table_i[m] = {"Qx_px": stats(e[:, 0]), "Qy_px": stats(e[:, 1]), "dist_px": stats(np.hypot(e[:, 0], e[:, 1]))}
        c_meas = im.estimate_c(Q, fc(q_f))[0]
    else:
        c_meas = obs[:, 0]
        for m, c in pred.items():
            table_i[m] = {"c_deg": stats(c - c_meas), "c_rmse_deg": rmse(c - c_meas)}
    if s.truth is not None:
        c_true = np.interp(t_acq, s.truth["t_s"], s.truth["c_deg"])
        for m, c in pred.items():
            table_i[m]["c_rmse_truth_deg"] = rmse(c - c_true)

    # Compensation test (eq. 4 with 5 / 9) through the plant.
    if plant is None:
        plant_note = plant_note or NO_PLANT
    elif plant_note is None:
        plant_note = "plant given by the caller"
    rate = float(1.0 / np.median(np.diff(t_enc)))
    t_c, c_ref = reference_trajectory(cal, comp_duration_s, rate)
    q0, q1 = cal.q_range
    f_inv = inverse_of(cal.f_play, q0, q1)
    fc_inv = lambda c: model.f_coarse_inv(c, cal.q_per_rad)
    fc_sign = 1 if cal.q_per_rad > 0 else -1
    comp_q = {"f_coarse_inv": fc_inv(c_ref),
              "f_coarse+B": model.compensator(c_ref, cal.B, fc_inv, fc_sign),
              "f_remain+B": model.compensator(c_ref, cal.B, f_inv, cal.f_play_sign or cal.f_sign)}
    if not cal.transition.is_play or cal.relax is not None:
        f_inv_pi = inverse_of(cal.f, q0, q1)
        if cal.relax is not None:  # R^-1 on f^-1(c*), before the PI inverse (relax.py)
            f_inv_y, rl = f_inv_pi, cal.relax
            f_inv_pi = lambda c: rl.inverse(f_inv_y(c))  # noqa: E731
        comp_q["f_remain+B+PI"] = T.compensate_chain(c_ref, cal.B_model, cal.transition, f_inv_pi, cal.f_sign)
    if table is not None:
        comp_q[fixed] = table.compensate(c_ref)
    comp_c: dict = {}
    comp_res: dict = {}
    if plant is not None:
        skip = t_c >= 1.0  # the first second: the plant's play starts centred, the model's direction unknown
        im = model.ImageModel(s.robot, s.camera, s.hand_eye) if s.camera is not None and s.hand_eye is not None else None
        for m, qc in comp_q.items():
            c_act = np.asarray(plant(t_c, qc), float)
            comp_c[m] = c_act
            e = (c_act - c_ref)[skip]
            r = {"c_rmse_deg": rmse(e), "c_max_deg": float(np.max(np.abs(e)))}
            if im is not None:
                d = np.hypot(*(im(c_act[skip]) - im(c_ref[skip])).T)
                r["dist_px"] = stats(d)
            comp_res[m] = r
    summary = {
        "format": "playscope-evaluate/1",
        "session": src, "calibration": cal.source,
        "distal_kind": s.distal_kind, "t_delay_s": td, "frames_scored": int(t_f.size),
        "table": table_src,
        "prediction": table_i,
        "compensation": {"plant": plant_note if plant is not None else None, "note": plant_note,
                         "reference": {"duration_s": float(comp_duration_s), "rate_hz": rate,
                                       "c_min_deg": float(c_ref.min()), "c_max_deg": float(c_ref.max())},
                         "methods": comp_res},
        "notes": notes,
    }
    series = {"t_f": t_f, "Q": Q, "c_meas": c_meas, "q_f": q_f, "pred": pred, "pred_Q": pred_Q,
              "comp_t": t_c, "comp_ref": c_ref, "comp_q": comp_q, "comp_c": comp_c}
    return Evaluation(summary, series)


def format_table(summary: dict) -> str:
    """Markdown rendering of Table I and the compensation rows of evaluate()'s summary."""
    p = summary["prediction"]
    lines = []
    if summary["distal_kind"] == "image":
        lines += ["| model | Qx (px) | Qy (px) | distance (px) | max dist (px) |" +
                  (" c RMSE vs truth (deg) |" if any("c_rmse_truth_deg" in r for r in p.values()) else ""),
                  "|---|---|---|---|---|" + ("---|" if any("c_rmse_truth_deg" in r for r in p.values()) else "")]
        for m, r in p.items():
            row = (f"| {m} | {r['Qx_px']['mean']:.2f} ± {r['Qx_px']['std']:.2f} | {r['Qy_px']['mean']:.2f} ± "
                   f"{r['Qy_px']['std']:.2f} | {r['dist_px']['mean']:.2f} ± {r['dist_px']['std']:.2f} | "
                   f"{r['dist_px']['max']:.2f} |")
            if "c_rmse_truth_deg" in r:
                row += f" {r['c_rmse_truth_deg']:.3f} |"
            lines.append(row)
    else:
        lines += ["| model | c RMSE (deg) | mean ± std abs (deg) | max (deg) |", "|---|---|---|---|"]
        for m, r in p.items():
            lines.append(f"| {m} | {r['c_rmse_deg']:.3f} | {r['c_deg']['mean']:.3f} ± {r['c_deg']['std']:.3f} | "
                         f"{r['c_deg']['max']:.3f} |")
    comp = summary["compensation"]
    lines.append("")
    if comp["methods"]:
        lines += [f"Compensation, open loop through the plant ({comp['plant']}):", "",
                  "| command | c RMSE (deg) | c max (deg) | image distance (px) |", "|---|---|---|---|"]
        for m, r in comp["methods"].items():
            d = r.get("dist_px")
            lines.append(f"| {m} | {r['c_rmse_deg']:.3f} | {r['c_max_deg']:.3f} | " +
                         (f"{d['mean']:.2f} ± {d['std']:.2f} |" if d else "- |"))
    else:
        lines.append(f"Compensation: {comp['note']}")
    return "\n".join(lines)
