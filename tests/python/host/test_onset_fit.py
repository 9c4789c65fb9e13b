"""Fitting one record model (playscope.fit.onset_fit): finite fits, fits that do not depend on the
process that ran them, a slide's and a shift's fit against their truth."""

import numpy as np
import pytest

from playscope.fit import onset_fit as OF
from playscope.fit import onset_model as OM
from playscope.fit import onset_search as OS
from playscope.fit.reversals import detect_reversals

from .onset_records import bench_module, record


def test_a_fit_whose_jacobian_goes_non_finite_keeps_a_finite_theta(monkeypatch):
    # A switch's scale gone to 0 once gave a NaN Jacobian, LM a NaN step and the next evaluation
    # a ValueError deep in the B-spline basis; the fit must instead stay where it was.
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    m = OM.RecordModel(rec, 1, 6, OM.Terms(), None)
    th0 = m.theta({"d": np.array([r.delay_s]), "B": np.array([0.2])})
    exact = m.jacobian

    def b_column_infinite(th, ev, sig):
        J = exact(th, ev, sig).copy()
        J[:, 1] = np.inf  # B's column; without the guard LM steps to NaN and the basis raises
        return J

    monkeypatch.setattr(m, "jacobian", b_column_infinite)
    f = OF.fit_model(m, th0, sigma=OM.noise_sigma(rec.obs), max_nfev=4, rounds=1)
    assert np.all(np.isfinite(f.theta)) and f.theta[1] == th0[1]


