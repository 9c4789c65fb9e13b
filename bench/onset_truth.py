#!/usr/bin/env python3
"""A failed scoreboard row: is the record's model wrong there, or did its search miss the model's
own best fit? The row is rendered and calibrated as the scoreboard does it, and the model the
search chose is then fitted again from the rendering's truth: B(q) from the renderer's true width,
the delay from its true mean lag, the other nonlinear parameters (switch lags, slides, exposure, tip
mode) from the search's fit or as given. Both fits are scored by the search's own criterion (the
BIC at the search's scale, onset_fit.Fit.bic).

  - from the truth clearly lower than the search's: the model holds the truth and scores it better;
    the search never reached it (a start or basin problem, not a missing term);
  - from the truth higher: the record prefers something other than the truth under this model, so a
    term is missing or wrong (bench/onset_variants.py then says which effect of the rendering).

Prints one JSON line: the search's BIC and B error %, the truth start's BIC (one evaluation) and
the fit from it (BIC, B error %, and its switch lags, slides, exposure in s), and the search's BIC
minus the truth's fit's (positive: the truth scores lower). A BIC difference of a few units is within
the fits' own stopping tolerance: a passing no-effect row gave 0.002; s12-swing-048-registration, 100.

The delay: the model's is the image's mean lag behind the encoder (onset_model's module doc, the
exposure), taken as the scoreboard takes it (onset_scoreboard.true_mean_lag). B error % here is over
the model's own travel (`b_error_pct`), not over the B samples' range as the scoreboard's, so the two
differ a little (10.54 against 10.32 % on s12-swing-048-registration).

Run a row only once it has been judged: a set-aside row examined before its group's run is spent.

Usage: PYTHONPATH=host:bench .venv/bin/python bench/onset_truth.py GROUP ROW ['{"lag_tip": 0.005}'] [--terms T,...]
  The optional JSON object sets the start of named nonlinear parts from the truth, in s: lag_tip,
  lag_motor, slide_tip, slide_motor, expo (only parts of the model refitted).
  --terms refits the truth under other terms than the search chose (e.g. the rendering's own:
  reg_tip,slide_tip,expo; "" for the plain model), at the search's B and path sizes; parts the
  search's fit lacks start at the model's defaults. The search's fit is scored as it was.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import onset_scoreboard as SB  # noqa: E402
from onset_variants import captured_fit_record  # noqa: E402

from playscope.fit.calibration import calibrate  # noqa: E402
from playscope.fit.onset_fit import IRLS_ROUNDS, _basis, _fit_one  # noqa: E402
from playscope.fit.onset_model import TERMS, RecordModel, Terms  # noqa: E402
from playscope.io.session import load_session  # noqa: E402

SETTERS = {"lag_tip": "lag_x", "lag_motor": "lag_x", "slide_tip": "slide_x", "slide_motor": "slide_x",
           "expo": "expo_x"}


def b_error_pct(fit, true_B) -> float:
    """Mean |B_fit - B_true| over the model's travel, % of the mean true B (400 points)."""
    m = fit.model
    qq = np.linspace(m.q_lo, m.q_hi, 400)
    tb = np.asarray(true_B(qq), float)
    return float(100 * np.mean(np.abs(m.B_of(m.unpack(fit.theta)[1], qq) - tb)) / np.mean(tb))


def _switches(fit) -> dict:
    m = fit.model
    out = {"lag_s": m.unpack(fit.theta)[3], "slide_s": m.slides(fit.theta)}
    if m.terms.expo:
        out["expo_s"] = float(m.exposure(fit.theta))
    return out


def check_terms(terms: list[str] | None) -> None:
    """Errors: ValueError naming the terms onset_model does not know (its TERMS)."""
    unknown = sorted(set(terms or ()) - set(TERMS))
    if unknown:
        raise ValueError(f"unknown terms {unknown}: onset_model's are {list(TERMS)}")


