"""The dead band's start is chosen after refining its own parameters (fitmodel.Model._profile_dead_zone),
and a band cannot reach past the range of what it acts on (fitmodel.Model._band): q's on the
actuator side, the play output z's on the distal side (fitmodel.Model._z_ends).

Record: the blind generator's soft distal dead zone (4 deg, rounded) of development seed 2000, the
case the self-test missed before the profiled start: the full fit then went from the lowest
unrefined start, a band at the edge of the travel that f_remain absorbs as a shift, and the test
part's RMSE against the noise-free reading stayed near the base's (0.167 against 0.174 deg with the
hard band; 0.074 with the rounded one, still from a band at the edge). With the profiled start the
band is found near straight and that RMSE is 0.023 deg (measured, rounded band).
"""

from __future__ import annotations

import numpy as np

from playscope.diagnose import fitmodel
from playscope.diagnose.fitmodel import Model, from_session
from playscope.diagnose.selftest import cases, make_session
from playscope.diagnose.split import choose_split


def _case(strength=4.0, seed=2000):
    c = next(c for c in cases("both", 4, True, seed=seed)
             if c["variant"] == "distal_side" and c["strength"] == strength)
    s = make_session(c)
    data = from_session(s)
    clean = from_session(type(s)(**{**s.__dict__, "distal": {"t_s": s.distal["t_s"],
                                                               "c_deg": s.meta["clean_reading_deg"]}}))
    return data, clean.y_m, choose_split(data)


def _test_rmse_vs_clean(fit, y_clean, test):
    e = (y_clean - fit.pred)[test & np.isfinite(y_clean)]
    return float(np.sqrt(np.mean(e * e)))


def test_distal_band_near_straight_is_found_from_the_grid(monkeypatch):
    data, y_clean, sp = _case()
    base = Model(data).fit(sp.fit, uncertainty=False)
    m = Model(data, ["dead_zone"], dead_zone_side="distal")
    th0 = m.init.copy()
    th0[: fitmodel.N_KNOTS] = base.theta[: fitmodel.N_KNOTS]
    f = m.fit(sp.fit, th0, uncertainty=False)
    z0 = f.theta[m.names.index("dead_zone.z0_q")]
    w = f.theta[m.names.index("dead_zone.w_q")]
    span = data.q_hi - data.q_lo
    # Near straight (the excitation is centred on it) and of the planted size, not at an edge.
    assert abs(z0 - 0.5 * (data.q_hi + data.q_lo)) < 0.1 * span and 0.02 * span < w < 0.08 * span
    assert _test_rmse_vs_clean(f, y_clean, sp.test) < 0.045  # measured 0.023
    # The same fit with the unrefined comparison of the starts stays on the plateau.
    monkeypatch.setattr(Model, "_profile_dead_zone", lambda self, th, mask: th)
    f0 = m.fit(sp.fit, th0, uncertainty=False)
    assert _test_rmse_vs_clean(f0, y_clean, sp.test) > 0.05  # measured 0.074


def test_a_band_cannot_reach_past_the_travel():
    data, y_clean, sp = _case(8.0)
    m = Model(data, ["dead_zone"], dead_zone_side="distal")
    th = m.init.copy()
    i_w, i_c = m.names.index("dead_zone.w_q"), m.names.index("dead_zone.z0_q")
    th[[i_w, i_c]] = 0.3, data.q_hi - 0.1
    assert np.allclose(m._band(th, m.q_range), (data.q_hi - 0.1, 0.1))
    th[[i_w, i_c]] = 0.3, data.q_hi + 0.2
    assert m._band(th, m.q_range)[1] == 0.0
    # The soft distal band of 8 deg (development seed 2000), fitted from the base model's B as
    # attribute's distal screen starts it: with the cap, near straight, test RMSE against the
    # noise-free reading 0.025 deg; without it the band goes to the top end of the travel (centre
    # 2.89 mm, past the end of z), RMSE 0.064 deg (base model 0.081; with the hard band of the
    # release before the rounded corners: 0.157). Measured.
    base = Model(data).fit(sp.fit, uncertainty=False)
    th0 = m.init.copy()
    th0[: fitmodel.N_KNOTS] = base.theta[: fitmodel.N_KNOTS]
    f = m.fit(sp.fit, th0, uncertainty=False)
    span = data.q_hi - data.q_lo
    assert abs(f.theta[i_c] - 0.5 * (data.q_hi + data.q_lo)) < 0.1 * span
    assert _test_rmse_vs_clean(f, y_clean, sp.test) < 0.04  # measured 0.025
    # (Without the cap the band went past the end of z and the test RMSE was 0.064 deg; since the
    # distal band's output is stretched back over z's range (fitmodel._distal_stretch) the uncapped
    # fit also gives 0.018 deg here, so that comparison no longer tells the cap's worth: the cap
    # stays because a band past the data has an edge no sample shows.)


