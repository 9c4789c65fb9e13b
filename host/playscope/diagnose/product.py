"""Shrink measured in the product (issue 10 item 4): the test-part RMSE of `calibrate` (the
product's own model, float) fitted on the fit part of a record, without and with the effects the
diagnosis kept that the product can represent:
  smooth_transition -> the transition model of the model issue (calibrate model_kind="pi"),
  camera_delay      -> the kept delay applied to the product's prediction (angle sessions share the
                       encoder clock, so calibrate itself estimates none);
other kept effects have no counterpart in the product and are listed as such. The fixed-point
tables are not evaluated here (the host's native build must match the merged C first).
"""

from __future__ import annotations

import numpy as np

from ..calibration import calibrate
from ..session import Session


def _until(s: Session, t_end: float) -> Session:
    enc = {k: v[s.encoder["t_s"] <= t_end] for k, v in s.encoder.items()}
    dist = {k: v[s.distal["t_s"] <= t_end] for k, v in s.distal.items()}
    return Session(actuator_unit=s.actuator_unit, distal_kind=s.distal_kind, robot=s.robot, encoder=enc,
                   distal=dist, t_delay_s=s.t_delay_s, meta=dict(s.meta), path=s.path)


def product_rmse(session: Session, data, fit_mask: np.ndarray, test_mask: np.ndarray, kept: list,
                 delay_s: float = 0.0) -> dict:
    """{"play": RMSE, "with_kept": RMSE, "model": model_kind, "not_in_product": [...]} in deg on
    the test rows of ``data`` (diagnose Data of the same session); fit on rows up to the last fit row
    (angle sessions only)."""
    if session.distal_kind != "angle":
        raise ValueError("product shrink: angle sessions only")
    t_end = float(data.t_m[fit_mask].max())
    sub = _until(session, t_end)
    t = session.encoder["t_s"]
    out = {"not_in_product": [e for e in kept if e not in ("smooth_transition", "camera_delay")]}
    for label, kind, delay in (("play", "play", 0.0),
                               ("with_kept", "pi" if "smooth_transition" in kept else "play",
                                delay_s if "camera_delay" in kept else 0.0)):
        cal = calibrate(sub, model_kind=kind, source=str(session.path or "record"))
        c = cal.predict(session.encoder["q"])
        pred = np.interp(data.t_m - data.t_delay_s - delay, t, c)  # declared acquisition delay too
        r = (data.y_m - pred)[test_mask & np.isfinite(data.y_m)]
        out[label] = float(np.sqrt(np.mean(r * r)))
        if label == "with_kept":
            out["model"] = kind
    return out
