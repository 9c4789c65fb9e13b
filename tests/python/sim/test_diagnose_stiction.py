"""The diagnosis' stick-slip model (Karnopp carrier in the transmission, fitmodel._karnopp_carrier)
recovers a stick-slip planted by a generator written here, apart from it: a carrier of unit mass on
a spring behind a pure play, Coulomb friction with a stuck flag (sticks when its velocity changes
sign under the static force), integrated at 20 kHz by explicit Euler on the relative coordinate."""

from __future__ import annotations

import numpy as np

from playscope.diagnose.fitmodel import INTERNAL_HZ, Data, Model

RATE = 20000.0
PLAY = 0.3          # mm, width of the play
GAIN = 20.0         # deg per mm of carrier
TRUE = {"static_q": 0.04, "kin_ratio": 0.4, "fn": 40.0, "zeta": 0.7}


def _plant(duration=40.0, seed=5, noise=0.02, truth=False):
    """q: legs of +-0.8 mm at 0.6 mm/s around a centre ramping over [-1, 1] mm; z = play of width
    PLAY; carrier e = z - p, e'' via the spring, damping and friction; c = GAIN p + noise at 50 Hz."""
    n = int(duration * RATE)
    t = np.arange(n) / RATE
    centre = np.interp(t, [0, duration / 2, duration], [-1.0, 1.0, -1.0])
    ph = (t * 0.6 / 1.6) % 2.0
    q = centre + 0.8 * (2 * np.abs(ph - 1.0) - 1.0)
    z = np.empty(n)
    zz = q[0]
    for k, v in enumerate(q.tolist()):
        zz = min(max(zz, v - PLAY / 2), v + PLAY / 2)
        z[k] = zz
    wn = 2 * np.pi * TRUE["fn"]
    fs, fc = wn * wn * TRUE["static_q"], wn * wn * TRUE["static_q"] * TRUE["kin_ratio"]
    p, v, stuck = z[0], 0.0, True
    h = 1.0 / RATE
    out = np.empty(n)
    for k, zk in enumerate(z.tolist()):
        spring = wn * wn * (zk - p)
        if stuck and abs(spring) > fs:
            stuck = False
        if not stuck:
            dirn = np.sign(v) if v != 0.0 else np.sign(spring)
            acc = spring - 2 * TRUE["zeta"] * wn * v - fc * dirn
            nv = v + h * acc
            if v != 0.0 and nv * v < 0.0 and abs(spring) <= fs:
                nv, stuck = 0.0, True
            v = nv
            p += h * v
        out[k] = p
    rng = np.random.default_rng(seed)
    step = int(RATE / 50)
    tm = t[::step] + 0.5 / 50
    clean = np.interp(tm, t, GAIN * out)
    c = clean + rng.normal(0, noise, tm.size)
    t_int = np.arange(t[0], t[-1], 1.0 / INTERNAL_HZ)
    d = Data(t_int, np.interp(t_int, t, q), tm, c)
    return (d, noise, clean) if truth else (d, noise)


def _at(m, theta, **kw):
    th = theta.copy()
    for k, v in kw.items():
        th[m.names.index("stick_slip." + k)] = v
    return th


def test_karnopp_model_recovers_a_planted_stick_slip_from_near_it():
    # A fast, well-damped slip (40 Hz, zeta 0.7; breakaway 0.04 mm, kinetic 0.4 of it) behind a
    # play. Started within 5 % of the planted friction (B and f_remain from the base fit),
    # least_squares follows the staircase: RMSE on the fit rows 0.0275 deg against 0.020 deg of
    # noise (the play alone: 0.058). The friction parameters trade off against each other (the
    # slips' size and phase are what the record shows): measured static 0.028 mm, kinetic ratio
    # 0.22, fn 23 Hz, zeta 0.91 -- so the test asks for the staircase, not the four numbers:
    # the prediction against the planted noise-free reading within 0.05 deg (measured 0.020; the
    # play alone 0.055), and the breakaway lag within 40 % (measured 29 %).
    d, noise, clean = _plant(truth=True)
    fit_rows = d.t_m < 30.0
    base = Model(d).fit(fit_rows)
    m = Model(d, ["stick_slip"])
    th0 = m.init.copy()
    th0[: base.theta.size] = base.theta
    th0 = _at(m, th0, static_q=1.05 * TRUE["static_q"], kin_ratio=0.95 * TRUE["kin_ratio"],
              log_fn=np.log(0.97 * TRUE["fn"]), zeta=1.05 * TRUE["zeta"])
    f = m.fit(fit_rows, th0, grid=False)
    p = {k.split(".")[1]: v[0] for k, v in f.params().items() if k.startswith("stick_slip.")}
    e = float(np.sqrt(np.mean((f.pred - clean)[fit_rows] ** 2)))
    e0 = float(np.sqrt(np.mean((base.pred - clean)[fit_rows] ** 2)))
    assert e < 0.05 and e < 0.5 * e0
    assert abs(p["static_q"] / TRUE["static_q"] - 1) < 0.4