def test_the_distal_band_is_capped_by_the_play_outputs_range():
    # Development seed 3400, soft distal dead zone of 8 deg. The distal band acts on z, which stops
    # about half a play short of q at each end (here z -2.54..2.70 mm against q -2.80..2.95).
    # Capped by q's range, the fit from the base model's B puts the band at z0 = 2.80 mm, past the
    # end of z, where it holds c at the top of the travel: test RMSE against the noise-free
    # reading 0.100 deg, worse than the base model's 0.090 (0.144 with the hard band). Capped by
    # z's range it finds the band near straight (z0 -0.25 mm): 0.030 deg. All measured.
    data, y_clean, sp = _case(8.0, seed=3400)
    base = Model(data).fit(sp.fit, uncertainty=False)
    m = Model(data, ["dead_zone"], dead_zone_side="distal")
    th0 = m.init.copy()
    th0[: fitmodel.N_KNOTS] = base.theta[: fitmodel.N_KNOTS]
    i_c = m.names.index("dead_zone.z0_q")
    z_lo, z_hi = m._z_ends(th0, m._play_output(th0)[0])
    assert data.q_lo < z_lo < z_hi < data.q_hi
    f = m.fit(sp.fit, th0, uncertainty=False)
    assert z_lo + 0.25 * (z_hi - z_lo) < f.theta[i_c] < z_hi - 0.25 * (z_hi - z_lo)
    assert _test_rmse_vs_clean(f, y_clean, sp.test) < 0.045  # measured 0.030 (base 0.090)
    # (Capped by q's range the band sat past the end of z, test RMSE 0.100 deg; with the distal
    # band's output stretched back over the range (fitmodel._distal_stretch) that fit gives
    # 0.026 deg too, so the comparison no longer tells the cap's worth.)


def test_rounded_band_is_the_hard_band_at_zero_corner_and_smooth_otherwise():
    u = np.linspace(-2.0, 2.0, 4001)
    w = 0.5
    hard = fitmodel._dead_band(u, w, 0.0)
    assert np.array_equal(hard, u - np.clip(u, -w, w))
    r = 0.2
    soft = fitmodel._dead_band(u, w, r)
    # Equal to the hard band outside the corners, 0 inside the band's core, odd, C1 (slope continuous).
    far = np.abs(np.abs(u) - w) >= r
    assert np.allclose(soft[far], hard[far], atol=1e-12)
    assert np.all(soft[np.abs(u) <= w - r] == 0.0)
    assert np.allclose(soft, -soft[::-1], atol=1e-12)
    slope = np.diff(soft) / np.diff(u)
    assert np.all(slope >= -1e-12) and np.all(slope <= 1 + 1e-9) and np.max(np.abs(np.diff(slope))) < 0.02
    # At an edge the rounded band sits r / 4 above the hard one (the smooth hinge's offset).
    i = np.argmin(np.abs(u - w))
    assert abs(soft[i] - r / 4) < 1e-9


def test_a_band_fitted_on_one_record_keeps_its_cap_on_another():
    # Across records (attribute.judged_rmse, the paper's protocol) the distal band's cap comes
    # from the fitted record's z, not from the record it is evaluated on: the same band.
    a, _, _ = _case(8.0, seed=2000)
    c = next(c for c in cases("both", 4, True, seed=3400) if c["variant"] == "distal_side")
    b = from_session(make_session(c, duration_s=40.0))  # a shorter record: another q range
    m = Model(a, ["dead_zone"], dead_zone_side="distal")
    th = m.init.copy()
    th[m.names.index("dead_zone.z0_q")] = 2.6
    th[m.names.index("dead_zone.w_q")] = 0.5
    own = m._z_ends(th, m._play_output(th)[0])
    mb = Model(b, m.effects, frame=m)
    zb = mb._play_output(th)[0]
    assert mb._z_ends(th, zb) == own != (float(zb.min()), float(zb.max()))
    assert m._band(th, own) == mb._band(th, mb._z_ends(th, zb)) and m._band(th, own)[1] < 0.5


def test_the_distal_bands_output_is_stretched_back_over_the_range_of_z():
    # f_remain's knots cover the range of z; the band's output, shortened by w at each end, is
    # stretched back so that the ends of z map to themselves, linearly on each side of the band,
    # and a band that takes nearly a whole side is stretched at most STRETCH_MAX times.
    lo, hi, zc, w = -2.0, 3.0, 0.5, 0.4
    z = np.linspace(lo, hi, 501)
    v = fitmodel._distal_stretch(fitmodel._dead_band(z - zc, w, 0.0), zc, w, (lo, hi))
    assert np.isclose(zc + v[0], lo) and np.isclose(zc + v[-1], hi)
    assert np.all(v[np.abs(z - zc) <= w] == 0.0) and np.all(np.diff(v) >= 0.0)
    above = z > zc + w
    assert np.allclose(np.diff(v[above]) / np.diff(z[above]), (hi - zc) / (hi - zc - w))
    v = fitmodel._distal_stretch(fitmodel._dead_band(z - zc, 2.45, 0.0), zc, 2.45, (lo, hi))
    assert np.isclose(v.max(), fitmodel.STRETCH_MAX * (hi - zc - 2.45))
