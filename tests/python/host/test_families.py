"""The model choice across families (playscope.fit.families) inside `calibrate`, thin records, a
refused row in the in-situ evaluation, and each family's table through the loader.

The synthetic records come from generators written here, sharing no code with the fitters: a
per-threshold play loop in plain Python, cosine strokes between turning points, and the angle
block-sampled by np.interp."""

from __future__ import annotations

import json
import os
import types
from pathlib import Path

import numpy as np
import pytest

from playscope.fit import families as FAM
from playscope.evaluate import insitu_split as insitu
from playscope.fit import transition as T
from playscope.fit.calibration import Calibration, calibrate
from playscope.fit.model import play_operator
from playscope.io.session import Robot, Session
from playscope.fit.table_build import CalibTable, TableError, build_table

from .forkpipe import through_the_pipe

# As tests/python/conftest.py: $PLAYSCOPE_REAL_DATA, else ../shared/data/real (read in place).
ENDOSCOPE = Path(os.environ.get("PLAYSCOPE_REAL_DATA", Path(__file__).resolve().parents[3].parent / "shared" / "data"
                                / "real")) / "endoscope"


# --------------------------------------------------------------------------- generators
def strokes(tops, lows, per_stroke=900):
    """q (mm) from 0 through alternating tops and lows along cosine profiles."""
    pts = [0.0]
    for a, b in zip(tops, lows):
        pts += [a, b]
    seg = np.linspace(0, 1, per_stroke, endpoint=False)
    q = np.concatenate([a + (b - a) * 0.5 * (1 - np.cos(np.pi * seg)) for a, b in zip(pts[:-1], pts[1:])])
    return np.r_[q, pts[-1]]


def play_loop(q, r):
    """Classical play operator of threshold r, state at q[0] (Brokate & Sprekels)."""
    out, y = [], q[0]
    for x in q:
        if x - y > r:
            y = x - r
        elif y - x > r:
            y = x + r
        out.append(y)
    return np.array(out)


def session_of(q, c, rate_hz=500.0, fps=25.0, noise_deg=0.02, seed=0) -> Session:
    """An angle session: encoder at rate_hz, angle sampled at fps with Gaussian noise."""
    t = np.arange(q.size) / rate_hz
    tf = np.arange(0.0, t[-1], 1.0 / fps)
    cf = np.interp(tf, t, c) + np.random.default_rng(seed).normal(0, noise_deg, tf.size)
    return Session(actuator_unit="mm", distal_kind="angle", robot=Robot("constant_curvature", 20.0, 0.0, 3.0),
                   encoder={"t_s": t, "q": q}, distal={"t_s": tf, "c_deg": cf}, t_delay_s=0.0)


TOPS = [4.0, 3.2, 2.6, 3.6, 4.0, 2.2, 3.0, 4.0]
LOWS = [-3.0, -2.2, -3.6, -1.8, -3.0, -2.6, -3.6, 0.0]


def play_record():
    """Constant play (width 0.8 mm) + a smooth increasing f: the pure play's family."""
    q = strokes(TOPS, LOWS)
    z = play_loop(q, 0.4)
    return session_of(q, 9.0 * z + 3.0 * np.tanh(0.6 * z))


def pi_record():
    """A PI operator without a sharp play: weights spread over thresholds 0..1.4 mm, small at 0,
    so the tip creeps after each reversal; f linear."""
    q = strokes(TOPS, LOWS)
    r = np.linspace(0.0, 1.4, 8)
    w = np.r_[0.04, np.full(7, 0.96 / 7)]
    y = sum(wi * play_loop(q, ri) for wi, ri in zip(w, r))
    return session_of(q, 10.0 * y)


def relax_loop(x, kappa, lam):
    """The travel-domain relaxation written from its equations (docs/method.md): output
    v = x + kappa (r - x), then r moves towards x by min(|v - v_prev| / lam, 1 - kappa) of the
    gap; r and v_prev start at x[0]."""
    out, r, vp = [], x[0], None
    for xk in x:
        v = xk + kappa * (r - xk)
        vp = v if vp is None else vp
        r += min(abs(v - vp) / lam, 1.0 - kappa) * (xk - r)
        vp = v
        out.append(v)
    return np.array(out)


KAPPA, LAM = 0.4, 0.6  # planted relaxation: 40 % of the output creeps over 0.6 mm of travel


