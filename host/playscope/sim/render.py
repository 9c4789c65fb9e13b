"""Rendering of endoscope frames (tracking path) and re-imaging of measured tip angles.

Frames: a reddish mucosa-like texture (low-pass noise), vignetting, a few specular highlights,
the grey instrument (the projected bending section) and a green tip marker (playscope.io.marker_track's
default hue). Written with OpenCV's VideoWriter (MJPG .avi, whole or absent: io.videofile) plus frames.csv (frame, t_s).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..fit import model as M
from ..io.session import write_csv
from ..io.videofile import video_writer
from .core import SimConfig, rot_y, tip_position


def background(width: int, height: int, seed: int = 0) -> np.ndarray:
    """Static endoscopic-looking background, BGR uint8 (height, width, 3): reddish texture with
    folds (blurred noise at two scales), radial vignetting and specular spots."""
    rng = np.random.default_rng(seed)
    tex = cv2.GaussianBlur(rng.random((height, width)).astype(np.float32), (0, 0), 18)
    tex = (tex - tex.min()) / (np.ptp(tex) + 1e-9)
    fine = cv2.GaussianBlur(rng.random((height, width)).astype(np.float32), (0, 0), 3)
    fine = (fine - fine.min()) / (np.ptp(fine) + 1e-9)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    r = np.hypot((x - width / 2) / (width / 2), (y - height / 2) / (height / 2))
    vign = np.clip(1.15 - 0.75 * r ** 2, 0.08, 1.0)
    lum = (0.55 + 0.3 * tex + 0.15 * fine) * vign
    img = np.stack([lum * 70, lum * 85, lum * 215], -1)  # B, G, R: pink-red mucosa
    for _ in range(8):  # specular highlights: small saturated white blobs
        cx, cy = rng.integers(0, width), rng.integers(0, height)
        ax = int(rng.integers(3, 10))
        cv2.ellipse(img, (int(cx), int(cy)), (ax, max(2, ax // 2)), float(rng.uniform(0, 180)), 0, 360, (255, 255, 255), -1)
    img = cv2.GaussianBlur(img, (0, 0), 1.2)
    return np.clip(img, 0, 255).astype(np.uint8)


def render_frame(bg: np.ndarray, arc_px: np.ndarray, tip_px: np.ndarray, marker_r_px: float,
                 shaft_w_px: float) -> np.ndarray:
    """One frame: the instrument as a grey polyline through arc_px ((n, 2) px, base to tip) and a
    green disc of radius marker_r_px at tip_px (px). Anti-aliased, sub-pixel (shift=4)."""
    img = bg.copy()
    S = 16
    pts = np.round(arc_px[np.all(np.isfinite(arc_px), 1)] * S).astype(np.int32)
    if len(pts) >= 2:
        cv2.polylines(img, [pts.reshape(-1, 1, 2)], False, (150, 150, 150), max(1, int(shaft_w_px)), cv2.LINE_AA, shift=4)
    if np.all(np.isfinite(tip_px)):
        c = tuple(int(v) for v in np.round(tip_px * S))
        cv2.circle(img, c, int(round(marker_r_px * S)), (60, 200, 40), -1, cv2.LINE_AA, shift=4)
    return img


def write_video(cfg: SimConfig, c_frames: np.ndarray, t_frames: np.ndarray, folder: Path,
                dir_frames: np.ndarray | None = None, translation: np.ndarray | None = None,
                effects: dict | None = None, marker_mm: float = 1.2) -> Path:
    """Render one frame per (t_frames[k], c_frames[k] deg) into folder/video.avi (MJPG) and write
    folder/frames.csv (frame, t_s). Geometry as observe_image (hand-eye direction, lens and
    curvature effects from ``effects``). Returns the video path."""
    effects = effects or {}
    gamma = effects.get("nonconstant_curvature", {}).get("gamma", 0.0)
    delta = effects.get("handeye_direction", {}).get("delta_deg", 0.0)
    dist = np.array(cfg.dist, float)
    dist[0] += effects.get("lens_distortion", {}).get("dk1", 0.0)
    K, R, t = np.array(cfg.K, float), np.array(cfg.R, float), np.array(cfg.t_mm, float)
    bg = background(cfg.width, cfg.height, cfg.seed)
    path = Path(folder) / "video.avi"
    with video_writer(path, cfg.fps, (cfg.width, cfg.height)) as vw:
        _render_frames(vw, cfg, c_frames, bg, K, R, t, dist, gamma, delta, dir_frames, translation, marker_mm)
    write_csv(Path(folder) / "frames.csv", {"frame": np.arange(len(t_frames)), "t_s": t_frames}, {"frame": "{:.0f}"})
    return path


def _render_frames(vw, cfg, c_frames, bg, K, R, t, dist, gamma, delta, dir_frames, translation, marker_mm) -> None:
    """write_video's frames, one per c_frames entry (deg), onto the writer vw."""
    s_arc = np.linspace(0, 1, 24)
    for k, c in enumerate(c_frames):
        # Points along the arc: the same section with a fraction of the bend and of the length.
        arc = np.array([tip_position(c * f, cfg.bend_length_mm * f, 0.0, gamma) for f in s_arc[1:]])
        arc = np.vstack([[0, 0, 0], arc, tip_position(c, cfg.bend_length_mm, cfg.tip_length_mm, gamma)])
        if translation is not None:
            arc[:, 2] += translation[k]
        Pc = arc @ R.T + t
        if delta and dir_frames is not None:
            Pc = Pc @ rot_y(np.sign(dir_frames[k]) * delta).T
        uv = M.project(Pc, np.eye(3), np.zeros(3), K, dist)
        depth = max(Pc[-1, 2], 1.0)
        img = render_frame(bg, uv, uv[-1], K[0, 0] * marker_mm / depth, K[0, 0] * 1.5 / depth)
        vw.write(img)
