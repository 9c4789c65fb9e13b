"""model.py against the paper's equations and independent double-precision computations."""

import cv2
import numpy as np
import pytest

from playscope.fit import model

from .synth import ROBOT, image_model_parts, true_B, true_f


def test_z_up_down_solve_eq2():
    q = np.linspace(-5, 5, 101)
    zu, zd = model.z_up(q, true_B), model.z_down(q, true_B)
    np.testing.assert_allclose(zu + true_B(zu) / 2, q, atol=1e-12)
    np.testing.assert_allclose(zd - true_B(zd) / 2, q, atol=1e-12)
    assert np.all(zu <= zd)


def test_z_up_down_on_repeated_encoder_counts_equal_the_solve_of_every_sample(monkeypatch):
    # An encoder's q repeats its counts (1 um steps): z_up / z_down bisect its distinct values
    # only (model._on_distinct) and scatter them back, bit for bit the solve of every sample.
    q = np.round(np.sin(np.linspace(0, 40, 20000)) * 4.0, 3)
    assert np.unique(q).size < q.size // 2  # the distinct-value path is taken
    fast = [model.z_up(q, true_B), model.z_down(q, true_B)]
    monkeypatch.setattr(model, "_on_distinct", lambda v, solve: solve(v))
    assert np.array_equal(fast[0], model.z_up(q, true_B)) and np.array_equal(fast[1], model.z_down(q, true_B))


def test_envelopes_are_reindexed_f_eq2():
    # eq. 2: f_{1,2}(q_off) = f(q) with q_off = q -+ B(q)/2 ; in our naming f2 = f(z_up).
    z = np.linspace(-3, 3, 50)
    f2, f1 = model.envelopes(z + true_B(z) / 2, true_B, true_f)
    np.testing.assert_allclose(f2, true_f(z), atol=1e-10)
    f2, f1 = model.envelopes(z - true_B(z) / 2, true_B, true_f)
    np.testing.assert_allclose(f1, true_f(z), atol=1e-10)


def test_play_operator_matches_eq3_casewise():
    """Eq. 3 as written in c-space (valid for increasing f) gives the same c[k]."""
    rng = np.random.default_rng(1)
    q = np.cumsum(rng.normal(0, 0.05, 3000))
    c = model.direct_model(q, true_B, true_f)
    f2, f1 = model.envelopes(q, true_B, true_f)
    ref = np.empty_like(q)
    prev = true_f(q[:1])[0]
    for k in range(q.size):
        # c stays unless it falls outside the band [f2, f1] (f2 <= f1 for increasing f).
        if prev < f2[k]:
            prev = f2[k]
        elif prev > f1[k]:
            prev = f1[k]
        ref[k] = prev
    np.testing.assert_allclose(c, ref, atol=1e-9)


def test_constant_play_dead_band_width():
    """After a reversal, c does not move for exactly B of actuator travel."""
    B = model.constant(0.6)
    q = np.concatenate([np.linspace(0, 2, 201), np.linspace(2, 0, 201)[1:]])
    c = model.direct_model(q, B, lambda x: 10 * x)
    moving_down = np.nonzero(np.abs(np.diff(c[200:])) > 1e-12)[0]
    q_first = q[200 + moving_down[0] + 1]
    assert 2 - q_first == pytest.approx(0.6, abs=0.011)


def test_compensator_inverts_direct_model():
    """Play operator fed with q* from eq. 4/5 tracks c* after the first direction is known."""
    t = np.linspace(0, 20, 4001)
    c_ref = 10 * np.sin(2 * np.pi * t / 5) + 2
    f = lambda q: model.f_coarse(q, ROBOT.q_per_rad)
    f_inv = lambda c: model.f_coarse_inv(c, ROBOT.q_per_rad)
    q_star = model.compensator(c_ref, true_B, f_inv, +1)
    c = model.direct_model(q_star, true_B, f, z0=f_inv(c_ref[0]))
    assert np.max(np.abs(c[10:] - c_ref[10:])) < 1e-6
    # Without compensation the error is of the order of the play.
    c_nc = model.direct_model(f_inv(c_ref), true_B, f)
    assert np.max(np.abs(c_nc - c_ref)) > 1.0


