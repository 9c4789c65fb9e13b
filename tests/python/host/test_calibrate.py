"""The estimation chain on synthetic sessions with a known B(q) and f, tables, and CLI errors."""

import json

import numpy as np
import pytest

from playscope.fit.backlash import fit_backlash
from playscope.fit.baselines import fit_constant_play
from playscope.fit.reversals import detect_reversals
from playscope.fit import model
from playscope.fit.calibration import Calibration, calibrate
from playscope.cli import main
from playscope.io.session import write_session
from playscope.fit.table_build import build_table, table_errors

from .synth import angle_session, true_B, true_f


@pytest.fixture(scope="module")
def synth_cal():
    s = angle_session(noise_deg=0.01, rate_hz=200.0)
    return s, calibrate(s, fps=25.0)


def test_reversals_found_at_extrema():
    t, q, turns = __import__("host.synth", fromlist=["x"]).excitation(rate_hz=200.0)
    rt, rq, d = detect_reversals(t, q, 0.05)
    # Every knot of the ramp is a reversal but the one where the return sweep begins,
    # which continues downwards.
    assert rt.size == turns.size - 1
    assert np.max(np.min(np.abs(rt[:, None] - turns[None, :]), axis=1)) < 0.006
    assert set(np.unique(d)) == {-1, 1}


def test_backlash_recovered_from_onsets(synth_cal):
    s, cal = synth_cal
    g = np.linspace(-3, 3, 61)
    err = np.abs(cal.B(g) - true_B(g))
    # Onsets need one frame of motion above T: a bias of a few frames of travel at most.
    assert np.median(err) < 0.06 and np.max(err) < 0.15, err.max()


def test_prediction_matches_truth(synth_cal):
    s, cal = synth_cal
    c = cal.predict(s.encoder["q"])
    assert np.sqrt(np.mean((c - s.truth["c_deg"]) ** 2)) < 0.5


def test_spline_is_robust_to_an_outlier():
    rng = np.random.default_rng(3)
    x = np.linspace(0, 5, 40)
    y = 0.4 + 0.05 * x + rng.normal(0, 0.005, x.size)
    y[10] = 3.0
    B, w = fit_backlash(x, y)
    assert abs(B(np.array([x[10]]))[0] - (0.4 + 0.05 * x[10])) < 0.03
    assert w[10] < 0.1


def test_too_few_samples_is_a_one_line_error():
    with pytest.raises(Exception, match="only 3 valid backlash samples"):
        fit_backlash(np.array([0, 1, 2.0]), np.array([0.1, 0.2, 0.3]), source="x.csv")


def test_constant_play_baseline_recovers_width():
    t, q, _ = __import__("host.synth", fromlist=["x"]).excitation(rate_hz=100.0)
    f = lambda z: 3 * z + 0.1 * z**2
    c = model.direct_model(q, model.constant(0.7), f)
    w, fp, _ = fit_constant_play(q, c)
    assert w == pytest.approx(0.7, abs=0.01)


def test_table_round_trip_and_error_bound(synth_cal):
    s, cal = synth_cal
    q0, q1 = cal.q_range
    tab = build_table(cal.B, cal.f, q0, q1, "mm")
    err = table_errors(tab, cal.B, cal.f, q0, q1)
    assert err["direct_c_deg_max"] < 0.2 and err["comp_q_max"] < 0.02
    bad = bytearray(tab.blob)
    bad[-1] ^= 1
    from playscope.fit.table_build import CalibTable

    with pytest.raises(Exception, match="CRC"):
        CalibTable(bytes(bad))


def test_cli_calibrate_tables_json(tmp_path):
    # The CLI's plumbing (session folder in, calibration, JSON report and table out) on the
    # helper's session over half the travel (58 s, 22 reversals): a third of the full one's cost.
    s = angle_session(noise_deg=0.01, rate_hz=200.0, q_start=-2.0, q_end=2.0)
    write_session(s, tmp_path / "s")
    assert main(["calibrate", str(tmp_path / "s"), "-o", str(tmp_path / "c.json"), "--fps", "25",
                 "--json", str(tmp_path / "r.json")]) == 0
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["b_samples"] >= 10
    assert main(["tables", str(tmp_path / "c.json"), "-o", str(tmp_path / "t.pstb")]) == 0
    assert (tmp_path / "t.pstb").stat().st_size > 60
    Calibration.load(tmp_path / "c.json")


def test_cli_errors_name_file_and_write_nothing(tmp_path, capsys):
    s = angle_session(rate_hz=100.0)
    s.encoder = {k: v[:250] for k, v in s.encoder.items()}  # 2.5 s, before the first reversal (3 s)
    write_session(s, tmp_path / "s")
    assert main(["calibrate", str(tmp_path / "s"), "-o", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no direction reversal" in err and str(tmp_path / "s" / "encoder.csv") in err
    assert not (tmp_path / "c.json").exists()
    assert main(["calibrate", str(tmp_path / "missing"), "-o", str(tmp_path / "c.json")]) == 2
    assert "session folder not found" in capsys.readouterr().err


def test_real_catheter_in_situ_beats_constant_play(real_catheter_dir):
    from playscope.io.importer import import_catheter
    from playscope.evaluate.real_eval import fit_models, rmse

    s = import_catheter(real_catheter_dir / "data_2_3.txt")
    t = s.encoder["t_s"]
    half = 0.5 * (t[0] + t[-1])
    fit = fit_models(s.slice_time(-np.inf, half))
    m = s.distal["t_s"] >= half
    r = {k: rmse(model.direct_model(s.encoder["q"], *fit[k])[m] - s.distal["c_deg"][m]) for k in ("ours", "const_play")}
    assert r["ours"] <= r["const_play"]


def test_the_calibration_is_the_same_bit_for_bit_with_a_second_core_or_without(synth_cal, monkeypatch):
    # calibrate shares its independent fits with a forked child (base.forkmap: the model choice per
    # B alternative here); each fit depends on its item alone, so the calibration file is the same
    # whichever process fitted what
    from playscope.base import forkmap

    s, cal = synth_cal
    if not forkmap.can_fork():
        pytest.skip("needs Linux and two cores")
    assert len(cal.doc["B_fit"]["model_cv"]) >= 2  # more than one alternative: the map had work to share
    monkeypatch.setattr(forkmap, "can_fork", lambda: False)
    assert json.dumps(calibrate(s, fps=25.0).doc) == json.dumps(cal.doc)


def test_an_image_calibration_is_the_same_bit_for_bit_in_lockstep_and_on_one_core(tmp_path, monkeypatch):
    # calibrate's lockstep child (base.forkmap.lockstep) runs the same chain and takes items of every
    # map, the record model's term rounds among them (a registration record: rounds with offers); the
    # file must be the one a single process writes
    from playscope.base import forkmap
    from playscope.io.session import load_session

    from .onset_records import SR

    if not forkmap.can_fork():
        pytest.skip("needs Linux and two cores")
    SR.write(SR.Rendering("lockstep", 7, duration_s=5.0, reg_deg=1.5), tmp_path / "s")
    two = calibrate(load_session(tmp_path / "s")).doc
    assert two["onset"]["refine"]["terms"]["chosen"]  # a term entered: the rounds had work to share
    monkeypatch.setattr(forkmap, "can_fork", lambda: False)
    one = calibrate(load_session(tmp_path / "s")).doc
    assert json.dumps(two) == json.dumps(one)
