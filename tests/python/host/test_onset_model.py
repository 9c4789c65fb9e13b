"""The record model of the onsets (playscope.fit.onset_model): its equations, Jacobian and
objective against their definitions, finite differences and small renderings."""

import sys

import numpy as np
import pytest

from playscope.fit import onset_fit as OF
from playscope.fit import onset_model as OM
from playscope.fit.reversals import detect_reversals

from .onset_records import ROOT, record


def test_onsets_of_the_play_are_where_q_has_come_back_by_B_eq_1():
    # A constant width b and a triangle q: after each reversal the play output holds until q has
    # come back by b (eq. 1), at t1 + b / speed.
    t = np.arange(0.0, 10.0, 1e-3)
    speed, b = 2.0, 0.3
    q = 1.0 - np.abs(((speed * t) % 4.0) - 2.0)  # legs of 2 units at 2 units/s, reversals every 1 s
    rt = np.arange(1.0, 9.5, 1.0)
    rq = np.interp(rt, t, q)
    rec = OM.make_record(t, q, rt, rq, np.arange(0.5, 9.5, 0.04), np.zeros((225, 2)), 25.0)
    m = OM.RecordModel(rec, 1, 6, OM.Terms(), None)
    t_on = m.onsets(m.play(np.array([b])))
    assert np.allclose(t_on[1:], rt[1:] + b / speed, atol=1.5e-3)  # one grid step


def test_the_tip_modes_stop_is_driven_by_the_play_output_or_by_the_motor():
    # A triangle at speed v through a play whose width grows along the travel, B(q) = b0 + k q read
    # at the input: while dragged, z = q -+ B(q) / 2 moves at v (1 -+ k / 2), so each stop's drive
    # (the velocity change, the area of -z'') is v (1 - k / 2) going up and v (1 + k / 2) going
    # down; driven by the motor (ring_motor) it is the motor's whole reversal, 2 v, at every stop.
    # The reversals fall 0.4 ms before a grid sample, so the motor's second difference spreads over
    # two samples (the stop's and the next), as on a real record.
    dt, v, k = 1e-3, 2.0, 0.2
    t = np.arange(0.0, 6.0, dt)
    q = 1.0 - np.abs(((v * (t + 4e-4)) % 4.0) - 2.0)  # reversals every 1 s, at q = +-1
    rt = np.arange(1.0, 5.5, 1.0) - 4e-4
    rec = OM.make_record(t, q, rt, np.interp(rt, t, q), np.arange(0.5, 5.5, 0.04), np.zeros((125, 2)), 25.0)
    for motor in (False, True):
        m = OM.RecordModel(rec, 4, 6, OM.Terms(ring=True, ring_motor=motor), None)
        g = np.linspace(m.q_lo, m.q_hi, 50)
        cB = np.linalg.lstsq(OM._basis(g, g[0], g[-1], 4), 0.3 + k * g, rcond=None)[0]
        th = m.theta({"d": np.array([0.0]), "B": cB, "ring": m.ring_theta(3.0, 0.1)})
        (stop, _), (u_stop, _) = m._play_part(0.0, m.unpack(th)[1], m.z0_of(th), m.exposure(th))[-2]
        for tr in rt[1:]:  # the first reversal's stop depends on the first state
            near = np.abs(rec.t[1:-1] - tr) < 0.05
            area = np.sum(u_stop[near]) * rec.dt
            going_up = np.interp(tr - 0.1, t, q) < np.interp(tr, t, q)
            want = 2 * v if motor else v * (1 - k / 2 if going_up else 1 + k / 2)
            assert area * (1 if going_up else -1) == pytest.approx(want, rel=0.02)
        # and so the stop's response moves with B only when the play output drives it (`ring_gradient`)
        st = m.columns(th)[3]
        dx = m.ring_gradient(m.unpack(th)[1], st, m.z0_of(th), np.array([1.0, 0.0]))
        assert (np.abs(dx).max() == 0.0) if motor else (np.abs(dx).max() > 1e-3)


