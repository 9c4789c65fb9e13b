"""The simulator's configuration checked key by key (nested keys included) as `simulate --config`,
`simulate()` and `evaluate` (a simulated session's recorded parameters) read it: one-line
InputError naming the file or source, the dotted key and what it must be."""

from __future__ import annotations

import json
import math

import numpy as np

def _num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _pos(v) -> bool:
    return _num(v) and v > 0


def _nonneg(v) -> bool:
    return _num(v) and v >= 0


def _matrix(rows: int, cols: int | None):
    def ok(v) -> bool:
        if cols is None:
            return isinstance(v, list) and len(v) == rows and all(_num(x) for x in v)
        return (isinstance(v, list) and len(v) == rows
                and all(isinstance(r, list) and len(r) == cols and all(_num(x) for x in r) for r in v))
    return ok


# SimConfig key -> (what it must be, check). Nested objects (B, f, trajectory, effects) below.
_SCALARS = {
    "name": ("a string", lambda v: isinstance(v, str)),
    "seed": ("an integer >= 0", lambda v: isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 2**63),
    "distal_kind": ("\"image\" or \"angle\"", lambda v: v in ("image", "angle")),
    "encoder_hz": ("a number in (0, 100000] Hz", lambda v: _pos(v) and v <= 1e5),
    "q_per_rad": ("a non-zero number", lambda v: _num(v) and v != 0),
    "bend_length_mm": ("a number > 0 (mm)", _pos),
    "tip_length_mm": ("a number >= 0 (mm)", _nonneg),
    "width": ("a whole number of px in 1..100000", lambda v: isinstance(v, int) and not isinstance(v, bool)
              and 1 <= v <= 100_000),
    "height": ("a whole number of px in 1..100000", lambda v: isinstance(v, int) and not isinstance(v, bool)
               and 1 <= v <= 100_000),
    "fps": ("a number in (0, 100000] frames/s", lambda v: _pos(v) and v <= 1e5),
    "K": ("a 3x3 list of numbers", _matrix(3, 3)),
    "dist": ("a list of 5 numbers (k1 k2 p1 p2 k3)", _matrix(5, None)),
    "R": ("a 3x3 list of numbers (a rotation)", _matrix(3, 3)),
    "t_mm": ("a list of 3 numbers (mm)", _matrix(3, None)),
    "t_delay_s": ("a number in [0, 10] s", lambda v: _nonneg(v) and v <= 10),
    "marker_noise_px": ("a number >= 0 (px)", _nonneg),
    "angle_noise_deg": ("a number >= 0 (deg)", _nonneg),
    "angle_rate_hz": ("a number in (0, 100000] Hz", lambda v: _pos(v) and v <= 1e5),
}
_NESTED = {
    "B": {"base": ("a number >= 0 (mm)", _nonneg), "peak": ("a number (mm)", _num),
          "centre": ("a number (mm)", _num), "sigma": ("a number > 0 (mm)", _pos)},
    "f": {"gain": ("a number", _num), "soft": ("a number", _num), "soft_width": ("a number > 0", _pos),
          "offset_deg": ("a number (deg)", _num)},
}
# Per trajectory kind: keys it needs, then keys it may have (sim.core.make_trajectory).
_TRAJ_KEYS = {
    "excitation": (("q_lo", "q_hi", "amp", "duration_s"), ("speed", "hold_s", "cycles")),
    "test": (("q_lo", "q_hi", "amp", "speed", "duration_s"), ("hold_s",)),
    "random_walk": (("q_lo", "q_hi", "speed", "duration_s"), ("corr_s",)),
    "ellipse": ((), ("a_mm", "b_mm", "period_s", "cycles", "x0_mm")),
}
_TRAJ_VALUES = {"q_lo": ("a number", _num), "q_hi": ("a number", _num), "x0_mm": ("a number (mm)", _num),
                "speed": ("a number > 0 (actuator units/s)", _pos)}


