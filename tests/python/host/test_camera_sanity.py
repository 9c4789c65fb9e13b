"""Camera sanity: a singular or non-finite K, and distortion coefficients that fold
the image, are refused with one line naming session.json. The fold rule is checked against
OpenCV's own projection (cv2.projectPoints), which shares no code with session.check_camera."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from playscope.cli import main
from playscope.base.errors import InputError
from playscope.io.session import Camera, check_camera, load_session, write_session

from .synth import angle_session

K_OK = [[380.0, 0, 360.0], [0, 380.0, 288.0], [0, 0, 1]]
W, H = 720, 576


def _radial_profile(K, dist, r_max, n=2000):
    """Distorted pixel radius (from the principal point, px) of points along the image
    diagonal direction at undistorted normalised radius 0..r_max, by OpenCV."""
    r = np.linspace(1e-4, r_max, n)
    d = np.array([W - K[0][2], H - K[1][2]]) / np.array([K[0][0], K[1][1]])
    d /= np.linalg.norm(d)
    pts = np.column_stack([r * d[0], r * d[1], np.ones_like(r)])
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), np.array(K, float), np.array(dist, float))
    uv = uv.reshape(-1, 2)
    return r, np.hypot(uv[:, 0] - K[0][2], uv[:, 1] - K[1][2])


def _corner_px():
    return np.hypot(W - K_OK[0][2], H - K_OK[1][2])


@pytest.mark.parametrize("dist", [[-0.25, 0.08, 0, 0, 0], [0.3, 0.1, 0, 0, 0], [-0.05, 0, 0, 0, 0], [0, 0, 0, 0, 0]])
def test_accepted_distortion_is_monotone_by_opencv(dist):
    check_camera(Camera(W, H, 25.0, np.array(K_OK), np.array(dist, float)), "s.json")
    r, rad = _radial_profile(K_OK, dist, 3.0)
    inside = rad <= _corner_px()
    # up to where OpenCV's projection first leaves the image corner, it never turns back
    first_out = np.argmax(~inside) if (~inside).any() else r.size
    assert np.all(np.diff(rad[:first_out]) > 0)


@pytest.mark.parametrize("dist", [[-1.0, 0.08, 0, 0, 0], [-0.75, 0.08, 0, 0, 0], [0.0, -0.3, 0, 0, 0],
                                  [0.1, 0.0, 0, 0, -0.2], [-0.4, 0, 0, 0, 0]])
def test_refused_distortion_folds_by_opencv(dist):
    with pytest.raises(InputError) as e:
        check_camera(Camera(W, H, 25.0, np.array(K_OK), np.array(dist, float)), "s.json")
    assert str(e.value).startswith("s.json: camera.dist") and "folds the image" in str(e.value)
    r, rad = _radial_profile(K_OK, dist, 3.0)
    # OpenCV agrees: the distorted radius turns back before it reaches the image corner
    turn = np.argmax(np.diff(rad) <= 0)
    assert np.diff(rad)[turn] <= 0 and rad[turn] < _corner_px()


@pytest.mark.parametrize("K,what", [
    ([[0, 0, 360.0], [0, 380.0, 288.0], [0, 0, 1]], "singular"),
    ([[380.0, 0, 360.0], [0, 380.0, 288.0], [0, 0, 0]], "singular"),
    ([[380.0, 0, 360.0], [0, -380.0, 288.0], [0, 0, 1]], "singular"),
    ([[380.0, 0, 360.0], [0, 380.0, 288.0], [0.5, 0, 1]], "singular"),
    ([[380.0, 0, 360.0], [0, 380.0, 288.0]], "shape"),
    ([[380.0, 0, "x"], [0, 380.0, 288.0], [0, 0, 1]], "numeric"),
])
def test_bad_K_refused_through_the_cli(K, what, tmp_path, capsys):
    s = angle_session(rate_hz=50.0)
    write_session(s, tmp_path / "s")
    j = json.loads((tmp_path / "s" / "session.json").read_text())
    j["camera"] = {"width": W, "height": H, "fps": 25.0, "K": K, "dist": [0, 0, 0, 0, 0]}
    (tmp_path / "s" / "session.json").write_text(json.dumps(j))
    with pytest.raises(InputError):
        load_session(tmp_path / "s")
    assert main(["calibrate", str(tmp_path / "s"), "-o", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"playscope: error: {tmp_path / 's' / 'session.json'}: camera.K") and "\n" not in err
    assert not (tmp_path / "c.json").exists()


def test_nan_K_refused():
    from playscope.io.session import parse_meta

    d = {"format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "angle"},
         "robot": {"model": "constant_curvature", "bend_length_mm": 20, "tip_length_mm": 5, "q_per_rad": 3},
         "camera": {"width": W, "height": H, "fps": 25, "K": [[float("nan"), 0, 1], [0, 1, 1], [0, 0, 1]]}}
    with pytest.raises(InputError, match="camera.K must be finite"):
        parse_meta(d, "session.json")
