"""The transition model (docs/method.md, "Transition model"): fit, model choice, inverse, v2 tables against the C loader.

Data come from an independent double-precision generator written here (scalar loops of the
play and the PI operator, no code shared with playscope.fit.transition or playscope.fit.model)."""

import json

import numpy as np
import pytest

from playscope.fit import table_build as TB
from playscope.fit import transition as T
from playscope.base.native import core, from_q16, to_q16

RATE_HZ = 50.0
B_MM = 0.4


def ref_play(x, half_width, start):
    """Classical play of half width r on x, started at `start` (scalar loop, reference)."""
    out, p = [], start
    for v in x:
        p = min(v + half_width, max(v - half_width, p))
        out.append(p)
    return np.array(out)


def ref_session(r, w, noise_deg=0.02, seed=0):
    """Reversals at many positions and amplitudes; c = f(sum w_i play_{r_i}(play_{B/2}(q))).

    Returns (FitData, q, c_true at the encoder rate, f)."""
    t = np.arange(0, 80, 1 / RATE_HZ)
    q = 1.6 * np.sin(2 * np.pi * t / 17) + 0.9 * np.sin(2 * np.pi * t / 5.3 + 1) + 0.3 * np.sin(2 * np.pi * t / 2.1)
    z = ref_play(q, B_MM / 2, q[0])
    y = sum(wi * ref_play(z, ri, z[0]) for ri, wi in zip(r, w))
    f = lambda v: 12.0 * np.asarray(v) + 1.5 * np.asarray(v) ** 2 / 3  # monotone on |v| < 9
    c = f(y)
    rng = np.random.default_rng(seed)
    k = slice(None, None, 5)  # frames at 10 Hz
    data = T.FitData(t, q, lambda x: np.full(np.shape(x), B_MM), t[k], c[k] + rng.normal(0, noise_deg, c[k].size))
    return data, q, c, f


def span_rule(data):
    """The candidate grid's span, recomputed here: the largest excursion of z between
    reversals (scalar loop over the turning points of the play centre, 1 % hysteresis)."""
    z = data.z_enc()
    h = 0.01 * float(np.ptp(z))
    turns, ext, d = [z[0]], z[0], 0
    for v in z:
        if d >= 0 and v > ext or d <= 0 and v < ext:
            ext = v
            if d == 0 and abs(v - z[0]) > h:
                d = 1 if v > z[0] else -1
        elif abs(v - ext) > h:
            turns.append(ext)
            d, ext = -d if d else (1 if v > ext else -1), v
    turns.append(z[-1])
    return float(np.max(np.abs(np.diff(turns))))


def threshold_rule(data, n=16):
    """The candidates' thresholds, recomputed here: r_i = span (i/n)^2."""
    return span_rule(data) * (np.arange(n) / n) ** 2


def test_operators_match_the_reference_loop():
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(0, 0.1, 500))
    r = np.array([0.0, 0.1, 0.35])
    P = T.play_ops(x, r)
    for i, ri in enumerate(r):
        assert np.array_equal(P[:, i], ref_play(x, ri, x[0]))


def test_play_ops_in_c_is_the_numpy_loop_bit_for_bit():
    """kernels.play_ops (what play_ops runs when the C is compiled) against the numpy reference,
    signed zeros included: holds (ties with the band), a zero threshold, x through -0.0 and 0.0."""
    from playscope.base import kernels

    if not kernels.available():
        pytest.skip("no C compiler for the kernels")
    rng = np.random.default_rng(5)
    x = np.cumsum(rng.normal(0, 0.1, 3000))
    x[100:200] = x[100]
    x[300:310] = [0.0, -0.0, 0.0, -0.0, -0.0, 0.0, 0.0, -0.0, 0.0, -0.0]
    r = T.thresholds(16, 0.8)
    for p0 in (np.full(16, x[0]), rng.normal(0, 1, 16), np.full(16, -0.0)):
        a, b = kernels.play_ops(x, r, p0), T._play_ops_numpy(x, r, p0.copy())
        assert np.array_equal(a.view(np.int64), b.view(np.int64))


