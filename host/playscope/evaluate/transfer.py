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
  <peer>_ref, <peer>_ref_offset, <peer>_ref_affine, <peer>_ref_board
                     each textbook peer of PEERS (generalized PI, the same with its cubic held
                     increasing, modified PI, the same with its output monotone) fitted on the
                     calibration record's frames (online.reference_frames, as const_play_ref),
                     as is and with ours' three updates, same settings; peer_comparison puts
                     ours (the transition rows) against them on the mean

Drift measurement (`drift`): each record calibrated in situ on its whole length; its
parameters compared with the calibration record's over the travel both saw.

What learning could reach (double precision, for choosing what the board should learn):
`learnable_ceiling` (offset, gain and a B level chosen on the scored samples), `shape_ceiling`
(a correction of f's shape, per branch of the loop, of the transition's weights, or weights and
branch together: oracle, warm-up fit and causal RLS) and `shape_noregress` (those learners on
each record's in-situ model, where nothing drifts).

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
from ..fit.peers import GeneralizedPI, IncreasingGPI, ModifiedPI
from .insitu_split import INVERTIBLE, calibration_frames

FORMAT = "playscope-transfer/1"
# Textbook peers calibrated on the same record (its frames, as const_play_ref) and given the same
# updates as ours (transition_*): (key, label, fit(q, c) -> object with predict(q)).
PEERS = [
    ("gpi", "generalized PI (16 plays + cubic)", lambda q, c: GeneralizedPI.fit(q, c)),
    ("gpi_inc", "generalized PI, cubic held increasing (invertible)", lambda q, c: IncreasingGPI.fit(q, c)),
    ("mpi", "modified PI (16 plays + output spline)", lambda q, c: ModifiedPI.fit(q, c)),
    ("mpi_inc", "modified PI, output monotone (invertible: pi_const)", lambda q, c: ModifiedPI.fit(q, c, monotone=True)),
]
# The peers whose model has an inverse a compensator can run: those of PEERS that the in-situ
# evaluation counts invertible (insitu_split.INVERTIBLE: the forms fitted under the constraint that
# makes them so). The generalized PI's fitted cubic turns back on every development record
# (peers.IncreasingGPI), and the modified PI's free output spline may.
INVERTIBLE_PEERS = tuple(k for k, _, _ in PEERS if k in INVERTIBLE)
UPDATES = [("", "as is"), ("_offset", "+ offset refresh"), ("_affine", "+ offset and gain refresh"),
           ("_board", "+ the board's offset and gain learner")]
PEER_ROWS = [f"{k}_ref{u}" for k, _, _ in PEERS for u, _ in UPDATES]
ROWS = ["in_situ", "in_situ_affine", "in_situ_const_play", "static", "static_transition", "online_b_only", "online_offset_only",
        "online", "transition_offset", "const_play_ref", "const_play_ref_offset", "static_affine", "transition_affine",
        "const_play_ref_affine", "in_situ_board", "static_board", "transition_board", "const_play_ref_board"] + PEER_ROWS
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
    **{f"{k}_ref{u}": f"{lab} of the calibration record {ul}" for k, lab, _ in PEERS for u, ul in UPDATES},
}
GAIN_BOUNDS = (0.5, 2.0)  # the gain refresh's clamp: a factor 2 either way, far outside any record's fitted gain
WARMUP = 0.5  # fraction of the duration; the only split giving every endoscope record >= 2 reversals before it
JSON_KEYS = ("format, calibration {file, reversals, b_samples}, settings {warmup, refresh_s, board_f {mem_log2, "
             "publish_every, prior_var_q16}}, order [row], labels {row: str}, files {name: {config_deg (sheath angle "
             "from the file name, null for the catheter), t_split_s, rmse_deg {row: float}, b_samples (learnt on "
             "line), board_f {publishes, a_deg, g} (the transition row's learner at the end)}}, mean {row: float}, "
             "worst {row: float}, peers_vs_ours {update suffix: {ours, ours_mean, peers {row: mean}, best_peer, "
             "ours_le_every_peer, invertible_peers [row], best_invertible_peer, ours_le_every_invertible_peer}}")

