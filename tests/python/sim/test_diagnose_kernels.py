"""The diagnosis' C kernels and vectorised design agree bit for bit with their Python references
(the recursions in fitmodel.py / model.py, np.interp column by column, the sparse B-spline
design matrix), on inputs that exercise every branch: sticks and slips, clipping at both band
edges, ties with the band, knots hit exactly, rows outside the grid."""

import numpy as np
import pytest
from scipy.interpolate import BSpline

from playscope.base import kernels
from playscope.diagnose import fitmodel
from playscope.fit.model import play_on_edges

pytestmark = pytest.mark.skipif(not kernels.available(), reason="no C compiler for the diagnosis kernels")


def _drive(n=6000, seed=0):
    """A back-and-forth input with holds, ramps and noise (mm), and band edges around it."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    q = 1.2 * np.sin(2 * np.pi * t / 7.0) + 0.3 * np.sin(2 * np.pi * t / 1.3) + rng.normal(0, 0.01, n)
    q[1000:1200] = q[1000]  # a hold: the recursions' still branches
    half = 0.15 + 0.05 * np.cos(q)
    return q, q - half, q + half


def test_play_and_viscous_play_bit_for_bit():
    q, lo, hi = _drive()
    lo[50] = hi[50] = 0.25  # a zero-width band: ties of min and max
    for z0 in (0.0, lo[0], 5.0):
        assert np.array_equal(kernels.play_on_edges(lo, hi, z0), play_on_edges(lo, hi, z0))
        for a in (1.0, 0.3, 0.01):
            assert np.array_equal(fitmodel._viscous_play(lo, hi, z0, a),
                                  fitmodel._viscous_play(lo, hi, z0, a, native=False))


def test_the_record_models_play_with_its_drags_and_its_band_bit_for_bit():
    # onset_model's bookkeeping (the last drag and its edge) and the band at the input, in C against
    # their numpy references: a first state inside the band (samples before the first drag), a
    # zero-width band (z on both edges: the lower counts), a hold, and B-spline widths that go
    # negative (clipped to 0)
    from playscope.fit import onset_model as OM

    q, lo, hi = _drive()
    lo[50] = hi[50] = 0.25
    for z0 in (0.5 * (lo[0] + hi[0]), lo[0], 5.0):
        ref = OM.play_drags_ref(lo, hi, z0)
        got = kernels.play_drags(lo, hi, z0)
        assert all(np.array_equal(a, b) for a, b in zip(got, ref))
    assert ref[1][0] == 0 and ref[2][0] == 0.5  # z0 = 5.0: dragged by the upper edge at once
    assert (OM.play_drags_ref(lo, hi, 0.5 * (lo[0] + hi[0]))[1] < 0).sum() > 0  # a first hold inside the band
    rec = OM.make_record(np.arange(q.size) / 50.0, q, np.array([1.0, 7.0]), np.array([q[50], q[350]]),
                         np.arange(0.0, 100.0, 0.04), np.zeros((2500, 2)), 25.0)
    cases = set()
    for n_b in (1, 4, 16):
        m = OM.RecordModel(rec, n_b, 6, OM.Terms(), None)
        cB = np.linspace(-0.05, 0.4, n_b)
        B = np.maximum(m.Phi_B @ cB if m.Phi_B is not None else np.full(rec.q.size, cB[0]), 0.0)
        lo_c, hi_c = kernels.band_input(rec.q, m._taps[0], m._taps[1], cB)
        assert np.array_equal(lo_c, rec.q - 0.5 * B) and np.array_equal(hi_c, rec.q + 0.5 * B)
        assert (n_b == 1) or (B == 0.0).any()
        for f in (0.0, 0.3, 1.0):  # the band and the play in one pass: the same bits as the two
            z0 = float(lo_c[0] + f * (hi_c[0] - lo_c[0]))
            z, last, side, lo0, hi0 = kernels.band_play_drags(rec.q, m._taps[0], m._taps[1], cB, f)
            want = kernels.play_drags(lo_c, hi_c, z0)
            assert all(np.array_equal(a, b) for a, b in zip((z, last, side), want))
            assert (lo0, hi0) == (lo_c[0], hi_c[0])
        # the play's gradient over B at grid samples, some before the first drag (last < 0): the rows of
        # edge_gradient times the edge's side, bit for bit (the zeros' signs too), and z_gradient with it
        z, band0, last, side = m.play_drags(cB, 0.0)
        k = np.r_[0, 1, 2, np.arange(3, q.size, 37)]
        lk, sk = last[k], side[k]
        ref = np.zeros((k.size, n_b))
        ok = lk >= 0
        ref[ok] = m.edge_gradient(cB, lk[ok], z[lk[ok]], sk[ok])
        got = kernels.drag_gradient(m._taps[0], m._taps[1], lk, sk, n_b)
        assert np.array_equal(got.view(np.int64), ref.view(np.int64))
        cases |= {"before the first drag"} if (~ok).any() else set()
        cases |= {"lower edge"} if ((sk < 0) & ok).any() else set()
        st = {"z": z, "band0": band0, "last": last, "side": side}
        with pytest.MonkeyPatch.context() as mp:
            want = m.z_gradient(cB, st, k, 0.0)
            mp.setattr(kernels, "available", lambda: False)
            ref_g = m.z_gradient(cB, st, k, 0.0)
        assert all(np.array_equal(a.view(np.int64), b.view(np.int64)) for a, b in zip(want, ref_g))
        for x0 in (-3.0, 0.0, 2.5):  # the model's play through it: the band's edges then the reference play
            from scipy.special import expit

            lo_e, hi_e = m.edges(cB)
            got = m.play_drags(cB, x0)
            want = OM.play_drags_ref(lo_e, hi_e, float(lo_e[0] + expit(x0) * (hi_e[0] - lo_e[0])))
            assert all(np.array_equal(a, b) for a, b in zip((got[0], got[2], got[3]), want))
            assert got[1] == (lo_e[0], hi_e[0])
    assert cases == {"before the first drag", "lower edge"}


def test_the_drag_gradient_refuses_a_sample_past_its_table():
    cols, vals = np.zeros((5, 1), np.int32), np.ones((5, 1))
    assert kernels.drag_gradient(cols, vals, np.array([-1, 4]), np.array([0.5, -0.5]), 1).tolist() == [[0.0], [-0.5]]
    with pytest.raises(ValueError):
        kernels.drag_gradient(cols, vals, np.array([5]), np.array([0.5]), 1)
    with pytest.raises(ValueError):
        kernels.drag_gradient(cols + 1, vals, np.array([0]), np.array([0.5]), 1)


def test_the_record_models_first_moves_are_its_references():
    # onset_model.onsets' search, in C against the numpy reference: a span whose first move is at its
    # start, one with none (held to the next span), one starting at sample 0 (no move can be there),
    # one past the grid, a NaN (it moves: NaN != NaN) and a span that ends where a move begins
    from playscope.fit import onset_model as OM

    q, lo, hi = _drive()
    z = OM.play_drags_ref(lo, hi, 0.5 * (lo[0] + hi[0]))[0]
    z[3000] = np.nan
    start = np.array([0, 10, 1000, 1100, 2990, 2999, 3001, 5990, 7000])
    stop = np.array([5, 400, 1150, 1300, 3000, 3001, 3010, 6100, 8000])
    got, ref = kernels.first_moves(z, start, stop), OM._first_moves_ref(z, start, stop)
    assert np.array_equal(got, ref) and got.dtype == ref.dtype == np.int64
    assert ref[2] == -1 and ref[5] == 3000 and ref[-1] == -1  # the hold, the NaN, past the grid
    rng = np.random.default_rng(3)
    a = np.sort(rng.integers(0, z.size, 200))
    b = a + rng.integers(0, 300, 200)
    assert np.array_equal(kernels.first_moves(z, a, b), OM._first_moves_ref(z, a, b))
    held = np.full(50, 2.0)  # no move anywhere
    assert np.array_equal(kernels.first_moves(held, [1, 10], [20, 60]), OM._first_moves_ref(held, np.array([1, 10]), np.array([20, 60])))
    with pytest.raises(ValueError):
        kernels.first_moves(z, [1, 2], [3])


def test_switch_bit_for_bit():
    q, _, _ = _drive(seed=1)
    for travel in (1e-3, 0.05, 0.4, 10.0):
        assert np.array_equal(fitmodel._switch(q, travel), fitmodel._switch(q, travel, native=False))
    assert np.array_equal(fitmodel._switch(q[:1], 0.1), fitmodel._switch(q[:1], 0.1, native=False))


@pytest.mark.parametrize("static,kin,fn,zeta", [(0.02, 0.5, 20.0, 0.5), (0.05, 0.2, 12.0, 0.05),
                                                 (1e-4, 0.5, 60.0, 1.0), (0.0, 0.5, 20.0, 0.5)])
def test_karnopp_bit_for_bit(static, kin, fn, zeta):
    z, _, _ = _drive(seed=2)
    c = fitmodel._karnopp_carrier(z, 50.0, static, kin, fn, zeta)
    r = fitmodel._karnopp_carrier(z, 50.0, static, kin, fn, zeta, native=False)
    assert np.array_equal(c, r)
    if static > 0.01:  # the carrier really sticks and slips here (else the test proves little)
        assert np.mean(np.diff(c) == 0.0) > 0.1 and np.max(np.abs(c - z)) > static


@pytest.mark.parametrize("effects,side", [((), "actuator"), (("cable_elongation", "camera_delay"), "actuator"),
                                          (("dead_zone", "drift"), "distal"), (("handeye_direction", "stick_slip"), "actuator")])
def test_design_on_rows_is_the_full_design_sliced(effects, side):
    """A fit's rows only (the first part of the record, with gaps) give the rows of the full design."""
    q, _, _ = _drive(n=3000, seed=5)
    t = np.arange(q.size) / 50.0
    tm = np.arange(0.013, t[-1], 0.021)
    data = fitmodel.Data(t, q, tm, np.interp(tm, t, 10 * q), 0.0)
    m = fitmodel.Model(data, effects, dead_zone_side=side)
    th = m.init.copy()
    if "camera_delay" in effects:
        th[m.names.index("camera_delay.delay_s")] = 0.037
    full = m.design(th)
    for rows in (tm < 0.5 * tm[-1], (tm < 0.7 * tm[-1]) & (np.arange(tm.size) % 3 > 0), tm > 0.0):
        assert np.array_equal(m.design(th, rows), full[rows])


