"""A calibration made on one record, used on others (another session or sheath configuration):
the transfer table and the measurement of which model parameters move between records.

Transfer protocol (docs/online.md, "Calibrated once, used elsewhere"): the pure play (onset
B(q) + play-consistent f_remain, `calibrate(model_kind="play")`) and the transition model
(`model_kind="auto"`) are calibrated on the whole calibration record; every other record is run
with them from its first sample (play state from q[0]) and scored, bending-angle RMSE against
its angle sensor, on the samples after the warm-up (a fraction of the record's duration).
Rows, all scored on exactly the same samples:

  in_situ            ours with the transition fitted on the record's own warm-up part only
                     (the protocol of insitu_split.py with the split at the warm-up): the reference
  in_situ_affine     the same with the offset and gain refresh below: where nothing drifts
                     the refresh must not make it worse
  in_situ_const_play constant play + poly5 fitted on the same frames of that part
Every row is run in double precision except the on-line B rows (the board's fixed-point RLS
grid, through cffi); the endoscope's wide play exceeds the fixed-point table's precision
ceiling for the morphological f_remain, so the transfer protocol does not go through tables.
  static             ours (pure play) of the calibration record, as is
  static_transition  ours with the transition of the calibration record, as is
  online_b_only, online_offset_only, online
                     the pure play with each on-line update of online.py (the board's RLS on
                     B from the onsets, the host's offset refresh, both), from the first sample
  transition_offset  ours with the transition + the same offset refresh
  const_play_ref     constant play + poly5 of the calibration record, as is
  const_play_ref_offset  the same + the same offset refresh (the peer given our update)
  static_affine, transition_affine, const_play_ref_affine, in_situ_affine
                     the host's offset and gain refresh (least squares on every frame so far)
  static_board, transition_board, const_play_ref_board, in_situ_board
                     the board's offset and gain learner instead (firmware/core/f_online.c
                     through cffi, online.board_f_refreshed: fixed point, forgetting, a publish
                     every refresh period's worth of frames), settings by online.f_config_from

Drift measurement (`drift`): each record calibrated in situ on its whole length; its
parameters compared with the calibration record's over the travel both saw.

Readers: the catheter files (importer.import_catheter) and the endoscope files of
../shared/data/real/endoscope (importer.import_endoscope: headerless CSV, q = commanded angle, deg).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..fit import model
from ..board import online as O
from ..fit import transition as T
from ..fit.calibration import calibrate
from ..base.errors import InputError
from ..io.importer import read_record
from .insitu_split import calibration_frames

FORMAT = "playscope-transfer/1"
ROWS = ["in_situ", "in_situ_affine", "in_situ_const_play", "static", "static_transition", "online_b_only", "online_offset_only",
        "online", "transition_offset", "const_play_ref", "const_play_ref_offset", "static_affine", "transition_affine",
        "const_play_ref_affine", "in_situ_board", "static_board", "transition_board", "const_play_ref_board"]
LABELS = {
    "in_situ": "in situ: ours (transition) fitted on the record's own warm-up (reference)",
    "in_situ_affine": "in situ: the same + offset and gain refresh (no drift to learn)",
    "in_situ_const_play": "in situ: constant play + poly5 fitted on the record's own warm-up",
    "static": "transferred as is: ours, pure play",
    "static_transition": "transferred as is: ours with transition",
    "online_b_only": "transferred + on-line B (board RLS)",
    "online_offset_only": "transferred + offset refresh",
    "online": "transferred + on-line B + offset refresh",
    "transition_offset": "transferred with transition + offset refresh",
    "const_play_ref": "constant play + poly5 of the calibration record, as is",
    "const_play_ref_offset": "constant play + poly5 of the calibration record + offset refresh",
    "static_affine": "transferred + offset and gain refresh",
    "transition_affine": "transferred with transition + offset and gain refresh",
    "const_play_ref_affine": "constant play + poly5 of the calibration record + offset and gain refresh",
    "in_situ_board": "in situ: the same + the board's offset and gain learner (no drift to learn)",
    "static_board": "transferred + the board's offset and gain learner",
    "transition_board": "transferred with transition + the board's offset and gain learner",
    "const_play_ref_board": "constant play + poly5 of the calibration record + the board's offset and gain learner",
}
GAIN_BOUNDS = (0.5, 2.0)  # the gain refresh's clamp: a factor 2 either way, far outside any record's fitted gain
WARMUP = 0.5  # fraction of the duration; the only split giving every endoscope record >= 2 reversals before it
JSON_KEYS = ("format, calibration {file, reversals, b_samples}, settings {warmup, refresh_s, board_f {mem_log2, "
             "publish_every, prior_var_q16}}, order [row], labels {row: str}, files {name: {config_deg (sheath angle "
             "from the file name, null for the catheter), t_split_s, rmse_deg {row: float}, b_samples (learnt on "
             "line), board_f {publishes, a_deg, g} (the transition row's learner at the end)}}, mean {row: float}, "
             "worst {row: float}")

# Endoscope files: column of the distal angle by file name (README of the data set).


def config_angle(path) -> float | None:
    """Sheath configuration angle (deg) from an endoscope file name ("120.txt" -> 120,
    "conf0_60.txt" -> 0); None for any other file (e.g. the catheter's data_2_3)."""
    stem = Path(path).stem
    m = re.fullmatch(r"(\d+)", stem) or re.fullmatch(r"conf(\d+)_\d+", stem)
    return float(m.group(1)) if m else None


def _offset_refreshed(s, c_hat: np.ndarray, fps: float, refresh_s: float) -> np.ndarray:
    """c_hat plus the host's offset refresh of online.py (mean residual over the frames complete
    before each refresh, every refresh_s)."""
    from ..fit.reversals import frames_from_angle

    t = s.encoder["t_s"]
    t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], fps)
    r_f = c_f - np.interp(t_f, t, c_hat)
    return c_hat + O._offset_timeline(t, t_f, r_f, refresh_s, 1.0 / fps)