def test_noise_sigma_recovers_white_noise_on_a_slow_record():
    rng = np.random.default_rng(3)
    x = np.column_stack([np.linspace(0, 50, 4000), np.sin(np.linspace(0, 6, 4000)) * 30])
    assert OM.noise_sigma(x + rng.normal(0, 0.2, x.shape)) == pytest.approx(0.2, rel=0.08)


@pytest.mark.parametrize("terms,width_at", [((), "input"), ((), "output"), (("reg_tip", "reg_motor"), "input"),
                                             (("reg_tip", "reg_motor"), "output"), (("ring",), "input"),
                                             (("ring", "ring_motor"), "input"),
                                             (("reg_tip", "reg_motor", "mix"), "input"),
                                             (("reg_tip", "slide_tip", "reg_motor", "slide_motor", "mix"), "input"),
                                             (("reg_tip", "shift_tip", "reg_motor", "shift_motor", "mix"), "input"),
                                             (("expo",), "input"), (("expo",), "output"),
                                             (("reg_tip", "reg_motor", "expo", "mix"), "input"),
                                             (("spread",), "input"), (("spread",), "output"),
                                             (("ring", "spread"), "input"), (("expo", "spread"), "input"),
                                             (("reg_tip", "reg_motor", "spread"), "input"),
                                             (("reg_tip", "reg_motor", "spread", "mix"), "input")])
def test_the_analytic_jacobian_agrees_with_finite_differences(terms, width_at):
    # Kaufman's variable-projection Jacobian against the projected residual's forward differences
    # (which re-solve the linear parameters): the gradient J'r, what the fit follows, and each
    # column of the delay and of B. With the spread (module doc: its gradients the nodes' single-play
    # ones at m cB), on a rendering whose widths spread by 0.4 of B (swing_render's 41 plays, not the
    # model's 8), and its own column too.
    r, d, t, q, rt, rq, obs, _ = record(reg_deg=1.5 if terms and terms[0] == "reg_tip" else 0.0,
                                         ring_hz=3.0 if terms[:1] == ("ring",) else 0.0, duration_s=30.0,
                                         exposure_s=0.025 if "expo" in terms else 0.004,
                                         spread=0.4 if "spread" in terms else 0.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    m = OM.RecordModel(rec, 4, 10, OM.Terms(**{k: True for k in terms if k != "mix"}), (r.delay_s, 0.01),
                       width_at=width_at)
    g = np.linspace(rec.q.min(), rec.q.max(), 40)
    cB = np.linalg.lstsq(OM._basis(g, g[0], g[-1], 4), r.B(g), rcond=None)[0]
    th = m.theta({"d": np.array([r.delay_s + 0.003]), "B": 1.03 * cB, "ring": m.ring_theta(3.1, 0.06),
                  "expo": np.array([m.expo_x(0.010 if "mix" in terms else 0.022)]), "spread": np.array([m.spread_x(0.35)])})
    # (with the switches, an exposure shorter than their lag: at 22 ms, as long as the lag, the forward
    # step of a lag moves two frames across a share's clip and the differences read 0.84 there)
    ev = m.evaluate(th)
    m.slope = m.G_slope(ev)
    if "mix" in terms:  # the switches' mixture rows (an E-step first)
        m.e_step(ev, 0.12)
        assert sum(mx["j"].size for mx in m.mix.values()) > 10
    m.w = OM.huber_weights(m.evaluate(th).resid, 0.12)
    fun = OF._residual_fn(m, 0.12)
    r0 = fun(th)
    Ja = m.jacobian(th, m.evaluate(th), 0.12)
    Jf = OF._jac(m, fun, th, r0)
    cos = lambda a, b: float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))  # noqa: E731
    # measured 0.99999 (none); with the switches 0.970: a frame crossing a switch's
    # ramp edge between the forward steps makes the differences themselves coarse there
    # with the switches' mixture 0.99997: its frames' signs are the E-step's, so no ramp edge is crossed
    # the ring 0.9996 (0.9981 without the tip mode's drive through B); with the slides 0.999995
    assert cos(Ja.T @ r0, Jf.T @ r0) > (0.9 if "reg_tip" in terms and "mix" not in terms else 0.999)
    if "mix" in terms and "spread" not in terms:  # the switches' lags and slides, column by column: measured
        # 0.996..0.99997
        for name, sl in m.layout().items():
            if name.startswith(("lag_", "slide_")):
                assert cos(Ja[:, sl.start], Jf[:, sl.start]) > 0.99
    # column by column where no switch hangs on the onsets (through them, a forward step moves a
    # slow onset across frames; `test_the_onsets_gradient...` checks that part with a small step);
    # with the ring, B's columns carry the tip mode's drive through the onsets (`ring_gradient`)
    if "expo" in terms:  # the exposure's column: measured 0.9996 (both width forms)
        i = m.layout()["expo"].start
        assert cos(Ja[:, i], Jf[:, i]) > 0.99
    if "spread" in terms and "reg_tip" not in terms:  # measured: s's column 0.998-0.9991, B's 0.998-0.9999, the
        # delay's 0.995-0.9997
        for i in [0, *range(1, 1 + m.n_b), m.layout()["spread"].start]:
            assert cos(Ja[:, i], Jf[:, i]) > 0.99, i
    if "spread" in terms and "reg_tip" in terms:
        # With the switches, the tip's switch starts at the narrowest play's first motion, so B's and s's
        # forward steps (2 % of B, 0.05) move onsets across frames (measured: B 0.49-0.98, s 0.55-0.76, the
        # tip's lag 0.41 through its mixture rows). By central differences at a hundredth of those steps,
        # measured: on the switches' ramps B 0.991-0.9997, the lags 0.995-0.9999, s 0.990; through the
        # mixture rows B 0.9975-0.9998, the lags 1.0, s 0.990 (s's column is the narrowest play's onset
        # gradient times u_0: 0.06 and 0.68 with it left out of the ramps or of the mixture rows).
        h = OF._steps(m, th) / 100
        for name, sl in m.layout().items():
            for i in range(sl.start, sl.stop):
                if name in ("d", "z0"):  # the delay by the gradient check above; z0 moves nothing here
                    continue
                tp, tm = th.copy(), th.copy()
                tp[i] += h[i]
                tm[i] -= h[i]
                assert cos(Ja[:, i], (fun(tp) - fun(tm)) / (2 * h[i])) > 0.97, name
    if not terms or terms in (("ring",), ("ring", "ring_motor"), ("expo",)):
        for i in range(1 + m.n_b):
            # measured 0.98..1.0; the ring's B columns 0.989..0.9998 (0.93..0.97 without its drive through B);
            # with the exposure 0.988..0.9998
            assert cos(Ja[:, i], Jf[:, i]) > (0.975 if terms else 0.95)


