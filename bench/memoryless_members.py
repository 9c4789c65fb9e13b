#!/usr/bin/env python3
"""Which invertible members with a memoryless term in q could close the gap to the generalized PI?

A measurement, in double precision, before any table layout is built for such a term. On the
development recordings (catheter data_2_1..5 at splits 0.5 and 0.75; endoscope 30, 60, 120,
conf0_60), the protocol of playscope.evaluate.insitu_split (fit on t < t_split only, every model
run from the record's first sample with its state carried, scored on t >= t_split against the
angle sensor), these candidates are fitted on the calibration frames the chain sees:

  gpi        the generalized PI peer as it is (16 plays w >= 0 + cubic in q, lsq_linear);
             gpi_refit: the same refitted here by fit_gpi_like (a check: it equals gpi)
  gpi_mono   the same with its memoryless cubic m constrained increasing: m'(x) is a quadratic
             in Bernstein form with coefficients >= eps (a sufficient condition for m' > 0 on the
             calibration range), so with w >= 0 the whole is strictly increasing in q for every
             play state (the plays with r > 0 are all stuck right after a reversal, m alone moves)
  gpi_mono_grid  the same with m'(x) >= eps imposed on a grid of the calibration range (exact
             up to the grid; a small QP by SLSQP): the Bernstein condition is sufficient, not necessary
  ours+m     ours' onset transition (onset B, operators and weights as the calibration chose
             them) with f refitted beside an additive memoryless spline m(q):
             c = f(T[play_B(q)]) + m(q), f and m monotone cubic B-splines in the same direction
             (non-negative coefficient increments), one bounded linear least squares; play+m:
             the same on the onset play alone (no operator)
  chosen+m   the same additive m(q) beside the member the family choice picked (its B, operators;
             f refitted): on records where the onset B is poor (the endoscope) that is not the onset one
  cv+m       the honest rule: m's control points among CV_M_CTRL (0 = ours as shipped) chosen by
             the family choice's folds on the calibration part (cv_m_choice), one-SE rule
  cv+gpi_mono  the honest rule for gpi_mono_grid as one more family: its CV on the same folds
             (cv_gpi_mono), kept only when the chosen family's CV is more than one SE above it
  onset_gpi  onset B anchoring inside the gpi form: the 16 plays run on the onset play's centre
             z = play_B(q) at thresholds from 0 (the gpi rule minus its narrowest), w >= 0, + a
             cubic in q; onset_gpi_mono: that cubic constrained as in gpi_mono

and every row of evaluate_insitu (the peers and ours as the product ships it). Per file: every
candidate's test RMSE, ours / best peer, and the oracle (the best invertible candidate per file
by test error, which no rule can pick: an upper bound on what these members can give) / best peer,
with their geometric means; and the smallest slope of the gpi peer's fitted cubic over the
calibration range (fraction of c's mean slope in q: below 0 the peer itself is not invertible).

Development files only (the endoscope lockbox is never read here).

--families adds every family of playscope.fit.families.FAMILIES, fitted on the whole calibration
part and run through its own fixed-point table (fam:<name>), and the oracle over them: whether the
product's own family set or its choice is what loses.

Usage: PYTHONPATH=host .venv/bin/python bench/memoryless_members.py [--splits 0.5,0.75] [--families]
       [--m-ctrl N] [--files STEM,...] [--json PATH]      (~2 min; ~2.5 min with --families)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.interpolate import BSpline
from scipy.optimize import lsq_linear

from playscope.base.errors import InputError
from playscope.evaluate import insitu_split as IS
from playscope.fit import families as FAM
from playscope.fit import model
from playscope.fit import transition as T
from playscope.fit.bspline import SplineFn, clamped_knots
from playscope.fit.peers import GPI_OPERATORS, gpi_thresholds
from playscope.io.importer import import_catheter, import_endoscope

ROOT = Path(__file__).resolve().parent.parent
REAL = Path(os.environ.get("PLAYSCOPE_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))
FILES = [("catheter", import_catheter, f"data_2_{i}") for i in range(1, 6)] + \
        [("endoscope", import_endoscope, s) for s in ("30", "60", "120", "conf0_60")]
PEERS = [r for r in IS.ROWS if r != "ours"]
M_CTRL = 8  # control points of the memoryless spline m(q)
SMOOTH = 1e-3  # second-difference penalty, relative to the design's scale (as the P-splines of bspline)
EPS_REL = 1e-3  # m' floor: this fraction of c's span per q span


# --------------------------------------------------------------------------- monotone bases
def bernstein_int(x: np.ndarray, deg: int = 2) -> np.ndarray:
    """(N, deg+1): integrals from -1 to x of the Bernstein basis of degree deg on [-1, 1] (in x):
    m(x) = a0 + sum_k beta_k I_k(x), m'(x) = sum_k beta_k B_k(t(x)), t = (x + 1)/2. Beyond [-1, 1]
    the integrals continue with the polynomial (the cubic as gpi's)."""
    from math import comb

    t = (np.asarray(x, float) + 1.0) / 2.0
    n1 = deg + 1
    # int_0^t B_k^n(s) ds = (1/(n+1)) sum_{j=k+1}^{n+1} B_j^{n+1}(t); dx = 2 dt
    Bn1 = np.column_stack([comb(n1, j) * t ** j * (1 - t) ** (n1 - j) for j in range(n1 + 1)])
    return np.column_stack([2.0 / n1 * Bn1[:, k + 1:].sum(axis=1) for k in range(deg + 1)])


def spline_design(x: np.ndarray, lo: float, hi: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(design (N, n) of the clamped cubic B-spline of n control points on [lo, hi], x clipped;
    its knots)."""
    t = clamped_knots(lo, hi, n)
    xc = np.clip(np.asarray(x, float), lo, np.nextafter(hi, -np.inf))
    return BSpline.design_matrix(xc, t, 3).toarray(), t


def d2_rows(n: int, L: np.ndarray) -> np.ndarray:
    """Second differences of the coefficients a = L d, as rows over d."""
    Dm = np.diff(np.eye(n), 2, axis=0)
    return Dm @ L


# --------------------------------------------------------------------------- candidates
def fit_gpi_like(P_fit, q_fit, c_fit, q_mid, q_half, mono: bool):
    """c = sum w_i P_i + m(x), w >= 0, x = (q - q_mid)/q_half, m a cubic (mono: increasing, Bernstein
    form with m' coefficients >= eps). P_fit (F, n) the operators' outputs (raw units). Returns theta
    (w, m params) and a function (P, q) -> c."""
    x = (q_fit - q_mid) / q_half
    Pn = (P_fit - q_mid) / q_half
    n = P_fit.shape[1]
    if mono == "grid":
        return _fit_gpi_grid(Pn, x, c_fit, q_mid, q_half)
    if mono:
        eps = EPS_REL * float(np.ptp(c_fit)) / 2.0  # deg per unit x (x spans 2)
        Mx = np.column_stack([np.ones_like(x), bernstein_int(x)])
        lb = np.r_[np.zeros(n), -np.inf, np.full(3, eps)]
    else:
        Mx = np.vander(x, 4, increasing=True)
        lb = np.r_[np.zeros(n), np.full(4, -np.inf)]
    A = np.column_stack([Pn, Mx])
    th = lsq_linear(A, c_fit, bounds=(lb, np.inf), method="bvls").x

    def predict(P, q):
        xx = (q - q_mid) / q_half
        M = np.column_stack([np.ones_like(xx), bernstein_int(xx)]) if mono else np.vander(xx, 4, increasing=True)
        return ((P - q_mid) / q_half) @ th[:n] + M @ th[n:]

    return th, predict


def _fit_gpi_grid(Pn, x, c, q_mid, q_half, n_grid: int = 41):
    """gpi with the cubic's m'(x) >= eps at n_grid points of [x_min, x_max] (exact up to the grid,
    not the Bernstein sufficient condition): a small QP (SLSQP from the bounded fit with the
    Bernstein form's solution as start)."""
    from scipy.optimize import minimize

    n = Pn.shape[1]
    V = np.vander(x, 4, increasing=True)
    A = np.column_stack([Pn, V])
    eps = EPS_REL * float(np.ptp(c)) / 2.0
    xg = np.linspace(float(x.min()), float(x.max()), n_grid)
    G = np.column_stack([np.zeros((n_grid, n)), np.zeros(n_grid), np.ones(n_grid), 2 * xg, 3 * xg ** 2])
    AtA, Atc = A.T @ A, A.T @ c
    th0 = lsq_linear(A, c, bounds=(np.r_[np.zeros(n), np.full(4, -np.inf)], np.inf), method="bvls").x
    th0[n + 1] = max(th0[n + 1], float(np.max(-(G[:, n + 2:] @ th0[n + 2:])) + eps))  # feasible start
    res = minimize(lambda t: 0.5 * t @ AtA @ t - Atc @ t, th0, jac=lambda t: AtA @ t - Atc, method="SLSQP",
                   bounds=[(0, None)] * n + [(None, None)] * 4,
                   constraints=[{"type": "ineq", "fun": lambda t: G @ t - eps, "jac": lambda t: G}],
                   options={"maxiter": 500, "ftol": 1e-12})
    th = res.x

    def predict(P, q):
        xx = (q - q_mid) / q_half
        return ((P - q_mid) / q_half) @ th[:n] + np.vander(xx, 4, increasing=True) @ th[n:]

    return th, predict


def gpi_min_slope(q_c, c_c) -> float:
    """The smallest slope of the gpi peer's cubic over the calibration range, as a fraction of the mean
    slope of c over q: below 0 the peer decreases in q right after a reversal (every play of r > 0
    stuck), so it has no inverse there."""
    from playscope.fit.peers import GeneralizedPI

    g = GeneralizedPI.fit(q_c, c_c)
    x = np.linspace(-1, 1, 401)
    d = np.polynomial.polynomial.polyval(x, np.polynomial.polynomial.polyder(g.poly)) / g.q_half
    mean = abs(np.polyfit(q_c, c_c, 1)[0])
    return float(d.min() / mean)


def fit_f_plus_m(y, q, c, n_f: int, sign: int, m_ctrl: int | None = None):
    """c = f(y) + m(q): f a cubic B-spline of n_f control points on y's range, m one of m_ctrl
    (default M_CTRL; 0: no m, m = 0) on
    q's range with m = 0 at q's lower end, both monotone in direction sign (coefficient increments
    >= 0 after multiplying by sign), a small second-difference penalty on each; one bounded linear
    least squares. Returns (f SplineFn, m SplineFn), linear ends."""
    M = M_CTRL if m_ctrl is None else m_ctrl
    ylo, yhi = float(y.min()), float(y.max())
    qlo, qhi = float(q.min()), float(q.max())
    Df, tf = spline_design(y, ylo, yhi, n_f)
    if M == 0:
        Lf = np.tril(np.ones((n_f, n_f)))
        scale = np.sqrt(c.size) * SMOOTH * 10
        Apen = np.vstack([Df @ Lf, d2_rows(n_f, Lf) * scale])
        d = lsq_linear(Apen, np.r_[sign * c, np.zeros(n_f - 2)], bounds=(np.r_[-np.inf, np.zeros(n_f - 1)], np.inf),
                       method="bvls").x
        f = SplineFn(BSpline(tf, sign * (Lf @ d), 3, extrapolate=False), ylo, yhi, linear_ends=True)
        return f, (lambda x: np.zeros(np.shape(x)))
    Dm, tm = spline_design(q, qlo, qhi, M)
    Lf, Lm = np.tril(np.ones((n_f, n_f))), np.tril(np.ones((M, M)))
    Af, Am = Df @ Lf, (Dm @ Lm)[:, 1:]
    A = np.column_stack([Af, Am])
    scale = np.sqrt(c.size) * SMOOTH * 10
    Pf = d2_rows(n_f, Lf) * scale
    Pm = d2_rows(M, Lm)[:, 1:] * scale
    Apen = np.vstack([A, np.column_stack([Pf, np.zeros((Pf.shape[0], Am.shape[1]))]),
                      np.column_stack([np.zeros((Pm.shape[0], n_f)), Pm])])
    b = np.r_[sign * c, np.zeros(Pf.shape[0] + Pm.shape[0])]
    lb = np.r_[-np.inf, np.zeros(n_f - 1), np.zeros(M - 1)]
    d = lsq_linear(Apen, b, bounds=(lb, np.inf), method="bvls").x
    af = sign * (Lf @ d[:n_f])
    am = sign * (Lm @ np.r_[0.0, d[n_f:]])
    f = SplineFn(BSpline(tf, af, 3, extrapolate=False), ylo, yhi, linear_ends=True)
    m = SplineFn(BSpline(tm, am, 3, extrapolate=False), qlo, qhi, linear_ends=True)
    return f, m


def _member_frames(ctx: FAM.Context, mem: FAM.Member):
    """(y at the frames (F,): the member's transition output from the record's start, f's control
    points)."""
    tr = mem.transition
    d = ctx.data if mem.B is ctx.data.B else ctx.data.with_B(mem.B)
    return d.ops_at_frames(tr.r, tr.b_scale, tr.tmap is not None) @ tr.w, max(mem.f_ctrl or ctx.f_n, 4)


def member_plus_m(ctx: FAM.Context, mem: FAM.Member, m_ctrl: int | None = None):
    """c = f(T[play_B(q)]) + m(q) on the member's own B and transition (the chosen family's), f and m
    refitted (fit_f_plus_m). Returns predict(q_full) -> c_full."""
    tr, Bm = mem.transition, mem.transition.play_width(mem.B)
    y_f, nf = _member_frames(ctx, mem)
    f, m = fit_f_plus_m(y_f, ctx.q_frames(), ctx.data.c, nf, mem.sign, m_ctrl)
    return lambda q: f(tr.direct(model.play_operator(np.asarray(q, float), Bm))) + m(np.asarray(q, float))


CV_M_CTRL = (0, 4, 8)  # m's control points the honest rule chooses among (0: no m), fewest first


def cv_m_choice(ctx: FAM.Context, mem: FAM.Member, reversals: int) -> tuple[int, list]:
    """The number of m's control points by the family choice's own folds on the calibration frames
    (rolling origins, or swing folds on a thin record: families.choose's), in double precision,
    the member's B and transition fixed, f and m refitted per fold; one-SE rule, fewest first.
    Returns (m_ctrl, [(m_ctrl, cv_rmse, se)])."""
    thin = reversals < FAM.MIN_REVERSALS_CHOICE
    splits = FAM.swing_splits(ctx) if thin else T.rolling_origins(ctx.data, T.KFOLD)
    y_f, nf = _member_frames(ctx, mem)
    qf, c = ctx.q_frames(), ctx.data.c
    rows = []
    for mc in CV_M_CTRL:
        errs = []
        for tr_m, te_m in splits:
            if te_m.sum() < FAM.MIN_TEST_FRAMES or tr_m.sum() < FAM.MIN_TRAIN_FRAMES:
                continue
            f, m = fit_f_plus_m(y_f[tr_m], qf[tr_m], c[tr_m], nf, mem.sign, mc)
            errs.append(float(np.sqrt(np.mean((f(y_f[te_m]) + m(qf[te_m]) - c[te_m]) ** 2))))
        e = np.array(errs)
        rows.append((mc, float(np.sqrt(np.mean(e ** 2))) if e.size else np.inf,
                     float(np.std(e, ddof=1) / np.sqrt(e.size)) if e.size > 1 else 0.0))
    best = min(rows, key=lambda r: r[1])
    return next(r[0] for r in rows if r[1] <= best[1] + best[2]), rows


def cv_gpi_mono(ctx: FAM.Context, reversals: int) -> tuple[float, float]:
    """gpi_mono_grid's CV on the family choice's folds (as cv_m_choice), fitted on the frames' (q, c)
    of each fold's training part with gpi_thresholds of those frames, the plays run over the frames'
    path from the first frame (as the pi_const family). Returns (cv_rmse, se), deg."""
    thin = reversals < FAM.MIN_REVERSALS_CHOICE
    splits = FAM.swing_splits(ctx) if thin else T.rolling_origins(ctx.data, T.KFOLD)
    qf, c = ctx.q_frames(), ctx.data.c
    errs = []
    for tr_m, te_m in splits:
        if te_m.sum() < FAM.MIN_TEST_FRAMES or tr_m.sum() < FAM.MIN_TRAIN_FRAMES:
            continue
        q_t, c_t = qf[tr_m], c[tr_m]
        sg = 1.0 if np.corrcoef(q_t, c_t)[0, 1] >= 0 else -1.0
        lo, hi = float(q_t.min()), float(q_t.max())
        r = gpi_thresholds(q_t, GPI_OPERATORS)
        P = T.play_ops(qf, r)
        _, pr = fit_gpi_like(P[tr_m], q_t, sg * c_t, 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-12), "grid")
        errs.append(float(np.sqrt(np.mean((sg * pr(P[te_m], qf[te_m]) - c[te_m]) ** 2))))
    e = np.array(errs)
    return float(np.sqrt(np.mean(e ** 2))), float(np.std(e, ddof=1) / np.sqrt(e.size)) if e.size > 1 else 0.0


def candidates(ctx: FAM.Context, q_c, c_c, chosen: FAM.Member | None = None) -> dict:
    """{name: predict(q_full) -> c_full} of the candidates above, fitted on the calibration part."""
    out = {}
    # gpi_mono on the frames' (q, c), as the peer
    s = 1.0 if np.corrcoef(q_c, c_c)[0, 1] >= 0 else -1.0
    lo, hi = float(q_c.min()), float(q_c.max())
    q_mid, q_half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-12)
    r = gpi_thresholds(q_c, GPI_OPERATORS)
    for mono in (False, True, "grid"):
        _, pr = fit_gpi_like(T.play_ops(q_c, r), q_c, s * c_c, q_mid, q_half, mono)
        out[{False: "gpi_refit", True: "gpi_mono", "grid": "gpi_mono_grid"}[mono]] = (lambda q, pr=pr: s * pr(T.play_ops(np.asarray(q, float), r),
                                                                             np.asarray(q, float)))

    # ours + m: the onset transition as calibrated, f and m refitted
    d = ctx.data
    tr = ctx.onset_tr
    scaled = tr.tmap is not None
    y_f = d.ops_at_frames(tr.r, tr.b_scale, scaled) @ tr.w
    qf = ctx.q_frames()
    nf = int(ctx.choice["n_ctrl"]) if ctx.choice and ctx.choice.get("n_ctrl") else ctx.f_n
    f, m = fit_f_plus_m(y_f, qf, d.c, nf, ctx.onset_sign)
    Bm = tr.play_width(d.B)

    def ours_m(q, f=f, m=m, tr=tr, Bm=Bm):
        q = np.asarray(q, float)
        y = tr.direct(model.play_operator(q, Bm))
        return f(y) + m(q)

    out["ours+m"] = ours_m
    # the same with the onset play alone (no operator)
    z_f = d.ops_at_frames(np.zeros(1))[:, 0]
    f0, m0 = fit_f_plus_m(z_f, qf, d.c, ctx.f_n, ctx.play_sign)
    out["play+m"] = lambda q, f=f0, m=m0: f(model.play_operator(np.asarray(q, float), d.B)) + m(np.asarray(q, float))

    if chosen is not None:
        out["chosen+m"] = member_plus_m(ctx, chosen)
    if FAMILY_ROWS:
        # Every family the product already offers, fitted on the whole calibration part and run through
        # its own table (what the choice would ship had it picked that family).
        for fam in FAM.FAMILIES:
            try:
                mem = fam.fit(ctx, None)
                out["fam:" + fam.name] = FAM.table_of(ctx, mem).predict
            except Exception as e:  # noqa: BLE001  (a refused table is that row's absence)
                print(f"  {fam.name}: {e}", file=sys.stderr)
    # onset B inside the gpi form: plays on the onset play's centre z
    rz = gpi_thresholds(z_f, GPI_OPERATORS)
    rz = rz - rz[0]
    P = d.ops_at_frames(rz)
    for mono in (False, True):
        _, pr = fit_gpi_like(P, qf, s * d.c, q_mid, q_half, mono)

        def og(q, pr=pr):
            q = np.asarray(q, float)
            z = model.play_operator(q, d.B)
            return s * pr(T.play_ops(z, rz, z[0]), q)

        out["onset_gpi_mono" if mono else "onset_gpi"] = og
    return out


FAMILY_ROWS = False  # --families: also every existing family's own table (slower: the relaxed fits)
INVERTIBLE = ("ours", "gpi_mono", "gpi_mono_grid", "ours+m", "play+m", "chosen+m", "onset_gpi_mono")


def run(inst, reader, stem, split) -> dict:
    """One development file at one split (fraction of its duration, 0..1): every candidate and
    peer fitted on t < t_split and scored on t >= t_split (test RMSE, deg, in "test"), with the
    family chosen, the gpi peer's lowest slope and the CV rules' choices. Errors: InputError from
    the reader (the row then says so)."""
    path = REAL / inst / f"{stem}.txt"
    s = reader(path)
    ts = IS.split_time(s.encoder["t_s"], split)
    grab = {}
    orig, orig_frames = FAM.choose, IS.calibration_frames

    def choose(ctx, *a, **k):  # the family choice's context: onset B, onset transition, frames
        grab["ctx"], grab["reversals"] = ctx, int(a[0])
        grab["member"] = orig(ctx, *a, **k)
        return grab["member"]

    def frames(*a, **k):  # the calibration frames the peers are fitted on
        grab["qc"] = orig_frames(*a, **k)
        return grab["qc"]

    FAM.choose, IS.calibration_frames = choose, frames
    try:
        rows = IS.fit_rows(s, ts, source=str(path))
    finally:
        FAM.choose, IS.calibration_frames = orig, orig_frames
    ctx = grab["ctx"]
    q_c, c_c = grab["qc"]
    for name, pr in candidates(ctx, q_c, c_c, grab["member"][0]).items():
        rows[name] = IS.Row(name, False, pr)
    # The honest rule: m's control points (0 = the product as it is) by CV on the calibration part.
    mc, cv = cv_m_choice(ctx, grab["member"][0], grab["reversals"])
    rows["cv+m"] = rows["ours"] if mc == 0 else IS.Row("cv+m", False, member_plus_m(ctx, grab["member"][0], mc))
    # The honest rule for the increasing generalized PI as one more family: after the others in the
    # one-SE order (most parameters), kept only when the chosen family's CV is more than one SE of
    # gpi_mono's above it.
    g_cv, g_se = cv_gpi_mono(ctx, grab["reversals"])
    ch = grab["member"][1]
    own = next((r for r in ch["candidates"] if r["family"] == ch["family"]), None)
    own_cv = None if own is None else own.get("cv_rmse_deg")
    take = own_cv is not None and own_cv > g_cv + g_se
    rows["cv+gpi_mono"] = rows["gpi_mono_grid"] if take else rows["ours"]
    td = float(s.t_delay_s) if s.t_delay_s is not None else float(rows["onset_lsq"].params["t_delay_s"])
    rm, _, rc, _, _ = IS.score_rows(rows, s, ts, td)
    return {"test": rm, "cal": rc, "family": rows["ours"].params.get("family"), "cv_m_ctrl": mc, "cv_m": cv,
            "cv_gpi_mono": [g_cv, g_se], "cv_chosen": own_cv, "cv_takes_gpi_mono": bool(take),
            "gpi_min_slope": gpi_min_slope(q_c, c_c)}


def main(argv=None) -> int:
    global M_CTRL, FAMILY_ROWS, INVERTIBLE
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--splits", default="0.5,0.75")
    ap.add_argument("--json")
    ap.add_argument("--families", action="store_true", help="also score every family of families.FAMILIES "
                    "through its table (the oracle over the families the product has)")
    ap.add_argument("--m-ctrl", type=int, default=8, help="control points of m(q) (default %(default)s)")
    ap.add_argument("--files", default="", help="comma-separated stems (default: every development file)")
    a = ap.parse_args(argv)
    splits = [float(v) for v in a.splits.split(",")]
    M_CTRL, FAMILY_ROWS = a.m_ctrl, a.families
    want = set(a.files.split(",")) if a.files else None
    out = {}
    t0 = time.perf_counter()
    for inst, reader, stem in FILES:
        if want and stem not in want:
            continue
        for fr in splits:
            try:
                out[f"{stem}@{fr:g}"] = {"instrument": inst, **run(inst, reader, stem, fr)}
            except InputError as e:
                out[f"{stem}@{fr:g}"] = {"instrument": inst, "error": str(e)}
            print(f"{stem}@{fr:g} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    fam_cols = ["fam:" + f.name for f in FAM.FAMILIES] if FAMILY_ROWS else []
    cands = fam_cols + ["gpi", "gpi_refit", "mpi", "const_play", "ours", "gpi_mono", "gpi_mono_grid", "ours+m", "play+m", "chosen+m", "cv+m", "cv+gpi_mono", "onset_gpi",
             "onset_gpi_mono"]
    for inst in ("catheter", "endoscope"):
        for fr in splits:
            keys = [k for k, v in out.items() if v["instrument"] == inst and k.endswith(f"@{fr:g}")]
            if not keys:
                continue
            print(f"\n**Memoryless term in q, {inst}, split {fr:g}: test RMSE (deg)**\n")
            print("| file | " + " | ".join(cands) + " | best peer | ours/peer | oracle/peer (which) | family | gpi min m' | cv m_ctrl | CV chosen / gpi_mono (deg) |")
            print("|---" * (len(cands) + 8) + "|")
            r_ours, r_or, r_cm, r_fam, r_cv, r_cg = [], [], [], [], [], []
            for k in keys:
                v = out[k]
                if "error" in v:
                    print(f"| {k} | error: {v['error']} |")
                    continue
                te = v["test"]
                peers = {p: te[p] for p in PEERS if te.get(p) is not None}
                bp = min(peers, key=peers.get)
                inv = {c: te[c] for c in INVERTIBLE if te.get(c) is not None}
                orc = min(inv, key=inv.get)
                r_ours.append(te["ours"] / peers[bp])
                r_or.append(inv[orc] / peers[bp])
                r_cm.append(te["ours+m"] / peers[bp])
                r_cv.append(te["cv+m"] / peers[bp])
                r_cg.append(te["cv+gpi_mono"] / peers[bp])
                fams = [te[c] for c in fam_cols if te.get(c) is not None]
                if fams:
                    r_fam.append(min(fams) / peers[bp])
                cells = ["-" if te.get(c) is None else f"{te[c]:.3f}" for c in cands]
                print(f"| {k.split('@')[0]} | " + " | ".join(cells) + f" | {bp} {peers[bp]:.3f} | "
                      f"{r_ours[-1]:.3f} | {r_or[-1]:.3f} ({orc}) | {v['family']} | {v['gpi_min_slope']:.2f} | {v['cv_m_ctrl']} | "
                      f"{'-' if v['cv_chosen'] is None else format(v['cv_chosen'], '.3f')} / {v['cv_gpi_mono'][0]:.3f} "
                      f"+- {v['cv_gpi_mono'][1]:.3f} |")
            if r_ours:
                g = lambda v: float(np.exp(np.mean(np.log(v))))  # noqa: E731
                print(f"\ngeomean ours / best peer {g(r_ours):.3f} (worst {max(r_ours):.3f}); ours+m / best peer "
                      f"{g(r_cm):.3f} (worst {max(r_cm):.3f}); oracle of {', '.join(INVERTIBLE)} / best peer "
                      f"{g(r_or):.3f} (worst {max(r_or):.3f}); cv+m (m's control points {CV_M_CTRL} by CV on the "
                      f"calibration part, 0 = ours) / best peer {g(r_cv):.3f} (worst {max(r_cv):.3f}); cv+gpi_mono (gpi_mono_grid "
                      f"as one more family by the one-SE rule) / best peer {g(r_cg):.3f} (worst {max(r_cg):.3f})")
                if r_fam:
                    print(f"oracle of the product's existing families (each through its table) / best peer "
                          f"{g(r_fam):.3f} (worst {max(r_fam):.3f})")
    print(f"\n({time.perf_counter() - t0:.0f} s wall)")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
