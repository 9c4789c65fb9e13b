"""On-line update during use: the across-session protocol with the board's
B(q) learnt from the onsets of the new session and an offset of f refreshed by the host.

Protocol (docs/online.md): calibrate the pure play (onset B(q) + f_remain) on a reference
session; run every other session from its first sample with
- B: the flashed grid updated by the firmware's own RLS (`firmware/core/b_online.c`, through
  cffi, bit for bit what the board computes) on each B sample the firmware's onset detector
  gives (`onset_tick` / `onset_reversal` / `onset_observe_deg`, fed in time order as the
  board is; the detector's configuration is the reference calibration's, as flashed);
  the new B is used from the frame that completed the onset;
- offset: every `refresh_s` the host sets c_offset = mean(c_frame - f(z)) over every frame
  of the session so far (a session offset is a constant, so its estimate is the mean
  residual since the session start; the paper's Fig. 2 drift) and commits it (A/B table);
  it applies from the refresh on;
and judge the prediction c = f(z) + c_offset against the angle sensor after the first
`score_after` of the duration. Everything is causal: no sample is used before it exists.

Peer, on the same split and the same state handling: a constant play + degree-5 polynomial
(Reilink et al.; `baselines.fit_constant_play`) fitted on the first `score_after` of the same
session (frames block-averaged at the rate `calibration.auto_fps` gives that part's
reversals), run from the session's first sample (play centred at q[0]) and judged on the rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fit.baselines import fit_constant_play
from ..fit.f_remain import characteristic
from ..fit.onsets import JUMP_RATIO_SCALE, OnsetConfig
from ..fit.reversals import detect_reversals, frames_from_angle
from ..fit import model
from ..fit.calibration import auto_fps
from ..base.native import core, from_q16, to_q16
from ..base.metrics import rmse  # noqa: F401  (online.rmse: the figure the transfer and no-regression rows use)
from ..fit.table_build import grid_for

ROWS = ["online", "online_b_only", "online_offset_only", "static", "const_play_insitu",
        "const_play_insitu_offset", "const_play_ref_offset"]
LABELS = {
    "online": "ours, on-line B (board RLS) + offset refresh",
    "online_b_only": "ours, on-line B only",
    "online_offset_only": "ours, offset refresh only",
    "static": "ours without update (calibration session's B, f)",
    "const_play_insitu": "constant play + poly5 refitted in situ (first 20 %)",
    "const_play_insitu_offset": "same + the same offset refresh (peer given our update)",
    "const_play_ref_offset": "constant play + poly5 fitted on the reference file + the same offset refresh",
}


@dataclass
class OnlineSettings:
    """The settings of the protocol; each has a rule (docs/online.md), none was tuned on the
    catheter files. b_config: the C b_online_config_t (None: b_online_default_config())."""

    refresh_s: float = 1.0      # host refresh period of the offset (a table commit per second)
    score_after: float = 0.2    # fraction of the duration before scoring starts


def onset_config_from(cal) -> OnsetConfig:
    """The onset configuration the reference calibration ran (its effective C config), so the
    board's detector during use is the one that calibrated it."""
    c = cal.onset_config
    return OnsetConfig(t_delay_s=c["t_delay_s"], fps=1.0 / c["frame_period_s"], threshold=c["threshold"],
                         threshold_floor=c["threshold_floor"], threshold_max=c["threshold_max"],
                         noise_k=c["noise_k"], settle_frames=c["settle_frames"],
                         max_lost_frames=c["max_lost_frames"], jump_ratio=c["jump_ratio_q8"] / JUMP_RATIO_SCALE,
                         timeout_s=c["timeout_s"])