def _affine_refreshed(s, c_hat: np.ndarray, fps: float, refresh_s: float, prior_var: float) -> np.ndarray:
    """a + g c_hat, with (a, g) refreshed every refresh_s from the frames complete before the
    refresh: least squares of the frame angles on c_hat with a prior g = 1 worth one frame of
    spread prior_var (deg^2; the calibration record's angle variance), so that the first frames,
    which barely move, leave the gain at 1; g clamped to GAIN_BOUNDS; a = c_hat's offset alone
    (g = 1, a = 0) before the first frame. The offset-only refresh is the case prior_var -> inf.
    Causal as online._offset_timeline: (a, g) at t use frames ending before the last refresh."""
    from ..fit.reversals import frames_from_angle

    t = s.encoder["t_s"]
    t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], fps)
    x_f = np.interp(t_f, t, c_hat)
    ok = np.isfinite(c_f)
    tf, x, y = t_f[ok] + 0.5 / fps, x_f[ok], c_f[ok]
    cs = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones_like(x), x, y, x * x, x * y)]
    t_r = t[0] + refresh_s * np.floor((t - t[0]) / refresh_s)
    n = np.searchsorted(tf, t_r, side="left")
    N, Sx, Sy, Sxx, Sxy = (c[n] for c in cs)
    Nn = np.maximum(N, 1)
    mx, my = Sx / Nn, Sy / Nn
    g = (Sxy - Nn * mx * my + prior_var) / (Sxx - Nn * mx * mx + prior_var)
    g = np.where(N > 0, np.clip(g, *GAIN_BOUNDS), 1.0)
    a = np.where(N > 0, my - g * mx, 0.0)
    return a + g * c_hat


def _in_situ(s, t_split: float, src: str):
    """Ours with the transition (calibrate, model_kind "auto") and the constant play + poly5,
    both fitted on the samples of s with t < t_split only (on the frames the chain sees,
    insitu.calibration_frames), run over the whole record from q[0] in double precision:
    (their predictions (N,) deg at the encoder samples, ours' Calibration, the part it saw)."""
    from ..fit.baselines import fit_constant_play

    cal_s = s.slice_time(-np.inf, t_split)
    cal = calibrate(cal_s, f_method="lsq", model_kind="auto", source=src)
    _, fp, Bc = fit_constant_play(*calibration_frames(cal_s, cal))
    q = s.encoder["q"]
    return cal.predict(q), model.direct_model(q, Bc, fp), cal, cal_s