def compare(group: str, row: tuple, given: dict, terms: list[str] | None = None) -> dict:
    """The row calibrated, then its chosen model (or the model with `terms`, onset_model.TERMS'
    names) refitted from the truth (module doc). given: {part name: s} for SETTERS' parts. Returns a
    JSON-ready dict. Errors: ValueError naming a given part the refitted model lacks or SETTERS does
    not know, or a term onset_model does not know."""
    check_terms(terms)  # before the calibration's minutes
    obj, write, true_B, d_true, _ = SB.row_objects(group, row)
    lag = SB.true_mean_lag(row[0], obj, d_true)
    with captured_fit_record() as captured, tempfile.TemporaryDirectory() as d:
        write(obj, Path(d))
        calibrate(load_session(d))
    fit, search = captured["fit"]
    m, sigma = fit.model, float(search["sigma_px"])
    parts = m.parts(fit.theta)
    if terms is not None:
        mt = RecordModel(m.rec, m.n_b, m.n_g, Terms(**{n: True for n in terms}), m.prior, m.d_fixed, m.width_at)
        mt.slope = m.slope
        parts = {k: v for k, v in parts.items() if k in mt.layout()}
        m = mt
    qq = np.linspace(m.q_lo, m.q_hi, 400)
    if m.n_b == 1:
        parts["B"] = np.array([float(np.mean(true_B(qq)))])
    else:
        parts["B"] = np.linalg.lstsq(_basis(qq, m.q_lo, m.q_hi, m.n_b), np.asarray(true_B(qq), float), rcond=None)[0]
    parts["d"] = np.array([lag])
    for name, s in given.items():
        if name not in SETTERS or name not in m.layout():
            raise ValueError(f"part {name!r} is not one of the refitted model's {sorted(set(SETTERS) & set(m.layout()))}")
        parts[name] = np.array([getattr(m, SETTERS[name])(float(s))])
    th = m.theta(parts)
    at = _fit_one((m, th, sigma, 1, 1))
    refit = _fit_one((m, th, sigma, 20, IRLS_ROUNDS))
    return {"row": row[1], "terms": m.terms.names(), "search_terms": fit.model.terms.names(), "B_ctrl": m.n_b, "B_read_at": m.width_at, "sigma_px": sigma,
            "search": {"bic": fit.bic(sigma), "B_err_pct": b_error_pct(fit, true_B), "t_delay_s": float(fit.theta[0]),
                       **_switches(fit)},
            "truth_start_bic": at.bic(sigma),
            "from_truth": {"bic": refit.bic(sigma), "B_err_pct": b_error_pct(refit, true_B),
                           "t_delay_s": float(refit.theta[0]), **_switches(refit)},
            "bic_search_minus_truth": fit.bic(sigma) - refit.bic(sigma)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("group", choices=(*SB.FROM_CASES, "development"))
    ap.add_argument("row", help="the row's name, as the scoreboard prints it")
    ap.add_argument("given", nargs="?", default="{}", help="JSON object {part: s}, e.g. '{\"expo\": 0.004}'")
    ap.add_argument("--terms", help="comma-separated terms to refit the truth under instead of the search's "
                    "(e.g. reg_tip,slide_tip,expo; '' for the plain model)")
    a = ap.parse_args(argv)
    rows = {r[1]: r for r in SB._rows(a.group)}
    if a.row not in rows:
        ap.error(f"no row {a.row!r} in group {a.group} ({len(rows)} rows)")
    try:
        given = json.loads(a.given)
    except json.JSONDecodeError as e:
        ap.error(f"{a.given!r} is not JSON: {e}")
    if not isinstance(given, dict):
        ap.error(f"{a.given!r} is not a JSON object")
    unknown = sorted(set(given) - set(SETTERS))
    if unknown:
        ap.error(f"unknown parts {unknown}: the parts that can be given are {sorted(SETTERS)}")
    terms = None if a.terms is None else [t for t in a.terms.split(",") if t]
    try:
        check_terms(terms)
    except ValueError as e:
        ap.error(str(e))
    print(json.dumps(compare(a.group, rows[a.row], given, terms)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
