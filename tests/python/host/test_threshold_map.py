"""B-proportional thresholds (transition.ThresholdMap, docs/method.md "B-proportional
thresholds"): the classical PI run on u = g(z), g' = b_ref / B(z), against an independent
reference written here from the definition (operators whose half width is r_i B(z) / b_ref,
run on z itself), and the model choice's offer rule."""

import numpy as np
import pytest

from playscope.fit import transition as T

RATE_HZ = 50.0


def B_lin(z):
    """Onset width growing 2x over the travel 0..4 (actuator units)."""
    return 0.3 + 0.075 * np.asarray(z, float)


def ref_scaled_play(z, r, b_ref, B, start):
    """Play of half width r B(z) / b_ref on z, scalar loop (the definition, not the map)."""
    out, p = [], start
    for v in z:
        h = r * float(B(v)) / b_ref
        p = min(v + h, max(v - h, p))
        out.append(p)
    return np.array(out)


def path(seed=0, n=4000):
    t = np.arange(n) / RATE_HZ
    z = 2.0 + 1.6 * np.sin(2 * np.pi * t / 17) + 0.3 * np.sin(2 * np.pi * t / 2.1 + seed)
    return t, z


def test_map_slope_is_b_ref_over_B_and_identity_for_a_constant_B():
    tm = T.ThresholdMap.from_backlash(B_lin, 0.0, 4.0)
    b_ref = float(np.median(B_lin(np.linspace(0, 4, T.MAP_POINTS))))
    mid = 0.5 * (tm.z[1:] + tm.z[:-1])
    slope = np.diff(tm.u) / np.diff(tm.z)
    # Trapezoid of a smooth integrand: the secant slope is the mean of the end slopes, within
    # (h^2 / 8) max|s''| of the midpoint value, s = b_ref / B, s'' = 2 b_ref B'^2 / B^3
    # (measured 2.26e-5 against the bound 2.29e-5).
    h = tm.z[1] - tm.z[0]
    bound = h * h / 8 * 2 * b_ref * 0.075 ** 2 / 0.3 ** 3
    assert np.max(np.abs(slope - b_ref / B_lin(mid))) <= 1.01 * bound
    assert np.allclose(tm.inv(tm.fwd(np.linspace(-1, 5, 101))), np.linspace(-1, 5, 101), atol=1e-12)
    flat = T.ThresholdMap.from_backlash(lambda z: np.full(np.shape(z), 0.4), -1.0, 3.0)
    x = np.linspace(-2, 4, 37)  # linear ends beyond the grid too
    assert np.allclose(flat.fwd(x), x, atol=1e-12)


def test_direct_model_matches_position_dependent_thresholds_to_second_order():
    _, z = path()
    tm = T.ThresholdMap.from_backlash(B_lin, -1.0, 5.0)
    b_ref = float(np.median(B_lin(np.linspace(-1, 5, T.MAP_POINTS))))
    errs = []
    for r in (0.1, 0.2, 0.4):
        u_ops = T.play_ops(tm.fwd(z), np.array([r]))[:, 0]
        ref = ref_scaled_play(z, r, b_ref, B_lin, z[0])
        errs.append(np.max(np.abs(tm.inv(u_ops) - ref)))
    # The map equals the definition to first order in r B'/B: the error grows as r^2
    # (measured 1.1e-3, 4.4e-3, 1.7e-2 for r = 0.1, 0.2, 0.4, against half widths up to 0.13,
    # 0.26, 0.53: 0.8 %, 1.7 %, 3.3 %).
    widest = 0.4 * float(np.max(B_lin(z))) / b_ref
    assert errs[2] < 0.05 * widest
    assert 3.0 < errs[2] / errs[1] < 5.0 and 3.0 < errs[1] / errs[0] < 5.0


def test_inverse_with_a_map_undoes_the_direct_model():
    _, z = path(1)
    tm = T.ThresholdMap.from_backlash(B_lin, -1.0, 5.0)
    tr = T.Transition(T.thresholds(8, 1.2), np.array([0.3, 0.1, 0.0, 0.2, 0.1, 0.1, 0.1, 0.1]), 1.0, tm)
    z_back = tr.inverse(tr.direct(z))
    # Exact PI inverse (Krejci & Kuhnen 2001) then g^-1 of the same piecewise-linear g:
    # float64 rounding only (measured 9e-16).
    assert np.max(np.abs(z_back - z)) < 1e-12


def test_transition_json_round_trip_keeps_the_map():
    tm = T.ThresholdMap.from_backlash(B_lin, 0.0, 4.0)
    tr = T.Transition(T.thresholds(4, 1.0), np.array([0.4, 0.2, 0.2, 0.2]), 0.5, tm)
    back = T.Transition.from_json(tr.to_json())
    assert np.array_equal(back.tmap.u, tm.u) and back.b_scale == 0.5
    assert T.Transition.from_json(T.Transition.play().to_json()).tmap is None


