"""Which model of the record (onset_model): the starts, B's size and where it is read, and the terms,
each chosen by the same BIC (onset_fit.Fit.bic); `fit_record` is the onset stage's estimator.

Start: the coarse delay and the configured one, each with the constant play width that fits best.
The coarse delay is the peak of delay_guess's correlation, profiled over the frame before it, whose
profiled start the plain model scores best (`_coarse_starts`): an excitation that repeats makes the
correlation as high one period late, and a peak sits late by up to the play's take-up. The plain
model's own start is then the one, of every profiled peak and the configured delay, whose
constant-width trial fit scores the lowest BIC (`_fitted_start`): the profiled score alone can rank an
alias first where B varies over the travel.
The board's plain eq. 1 samples are a third start when given. B is fitted coarse to fine
(`_fit_chain`): a constant width, then each of B_CTRL's sizes from the last one's fit. A term the
plain model lacks drags its width, so each term also gets starts profiled with it on (the
delay and the constant width by the robust cost; the tip mode's at each of RING_ZETA_STARTS at the
one of its scan's local minima that profiles lowest), each carried coarse to fine and scored by
the BIC, for the term whose trial fit leads the round once it lowers the BIC (those chains are a
round's costly part). A switch's trials start from the fit so far and from the one of its other
starts whose settled cost is lowest (`_trial_starts`).

Terms by evidence: the tip mode, each registration term, the exposure and the plant's spread of widths
enter when they lower the record's
BIC (Schwarz 1978) on the robust objective (2 sum rho(r_j / sigma_j) + 2 sum ln(sigma_j / sigma),
the Gaussian's normalisation for the inflated scales), the same criterion for each; the search
adds the best term, refits, and tries the rest again. Then each entered term is offered in exchange
for its round's near rivals (`_exchange`: runner-ups within Occam's window, OCCAM_BIC). Last, the
final model is restarted along the directions its parts trade in (`_trade_profile`): B's level
scaled up and down, each switch's lag crossed with the exposure; the best kept where the BIC is lower.

Units: t in s, q and B in actuator units, image points in px.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .delay_guess import SUB
from ..base.forkmap import fork_map
from .onset_fit import (IRLS_ROUNDS, Fit, _fit_all, _fit_chain, _fit_distinct, _fresh,
                        _resample_B, _settle, _slim, _unslim, fit_model)
from .onset_model import WIDTH_AT, Record, RecordModel, Terms, noise_sigma, robust_sigma

G_CTRL = (6, 10, 14)   # the image path's coefficients per axis, chosen by BIC on the start
B_CTRL = (4, 8, 16)    # B(q)'s coefficients, chosen by BIC on the plain model (a cubic needs 4) ...
B_REV_PER_CTRL = 1     # ... with at least one reversal (one onset) per coefficient
SIGMA_RERUN = 0.7      # the search runs again at the fit's residual scale when that is below this share of
                       # the second differences' (a scale 30 % off moves the Huber corner and the weight
                       # of the data in the BIC by as much; the MAD of a few thousand residuals is
                       # itself good to a few %)
RING_ZETA_STARTS = (0.03, 0.1, 0.3)  # the tip mode's damping ratios a ring start is profiled at: a factor
                       # of about 3 apart over the lightly damped modes the term is for (above about 0.5 a
                       # mode barely rings), so LM starts within its reach of the ratio
EXPO_GRID = (0.1, 0.25, 0.5, 1.0)  # the exposure term's start grid, frame periods (its trial starts at the point
                       # whose settled cost is lowest, `_lowest_settled`), as a slide's lag grid: at most a
                       # factor 2.5 apart over its range [T / 20, T] (from 0.25 up, the 4 ms exposure of
                       # dev-reg0-swings25-fast was out of a trial fit's reach: its best trial 4,999 against
                       # 4,987 from 0.1; the settled cost over e was unimodal about the truth on two renderings,
                       # 20 and 35 ms at 25 fps)
SPREAD_GRID = (0.2, 0.5, 0.8)  # the spread term's start grid (onset_model's module doc: the spread; its trial starts
                       # at the point whose settled cost is lowest, as the exposure's): over its range
                       # [0, SPREAD_MAX], from a take-up a fifth of B wide to most of it


TRIAL_OTHER_STARTS = 1  # a switch's trial starts besides the fit so far (`_trial_starts`): the lowest by their settled
                       # cost of its other starts (each delay start, its profiled start). Over the development
                       # rendering traced (fifteenth-registration-triangle25: 12 switch or shift trials over two
                       # searches, every other start given its trial), the lowest settled of a switch's other
                       # starts was its best other trial's in 11 of 12; the miss, a motor switch, ended at BIC
                       # 303,841 against 290,874 in a round the tip switch led at 27,971. The fit so far's start
                       # is always tried. Not the tip mode's: there the settled cost at a start
                       # (its frequency from the scan) ranked the best trial's last twice, and on the alias test
                       # (`_ring_profiled_starts`) the mode was lost (5.45 Hz for 5.73)


TRIAL_ROUNDS = 1       # a term's trial fit (8 evaluations): one reweighting, since a term that adds to the fit so
                       # far starts from that fit, its own linear gains solved there, so the weights set at
                       # the start are near that fit's settled ones; a shift is the exception (`_trial_rounds`)


def _trial_rounds(name: str) -> int:
    """The IRLS rounds of a term's trial fit: TRIAL_ROUNDS, or IRLS_ROUNDS for a shift, which takes its
    rotation's place rather than adding to the fit so far. At its start the switch frames are the
    translation's misfit to the rotation's jump (tens of px where the jump is), so the weights and the
    mixture's shares set there are not the fit so far's, and one round scores the shift at weights it
    has not settled: on s9-marker-032 of LOCKBOX9_300 (a 2.63 deg channel translation at 60 fps) the
    shift's trial scored BIC 21,711 after one round, 17,894 after two, 16,974 after three, against the
    rotation's 20,045, so the search kept the rotation (B 5.2 % off; with these rounds the shift enters, 0.6 %)."""
    return IRLS_ROUNDS if name.startswith("shift_") else TRIAL_ROUNDS


# --------------------------------------------------------------------------- the start
def _n_b_ladder(n_rev: int) -> list[int]:
    """B's sizes the plain model tries for n_rev reversals: those of B_CTRL with at least
    B_REV_PER_CTRL reversals each; a constant width (1) when none has."""
    return [n for n in B_CTRL if n * B_REV_PER_CTRL <= n_rev] or [1]


