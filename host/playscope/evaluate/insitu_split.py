"""In-situ evaluation of one session, with state carried: calibrate on the part before a split,
score the part after, every model run from the record's first sample.

This is what a board that has been running all along would have predicted: the play and
hysteresis states at the split are those the part before left, not a fresh reset. Every
row is fitted on exactly the same calibration part (samples with t < t_split, reached only
through Session.slice_time) and scored on exactly the same test part (t >= t_split):

  linear      c = a q + b, least squares (no hysteresis)
  const_play  constant-width play + degree-5 polynomial, least squares (Reilink et al.)
  paper       onset B(q) + f_remain by the paper's morphological median line (section IV),
              on the fixed-point tables (firmware playop_step through cffi)
  onset_lsq   onset B(q) + play-consistent least-squares f_remain, fixed-point tables
  gpi         generalized Prandtl-Ishlinskii, 16 play operators (w >= 0) + cubic in q,
              scipy.optimize.lsq_linear (playscope.fit.peers.GeneralizedPI), double precision
  bouc_wen    Bouc-Wen, n = 1, scipy.optimize.least_squares (playscope.fit.peers.BoucWen), double
  mpi         modified Prandtl-Ishlinskii: 16 play operators (w >= 0) then a monotone-free output
              spline, by variable projection (playscope.fit.peers.ModifiedPI), double precision
  gpi_inc     the generalized PI with its cubic held increasing (peers.IncreasingGPI): invertible
  mpi_inc     the modified PI with its output spline monotone (ModifiedPI(monotone=True)): invertible,
              the pi_const family in double precision
  ours        the model family chosen inside the calibration part (playscope.fit.families: onset play,
              onset B + transition, generalized PI made invertible, constant play + poly5, by
              rolling-origin CV through the tables), fixed-point tables

The baselines and peers are fitted on the calibration frames the chain itself sees (angle
block-averaged at the chain's frame rate, or the per-frame pose estimate of eq. 8), so no
model gets more or cleaner data than another. Scored against the angle sensor, else the
simulator's truth.csv, else the per-frame pose estimate, at the measurement times.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..fit.baselines import fit_constant_play, fit_linear
from ..fit.f_remain import characteristic
from ..fit.reversals import frames_from_angle
from ..fit import model
from ..fit.calibration import calibrate
from ..base.errors import InputError
from ..fit.peers import BoucWen, GeneralizedPI, IncreasingGPI, ModifiedPI
from ..io.session import Session

FORMAT = "playscope-insitu/1"
ROWS = ["linear", "const_play", "paper", "onset_lsq", "gpi", "gpi_inc", "bouc_wen", "mpi", "mpi_inc", "ours"]
# The rows whose model has an inverse a compensator can run (the peers' invertible forms among them).
INVERTIBLE = ("linear", "paper", "onset_lsq", "gpi_inc", "mpi_inc")
LABELS = {
    "linear": "linear (c = a q + b)",
    "const_play": "constant play + poly5",
    "paper": "paper: onset B + morphological f_remain (sec. IV)",
    "onset_lsq": "onset B + least-squares f_remain",
    "gpi": "generalized PI: 16 plays (w >= 0) + cubic, lsq_linear",
    "bouc_wen": "Bouc-Wen (n = 1), least_squares",
    "mpi": "modified PI: 16 plays (w >= 0) + output spline",
    "gpi_inc": "generalized PI, cubic held increasing (invertible)",
    "mpi_inc": "modified PI, output monotone (invertible)",
    "ours": "ours: model family chosen by CV through the tables",
}
MIN_PART_S = 1.0  # a part shorter than this cannot hold a reversal cycle of any instrument

JSON_KEYS = ("format, session, distal_kind, judged_against, state, split {t_split_s, fraction, t_start_s, "
             "t_end_s, cal_frames, test_samples}, order [row], rows {row: {label, fixed_point, rmse_deg, "
             "max_deg, cal_rmse_deg (in sample, t < t_split), refused (the loader's reason naming the file, or null; "
             "the three figures are then null), params}}, notes [str]; rows: " + ", ".join(ROWS))


@dataclass
class Row:
    """One fitted model: predict maps the whole record's q (N,) to c (N,) deg, state from q[0].
    refused: why the board's loader refused the row's table (naming the file; predict is then
    None and the row is reported, not scored), else None."""

    name: str
    fixed_point: bool
    predict: Callable[[np.ndarray], np.ndarray] | None
    params: dict = field(default_factory=dict)
    refused: str | None = None


def split_time(t_s: np.ndarray, split: float | str) -> float:
    """The split instant (s, on the session clock) from a fraction of the duration in (0, 1)
    or a string "<seconds>s" counted from the first sample. Errors: InputError when it is
    malformed or leaves either part shorter than MIN_PART_S."""
    t0, t1 = float(t_s[0]), float(t_s[-1])
    text = str(split).strip()
    try:
        value = float(text[:-1] if text.endswith("s") else text)
    except ValueError:
        raise InputError(None, f"split {split!r} is neither a fraction in (0, 1) nor a time like 30s") from None
    if text.endswith("s"):
        ts = t0 + value
    elif 0.0 < value < 1.0:
        ts = t0 + value * (t1 - t0)
    else:
        raise InputError(None, f"split fraction {value} outside (0, 1); give a time as e.g. {value:g}s")
    if ts - t0 < MIN_PART_S or t1 - ts < MIN_PART_S:
        raise InputError(None, f"split at {ts - t0:.2f} s leaves a part shorter than {MIN_PART_S} s "
                         f"(record {t1 - t0:.2f} s long)")
    return ts


def calibration_frames(cal_s: Session, cal) -> tuple[np.ndarray, np.ndarray]:
    """The (q, c) frames of the calibration part the chain fits f_remain on (Fig. 9):
    angle block-averaged at the chain's frame rate, or LM pose estimates (eqs. 6-8)."""
    t_enc, q = cal_s.encoder["t_s"], cal_s.encoder["q"]
    td = cal.t_delay_s
    if cal_s.distal_kind == "angle":
        t_f, c_f = frames_from_angle(cal_s.distal["t_s"], cal_s.distal["c_deg"], cal.fps_frames)
    else:
        t_f, obs = cal_s.observations()
        im = model.ImageModel(cal_s.robot, cal_s.camera, cal_s.hand_eye)
        q_f = np.interp(t_f - td, t_enc, q)
        c_f, _ = im.estimate_c(obs, model.f_coarse(q_f, cal_s.robot.q_per_rad))
    return characteristic(t_enc, q, t_f, c_f, td)