def test_map_refuses_a_non_positive_width():
    with pytest.raises(ValueError):
        T.ThresholdMap.from_backlash(lambda z: np.zeros(np.shape(z)), 0.0, 1.0)
    with pytest.raises(ValueError):
        T.ThresholdMap(np.array([0.0, 1.0, 1.0]), np.array([0.0, 1.0, 2.0]))


def test_offer_rule_needs_two_onset_samples_per_B_control_point():
    assert T.threshold_kinds("spline", 28, 14) == T.BOTH_KINDS
    assert T.threshold_kinds("spline", 27, 14) == T.CONSTANT_ONLY
    assert T.threshold_kinds("spline", 6, 6) == T.CONSTANT_ONLY  # N = M: B interpolates its samples
    assert T.threshold_kinds("constant", 100, 4) == T.CONSTANT_ONLY


def session(scaled: bool, seed: int = 0, B=B_lin):
    """A fit record whose transition has thresholds proportional to B (scaled) or constant,
    written here with the reference loop: c = f(sum_i w_i P_i(play_{B/2}(q)))."""
    t = np.arange(0, 80, 1 / RATE_HZ)
    q = 2.0 + 1.6 * np.sin(2 * np.pi * t / 17) + 0.9 * np.sin(2 * np.pi * t / 5.3 + 1) + 0.3 * np.sin(2 * np.pi * t / 2.1)
    z, p = [], q[0]
    for v in q:  # play of width B(z): z + B(z)/2 >= v >= z - B(z)/2, solved by fixed point (B' small)
        for _ in range(20):
            p_new = min(v + B(p) / 2, max(v - B(p) / 2, p))
            if abs(p_new - p) < 1e-13:
                break
            p = p_new
        z.append(p)
    z = np.array(z)
    b_ref = 0.45
    r = np.array([0.0, 0.15, 0.3, 0.45])
    w = np.array([0.3, 0.3, 0.2, 0.2])
    if scaled:
        y = sum(wi * ref_scaled_play(z, ri, b_ref, B, z[0]) for ri, wi in zip(r, w))
    else:
        y = sum(wi * ref_scaled_play(z, ri, 1.0, lambda v: 1.0, z[0]) for ri, wi in zip(r, w))
    c = 10.0 * y + 0.4 * y ** 2
    rng = np.random.default_rng(seed)
    k = slice(None, None, 5)
    return T.FitData(t, q, B, t[k], c[k] + rng.normal(0, 0.02, c[k].size))


@pytest.mark.parametrize("scaled", [True, False])
def test_model_choice_names_the_threshold_kind_the_data_were_made_with(scaled):
    data = session(scaled)
    _, _, _, ch = T.choose_model(data, "pi", kinds=T.BOTH_KINDS)
    assert ch["thresholds"] == ("B-proportional" if scaled else "constant"), ch["candidates"]
    assert ch["thresholds_offered"] == ["constant", "B-proportional"]
    # The picked row is found again in the stored candidates (what the summaries print).
    row = T.picked_candidate(ch)
    assert row is not None and row["scaled"] == scaled and row["n"] == ch["n_tried"]
    best = min(ch["candidates"], key=lambda c: c["cv_rmse_deg"])  # the one-SE rule's limit
    assert row["cv_rmse_deg"] <= best["cv_rmse_deg"] + best["cv_se_deg"]


def test_a_fitted_map_table_loads_when_B_varies_tenfold():
    """The thresholds of a map live in u = g(z), whose extent exceeds the travel where B is
    below b_ref: the loader bounds them by that extent (calib.c), and v_max_for_table divides
    the precision ceiling by the map's Lipschitz constant, so the fitted table loads. B here
    runs from 0.06 to 0.66 mm (11x) over the session; the fixed-point chain then stays within
    its measured 0.023 deg (direct) and 4e-6 mm (compensator) of the float chain."""
    from playscope.fit import table_build as TB

    B_steep = lambda z: 0.06 + 0.15 * np.clip(np.asarray(z, float), 0.0, 4.0)
    data = session(True, B=B_steep)
    tr, f, _, ch = T.choose_model(data, "pi", kinds=T.BOTH_KINDS)
    assert ch["thresholds"] == "B-proportional" and tr.tmap is not None
    q0, q1 = float(data.q_enc.min()), float(data.q_enc.max())
    assert tr.r[-1] > q1 - q0  # beyond the travel: refused before the loader took u's extent
    tab = TB.build_table(B_steep, f, q0, q1, "mm", transition=tr)
    err = TB.table_errors(tab, B_steep, f, q0, q1, tr)
    assert tab.has_map and err["direct_c_deg_max"] < 0.07 and err["comp_q_max"] < 1e-4