def _start_widths(rec: Record, board_b: np.ndarray | None) -> list[float]:
    """The constant widths a start is profiled over (actuator units): 12 log-spaced in 2 %..100 %
    of the median swing between reversals (a play from a trace of one swing to all of it), and
    the board's median sample when given."""
    swing = float(np.median(np.abs(np.diff(rec.rq)))) if rec.rq.size > 1 else float(np.ptp(rec.q))
    widths = list(swing * np.geomspace(0.02, 1.0, 12))
    if board_b is not None and board_b.size:
        widths.append(float(np.median(board_b)))
    return widths


def _start(rec: Record, d_starts: list[float], prior, d_fixed, board_b: np.ndarray | None,
           sigma: float) -> tuple[dict, int]:
    """The start: for each delay candidate, each constant width (12 log-spaced in 2 %..100 % of
    the median swing between reversals, and the board's median sample when given) and each set of
    the linear registration terms (none, tip, motor: cheap, and a switch left out of the start
    drags the width), the lowest BIC at sigma; then G's size by BIC there. The terms themselves
    are chosen later, on B(q) as a spline (at a constant width, a tip-registration offset takes
    up B's own variation over the travel); each registration term's own best start is kept for
    when the search tries it. Returns ({term names (tuple): (t_delay, width)}, n_g)."""
    widths = _start_widths(rec, board_b)

    def lowest(terms: Terms) -> tuple[float, float, float]:
        """(BIC, delay, width) of the lowest of terms' profile, the first of equal scores: a set of terms
        an item on two cores (base.forkmap; a score depends on its delay and width alone)."""
        m = RecordModel(rec, 1, G_CTRL[1], terms, prior, d_fixed)
        best = None
        for d in d_starts:
            for b in widths:
                c = _start_bic(m, d, b, sigma)
                if best is None or c < best[0]:
                    best = (c, d, b)
        return best

    sets = [Terms(), Terms(reg_tip=True), Terms(reg_motor=True)]
    best = {tuple(t.names()): v for t, v in zip(sets, fork_map(lowest, sets))}
    _, d, b = min(best.values())
    bics = [_start_bic(RecordModel(rec, 1, n_g, Terms(), prior, d_fixed), d, b, sigma) for n_g in G_CTRL]
    return {k: v[1:] for k, v in best.items()}, G_CTRL[int(np.argmin(bics))]


def _start_bic(m: RecordModel, d: float, b: float, sigma: float) -> float:
    """A start's score: the BIC at sigma (px) of model m (a constant width) at delay d (s) and width
    b (actuator units), its other nonlinear parameters at their starts and its linear ones solved."""
    ev = m.evaluate(m.theta({"d": np.array([d]), "B": np.array([b])}))
    return float(m.objective(ev, sigma) + m.n_linear() * np.log(ev.resid.size))


def _profiled_start(m: RecordModel, d: float, widths: list[float], sigma: float, step: float) -> tuple[float, float, float]:
    """The start a correlation peak at d (s) means: over the delays d, d - step, ..., d - SUB * step
    (one frame period back on the correlation's own grid, step = period / SUB), the delay and
    constant width of lowest `_start_bic` (model m, a constant width; sigma px). widths (W,)
    ascending, actuator units: all are scored at d, and from there the width only grows as the
    delay shrinks (the onset after a reversal comes at delay + width / speed, so an earlier delay
    needs a wider play to place it), each step trying the next wider while it scores lower.
    Returns (BIC, delay s, width)."""
    score = lambda dd, k: _start_bic(m, dd, widths[k], sigma)  # noqa: E731
    c = [score(d, k) for k in range(len(widths))]
    k = int(np.argmin(c))
    best = (c[k], d, widths[k])
    for dd in d - step * np.arange(1, SUB + 1):
        if dd < 0.0:
            break
        ck = score(dd, k)
        while k + 1 < len(widths):
            cn = score(dd, k + 1)
            if cn >= ck:
                break
            k, ck = k + 1, cn
        if ck < best[0]:
            best = (ck, float(dd), widths[k])
    return best


def _coarse_starts(rec: Record, cands: np.ndarray, prior, board_b: np.ndarray | None, sigma: float) -> list[float]:
    """The coarse delays the search may start from: the correlation's candidates cands (K,) s
    (delay_guess.coarse_delay_peaks, its highest first), each profiled over the frame period before
    it (`_profiled_start`: the plain model at a constant width, BIC at sigma), lowest BIC first
    (ties keep the earlier). prior: the configured delay's (mean, sd) s or None; board_b: the
    board's eq. 1 samples or None (`_start_widths`). Returns (K,) s; the first is the coarse start,
    and all are offered to `_fitted_start`.

    Why a profile a frame back: the correlation is flat from the delay to where the play is taken
    up (delay_guess.delay_score), so its peak sits up to that much late, and the frames time it to
    about a frame. On a fast swing a delay and a width trade, so the start's basin in the delay is
    narrow (+-5 ms), and neither the score at the peak nor a fit from it reaches the delay: on
    s11-swing-066 (a 25 fps triangle of 0.376 s period, delay 50 ms, none configured) the peak near
    the delay was at 75 ms, where the best width was the grid's narrowest (BIC 5,958), and an
    8-evaluation fit from there ended at 72 ms, BIC 4,518, above the alias one period late (3,447);
    the search from the alias was 9.1 frames late, B 11.6 % off. Profiled, that peak starts at 50 ms,
    BIC 1,952, the alias at 425 ms, 3,341.
    Why more than the highest: an excitation that repeats makes the correlation as high one period
    late as at the delay, where the record's model is not: on s5-swing-056 (a 60 fps triangle of
    0.29 s period, delay 92 ms, configured 179 ms) the correlation's highest point was the alias at
    408 ms (the search from there 17.8 frames late with B 29 % off), its other peak at 117 ms.
    The start's B is a constant width, so where B varies over the travel its score is biased in the
    delay (on the 3-minute bench record, delay 80 ms, it is lowest at 40 ms): it only has to tell a
    peak from an alias, and the search's B(q) takes the rest back."""
    m = RecordModel(rec, 1, G_CTRL[1], Terms(), prior, None)
    widths = sorted(_start_widths(rec, board_b))
    # each peak's profile on two cores (base.forkmap): m's weights stay at 1, so a score is a function of
    # its delay and width alone, whichever process computes it
    starts = fork_map(lambda d: _profiled_start(m, float(d), widths, sigma, rec.period_s / SUB), list(cands))
    return [s[1] for s in sorted(starts, key=lambda s: s[0])]  # sorted keeps the first of equal scores


