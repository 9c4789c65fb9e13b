"""Results that would be wrong without a word are warned or refused with one line: a table of
another calibration given to `evaluate --table`, records of another actuator unit in one
`evaluate-transfer`, frames of another size than session.json's camera (the video's own size,
or marker positions outside the image) when a session is loaded for `calibrate`."""

from __future__ import annotations

import json

import numpy as np

from playscope.cli import main
from playscope.io.session import load_session

from .goodfiles import copy_good


def _warnings(err: str) -> list[str]:
    return [x for x in err.splitlines() if x.startswith("playscope: warning:")]


def test_evaluate_warns_about_another_calibrations_table(tmp_path, good, capsys):
    """The good table (built from this calibration) passes without a word; a table whose B is
    three times this calibration's (another instrument's) is warned about in one line."""
    from playscope.fit.calibration_check import load_calibration
    from playscope.fit.table_build import build_table

    g = copy_good(good, tmp_path)
    argv = ["evaluate", str(g["session"]), str(g["cal"]), "--comp-duration", "2"]
    assert main(argv + ["--table", str(g["table"])]) == 0
    assert not [w for w in _warnings(capsys.readouterr().err) if "does not match" in w]
    cal = load_calibration(g["cal"])
    q0, q1 = cal.q_range
    other = tmp_path / "other.pstb"
    other.write_bytes(build_table(lambda q: 3.0 * cal.B(q), cal.f, q0, q1, cal.actuator_unit, "remain", 1, 64).blob)
    assert main(argv + ["--table", str(other)]) == 0
    w = [x for x in _warnings(capsys.readouterr().err) if "does not match" in x]
    assert len(w) == 1 and str(other) in w[0] and str(g["cal"]) in w[0], w


def test_transfer_refuses_records_of_another_unit(tmp_path, good, capsys):
    """A catheter record (q in mm of cable) as the calibration, an endoscope record (q in deg
    of commanded angle, headerless) to run it on: refused naming the record, before any work."""
    g = copy_good(good, tmp_path)
    rows = [r.split(",") for r in g["csv"].read_text().splitlines()[1:]]
    deg = tmp_path / "endo.csv"
    deg.write_text("".join(f"{t},{float(q) * 10:.4f},0,{c}\n" for t, q, c in rows))
    assert main(["evaluate-transfer", str(g["csv"]), str(deg)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"playscope: error: {deg}: q is in deg but the calibration record") and "\n" not in err, err


def _image_session(tmp_path, video: bool):
    s = tmp_path / "S"
    assert main(["simulate", str(s), "--duration", "3", "-q"] + (["--video"] if video else [])) == 0
    return s


def _resize_camera(s, w, h):
    d = json.loads((s / "session.json").read_text())
    d["camera"]["width"], d["camera"]["height"] = w, h
    (s / "session.json").write_text(json.dumps(d))


def test_video_of_another_size_is_noted(tmp_path):
    s = _image_session(tmp_path, video=True)
    d = json.loads((s / "session.json").read_text())
    W, H = d["camera"]["width"], d["camera"]["height"]
    assert not [n for n in load_session(s).notes if "camera" in n]
    _resize_camera(s, W * 2, H * 2)
    notes = [n for n in load_session(s).notes if "session.json says camera" in n]
    assert len(notes) == 1 and f"frames are {W}x{H} px" in notes[0], notes


def test_marker_outside_the_image_is_noted(tmp_path):
    s = _image_session(tmp_path, video=False)
    m = np.genfromtxt(s / "marker.csv", delimiter=",", names=True)
    _resize_camera(s, int(np.nanmax(m["u_px"]) // 2), int(np.nanmax(m["v_px"]) // 2))
    notes = [n for n in load_session(s).notes if "outside the" in n]
    assert len(notes) == 1 and "marker.csv" in notes[0], notes


def test_compensation_reference_shorter_than_its_unscored_second_is_refused(tmp_path, good, capsys):
    """--comp-duration 1 left nothing to score after the reference's first (unscored) second:
    a numpy error as the one line; now refused as an option value."""
    g = copy_good(good, tmp_path)
    assert main(["evaluate", str(g["session"]), str(g["cal"]), "--comp-duration", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--comp-duration" in err and "\n" not in err, err


def test_evaluate_table_is_checked_as_flash_checks_it(tmp_path, good, capsys):
    """A table with bytes appended (its total_size no longer the file's length) was scored as
    if flashed; now refused as `flash` refuses it, naming the field."""
    g = copy_good(good, tmp_path)
    bad = tmp_path / "bad.pstb"
    bad.write_bytes(g["table"].read_bytes() + b"\0" * 64)
    assert main(["evaluate", str(g["session"]), str(g["cal"]), "--table", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"playscope: error: {bad}") and "\n" not in err, err