def relaxed_record():
    """The play record's play (0.8 mm) and f, with a relaxation on the play centre before f."""
    q = strokes(TOPS, LOWS)
    v = relax_loop(play_loop(q, 0.4), KAPPA, LAM)
    return session_of(q, 9.0 * v + 3.0 * np.tanh(0.6 * v))


def spy_context(monkeypatch):
    """Calls to families.choose record their Context (what calibrate built)."""
    seen = {}
    real = FAM.choose

    def spy(ctx, reversals, families=None, source=None):
        seen["ctx"], seen["reversals"] = ctx, reversals
        return real(ctx, reversals, families, source)

    monkeypatch.setattr(FAM, "choose", spy)
    return seen


@pytest.fixture(scope="module")
def auto_cal():
    """auto_cal(record) -> (calibrate(record(), model_kind="auto"), the Context it gave
    families.choose): each generator record calibrated once for the module (a calibration takes
    seconds; calibrate is deterministic, and the tests only read what it returns)."""
    done = {}

    def get(record):
        if record.__name__ not in done:
            mp = pytest.MonkeyPatch()
            seen = spy_context(mp)
            try:
                cal = calibrate(record(), model_kind="auto")
            finally:
                mp.undo()
            done[record.__name__] = (cal, seen["ctx"])
        return done[record.__name__]
    return get


# --------------------------------------------------------------------------- the choice
# right: families that hold the generating model; wrong: ones that cannot (onset_transition reduces to
# the pure play when its own choice finds no transition, so it is neither for the play record).
@pytest.mark.parametrize("record,right,wrong", [(play_record, {"onset_play", "const_play"}, {"pi_const"}),
                                                (pi_record, {"onset_transition", "pi_const"}, {"onset_play", "const_play"})])
def test_choice_picks_the_family_that_generated_the_record(record, right, wrong, auto_cal):
    cal, _ = auto_cal(record)
    ch = cal.family_choice
    cvs = {d["family"]: d["cv_rmse_deg"] for d in ch["candidates"]}
    print(record.__name__, cal.family, cvs)
    assert [d["family"] for d in ch["candidates"]] == [f.name for f in FAM.FAMILIES]
    assert cal.family in right, cvs
    # The other kind is clearly worse on the same folds: the choice sees a difference, not noise.
    other = min(v for k, v in cvs.items() if k in wrong)
    assert other > 1.5 * cvs[cal.family]
    # What the table carries is the chosen family's, and the JSON says so.
    assert cal.doc["model_family"]["family"] == cal.family
    assert ("B" in cal.doc["model_family"]) and (cal.doc["model_family"]["B"] is None) == \
        (cal.family in ("onset_play", "onset_transition"))


def test_calibration_round_trip_writes_the_same_table(tmp_path, auto_cal):
    cal, _ = auto_cal(pi_record)
    cal.save(tmp_path / "cal.json")
    back = Calibration.load(tmp_path / "cal.json")
    assert back.family == cal.family and back.family_choice == cal.family_choice
    a = build_table(cal.B_model, cal.f, *cal.q_range, "mm", transition=cal.transition).blob
    b = build_table(back.B_model, back.f, *back.q_range, "mm", transition=back.transition).blob
    assert a == b


@pytest.mark.parametrize("record", [pi_record, relaxed_record])
def test_the_calibration_is_the_same_whichever_process_fitted_each_item(record, auto_cal, relaxed_cal, monkeypatch):
    # calibrate shares its independent items with a forked child (the model choice per B
    # alternative, the families' scores and the relaxation's search); what comes back through the
    # pipe is a copy, and the calibration must go on from it exactly as from the item fitted here.
    # The PI record's kept model choice carries the folds' weights the family choice's onset
    # transition starts from (transition.cv_start: with the copy's B the calibration once started
    # afresh, and its result hung on which process had fitted the kept alternative); the relaxed
    # record's relaxation is searched in one process and its member fitted in full in the other.
    from playscope.base import forkmap
    from playscope.fit import calibration as C

    cal = relaxed_cal if record is relaxed_record else auto_cal(record)[0]
    assert cal.doc["transition"]["model"] == "pi" if record is pi_record else cal.family == "onset_play_relax"
    monkeypatch.setattr(forkmap, "can_fork", lambda: False)
    here = calibrate(record(), model_kind="auto").doc  # every item fitted in this process, in turn
    monkeypatch.setattr(C, "fork_map", through_the_pipe)
    monkeypatch.setattr(forkmap, "fork_map", through_the_pipe)
    assert json.dumps(calibrate(record(), model_kind="auto").doc) == json.dumps(here)