SLIDE_GRID = ((0.25, 0.5, 1.0), (0.25, 0.5, 1.0))  # a slide's start grid: lags, longest slides (frame periods)


def _lowest_settled(m: RecordModel, th0s: list, sigma: float, keep: int, fresh: bool = False) -> tuple[list, list]:
    """(the indices of the keep of the starts th0s (thetas of model m) with the lowest settled robust
    objective (`_settle`, at sigma px), lowest first, ties keeping the earlier; every start's cost).
    fresh False: the starts are settled on m in turn, which leaves m's weights and mixture (and,
    with the tip mode, its tangent) as the last start's settle set them; a trial fit from a kept start
    resets the weights and mixture (`_fit_one`) but not the tangent. fresh True: each on its own fresh
    copy of m (`_fresh`), as its trial fit would begin, so a start's cost depends on it alone."""
    if fresh:  # each on its own copy: on two cores (base.forkmap; in turn within another map's item)
        costs = fork_map(lambda th: _settle(_fresh(m), th, sigma)[1], th0s)
    else:
        costs = [_settle(m, th, sigma)[1] for th in th0s]
    return sorted(range(len(th0s)), key=lambda i: (costs[i], i))[:keep], costs


def _trial_starts(m: RecordModel, th0s: list, sigma: float) -> list:
    """A switch's trial starts (thetas (n_theta,) of its model m) from its candidates th0s, the fit so
    far's first: that one, and the TRIAL_OTHER_STARTS of the rest with the lowest settled robust
    objective at sigma px (`_lowest_settled`, each on a fresh copy of m, as its trial fit begins).
    Returns a sublist of th0s (th0s itself when it holds no more than that); no errors of its own. Why not a trial from
    each: the other starts (each delay start at the start's width, a switch's profiled start) are
    there for a fit so far dragged into another basin by the term's absence, where the start nearest
    the term's own basin settles lowest, and each trial is 8 evaluations with their Jacobians against
    a settle's 3 evaluations: on the 3-minute bench record, 12 trials became 9."""
    if len(th0s) <= 1 + TRIAL_OTHER_STARTS:
        return th0s
    kept, _ = _lowest_settled(m, th0s[1:], sigma, TRIAL_OTHER_STARTS, fresh=True)
    return [th0s[0]] + [th0s[1 + i] for i in kept]


def _slide_starts(m: RecordModel, name: str, parts: dict, sigma: float, keep: int = 2) -> list:
    """Starts (theta) for the switch name's slide ("tip" or "motor") from the fit so far's parts: its
    lag L and longest slide D on SLIDE_GRID, the keep lowest by the settled robust objective
    (`_lowest_settled`). Why a grid: L and D trade against each other (a late start with a short slide
    against an early one with a long slide), and from the middle of both ranges LM stopped in the
    wrong one (a 15 s channel rendering: L at its floor, B 4.7 % off, BIC 862; from the grid, BIC 676
    and B 0.6 % off). Why two kept: the two trade, so the settled cost has a ridge, not one minimum."""
    T = m.rec.period_s
    th0s = [m.theta({**parts, "lag_" + name: np.array([m.lag_x(L * T)]), "slide_" + name: np.array([m.slide_x(D * T)])})
            for L in SLIDE_GRID[0] for D in SLIDE_GRID[1]]  # at most a frame period, within every slide bound (`slide_max_s` >= T)
    return [th0s[i] for i in _lowest_settled(m, th0s, sigma, keep)[0]]


def _ring_scan(m: RecordModel, parts: dict, sigma: float) -> np.ndarray:
    """The tip mode's frequency scan for model m (with the ring term) at the other parts of theta:
    the robust cost at damping ratio 0.1 on 0.25 Hz steps from RING_HZ_LO to RING_NYQUIST of the
    frame rate. Returns the scan's local minima (K,) Hz, its lowest first, then the others by cost.
    Sets m.slope (the path's tangent at the first frequency)."""
    fs = np.arange(*m.ring_band(), 0.25)
    m.slope = m.G_slope(m.evaluate(m.theta({**parts, "ring": m.ring_theta(fs[0], 0.1)})))
    c = np.array([m.objective(m.evaluate(m.theta({**parts, "ring": m.ring_theta(f, 0.1)})), sigma) for f in fs])
    lo = np.r_[True, c[1:] <= c[:-1]] & np.r_[c[:-1] < c[1:], True]
    i0 = int(np.argmin(c))
    others = [i for i in np.flatnonzero(lo)[np.argsort(c[lo], kind="stable")] if i != i0]
    return fs[[i0] + others]


def _ring_start(m: RecordModel, parts: dict, freqs_hz: np.ndarray, sigma: float) -> np.ndarray:
    """The tip mode's start for model m (with the ring term) from the other parts of theta: of the
    scan's local minima freqs_hz (Hz, `_ring_scan` at the fit so far), the one with the lowest robust
    cost at these parts, damping ratio 0.1 (ties keep the earlier). The minima, not a scan of their
    own: the parts (a delay start) move the onsets, not the mode the frames ring at, and a scan at a
    dragged fit can rank an alias lowest (`_ring_profiled_starts`)."""
    cost = [m.objective(m.evaluate(m.theta({**parts, "ring": m.ring_theta(float(f), 0.1)})), sigma) for f in freqs_hz]
    return m.theta({**parts, "ring": m.ring_theta(float(freqs_hz[int(np.argmin(cost))]), 0.1)})


