"""Blind self-test of the diagnosis: simulated sessions with one effect at a few strengths (the
identity hidden), perturbed simulator parameters, null cases and out-of-library cases.

Scores (issue 5 targets): top-1 accuracy on the in-library cases (>= 90 %); a planted effect whose
oracle shrink is below the practical margin is "absorbed" by the in situ refit of B(q) and
f_remain and is expected to give "none"; false discoveries on
the null cases (an effect kept; <= 10 %), and the recovered shrink of the held-out RMSE against
the true one (|recovered - true| <= 25 % of true), where the true shrink is what the base model
gains when the true effect is added (the oracle knows which one and starts from its true values).
"""

from __future__ import annotations

import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from ..sim.core import preset, simulate
from ..sim.effects import EFFECTS
from .attribute import MARGIN_ABS, MARGIN_FRAC, attribute, halves
from .fitmodel import C_LIBRARY, Model, from_session
from .geometry import GEOM

BLIND_EFFECTS = tuple(C_LIBRARY) + tuple(GEOM)

# Effects checked blind (visible in c) and the parameter overrides that go with each strength.
EXTRA = {"dead_zone": {"c0_deg": 0.0}, "cable_elongation": {"tau_s": 1.0}}


def cases(strengths_per_effect: int = 2, nulls: int = 4, ool: int = 2, seed: int = 0,
          effects=BLIND_EFFECTS) -> list[dict]:
    """The case list: {"id", "truth" (effect name, "none" or "unexplained"), "effect", "params",
    "seed", "perturb"} with perturbed B, f and noise drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    out = []

    def perturb():
        return {"B_scale": float(rng.uniform(0.8, 1.2)), "B_peak": float(rng.uniform(0.7, 1.3)),
                "B_sigma": float(rng.uniform(0.8, 1.25)), "soft": float(rng.uniform(0.6, 1.3)),
                "gain": float(rng.uniform(0.9, 1.1)), "noise": float(rng.uniform(0.7, 1.5))}

    for e in effects:
        p0 = EFFECTS[e].params[0]
        for s in p0.strengths[:strengths_per_effect]:
            params = {p0.name: s, **EXTRA.get(e, {})}
            out.append({"truth": e, "effect": e, "params": params, "seed": int(rng.integers(1 << 30)), "perturb": perturb()})
    for _ in range(nulls):
        out.append({"truth": "none", "effect": None, "params": {}, "seed": int(rng.integers(1 << 30)), "perturb": perturb()})
    ools = ["breathing", "tissue_catch"]
    for i in range(ool):
        e = ools[i % 2]
        p = {p.name: (p.strengths[0] if p.strengths else p.off) for p in EFFECTS[e].params}
        out.append({"truth": "unexplained", "effect": e, "params": p, "seed": int(rng.integers(1 << 30)), "perturb": perturb()})
    for i, c in enumerate(out):
        c["id"] = i
    return out


def make_config(case: dict, duration_s: float = 120.0):
    """Simulator configuration for a case: the STRAS preset without its default effect, the
    parameters perturbed, the case's effect on."""
    cfg = preset("stras", effects={}, seed=case["seed"])
    p = case["perturb"]
    cfg.B = {"base": cfg.B["base"] * p["B_scale"], "peak": cfg.B["peak"] * p["B_peak"],
             "centre": cfg.B["centre"], "sigma": cfg.B["sigma"] * p["B_sigma"]}
    cfg.f = dict(cfg.f, soft=min(cfg.f["soft"] * p["soft"], 0.8), gain=cfg.f["gain"] * p["gain"])
    cfg.marker_noise_px *= p["noise"]
    cfg.trajectory = dict(cfg.trajectory, duration_s=duration_s)
    if case["effect"]:
        cfg.effects = {case["effect"]: dict(case["params"])}
    return cfg


def combine_geometry(res: dict, session, data, fm, em) -> dict:
    """Run the image-geometry screen (geometry.py) and fold it into res["verdict"]: a geometry
    effect becomes the verdict when the c channel found nothing ("none")."""
    from .geometry import screen
    geo = screen(session, data, fm, em)
    res["geometry"] = geo
    if geo["kept"] and res["verdict"] == "none":
        res["verdict"] = geo["kept"][0]
    return geo


