"""Stamps in ms, us or ns: refused with a one-line message naming the unit when their median
step says they are not seconds (session.check_time_unit: vs camera.fps for the camera's streams,
vs a plausible rate otherwise), or read with `import --time-unit`."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from playscope.base.errors import InputError
from playscope.cli import main
from playscope.io.importer import import_csv
from playscope.io.session import load_session

UNITS = {"ms": 1000, "us": 10**6, "ns": 10**9}


def _log(path, per_s: int, origin: int = 0, n: int = 500, rate_hz: float = 500.0):
    """A CSV log at rate_hz with integer stamps in units of 1/per_s s from origin (in those units)."""
    k = np.arange(n)
    t = origin + (k * per_s) // int(rate_hz)
    q = np.sin(k / 50.0)
    lines = ["t,q,c"] + [f"{a},{b:.6f},{10 * b:.6f}" for a, b in zip(t, q)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("unit", list(UNITS))
def test_import_refuses_stamps_in_a_smaller_unit(unit, tmp_path):
    with pytest.raises(InputError, match=rf"look like \w+seconds \(a 500 Hz stream\); pass --time-unit {unit}$"):
        import_csv(_log(tmp_path / "a.csv", UNITS[unit]), "t", "q", "c")


@pytest.mark.parametrize("unit", list(UNITS))
def test_import_reads_the_unit_given(unit, tmp_path):
    s = import_csv(_log(tmp_path / "a.csv", UNITS[unit], origin=1_700_000_000 * UNITS[unit]), "t", "q", "c",
                   time_unit=unit)
    assert s.t_origin_us == 1_700_000_000 * 10**6
    assert np.allclose(s.encoder["t_s"], np.arange(500) / 500.0, atol=1e-6)


def test_wrong_unit_named_against_the_one_given(tmp_path):
    with pytest.raises(InputError, match=r"pass --time-unit us instead of --time-unit ms$"):
        import_csv(_log(tmp_path / "a.csv", UNITS["us"]), "t", "q", "c", time_unit="ms")


def test_cli_one_line_exit_2(tmp_path, capsys):
    rc = main(["import", str(_log(tmp_path / "a.csv", UNITS["ns"])), "--t-col", "t", "--q-col", "q", "--c-col", "c",
               "-o", str(tmp_path / "S")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "they look like nanoseconds" in err and "--time-unit ns" in err
    assert not (tmp_path / "S").exists()
    assert main(["import", str(tmp_path / "a.csv"), "--t-col", "t", "--q-col", "q", "--c-col", "c",
                 "--time-unit", "ns", "-o", str(tmp_path / "S"), "-q"]) == 0


def test_time_unit_and_scale_together_refused(tmp_path):
    with pytest.raises(InputError, match="give one"):
        import_csv(_log(tmp_path / "a.csv", 1000), "t", "q", "c", time_unit="ms", time_scale=1e-3)


def _angle_session(root):
    """A minimal angle session (encoder 500 Hz, distal 100 Hz over 4 s) with a camera in session.json."""
    root.mkdir()
    meta = {"format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "angle"},
            "robot": {"model": "constant_curvature", "bend_length_mm": 20.0, "tip_length_mm": 5.0, "q_per_rad": 3.0},
            "camera": {"width": 720, "height": 576, "fps": 25.0,
                       "K": [[380.0, 0, 360.0], [0, 380.0, 288.0], [0, 0, 1]], "dist": [0, 0, 0, 0, 0]},
            "hand_eye": {"R": np.eye(3).tolist(), "t_mm": [0.0, 5.0, 10.0]}}
    (root / "session.json").write_text(json.dumps(meta))
    k = np.arange(2000)
    (root / "encoder.csv").write_text("t_s,q\n" + "".join(f"{i / 500:.3f},{np.sin(i / 100):.5f}\n" for i in k))
    (root / "distal.csv").write_text("t_s,c_deg\n" + "".join(f"{i / 100:.2f},{np.sin(i / 20):.5f}\n" for i in k[:400]))
    return root


@pytest.mark.parametrize("unit", list(UNITS))
def test_session_in_a_smaller_unit_refused(unit, tmp_path):
    s = _angle_session(tmp_path / "s")
    lines = (s / "encoder.csv").read_text().splitlines()
    f = UNITS[unit]
    (s / "encoder.csv").write_text("\n".join([lines[0]] + [f"{round(float(a) * f)},{b}" for a, b in
                                                          (x.split(",") for x in lines[1:])]) + "\n")
    with pytest.raises(InputError, match=rf"encoder.csv: .* they look like \w+seconds \(a 500 Hz stream\); session "
                                         rf"files hold seconds: divide t_s by .* --time-unit {unit}`\)$"):
        load_session(s)


def test_marker_in_ms_against_camera_fps(tmp_path):
    s = _angle_session(tmp_path / "s")
    meta = json.loads((s / "session.json").read_text())
    meta["distal"]["kind"] = "image"
    (s / "session.json").write_text(json.dumps(meta))
    (s / "distal.csv").unlink()
    (s / "marker.csv").write_text("t_s,u_px,v_px\n" + "".join(f"{40 * i},{300 + i % 7},{200}\n" for i in range(100)))
    with pytest.raises(InputError, match=r"marker.csv: the time stamps step by a median of 40 s \(1000 frame periods at "
                                         r"camera.fps 25\): they look like milliseconds \(a 25 Hz stream\)"):
        load_session(s)


def test_seconds_pass(tmp_path):
    assert load_session(_angle_session(tmp_path / "s")).encoder["t_s"].size == 2000
