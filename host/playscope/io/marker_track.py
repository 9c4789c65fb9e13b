"""Coloured-marker tracking in a session video -> marker.csv (paper V-A: the distal marker Q).

Per frame (``MarkerTracker.track``):
  1. search window: a square ROI (``roi_half`` px each side) around the last position; when
     the marker was lost, candidates found on a 1/4-scale copy of the whole frame, each then
     measured in a window at full resolution (a full-resolution whole-frame pass costs ~20x
     an ROI pass, the 1/4-scale one ~3x);
  2. colour mask: OpenCV HSV threshold, hue in [hue_lo, hue_hi] (OpenCV hue units 0-179; a
     range with hue_lo > hue_hi wraps through red), saturation >= s_min and value >= v_min.
     A specular highlight is white (low saturation), so it never enters the mask;
  3. blob: the largest connected component whose area is within [area_min, area_max] px;
     holes (a highlight on the marker) are filled through its outer contour;
  4. validity: circularity 4 pi A / P^2 >= circ_min on the filled outline (a motion-blurred
     disc stays above ~0.5, a thin streak or a fragment does not) -- else the frame is lost;
  5. sub-pixel centroid: image moments of a soft weight: w = 1 on the filled blob eroded by
     2 px (so holes and highlights inside count fully), and on the rim (the blob dilated by
     2 px, minus that core) w = clip((S - S_bg) / (S_core - S_bg), 0, 1), S_core = median
     saturation inside the blob, S_bg = median saturation around it. Anti-aliased edge pixels thus count by their colour coverage, which is
     what takes the centroid below 0.1 px; a binary mask would quantise the edge.
Lost frames are written as empty u_px, v_px: a position is never interpolated or invented.

Units: px, OpenCV image convention (u to the right, v down, pixel centres at integers).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ..base.atomic import atomic_path
from ..base.errors import InputError
from .session import VIDEO_SUFFIXES, format_us, read_csv, time_us, write_csv

# Hue presets in OpenCV units (0-179 = 0-358 deg).
HUE_PRESETS = {"green": (40, 85), "blue": (95, 130), "red": (170, 10), "yellow": (20, 35)}


@dataclass
class TrackConfig:
    """Thresholds of MarkerTracker (see the module docstring for their role).

    hue_lo, hue_hi: OpenCV hue 0-179 (default green, 40-85); s_min, v_min: 0-255;
    area_min, area_max: px^2 of the blob (area_max None = 5 % of the frame);
    circ_min: 4 pi A / P^2 of the filled outline (1 for a disc); roi_half: px.
    """

    hue_lo: int = HUE_PRESETS["green"][0]
    hue_hi: int = HUE_PRESETS["green"][1]
    s_min: int = 80
    v_min: int = 40
    area_min: float = 12.0
    area_max: float | None = None
    circ_min: float = 0.45
    roi_half: int = 48

    def check(self) -> None:
        """Errors: ValueError for an out-of-range threshold."""
        if not (0 <= self.hue_lo <= 179 and 0 <= self.hue_hi <= 179):
            raise ValueError("hue bounds must lie in 0..179 (OpenCV hue units)")
        if not (0 <= self.s_min <= 255 and 0 <= self.v_min <= 255):
            raise ValueError("s_min and v_min must lie in 0..255")
        if self.area_min <= 0 or (self.area_max is not None and self.area_max <= self.area_min):
            raise ValueError("need 0 < area_min < area_max")
        if self.roi_half < 8:
            raise ValueError("roi_half must be >= 8 px")


@dataclass
class Detection:
    """One frame's result: u, v px (NaN when lost), blob area px^2, circularity, and why lost."""

    u: float = math.nan
    v: float = math.nan
    area: float = 0.0
    circularity: float = 0.0
    reason: str = "ok"