def run_case(case: dict, duration_s: float = 120.0, candidates=C_LIBRARY, geometry: bool = True) -> dict:
    """Simulate blind, diagnose (screening ``candidates``), and score one case (also the
    oracle's true shrink)."""
    t0 = time.time()
    s = simulate(make_config(case, duration_s), blind=True)
    data = from_session(s)
    fm, em = halves(data)
    res = attribute(data, fm, em, candidates=candidates)
    geo = combine_geometry(res, s, data, fm, em) if geometry else None
    r0 = res["base"]["rmse_heldout_deg"]
    out = {"id": case["id"], "truth": case["truth"], "effect": case["effect"], "params": case["params"],
           "verdict": res["verdict"], "kept": [k["effect"] for k in res["kept"]],
           "indistinguishable": {k["effect"]: k["indistinguishable_from"] for k in res["kept"]},
           "rmse_base_deg": r0, "rmse_after_deg": res["final"]["rmse_heldout_deg"],
           "noise_floor_deg": res["noise_floor_deg"], "shrink_recovered_deg": r0 - res["final"]["rmse_heldout_deg"]}
    if case["effect"] in C_LIBRARY:
        # Oracle: knows the effect, starts from the base fit; its gain is the true shrink.
        m = Model(data, [case["effect"]])
        th = m.init.copy()
        for n, v in zip(res["_fits"]["base"].names, res["_fits"]["base"].theta):
            th[m.names.index(n)] = v
        f = m.fit(fm, th)
        out["shrink_true_deg"] = r0 - f.rmse(data.y_m, em)
        # When even the oracle cannot shrink the gap by the practical margin, the effect is not
        # recoverable in this protocol (absorbed by the in situ refit of B(q) and f_remain, or
        # beyond the library model's reach): the right verdict is then what the rule says of an
        # unfitted gap -- "none" within 1.5x the noise floor, else "unexplained". Such cases are
        # listed apart and left out of top-1.
        if out["shrink_true_deg"] < max(MARGIN_FRAC * r0, MARGIN_ABS):
            out["truth"] = "none" if (r0 <= 1.5 * res["noise_floor_deg"] or res["excess_before_deg"] < 2 * MARGIN_ABS) else "unexplained"
            out["absorbed"] = True
    if geo is not None:
        out["geometry_kept"] = geo["kept"]
    if case["effect"] in GEOM:
        from .geometry import _reproj
        p = GEOM[case["effect"]][0]
        Q = np.column_stack([data.extra["u"], data.extra["v"]])
        _, rt = _reproj(s, Q, np.nan_to_num(data.y_m), **{p: case["params"][p]})
        m = em & np.isfinite(rt)
        base_px = geo["base_px"]["heldout"]
        out["shrink_true_px"] = base_px - float(np.sqrt(np.mean(rt[m] ** 2)))
        kept = [g for g in geo["screen"] if g["effect"] in geo["kept"]]
        out["shrink_recovered_px"] = base_px - kept[0]["heldout_px"] if kept else 0.0
        out["recovered_value"] = next(g["value"] for g in geo["screen"] if g["effect"] == case["effect"])
    out["seconds"] = time.time() - t0
    return out


def run(n_strengths: int = 2, nulls: int = 4, ool: int = 2, seed: int = 0, duration_s: float = 120.0,
        workers: int = 2, effects=BLIND_EFFECTS, log=print) -> dict:
    """Run the whole self-test; returns {"cases": [...], "labels", "confusion", "top1", ...}."""
    cl = cases(n_strengths, nulls, ool, seed, effects)
    results = []
    if workers > 1:
        # One BLAS thread per worker: small least-squares problems gain nothing from threads, and
        # oversubscribed cores made the self-test an order of magnitude slower. Spawned workers
        # read these variables when they import numpy.
        for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(var, "1")
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as ex:
            for r in ex.map(run_case, cl, [duration_s] * len(cl)):
                results.append(r)
                log(_line(r))
    else:
        for c in cl:
            r = run_case(c, duration_s)
            results.append(r)
            log(_line(r))
    return score(results)


