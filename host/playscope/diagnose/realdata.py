"""The catheter recordings (../shared/data/real/catheter, no licence: read in place at run time,
never copied) through the diagnosis: in situ and across files, with the effects it keeps.

In situ: fit on the first half of a file, judge on its second half (attribute()).
Across files: fit on the whole of the first file (base model, and base + the effects kept in situ
on that file), judge on each other file; drift is left out across files (a per-session offset
trend has no meaning on another recording).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .attribute import attribute, halves
from .fitmodel import Model, from_session

CATHETER_DIR = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "real" / "catheter"


def _data(path):
    from ..importer import import_catheter
    return from_session(import_catheter(path))


def catheter_table(files, log=print) -> dict:
    """{"in_situ": {name: {...}}, "across": {"fit_on", "effects", "rows": {name: {...}}}}."""
    files = [Path(f) for f in files]
    datas = {f.stem: _data(f) for f in files}
    out = {"in_situ": {}, "across": {}}
    for name, d in datas.items():
        fm, em = halves(d)
        res = attribute(d, fm, em)
        out["in_situ"][name] = {
            "noise_floor_deg": res["noise_floor_deg"], "rmse_base_deg": res["base"]["rmse_heldout_deg"],
            "rmse_kept_deg": res["final"]["rmse_heldout_deg"], "verdict": res["verdict"],
            "kept": [{k2: v for k2, v in k.items()} for k in res["kept"]],
            "screen": {r["effect"]: r["rmse_heldout_deg"] for r in res["screen"]}}
        log(f"{name}: in situ {res['base']['rmse_heldout_deg']:.3f} -> {res['final']['rmse_heldout_deg']:.3f} deg "
            f"kept {[k['effect'] for k in res['kept']]}")
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
    lines = ["In situ (fit on the first half, judge on the second half), bending-angle RMSE [deg]:", "",
             "| file | noise floor | play + f_remain (base) | + kept effects | kept effects (parameters ± 1 sd; held-out RMSE after each; share of excess removed) |",
             "|---|---|---|---|---|"]
    for name, r in tab["in_situ"].items():
        ks = []
        for k in r["kept"]:
            ps = ", ".join(f"{n.split('.', 1)[1]} = {v[0]:.3g} ± {v[1]:.2g}" for n, v in k["params"].items())
            ind = f"; cannot tell from {', '.join(k['indistinguishable_from'])}" if k["indistinguishable_from"] else ""
            ks.append(f"{k['effect']} ({ps}) → {k['rmse_after_deg']:.3f}, {100 * k['share_of_excess_removed']:.0f} %{ind}")
        lines.append(f"| {name} | {r['noise_floor_deg']:.3f} | {r['rmse_base_deg']:.3f} | {r['rmse_kept_deg']:.3f} | {'; '.join(ks) or '—'} |")
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