class MarkerTracker:
    """Stateful per-frame tracker (keeps the last position for the ROI search).

    frame: (H, W, 3) uint8 BGR, any size (the first frame fixes area_max when None).
    """

    def __init__(self, cfg: TrackConfig | None = None):
        self.cfg = cfg or TrackConfig()
        self.cfg.check()
        self.last: tuple[float, float] | None = None
        self._k3 = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))

    def reset(self) -> None:
        self.last = None

    def _mask(self, hsv: np.ndarray) -> np.ndarray:
        c = self.cfg
        if c.hue_lo <= c.hue_hi:
            return cv2.inRange(hsv, (c.hue_lo, c.s_min, c.v_min), (c.hue_hi, 255, 255))
        # Wrapping range (red): union of [hue_lo, 179] and [0, hue_hi].
        return cv2.inRange(hsv, (c.hue_lo, c.s_min, c.v_min), (179, 255, 255)) | \
            cv2.inRange(hsv, (0, c.s_min, c.v_min), (c.hue_hi, 255, 255))

    def track(self, frame: np.ndarray) -> Detection:
        """Find the marker in one BGR frame. Returns a Detection (NaN u, v when lost)."""
        H, W = frame.shape[:2]
        c = self.cfg
        area_max = c.area_max if c.area_max is not None else 0.05 * H * W
        if self.last is not None:
            x0 = max(int(self.last[0]) - c.roi_half, 0)
            y0 = max(int(self.last[1]) - c.roi_half, 0)
            x1 = min(int(self.last[0]) + c.roi_half + 1, W)
            y1 = min(int(self.last[1]) + c.roi_half + 1, H)
            det = self._search(frame[y0:y1, x0:x1], x0, y0, area_max, roi=True)
            if not math.isnan(det.u):
                self.last = (det.u, det.v)
                return det
        det = self._full_search(frame, area_max)
        self.last = None if math.isnan(det.u) else (det.u, det.v)
        return det

    def _full_search(self, frame: np.ndarray, area_max: float) -> Detection:
        """Whole-frame search: candidates on a 1/4-scale copy (16x fewer pixels), each then
        measured at full resolution in a window around it. The coarse mask takes half the
        saturation threshold, as the marker's rim blends with the background when shrunk."""
        c = self.cfg
        H, W = frame.shape[:2]
        f = 4
        small = cv2.resize(frame, (max(W // f, 1), max(H // f, 1)), interpolation=cv2.INTER_AREA)
        hsv = cv2.cvtColor(small, cv2.COLOR_BGR2HSV)
        s_min = c.s_min
        c.s_min = max(c.s_min // 2, 1)
        try:
            mask = self._mask(hsv)
        finally:
            c.s_min = s_min
        n, _, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if n <= 1:
            return Detection(reason="no_colour")
        best = Detection(reason="area")
        for lab in (np.argsort(stats[1:, cv2.CC_STAT_AREA])[::-1] + 1)[:3]:
            if stats[lab, cv2.CC_STAT_AREA] * f * f > 4 * area_max:
                continue
            half = max(c.roi_half, int(f * max(stats[lab, 2], stats[lab, 3])) + 8)
            cu, cv_ = (cents[lab] + 0.5) * f - 0.5
            x0, y0 = max(int(cu) - half, 0), max(int(cv_) - half, 0)
            x1, y1 = min(int(cu) + half + 1, W), min(int(cv_) + half + 1, H)
            det = self._search(frame[y0:y1, x0:x1], x0, y0, area_max, roi=False)
            if not math.isnan(det.u):
                return det
            best = det
        return best

    def _search(self, img: np.ndarray, ox: int, oy: int, area_max: float, roi: bool) -> Detection:
        c = self.cfg
        hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
        mask = self._mask(hsv)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if n <= 1:
            return Detection(reason="no_colour")
        areas = stats[1:, cv2.CC_STAT_AREA]
        order = np.argsort(areas)[::-1] + 1
        best = Detection(reason="area")
        for lab in order[:3]:  # the biggest few blobs: the marker is the largest valid one
            a = float(stats[lab, cv2.CC_STAT_AREA])
            if a < c.area_min:
                break
            if a > area_max:
                continue
            x, y, w, h = stats[lab, :4]
            # A blob touching the ROI border may be cut: search the whole frame instead.
            if roi and (x == 0 or y == 0 or x + w >= img.shape[1] or y + h >= img.shape[0]):
                best = Detection(reason="roi_border")
                continue
            d = self._measure(hsv, labels, lab, x, y, w, h)
            if d.reason == "ok":
                d.u += ox
                d.v += oy
                return d
            best = d
        return best

    def _measure(self, hsv, labels, lab, x, y, w, h) -> Detection:
        c = self.cfg
        pad = 3
        Hh, Ww = labels.shape
        xa, ya = max(x - pad, 0), max(y - pad, 0)
        xb, yb = min(x + w + pad, Ww), min(y + h + pad, Hh)
        comp = (labels[ya:yb, xa:xb] == lab).astype(np.uint8)
        cnts, _ = cv2.findContours(comp, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cnt = max(cnts, key=cv2.contourArea)
        filled = np.zeros_like(comp)
        cv2.drawContours(filled, [cnt], -1, 1, thickness=cv2.FILLED)
        area = float(filled.sum())
        perim = cv2.arcLength(cnt, True)
        # Digital outlines of small discs are over-long by ~pi/4 per px of radius; the +pi
        # term is the usual correction so that a 3 px disc is not rejected as non-circular.
        circ = 4 * math.pi * area / (perim + math.pi) ** 2 if perim > 0 else 0.0
        if circ < c.circ_min:
            return Detection(area=area, circularity=circ, reason="circularity")
        sat = hsv[ya:yb, xa:xb, 1].astype(np.float32)
        s_core = float(np.median(sat[comp.astype(bool)]))
        region = cv2.dilate(filled, self._k3)
        outside = region == 0
        # Background saturation (camera noise, tinted tissue) would otherwise weigh on the
        # rim on the side with more background pixels in the window.
        s_bg = float(np.median(sat[outside])) if outside.any() else 0.0
        wgt = np.clip((sat - s_bg) / max(s_core - s_bg, 1.0), 0.0, 1.0) * region
        # Interior = 1 whatever its colour: a highlight (white) or a hole in the mask on the
        # marker must not pull the centroid; only the rim carries sub-pixel coverage.
        wgt[cv2.erode(filled, self._k3) == 1] = 1.0
        m = cv2.moments(wgt)
        if m["m00"] <= 0:
            return Detection(reason="empty")
        return Detection(xa + m["m10"] / m["m00"], ya + m["m01"] / m["m00"], area, circ)


# --------------------------------------------------------------------------- video
@dataclass
class TrackResult:
    """Output of track_video: per tracked frame t_s, u_px, v_px (NaN = lost), plus counts.

    frames_listed: rows of frames.csv; frames_decoded: frames the video yielded; truncated:
    decoding stopped before the last listed frame; reasons: {lost reason: count}.
    """

    t_s: np.ndarray
    u_px: np.ndarray
    v_px: np.ndarray
    frames_listed: int
    frames_decoded: int
    truncated: bool
    seconds: float
    reasons: dict = field(default_factory=dict)
    warning: str | None = None
    t_text: list | None = None  # frames.csv's own text of each t_s (marker.csv repeats it)
    frame_size: tuple | None = None  # (width, height) px of the decoded frames

    def summary(self) -> dict:
        n = int(self.t_s.size)
        lost = int(np.isnan(self.u_px).sum())
        return {"frames_listed": self.frames_listed, "frames_decoded": self.frames_decoded,
                "frames_tracked": n, "lost": lost, "lost_fraction": lost / n if n else None,
                "truncated": self.truncated, "reasons": self.reasons, "seconds": self.seconds,
                "fps": n / self.seconds if self.seconds > 0 else None, "warning": self.warning}


def find_video(folder: Path) -> Path:
    """The session's video.* (first in name order). Errors: InputError when none."""
    vids = sorted(p for p in Path(folder).glob("video.*") if p.suffix.lower() in VIDEO_SUFFIXES)
    if not vids:
        raise InputError(Path(folder) / "video.*", f"file not found (suffixes {', '.join(VIDEO_SUFFIXES)})")
    return vids[0]


def read_frames_csv(path: Path, texts: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """frames.csv -> (frame (N,) int64, t_s (N,) s). texts: a list to which the stamps' own
    text is appended, one str per row (the decimal digits as written). Errors: InputError
    naming the row for a non-integer, negative or non-increasing frame number (time order is
    checked by read_csv)."""
    tt: list = []
    d = read_csv(path, ["frame", "t_s"], time_text=tt)
    if texts is not None:
        got = tt[0].ticks() if tt else None
        if got is None:  # not decimal text (cannot happen after read_csv): the parsed floats, to the us
            texts.extend(format_us(int(x)) for x in time_us(d["t_s"]).tolist())
        else:
            tk, dec = got
            texts.extend(_ticks_text(int(x), dec) for x in tk[d["_row"]].tolist())
    fr = d["frame"]
    bad = np.nonzero((fr != np.round(fr)) | (fr < 0))[0]
    if bad.size:
        raise InputError(path, f"frame must be a non-negative integer, got {fr[bad[0]]!r}", int(bad[0]) + 2)
    bad = np.nonzero(np.diff(fr) <= 0)[0]
    if bad.size:
        raise InputError(path, "frame numbers must increase", int(bad[0]) + 3)
    return fr.astype(np.int64), d["t_s"]


def _ticks_text(tick: int, dec: int) -> str:
    """tick / 10^dec as decimal text, trailing zeros dropped."""
    sign, tick = ("-", -tick) if tick < 0 else ("", tick)
    q, r = divmod(tick, 10 ** dec)
    return f"{sign}{q}" if r == 0 else f"{sign}{q}.{r:0{dec}d}".rstrip("0")


def track_video(video: Path, frames_csv: Path, cfg: TrackConfig | None = None, progress=None,
                tolerance: float = 0.02) -> TrackResult:
    """Track the marker through ``video``, stamping frame k with frames.csv's t_s.

    Decoding stops at the first frame the video cannot give (a truncated file): what was
    tracked up to the last good frame is returned with ``warning`` set (one line naming the
    file and frame). Errors (InputError): video unreadable; frames.csv and the video's own
    frame count disagree by more than max(2, tolerance * N) frames; the video decodes more
    frames than frames.csv lists by that much; no frame decoded at all.
    progress: a tqdm-like factory progress(total=..., desc=...) or None.
    """
    from .inputfile import check_input_file

    video, frames_csv = Path(video), Path(frames_csv)
    check_input_file(video, "video")  # a pipe or a device would block or never end
    texts: list[str] = []
    fr, t = read_frames_csv(frames_csv, texts)
    cap = cv2.VideoCapture(str(video))
    if not cap.isOpened():
        raise InputError(video, "cannot open the video (unknown codec or not a video)")
    n_list = int(fr[-1]) + 1
    slack = max(2, int(tolerance * n_list))
    n_hdr = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    # A truncated file usually keeps its header's count; a file whose header disagrees with
    # frames.csv is the wrong pairing, and tracking it would stamp frames with wrong times.
    if n_hdr > 0 and abs(n_hdr - n_list) > slack:
        cap.release()
        raise InputError(frames_csv, f"lists {n_list} frames but {video.name} has {n_hdr} "
                         f"(more than {slack} apart: wrong frames.csv for this video?)")
    tr = MarkerTracker(cfg)
    row_of = {int(f): i for i, f in enumerate(fr)}
    u = np.full(fr.size, np.nan)
    v = np.full(fr.size, np.nan)
    reasons: dict[str, int] = {}
    bar = progress(total=n_list, desc=f"track {video.name}", unit="frame") if progress else None
    k = 0
    size = None
    t0 = time.perf_counter()
    try:
        while True:
            ok, img = cap.read()
            if not ok or img is None:
                break
            if size is None:
                size = (int(img.shape[1]), int(img.shape[0]))
            i = row_of.get(k)
            if i is not None:
                d = tr.track(img)
                u[i], v[i] = d.u, d.v
                if d.reason != "ok":
                    reasons[d.reason] = reasons.get(d.reason, 0) + 1
            k += 1
            if bar is not None:
                bar.update(1)
            if k > n_list + slack:
                raise InputError(video, f"decodes more than {n_list + slack} frames but {frames_csv.name} "
                                 f"lists {n_list} (wrong frames.csv for this video?)")
    finally:
        cap.release()
        if bar is not None:
            bar.close()
    secs = time.perf_counter() - t0
    if k == 0:
        raise InputError(video, "no frame could be decoded")
    keep = fr < k
    truncated = bool(k < n_list)
    warn = None
    if truncated:
        warn = (f"{video}: video ends at frame {k - 1} (frames.csv lists up to {n_list - 1}); "
                f"marker.csv holds the {int(keep.sum())} frames decoded")
    n_kept = int(keep.sum())
    n_lost = int(np.isnan(u[keep]).sum())
    if n_kept and n_lost > LOST_WARN_FRACTION * n_kept:
        most = max(reasons, key=reasons.get) if reasons else "unknown"
        c = cfg or TrackConfig()
        lost_line = (f"{video}: the marker was lost in {n_lost} of {n_kept} frames (most often: {most}); "
                     f"check --marker / --hue ({c.hue_lo}..{c.hue_hi}), --s-min, --v-min, --area against the video")
        warn = lost_line if warn is None else f"{warn}; {lost_line}"
    jump_line = jump_warning(video, fr[keep], t[keep], u[keep], v[keep], (cfg or TrackConfig()).roi_half)
    if jump_line:
        warn = jump_line if warn is None else f"{warn}; {jump_line}"
    return TrackResult(t[keep], u[keep], v[keep], int(fr.size), k, truncated, secs, reasons, warn,
                       [x for x, kp in zip(texts, keep) if kp], size)


def jump_warning(video, fr, t, u, v, roi_half: float) -> str | None:
    """One line when the tracked marker jumps between consecutive frames by more than the
    tracker's own search window (roi_half px per frame): the instrument's tip moves a few px
    per frame in an excitation (its swings are slow so the play can be seen), so such a jump
    means the tracker lost the marker and found something else of its colour (tissue, a
    reflection), which would be calibrated as the tip's motion. None when there is none."""
    ok = np.isfinite(u) & np.isfinite(v)
    idx = np.nonzero(ok)[0]
    if idx.size < 2:
        return None
    gap = np.diff(fr[idx]).astype(float)
    step = np.hypot(np.diff(u[idx]), np.diff(v[idx]))
    jump = step > roi_half * np.maximum(gap, 1.0)
    if not jump.any():
        return None
    j = int(np.argmax(np.where(jump, step, -1.0)))
    return (f"{video}: the marker jumps {int(jump.sum())} time(s) by more than the {roi_half:.0f} px a frame the tip "
            f"can move (largest {step[j]:.0f} px, at frame {int(fr[idx[j + 1]])}, t = {t[idx[j + 1]]:.3f} s): "
            "the tracker followed something else of the marker's colour there; check --marker / --hue against the video")


# Above this fraction of lost frames, `track` warns: a marker.csv that is mostly empty is an
# option or lighting problem, not a result (a good recording loses a few percent at most).
LOST_WARN_FRACTION = 0.5


def write_marker_csv(path: Path, res: TrackResult) -> None:
    """marker.csv (t_s,u_px,v_px; empty u/v when lost), atomically (temp file + rename). Each
    t_s is its frame's stamp as frames.csv writes it (res.t_text), digit for digit: loaded,
    both are rebased from the same text to the record's origin (session.time_origin), so a
    marker row's time is its frame's time to the last bit, whatever the clock."""
    with atomic_path(path) as tmp:
        write_csv(tmp, {"t_s": res.t_s, "u_px": res.u_px, "v_px": res.v_px},
                  {"u_px": "{:.4f}", "v_px": "{:.4f}"}, t_text=res.t_text)


def single_thread() -> None:
    """One OpenCV thread: the speed target is per core, and several sessions are tracked in
    parallel processes rather than one frame across threads (ROIs are too small to split)."""
    cv2.setNumThreads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")


# --------------------------------------------------------------------------- the track step
@dataclass
class Tracked:
    """track_session's result: the marker CSV written, the video read, TrackResult's
    summary (frames_listed, frames_decoded, frames_tracked, lost, lost_fraction, truncated,
    reasons, seconds, fps, warning)."""

    marker_csv: Path
    video: Path
    summary: dict

    @property
    def warning(self) -> str | None:
        return self.summary.get("warning")

    def line(self) -> str:
        sm = self.summary
        return (f"{self.marker_csv}: {sm['frames_tracked']} frames, {sm['lost']} lost "
                f"({100 * (sm['lost_fraction'] or 0):.1f} %), {sm['fps']:.0f} frames/s")

    def to_json(self) -> dict:
        return {"marker_csv": str(self.marker_csv), "video": str(self.video), **self.summary}


def check_frame_size(folder: Path, video: Path, size) -> None:
    """Refuse (InputError naming the video) frames of another size than session.json's
    camera.width x camera.height: K, the distortion and the image bounds are stated for that
    size, so the marker's pixels would be calibrated in the wrong camera. No-op when the
    session.json gives no usable size (its loader names that)."""
    from .session import read_json

    from .inputfile import check_input_file

    if size is None or not os.path.lexists(folder / "session.json"):
        return
    check_input_file(folder / "session.json", "session.json")  # a pipe or a device: refused, never opened
    try:
        cam = read_json(folder / "session.json", "session.json").get("camera") or {}
        w, h = int(cam["width"]), int(cam["height"])
    except (InputError, AttributeError, KeyError, TypeError, ValueError):
        return
    if (w, h) != tuple(size):
        raise InputError(video, f"frames are {size[0]}x{size[1]} px but session.json says camera {w}x{h}: the "
                         "marker would be calibrated in another camera's pixels; fix camera.width/height (and K) "
                         "or give the session its own video")


def track_session(session_dir, out=None, cfg=None, overwrite: bool = False, progress=None) -> Tracked:
    """Find the marker in session_dir's video.* (frames.csv gives the times) and write
    marker.csv (default session_dir/marker.csv). cfg: TrackConfig (default: green).
    progress: callable(**tqdm kwargs) -> bar, as track_video takes. One OpenCV thread."""
    folder = Path(session_dir)
    if not folder.is_dir():
        raise InputError(folder, "session folder not found")
    video = find_video(folder)
    out = Path(out) if out else folder / "marker.csv"
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out}: exists (use --force)")
    cfg = cfg or TrackConfig()
    try:
        cfg.check()
    except ValueError as e:
        raise InputError(None, f"track options: {e}") from None
    single_thread()
    res = track_video(video, folder / "frames.csv", cfg, progress=progress)
    check_frame_size(folder, video, res.frame_size)
    write_marker_csv(out, res)
    return Tracked(out, video, res.summary())
