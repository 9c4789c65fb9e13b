"""Fitting one record model (onset_model.RecordModel) and reading eq. 1's samples off the fit.

A model is fitted by iteratively reweighted Huber least squares (`fit_model`: Levenberg-Marquardt,
scipy.optimize.least_squares, on the model's variable-projection Jacobian); B coarse to fine in its
size (`_fit_chain`); many fits on two cores, each on its own copy of its model, so that a result
does not depend on which process fitted it (`_fit_all`). A Fit carries its BIC on the robust
objective, the criterion every choice of onset_search makes.

Eq. 1's samples are then read off the fitted model: after each reversal (t1, q1), the instant t2
the play output starts to move, b = |q(t2) - q1|, with its standard error from the fit's
covariance.

Units: t in s, q and B in actuator units, image points in px.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..base.forkmap import fork_map
from .onset_model import Eval, Record, RecordModel, _basis, robust_sigma

IRLS_ROUNDS = 3        # reweightings of the Huber fit (the weights settle in 2-3 on every record tried)
EXPO_BOUND_CHI2 = 3.84  # the robust objective's rise (a -2 ln likelihood) that rules an exposure out: the
                       # 95 % point of chi-square with one degree of freedom (Wilks 1938; the exposure is one
                       # parameter)
EXPO_BOUND_GRID = (1.0, 0.5, 0.25, 0.125)  # the exposures the bound is read at, frame periods, longest first:
                       # halving from the longest a camera exposes, so the bound is good to a factor 2 (it
                       # only judges a configured delay, whose test has a tolerance of 0.87 frame)


@dataclass
class Fit:
    """A fitted model: theta (model.layout), its evaluation, the noise scale sigma (px) the fit
    and its BIC use, cost (half the robust objective, plus the delay prior's half square, in
    sigma^2 units), fit details, the model's state the fit left (its IRLS weights, mixture and
    tangent: what its evaluations depend on beside theta), and, on demand, the weighted Jacobian
    (2F [+1], n_theta) in sigma units (`jac`)."""

    model: RecordModel
    theta: np.ndarray
    ev: Eval
    sigma: float
    cost: float          # sum of Huber rho at sigma (plus the prior's half square)
    info: dict = field(default_factory=dict)
    state: tuple | None = field(default=None, repr=False)  # (w, mix, slope) as the fit left them; fit_model sets it, `jac` needs it
    _jac: np.ndarray | None = field(default=None, init=False, repr=False)

    @property
    def jac(self) -> np.ndarray:
        """The weighted Jacobian at theta (2F [+1], n_theta), sigma units, in the state the fit left
        (on a copy of the model, so the model's own state is not touched). Computed when first
        asked for: of the search's many fits only the final one's is read (`samples`' covariance),
        and a Jacobian costs about two evaluations. The same bits as one taken when the fit ended:
        the model's evaluation, and with it its linear solve, is a function of theta and that state."""
        if self._jac is None:
            m = copy.copy(self.model)
            m.w, m.mix, m.slope = self.state
            self._jac = m.jacobian(self.theta, m.evaluate(self.theta), self.sigma)
        return self._jac

    def bic(self, sigma: float) -> float:
        """BIC on the robust objective at a common sigma (RecordModel.objective) + k ln n."""
        m = self.model
        n = self.ev.resid.size
        k = m.n_theta() - (1 if m.d_fixed is not None else 0) + m.n_linear()
        return m.objective(self.ev, sigma) + k * np.log(n)


def _steps(m: RecordModel, th: np.ndarray) -> np.ndarray:
    """Forward-difference steps (the reference `jacobian` is checked against): t_delay T/16; B
    coefficients 2 % of the mean width, at least the travel of two grid steps at the record's
    median speed; the ring's and the lags', slides' and first state's (logistic) parts 0.01 and 0.05."""
    rec = m.rec
    v = float(np.median(np.abs(np.diff(rec.q)))) / rec.dt
    hb = max(0.02 * float(np.mean(np.abs(th[1:1 + m.n_b]))), 2 * v * rec.dt, 1e-6)
    h = [rec.period_s / 16] + [hb] * m.n_b
    if m.terms.ring:
        h += [0.01, 0.01]
    h += [0.05] * (m.terms.reg_tip + m.terms.reg_motor + m.terms.slide_tip + m.terms.slide_motor + m.terms.expo
                   + m.terms.spread)
    return np.array(h + [0.05])  # the first state's (logistic) part


def _residual_fn(m: RecordModel, sigma: float):
    """theta -> weighted residuals in sigma units (and the delay prior), for least_squares."""
    sw = np.sqrt(m.w)
    cache = {}

    def fun(th):
        key = th.tobytes()
        if key not in cache:
            ev = m.evaluate(th)
            r = sw * ev.resid / sigma
            if m.prior is not None and m.d_fixed is None:
                r = np.r_[r, m.prior_residual(m.unpack(th)[0])[0]]
            kl, pen = m.mix_rows(ev, sigma)
            r = np.r_[r, kl, pen]
            cache.clear()
            cache[key] = (r, ev)
        return cache[key][0]

    def evaluation(th):
        """The model's evaluation at th: the last one fun made when at th (the model's linear
        solve is still that one's, as the Jacobian needs), else a new one."""
        hit = cache.get(th.tobytes())
        return hit[1] if hit is not None else m.evaluate(th)

    fun.evaluation = evaluation
    return fun


def _jac(m: RecordModel, fun, th: np.ndarray, r0: np.ndarray) -> np.ndarray:
    h = _steps(m, th)
    J = np.empty((r0.size, th.size))
    for i in range(th.size):
        if i == 0 and m.d_fixed is not None:
            J[:, 0] = 0.0
            continue
        t2 = th.copy()
        t2[i] += h[i]
        J[:, i] = (fun(t2) - r0) / h[i]
    return J


def _settle(m: RecordModel, th: np.ndarray, sig: float) -> tuple[Eval, float]:
    """The model at theta with its Huber weights reweighted once from there (the form every fit
    is scored in): (its evaluation, half the robust objective plus the delay prior's half square)."""
    ev = m.evaluate(th)
    if m.terms.ring:  # a new tangent changes the ring's columns: ev is stale whatever the E-step does
        m.slope = m.G_slope(ev)
    if m.e_step(ev, sig) or m.terms.ring:
        ev = m.evaluate(th)
    m.w = m.weights(ev, sig)
    ev = m.evaluate(th)
    cost = 0.5 * m.objective(ev, sig)
    cost += 0.5 * m.prior_residual(m.unpack(th)[0])[0] ** 2
    return ev, cost


def fit_model(m: RecordModel, th0: np.ndarray, sigma: float | None = None, max_nfev: int = 20,
              rounds: int = IRLS_ROUNDS) -> Fit:
    """Huber fit of the model from th0 by IRLS rounds of least_squares (Levenberg-Marquardt,
    MINPACK; the model clips theta into its admissible region: d >= 0, B >= 0, the tip mode in
    its band). sigma: the scale (None: from the first round's residuals, 1.4826 MAD). The scales
    of a switch window follow the fitted jump, so a round need not lower the objective: the best
    of the start and every round is returned, as it was scored (`_settle`: the one reweighting the
    score and the returned weights share). Returns Fit."""
    th = np.array(th0, float)
    ev = m.evaluate(th)
    if m.terms.ring:
        m.slope = m.G_slope(ev)
    sig = sigma if sigma is not None else robust_sigma(ev.resid)
    nfev = 0
    tried = [th.copy()]
    stale = bool(m.terms.ring)  # ev was evaluated before the tangent was set (below, after every round, it is not)
    for rnd in range(rounds):
        if m.e_step(ev, sig) or stale:  # else ev is the model's evaluation at th as it stands, bit for bit
            ev = m.evaluate(th)
        stale = False
        m.w = m.weights(ev, sig)
        fun = _residual_fn(m, sig)
        free = np.arange(th.size) if m.d_fixed is None else np.arange(1, th.size)
        full = th.copy()

        r_bad = None

        def f_free(x, full=full, free=free, fun=fun):
            nonlocal r_bad
            if not np.all(np.isfinite(x)):  # a step LM took off the finite (a switch's scale gone to 0):
                return r_bad                # a cost above the start's, so LM shrinks its step
            full[free] = x
            r = fun(full)
            if r_bad is None:
                r_bad = np.full(r.size, 10.0 * (np.linalg.norm(r) + 1.0) / np.sqrt(r.size))
            return r

        def j_free(x, full=full, free=free, sig=sig, fun=fun):
            full[free] = x
            return np.nan_to_num(m.jacobian(full, fun.evaluation(full), sig)[:, free], nan=0.0, posinf=0.0, neginf=0.0)

        res = least_squares(f_free, th[free], jac=j_free, method="lm", max_nfev=max_nfev, xtol=1e-6, ftol=1e-8)
        th[free] = res.x
        nfev += res.nfev
        tried.append(th.copy())
        ev = fun.evaluation(th)  # LM's own when its last step was kept (the state has not changed since)
        if m.terms.ring:
            m.slope = m.G_slope(ev)
            ev = m.evaluate(th)
        if sigma is None and rnd == 0:
            sig = robust_sigma(ev.resid)
    settled = []  # each tried theta in the form a fit is scored in, with the state it was scored in
    for t in tried:
        ev, cost = _settle(m, t, sig)
        settled.append((cost, ev, (m.w, m.mix, m.slope)))
    k = int(np.argmin([c for c, _, _ in settled]))
    cost, ev, state = settled[k]
    if k != len(tried) - 1:  # the model's last evaluation is to be the returned one's (its linear solve,
        m.w, m.mix, m.slope = state  # which `jacobian` and `project` read): the same bits in the same state
        ev = m.evaluate(tried[k])
    return Fit(m, tried[k], ev, sig, cost, info={"nfev": nfev}, state=state)


def _fresh(m: RecordModel) -> RecordModel:
    """A copy of m with its IRLS weights at 1 and no mixture: what it fits or scores next depends on
    its arguments alone, and m's own state stays as it was."""
    mc = copy.copy(m)
    mc.w, mc.mix = np.ones_like(m.w), {}
    return mc


def _fit_one(job) -> "Fit":
    """fit_model for one job (model, theta0, sigma, max_nfev, rounds) on its own copy of the model,
    its IRLS weights and mixture started afresh and first set at theta0: the fit depends on the
    job alone, not on which fits ran on the same model before it nor in which process (a term's
    starts share one model; the weights the last fit left moved the next one's delay by up to
    0.9 ms on a test record, so a record's result hung on the machine's core count). The returned
    Fit holds the copy."""
    m, th0, sigma, max_nfev, rounds = job
    m = _fresh(m)
    ev = m.evaluate(th0)
    if m.e_step(ev, sigma):  # else ev stands (no mixture before or after)
        ev = m.evaluate(th0)
    m.w = m.weights(ev, sigma)
    return fit_model(m, th0, sigma=sigma, max_nfev=max_nfev, rounds=rounds)


def _resample_B(m_from: "RecordModel", cB: np.ndarray, m_to: "RecordModel") -> np.ndarray:
    """B's coefficients (m_to.n_b,), actuator units, for m_to's size from m_from's B(q) with
    coefficients cB (least squares on 400 points over the travel; a constant width: B's mean over
    the record's q)."""
    if m_to.n_b == 1:
        return np.array([float(np.mean(m_from.B_of(cB, m_from.rec.q)))])
    qq = np.linspace(m_to.q_lo, m_to.q_hi, 400)
    return np.linalg.lstsq(_basis(qq, m_to.q_lo, m_to.q_hi, m_to.n_b), m_from.B_of(cB, qq), rcond=None)[0]


def _fit_chain(job) -> list:
    """Coarse to fine in B's size: job (models, theta0 of the first, sigma, max_nfev, rounds[, the
    first model's Fit]), the models alike but for B's size; each is fitted from the last one's fit,
    its B resampled (`_resample_B`). A width fitted with few coefficients first finds the level,
    and the finer sizes then only shape it: started at full size from a constant width, the
    B-spline's many directions meet the switches' onsets and the fit settles in a basin of a wrong
    B (measured: from 5 constant widths 0.1-0.3 on a 1.5 deg registration record, 5 reach B within
    3.7 % this way, 1 from full size). The first model's Fit, when given, is that fit done already
    (the same job fitted elsewhere: a fit depends on its job alone, `_fit_one`), and the chain
    starts from it. Returns the fits, one per model."""
    models, th0, sigma, max_nfev, rounds, *done = job
    out = list(done[:1])
    for m in models[len(out):]:
        if out:
            prev = out[-1]
            parts = prev.model.parts(prev.theta)
            parts["B"] = _resample_B(prev.model, prev.model.unpack(prev.theta)[1], m)
            th0 = m.theta({k: v for k, v in parts.items() if k in m.layout()})
        out.append(_fit_one((m, th0, sigma, max_nfev, rounds)))
    return out


RING_COST_FACTOR = 5.0  # a ring model's fit against a plain one's (its Jacobian filters the grid once per B
                        # coefficient: 19 against 4 ms on the bench record, 16 coefficients)


def _job_cost(job) -> float:
    """A fit job's relative cost, to start the costly ones first (`_fit_all`): its models, one
    with the tip mode RING_COST_FACTOR times one without."""
    models = job[0] if isinstance(job[0], list) else [job[0]]
    return float(sum(RING_COST_FACTOR if m.terms.ring else 1.0 for m in models))


def _slim(result):
    """A job's result (a Fit or a list of Fits) without its evaluations, for the pipe: an evaluation
    holds the grid's play and drive (35 MB on the bench record, so a chain's took seconds to pass),
    and the model it came from gives it again bit for bit (`_unslim`: a Fit's evaluation is its
    model's at theta in the state the fit left, `fit_model`'s last settle). Copies (shallow): the
    process that fitted them keeps its own Fits whole (base.forkmap.lockstep)."""
    out = [copy.copy(f) for f in (result if isinstance(result, list) else [result])]
    for f in out:
        f.ev = None
    return out if isinstance(result, list) else out[0]


def _unslim(result):
    """The evaluations `_slim` dropped, from each Fit's model (and with them the model's last linear
    solve, which the Jacobian reads)."""
    for f in (result if isinstance(result, list) else [result]):
        if f.ev is None:
            f.ev = f.model.evaluate(f.theta)
    return result


def _fit_all(jobs: list, fn=None) -> list:
    """fn (default `_fit_one`; `_fit_chain` for chains) on each job, results in the jobs' order, on
    two cores when the machine has them (base.forkmap: the costly jobs first, `_job_cost`; the
    child's fits sent without their evaluations, `_slim`). Each fit is on its own copy of its model
    (`_fit_one`), so the result does not depend on which process fitted a job (a test checks it bit
    for bit)."""
    return fork_map(fn or _fit_one, jobs, cost=_job_cost, pack=_slim, unpack=_unslim)


def _fit_distinct(jobs: list, here: bool = False) -> list:
    """The last Fit of each chain job (`_fit_chain`), a job alike another (the same models, start and
    budget: a start the term's bases repeat, e.g. the coarse delay equal to the configured one)
    fitted once; its Fit then stands for both (a job's fit depends on the job alone, `_fit_one`).
    here: in this process, in turn (for a caller that is itself one item of a fork_map)."""
    key = [(tuple(id(m) for m in j[0]), j[1].tobytes(), j[2], j[3], j[4]) for j in jobs]
    first = {}
    for i, k in enumerate(key):
        first.setdefault(k, i)
    uniq = sorted(set(first.values()))
    todo = [jobs[i] for i in uniq]
    fits = dict(zip(uniq, (fs[-1] for fs in ([_fit_chain(j) for j in todo] if here else _fit_all(todo, _fit_chain)))))
    return [fits[first[k]] for k in key]


# --------------------------------------------------------------------------- samples
@dataclass
class ModelSamples:
    """Eq. 1's samples read off a fitted model (arrays (K,), one per reversal whose play was
    taken up within the record's frames): t1_s (scene), t2_s (image clock = scene + t_delay: the
    stamp of a frame whose exposure ends at the onset), q1, q2, q_mean, b (actuator units), sigma_b;
    t_delay_s, the delay to the exposure's end, and its standard error (the mean lag's); rev (K,)
    the reversal indices; exposure_s the exposure that splits the mean lag (None: nothing split it;
    module doc, the exposure)."""

    t1_s: np.ndarray
    t2_s: np.ndarray
    q1: np.ndarray
    q2: np.ndarray
    q_mean: np.ndarray
    b: np.ndarray
    sigma_b: np.ndarray
    rev: np.ndarray
    t_delay_s: float
    t_delay_se_s: float
    exposure_s: float | None = None
    exposure_bound_s: float | None = None


def exposure_bound(fit: Fit) -> float:
    """The longest exposure e s the fitted record allows (onset_model's module doc, the exposure):
    the exposure term set to each e of EXPO_BOUND_GRID (frame periods, longest first, those above
    the fit's own e), every other parameter at the fit, each scored as a fit is (`_settle`); the
    bound is the shortest e whose robust objective lies more than EXPO_BOUND_CHI2 above the lowest
    scored (the fit's own among them), so the record rules it out, and every longer one was ruled
    out before it; a frame period T where the longest is not ruled out.

    A conditional, not a profile: the other parameters are not refitted at each e (a profile is a
    fit per e). A blur centred on each frame's time leaves every frame more than e / 2 from an onset
    as it was (the mean of a straight stretch is its middle) and rounds the frames nearer by a
    corner that no shift of the onset undoes; but where another term has taken up part of the
    rounding (a tip mode), the rise is overstated and the bound can fall below the true exposure
    (measured: 3 of 19 marker_render renderings exposed 8 ms, all with a tip mode). So the bound
    only judges a configured delay (RecordModel.exposure_end), where that error cannot contradict a
    right one. The scan stops at the first e allowed, on the assumption (not tested) that the rise
    grows with e above the fit's own."""
    m, sig = fit.model, fit.sigma
    T = m.rec.period_s
    e_fit = m.exposure(fit.theta)
    mt = m if m.terms.expo else RecordModel(m.rec, m.n_b, m.n_g, m.terms.with_("expo"), m.prior, m.d_fixed, m.width_at)
    parts = m.parts(fit.theta)

    def score(model, th):
        mc = _fresh(model)  # `_settle` sets the weights and the mixture: the fit's own stay as they were
        mc.slope = m.slope
        ev, _ = _settle(mc, th, sig)
        return mc.objective(ev, sig)

    best = score(m, fit.theta)
    bound = T
    for g in EXPO_BOUND_GRID:
        e = g * T
        if e <= e_fit:
            break
        obj = score(mt, mt.theta({**parts, "expo": np.array([mt.expo_x(e)])}))
        best = min(best, obj)
        if obj - best <= EXPO_BOUND_CHI2:
            break
        bound = e
    return float(bound)


def engaged_at_reversals(rec: Record, last: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Whether the play was engaged at each reversal (M,) bool: at the reversal's extremum (the
    grid point make_record put it on) the output sat on the edge the old direction drags, the
    upper (side +0.5) before a reversal upwards (s_new +1), the lower before one downwards, at that
    point or the one before. last, side (N,): `RecordModel.play_drags`' bookkeeping."""
    k = np.clip(np.rint((rec.rt - rec.t[0]) / rec.dt).astype(np.int64), 0, rec.t.size - 1)
    return (last[k] >= k - 1) & (side[k] == 0.5 * rec.s_new)


def samples(fit: Fit) -> ModelSamples:
    """B samples of eq. 1 from the fitted play (module doc), each with its standard error from the
    fit's covariance sigma^2 (J'J)^-1 (J: the weighted residuals' Jacobian in sigma units, so the
    covariance is (J'J)^-1).

    Only reversals at which the fitted play was engaged give a sample: the output on the edge that
    the old direction drags (`engaged_at_reversals`). Eq. 1's |q(t2) - q1| is the play's width only
    when the take-up starts from that edge; at a reversal the play reached from inside its band
    (the record's first, when the output starts anywhere in the play, or one after a stroke shorter
    than the play) it is a part of the width, which the model itself says. Such a sample is no
    evidence about B, and at the end of the travel it pulled B's spline down: on s9-render_c-027
    of LOCKBOX9_300 the first reversal gave 0.10 mm against a width of 0.31, with a standard error
    of zero (its onset moves with no parameter the covariance spans), so every other sample near it
    read as inconsistent and B's spline was 5.7 % off with the model's own B 1.2 % off."""
    m, th = fit.model, fit.theta
    rec = m.rec
    d, cB = m.unpack(th)[:2]
    z, _, last, side = m.play_drags(cB, m.z0_of(th))
    t_on = m.onsets(z)
    J = fit.jac
    cov = np.linalg.pinv(J.T @ J)
    # b's gradient over theta by the same forward steps
    h = _steps(m, th)
    q_on = np.interp(t_on, rec.t, rec.q)
    grad = np.zeros((rec.rt.size, th.size))
    for i in [*range(1, 1 + m.n_b), m.layout()["z0"].start]:
        t2 = th.copy()
        t2[i] += h[i]
        on2 = m.onsets(m.play(m.unpack(t2)[1], m.z0_of(t2)))
        grad[:, i] = (np.abs(np.interp(on2, rec.t, rec.q) - rec.rq) - np.abs(q_on - rec.rq)) / h[i]
    var_b = np.einsum("mi,ij,mj->m", np.nan_to_num(grad), cov, np.nan_to_num(grad))
    se_d = float(np.sqrt(max(cov[0, 0], 0.0))) if m.d_fixed is None else 0.0
    # the onset must fall within the frames' span (a model extrapolated past the video says nothing)
    ok = np.isfinite(t_on) & (t_on + d > rec.t_f[0] + rec.period_s) & (t_on + d < rec.t_f[-1] - rec.period_s)
    ok &= engaged_at_reversals(rec, last, side)
    q2 = q_on[ok]
    # the record's bound on the exposure can change the verdict on the configured delay only where that
    # lies further below the mean lag than the test allows, and not that far below the band [0, T]
    # allows already (module doc of onset_model, the exposure)
    e_max = None
    if m.prior is not None and m.d_fixed is None:
        short = d - m.prior[0]
        if short > m.disagree_s(se_d) >= short - 0.5 * rec.period_s:
            e_max = exposure_bound(fit)
    d_end, e = m.exposure_end(d, se_d, e_max)
    return ModelSamples(rec.rt[ok], t_on[ok] + d_end, rec.rq[ok], q2, 0.5 * (rec.rq[ok] + q2), np.abs(q2 - rec.rq[ok]),
                        np.sqrt(np.maximum(var_b[ok], 0.0)), np.flatnonzero(ok), d_end, se_d, e, e_max)