class BoardB:
    """The flashed B grid of a calibration and the firmware's b_online state (cffi)."""

    def __init__(self, B, q_min: float, q_max: float, b_config=None):
        ffi, lib = core()
        self.ffi, self.lib = ffi, lib
        x0, step, n = grid_for(q_min, q_max, lib.PST_MAX_ENTRIES)
        self.xs = from_q16(x0 + step * np.arange(n, dtype=np.int64))
        prior = np.maximum(to_q16(np.maximum(B(self.xs), 0.0)), 0).astype(np.int64)  # as tables.build_table
        self._prior = ffi.new("int32_t[]", prior.tolist())
        self.lut = ffi.new("lut_t *")
        if lib.lut_init(self.lut, self._prior, n, x0, step) != lib.LUT_OK:
            raise ValueError("B grid refused by lut_init")
        self.bo = ffi.new("b_online_t *")
        cfg = lib.b_online_default_config() if b_config is None else b_config
        st = lib.b_online_init(self.bo, ffi.new("b_online_config_t *", cfg), self.lut)
        if st != lib.B_ONLINE_OK:
            raise ValueError(f"b_online_init refused the B grid (status {st})")

    def commit_learnt(self) -> None:
        """A table carrying the learnt B is committed (the host's refresh): b_online_rebind
        onto a copy of the current entries, as the board does on the new blob."""
        lib, ffi = self.lib, self.ffi
        blob_b = ffi.new("int32_t[]", ffi.unpack(lib.b_online_entries(self.bo), int(self.bo.n_grid)))
        lut = ffi.new("lut_t *")
        lib.lut_init(lut, blob_b, self.bo.n_grid, self.lut.x0_q16, 1 << self.lut.step_log2)
        if lib.b_online_rebind(self.bo, lut) != lib.B_ONLINE_OK:
            raise ValueError("b_online_rebind refused the committed B grid")
        self._keep = (blob_b, lut)  # the new prior and the lut the learner publishes into must live on

    def grid(self) -> np.ndarray:
        """The B entries the board runs now (actuator units)."""
        return from_q16(self.ffi.unpack(self.lib.b_online_entries(self.bo), int(self.bo.n_grid)))

    def crc32(self) -> int:
        """CRC-32 of the entries (int32 LE), as the board reports it (psp_learn_state_t.b_crc32)."""
        return int(self.lib.ps_crc32_update(0, self.lib.b_online_entries(self.bo), 4 * int(self.bo.n_grid)))

    def fn(self):
        return model.piecewise_linear(self.xs, self.grid())


class BoardF:
    """The board's on-line offset and gain of f (firmware/core/f_online.c, through cffi: the
    board's integer arithmetic bit for bit) on an f table: f entries (deg, Q16 raw) on the grid
    x0_q16 + i step_q16, and its f^-1 derived as calib_load derives it (lut_build_inverse into
    CALIB_DERIVED_MAX entries). `from_range` builds the identity table over an angle range for a
    replay that has no table (x = f(y) is then a plain angle). f_config: f_online_config_t
    fields as a dict (None: f_online_default_config()). Errors: ValueError when the C refuses
    the table or the settings."""

    def __init__(self, f_q16, x0_q16: int, step_q16: int, f_config: dict | None = None):
        ffi, lib = core()
        self.ffi, self.lib = ffi, lib
        self._f = ffi.new("int32_t[]", [int(v) for v in f_q16])
        self.f_lut = ffi.new("lut_t *")
        if lib.lut_init(self.f_lut, self._f, len(f_q16), int(x0_q16), int(step_q16)) != lib.LUT_OK:
            raise ValueError("f grid refused by lut_init")
        self._inv = ffi.new("int32_t[]", int(lib.CALIB_DERIVED_MAX))
        self.inv_lut = ffi.new("lut_t *")
        if lib.lut_build_inverse(self.f_lut, self._inv, lib.CALIB_DERIVED_MAX, self.inv_lut, ffi.NULL) != lib.LUT_OK:
            raise ValueError("f is not strictly monotone: no f^-1")
        cfg = lib.f_online_default_config()
        for k, v in (f_config or {}).items():
            setattr(cfg, k, int(v))
        self.fo = ffi.new("f_online_t *")
        st = lib.f_online_init(self.fo, ffi.new("f_online_config_t *", cfg), self.f_lut, self.inv_lut)
        if st != lib.F_ONLINE_OK:
            raise ValueError(f"f_online_init refused the table or the settings (status {st})")

    @classmethod
    def from_range(cls, lo_deg: float, hi_deg: float, f_config: dict | None = None) -> "BoardF":
        """Identity f (deg -> deg) on the smallest power-of-two grid of <= PST_MAX_ENTRIES covering
        [lo_deg, hi_deg] (widened by a quarter of the span each way)."""
        _, lib = core()
        pad = 0.25 * (hi_deg - lo_deg)
        x0, step, n = grid_for(lo_deg - pad, hi_deg + pad, lib.PST_MAX_ENTRIES)
        xs = x0 + step * np.arange(n, dtype=np.int64)
        return cls(xs.tolist(), x0, step, f_config)

    def step(self, x_deg: float, c_deg: float) -> bool:
        """One reading (f_online_step): x the uncorrected model angle, c the angle read. True
        when it published a new (a, g)."""
        return bool(self.lib.f_online_step(self.fo, int(to_q16(x_deg)), int(to_q16(c_deg))))

    def map(self) -> tuple[float, float]:
        """The published (a deg, g): the board's model is a + g f."""
        return float(from_q16(self.fo.a_q16)), float(from_q16(self.fo.g_q16))

    def inverse_entries(self) -> np.ndarray:
        """The f^-1 entries the loop runs now (raw Q16)."""
        return np.array(self.ffi.unpack(self.lib.f_online_entries(self.fo), int(self.inv_lut.n)), dtype=np.int64)


