"""B(q) from the onset samples (paper Fig. 4, section III-C): the robust spline of the play
width, its stiffness and control points by cross-validation, the constant B for few samples,
and the alternatives the model choice scores.

Units: q and B in actuator units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline

from .bspline import SplineFn, clamped_knots, robust_spline
from ..base.errors import InputError

@dataclass
class BacklashFit:
    """B(q) spline and what the fit made of each sample (M,): weight (normalised to max 1),
    z the standardised residual (residual / its standard deviation: the sample's sigma and
    the scatter between samples), and inconsistent = |z| > 3.5 (modified z-score rule of
    Iglewicz & Hoaglin 1993), samples the fit disagrees with rather than averages."""

    B: "SplineFn"
    weight: np.ndarray
    z: np.ndarray
    inconsistent: np.ndarray
    scatter: float
    kind: str = "spline"              # "spline" (B(q)) or "constant" (too few samples for a shape)
    n_ctrl: int = 0                   # control points used (4 for a constant)
    smooth: float | None = None       # difference-penalty weight (chosen by cross-validation)
    ci95: tuple[float, float] | None = None  # constant B: 95 % confidence interval, None if unknown
    cv: dict | None = None            # the stiffness choice: candidates and their CV scores


Z_INCONSISTENT = 3.5


def fit_backlash_samples(q_mean: np.ndarray, b: np.ndarray, n_ctrl: int = 14, smooth: float = 1e-3,
                         q_range: tuple[float, float] | None = None, source: str | None = None,
                         max_slope: float = 1.5, sigma: np.ndarray | None = None) -> BacklashFit:
    """B(q) from onset samples (section III-B): robust cubic B-spline, N control points,
    constrained to B >= 0 and |B'| <= max_slope, each sample weighted by its uncertainty.

    N = 14 is the paper's setting; with fewer samples than control points the difference
    penalty carries the fit (shape between samples is then the smoothest one). |B'| < 2 is
    physical (eq. 2: the envelopes would fold back) and the firmware's loader refuses steeper
    tables, so max_slope = 1.5 keeps a margin. q_mean, b, sigma: (M,) actuator units (sigma
    None: equal weights). Errors: InputError (naming ``source``) with fewer than 4 samples.
    """
    if q_mean.size < 4:
        raise InputError(source, f"only {q_mean.size} valid backlash samples (need >= 4 reversals with a "
                         f"detected onset); record a longer excitation")
    lo, hi = (float(np.min(q_mean)), float(np.max(q_mean))) if q_range is None else q_range
    if hi - lo <= 0:
        raise InputError(source, "all backlash samples at the same actuator position")
    spl, w = robust_spline(q_mean, b, n_ctrl, lo, hi, smooth, sigma=sigma, lower=0.0, max_slope=max_slope)
    r = b - spl(np.clip(q_mean, lo, np.nextafter(hi, -np.inf)))
    s = 1.4826 * float(np.median(np.abs(r - np.median(r)))) + 1e-12
    if sigma is None:
        z = r / s
        scatter = s
    else:
        sig2 = np.asarray(sigma, float) ** 2
        scatter = float(np.sqrt(max(s * s - float(np.median(sig2)), 0.0)))
        z = r / np.sqrt(sig2 + max(scatter * scatter, 1e-6 * s * s))
    return BacklashFit(SplineFn(spl, lo, hi, linear_ends=False, floor=0.0), w, z, np.abs(z) > Z_INCONSISTENT, scatter)


def fit_backlash(q_mean: np.ndarray, b: np.ndarray, n_ctrl: int = 14, smooth: float = 1e-3,
                 q_range: tuple[float, float] | None = None, source: str | None = None, max_slope: float = 1.5,
                 sigma: np.ndarray | None = None):
    """fit_backlash_samples, returning (SplineFn, weights (M,)) only."""
    f = fit_backlash_samples(q_mean, b, n_ctrl, smooth, q_range, source, max_slope, sigma)
    return f.B, f.weight


# --------------------------------------------------------------------------- B from few or many samples
MIN_SPLINE_SAMPLES = 4  # a cubic needs 4 coefficients: fewer samples give a constant B


def _constant_spline(value: float, lo: float, hi: float) -> SplineFn:
    """A B(q) SplineFn equal to value everywhere (clamped cubic, 4 equal coefficients), so
    tables and the model read a constant B like any other."""
    if not hi > lo:
        lo, hi = lo - 0.5, hi + 0.5
    t = clamped_knots(lo, hi, 4)
    return SplineFn(BSpline(t, np.full(4, float(value)), 3, extrapolate=False), lo, hi, linear_ends=False, floor=0.0)


def constant_backlash(b: np.ndarray, sigma: np.ndarray | None = None,
                      q_range: tuple[float, float] = (0.0, 1.0)) -> tuple[float, tuple[float, float] | None]:
    """Constant B from M >= 1 onset samples b (M,) and its 95 % confidence interval.

    Weighted mean with weights 1 / sigma^2 (equal without sigma). Interval: Student t with
    M - 1 degrees of freedom on the samples' own scatter (M >= 2), widened to the sigmas'
    standard error when that is larger; one sample: +-1.96 sigma, or None without sigma.
    Returns (B, (lo, hi) or None). Units: actuator units."""
    # The Student t quantile straight from scipy.special (what scipy.stats.t.ppf evaluates, the
    # same bits): importing scipy.stats costs ~0.5 s of the first calibration in a process.
    from scipy.special import stdtrit

    b = np.asarray(b, float)
    m = b.size
    w = np.ones(m) if sigma is None else 1.0 / np.maximum(np.asarray(sigma, float) ** 2, 1e-24)
    b0 = float(np.sum(w * b) / np.sum(w))
    se_sig = None if sigma is None else float(np.sqrt(1.0 / np.sum(w)))
    if m >= 2:
        se = float(np.sqrt(np.sum(w * (b - b0) ** 2) / ((m - 1) * np.sum(w))))
        se = max(se, se_sig or 0.0)
        h = float(stdtrit(m - 1, 0.975)) * se
    elif se_sig is not None:
        h = 1.96 * se_sig
    else:
        return b0, None
    return b0, (max(b0 - h, 0.0), b0 + h)


def _cv_folds(q: np.ndarray, k: int) -> np.ndarray:
    """Fold of each sample: samples sorted by q dealt round-robin, so every fold spans the range."""
    f = np.empty(q.size, int)
    f[np.argsort(q, kind="stable")] = np.arange(q.size) % k
    return f


def _cv_predictions(q, b, sm, folds, k, n_ctrl, lo, hi, sigma) -> np.ndarray:
    """Held-out predictions (M,) of one choose_stiffness candidate (sm None: the constant B)."""
    pred = np.empty(b.size)
    for j in range(k):
        tr, te = folds != j, folds == j
        sg = None if sigma is None else np.asarray(sigma, float)[tr]
        if sm is None or tr.sum() < MIN_SPLINE_SAMPLES:
            pred[te] = constant_backlash(b[tr], sg)[0]
        else:
            spl, _ = robust_spline(q[tr], b[tr], n_ctrl, lo, hi, sm, sigma=sg)
            pred[te] = spl(np.clip(q[te], lo, np.nextafter(hi, -np.inf)))
    return pred


SMOOTH_GRID = tuple(10.0 ** np.arange(-4, 3))  # penalty weights tried, relative to the data term


def choose_stiffness(q: np.ndarray, b: np.ndarray, n_ctrl: int, lo: float, hi: float,
                     sigma: np.ndarray | None = None, grid=SMOOTH_GRID) -> dict:
    """Spline stiffness of B(q) by k-fold cross-validation on the B samples themselves.

    Candidates: a constant B, and the penalised spline (robust_spline) for each penalty in
    grid. Folds: k = min(M, 5), the samples sorted by q dealt round-robin. Score: mean over
    held-out samples of the squared prediction error, each clipped at (3 s)^2, s the robust
    scatter (MAD) of the held-out residuals of the candidate they scatter least about, or of
    the samples about their median where that is smaller (a false onset must not pick the model), and
    weighted 1 / sigma^2 when the samples carry one. Choice: the stiffest candidate (constant
    first, then the largest penalty) within one standard error of the best (the one-standard-
    error rule, as transition.choose_model). Returns {"choice": "constant" | smooth (float),
    "candidates": [{"smooth": None | float, "cv": float, "se": float}]}.
    """
    q, b = np.asarray(q, float), np.asarray(b, float)
    m = b.size
    k = min(m, 5)
    folds = _cv_folds(q, k)
    s = 1.4826 * float(np.median(np.abs(b - np.median(b)))) + 1e-9 * (1 + float(np.max(np.abs(b))))
    wt = np.ones(m) if sigma is None else 1.0 / np.maximum(np.asarray(sigma, float) ** 2 + np.median(np.asarray(sigma) ** 2), 1e-24)
    wt = wt / wt.mean()
    cands = [None] + [float(g) for g in grid]
    preds = []
    # One BLAS thread for the (k folds x 8 candidates x 15 reweightings) small least-squares solves,
    # as transition.fit_weights: threaded, each (M x n_ctrl) solve cost ~10 ms instead of ~0.3 with
    # both cores busy (9.8 s of a 1-hour log's calibrate, 1 500 B samples).
    from .transition import _blas_controller

    with _blas_controller().limit(limits=1, user_api="blas"):
        for sm in cands:
            preds.append(_cv_predictions(q, b, sm, folds, k, n_ctrl, lo, hi, sigma))
    # The clip: 3 robust sds of the held-out residuals of the candidate they scatter least about
    # (MAD), where that is below B's own spread s. Clipped at B's spread, one false onset among
    # many still chose the model alone: a sample 0.14 mm off among 83 (twelfth-ringing-sine60-noisy,
    # B 0.13-0.26 mm) outweighed every other error 30 times, and its standard error let the
    # one-standard-error rule take the stiffest spline (5.5 % off B against 1.0 at the best).
    s_res = min(1.4826 * float(np.median(np.abs((p - b) - np.median(p - b)))) for p in preds)
    clip = (3 * min(s, max(s_res, 1e-9 * (1 + float(np.max(np.abs(b))))))) ** 2
    out = []
    for sm, pred in zip(cands, preds):
        loss = wt * np.minimum((pred - b) ** 2, clip)
        out.append({"smooth": sm, "cv": float(loss.mean()), "se": float(loss.std(ddof=1) / np.sqrt(m))})
    best = min(range(len(out)), key=lambda i: out[i]["cv"])
    limit = out[best]["cv"] + out[best]["se"]
    # Stiffest first: the constant, then the spline penalties from the largest down.
    order = [0] + sorted(range(1, len(out)), key=lambda i: -out[i]["smooth"])
    pick = next(i for i in order if out[i]["cv"] <= limit)
    return {"choice": "constant" if out[pick]["smooth"] is None else out[pick]["smooth"], "candidates": out}


def fit_backlash_auto(q_mean: np.ndarray, b: np.ndarray, n_max: int = 14, q_range: tuple[float, float] | None = None,
                      source: str | None = None, max_slope: float = 1.5, sigma: np.ndarray | None = None) -> BacklashFit:
    """B from whatever number of onset samples the record holds.

    - M = 0: InputError naming ``source`` (nothing to fit).
    - 1 <= M < 4: constant B (weighted mean) with its 95 % confidence interval
      (``constant_backlash``); kind "constant".
    - M >= 4: a B(q) spline with N = min(n_max, M) control points (no more coefficients than
      samples; N = 14 is the paper's setting, reached from 14 samples on) and its stiffness,
      or a constant, chosen by cross-validation on the samples (``choose_stiffness``); then
      fitted by fit_backlash_samples (B >= 0, |B'| <= max_slope, robust, sigma-weighted).
    q_mean, b, sigma: (M,) actuator units. Returns a BacklashFit.
    """
    q_mean, b = np.asarray(q_mean, float), np.asarray(b, float)
    m = b.size
    if m == 0:
        raise InputError(source, "no B sample: no reversal ended with a detected onset")
    lo, hi = (float(np.min(q_mean)), float(np.max(q_mean))) if q_range is None else q_range
    cv = None
    if m >= MIN_SPLINE_SAMPLES and hi > lo:
        n_ctrl = int(min(n_max, m))
        cv = choose_stiffness(q_mean, b, n_ctrl, lo, hi, sigma)
        if cv["choice"] != "constant":
            f = fit_backlash_samples(q_mean, b, n_ctrl, cv["choice"], (lo, hi), source, max_slope, sigma)
            f.kind, f.n_ctrl, f.smooth, f.cv = "spline", n_ctrl, float(cv["choice"]), cv
            return f
    b0, ci = constant_backlash(b, sigma)
    r = b - b0
    s = 1.4826 * float(np.median(np.abs(r - np.median(r)))) + 1e-12 if m >= 3 else 0.0
    z = r / s if s > 0 else np.zeros(m)
    return BacklashFit(_constant_spline(b0, lo, hi), np.ones(m), z, np.abs(z) > Z_INCONSISTENT, s,
                       "constant", 4, None, ci, cv)


def backlash_alternatives(q_mean: np.ndarray, b: np.ndarray, bfit: BacklashFit, source: str | None = None,
                          max_slope: float = 1.5, sigma: np.ndarray | None = None) -> list[tuple[float, BacklashFit]]:
    """The B(q) splines of every penalty choose_stiffness tried (bfit.cv), stiffest first, for a
    choice of the stiffness by a downstream criterion (calibration: the model's own cross-
    validation on c). Splines that differ from a stiffer kept one by less than the samples'
    median standard error (sigma) everywhere on the range are the same B to the data and are
    dropped. bfit: fit_backlash_auto's result for the same samples (kind "spline"; a constant
    or a fit without cv gives [(bfit.smooth, bfit)]). q_mean, b, sigma: (M,) actuator units.
    Returns [(penalty, BacklashFit)], bfit's own penalty included (its fit object)."""
    if bfit.kind != "spline" or not bfit.cv:
        return [(bfit.smooth, bfit)]
    q_mean, b = np.asarray(q_mean, float), np.asarray(b, float)
    lo, hi = float(np.min(q_mean)), float(np.max(q_mean))
    tol = float(np.median(sigma)) if sigma is not None and np.size(sigma) else 0.0
    grid = np.linspace(lo, hi, 201)
    out: list[tuple[float, BacklashFit]] = [(float(bfit.smooth), bfit)]  # the B-sample CV's own pick
    for sm in sorted((c["smooth"] for c in bfit.cv["candidates"] if c["smooth"] is not None), reverse=True):
        if sm == bfit.smooth:
            continue
        f = fit_backlash_samples(q_mean, b, bfit.n_ctrl, sm, (lo, hi), source, max_slope, sigma)
        f.kind, f.n_ctrl, f.smooth, f.cv = "spline", bfit.n_ctrl, float(sm), bfit.cv
        Bg = f.B(grid)
        if all(np.max(np.abs(Bg - g.B(grid))) > tol for _, g in out):
            out.append((float(sm), f))
    out.sort(key=lambda p: -p[0])
    return out