def test_inverse_undoes_the_direct_operator():
    rng = np.random.default_rng(4)
    z = np.cumsum(rng.normal(0, 0.05, 3000))
    tr = T.Transition(T.thresholds(8, 0.8), np.array([0.2, 0.1, 0.0, 0.3, 0.1, 0.1, 0.1, 0.1]))
    z_back = tr.inverse(tr.direct(z))
    # Exact in exact arithmetic (Krejci & Kuhnen 2001); measured 4e-16 in float64.
    assert np.max(np.abs(z_back - z)) < 1e-12


def test_fit_recovers_planted_weights_and_thresholds():
    data, *_ = ref_session(np.zeros(1), np.ones(1))
    r = threshold_rule(data)
    w = np.zeros(16)
    w[[0, 3, 9]] = 0.4, 0.3, 0.3
    data, *_ = ref_session(r, w)
    tr, f, sign, ch = T.choose_model(data, "auto")
    assert ch["model"] == "pi" and ch["b_scale"] == 1.0 and ch["n_tried"] == 16
    assert ch["r_span"] == pytest.approx(span_rule(data), rel=1e-9)
    full = np.zeros(16)
    full[np.searchsorted(r, tr.r)] = tr.w
    # Measured |w - w_planted| <= 0.023 with 0.02 deg noise (the quadratic spacing puts
    # neighbouring small thresholds close, so weight trades between them); 0.06 leaves room.
    assert np.max(np.abs(full - w)) < 0.06, full
    assert sign == 1 and ch["fit_rmse_deg"] < 0.03


@pytest.mark.parametrize("kind", ["play", "pi"])
def test_cv_picks_play_on_play_data_and_pi_on_transition_data(kind):
    data, *_ = ref_session(np.zeros(1), np.ones(1))
    if kind == "pi":
        r = threshold_rule(data)
        w = np.r_[0.4, np.full(15, 0.6 / 15)]
        data, *_ = ref_session(r, w, seed=1)
    else:
        data, *_ = ref_session(np.zeros(1), np.ones(1), seed=1)
    tr, _, _, ch = T.choose_model(data, "auto")
    assert ch["model"] == kind, ch["candidates"]
    play = next(c for c in ch["candidates"] if c["n"] == 1)
    best = min(c["cv_rmse_deg"] for c in ch["candidates"])
    if kind == "pi":
        assert best < 0.5 * play["cv_rmse_deg"]  # the transition is visible to the CV
    assert tr.is_play == (kind == "play")


@pytest.mark.parametrize("kind", ["play", "pi"])
def test_lazy_model_choice_picks_what_the_full_table_picks(kind):
    # ModelChoice.pick() stops candidates early; the rule recomputed here on the complete
    # candidate table (best CV, limit = best + its SE, then fewest operators, b_scale closest
    # to 1, stiffest f) must give the same row, and resuming the stopped candidates must give
    # the very numbers of an uninterrupted run (bit for bit: same fits in the same order).
    data, *_ = ref_session(np.zeros(1), np.ones(1))
    w = np.r_[0.4, np.full(15, 0.6 / 15)] if kind == "pi" else np.ones(1)
    r = threshold_rule(data) if kind == "pi" else np.zeros(1)
    data, *_ = ref_session(r, w, seed=1)
    lazy = T.ModelChoice(data, "auto")
    pick = lazy.pick()
    folds_lazy = sum(len(c.errs) for c in lazy.cands)
    eager = T.ModelChoice(data, "auto")
    for c in eager.cands:
        c.complete()
    rows = [c.row() for c in eager.cands]
    best = min(rows, key=lambda d: d["cv_rmse_deg"])
    within = [d for d in rows if d["cv_rmse_deg"] <= best["cv_rmse_deg"] + best["cv_se_deg"]]
    assert pick == min(within, key=lambda d: (d["n"], -d["b_scale"], d["n_ctrl"]))
    assert folds_lazy < sum(len(c.errs) for c in eager.cands)  # it did stop something
    assert lazy.result()[3]["candidates"] == rows