def test_karnopp_carrier_sticks_then_slips_and_nests_the_play():
    from playscope.diagnose.fitmodel import _karnopp_carrier
    z = np.r_[np.zeros(10), np.linspace(0, 1.0, 200)]
    p = _karnopp_carrier(z, INTERNAL_HZ, 0.1, 0.3, 20.0, 0.3)
    assert np.all(p[:20] == 0.0)                 # held while the spring stretches under 0.1 mm
    assert np.max(z - p) <= 0.1 + 0.05           # never far beyond the breakaway lag
    assert len(np.unique(np.round(p, 9))) > 5    # it slips, more than once
    # no friction, stiff well-damped carrier: follows z within a few ms of lag
    p0 = _karnopp_carrier(z, INTERNAL_HZ, 0.0, 0.5, 60.0, 1.0)
    assert np.max(np.abs(p0 - z)) < 0.03


def _legs(rate_hz=50.0, duration_s=120.0, speed=0.8, amp=1.4, hold_s=0.3):
    """Back-and-forth legs of amp mm at speed mm/s with holds at the turns: (t (N,) s, q (N,) mm,
    direction (N,) +-1 of the motion, held)."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    q, d, pos, hold = np.empty(t.size), 1.0, 0.0, 0.0
    dirs = np.empty(t.size)
    for k in range(t.size):
        if hold > 0:
            hold -= 1.0 / rate_hz
        else:
            pos += d * speed / rate_hz
            if d * pos >= amp / 2:
                d, hold = -d, hold_s
        q[k], dirs[k] = pos, d
    return t, q, dirs


def test_signature_needs_slips_along_the_legs_not_at_the_reversals():
    """Residual increments skewed towards the motion all along each leg (slow drift against the
    motion, quick slips with it, 6 a second) carry the stick-slip signature; the same skew put
    only at the reversals -- a +-1.5 deg offset that flips with the direction, or a ringing rung at
    each reversal -- is reported at_reversals_only, not present."""
    from types import SimpleNamespace

    from playscope.diagnose.attribute import stick_slip_signature
    from playscope.diagnose.fitmodel import Data

    from playscope.fit.model import held_direction, play_on_edges

    t, q, _ = _legs()
    # the bend follows a play of 0.3 mm: the distal motion reverses after the dead travel, while q moves
    pred = 10.0 * play_on_edges(q - 0.15, q + 0.15, q[0])
    dirs = held_direction(pred, 1e-9)
    noise = np.random.default_rng(0).normal(0, 0.02, t.size)
    mask = t > 60.0
    slips = dirs * 0.3 * (1.0 - (t * 6.0) % 1.0)          # sawtooth: drift against, slip with the motion
    flip = 1.5 * dirs                                       # offset flipping with the distal direction
    since = t - t[np.maximum.accumulate(np.where(np.r_[True, np.diff(dirs) != 0], np.arange(t.size), 0))]
    ring = dirs * 1.0 * np.exp(-since / 0.4) * np.sin(2 * np.pi * 3.0 * since) * (since < 3.0)
    out = {}
    for name, r in (("slips", slips), ("flip", flip), ("ring", ring)):
        data = Data(t, q, t, pred + r + noise, 0.0)
        out[name] = stick_slip_signature(data, SimpleNamespace(pred=pred), mask)
    assert out["slips"]["present"] and out["slips"]["skewness_interior"] > 0.6
    assert out["flip"]["skewness"] > out["flip"]["threshold"]       # the old, phase-blind rule fired
    assert out["flip"]["at_reversals_only"] and not out["flip"]["present"]
    assert not out["ring"]["present"]
