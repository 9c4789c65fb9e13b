"""The catheter recordings (no licence: read in place at run time, never copied) through the
diagnosis: in situ and across files, with the effects it keeps.

Folder: catheter_dir(arg) -- the argument, else $PLAYSCOPE_CATHETER_DIR, else
$PLAYSCOPE_REAL_DATA/catheter, else the caller's default (the bench scripts pass
../shared/data/real/catheter next to the repository); the package itself assumes no path.

In situ, three-way (split.choose_split): fit on the first half of a file, select effects on the
next quarter (validation), report on the last quarter (test), which neither the fit nor the
selection saw; all three RMSEs per file.
Across files: fit on the whole of the first file (base model, and base + the effects kept in situ
on that file), judge on each other file; drift is left out across files (a per-session offset
trend has no meaning on another recording).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import os

from .attribute import attribute
from .fitmodel import Model, from_session
from .split import choose_split


def catheter_dir(arg=None, default=None) -> Path | None:
    """Folder of the catheter recordings (module doc); None when nothing is given or set."""
    for v in (arg, os.environ.get("PLAYSCOPE_CATHETER_DIR")):
        if v:
            return Path(v)
    if os.environ.get("PLAYSCOPE_REAL_DATA"):
        return Path(os.environ["PLAYSCOPE_REAL_DATA"]) / "catheter"
    return Path(default) if default else None


def _product(session, data, fit_mask, test_mask, kept: list) -> dict:
    from .product import product_rmse
    delay = next((k["params"].get("camera_delay.delay_s", (0.0, 0.0))[0] for k in kept
                  if k["effect"] == "camera_delay"), 0.0)
    return product_rmse(session, data, fit_mask, test_mask, [k["effect"] for k in kept], delay)


# Hook for the product's own model: a callable (session, data, fit_mask,
# test_mask, kept) -> {"play", "with_kept", "model", "not_in_product"} test-part RMSEs (deg) of
# `calibrate` (product.py); None leaves the column "not measured".
PRODUCT_RMSE = _product


def _session(path):
    from ..io.importer import import_catheter
    return import_catheter(path)


def catheter_table(files, log=print) -> dict:
    """{"in_situ": {name: {...}}, "across": {"fit_on", "effects", "rows": {name: {...}}}}."""
    files = [Path(f) for f in files]
    sessions = {f.stem: _session(f) for f in files}
    datas = {k: from_session(v) for k, v in sessions.items()}
    out = {"in_situ": {}, "across": {}}
    for name, d in datas.items():
        sp = choose_split(d)
        res = attribute(d, sp.fit, sp.val, test_mask=sp.test)
        fb, ff = res["_fits"]["base"], res["_fits"]["final"]
        row = {
            "split": sp.summary(), "noise_floor_deg": res["noise_floor_deg"],
            "base": {"fit": fb.rmse(d.y_m, sp.fit), "validation": res["base"]["rmse_heldout_deg"],
                     "test": res["test"]["rmse_base_deg"]},
            "kept_model": {"fit": ff.rmse(d.y_m, sp.fit), "validation": res["final"]["rmse_heldout_deg"],
                           "test": res["test"]["rmse_final_deg"]},
            "verdict": res["verdict"], "kept": [{k2: v for k2, v in k.items()} for k in res["kept"]],
            "at_bounds": ff.at_bounds(),
            "screen": {r["effect"]: r["rmse_heldout_deg"] for r in res["screen"]}}
        if PRODUCT_RMSE is not None:
            row["product_test"] = PRODUCT_RMSE(sessions[name], d, sp.fit, sp.test, res["kept"])
        out["in_situ"][name] = row
        log(f"{name}: fit/validation/test {row['base']['fit']:.3f}/{row['base']['validation']:.3f}/{row['base']['test']:.3f}"
            f" -> {row['kept_model']['fit']:.3f}/{row['kept_model']['validation']:.3f}/{row['kept_model']['test']:.3f} deg"
            f" kept {[k['effect'] for k in res['kept']]} ({sp.method})")
    ref = files[0].stem
    eff = [k["effect"] for k in out["in_situ"][ref]["kept"] if k["effect"] != "drift"]
    union = sorted({k["effect"] for r in out["in_situ"].values() for k in r["kept"]} - {"drift"})
    d0 = datas[ref]
    full = np.ones(d0.t_m.size, bool)
    fits = {}
    for label, effects in [("base", []), ("kept", eff)] + [(e, [e]) for e in union]:
        m = Model(d0, effects)
        fits[label] = (m, m.fit(full, uncertainty=False))
    rows = {}
    for name, d in datas.items():
        if name == ref:
            continue
        row = {}
        for label, (m0, f0) in fits.items():
            m = Model(d, m0.effects, frame=m0)
            r = d.y_m - m.predict(f0.theta, f0.coef)
            r = r[np.isfinite(r)]
            row[f"rmse_{label}_deg"] = float(np.sqrt(np.mean(r * r)))
            row[f"rmse_{label}_offset_removed_deg"] = float(np.std(r))
        rows[name] = row
    out["across"] = {"fit_on": ref, "effects": eff, "single_effects": union, "rows": rows}
    return out


def format_catheter(tab: dict) -> str:
    """Markdown tables of catheter_table()'s result."""
    lines = ["In situ, three-way (fit on the first half, select effects on the next quarter, test on the last "
             "quarter), bending-angle RMSE [deg] fit / validation / test:", "",
             "| file | split | noise floor | play + f_remain (base) | + kept effects | kept effects (parameters ± 1 sd; validation RMSE after each; parameters at a bound) | product (calibrate), test: play -> with kept, float; fixed point (board's playop_step) |",
             "|---|---|---|---|---|---|---|"]
    for name, r in tab["in_situ"].items():
        ks = []
        for k in r["kept"]:
            ps = ", ".join(f"{n.split('.', 1)[1]} = {v[0]:.3g} ± {v[1]:.2g}" for n, v in k["params"].items())
            ind = f"; cannot tell from {', '.join(k['indistinguishable_from'])}" if k["indistinguishable_from"] else ""
            ab = "".join(f"; {n.split('.', 1)[1]} AT {b.upper()} BOUND" for n, b in k.get("at_bounds", {}).items())
            ks.append(f"{k['effect']} ({ps}) → {k['rmse_after_deg']:.3f}{ind}{ab}")
        b, m = r["base"], r["kept_model"]
        pt = r.get("product_test")
        fx = "" if pt is None or "play_fixed" not in pt else (
            f"; fixed point {pt['play_fixed']:.3f} -> {pt['with_kept_fixed']:.3f}")
        prod = None if pt is None else (f"{pt['play']:.3f} -> {pt['with_kept']:.3f}{fx} ({pt['model']}"
                                        + (f"; not in the product: {', '.join(pt['not_in_product'])}" if pt["not_in_product"] else "")
                                        + ")")
        lines.append(f"| {name} | {r['split']['method']} | {r['noise_floor_deg']:.3f} | "
                     f"{b['fit']:.3f} / {b['validation']:.3f} / {b['test']:.3f} | {m['fit']:.3f} / {m['validation']:.3f} / {m['test']:.3f} | "
                     f"{'; '.join(ks) or '—'} | {'not measured (hook unset)' if prod is None else prod} |")
    a = tab["across"]
    if a.get("rows"):
        lines += ["", f"Across files (fit on all of {a['fit_on']}, judge on the others; kept effects: "
                      f"{', '.join(a['effects']) or 'none'}), RMSE [deg] (and with the per-session mean offset removed):", "",
                  "| file | base | base, offset removed | + kept effects | + kept, offset removed | "
                  + " | ".join(f"+ {e} only (offset removed)" for e in a.get("single_effects", [])) + " |",
                  "|---|---|---|---|---|" + "---|" * len(a.get("single_effects", []))]
        for name, r in a["rows"].items():
            lines.append(f"| {name} | {r['rmse_base_deg']:.3f} | {r['rmse_base_offset_removed_deg']:.3f} | "
                         f"{r['rmse_kept_deg']:.3f} | {r['rmse_kept_offset_removed_deg']:.3f} | "
                         + " | ".join(f"{r[f'rmse_{e}_deg']:.3f} ({r[f'rmse_{e}_offset_removed_deg']:.3f})"
                                      for e in a.get("single_effects", [])) + " |")
    return "\n".join(lines)