def f_config_from(s_ref, cal, refresh_s: float) -> dict:
    """The board learner's settings by their rules (docs/online.md), from the calibration record
    only: prior_var = the variance of its angle (the host gain refresh's prior, one reading's
    worth; a record without an angle sensor: the variance of f over the travel); publish_every = the host refresh period in readings at the onset frame rate;
    mem_log2 = the memory of the B learner, 8 reversals, in readings at that rate (the
    calibration record's mean reversal period), rounded up to a power of two, at most the
    longest the fixed-point sums hold (F_ONLINE_MEM_LOG2_MAX)."""
    _, lib = core()
    fps = 1.0 / cal.onset_config["frame_period_s"]
    t = s_ref.encoder["t_s"]
    per_rev = float(t[-1] - t[0]) / max(int(cal.doc["reversals"]), 1)
    mem = int(np.clip(np.ceil(np.log2(max(8.0 * per_rev * fps, 2.0))), 1, lib.F_ONLINE_MEM_LOG2_MAX))
    distal = getattr(s_ref, "distal", None) or {}
    c = distal.get("c_deg") if hasattr(distal, "get") else None
    if c is None or not np.any(np.isfinite(c)):  # an image session: the spread of f over the travel
        c = cal.f(np.linspace(*cal.q_range, 257))
    var = float(np.nanvar(c))
    return {"mem_log2": mem, "publish_every": max(1, int(round(refresh_s * fps))),
            "prior_var_q16": max(int(to_q16(var)), 1)}


def board_f_refreshed(s, c_hat: np.ndarray, fps: float, f_config: dict, f_range: tuple[float, float]) -> tuple[np.ndarray, dict]:
    """c_hat (the model's angle at every encoder sample, deg) corrected by the board's learner
    (BoardF.from_range over f_range) fed the session's angle frames in time order: each valid
    frame (frames_from_angle at fps, complete at t_f + 1/(2 fps)) is one reading against
    c_hat at the frame; each published (a, g) applies from that frame's completion on.
    Causal. Returns (a + g c_hat (N,), {"publishes", "a_deg", "g"} at the end)."""
    from ..fit.reversals import frames_from_angle

    t = s.encoder["t_s"]
    t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], fps)
    x_f = np.interp(t_f, t, c_hat)
    bf = BoardF.from_range(*f_range, f_config=f_config)
    a = np.zeros_like(c_hat)
    g = np.ones_like(c_hat)
    t_done = t_f + 0.5 / fps
    for tf, x, c in zip(t_done, x_f, c_f):
        if np.isfinite(c) and bf.step(float(x), float(c)):
            ai, gi = bf.map()
            k = int(np.searchsorted(t, tf, side="left"))
            a[k:], g[k:] = ai, gi
    ai, gi = bf.map()
    return a + g * c_hat, {"publishes": int(bf.fo.publishes), "a_deg": ai, "g": gi}


