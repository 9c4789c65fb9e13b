"""Bounded resources for long, dense logs: session.thin_encoder keeps the first sample of each
1/ENCODER_MAX_HZ (2 ms) when an encoder log is denser than that (bench/bench_large_log.py
measures calibrate on a 27-minute 5 kHz log), and leaves slower logs alone."""

from __future__ import annotations

import numpy as np
import pytest

from playscope.io.session import ENCODER_MAX_HZ, load_session, thin_encoder, write_session

from .synth import angle_session


def test_thin_rule():
    t = np.arange(0, 2.0, 1 / 5000.0)
    enc = {"t_s": t, "q": np.sin(t)}
    out, note = thin_encoder(enc, "e.csv", 1000.0)
    assert out["t_s"].size == 2000 and np.all(np.diff(out["t_s"]) > 0.9e-3)
    assert np.array_equal(out["t_s"], t[::5]) and np.array_equal(out["q"], enc["q"][::5])
    assert "5000 Hz log, thinned to 1000 Hz" in note and "2000 of 10000 rows kept" in note
    out, note = thin_encoder(enc, "e.csv")
    assert np.array_equal(out["t_s"], t[::10]) and f"thinned to {ENCODER_MAX_HZ:.0f} Hz" in note
    for hz in (100.0, 300.0, ENCODER_MAX_HZ):
        t = np.arange(0, 2.0, 1 / hz)
        same, note = thin_encoder({"t_s": t, "q": t}, "e.csv")
        assert same["t_s"] is t and note is None


def test_dense_session_loads_thinned(tmp_path):
    s = angle_session()
    t = np.arange(s.encoder["t_s"][0], s.encoder["t_s"][-1], 1 / 4000.0)
    s.encoder = {"t_s": t, "q": np.interp(t, s.encoder["t_s"], s.encoder["q"])}
    write_session(s, tmp_path / "s")
    a = load_session(tmp_path / "s")
    assert abs(np.median(np.diff(a.encoder["t_s"])) - 1 / ENCODER_MAX_HZ) < 1e-9
    assert any(f"thinned to {ENCODER_MAX_HZ:.0f} Hz" in n for n in a.notes)


def test_thinned_log_calibrates_as_the_full_one():
    """A 2 kHz encoder log with 2 um noise in 1 um counts (the 138-s synthetic session),
    calibrated whole and thinned (session.thin_record, to ENCODER_MAX_HZ). Measured here: B(q)
    within 0.0045 mm of each other, best CV RMSE of f 0.141 (whole) and 0.126 deg (thinned);
    the bounds are about three times that."""
    import copy

    from playscope.fit.calibration import calibrate
    from playscope.io.session import thin_record

    s = angle_session()
    rng = np.random.default_rng(3)
    t = np.arange(s.encoder["t_s"][0], s.encoder["t_s"][-1], 1 / 2000.0)
    q = np.interp(t, s.encoder["t_s"], s.encoder["q"]) + rng.normal(0, 2e-3, t.size)
    s.encoder = {"t_s": t, "q": np.round(q * 1000) / 1000}
    full = calibrate(s, model_kind="play")
    thin = thin_record(copy.copy(s), "encoder.csv")
    assert thin.encoder["t_s"].size * 4 == pytest.approx(t.size, abs=4)
    cal = calibrate(thin, model_kind="play")
    g = np.linspace(-3, 3, 13)
    assert np.max(np.abs(cal.B(g) - full.B(g))) < 0.015
    best = [min(c["cv_rmse_deg"] for c in x.doc["f_fit"]["candidates"]) for x in (full, cal)]
    assert abs(best[0] - best[1]) < 0.05
