"""The record's image curve: where the marker lies in the image for each position z of the play's
centre, one smooth curve for the whole record (used by the actuator-shape onset model,
playscope.fit.onset_play).

The marker is Q = h(g(f(z))) (eqs. 6-7 with c = f(z)): a fixed smooth map of z, the same at
every reversal. Fitting it once, over the whole travel and every frame, leaves each reversal's
B sample to be measured from the timing of the motion against the encoder alone (eq. 1); a
polynomial of z free at every reversal, fitted on the few frames of a fast swing, trades its
curvature with b (sd of the B samples 0.043 mm against 0.016 mm on a 25 fps fast-swing rendering,
true delay and true B(q) given, both ways).

    Q_k = G(z(t_k - t_delay)) + J dir_k + e_k

G: a cubic B-spline per image axis, INTERVALS even knot intervals over the z range;
z: the play operator (eq. 3) of the encoder record with a first B(q); dir_k: the sign of the
tip's last motion (a hand-eye error that follows the direction of motion, as the paper's Fig. 7
simulation has, shifts the image by J; without one J is ~0). J is only there so that G is not bent by such a
jump: a constant J and b trade one for one, so the onset model takes its jump from the onsets'
timing (onset_play._jump_profile), not from here. (A rotation of the view moves J over the
travel, 1.4 px of 31 px on a 1.5 deg registration rendering; taking that change from here into
the onset model made dev-reg-swings25 worse, 8.2 -> 11.0 %, and is not done.) Frames within SKIP_FRAMES frame
periods after a reversal of z are left out (where a direction-following jump lands, and where
the onset's timing is what is measured). Least squares, then once more without frames beyond
OUTLIER_K robust standard deviations (a marker mis-detection).

z is only as right as the first B(q) it comes from: a wrong B shifts the up- and down-going
branches of z apart, which J and G absorb between them; the onset model keeps a free offset and
slope per reversal on top of G, so that only G's shape is relied on (with B(q) off by a constant
0.05-0.15 mm, the B samples' mean error stayed within 0.002 mm on the same rendering).

Units: t s, q and z actuator units, image px.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline

from .model import held_direction, play_operator

INTERVALS = 14        # knot intervals over the z range (a 4 mm travel: one per 0.3 mm)
SKIP_FRAMES = 2.0     # frames after each reversal of z left out of the fit
OUTLIER_K = 5.0       # residuals beyond this many robust sd are left out of the second pass
MIN_FRAMES = 40       # fewer frames than this: no curve


@dataclass
class ImageCurve:
    """G(z) (px) over [z_lo, z_hi] (held constant beyond), J (2,) px, and the fit's figures."""

    knots: np.ndarray
    coef: np.ndarray      # (n_ctrl, 2)
    z_lo: float
    z_hi: float
    jump_px: np.ndarray   # (2,)
    rms_px: np.ndarray    # (2,) residual rms of the second pass
    frames: int

    def __call__(self, z: np.ndarray) -> np.ndarray:
        """G(z): z any shape (actuator units) -> shape + (2,) px."""
        z = np.asarray(z, float)
        zz = np.clip(z, self.z_lo, self.z_hi).ravel()
        return (BSpline.design_matrix(zz, self.knots, 3) @ self.coef).reshape(z.shape + (2,))

    def doc(self) -> dict:
        """JSON-ready summary for the calibration record."""
        return {"z_range": [self.z_lo, self.z_hi], "intervals": int(self.knots.size - 7),
                "jump_px": [float(x) for x in self.jump_px], "rms_px": [float(x) for x in self.rms_px],
                "frames": self.frames}


def fit_image_curve(t_enc: np.ndarray, q: np.ndarray, t_f: np.ndarray, obs: np.ndarray, t_delay_s: float,
                    b_of_q, period_s: float) -> ImageCurve | None:
    """Fit G and J (module doc) at delay t_delay_s with the play width b_of_q (callable q -> B).

    t_enc, q (N,) encoder; t_f (F,) frame stamps, obs (F, 2) px (NaN = lost); period_s the frame
    period. Returns ImageCurve, or None with fewer than MIN_FRAMES usable frames or no z range."""
    t_enc, q = np.asarray(t_enc, float), np.asarray(q, float)
    z = play_operator(q, b_of_q)
    ts = np.asarray(t_f, float) - t_delay_s
    ok = np.all(np.isfinite(obs), axis=1) & (ts >= t_enc[0]) & (ts <= t_enc[-1])
    held = held_direction(z, 1e-12)
    flips = t_enc[np.nonzero(np.diff(held))[0] + 1]
    zk = np.interp(ts, t_enc, z)
    dk = held[np.clip(np.searchsorted(t_enc, ts, side="right") - 1, 0, t_enc.size - 1)]
    if flips.size:
        j = np.searchsorted(flips, ts, side="right") - 1
        since = ts - flips[np.clip(j, 0, flips.size - 1)]
        ok &= ~((j >= 0) & (since < SKIP_FRAMES * period_s))
    if ok.sum() < MIN_FRAMES:
        return None
    z_lo, z_hi = float(zk[ok].min()), float(zk[ok].max())
    if not z_hi > z_lo:
        return None
    knots = np.r_[[z_lo] * 3, np.linspace(z_lo, z_hi, INTERVALS + 1), [z_hi] * 3]
    Y = np.asarray(obs, float)
    keep = ok.copy()
    for first in (True, False):
        A = np.column_stack([BSpline.design_matrix(np.clip(zk[keep], z_lo, z_hi), knots, 3).toarray(), dk[keep]])
        coef, *_ = np.linalg.lstsq(A, Y[keep], rcond=None)
        res = Y[keep] - A @ coef
        if not first:
            break
        sd = 1.4826 * np.median(np.abs(res - np.median(res, axis=0)), axis=0)
        out = np.any(np.abs(res) > OUTLIER_K * np.maximum(sd, 1e-9), axis=1)
        if not out.any() or (keep.sum() - out.sum()) < MIN_FRAMES:
            break
        keep[np.nonzero(keep)[0][out]] = False
    # The figures of the fit returned: its residual rms over the frames it was fitted on.
    rms = np.sqrt(np.mean(res * res, axis=0))
    return ImageCurve(knots, coef[:-1], z_lo, z_hi, coef[-1], rms, int(keep.sum()))
