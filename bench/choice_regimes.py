#!/usr/bin/env python3
"""Can any criterion on the calibration part see which family wins on the judged part?

On the development recordings (catheter data_2_1..5 and data_1_1..2, endoscope 30, 60, 120,
conf0_60), at each split, the protocol of playscope.evaluate.insitu_split (calibrate on t < t_split
only, run from the record's first sample, judge t >= t_split against the angle sensor): every
family the choice scores (families.FAMILIES without the relaxed ones, and on thin records
families.THIN_FAMILIES, offered or not) is fitted on the calibration part, written to its table
and judged; beside that, on the calibration part only, the choice's own folds (rolling origins, or
swing folds on thin records) per family, and three criteria read from them: the CV RMSE over the
folds (the product's, before the one-SE rule), the last fold alone (the regime closest to what
follows), and the in-sample error on every calibration frame. Per file-split: the strokes of q (the
travel between reversals) of each part, the family chosen, each family's judged error and CV, each
criterion's pick among the families the choice offers, and the oracle (the family with the lowest judged error: no rule can pick it, it
is what any rule over these families could reach) against the best row of evaluate-insitu's table.

First pass and re-pass (repass_folds): a fold's test frames are a re-pass when, in its training part,
frames after q's first reversal moving the same way already covered their q (a branch the fit has
seen, what the model chosen on the whole calibration part does on a record that goes on over the
same travel); otherwise a first pass (the fit extrapolates a branch it has only seen on the start's
virgin curve, or not at all). Two more criteria read the re-pass folds only: the lowest re-pass CV,
and the product's rule (families.choose: the one-SE rule, from const_play on thin records) on the
re-pass CVs; "-" when the calibration part has no re-pass fold.

Paired folds (rolling-origin file-splits only, where the product's rule uses the SE of the per-fold
differences from the best, families.one_se_margin): per file-split, for each family against the one
with the lowest CV, the SE of their per-fold differences over the best's own SE, and whether the
families' fold errors rise and fall together (every family's per-fold errors correlated with the
best's, Pearson's r over the folds). A ratio below 1 means fold difficulty shared by the families is
most of the best's own spread.

Development files only (the endoscope's set-aside files are never read here).

Usage: PYTHONPATH=host .venv/bin/python bench/choice_regimes.py [--splits 0.5,0.75] [--instruments catheter,endoscope]
       [--json PATH]       (~2 min)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from playscope.evaluate import insitu_split as IS
from playscope.fit import families as FAM
from playscope.fit import transition as T
from playscope.fit.reversals import detect_reversals
from playscope.io.importer import import_catheter, import_endoscope

ROOT = Path(__file__).resolve().parent.parent
REAL = Path(os.environ.get("PLAYSCOPE_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))
INSTRUMENTS = {"catheter": (import_catheter, [f"data_2_{i}" for i in range(1, 6)] + ["data_1_1", "data_1_2"]),
               "endoscope": (import_endoscope, ["30", "60", "120", "conf0_60"])}
BASE = ("onset_play", "const_play", "onset_transition", "pi_const")
REPASS_SHARE = 0.9  # a fold is a re-pass when this share of its test frames is (repass_folds)


def strokes(t, q, t_split):
    """(shortest stroke ending before t_split, longest stroke starting after it): travel of q
    between reversals (hysteresis 1 % of its span, the first and last samples as turning points)."""
    rt, qr, _ = detect_reversals(t, q, 0.01 * float(np.ptp(q)))
    tt, qq = np.r_[t[0], rt, t[-1]], np.r_[q[0], qr, q[-1]]
    amp = np.abs(np.diff(qq))
    cal, test = amp[tt[1:] <= t_split], amp[tt[:-1] >= t_split]
    return (float(cal.min()) if cal.size else float("nan")), (float(test.max()) if test.size else float("nan"))


def run(reader, path: Path, split: float) -> dict:
    s = reader(path)
    t, q = s.encoder["t_s"], s.encoder["q"]
    ts = IS.split_time(t, split)
    grab = {}
    orig = FAM.choose

    def spy(ctx, reversals, *a, **k):
        grab["ctx"], grab["reversals"] = ctx, int(reversals)
        grab["out"] = orig(ctx, reversals, *a, **k)
        return grab["out"]

    FAM.choose = spy
    try:
        rows = IS.fit_rows(s, ts, source=str(path))
    finally:
        FAM.choose = orig
    td = float(s.t_delay_s) if s.t_delay_s is not None else float(rows["onset_lsq"].params["t_delay_s"])
    rm, _, _, _, _ = IS.score_rows(rows, s, ts, td)
    ctx, rev = grab["ctx"], grab["reversals"]
    thin = rev < FAM.MIN_REVERSALS_CHOICE
    folds = FAM.swing_splits(ctx) if thin else T.rolling_origins(ctx.data, T.KFOLD)
    folds = [(a, b) for a, b in folds if b.sum() >= FAM.MIN_TEST_FRAMES and a.sum() >= FAM.MIN_TRAIN_FRAMES]
    rep = repass_folds(ctx, folds)
    tm, cm, _ = IS.judged_samples(s, ts, td)
    fams = [f for f in FAM.FAMILIES if f.name in BASE] + (FAM.THIN_FAMILIES if thin else [])
    out = {}
    for fam in fams:
        try:
            errs = []
            for tr_m, te_m in folds:
                c_hat = FAM.predict_frames(ctx, FAM.table_of(ctx, fam.fit(ctx, tr_m)))
                errs.append(float(np.sqrt(np.mean((c_hat[te_m] - ctx.data.c[te_m]) ** 2))))
            tab = FAM.table_of(ctx, fam.fit(ctx, None))
            judged = float(np.sqrt(np.mean((np.interp(tm, t, tab.predict(q)) - cm) ** 2)))
            ins = float(np.sqrt(np.mean((FAM.predict_frames(ctx, tab) - ctx.data.c) ** 2)))
        except Exception as e:  # a refused table or a failed fit: that family is out of this file-split
            out[fam.name] = {"error": str(getattr(e, "message", e))}
            continue
        er = np.asarray(errs)[rep] if errs else np.zeros(0)
        out[fam.name] = {"folds": errs, "folds_repass": er.tolist(),
                         "cv": float(np.sqrt(np.mean(np.square(errs)))) if errs else float("nan"),
                         "last": errs[-1] if errs else float("nan"), "in_sample": ins, "judged": judged,
                         "cv_repass": float(np.sqrt(np.mean(er ** 2))) if er.size else float("nan"),
                         "se_repass": float(np.std(er, ddof=1) / np.sqrt(er.size)) if er.size > 1 else 0.0}
    # The criteria and the oracle range over the families the choice offers (a thin family not in
    # THIN_OFFERED is shown, not picked).
    ok = {k: v for k, v in out.items() if "error" not in v and (k in BASE or k in FAM.THIN_OFFERED)}
    pick = lambda key: min(ok, key=lambda k: ok[k][key])  # noqa: E731
    has_rep = bool(rep.any())
    best_row = min(v for v in rm.values() if v is not None)
    cal_min, test_max = strokes(t, q, ts)
    return {"reversals": rev, "thin": thin, "chosen": rows["ours"].params.get("family"), "ours": rm["ours"],
            "best_row": best_row, "best_row_name": min((k for k in rm if rm[k] is not None), key=lambda k: rm[k]),
            "strokes_cal_min": cal_min, "strokes_test_max": test_max, "families": out,
            "repass_folds": rep.tolist(), "paired": None if thin else paired_folds(out),
            "pick": {"cv": pick("cv"), "last_fold": pick("last"), "in_sample": pick("in_sample"), "oracle": pick("judged"),
                     "repass_lowest": pick("cv_repass") if has_rep else None,
                     "repass_rule": product_rule(ok, thin, "cv_repass", "se_repass") if has_rep else None}}


def repass_folds(ctx, folds) -> np.ndarray:
    """(n_folds,) bool: True where at least REPASS_SHARE of the fold's test frames are a re-pass: their q
    lies in the travel of a swing after q's first reversal that moves the same way and that the
    training part holds (from the reversal that starts it to its last training frame, or to the
    reversal that ends it when the training part holds the whole swing: frames miss the peaks), within
    the swings' hysteresis (families.SWING_HYSTERESIS of q's span)."""
    d = ctx.data
    tol = FAM.SWING_HYSTERESIS * float(np.ptp(d.q_enc)) + 1e-12  # the swings' own resolution in q
    rt, _, _ = detect_reversals(d.t_enc, d.q_enc, tol)
    edges = np.r_[d.t_enc[0], rt, d.t_enc[-1]]
    qe = np.interp(edges, d.t_enc, d.q_enc)
    qf = ctx.q_frames()
    sw = np.clip(np.searchsorted(edges, d.t_frame, side="right") - 1, 0, edges.size - 2)
    way = np.sign(qe[sw + 1] - qe[sw])
    out = []
    for tr, te in folds:
        seen = np.zeros(te.sum(), bool)
        for j in np.unique(sw[tr & (sw >= 1)]):
            m = tr & (sw == j)
            end = qe[j + 1] if np.all(tr[sw == j]) else qf[m][np.argmax(d.t_frame[m])]
            lo, hi = min(qe[j], end), max(qe[j], end)
            seen |= (way[te] == way[m][0]) & (qf[te] >= lo - tol) & (qf[te] <= hi + tol)
        out.append(bool(te.sum()) and seen.mean() >= REPASS_SHARE)
    return np.array(out, bool)


def product_rule(ok: dict, thin: bool, key: str, se_key: str) -> str:
    """families.choose's rule on the CVs ok[name][key] (SE ok[name][se_key]): the first family in the
    registry's order (const_play first on thin records) within one SE of the best (families.one_se_margin:
    on rolling origins the SE of the per-fold differences from the best, on thin records the best's own);
    on thin records, once const_play is out, the lowest CV."""
    order = [f.name for f in FAM.FAMILIES if f.name in ok] + [n for n in ok if n not in {f.name for f in FAM.FAMILIES}]
    if thin:
        order = sorted(order, key=lambda n: n != FAM.FALLBACK)
    order = [n for n in order if np.isfinite(ok[n][key])]
    best = min(order, key=lambda n: ok[n][key])
    fk = {"cv": "folds", "cv_repass": "folds_repass"}.get(key)  # the per-fold errors the rule pairs
    row = lambda n: {"cv_se_deg": ok[n][se_key], "fold_rmse_deg": ok[n].get(fk)}  # noqa: E731
    first = next(n for n in order if ok[n][key] <= ok[best][key] + FAM.one_se_margin(row(n), row(best), not thin))
    return best if thin and first != FAM.FALLBACK else first


def paired_folds(fams: dict) -> dict | None:
    """Per family against the one of lowest CV among fams ({name: {"folds", "cv"}}, families with
    per-fold errors on the same folds): {"best", "ratio": {name: paired SE / best's own SE},
    "r": {name: Pearson r of its per-fold errors with the best's}, "z_paired", "z_own": {name: its
    CV above the best's in paired SEs, in the best's own SEs}}; None with fewer than 3 folds or 2
    families."""
    ok = {k: v for k, v in fams.items() if "error" not in v and len(v["folds"]) >= 3}
    if len(ok) < 2 or len({len(v["folds"]) for v in ok.values()}) != 1:
        return None
    best = min(ok, key=lambda k: ok[k]["cv"])
    eb = np.asarray(ok[best]["folds"])
    se_b = float(np.std(eb, ddof=1) / np.sqrt(eb.size))
    out = {"best": best, "ratio": {}, "r": {}, "z_paired": {}, "z_own": {}}
    for k, v in ok.items():
        if k == best:
            continue
        e = np.asarray(v["folds"])
        se_p = float(np.std(e - eb, ddof=1) / np.sqrt(e.size))
        out["ratio"][k] = se_p / max(se_b, 1e-12)
        out["r"][k] = float(np.corrcoef(e, eb)[0, 1])
        out["z_paired"][k] = (v["cv"] - ok[best]["cv"]) / max(se_p, 1e-12)
        out["z_own"][k] = (v["cv"] - ok[best]["cv"]) / max(se_b, 1e-12)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--splits", default="0.5,0.75")
    ap.add_argument("--instruments", default="catheter,endoscope")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = {}
    for inst in a.instruments.split(","):
        reader, stems = INSTRUMENTS[inst]
        for fr in (float(v) for v in a.splits.split(",")):
            print(f"**{inst}, split {fr:g}: each family judged (its CV on the calibration part's folds); each criterion's "
                  "pick; the oracle over the families against the best row of evaluate-insitu's table**\n")
            names = None
            lines = []
            picks = {"cv": 0, "last_fold": 0, "in_sample": 0, "repass_lowest": 0, "repass_rule": 0}
            n = shorter = oracle_within = ours_within = 0
            within_by = {}
            n_all_rep = n_no_rep = 0
            pair_n = pair_lt = pair_files = pair_files_all = pair_pos = 0
            pair_ratios, z_before = [], []  # z: (paired, own) of the families the rule passed over
            for stem in stems:
                r = run(reader, REAL / inst / f"{stem}.txt", fr)
                res[f"{inst}/{stem}@{fr:g}"] = r
                fams = list(r["families"])
                if names is None or len(fams) > len(names):
                    names = fams
                cells = []
                for k in fams:
                    v = r["families"][k]
                    cells.append("refused" if "error" in v else f"{v['judged']:.3f} ({v['cv']:.3f}; {v['cv_repass']:.3f})")
                o = r["pick"]["oracle"]
                orc = r["families"][o]["judged"]
                lines.append((stem, fams, cells, r, o, orc))
                n += 1
                shorter += r["strokes_test_max"] < r["strokes_cal_min"]
                oracle_within += orc <= 1.1 * r["best_row"]
                ours_within += r["ours"] <= 1.1 * r["best_row"]
                for c in picks:
                    picks[c] += r["pick"][c] == o
                if r["paired"]:
                    ratios, rs = list(r["paired"]["ratio"].values()), list(r["paired"]["r"].values())
                    pair_files += 1
                    pair_n += len(ratios)
                    pair_lt += sum(x < 1 for x in ratios)
                    pair_pos += sum(x > 0 for x in rs)
                    pair_files_all += all(x < 1 for x in ratios)
                    pair_ratios += ratios
                    order = [f.name for f in FAM.FAMILIES]
                    z_before += [(r["paired"]["z_paired"][k], r["paired"]["z_own"][k]) for k in r["paired"]["z_paired"]
                                 if r["chosen"] in order and order.index(k) < order.index(r["chosen"])]
                n_all_rep += all(r["repass_folds"])
                n_no_rep += not any(r["repass_folds"])
                for c in ("repass_lowest", "repass_rule"):  # no re-pass fold: the product's choice stands
                    pj = r["families"][r["pick"][c]]["judged"] if r["pick"][c] else r["ours"]
                    within_by.setdefault(c, 0)
                    within_by[c] += pj <= 1.1 * r["best_row"]
            print("| file | reversals | strokes: shortest before / longest after the split | chosen | " +
                  " | ".join(f"{k} judged (CV; re-pass CV)" for k in names) +
                  " | CV picks | last fold picks | in-sample picks | re-pass folds | re-pass CV picks | product's rule on "
                  "the re-pass CV picks | oracle | oracle / best row | ours / best row |")
            print("|---" * (len(names) + 13) + "|")
            for stem, fams, cells, r, o, orc in lines:
                cd = dict(zip(fams, cells))
                print(f"| {stem} | {r['reversals']} | {r['strokes_cal_min']:.2f} / {r['strokes_test_max']:.2f} | {r['chosen']} | " +
                      " | ".join(cd.get(k, "-") for k in names) +
                      f" | {r['pick']['cv']} | {r['pick']['last_fold']} | {r['pick']['in_sample']} | "
                      f"{sum(r['repass_folds'])} of {len(r['repass_folds'])} | {r['pick']['repass_lowest'] or '-'} | "
                      f"{r['pick']['repass_rule'] or '-'} | {o} | "
                      f"{orc / r['best_row']:.2f} ({r['best_row_name']}) | {r['ours'] / r['best_row']:.2f} |")
            print(f"\n{inst}, split {fr:g}: judged strokes all shorter than every calibration stroke on {shorter} of {n}; "
                  f"the pick is the oracle's on {picks['cv']} (CV), {picks['last_fold']} (last fold), "
                  f"{picks['in_sample']} (in sample) of {n}; oracle within 1.1 x the best row on {oracle_within} of {n}, "
                  f"ours on {ours_within} of {n}", flush=True)
            print(f"{inst}, split {fr:g}, re-pass folds only: {n_all_rep} of {n} file-splits have every fold a re-pass, "
                  f"{n_no_rep} none; the pick is the oracle's on {picks['repass_lowest']} (re-pass CV), "
                  f"{picks['repass_rule']} (the product's rule on the re-pass CV) of {n}; within 1.1 x the best row "
                  f"(the product's choice where no fold is a re-pass): the re-pass CV's pick on "
                  f"{within_by.get('repass_lowest', 0)} of {n}, the product's rule on the re-pass CV on "
                  f"{within_by.get('repass_rule', 0)} of {n}\n", flush=True)
            if pair_files:
                passed = (f"; the families before the one kept (in the rule's order) lie above the best by at least "
                          f"{min(z[0] for z in z_before):.2f} paired SEs ({min(z[1] for z in z_before):.2f} of the "
                          "best's own SE)") if z_before else ""
                print(f"{inst}, split {fr:g}, paired folds (rolling origins, {pair_files} of {n} file-splits): the SE "
                      f"of the per-fold differences from the best family below the best's own SE for {pair_lt} of "
                      f"{pair_n} families (every family on {pair_files_all} of {pair_files} file-splits; ratio median "
                      f"{np.median(pair_ratios):.2f}, largest {max(pair_ratios):.2f}); fold errors correlated with the "
                      f"best's (r > 0) for {pair_pos} of {pair_n}{passed}\n", flush=True)
    print(f"({time.perf_counter() - t0:.0f} s)")
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