def _kind(v) -> str:
    """The JSON type of v, as a user reads it."""
    if isinstance(v, bool):
        return "a boolean"
    return {dict: "an object", list: "a list", str: "a string", type(None): "null"}.get(
        type(v), "a number") + f" {json.dumps(v)[:40]}"


def check_config(d: dict, path) -> None:
    """Refuse a SimConfig dict (preset keys with a --config file's over them) with a key missing,
    unknown, or of the wrong type or range, nested keys included: one-line InputError naming
    path, the key (dotted: B.peak, trajectory.q_lo, effects.drift.rate_deg_per_min) and what it
    must be. Only keys of the file can be wrong: the presets pass."""
    from ..base.errors import InputError
    from .effects import EFFECTS

    def bad(key: str, what: str, v=None, missing: bool = False):
        got = "missing" if missing else f"got {_kind(v)}"
        raise InputError(path, f"key {key}: expected {what}, {got}")

    def unknown(key: str, what: str, known):
        raise InputError(path, f"key {key}: no such {what} (known: {', '.join(known)})")

    for k, (what, ok) in _SCALARS.items():
        if k in d and not ok(d[k]):
            bad(k, what, d[k])
    for k, spec in _NESTED.items():
        sub = d.get(k)
        if not isinstance(sub, dict):
            bad(k, f"an object with keys {', '.join(spec)}", sub)
        for kk, (what, ok) in spec.items():
            if kk not in sub:
                bad(f"{k}.{kk}", what, missing=True)
            if not ok(sub[kk]):
                bad(f"{k}.{kk}", what, sub[kk])
        for kk in sub:
            if kk not in spec:
                unknown(f"{k}.{kk}", f"key in {k}", spec)
    tr = d.get("trajectory")
    if not isinstance(tr, dict):
        bad("trajectory", "an object with a \"kind\"", tr)
    if not isinstance(tr.get("kind"), str) or tr.get("kind") not in _TRAJ_KEYS:
        bad("trajectory.kind", " or ".join(f'"{k}"' for k in _TRAJ_KEYS), tr.get("kind"),
            missing="kind" not in tr)
    need, may = _TRAJ_KEYS[tr["kind"]]
    for kk in need:
        if kk not in tr:
            bad(f"trajectory.{kk}", f"{_TRAJ_VALUES.get(kk, ('a number > 0',))[0]} (the {tr['kind']} trajectory needs it)",
                missing=True)
    for kk, v in tr.items():
        if kk == "kind":
            continue
        if kk not in need + may:
            unknown(f"trajectory.{kk}", f"key in a {tr['kind']} trajectory", need + may)
        if kk == "speed" and v is None and tr["kind"] == "excitation":
            continue  # the pacing rule picks it
        what, ok = _TRAJ_VALUES.get(kk, ("a number > 0", _pos))
        if not ok(v):
            bad(f"trajectory.{kk}", what, v)
    if "q_lo" in tr and not tr["q_lo"] < tr["q_hi"]:
        bad("trajectory.q_hi", f"a number above trajectory.q_lo ({tr['q_lo']:g})", tr["q_hi"])
    eff = d.get("effects")
    if not isinstance(eff, dict):
        bad("effects", "an object {effect: {parameter: number}}", eff)
    for name, params in eff.items():
        if name not in EFFECTS:
            unknown(f"effects.{name}", "effect", EFFECTS)
        if not isinstance(params, dict):
            bad(f"effects.{name}", "an object {parameter: number}", params)
        known = [p.name for p in EFFECTS[name].params]
        for pn, v in params.items():
            if pn not in known:
                unknown(f"effects.{name}.{pn}", f"parameter of {name}", known)
            if not _num(v):
                bad(f"effects.{name}.{pn}", "a number", v)
    if "R" not in d:
        bad("R", "a rotation matrix (R R^T = I, det +1)", missing=True)
    try:
        R = np.asarray(d["R"], float)
    except (TypeError, ValueError):
        bad("R", "a 3x3 rotation matrix of numbers", d["R"])
    if R.shape != (3, 3) or not (np.allclose(R @ R.T, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0):
        bad("R", "a rotation matrix (R R^T = I, det +1)", d["R"])