def _ring_profiled_starts(rec: Record, n_g: int, terms: Terms, prior, d_fixed, parts: dict, freqs_hz: np.ndarray,
                          d_starts: list[float], widths: list[float], slope: np.ndarray, sigma: float) -> list[dict]:
    """The tip mode's own profiled starts, as `_start` gives each registration term its own: at a
    constant width with the ring on (and the terms of parts), for each delay of d_starts and each
    damping ratio of RING_ZETA_STARTS, the width of widths with the lowest robust cost, at the one
    of the scan's local minima freqs_hz (Hz, `_ring_scan`, its lowest first) whose profile at that
    delay and the scan's ratio, 0.1, is lowest (ties keep the earlier). Why profiled: a ring the
    plain fit lacked drags its width (the stop's swing read as an early onset: a play 10 times too
    narrow on a development record), and from there no fit reaches the ring's basin. Why each
    delay and each damping ratio its own start: the profile's cost ranks neither, since the
    constant width's misfit outweighs them, so each distinct start is carried through the chain and
    the BIC chooses. On s8-swing-086 of LOCKBOX8_300 (30 fps triangle, 0.368 s legs, a 7.44 Hz
    mode, B 0.15..0.28) the configured delay's best width profiled at 57,535 and the coarse delay's
    (1.2 frames late, a width a tenth of the truth's) at 58,437; kept at the lowest over both
    delays, only the late start was chained, and the search ended 1.76 frames late with B 72 % off
    (BIC 12,775); chained from the configured delay, the ring alone reaches BIC 3,315 at the truth.
    Why the frequency by the profile, not the scan: the scan runs at the dragged fit, where an
    alias can score lowest. On s5-render_c-092 (30 fps triangle, 89 ms legs, a 5.73 Hz mode) it
    picked 13.25 Hz, the frames' alias of the triangle's third harmonic, from which the search's
    best ring reached BIC 386; its minimum at 4.75 Hz profiles at cost 380 against 13.25's 725, and
    its chains reach 5.74 Hz, BIC 301. Each minimum is ranked by one profile per delay
    (len(widths) evaluations, 13 with the board's samples). Returns the distinct starts, parts of
    the constant-width model."""
    m = RecordModel(rec, 1, n_g, terms, prior, d_fixed)
    m.slope = slope
    keep = {k: v for k, v in parts.items() if k in m.layout() and k not in ("d", "B", "ring")}

    @functools.lru_cache(maxsize=None)  # the chosen minimum's profile at 0.1 is asked for twice
    def profile(f_hz, zeta, d):
        """(the lowest robust cost, its parts) over widths at the delay d and the mode (f_hz, zeta)."""
        best = None
        for b in widths:
            p = {**keep, "d": np.array([d]), "B": np.array([b]), "ring": m.ring_theta(f_hz, zeta)}
            c = m.objective(m.evaluate(m.theta(p)), sigma)
            if best is None or c < best[0]:
                best = (c, p)
        return best

    out = {}
    for d in dict.fromkeys(float(d) for d in d_starts):
        f_hz = float(min(freqs_hz, key=lambda f: profile(float(f), 0.1, d)[0]))
        for zeta in RING_ZETA_STARTS:
            best = profile(f_hz, zeta, d)
            key = (d, float(best[1]["B"][0]))
            if key not in out or best[0] < out[key][0]:
                out[key] = best
    return [p for _, p in out.values()]