def test_the_spreads_output_is_the_mean_of_its_widths_plays_and_its_onsets_the_narrowests():
    # At a constant width: z is the mean of the single plays of widths m B (the model's own play, one per
    # node), and after each reversal the first motion, the onset a switch that follows the tip starts
    # at, comes once q has come back by the narrowest width (1 - s (1 - 1 / K)) B, K the nodes (eq. 1 of
    # that play); the centre width's play, what the samples are read off, is unchanged by s.
    r, d, t, q, rt, rq, obs, _ = record(duration_s=20.0, spread=0.5)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    m = OM.RecordModel(rec, 1, 10, OM.Terms(spread=True), None)
    s, b = 0.5, 0.2
    th = m.theta({"d": np.array([r.delay_s]), "B": np.array([b]), "spread": np.array([m.spread_x(s)])})
    _, t_on, _, st = m.columns(th)
    z = st["z"]
    mk, _ = m.spread_factors(m.spread(th))
    assert m.spread(th) == pytest.approx(s)
    assert np.allclose(z, np.mean([m.play(mm * np.array([b]), 0.0) for mm in mk], axis=0), atol=1e-12)
    ok = np.isfinite(t_on)
    assert ok.sum() > 10
    back = np.abs(np.interp(t_on[ok], rec.t, rec.q) - rec.rq[ok])
    assert np.allclose(back, (1.0 - s * (1.0 - 1.0 / OM.SPREAD_NODES)) * b, atol=2 * np.max(np.abs(np.diff(rec.q))))
    plain = OM.RecordModel(rec, 1, 10, OM.Terms(), None)
    assert np.array_equal(m.play(np.array([b]), 0.0), plain.play(np.array([b]), 0.0))


