"""Recoverable in situ? The generator's oracle that knows the planted effect's form.

The blind self-test asks the diagnosis to recover the shrink of a planted effect "within 25 % of
the truth on the recoverable cases, measured against the generator's truth, not an oracle of the
diagnoser's". Which cases are recoverable is decided here, on the generator's side, by
an experiment: could a model that has the planted effect's exact form, but has to estimate
everything else in situ like any user, take out 75 % of what the effect-free model leaves over the
noise? Knowing the form is legitimate here because this is the generator's oracle; nothing of it
reaches the diagnosis.

What the oracle knows: the planted variant's hook (``variants.Variant.fn``), applied at the stage
where plant.run applies it ("actuator", "clearance", "carrier", "bend", "sensor", "reading") to the
oracle's own intermediate signals (actuator position qa, clearance edges below/above, carrier
position x, bend c, sample times t_seen, reading cs; the ctx keys of plant.run), on the plant's
state grid (STATE_HZ: the hooks' time constants and integrators are written for it).
What it does not know, and fits on the fit samples only:
  - the base model: the effect-free oracle's (oracle.py): clearance half-width h piecewise linear
    at 9 knots, evaluated at the actuator position the hook leaves; bending map a Chebyshev series
    of degree 15 in the normalised carrier position. Knots by least_squares, map by linear least
    squares. One change, applied to both figures of the rule: outside the carrier range seen on
    the fit samples the map continues along its tangent (``map_columns(inside=...)``); the series
    itself, 0.05 mm beyond its data at the top of the range, was measured 0.4-0.9 deg off (dev
    seed 1000), which would decide small cases by extrapolation rather than by the effect.
  - the strength: a log grid of GRID_POINTS over [min/4, 4 max] of the variant's ``strengths``
    (the planted value is never read; the grid cannot reach zero), each point refitted from its
    weaker neighbour's fit (continuation; the first from the effect-free fit), then bounded Brent
    on log strength between the best point's neighbours, then a final refit at the best strength
    (more alternations, also from the effect-free oracle's flat knots).
  - any plant quantity the hook reads (``ctx["plant"]``), answered by ``_InSituPlant`` from the
    oracle's own fit; any other attribute raises. The hooks read only the straight position q_c
    (the dead zones' centre, a nuisance fitted within the middle 30 % of the q range: the form
    says "near straight" and the excitation is centred on it) and bend(x) (the distal dead zone's
    c0 = bend(q_c): the oracle's own map).
How the base is refitted with the effect in. Before the bend (actuator, clearance, carrier) the
effect changes the carrier position, and the map stays linear: variable projection, the knots
(with the centre, for the actuator dead zone) by least_squares, the map solved inside. A sensor
hook that only moves the sample times (transport delay) is linear too (columns at the seen
times). Any other effect after the bend (stiction or a dead zone on the bend, creep, a reading
offset, a buffered sensor) by a fixed number of alternations (GRID_ALT, FINAL_ALT): its
contribution d = prediction - base is held while the knots and map are refitted to y - d, then
recomputed; after each, NEWTON_ITER Gauss-Newton steps of the map through the whole pipeline
(Jacobian by forward differences, the knots held), kept only when they lower the fit RMSE, and no
longer tried once they gain under 1 % a step (a staircase has no useful derivative). The distal
dead zone's centre is scanned with the base held. The fit with the lowest fit RMSE is kept; its
prediction is always the full pipeline's.

The rule: with n the noise-only RMSE on the judged samples (the record minus the generator's
noise-free reading, as oracle.identifiable), r_free the effect-free model's judged RMSE and r_eff
this oracle's, both from this code (same grid, same guarded map), the case is recoverable when
    r_eff - n <= RULE_SHARE (r_free - n),   RULE_SHARE = 0.25:
knowing the form, what is left over the noise is at most a quarter of what the effect-free model
leaves, i.e. the oracle itself would meet the issue's criterion (a shrink within 25 % of the
truth's). Otherwise even the effect's own form, fitted in situ, does not get there: the base's
own misfit is a large part of a small effect's excess, the record does not pin a parameter down
(a soft distal dead zone: the map is free inside the band), or the effect depends on a state the
base does not reproduce exactly (where each slip of a stiction falls; the sample at which a seat
switches). The same rule with the effect-free oracle's own r_free and an unguarded map is
returned as ``recoverable_unguarded``; a refit at the planted strength (``planted``) is a
diagnostic of the search, never used by the rule.

Units: q, x, knots in mm; c, y, RMSE in deg; t in s; strength in the variant's ``unit``.
Nothing here imports playscope.diagnose, and the diagnosis imports nothing from here
(tests/python/sim/test_blind_imports.py).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import minimize_scalar

from .oracle import (N_HALF_KNOTS, effect_free_fit, fit_half_widths, half_width_knots, linear_map, map_columns,
                     noise_only_rmse)
from .hidden_plant import STATE_HZ, clearance
from .variants import Bound, Variant

RULE_SHARE = 0.25       # recoverable: r_eff - n <= RULE_SHARE (r_free - n) (the 25 %)
GRID_POINTS = 9         # log grid of the strength over [min/4, 4 max] of the variant's strengths
GRID_NFEV = 30          # least_squares iterations of the knots at each grid point (warm-started)
GRID_ALT = 3            # alternations at each grid point (effects after the bend)
SEARCH_FTOL = 1e-4      # the knots' least_squares stops when the cost changes by less (grid, refine)
FINAL_FTOL = 1e-6
REFINE_ITER = 6         # bounded Brent iterations on log strength
FINAL_NFEV = 30         # the final refit at the chosen strength
FINAL_ALT = 4
NEWTON_ITER = 2         # Gauss-Newton steps of the map after each alternation (effects after the bend)
NEWTON_TRIAL = 3        # after this many steps, Gauss-Newton is kept only if it gained on average ...
NEWTON_MIN_GAIN = 0.01  # ... this share of the fit RMSE a step (a staircase's derivative is useless)
NEWTON_STEP_DEG = 1e-3  # forward-difference step of the map's coefficients (deg)
FLAT_STARTS = (0.06, 0.2)   # the final refit also starts from the effect-free oracle's flat knots (x span)
CENTRE_SCAN = 0.15      # nuisance q_c: within mid +- CENTRE_SCAN x span of q, fitted with the knots ...
CENTRE_STEPS = 19       # ... from the previous centre and from the best of a scan at this many points
RNG_SEED = 20240610     # the oracle's own random stream for hooks that draw (a sensor's jitter)


class _InSituPlant:
    """The plant as the oracle knows it: the straight position q_c (a fitted nuisance, mm) and the
    bending map bend(x) (the oracle's own Chebyshev map, deg). ``asked`` records which of them a
    hook read; any other plant attribute raises AttributeError."""

    def __init__(self, q_c: float, lo: float, hi: float, coef: np.ndarray):
        self._q_c, self._lo, self._hi, self.coef = float(q_c), lo, hi, coef
        self.asked: set[str] = set()

    @property
    def q_c(self) -> float:
        self.asked.add("q_c")
        return self._q_c

    def bend(self, x):
        self.asked.add("bend")
        v = map_columns(np.atleast_1d(np.asarray(x, float)), self._lo, self._hi) @ self.coef
        return float(v[0]) if np.ndim(x) == 0 else v

    def __getattr__(self, name):
        raise AttributeError(f"plant.{name}: not known to the recoverability oracle (estimate it in situ)")


class _Fit:
    """One refit of the base at a given strength (and centre): knots h (9,), map coef (16,),
    prediction at the sensor samples (Ny,), fit RMSE (deg)."""

    def __init__(self, k, q0, h, coef, pred, rmse_fit):
        self.k, self.q0, self.h, self.coef, self.pred, self.rmse_fit = k, q0, h, coef, pred, rmse_fit


class _Oracle:
    def __init__(self, session, variant: Variant, fit_sel: np.ndarray):
        t_q, q = np.asarray(session.encoder["t_s"], float), np.asarray(session.encoder["q"], float)
        n = int(np.floor((t_q[-1] - t_q[0]) * STATE_HZ + 1e-6)) + 1
        t = t_q[0] + np.arange(n) / STATE_HZ
        if t_q.size == n and np.allclose(t_q, t, atol=1e-9, rtol=0):
            self.t, self.q = t_q, q                     # the generator's own state grid
        else:
            self.t, self.q = t, np.interp(t, t_q, q)
        self.lo, self.hi = float(self.q.min()), float(self.q.max())
        self.span = max(self.hi - self.lo, 1e-9)
        self.kn = half_width_knots(self.lo, self.hi)
        self.t_y = np.asarray(session.distal["t_s"], float)
        self.y = np.asarray(session.distal["c_deg"], float)
        self.fit = np.asarray(fit_sel, bool) & np.isfinite(self.y)
        self.v = variant
        self.guard = True        # the map continues along its tangent outside the fitted carrier range
        self.plant = _InSituPlant(0.5 * (self.lo + self.hi), self.lo, self.hi, np.zeros(1))
        self.acted: set[str] = set()
        self.newton_tried = 0        # Gauss-Newton steps tried, and their summed relative gain in fit RMSE:
        self.newton_gain = 0.0       # under NEWTON_MIN_GAIN a step on average, no more are tried
        self.centre_in_fit = True    # the nuisance centre fitted with the knots (hooks before the bend)
        self.ftol = SEARCH_FTOL      # least_squares' relative cost tolerance (FINAL_FTOL for the last refit)

    # ------------------------------------------------------------------ the pipeline of plant.run
    def carrier(self, k: float, q0: float, h: np.ndarray) -> dict:
        """Actuator, clearance and carrier stages with the oracle's half-width h at its knots."""
        self.plant._q_c = float(q0)
        ctx = {"t": self.t, "q": self.q, "plant": self.plant, "rng": np.random.default_rng(RNG_SEED),
               "qa": self.q.copy()}
        self.hook("actuator", ctx, k)
        if not np.array_equal(ctx["qa"], self.q):
            self.acted.add("actuator")
        half = np.interp(ctx["qa"], self.kn, h)
        ctx["below"], ctx["above"], ctx["x"] = half, half.copy(), None
        self.hook("clearance", ctx, k)
        if ctx["x"] is None:
            if not (np.array_equal(ctx["below"], half) and np.array_equal(ctx["above"], half)):
                self.acted.add("clearance")
            ctx["x"] = clearance(ctx["qa"], ctx["below"], ctx["above"])
        else:
            self.acted.add("clearance")
        x = ctx["x"]
        self.hook("carrier", ctx, k)
        if ctx["x"] is not x and not np.array_equal(ctx["x"], x):
            self.acted.add("carrier")
        return ctx

    def hook(self, stage: str, ctx: dict, k: float) -> None:
        if self.v is not None:
            self.v.fn(stage, ctx, k)

    def inside(self, x: np.ndarray, t_seen: np.ndarray):
        """The carrier range (mm) seen on the fit samples, or None (no guard)."""
        if not self.guard:
            return None
        xf = np.interp(t_seen[self.fit], self.t, x)
        return float(xf.min()), float(xf.max())

    def columns(self, x: np.ndarray, t_seen: np.ndarray) -> np.ndarray:
        return map_columns(np.interp(t_seen, self.t, x), self.lo, self.hi, self.inside(x, t_seen))

    def post(self, ctx: dict, k: float, coef: np.ndarray):
        """Bend, sensor and reading stages on the oracle's map. Returns (prediction (Ny,), d: its
        difference from the plain base at the seen times (Ny,), t_seen (Ny,), plain: no hook acted
        after the bend other than moving the sample times)."""
        self.plant.coef = coef
        ctx["rng"] = np.random.default_rng(RNG_SEED)   # the same draws at every evaluation
        x = ctx["x"]
        c = map_columns(x, self.lo, self.hi, self.inside(x, self.t_y)) @ coef
        ctx["c"] = c.copy()
        self.hook("bend", ctx, k)
        bent = not np.array_equal(ctx["c"], c)
        ctx["ts"], ctx["t_seen"], ctx["cs"] = self.t_y, self.t_y.copy(), None
        self.hook("sensor", ctx, k)
        set_cs = ctx["cs"] is not None
        if not np.array_equal(ctx["t_seen"], self.t_y):
            self.acted.add("sensor")
        if not set_cs:
            ctx["cs"] = np.interp(ctx["t_seen"], self.t, ctx["c"])
        cs = ctx["cs"].copy()
        self.hook("reading", ctx, k)
        read = not np.array_equal(ctx["cs"], cs)
        for st, on in (("bend", bent), ("sensor", set_cs), ("reading", read)):
            if on:
                self.acted.add(st)
        t_seen = ctx["t_seen"]
        base = self.columns(x, t_seen) @ coef
        if not (bent or set_cs or read):
            return base, np.zeros(base.size), t_seen, True
        return ctx["cs"], ctx["cs"] - base, t_seen, False

    def rms_fit(self, pred: np.ndarray) -> float:
        e = (self.y - pred)[self.fit]
        return float(np.sqrt(np.mean(e * e)))

    # ------------------------------------------------------------------ refits
    def refit(self, k: float, q0: float, h0: np.ndarray, coef0: np.ndarray, n_alt: int, nfev: int,
              fresh: bool = False, nuisance: bool = False) -> _Fit:
        """The base refitted at strength k, from knots h0, centre q0 and map coef0. fresh: also from
        the effect-free oracle's two flat starts, at the first alternation; nuisance: the centre q0 is
        fitted with the knots (its effect after the bend recomputed at each trial, the map held)."""
        ctx = self.carrier(k, q0, h0)
        _, d, t_seen, plain = self.post(ctx, k, coef0)
        best, h, coef = None, np.asarray(h0, float), coef0
        lo_c, hi_c = self.centre_bounds()
        for it in range(1 if plain else n_alt):
            def res(p, d=d, t_fit=t_seen[self.fit], coef=coef):
                c2 = self.carrier(k, p[-1] if nuisance else q0, p[:N_HALF_KNOTS])
                A = map_columns(np.interp(t_fit, self.t, c2["x"]), self.lo, self.hi)   # fit rows: no guard
                target = (self.y - (self.post(c2, k, coef)[1] if nuisance and not plain else d))[self.fit]
                return target - A @ linear_map(A, target, np.ones(target.size, bool))

            hs = [h] + ([np.full(h.size, f * self.span) for f in FLAT_STARTS] if fresh and it == 0 else [])
            starts = [np.append(hh, np.clip(q0, lo_c, hi_c)) for hh in hs] if nuisance else hs
            p = fit_half_widths(res, starts, self.span, max_nfev=nfev,
                                extra_bounds=[(lo_c, hi_c)] if nuisance else (), ftol=self.ftol).x
            h, q0 = (p[:N_HALF_KNOTS], float(p[-1])) if nuisance else (p, q0)
            ctx = self.carrier(k, q0, h)
            if nuisance and not plain:
                d = self.post(ctx, k, coef)[1]
            coef = linear_map(self.columns(ctx["x"], t_seen), self.y - d, self.fit)
            pred, d, t_seen, plain = self.post(ctx, k, coef)
            for _ in range(0 if plain else NEWTON_ITER):
                coef, pred, d = self.newton(ctx, k, coef, pred, d)
            f = _Fit(k, q0, h, coef, pred, self.rms_fit(pred))
            if best is None or f.rmse_fit < best.rmse_fit:
                best = f
        return best

    def newton(self, ctx: dict, k: float, coef: np.ndarray, pred: np.ndarray, d: np.ndarray):
        """One Gauss-Newton step of the map through the whole pipeline after the bend (Jacobian by
        forward differences of the coefficients, the knots held; a full then a half step), kept
        only if it lowers the fit RMSE. A staircase or a switch has no useful derivative: once the
        steps tried gain under NEWTON_MIN_GAIN on average, none is tried (its 16 evaluations of
        the pipeline are the cost of a refit for a slow hook)."""
        if self.newton_tried >= NEWTON_TRIAL and self.newton_gain < NEWTON_MIN_GAIN * self.newton_tried:
            return coef, pred, d
        self.newton_tried += 1
        J = np.empty((pred.size, coef.size))
        for j in range(coef.size):
            dc = np.zeros(coef.size)
            dc[j] = NEWTON_STEP_DEG
            J[:, j] = (self.post(ctx, k, coef + dc)[0] - pred) / NEWTON_STEP_DEG
        r0 = self.rms_fit(pred)
        step = linear_map(J, self.y - pred, self.fit)
        for a in (1.0, 0.5):
            p2, d2, _, _ = self.post(ctx, k, coef + a * step)
            r2 = self.rms_fit(p2)
            if r2 < r0:
                self.newton_gain += (r0 - r2) / r0
                return coef + a * step, p2, d2
        return coef, pred, d

    def centre_bounds(self) -> tuple[float, float]:
        mid = 0.5 * (self.lo + self.hi)
        return mid - CENTRE_SCAN * self.span, mid + CENTRE_SCAN * self.span

    def centre(self, k: float, h: np.ndarray, coef: np.ndarray, refine: bool = False) -> float:
        """The nuisance q_c at strength k, the knots held: a scan over the middle of the q range, the
        map refitted to y - d at each point (one alternation); refine: then bounded Brent within
        one step of the scan's best."""
        lo_c, hi_c = self.centre_bounds()

        def cost(q0):
            ctx = self.carrier(k, q0, h)
            _, d, t_seen, _ = self.post(ctx, k, coef)
            c1 = linear_map(self.columns(ctx["x"], t_seen), self.y - d, self.fit)
            return self.rms_fit(self.post(ctx, k, c1)[0])

        grid = np.linspace(lo_c, hi_c, CENTRE_STEPS)
        costs = [cost(q0) for q0 in grid]
        i = int(np.argmin(costs))
        if not refine:
            return float(grid[i])
        step = grid[1] - grid[0]
        r = minimize_scalar(cost, bounds=(grid[i] - step, grid[i] + step), method="bounded",
                            options={"xatol": 0.01 * step, "maxiter": 8})
        return float(r.x) if r.fun < costs[i] else float(grid[i])

    def at(self, k: float, start: _Fit, nuisance: bool, n_alt: int, nfev: int, fresh: bool = False,
           rounds: int = 1) -> _Fit:
        """The refit at strength k from a previous fit. With the nuisance centre: from the previous
        centre and from the best of a scan (the base held), the better kept; for a hook before the
        bend the centre is then fitted with the knots, after the bend (the centre moves the effect
        the knots fit holds) it stays where it started, and ``rounds`` - 1 more times a refined scan
        from the kept fit's base and a refit from there."""
        if not nuisance:
            return self.refit(k, start.q0, start.h, start.coef, n_alt, nfev, fresh)
        best = self.refit(k, start.q0, start.h, start.coef, n_alt, nfev, fresh, self.centre_in_fit)
        q1 = self.centre(k, start.h, start.coef)
        lo_c, hi_c = self.centre_bounds()
        if abs(q1 - start.q0) > 0.5 * (hi_c - lo_c) / (CENTRE_STEPS - 1):
            f = self.refit(k, q1, start.h, start.coef, n_alt, nfev, fresh, self.centre_in_fit)
            if f.rmse_fit < best.rmse_fit:
                best = f
        for _ in range(rounds - 1):
            q2 = self.centre(k, best.h, best.coef, refine=True)
            if abs(q2 - best.q0) > 1e-3 * (hi_c - lo_c):
                f = self.refit(k, q2, best.h, best.coef, n_alt, nfev, False, self.centre_in_fit)
                if f.rmse_fit < best.rmse_fit:
                    best = f
        return best


def recoverable(session, variant, fit_sel: np.ndarray, judge_sel: np.ndarray, free: dict | None = None,
                share: float = RULE_SHARE, planted: float | None = None) -> dict:
    """Is the planted effect of a generator session recoverable in situ by a model that knows its form?

    session: a generator record (plant.record; meta["clean_reading_deg"] is the noise-free reading);
    variant: the planted variants.Variant (or a Bound: only its form is used, never its strength);
    fit_sel, judge_sel: bool (Ny,) over the session's sensor samples (the oracle fits on fit_sel,
    judges on judge_sel); free: oracle.effect_free_fit on the same selections, when already computed
    (its knots are the warm start); planted: the planted strength, for a diagnostic refit at it
    (``rmse_effect_at_planted_deg``) that the rule never uses.
    Returns (RMSE in deg, judged on judge_sel unless named _fit):
      rmse_free_deg      r_free: the effect-free oracle's model refitted by this oracle's code (same
                         state grid, same guarded map), no effect;
      rmse_effect_deg    r_eff: the same model with the effect at its fitted strength;
      noise_deg          n: the record minus the generator's noise-free reading;
      strength_fitted    in the variant's unit; centre_fitted_mm: the fitted straight position
                         (None when the hook does not read it);
      excess_left        (r_eff - n) / (r_free - n);
      recoverable        r_eff - n <= share (r_free - n);
      rmse_free_oracle_deg, rmse_effect_unguarded_deg, recoverable_unguarded: the same rule with
                         the effect-free oracle's own figure (oracle.effect_free_fit, as the
                         "identifiable" column) and this oracle's map extrapolated as a plain series;
      stages, grid [(strength, fit RMSE)], rmse_effect_fit_deg, rmse_free_fit_deg, seconds.
    The rule and why: module docstring.
    """
    t0 = time.time()
    v = variant.v if isinstance(variant, Bound) else variant
    fit_sel, judge_sel = np.asarray(fit_sel, bool), np.asarray(judge_sel, bool)
    t_y, y = session.distal["t_s"], session.distal["c_deg"]
    if free is None:
        free = effect_free_fit(session.encoder["t_s"], session.encoder["q"], t_y, y, fit_sel, judge_sel)
    o = _Oracle(session, v, fit_sel)
    judged = judge_sel & np.isfinite(o.y)

    def judge(pred):
        e = (o.y - pred)[judged]
        return float(np.sqrt(np.mean(e * e)))

    # The effect-free model on this oracle's grid and map (the reference of the rule).
    h_free = np.asarray(free["half_knots_mm"], float)
    o.v = None
    ctx = o.carrier(0.0, o.plant._q_c, h_free)
    coef_free = linear_map(o.columns(ctx["x"], o.t_y), o.y, o.fit)
    o.ftol = FINAL_FTOL
    base = o.refit(0.0, o.plant._q_c, h_free, coef_free, 1, FINAL_NFEV, fresh=True)
    o.ftol = SEARCH_FTOL
    o.v, o.acted = v, set()
    start = base

    # Which plant quantities does the hook read? (a probe at the middle strength; nothing fitted)
    k_lo, k_hi = min(v.strengths) / 4.0, max(v.strengths) * 4.0
    probe = o.carrier(np.sqrt(k_lo * k_hi), start.q0, start.h)
    o.post(probe, np.sqrt(k_lo * k_hi), start.coef)
    nuisance = "q_c" in o.plant.asked
    o.centre_in_fit = not (o.acted & {"bend", "sensor", "reading"})

    # Continuation: each grid point from its weaker neighbour's fit (the effect-free fit first).
    fits, cur = [], start
    for k in np.geomspace(k_lo, k_hi, GRID_POINTS):
        cur = o.at(float(k), cur, nuisance, GRID_ALT, GRID_NFEV)
        fits.append(cur)
    grid = [(f.k, f.rmse_fit) for f in fits]
    i = int(np.argmin([f.rmse_fit for f in fits]))
    best = fits[i]
    lk = np.log([f.k for f in fits])
    tried = []

    def obj(u):
        f = o.at(float(np.exp(u)), fits[i], nuisance, GRID_ALT, GRID_NFEV)
        tried.append(f)
        return f.rmse_fit

    minimize_scalar(obj, bounds=(lk[max(i - 1, 0)], lk[min(i + 1, len(lk) - 1)]), method="bounded",
                    options={"xatol": 0.01, "maxiter": REFINE_ITER})
    for f in tried:
        if f.rmse_fit < best.rmse_fit:
            best = f
    o.ftol = FINAL_FTOL
    final = o.at(best.k, best, nuisance, FINAL_ALT, FINAL_NFEV, fresh=True, rounds=2)
    if final.rmse_fit > best.rmse_fit:
        final = best

    out = {}
    if planted is not None:
        fp = o.at(float(planted), final, nuisance, FINAL_ALT, FINAL_NFEV, fresh=True, rounds=2)
        out["rmse_effect_at_planted_deg"] = judge(fp.pred)
        out["rmse_effect_at_planted_fit_deg"] = fp.rmse_fit
    r_eff, r_free = judge(final.pred), judge(base.pred)
    # The same fits with the map extrapolated as a plain series (the effect-free oracle's map).
    o.guard = False
    r_eff_plain = judge(o.post(o.carrier(final.k, final.q0, final.h), final.k, final.coef)[0])
    o.guard = True
    r_free_oracle = float(free["rmse_judged_deg"])
    n = noise_only_rmse(session, judge_sel)
    out.update({
        "rmse_free_deg": r_free, "rmse_effect_deg": r_eff, "noise_deg": n,
        "strength_fitted": float(final.k), "centre_fitted_mm": float(final.q0) if nuisance else None,
        "excess_left": (r_eff - n) / (r_free - n) if r_free > n else float("inf"),
        "recoverable": bool(r_eff - n <= share * (r_free - n)),
        "rmse_free_oracle_deg": r_free_oracle, "rmse_effect_unguarded_deg": r_eff_plain,
        "recoverable_unguarded": bool(r_eff_plain - n <= share * (r_free_oracle - n)),
        "stages": sorted(o.acted), "grid": grid, "rmse_effect_fit_deg": final.rmse_fit,
        "rmse_free_fit_deg": base.rmse_fit, "seconds": time.time() - t0})
    return out
