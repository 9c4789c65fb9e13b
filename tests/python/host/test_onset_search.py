"""The onset stage's search (playscope.fit.onset_search): the starts it takes and where they lead, on
short renderings of bench/swing_render.py. Statistics over many renderings live in
bench/onset_scoreboard.py, not here."""

import numpy as np
import pytest

from playscope.fit import onset_fit as OF
from playscope.fit import onset_model as OM
from playscope.fit import onset_search as OS
from playscope.fit.onset_stage import record_samples

from .onset_records import b_error_pct, bench_module, record


def test_a_clean_record_gives_B_and_the_delay():
    # 20 s, 13 reversals: measured B 0.36 % off, the delay within 0.001 frame
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=20.0)
    rob = record_samples(t, q, q, rt, rq, d["t_f"], obs, r.fps, r.delay_cfg_s, "data", hysteresis=hyst)
    assert rob.report["terms"]["chosen"] == []
    assert abs(rob.t_delay_s - r.delay_s) * r.fps < 0.125
    assert b_error_pct(r, rob.onsets) < 1.5
    assert np.all(rob.onsets.sigma_b > 0) and np.all(rob.onsets.sigma_b < 0.05 * r.b_hi)


def test_the_noise_scale_comes_from_the_fit_when_the_motion_turns_within_a_few_frames():
    # A 25 fps triangle whose legs last 0.13 s (3 frames): the frames' second differences see
    # the motion's own turns (about 2.6 px here against the renderer's 0.2), so the search runs
    # again at the fitted residuals' scale (SIGMA_RERUN); measured 0.29 px on this 12 s rendering.
    r, d, t, q, rt, rq, obs, hyst = record(shape="triangle", swing_s=0.13, fps=25.0, noise_px=0.2, duration_s=12.0)
    assert OM.noise_sigma(obs) > 5 * r.noise_px  # the record shows the case
    rob = record_samples(t, q, q, rt, rq, d["t_f"], obs, r.fps, r.delay_cfg_s, "data", hysteresis=hyst)
    assert rob.report["terms"]["noise_px"] < 2 * r.noise_px


