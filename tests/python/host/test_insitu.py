"""In-situ evaluation (playscope.evaluate.insitu_split) and the textbook peers (playscope.fit.peers).

The peers are checked on data from generators written here, which share no code with the
fitters: a per-threshold play loop in plain Python for the generalized PI, and the Bouc-Wen
ODE integrated in time by scipy's solve_ivp for Bouc-Wen (the fitter integrates in q, in
closed form)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from playscope.evaluate import insitu_split as insitu
from playscope.fit.peers import BoucWen, GeneralizedPI

from .synth import angle_session


# --------------------------------------------------------------------------- generators
def excursion_path(n=6000, q_lo=0.0, q_hi=5.0):
    """Strokes from q_lo up to decreasing tops and back (like the catheter files), then
    increasing ones, sampled along a cosine profile: every threshold closes loops."""
    tops = np.r_[np.linspace(q_hi, q_lo + 0.15 * (q_hi - q_lo), 7), np.linspace(q_lo + 0.3 * (q_hi - q_lo), q_hi, 5)]
    pts = np.r_[[q_lo], np.ravel(np.column_stack([tops, np.full(tops.size, q_lo)]))]
    seg = np.linspace(0, 1, n // (pts.size - 1), endpoint=False)
    q = np.concatenate([a + (b - a) * 0.5 * (1 - np.cos(np.pi * seg)) for a, b in zip(pts[:-1], pts[1:])])
    return np.r_[q, pts[-1]]


def play_loop(q, r):
    """Classical play operator, one threshold, state centred at q[0] (Brokate & Sprekels)."""
    out, y = [], q[0]
    for x in q:
        if x - y > r:
            y = x - r
        elif y - x > r:
            y = x + r
        out.append(y)
    return np.array(out)


# --------------------------------------------------------------------------- peers
def test_gpi_recovers_planted_weights_and_polynomial():
    q = excursion_path()
    n = 16
    # The documented rule: midpoints of 16 bins of [0, E/2], E the largest stroke (here the span 5).
    r = (np.arange(n) + 0.5) / n * 0.5 * 5.0
    w = np.zeros(n)
    w[[0, 3, 7, 12]] = [4.0, 2.5, 1.5, 1.0]  # deg/mm
    cubic = np.array([30.0, 2.0, -0.4, 0.05])  # c0 + c1 q + c2 q^2 + c3 q^3, deg
    c = sum(wi * play_loop(q, ri) for wi, ri in zip(w, r)) + np.polynomial.polynomial.polyval(q, cubic)
    c = c + np.random.default_rng(1).normal(0, 0.01, q.size)
    m = GeneralizedPI.fit(q, c)
    np.testing.assert_allclose(m.r, r, rtol=1e-12)
    # Measured: max weight error 0.0018 deg/mm at 0.01 deg noise; tolerance 0.01 deg/mm.
    np.testing.assert_allclose(m.w, w, atol=0.01)
    grid = np.linspace(0, 5, 101)
    x = (grid - m.q_mid) / m.q_half
    memoryless = np.vander(x, 4, increasing=True) @ m.poly
    # Measured 0.0097 deg; tolerance 0.04 deg.
    np.testing.assert_allclose(memoryless, np.polynomial.polynomial.polyval(grid, cubic), atol=0.04)
    assert np.sqrt(np.mean((m.predict(q) - c) ** 2)) < 0.012  # noise 0.01 deg


def bouc_wen_ode(t, q_fn, dq_fn, beta, gamma):
    """h(t) with dh/dt = q' - beta |q'| h - gamma q' |h| (A = 1, n = 1), solve_ivp in time."""
    rhs = lambda tt, h: [dq_fn(tt) - beta * abs(dq_fn(tt)) * h[0] - gamma * dq_fn(tt) * abs(h[0])]
    sol = solve_ivp(rhs, (t[0], t[-1]), [0.0], t_eval=t, rtol=1e-10, atol=1e-12, max_step=0.01)
    return sol.y[0]


