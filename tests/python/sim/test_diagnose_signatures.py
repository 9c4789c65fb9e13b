"""Each signature test keeps its effect on a synthetic record that has it and refuses the look-alike
that the margin alone would let through (diagnose/signatures.py)."""

from __future__ import annotations

import numpy as np
import pytest

from playscope.diagnose.fitmodel import INTERNAL_HZ, Data, Model
from playscope.fit.model import play_edges as _play
from playscope.diagnose.signatures import signature
from playscope.fit.model import held_direction

B_MM = 0.4      # play width
G_DEG = 12.0    # deg per mm of play output
NOISE = 0.03    # deg


def _drive(duration_s=90.0, seed=0):
    """q (mm) on the internal grid: back and forth with a speed that changes leg by leg
    (0.6-4 mm/s), so a delay and a speed-dependent lag differ."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / INTERNAL_HZ)
    q = np.empty_like(t)
    x, d, v = 0.0, 1.0, 1.0
    for k in range(t.size):
        x += d * v / INTERNAL_HZ
        if abs(x) >= 1.5:
            x = np.clip(x, -1.5, 1.5)
            d = -d
            v = float(np.exp(rng.uniform(np.log(0.6), np.log(4.0))))
        q[k] = x
    return t, q


def _record(t, q, extra_band=None, delay_s=0.0, add=None, seed=1):
    """Data of a play of width B_MM (extra half-width extra_band(speed) mm when given), c = G_DEG z,
    read delay_s late at 40 Hz with NOISE, plus add(t_m, z_m, q_m) deg."""
    v = np.abs(np.gradient(q, t))
    w = B_MM / 2 + (extra_band(v) if extra_band else 0.0)
    z = _play(q - w, q + w, q[0])
    tm = np.arange(t[0] + 0.5, t[-1] - 0.5, 1 / 40.0)
    c = G_DEG * np.interp(tm - delay_s, t, z)
    if add is not None:
        c = c + add(tm, np.interp(tm, t, z), np.interp(tm, t, q), t, z, q)
    rng = np.random.default_rng(seed)
    return Data(t, q, tm, c + rng.normal(0, NOISE, tm.size))


def _kept(data, effect):
    """Fit the base and base + effect on the first half; signature judged on the second."""
    half = data.t_m < data.t_m[0] + 0.5 * (data.t_m[-1] - data.t_m[0])
    before = Model(data).fit(half)
    m = Model(data, [effect])
    f = m.fit(half)
    assert f.rmse(data.y_m, ~half) < before.rmse(data.y_m, ~half)  # the margin would consider it
    return signature(effect, m, f, before, half, ~half)


def test_delay_signature_keeps_a_delay_and_refuses_a_lag_growing_with_sqrt_speed():
    t, q = _drive()
    pos = _kept(_record(t, q, delay_s=0.08), "camera_delay")
    assert pos["present"], pos
    assert abs(pos["delay_s"] - 0.08) < 0.01
    neg = _kept(_record(t, q, extra_band=lambda v: 0.12 * np.sqrt(v)), "camera_delay")
    assert not neg["present"], neg
    # the slow legs lag longer than the fast ones (a lag of 0.12 sqrt(v) mm is 0.12 / sqrt(v) s)
    assert neg["delay_slow_s"] > neg["delay_fast_s"]


def test_drift_signature_keeps_a_smooth_trend_and_refuses_lasting_jumps():
    t, q = _drive()
    pos = _kept(_record(t, q, add=lambda tm, *_: 1.0 * (tm - tm[0]) / 60.0), "drift")
    assert pos["present"], pos

    def slips(tm, *_):
        # the same net 1.5 deg over the record, in three jumps of 0.5 deg
        return 0.5 * ((tm > 20.0).astype(float) + (tm > 47.0) + (tm > 71.0))
    neg = _kept(_record(t, q, add=slips), "drift")
    assert not neg["present"], neg


@pytest.mark.parametrize("follows, present", [("tip", True), ("actuator", False)])
def test_handeye_signature_needs_the_offset_to_follow_the_tip_not_the_actuator(follows, present):
    t, q = _drive()

    def offset(tm, zm, qm, t_i, z_i, q_i):
        x = z_i if follows == "tip" else q_i
        s = held_direction(x, 1e-9)
        return 1.2 * np.interp(tm, t_i, s)
    g = _kept(_record(t, q, add=offset), "handeye_direction")
    assert g["present"] is present, g


def test_a_refused_effect_leaves_the_verdict_unexplained_and_is_the_hint():
    from playscope.diagnose.attribute import attribute, halves
    t, q = _drive()
    cands = ("drift", "camera_delay")
    smooth = _record(t, q, add=lambda tm, *_: 1.0 * (tm - tm[0]) / 60.0)
    res = attribute(smooth, *halves(smooth), candidates=cands)
    assert res["verdict"] == "drift" and res["refused"] == []
    jumps = _record(t, q, add=lambda tm, *_: 0.5 * ((tm > 20.0).astype(float) + (tm > 47.0) + (tm > 71.0)))
    res = attribute(jumps, *halves(jumps), candidates=cands)
    assert [z["effect"] for z in res["refused"]] == ["drift"] and res["kept"] == []
    assert res["verdict"] == "unexplained" and res["hint"]["effect"] == "drift"


def _pi_record(t, q, spread=0.8, seed=1):
    """A smooth transition: the mean of 9 plays of widths B_MM (1 - spread ... 1 + spread)
    (Prandtl-Ishlinskii), c = G_DEG times it, read at 40 Hz with NOISE."""
    z = np.mean([_play(q - r * B_MM / 2, q + r * B_MM / 2, q[0]) for r in np.linspace(1 - spread, 1 + spread, 9)], axis=0)
    tm = np.arange(t[0] + 0.5, t[-1] - 0.5, 1 / 40.0)
    rng = np.random.default_rng(seed)
    return Data(t, q, tm, G_DEG * np.interp(tm, t, z) + rng.normal(0, NOISE, tm.size))


def test_handeye_signature_refuses_a_smooth_transition():
    # the soft switch of the hand-eye term, against the motion and over about a play's width,
    # takes up a transition's slow engagement; that is a lag, not a registration error
    t, q = _drive()
    g = _kept(_pi_record(t, q), "handeye_direction")
    assert g["lags_motion"] and g["switch_travel_mm"] > 0.3 * g["play_width_mm"], g
    assert g["gradual_lag"] and not g["present"], g


@pytest.mark.parametrize("form", ["against_motion", "drag"])
def test_handeye_signature_keeps_registration_offsets_of_either_sign_and_a_dragged_one(form):
    # an offset against the motion that switches at once (a registration tilted the other way),
    # and one dragged along with the motion over 2 deg of c (the instrument in its channel)
    t, q = _drive()

    def offset(tm, zm, qm, t_i, z_i, q_i):
        if form == "against_motion":
            return -1.2 * np.interp(tm, t_i, held_direction(z_i, 1e-9))
        c = G_DEG * z_i
        o = np.empty(c.size)
        acc = 0.0
        for k, dc in enumerate(np.diff(c, prepend=c[:1]).tolist()):
            acc = min(max(acc + 0.5 * dc, -1.0), 1.0)
            o[k] = acc
        return np.interp(tm, t_i, o)
    g = _kept(_record(t, q, add=offset), "handeye_direction")
    assert g["present"], g
    assert g["lags_motion"] is (form == "against_motion"), g