# --------------------------------------------------------------------------- the relaxation as a family
@pytest.fixture(scope="module")
def relaxed_cal():
    return calibrate(relaxed_record(), model_kind="auto")


def test_choice_takes_the_relaxation_on_a_record_that_has_one(relaxed_cal):
    cal = relaxed_cal
    cvs = {d["family"]: d["cv_rmse_deg"] for d in cal.family_choice["candidates"]}
    print(cal.family, cal.relax, cvs)
    assert cal.family.endswith("_relax") and cal.relax is not None, cvs
    # Every family without it is worse on the same folds by more than the chosen one's SE.
    plain = min(v for k, v in cvs.items() if not k.endswith("_relax") and v is not None)
    assert plain > cvs[cal.family] + next(d["cv_se_deg"] for d in cal.family_choice["candidates"]
                                          if d["family"] == cal.family)
    # The planted (kappa, lambda), fitted on every calibration frame (measured 0.374, 0.613 mm).
    assert cal.relax.kappa == pytest.approx(KAPPA, abs=0.08) and cal.relax.lam == pytest.approx(LAM, rel=0.25)
    assert cal.doc["model_family"]["choice"]["relax"] == cal.relax.to_json()


@pytest.mark.parametrize("record", [play_record, pi_record])
def test_choice_leaves_the_relaxation_out_on_records_without_one(record, auto_cal):
    cal, _ = auto_cal(record)
    assert not cal.family.endswith("_relax") and cal.relax is None
    assert cal.family_choice["relax"] is None


def image_record():
    """45 s of the host bench's image session (tests/python/host/synth: variable B, non-linear f,
    an 80 ms delay, marker pixels with 0.3 px noise): its relaxation search finds a kappa > 0
    that lowers the residual by ~3e-5 deg, so choose's SE shortcut is the one that acts (at
    0.05 px the record model's B leaves the relaxation nothing: kappa 0, the other shortcut)."""
    from playscope.fit import model

    from .synth import ROBOT, excitation, image_model_parts, true_B, true_f

    t, q, _ = excitation(v=0.4, rate_hz=1000.0)
    t, q = t[t < 45.0], q[t < 45.0]
    cam, he = image_model_parts()
    c = model.direct_model(q, true_B, true_f)
    tf = np.arange(0.0, t[-1], 1 / 25.0)
    uv = model.ImageModel(ROBOT, cam, he)(np.interp(tf - 0.08, t, c)) + np.random.default_rng(0).normal(0, 0.3, (tf.size, 2))
    return Session("mm", "image", ROBOT, {"t_s": t, "q": q}, cam, he, 0.08,
                   marker={"t_s": tf, "u_px": uv[:, 0], "v_px": uv[:, 1]})


@pytest.mark.parametrize("record,why", [(play_record, "kappa 0"), (pi_record, "kappa 0"),
                                        (image_record, "cannot win by the one-SE margin")])
def test_a_skipped_relaxed_member_would_not_have_won_its_cv(record, why, auto_cal):
    """The shortcuts of choose (a relaxed member whose search finds kappa 0, or whose in-sample
    gain is at most its base's CV SE, is not cross-validated) against the CV they skip, run here
    anyway on the same folds."""
    cal, ctx = auto_cal(record)
    rows = {d["family"]: d for d in cal.family_choice["candidates"]}
    skipped = [n for n in FAM.RELAXED if rows[n].get("skipped")]
    assert skipped and all(why in rows[n]["skipped"] for n in skipped), rows
    splits = T.rolling_origins(ctx.data, T.KFOLD)
    for name in skipped:
        base = rows[FAM.RELAXED[name]]
        ran = FAM.score(ctx, next(f for f in FAM.FAMILIES if f.name == name), splits)
        # The shortcut's own margin, the base's own CV SE (not the paired one of the choice: on
        # image_record the skipped member's CV is below its base's by more than one paired SE,
        # measured 1.5e-3 deg against a paired SE of 9.5e-4; the shortcut, not the CV, keeps it out).
        print(name, rows[name]["skipped"], ran["cv_rmse_deg"], base["cv_rmse_deg"], base["cv_se_deg"])
        assert ran["cv_rmse_deg"] is None or ran["cv_rmse_deg"] + base["cv_se_deg"] >= base["cv_rmse_deg"]