def test_fits_in_a_forked_child_equal_the_same_fits_run_in_turn_when_jobs_share_a_model():
    # _fit_all's child gets its jobs pickled before this process fits the rest, and each job fits its
    # own copy of the model: the jobs here share one model (as a term's starts do), and before, the
    # weights one fit left started the next (delays 0.9 ms apart), so the split into processes
    # changed the result. On one core _fit_all runs them in turn, and the in-turn and alone fits still
    # differ without the copy.
    r, d, t, q, rt, rq, obs, _ = record(duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    starts = ((0.0, 0.15), (0.01, 0.2), (-0.01, 0.25), (0.005, 0.3))

    def jobs(m):
        return [(m, m.theta({"d": np.array([r.delay_s + e]), "B": np.array([b])}), 0.1, 6, 1) for e, b in starts]

    def model():
        return OM.RecordModel(rec, 1, 6, OM.Terms(), (r.delay_s, 0.01))

    par = [f.theta for f in OF._fit_all(jobs(model()))]
    seq = [OF._fit_one(j).theta for j in jobs(model())]
    alone = [OF._fit_one(jobs(model())[i]).theta for i in range(len(starts))]  # each on a model of its own
    for a, b, c in zip(par, seq, alone):
        assert np.array_equal(a, b) and np.array_equal(b, c)


def test_a_chain_given_its_first_fit_goes_on_from_it_as_from_its_own():
    # B's size chains start from the fitted start's winning fit, which is their first link's job
    # (onset_search._search): handed that fit, the chain does not refit its first model, and its
    # later links are the same bits as the chain that fitted it itself.
    r, d, t, q, rt, rq, obs, _ = record(duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    sigma = OM.noise_sigma(rec.obs)

    def job():
        ms = [OM.RecordModel(rec, n, 6, OM.Terms(), (r.delay_s, 0.01)) for n in (1, 4)]
        return ms, ms[0].theta({"d": np.array([r.delay_s + 0.004]), "B": np.array([0.2])}), sigma, 6, 2

    own = OF._fit_chain(job())
    ms, th0, sig, nfev, rounds = job()
    first = OF._fit_one((ms[0], th0, sig, nfev, rounds))  # the first link's job, fitted elsewhere
    given = OF._fit_chain((ms, th0, sig, nfev, rounds, first))
    assert given[0] is first and np.array_equal(first.theta, own[0].theta)
    assert np.array_equal(given[1].theta, own[1].theta) and given[1].cost == own[1].cost


@pytest.mark.parametrize("terms", [OM.Terms(), OM.Terms(ring=True), OM.Terms(reg_tip=True)], ids=["plain", "ring", "reg_tip"])
def test_a_fit_skips_no_evaluation_that_would_change_a_bit_and_its_jacobian_is_the_one_its_end_state_gives(terms, monkeypatch):
    # The fits re-evaluate the model after each E-step only when the mixture changed (no switch term:
    # it never does), and a Fit's Jacobian is computed when asked for, on the model's state the fit
    # left. Against the fits that always re-evaluate and the Jacobian taken as the fit ended: the same
    # bits, even after the model's state has since moved (as a term's later fit moves its model's).
    r, d, t, q, rt, rq, obs, _ = record(duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    sigma = OM.noise_sigma(rec.obs)

    def fit():
        m = OM.RecordModel(rec, 4, 6, terms, (r.delay_s, 0.01))
        th0 = m.theta({"d": np.array([r.delay_s + 0.004]), "B": np.full(4, 0.2)})
        return OF._fit_chain(([m], th0, sigma, 6, 2))[-1]

    f = fit()
    assert f.model.e_step(f.ev, sigma) == terms.reg_tip  # a switch has frames near its windows; else no mixture
    f = fit()
    at_end = f.model.jacobian(f.theta, f.ev, f.sigma)  # as fit_model took it, in the state it left
    OF._settle(f.model, f.theta + 0.01, sigma)  # the model's weights, mixture and solve move on
    moved = f.model.w
    assert np.array_equal(f.jac, at_end) and f.model.w is moved
    monkeypatch.setattr(OM.RecordModel, "e_step", lambda self, ev, s, _e=OM.RecordModel.e_step: _e(self, ev, s) or True)
    g = fit()  # every E-step followed by an evaluation, as before the skip
    assert np.array_equal(g.theta, f.theta) and g.cost == f.cost and np.array_equal(g.jac, f.jac)


def test_a_fit_whose_last_round_scores_worse_returns_an_earlier_round_as_it_was_scored(monkeypatch):
    # fit_model keeps the best of its tried thetas by their settled cost (`_settle`) and returns it in
    # the state that cost was scored in, without settling it again. Forced here: the last round's LM
    # result is moved off by 10 % of B, so an earlier round is best. The returned Fit must then be that
    # round's score and state: its cost the settled one, its evaluation the model's in its state bit
    # for bit, and the model's own last evaluation (the linear solve `jacobian` reads) that theta's.
    r, d, t, q, rt, rq, obs, _ = record(duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    sigma = OM.noise_sigma(rec.obs)
    m = OM.RecordModel(rec, 4, 6, OM.Terms(reg_tip=True), (r.delay_s, 0.01))
    th0 = m.theta({"d": np.array([r.delay_s + 0.004]), "B": np.full(4, 0.2)})
    calls, costs = [], []
    real_lsq, real_settle = OF.least_squares, OF._settle

    def lsq(*a, **k):
        res = real_lsq(*a, **k)
        calls.append(res.x.copy())
        if len(calls) == 3:
            res.x = res.x.copy()
            res.x[1:1 + m.n_b] *= 0.5  # B's coefficients (the delay is free, so x is theta)
        return res

    def settle(model, th, sig):
        out = real_settle(model, th, sig)
        costs.append(out[1])
        return out

    monkeypatch.setattr(OF, "least_squares", lsq)
    monkeypatch.setattr(OF, "_settle", settle)
    f = OF._fit_one((m, th0, sigma, 6, 3))
    assert len(costs) == 4 and int(np.argmin(costs)) == 2  # the start and three rounds, the second round best
    assert np.array_equal(f.theta, calls[1]) and f.cost == costs[2]
    mc = OM.RecordModel.__new__(OM.RecordModel)
    mc.__dict__.update(f.model.__dict__)
    mc.w, mc.mix, mc.slope = f.state
    assert np.array_equal(mc.evaluate(f.theta).resid, f.ev.resid)
    assert np.array_equal(f.model.jacobian(f.theta, f.ev, sigma), f.jac)


def _channel_record(fps=25.0, B_kind="fig7", **scene):
    """marker_render's `channel` form (a Fig. 7 robot's B and 25 fps unless said) with the scene's settings:
    (the Scene, its Record with the renderer's principal point and focal length, the configured
    delay's prior, the record's noise scale px)."""
    MR = bench_module("marker_render")
    sc = MR.Scene(B_kind=B_kind, fps=fps, form="channel", **scene)
    d = MR.render(sc)
    t, q = d["t_enc"], d["q"]
    rt, rq, _ = detect_reversals(t, q, 0.01 * np.ptp(q))
    rec = OM.make_record(t, q, rt, rq, d["t_f"], np.column_stack([d["u"], d["v"]]), sc.fps, (360.0, 288.0), 600.0)
    return sc, rec, (sc.t_delay_config, rec.period_s / np.sqrt(12)), OM.noise_sigma(rec.obs)


@pytest.mark.parametrize("fps", [25.0, 60.0])
def test_a_registration_that_slides_is_fitted_as_a_slide_with_its_duration_and_B(fps):
    # marker_render's `channel` form (written apart from the estimator): the instrument slides in its
    # channel for U(0, 40 ms) starting U(0, T) after the tip reverses, seen through an 8 ms exposure.
    # From the stepped switch's fit, the slide's grid start and fit. Measured at 25 fps: BIC 680
    # against the stepped switch's 2,257, B 0.6 % off (constant width), the longest slide 50 ms (the
    # renderer's 40 ms plus its exposure). At 60 fps: BIC 2,236 against 10,461, the slide 48 ms. The
    # slide's bound is time (SLIDE_MAX_S), not a frame period: bounded by one frame (16.7 ms at
    # 60 fps) it stopped there, BIC 2,753.
    sc, rec, prior, sig = _channel_record(fps=fps, seed=3, speed=4.0, duration=15.0, size_deg=2.0, noise_px=0.15)
    step = OM.RecordModel(rec, 1, 10, OM.Terms(reg_tip=True), prior)
    fs = OF.fit_model(step, step.theta({"d": np.array([sc.t_delay_true]), "B": np.array([1.1 * sc.B(0.0)])}), sigma=sig)
    slide = OM.RecordModel(rec, 1, 10, OM.Terms(reg_tip=True, slide_tip=True), prior)
    fits = [OF.fit_model(slide, th, sigma=sig) for th in OS._slide_starts(slide, "tip", step.parts(fs.theta), sig)]
    f = min(fits, key=lambda f: f.bic(sig))
    assert f.bic(sig) < fs.bic(sig) - 500
    assert slide.unpack(f.theta)[1][0] == pytest.approx(sc.B(0.0), rel=0.02)
    assert 0.04 < slide.slides(f.theta)["tip"] < 0.06  # 40 ms and the 8 ms exposure, whatever the frame rate


def test_a_channel_translation_is_fitted_by_the_shift_as_one_offset_of_the_whole_image():
    # marker_render's `channel` form at the size of a LOCKBOX6_300 failure (2.8 deg, 25 fps, 0.05 px):
    # the image moves by f tan(size) px along u wherever the marker is, which the rotation alone
    # meets only to x^2 of it. From the switch-and-slide fit, the shift's fit (the translation in
    # the rotation's place): its half jump along u is the rendered one, none along v, and B closer
    # to the truth.
    sc, rec, prior, sig = _channel_record(seed=5, speed=1.0, duration=20.0, size_deg=2.8, noise_px=0.05)
    base = OM.RecordModel(rec, 1, 10, OM.Terms(reg_tip=True, slide_tip=True), prior)
    th = base.theta({"d": np.array([sc.t_delay_true]), "B": np.array([sc.B(0.0)])})
    f0 = OF.fit_model(base, th, sigma=sig)
    shift = OM.RecordModel(rec, 1, 10, OM.Terms(reg_tip=True, slide_tip=True, shift_tip=True), prior)
    shift.slope = base.slope
    f1 = OF.fit_model(shift, shift.theta(base.parts(f0.theta)), sigma=sig)
    half = sc.focal_px * np.tan(np.radians(sc.size_deg))
    du, dv = shift.reg_offset(f1.ev, "tip")
    # measured: BIC 3,545 -> 1,138; the half jump 29.336 px against 29.345, -0.004 px along v;
    # B 0.05 % off with the shift, 0.3 % without (a constant width here)
    assert shift.n_reg("tip") == OM.N_SHIFT and np.ptp(du) == 0.0  # one vector for the whole image
    assert f1.bic(sig) < f0.bic(sig) - 1000
    assert np.median(np.abs(du)) == pytest.approx(half, rel=0.005) and abs(np.median(dv)) < 0.05
    assert abs(shift.unpack(f1.theta)[1][0] / sc.B(0.0) - 1) < 0.005


def test_a_shifts_trial_is_scored_after_a_whole_fits_reweightings():
    # The shift takes the rotation's place, so at its trial's start the switch frames are the
    # translation's misfit to the rotation's jump and the weights set there are not the fit so far's.
    # A 20 s channel rendering at the size of s9-marker-032 of LOCKBOX9_300 (2.63 deg, 60 fps, stras B,
    # 8 coefficients): from the rotation's fit (BIC measured 4,976), the shift's trial after one
    # reweighting, the budget of a trial that adds to the fit so far, scored 5,859 and lost; after
    # the search's rounds for a shift, 4,169.
    sc, rec, prior, sig = _channel_record(fps=60.0, B_kind="stras", seed=690033, speed=5.739, duration=20.0,
                                          size_deg=2.63, noise_px=0.079, t_delay_true=0.195, t_delay_config=0.195)
    terms = dict(reg_tip=True, slide_tip=True, expo=True)
    rot = OM.RecordModel(rec, 8, 14, OM.Terms(**terms), prior, None, "input")
    qq = np.linspace(rot.q_lo, rot.q_hi, 400)
    cB = np.linalg.lstsq(OM._basis(qq, rot.q_lo, rot.q_hi, 8), sc.B(qq), rcond=None)[0]
    f0 = OF._fit_one((rot, rot.theta({"d": np.array([sc.t_delay_true]), "B": cB}), sig, 20, OF.IRLS_ROUNDS))
    shift = OM.RecordModel(rec, 8, 14, OM.Terms(**terms, shift_tip=True), prior, None, "input")
    shift.slope = f0.model.slope

    def trial(rounds):
        return OF._fit_one((shift, shift.theta(f0.model.parts(f0.theta)), sig, 8, rounds)).bic(sig)

    assert trial(OS._trial_rounds("shift_tip")) < f0.bic(sig) - 400
    assert trial(OS.TRIAL_ROUNDS) > f0.bic(sig)


def _short_first_stroke_record():
    """A 1 kHz triangle that first rises 0.05 mm, then swings between -1 and +1 mm (reversals at
    0.05, -1, +1, -1 mm), 25 fps frames: with a play 0.3 mm wide starting mid-band, the first
    stroke never reaches the play's edge."""
    t = np.arange(0.0, 4.0, 0.001)
    knots_t = np.array([0.0, 0.05, 1.1, 2.3, 3.5, 4.0])
    knots_q = np.array([0.0, 0.05, -1.0, 1.0, -1.0, -0.5])
    q = np.interp(t, knots_t, knots_q)
    t_f = np.arange(0.02, 3.98, 0.04)
    obs = np.column_stack([np.linspace(300, 400, t_f.size), np.full(t_f.size, 250.0)])
    return OM.make_record(t, q, knots_t[1:5], knots_q[1:5], t_f, obs, 25.0, (360.0, 288.0), 600.0)


@pytest.mark.parametrize("x0, first_kept", [(0.0, False), (-30.0, True)])
def test_eq1_samples_come_only_from_reversals_the_play_was_engaged_at(x0, first_kept):
    # Eq. 1 measures the width from the reversal only when the output sat on the edge the old
    # direction drags. Started mid-band (x0 = 0), the first stroke (0.05 mm, under half the 0.3 mm
    # play) leaves the output inside the band, so the first take-up is 0.20 mm, not the width:
    # no sample there. Started on the lower edge (x0 -> -inf), the first stroke drags it: a sample.
    from types import SimpleNamespace

    rec = _short_first_stroke_record()
    m = OM.RecordModel(rec, 1, 6, OM.Terms(), None)
    th = m.theta({"d": np.array([0.0]), "B": np.array([0.3]), "z0": np.array([x0])})
    sm = OF.samples(SimpleNamespace(model=m, theta=th, jac=np.eye(th.size), sigma=1.0))
    assert list(sm.rev) == ([0, 1, 2, 3] if first_kept else [1, 2, 3])
    # every kept sample is the width, to the 1 ms grid at 1.8 mm/s (and the q at the onset's interpolation)
    np.testing.assert_allclose(sm.b, 0.3, atol=0.003)