def test_the_tip_modes_profiled_starts_keep_each_delays_own_width():
    # A lightly damped 5.5 Hz tip mode on a 60 fps triangle (30 s of development rendering
    # swing-081's settings), started as the search is, from the coarse delay and the configured
    # one: the plain model, which lacks the ring, reads the stop's swing as an early onset and
    # starts at the coarse delay (2.5 frames late) with a width 0.078 of the truth. The ring's
    # profiled starts (`_ring_profiled_starts`) keep each delay's own best width: at a constant
    # width the profile's cost does not rank the delays, and kept at the lowest over both, every
    # damping ratio's start stayed at the coarse delay's narrow width. The configured delay's
    # starts have widths 0.94 and 1.35 of the truth (measured), the nearer within the width grid's
    # half step (12 widths over a factor 50, so 1.43 apart: +-20 %).
    from playscope.fit.delay_guess import coarse_delay, motor_stop_times

    r, d, t, q, rt, rq, obs, hyst = record(shape="triangle", fps=60.0, jitter=0.18, noise_px=0.176, delay_s=0.083,
                                            delay_cfg_s=0.083, b_lo=0.105, b_hi=0.309, b_qc=0.24, b_w=1.24,
                                            swing_s=0.342, ring_hz=5.5, ring_zeta=0.046, ring_px=9.5, seed=3,
                                            duration_s=30.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    sig = OM.noise_sigma(obs)
    prior = (r.delay_cfg_s, rec.period_s / np.sqrt(12))
    starts = [coarse_delay(d["t_f"], obs, motor_stop_times(t, q, rt, rq, 0.02 * hyst), t, q, rec.period_s),
              r.delay_cfg_s]
    st, n_g = OS._start(rec, starts, prior, None, None, sig)
    qq = np.linspace(q.min(), q.max(), 100)
    B_true = float(np.mean(r.B(qq)))
    assert st[()][1] < 0.2 * B_true  # the record shows the drag
    ms = [OM.RecordModel(rec, n, n_g, OM.Terms(), prior) for n in [1] + [n for n in OS._n_b_ladder(rt.size) if n > 1]]
    plain = OF._fit_chain((ms, ms[0].theta({"d": np.array([st[()][0]]), "B": np.array([st[()][1]])}), sig, 20, 3))[-1]
    m = plain.model
    mt = OM.RecordModel(rec, m.n_b, n_g, OM.Terms(ring=True), prior)
    freqs = OS._ring_scan(mt, m.parts(plain.theta), sig)
    found = OS._ring_profiled_starts(rec, n_g, OM.Terms(ring=True), prior, None, m.parts(plain.theta), freqs,
                                     starts, OS._start_widths(rec, None), m.G_slope(plain.ev), sig)
    at_cfg = [p for p in found if float(p["d"][0]) == r.delay_cfg_s]
    assert at_cfg and min(abs(float(p["B"][0]) / B_true - 1.0) for p in at_cfg) < 0.2


def test_a_tip_mode_is_found_where_the_scan_at_the_dragged_fit_scores_an_alias_lowest(monkeypatch):
    # A 5.73 Hz tip mode on a 30 fps triangle of 89 ms legs (10 s of lockbox rendering
    # s5-render_c-092's settings): at the plain fit, whose width the mode dragged, the ring's
    # frequency scan scores 13.25 Hz lowest (the frames' alias of the triangle's third harmonic);
    # from there alone the search took a 13.5 Hz ring and B was 24 % off. The profiled starts are
    # taken at the scan's minimum that profiles lowest (`_ring_profiled_starts`); measured: 5.740
    # Hz, damping 0.110 (rendered 0.11), B 0.25 % off.
    r, d, t, q, rt, rq, obs, hyst = record(shape="triangle", fps=30.0, jitter=0.44, noise_px=0.095, delay_s=0.149,
                                            delay_cfg_s=0.149, b_lo=0.139, b_hi=0.278, swing_mm=0.39, swing_s=0.089,
                                            ring_hz=5.73, ring_zeta=0.11, ring_px=7.5, seed=3, duration_s=10.0)
    scans = []
    profiled = OS._ring_profiled_starts

    def spy(rec, n_g, terms, prior, d_fixed, parts, freqs_hz, *a):
        scans.append(np.asarray(freqs_hz))
        return profiled(rec, n_g, terms, prior, d_fixed, parts, freqs_hz, *a)

    monkeypatch.setattr(OS, "_ring_profiled_starts", spy)
    rob = record_samples(t, q, q, rt, rq, d["t_f"], obs, r.fps, r.delay_cfg_s, "data", hysteresis=hyst)
    assert scans[0][0] > 10.0 and scans[0].size > 1  # the record shows the alias, and other minima
    ring = rob.report["ringing"]
    assert ring["found"] and ring["freq_hz"] == pytest.approx(5.73, rel=0.02)
    assert b_error_pct(r, rob.onsets) < 1.0


def test_the_search_starts_from_the_correlations_peak_the_record_fits_not_an_alias_a_period_late(monkeypatch):
    # A 60 fps triangle of 0.29 s period (30 s of lockbox rendering s5-swing-056's settings, delay
    # 92 ms, configured 179 ms): the correlation of commanded and image motion repeats with the
    # triangle, and its highest peak is the alias one period late, its other the delay (both about
    # 25 ms late: delay_guess.delay_score). The start profiles the plain model over the frame before
    # each and keeps the one the record fits best.
    from playscope.fit.delay_guess import coarse_delay_peaks, motor_stop_times

    r, d, t, q, rt, rq, obs, hyst = record(shape="triangle", fps=60.0, jitter=0.38, noise_px=0.158, delay_s=0.092,
                                            delay_cfg_s=0.179, b_lo=0.149, b_hi=0.221, b_qc=0.5, b_w=1.47,
                                            swing_s=0.146, swing_period_s=1.5, seed=3, duration_s=30.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    peaks = coarse_delay_peaks(d["t_f"], obs, motor_stop_times(t, q, rt, rq, 0.02 * hyst), t, q, rec.period_s)
    assert peaks[0] > r.delay_s + 0.25  # the highest: the alias, a period (0.29 s) late
    near = [p for p in peaks if abs(p - r.delay_s) < 0.03]
    assert len(near) == 1
    d0 = OS._coarse_starts(rec, peaks, (r.delay_cfg_s, rec.period_s / np.sqrt(12)), None, OM.noise_sigma(obs))[0]
    assert near[0] - rec.period_s <= d0 <= near[0]  # that peak, profiled over the frame before it
    assert abs(d0 - r.delay_s) < abs(near[0] - r.delay_s)
    # and fit_record's search starts from it and the configured delay (the search itself stubbed out);
    # a held configured delay is the only start, no candidate fitted
    seen = []

    class Started(Exception):
        pass

    def search(rec, starts, *a):
        seen.append(list(starts))
        raise Started

    monkeypatch.setattr(OS, "_search", search)
    with pytest.raises(Started):
        OS.fit_record(rec, r.delay_cfg_s, "data", peaks)
    assert seen[-1] == [d0, r.delay_cfg_s]
    monkeypatch.setattr(OS, "_coarse_starts", lambda *a: pytest.fail("a held delay fits no candidate"))
    with pytest.raises(Started):
        OS.fit_record(rec, r.delay_cfg_s, "config", peaks)
    assert seen[-1] == [r.delay_cfg_s]
    # the onset stage hands fit_record every candidate, not the highest alone
    got = []

    def fit_record(rec, cfg, how, d_coarse, *a):
        got.append(np.atleast_1d(d_coarse))
        raise Started

    monkeypatch.setattr(OS, "fit_record", fit_record)
    with pytest.raises(Started):
        record_samples(t, q, q, rt, rq, d["t_f"], obs, r.fps, r.delay_cfg_s, "data", hysteresis=hyst)
    assert np.array_equal(got[0], peaks)


def test_a_correlation_peak_a_fraction_of_a_frame_late_starts_at_the_delay_it_means():
    # A 25 fps triangle of 0.376 s period, no delay configured (10 s of the spent lockbox rendering
    # s11-swing-066's settings, delay 50 ms): the correlation is flat from the delay to where the play
    # is taken up, and its peak near the delay is 0.5-0.6 frame late (measured 70-75 ms). The start
    # profiles each peak over the frame before it (`_profiled_start`): measured 50 ms, on the
    # correlation's grid (5 ms). On the 124 s rendering the 8-evaluation fit from the late peak
    # stayed at 72 ms and lost to the alias one period late (B 11.6 % off); from the profiled start
    # it scored below the alias.
    from playscope.fit.delay_guess import coarse_delay_peaks, motor_stop_times

    r, d, t, q, rt, rq, obs, hyst = record(shape="triangle", fps=25.0, jitter=0.42, noise_px=0.092, delay_s=0.05,
                                            delay_cfg_s=None, b_lo=0.131, b_hi=0.272, b_qc=0.18, b_w=1.08,
                                            swing_s=0.188, swing_period_s=1.5, seed=1, duration_s=10.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    peaks = coarse_delay_peaks(d["t_f"], obs, motor_stop_times(t, q, rt, rq, 0.02 * hyst), t, q, rec.period_s)
    near = [p for p in peaks if abs(p - r.delay_s) < rec.period_s]
    assert len(near) == 1 and near[0] - r.delay_s > 0.4 * rec.period_s  # the record shows a late peak
    d0 = OS._coarse_starts(rec, peaks, None, None, OM.noise_sigma(obs))[0]
    assert abs(d0 - r.delay_s) * r.fps < 0.125


def test_the_trade_profile_reaches_the_level_a_dense_scan_finds_where_a_local_fit_stalls():
    # `_trade_profile` against a brute-force reference: the constant-width plain model of a clean
    # 20 s rendering, fitted in full from 17 widths over 0.20-0.28 mm, the lowest BIC taken (measured
    # 8,794 at 0.250 mm). The model's cost in B's level is rugged (each onset moves a frame at a
    # time), so a full local fit from a width 18 % short stalls (measured 9,521 at 0.231 mm); the
    # profile from there reaches 8,805 at 0.248 mm. A fit at the scan's best is kept or lowered,
    # never raised.
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    sig = OM.noise_sigma(obs)
    m = OM.RecordModel(rec, 1, 10, OM.Terms(), (r.delay_cfg_s, rec.period_s / np.sqrt(12)))

    def fit_from(width_mm, **kw):
        return OF.fit_model(m, m.theta({"d": np.array([r.delay_cfg_s]), "B": np.array([width_mm])}), sigma=sig, **kw)

    def width(f):
        return float(m.parts(f.theta)["B"][0])

    scan = min((fit_from(w) for w in np.linspace(0.20, 0.28, 17)), key=lambda f: f.bic(sig))
    off = 0.82 * width(scan)
    assert fit_from(off).bic(sig) > scan.bic(sig) + 300  # the record shows the stall

    log = []
    start = fit_from(off, max_nfev=1, rounds=1)  # the short width, unfitted
    back, bic = OS._trade_profile(start, start.bic(sig), sig, log)
    assert bic < scan.bic(sig) + 30 and log[-1].get("trade_profile")
    assert width(back) == pytest.approx(width(scan), rel=0.025)

    kept, bic_kept = OS._trade_profile(scan, scan.bic(sig), sig, [])
    assert bic_kept <= scan.bic(sig) and width(kept) == pytest.approx(width(scan), rel=0.025)


def test_the_trade_profile_restarts_a_switch_lag_stalled_at_its_floor_with_the_exposure_doing_its_work():
    # `_trade_profile` along the lag-exposure trade: a 30 s rendering whose registration flips by
    # 2 deg with the tip (a uniform 0..T late) and whose frames each expose 30 ms. The model with
    # that switch and the exposure, fitted in full from the rendering's mean lag (T / 2) and its
    # exposure, scores 1,289 (lag T, exposure 30.8 ms). From the lag at its floor T / 20 and the exposure at
    # its bound T, the full fit stalls with the lag at the floor (measured 2,013): the exposure
    # spreads each switch over its frame in the lag's place. B's level alone cannot leave that
    # basin (its restarts kept 2,013); the lag's restarts reach 1,289, lag T, exposure 31.0 ms.
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=30.0, reg_deg=2.0, exposure_s=0.03, b_lo=0.25, b_hi=0.25)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    sig, T = OM.noise_sigma(obs), rec.period_s
    m = OM.RecordModel(rec, 1, 10, OM.Terms(reg_tip=True, expo=True), (r.delay_cfg_s, T / np.sqrt(12)))

    def fit_from(lag_s, expo_s):
        return OF.fit_model(m, m.theta({"d": np.array([r.delay_cfg_s]), "B": np.array([0.25]),
                                        "lag_tip": np.array([m.lag_x(lag_s)]), "expo": np.array([m.expo_x(expo_s)])}),
                            sigma=sig)

    ref = fit_from(0.5 * T, r.exposure_s)
    stalled = fit_from(T / 20, T)
    assert stalled.bic(sig) > ref.bic(sig) + 300  # the record shows the stall

    log = []
    back, bic = OS._trade_profile(stalled, stalled.bic(sig), sig, log)
    assert bic < ref.bic(sig) + 30 and log[-1].get("trade_profile")
    assert m.unpack(back.theta)[3]["tip"] > 0.5 * T
    assert m.exposure(back.theta) == pytest.approx(r.exposure_s, rel=0.1)
    assert float(m.parts(back.theta)["B"][0]) == pytest.approx(0.25, rel=0.025)


def test_the_plain_models_start_is_the_peak_whose_fit_scores_lowest_where_the_unfitted_score_ranks_an_alias():
    # s15-render_c-055 of the spent LOCKBOX15_300, from render_c (a renderer written apart): a 25 fps
    # triangle of 98 ms legs over 137 s, delay 87 ms, configured 175 ms, B 0.144-0.253 over the travel.
    # The correlation's peaks lie a triangle period (196 ms) apart. Profiled at a constant width,
    # unfitted, the alias 0.285 s scores lowest (measured 623 against 652 at 0.09 s; cut to 100 s the
    # rendering ranks the delay first), and the search that started there ended 4.9 frames late. A
    # constant-width fit from each (`_fitted_start`) scores the delay's start lowest (measured 436
    # against 514 for the alias and for the configured delay, 748 for the next alias; as trial fits,
    # one reweighting each, the same to 1.3).
    from playscope.fit.delay_guess import coarse_delay_peaks, motor_stop_times
    from playscope.fit.reversals import detect_reversals

    rc = bench_module("render_c")
    sp = rc.Spec(name="s15-render_c-055", seed=750456, fps=25.0, jitter_frac=0.25, excitation="triangle",
                 swing_mm=0.367, swing_time_s=0.098, swing_period_s=1.5, duration_s=137.2, noise_px=0.089,
                 delay_s=0.087, delay_cfg_s=0.175, b_min_mm=0.144, b_max_mm=0.253)
    d = rc.render(sp)
    t, q = d["t_enc"], d["q"]
    hyst = 0.01 * np.ptp(q)
    rt, rq, _ = detect_reversals(t, q, hyst)
    obs = np.column_stack([d["u"], d["v"]])
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, sp.fps)
    T, sig, prior = rec.period_s, OM.noise_sigma(obs), (sp.delay_cfg_s, rec.period_s / np.sqrt(12))
    peaks = coarse_delay_peaks(d["t_f"], obs, motor_stop_times(t, q, rt, rq, 0.02 * hyst), t, q, T)
    ranked = OS._coarse_starts(rec, peaks, prior, None, sig)
    assert abs(ranked[0] - sp.delay_s) > 0.5 * sp.swing_time_s  # the record shows the inversion: an alias first
    st, n_g = OS._start(rec, [ranked[0], sp.delay_cfg_s], prior, None, None, sig)
    (d0, _), bics, _ = OS._fitted_start(rec, n_g, [st[()][0], *ranked, sp.delay_cfg_s], OS._start_widths(rec, None), prior, sig)
    assert abs(d0 - sp.delay_s) < 0.125 * T
    assert min(b for k, b in bics.items() if abs(float(k) - sp.delay_s) > T) > bics[f"{d0:.4f}"] + 30


def test_the_search_fits_its_plain_model_from_the_fitted_start_and_a_held_delay_skips_it(monkeypatch):
    # The wiring of `_fitted_start` into `_search`: B's size chains start from the theta of the trial
    # fit it returns (here a stand-in's, at 0.123 s and 0.2), their first link a full fit from there,
    # the terms' delay starts put its delay in the coarse start's place, and a held configured delay
    # is fitted from as it is, no start chosen.
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=10.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    prior, sig = (r.delay_cfg_s, rec.period_s / np.sqrt(12)), OM.noise_sigma(obs)
    offered = []

    def fitted(rec, n_g, delays, widths, prior, sigma):
        offered.append(list(delays))
        m = OM.RecordModel(rec, 1, 6, OM.Terms(), prior, None, "input")
        th = m.theta({"d": np.array([0.123]), "B": np.array([0.2])})
        return (0.1, 0.15), {}, OF.Fit(m, th, None, sigma, 0.0)  # a start (d, b) and its trial fit, elsewhere

    class Chained(Exception):
        pass

    def fit_all(jobs, fn=None):
        m, th = jobs[0][0][0], jobs[0][1]
        raise Chained(float(th[0]), float(m.parts(th)["B"][0]), {j[5:] for j in jobs})

    monkeypatch.setattr(OS, "_fitted_start", fitted)
    monkeypatch.setattr(OS, "_fit_all", fit_all)
    with pytest.raises(Chained) as e:
        OS._search(rec, [0.05, r.delay_cfg_s], prior, None, None, sig, [0.05, 0.3])
    assert e.value.args == (0.123, 0.2, {()})
    assert {0.05, 0.3, r.delay_cfg_s} <= set(offered[-1])  # every peak and the configured delay offered
    with pytest.raises(Chained) as e:
        OS._search(rec, [r.delay_cfg_s], prior, r.delay_cfg_s, None, sig, [r.delay_cfg_s])
    assert len(offered) == 1 and e.value.args[0] == pytest.approx(r.delay_cfg_s) and e.value.args[2] == {()}


@pytest.mark.parametrize("evident, runner_up", [("ring", "reg_tip"), ("reg_tip", "ring")])
def test_a_rounds_chains_run_for_the_term_whose_trial_leads_it(monkeypatch, evident, runner_up):
    # A round's chains (a term's profiled starts carried coarse to fine: four full fits each) run for
    # the term whose trial fit leads the round, once it lowers the record's BIC, and for no other: not
    # for a runner-up whose trial lowers the BIC too (it is offered again in the next round). The
    # trials are stood in for: the evident term's score far below the fit so far's, the runner-up's
    # below it by less, every other term's far above.
    from types import SimpleNamespace

    r, d, t, q, rt, rq, obs, hyst = record(duration_s=10.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    prior, sig = (r.delay_cfg_s, rec.period_s / np.sqrt(12)), OM.noise_sigma(obs)
    rounds, profiled = [], []

    class Chains(Exception):
        pass

    def trial_fits(s, offers, fit):  # the round's trials, one stand-in fit a term
        rounds.append([(name,) for name, _ in offers])
        return [[SimpleNamespace(bic=lambda s, k=name: -1e12 if evident == k else (-1e11 if runner_up == k else 1e12))]
                for name, _ in offers]

    def fit_distinct(jobs, here=False):  # the chains' call: what was asked for is the test's answer
        raise Chains([tuple(j[0][0].terms.names()) for j in jobs], [len(j[0]) for j in jobs])

    real = OS._ring_profiled_starts
    monkeypatch.setattr(OS, "_trial_fits", trial_fits)
    monkeypatch.setattr(OS, "_fit_distinct", fit_distinct)
    monkeypatch.setattr(OS, "_ring_profiled_starts", lambda *a: profiled.append(1) or real(*a))
    with pytest.raises(Chains) as e:
        OS._search(rec, [r.delay_cfg_s], prior, None, None, sig, [r.delay_cfg_s])
    terms, sizes = e.value.args
    assert {("ring",), ("reg_tip",), ("reg_motor",), ("expo",)} <= set(rounds[0])  # every term had its trials
    assert terms and all(k == (evident,) for k in terms) and all(n > 1 for n in sizes)  # its chains, no other's
    assert bool(profiled) == (evident == "ring")  # the ring's profiled starts are built only when they run


def test_the_trade_starts_move_a_motor_switchs_delay_to_keep_its_windows_middle():
    # `_trade_starts`' contract along the lag-delay trade: the encoder fixes the motor's reversal, so
    # the frames see a motor switch over [d, d + L] after it and the record fixes d + L / 2, not d or
    # L. Each motor lag restart moves the delay to keep that middle; a tip switch's (timed from the
    # play's own onset) leaves it. With one switch and the exposure: 8 + 4 x 5 + 4 = 32 starts.
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=10.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    T = rec.period_s
    for name in ("motor", "tip"):
        m = OM.RecordModel(rec, 1, 10, OM.Terms(**{"reg_" + name: True}, expo=True), None)
        d_fit = 0.081
        parts = m.parts(m.theta({"d": np.array([d_fit]), "B": np.array([0.25]), "lag_" + name: np.array([m.lag_x(0.37 * T)]),
                                 "expo": np.array([m.expo_x(0.3 * T)])}))
        starts = OS._trade_starts(m, parts)
        assert len(starts) == len(OS.B_LEVELS) + len(OS.LAG_GRID) * (1 + len(OS.EXPO_GRID)) + len(OS.EXPO_GRID)
        lagged = [(lab, p) for lab, p in starts if lab.startswith("lag_")]
        assert {round(m.lag_map(p["lag_" + name][0])[0] / T, 2) for _, p in lagged} == set(OS.LAG_GRID)
        L_fit = m.lag_map(parts["lag_" + name][0])[0]  # the fit's lag, as _trade_starts reads it back
        for lab, p in lagged:
            g = float(lab.split()[1].rstrip("T"))
            if name == "motor":
                assert float(p["d"][0]) + 0.5 * g * T == pytest.approx(d_fit + 0.5 * L_fit, abs=1e-12)
            else:
                assert float(p["d"][0]) == d_fit


def test_a_take_up_spread_over_widths_is_fitted_as_the_spread_with_its_value_and_the_centre_width():
    # The spread (onset_model's module doc): a 20 s swing_render rendering whose plant takes its play up
    # over widths spread by half of B about it (41 plays; the model's 8 nodes are its own), no camera
    # effect. The search takes the spread alone, at its value, and eq. 1's samples read the centre
    # width (measured: s 0.51, B 0.44 % off). Without the term the camera terms took the creep up (the
    # product's simulator's main job: six of them, B 20 % short of the centre width).
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=20.0, spread=0.5)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    fit, _ = OS.fit_record(rec, r.delay_cfg_s, "data", r.delay_cfg_s)
    assert fit.model.terms.names() == ["spread"]
    assert fit.model.spread(fit.theta) == pytest.approx(0.5, abs=0.05)
    sm = OF.samples(fit)
    true = 0.5 * (r.B(sm.q1) + r.B(sm.q2))
    assert 100 * np.mean(np.abs(sm.b - true)) / np.mean(true) < 2.0
    assert abs(sm.t_delay_s - r.delay_s) * r.fps < 0.125


@pytest.mark.parametrize("exposure_frames", [0.25, 0.5])
def test_the_exposures_trial_starts_at_the_grid_point_nearest_the_blur(exposure_frames):
    # The exposure's trial fit starts at the one point of EXPO_GRID whose settled cost is lowest
    # (`_lowest_settled`), not at each: that rests on the settled cost over e being unimodal about
    # the blur. Checked from the plain model's fit (B of 8 coefficients, as the search sizes it before
    # the terms) on 20 s renderings exposed a quarter and half a frame at 25 fps (the grid's 0.25 and
    # 0.5 points). Measured at half a frame: 297.1, 295.0, 290.9, 338.3 over the grid.
    r, d, t, q, rt, rq, obs, hyst = record(exposure_s=exposure_frames / 25.0, duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    sig = OM.noise_sigma(obs)
    m = OM.RecordModel(rec, 8, 10, OM.Terms(), (r.delay_cfg_s, rec.period_s / np.sqrt(12)))
    plain = OF.fit_model(m, m.theta({"d": np.array([r.delay_s]), "B": np.full(8, float(np.mean(r.B(q))))}), sigma=sig)
    mt = OM.RecordModel(rec, 8, 10, OM.Terms(expo=True), m.prior)
    mt.slope = plain.model.slope
    grid = [mt.theta({**m.parts(plain.theta), "expo": np.array([mt.expo_x(g * rec.period_s)])}) for g in OS.EXPO_GRID]
    (k,), _ = OS._lowest_settled(mt, grid, sig, 1)
    chosen = grid[k]
    assert mt.exposure(chosen) == pytest.approx(exposure_frames * rec.period_s)


def test_a_switchs_trial_from_its_lowest_settled_other_start_is_its_best_other_trial(monkeypatch):
    # A switch's trial fits start at the fit so far's theta and at the one of its other starts (each
    # delay start at the start's width, its profiled start) whose settled cost is lowest
    # (`_trial_starts`), not at each: that rests on the lowest settled of those starts being the one
    # whose trial ends lowest. Checked in the first round on a 20 s rendering with a 2 deg
    # registration switching with the tip's direction (25 fps triangle): the starts are taken as the
    # search builds them, and every other start is given its trial fit. Measured: the other starts (the
    # delay start, the profiled one) settle at 4,603 and 1,003, their trials end at BIC 1,372 and 477.
    r, d, t, q, rt, rq, obs, hyst = record(shape="triangle", swing_s=0.3, fps=25.0, reg_deg=2.0, reg_lag=0.5,
                                            duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    prior, sig = (r.delay_cfg_s, rec.period_s / np.sqrt(12)), OM.noise_sigma(obs)
    seen = {}
    real = OS._trial_starts

    class Built(Exception):
        pass

    def spy(m, th0s, sigma):
        kept = real(m, th0s, sigma)
        seen.setdefault(tuple(m.terms.names()), (m, th0s, sigma, kept))
        return kept

    def trial_fits(s, offers, fit):  # the first round's starts, built here in turn: what the test asks about
        for name, base in offers:
            OS._term_trials(s, name, base, fit)
        raise Built

    monkeypatch.setattr(OS, "_trial_starts", spy)
    monkeypatch.setattr(OS, "_trial_fits", trial_fits)
    with pytest.raises(Built):
        OS._search(rec, [r.delay_cfg_s], prior, None, None, sig, [r.delay_cfg_s])
    m, th0s, sigma, kept = seen[("reg_tip",)]
    assert len(th0s) >= 3 and len(kept) == 1 + OS.TRIAL_OTHER_STARTS and kept[0] is th0s[0]
    others = th0s[1:]
    k = next(i for i, th in enumerate(others) if th is kept[1])
    _, costs = OS._lowest_settled(m, others, sigma, len(others), fresh=True)
    assert costs[k] == min(costs)  # the contract: the lowest settled of the others
    bics = [f.bic(sigma) for f in OF._fit_all([(m, th, sigma, 8, OS.TRIAL_ROUNDS) for th in others])]
    assert bics[k] == min(bics)  # the premise: its trial ends lowest of theirs


def test_a_terms_runner_ups_are_the_other_terms_within_occams_window_lowest_first():
    w = OS.OCCAM_BIC
    cands = [(100.0, "slide_tip", None), (100.0 + 0.5 * w, "expo", None), (100.0 + 0.4 * w, "expo", None),
             (100.0 + 0.9 * w, "ring", None), (100.0 + 1.1 * w, "reg_motor", None), (100.0 + 0.2 * w, "slide_tip", None)]
    assert OS._runner_ups(cands, "slide_tip", 100.0) == ["expo", "ring"]  # each term by its best candidate
    assert OS._runner_ups(cands[:1], "slide_tip", 100.0) == []


def test_a_term_another_needs_cannot_be_taken_out():
    t = OM.Terms(reg_tip=True, slide_tip=True, ring=True, ring_motor=True, expo=True)
    assert t.without_("reg_tip") is None and t.without_("ring") is None  # the slide needs its switch; the drive its mode
    assert t.without_("slide_tip").names() == ["ring", "ring_motor", "reg_tip", "expo"]
    assert t.without_("expo").names() == ["ring", "ring_motor", "reg_tip", "slide_tip"]


def test_the_exchange_puts_a_near_rival_in_an_entered_terms_place_only_where_it_scores_lower():
    # A 20 s rendering of 30 fps swings with a 2 deg registration switching with the tip's direction
    # (within 0.04 frame of the reversal, not sliding) and frames exposed half a frame. The model with
    # the switch and its slide, and the one with the switch and the exposure, both fitted from the
    # truth (B of 8 coefficients): measured BIC 1,184.5 with the slide, 1,015.8 with the exposure.
    # Offered as a near rival of the entered slide, the exposure's trial (the search's own starts,
    # `_term_trials`, from the slide's fit) takes its place; offered the other way, the slide does not.
    r, d, t, q, rt, rq, obs, hyst = record(shape="swings", swing_s=0.16, fps=30.0, reg_deg=2.0, reg_lag=0.04,
                                            exposure_s=0.5 / 30, noise_px=0.25, duration_s=20.0, seed=8)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    prior, sig = (r.delay_cfg_s, rec.period_s / np.sqrt(12)), OM.noise_sigma(obs)
    qq = np.linspace(rec.q.min(), rec.q.max(), 400)
    B8 = np.linalg.lstsq(OM._basis(qq, rec.q.min(), rec.q.max(), 8), r.B(qq), rcond=None)[0]

    def fitted(*terms):
        m = OM.RecordModel(rec, 8, 10, OM.Terms(**{n: True for n in terms}), prior)
        return OF._fit_one((m, m.theta({"d": np.array([r.delay_s]), "B": B8}), sig, 20, OF.IRLS_ROUNDS))

    ctx = OS._Search(rec, 10, prior, None, [r.delay_cfg_s], OS._start_widths(rec, None), float(np.mean(B8)), {}, [8], sig)
    slide, expo = fitted("reg_tip", "slide_tip"), fitted("reg_tip", "expo")
    log = []
    fit, bic = OS._exchange(ctx, slide, slide.bic(sig), {"reg_tip": ["reg_motor"]}, log)
    assert fit is slide and log == []  # the switch stays: its slide needs it
    fit, bic = OS._exchange(ctx, slide, slide.bic(sig), {"slide_tip": ["expo"]}, log)
    assert fit.model.terms.names() == ["reg_tip", "expo"] and bic == fit.bic(sig) < slide.bic(sig)
    assert log[-1]["exchanged"] == "slide_tip->expo"
    fit, bic = OS._exchange(ctx, expo, expo.bic(sig), {"expo": ["slide_tip"]}, log)
    assert fit is expo and bic == expo.bic(sig)
    assert min(b for _, b in log[-1]["exchange"]) >= expo.bic(sig)  # tried, and kept out


@pytest.mark.parametrize("through", ["fork", "pipe"])
def test_a_rounds_trials_built_and_fitted_in_their_items_are_the_offers_built_and_fitted_in_turn(monkeypatch, through):
    # `_trial_fits` builds each offer's starts beside its fits, an offer an item on two cores
    # (base.forkmap; "pipe": every item as a forked child hands it back, forkpipe). The fits are
    # those of each offer's starts built and fitted in turn here, bit for bit: a term's starts depend
    # on the fit so far and the search's context alone.
    from .forkpipe import through_the_pipe

    r, d, t, q, rt, rq, obs, hyst = record(duration_s=10.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    prior, sig = (r.delay_cfg_s, rec.period_s / np.sqrt(12)), OM.noise_sigma(obs)
    st, n_g = OS._start(rec, [r.delay_cfg_s], prior, None, None, sig)
    b0 = float(np.mean(r.B(q)))
    m = OM.RecordModel(rec, 4, n_g, OM.Terms(), prior)
    fit = OF.fit_model(m, m.theta({"d": np.array([r.delay_cfg_s]), "B": np.full(4, b0)}), sigma=sig, max_nfev=6, rounds=1)
    ctx = OS._Search(rec, n_g, prior, None, [r.delay_cfg_s], OS._start_widths(rec, None), b0, st, [1, 4], sig)
    offers = [(name, OM.Terms()) for name in ("ring", "reg_tip", "expo")]
    if through == "pipe":
        monkeypatch.setattr(OS, "fork_map", through_the_pipe)
    got = OS._trial_fits(ctx, offers, fit)
    want = [OF._fit_distinct([j[:5] for j in OS._term_trials(ctx, name, base, fit)[0]], here=True) for name, base in offers]
    assert [len(fs) for fs in got] == [len(fs) for fs in want] and min(len(fs) for fs in want) >= 1
    for fs_got, fs_want in zip(got, want):
        for a, b in zip(fs_got, fs_want):
            assert np.array_equal(a.theta, b.theta) and a.bic(sig) == b.bic(sig)
            assert np.array_equal(a.ev.resid, b.ev.resid)  # its evaluation too (from the model when it came through the pipe)
