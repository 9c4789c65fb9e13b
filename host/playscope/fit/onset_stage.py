"""The onset stage of `calibrate` for image sessions: eq. 1's B samples and t_delay from the one
model of the record (onset_model), started from the board's plain eq. 1 onsets.

1. Motor stops and the coarse delay's candidates, the correlation's peaks (delay_guess); the
   board's detector (firmware/core/onset.c via cffi, onsets.run_onsets) at the configured delay,
   or the correlation's highest peak when none is configured,
   with its threshold from the record's still noise (onset_settings.image_onset_settings) unless
   onset_cfg gives one; or the onsets the board itself measured (`board`, run-insitu).
2. The record model fitted with its terms chosen by BIC (onset_search.fit_record); the configured
   delay is its prior (t_delay_from "data", the default) or held (t_delay_from "config").
3. The samples read off the model (onset_fit.samples), with their standard errors.

A record the model cannot take (fewer than 2 reversals or 20 frames) keeps the board's samples.
Units: t in s, q in actuator units, image points in px.
"""

from __future__ import annotations

import numpy as np

from . import onset_fit, onset_search
from . import onset_model as OM
from .delay_guess import coarse_delay_peaks, motor_stop_times
from .onset_settings import board_onsets
from .onsets import Onsets, RobustOnsets
from .pacing import pacing



def along_path_share(du: np.ndarray, dv: np.ndarray, slope: np.ndarray) -> float:
    """Median over the frames of |cos| between a registration's jump (du, dv) (F,) px each and the
    image path's tangent slope (F, 2): 1 where the switch moves the image along the path (there a
    change of B at the image's level), 0 across it. NaN when no frame has both non-zero."""
    jn, sn = np.hypot(du, dv), np.hypot(slope[:, 0], slope[:, 1])
    ok = (jn > 0) & (sn > 0)
    if not ok.any():
        return float("nan")
    return float(np.median(np.abs(du[ok] * slope[ok, 0] + dv[ok] * slope[ok, 1]) / (jn[ok] * sn[ok])))