def _table_row(name, B, f, cal, params, transition=None, source=None, relax=None) -> Row:
    """A row the board runs: its table (tables.build_table) through playop_step; a table the
    loader refuses gives a refused row (the reason, naming source) instead of an error, so the
    other rows are still scored."""
    from ..fit.table_build import TableError, build_table

    q0, q1 = cal.q_range
    try:
        tab = build_table(B, f, q0, q1, cal.actuator_unit, "remain", transition=transition, source=source,
                          relax=relax)
    except TableError as e:
        return Row(name, True, None, params, refused=str(e))
    except OverflowError as e:  # beyond the Q16.16 range
        return Row(name, True, None, params, refused=f"{source or '<input>'}: {e}")
    return Row(name, True, tab.predict, {**params, "table_bytes": len(tab.blob), "table_ops": tab.n_ops})


def fit_ours(cal_s: Session, cal, q_c: np.ndarray, c_c: np.ndarray, source: str | None = None) -> Row:
    """Ours: the table of the model family `calibrate` chose inside the calibration part
    (calibrate(model_kind="auto") -> families.choose: onset play, onset B + PI transition, the
    generalized PI made invertible or constant play + poly5, by rolling-origin CV through the
    tables; the transition's own operator count, span and b_scale by transition.choose_model),
    run through the firmware's playop_step. A table the loader refuses is a refused row."""
    tr = cal.transition
    choice = cal.model_choice or {}
    params = {"model": "play" if tr.is_play else "pi", "n_ops": tr.n, "r": tr.r.tolist(), "w": tr.w.tolist(),
              "b_scale": float(tr.b_scale), "r_span": choice.get("r_span"),
              "thresholds": "B-proportional" if tr.tmap is not None else "constant",
              "cv": [{k: d.get(k) for k in ("b_scale", "n", "r_span", "cv_rmse_deg")}
                     for d in choice.get("candidates", [])],
              "family": cal.family,
              "family_cv": [{k: d.get(k) for k in ("family", "cv_rmse_deg", "refused", "skipped")}
                            for d in (cal.family_choice or {}).get("candidates", [])]}
    rl = cal.relax
    params["relax"] = None if rl is None else rl.to_json()
    return _table_row("ours", cal.B_model, cal.f, cal, params, transition=tr, source=source, relax=rl)