# Endoscope files: column of the distal angle by file name (README of the data set).



def _read_records(cal_path, paths) -> tuple:
    """(the calibration record, {path: record}) read with read_record, every one before any work;
    InputError naming the file for a record in another actuator unit than the calibration's."""
    s_ref = read_record(cal_path)
    records = {}
    for p in paths:
        records[p] = read_record(p)
        if records[p].actuator_unit != s_ref.actuator_unit:
            raise InputError(p, f"q is in {records[p].actuator_unit} but the calibration record {cal_path} is in "
                             f"{s_ref.actuator_unit}: a calibration runs only on records of its own actuator unit "
                             "(mm of cable or deg of motor); transfer between records of one kind")
    return s_ref, records

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
    s_ref, records = _read_records(cal_path, paths)
    cal = calibrate(s_ref, f_method="lsq", model_kind="play", source=str(cal_path))
    cal_tr = calibrate(s_ref, f_method="lsq", model_kind="auto", source=str(cal_path))
    ref_const = O.const_play_ref(s_ref, cal.fps_frames)
    q_ref, c_ref = O.reference_frames(s_ref, cal.fps_frames)  # the frames const_play_ref is fitted on
    peers = {k: fit(q_ref, c_ref) for k, _, fit in PEERS}
    prior_var = float(np.var(s_ref.distal["c_deg"]))
    fps = 1.0 / cal.onset_config["frame_period_s"]  # the board's detector frame rate, as online.evaluate_online
    f_cfg = O.f_config_from(s_ref, cal, refresh_s)
    f_range = (float(np.nanmin(s_ref.distal["c_deg"])), float(np.nanmax(s_ref.distal["c_deg"])))
    st = O.OnlineSettings(refresh_s=refresh_s, score_after=warmup)
    files = {}
    for p in progress(list(paths), desc="transfer"):
        s = records[p]
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
        for k, m in peers.items():  # each peer with ours' updates (settings of the calibration record)
            c_p = m.predict(q)
            r[f"{k}_ref"] = err(c_p)
            r[f"{k}_ref_offset"] = err(_offset_refreshed(s, c_p, fps, refresh_s))
            r[f"{k}_ref_affine"] = err(_affine_refreshed(s, c_p, fps, refresh_s, prior_var))
            r[f"{k}_ref_board"] = err(O.board_f_refreshed(s, c_p, fps, f_cfg, f_range)[0])
        files[Path(p).stem] = {"config_deg": config_angle(p), "t_split_s": t_split,
                               "rmse_deg": {k: r[k] for k in ROWS}, "b_samples": on["b_samples"], "board_f": board_f}
    doc = {"format": FORMAT, "calibration": {"file": str(cal_path), "reversals": int(cal.doc["reversals"]),
                                              "b_samples": cal.n_b_samples},
            "settings": {"warmup": warmup, "refresh_s": refresh_s, "board_f": f_cfg}, "order": ROWS, "labels": LABELS, "files": files,
            "mean": {k: float(np.mean([f["rmse_deg"][k] for f in files.values()])) for k in ROWS},
            "worst": {k: float(np.max([f["rmse_deg"][k] for f in files.values()])) for k in ROWS}}
    doc["peers_vs_ours"] = peer_comparison(doc)
    return doc


OURS_BY_UPDATE = {"": "static_transition", "_offset": "transition_offset", "_affine": "transition_affine",
                  "_board": "transition_board"}  # ours (with the transition) with each update of UPDATES


TIE_DEG = 1e-3  # ours <= a peer within this: where the family chosen is pi_const, ours is the mpi_inc peer itself