@pytest.mark.parametrize("D,E", [(0.025, 0.0), (0.025, 0.011), (0.0, 0.011)])
def test_the_switchs_level_shares_are_those_of_a_uniform_start_a_uniform_slide_and_the_exposure(D, E):
    # Monte Carlo of the switch the shares assume (start u ~ U(0, L), duration E + U(0, D): a slide
    # seen through an exposure E), apart from the closed form: the share still at the old level and
    # the share already at the new one, with the stepped switch (D = E = 0) as p = since / L; and
    # their derivatives over (since, L, D, E) against central differences
    rng = np.random.default_rng(5)
    L = 0.03
    u, dur = rng.uniform(0, L, 200_000), E + rng.uniform(0, D, 200_000)
    since = np.linspace(-0.0093, 0.0807, 17)  # off the kinks at 0, E, D + E, L and L + D + E
    p_old, p_new, dp_old, dp_new = OM._switch_shares(since, L, D, E)
    mc_old = np.array([(u >= s).mean() for s in since])
    mc_new = np.array([(u + dur <= s).mean() for s in since])
    assert np.abs(p_old - mc_old).max() < 4e-3 and np.abs(p_new - mc_new).max() < 4e-3  # MC sd <= 1.1e-3
    assert np.allclose(OM._switch_shares(since, L, 0.0)[1], np.clip(since / L, 0, 1))
    h = 1e-6
    x = np.array([0.0, L, D, E])
    for k in range(4):
        if x[k] == 0.0 and k >= 2:  # a one-sided parameter at its bound
            continue
        dx = np.zeros(4)
        dx[k] = h
        up = OM._switch_shares(since + dx[0], *(x[1:] + dx[1:]))
        dn = OM._switch_shares(since - dx[0], *(x[1:] - dx[1:]))
        for i, dp in ((0, dp_old), (1, dp_new)):
            assert np.allclose((up[i] - dn[i]) / (2 * h), dp[k], rtol=1e-6, atol=1e-6)


def test_the_mid_slide_levels_likelihood_is_the_integral_over_its_level():
    # ln of the integral over h in [0, 1] of e^-rho(ro - h J), rho Huber per axis, by quadrature. The
    # level is the least squares one clipped into [0, 1]; along the jump the loss is taken Gaussian,
    # whose tails are lighter than Huber's linear ones: measured 0.05-0.10 low in ln (5-10 % of the
    # integral) within the slide, and far lower beyond its end, so a frame past either level never
    # reads as mid slide more than the Huber loss says
    from scipy.integrate import quad

    sigma = 0.15
    J = np.array([30.0, -8.0])
    for h_true, off in ((0.4, (0.1, 0.2)), (0.0, (0.05, -0.1)), (0.97, (0.0, 0.0)), (1.3, (0.1, 0.1))):
        ro = h_true * J + np.array(off)
        h, ln_int = OM._mid_level(np.array([ro[0]]), np.array([ro[1]]), np.array([J[0]]), np.array([J[1]]), sigma)
        f = lambda x: np.exp(-(OM.huber_rho(ro[0] - x * J[0], sigma) + OM.huber_rho(ro[1] - x * J[1], sigma)))  # noqa: E731
        ref = quad(f, 0.0, 1.0, points=[min(max(h_true, 0.0), 1.0)], epsabs=0.0, epsrel=1e-10, limit=200)[0]
        assert h[0] == pytest.approx(np.clip(h_true + np.dot(off, J) / np.dot(J, J), 0.0, 1.0), abs=1e-9)
        if h_true <= 1.0:
            assert np.log(ref) - 0.2 < ln_int[0] <= np.log(ref)
        else:
            assert ln_int[0] < np.log(ref) - 10.0