def fit_record(rec: Record, t_delay_cfg: float | None, t_delay_from: str, d_coarse: float | np.ndarray,
               board_b: np.ndarray | None = None, prior_sd_s: float | None = None) -> tuple[Fit, dict]:
    """The record's model with its terms chosen by BIC (module doc). d_coarse: the coarse delay, s,
    or the correlation's candidates (K,) s, its highest first (delay_guess.coarse_delay_peaks), of
    which the search starts from the one the record scores best (`_coarse_starts`, `_fitted_start`). Returns (the
    final Fit, a JSON-ready dict of the term search). Runs its linear algebra on one BLAS thread: the
    matrices are small (frames x tens), where threads cost more than they give."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        fit, search = _fit_record(rec, t_delay_cfg, t_delay_from, d_coarse, board_b, prior_sd_s)
        fit.jac  # the final fit's Jacobian (computed when first asked for, onset_fit.Fit) on one thread too
        return fit, search


def _fit_record(rec, t_delay_cfg, t_delay_from, d_coarse, board_b, prior_sd_s):
    T = rec.period_s
    sd = prior_sd_s if prior_sd_s is not None else T / np.sqrt(12.0)
    prior = None if t_delay_cfg is None else (float(t_delay_cfg), float(sd))
    d_fixed = float(t_delay_cfg) if (t_delay_from == "config" and t_delay_cfg is not None) else None
    sigma = noise_sigma(rec.obs)
    cands = np.atleast_1d(np.asarray(d_coarse, float))
    peaks = [float(cands[0])] if d_fixed is not None else _coarse_starts(rec, cands, prior, board_b, sigma)
    d_coarse = peaks[0]
    starts = [d_coarse] + ([] if t_delay_cfg is None else [float(t_delay_cfg)])
    if d_fixed is not None:
        starts = [d_fixed]
    coarse = {"coarse_candidates_s": [float(d) for d in cands], "coarse_start_s": d_coarse}
    fit, search = _search(rec, starts, prior, d_fixed, board_b, sigma, peaks)
    search.update(coarse)
    # The second differences overstate the noise when the motion itself turns within a few frames
    # (a fast triangle: 5.2 px against the renderer's 0.24). The fitted model's residuals bound it
    # too; when they say it is clearly smaller, the search runs again at their scale, once, so that
    # every fit and every BIC of the record still share one scale.
    s_fit = robust_sigma(fit.ev.resid)
    if s_fit < SIGMA_RERUN * sigma:
        fit2, search2 = _search(rec, starts, prior, d_fixed, board_b, s_fit, peaks)
        search2["sigma_second_differences_px"] = sigma
        search2.update(coarse)
        return fit2, search2
    return fit, search


def _fitted_start(rec: Record, n_g: int, delays: list[float], widths: list[float], prior,
                  sigma: float) -> tuple[tuple[float, float], dict, Fit]:
    """The plain model's start: of the delays (s; the start's own, every profiled correlation peak
    and the configured delay), each at its constant width of widths (actuator units) of lowest
    `_start_bic`, the one whose constant-width plain trial fit (20 evaluations, TRIAL_ROUNDS
    reweightings: a ranking, as a term's trials rank its starts) scores the lowest BIC at sigma (px).
    Returns ((delay s, width), {delay: BIC} for the log, that trial fit: B's size chains start from
    its theta, their first link a full fit from there).

    Why a fit, not the start's score: the start's score is the model at one delay and width, its
    other parts unsettled, and where B varies over the travel its ranking of a peak against an alias
    a period late can invert. On s15-render_c-055 of LOCKBOX15_300 (a 25 fps triangle of 98 ms legs,
    delay 87 ms, configured 175 ms, B 0.144-0.253) the peaks profiled at 0.09 s (BIC 652) and at the
    alias 0.285 s (623); the search started from the alias and ended there, 4.9 frames late, its
    model 5,050 above the truth's, with a tip mode, a switch and a slide taking up the misfit. Fitted
    from each, the delay's start scores 435 and the alias's 514; the configured delay's fit also
    reaches 87 ms (436) (each a full fit, 3 reweightings; their trial fits, one, rank them the same)."""
    m = RecordModel(rec, 1, n_g, Terms(), prior, None, "input")

    def start(d: float) -> tuple[float, Fit]:
        """The delay d's width (of lowest `_start_bic`) and its trial fit: one item on two cores
        (base.forkmap; m's weights stay at 1, so a score depends on its delay and width alone, and a
        fit on its job alone, `_fit_one`)."""
        b = min(widths, key=lambda b: _start_bic(m, d, b, sigma))
        job = ([RecordModel(rec, 1, n_g, Terms(), prior, None, "input")], m.theta({"d": np.array([d]), "B": np.array([b])}),
               sigma, 20, TRIAL_ROUNDS)
        return b, _fit_chain(job)[-1]

    ds = list(dict.fromkeys(float(d) for d in delays))
    done = fork_map(start, ds, pack=lambda r: (r[0], _slim(r[1])), unpack=lambda r: (r[0], _unslim(r[1])))
    cands = [(d, b) for d, (b, _) in zip(ds, done)]
    fits = [f for _, f in done]
    bics = [f.bic(sigma) for f in fits]
    k = int(np.argmin(bics))
    return cands[k], {f"{d:.4f}": b for (d, _), b in zip(cands, bics)}, fits[k]


@dataclass
class _Search:
    """What a search builds its term trials from (`_term_trials`), fixed once its start is chosen:
    the record, G's size, the delay's prior (mean, sd) s or None and the held delay s or None, the
    delay starts s (the coarse, then the configured), the constant widths of the start's profile and
    the start's own (actuator units), each registration term's profiled start ({(name,): (delay s,
    width)}, `_start`), B's sizes (`_n_b_ladder`) and the scale sigma px."""

    rec: Record
    n_g: int
    prior: tuple | None
    d_fixed: float | None
    starts: list
    widths: list
    b0: float
    st: dict
    ladder: list
    sigma: float

    def chain(self, terms: Terms, sizes: list, width_at: str) -> list:
        """The models of a coarse-to-fine chain (`_fit_chain`): a constant width, then each size."""
        return [RecordModel(self.rec, 1, self.n_g, terms, self.prior, self.d_fixed, "input")] + \
               [RecordModel(self.rec, n, self.n_g, terms, self.prior, self.d_fixed, width_at) for n in sizes if n > 1]


def _term_trials(s: "_Search", name: str, base: Terms, fit: Fit) -> tuple[list, Callable[[], list] | None]:
    """The term name's trial jobs onto the terms base (a Terms without it) from the Fit fit (its
    model's parts the start, those base's model lacks dropped; B's size and where it is read the
    fit's), and its chains' builder (a function giving their jobs) or None: (jobs [(models, theta0,
    sigma, max_nfev, rounds, name)], builder). s: the search's context (`_Search`)."""
    rec, n_g, prior, d_fixed, starts, widths, b0, st, ladder, sigma = \
        s.rec, s.n_g, s.prior, s.d_fixed, s.starts, s.widths, s.b0, s.st, s.ladder, s.sigma
    chain = s.chain
    m, n_b, width_at = fit.model, fit.model.n_b, fit.model.width_at
    mt = RecordModel(rec, n_b, n_g, base.with_(name), prior, d_fixed, width_at)
    parts = {k: v for k, v in m.parts(fit.theta).items() if k in mt.layout()}
    # from the fit so far, and from each delay start (the coarse and the configured one) at
    # the start's width: a term the fit so far lacked may have dragged its delay and B into
    # another basin (a ring read as a late onset)
    bases = [{**parts, "d": np.array([d]), "B": np.full(n_b, b0)} for d in starts]
    builder = None
    if name == "ring":
        freqs = _ring_scan(mt, parts, sigma)
        th0s = [mt.theta({**parts, "ring": mt.ring_theta(freqs[0], 0.1)})] + \
               [_ring_start(mt, p, freqs, sigma) for p in bases]
        if _has_chains(name, n_b):  # and coarse to fine from the starts profiled with it (`_ring_profiled_starts`)
            def builder(mt=mt, parts=parts, freqs=freqs, slope=m.G_slope(fit.ev)):
                out = []  # slope: the path's tangent of the fit so far
                for p in _ring_profiled_starts(rec, n_g, base.with_(name), prior, d_fixed, parts, freqs,
                                               starts, widths, slope, sigma):
                    ms = chain(base.with_(name), [n for n in ladder if n < n_b], width_at) + [mt]
                    out.append((ms, ms[0].theta(p), sigma, 20, 2, name))
                return out
    elif name.startswith("slide_"):
        mt.slope = m.slope
        th0s = _slide_starts(mt, name[6:], parts, sigma)
    elif name == "expo":  # from the fit so far, at the exposure of EXPO_GRID that settles lowest
        mt.slope = m.slope
        grid = [mt.theta({**parts, "expo": np.array([mt.expo_x(g * rec.period_s)])}) for g in EXPO_GRID]
        th0s = [grid[i] for i in _lowest_settled(mt, grid, sigma, 1)[0]]
    elif name == "spread":  # from the fit so far, at the spread of SPREAD_GRID that settles lowest
        mt.slope = m.slope
        grid = [mt.theta({**parts, "spread": np.array([mt.spread_x(g)])}) for g in SPREAD_GRID]
        th0s = [grid[i] for i in _lowest_settled(mt, grid, sigma, 1)[0]]
    else:  # a switch, or a switch's shift (linear only): from the fit so far and each delay start
        mt.slope = m.slope
        th0s = [mt.theta(p) for p in [parts] + bases]
        if (name,) in st:  # also from the start profiled with this switch
            d_s, b_s = st[(name,)]
            th0s.append(mt.theta({**parts, "d": np.array([d_s]), "B": np.full(n_b, b_s)}))
        th0s = _trial_starts(mt, th0s, sigma)
    jobs = [([mt], th0, sigma, 8, _trial_rounds(name), name) for th0 in th0s]
    if _has_chains(name, n_b) and name.startswith("reg_"):  # and coarse to fine from the start profiled with it (`_fit_chain`)
        def builder(mt=mt, parts=parts, slope=m.slope):
            d_s, b_s = st.get((name,), (starts[-1], b0))
            ms = chain(base.with_(name), [n for n in ladder if n < n_b], width_at) + [mt]
            for mc in ms:
                mc.slope = slope
            return [(ms, ms[0].theta({**{k: v for k, v in parts.items() if k in ms[0].layout()},
                                      "d": np.array([d_s]), "B": np.array([b_s])}), sigma, 20, 2, name)]
    return jobs, builder


def _has_chains(name: str, n_b: int) -> bool:
    """Whether the term name's trials come with chains (`_term_trials`' builder) at B's size n_b: the
    tip mode's and a registration switch's, when B has more than one coefficient to carry them to."""
    return n_b > 1 and (name == "ring" or name.startswith("reg_"))


def _trial_fits(s: _Search, offers: list, fit: Fit) -> list:
    """The trial fits of each offer (term name, the Terms it goes onto) from the Fit fit: per offer,
    the last Fit of each of `_term_trials`' jobs, in their order (a job alike another fitted once,
    `_fit_distinct`). One offer is one item on two cores (base.forkmap; the costly first,
    OFFER_COST), its starts built there beside its fits. s: the search's context (`_Search`).

    Why the offer, not the fit, an item: a term's starts (the tip mode's frequency scan and its
    starts at each delay, the settles that rank a switch's, a slide's, the exposure's and the spread's
    starts) are evaluations too, a quarter of a round (0.25 of the bench record's 1.1 s), and built
    in turn before the fits they ran on one core. The fits are the same whichever process builds
    and fits an offer (a fit depends on its job alone, `_fit_one`, and a term's starts on the fit so
    far and the context alone); a test checks a round bit for bit against its offers run in turn."""

    def item(offer):
        name, base = offer
        return _fit_distinct([j[:5] for j in _term_trials(s, name, base, fit)[0]], here=True)

    return fork_map(item, offers, cost=lambda o: OFFER_COST.get(o[0].split("_")[0], 1.0), pack=_slim, unpack=_unslim)


OFFER_COST = {"ring": 6.0, "spread": 3.0, "reg": 2.0, "slide": 2.0, "shift": 2.0}  # an offer's relative cost in a
                       # round (`_trial_fits`; the exposure's 1), so the costly are taken first and the two cores
                       # end together: its starts' building and trial fits on the bench record, alone on one core,
                       # tip mode 0.60, spread 0.25, motor switch 0.23, tip switch 0.19, exposure 0.08 s. A schedule
                       # only: the fits are the same in any order


def _search(rec, starts, prior, d_fixed, board_b, sigma, peaks=()):
    """The start, B's size and where it is read, then the terms by BIC, all at the scale sigma
    (px): (the final Fit, the search's JSON-ready log). starts: the delay starts (s; the coarse,
    then the configured); peaks: every profiled correlation peak (s, `_coarse_starts`), offered
    to `_fitted_start` beside them."""
    st, n_g = _start(rec, starts, prior, d_fixed, board_b, sigma)
    widths = _start_widths(rec, board_b)
    d0, b0 = min(st.items(), key=lambda kv: len(kv[0]))[1]  # the base model's own start
    fitted_log, th_first = None, None
    if d_fixed is None:
        (d0, b0), fitted_log, fs = _fitted_start(rec, n_g, [d0, *peaks, *starts], widths, prior, sigma)
        th_first = fs.theta  # the size chains' first link starts from its trial fit (below)
        starts = list(dict.fromkeys([d0, *starts[1:]]))  # the winner in the coarse start's place, so
        # the terms' trials start from it and the configured delay, as before from the coarse start
    terms = Terms()
    ladder = _n_b_ladder(rec.rt.size)

    ctx = _Search(rec, n_g, prior, d_fixed, starts, widths, b0, st, ladder, sigma)

    jobs = []
    for width_at in (WIDTH_AT if ladder[-1] > 1 else WIDTH_AT[:1]):  # a constant width is read nowhere
        ms = ctx.chain(terms, ladder, width_at)  # B's size and where it is read, by the same criterion as the terms
        th0 = ms[0].theta({"d": np.array([d0]), "B": np.array([b0])}) if th_first is None else th_first
        jobs.append((ms, th0, sigma, 20, IRLS_ROUNDS))
    fits = [(f.bic(sigma), f.model.n_b, f.model.width_at, f) for fs in _fit_all(jobs, _fit_chain)
            for f in (fs[1:] if len(fs) > 1 else fs)]
    bic, n_b, width_at, fit = min(fits, key=lambda x: x[0])
    m = fit.model
    log = [{"fitted_start": fitted_log}, {"B_ctrl": {f"{n} {w}": b for b, n, w, _ in fits}},
           {"terms": terms.names(), "bic": bic, "t_delay_s": float(fit.theta[0])}]
    near = {}  # each entered term's runner-ups in its round, within Occam's window (`_exchange`)
    while True:
        offered = terms.offered()
        trials = [(f.bic(sigma), name, f) for name, fs in zip(offered, _trial_fits(ctx, [(n, terms) for n in offered], fit))
                  for f in fs]
        # The chains run for the term whose trial leads the round (the lowest BIC), once that trial
        # lowers the record's BIC: they carry the term's own profiled start coarse to fine, to reach its
        # best basin where the fit so far was dragged by its absence, and a term that no start lowers
        # the BIC from is not in evidence by the same criterion. A term whose trials trail another's
        # is offered again in the next round, from the fit with the leader in, with its chains if it
        # then leads. Why not every term whose trial lowers the BIC: the chains are the round's costly
        # part (four full fits a profiled start, the tip mode's Jacobian filtering the grid per B
        # coefficient), and on a registration record every term's trial lowers the plain model's BIC:
        # on a 25 fps registration triangle of the development group the tip mode's chains, which
        # trailed the switch's trial by a factor 20 in BIC, were 19.6 of calibrate's 57 s on one core.
        # The lead's chains are built here, its starts once more (`_trial_fits` built them in an item):
        # the builder carries the models its starts were ranked on, which do not come back through the pipe.
        lead = min(trials, key=lambda c: c[0]) if trials else None
        jobs = []
        if lead is not None and lead[0] < bic and _has_chains(lead[1], fit.model.n_b):
            jobs = _term_trials(ctx, lead[1], terms, fit)[1]()
        chained = [(f.bic(sigma), job[5], f) for job, f in zip(jobs, _fit_distinct([j[:5] for j in jobs]))]
        cands = [c for n in offered  # by term, as they were built: the ring's chains first, a switch's last
                 for c in (chained + trials if n == "ring" else trials + chained) if c[1] == n]
        if not cands:
            break
        c_bic, name, f = min(cands, key=lambda c: c[0])
        log.append({"tried": [(c[1], c[0]) for c in cands]})
        if c_bic >= bic:
            break
        near[name] = _runner_ups(cands, name, c_bic)
        terms, m = terms.with_(name), f.model
        fit = fit_model(m, f.theta, sigma=sigma)  # from the trial, so at worst the trial again
        bic = fit.bic(sigma)
        log.append({"terms": terms.names(), "bic": bic, "t_delay_s": float(fit.theta[0])})
        if len(ladder) > 1:
            fit, bic, n_b, width_at = _resize(fit, bic, ladder, sigma, log)
            m = fit.model
    fit, bic = _exchange(ctx, fit, bic, near, log)
    fit, bic = _trade_profile(fit, bic, sigma, log)
    return fit, {"steps": log, "sigma_px": sigma, "n_b": fit.model.n_b, "n_g": n_g, "width_at": fit.model.width_at}


OCCAM_BIC = 2.0 * np.log(20.0)  # Occam's window (Madigan & Raftery 1994, JASA 89(428)): a model whose posterior odds
                       # against the best are below 1 / 20 is set aside; by the BIC's approximation of the odds,
                       # exp(-dBIC / 2), one more than 2 ln 20 = 6.0 above it. A round's runner-up within it is
                       # offered in the entered term's place once the search ends (`_exchange`)


def _runner_ups(cands: list, name: str, c_bic: float) -> list[str]:
    """The terms of a round's candidates cands [(BIC, term, Fit)] other than the entered name whose
    best BIC lies within OCCAM_BIC of c_bic (the entered term's), lowest first."""
    best = {}
    for b, n, _ in cands:
        if n != name and b <= c_bic + OCCAM_BIC:
            best[n] = min(b, best.get(n, np.inf))
    return sorted(best, key=lambda n: (best[n], n))


def _exchange(s: _Search, fit: Fit, bic: float, near: dict, log: list) -> tuple:
    """The search's last move: each entered term X that no other term needs (a switch with its slide
    or shift on, the ring with its motor drive, stays) exchanged for each of its round's runner-ups Y
    (near: {X: [Y, ...]}, `_runner_ups`) that the other terms admit; Y's trial fits start from the
    final fit with X's parts dropped (`_term_trials`(s, Y, terms without X, fit): Y's own starts,
    no chains; s the search's context). The best trial, when it lowers the BIC, is carried to a full fit and kept, with B's size
    and where it is read once more (`_resize`). Returns (fit, bic); log (the search's step list)
    gets the trials' BICs.

    Why: the search adds one term a round, the one whose trial leads, and never takes one out, so a
    term that entered ahead of a rival by less than the trials' own spread is kept whatever the
    final model says of the rival (forward selection is greedy; an exchange move is the stepwise
    search's answer, Efroymson 1960). Two terms that trade (a switch's slide and the exposure both
    round the onsets' corners) are such rivals: on s22-swing-035-registration of LOCKBOX22_300
    (30 fps swings, a camera turn of 2.36 deg with the tip's direction) the slide's trial led the
    exposure's by 1.7 and entered, the exposure then scored worse on top of it, and the search ended
    at BIC 4,006.6 with B 6.6 % off; the exposure in the slide's place reaches 4,005.9, B 1.2 % off.
    Only a round's runner-ups within Occam's window are exchanged: a term trailing by more is not
    a rival by the same criterion, and a record without a near tie (the bench session's, with no
    term) costs nothing."""
    terms = fit.model.terms
    pairs = []  # (x, terms without x, y)
    for x in terms.names():
        base = terms.without_(x)
        if base is not None:
            pairs += [(x, base, y) for y in near.get(x, []) if y in base.offered() and not getattr(terms, y)]
    if not pairs:
        return fit, bic
    sigma = s.sigma
    trials = [(f.bic(sigma), f"{x}->{y}", f) for (x, _, y), fs in zip(pairs, _trial_fits(s, [(y, base) for _, base, y in pairs], fit))
              for f in fs]
    log.append({"exchange": [(label, b) for b, label, _ in trials]})
    c_bic, label, f = min(trials, key=lambda c: c[0])
    if c_bic >= bic:
        return fit, bic
    full = fit_model(f.model, f.theta, sigma=sigma)  # from the trial, so at worst the trial again
    fit, bic = full, full.bic(sigma)
    log.append({"terms": fit.model.terms.names(), "bic": bic, "t_delay_s": float(fit.theta[0]), "exchanged": label})
    if len(s.ladder) > 1:
        fit, bic, _, _ = _resize(fit, bic, s.ladder, sigma, log)
    return fit, bic


B_LEVELS = tuple(1.05 ** k for k in (-4, -3, -2, -1, 1, 2, 3, 4))  # B's levels the final model is refitted
                       # from (`_trade_profile`): steps of 5 %, the B limit of a fresh rendering, so one of them
                       # starts within 2.5 % of any level in range; -18 % to +22 %: up to twice the largest level
                       # error of a search-side failure seen (s12-swing-048 of LOCKBOX12_300, B 10.5 % short)


LAG_GRID = (0.05, 0.25, 0.5, 1.0)  # a switch lag's restarts (`_trade_profile`), frame periods: both ends of its
                       # range [T / 20, T] (the lag's logistic map is flat near them, so a fit that reaches
                       # one moves away slowly: s15-marker-037 of LOCKBOX15_300 settled at the floor, the
                       # truth at T) and between them a factor 2 apart, as EXPO_GRID's upper points


TRADE_KEEP = 2         # the trade starts carried to a trial fit (`_trade_profile`): the lowest by their settled
                       # cost. Its lowest was the best trial's start on the two records the trade tests use:
                       # along B's level from 12 % short, 7 % short and 5 % long of a clean 20 s rendering's
                       # width, and of the 32 starts of a switch stalled at its lag's floor (settled 543, trial
                       # 1,289; the next, 565 and 1,290); two, as a slide's starts, where two parts trade


def _trade_starts(m: RecordModel, parts: dict) -> list[tuple[str, dict]]:
    """The final model's restarts along the directions its parts trade in (`_trade_profile`), as
    (label, parts): B scaled by each of B_LEVELS; each switch's lag at each of LAG_GRID, crossed
    with the exposure at the fit's own and each of EXPO_GRID when the exposure is on, a motor
    switch's with the delay moved to keep its window's middle d + L / 2 (the encoder fixes the motor's
    reversal, so the frames see the switch over [d, d + L] after it, and the record fixes that
    window's middle, not d or L); the exposure alone at each of EXPO_GRID. m: the final model;
    parts: its fit's `RecordModel.parts`. 8 starts with neither a switch nor the exposure, 12 with
    one of them, 32 with one switch and the exposure, up to 8 + 2 x 4 x 5 + 4 = 52."""
    T, lay = m.rec.period_s, m.layout()
    out = [(f"B x{s:.3f}", {**parts, "B": parts["B"] * s}) for s in B_LEVELS]
    expos = [("own", parts.get("expo"))]
    if "expo" in lay:
        expos += [(f"{g}T", np.array([m.expo_x(g * T)])) for g in EXPO_GRID]
    for n in ("tip", "motor"):
        if "lag_" + n not in lay:
            continue
        L_fit = m.lag_map(parts["lag_" + n][0])[0]
        for g in LAG_GRID:
            for e_label, e in expos:
                p = {**parts, "lag_" + n: np.array([m.lag_x(g * T)])}
                if e is not None:
                    p["expo"] = e
                if n == "motor":
                    p["d"] = np.array([float(parts["d"][0]) + 0.5 * (L_fit - g * T)])
                out.append((f"lag_{n} {g}T expo {e_label}", p))
    out += [(f"expo {label}", {**parts, "expo": e}) for label, e in expos[1:]]
    return out


def _trade_profile(fit: Fit, bic: float, sigma: float, log: list) -> tuple:
    """The final model refitted from the TRADE_KEEP of `_trade_starts` whose settled cost is lowest
    (a trial fit each, as a term's), the best trial carried to a full fit and kept when its BIC is
    lower: (fit, bic). bic: the fit's BIC
    at sigma (px), the search's scale; log: the search's step list, appended to. No errors of its own.

    Why: with a switch, a slide or the exposure on, B's level trades against the switch's lag, the
    slide and the exposure (each moves the onsets a few ms), and the search's fits start from one
    level and stay near it. On s12-swing-048 of LOCKBOX12_300 the search settled with every onset
    2.4 ms early and B 9.4 % short, the slide doing the exposure's work; at its switch lags the
    settled cost rose 2,076 -> 3,291 with B x 1.1, so no local fit crossed to the model's own best
    (BIC 4,528 against 4,429 from the truth; bench/onset_truth.py). A switch's lag trades against
    the exposure, and a motor switch's against the delay, the same way: on s15-marker-037 of
    LOCKBOX15_300 the search settled with the motor switch's lag at its floor T / 20, the exposure
    at its bound T and the mean lag 0.41 frame late (BIC 10,083; from the truth 10,050, the lag T).
    Restarts along each of these directions (a coarse profile: the profile likelihood's use, Venzon &
    Moolgavkar 1988, Appl. Statist. 37(1)) cross such barriers with the other parts settling at each.
    Same BIC, so it can only lower it. Cost: a settle per start (the start's settled cost, on a fresh
    copy of the model), and a trial fit (8 evaluations) from each of the TRADE_KEEP lowest."""
    m = fit.model
    starts = _trade_starts(m, m.parts(fit.theta))
    kept, costs = _lowest_settled(m, [m.theta(p) for _, p in starts], sigma, TRADE_KEEP, fresh=True)
    jobs = [([m], m.theta(starts[i][1]), sigma, 8, TRIAL_ROUNDS) for i in kept]
    trials = [fs[-1] for fs in _fit_all(jobs, _fit_chain)]
    best = min(trials, key=lambda f: f.bic(sigma))
    log.append({"trade_starts": {label: c for (label, _), c in zip(starts, costs)},
                "trade_trials": {starts[i][0]: f.bic(sigma) for i, f in zip(kept, trials)}})
    if best.bic(sigma) >= bic:
        return fit, bic
    full = fit_model(best.model, best.theta, sigma=sigma)
    if full.bic(sigma) >= bic:
        return fit, bic
    log.append({"terms": full.model.terms.names(), "bic": full.bic(sigma), "t_delay_s": float(full.theta[0]),
                "trade_profile": True})
    return full, full.bic(sigma)


def _resize(fit: Fit, bic: float, ladder: list, sigma: float, log: list) -> tuple:
    """B's size and where it is read once more, with the terms the search has so far: chosen on the
    plain model, a strong term it lacks (a switch of tens of px) can leave every size alike and the
    smallest wins (a 4-coefficient B 17.8 % off a registration record's stras B), and the next terms
    are then chosen to mend the coarse B (s4-marker-044 of LOCKBOX4_300, with the slide not yet
    bounded: a motor switch and two slides at 4 coefficients, BIC 19,913 once resized to 16, where
    the tip's switch and its slide alone reach 8,347 at 16). So after each term enters, each other size is fitted from the fit so
    far, B resampled (`_resample_B`), and scored by the same BIC. Returns (fit, bic, n_b, width_at)."""
    m = fit.model
    jobs = []
    for n in ladder:
        for w in WIDTH_AT:
            if (n, w) == (m.n_b, m.width_at):
                continue
            mb = RecordModel(m.rec, n, m.n_g, m.terms, m.prior, m.d_fixed, w)
            mb.slope = m.slope
            parts = m.parts(fit.theta)
            parts["B"] = _resample_B(m, m.unpack(fit.theta)[1], mb)
            jobs.append(([mb], mb.theta(parts), sigma, 20, IRLS_ROUNDS))
    alts = [fs[-1] for fs in _fit_all(jobs, _fit_chain)]
    log.append({"B_ctrl_with_terms": {f"{f.model.n_b} {f.model.width_at}": f.bic(sigma) for f in alts}})
    best = min(alts, key=lambda f: f.bic(sigma))
    if best.bic(sigma) < bic:
        fit, bic = best, best.bic(sigma)
        log.append({"terms": fit.model.terms.names(), "bic": bic, "t_delay_s": float(fit.theta[0]),
                    "B_ctrl": fit.model.n_b, "B_read_at": fit.model.width_at})
    return fit, bic, fit.model.n_b, fit.model.width_at
