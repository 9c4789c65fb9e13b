"""`playscope run-insitu`: board excitation, marker observations streamed to the board, B samples back."""

from __future__ import annotations

import csv
import sys
import time


def run_insitu(link, args) -> int:
    """Drive the board's excitation and feed it marker positions from OpenCV VideoCapture.

    The marker tracker is the host's (playscope.track, owned by the host package); this
    loop only moves data: frames -> (t, u, v) -> PSP_MSG_MARKER_OBS, B samples <- board.
    Without a tracker or a video source it refuses with a message instead of guessing."""
    try:
        import cv2
        from ..track import track_frame  # provided by the host package's tracker
    except ImportError as e:
        print(f"playscope: run-insitu needs OpenCV and playscope.track ({e.name} missing)", file=sys.stderr)
        return 2
    if args.video is None:
        print("playscope: run-insitu needs --video FILE or a camera index", file=sys.stderr)
        return 2
    cap = cv2.VideoCapture(int(args.video) if args.video.isdigit() else args.video)
    if not cap.isOpened():
        print(f"playscope: cannot open video {args.video}", file=sys.stderr)
        return 2
    link.set_mode("excitation")
    t0 = time.monotonic()
    samples = []
    while time.monotonic() - t0 < args.seconds:
        ok, img = cap.read()
        if not ok:
            break
        t_us = int((time.monotonic() - t0) * 1e6)
        pt = track_frame(img)
        u, v = (pt if pt is not None else (0.0, 0.0))
        b = link.marker(t_us, int(u * 65536), int(v * 65536), valid=pt is not None)
        if b:
            samples.append(b)
        samples += [e for k, e in link.poll_events() if k == "b"]
        if link.info()["mode"] == "idle":
            break
    link.set_mode("idle")
    if args.output:
        with open(args.output, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(samples[0]) if samples else ["reason"])
            w.writeheader()
            w.writerows(samples)
    print(f"{len(samples)} B samples ({sum(1 for s in samples if s['reason'] <= 1)} valid)")
    return 0
