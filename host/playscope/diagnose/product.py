"""Shrink measured in the product: the test-part RMSE of `calibrate` (the
product's own model, float) fitted on the fit part of a record, without and with the effects the
diagnosis kept that the product can represent:
  smooth_transition -> the transition model of the model issue (calibrate model_kind="auto": the
                       calibration's own cross-validation on the fit part decides whether the
                       transition pays off; forcing "pi" on a record without one only adds
                       variance, 0.41 against 0.13 deg on an effect-free record),
  camera_delay      -> the kept delay applied to the product's prediction (angle sessions share the
                       encoder clock, so calibrate itself estimates none);
other kept effects have no counterpart in the product and are listed as such. Each model is
judged twice: in float (Calibration.predict) and through the fixed-point path the board runs
(tables.build_table -> the firmware's playop_step via cffi, the same table `calibrate` writes;
the delay is applied to the table's output, as the board's latency compensation would).
"""

from __future__ import annotations

import numpy as np

from ..fit.calibration import calibrate
from ..io.session import Session
from ..fit.table_build import TableError, build_table


def _until(s: Session, t_end: float) -> Session:
    enc = {k: v[s.encoder["t_s"] <= t_end] for k, v in s.encoder.items()}
    dist = {k: v[s.distal["t_s"] <= t_end] for k, v in s.distal.items()}
    return Session(actuator_unit=s.actuator_unit, distal_kind=s.distal_kind, robot=s.robot, encoder=enc,
                   distal=dist, t_delay_s=s.t_delay_s, meta=dict(s.meta), path=s.path)


def product_rmse(session: Session, data, fit_mask: np.ndarray, test_mask: np.ndarray, kept: list,
                 delay_s: float = 0.0) -> dict:
    """{"play", "with_kept" (float), "play_fixed", "with_kept_fixed" (fixed-point table through the
    firmware's playop_step; NaN with "fixed_error" when the table cannot be built): RMSE in deg on
    the test rows of ``data`` (diagnose Data of the same session), "model": "pi" or "play" (what the
    with-kept calibration chose),
    "not_in_product": [...]}; fit on rows up to the last fit row (angle sessions only)."""
    if session.distal_kind != "angle":
        raise ValueError("product shrink: angle sessions only")
    t_end = float(data.t_m[fit_mask].max())
    sub = _until(session, t_end)
    t = session.encoder["t_s"]
    out = {"not_in_product": [e for e in kept if e not in ("smooth_transition", "camera_delay")]}
    for label, kind, delay in (("play", "play", 0.0),
                               ("with_kept", "auto" if "smooth_transition" in kept else "play",
                                delay_s if "camera_delay" in kept else 0.0)):
        cal = calibrate(sub, model_kind=kind, source=str(session.path or "record"))
        q = session.encoder["q"]

        def rmse(c):
            pred = np.interp(data.t_m - data.t_delay_s - delay, t, c)  # declared acquisition delay too
            r = (data.y_m - pred)[test_mask & np.isfinite(data.y_m)]
            return float(np.sqrt(np.mean(r * r)))
        out[label] = rmse(cal.predict(q))
        try:
            q0, q1 = cal.q_range
            tab = build_table(cal.B_model, cal.f, q0, q1, cal.actuator_unit, "remain",
                              transition=cal.transition)
            out[label + "_fixed"] = rmse(tab.predict(q))
        except (TableError, OverflowError) as exc:
            out[label + "_fixed"] = float("nan")
            out.setdefault("fixed_error", {})[label] = str(exc)
        if label == "with_kept":
            out["model"] = "play" if cal.transition.is_play else "pi"  # what the product chose
    return out