def test_chosen_relaxed_table_is_layout_4_bit_exact_and_follows_the_double_chain(relaxed_cal, tmp_path):
    from playscope.fit.table_build import header

    cal = relaxed_cal
    tab = build_table(cal.B_model, cal.f, *cal.q_range, "mm", transition=cal.transition, relax=cal.relax)
    assert header(tab.blob).layout_version == 5 and tab.cal.relax.kappa_q16 != 0
    q = relaxed_record().encoder["q"]
    c_tab = tab.predict(q)
    np.testing.assert_array_equal(CalibTable(tab.blob).predict(q), c_tab)
    # Against the double chain c = f(R[PI(play(q))]) (Calibration.predict): grids and Q16 rounding.
    err = float(np.max(np.abs(c_tab - cal.predict(q))))
    print("relaxed table: fixed vs float max", err)
    assert err < 0.02
    # The calibration file carries it: loaded back, the same v4 table byte for byte.
    cal.save(tmp_path / "cal.json")
    back = Calibration.load(tmp_path / "cal.json")
    assert back.relax == cal.relax
    assert build_table(back.B_model, back.f, *back.q_range, "mm", transition=back.transition,
                       relax=back.relax).blob == tab.blob
    # The board's row of evaluate-insitu runs the same table.
    row = insitu.fit_ours(None, cal, None, None)
    assert row.params["relax"] == cal.relax.to_json() and row.params["table_bytes"] == len(tab.blob)
    np.testing.assert_array_equal(row.predict(q), c_tab)


# --------------------------------------------------------------------------- every family's table
@pytest.fixture(scope="module")
def pi_context(auto_cal):
    return auto_cal(pi_record)[1]


@pytest.mark.parametrize("fam", FAM.FAMILIES + FAM.THIN_FAMILIES, ids=lambda f: f.name)
def test_each_family_table_loads_bit_exact_and_follows_its_float_model(pi_context, fam):
    ctx = pi_context
    m = fam.fit(ctx, None)
    tab = FAM.table_of(ctx, m)
    q = ctx.data.q_enc
    c_tab = tab.predict(q)
    # The blob as the board receives it: a fresh load gives the same fixed-point run, bit for bit.
    np.testing.assert_array_equal(CalibTable(tab.blob).predict(q), c_tab)
    # Strictly increasing f (eq. 9's inverse) and a PI the Krejci-Kuhnen inverse holds (w_0 > 0).
    y = np.linspace(m.f.lo, m.f.hi, 2001)
    assert np.all(m.sign * np.diff(m.f(y)) > 0)
    assert m.transition.w[0] > 0 and np.all(m.transition.w >= 0)
    # Fixed point against the double-precision chain c = f(R[PI(play(q; B))]) (R: the relaxation,
    # identity without one): the tables' grids and Q16 rounding only (measured <= 6.6e-4 deg on
    # this record, the four families without a relaxation).
    y = m.transition.direct(play_operator(q, m.transition.play_width(m.B)))
    c_float = m.f(y if m.relax is None else relax_loop(y, m.relax.kappa, m.relax.lam))
    err = float(np.max(np.abs(c_tab - c_float)))
    print(fam.name, "fixed vs float max", err)
    assert err < 3e-3
    # The CV's shortcut (the table run on the record's turning points and the frames) gives the
    # full run's values at the frames.
    t = ctx.data.t_enc
    np.testing.assert_allclose(FAM.predict_frames(ctx, tab), np.interp(ctx.data.t_frame, t, c_tab), atol=0.02)


# --------------------------------------------------------------------------- thin records
def var_play_loop(q, b_lo, b_hi, lo, hi):
    """Play of width B(z) = b_lo .. b_hi linear in the centre z over [lo, hi] (edges z + B(z)/2 = q
    going up, z - B(z)/2 = q going down, solved in closed form), state centred at q[0]."""
    k = (b_hi - b_lo) / (hi - lo)
    a = b_lo - k * lo  # B(z) = a + k z
    out, z = [], q[0]
    for x in q:
        up = (x - a / 2) / (1 + k / 2)
        down = (x + a / 2) / (1 - k / 2)
        z = min(down, max(up, z))
        out.append(z)
    return np.array(out)