@pytest.mark.parametrize("beta,gamma", [(0.8, 0.3), (1.5, -0.5)])
def test_bouc_wen_recovers_planted_parameters(beta, gamma):
    # Sine sweeps of growing then shrinking amplitude around 2.5 mm: loops of every size.
    t = np.linspace(0, 60, 3001)
    amp = lambda tt: 2.5 * np.sin(np.pi * tt / 60) + 0.2
    q_fn = lambda tt: 2.5 + amp(tt) * np.sin(2 * np.pi * tt / 6)
    dq_fn = lambda tt: (2.5 * np.pi / 60 * np.cos(np.pi * tt / 60) * np.sin(2 * np.pi * tt / 6)
                        + amp(tt) * 2 * np.pi / 6 * np.cos(2 * np.pi * tt / 6))
    q = q_fn(t)
    h = bouc_wen_ode(t, q_fn, dq_fn, beta, gamma)
    a, b, d = 9.0, 6.0, 20.0
    c = a * q + b * h + d + np.random.default_rng(2).normal(0, 0.01, t.size)
    p = BoucWen.fit(q, c).params()
    # Measured: relative errors <= 0.17 % (gamma), d within 0.0011 deg, at 0.01 deg noise;
    # tolerances 1 % and 0.01 deg.
    assert p["beta_per_unit"] == pytest.approx(beta, rel=0.01)
    assert p["gamma_per_unit"] == pytest.approx(gamma, rel=0.01)
    assert p["a_deg_per_unit"] == pytest.approx(a, rel=0.01)
    assert p["b_deg_per_unit"] == pytest.approx(b, rel=0.01)
    assert p["d_deg"] == pytest.approx(d, abs=0.01)


# --------------------------------------------------------------------------- split and state
@pytest.fixture(scope="module")
def session():
    # 61 s at 100 Hz: short enough for the transition's model choice to run in a few seconds.
    return angle_session(rate_hz=100.0, q_start=-3.0, q_end=3.0, advance=0.75)


@pytest.fixture(scope="module")
def split(session):
    return insitu.split_time(session.encoder["t_s"], 0.5)


@pytest.fixture(scope="module")
def rows(session, split):
    return insitu.fit_rows(session, split)


def test_split_never_lets_test_samples_into_a_fit(session, split, rows):
    bad = copy.copy(session)
    rng = np.random.default_rng(3)
    enc, dist = dict(session.encoder), dict(session.distal)
    after_e, after_d = enc["t_s"] >= split, dist["t_s"] >= split
    enc["q"] = np.where(after_e, rng.uniform(-1e3, 1e3, after_e.size), enc["q"])  # garbage actuator
    dist["c_deg"] = np.where(after_d, np.nan, dist["c_deg"])  # and no angle at all
    bad.encoder, bad.distal, bad.truth = enc, dist, None
    poisoned = insitu.fit_rows(bad, split)
    q = session.encoder["q"]
    for name in insitu.ROWS:
        # Same fitted model: the same prediction bit for bit on the clean record.
        np.testing.assert_array_equal(poisoned[name].predict(q), rows[name].predict(q), err_msg=name)
    # ...and the poisoning does reach the samples a leaking fit would see.
    assert np.isnan(bad.distal["c_deg"][after_d]).all() and np.abs(bad.encoder["q"][after_e]).max() > 100


