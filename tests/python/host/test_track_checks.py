"""`playscope track` on the smallest drawn videos: a marker that jumps further than the tip can
move in a frame is warned (before: followed without a word, 0 lost frames), frames of another
size than session.json's camera are refused, and marker.csv repeats frames.csv's stamps digit
for digit, so after load a marker row's time is its frame's time whatever the clock's origin."""

from __future__ import annotations

import json
from decimal import Decimal

import cv2
import numpy as np

from playscope.cli import main
from playscope.io.session import load_session

from .test_track import draw


def _video(folder, centres, size=(320, 240), stamps=None):
    """video.avi with a green disc at each centre, frames.csv with stamps (text) or k / 25 s."""
    folder.mkdir(parents=True, exist_ok=True)
    W, H = size
    wr = cv2.VideoWriter(str(folder / "video.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (W, H))
    for k, (u, v) in enumerate(centres):
        wr.write(draw(u, v, r=8, H=H, W=W, rng=np.random.default_rng(k)))
    wr.release()
    stamps = stamps or [f"{k / 25:.6f}" for k in range(len(centres))]
    (folder / "frames.csv").write_text("frame,t_s\n" + "".join(f"{k},{s}\n" for k, s in enumerate(stamps)))


def test_a_jump_beyond_the_tips_motion_is_warned(tmp_path, capsys):
    """20 frames: the disc moves 1 px a frame, then another disc 191 px away takes its place
    (the tracker follows it: nothing is lost, so only the jump tells)."""
    c = [(60 + k, 120) for k in range(10)] + [(260 + k, 120) for k in range(10)]
    _video(tmp_path / "s", c)
    assert main(["track", str(tmp_path / "s")]) == 0
    err = capsys.readouterr().err.strip()
    assert "jumps 1 time(s)" in err and "largest 191 px, at frame 10" in err and "\n" not in err, err


def test_a_steady_marker_is_not_warned(tmp_path, capsys):
    _video(tmp_path / "s", [(60 + 2 * k, 120 + k) for k in range(20)])
    assert main(["track", str(tmp_path / "s")]) == 0
    assert capsys.readouterr().err == ""


def test_frames_of_another_size_than_session_json_are_refused(tmp_path, capsys):
    _video(tmp_path / "s", [(60 + k, 120) for k in range(10)], size=(320, 240))
    (tmp_path / "s" / "session.json").write_text(json.dumps({"format": "playscope-session/1",
                                                             "camera": {"width": 640, "height": 480}}))
    assert main(["track", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert "frames are 320x240 px but session.json says camera 640x480" in err and "\n" not in err, err
    assert not (tmp_path / "s" / "marker.csv").exists()


def test_marker_stamps_are_the_frames_stamps(tmp_path):
    """Epoch stamps with a half-microsecond digit: parsed as floats and written to the us, a
    few rows moved by 1 us against their frame after load (6 of 70 in the first report)."""
    s = tmp_path / "S"
    assert main(["simulate", str(s), "--duration", "3", "--video", "-q"]) == 0
    rows = (s / "frames.csv").read_text().splitlines()[1:]
    t0, dt = Decimal("1700000000.0000005"), Decimal("0.0400001")
    (s / "frames.csv").write_text("frame,t_s\n" + "".join(f"{k},{t0 + k * dt}\n" for k in range(len(rows))))
    enc = (s / "encoder.csv").read_text().splitlines()
    (s / "encoder.csv").write_text("\n".join([enc[0]] + [",".join([str(Decimal(r.split(",")[0]) + Decimal(1700000000))]
                                                                  + r.split(",")[1:]) for r in enc[1:]]) + "\n")
    for f in ("truth.csv", "marker.csv"):
        (s / f).unlink()
    (s / ".playscope").unlink()
    assert main(["track", str(s), "-q"]) == 0
    got = load_session(s)
    assert got.marker["t_s"].size == len(rows)
    assert np.array_equal(got.marker["t_s"], got.frames["t_s"])