def test_var_play_recovers_a_planted_linearly_varying_width(monkeypatch):
    # Two cycles over q in [-3, 4] (a thin record: 3 reversals): wide enough strokes that both
    # ends of the travel show their own width; f smooth and increasing.
    q = strokes([4.0, 4.0], [-3.0, -3.0], per_stroke=1500)
    z = var_play_loop(q, 0.4, 1.4, -3.0, 4.0)
    seen = spy_context(monkeypatch)
    calibrate(session_of(q, 9.0 * z + 3.0 * np.tanh(0.6 * z)), model_kind="auto")
    ctx = seen["ctx"]
    m = FAM.fit_var_play(ctx, None)
    # Measured: 0.41 / 1.37 mm at the ends of the travel; in-sample 0.036 deg against the constant play's 0.94.
    np.testing.assert_allclose(m.B(np.array([-3.0, 4.0])), [0.4, 1.4], atol=0.1)
    const = FAM.fit_const_play(ctx, None)
    rms = lambda mm: float(np.sqrt(np.mean((FAM.predict_frames(ctx, FAM.table_of(ctx, mm)) - ctx.data.c) ** 2)))  # noqa: E731
    assert rms(m) < 0.5 * rms(const)


def thin_record(seed=0):
    """2 cycles (4 reversals in the whole record, 2 in each half): play + a creep after it."""
    q = strokes([4.0, 4.0], [-3.0, 0.0], per_stroke=2500)
    z = play_loop(q, 0.5)
    y = 0.5 * z + 0.5 * play_loop(z, 0.6)
    return session_of(q, 8.0 * y + 2.0 * np.tanh(0.5 * y), seed=seed)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_thin_record_falls_back_to_constant_play_and_is_never_worse(seed):
    doc = insitu.evaluate_insitu(thin_record(seed), 0.5)
    r = doc["rows"]
    assert r["ours"]["params"]["family"] == "const_play"
    # The same model as the constant play + poly5 row, carried by Q16.16 tables.
    assert r["ours"]["rmse_deg"] <= r["const_play"]["rmse_deg"] + 1e-3
    assert abs(r["ours"]["rmse_deg"] - r["const_play"]["rmse_deg"]) < 1e-3


def thin_swings_record(kind, seed=0):
    """3 cycles (2 reversals and a third swing before the half): "pi" the thin record's play +
    creep, "play" a constant play (width 1 mm) and the same f."""
    q = strokes([4.0, 4.0, 4.0], [-3.0, -3.0, 0.0], per_stroke=2500)
    z = play_loop(q, 0.5)
    y = 0.5 * z + 0.5 * play_loop(z, 0.6) if kind == "pi" else z
    return session_of(q, 8.0 * y + 2.0 * np.tanh(0.5 * y), seed=seed)


def test_swing_folds_forecast_each_half_swing_from_the_third_on(monkeypatch):
    seen = spy_context(monkeypatch)
    calibrate(thin_swings_record("pi").slice_time(-np.inf, 15.0), model_kind="auto")
    ctx = seen["ctx"]
    folds = FAM.swing_splits(ctx)
    t = ctx.data.t_frame
    assert len(folds) == 2  # strokes of 5 s: reversals at 5 and 10 s, the third swing 10..15 s in two halves
    for train, test in folds:
        assert train.sum() > 0 and test.sum() > 0 and not np.any(train & test)
        assert t[train].max() < t[test].min()  # a forecast: trained on what came before only
        assert t[test].min() >= 10.0 - 0.05 and np.ptp(t[test]) < 2.6  # within one half of the third swing
    assert np.all(t[folds[0][1]] < t[folds[1][1]].min())


@pytest.mark.parametrize("seed", [0, 1])
def test_thin_record_takes_a_pi_form_when_its_swing_cv_supports_it(seed):
    r = insitu.evaluate_insitu(thin_swings_record("pi", seed), 0.5)["rows"]
    p = r["ours"]["params"]
    assert p["family"] == "pi_const"
    # measured 0.073 deg against 0.485 for the constant play + poly5 and 0.070 for the modified PI peer
    assert r["ours"]["rmse_deg"] < 0.25 * r["const_play"]["rmse_deg"]
    assert r["ours"]["rmse_deg"] < 1.15 * r["mpi"]["rmse_deg"]


def test_thin_record_of_a_constant_play_keeps_the_model_fitted_by_hand():
    r = insitu.evaluate_insitu(thin_swings_record("play"), 0.5)["rows"]
    assert r["ours"]["params"]["family"] in ("const_play", "onset_play")
    assert r["ours"]["rmse_deg"] <= r["const_play"]["rmse_deg"] + 1e-3