def peer_comparison(doc: dict) -> dict:
    """Ours against every peer given the same update, on the mean over the records (RMSE, deg):
    {update suffix: {"ours": row, "ours_mean", "peers": {row: mean}, "best_peer",
    "ours_le_every_peer", "invertible_peers": [row] (INVERTIBLE_PEERS with that update),
    "best_invertible_peer", "ours_le_every_invertible_peer"}}, each verdict within TIE_DEG.
    The invertible verdict is the one a compensator can be held to: a peer without an inverse
    predicts the angle but cannot be run backwards to command the actuator."""
    out = {}
    for u, _ in UPDATES:
        ours = OURS_BY_UPDATE[u]
        pm = {f"{k}_ref{u}": doc["mean"][f"{k}_ref{u}"] for k, _, _ in PEERS}
        inv = [f"{k}_ref{u}" for k in INVERTIBLE_PEERS]
        best, best_inv = min(pm, key=pm.get), min(inv, key=pm.get)
        out[u] = {"ours": ours, "ours_mean": doc["mean"][ours], "peers": pm, "best_peer": best,
                  "ours_le_every_peer": bool(doc["mean"][ours] <= pm[best] + TIE_DEG),
                  "invertible_peers": inv, "best_invertible_peer": best_inv,
                  "ours_le_every_invertible_peer": bool(doc["mean"][ours] <= pm[best_inv] + TIE_DEG)}
    return out


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
    lines.append("")
    name = lambda row: doc["labels"][row].split(" of the calibration record")[0]  # noqa: E731
    yes = lambda v: "yes" if v else "NO"  # noqa: E731
    cmp = peer_comparison(doc)  # from the rows, so a document written before the invertible verdict prints it too
    for u, ul in UPDATES:
        c = cmp[u]
        lines.append(f"Ours with the transition {ul}: mean {c['ours_mean']:.3f} deg; best peer given the same, "
                     f"{name(c['best_peer'])}: {c['peers'][c['best_peer']]:.3f} deg; ours <= every peer: "
                     f"{yes(c['ours_le_every_peer'])}; best invertible peer ({', '.join(INVERTIBLE_PEERS)}), "
                     f"{name(c['best_invertible_peer'])}: {c['peers'][c['best_invertible_peer']]:.3f} deg; ours <= every "
                     f"invertible peer: {yes(c['ours_le_every_invertible_peer'])}")
    return "\n".join(lines + [""])