def test_the_model_choice_is_the_same_through_the_pipe(monkeypatch):
    # ModelChoice.complete_all shares the open candidates with a forked child, and one the child
    # completed comes back as its state. Every open candidate completed in a child must give the
    # choice of every candidate completed here, and the same folds' weights for cv_start (the
    # family choice's onset transition starts from them), bit for bit.
    from playscope.base import forkmap

    from .forkpipe import in_a_child

    r = threshold_rule(ref_session(np.zeros(1), np.ones(1))[0])

    def run():
        data, *_ = ref_session(r, np.r_[0.4, np.full(15, 0.6 / 15)], seed=1)
        _, f, _, ch = T.ModelChoice(data, "auto").result()  # as calibrate's kept alternative: the pick after
        folds = {k: v for k, v in data._cache.items() if k[0] == "cv_v"}
        return ch, f(np.linspace(-1.0, 1.0, 7)), folds

    monkeypatch.setattr(forkmap, "can_fork", lambda: False)
    here = run()
    monkeypatch.setattr(forkmap, "fork_map", in_a_child)
    piped = run()
    assert json.dumps(piped[0]) == json.dumps(here[0]) and np.array_equal(piped[1], here[1])
    assert piped[2].keys() == here[2].keys() and len(here[2]) > 9  # every candidate's scored folds
    assert all(np.array_equal(piped[2][k], here[2][k]) for k in here[2])


def test_table_f_is_the_f_the_weights_were_fitted_with():
    # Monotone data: the f written to the table is the projection's P-spline (the f the CV
    # scored), not a refit; data bending back: the monotone robust spline instead (eq. 9 needs f^-1).
    r = np.array([0.0, 0.1, 0.4])
    w = np.array([0.5, 0.3, 0.2])
    data, *_ = ref_session(r, w)
    P = data.ops_at_frames(r)
    wa, fa, _, ra = T.fit_weights(P, data.c, 4, robust_f=True)
    wb, fb, _, rb = T.fit_weights(P, data.c, 4, robust_f=False)
    y = np.linspace(-4, 4, 101)
    assert np.array_equal(wa, wb) and np.array_equal(fa(y), fb(y)) and ra == rb
    y_f = P @ wa
    c_bent = np.where(y_f > 1.0, 12.0 - 6.0 * (y_f - 1.0), 12.0 * y_f)  # turns back above y = 1
    _, fm, sign, _ = T.fit_weights(P, c_bent, 14, robust_f=True)
    _, fp, _, _ = T.fit_weights(P, c_bent, 14, robust_f=False)
    g = np.linspace(y_f.min(), y_f.max(), 401)
    assert np.any(np.diff(fp(g)) < 0)  # the plain P-spline follows the turn
    # The constrained fit is monotone (flat where the data turn back; build_table then makes it
    # strictly monotone by one LSB, as for f_remain).
    assert sign == 1 and np.all(np.diff(fm(g)) >= -1e-9)


def test_fitted_table_loads_when_the_data_want_a_tiny_first_weight():
    # Planted w_0 = 1e-4: the inverse's error bound (~1/w_0 raw) would exceed calib_load's
    # precision ceiling (B/16 = 1638 raw here) and the table would be refused; the fit bounds
    # v_i = w_i/w_0 so that the table it writes always loads (v_max_for_table).
    data, *_ = ref_session(np.zeros(1), np.ones(1))
    r = threshold_rule(data)
    w = np.zeros(16)
    w[[0, 6, 12]] = 1e-4, 0.5, 0.5 - 1e-4
    data, q, _, _ = ref_session(r, w)
    tr, f, _, ch = T.choose_model(data, "pi")
    assert ch["model"] == "pi" and tr.n > 1
    assert 1 / tr.w[0] <= 0.5 * 1638 + 1e-6  # sum v <= ceiling/2
    tab = TB.build_table(tr.play_width(data.B), f, float(q.min()), float(q.max()), "mm", transition=tr)
    assert tab.n_ops == tr.n


def test_model_play_and_pi_restrict_the_candidates():
    data, *_ = ref_session(np.zeros(1), np.ones(1))
    assert T.candidates(data, "play") == [(1.0, 1, 0.0, 14, False)]
    assert T.candidates(data, "play", kinds=T.BOTH_KINDS) == [(1.0, 1, 0.0, 14, False)]
    pi = T.candidates(data, "pi")
    assert {(kb, n, nc, sc) for kb, n, _, nc, sc in pi} == {(kb, T.N_OPS, nc, False) for kb in T.B_SCALES
                                                            for nc in T.F_CTRL}
    both = T.candidates(data, "pi", kinds=T.BOTH_KINDS)
    assert {(kb, n, nc, sc) for kb, n, _, nc, sc in both} == {(kb, T.N_OPS, nc, sc) for kb in T.B_SCALES
                                                              for nc in T.F_CTRL for sc in (False, True)}
    with pytest.raises(ValueError):
        T.choose_model(data, "bogus")