@pytest.mark.skipif(not ENDOSCOPE.is_dir(), reason="real endoscope recordings not present")
@pytest.mark.parametrize("stem", ["30", "60", "120"])
def test_thin_endoscope_development_records(stem):
    from playscope.io.importer import import_endoscope

    doc = insitu.evaluate_insitu(import_endoscope(ENDOSCOPE / f"{stem}.txt"), 0.5)
    r = doc["rows"]
    assert r["ours"]["refused"] is None
    assert r["ours"]["rmse_deg"] <= r["const_play"]["rmse_deg"] + 1e-3


# --------------------------------------------------------------------------- refused rows
def test_a_refused_table_is_its_rows_refusal_naming_the_file():
    cal = types.SimpleNamespace(q_range=(-1.0, 1.0), actuator_unit="mm")
    # f flat over half the travel: f^-1 jumps there, far above the precision ceiling (B / 16).
    flat = lambda q: 10.0 * np.minimum(np.asarray(q, float), 0.0) + 1e-9 * np.asarray(q, float)  # noqa: E731
    row = insitu._table_row("paper", lambda q: np.full(np.shape(q), 0.2), flat, cal, {}, source="rec.txt")
    assert row.predict is None and "rec.txt" in row.refused and "refused by calib_load" in row.refused


def test_evaluation_goes_on_past_a_refused_row(monkeypatch):
    s = play_record()

    def refused(cal_s, cal, q_c, c_c, source=None):
        return insitu.Row("ours", True, None, {"family": cal.family}, refused=f"{source}: table refused by calib_load: x")

    monkeypatch.setattr(insitu, "fit_ours", refused)
    doc = insitu.evaluate_insitu(s, 0.5, source="rec.txt")
    assert doc["rows"]["ours"]["refused"].startswith("rec.txt") and doc["rows"]["ours"]["rmse_deg"] is None
    assert all(doc["rows"][k]["rmse_deg"] > 0 for k in insitu.ROWS if k != "ours")
    assert any("ours" in n and "rec.txt" in n for n in doc["notes"])
    assert "refused: rec.txt" in insitu.format_insitu(doc)


@pytest.mark.skipif(not ENDOSCOPE.is_dir(), reason="real endoscope recordings not present")
def test_real_record_with_a_refused_row_does_not_abort():
    from playscope.io.importer import import_endoscope

    path = ENDOSCOPE / "120.txt"
    doc = insitu.evaluate_insitu(import_endoscope(path), 0.5, source=str(path))
    scored = [k for k in insitu.ROWS if doc["rows"][k]["refused"] is None]
    assert "ours" in scored and len(scored) >= len(insitu.ROWS) - 1
    for k in insitu.ROWS:
        if doc["rows"][k]["refused"]:
            assert str(path) in doc["rows"][k]["refused"]


def test_refusal_of_every_family_is_an_error_naming_none_loadable(pi_context, monkeypatch):
    def refuse(ctx, m, source=None):
        raise TableError("rec.txt", "table refused by calib_load: test")

    monkeypatch.setattr(FAM, "table_of", refuse)
    from playscope.base.errors import InputError

    with pytest.raises(InputError, match="rec.txt: no model family gives a table"):
        FAM.choose(pi_context, 10, source="rec.txt")


def test_record_without_any_onset_keeps_a_play_fitted_on_c():
    # No B sample from the onsets (as a record whose tip is never still after a reversal, the
    # detector's no_still): the families fitted on c alone still give a table.
    from playscope.fit.onsets import Onsets

    s = play_record()
    none = Onsets(*(np.zeros(0) for _ in range(6)), reasons={"no_still": 15})
    with pytest.raises(Exception, match="no usable reversal"):
        calibrate(s, model_kind="play", onsets=none)
    cal = calibrate(s, model_kind="auto", onsets=none)
    assert cal.n_b_samples == 0 and cal.family in {f.name for f in FAM.FAMILIES_FROM_C}
    assert any("no usable reversal" in w for w in cal.warnings)
    print(cal.family, {d["family"]: d["cv_rmse_deg"] for d in cal.family_choice["candidates"]})
    # The constant play fitted on c is the generating play (width 0.8 mm), and the model fits.
    assert cal.B_model(np.array([0.0]))[0] == pytest.approx(0.8, rel=0.1) or cal.family == "pi_const"
    c_hat = cal.predict(s.encoder["q"])
    e = np.interp(s.distal["t_s"], s.encoder["t_s"], c_hat) - s.distal["c_deg"]
    assert np.sqrt(np.mean(e * e)) < 0.1