@pytest.mark.parametrize("width_at", OM.WIDTH_AT)
def test_the_plays_first_state_moves_the_frames_and_onset_before_its_first_drag(width_at):
    # eq. 3 needs z[-1]: a record may start with the play anywhere in its band. Two short legs
    # that turn back before they take the play up: the first state alone sets z up to the first
    # drag (the hold continues through two reversals), and moves that onset by dz0 / q'. The closed forms against central differences, and nothing after the first drag moves.
    t = np.arange(0.0, 6.0, 1e-3)
    q = np.interp(t, np.arange(7.0), [0.5, 0.55, 0.45, 0.8, 0.2, 0.8, 0.2])  # two short legs, then long ones
    rt, rq, _ = detect_reversals(t, q, 0.01)
    t_f = np.arange(0.1, 5.9, 0.04)
    rec = OM.make_record(t, q, rt, rq, t_f, np.zeros((t_f.size, 2)), 25.0)
    m = OM.RecordModel(rec, 1, 6, OM.Terms(), None, width_at=width_at)
    cB, x0, h = np.array([0.31]), 0.4, 1e-6
    st = m.columns(m.theta({"d": np.zeros(1), "B": cB, "z0": np.array([x0])}))[3]
    t_on = m.onsets(st["z"])
    first = int(np.flatnonzero(st["last"] >= 0)[0])
    assert rt[1] < rec.t[first]  # the hold from the first state outlasts the first reversal
    k = np.arange(0, rec.t.size, 7)
    dzc, dzx = m.z_gradient(cB, st, k, x0)
    zp, zm = m.play(cB, x0 + h), m.play(cB, x0 - h)
    assert np.allclose(dzx, (zp - zm)[k] / (2 * h), atol=1e-7)
    assert np.all(dzx[k > first] == 0.0) and np.all(dzx[k < first] > 0.0)
    zb = [m.play(cB + s * h, x0) for s in (1, -1)]
    assert np.allclose(dzc[:, 0], (zb[0] - zb[1])[k] / (2 * h), atol=1e-6)
    ok = np.isfinite(t_on)
    dton_x = m.onset_gradient(cB, st, t_on[ok], rec.s_new[ok], x0)[1]
    fd = (m.onsets(zp)[ok] - m.onsets(zm)[ok]) / (2 * h)
    assert np.allclose(dton_x, fd, rtol=1e-3, atol=1e-6) and np.count_nonzero(dton_x) == 1


def test_the_jacobians_first_state_column_agrees_with_finite_differences():
    # The same two short legs seen by a camera (a curved image path of the play's output, 0.1 px
    # noise, the first state at x0 = 0.8): the variable-projection Jacobian's column of the first
    # state (the frames of the first hold, through G') against the projected residual's forward
    # differences, which re-solve G; at the truth, where Kaufman's dropped term is the noise's
    # (measured cosine 0.9996, norms 1.3 % apart; 0.992 and 3.3 % at x0 = 0.7, 0.74 at x0 = 0,
    # 0.2 of the band away, where the residuals' dropped term dominates).
    t = np.arange(0.0, 6.0, 1e-3)
    q = np.interp(t, np.arange(7.0), [0.5, 0.55, 0.45, 0.8, 0.2, 0.8, 0.2])
    rt, rq, _ = detect_reversals(t, q, 0.01)
    t_f = np.arange(0.1, 5.9, 0.04)
    rec0 = OM.make_record(t, q, rt, rq, t_f, np.zeros((t_f.size, 2)), 25.0)
    m0 = OM.RecordModel(rec0, 1, 6, OM.Terms(), None)
    zf = np.interp(t_f, rec0.t, m0.play(np.array([0.31]), 0.8))
    obs = np.column_stack([300 + 400 * zf, 200 + 300 * zf ** 2]) + np.random.default_rng(2).normal(0, 0.1, (t_f.size, 2))
    rec = OM.make_record(t, q, rt, rq, t_f, obs, 25.0)
    m = OM.RecordModel(rec, 1, 6, OM.Terms(), None)
    th = m.theta({"d": np.zeros(1), "B": np.array([0.31]), "z0": np.array([0.8])})
    fun = OF._residual_fn(m, 0.1)
    r0 = fun(th)
    Ja = m.jacobian(th, m.evaluate(th), 0.1)
    Jf = OF._jac(m, fun, th, r0)
    i = m.layout()["z0"].start
    cos = float(Ja[:, i] @ Jf[:, i] / np.linalg.norm(Ja[:, i]) / np.linalg.norm(Jf[:, i]))
    assert np.count_nonzero(Jf[:, i]) > 10 and cos > 0.998
    assert np.linalg.norm(Ja[:, i]) == pytest.approx(np.linalg.norm(Jf[:, i]), rel=0.05)


