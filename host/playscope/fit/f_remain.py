"""f_remain: the characteristic after the play (paper section IV): the (q, c) pairs at each
frame's acquisition time, the play-consistent monotone least-squares fit with its control
points by cross-validation, and the paper's morphological median line.

Units: q in actuator units, c in deg.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline
from scipy.optimize import lsq_linear

from . import model
from .bspline import SplineFn, _diff_penalty, clamped_knots, design_dense, robust_spline

def characteristic(t_enc, q, t_f, c_f, t_delay_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (q, c) of the characteristic (Fig. 9): each valid frame with the actuator
    position at its acquisition time t - t_delay. Returns (q (F,), c (F,))."""
    ok = np.isfinite(c_f)
    return np.interp(t_f[ok] - t_delay_s, t_enc, q), c_f[ok]


def f_remain_lsq(q_c: np.ndarray, c: np.ndarray, B, n_ctrl: int = 14, smooth: float = 1e-3,
                 z_range: tuple[float, float] | None = None, z: np.ndarray | None = None,
                 min_slope: float = 0.0):
    """f_remain by play-consistent least squares (our estimator).

    With B fixed from the onsets, the play operator gives the centre z[k] from q alone
    (eq. 3), and the model says c[k] = f(z[k]); f is then a monotone robust spline
    regression of c on z, using every frame (transitions included) instead of the loop's
    outline only. q_c, c: (F,) in time order; z: the play centre if the caller has it
    (model.play_operator(q_c, B)); min_slope: |f'| >= min_slope, deg per actuator unit
    (robust_spline). Returns (SplineFn, sign of f', z (F,)).
    """
    z = model.play_operator(q_c, B) if z is None else np.asarray(z, float)
    sign = 1 if np.corrcoef(z, c)[0, 1] >= 0 else -1
    lo, hi = (float(z.min()), float(z.max())) if z_range is None else z_range
    spl, _ = robust_spline(z, c, n_ctrl, lo, hi, smooth, monotone=sign, min_slope=min_slope)
    return SplineFn(spl, lo, hi, linear_ends=True), sign, z


# f_remain's stiffness: its number of control points, chosen by cross-validation on
# the calibration frames. Candidates fixed a priori: a single cubic (4) up to 2x the paper's 14.
F_CTRL_GRID = (4, 6, 8, 10, 14, 20, 28)
F_FRAMES_PER_CTRL = 10  # a candidate needs >= 10 training frames per coefficient in every fold


def _monotone_pspline(x: np.ndarray, y: np.ndarray, n_ctrl: int, lo: float, hi: float, smooth: float,
                      sign: int) -> SplineFn:
    """robust_spline's first (unweighted) iteration, monotone, solved on its normal equations:
    with N = A'A + lam D'D = R'R (Cholesky) the F-row problem equals ||R c - R^-T A'y||^2 + const,
    an n_ctrl-row bounded least squares (bvls), so a fit costs one design matrix and an n x n
    solve. For the cross-validation's many fits (the final fit is the robust one). Returns the
    SplineFn with linear ends over [lo, hi], as f_remain_lsq's."""
    from scipy.linalg import cho_factor, solve_triangular

    t = clamped_knots(lo, hi, n_ctrl)
    A = design_dense(np.clip(x, lo, hi), t, n_ctrl)
    D = _diff_penalty(n_ctrl)
    AtA = A.T @ A
    lam = smooth * max(np.trace(AtA) / n_ctrl, 1e-12)
    N = AtA + lam * (D.T @ D) + 1e-12 * np.eye(n_ctrl) * max(np.trace(AtA), 1.0)
    R, _ = cho_factor(N, lower=False)
    R = np.triu(R)
    rhs = solve_triangular(R, A.T @ y, trans="T", lower=False)
    Tm = np.tril(np.ones((n_ctrl, n_ctrl))) * np.where(np.arange(n_ctrl) == 0, 1.0, float(sign))[None, :]
    lb = np.r_[-np.inf, np.zeros(n_ctrl - 1)]
    th = lsq_linear(R @ Tm, rhs, bounds=(lb, np.full(n_ctrl, np.inf)), method="bvls").x
    return SplineFn(BSpline(t, Tm @ th, 3, extrapolate=False), lo, hi, linear_ends=True)