def test_a_measured_play_wider_than_the_board_accepts_leaves_the_families_fitted_on_c():
    # B samples (here given, as a board's) of 4.5 mm on a record whose travel is 7.6 mm: no table
    # carrying that B loads (the loader's plausibility rule, a play within half the travel), so the
    # onset families cannot be the product's. With the families offered, the play is fitted on c
    # (the generating 0.8 mm) and the table loads; with the pure play asked for, the loader's refusal.
    from playscope.fit.calibration import b_beyond_board
    from playscope.fit.onsets import Onsets
    from playscope.fit.reversals import detect_reversals

    s = play_record()
    t, q = s.encoder["t_s"], s.encoder["q"]
    rt, rq, _ = detect_reversals(t, q, 0.01 * np.ptp(q))
    sgn = np.sign(np.interp(rt + 0.05, t, q) - rq)  # each reversal's new direction
    q2 = rq + 4.5 * sgn
    wide = Onsets(rt, rt + 0.5, rq, q2, 0.5 * (rq + q2), np.full(rt.size, 4.5), reasons={"given": int(rt.size)})
    assert b_beyond_board(lambda x: np.full(x.size, 4.5), (float(q.min()), float(q.max()))) == \
        pytest.approx((4.5, 0.5 * np.ptp(q)))
    assert b_beyond_board(lambda x: np.full(x.size, 3.7), (float(q.min()), float(q.max()))) is None
    with pytest.raises(TableError, match="travel / 2"):
        calibrate(s, model_kind="play", onsets=wide)
    cal = calibrate(s, model_kind="auto", onsets=wide)
    assert cal.family in {f.name for f in FAM.FAMILIES_FROM_C}
    assert any("more than the board accepts" in w for w in cal.warnings)
    assert cal.B_model(np.array([0.0]))[0] == pytest.approx(0.8, rel=0.1) or cal.family == "pi_const"
    c_hat = cal.predict(q)
    e = np.interp(s.distal["t_s"], t, c_hat) - s.distal["c_deg"]
    assert np.sqrt(np.mean(e * e)) < 0.1


def test_evaluation_without_any_onset_refuses_the_onset_rows_and_scores_ours(monkeypatch):
    from playscope.fit.onsets import Onsets

    none = Onsets(*(np.zeros(0) for _ in range(6)), reasons={"no_still": 3})
    from playscope.fit import calibration, onset_settings, onsets

    # the detector's module and the modules binding its name
    for mod in (onsets, calibration, onset_settings):
        monkeypatch.setattr(mod, "run_onsets", lambda *a, **k: none)
    doc = insitu.evaluate_insitu(play_record(), 0.5, source="rec.txt")
    r = doc["rows"]
    assert "no motion onset" in r["onset_lsq"]["refused"] and "rec.txt" in r["paper"]["refused"]
    assert r["ours"]["refused"] is None and r["ours"]["rmse_deg"] < 0.1
    assert r["ours"]["rmse_deg"] <= r["const_play"]["rmse_deg"] + 1e-3



def test_relaxed_calibration_through_playscope_tables(relaxed_cal, tmp_path):
    # `playscope tables` writes the relaxed model (layout 4): the same blob as the chosen table,
    # and its precision check holds against the double chain with the relaxation (direct model
    # and compensator, tables.table_errors).
    from playscope import pipeline
    from playscope.fit.table_build import header

    cal = relaxed_cal
    cal.save(tmp_path / "cal.json")
    w = pipeline.write_tables(tmp_path / "cal.json", tmp_path / "t.bin")
    assert header(w.table.blob).layout_version == 5 and w.table.cal.relax.kappa_q16 != 0
    assert w.table.blob == build_table(cal.B_model, cal.f, *cal.q_range, "mm", transition=cal.transition,
                                       relax=cal.relax).blob
    print("relaxed table errors", w.errors)
    # measured 2.9e-4 deg and 4.3e-5 mm (the compensator compared within a tick, tables.table_errors)
    assert w.errors["direct_c_deg_max"] < 3e-3 and w.errors["comp_q_max"] < 1e-3


