"""Image-geometry screen: effects that act on h and g only (lens_distortion, nonconstant_curvature)
are invisible in c once f_remain is refitted, but they move the marker off the path h(g(c)) of the
nominal model. Per frame, c is re-estimated (eq. 8) for a candidate parameter and the reprojection
residual (px, across the path) is what the parameter must lower, on held-out frames.

Same decision rule as attribute.py: the held-out reprojection RMS must drop by a practical margin
(max(8 %, 0.05 px)) and the BIC (effective sample size from the residual autocorrelation) agree.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from scipy.integrate import cumulative_trapezoid

from ..fit import model as M

GEOM = {"lens_distortion": ("dk1", (-0.5, 0.5)), "nonconstant_curvature": ("gamma", (-0.9, 0.9))}


def _tip_graded(c_deg: np.ndarray, L: float, l_tip: float, gamma: float) -> np.ndarray:
    """Tip position (..., 3) mm for a curvature graded along the section, kappa(s) = c/L (1 +
    gamma (2 s/L - 1)) (same total bend c): the tangent angle is integrated in closed form,
    theta(s) = c (s + gamma (s^2/L - s)) / L, the position by the trapezoid rule on 129 points.
    gamma = 0 is model.constant_curvature (the diagnosis' own form; the simulator keeps its own)."""
    if gamma == 0.0:
        return M.constant_curvature(c_deg, L, l_tip)
    c = np.radians(np.asarray(c_deg, float))[..., None]
    s = np.linspace(0.0, L, 129)
    th = c * (s + gamma * (s * s / L - s)) / L
    x = cumulative_trapezoid(np.sin(th), s, axis=-1)[..., -1]
    z = cumulative_trapezoid(np.cos(th), s, axis=-1)[..., -1]
    c = c[..., 0]
    return np.stack([x + l_tip * np.sin(c), np.zeros_like(x), z + l_tip * np.cos(c)], axis=-1)


class _Geom(M.ImageModel):
    """ImageModel with an extra radial term dk1 and a linear curvature gradient gamma."""

    def __init__(self, session, dk1=0.0, gamma=0.0):
        super().__init__(session.robot, session.camera, session.hand_eye)
        self.dist = self.dist.copy()
        self.dist[0] += dk1
        self.gamma = gamma

    def __call__(self, c_deg):
        P = _tip_graded(c_deg, self.L, self.l, self.gamma)
        return M.project(P, self.R, self.t, self.K, self.dist)


def _reproj(session, Q, c0, **kw) -> tuple[np.ndarray, np.ndarray]:
    im = _Geom(session, **kw)
    c, r = im.estimate_c(Q, c0, iters=15)
    return c, r


def screen(session, data, fit_mask, eval_mask, margin_frac=0.08, margin_abs=0.05, bic_min=10.0) -> dict:
    """Screen GEOM effects on an image session. Returns {"base_px": {"fit", "heldout"},
    "screen": [{effect, param, value, heldout_px, delta_bic, kept}], "kept": [names]}."""
    Q = np.column_stack([data.extra["u"], data.extra["v"]])
    c0 = np.nan_to_num(data.y_m)
    ok = np.all(np.isfinite(Q), 1)
    _, r0 = _reproj(session, Q, c0)

    def rms(r, m):
        m = m & ok & np.isfinite(r)
        return float(np.sqrt(np.mean(r[m] ** 2)))

    def neff(r, m):
        rr = r[m & ok & np.isfinite(r)]
        rho = min(max(float(np.corrcoef(rr[:-1], rr[1:])[0, 1]), 0.0), 0.9) if rr.size > 3 else 0.0
        return max(rr.size * (1 - rho) / (1 + rho), 10.0), float(np.sum(rr * rr))

    out = {"base_px": {"fit": rms(r0, fit_mask), "heldout": rms(r0, eval_mask)}, "screen": [], "kept": []}
    base_h = out["base_px"]["heldout"]
    _, rss0 = neff(r0, fit_mask)
    for name, (p, bounds) in GEOM.items():
        res = minimize_scalar(lambda v: rms(_reproj(session, Q, c0, **{p: v})[1], fit_mask), bounds=bounds,
                              method="bounded", options={"xatol": 1e-3})
        _, r1 = _reproj(session, Q, c0, **{p: res.x})
        n, rss1 = neff(r1, fit_mask)
        dbic = float(n * np.log(rss1 / rss0) + np.log(n))
        h = rms(r1, eval_mask)
        kept = bool(base_h - h >= max(margin_frac * base_h, margin_abs) and dbic < -bic_min)
        out["screen"].append({"effect": name, "param": p, "value": float(res.x), "heldout_px": h,
                              "delta_bic": dbic, "kept": kept})
    best = sorted([s for s in out["screen"] if s["kept"]], key=lambda s: s["heldout_px"])
    out["kept"] = [s["effect"] for s in best[:1]]
    return out