def record_samples(t_enc: np.ndarray, q: np.ndarray, q_rev: np.ndarray, rt: np.ndarray, rq: np.ndarray,
                   t_f: np.ndarray, obs: np.ndarray, fps: float, t_delay_cfg: float | None,
                   t_delay_from: str = "data", board: Onsets | None = None, onset_cfg: dict | None = None,
                   hysteresis: float = 0.0, t_delay_sd_s: float | None = None,
                   camera_K: np.ndarray | None = None) -> RobustOnsets:
    """B samples of eq. 1 and t_delay for an image session (module doc). t_enc, q, q_rev (N,) the
    encoder (q_rev: the signal the reversals rt, rq (M,) came from); t_f (F,) s, obs (F, 2) px (NaN
    rows: lost); fps the camera's rate; t_delay_cfg s or None; t_delay_sd_s the configured delay's
    standard deviation (None: one frame period / sqrt(12)); camera_K (3, 3) px the camera's
    intrinsics (its principal point and focal length place the registration term's perspective
    parts; None: from the frames, onset_model.make_record). Errors: ValueError for an unknown
    t_delay_from."""
    if t_delay_from not in ("data", "config"):
        raise ValueError(f"t_delay_from must be 'data' or 'config', not {t_delay_from!r}")
    period = 1.0 / fps
    tol = max(0.02 * hysteresis, 1e-9 * max(float(np.ptp(q_rev)), 1.0))
    t_stop = motor_stop_times(t_enc, q_rev, rt, rq, tol)
    d_peaks = coarse_delay_peaks(t_f, obs, t_stop, t_enc, q_rev, period)
    d0 = float(d_peaks[0])  # the correlation's highest point; the model chooses among its peaks
    rule = None
    if board is None:
        board, rule = board_onsets(t_enc, q, rt, rq, t_f, obs, fps, d0 if t_delay_cfg is None else t_delay_cfg, onset_cfg)
    warnings: list[str] = []
    try:
        K = None if camera_K is None else np.asarray(camera_K, float)
        rec = OM.make_record(t_enc, q, rt, rq, t_f, obs, fps, None if K is None else K[:2, 2],
                             None if K is None else float(np.sqrt(K[0, 0] * K[1, 1])))
    except ValueError as e:
        td = float(t_delay_cfg if t_delay_cfg is not None else d0)
        warnings.append(f"onsets: {e}; the board's plain eq. 1 samples are used")
        report = {"method": "the board's eq. 1 detector (the record is too short for the record model)",
                  "board_reasons": board.reasons, "board_threshold": rule,
                  "t_delay": {"configured_s": t_delay_cfg, "coarse_s": d0, "coarse_candidates_s": None,
                              "coarse_start_s": None, "used_s": td}, "lost_before_reversal": 0,
                  "registration": {"found": False}, "ringing": {"found": False}}
        return RobustOnsets(board, td, "configured" if t_delay_cfg is not None else "coarse (record)", report, warnings)
    fit, search = onset_search.fit_record(rec, t_delay_cfg, t_delay_from, d_peaks, board.b if board.b.size else None, t_delay_sd_s)
    sm = onset_fit.samples(fit)
    m = fit.model
    lag, _, ring, lags = m.unpack(fit.theta)
    slides = m.slides(fit.theta)  # each switch's longest slide, s (0: it steps)
    d = sm.t_delay_s  # the delay to the exposure's end (onset_model's doc: the exposure)
    held = m.d_fixed is not None
    se = sm.t_delay_se_s
    if held:
        src = "configured (--t-delay-from config)"
    elif t_delay_cfg is None:
        src = "estimated from the record (record model)"
    else:
        src = "estimated from the record (record model, the configured delay its prior)"
    agree = None
    if t_delay_cfg is not None and not held:
        # the record's delay agrees with the configured one exactly when the configured one split
        # the mean lag (onset_model.RecordModel.exposure_end: the one test, DELAY_DISAGREE_Z)
        agree = sm.exposure_s is not None
        if not agree:
            warnings.append(f"t_delay: the record gives {d:.4f} s (95 % {d - 1.96 * se:.4f}..{d + 1.96 * se:.4f} s) "
                            f"against the configured {t_delay_cfg:.4f} s; using the record's (--t-delay-from config "
                            "to keep the configured one)")
    n = sm.b.size
    reasons = {"record_model": int(n), "none": int(rt.size - n)}
    on = Onsets(sm.t1_s, sm.t2_s, sm.q1, sm.q2, sm.q_mean, sm.b, reasons, sigma_b=sm.sigma_b)
    pace = pacing(t_enc, q, on, fps, d)
    if n and pace["frames_to_take_up"] < pace["frames_wanted"]:
        warnings.append(f"the play is taken up in {pace['frames_to_take_up']:.1f} frame(s) (median): B is timed to "
                        f"about {pace['sigma_frame_travel']:.3g} per sample by the frame period; a swing at "
                        f"<= {pace['speed_to_use']:.3g} units/s would take it up over {pace['frames_wanted']} frames")
    terms = m.terms
    F = rec.t_f.size
    beta = fit.ev.beta
    reg = {}
    slope = m.G_slope(fit.ev) if (terms.reg_tip or terms.reg_motor) else None  # the path's tangent (F, 2)
    for name in ("tip", "motor"):
        if getattr(terms, "reg_" + name):
            du, dv = m.reg_offset(fit.ev, name)
            k = 2 * m.n_g + m.mix_block(name)
            shift = getattr(terms, "shift_" + name)
            along = along_path_share(du, dv, slope)
            reg[name] = {"jump_px": [2 * float(np.median(du)), 2 * float(np.median(dv))],
                         "jump_px_range": [2 * float(np.min(np.hypot(du, dv))), 2 * float(np.max(np.hypot(du, dv)))],
                         # a switch is a camera rotation, or with the shift_ term an image translation
                         "half_switch_deg_about_xyz": None if shift else [float(np.degrees(a)) for a in beta[k:k + OM.N_REG]],
                         "half_switch_px_uv": [float(a) for a in beta[k:k + OM.N_SHIFT]] if shift else None,
                         "switch_lag_s": lags[name], "slide_s": slides[name], "along_path": along}
    report = {
        "method": "one model of the record (playscope.fit.onset_model)",
        "board_reasons": board.reasons, "board_threshold": rule,
        "board_samples": int(board.b.size),
        "t_delay": {"configured_s": t_delay_cfg, "record_s": None if held else d, "record_se_s": None if held else se,
                    "record_ci95_s": None if held else [d - 1.96 * se, d + 1.96 * se],
                    "prior_sd_s": None if m.prior is None else m.prior[1], "agrees_with_configured": agree,
                    "used_s": d, "used": "configured" if held else "record", "from": t_delay_from, "source": src,
                    "coarse_s": d0, "coarse_candidates_s": search.get("coarse_candidates_s"),
                    "coarse_start_s": search.get("coarse_start_s")},
        "terms": {"chosen": terms.names(), "search": search["steps"], "criterion": "BIC on the Huber objective",
                  "noise_px": search["sigma_px"], "B_ctrl": search["n_b"], "B_read_at": search["width_at"], "G_ctrl": search["n_g"], "frames": int(F)},
        "ringing": {"found": terms.ring, "freq_hz": ring[0] if ring else None,
                    "damping_ratio": ring[1] if ring else None,
                    "gains": [float(g) for g in beta[2 * m.n_g:2 * m.n_g + 2]] if ring else None,
                    "stop_drive": ("motor" if terms.ring_motor else "output") if ring else None},
        "registration": {"found": bool(reg), **reg},
        "exposure_s": sm.exposure_s, "exposure_bound_s": sm.exposure_bound_s, "image_mean_lag_s": lag,
        "exposure_blur_s": m.exposure(fit.theta) if terms.expo else None,
        # the plant's take-up spread over widths (1 -+ s) B about B (onset_model: the spread); B and the
        # samples are the centre width's
        "take_up_spread": m.spread(fit.theta) if terms.spread else None,
        "pacing": pace,
        "sigma_b_median": float(np.median(sm.sigma_b)) if n else None,
        "lost_before_reversal": 0,
    }
    return RobustOnsets(on, float(d), src, report, warnings)