def test_thin_rule_takes_the_lowest_swing_cv_once_the_hand_model_is_out(pi_context, monkeypatch):
    # The rule alone, on planted swing-CV rows (the conf0_60 endoscope record's at split 0.5, deg):
    # the constant play is more than one SE above the best, and the onset play, first by parameter
    # count, is within one SE of it but not the lowest. Thin: the lowest is kept; not thin: the
    # one-SE rule's first by parameter count.
    cv = {"onset_play": (1.868, 0.347), "const_play": (2.149, 0.294), "pi_const": (1.586, 0.360)}

    def planted(ctx, fam, splits, source=None):
        m, s = cv.get(fam.name, (None, None))
        return {"family": fam.name, "label": fam.label, "cv_rmse_deg": m, "cv_se_deg": s, "folds": 4,
                "refused": None if m is not None else "not planted"}

    monkeypatch.setattr(FAM, "score", planted)
    fams = [f for f in FAM.FAMILIES if f.name in cv]
    assert FAM.choose(pi_context, 2, fams)[1]["family"] == "pi_const"
    assert FAM.choose(pi_context, 10, fams)[1]["family"] == "onset_play"
    # The hand model within one SE of the best stays, thin.
    cv["const_play"] = (1.9, 0.3)
    assert FAM.choose(pi_context, 2, fams)[1]["family"] == "const_play"


def test_rolling_origin_rule_pairs_the_folds_thin_records_do_not(pi_context, monkeypatch):
    # Planted per-fold errors (deg) on four shared folds whose difficulty spreads widely (a far
    # reach, a fast stroke); pi_const is lower than the onset play on every fold, by 0.25-0.35.
    # The best's own SE (0.55) swallows that gap, the SE of the per-fold differences (0.02) does
    # not: on rolling origins the paired rule keeps pi_const, the old one the onset play.
    hard = np.array([0.5, 1.0, 2.0, 3.0])
    folds = {"onset_play": hard + [0.30, 0.25, 0.35, 0.30], "const_play": hard + [0.30, 0.25, 0.35, 0.30],
             "pi_const": hard}

    def planted(ctx, fam, splits, source=None):
        if fam.name not in folds:  # the thin-record members
            return {"family": fam.name, "label": fam.label, "cv_rmse_deg": None, "cv_se_deg": None,
                    "fold_rmse_deg": None, "folds": 0, "refused": "not planted"}
        e = folds[fam.name]
        return {"family": fam.name, "label": fam.label, "cv_rmse_deg": float(np.sqrt(np.mean(e ** 2))),
                "cv_se_deg": float(np.std(e, ddof=1) / 2.0), "fold_rmse_deg": e.tolist(), "folds": 4, "refused": None}

    monkeypatch.setattr(FAM, "score", planted)
    fams = [f for f in FAM.FAMILIES if f.name in folds]
    rows = {n: planted(None, next(f for f in fams if f.name == n), None) for n in folds}
    best = rows["pi_const"]
    gap = rows["onset_play"]["cv_rmse_deg"] - best["cv_rmse_deg"]
    assert FAM.one_se_margin(rows["onset_play"], best, paired=False) > gap  # the old rule keeps the onset play
    assert FAM.one_se_margin(rows["onset_play"], best, paired=True) < 0.1 * gap
    assert FAM.one_se_margin(best, best, paired=True) == 0.0
    assert FAM.choose(pi_context, 10, fams)[1]["family"] == "pi_const"
    # Thin (swing folds): the best's own SE, so the hand model within it stays.
    assert FAM.choose(pi_context, 2, fams)[1]["family"] == "const_play"
    # pi_const lower on average but not fold by fold (the differences swing in sign): the paired SE
    # is wide and the first family by parameter count stays.
    folds["onset_play"] = hard + [0.9, -0.5, 0.8, -0.2]
    assert FAM.choose(pi_context, 10, fams)[1]["family"] == "onset_play"


def test_score_rows_keep_the_per_fold_errors_the_rule_pairs(auto_cal):
    cal, _ = auto_cal(pi_record)
    rows = [d for d in cal.family_choice["candidates"] if d["cv_rmse_deg"] is not None]
    assert rows and all(len(d["fold_rmse_deg"]) == d["folds"] for d in rows)
    for d in rows:
        e = np.asarray(d["fold_rmse_deg"])
        assert d["cv_rmse_deg"] == pytest.approx(float(np.sqrt(np.mean(e ** 2))), rel=1e-12)
    # The chosen family is within the paired margin of the best, and no family before it is.
    best = min(rows, key=lambda d: d["cv_rmse_deg"])
    order = [f.name for f in FAM.FAMILIES]
    within = [d["family"] for d in rows if d["cv_rmse_deg"] <= best["cv_rmse_deg"] + FAM.one_se_margin(d, best, True)]
    assert cal.family == min(within, key=order.index)
