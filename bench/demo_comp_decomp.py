#!/usr/bin/env python3
"""Where the main job's open-loop compensation error comes from (against its 0.3 deg target).

Reads a finished `playscope demo --out DIR` (its two simulated sessions and calibration.json)
and replaces one input of the transition's model choice at a time by what only the simulator
knows, re-running the product's own choice (transition.choose_model) each time; every row is
scored the same way as the main job's compensation line: the float compensator
(transition.compensate_chain) on evaluate.reference_trajectory, open loop through the
simulator's plant (sim.plant.session_plant), RMSE against c* after the first second.

Rows: the product as calibrated; the compensator's own residual |model(q*) - c*| (inverse
exactness); c from plain LM pose estimation (the registration error pulls c) / with the
image offset (the product) / with the true hand-eye; noise-free true c at the true delay;
the true B(q) x b_scale in place of the onset B; and an oracle grid (B penalty x b_scale x
threshold span, 16 operators, weights fitted on the plant's noise-free response at 50 Hz,
the best compensation kept: what the constant-threshold PI can reach on this plant).

Usage: .venv/bin/python bench/demo_comp_decomp.py [--out out/main] [--no-oracle]   (~1-3 min)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from playscope.fit import model as M
from playscope.fit import transition as T
from playscope.fit.calibration import Calibration, pose_with_offset
from playscope.fit.backlash import fit_backlash_samples
from playscope.evaluate.prediction import inverse_of, reference_trajectory, rmse
from playscope.io.session import load_session
from playscope.sim.core import SimConfig
from playscope.sim.plant import session_plant


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/main", help="a finished `playscope demo` folder")
    ap.add_argument("--no-oracle", action="store_true", help="skip the oracle grid (36 fits)")
    a = ap.parse_args()
    out = Path(a.out)
    cal = Calibration.load(out / "calibration.json")
    s, test = load_session(out / "session_excitation"), load_session(out / "session_test")
    plant, _ = session_plant(test)
    sim = SimConfig.from_json(s.meta["simulator"])
    B_true = sim.B_fn()
    t_enc, q_enc = s.encoder["t_s"], s.encoder["q"]
    t_ref, c_ref = reference_trajectory(cal, 60.0, float(1 / np.median(np.diff(test.encoder["t_s"]))))
    keep = t_ref >= 1.0
    lo, hi = cal.q_range

    def comp(B_model, tr, f, sign):
        qs = T.compensate_chain(c_ref, B_model, tr, inverse_of(f, lo, hi), sign)
        return rmse((plant(t_ref, qs) - c_ref)[keep]), qs

    def chosen(B, t_f, c_f, td):
        data = T.FitData.from_session(t_enc, q_enc, B, t_f, c_f, td)
        tr, f, sign, _ = T.choose_model(data, "auto", 14)
        return comp(tr.play_width(B), tr, f, sign)[0], tr

    rows = []
    e, qs = comp(cal.B_model, cal.transition, cal.f, cal.f_sign)
    rows.append(("product (calibration.json, float compensator)", e, ""))
    res = rmse((cal.predict(qs) - c_ref)[keep])
    rows.append(("  compensator residual |model(q*) - c*| (inverse exactness)", res, ""))

    t_f, obs = s.observations()
    td = cal.t_delay_s
    im = M.ImageModel(s.robot, s.camera, s.hand_eye)
    c0 = M.f_coarse(np.interp(t_f - td, t_enc, q_enc), s.robot.q_per_rad)
    c_plain = im.estimate_c(obs, c0)[0]
    c_off = pose_with_offset(im, obs, c0)[0]
    c_he = M.ImageModel(s.robot, s.camera, sim.hand_eye()).estimate_c(obs, c0)[0]
    c_true = np.interp(t_f - sim.t_delay_s, s.truth["t_s"], s.truth["c_deg"])
    for label, c, d in (("c by plain LM pose (registration error pulls c)", c_plain, td),
                        ("c with the session's image offset (the product's rule)", c_off, td),
                        ("c with the true hand-eye", c_he, td),
                        ("noise-free true c at the true delay", c_true, sim.t_delay_s)):
        ok = np.isfinite(c)
        e, tr = chosen(cal.B, t_f, c, d)
        rows.append((f"product's B, choice on {label}", e,
                     f"c vs truth {rmse((c - c_true)[ok]):.3f} deg; b_scale {tr.b_scale:g}, r <= {tr.r[-1]:.3f}"))
    for kb in (1.0, 0.75, 0.5):
        e, tr = chosen(lambda x, k=kb: k * B_true(x), t_f, c_true, sim.t_delay_s)
        rows.append((f"true B x {kb:g}, noise-free true c", e, f"chosen b_scale {tr.b_scale:g}"))

    if not a.no_oracle:
        bs = cal.b_samples
        rng = (float(bs["q_mean"].min()), float(bs["q_mean"].max()))
        sel = np.arange(0, s.truth["t_s"].size, max(1, int(round(sim.encoder_hz / 50))))
        best = (np.inf, "")
        for sm in (1e-3, 1e-2, 1e-1, 1.0):
            B = fit_backlash_samples(bs["q_mean"], bs["b"], 14, sm, rng, sigma=bs.get("sigma_b")).B
            data = T.FitData(np.asarray(t_enc, float), np.asarray(q_enc, float), B, s.truth["t_s"][sel],
                             s.truth["c_deg"][sel])
            for kb in (1.0, 0.85, 0.7):
                for span in (0.25, 0.5, 0.8):
                    r = T.thresholds(T.N_OPS, span)
                    w, f, sign, fit = T.fit_weights(data.ops_at_frames(r, kb), data.c, 14)
                    nz = (w > 0) | (np.arange(r.size) == 0)
                    tr = T.Transition(r[nz], w[nz] / w[nz].sum(), kb)
                    e = comp(tr.play_width(B), tr, f, sign)[0]
                    if e < best[0]:
                        best = (e, f"B penalty {sm:g}, b_scale {kb:g}, span {span:g}: noise-free fit RMSE {fit:.3f} deg")
        rows.append(("oracle constant-threshold PI (best of 36, fitted on the plant's noise-free response)",
                     best[0], best[1]))

    print(f"Compensation through the plant, RMSE after 1 s (deg); demo folder {out}\n")
    print("| row | RMSE (deg) | note |\n|---|---|---|")
    for label, e, note in rows:
        print(f"| {label} | {e:.3f} | {note} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