def fit_rows(s: Session, t_split: float, progress=lambda it, **kw: it, source: str | None = None) -> dict[str, Row]:
    """Fit every row on the samples of s with t < t_split (and on nothing else).

    Returns {name: Row} in ROWS order. Errors: InputError (naming source) when the
    calibration part has too few reversals or onsets for the chain."""
    cal_s = s.slice_time(-np.inf, t_split)
    src = source or (str(s.path) if s.path else None)
    rows: dict[str, Row] = {}
    state: dict = {}

    def chain():
        # model_kind "auto": ours chooses its transition inside the calibration part; the pure
        # play's f_remain (cal.f_play) is fitted in the same call for the onset_lsq row.
        state["cal"] = cal = calibrate(cal_s, f_method="lsq", source=src, model_kind="auto")
        state["qc"] = calibration_frames(cal_s, cal)
        state["paper_f"] = cal.f_alt

    def baselines():
        q_c, c_c = state["qc"]
        lin = fit_linear(q_c, c_c)
        rows["linear"] = Row("linear", False, lambda q: lin(q), {})
        w, fp, Bc = fit_constant_play(q_c, c_c)
        rows["const_play"] = Row("const_play", False, lambda q: model.direct_model(q, Bc, fp), {"width": w})

    def tables():
        cal = state["cal"]
        nb = cal.n_b_samples
        if nb == 0:  # calibrate fitted the play on c alone: there is no onset B to tabulate
            why = f"{src or '<input>'}: no motion onset in the calibration part, so no onset B"
            rows["paper"] = Row("paper", True, None, {"b_samples": 0}, refused=why)
            rows["onset_lsq"] = Row("onset_lsq", True, None, {"b_samples": 0, "t_delay_s": cal.t_delay_s}, refused=why)
            return
        rows["paper"] = _table_row("paper", cal.B, state["paper_f"], cal, {"b_samples": nb, "f_remain": "morph"},
                                   source=src)
        rows["onset_lsq"] = _table_row("onset_lsq", cal.B, cal.f_play, cal, {"b_samples": nb, "f_remain": "lsq",
                                                                             "t_delay_s": cal.t_delay_s}, source=src)

    def gpi():
        m = GeneralizedPI.fit(*state["qc"])
        rows["gpi"] = Row("gpi", False, m.predict, {**m.params(), "fit_frames": int(state["qc"][0].size)})

    def bouc_wen():
        m = BoucWen.fit(*state["qc"])
        rows["bouc_wen"] = Row("bouc_wen", False, m.predict, m.params())

    def mpi():
        m = ModifiedPI.fit(*state["qc"])
        rows["mpi"] = Row("mpi", False, m.predict, m.params())

    def invertible():
        m = IncreasingGPI.fit(*state["qc"])
        rows["gpi_inc"] = Row("gpi_inc", False, m.predict, m.params())
        m = ModifiedPI.fit(*state["qc"], monotone=True)
        rows["mpi_inc"] = Row("mpi_inc", False, m.predict, m.params())

    def ours():
        rows["ours"] = fit_ours(cal_s, state["cal"], *state["qc"], source=src)

    steps = [("calibrate (onsets, B, transition choice, f_remain)", chain), ("linear, constant play", baselines),
             ("fixed-point tables", tables), ("generalized PI", gpi), ("Bouc-Wen", bouc_wen), ("modified PI", mpi),
             ("the peers' invertible forms", invertible),
             ("ours: the chosen family", ours)]
    bar = progress(steps, desc="fit", total=len(steps))
    for label, fn in bar:
        if hasattr(bar, "set_postfix_str"):
            bar.set_postfix_str(label)
        fn()
    return {k: rows[k] for k in ROWS}


def judged_samples(s: Session, t_split: float, t_delay_s: float, part: str = "test") -> tuple[np.ndarray, np.ndarray, str]:
    """Measurement times on the encoder clock (acquisition time = stamp - t_delay) and values
    of the test part (t >= t_split), or of the calibration part (part="cal", t < t_split, for
    the in-sample figure): (t (M,), c (M,) deg, what c is)."""
    if s.distal_kind == "angle":
        t, c, what = s.distal["t_s"], s.distal["c_deg"], "angle sensor"
    elif s.truth is not None:
        t, c, what = s.truth["t_s"], s.truth["c_deg"], "truth.csv (simulator)"
        t_delay_s = 0.0  # the simulator's truth is stamped at the pose's own time
    else:
        t_f, obs = s.observations()
        im = model.ImageModel(s.robot, s.camera, s.hand_eye)
        q_f = np.interp(t_f - t_delay_s, s.encoder["t_s"], s.encoder["q"])
        t, c, what = t_f, im.estimate_c(obs, model.f_coarse(q_f, s.robot.q_per_rad))[0], "pose estimate per frame (eq. 8)"
    t_acq = np.asarray(t, float) - t_delay_s
    after = np.asarray(t, float) >= t_split
    m = (after if part == "test" else ~after) & np.isfinite(c) & (t_acq >= s.encoder["t_s"][0]) & (t_acq <= s.encoder["t_s"][-1])
    return t_acq[m], np.asarray(c, float)[m], what