# --------------------------------------------------------------------------- tables v2
def _fixture_model():
    B = lambda q: 0.35 + 0.45 * np.exp(-(np.asarray(q, float) / 0.8) ** 2)
    f = lambda z: np.degrees(np.asarray(z, float) / 3.0) * (1 - 0.45 * np.exp(-(np.asarray(z, float) / 1.0) ** 2))
    tr = T.Transition(T.thresholds(8, 1.2), np.array([0.3, 0.1, 0.2, 0.0, 0.15, 0.05, 0.1, 0.1]))
    return B, f, tr


def test_v2_table_round_trip_through_the_c_loader():
    ffi, lib = core()
    B, f, tr = _fixture_model()
    tab = TB.build_table(B, f, -3.0, 3.0, "mm", transition=tr)
    hd = TB.header(tab.blob)
    assert hd.layout_version == 5 and hd.pi.n == tr.n == tab.n_ops
    raw = np.frombuffer(tab.blob[hd.pi.offset:hd.pi.offset + 8 * tr.n], "<i4")
    assert np.array_equal(raw[:tr.n], to_q16(tr.r))
    assert raw[tr.n:].sum() == 65536 and np.max(np.abs(from_q16(raw[tr.n:]) - tr.w)) <= 2 / 65536
    # Pure play: no operator block, still layout 2, loads.
    assert TB.build_table(B, f, -3.0, 3.0, "mm").n_ops == 0
    # A corrupted operator weight is refused by the loader, with its reason.
    bad = bytearray(tab.blob)
    off = hd.pi.offset + 4 * tr.n
    bad[off:off + 4] = int(-1).to_bytes(4, "little", signed=True)
    with pytest.raises(TB.TableError):
        TB.CalibTable(bytes(bad))  # CRC first
    with pytest.raises(TB.TableError, match="refused"):
        TB.CalibTable(_reseal(bytes(bad)))


def _reseal(blob: bytes) -> bytes:
    ffi, lib = core()
    b = bytearray(blob)
    off = ffi.offsetof("pst_header_t", "crc32")
    b[off:off + 4] = int(lib.calib_table_crc(bytes(b), len(b))).to_bytes(4, "little")
    return bytes(b)


def test_set_generation_refuses_a_corrupted_blob():
    blob = TB.builtin_table()
    assert TB.header(TB.set_generation(blob, 7)).generation == 7
    bad = bytearray(blob)
    bad[-1] ^= 1
    with pytest.raises(TB.TableError, match="CRC"):
        TB.set_generation(bytes(bad), 7)


def test_fixed_point_matches_the_float_chain():
    B, f, tr = _fixture_model()
    tab = TB.build_table(B, f, -3.0, 3.0, "mm", transition=tr)
    err = TB.table_errors(tab, B, f, -3.0, 3.0, tr)
    # Measured: direct 2.1e-3 deg (the f grid's interpolation, as for the pure play: 2.8e-3),
    # compensator 1.8e-4 mm. Bounds about 3x.
    assert err["direct_c_deg_max"] < 6e-3, err
    assert err["comp_q_max"] < 6e-4, err


def test_reduced_path_gives_the_full_rate_operators_at_the_frames():
    data, q, _, _ = ref_session(np.zeros(1), np.ones(1))
    r = np.array([0.0, 0.05, 0.3, 0.9])
    z = ref_play(q, B_MM / 2, q[0])  # independent loop at the encoder rate
    ref = np.column_stack([ref_play(z, ri, z[0]) for ri in r])
    k = np.searchsorted(data.t_enc, data.t_frame)  # the frames are encoder samples here
    # Exact in exact arithmetic (rate independence); measured 0 (float64 identical).
    assert np.max(np.abs(data.ops_at_frames(r) - ref[k])) < 1e-12