def choose_f_ctrl(z: np.ndarray, c: np.ndarray, splits, grid=F_CTRL_GRID, smooth: float = 1e-3) -> dict:
    """f_remain's stiffness (control points N) by cross-validation on the calibration frames.

    z, c: (F,) play centre (eq. 3, actuator units) and angle (deg) at the calibration frames, in
    time order. splits: [(train mask (F,), test mask (F,))], the rolling origins of the
    transition's model choice (transition.rolling_origins: fit on the frames before each origin,
    score the next block), so f is judged as the board uses it: fitted on the past, predicting
    frames that come after, whose z may reach beyond the trained range (linear ends, as the
    tables). Each candidate N of ``grid`` (at most one per F_FRAMES_PER_CTRL frames of the
    smallest training part; 4, a single cubic, always) is fitted on each training part by the
    monotone P-spline (_monotone_pspline, the penalty ``smooth`` relative to the data term as in
    robust_spline), scored by the held-out RMSE per fold; cv = rms over folds, se = their standard
    error. Choice: the lowest CV RMSE. The one-standard-error rule (Hastie, Tibshirani & Friedman,
    ESL 2nd ed., 7.10) was the first rule; its stiffer picks generalised worse (an effect-free
    simulated record: 0.31 against 0.13 deg on the judged part; the catheter's least-squares
    f_remain row: 1.20 against 0.83 deg mean), and f is already regularised by its penalty, so
    the choice is the CV's minimum (docs/robustness.md). Returns {"n_ctrl": N,
    "rule": str, "candidates": [{"n_ctrl", "cv_rmse_deg", "cv_se_deg"}]}; n_ctrl is None when no
    fold has frames to judge (the caller keeps its default). Errors: none (bad folds are skipped).
    """
    z, c = np.asarray(z, float), np.asarray(c, float)
    folds = [(tr, te) for tr, te in splits if te.sum() >= 3 and tr.sum() >= 4 * F_FRAMES_PER_CTRL]
    rule = "CV on a rolling origin (fit before, score the next block), the lowest CV RMSE"
    if not folds:
        return {"n_ctrl": None, "rule": rule + " (no fold with frames to judge)", "candidates": []}
    n_max = min(int(tr.sum()) for tr, _ in folds) // F_FRAMES_PER_CTRL
    grid = [int(n) for n in grid if n <= n_max] or [4]
    sign = 1 if np.corrcoef(z, c)[0, 1] >= 0 else -1
    rows = []
    for n in grid:
        errs = []
        for tr, te in folds:
            lo, hi = float(z[tr].min()), float(z[tr].max())
            if hi <= lo:
                continue
            f = _monotone_pspline(z[tr], c[tr], n, lo, hi, smooth, sign)
            errs.append(float(np.sqrt(np.mean((f(z[te]) - c[te]) ** 2))))
        if not errs:
            continue
        e = np.array(errs)
        rows.append({"n_ctrl": n, "cv_rmse_deg": float(np.sqrt(np.mean(e ** 2))),
                     "cv_se_deg": float(np.std(e, ddof=1) / np.sqrt(e.size)) if e.size > 1 else 0.0})
    if not rows:
        return {"n_ctrl": None, "rule": rule + " (no fold with a z range)", "candidates": []}
    # The argmin, not the one-standard-error rule: f is a penalised spline (already regularised),
    # and on an effect-free simulated record the one-SE rule's stiffer pick (N = 8, CV 0.242
    # against 0.208 for N = 14, within one SE) gave 0.31 deg on the judged part against 0.13.
    pick = min(rows, key=lambda d: d["cv_rmse_deg"])
    return {"n_ctrl": int(pick["n_ctrl"]), "rule": rule, "candidates": rows}


def f_remain_morph(q_c: np.ndarray, c: np.ndarray, n_ctrl: int = 14, size: int = 512, close_px: int = 7,
                   smooth: float = 1e-3, min_slope: float = 0.0):
    """f_remain by the paper's method (section IV): the characteristic drawn as an image,
    holes filled by morphology, then for each row (a value of c) the middle between the
    leftmost and rightmost filled pixels (extremal horizontal values), then a spline.

    The polyline through consecutive (q, c) pairs is drawn at size x size px, closed with
    a close_px elliptic kernel (joins the loop's outline where samples are sparse), and
    the inside of each loop filled by flood-filling the background from the border.
    Returns (SplineFn, sign of f', (q_mid, c_row) samples).
    """
    import cv2

    qlo, qhi = float(q_c.min()), float(q_c.max())
    clo, chi = float(c.min()), float(c.max())
    sx = (size - 1) / max(qhi - qlo, 1e-12)
    sy = (size - 1) / max(chi - clo, 1e-12)
    pts = np.column_stack([(q_c - qlo) * sx, (chi - c) * sy])  # row 0 = largest c
    # A free margin wider than the kernel keeps the background ring connected, so the
    # flood fill from a corner reaches every outside pixel.
    m = close_px + 2
    img = np.zeros((size + 2 * m, size + 2 * m), np.uint8)
    cv2.polylines(img, [np.round(pts + m).astype(np.int32).reshape(-1, 1, 2)], False, 255, 1)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (close_px, close_px))
    img = cv2.morphologyEx(img, cv2.MORPH_CLOSE, k)
    flood = img.copy()
    mask = np.zeros((img.shape[0] + 2, img.shape[1] + 2), np.uint8)
    cv2.floodFill(flood, mask, (0, 0), 255)
    filled = img | cv2.bitwise_not(flood)
    rows = np.nonzero(filled.any(axis=1))[0]
    q_mid, c_row = [], []
    for r in rows:
        cols = np.nonzero(filled[r])[0]
        q_mid.append(0.5 * (cols[0] + cols[-1] - 2 * m) / sx + qlo)
        c_row.append(chi - (r - m) / sy)
    q_mid, c_row = np.array(q_mid), np.array(c_row)
    sign = 1 if np.corrcoef(q_c, c)[0, 1] >= 0 else -1
    spl, _ = robust_spline(q_mid, c_row, n_ctrl, qlo, qhi, smooth, monotone=sign, min_slope=min_slope)
    return SplineFn(spl, qlo, qhi, linear_ends=True), sign, (q_mid, c_row)
