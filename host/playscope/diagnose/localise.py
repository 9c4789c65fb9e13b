"""Localisation of the gap: residuals of a fitted model broken down by time and motor travel since
the last reversal and by direction, by q and c, by speed, over wall-clock time, by image position
(image sessions), plus the spectrum and the cross-correlation with the distal (image) velocity.

Every breakdown is binned RMS of the residual (deg) with the bin centres, so the JSON carries the
residual atlas and diagnosis_report.py draws it.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import correlate, welch

from ..fit.model import held_direction
from .fitmodel import Data


def reversal_features(data: Data) -> dict[str, np.ndarray]:
    """Per measurement row: motor direction (+1/-1), travel (mm) and time (s) since the last
    actuator reversal, q (mm) and speed |dq/dt| (mm/s), all at t - t_delay."""
    t, q = data.t_int, data.q_int
    dirn = held_direction(q, 1e-9)
    rev = np.r_[True, dirn[1:] != dirn[:-1]]
    last = np.maximum.accumulate(np.where(rev, np.arange(t.size), 0))
    travel = np.abs(q - q[last])
    since = t - t[last]
    speed = np.abs(np.gradient(q, t))
    k = np.clip(np.searchsorted(t, data.t_m - data.t_delay_s) - 1, 0, t.size - 1)
    return {"direction": dirn[k], "travel_mm": travel[k], "time_s": since[k], "q_mm": q[k], "speed_mm_s": speed[k]}


def binned(x: np.ndarray, r: np.ndarray, bins: int = 12) -> dict:
    """RMS and mean of r in quantile bins of x: {"x", "rms", "mean", "n"} (lists)."""
    ok = np.isfinite(x) & np.isfinite(r)
    x, r = x[ok], r[ok]
    if x.size < bins * 3:
        return {"x": [], "rms": [], "mean": [], "n": []}
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    ids = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
    out = {"x": [], "rms": [], "mean": [], "n": []}
    for b in range(edges.size - 1):
        m = ids == b
        if m.sum() == 0:
            continue
        out["x"].append(float(np.mean(x[m])))
        out["rms"].append(float(np.sqrt(np.mean(r[m] ** 2))))
        out["mean"].append(float(np.mean(r[m])))
        out["n"].append(int(m.sum()))
    return out


def atlas(data: Data, pred: np.ndarray, mask: np.ndarray | None = None) -> dict:
    """Residual atlas of y - pred on rows ``mask`` (default: all). Keys: by_travel_up/down,
    by_time_since_reversal, by_q, by_c, by_speed, by_speed_signed (residual x direction), by_wallclock,
    by_direction, by_u/by_v (image),
    spectrum {"f_hz", "psd"}, xcorr_velocity {"lag_s", "r"}, rms."""
    r = data.y_m - pred
    m = np.isfinite(r) if mask is None else (mask & np.isfinite(r))
    f = reversal_features(data)
    out = {"rms": float(np.sqrt(np.mean(r[m] ** 2)))}
    for dname, dv in (("up", 1.0), ("down", -1.0)):
        mm = m & (f["direction"] == dv)
        out[f"by_travel_{dname}"] = binned(f["travel_mm"][mm], r[mm])
    out["by_time_since_reversal"] = binned(f["time_s"][m], r[m])
    out["by_q"] = binned(f["q_mm"][m], r[m])
    out["by_c"] = binned(data.y_m[m], r[m])
    out["by_speed"] = binned(f["speed_mm_s"][m], r[m])
    # Residual times the motor direction, by speed: a lag that grows with speed (viscous
    # hysteresis, a delay, elongation) shows as a mean growing in magnitude with speed; a
    # rate-independent play error does not.
    out["by_speed_signed"] = binned(f["speed_mm_s"][m], (r * f["direction"])[m])
    out["by_wallclock"] = binned(data.t_m[m], r[m])
    out["by_direction"] = {str(int(dv)): {"mean": float(np.mean(r[m & (f["direction"] == dv)])) if np.any(m & (f["direction"] == dv)) else None,
                                          "rms": float(np.sqrt(np.mean(r[m & (f["direction"] == dv)] ** 2))) if np.any(m & (f["direction"] == dv)) else None}
                           for dv in (1.0, -1.0)}
    if "u" in data.extra:
        out["by_u"] = binned(data.extra["u"][m], r[m])
        out["by_v"] = binned(data.extra["v"][m], r[m])
    # Spectrum and cross-correlation need a uniform series: the rows are (nearly) uniform.
    rr = np.where(m, r, 0.0)
    dt = float(np.median(np.diff(data.t_m)))
    fs = 1.0 / dt
    fr, psd = welch(rr, fs=fs, nperseg=min(1024, rr.size))
    out["spectrum"] = {"f_hz": fr.tolist(), "psd": psd.tolist()}
    # Velocity of the distal measurement: image velocity's projection on the motion (dc/dt).
    v = np.gradient(np.nan_to_num(data.y_m), data.t_m)
    v = np.where(m, v - np.mean(v[m]), 0.0)
    rc = np.where(m, rr - np.mean(rr[m]), 0.0)
    maxlag = int(round(1.0 * fs))
    xc = correlate(rc, v, mode="full") / (np.linalg.norm(rc) * np.linalg.norm(v) + 1e-12)
    mid = xc.size // 2
    lags = np.arange(-maxlag, maxlag + 1)
    out["xcorr_velocity"] = {"lag_s": (lags * dt).tolist(), "r": xc[mid - maxlag: mid + maxlag + 1].tolist()}
    return out