def test_state_carried_equals_full_run_restricted_to_test_part(session, split, rows):
    doc = insitu.evaluate_insitu(session, 0.5)
    assert doc["split"]["t_split_s"] == split
    q, t_enc = session.encoder["q"], session.encoder["t_s"]
    t_m, c_m = session.distal["t_s"], session.distal["c_deg"]
    test = t_m >= split
    gpi = doc["rows"]["gpi"]["params"]
    # Independent run of the fitted GPI over the whole record, from its first sample.
    full = sum(w * play_loop(q, r) for w, r in zip(gpi["weights_deg_per_unit"], gpi["thresholds"]))
    x = (q - gpi["q_mid"]) / gpi["q_half"]
    full = full + np.vander(x, 4, increasing=True) @ np.array(gpi["poly_deg"])
    e = np.interp(t_m[test], t_enc, full) - c_m[test]
    assert doc["rows"]["gpi"]["rmse_deg"] == pytest.approx(np.sqrt(np.mean(e * e)), rel=1e-9)
    # A board reset at the split (play state lost) scores differently, so this can fail:
    # measured 0.256 deg against 0.208 deg carried for the onset B + lsq table.
    after = t_enc >= split
    fresh = np.interp(t_m[test], t_enc[after], rows["onset_lsq"].predict(q[after])) - c_m[test]
    assert np.sqrt(np.mean(fresh**2)) > 1.1 * doc["rows"]["onset_lsq"]["rmse_deg"]
    # Every row: the score is that of its full-record run restricted to the test part.
    for name, row in rows.items():
        e = np.interp(t_m[test], t_enc, row.predict(q)) - c_m[test]
        assert doc["rows"][name]["rmse_deg"] == pytest.approx(np.sqrt(np.mean(e * e)), rel=1e-9), name
        assert doc["rows"][name]["max_deg"] == pytest.approx(np.max(np.abs(e)), rel=1e-9), name


def test_table_rows_run_the_firmware_from_the_record_start(session, split, rows):
    from playscope.fit.calibration import calibrate
    from playscope.fit.table_build import build_table

    # The row is the auto calibration's B (its stiffness chosen with the model) with the pure
    # play's f_remain, as evaluate_insitu builds it.
    cal = calibrate(session.slice_time(-np.inf, split), model_kind="auto")
    tab = build_table(cal.B, cal.f_play, *cal.q_range, "mm")
    q = session.encoder["q"]
    np.testing.assert_array_equal(rows["onset_lsq"].predict(q), tab.predict(q))
    # Ours: the table carries the chosen transition's operators (none for the pure play).
    p = rows["ours"].params
    assert p["table_ops"] == (0 if p["model"] == "play" else p["n_ops"])
    assert rows["onset_lsq"].fixed_point and rows["paper"].fixed_point and rows["ours"].fixed_point
    assert not rows["gpi"].fixed_point and not rows["bouc_wen"].fixed_point


@pytest.mark.parametrize("split,msg", [("1.5", "outside (0, 1)"), ("abc", "neither"), ("0.001", "shorter than")])
def test_bad_split_is_one_line_error(session, split, msg):
    from playscope.base.errors import InputError

    with pytest.raises(InputError, match=msg.replace("(", r"\(").replace(")", r"\)")):
        insitu.evaluate_insitu(session, split)


def test_cli_prints_table_and_writes_documented_json(tmp_path, session):
    import json

    from playscope.cli import main
    from playscope.io.session import write_session

    write_session(session, tmp_path / "s")
    assert main(["evaluate-insitu", str(tmp_path / "s"), "--split", "30s", "--json", str(tmp_path / "o.json")]) == 0
    d = json.loads((tmp_path / "o.json").read_text())
    assert d["order"] == insitu.ROWS and set(d["rows"]) == set(insitu.ROWS)
    for k in ("format", "session", "distal_kind", "judged_against", "state", "split", "notes"):
        assert k in d and k in insitu.JSON_KEYS
    assert d["split"]["t_split_s"] == pytest.approx(30.0)
    # Every candidate of the model choice is listed with why it has no CV error when it has none
    # (refused by the loader, or skipped by the one-SE shortcut), as in the calibration JSON.
    fam = d["rows"]["ours"]["params"]["family_cv"]
    assert fam and all(set(r) == {"family", "cv_rmse_deg", "refused", "skipped"} for r in fam)
    assert all(r["cv_rmse_deg"] is not None or r["refused"] or r["skipped"] for r in fam)
    assert main(["evaluate-insitu", str(tmp_path / "s"), "--split", "2"]) == 2
