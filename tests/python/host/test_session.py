"""Session format: round trip and one-line errors naming file and row."""

import json

import numpy as np
import pytest

from playscope.base.errors import InputError
from playscope.io.session import load_session, write_session

from .synth import angle_session, image_model_parts


def _image_session(tmp_path):
    s = angle_session()
    cam, he = image_model_parts()
    s.distal_kind, s.camera, s.hand_eye = "image", cam, he
    tf = s.distal["t_s"]
    u = np.linspace(100, 200, tf.size)
    v = np.full(tf.size, 300.0)
    u[5] = v[5] = np.nan
    s.marker = {"t_s": tf, "u_px": u, "v_px": v}
    s.distal = None
    return write_session(s, tmp_path / "img"), s


def test_round_trip_angle(tmp_path):
    s = angle_session()
    write_session(s, tmp_path / "s")
    r = load_session(tmp_path / "s")
    assert r.distal_kind == "angle" and r.actuator_unit == "mm"
    np.testing.assert_allclose(r.encoder["q"], s.encoder["q"], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(r.distal["c_deg"], s.distal["c_deg"], rtol=1e-8, atol=1e-12)
    assert r.robot == s.robot


def test_round_trip_image_with_lost_frames(tmp_path):
    folder, s = _image_session(tmp_path)
    r = load_session(folder)
    assert np.isnan(r.marker["u_px"][5]) and np.isnan(r.marker["v_px"][5])
    np.testing.assert_allclose(r.camera.K, s.camera.K)
    np.testing.assert_allclose(r.hand_eye.R, s.hand_eye.R)
    t, obs = r.observations()
    assert obs.shape == (t.size, 2)


def _corrupt(folder, name, lineno, text):
    lines = (folder / name).read_text().splitlines()
    lines[lineno - 1] = text
    (folder / name).write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("line,text,msg", [
    (5, "0.008,nan", "non-finite"),
    (5, "0.008,", "empty value"),
    (5, "0.008,abc", "not a number"),
    (5, "0.008", "expected 2 fields"),
])
def test_bad_encoder_rows_name_file_and_row(tmp_path, line, text, msg):
    s = angle_session()
    write_session(s, tmp_path / "s")
    _corrupt(tmp_path / "s", "encoder.csv", line, text)
    with pytest.raises(InputError) as ei:
        load_session(tmp_path / "s")
    assert f"encoder.csv:{line}:" in str(ei.value) and msg in str(ei.value)
    assert "\n" not in str(ei.value)


def test_backward_time_one_row_repaired_clock_reset_refused(tmp_path):
    """One row stamped before its predecessor is dropped with a note (it used to be
    refused); time going back for the rest of the file is a clock reset, refused at its row."""
    s = angle_session()
    write_session(s, tmp_path / "s")
    _corrupt(tmp_path / "s", "encoder.csv", 5, "0.0001,1.0")
    r = load_session(tmp_path / "s")
    assert r.encoder["t_s"].size == s.encoder["t_s"].size - 1
    assert r.notes == [f"{tmp_path / 's' / 'encoder.csv'}: 1 row(s) go back in time, the first at row 5 (dropped): "
                       f"1 of {s.encoder['t_s'].size} rows dropped"]
    p = tmp_path / "s" / "encoder.csv"
    lines = p.read_text().splitlines()
    lines[100:] = [f"{float(x.split(',')[0]) - 50:.6f},{x.split(',')[1]}" for x in lines[100:]]
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as ei:
        load_session(tmp_path / "s")
    assert "encoder.csv:101:" in str(ei.value) and "clock reset" in str(ei.value) and "\n" not in str(ei.value)


def test_missing_file_and_bad_json(tmp_path):
    s = angle_session()
    write_session(s, tmp_path / "s")
    (tmp_path / "s" / "distal.csv").unlink()
    with pytest.raises(InputError, match=r"distal.csv: file not found"):
        load_session(tmp_path / "s")
    with pytest.raises(InputError, match="session folder not found"):
        load_session(tmp_path / "nope")
    (tmp_path / "s" / "session.json").write_text('{"format": "other"}')
    with pytest.raises(InputError, match="format is 'other'"):
        load_session(tmp_path / "s")


def test_half_marker_row_refused(tmp_path):
    folder, _ = _image_session(tmp_path)
    _corrupt(folder, "marker.csv", 4, "0.1,150,")
    with pytest.raises(InputError, match=r"marker.csv:4: u_px and v_px"):
        load_session(folder)


def test_write_is_atomic(tmp_path):
    s = angle_session()
    write_session(s, tmp_path / "s")
    before = (tmp_path / "s" / "encoder.csv").read_text()
    s.encoder = {"t_s": s.encoder["t_s"], "q": s.encoder["q"][:-1]}  # wrong length -> fails mid-write
    with pytest.raises(Exception):
        write_session(s, tmp_path / "s", overwrite=True)
    assert (tmp_path / "s" / "encoder.csv").read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["s"]
    with pytest.raises(FileExistsError):
        write_session(angle_session(), tmp_path / "s")