def test_the_dense_basis_and_lowpass_columns():
    x = np.clip(np.random.default_rng(4).uniform(-2, 2, 4000), -1.5, 1.5)
    inner = np.linspace(-1, 1, fitmodel.N_FKNOTS + 2)
    t = np.r_[[-1.5] * 4, inner[1:-1], [1.5] * 4]
    P = fitmodel.design_dense(x, t, t.size - 4)  # the basis the diagnosis model builds
    assert np.array_equal(P, BSpline.design_matrix(x, t, 3).toarray())
    L = fitmodel.lowpass(P, 0.3, 50.0)
    assert np.array_equal(L, np.column_stack([fitmodel.lowpass(P[:, j], 0.3, 50.0) for j in range(P.shape[1])]))


def test_the_tip_modes_filter_and_its_gradient_drive_bit_for_bit():
    # onset_model's tip mode in C against scipy.signal.lfilter, and its B gradient's pass (the edge
    # gradient built row by row from a table of taps, second differences, the filter, read between
    # grid samples) against the dense numpy pipeline: held runs (a row kept), samples before any
    # drag (the first state's row), zero drives and frames sharing a grid step
    from scipy.signal import lfilter

    from playscope.fit import onset_model as OM

    rng = np.random.default_rng(3)
    n, R, w = 5000, 6, 4
    u = rng.normal(size=n)
    u[100:300] = 0.0
    b, a = OM._tip_filter(4.3, 0.07, 1e-3)
    assert np.array_equal(kernels.tip_mode(u, b[1], a[1], a[2]), lfilter(b, a, u))
    K = 900
    cols = np.array([rng.choice(R, w, replace=False) for _ in range(K)], np.int32)
    vals = rng.normal(size=(K, w))
    src = np.sort(rng.integers(0, K, n))
    src[:40] = -1                           # before the first drag
    src[2000:2300] = src[1999]              # a hold keeps its last drag's row
    scale = rng.choice([-0.5, 0.5], n)
    pre = rng.normal(size=R)
    wd = rng.normal(size=n - 2)
    pos = np.sort(np.r_[rng.uniform(0, n - 3.000001, 200), [17.5, 17.25]])
    i0 = pos.astype(int)
    wgt = pos - i0
    Z = np.zeros((R, n))
    for j in range(w):
        Z[cols[np.maximum(src, 0), j], np.arange(n)] = vals[np.maximum(src, 0), j] * scale
    Z[:, src < 0] = pre[:, None]
    x = lfilter(b, a, np.diff(Z, 2, axis=1) * wd, axis=1)
    ref = (x[:, i0] * (1.0 - wgt) + x[:, i0 + 1] * wgt).T
    got = kernels.tip_mode_edges(cols, vals, src, scale, pre, wd, b[1], a[1], a[2], i0, 1.0 - wgt, wgt)
    assert np.array_equal(got, ref)
    with pytest.raises(ValueError):
        kernels.tip_mode_edges(cols, vals, src, scale, pre, wd, b[1], a[1], a[2], i0[::-1], 1.0 - wgt, wgt)