@pytest.mark.parametrize("width_at", OM.WIDTH_AT)
def test_the_onsets_gradient_over_B_agrees_with_small_differences(width_at):
    r, d, t, q, rt, rq, obs, _ = record(duration_s=30.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    m = OM.RecordModel(rec, 4, 10, OM.Terms(), None, width_at=width_at)
    cB = np.array([0.15, 0.25, 0.28, 0.16])
    th = m.theta({"d": np.array([r.delay_s]), "B": cB})
    st = m.columns(th)[3]
    t_on = m.onsets(st["z"])
    ok = np.isfinite(t_on)
    an = m.onset_gradient(cB, st, t_on[ok], rec.s_new[ok], 0.0)[0]
    for i in range(4):
        c2 = cB.copy()
        c2[i] += 1e-4
        fd = (m.onsets(m.play(c2))[ok] - t_on[ok]) / 1e-4
        rel = np.abs(an[:, i] - fd) / (np.abs(fd) + 1e-3)
        # measured: median 1e-10 at the input, 4e-6 at the output (its band is interpolated on
        # the model's z grid); all but one or two onsets within 9 %, the rest where the step
        # moves a near-still onset across a grid sample
        assert np.median(rel) < (1e-6 if width_at == "input" else 2e-5) and np.mean(rel < 0.1) >= 0.85


def test_the_along_path_share_is_the_cosine_between_the_jump_and_the_paths_tangent():
    from playscope.fit.onset_stage import along_path_share

    ang = np.radians([0.0, 30.0, 60.0, 90.0, 120.0])  # the path's tangent against a jump along u
    slope = 3.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    du, dv = np.full(5, 2.0), np.zeros(5)
    assert along_path_share(du, dv, slope) == pytest.approx(np.median(np.abs(np.cos(ang))))
    assert np.isnan(along_path_share(np.zeros(5), np.zeros(5), slope))


def test_a_slide_or_a_shift_is_offered_only_onto_its_own_switch():
    assert OM.Terms().offered() == ["ring", "reg_tip", "reg_motor", "expo", "spread"]
    assert OM.Terms(ring=True).offered() == ["ring_motor", "reg_tip", "reg_motor", "expo", "spread"]
    assert OM.Terms(reg_tip=True).offered() == ["ring", "reg_motor", "slide_tip", "shift_tip", "expo", "spread"]
    assert OM.Terms(reg_tip=True, reg_motor=True, slide_tip=True).offered() == \
        ["ring", "slide_motor", "shift_tip", "shift_motor", "expo", "spread"]


@pytest.mark.parametrize("name", ["marker_render.py", "swing_render.py"])
def test_the_renderers_that_judge_the_onset_stage_import_numpy_and_the_standard_library_only(name):
    import ast

    tree = ast.parse((ROOT / "bench" / name).read_text())
    mods = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    mods |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert mods <= {"numpy", "json", "dataclasses", "pathlib", "__future__", "math"} | set(sys.stdlib_module_names)
    assert "playscope" not in mods


def test_the_delay_prior_is_flat_over_the_exposures_half_frame_and_gaussian_beyond():
    # module doc, the exposure: the configured delay d_cfg is to the exposure's end, so the mean
    # lag may lie anywhere in [d_cfg, d_cfg + T/2] at no cost; beyond, the distance in prior sds
    t = np.arange(0.0, 10.0, 1e-3)
    q = 1.0 - np.abs(((2.0 * t) % 4.0) - 2.0)
    rt = np.arange(1.0, 9.5, 1.0)
    rec = OM.make_record(t, q, rt, np.interp(rt, t, q), np.arange(0.5, 9.5, 0.04), np.zeros((225, 2)), 25.0)
    m = OM.RecordModel(rec, 1, 6, OM.Terms(), (0.1, 0.01))
    assert m.prior_residual(0.1) == (0.0, 0.0) and m.prior_residual(0.1 + 0.019) == (0.0, 0.0)
    assert m.prior_residual(0.08)[0] == pytest.approx(-2.0) and m.prior_residual(0.08)[1] == pytest.approx(100.0)
    assert m.prior_residual(0.14)[0] == pytest.approx((0.14 - 0.12) / 0.01)
    # the delay reported: the exposure's end nearest d_cfg, its exposure twice the rest of the lag
    assert m.exposure_end(0.106, 0.001) == pytest.approx((0.1, 0.012))
    assert m.exposure_end(0.125, 0.001) == pytest.approx((0.105, 0.04))  # a whole frame, the most it may be
    assert m.exposure_end(0.2, 0.001) == (0.2, None)  # contradicted: unsplit
    # the record's bound on the exposure (onset_fit.exposure_bound) judges the configured delay against
    # [lag - e_max / 2, lag], but does not place the exposure's end
    assert m.exposure_end(0.14, 0.001, 0.01) == (0.14, None)  # 0.035 from that band: 3.5 sd, contradicted
    assert m.exposure_end(0.14, 0.001) == pytest.approx((0.12, 0.04))  # 0.02 from [lag - T/2, lag]: 2 sd, split
    assert m.exposure_end(0.125, 0.001, 0.01) == pytest.approx((0.105, 0.04))  # 2.0 sd: split as without


def test_the_linear_solve_is_the_weighted_least_squares_one_where_frames_miss_the_paths_ends():
    # G's end coefficients reach beyond the frames; the registration's columns (px per rad) are
    # thousands of times G's. A ridge scaled by the trace once pulled those ends towards 0 px:
    # the weighted sum of squares came out above lstsq's, and each Huber reweighting raised it.
    r, d, t, q, rt, rq, obs, hyst = record(reg_deg=1.5, seed=11, duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    m = OM.RecordModel(rec, 4, 10, OM.Terms(reg_tip=True), None)
    th = m.theta({"d": np.array([r.delay_s]), "B": np.full(4, float(np.mean(r.B(q))))})
    F = rec.t_f.size
    sigma = OM.noise_sigma(rec.obs)
    m.w = np.ones(2 * F)
    ev = m.evaluate(th)
    m.w = m.weights(ev, sigma)
    ev = m.evaluate(th)
    A1, sh = ev.cols["G"], m.shared_columns(ev.cols)
    Z = np.zeros_like(A1)
    A = np.vstack([np.hstack([A1, Z] + [c[0][:, None] for c in sh]), np.hstack([Z, A1] + [c[1][:, None] for c in sh])])
    y = np.r_[rec.obs[:, 0], rec.obs[:, 1]]
    sw = np.sqrt(m.w)
    r_ls = y - A @ np.linalg.lstsq(sw[:, None] * A, sw * y, rcond=None)[0]
    wss, wss_ls = np.sum(m.w * ev.resid ** 2), np.sum(m.w * r_ls ** 2)
    # measured: 7e-6 above lstsq (the P-spline's continuation); the trace-scaled ridge was 12 % above
    assert wss == pytest.approx(wss_ls, rel=5e-5)


def test_the_jacobian_of_a_switch_model_whose_width_no_swing_takes_up_is_finite():
    # A coarse-to-fine trial can pass through a B wider than every swing: no onset, so no tip switch.
    # The Jacobian once indexed the empty list of switches (an IndexError on a held-out rendering).
    r, d, t, q, rt, rq, obs, hyst = record(reg_deg=1.5, seed=11, duration_s=20.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    m = OM.RecordModel(rec, 1, 10, OM.Terms(reg_tip=True, reg_motor=True), (r.delay_s, 0.01))
    th = m.theta({"d": np.array([r.delay_s]), "B": np.array([10.0 * np.ptp(q)])})
    ev = m.evaluate(th)
    assert np.all(np.isnan(ev.t_on))
    m.w = m.weights(ev, 0.12)
    J = m.jacobian(th, m.evaluate(th), 0.12)
    assert J.shape[1] == th.size and np.all(np.isfinite(J))


def test_the_basis_and_its_derivative_are_the_design_matrix_and_de_boors_recurrence_bit_for_bit():
    # _basis and _dbasis evaluate one vector-valued spline (identity coefficients) for speed; they
    # must give what the definitions give, to the bit (a fit's path depends on every bit): the
    # basis as scipy's sparse design matrix, the derivative by de Boor's recurrence from the
    # quadratic basis on the same knots (A Practical Guide to Splines, 1978, ch. X), B_i,3' =
    # 3 B_i,2 / (t_i+3 - t_i) - 3 B_i+1,2 / (t_i+4 - t_i+1), a zero span's term 0. At random
    # points, the knots themselves and the range's ends, inside the range and clipped beyond it.
    from scipy.interpolate import BSpline

    rng = np.random.default_rng(0)
    for n in (4, 5, 6, 10, 16):
        lo, hi = float(rng.uniform(-2, 0)), float(rng.uniform(0.5, 3))
        inner = np.linspace(lo, hi, n - 2)
        t = np.r_[[lo] * 3, inner, [hi] * 3]
        x = np.r_[rng.uniform(lo - 1, hi + 1, 400), inner, np.nextafter(hi, -np.inf)]
        xc = np.clip(x, lo, np.nextafter(hi, -np.inf))
        assert np.array_equal(OM._basis(x, lo, hi, n), BSpline.design_matrix(xc, t, 3, extrapolate=True).toarray())
        B2 = BSpline.design_matrix(xc, t, 2, extrapolate=True).toarray()
        span = t[3:n + 4] - t[:n + 1]
        c = np.where(span > 0, 3.0 / np.where(span > 0, span, 1.0), 0.0)
        assert np.array_equal(OM._dbasis(x, lo, hi, n), B2[:, :n] * c[:n] - B2[:, 1:] * c[1:])


def test_the_plays_edge_gradient_at_the_input_is_the_designs_rows():
    # edge_gradient reads B's design rows from its taps (fast); they are the sparse design's rows
    r, d, t, q, rt, rq, obs, hyst = record(duration_s=6.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    m = OM.RecordModel(rec, 8, 6, OM.Terms(), None)
    k = np.random.default_rng(1).integers(0, rec.q.size, 300)
    side = np.where(np.arange(300) % 2 == 0, -0.5, 0.5)
    assert np.array_equal(m.edge_gradient(np.full(8, 0.2), k, rec.q[k], side), m.Phi_B[k].toarray() * side[:, None])


def test_models_of_a_size_share_their_records_design_and_a_pickled_one_rebuilds_it():
    # B's design on the grid is the record's (Record.width_basis), one per size, shared by every model
    # of that size; a model pickled (a forked child's fit coming back) leaves it out, and the one that
    # comes back builds it from its record again: the same design, and the same evaluation bit for bit.
    import pickle

    r, d, t, q, rt, rq, obs, _ = record(duration_s=10.0)
    rec = OM.make_record(t, q, rt, rq, d["t_f"], obs, r.fps)
    a, b = (OM.RecordModel(rec, 8, 6, OM.Terms(reg_tip=True), None, None, w) for w in ("input", "output"))
    assert a.Phi_B is b.Phi_B and a.Phi_B is rec.width_basis(8) and b.Phi_Bz is rec.width_basis(8, "z")
    with pytest.raises(ValueError, match="'grid' or 'z'"):
        rec.width_basis(8, "output")
    for m in (a, b):
        th = m.theta({"d": np.array([r.delay_s]), "B": np.full(8, 0.2)})
        want = m.evaluate(th).resid
        blob = pickle.dumps(m)
        assert len(blob) < len(pickle.dumps(rec)) + 2 * m.w.nbytes + 200_000  # the record and the weights, no design
        back = pickle.loads(blob)
        assert (back.Phi_B != m.Phi_B).nnz == 0 and np.array_equal(back.evaluate(th).resid, want)
