"""Each library effect leaves the signature docs/simulator.md gives it (short simulations)."""

from __future__ import annotations

import numpy as np
import pytest

from playscope.fit import model as M
from playscope.sim.core import observe_image, preset, simulate, tip_position
from playscope.sim.effects import EFFECTS, EffectSet, parse_effect

SHORT = {"kind": "excitation", "q_lo": -3.0, "q_hi": 3.0, "amp": 1.4, "speed": 0.8, "duration_s": 30.0, "cycles": 1}


def sim(effects=None, **kw):
    cfg = preset("ideal", trajectory=dict(SHORT), effects=effects or {}, **kw)
    return cfg, simulate(cfg)


def test_every_effect_documented_and_off_by_default():
    for e in EFFECTS.values():
        assert e.signature and e.params and 1 <= len(e.params) <= 3
        assert not EffectSet({}).active(e.name)
    assert parse_effect("drift:rate_deg_per_min=2")[1]["rate_deg_per_min"] == 2.0
    with pytest.raises(ValueError):
        parse_effect("no_such_effect")


def test_camera_delay_residual_proportional_to_speed():
    cfg, s0 = sim(distal_kind="angle", angle_noise_deg=0.0)
    _, s1 = sim({"camera_delay": {"delay_s": 0.1}}, distal_kind="angle", angle_noise_deg=0.0)
    t = s1.distal["t_s"]
    r = s1.distal["c_deg"] - s0.distal["c_deg"]
    v = np.gradient(s0.distal["c_deg"], t)
    slope = np.sum(r * v) / np.sum(v * v)
    assert slope == pytest.approx(-0.1, rel=0.1)  # r = -delay * dc/dt


def test_handeye_direction_jumps_with_distal_direction():
    cfg, s0 = sim(marker_noise_px=0.0)
    _, s1 = sim({"handeye_direction": {"delta_deg": 1.5}}, marker_noise_px=0.0)
    du = s1.marker["u_px"] - s0.marker["u_px"]
    tc = s0.marker["t_s"] - cfg.t_delay_s
    d = np.sign(np.interp(tc, s0.truth["t_s"], s0.truth["dir"]))
    ok = np.isfinite(du)
    # The offset has one sign per direction of distal motion, several px (f * 1.5 deg ~ 10 px).
    assert np.all(np.sign(du[ok & (d > 0)]) == np.sign(np.median(du[ok & (d > 0)])))
    assert np.median(du[ok & (d > 0)]) * np.median(du[ok & (d < 0)]) < 0
    assert np.median(np.abs(du[ok])) > 5


def test_drift_is_a_trend_in_time():
    _, s0 = sim()
    _, s1 = sim({"drift": {"rate_deg_per_min": 3.0}})
    r = s1.truth["c_deg"] - s0.truth["c_deg"]
    assert np.allclose(r, 3.0 * s1.truth["t_s"] / 60.0)


def test_smooth_transition_moves_before_the_nominal_onset():
    _, s0 = sim()
    _, s1 = sim({"smooth_transition": {"spread": 0.6}})
    q = s0.encoder["q"]
    # Travel after each reversal before the tip moves: shorter with the smooth transition.
    def dead_travel(c):
        mv = np.nonzero(np.diff(q))[0]  # moving samples; a reversal is a sign change between two of them
        dq = np.sign(np.diff(q)[mv])
        rev = mv[np.nonzero(dq[1:] * dq[:-1] < 0)[0] + 1]
        out = []
        for k in rev[1:-1]:
            m = np.nonzero(np.abs(c[k:] - c[k]) > 1e-6)[0]
            if m.size:
                out.append(abs(q[k + m[0]] - q[k]))
        return np.median(out)
    assert dead_travel(s1.truth["c_deg"]) < 0.6 * dead_travel(s0.truth["c_deg"])
    # ... and the same envelope far from reversals (mean width unchanged).
    assert abs(np.median(s1.truth["c_deg"] - s0.truth["c_deg"])) < 0.5


def test_stick_slip_moves_in_steps():
    _, s = sim({"stick_slip": {"step_deg": 1.0}})
    c = s.truth["c_deg"]
    jumps = np.abs(np.diff(c))
    jumps = jumps[jumps > 1e-9]
    assert jumps.min() >= 1.0 - 1e-9
    assert np.max(np.abs(c - s.truth["c_elastic_deg"])) <= 1.0 + 1e-9


def test_dead_zone_flat_near_c0():
    _, s0 = sim()
    _, s1 = sim({"dead_zone": {"width_deg": 5.0, "c0_deg": 0.0}})
    c0, c1 = s0.truth["c_deg"], s1.truth["c_deg"]
    inside = np.abs(c0) < 5.0
    assert np.allclose(c1[inside], 0.0)
    assert np.allclose(np.abs(c0[~inside]) - np.abs(c1[~inside]), 5.0)


def test_cable_elongation_creeps_after_stops():
    _, s = sim({"cable_elongation": {"kappa": 0.5, "tau_s": 1.0}})
    q, c = s.encoder["q"], s.truth["c_deg"]
    still = np.r_[False, np.diff(q) == 0]
    # While the motor holds at a turn the tip still moves (it would not under pure play).
    assert np.max(np.abs(np.diff(c)[still[1:]])) > 1e-4
    _, s0 = sim()
    assert np.max(np.abs(np.diff(s0.truth["c_deg"])[still[1:]])) < 1e-12


def test_asymmetric_backlash_shifts_the_centre_line():
    _, s0 = sim()
    _, s1 = sim({"asymmetric_backlash": {"alpha": 0.5}})
    z0, z1 = s0.truth["z_mm"], s1.truth["z_mm"]
    B = s0.truth["B_mm"]
    moving = np.abs(np.gradient(z0)) > 0
    # On the envelopes the play centre lags by (1 + alpha) B/2 going up and leads by (1 - alpha) B/2 going down:
    # a shift of -alpha B/2 in both directions.
    shift = (z1 - z0)[moving & (np.abs(np.gradient(z1)) > 0)]
    assert np.median(shift) == pytest.approx(-0.5 * np.median(B) * 0.5, rel=0.3)


def test_image_only_effects_leave_the_cc_path():
    cfg = preset("ideal")
    c = np.linspace(-50, 50, 21)
    P0 = tip_position(c, cfg.bend_length_mm, cfg.tip_length_mm)
    P1 = tip_position(c, cfg.bend_length_mm, cfg.tip_length_mm, gamma=0.5)
    assert np.allclose(tip_position(c, 20, 5, 1e-12), P0, atol=1e-5)  # integration matches g
    assert np.max(np.linalg.norm(P1 - P0, axis=1)) > 0.5
    assert np.linalg.norm(P1[10] - P0[10]) < 1e-9  # straight pose unaffected
    K, R, t = np.array(cfg.K), np.array(cfg.R), np.array(cfg.t_mm)
    Q0 = M.project(P0, R, t, K, np.array(cfg.dist))
    d = np.array(cfg.dist); d[0] -= 0.2
    Q1 = M.project(P0, R, t, K, d)
    r = np.linalg.norm(Q0 - K[:2, 2], axis=1)
    err = np.linalg.norm(Q1 - Q0, axis=1)
    assert np.corrcoef(r, err)[0, 1] > 0.9  # lens error grows with the radius
