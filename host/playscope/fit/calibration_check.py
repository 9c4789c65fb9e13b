"""A calibration file checked before it is used: readable, UTF-8, a JSON object of the
calibration format, q_range inside Q16.16, the splines well formed (docs/calibration-format.md).
Mirrors table_check.py for table blobs; every refusal is a one-line InputError naming the file."""

from __future__ import annotations


def q16_limit() -> float:
    """|q| (actuator units) the board's int32 Q format holds (session.q_limit, the one definition)."""
    from ..io.session import q_limit

    return q_limit()


def load_calibration(path):
    """Calibration.load behind a file-level check (readable, UTF-8, a JSON object, a q_range of
    two finite numbers q_min < q_max inside Q16.16): one-line InputError naming the file."""
    import math

    from .calibration import FORMAT, Calibration
    from ..base.errors import InputError
    from ..io.session import read_json

    d = read_json(path, "calibration JSON")
    if not isinstance(d, dict):
        raise InputError(path, f"a calibration is a JSON object, this file holds a {type(d).__name__}; "
                         "make one with `playscope calibrate`")
    if d.get("format") != FORMAT:
        raise InputError(path, f"format is {d.get('format')!r}, not a calibration ({FORMAT!r}); "
                         "make one with `playscope calibrate`")
    qr = d.get("q_range")
    if not (isinstance(qr, list) and len(qr) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                           and math.isfinite(x) for x in qr)):
        raise InputError(path, f"q_range must be two finite numbers [q_min, q_max], got {qr!r}")
    lim = q16_limit()
    if not -lim <= qr[0] < qr[1] <= lim:
        raise InputError(path, f"q_range {qr} must satisfy -{lim:g} <= q_min < q_max <= {lim:g} "
                         "(actuator units in Q16.16)")
    if d.get("actuator_unit") not in ("mm", "deg"):
        raise InputError(path, f"actuator_unit must be 'mm' or 'deg', got {d.get('actuator_unit')!r}")
    for key in ("B", "f_remain"):
        _check_spline(d.get(key), key, path)
    if d["f_remain"].get("sign") not in (-1, 1):
        raise InputError(path, f"f_remain.sign must be 1 or -1, got {d['f_remain'].get('sign')!r}")
    qpr = (d.get("f_coarse") or {}).get("q_per_rad") if isinstance(d.get("f_coarse"), dict) else None
    if not _finite(qpr) or qpr == 0:
        raise InputError(path, f"f_coarse.q_per_rad must be a finite non-zero number, got {qpr!r}")
    _check_optional_fields(d, path)
    return Calibration.load(path)


def _what(v) -> str:
    """A JSON value's type as the messages name it ("a string \"x\"", "a list", "null")."""
    import json

    kind = {bool: "a boolean", str: "a string", list: "a list", dict: "an object", int: "a number",
            float: "a number", type(None): "null"}.get(type(v), type(v).__name__)
    text = json.dumps(v)
    return f"{kind} {text}" if len(text) <= 40 and not isinstance(v, (list, dict)) else kind


def _check_optional_fields(d: dict, path) -> None:
    """The calibration's optional parts, each null/absent or of the type the loader reads: one
    InputError naming the file, the key, what it must be and what it is."""
    from ..base.errors import InputError

    def refuse(key, must, v):
        raise InputError(path, f"key {key}: expected {must}, got {_what(v)}; make the file with `playscope calibrate`")

    for key in ("B", "f_remain"):
        fl = d[key].get("floor")
        if fl is not None and not _finite(fl):
            refuse(f"{key}.floor", "a finite number or null", fl)
    for key in ("transition", "model_family"):
        if d.get(key) is not None and not isinstance(d[key], dict):
            refuse(key, "an object or null", d[key])
    tr = d.get("transition") or {}
    if tr.get("f_remain_play"):
        _check_spline(tr["f_remain_play"], "transition.f_remain_play", path)
        if tr["f_remain_play"].get("sign") not in (-1, 1):
            refuse("transition.f_remain_play.sign", "1 or -1", tr["f_remain_play"].get("sign"))
    fam = d.get("model_family") or {}
    if fam.get("B"):
        _check_spline(fam["B"], "model_family.B", path)
    ch = fam.get("choice")
    if ch is not None and not isinstance(ch, dict):
        refuse("model_family.choice", "an object or null", ch)
    rl = (ch or {}).get("relax")
    if rl:
        if not isinstance(rl, dict):
            refuse("model_family.choice.relax", "an object {kappa, lambda} or null", rl)
        for k in ("kappa", "lambda"):
            if not _finite(rl.get(k)):
                refuse(f"model_family.choice.relax.{k}", "a finite number", rl.get(k))


def _finite(x) -> bool:
    import math

    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _check_spline(sp, key: str, path) -> None:
    """A B-spline as calibrate writes it (bspline.SplineFn.to_json): degree 1..5, knots and
    coefficients finite, a range a < b. Errors: InputError naming the file and the key."""
    from ..base.errors import InputError

    if not isinstance(sp, dict):
        raise InputError(path, f"{key} must be a spline object, got {type(sp).__name__}; make the file with "
                         "`playscope calibrate`")
    deg, knots, coef, rng = sp.get("degree"), sp.get("knots"), sp.get("coef"), sp.get("range")
    if not (isinstance(deg, int) and not isinstance(deg, bool) and 1 <= deg <= 5):
        raise InputError(path, f"{key}.degree must be an integer 1..5 (calibrate writes 3), got {deg!r}")
    for name, v in (("knots", knots), ("coef", coef)):
        if not (isinstance(v, list) and v and all(_finite(x) for x in v)):
            raise InputError(path, f"{key}.{name} must be a list of finite numbers")
    if len(knots) != len(coef) + deg + 1:
        raise InputError(path, f"{key}: {len(knots)} knots for {len(coef)} coefficients of degree {deg} "
                         f"(need {len(coef) + deg + 1})")
    if not (isinstance(rng, list) and len(rng) == 2 and all(_finite(x) for x in rng) and rng[0] < rng[1]):
        raise InputError(path, f"{key}.range must be [a, b] with finite a < b, got {rng!r}")