def compensate_learning(blob: bytes, t: np.ndarray, c_ref: np.ndarray, plant, fps: float,
                        f_config: dict | None = None) -> tuple[np.ndarray, dict]:
    """Compensation of the reference c_ref (N,) deg at times t (N,) s with the board's table
    (blob) while the board learns the offset and gain of f from the plant's angle, closed
    loop, as psa_loop runs it: comp_step per sample (no smoothing, as CalibTable.compensate);
    one angle reading per frame (every 1/fps s, the plant's angle at that sample) learnt
    against psa_f_regressor's x = f(f^-1(c*)); each publish rewrites the table's f^-1 and
    empties the compensator's cached f^-1 cell (psa_f_changed) before the next sample.
    plant: (t (k,), q (k,)) -> c (k,) deg, causal (run on the prefix up to each publish).
    Returns (q* (N,) actuator units, {"publishes", "a_deg", "g"})."""
    from ..fit.table_build import CalibTable

    tab = CalibTable(blob)
    ffi, lib = tab.ffi, tab.lib
    cfg = lib.f_online_default_config()
    for k, v in (f_config or {}).items():
        setattr(cfg, k, int(v))
    fo = ffi.new("f_online_t *")
    f_lut, inv_lut = ffi.addressof(tab.cal.f), ffi.addressof(tab.cal.f_inv)
    if lib.f_online_init(fo, ffi.new("f_online_config_t *", cfg), f_lut, inv_lut) != lib.F_ONLINE_OK:
        raise ValueError("f_online_init refused the table or the settings")
    c_raw = to_q16(c_ref).tolist()
    frame = np.zeros(len(c_raw), bool)
    k_f = np.unique(np.searchsorted(t, np.arange(t[0], t[-1], 1.0 / fps), side="left"))
    frame[k_f[k_f < frame.size]] = True
    cp = ffi.new("comp_t *")
    lib.comp_reset(cp, tab.cal, ffi.NULL, c_raw[0])
    q = np.empty(len(c_raw), np.int64)
    pending: list[tuple[int, int]] = []  # (sample index, x raw) of readings not yet learnt
    for k, c in enumerate(c_raw):
        q[k] = lib.comp_step(cp, c)
        if frame[k]:
            pending.append((k, lib.lut_eval(f_lut, lib.lut_eval(inv_lut, c))))
        if len(pending) == cfg.publish_every or k == len(c_raw) - 1:
            # The readings of this stretch: the plant on the commands so far (it is causal).
            c_meas = np.asarray(plant(t[:k + 1], from_q16(q[:k + 1])), float)
            published = False
            for i, x in pending:
                published |= bool(lib.f_online_step(fo, x, int(to_q16(c_meas[i]))))
            if published:
                cp.f_inv_cell.width = 0
            pending = []
    return from_q16(q), {"publishes": int(fo.publishes), "a_deg": float(from_q16(fo.a_q16)),
                         "g": float(from_q16(fo.g_q16))}


