"""Calibrated on one record, run on another (playscope.evaluate.transfer): the endoscope reader, the
transfer rows against the on-line protocol they reuse, and the drift measurement on the real
catheter recordings (read in place; skipped when absent)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from playscope.board import online as O
from playscope.base.errors import InputError
from playscope.evaluate.transfer import ROWS, config_angle, drift, evaluate_transfer
from playscope.io.importer import import_endoscope as read_endoscope, read_record

_REAL = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "real"  # as conftest.REAL_CATHETER
REAL_CATHETER = Path(os.environ.get("PLAYSCOPE_REAL_DATA", _REAL)) / "catheter"


def _write(path, rows):
    path.write_text("\n".join(", ".join(f"{v:.6f}" for v in r) for r in rows) + "\n")


def test_endoscope_reader_drops_zero_block_and_keeps_last_of_repeated_stamps(tmp_path):
    # t, q, (unused), c: a zero-stamped block, then stamps repeated with the newest value last.
    rows = ([[0, 0, 0, 0]] * 3 + [[0.025, 1, 9, 0.5], [0.025, 1.5, 9, 0.7], [0.05, 2, 9, 1.0], [0.05, 2.5, 9, 1.2],
                                  [0.075, 3, 9, 1.5]] + [[0.1 + 0.025 * k, 3 + k, 9, 2 + k] for k in range(8)])
    p = tmp_path / "30.txt"
    _write(p, rows)
    s = read_endoscope(p)
    assert s.actuator_unit == "deg" and s.distal_kind == "angle"
    # The zero block before the motion goes, but for its last row (the state at rest).
    np.testing.assert_allclose(s.encoder["t_s"][:4] - s.encoder["t_s"][0], [0, 0.025, 0.05, 0.075])
    np.testing.assert_allclose(s.encoder["q"][1:4], [1.5, 2.5, 3])   # the last of each stamp
    np.testing.assert_allclose(s.distal["c_deg"][1:4], [0.7, 1.2, 1.5])
    assert any("repeat an earlier time stamp" in n for n in s.notes)
    assert read_record(p).encoder["q"].size == s.encoder["q"].size  # headerless -> the endoscope reader


def test_endoscope_reader_conf_files_read_column_5_and_refuse_bad_files(tmp_path):
    p = tmp_path / "conf0_60.txt"
    _write(p, [[0.01 * (k + 1), k, 0, 0, 0, -k, 0] for k in range(20)])
    np.testing.assert_allclose(read_endoscope(p).distal["c_deg"], -np.arange(20.0))
    bad = tmp_path / "60.txt"
    _write(bad, [[0.01 * (k + 1), k] for k in range(20)])  # no column 3
    with pytest.raises(InputError, match="60.txt"):
        read_endoscope(bad)
    with pytest.raises(InputError, match="not found"):
        read_endoscope(tmp_path / "none.txt")


def test_peer_verdicts_every_peer_and_every_invertible_peer():
    # Ours between the generalized PI (no inverse: its cubic turns back) and the invertible peers,
    # on the means of a planted document: NO against every peer, yes against the invertible ones.
    from playscope.evaluate.transfer import (INVERTIBLE_PEERS, LABELS, PEERS, TIE_DEG, UPDATES, format_transfer,
                                             peer_comparison)

    assert INVERTIBLE_PEERS == ("gpi_inc", "mpi_inc")
    mean = {"gpi": 0.311, "gpi_inc": 0.347, "mpi": 0.3325, "mpi_inc": 0.3325}
    doc = {"mean": {f"{k}_ref{u}": mean[k] for k, _, _ in PEERS for u, _ in UPDATES}, "labels": LABELS,
           "files": {}, "order": [], "calibration": {"file": "cal.txt"}, "settings": {"warmup": 0.5}}
    doc["mean"].update({"static_transition": 0.3225, "transition_offset": 0.3225, "transition_affine": 0.3225,
                        "transition_board": 0.3325 + 0.5 * TIE_DEG})  # a tie with mpi_inc within TIE_DEG
    c = peer_comparison(doc)
    assert c[""]["best_peer"] == "gpi_ref" and not c[""]["ours_le_every_peer"]
    assert c[""]["invertible_peers"] == ["gpi_inc_ref", "mpi_inc_ref"] and c[""]["best_invertible_peer"] == "mpi_inc_ref"
    assert c[""]["ours_le_every_invertible_peer"] and c["_board"]["ours_le_every_invertible_peer"]
    doc["mean"]["transition_board"] = 0.3325 + 2 * TIE_DEG
    assert not peer_comparison(doc)["_board"]["ours_le_every_invertible_peer"]
    out = format_transfer(doc)
    assert ("ours <= every peer: NO; best invertible peer (gpi_inc, mpi_inc), modified PI, output monotone "
            "(invertible: pi_const): 0.333 deg; ours <= every invertible peer: yes") in out
    assert out.rstrip().endswith("ours <= every invertible peer: NO")


def test_config_angle_from_file_names():
    assert config_angle("x/120.txt") == 120.0 and config_angle("conf90_60.txt") == 90.0
    assert config_angle("data_2_3.txt") is None


@pytest.fixture(scope="module")
def catheter_transfer():
    if not (REAL_CATHETER / "data_2_1.txt").is_file():
        pytest.skip(f"real catheter data not found in {REAL_CATHETER}")
    return REAL_CATHETER, evaluate_transfer(REAL_CATHETER / "data_2_1.txt", [REAL_CATHETER / "data_2_5.txt"], 0.2)


def test_transfer_rows_equal_the_online_protocol_they_reuse(catheter_transfer):
    folder, doc = catheter_transfer
    r = doc["files"]["data_2_5"]["rmse_deg"]
    assert list(r) == ROWS and all(np.isfinite(v) for v in r.values())
    # The pure-play rows are online.evaluate_online's with the same reference and split, run independently.
    ref = O.evaluate_real_online(folder, settings=O.OnlineSettings(score_after=0.2))["files"]["data_2_5"]["rmse_deg"]
    for k in ("static", "online_b_only", "online_offset_only", "online", "const_play_ref_offset"):
        assert r[k] == pytest.approx(ref[k], rel=1e-9)
    # Measured on data_2_5 at a 20 % warm-up (deg): transition + offset refresh 0.53, pure play with
    # both updates 1.57; transition as is 0.57, pure play as is 1.46. Pinned with a margin.
    assert r["transition_offset"] < 0.5 * r["online"]
    # The refresh where nothing drifts (in situ): 2.46 -> 1.47 deg measured on data_2_5 at 20 % (its
    # 20 % in-situ fit is poor), 0.40 -> 0.41 at 50 %.
    assert r["in_situ_affine"] <= 1.1 * r["in_situ"]
    assert r["static_transition"] < r["static"]


def test_drift_on_catheter_self_is_zero_and_data_2_5_play_is_wider(real_catheter_dir):
    d = drift([real_catheter_dir / "data_2_5.txt"], real_catheter_dir / "data_2_1.txt")
    me, other = d["files"]["data_2_1"], d["files"]["data_2_5"]
    assert abs(me["offset_deg"]) < 1e-9 and me["gain"] == pytest.approx(1.0) and me["b_shape"] < 1e-9
    # Measured: B of data_2_5 0.128 mm (40 %) above data_2_1's, gain 0.970, offset -0.31 deg.
    assert 0.06 < other["b_level"] < 0.25
    assert 0.9 < other["gain"] < 1.05


def test_affine_refresh_learns_gain_and_offset_causally():
    from types import SimpleNamespace

    from playscope.evaluate.transfer import _affine_refreshed

    t = np.arange(0.0, 20.0, 0.002)
    c_hat = 30.0 * np.sin(2 * np.pi * t / 4)
    truth = 3.0 + 1.2 * c_hat
    s = SimpleNamespace(encoder={"t_s": t}, distal={"t_s": t, "c_deg": truth})
    out = _affine_refreshed(s, c_hat, 25.0, 1.0, float(np.var(truth)))
    assert np.array_equal(out[t < 1.0], c_hat[t < 1.0])  # nothing before the first refresh
    late = t > 10.0
    assert np.max(np.abs(out[late] - truth[late])) < 0.05 * np.max(np.abs(truth))  # gain and offset learnt
    # Causal: changing the angle after 12 s leaves everything before the refresh at 12 s unchanged.
    s2 = SimpleNamespace(encoder={"t_s": t}, distal={"t_s": t, "c_deg": np.where(t >= 12.0, -truth, truth)})
    out2 = _affine_refreshed(s2, c_hat, 25.0, 1.0, float(np.var(truth)))
    assert np.array_equal(out[t < 12.0], out2[t < 12.0]) and not np.array_equal(out, out2)


def _ewls(x, c, mem_log2, prior_var, publish_every):
    """Double reference of the board learner: exponentially weighted least squares of c on x
    (weights (1 - 2^-k)^age), prior g = 1 worth prior_var, g clamped to [1/2, 2]; (a, g) at
    every publish_every-th reading."""
    lam = 1.0 - 2.0 ** -mem_log2
    w = sx = sc = sxx = sxc = 0.0
    out = []
    for i, (xi, ci) in enumerate(zip(x, c)):
        w, sx, sc = lam * w + 1, lam * sx + xi, lam * sc + ci
        sxx, sxc = lam * sxx + xi * xi, lam * sxc + xi * ci
        if (i + 1) % publish_every == 0:
            mx, mc = sx / w, sc / w
            g = float(np.clip((sxc - w * mx * mc + prior_var) / (sxx - w * mx * mx + prior_var), 0.5, 2.0))
            out.append((mc - g * mx, g))
    return np.array(out)


def test_board_learner_is_the_weighted_least_squares_it_claims():
    rng = np.random.default_rng(5)
    n, cfg = 900, {"mem_log2": 7, "publish_every": 10, "prior_var_q16": 40 * 65536}
    x = 35.0 * np.sin(0.07 * np.arange(n)) + 4.0
    a_t = np.where(np.arange(n) < 450, 2.5, -1.0)  # a drift the forgetting must follow
    c = a_t + 0.95 * x + 0.2 * rng.normal(size=n)
    bf = O.BoardF.from_range(-40.0, 50.0, cfg)
    got = []
    for xi, ci in zip(x, c):
        if bf.step(xi, ci):
            got.append(bf.map())
    # The reference on the same Q16-rounded inputs.
    xr, cr = np.round(x * 65536) / 65536, np.round(c * 65536) / 65536
    ref = _ewls(xr, cr, 7, 40.0, 10)
    got = np.array(got)
    assert got.shape == ref.shape == (90, 2)
    # Measured: |a| 2.3e-4 deg, |g| 7.6e-6 worst: the Q16 rounding of the sums.
    assert np.max(np.abs(got[:, 0] - ref[:, 0])) < 2e-3
    assert np.max(np.abs(got[:, 1] - ref[:, 1])) < 3e-5
    assert abs(got[-1, 0] + 1.0) < 0.2 and abs(got[-1, 1] - 0.95) < 0.01


def test_board_learner_in_the_replay_is_causal_and_learns_the_drift():
    from types import SimpleNamespace

    t = np.arange(0.0, 20.0, 0.002)
    c_hat = 30.0 * np.sin(2 * np.pi * t / 4)
    truth = 3.0 + 1.2 * c_hat
    cfg = {"mem_log2": 10, "publish_every": 25, "prior_var_q16": int(np.var(truth) * 65536)}
    s = SimpleNamespace(encoder={"t_s": t}, distal={"t_s": t, "c_deg": truth})
    out, end = O.board_f_refreshed(s, c_hat, 25.0, cfg, (-40.0, 40.0))
    assert np.array_equal(out[t < 1.0], c_hat[t < 1.0])  # nothing before the first publish
    late = t > 10.0
    assert np.max(np.abs(out[late] - truth[late])) < 0.02 * np.max(np.abs(truth))
    assert abs(end["g"] - 1.2) < 0.01 and abs(end["a_deg"] - 3.0) < 0.1 and end["publishes"] == 20
    s2 = SimpleNamespace(encoder={"t_s": t}, distal={"t_s": t, "c_deg": np.where(t >= 12.0, -truth, truth)})
    out2, _ = O.board_f_refreshed(s2, c_hat, 25.0, cfg, (-40.0, 40.0))
    assert np.array_equal(out[t < 12.0], out2[t < 12.0]) and not np.array_equal(out, out2)


def _demo_table():
    import math

    from playscope.fit.table_build import write_blob

    n, step, x0 = 256, 2 ** 11, int(-4.0 * 65536)
    qs = [(x0 + i * step) / 65536 for i in range(n)]
    b = [int(round(0.5 * 65536)) for _ in qs]
    f = [int(round((10 * q + 0.3 * q ** 3) * 65536)) for q in qs]
    fn = lambda q: 10 * q + 0.3 * q ** 3  # noqa: E731
    return write_blob(x0, step, b, f, -4.0, (x0 + (n - 1) * step) / 65536, "mm", "remain", 1), fn


def _play_plant(fn, B, a, g):
    from playscope.fit import model

    def plant(t, q):
        z = model.play_operator(np.asarray(q, float), lambda x: np.full_like(np.asarray(x, float), B), z0=float(q[0]))
        return a + g * fn(z)
    return plant


def test_closed_loop_learner_removes_a_drift_and_costs_nothing_without_one():
    from playscope.fit.table_build import CalibTable

    blob, fn = _demo_table()
    t = np.arange(0.0, 40.0, 0.01)
    c_ref = 25.0 * np.sin(2 * np.pi * t / 6.0) + 8.0 * np.sin(2 * np.pi * t / 2.3)
    cfg = {"mem_log2": 9, "publish_every": 10, "prior_var_q16": int(np.var(c_ref) * 65536)}
    late = t > 20.0
    q_static = CalibTable(blob).compensate(c_ref)
    for a, g in ((2.0, 1.08), (0.0, 1.0)):
        plant = _play_plant(fn, 0.5, a, g)
        q_learn, end = O.compensate_learning(blob, t, c_ref, plant, 10.0, cfg)
        e_static = np.sqrt(np.mean((plant(t, q_static) - c_ref)[late] ** 2))
        e_learn = np.sqrt(np.mean((plant(t, q_learn) - c_ref)[late] ** 2))
        if a:
            # Measured: 2.46 deg as flashed, 0.007 deg learnt (g 1.0797, a 2.000).
            assert e_learn < 0.01 * e_static and abs(end["g"] - g) < 0.002
        else:
            # Nothing drifts: the learner stays at the identity up to the table's own error
            # (measured 3.3e-4 deg as flashed, 1.2e-4 deg learning).
            assert e_learn <= 1.02 * e_static + 1e-3 and abs(end["g"] - 1.0) < 0.002


def test_oracle_ceiling_bounds_the_causal_learners(catheter_transfer):
    """The oracle (offset and gain chosen on the scored samples) is a lower bound of every causal
    update of those terms on the same model and samples: the board learner's and the host's."""
    from playscope.evaluate.transfer import learnable_ceiling

    folder, doc = catheter_transfer
    r = doc["files"]["data_2_5"]["rmse_deg"]
    c = learnable_ceiling(folder / "data_2_1.txt", [folder / "data_2_5.txt"], 0.2)["files"]["data_2_5"]
    assert c["in_situ"] == pytest.approx(r["in_situ"], rel=1e-9)  # the same reference, same samples
    assert c["affine"] <= r["transition_board"] and c["affine"] <= r["transition_affine"]
    assert c["affine_b_level"] <= c["affine"]


def test_hat_basis_is_linear_interpolation_of_node_values_held_beyond_the_ends():
    """H @ v is np.interp of the node values v (the correction the board would write on its grid),
    each row sums to 1 (an offset is in the span), and beyond the range the end value is held."""
    from playscope.evaluate.transfer import hat_basis

    rng = np.random.default_rng(3)
    y = np.r_[rng.uniform(-12.0, 12.0, 500), -30.0, 40.0]
    v = rng.normal(size=7)
    H = hat_basis(y, -10.0, 10.0, 7)
    nodes = np.linspace(-10.0, 10.0, 7)
    assert np.allclose(H.sum(axis=1), 1.0, atol=1e-12)
    assert np.allclose(H @ v, np.interp(y, nodes, v), atol=1e-12)
    assert H[-2] @ v == pytest.approx(v[0]) and H[-1] @ v == pytest.approx(v[-1])


def test_rls_shape_without_forgetting_is_least_squares_with_the_p0_prior_and_forgetting_tracks_a_change():
    """lambda = 1: the last theta is the ridge solution (H'H + I/p0)^-1 H'r exactly (RLS identity);
    lambda < 1: after the target moves, theta follows it (the old value forgotten)."""
    from playscope.evaluate.transfer import hat_basis, rls_shape

    rng = np.random.default_rng(5)
    y = rng.uniform(0.0, 1.0, 400)
    H = hat_basis(y, 0.0, 1.0, 5)
    th_true = np.array([0.5, -1.0, 2.0, 0.0, 1.5])
    r = H @ th_true + 0.05 * rng.normal(size=y.size)
    for p0 in (1.0, 0.25):
        ridge = np.linalg.solve(H.T @ H + np.eye(5) / p0, H.T @ r)
        assert np.allclose(rls_shape(H, r, 1.0, p0)[-1], ridge, atol=1e-9)
    th_new = th_true + 3.0
    r2 = np.r_[r, H @ th_new]  # the same readings again, the correction moved by 3 deg
    end_forget = rls_shape(np.vstack([H, H]), r2, 1.0 - 2.0 ** -5)[-1]
    end_keep = rls_shape(np.vstack([H, H]), r2, 1.0)[-1]
    assert np.max(np.abs(end_forget - th_new)) < 0.05  # memory 32 readings of 400 new ones
    assert np.max(np.abs(end_keep - th_new)) > 1.0     # without forgetting it averages the two


REAL_ENDOSCOPE = REAL_CATHETER.parent / "endoscope"


@pytest.fixture(scope="module")
def transfer_30_60():
    """The transfer table's rows for the endoscope pair 30 -> 60 deg (both shape tests compare
    with it; computed once)."""
    return evaluate_transfer(REAL_ENDOSCOPE / "30.txt", [REAL_ENDOSCOPE / "60.txt"])["files"]["60"]["rmse_deg"]


@pytest.mark.skipif(not (REAL_ENDOSCOPE / "60.txt").is_file(), reason="real endoscope recordings absent")
def test_shape_ceiling_rows_keep_their_bounds_on_an_endoscope_pair(transfer_30_60):
    """On 30 -> 60 deg (development files): the oracle of each correction is at most its warm-up
    fit (both a constant theta on the same basis; the oracle is the least squares on the scored
    samples), the per-branch span holds the f-shape span and the weights-plus-branch span holds
    both (oracle lower), the reference is the
    ceiling's in-situ figure, and the board row equals the transfer table's."""
    from playscope.evaluate.transfer import learnable_ceiling, shape_ceiling

    cal, run = REAL_ENDOSCOPE / "30.txt", REAL_ENDOSCOPE / "60.txt"
    cache: dict = {}
    f = shape_ceiling(cal, [run], in_situ_cache=cache, nodes=(4,))["files"]["60"]
    for k in ("shape_4", "branch_4", "weights", "wbranch_4"):
        assert f[f"{k}_oracle"] <= f[f"{k}_warmup"] + 1e-12
    assert f["branch_4_oracle"] <= f["shape_4_oracle"] + 1e-12
    assert f["wbranch_4_oracle"] <= min(f["branch_4_oracle"], f["weights_oracle"]) + 1e-12
    assert f["in_situ"] == pytest.approx(learnable_ceiling(cal, [run], in_situ_cache=cache)["files"]["60"]["in_situ"], rel=1e-12)
    tr = transfer_30_60
    assert f["board"] == pytest.approx(tr["transition_board"], rel=1e-9)
    assert f["in_situ"] == pytest.approx(tr["in_situ"], rel=1e-9)


@pytest.mark.skipif(not (REAL_ENDOSCOPE / "60.txt").is_file(), reason="real endoscope recordings absent")
def test_shape_noregress_runs_the_learners_on_the_in_situ_model(transfer_30_60):
    """Nothing drifts: the learners sit on the record's own in-situ model, so its reference and the
    board learner's row are the transfer table's in_situ and in_situ_board on that record, and
    the oracle bounds hold as on a transferred model."""
    from playscope.evaluate.transfer import shape_noregress

    run = REAL_ENDOSCOPE / "60.txt"
    f = shape_noregress([run], nodes=(4,))["files"]["60"]
    tr = transfer_30_60
    assert f["in_situ"] == pytest.approx(tr["in_situ"], rel=1e-12)
    assert f["board"] == pytest.approx(tr["in_situ_board"], rel=1e-9)
    for k in ("shape_4", "branch_4", "weights", "wbranch_4"):
        assert f[f"{k}_oracle"] <= min(f[f"{k}_warmup"], f["in_situ"]) + 1e-12


def test_transfer_peers_are_fitted_on_the_reference_frames_and_given_ours_updates(catheter_transfer):
    """The peer rows (generalized and modified PI and their invertible forms) are the peers fitted
    on the calibration record's frames (those const_play_ref is fitted on), run from the record's
    first sample, with the same offset refresh and board learner (same settings) as ours: one row
    recomputed here by hand, and the comparison with ours read from the rows."""
    from playscope.evaluate.transfer import PEER_ROWS, UPDATES, _offset_refreshed
    from playscope.fit.calibration import calibrate
    from playscope.fit.peers import IncreasingGPI

    folder, doc = catheter_transfer
    r = doc["files"]["data_2_5"]["rmse_deg"]
    assert set(PEER_ROWS) <= set(r) and all(np.isfinite(r[k]) for k in PEER_ROWS)
    s_ref, s = read_record(folder / "data_2_1.txt"), read_record(folder / "data_2_5.txt")
    cal = calibrate(s_ref, f_method="lsq", model_kind="play", source="data_2_1")
    m = IncreasingGPI.fit(*O.reference_frames(s_ref, cal.fps_frames))
    t, q = s.encoder["t_s"], s.encoder["q"]
    mask = t >= doc["files"]["data_2_5"]["t_split_s"]
    c_true = np.interp(t, s.distal["t_s"], s.distal["c_deg"])
    fps = 1.0 / cal.onset_config["frame_period_s"]
    c_hat = m.predict(q)
    assert r["gpi_inc_ref"] == pytest.approx(O.rmse((c_hat - c_true)[mask]), rel=1e-9)
    assert r["gpi_inc_ref_offset"] == pytest.approx(O.rmse((_offset_refreshed(s, c_hat, fps, 1.0) - c_true)[mask]),
                                                    rel=1e-9)
    f_range = (float(np.nanmin(s_ref.distal["c_deg"])), float(np.nanmax(s_ref.distal["c_deg"])))
    c_b, _ = O.board_f_refreshed(s, c_hat, fps, doc["settings"]["board_f"], f_range)
    assert r["gpi_inc_ref_board"] == pytest.approx(O.rmse((c_b - c_true)[mask]), rel=1e-9)
    cmp = doc["peers_vs_ours"]
    assert set(cmp) == {u for u, _ in UPDATES} and cmp["_board"]["ours"] == "transition_board"
    assert cmp["_board"]["ours_le_every_peer"] == (doc["mean"]["transition_board"] <= min(cmp["_board"]["peers"].values()) + 1e-3)
    inv = cmp["_board"]["invertible_peers"]
    assert inv == ["gpi_inc_ref_board", "mpi_inc_ref_board"]
    assert cmp["_board"]["ours_le_every_invertible_peer"] == (
        doc["mean"]["transition_board"] <= min(cmp["_board"]["peers"][k] for k in inv) + 1e-3)
