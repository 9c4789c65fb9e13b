"""Calibration: session -> B(q) spline + f_remain (Fig. 4 blocks 1-6), and its JSON file.

The calibration file (docs/calibration-format.md), "format": "playscope-calibration/1":
  actuator_unit, q_range [min, max] (actuator travel seen), t_delay_s (+ t_delay_source),
  fps_frames (frame rate the onset detector saw), onset: {config, reasons},
  b_samples: {t1_s, t2_s, q1, q2, q_mean, b, weight}, B: spline (SplineFn.to_json),
  f_remain: spline + "sign" + "method" ("lsq" or "morph"), f_coarse: {q_per_rad},
  f_remain_alt: the other estimator, for comparison; transition: the smooth transition after
  the play (PI operators r, w on the play centre, playscope.fit.transition) and the model choice.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .backlash import BacklashFit, MIN_SPLINE_SAMPLES, Z_INCONSISTENT, backlash_alternatives, fit_backlash_auto
from .bspline import SplineFn
from .f_remain import characteristic, choose_f_ctrl, f_remain_lsq, f_remain_morph
from .onset_settings import angle_onset_settings, bootstrap_fps
from .onsets import OnsetConfig, Onsets, run_onsets
from .reversals import detect_reversals, frames_from_angle, q_looks_commanded
from . import model
from . import transition as T
from ..base.atomic import write_text_atomic
from ..base.errors import InputError
from ..base.forkmap import fork_map
from ..base.stage import stage
from ..io.session import Session
from .table_build import F_SLOPE_FLOORS

FORMAT = "playscope-calibration/1"


@dataclass
class Calibration:
    """Estimated model: B and f are callables on arrays (actuator units -> units, deg).

    transition: the PI operators after the play (n = 1: the paper's pure play, f on z);
    model_choice: how it was chosen ({"model", "n", "r_span", "candidates": [...]}, see
    transition.choose_model), None when the model was given."""

    B: SplineFn
    f: SplineFn
    f_sign: int
    q_per_rad: float
    doc: dict
    transition: T.Transition = field(default_factory=T.Transition.play)
    model_choice: dict | None = None
    f_play_fit: SplineFn | None = None
    f_play_sign: int | None = None
    B_product: SplineFn | None = None  # the chosen family's play width when it is not the onset B
    family_choice: dict | None = None    # families.choose's dict (model_family in the JSON)

    # Typed views of the file's fields (docs/calibration-format.md): the rest of the host reads
    # these, never doc[...] (doc is the file as written, kept for save()).
    @property
    def q_range(self) -> tuple[float, float]:
        """(q_min, q_max): the actuator travel seen while calibrating, actuator units."""
        lo, hi = self.doc["q_range"]
        return float(lo), float(hi)

    @property
    def actuator_unit(self) -> str:
        """"mm" (tendon displacement) or "deg" (motor angle)."""
        return self.doc.get("actuator_unit", "mm")

    @property
    def t_delay_s(self) -> float:
        """Image acquisition delay t_delay used by the calibration, s (eq. 1)."""
        return float(self.doc.get("t_delay_s", 0.0))

    @property
    def fps_frames(self) -> float:
        """Frame rate the onset detector saw, Hz (angle sessions: the block-averaging rate)."""
        return float(self.doc["fps_frames"])

    @property
    def reversals(self) -> int:
        """Direction reversals found in the calibration session."""
        return int(self.doc["reversals"])

    @property
    def b_samples(self) -> dict:
        """The B samples (eq. 1), arrays of equal length: t1_s, t2_s, q1, q2, q_mean, b, weight,
        and sigma_b, z when the file has them (actuator units, s)."""
        return {k: np.asarray(v, float) for k, v in self.doc["b_samples"].items() if v is not None}

    @property
    def n_b_samples(self) -> int:
        """Number of B samples (motion onsets, eq. 1) the B(q) fit used."""
        return len(self.doc["b_samples"]["b"])

    @property
    def onset_reasons(self) -> dict:
        """{reason name: count} of the onset detector (names from the C enum)."""
        return dict(self.doc["onset"]["reasons"])

    @property
    def onset_config(self) -> dict:
        """The onset detector's settings used (onset_config_t fields: threshold, timeouts, ...)."""
        return dict(self.doc["onset"]["config"])

    @property
    def reversal_hysteresis(self) -> float:
        """Hysteresis (actuator units) with which direction reversals were taken from q."""
        return float(self.doc["reversal_hysteresis"])

    @property
    def onset_refine(self) -> dict | None:
        """Image sessions: the onset refinement's report (t_delay, ringing, ...), else None."""
        return self.doc.get("onset", {}).get("refine")

    @property
    def warnings(self) -> list:
        """The calibration's warnings (one line each), as printed by `calibrate`."""
        return list(self.doc.get("warnings", []))

    @property
    def b_inconsistent(self) -> list:
        """B samples inconsistent with their neighbours: [{index, q_mean, b, z}]."""
        return list(self.doc.get("b_inconsistent", []))

    @property
    def f_alt(self) -> SplineFn:
        """The other f_remain estimator's fit (f_remain_alt: morph when f is lsq, and back)."""
        return SplineFn.from_json(self.doc["f_remain_alt"])

    @property
    def source(self) -> str | None:
        """The session the calibration was made from, as recorded."""
        return self.doc.get("source")

    @property
    def B_model(self):
        """Play width of the model the table carries: b_scale x B (the onset B, transition.py),
        or the chosen family's own B (a constant play: families.py) when it is not the onset B."""
        return self.transition.play_width(self.B if self.B_product is None else self.B_product)

    @property
    def family(self) -> str:
        """The model family the table carries (families.FAMILIES names); files written before
        the choice across families: onset_transition, or onset_play for a pure play."""
        if self.family_choice:
            return str(self.family_choice["family"])
        return "onset_play" if self.transition.is_play else "onset_transition"

    @property
    def relax(self):
        """The travel-domain relaxation the chosen family carries on the transition's output
        before f (playscope.fit.relax.Relaxation, layout-4 table), or None."""
        d = (self.family_choice or {}).get("relax")
        if not d:
            return None
        from .relax import Relaxation

        return Relaxation.from_json(d)

    @property
    def f_play(self) -> SplineFn:
        """f_remain of the pure-play model (eqs. 2, 3, 9: f on z), kept beside the transition's."""
        return self.f if self.f_play_fit is None else self.f_play_fit

    def predict(self, q: np.ndarray, z0: float | None = None) -> np.ndarray:
        """Direct model c = f_remain(PI(play(q; B))) (eqs. 2, 3 and the transition model, docs/method.md), state run from
        q[0]; q (N,) actuator units -> c (N,) deg."""
        rl = self.relax
        if rl is not None:  # c = f(R[PI(play(q))]) (playscope.fit.relax)
            return self.f(rl.direct(self.transition.direct(model.play_operator(np.asarray(q, float), self.B_model, z0))))
        if self.transition.is_play:
            return model.direct_model(q, self.B_model, self.f, z0)
        return T.direct_chain(q, self.B_model, self.transition, self.f, z0)

    def f_coarse(self, q):
        """f_coarse(q) (eq. 5, deg) at q (any shape, actuator units)."""
        return model.f_coarse(q, self.q_per_rad)

    def save(self, path) -> None:
        """Write the calibration JSON (docs/calibration-format.md) atomically. Errors: OSError."""
        write_text_atomic(path, json.dumps(self.doc, indent=1) + "\n")

    @classmethod
    def load(cls, path) -> "Calibration":
        """Errors: InputError naming the file for a missing file or a wrong format."""
        path = Path(path)
        if not path.is_file():
            raise InputError(path, "file not found")
        try:
            d = json.loads(path.read_text())
        except json.JSONDecodeError as e:
            raise InputError(path, f"invalid JSON: {e.msg}", e.lineno) from None
        if d.get("format") != FORMAT:
            raise InputError(path, f"format is {d.get('format')!r}, expected {FORMAT!r}")
        try:
            tr = d.get("transition") or {}
            fp = tr.get("f_remain_play")
            fam = d.get("model_family") or {}
            bp = fam.get("B")
            return cls(SplineFn.from_json(d["B"]), SplineFn.from_json(d["f_remain"]),
                       int(d["f_remain"]["sign"]), float(d["f_coarse"]["q_per_rad"]), d,
                       T.Transition.from_json(tr) if "r" in tr else T.Transition.play(), tr.get("choice"),
                       SplineFn.from_json(fp) if fp else None, int(fp["sign"]) if fp else None,
                       SplineFn.from_json(bp) if bp else None, fam.get("choice"))
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(path, f"malformed calibration: {e}") from None


def auto_fps(t1: np.ndarray, fps_max: float = 50.0, fps_min: float = 10.0) -> float:
    """The bootstrap frame rate (onset_settings.bootstrap_fps); `calibrate` then sets the rate from
    the record's dead bands (onset_settings.angle_onset_settings)."""
    return bootstrap_fps(t1, fps_max, fps_min)


# The transition's model choice deals the strokes to transition.KFOLD folds: with fewer
# reversals than folds a fold gets no stroke, and the choice falls back to the paper's play.
MIN_REVERSALS_TRANSITION = T.KFOLD


# Without any motion onset the play is fitted on c alone (families.FAMILIES_FROM_C), but only when
# the tip moves: its span over the calibration frames must exceed this many times the median
# |second difference| of c (1.65 sigma for white noise, so a still tip's span of ~6 sigma stays
# below; a cosine stroke of m frames has it ~5/m^2 of its span, far below at any frame rate).
STILL_SPAN_NOISE = 20


def b_beyond_board(B, q_range: tuple[float, float], n: int = 2001) -> tuple[float, float] | None:
    """(B's largest width over q_range on n points, the board's limit) in actuator units when B is
    wider somewhere than the loader accepts for that travel (common/ps_table.h's plausibility rule:
    the instrument's largest play within (0, travel / PST_PLAUS_B_TRAVEL_DIV], a play of half the
    travel leaving no motion), else None. B: callable on (n,) q. A mirror of the C rule for deciding
    early, on B alone; the loader (calib_load_guarded) stays the judge of every table. Errors: the
    native core's build errors (base.native.constant)."""
    from ..base.native import constant

    lim = (q_range[1] - q_range[0]) / constant("PST_PLAUS_B_TRAVEL_DIV")
    b_max = float(np.max(B(np.linspace(q_range[0], q_range[1], n))))
    return (b_max, lim) if b_max > lim else None


def loadable_f(refit, f, sign, B, q_range, unit: str, transition=None, source=None):
    """f as fitted when the board loads its table; else f refitted with the smallest slope floor
    of F_SLOPE_FLOORS at which it does.

    Why: eq. 9 inverts f, and the loader holds f^-1's fixed-point error to the precision ceiling
    (calib_load, CALIB_ERR_PRECISION: 1/16 of the largest play). A monotone fit may leave f
    nearly flat over a stretch where the record's c barely moves (the whole of data_2_2 gave
    |f'| = 2e-4 deg/mm at one point against 9.8 median): f^-1 then jumps there and the table is
    refused, so a valid calibration could not be flashed. The floor |f'| >= k x mean slope
    (bspline.robust_spline's min_slope) is raised only until the loader, the one judge of
    the table, accepts it (tables.build_table: the same table `playscope tables` writes).
    refit(min_slope) -> (f, sign): the same estimator with the floor (deg per actuator unit).
    B: the table's play width; q_range: (q_min, q_max); transition: the table's operators.
    Returns (f, sign, floor or None). Errors: TableError for any other refusal (not f's)."""
    from ..base.native import core
    from .table_build import TableError, build_table

    _, lib = core()

    def loads(fn) -> bool:
        try:
            build_table(B, fn, q_range[0], q_range[1], unit, "remain", transition=transition, source=source)
            return True
        except TableError as e:
            if e.status != lib.CALIB_ERR_PRECISION:
                raise
            return False

    if loads(f):
        return f, sign, None
    mean_slope = abs(f.y_hi - f.y_lo) / max(f.hi - f.lo, 1e-12)
    for k in F_SLOPE_FLOORS:
        g, sg = refit(k * mean_slope)
        if loads(g):
            return g, sg, {"min_slope": k * mean_slope, "fraction_of_mean": k,
                           "why": "table of the unconstrained f refused (CALIB_ERR_PRECISION: f nearly flat)"}
    raise TableError(source, "f^-1 stays above the precision ceiling even for a straight f")


def _command_lag(s: Session, t_enc, q, rt, rq, hyst) -> float:
    """Delay from a commanded q to the angle sensor (servo lag + sensor delay), s: the lag at
    which the tip's velocity best follows the command's sign around the reversals
    (delay_guess.coarse_delay on frames at the bootstrap rate; the tip stops as the motor
    turns, eq. 1's dead band)."""
    from .delay_guess import coarse_delay, motor_stop_times

    fr = bootstrap_fps(rt)
    t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], fr)
    t_stop = motor_stop_times(t_enc, q, rt, rq, 0.1 * hyst)
    return coarse_delay(t_f, np.column_stack([c_f, np.zeros_like(c_f)]), t_stop, t_enc, q, 1.0 / fr)


