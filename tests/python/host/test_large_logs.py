"""Bounded resources for long, dense logs: session.thin_encoder keeps an encoder log denser than
ENCODER_MAX_HZ as its path at
the resolution THIN_TRAVEL_FRAC of its travel (one sample per delta of travel, every turn and
its held extremum), whatever the log's rate, and leaves a log it would not halve alone
(bench/bench_long_log.py times import, calibrate and evaluate-insitu on a 1-hour 1 kHz log)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from playscope.fit.reversals import detect_reversals
from playscope.io.session import THIN_TRAVEL_FRAC, load_session, thin_encoder, thin_record, write_session

from .synth import angle_session


def _noisy(rate_hz: float, seed: int = 3):
    """The 138-s synthetic angle session with its encoder at rate_hz, 2 um noise in 1 um counts."""
    s = angle_session()
    rng = np.random.default_rng(seed)
    t = np.arange(s.encoder["t_s"][0], s.encoder["t_s"][-1], 1 / rate_hz)
    q = np.interp(t, s.encoder["t_s"], s.encoder["q"]) + rng.normal(0, 2e-3, t.size)
    s.encoder = {"t_s": t, "q": np.round(q * 1000) / 1000}
    return s


def test_thin_rule_keeps_the_path_and_every_reversal():
    s = _noisy(2000.0)
    enc = s.encoder
    out, note = thin_encoder(enc, "e.csv")
    d = THIN_TRAVEL_FRAC * np.ptp(enc["q"])
    assert "thinned by travel" in note and f"{out['t_s'].size} of {enc['t_s'].size} rows kept" in note
    # Far fewer rows (1 per delta of travel, not per tick), every kept row a row of the log.
    assert out["t_s"].size * 10 < enc["t_s"].size
    idx = np.searchsorted(enc["t_s"], out["t_s"])
    assert np.array_equal(enc["q"][idx], out["q"])
    # The path between kept rows: within 3 delta of the line through them (the docstring's bound).
    assert np.max(np.abs(np.interp(enc["t_s"], out["t_s"], out["q"]) - enc["q"])) <= 3 * d
    # Every reversal the calibration finds (1 % hysteresis) at the same instant and q1.
    h = 0.01 * np.ptp(enc["q"])
    full, thin = detect_reversals(enc["t_s"], enc["q"], h), detect_reversals(out["t_s"], out["q"], h)
    assert full[0].size == thin[0].size > 10
    assert np.array_equal(full[0], thin[0]) and np.array_equal(full[1], thin[1])


def test_thin_rule_leaves_sparse_logs_alone():
    t = np.arange(0, 2.0, 1 / 50.0)
    enc = {"t_s": t, "q": np.sin(3 * t)}
    same, note = thin_encoder(enc, "e.csv")
    assert same is enc and note is None
    for q in (np.zeros(100), np.arange(2.0)):
        same, note = thin_encoder({"t_s": np.arange(q.size) / 1e3, "q": q}, "e.csv")
        assert note is None and same["q"] is q


def test_dense_session_loads_thinned(tmp_path):
    s = _noisy(4000.0)
    write_session(s, tmp_path / "s")
    a = load_session(tmp_path / "s")
    want, _ = thin_encoder(s.encoder, "x")
    assert a.encoder["t_s"].size == want["t_s"].size < s.encoder["t_s"].size / 10
    assert any("thinned by travel" in n for n in a.notes)


def test_thinned_log_calibrates_as_the_full_one():
    """A 2 kHz encoder log with 2 um noise in 1 um counts (the 138-s synthetic session),
    calibrated whole and thinned (session.thin_record: 4 284 of 275 996 rows). Measured here: B(q) within 0.0042 mm of
    each other, best CV RMSE of f 0.141 (whole) and 0.122 deg (thinned); the bounds are about
    three times that."""
    from playscope.fit.calibration import calibrate

    s = _noisy(2000.0)
    full = calibrate(s, model_kind="play")
    thin = thin_record(copy.copy(s), "encoder.csv")
    assert thin.encoder["t_s"].size * 10 < s.encoder["t_s"].size
    cal = calibrate(thin, model_kind="play")
    g = np.linspace(-3, 3, 13)
    assert np.max(np.abs(cal.B(g) - full.B(g))) < 0.012
    best = [min(c["cv_rmse_deg"] for c in x.doc["f_fit"]["candidates"]) for x in (full, cal)]
    assert abs(best[0] - best[1]) < 0.06


def test_an_image_sessions_dense_log_is_thinned_by_time_not_travel(tmp_path):
    # Its onsets are timed against the frames (eq. 1 at t2 - t_delay): a 2 kHz log keeps one
    # sample per 2 ms, uniform in time, where travel thinning would leave one per 40 ms of slow motion.
    from playscope.fit import model
    from playscope.io.session import Session

    from .synth import ROBOT, excitation, image_model_parts, true_B, true_f

    t, q, _ = excitation(v=0.4, rate_hz=2000.0)
    t, q = t[t < 30.0], q[t < 30.0]
    cam, he = image_model_parts()
    tf = np.arange(0.0, t[-1], 1 / 25.0)
    Q = model.ImageModel(ROBOT, cam, he)(np.interp(tf - 0.08, t, model.direct_model(q, true_B, true_f)))
    s = Session("mm", "image", ROBOT, {"t_s": t, "q": q}, cam, he, 0.08,
                marker={"t_s": tf, "u_px": Q[:, 0], "v_px": Q[:, 1]})
    write_session(s, tmp_path / "s")
    a = load_session(tmp_path / "s")
    dt = np.diff(a.encoder["t_s"])
    assert abs(np.median(dt) - 2e-3) < 1e-6 and dt.max() < 3e-3
    assert any("thinned to 500 Hz" in n for n in a.notes)


def test_thinning_by_time_keeps_a_sharp_reversals_extremum_and_the_record_model_puts_it_on_its_grid():
    # A 1 kHz triangle whose apexes fall on odd ms: the first sample of each 2 ms bin misses each
    # by the speed times 1 ms (10 um here, 6 % of a 0.17 mm play), and eq. 1 measures
    # from q1. The thinned log keeps each turn's sample, and the record model's 500 Hz grid holds it.
    from playscope.fit import onset_model as OM
    from playscope.io.session import thin_encoder_by_time

    k = np.arange(3000)
    t = k * 1e-3
    q = 0.45 * (np.abs((k - 1) % 180 - 90) / 45.0 - 1.0)  # 10 mm/s, 90 ms legs, every apex on an odd ms
    full = detect_reversals(t, q, 0.01 * np.ptp(q))
    enc, note = thin_encoder_by_time({"t_s": t, "q": q}, "encoder.csv")
    assert "every turn" in note and np.median(np.diff(enc["t_s"])) == pytest.approx(2e-3)
    thin = detect_reversals(enc["t_s"], enc["q"], 0.01 * np.ptp(q))
    assert np.array_equal(thin[0], full[0]) and np.array_equal(thin[1], full[1])
    short = detect_reversals(t[::2], q[::2], 0.01 * np.ptp(q))  # what the bins alone keep
    later = full[0] > 0.05  # the bins alone also lose the first, 1 ms into the log
    assert short[0].size == later.sum() and np.all(np.abs(short[1] - full[1][later]) > 0.009)
    rec = OM.make_record(enc["t_s"], enc["q"], thin[0], thin[1], np.arange(0.1, 2.9, 0.04), np.zeros((70, 2)), 25.0)
    assert rec.dt == pytest.approx(2e-3)
    for a, b in zip(thin[0], thin[1]):  # each extremum on the grid point nearest it
        assert rec.q[int(np.argmin(np.abs(rec.t - a)))] == b