def test_rolling_origins_fit_on_the_past_and_judge_the_next_block():
    data, *_ = ref_session(np.zeros(1), np.ones(1))
    splits = T.rolling_origins(data, 4)
    F = data.t_frame.size
    seen = np.zeros(F, bool)
    for j, (tr_m, te_m) in enumerate(splits):
        assert not np.any(tr_m & te_m) and te_m.sum() >= F // 8 - 1
        assert data.t_frame[tr_m].max() < data.t_frame[te_m].min()  # the past only
        assert tr_m.sum() == pytest.approx(F * (0.5 + j / 8), abs=1)
        seen |= te_m
    # The judged blocks tile the second half; the first half (the record's start) is never judged.
    assert np.array_equal(seen, data.t_frame >= np.sort(data.t_frame)[int(round(F * 0.5))])


def test_tall_skinny_r_is_the_r_of_a_householder_qr():
    # Blocks of rows reduced, then the stacked R's: R^T R = H^T H and |R| that of one QR of H
    # (rows may differ in sign), with and without rows left over, and below two blocks.
    rng = np.random.default_rng(3)
    for m in (40, 2 * T.TSQR_BLOCK + 7, 9 * T.TSQR_BLOCK):
        H = rng.normal(size=(m, 16)) * np.logspace(0, 4, 16)  # columns 4 decades apart
        R = T.tall_skinny_r(H)
        R0 = np.linalg.qr(H, mode="r")
        assert R.shape == (16, 16) and np.allclose(np.tril(R, -1), 0.0)
        assert np.allclose(np.sign(np.diag(R))[:, None] * R, np.sign(np.diag(R0))[:, None] * R0,
                           rtol=1e-12, atol=1e-10 * np.abs(R0).max())


def test_compressed_projection_gives_the_trust_region_what_the_frames_give():
    # The (n + 1)-row residual and Jacobian handed to least_squares carry the F-row problem's
    # cost, gradient and Gauss-Newton matrix, and a tightly converged fit lands on the same weights.
    from scipy.optimize import least_squares

    data, *_ = ref_session(threshold_rule(ref_session(np.zeros(1), np.ones(1))[0]), np.r_[0.4, np.full(15, 0.6 / 15)])
    P = data.ops_at_frames(threshold_rule(data))
    vp = T._SplineProjection(P, data.c, 14, 1e-3)
    cp = T._CompressedProjection(vp)
    x = np.random.default_rng(0).uniform(0.0, 0.3, 15)
    f, J, r, K = vp.resid(x), vp.jac(x), cp.resid(x), cp.jac(x)
    assert r.shape == (16,) and K.shape == (16, 15)
    assert r @ r == pytest.approx(f @ f, rel=1e-12)
    assert np.allclose(K.T @ r, J.T @ f, rtol=1e-9, atol=1e-12 * np.abs(J.T @ f).max())
    assert np.allclose(K.T @ K, J.T @ J, rtol=1e-9, atol=1e-12 * np.abs(J.T @ J).max())
    kw = dict(bounds=(0.0, 1e3), ftol=1e-14, xtol=1e-14, gtol=1e-14, max_nfev=500, tr_solver="exact")
    full = least_squares(vp.resid, np.full(15, 1 / 15), jac=vp.jac, **kw)
    comp = least_squares(cp.resid, np.full(15, 1 / 15), jac=cp.jac, **kw)
    assert comp.cost == pytest.approx(full.cost, rel=1e-9)
    assert np.allclose(comp.x, full.x, atol=1e-6)


def test_a_fold_fitted_again_starts_from_the_cross_validations_weights():
    # transition.cv_start: each scored fold's weights are kept on the FitData under the
    # candidate and the exact training frames; another mask gets None.
    data, *_ = ref_session(threshold_rule(ref_session(np.zeros(1), np.ones(1))[0]), np.r_[0.4, np.full(15, 0.6 / 15)])
    mc = T.ModelChoice(data, "pi")
    mc.result()
    cand = mc.cands[0]
    scored = [(tr, te) for tr, te in T.rolling_origins(data, T.KFOLD) if te.sum() >= 3 and tr.sum() >= 10]
    assert len(scored) == len(cand.errs) >= 2
    v_last = T.cv_start(data, cand.key, scored[-1][0])
    assert v_last is not None and np.array_equal(v_last, cand._v)
    for tr, _ in scored:
        assert T.cv_start(data, cand.key, tr).shape == (cand.n - 1,)
    other = scored[0][0].copy()
    other[np.flatnonzero(other)[-1]] = False
    assert T.cv_start(data, cand.key, other) is None