def _line(r: dict) -> str:
    extra = ""
    if "shrink_true_px" in r:
        extra = f" path shrink {r['shrink_recovered_px']:.3f}/{r['shrink_true_px']:.3f} px (value {r['recovered_value']:.3f})"
    elif "shrink_true_deg" in r:
        extra = f" shrink {r['shrink_recovered_deg']:.3f}/{r['shrink_true_deg']:.3f} deg"
    return (f"case {r['id']:3d} truth {r['truth']:<20s} -> {r['verdict']:<20s} kept {','.join(r['kept']) or '-':<40s}"
            f" rmse {r['rmse_base_deg']:.3f}->{r['rmse_after_deg']:.3f} (floor {r['noise_floor_deg']:.3f}){extra}"
            f" [{r['seconds']:.0f} s]")


def score(results: list[dict]) -> dict:
    """Confusion matrix (rows truth, columns verdict), top-1 accuracy on in-library cases,
    false-discovery rate on nulls, shrink agreement; all JSON-able."""
    labels = sorted({r["truth"] for r in results} | {r["verdict"] for r in results},
                    key=lambda x: (x in ("none", "unexplained"), x))
    conf = {t: {v: 0 for v in labels} for t in labels}
    for r in results:
        conf[r["truth"]][r["verdict"]] += 1
    lib = [r for r in results if r["truth"] not in ("none", "unexplained") and not r.get("absorbed")]
    nulls = [r for r in results if r["effect"] is None]
    absorbed = [r for r in results if r.get("absorbed")]
    ool = [r for r in results if r["effect"] is not None and r["effect"] not in BLIND_EFFECTS]
    top1 = float(np.mean([r["verdict"] == r["truth"] for r in lib])) if lib else float("nan")
    fd = float(np.mean([bool(r["kept"] or r.get("geometry_kept")) for r in nulls])) if nulls else float("nan")
    within = []
    for r in lib:
        if r["verdict"] != r["truth"]:
            continue
        u = "px" if "shrink_true_px" in r else "deg"
        tr, rc = r.get(f"shrink_true_{u}", 0.0), r.get(f"shrink_recovered_{u}", 0.0)
        if tr > 0:
            within.append(abs(rc - tr) <= 0.25 * tr)
    return {"cases": results, "labels": labels, "confusion": conf, "top1": top1, "false_discovery_nulls": fd,
            "absorbed": [{"effect": r["effect"], "params": r["params"], "verdict": r["verdict"],
                          "shrink_true_deg": r["shrink_true_deg"]} for r in absorbed],
            "ool_unexplained": float(np.mean([r["verdict"] == "unexplained" for r in ool])) if ool else float("nan"),
            "shrink_within_25pct": float(np.mean(within)) if within else float("nan"), "n_cases": len(results)}


def format_report(sc: dict) -> str:
    """Plain-text confusion matrix and scores."""
    labels = sc["labels"]
    short = {l: l[:10] for l in labels}
    w = max(len(l) for l in labels) + 2
    lines = ["confusion (rows: truth, columns: verdict)", " " * w + " ".join(f"{short[l]:>10s}" for l in labels)]
    for t in labels:
        if sum(sc["confusion"][t].values()) == 0:
            continue
        lines.append(f"{t:<{w}s}" + " ".join(f"{sc['confusion'][t][v]:>10d}" for v in labels))
    lines.append(f"top-1 accuracy (in-library cases): {100 * sc['top1']:.0f} %   (target >= 90 %)")
    lines.append(f"false discoveries on nulls: {100 * sc['false_discovery_nulls']:.0f} %   (target <= 10 %)")
    lines.append(f"out-of-library cases called unexplained: {100 * sc['ool_unexplained']:.0f} %")
    lines.append(f"recovered shrink within 25 % of the true one: {100 * sc['shrink_within_25pct']:.0f} % of correct cases")
    for a in sc["absorbed"]:
        lines.append(f"not recoverable (oracle shrink {a['shrink_true_deg']:.3f} deg < margin): "
                     f"{a['effect']} {a['params']} -> {a['verdict']}")
    return "\n".join(lines)