def test_compensator_decreasing_f_uses_eq9_signs():
    f = lambda q: -8.0 * q
    f_inv = lambda c: -c / 8.0
    c_ref = 5 * np.sin(np.linspace(0, 6 * np.pi, 2000))
    q_star = model.compensator(c_ref, true_B, f_inv, -1)
    c = model.direct_model(q_star, true_B, f, z0=0.0)
    assert np.max(np.abs(c[5:] - c_ref[5:])) < 1e-6
    # eq. 9: c* increasing -> q* = f^-1(c*) - B/2
    k = 10
    assert c_ref[k] > c_ref[k - 1]
    assert q_star[k] == pytest.approx(f_inv(c_ref[k]) - true_B(f_inv(c_ref[k])) / 2)


def test_compensator_holds_direction_when_still():
    c_ref = np.array([0, 1, 2, 2, 2, 1, 1, 0.0])
    B = model.constant(1.0)
    q = model.compensator(c_ref, B, lambda c: c, +1)
    np.testing.assert_allclose(q, [0, 1.5, 2.5, 2.5, 2.5, 0.5, 0.5, -0.5])


def test_constant_curvature_geometry():
    L, l = 20.0, 5.0
    P = model.constant_curvature(np.array([0.0, 90.0, -90.0]), L, l)
    np.testing.assert_allclose(P[0], [0, 0, L + l], atol=1e-12)
    r = L / (np.pi / 2)
    np.testing.assert_allclose(P[1], [r + l, 0, r], atol=1e-12)
    np.testing.assert_allclose(P[2], [-(r + l), 0, r], atol=1e-12)
    # Smooth through the straight pose (series branch vs exact branch).
    a = model.constant_curvature(np.array([0.9e-4 * 180 / np.pi, 1.1e-4 * 180 / np.pi]), L, l)
    assert np.all(np.isfinite(a))
    assert a[1, 0] > a[0, 0]


def test_project_matches_opencv():
    cam, he = image_model_parts()
    P = model.constant_curvature(np.linspace(-60, 60, 25), ROBOT.bend_length_mm, ROBOT.tip_length_mm)
    ours = model.project(P, he.R, he.t_mm, cam.K, cam.dist)
    rvec, _ = cv2.Rodrigues(he.R)
    ref, _ = cv2.projectPoints(P.reshape(-1, 1, 3), rvec, he.t_mm, cam.K, cam.dist)
    np.testing.assert_allclose(ours, ref.reshape(-1, 2), atol=1e-9)


def test_lm_recovers_c_eq8():
    from scipy.optimize import least_squares

    cam, he = image_model_parts()
    im = model.ImageModel(ROBOT, cam, he)
    c_true = np.linspace(-50, 50, 41)
    Q = im(c_true) + np.random.default_rng(0).normal(0, 0.1, (41, 2))
    Q[3] = np.nan
    c, res = im.estimate_c(Q, c_true + 5.0)
    assert np.isnan(c[3])
    ok = ~np.isnan(c)
    # Same optimum as SciPy's MINPACK LM on each frame independently.
    for k in np.nonzero(ok)[0][::8]:
        sol = least_squares(lambda x: (Q[k] - im(x[0])), [c_true[k] + 5.0], method="lm", xtol=1e-14)
        assert c[k] == pytest.approx(sol.x[0], abs=1e-6)
    assert np.max(np.abs(c[ok] - c_true[ok])) < 0.5


def test_jacobian_is_derivative_eq7():
    cam, he = image_model_parts()
    im = model.ImageModel(ROBOT, cam, he)
    c = np.array([-20.0, 0.0, 33.0])
    h = 1e-3
    fd = (im(c + h) - im(c - h)) / (2 * h)
    np.testing.assert_allclose(im.jacobian(c), fd, rtol=1e-5, atol=1e-6)


def test_held_direction_holds_the_last_move():
    """model.held_direction, the direction hold of eq. 4 (third case) shared by the compensator,
    the simulator and the diagnosis: worked by hand."""
    from playscope.fit.model import held_direction

    x = np.array([0.0, 0.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.52, 2.0])
    assert held_direction(x).tolist() == [1, 1, 1, 1, -1, -1, -1, 1, 1]
    assert held_direction(x, before=0.0).tolist() == [0, 0, 1, 1, -1, -1, -1, 1, 1]
    # a change of 0.02 within tol 0.05 is no move: the down direction is held through it
    assert held_direction(x, tol=0.05).tolist() == [1, 1, 1, 1, -1, -1, -1, -1, 1]
