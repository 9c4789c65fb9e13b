#!/usr/bin/env python3
"""One scoreboard row rendered again with one setting changed at a time: which effect of the
rendering a failure comes from, so the model's missing term can be named (not a gate added).

Each variant is the row's own renderer parameters (bench/onset_cases.py or bench/swing_cases.py)
updated by a JSON object, rendered, written and calibrated by the scoreboard's own `run_row`, and
printed as one JSON line: the change, the B error % (bench/b_score.py) and its limit, the t_delay
error in frames, the terms the record model chose, pass or fail, and the record model's switch
lags and slides (s), B's size and where it is read. `{}` re-runs the row as drawn.

Run a row only once it has been judged: a set-aside row varied before its group's run is spent.

Usage: PYTHONPATH=host:bench .venv/bin/python bench/onset_variants.py GROUP ROW '{}' '{"exposure_s": 0}' ...
  e.g. ... lockbox6 s6-swing-029-registration '{}' '{"exposure_s": 0.0}' '{"reg_deg": 0.0}'
The parameter names are the renderer's: marker_render.Scene, swing_render.Rendering, render_c.Spec.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import onset_scoreboard as SB  # noqa: E402

from playscope.fit import onset_search  # noqa: E402


@contextlib.contextmanager
def captured_fit_record():
    """onset_search.fit_record wrapped for the block: yields a dict whose "fit" receives what the
    onset stage's call returned (the final Fit, the search's log), the last call's when several."""
    captured = {}
    fit_record = onset_search.fit_record

    def capture(*a, **k):
        captured["fit"] = fit_record(*a, **k)
        return captured["fit"]

    onset_search.fit_record = capture  # onset_stage calls it through the module
    try:
        yield captured
    finally:
        onset_search.fit_record = fit_record


def run_variant(group: str, row: tuple, change: dict) -> dict:
    """The row (onset_scoreboard._rows' tuple) with its parameters updated by change, through
    onset_scoreboard.run_row; its figures and the record model's switches (a JSON-ready dict).
    Errors: TypeError naming a parameter the row's renderer does not have."""
    renderer, name, cat, limit, status, kw = row
    if not isinstance(kw, dict):
        import dataclasses

        kw = dataclasses.replace(kw, **change)
    else:
        kw = {**kw, **change}
    with captured_fit_record() as captured:
        d = SB.run_row((group, (renderer, name, cat, limit, status, kw)))
    out = {"change": change, **{k: d.get(k) for k in ("err_pct", "limit_pct", "td_err_frames", "terms", "fail", "refused")}}
    if "fit" in captured:
        fit = captured["fit"][0]
        m = fit.model
        out.update(switch_lag_s=m.unpack(fit.theta)[3], slide_s=m.slides(fit.theta), B_ctrl=m.n_b, B_read_at=m.width_at)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog="Each CHANGE is a JSON object of renderer parameters; '{}' is the row as drawn.")
    ap.add_argument("group", choices=(*SB.FROM_CASES, "development"))
    ap.add_argument("row", help="the row's name, as the scoreboard prints it")
    ap.add_argument("change", nargs="+", help="JSON object, e.g. '{\"exposure_s\": 0.0}'")
    a = ap.parse_args(argv)
    rows = {r[1]: r for r in SB._rows(a.group)}
    if a.row not in rows:
        ap.error(f"no row {a.row!r} in group {a.group} ({len(rows)} rows)")
    changes = []
    for c in a.change:
        try:
            ch = json.loads(c)
        except json.JSONDecodeError as e:
            ap.error(f"change {c!r} is not JSON: {e}")
        if not isinstance(ch, dict):
            ap.error(f"change {c!r} is not a JSON object")
        changes.append(ch)
    for ch in changes:
        print(json.dumps(run_variant(a.group, rows[a.row], ch)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