def evaluate_transfer(cal_path, paths, warmup: float = WARMUP, refresh_s: float = 1.0,
                      progress=lambda it, **kw: it) -> dict:
    """Every row of ROWS on each record of paths with the calibration of cal_path. Returns the
    JSON document (keys: JSON_KEYS). Errors: InputError for a bad warm-up, an unreadable
    record, or a record the chain cannot calibrate (naming the file)."""
    if not 0.0 < warmup < 1.0:
        raise InputError(None, f"--warmup {warmup} outside (0, 1)")
    s_ref = read_record(cal_path)
    cal = calibrate(s_ref, f_method="lsq", model_kind="play", source=str(cal_path))
    cal_tr = calibrate(s_ref, f_method="lsq", model_kind="auto", source=str(cal_path))
    ref_const = O.const_play_ref(s_ref, cal.fps_frames)
    prior_var = float(np.var(s_ref.distal["c_deg"]))
    fps = 1.0 / cal.onset_config["frame_period_s"]  # the board's detector frame rate, as online.evaluate_online
    f_cfg = O.f_config_from(s_ref, cal, refresh_s)
    f_range = (float(np.nanmin(s_ref.distal["c_deg"])), float(np.nanmax(s_ref.distal["c_deg"])))
    st = O.OnlineSettings(refresh_s=refresh_s, score_after=warmup)
    files = {}
    for p in progress(list(paths), desc="transfer"):
        s = read_record(p)
        t, q = s.encoder["t_s"], s.encoder["q"]
        on = O.evaluate_online(cal, s, st, ref_const=ref_const)
        t_split = on["t_split_s"]
        mask = t >= t_split
        c_true = np.interp(t, s.distal["t_s"], s.distal["c_deg"])
        ins = _in_situ(s, t_split, str(p))
        c_tr = T.direct_chain(q, cal_tr.B_model, cal_tr.transition, cal_tr.f)
        c_cp = model.direct_model(q, *ref_const)
        err = lambda c_hat: O.rmse((c_hat - c_true)[mask])  # noqa: E731
        r = {"in_situ": err(ins[0]), "in_situ_const_play": err(ins[1]), "static_transition": err(c_tr),
             "const_play_ref": err(c_cp), "transition_offset": err(_offset_refreshed(s, c_tr, fps, refresh_s))}
        for k, c_hat in (("in_situ_affine", ins[0]), ("static_affine", cal.predict(q)), ("transition_affine", c_tr),
                         ("const_play_ref_affine", c_cp)):
            r[k] = err(_affine_refreshed(s, c_hat, fps, refresh_s, prior_var))
        board_f = {}
        # In situ, the learner's settings come from the record's own calibration (its warm-up part),
        # as a board calibrated there would be flashed with them.
        cal_in, s_in = ins[2], ins[3]
        in_cfg = (O.f_config_from(s_in, cal_in, refresh_s), 1.0 / cal_in.onset_config["frame_period_s"],
                  (float(np.nanmin(s_in.distal["c_deg"])), float(np.nanmax(s_in.distal["c_deg"]))))
        for k, c_hat in (("in_situ_board", ins[0]), ("static_board", cal.predict(q)), ("transition_board", c_tr),
                         ("const_play_ref_board", c_cp)):
            cfg_k, fps_k, range_k = in_cfg if k == "in_situ_board" else (f_cfg, fps, f_range)
            c_fix, end = O.board_f_refreshed(s, c_hat, fps_k, cfg_k, range_k)
            r[k] = err(c_fix)
            if k == "transition_board":
                board_f = end
        for k in ("static", "online_b_only", "online_offset_only", "online", "const_play_ref_offset"):
            r[k] = on["rmse_deg"][k]
        files[Path(p).stem] = {"config_deg": config_angle(p), "t_split_s": t_split,
                               "rmse_deg": {k: r[k] for k in ROWS}, "b_samples": on["b_samples"], "board_f": board_f}
    return {"format": FORMAT, "calibration": {"file": str(cal_path), "reversals": int(cal.doc["reversals"]),
                                              "b_samples": cal.n_b_samples},
            "settings": {"warmup": warmup, "refresh_s": refresh_s, "board_f": f_cfg}, "order": ROWS, "labels": LABELS, "files": files,
            "mean": {k: float(np.mean([f["rmse_deg"][k] for f in files.values()])) for k in ROWS},
            "worst": {k: float(np.max([f["rmse_deg"][k] for f in files.values()])) for k in ROWS}}


