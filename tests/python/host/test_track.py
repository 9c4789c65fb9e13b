"""`playscope track` on frames drawn here with OpenCV: known centre, occlusion, highlight, truncation."""

import json
import os

import cv2
import numpy as np
import pytest

from playscope.cli import main
from playscope.base.errors import InputError
from playscope.io.marker_track import MarkerTracker, TrackConfig, track_video

GREEN = (40, 200, 40)  # BGR


def draw(u, v, r=9.0, rng=None, blur=0.0, highlight=False, occlude=False, H=576, W=720, distractor=False):
    """A grey noisy frame with an anti-aliased green disc of radius r centred at (u, v) px
    (sub-pixel through cv2's 4 fractional bits)."""
    rng = rng or np.random.default_rng(0)
    img = np.full((H, W, 3), (90, 100, 110), np.uint8)
    img = cv2.add(img, rng.integers(0, 12, img.shape, dtype=np.uint8))
    s = 16
    if not occlude:
        cv2.circle(img, (round(u * s), round(v * s)), round(r * s), GREEN, -1, cv2.LINE_AA, 4)
    if highlight:  # white specular spot, on the marker or beside it
        cv2.circle(img, (round((u + 2) * s), round((v - 2) * s)), 3 * s, (255, 255, 255), -1, cv2.LINE_AA, 4)
    if distractor:
        cv2.circle(img, (100, 100), 14, (250, 250, 250), -1, cv2.LINE_AA)
    if blur:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    return img


@pytest.mark.parametrize("blur,highlight", [(0.0, False), (1.2, False), (0.0, True), (1.2, True)])
def test_subpixel_centre(blur, highlight):
    rng = np.random.default_rng(1)
    tr = MarkerTracker()
    err = []
    for _ in range(40):
        u, v = rng.uniform(100, 600), rng.uniform(100, 470)
        d = tr.track(draw(u, v, rng=rng, blur=blur, highlight=highlight))
        err.append(np.hypot(d.u - u, d.v - v))
    assert max(err) < 0.1, max(err)


def test_highlight_alone_is_not_a_marker():
    tr = MarkerTracker()
    d = tr.track(draw(300, 300, occlude=True, highlight=True, distractor=True))
    assert np.isnan(d.u) and d.reason != "ok"


def test_wrong_colour_and_streak_rejected():
    img = np.full((200, 200, 3), 100, np.uint8)
    cv2.line(img, (20, 100), (180, 104), GREEN, 3)  # a green streak: not circular
    d = MarkerTracker().track(img)
    assert np.isnan(d.u) and d.reason == "circularity"
    img = np.full((200, 200, 3), 100, np.uint8)
    cv2.circle(img, (100, 100), 10, (200, 40, 40), -1)  # blue disc, green tracker
    assert np.isnan(MarkerTracker().track(img).u)
    blue = MarkerTracker(TrackConfig(95, 130))
    assert abs(blue.track(img).u - 100) < 0.1


def _write_video(folder, n, occluded=(), fps=25.0, size=(320, 240)):
    folder.mkdir(parents=True, exist_ok=True)
    W, H = size
    path = folder / "video.avi"
    wr = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (W, H))
    assert wr.isOpened()
    centres = []
    for k in range(n):
        u, v = 80 + 1.5 * k, 120 + 20 * np.sin(k / 5)
        centres.append((u, v))
        wr.write(draw(u, v, r=8, occlude=k in occluded, H=H, W=W, rng=np.random.default_rng(k)))
    wr.release()
    with open(folder / "frames.csv", "w") as fh:
        fh.write("frame,t_s\n" + "".join(f"{k},{k / fps:.6f}\n" for k in range(n)))
    return path, np.array(centres)


def test_video_occlusion_marked_lost(tmp_path):
    path, centres = _write_video(tmp_path / "s", 60, occluded=range(20, 24))
    res = track_video(path, tmp_path / "s" / "frames.csv")
    assert res.t_s.size == 60 and not res.truncated
    lost = np.isnan(res.u_px)
    assert list(np.nonzero(lost)[0]) == [20, 21, 22, 23]
    e = np.hypot(res.u_px - centres[:, 0], res.v_px - centres[:, 1])[~lost]
    assert np.max(e) < 0.3  # MJPEG compression, not the tracker, dominates here


def test_cli_track_and_truncated_video(tmp_path, capsys):
    path, _ = _write_video(tmp_path / "s", 80)
    data = path.read_bytes()
    # Cut the file in the middle of a frame: OpenCV stops decoding there.
    path.write_bytes(data[: int(len(data) * 0.6)])
    assert main(["track", str(tmp_path / "s"), "--json", str(tmp_path / "t.json")]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "video.avi" in err and "frame" in err and len(err.strip().splitlines()) == 1
    j = json.loads((tmp_path / "t.json").read_text())
    assert j["truncated"] and 0 < j["frames_tracked"] < 80
    rows = (tmp_path / "s" / "marker.csv").read_text().splitlines()
    assert rows[0] == "t_s,u_px,v_px" and len(rows) == j["frames_tracked"] + 1
    # Existing output is not replaced without --overwrite.
    assert main(["track", str(tmp_path / "s")]) == 2


def test_frames_csv_disagreeing_with_video_is_an_error(tmp_path, capsys):
    _write_video(tmp_path / "s", 40)
    with open(tmp_path / "s" / "frames.csv", "w") as fh:
        fh.write("frame,t_s\n" + "".join(f"{k},{k / 25:.6f}\n" for k in range(200)))
    assert main(["track", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "frames.csv" in err and "200" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s" / "marker.csv").exists()


def test_bad_frames_csv_names_row(tmp_path):
    path, _ = _write_video(tmp_path / "s", 10)
    (tmp_path / "s" / "frames.csv").write_text("frame,t_s\n0,0\n1,0.04\n1.5,0.08\n")
    with pytest.raises(InputError, match=r"frames.csv:4: frame must be a non-negative integer"):
        track_video(path, tmp_path / "s" / "frames.csv")


def test_missing_video(tmp_path):
    (tmp_path / "s").mkdir()
    assert main(["track", str(tmp_path / "s")]) == 2