def learn_session(s, board: BoardB | None, cfg: OnsetConfig, hysteresis: float, refresh_s: float | None = None):
    """Feed session s through the firmware's onset detector in time order (ticks, reversals,
    angle frames at cfg.fps) and, when board is given, each B sample into b_online_sample at
    the frame that completed it. refresh_s: every refresh_s from the first sample the host
    commits a table carrying the learnt B (its refreshed offset beside it), which the board
    takes with b_online_rebind. Returns (t_done (M,), grids [(n,)] after each sample, the
    samples (M, 2) of q_mean, b, (frame times, frame angles))."""
    ffi, lib = core()
    t_enc, q = s.encoder["t_s"], s.encoder["q"]
    rt, rq, _ = detect_reversals(t_enc, s.encoder.get("q_cmd", q), hysteresis)
    t_f, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], cfg.fps)
    t0 = min(t_enc[0], t_f[0]) - 1e-3
    us = lambda x: np.round((np.asarray(x, float) - t0) * 1e6).astype(np.int64)
    te, tr, tf = us(t_enc), us(rt), us(t_f)
    tc = us(np.arange(t_enc[0] + refresh_s, t_enc[-1], refresh_s)) if refresh_s and board is not None else np.zeros(0, np.int64)
    times = np.concatenate([te, tr, tf, tc])
    kinds = np.concatenate([np.zeros(te.size, np.int8), np.ones(tr.size, np.int8), np.full(tf.size, 2, np.int8),
                            np.full(tc.size, 3, np.int8)])
    idx = np.concatenate([np.arange(te.size), np.arange(tr.size), np.arange(tf.size), np.arange(tc.size)])
    order = np.lexsort((kinds, times))
    ok = np.isfinite(c_f)
    q_raw = to_q16(q).tolist()  # as onsets.run_onsets
    rq_raw = to_q16(rq).tolist()
    c_raw = to_q16(np.where(ok, c_f, 0.0)).tolist()
    o = ffi.new("onset_t *")
    lib.onset_init(o, ffi.new("onset_config_t *", cfg.to_c(ffi, lib)))
    ev = ffi.new("onset_event_t *")
    done, grids, samples = [], [], []
    for tt, k, i in zip(times[order].tolist(), kinds[order].tolist(), idx[order].tolist()):
        if k == 0:
            lib.onset_tick(o, tt, q_raw[i], ev)  # a sample finished on a tick is not learnt (psa_loop.h)
            continue
        if k == 1:
            lib.onset_reversal(o, tt, rq_raw[i], ev)
            continue
        if k == 3:
            board.commit_learnt()
            continue
        if lib.onset_observe_deg(o, tt, c_raw[i], bool(ok[i]), ev) and ev.reason in (lib.ONSET_OK, lib.ONSET_OK_COARSE):
            samples.append((float(from_q16(ev.q_mean_q16)), float(from_q16(ev.b_q16))))
            done.append(tt / 1e6 + t0)
            if board is not None:
                lib.b_online_sample(board.bo, ev.q_mean_q16, ev.b_q16)  # = psa_observe_deg's hook
                grids.append(board.grid())
    return np.array(done), grids, np.array(samples).reshape(-1, 2), (t_f, c_f)


def _play_timeline(q: np.ndarray, t: np.ndarray, xs: np.ndarray, grids: list, t_change: np.ndarray) -> np.ndarray:
    """Centre z of the play over the whole session, B piecewise constant in time: grids[0]
    until t_change[0], grids[j] from t_change[j-1], state carried across the changes."""
    z = np.empty_like(q)
    cuts = np.searchsorted(t, t_change, side="left")
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts, [q.size]])
    prev = float(q[0])
    for g, a, b in zip(grids, starts, ends):
        if b <= a:
            continue
        z[a:b] = model.play_operator(q[a:b], model.piecewise_linear(xs, g), z0=prev)
        prev = float(z[b - 1])
    return z


def _offset_timeline(t: np.ndarray, t_f: np.ndarray, r_f: np.ndarray, refresh_s: float,
                     frame_s: float = 0.0) -> np.ndarray:
    """c_offset at each time t: at every refresh t_r = t[0] + k refresh_s, the mean residual
    over the frames complete before t_r (a frame at t_f averages the samples up to t_f +
    frame_s / 2; 0 before the first), held until the next refresh."""
    ok = np.isfinite(r_f)
    tf, rf = t_f[ok] + 0.5 * frame_s, r_f[ok]
    csum = np.concatenate([[0.0], np.cumsum(rf)])
    t_r = t[0] + refresh_s * np.floor((t - t[0]) / refresh_s)  # last refresh at or before t
    n = np.searchsorted(tf, t_r, side="left")                   # frames strictly before it
    return np.where(n > 0, csum[n] / np.maximum(n, 1), 0.0)