def score_rows(rows: dict[str, Row], s: Session, t_split: float, t_delay_s: float,
               progress=lambda it, **kw: it) -> tuple[dict, dict, dict, str, int]:
    """Run every row over the whole record from its first sample and score t >= t_split.
    Returns ({row: rmse_deg}, {row: max_abs_deg}, {row: rmse_deg on the calibration part, in
    sample}, judged_against, samples scored); a refused row (Row.refused) has None in each."""
    t_m, c_m, what = judged_samples(s, t_split, t_delay_s)
    t_c, c_c, _ = judged_samples(s, t_split, t_delay_s, part="cal")
    if t_m.size == 0:
        raise InputError(None, "no valid measurement after the split")
    q, t_enc = s.encoder["q"], s.encoder["t_s"]
    rm, mx, rc = {}, {}, {}
    for name, row in progress(rows.items(), desc="run over the record", total=len(rows)):
        if row.refused is not None:
            rm[name] = mx[name] = rc[name] = None
            continue
        c_hat = row.predict(q)
        e = np.interp(t_m, t_enc, c_hat) - c_m
        rm[name] = float(np.sqrt(np.mean(e * e)))
        mx[name] = float(np.max(np.abs(e)))
        rc[name] = float(np.sqrt(np.mean((np.interp(t_c, t_enc, c_hat) - c_c) ** 2))) if t_c.size else float("nan")
    return rm, mx, rc, what, int(t_m.size)


def evaluate_insitu(s: Session, split: float | str = 0.5, progress=lambda it, **kw: it,
                    source: str | None = None) -> dict:
    """Fit every row on the part before the split, score the part after with state carried.
    Returns the JSON document (keys: JSON_KEYS). Errors: InputError for a bad split or a
    calibration part the chain cannot calibrate."""
    src = source or (str(s.path) if s.path else None)
    t = s.encoder["t_s"]
    try:
        ts = split_time(t, split)
    except InputError as e:
        raise InputError(src, e.message) from None
    rows = fit_rows(s, ts, progress, src)
    # The delay the chain used (session's, else estimated on the calibration part only).
    td = float(s.t_delay_s) if s.t_delay_s is not None else float(rows["onset_lsq"].params["t_delay_s"])
    rm, mx, rc, what, n = score_rows(rows, s, ts, td, progress)
    return {
        "format": FORMAT, "session": src, "distal_kind": s.distal_kind, "judged_against": what,
        "state": "every model runs from the record's first sample (board running all along); "
                 "fitted on t < t_split only, scored on t >= t_split",
        "split": {"t_split_s": ts, "fraction": (ts - t[0]) / (t[-1] - t[0]), "t_start_s": float(t[0]),
                  "t_end_s": float(t[-1]), "cal_frames": int(rows["gpi"].params["fit_frames"]), "test_samples": n},
        "order": ROWS,
        "rows": {k: {"label": LABELS[k], "fixed_point": r.fixed_point, "rmse_deg": rm[k], "max_deg": mx[k],
                     "cal_rmse_deg": rc[k], "refused": r.refused, "params": r.params} for k, r in rows.items()},
        "notes": [f"row {k} not scored: {r.refused}" for k, r in rows.items() if r.refused],
    }


def format_insitu(doc: dict) -> str:
    """Markdown table of one evaluate_insitu() result."""
    sp = doc["split"]
    lines = [f"**In situ, state carried: fit on t < {sp['t_split_s'] - sp['t_start_s']:.1f} s "
             f"({100 * sp['fraction']:.0f} %), scored on the rest against the {doc['judged_against']} "
             f"({sp['test_samples']} samples)**", "",
             "| model | fixed point | RMSE (deg) | max (deg) | in sample, calibration part (deg) |",
             "|---|---|---|---|---|"]
    for k in doc["order"]:
        r = doc["rows"][k]
        if r.get("refused"):
            lines.append(f"| {r['label']} | {'yes' if r['fixed_point'] else 'no (float)'} | refused | refused | "
                         f"refused: {r['refused']} |")
            continue
        lines.append(f"| {r['label']} | {'yes' if r['fixed_point'] else 'no (float)'} | "
                     f"{r['rmse_deg']:.3f} | {r['max_deg']:.3f} | {r['cal_rmse_deg']:.3f} |")
    return "\n".join(lines + [""])