def plot_transfer(doc: dict, path, rows=("in_situ", "static", "online", "online_offset_only", "transition_offset", "transition_affine",
                                         "const_play_ref_offset", "transition_board", "const_play_ref_board",
                                         "gpi_ref_board", "gpi_inc_ref_board", "mpi_ref_board", "mpi_inc_ref_board")) -> None:
    """PNG of the RMSE of rows against the configuration angle (or the record's index when the
    records carry none), the calibration record marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker  # noqa: F401  (the log axis' plain labels)

    names = list(doc["files"])
    x = [doc["files"][n]["config_deg"] for n in names]
    angle = all(v is not None for v in x)
    if not angle:
        x = list(range(len(names)))
    order = np.argsort(x)
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    colours = plt.get_cmap("tab20")
    for j, k in enumerate(rows):  # the textbook peers dashed, ours and the references solid
        ax.plot(np.asarray(x)[order], [doc["files"][names[i]]["rmse_deg"][k] for i in order],
                "s--" if k in PEER_ROWS else "o-", color=colours(j % 20), label=doc["labels"][k])
    cx = config_angle(doc["calibration"]["file"])
    if angle and cx is not None:
        ax.axvline(cx, color="0.6", ls="--", lw=1, label="calibration configuration")
    if not angle:
        ax.set_xticks(x, names)
    ax.set_xlabel("sheath configuration angle (deg)" if angle else "record")
    ax.set_ylabel(f"RMSE after the first {doc['settings']['warmup']:.0%} (deg)")
    ax.set_title(f"calibrated on {Path(doc['calibration']['file']).stem}")
    ax.grid(alpha=0.3)
    ax.set_yscale("log")  # as-is rows are ten times the updated ones
    ax.yaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=1, frameon=False)
    fig.tight_layout()
    from ..base.atomic import PNG_METADATA, atomic_path

    with atomic_path(path) as tmp:  # through the output guard, renamed into place
        fig.savefig(tmp, dpi=110, format="png", metadata=PNG_METADATA)
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


# ---------------------------------------------------------------- what learning f's shape could reach

SHAPE_NODES = (4, 8)  # node counts measured (16 adds nothing over 8 on the endoscope development pairs)


def hat_basis(y: np.ndarray, lo: float, hi: float, n_nodes: int) -> np.ndarray:
    """Hat functions (linear B-splines) on n_nodes evenly spaced nodes over [lo, hi] at y (N,),
    y clamped to [lo, hi] (the correction is held constant beyond the end nodes). Returns (N,
    n_nodes); each row sums to 1 (so the span holds a constant offset and, piecewise, a gain)."""
    u = (np.clip(np.asarray(y, float), lo, hi) - lo) / (hi - lo) * (n_nodes - 1)
    i = np.minimum(np.floor(u).astype(int), n_nodes - 2)
    w = u - i
    H = np.zeros((u.size, n_nodes))
    H[np.arange(u.size), i] = 1.0 - w
    H[np.arange(u.size), i + 1] = w
    return H


def motion_direction(q: np.ndarray) -> np.ndarray:
    """Direction of motion of q (N,) at each sample: +1 or -1, held through still stretches (the
    first motion's direction before it)."""
    dq = np.sign(np.diff(np.asarray(q, float), prepend=q[0]))
    idx = np.where(dq != 0, np.arange(dq.size), -1)
    np.maximum.accumulate(idx, out=idx)
    nz = np.flatnonzero(dq)
    first = dq[nz[0]] if nz.size else 1.0
    return np.where(idx >= 0, dq[np.maximum(idx, 0)], first)


def branch_split(H: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N, n) hat rows -> (N, 2n): the first n columns on the rising branch (d > 0), the last n on
    the falling one: a correction of f per branch of the loop (its width and its shape)."""
    up = (np.asarray(d) > 0)[:, None]
    return np.hstack([H * up, H * ~up])


def rls_shape(H: np.ndarray, r: np.ndarray, lam: float, p0: float = 1.0) -> np.ndarray:
    """Exponentially weighted RLS of r (M,) on the rows of H (M, n) with b_online's bounded
    covariance (firmware/core/b_online.c, in double): theta = 0, P = p0 I at the start; per row
    g = P h, s = lam + h'g, k = g/s, theta += k (r - h'theta), P = D (P - k g') D with
    d_i = 1/sqrt(lam) unless P_ii would pass p0 (then 1). Returns theta after each row (M, n)."""
    n = H.shape[1]
    th = np.zeros(n)
    P = p0 * np.eye(n)
    out = np.empty((H.shape[0], n))
    isl = 1.0 / np.sqrt(lam)
    for m in range(H.shape[0]):
        h = H[m]
        g = P @ h
        k = g / (lam + h @ g)
        th = th + k * (r[m] - h @ th)
        P = P - np.outer(k, g)
        d = np.where(np.diag(P) <= lam * p0, isl, 1.0)
        P = P * np.outer(d, d)
        out[m] = th
    return out


N_EXTRA_OPS = 4  # play operators added above the transition's widest for the weights' refit


def weights_regressor(cal_tr, q: np.ndarray, r_extra: np.ndarray) -> np.ndarray:
    """Regressor of a refit of the transition's operator weights, linearised about the model:
    c ~ f(y) + a + sum_i dw_i f'(y) p_i(z) over the transition's operators (thresholds r) and
    play operators of thresholds r_extra (a wider play than the calibration saw), z the play
    centre from q[0], y = PI(z). Columns [1, f'(y) p_i]. q: (N,); returns (N, 1 + n + len(r_extra))."""
    tr = cal_tr.transition
    z = model.play_operator(q, cal_tr.B_model)
    y = tr.direct(z)
    h = 1e-3 * max(float(np.ptp(y)), 1.0)
    fp = (cal_tr.f(y + h) - cal_tr.f(y - h)) / (2 * h)
    P = T.play_ops(tr.to_ops(z), np.r_[tr.r, r_extra])
    return np.column_stack([np.ones_like(y), fp[:, None] * P])


def shape_ceiling(cal_path, paths, warmup: float = WARMUP, refresh_s: float = 1.0, nodes=SHAPE_NODES,
                  in_situ_cache: dict | None = None) -> dict:
    """What learning f's shape could reach: CAL's model with the transition (y = PI(play(q; B)),
    the model's pre-f output) run on each record of paths from its first sample, corrected as
    c = f_cal(y) + sum_i theta_i h_i(y), h_i hat functions on n nodes evenly over the y range
    the calibration record's own run covers (hat_basis), scored after the warm-up beside the
    in-situ reference. Per node count n:
      shape_<n>_oracle  theta least squares on the scored samples themselves (a lower bound of any constant theta)
      shape_<n>_rls     theta by rls_shape on the record's angle frames (the board's onset frame
                        rate) from the first one, forgetting lambda = 1 - 2^-mem_log2 and a
                        publish every publish_every frames (both f_config_from's, from the
                        calibration record only), p0 = 1 (the flashed f weighs as one reading per
                        node); the theta published last applies from its frame's completion on
      shape_<n>_warmup  theta fitted once on the frames complete before the split (rls_shape
                        with lambda = 1, i.e. least squares with the p0 = 1 prior) and held: what a
                        learner with perfect memory knows when scoring starts
    the branch_<n>_* rows the same with one set of nodes per direction of motion of q
    (branch_split: a correction of the loop's width as well as of f's shape), the weights_* rows
    with weights_regressor's columns (a refit of the transition's weights, N_EXTRA_OPS wider plays
    up to half the calibration record's q span added, linearised, plus an offset), and "board" (the
    transition + the board's offset and gain learner, for comparison), the wbranch_<n>_* rows both
    (the weights' columns beside the per-branch hats). Row names: <kind>_oracle, <kind>_warmup,
    <kind>_rls with kind shape_<n>, branch_<n>, weights or wbranch_<n>.
    Returns {"calibration", "warmup", "settings", "files": {name: {"in_situ", row: rmse}}} (deg)."""
    s_ref, records = _read_records(cal_path, paths)
    cal = calibrate(s_ref, f_method="lsq", model_kind="play", source=str(cal_path))
    cal_tr = calibrate(s_ref, f_method="lsq", model_kind="auto", source=str(cal_path))
    learn = _Learners(s_ref, cal, cal_tr, refresh_s, nodes)
    files = {}
    for p in paths:
        s = read_record(p)
        t = s.encoder["t_s"]
        t_split = float(t[0] + warmup * (t[-1] - t[0]))
        cache = in_situ_cache if in_situ_cache is not None else {}
        if str(p) not in cache:
            cache[str(p)] = _in_situ(s, t_split, str(p))[0]
        files[Path(p).stem] = learn.rows(s, t_split, cache[str(p)])
    return {"calibration": str(cal_path), "warmup": warmup, "settings": learn.settings(), "files": files}


def shape_noregress(paths, warmup: float = WARMUP, refresh_s: float = 1.0, nodes=SHAPE_NODES) -> dict:
    """Where nothing drifts: each record of paths with the in-situ model (transition fitted on its
    own warm-up part, _in_situ) and each learner of shape_ceiling on it, its settings from that
    part (as a board calibrated there would be flashed), scored after the warm-up. Returns
    {"warmup", "files": {name: {"in_situ", row: rmse}}} with the rows of shape_ceiling (deg)."""
    files = {}
    for p in paths:
        s = read_record(p)
        t = s.encoder["t_s"]
        t_split = float(t[0] + warmup * (t[-1] - t[0]))
        c_in, _, cal_in, s_in = _in_situ(s, t_split, str(p))
        files[Path(p).stem] = _Learners(s_in, cal_in, cal_in, refresh_s, nodes).rows(s, t_split, c_in)
    return {"warmup": warmup, "files": files}


NOREGRESS_ROWS = ("board", "shape_8_rls", "branch_8_rls", "weights_rls", "wbranch_4_rls", "wbranch_8_rls")


def format_noregress(doc: dict, rows=NOREGRESS_ROWS) -> str:
    """Markdown table of shape_noregress(): RMSE after the warm-up per record and the change
    against the in-situ model (target: <= +2 %)."""
    lines = ["**Where nothing drifts: the in-situ model with each causal learner (RMSE after the warm-up, deg; "
             "change against in situ)**", "", "| record | in situ | " + " | ".join(rows) + " |",
             "|---|---" + "|---" * len(rows) + "|"]
    for n, f in doc["files"].items():
        lines.append(f"| {n} | {f['in_situ']:.3f} | " +
                     " | ".join(f"{f[k]:.3f} ({100 * (f[k] / f['in_situ'] - 1):+.0f} %)" for k in rows) + " |")
    return "\n".join(lines + [""])


class _Learners:
    """The corrections of shape_ceiling on one model (cal_tr: a Calibration with a transition),
    their settings from its calibration record s_cal (cal: the calibration whose onset frame rate
    and reversals f_config_from reads)."""

    def __init__(self, s_cal, cal, cal_tr, refresh_s: float, nodes):
        self.cal_tr, self.nodes = cal_tr, tuple(nodes)
        self.fps = 1.0 / cal.onset_config["frame_period_s"]
        self.f_cfg = O.f_config_from(s_cal, cal, refresh_s)
        self.lam = 1.0 - 2.0 ** -self.f_cfg["mem_log2"]
        self.every = int(self.f_cfg["publish_every"])
        y_ref = cal_tr.transition.direct(model.play_operator(s_cal.encoder["q"], cal_tr.B_model))
        self.y_lo, self.y_hi = float(np.min(y_ref)), float(np.max(y_ref))
        r_last = float(cal_tr.transition.r[-1])
        half_span = 0.5 * float(np.ptp(s_cal.encoder["q"]))
        self.r_extra = (np.linspace(r_last, half_span, N_EXTRA_OPS + 1)[1:] if half_span > r_last else np.zeros(0))
        self.f_range = (float(np.nanmin(s_cal.distal["c_deg"])), float(np.nanmax(s_cal.distal["c_deg"])))

    def settings(self) -> dict:
        return {"lambda": self.lam, "publish_every": self.every, "y_range": [self.y_lo, self.y_hi],
                "nodes": list(self.nodes), "r_extra": [float(v) for v in self.r_extra]}

    def rows(self, s, t_split: float, c_in_situ: np.ndarray) -> dict:
        """{"in_situ", "board", <kind>_oracle|_warmup|_rls}: RMSE (deg) after t_split on record s."""
        from ..fit.reversals import frames_from_angle

        cal_tr, fps, lam, every = self.cal_tr, self.fps, self.lam, self.every
        t, q = s.encoder["t_s"], s.encoder["q"]
        mask = t >= t_split
        c_true = np.interp(t, s.distal["t_s"], s.distal["c_deg"])
        y = cal_tr.transition.direct(model.play_operator(q, cal_tr.B_model))
        c0 = cal_tr.f(y)
        row = {"in_situ": O.rmse((c_in_situ - c_true)[mask])}
        row["board"] = O.rmse((O.board_f_refreshed(s, c0, fps, self.f_cfg, self.f_range)[0] - c_true)[mask])
        t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], fps)
        ok = np.isfinite(c_f)
        t_f, c_f = t_f[ok], c_f[ok]
        y_f = np.interp(t_f, t, y)
        k_done = np.searchsorted(t, t_f + 0.5 / fps, side="left")
        r_f = c_f - cal_tr.f(y_f)
        pre = k_done < np.searchsorted(t, t_split, side="left")

        def fit_rows(kind: str, H: np.ndarray, Hf: np.ndarray) -> None:
            # The correction H @ theta on the model's c0: oracle, warm-up fit, causal RLS.
            th, *_ = np.linalg.lstsq(H[mask], (c_true - c0)[mask], rcond=None)
            row[f"{kind}_oracle"] = O.rmse((c0 + H @ th - c_true)[mask])
            th_w = rls_shape(Hf[pre], r_f[pre], 1.0)[-1] if pre.any() else np.zeros(H.shape[1])
            row[f"{kind}_warmup"] = O.rmse((c0 + H @ th_w - c_true)[mask])
            ths = rls_shape(Hf, r_f, lam)
            theta_t = np.zeros(H.shape)
            for m in range(every - 1, len(t_f), every):  # a publish every `every` readings
                theta_t[k_done[m]:] = ths[m]
            row[f"{kind}_rls"] = O.rmse((c0 + np.einsum("ij,ij->i", H, theta_t) - c_true)[mask])

        d = motion_direction(q)
        j_f = np.clip(np.searchsorted(t, t_f, side="right") - 1, 0, t.size - 1)  # the sample a frame ends on
        X = weights_regressor(cal_tr, q, self.r_extra)
        fit_rows("weights", X, X[j_f])
        for n in self.nodes:
            H, Hf = hat_basis(y, self.y_lo, self.y_hi, n), hat_basis(y_f, self.y_lo, self.y_hi, n)
            fit_rows(f"shape_{n}", H, Hf)
            Hb, Hbf = branch_split(H, d), branch_split(Hf, d[j_f])
            fit_rows(f"branch_{n}", Hb, Hbf)
            fit_rows(f"wbranch_{n}", np.hstack([X, Hb]), np.hstack([X[j_f], Hbf]))
        return row