def pose_with_offset(im: model.ImageModel, obs: np.ndarray, c0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """c per frame by LM pose estimation (eqs. 6-8) with one constant image offset for the
    session: a registration error of the hand-eye (section V-F: it acts mainly across the
    motion, Table I's Qy) moves the marker's image by a nearly constant amount over the small
    workspace, and left in the residual it pulls each frame's c towards reducing it (LM fits
    one c to both image coordinates). First pass: c with the given registration; offset = the
    median image residual over the valid frames (its component along the motion is ~0, as c
    absorbs it, so only the part across the motion is taken out); second pass: c on Q - offset.
    obs: (F, 2) px, NaN rows lost; c0: (F,) deg seeds. Returns (c (F,) deg, residual (F,) px
    after the offset, offset (2,) px)."""
    c1, _ = im.estimate_c(obs, c0)
    r = obs - im(c1)
    ok = np.all(np.isfinite(r), axis=1)
    offset = np.median(r[ok], axis=0) if ok.any() else np.zeros(2)
    c2, res = im.estimate_c(obs - offset, c1)
    return c2, res, offset


@dataclass
class BAndModel:
    """choose_b_and_model's result: the kept B alternative (BacklashFit), the transition chosen
    with it (T.Transition), its f (SplineFn) and f's sign, the transition's choice dict
    (T.ModelChoice.result), one row per B alternative (rows, stiffest first: "smooth",
    "cv_rmse_deg", "cv_se_deg", "model", "b_scale", "n", "b_sample_pick"), and the kept
    alternative's T.FitData (its cached play centres and operator outputs, read again by the
    rest of the calibration)."""

    bfit: BacklashFit
    transition: T.Transition
    f: SplineFn
    sign: int
    choice: dict
    rows: list
    data: T.FitData


def choose_b_and_model(on, bfit, t_enc, q, t_f, c_f, td, model_kind, n_ctrl, src) -> BAndModel:
    """B(q)'s stiffness and the model chosen together by the model choice's own cross-
    validation on c (transition.choose_model: rolling origin, state from the record's start).

    The B-sample CV (backlash.choose_stiffness) judges a B by how well it predicts held-out
    onset widths; but an onset fires once the tip has moved by the detector's threshold, and
    with a smooth transition that width is not the play the model anchors on (the tip creeps
    from the narrowest operator). What the product needs from B is the c it predicts, so each
    stiffness the B-sample CV tried (backlash.backlash_alternatives: distinct B's only) gets
    its own model choice. The B-sample CV's own pick is kept when its model's CV RMSE is within
    one standard error of the best (no evidence against the measured B); otherwise the pick is
    the stiffest B whose chosen model's CV RMSE is within one standard error of the best (the
    one-standard-error rule of both CVs).
    Samples read off the record model (image sessions: onset_stage.record_samples, each with its
    standard error sigma_b) are not a detector's threshold crossings: each is where the fitted
    play starts to move (with the spread term, the centre width that B is), so the threshold's
    bias that the CV on c was for is not in them, and their own CV, weighted by sigma_b, is the
    judge of the stiffness. Their B-sample CV's pick is then the one alternative. Where c carries
    an effect the record model measured and no model on c has, the CV on c has evidence against
    the measured B: a registration switch (a direction-following offset that a wider or narrower
    B mimics) or a tip mode (on legs of one length a function of q and the direction, which the PI
    operators take up with a stiffer B: on s8-swing-078 of LOCKBOX8_300, a 60 fps triangle with a
    2.3 Hz mode of 9.5 px, the samples' spline was 0.4 % off the true B and the CV on c's pick
    16.8 %). What the samples' own pick gives up, measured on the 220 development renderings: the
    CV on c had moved the stiffness on 4 (fast 25 fps swings, no other effect or a wrong delay),
    where the samples' one-SE rule kept a spline a step stiffer than their best CV's and the CV on
    c took a softer one: B 0.41-0.64 % off the truth with it, 0.53-0.88 % without; the other 216
    the same. What it saves: all but one of the model choices (on the bench session the stage took
    1.8 s of calibrate's 5.5). It is still the CV on c that chooses the model for that B
    (transition.ModelChoice).
    Each alternative's model choice is transition.ModelChoice: pick() fits only the folds that
    can decide its pick (the rows here need its pick and refit alone), and only the B-sample CV's
    own pick completes every candidate for the choice dict: the same results as a full
    transition.choose_model per alternative, in fewer fits. The alternatives themselves cannot
    be cut short: the B rule's limit is the best alternative's CV + SE, and every alternative's
    row is part of the calibration file (B_fit.model_cv).
    on: the onset samples (onsets.Onsets; sigma_b None for a detector's); bfit: their
    fit_backlash_auto result; t_enc, q: (N,) s, actuator units; t_f, c_f: (F,) s, deg; td:
    acquisition delay, s; model_kind "auto"|"pi"; n_ctrl: f's control points for the pure-play
    candidate (14 from calibrate: the cross-validated f_remain N needs B first); src: file named
    in errors.
    Returns BAndModel (the kept B, its transition, f, sign and choice dict, every alternative's
    row (one for the record model's samples), the kept alternative's FitData)."""
    alts = [(bfit.smooth, bfit)] if on.sigma_b is not None else \
        backlash_alternatives(on.q_mean, on.b, bfit, src, sigma=on.sigma_b)
    base = T.FitData.from_session(t_enc, q, alts[0][1].B, t_f, c_f, td)

    def choice(alt) -> T.ModelChoice:
        """An alternative's model choice, picked and refitted. B-proportional thresholds
        (transition.ThresholdMap, built from this alternative's B) are offered when B's shape is
        measured (transition.threshold_kinds)."""
        bf = alt[1]
        mc = T.ModelChoice(base.with_B(bf.B), model_kind, n_ctrl, kinds=T.threshold_kinds(bf.kind, on.b.size, bf.n_ctrl))
        if alt[0] == bfit.smooth:
            # The B-sample CV's own pick is the one kept unless the CV on c puts it beyond one SE
            # (below), so its every candidate is completed (result: on two cores when it is the one
            # alternative), beside the other alternatives, rather than after them on one core. The
            # pick from the complete table is the lazy pick's (ModelChoice.pick): nothing else changes.
            mc.result()
        mc.pick()
        mc.refit()
        return mc

    # the alternatives are independent: on two cores (base.forkmap; 7 on the bench session, 0.2-0.8 s
    # each), the own pick first (it completes its candidates, above)
    choices = fork_map(choice, alts, cost=lambda alt: 1.0 if alt[0] == bfit.smooth else 0.0)
    rows = []
    for (sm, _), mc in zip(alts, choices):
        pick, (tr, _, _, _) = mc.pick(), mc.refit()
        rows.append({"smooth": sm, "cv_rmse_deg": pick["cv_rmse_deg"], "cv_se_deg": pick["cv_se_deg"],
                     "model": "play" if tr.is_play else "pi", "b_scale": pick["b_scale"], "n": tr.n})
    best = min(rows, key=lambda d: d["cv_rmse_deg"])
    limit = best["cv_rmse_deg"] + best["cv_se_deg"]
    own = next(i for i, (sm, _) in enumerate(alts) if sm == bfit.smooth)
    for j, d in enumerate(rows):
        d["b_sample_pick"] = j == own  # the B-sample CV's own choice (backlash.choose_stiffness)
    # The onset samples' own choice stays unless the model's CV on c puts it beyond one standard
    # error of the best: B is the anchor measured by eq. 1, and a CV on c that cannot tell the
    # stiffnesses apart has no evidence to move it. Beyond, the stiffest B within one SE of the
    # best (rows are stiffest first).
    i = own if rows[own]["cv_rmse_deg"] <= limit else \
        next(i for i, d in enumerate(rows) if d["cv_rmse_deg"] <= limit)
    tr, f, sign, ch = choices[i].result()
    return BAndModel(alts[i][1], tr, f, sign, ch, rows, choices[i].data)


# A calibration whose model explains less than this share of c's variance, and does no better
# than NOISE_LINE_RATIO times the error of a memoryless line c = a + b q, describes no instrument.
NOISE_R2_MIN = 0.5
NOISE_LINE_RATIO = 0.9


def check_not_noise(q_c: np.ndarray, c_c: np.ndarray, c_model: np.ndarray, source=None, splits=None,
                    model_cv_rmse: float | None = None) -> None:
    """Refuse a calibration fitted on noise: the play model's error on the angles c_c (deg) at the
    characteristic's samples q_c is no better than NOISE_LINE_RATIO times a memoryless line's
    (least squares c = a + b q) and explains less than NOISE_R2_MIN of their variance. With
    splits (the rolling-origin folds, masks over the samples) and model_cv_rmse (f_remain's CV
    error on them, choose_f_ctrl) both errors are held-out ones, the line fitted before and scored
    on each next block as f is; else in-sample (c_model: the model's prediction). A real
    instrument's c follows q (the line alone explains most of it) or follows it with a play (the
    model beats the line); a drift that merely shares the record's slow ramp is fitted in-sample
    but not forecast. Errors: InputError, one line with the figures."""
    q_c, c_c, c_model = (np.asarray(a, float) for a in (q_c, c_c, c_model))
    ok = np.isfinite(q_c) & np.isfinite(c_c) & np.isfinite(c_model)
    if ok.sum() < 3 or float(np.var(c_c[ok])) <= 0:
        return
    var = float(np.var(c_c[ok]))

    def line_fit(m):
        A = np.column_stack([np.ones(int(m.sum())), q_c[m]])
        return np.linalg.lstsq(A, c_c[m], rcond=None)[0]

    held = splits is not None and model_cv_rmse is not None and np.isfinite(model_cv_rmse)
    if held:
        errs = []
        for tr, te in splits:
            tr, te = tr & ok, te & ok
            if tr.sum() >= 3 and te.sum() >= 3:
                a, b = line_fit(tr)
                errs.append(float(np.mean((c_c[te] - a - b * q_c[te]) ** 2)))
        held = bool(errs)
    if held:
        rmse_line, rmse_model, how = float(np.sqrt(np.mean(errs))), float(model_cv_rmse), "held-out "
    else:
        a, b = line_fit(ok)
        rmse_line = float(np.sqrt(np.mean((c_c[ok] - a - b * q_c[ok]) ** 2)))
        rmse_model, how = float(np.sqrt(np.mean((c_c[ok] - c_model[ok]) ** 2))), ""
    r2 = 1.0 - rmse_model ** 2 / var
    if r2 < NOISE_R2_MIN and rmse_model > NOISE_LINE_RATIO * rmse_line:
        raise InputError(source, f"the fit is no better than a memoryless line ({how}RMSE {rmse_model:.3g} deg, "
                         f"line {rmse_line:.3g} deg; the model explains {max(r2, 0.0):.0%} of the angle's variance): "
                         "the angle does not follow the actuator (noise, or the wrong column or session); "
                         "no calibration written")


def _one_blas_thread(fn):
    """fn run on one BLAS thread. The chain's linear algebra is small (frames x tens of columns),
    where threads cost more than they give: transition.fit_weights measured a solve ~30x slower
    threaded on a busy 2-core machine."""
    @functools.wraps(fn)
    def run(*args, **kw):
        from .transition import _blas_controller

        with _blas_controller().limit(limits=1, user_api="blas"):
            return fn(*args, **kw)

    return run


def _in_lockstep(fn):
    """fn run within base.forkmap.lockstep: its fits shared with one child forked for the whole call,
    not one a map (that module's doc: why)."""
    @functools.wraps(fn)
    def run(*args, **kw):
        from ..base.forkmap import lockstep

        with lockstep():
            return fn(*args, **kw)

    return run


@_one_blas_thread
@_in_lockstep
def calibrate(s: Session, n_ctrl: int = 14, f_method: str = "lsq", fps: float | None = None,
              t_delay_s: float | None = None, hysteresis: float | None = None,
              onset_cfg: dict | None = None, source: str | None = None,
              onsets: Onsets | None = None, t_delay_from: str = "data",
              model_kind: str = "auto", f_ctrl: int | None = None) -> Calibration:
    """Run the chain on a session (image or angle).

    1 reversals (q_cmd if logged, else the encoder with hysteresis, default 1 % of the
      travel); 2 onsets by the C detector; 3 B spline (N = n_ctrl); 4 c per frame (angle
      sensor, or LM pose estimation eqs. 6-8 seeded with f_coarse); 5 f_remain by
      f_method "lsq" (play-consistent) or "morph" (paper); the other one is kept as
      f_remain_alt. t_delay: argument, else session.json, else estimated (image
      sessions; 0 for angle sessions, whose sensor shares the encoder clock).
    Image sessions: eq. 1's samples and t_delay come from one model of the record
      (playscope.fit.onset_stage.record_samples, the configured delay its prior); t_delay_from
      "data" (default) uses the record's delay, "config" the configured one; a disagreement is a
      warning (doc["warnings"]).
    onsets: B samples measured elsewhere (e.g. by the board's own detector during
      `playscope run-insitu`); they replace the detector run of step 2 (image sessions: as the
      refinement's candidates; angle sessions: fitted as they are).
    model_kind: "play" (the paper's pure play), "pi" (play + transition operators) or "auto"
      (default: play or PI and the operator count by cross-validation on the session itself,
      transition.choose_model); with a transition, f_remain is f of y (the transition model, docs/method.md).
    Thin records degrade: 1-3 B samples give a constant B with its 95 % interval, more
      a B(q) spline of min(n_ctrl, samples) control points with its stiffness by cross-validation
      (backlash.fit_backlash_auto); angle sessions take their frame rate and onset threshold from
      the record (onset_settings.angle_onset_settings); each fallback is a line in doc["warnings"].
      A measured B wider somewhere than the board's tables allow for the record's travel
      (`b_beyond_board`) is no table's play: with model_kind "auto" the play is then fitted on c, as
      for a record without any onset (families.FAMILIES_FROM_C).
    f_ctrl: f_remain's control points; None (default): chosen by rolling-origin cross-validation on
      the calibration frames (f_remain.choose_f_ctrl, the fewest within one standard error of the
      best); the choice and its scores are in doc["f_fit"]. The pure play's f in the transition's
      model choice uses the same N.
    q_source "command" (session.json actuator.q_source): angle sessions measure the command-to-tip
      delay from the record (servo lag) instead of taking 0.
    Errors: InputError (naming the file) when q never reverses, when no reversal gives an onset,
      or for lost markers.
    """
    src = source or (str(s.path) if s.path else None)
    across_families = model_kind == "auto"
    t_enc, q = s.encoder["t_s"], s.encoder["q"]
    q_rev = s.encoder.get("q_cmd", q)
    span = float(np.ptp(q))
    if span <= 0:
        raise InputError(src, "the actuator never moves (encoder.csv q constant)")
    hyst = 0.01 * span if hysteresis is None else hysteresis
    rt, rq, _ = detect_reversals(t_enc, q_rev, hyst)
    if "q_cmd" in s.encoder:
        rq = np.interp(rt, t_enc, q)  # q1 is the measured position at the commanded reversal
    enc_file = Path(s.path or ".") / "encoder.csv" if s.path else src
    if rt.size == 0:
        raise InputError(enc_file, f"no direction reversal (q moves one way only, hysteresis {hyst:.3g} "
                         f"{s.actuator_unit}): B needs at least one; record a back-and-forth motion")
    warnings = []
    if rt.size < 4:
        warnings.append(f"only {rt.size} direction reversal(s): B(q) needs >= 4 onsets, B is held constant "
                        "if fewer are detected (confidence interval in B_fit.ci95)")
    if s.q_source == "measured" and "q_cmd" not in s.encoder:
        cmd, ratio = q_looks_commanded(q)
        if cmd:
            warnings.append(f"encoder.csv q looks like a command, not a measurement (smooth to {ratio:.1e} of a "
                            "step): if it is, set actuator.q_source = \"command\" in session.json so the "
                            "servo lag is measured from the record (docs/session-format.md)")

    onset_rule = None
    if s.distal_kind == "angle":
        if t_delay_s is not None:
            td, td_src = t_delay_s, "argument"
        elif s.t_delay_s is not None and s.q_source != "command":
            td, td_src = s.t_delay_s, "session"
        elif s.q_source == "command":
            td, td_src = _command_lag(s, t_enc, q, rt, rq, hyst), "record (q is the command: servo lag + sensor delay)"
        else:
            td, td_src = 0.0, "angle sensor on the encoder clock"
        # No image registration here, so no jump at the onset: a fast start is real motion.
        # Frame rate and threshold from the record (onset_settings.angle_onset_settings).
        fr, defaults, onset_rule = angle_onset_settings(t_enc, q, rt, rq, s.distal["t_s"], s.distal["c_deg"], td, fps)
        t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], fr)
        obs = np.column_stack([c_f, np.zeros_like(c_f)])
    else:
        t_f, obs = s.observations()
        fr = s.camera.fps
        lost = ~np.all(np.isfinite(obs), axis=1)
        if lost.mean() > 0.5:
            raise InputError(Path(s.path or ".") / "marker.csv", f"marker lost in {lost.mean():.0%} of the frames")
        td = td_src = None  # set below from the record (the onset stage), checked against these
        defaults = {}
    refine_doc = None
    if s.distal_kind == "image":
        from .onset_stage import record_samples

        cfg_td = t_delay_s if t_delay_s is not None else s.t_delay_s
        stage("onsets: the record model (eq. 1)")
        rob = record_samples(t_enc, q, q_rev, rt, rq, t_f, obs, fr, cfg_td, t_delay_from, onsets, onset_cfg, hyst,
                             camera_K=s.camera.K)
        td, refine_doc = rob.t_delay_s, rob.report
        warnings += rob.warnings
        td_src = "argument" if t_delay_s is not None and t_delay_from == "config" else rob.t_delay_source
    cfg = OnsetConfig(t_delay_s=td, fps=fr, **{**defaults, **(onset_cfg or {})})
    if s.distal_kind == "image":
        on = rob.onsets
    else:
        on = onsets if onsets is not None else run_onsets(t_enc, q, rt, rq, t_f, obs, s.distal_kind, cfg)
    no_onset = on.b.size == 0
    no_b = None  # why B is fitted on c rather than measured (None: it is measured)
    if no_onset:
        why = ", ".join(f"{k} {v}" for k, v in on.reasons.items() if v) or "none reached"
        if (refine_doc or {}).get("lost_before_reversal"):
            why += (f"; on {refine_doc['lost_before_reversal']} of them every onset lay before the reversal at the "
                    f"t_delay used, {td:.4f} s: check the delay (session.json's t_delay, --t-delay-from config)")
        no_b = f"no usable reversal: none of the {rt.size} direction reversals gave a motion onset ({why})"
        if not across_families:
            raise InputError(src, f"{no_b}; check that the distal end moves after each reversal and the "
                             "back-and-forth exceeds the play")
    else:
        bfit = fit_backlash_auto(on.q_mean, on.b, n_ctrl, source=src, sigma=on.sigma_b)
        # A B that no table carries (the loader's plausibility rule) leaves no onset family to be the
        # product's; the families that fit their play on c may still give one that loads.
        wide = b_beyond_board(bfit.B, (float(q.min()), float(q.max()))) if across_families else None
        if wide is not None:
            no_onset = True
            no_b = (f"the measured play reaches {wide[0]:.3g} {s.actuator_unit}, more than the board accepts for this "
                    f"record's travel ({wide[1]:.3g}, half of it; a record over more of the travel measures B for a table)")
    if no_b is not None:
        # The families that fit their play from c alone still hold (families.FAMILIES_FROM_C); B
        # (set below from the frames) is then the constant play's width, not a measurement.
        warnings.append(f"{no_b}: the play's width is fitted on c alone (constant play), the onset families are "
                        "not offered")
        bfit = BacklashFit(None, np.zeros(0), np.zeros(0), np.zeros(0, bool), 0.0, kind="fitted on c", n_ctrl=4)
    B, w = bfit.B, bfit.weight
    if bfit.kind == "constant" and not no_onset:
        ci = "unknown (one sample without an uncertainty)" if bfit.ci95 is None else \
            f"95 % CI {bfit.ci95[0]:.3g}..{bfit.ci95[1]:.3g}"
        why = (f"only {on.b.size} B sample(s) (B(q) needs >= {MIN_SPLINE_SAMPLES})" if on.b.size < MIN_SPLINE_SAMPLES
               else f"cross-validation on the {on.b.size} B samples prefers it to a B(q) spline")
        warnings.append(f"B held constant at {float(B(np.array([0.0]))[0]):.3g} {s.actuator_unit}, {ci}: {why}")
    if bfit.inconsistent.any():
        warnings.append(f"{int(bfit.inconsistent.sum())} B sample(s) inconsistent with their neighbours "
                        f"(|z| > {Z_INCONSISTENT}): listed in b_inconsistent, down-weighted, not averaged in")

    # c per frame: the sensor, or LM pose estimation through h(g(c)) (eqs. 6-8).
    stage("c per frame (eqs. 6-8)" if s.distal_kind == "image" else "c per frame")
    if s.distal_kind == "angle":
        c_f = obs[:, 0]
        lm = None
    else:
        im = model.ImageModel(s.robot, s.camera, s.hand_eye)
        q_f = np.interp(t_f - td, t_enc, q)
        c_f, res, offset = pose_with_offset(im, obs, model.f_coarse(q_f, s.robot.q_per_rad))
        lm = {"residual_px_median": float(np.nanmedian(res)), "residual_px_max": float(np.nanmax(res)),
              "image_offset_px": [float(v) for v in offset]}
    if no_onset:
        from .families import constant_play_lsq, constant_spline

        q_c0, c_c0 = characteristic(t_enc, q, t_f, c_f, td)
        c_ok = c_c0[np.isfinite(c_c0)]
        noise = float(np.median(np.abs(np.diff(c_ok, 2)))) if c_ok.size > 2 else 0.0
        if c_ok.size < 3 or np.ptp(c_ok) <= STILL_SPAN_NOISE * noise:
            # A tip whose span is within its own noise has not followed q at all: nothing to fit
            # a play on.
            raise InputError(src, f"{no_b}, and the distal end spans only {np.ptp(c_ok) if c_ok.size else 0:.3g} deg; "
                             "check that it moves after each reversal and the back-and-forth exceeds the play")
        B = bfit.B = constant_spline(constant_play_lsq(q_c0, c_c0)[0], float(q.min()), float(q.max()))
        model_kind = "play"  # no onset B to anchor the transition on
    model_cv, fit_data = None, None
    if model_kind != "play" and rt.size >= MIN_REVERSALS_TRANSITION:
        # B(q)'s stiffness by the model's own cross-validation on c where the samples are a
        # detector's; the record model's samples keep their own (see choose_b_and_model).
        stage("B(q) and the model by cross-validation")
        joint = choose_b_and_model(on, bfit, t_enc, q, t_f, c_f, td, model_kind, n_ctrl, src)
        bfit, model_cv, fit_data = joint.bfit, joint.rows, joint.data
        B, w = bfit.B, bfit.weight
    if fit_data is None:
        # The kept choice's data is B's by construction (choose_b_and_model), and the calibration goes
        # on with it: its operator outputs and the folds' weights, which the family choice's onset
        # transition starts from (transition.cv_start). Not by B's identity: a choice fitted in the
        # forked child comes through the pipe with a copy of B, and an identity test then started the
        # data afresh, so the result hung on which process had fitted the kept alternative (on data_2_1
        # calibrated on its first half, the family CV's onset_transition row differed in the fourth
        # digit between one core and two).
        fit_data = T.FitData.from_session(t_enc, q, B, t_f, c_f, td)
    # One FitData for B from here on: the model choice, the PI's f refit and the family choice
    # read the same play centres and operator outputs (cached on it), computed once.
    q_c, c_c = characteristic(t_enc, q, t_f, c_f, td)
    # f_remain's stiffness from the calibration frames: rolling-origin CV on the transition's folds.
    z_c = model.play_operator(q_c, B)
    if f_ctrl is None:
        f_cv = choose_f_ctrl(z_c, c_c, T.rolling_origins(fit_data, T.KFOLD))
        f_n = f_cv["n_ctrl"] or n_ctrl
    else:
        f_cv, f_n = {"n_ctrl": int(f_ctrl), "rule": "given", "candidates": []}, int(f_ctrl)
    fits = {}
    fits["lsq"] = f_remain_lsq(q_c, c_c, B, f_n, z=z_c)[:2]
    fits["morph"] = f_remain_morph(q_c, c_c, n_ctrl)[:2]
    if f_method not in fits:
        raise ValueError(f"f_method must be 'lsq' or 'morph', not {f_method!r}")
    f, sign = fits[f_method]
    cv_rows = f_cv.get("candidates") or []
    check_not_noise(q_c, c_c, fits["lsq"][0](z_c), src, T.rolling_origins(fit_data, T.KFOLD) if cv_rows else None,
                    min((r["cv_rmse_deg"] for r in cv_rows), default=None))
    # The product's f must load on the board (loadable_f), for the pure play as for the PI below.
    refit_play = {"lsq": lambda ms: f_remain_lsq(q_c, c_c, B, f_n, z=z_c, min_slope=ms)[:2],
                  "morph": lambda ms: f_remain_morph(q_c, c_c, n_ctrl, min_slope=ms)[:2]}[f_method]
    q_rng = (float(q.min()), float(q.max()))
    f, sign, floor_play = loadable_f(refit_play, f, sign, B, q_rng, s.actuator_unit, source=src)
    floor = floor_play
    alt = "morph" if f_method == "lsq" else "lsq"
    tr, choice, f_play, play_doc = T.Transition.play(), None, None, None
    if model_kind == "auto" and rt.size < MIN_REVERSALS_TRANSITION:
        model_kind = "play"
        warnings.append(f"model play: {rt.size} reversals are too few to cross-validate a transition "
                        f"(needs >= {MIN_REVERSALS_TRANSITION}, one stroke per fold)")
    if model_kind != "play":
        if model_cv is not None:  # chosen with B above (its pure-play candidate uses n_ctrl: f_n needs B first)
            tr, f_pi, sign_pi, choice = joint.transition, joint.f, joint.sign, joint.choice
        else:
            tr, f_pi, sign_pi, choice = T.choose_model(fit_data, model_kind, f_n,
                                                       kinds=T.threshold_kinds(bfit.kind, on.b.size, bfit.n_ctrl))
        if not tr.is_play:
            f_play, play_doc = f, {**f.to_json(), "sign": sign, "method": f_method, "slope_floor": floor_play}
            nc = int(choice["n_ctrl"]) if choice and choice.get("n_ctrl") else f_n

            @functools.cache
            def pi_frames():
                # The PI's output at the frames: only when f must be refitted (the operators run
                # over the whole encoder record, so not on every calibration).
                return fit_data.ops_at_frames(tr.r, tr.b_scale, tr.tmap is not None) @ tr.w, fit_data.c

            f_pi, sign_pi, floor = loadable_f(lambda ms: T.fit_f(*pi_frames(), nc, sign=sign_pi, min_slope=ms),
                                              f_pi, sign_pi, tr.play_width(B), q_rng, s.actuator_unit, tr, src)
            f, sign, f_method = f_pi, sign_pi, "lsq+pi"
    B_product, fam_choice = None, None
    if across_families:
        # The family the table carries, by the rolling-origin CV through the tables (families.py).
        from . import families as FAM

        play_f, play_sign = (f, sign) if tr.is_play else (f_play, int(play_doc["sign"]))
        ctx = FAM.Context(fit_data, choice, tr, f, sign, play_f, play_sign,
                          int(f_n), q_rng, s.actuator_unit)
        stage("the model family")
        member, fam_choice = FAM.choose(ctx, int(rt.size), FAM.FAMILIES_FROM_C if no_onset else None, source=src)
        if fam_choice["rule"].startswith("thin"):
            warnings.append(f"model {member.family}: {fam_choice['rule']}")
        if member.family != ("onset_play" if tr.is_play else "onset_transition") or member.relax is not None:
            if tr.is_play:  # the pure play's f stays beside the product's (f_remain_play: the onset_lsq row)
                f_play, play_doc = f, {**f.to_json(), "sign": sign, "method": f_method, "slope_floor": floor_play}
            tr, f, sign, floor = member.transition, member.f, member.sign, None
            f_method = {"onset_play": "lsq", "const_play": "lsq+const_play", "pi_const": "lsq+pi_const"}.get(
                member.family, "lsq+" + member.family)
            if member.family not in FAM.ONSET_FAMILIES:
                B_product = member.B
    for name, fl in (("f_remain" if tr.is_play else "the pure play's f_remain", floor_play),
                     ("f of the transition model", None if tr.is_play else floor)):
        if fl:
            warnings.append(f"{name} held to |f'| >= {fl['min_slope']:.3g} deg per {s.actuator_unit} "
                            f"({fl['fraction_of_mean']:g} of its mean slope): fitted freely it was nearly flat "
                            f"somewhere and the board refused to invert it (slope_floor in the JSON)")
    doc = {
        "format": FORMAT, "actuator_unit": s.actuator_unit, "source": src,
        "t_origin_s": _origin_text(s.t_origin_us),
        "q_range": [float(q.min()), float(q.max())],
        "t_delay_s": float(td), "t_delay_source": td_src, "fps_frames": float(fr),
        "reversal_hysteresis": float(hyst), "reversals": int(rt.size),
        "onset": {"config": cfg.effective(), "reasons": on.reasons, "refine": refine_doc, "rule": onset_rule},
        "B_fit": {"kind": bfit.kind, "n_ctrl": bfit.n_ctrl, "smooth": bfit.smooth, "ci95": bfit.ci95,
                  "samples": int(on.b.size), "cv": bfit.cv, "model_cv": model_cv},
        "b_samples": {"t1_s": on.t1_s, "t2_s": on.t2_s, "q1": on.q1, "q2": on.q2, "q_mean": on.q_mean,
                      "b": on.b, "weight": w, "sigma_b": on.sigma_b, "z": bfit.z},
        "b_inconsistent": [{"index": int(i), "q_mean": float(on.q_mean[i]), "b": float(on.b[i]), "z": float(bfit.z[i])}
                           for i in np.nonzero(bfit.inconsistent)[0]],
        "warnings": warnings,
        "B": B.to_json(),
        "f_remain": {**f.to_json(), "sign": sign, "method": f_method, "slope_floor": floor},
        "f_fit": {"n_ctrl": f_n, **{k: v for k, v in f_cv.items() if k != "n_ctrl"}},
        "f_remain_alt": {**fits[alt][0].to_json(), "sign": fits[alt][1], "method": alt},
        "f_coarse": {"q_per_rad": s.robot.q_per_rad},
        "pose_estimation": lm,
        "transition": {**tr.to_json(), "model": "play" if tr.is_play else "pi", "choice": choice,
                       "f_remain_play": play_doc},
        "model_family": None if fam_choice is None else
        {"family": fam_choice["family"], "B": None if B_product is None else B_product.to_json(), "choice": fam_choice},
    }
    from ..base.jsonio import plain_json

    return Calibration(B, f, sign, s.robot.q_per_rad, plain_json(doc), tr, plain_json(choice), f_play,
                       None if f_play is None else int(play_doc["sign"]), B_product, plain_json(fam_choice))


def _origin_text(t_origin_us: int) -> str:
    """The files' time of the record's first sample (Session.t_origin_us) as exact decimal
    seconds: every time in the calibration (b_samples.t1_s, ...) is relative to it."""
    from ..io.session import format_us

    return format_us(int(t_origin_us))