def const_play_insitu(s, t_split: float) -> np.ndarray:
    """The peer: constant play + poly5 fitted on t < t_split of s, run from q[0]; its
    prediction at every encoder sample (deg)."""
    t, q = s.encoder["t_s"], s.encoder["q"]
    td, cd = s.distal["t_s"], s.distal["c_deg"]
    cal_e, cal_d = t < t_split, td < t_split
    span = float(np.ptp(q[cal_e]))
    rt, _, _ = detect_reversals(t[cal_e], q[cal_e], 0.01 * span)
    t_f, c_f = frames_from_angle(td[cal_d], cd[cal_d], auto_fps(rt))
    q_c, c_c = characteristic(t[cal_e], q[cal_e], t_f, c_f, 0.0)
    _, fp, Bc = fit_constant_play(q_c, c_c)
    return model.direct_model(q, Bc, fp)


def reference_frames(s_ref, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """The (q, c) frames of the whole reference session the reference peers are fitted on: the
    angle block-averaged at fps (the chain's frame rate), q at each frame's time."""
    t_f, c_f = frames_from_angle(s_ref.distal["t_s"], s_ref.distal["c_deg"], fps)
    return characteristic(s_ref.encoder["t_s"], s_ref.encoder["q"], t_f, c_f, 0.0)


def const_play_ref(s_ref, fps: float):
    """Constant play + poly5 fitted on the whole reference session (reference_frames): (B, f)
    for model.direct_model."""
    _, fp, Bc = fit_constant_play(*reference_frames(s_ref, fps))
    return Bc, fp


def evaluate_online(cal, s, settings: OnlineSettings | None = None, b_config=None, ref_const=None) -> dict:
    """Every row of ROWS on session s with the reference calibration cal (pure play);
    ref_const: (B, f) of the constant play fitted on the reference (None: that row is NaN).
    Returns {"rmse_deg": {row: float}, "b_samples": M, "t_split_s", "b_change_max_mm"}."""
    st = settings or OnlineSettings()
    t, q = s.encoder["t_s"], s.encoder["q"]
    t_split = float(t[0] + st.score_after * (t[-1] - t[0]))
    mask = t >= t_split
    lo, hi = cal.q_range
    board = BoardB(cal.B, lo, hi, b_config)
    g0 = board.grid()
    cfg = onset_config_from(cal)
    t_done, grids, samples, (t_f, _) = learn_session(s, board, cfg, cal.reversal_hysteresis, st.refresh_s)
    c_true = np.interp(t, s.distal["t_s"], s.distal["c_deg"])
    # Residual frames for the offset: the angle at the frame rate the board's detector runs.
    _, c_f = frames_from_angle(s.distal["t_s"], s.distal["c_deg"], cfg.fps)
    c_s = cal.f(_play_timeline(q, t, board.xs, [g0], np.array([])))
    c_b = cal.f(_play_timeline(q, t, board.xs, [g0] + grids, t_done))
    rows = {"static": rmse((c_s - c_true)[mask]), "online_b_only": rmse((c_b - c_true)[mask])}
    c_cp = const_play_insitu(s, t_split)
    c_ref = model.direct_model(q, *ref_const) if ref_const is not None else np.full_like(q, np.nan)
    rows["const_play_insitu"] = rmse((c_cp - c_true)[mask])
    for key, c_hat in (("online", c_b), ("online_offset_only", c_s), ("const_play_insitu_offset", c_cp),
                       ("const_play_ref_offset", c_ref)):
        r_f = c_f - np.interp(t_f, t, c_hat)
        rows[key] = rmse((c_hat + _offset_timeline(t, t_f, r_f, st.refresh_s, 1.0 / cfg.fps) - c_true)[mask])
    bias = float(np.mean(samples[:, 1] - cal.B(samples[:, 0]))) if samples.size else float("nan")
    return {"rmse_deg": {k: rows[k] for k in ROWS}, "b_samples": int(samples.shape[0]), "t_split_s": t_split,
            "b_sample_minus_cal_mm": bias,
            "b_change_max_mm": float(np.max(np.abs(board.grid() - g0))) if grids else 0.0}


def evaluate_real_online(folder, ref: str = "data_2_1", settings: OnlineSettings | None = None,
                         progress=lambda it, **kw: it, b_config=None) -> dict:
    """The protocol on the catheter recordings (data_2_*.txt in folder, read in place): the pure
    play calibrated on ref, every other file run with on-line update from its start and scored
    after its first 20 %. Returns {"files": {name: evaluate_online() result}, "reference": ref,
    "settings": {...}, "b_config": {...}}. Errors: InputError when ref or the others are missing."""
    from pathlib import Path

    from ..fit.calibration import calibrate
    from ..base.errors import InputError
    from ..io.importer import import_catheter

    st = settings or OnlineSettings()
    files = sorted(Path(folder).glob("data_2_*.txt"))
    ref_path = Path(folder) / f"{ref}.txt"
    if not ref_path.is_file() or len(files) < 2:
        raise InputError(folder, f"needs {ref}.txt and at least one other data_2_*.txt here")
    s_ref = import_catheter(ref_path)
    cal = calibrate(s_ref, f_method="lsq", model_kind="play", source=str(ref_path))
    ref_const = const_play_ref(s_ref, cal.fps_frames)
    _, lib = core()
    bc = lib.b_online_default_config() if b_config is None else b_config
    p_one = float(1 << lib.B_ONLINE_P_FRAC_BITS)
    out = {"reference": ref, "settings": {"refresh_s": st.refresh_s, "score_after": st.score_after},
           "b_config": {"lambda": bc.lambda_q30 / p_one, "p0": bc.p0_q30 / p_one, "slope_max": float(from_q16(bc.slope_max_q16))},
           "files": {}}
    for f in progress([f for f in files if f.stem != ref], desc="on-line"):
        out["files"][f.stem] = evaluate_online(cal, import_catheter(f), st, b_config=bc, ref_const=ref_const)
    return out


def format_online(res: dict) -> str:
    """Markdown table of evaluate_real_online(): one row per model, one column per file, then
    the mean and the worst file (RMSE, deg), and whether ours <= the in-situ constant play on
    every file."""
    files = list(res["files"])
    s = res["settings"]
    lines = [f"**On-line update: calibrated on {res['reference']}, each other file run from its start, "
             f"scored after its first {s['score_after']:.0%} (bending-angle RMSE, deg)**", "",
             "| model | " + " | ".join(files) + " | mean | worst |", "|---" * (len(files) + 3) + "|"]
    for m in ROWS:
        v = [res["files"][f]["rmse_deg"][m] for f in files]
        lines.append(f"| {LABELS[m]} | " + " | ".join(f"{x:.2f}" for x in v) + f" | {np.mean(v):.2f} | {np.max(v):.2f} |")
    lines.append("| B samples learnt (file) | " + " | ".join(str(res["files"][f]["b_samples"]) for f in files) + " | | |")
    lines.append("| mean B sample - calibration B (mm) | " +
                 " | ".join(f"{res['files'][f]['b_sample_minus_cal_mm']:+.3f}" for f in files) + " | | |")
    won = [res["files"][f]["rmse_deg"]["online"] <= res["files"][f]["rmse_deg"]["const_play_insitu"] for f in files]
    b = res["b_config"]
    lines += ["", f"Target (ours with on-line update <= constant play refitted in situ, every file): "
              f"{'met' if all(won) else 'NOT met'} ({sum(won)} of {len(won)} files). Settings: lambda = {b['lambda']:.4f}, "
              f"p0 = {b['p0']:g}, |B'| <= {b['slope_max']:g}, offset refresh every {s['refresh_s']:g} s.", ""]
    return "\n".join(lines)