def format_shape(docs: list[dict]) -> str:
    """Markdown table of shape_ceiling() results: RMSE after the warm-up and ratio to in situ."""
    nodes = docs[0]["settings"]["nodes"]
    kinds = [(f"shape_{n}", f"f shape {n}") for n in nodes] + [(f"branch_{n}", f"per branch {n}") for n in nodes] + \
        [("weights", "weights")] + [(f"wbranch_{n}", f"weights + per branch {n}") for n in nodes]
    ways = (("oracle", "oracle"), ("warmup", "warm-up fit"), ("rls", "RLS"))
    cols = ["board"] + [f"{k}_{w}" for k, _ in kinds for w, _ in ways]
    heads = [f"{h} {wh}" for _, h in kinds for _, wh in ways]
    lines = ["**Learning f's shape (hat functions on the pre-f output y; per branch: one set of nodes per direction "
             "of motion; weights: the transition's weights refitted, linearised): RMSE after the warm-up, deg (ratio to in situ)**", "",
             "| calibrated on | run on | in situ | offset+gain (board) | " + " | ".join(heads) + " |",
             "|---|---|---" + "|---" * len(cols) + "|"]
    for d in docs:
        for name, f in d["files"].items():
            lines.append(f"| {Path(d['calibration']).stem} | {name} | {f['in_situ']:.2f} | " +
                         " | ".join(f"{f[k]:.2f} ({f[k] / f['in_situ']:.1f})" for k in cols) + " |")
    return "\n".join(lines + [""])
