"""Host speed: `calibrate` on a 3-minute 25 Hz image session (a 1 kHz encoder log, which load_session
thins to io.session.ENCODER_MAX_HZ as it does every image session's; on two cores, its independent
fits shared with a forked child, playscope.base.forkmap), and marker tracking
at 720x576 (cv2.setNumThreads(1)): the per-frame tracker on frames already in memory, a lost
frame's whole-frame search, and `track_video` end to end (MJPEG decode included). Prints a table.

Usage: .venv/bin/python bench/bench_host.py
"""

import tempfile
import time
from pathlib import Path

import numpy as np

from bench_session import image_session

from playscope.fit.calibration import calibrate
from playscope.base.native import core
from playscope.io.session import load_session, write_session


core()
REPEATS = 3
rows = []
with tempfile.TemporaryDirectory() as d:
    write_session(image_session(), Path(d) / "s")
    runs = []  # (load, calibrate) seconds of each of REPEATS runs: median and worst are printed
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        s = load_session(Path(d) / "s")
        t1 = time.perf_counter()
        cal = calibrate(s)
        t2 = time.perf_counter()
        runs.append((t1 - t0, t2 - t1))
    ld, cb = np.array(runs).T
    rows.append(("load 3-min session (1 kHz encoder log thinned at load, 25 Hz marker): load_session", ld))
    rows.append((f"calibrate ({cal.n_b_samples} B samples, LM on {s.marker['t_s'].size} frames): calibrate", cb))
    rows.append(("load + calibrate (target < 3 s)", ld + cb))
print(f"| step | median of {REPEATS} (s) | worst (s) |\n|---|---|---|")
for name, sec in rows:
    print(f"| {name} | {np.median(sec):.2f} | {sec.max():.2f} |")

# ----------------------------------------------------------------------------- tracking
import cv2  # noqa: E402

from playscope.io.marker_track import MarkerTracker, single_thread, track_video  # noqa: E402

single_thread()
H, W, N = 576, 720, 1000
rng = np.random.default_rng(0)
base = cv2.add(np.full((H, W, 3), (90, 100, 110), np.uint8), rng.integers(0, 12, (H, W, 3), dtype=np.uint8))
centres = [(360 + 200 * np.sin(k / 40), 288 + 120 * np.sin(k / 23)) for k in range(N)]
frames = []
for u, v in centres:
    f = base.copy()
    cv2.circle(f, (round(u * 16), round(v * 16)), 10 * 16, (40, 200, 40), -1, cv2.LINE_AA, 4)
    frames.append(f)
tr = MarkerTracker()
per_frame = []
for f in frames:
    t0 = time.perf_counter()
    tr.track(f)
    per_frame.append(time.perf_counter() - t0)
roi_fps = N / sum(per_frame)
roi_worst_ms = 1e3 * max(per_frame)
tr = MarkerTracker()
t0 = time.perf_counter()
for f in frames[:200]:
    tr.reset()
    tr.track(f)
full_fps = 200 / (time.perf_counter() - t0)
with tempfile.TemporaryDirectory() as d:
    wr = cv2.VideoWriter(str(Path(d) / "video.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (W, H))
    for f in frames:
        wr.write(f)
    wr.release()
    (Path(d) / "frames.csv").write_text("frame,t_s\n" + "".join(f"{k},{k / 25:.6f}\n" for k in range(N)))
    cap = cv2.VideoCapture(str(Path(d) / "video.avi"))
    t0 = time.perf_counter()
    while cap.read()[0]:
        pass
    dec_fps = N / (time.perf_counter() - t0)
    res = track_video(Path(d) / "video.avi", Path(d) / "frames.csv")
    e2e_fps = res.t_s.size / res.seconds
print("\n| tracking, 720x576, 1 OpenCV thread | frames/s |\n|---|---|")
print(f"| tracker, ROI around last position (frames in memory; target >= 800) | {roi_fps:.0f} "
      f"(slowest frame {roi_worst_ms:.2f} ms) |")
print(f"| tracker, whole-frame search (marker lost before) | {full_fps:.0f} |")
print(f"| MJPEG decode alone (cv2.VideoCapture) | {dec_fps:.0f} |")
print(f"| track_video end to end (decode + track) | {e2e_fps:.0f} |")