def format_transfer(doc: dict) -> str:
    """Markdown table of evaluate_transfer(): one row per model, one column per record, mean and
    worst (RMSE, deg)."""
    names = list(doc["files"])
    head = [f"{n} ({doc['files'][n]['config_deg']:g} deg)" if doc["files"][n]["config_deg"] is not None else n
            for n in names]
    lines = [f"**Calibrated on {Path(doc['calibration']['file']).stem}, run on each record from its first sample, "
             f"scored after its first {doc['settings']['warmup']:.0%} (bending-angle RMSE, deg)**", "",
             "| model | " + " | ".join(head) + " | mean | worst |", "|---" * (len(names) + 3) + "|"]
    for k in doc["order"]:
        v = [doc["files"][n]["rmse_deg"][k] for n in names]
        lines.append(f"| {doc['labels'][k]} | " + " | ".join(f"{x:.2f}" for x in v) +
                     f" | {doc['mean'][k]:.2f} | {doc['worst'][k]:.2f} |")
    lines.append("| B samples learnt on line | " + " | ".join(str(doc["files"][n]["b_samples"]) for n in names) + " | | |")
    return "\n".join(lines + [""])


def plot_transfer(doc: dict, path, rows=("in_situ", "static", "online", "online_offset_only", "transition_offset", "transition_affine",
                                         "const_play_ref_offset")) -> None:
    """PNG of the RMSE of rows against the configuration angle (or the record's index when the
    records carry none), the calibration record marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(doc["files"])
    x = [doc["files"][n]["config_deg"] for n in names]
    angle = all(v is not None for v in x)
    if not angle:
        x = list(range(len(names)))
    order = np.argsort(x)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for k in rows:
        ax.plot(np.asarray(x)[order], [doc["files"][names[i]]["rmse_deg"][k] for i in order], "o-", label=doc["labels"][k])
    cx = config_angle(doc["calibration"]["file"])
    if angle and cx is not None:
        ax.axvline(cx, color="0.6", ls="--", lw=1, label="calibration configuration")
    if not angle:
        ax.set_xticks(x, names)
    ax.set_xlabel("sheath configuration angle (deg)" if angle else "record")
    ax.set_ylabel(f"RMSE after the first {doc['settings']['warmup']:.0%} (deg)")
    ax.set_title(f"calibrated on {Path(doc['calibration']['file']).stem}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- what learning the drift could reach

CEILING_LEVELS = np.round(np.arange(0.5, 2.0001, 0.05), 2)  # B scale factors tried: a factor 2 either way, as GAIN_BOUNDS


def _best_affine(c_hat: np.ndarray, c_true: np.ndarray) -> float:
    """RMSE of c_true against the least-squares a + g c_hat (fitted on the same samples)."""
    A = np.column_stack([np.ones_like(c_hat), c_hat])
    coef, *_ = np.linalg.lstsq(A, c_true, rcond=None)
    return float(np.sqrt(np.mean((A @ coef - c_true) ** 2)))


def learnable_ceiling(cal_path, paths, warmup: float = WARMUP, in_situ_cache: dict | None = None) -> dict:
    """What learning the drifting terms could reach at best: CAL's model with the transition run
    on each record of paths from its first sample, with the offset and gain (and the B level)
    chosen afterwards on the scored samples themselves (an oracle, not a causal update: a lower
    bound for any on-line learner of those terms), beside the in-situ reference on the same
    samples. B level: B scaled by each of CEILING_LEVELS, the best kept. in_situ_cache: a dict
    the in-situ predictions are kept in by record path (a caller running several calibrations).
    Returns {"calibration", "warmup", "files": {name: {"in_situ", "affine", "affine_b_level",
    "b_scale"}}} (RMSE, deg)."""
    s_ref = read_record(cal_path)
    cal_tr = calibrate(s_ref, f_method="lsq", model_kind="auto", source=str(cal_path))
    B = cal_tr.B_model
    files = {}
    for p in paths:
        s = read_record(p)
        t, q = s.encoder["t_s"], s.encoder["q"]
        t_split = float(t[0] + warmup * (t[-1] - t[0]))
        mask = t >= t_split
        c_true = np.interp(t, s.distal["t_s"], s.distal["c_deg"])[mask]
        cache = in_situ_cache if in_situ_cache is not None else {}
        if str(p) not in cache:
            cache[str(p)] = _in_situ(s, t_split, str(p))[0]
        ins = cache[str(p)]
        per_level = [_best_affine(T.direct_chain(q, lambda x, k=k: k * B(x), cal_tr.transition, cal_tr.f)[mask], c_true)
                     for k in CEILING_LEVELS]
        i = int(np.argmin(per_level))
        one = int(np.argmin(np.abs(CEILING_LEVELS - 1.0)))
        files[Path(p).stem] = {"config_deg": config_angle(p), "in_situ": O.rmse(ins[mask] - c_true),
                               "affine": per_level[one], "affine_b_level": per_level[i],
                               "b_scale": float(CEILING_LEVELS[i])}
    return {"calibration": str(cal_path), "warmup": warmup, "files": files}


def format_ceiling(docs: list[dict]) -> str:
    """Markdown table of learnable_ceiling() results (one per calibration record)."""
    lines = ["**What learning the drift could reach at best (oracle offset, gain and B level chosen on the scored "
             "samples; RMSE after the warm-up, deg)**", "",
             "| calibrated on | run on | in situ (reference) | + best offset and gain | ratio to in situ | "
             "+ best offset, gain and B level (B scale) | ratio to in situ |", "|---|---|---|---|---|---|---|"]
    for d in docs:
        for n, f in d["files"].items():
            lines.append(f"| {Path(d['calibration']).stem} | {n} | {f['in_situ']:.2f} | {f['affine']:.2f} | "
                         f"{f['affine'] / f['in_situ']:.1f} | {f['affine_b_level']:.2f} ({f['b_scale']:.2f}) | "
                         f"{f['affine_b_level'] / f['in_situ']:.1f} |")
    return "\n".join(lines + [""])


# ---------------------------------------------------------------- what drifts between records

DRIFT_KEYS = ["offset_deg", "gain", "f_shape_deg", "b_level", "b_level_rel", "b_shape", "transition"]


def _params(s, src: str) -> dict:
    cal = calibrate(s, f_method="lsq", model_kind="auto", source=src)
    tr = cal.transition
    return {"cal": cal, "transition": {"model": "play" if tr.is_play else "pi", "n_ops": int(tr.n),
                                       "b_scale": float(tr.b_scale), "w": [float(v) for v in tr.w],
                                       "r": [float(v) for v in tr.r]}}


def drift(paths, ref, n_grid: int = 200) -> dict:
    """Each record of paths (and ref) calibrated in situ on its whole length (`calibrate`,
    model_kind "auto"); parameters of each compared with ref's over the travel both saw.
    Per record (the pure-play f_remain, on the play centre z, and the onset B):
      offset_deg   mean of f(z) - f_ref(z) over the common z range (deg)
      gain         ratio of the least-squares slopes of f and f_ref against z over that range
      f_shape_deg  RMS of f - f_ref after removing the best affine map a + g f_ref (deg)
      b_level      mean of B - B_ref over the common q range (actuator units); b_level_rel / mean B_ref
      b_shape      RMS of (B - mean B) - (B_ref - mean B_ref) over that range (actuator units)
      transition   the chosen transition: model, n_ops, b_scale, operator weights w, thresholds r
      *_effect_deg what each change is worth at the tip: offset; (gain - 1) x half the f_ref span;
                   slope of f_ref x b_level / 2 and x b_shape / 2 (a play half-width moves z by B/2)
    Returns {"reference": name, "unit", "files": {name: {...}}} with ref among the files (zeros)."""
    sessions = {Path(p).stem: read_record(p) for p in [ref, *[p for p in paths if Path(p) != Path(ref)]]}
    par = {n: _params(s, n) for n, s in sessions.items()}
    rname = Path(ref).stem
    r = par[rname]["cal"]
    out = {"reference": rname, "unit": r.actuator_unit, "files": {}}
    for n, p in par.items():
        c = p["cal"]
        lo = max(c.q_range[0], r.q_range[0])
        hi = min(c.q_range[1], r.q_range[1])
        qg = np.linspace(lo, hi, n_grid)
        b, br = c.B(qg), r.B(qg)
        # f is on z; the common z range: the common q range less the half-widths both saw.
        zlo, zhi = lo + 0.5 * max(np.max(b), np.max(br)), hi - 0.5 * max(np.max(b), np.max(br))
        if zhi <= zlo:
            zlo, zhi = lo, hi
        zg = np.linspace(zlo, zhi, n_grid)
        f, fr = c.f_play(zg), r.f_play(zg)
        slope = np.polyfit(zg, f, 1)[0]
        slope_r = np.polyfit(zg, fr, 1)[0]
        A = np.column_stack([np.ones_like(fr), fr])
        coef, *_ = np.linalg.lstsq(A, f, rcond=None)
        d = {"offset_deg": float(np.mean(f - fr)), "gain": float(slope / slope_r),
             "f_shape_deg": float(np.sqrt(np.mean((f - A @ coef) ** 2))),
             "b_level": float(np.mean(b - br)), "b_level_rel": float(np.mean(b - br) / np.mean(br)),
             "b_shape": float(np.sqrt(np.mean(((b - b.mean()) - (br - br.mean())) ** 2))),
             "b_mean": float(np.mean(b)), "transition": p["transition"], "reversals": int(c.doc["reversals"]),
             "b_samples": c.n_b_samples, "config_deg": config_angle(sessions[n].meta["source"]["file"])}
        d["offset_effect_deg"] = abs(d["offset_deg"])
        d["gain_effect_deg"] = abs(d["gain"] - 1.0) * 0.5 * float(np.ptp(fr))
        d["b_level_effect_deg"] = abs(slope_r * d["b_level"]) / 2
        d["b_shape_effect_deg"] = abs(slope_r) * d["b_shape"] / 2
        out["files"][n] = d
    return out


def format_drift(res: dict) -> str:
    """Markdown table of drift(): one row per record, each parameter's change against the
    reference and its effect at the tip (deg)."""
    u = res["unit"]
    lines = [f"**What moves between records: each calibrated in situ on its whole length, compared with "
             f"{res['reference']} over the travel both saw**", "",
             f"| record | offset (deg) | gain of f_remain | f shape (deg) | B level ({u}) | B level (%) | "
             f"B shape ({u}) | transition (model, n, b_scale, w) | effect at the tip (deg): offset / gain / B level / B shape |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n, d in res["files"].items():
        tr = d["transition"]
        w = ", ".join(f"{v:.2f}" for v in tr["w"])
        lines.append(f"| {n} | {d['offset_deg']:+.2f} | {d['gain']:.3f} | {d['f_shape_deg']:.2f} | {d['b_level']:+.3f} | "
                     f"{100 * d['b_level_rel']:+.0f} | {d['b_shape']:.3f} | {tr['model']}, {tr['n_ops']}, "
                     f"{tr['b_scale']:.2f}, [{w}] | {d['offset_effect_deg']:.2f} / {d['gain_effect_deg']:.2f} / "
                     f"{d['b_level_effect_deg']:.2f} / {d['b_shape_effect_deg']:.2f} |")
    return "\n".join(lines + [""])
