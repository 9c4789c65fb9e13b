"""Property-based (Hypothesis): whatever bytes or JSON a user hands to session parsing,
calibration loading or the table check, the result is a value or a PlayscopeError, never any
other exception."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from playscope.fit.calibration_check import load_calibration
from playscope.fit.table_build import builtin_table
from playscope.base.errors import PlayscopeError
from playscope.io.session import load_session, parse_meta, read_csv
from playscope.board.table_check import check_blob

# A warning would print a second stderr line in the CLI: it fails the property too.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning", "error::UserWarning")

SETTINGS = settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])

KEYS = st.sampled_from(["format", "actuator", "unit", "distal", "kind", "robot", "model", "bend_length_mm",
                        "tip_length_mm", "q_per_rad", "camera", "K", "dist", "width", "height", "fps",
                        "hand_eye", "R", "t_mm", "t_delay_s", "x"])
LEAVES = (st.none() | st.booleans() | st.integers(-10**12, 10**12) | st.floats(allow_nan=True, allow_infinity=True)
          | st.text(max_size=12) | st.sampled_from(["playscope-session/1", "mm", "deg", "image", "angle",
                                                     "constant_curvature"]))
JSONISH = st.recursive(LEAVES, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(KEYS, inner, max_size=6),
                       max_leaves=25)

VALID_META = {"format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "image"},
              "robot": {"model": "constant_curvature", "bend_length_mm": 20.0, "tip_length_mm": 5.0, "q_per_rad": 3.0},
              "camera": {"width": 720, "height": 576, "fps": 25.0,
                         "K": [[380.0, 0, 360.0], [0, 380.0, 288.0], [0, 0, 1]], "dist": [-0.25, 0.08, 0, 0, 0]},
              "hand_eye": {"R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t_mm": [0, 0, 60]}, "t_delay_s": 0.04}


def _paths(d, prefix=()):
    if isinstance(d, dict):
        for k, v in d.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield prefix + (i,)
            yield from _paths(v, prefix + (i,))


META_PATHS = list(_paths(VALID_META))


def _replaced(path, value):
    d = json.loads(json.dumps(VALID_META))
    node = d
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return d


def test_valid_meta_parses():
    out = parse_meta(json.loads(json.dumps(VALID_META)), "session.json")
    assert out["camera"].width == 720


@SETTINGS
@given(JSONISH)
def test_parse_meta_any_json(d):
    try:
        parse_meta(d, "session.json")
    except PlayscopeError:
        pass


@SETTINGS
@given(st.sampled_from(META_PATHS), JSONISH)
@example(("camera", "K", 1, 2), 1.2737417533445467e+156)  # found by hypothesis: r * r overflowed in check_camera
def test_parse_meta_one_field_replaced(path, value):
    try:
        out = parse_meta(_replaced(path, value), "session.json")
    except PlayscopeError:
        return
    cam = out.get("camera")
    if cam is not None:  # anything accepted is a usable camera
        assert cam.K[0, 0] > 0 and cam.K[1, 1] > 0 and np.all(np.isfinite(cam.dist))


@SETTINGS
@given(st.binary(max_size=400) | st.text(max_size=300).map(str.encode))
def test_read_csv_any_bytes(data):
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "encoder.csv"
        p.write_bytes(data)
        try:
            out = read_csv(p, ["t_s", "q"])
        except PlayscopeError:
            return
        assert np.all(np.diff(out["t_s"]) > 0) and np.all(np.isfinite(out["q"]))


CSV_CELLS = st.sampled_from(["0", "1", "-1", "0.5", "1e3", "nan", "inf", "", "x", " 2 ", "1e400", "\x00", "é"])


@SETTINGS
@given(st.lists(st.lists(CSV_CELLS, min_size=1, max_size=4), max_size=12),
       st.sampled_from(["t_s,q", "t_s,q,q_cmd", "q,t_s", "t_s", ""]),
       st.binary(max_size=200) | st.builds(lambda d: json.dumps(d).encode(), JSONISH))
def test_load_session_any_files(rows, header, meta):
    with tempfile.TemporaryDirectory() as tmp:
        s = Path(tmp) / "s"
        s.mkdir()
        (s / "session.json").write_bytes(meta)
        (s / "encoder.csv").write_text(header + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
        (s / "marker.csv").write_text("t_s,u_px,v_px\n0,1,2\n0.04,,\n")
        try:
            load_session(s)
        except PlayscopeError:
            pass


@SETTINGS
@given(st.sampled_from(["q_range", "B", "f_remain", "f_coarse", "format"]), JSONISH)
def test_load_calibration_any_field(key, value):
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "cal.json"
        doc = {"format": "playscope-calibration/1", "q_range": [-2.0, 2.0], "B": {}, "f_remain": {"sign": 1},
               "f_coarse": {"q_per_rad": 3.0}}
        doc[key] = value
        p.write_text(json.dumps(doc))
        try:
            load_calibration(p)
        except PlayscopeError:
            pass


GOOD_TABLE = builtin_table(n=32, step_log2=14)


@SETTINGS
@given(st.binary(max_size=700))
def test_check_blob_any_bytes(data):
    try:
        check_blob(data)
    except PlayscopeError:
        pass


@SETTINGS
@given(st.lists(st.tuples(st.integers(0, len(GOOD_TABLE) - 1), st.integers(1, 255)), min_size=1, max_size=4))
def test_check_blob_mutated_table_is_refused(flips):
    b = bytearray(GOOD_TABLE)
    for at, mask in flips:
        b[at] ^= mask
    assume(bytes(b) != GOOD_TABLE)
    try:
        check_blob(bytes(b))
    except PlayscopeError:
        return
    # Passing would need a CRC-32 collision (about 2^-32 per example): treat it as a failure.
    raise AssertionError(f"mutated table accepted: {flips}")


@SETTINGS
@given(st.text(max_size=20) | st.floats().map(repr) | st.integers().map(str))
def test_argtypes_any_text(text):
    import argparse

    from playscope.commands import argtypes as T

    for parse, lo, hi in ((T.float_range(0.5, 1e4), 0.5, 1e4), (T.THRESHOLD, 0.0, 1e4), (T.CONTROL_POINTS, 4, 64),
                          (T.GENERATION, 1, 2**32 - 1)):
        try:
            v = parse(text)
        except argparse.ArgumentTypeError:
            continue
        assert math.isfinite(v) and lo <= v <= hi
