"""Session folders (format playscope-session/1): load, validate and write atomically.

A session is a folder (docs/session-format.md):
  session.json   metadata: "format", actuator.unit, distal.kind, camera, hand_eye, robot, t_delay_s
  encoder.csv    t_s,q[,q_cmd]       high-rate actuator log (s, actuator units)
  marker.csv     t_s,u_px,v_px       one row per frame, empty u/v for a lost marker (image sessions)
  frames.csv     frame,t_s           with video.* when the marker is still to be tracked
  distal.csv     t_s,c_deg           angle sessions (external sensor, e.g. EM tracker)
  truth.csv      t_s,c_deg[,...]     simulated sessions only: ground truth, any extra columns
Every error is an InputError naming the file and, for CSV content, the row (header = row 1).
"""

from __future__ import annotations

import copy
import csv
import json
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..base.atomic import atomic_path
from ..base.errors import InputError

FORMAT = "playscope-session/1"
ACTUATOR_UNITS = ("mm", "deg")
DISTAL_KINDS = ("image", "angle")
Q_SOURCES = ("measured", "command")  # actuator.q_source: encoder reading, or the position commanded
VIDEO_SUFFIXES = (".avi", ".mp4", ".mkv", ".mov", ".m4v")


# --------------------------------------------------------------------------- metadata
@dataclass
class Camera:
    """Pinhole camera with OpenCV distortion (eq. 6, h).

    K: (3, 3) intrinsics in px; dist: (5,) k1 k2 p1 p2 k3 (OpenCV order); fps in Hz;
    width, height in px.
    """

    width: int
    height: int
    fps: float
    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))

    def to_json(self) -> dict:
        return {"width": int(self.width), "height": int(self.height), "fps": float(self.fps),
                "K": np.asarray(self.K, float).tolist(), "dist": np.asarray(self.dist, float).tolist()}


@dataclass
class HandEye:
    """cam_T_base: P_cam = R @ P_base + t_mm. R: (3, 3) rotation; t_mm: (3,) mm."""

    R: np.ndarray
    t_mm: np.ndarray

    def to_json(self) -> dict:
        return {"R": np.asarray(self.R, float).tolist(), "t_mm": np.asarray(self.t_mm, float).tolist()}


@dataclass
class Robot:
    """Geometric model g (constant curvature) and f_coarse: c [rad] = q / q_per_rad.

    bend_length_mm: arc length of the bending section; tip_length_mm: rigid tip beyond it
    (the marker sits at its end); q_per_rad: actuator units per radian of bending (signed:
    negative when pulling the cable decreases c).
    """

    model: str
    bend_length_mm: float
    tip_length_mm: float
    q_per_rad: float

    def to_json(self) -> dict:
        return {"model": self.model, "bend_length_mm": float(self.bend_length_mm),
                "tip_length_mm": float(self.tip_length_mm), "q_per_rad": float(self.q_per_rad)}


@dataclass
class Session:
    """An in-memory session. Arrays are float64, 1-D, one entry per CSV row.

    encoder: {"t_s", "q"[, "q_cmd"]}; marker: {"t_s", "u_px", "v_px"} (NaN = lost) or None;
    distal: {"t_s", "c_deg"} or None; truth: {"t_s", "c_deg", ...} or None;
    frames: {"frame", "t_s"} with ``video`` (a path) when the marker is not tracked yet.
    ``meta`` keeps any extra keys of session.json (e.g. "source") for round trips.
    """

    actuator_unit: str
    distal_kind: str
    robot: Robot
    encoder: dict[str, np.ndarray]
    camera: Camera | None = None
    hand_eye: HandEye | None = None
    t_delay_s: float | None = None
    marker: dict[str, np.ndarray] | None = None
    distal: dict[str, np.ndarray] | None = None
    truth: dict[str, np.ndarray] | None = None
    frames: dict[str, np.ndarray] | None = None
    video: Path | None = None
    path: Path | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    q_source: str = "measured"
    notes: list[str] = field(default_factory=list)
    # The files' time of the session's first stamp, integer us: load_session makes every t_s
    # relative to it (time_origin), write_session adds it back, so the files keep their clock.
    t_origin_us: int = 0

    # Observations used by the estimator, whichever the distal kind.
    def observations(self) -> tuple[np.ndarray, np.ndarray]:
        """Distal observations: (t_s (N,), obs (N, 2)) with obs = (u_px, v_px) for image
        sessions, (c_deg, 0) for angle sessions; NaN rows are lost frames."""
        if self.distal_kind == "angle":
            t = self.distal["t_s"]
            return t, np.column_stack([self.distal["c_deg"], np.zeros_like(t)])
        if self.marker is None:
            raise InputError(self.path, "no marker.csv: run `playscope track` on the video first")
        return self.marker["t_s"], np.column_stack([self.marker["u_px"], self.marker["v_px"]])

    def to_json(self) -> dict:
        act = {"unit": self.actuator_unit} | ({"q_source": self.q_source} if self.q_source != "measured" else {})
        d: dict[str, Any] = {"format": FORMAT, "actuator": act,
                             "distal": {"kind": self.distal_kind}, "robot": self.robot.to_json()}
        if self.camera is not None:
            d["camera"] = self.camera.to_json()
        if self.hand_eye is not None:
            d["hand_eye"] = self.hand_eye.to_json()
        if self.t_delay_s is not None:
            d["t_delay_s"] = float(self.t_delay_s)
        for k, v in self.meta.items():
            d.setdefault(k, v)
        return d

    def slice_time(self, t0: float, t1: float) -> "Session":
        """A copy keeping rows with t0 <= t_s < t1 in every table (for in situ halves)."""
        s = copy.copy(self)
        for name in ("encoder", "marker", "distal", "truth", "frames"):
            tab = getattr(self, name)
            if tab is not None:
                m = (tab["t_s"] >= t0) & (tab["t_s"] < t1)
                setattr(s, name, {k: v[m] for k, v in tab.items()})
        s.path = None
        return s


# --------------------------------------------------------------------------- CSV
def read_csv(path: Path, required: list[str], optional: list[str] = (), nullable: set[str] = frozenset(),
             time_col: str | None = "t_s", notes: list[str] | None = None,
             header: list[str] | None = None, time_text: list | None = None,
             others: bool = True, progress=None) -> dict[str, np.ndarray]:
    """Read a numeric CSV with a header row into float64 arrays (n,), in chunks (csvtable).

    required/optional: column names; the header's other columns are kept too when others is
    True, a cell there that is not a finite number becoming NaN (they are not used by the
    method). nullable: columns whose empty or NaN fields mean "lost" (NaN); in a required column
    anywhere else an empty, non-numeric, NaN or infinite field is an error. An optional column
    with an empty or NaN field is left out, with a note when notes is given (a spreadsheet's
    half-filled column is not a measurement). A UTF-8 BOM and a trailing separator are read as
    spreadsheets write them. header: the column names of a file without a header row (its
    first line is data, row 1); None reads them from the first line. time_col must be strictly
    increasing, unless ``notes`` (a list) is given: then
    repeated and backward time stamps are repaired by ``regularize_time`` and what it did is
    appended to notes as one line. time_text: a list to which a TimeText of the time column is
    appended, the table then carrying a "_row" column (data row numbers, kept through the
    repairs) so that time_origin can rebase the stamps' text exactly. progress: a tqdm-like
    factory for a bar while a large file is read (csvtable.read_table), or None.
    Errors: InputError(file, message, row) with the 1-based line number.
    """
    from .csvtable import read_table
    from .inputfile import MAX_CSV_BYTES, check_input_file

    path = Path(path)
    check_input_file(path, "CSV file", MAX_CSV_BYTES)
    out, names = read_table(path, required, optional, nullable, header, others, progress)
    for name in optional:
        if name in out and name not in nullable and np.isnan(out[name]).any():
            bad = np.isnan(out[name])
            del out[name]
            if notes is not None:
                notes.append(f"{path}: column {name!r} is empty or NaN in {int(bad.sum())} of {bad.size} rows (the "
                             f"first at row {int(np.argmax(bad)) + (2 if header is None else 1)}): left out")
    if time_text is not None and time_col is not None:
        time_text.append(TimeText(path, names.index(time_col), header is None))
        out["_row"] = np.arange(len(out[time_col]), dtype=np.int64)
    if time_col is not None and notes is not None:
        out, note = regularize_time(out, path, time_col)
        if note:
            notes.append(note)
    elif time_col is not None:
        t = out[time_col]
        bad = np.nonzero(np.diff(t) <= 0)[0]
        if bad.size:
            k = int(bad[0]) + 1
            raise InputError(path, f"time {t_col_fmt(t[k])} s not after the previous row's "
                             f"{t_col_fmt(t[k - 1])} s (time must increase)", k + 2)
    return out


# Irregular logs (docs/session-format.md, "Irregular logs"). A row whose time stamp is
# behind an earlier row's cannot be placed without guessing which clock is right; a few
# such rows are dropped (a late packet, a corrupt stamp), but more than this fraction of the
# file means a clock reset or two joined logs, which only the user can untangle.
MAX_BACKWARD_FRACTION = 0.01
# A logger faster than its sensor repeats the last reading: when most rows equal the
# previous one, the repeats are not measurements (a measured signal with noise almost never
# repeats exactly, a still one at most half the time between quantisation steps).
HELD_FRACTION = 0.5


def regularize_time(tab: dict[str, np.ndarray], path, time_col: str = "t_s") -> tuple[dict[str, np.ndarray], str | None]:
    """Make ``tab[time_col]`` strictly increasing by the documented choice, and say so.

    - a row earlier than some row before it is dropped (its stamp cannot be placed);
    - rows sharing a time stamp keep the last of them (a sensor re-publishing keeps its
      newest reading; the same choice as ``playscope import`` of ROS bags).
    Returns (table, note) with note None when nothing changed, else one line naming the
    file and the number of rows affected. Errors: InputError(path, ..., row of the largest step back) when more than
    MAX_BACKWARD_FRACTION of the rows (and more than one) go back in time.
    """
    t = np.asarray(tab[time_col], float)
    n = t.size
    if n < 2:
        return tab, None
    prev_max = np.maximum.accumulate(np.r_[-np.inf, t[:-1]])
    back = t < prev_max
    nb = int(back.sum())
    first = int(np.argmax(back)) if nb else -1
    if nb > max(1.0, MAX_BACKWARD_FRACTION * n):
        k = int(np.argmin(t - prev_max))  # the largest step back: where the clock was reset
        raise InputError(path, f"time goes back in {nb} of {n} rows, the most here ({t_col_fmt(t[k])} s after "
                         f"{t_col_fmt(prev_max[k])} s): a clock reset or joined logs? split the file there "
                         f"(at most {MAX_BACKWARD_FRACTION:.0%} of the rows may be out of order)", k + 2)
    kept = np.nonzero(~back)[0]
    tk = t[kept]
    last = np.r_[tk[1:] != tk[:-1], True]
    nd = int((~last).sum())
    if nb == 0 and nd == 0:
        return tab, None
    idx = kept[last]
    parts = []
    if nd:
        parts.append(f"{nd} row(s) repeat an earlier time stamp (kept the last row of each)")
    if nb:
        parts.append(f"{nb} row(s) go back in time, the first at row {first + 2} (dropped)")
    note = f"{path}: " + "; ".join(parts) + f": {n - idx.size} of {n} rows dropped"
    return {k: v[idx] for k, v in tab.items()}, note


def drop_held(tab: dict[str, np.ndarray], cols: list[str], path) -> tuple[dict[str, np.ndarray], str | None]:
    """Read a sensor logged faster than it measures (sample-and-hold) at its own rate.

    When more than HELD_FRACTION of the rows repeat the previous row's ``cols`` exactly, each
    run of equal values is one reading, timed at the run's first row (when it arrived); the
    repeats are dropped. Lost rows (NaN) never count as repeats. Returns (table, note), note
    None when the file is not held, else one line with the count and the sensor's own rate.
    """
    X = np.column_stack([np.asarray(tab[c], float) for c in cols])
    n = X.shape[0]
    if n < 3:
        return tab, None
    same = np.r_[False, np.all(X[1:] == X[:-1], axis=1)]
    if same.mean() <= HELD_FRACTION:
        return tab, None
    t = tab["t_s"]
    keep = ~same
    rate = (int(keep.sum()) - 1) / max(float(t[-1] - t[0]), 1e-12)
    note = (f"{path}: {int(same.sum())} of {n} rows ({same.mean():.0%}) repeat the previous value: read as a "
            f"sensor slower than its log ({rate:.3g} new readings/s), each reading timed at its first row")
    return {k: v[keep] for k, v in tab.items()}, note


def t_col_fmt(x: float) -> str:
    return f"{x:.9g}"


@dataclass(frozen=True)
class TimeText:
    """Where a table's time stamps were read: the file, the time column's index, whether the
    file's first line is a header, and the factor to seconds the stamps were multiplied by
    (import --time-unit/--time-scale). time_origin re-reads the stamps' text through it to
    rebase them exactly in decimal."""

    path: Path
    col: int
    has_header: bool = True
    scale: float = 1.0

    def ticks(self) -> tuple[np.ndarray, int] | None:
        """The time column's exact values, (ticks (n,), D): stamp = ticks / 10^D, in the order
        read_csv numbered the rows (csvtable.time_ticks); None when the file cannot be read
        again or a stamp is not a decimal number."""
        from .csvtable import time_ticks

        return time_ticks(self.path, self.col, self.has_header)


def format_us(u: int) -> str:
    """Integer microseconds as exact decimal seconds, trailing zeros dropped."""
    sign, u = ("-", -u) if u < 0 else ("", u)
    q, r = divmod(u, 1_000_000)
    return f"{sign}{q}" if r == 0 else f"{sign}{q}.{r:06d}".rstrip("0")


def write_csv(path: Path, columns: dict[str, np.ndarray], formats: dict[str, str] | None = None,
              t_origin_us: int = 0, t_text: list[str] | None = None) -> None:
    """Write equal-length 1-D arrays as a CSV with a header; NaN becomes an empty field.
    The time column t_s is written to the microsecond, exactly (t_origin_us added back:
    Session.t_origin_us), whatever its magnitude: %.9g would keep whole seconds of an epoch
    stamp; or, with t_text, as those strings (another file's stamps, digit for digit)."""
    from .csvtable import CHUNK_ROWS

    names = list(columns)
    arrays = [np.asarray(columns[n], float) for n in names]
    n = len(arrays[0]) if arrays else 0
    if any(len(a) != n for a in arrays) or (t_text is not None and len(t_text) != n):  # zip would cut without a word
        raise ValueError(f"{path.name}: columns of unequal length " + ", ".join(f"{nm} {len(a)}" for nm, a in zip(names, arrays)))
    formats = formats or {}
    fmts = [formats.get(nm, "{:.9g}") for nm in names]
    exact_t = [nm == "t_s" and nm not in formats and bool(np.all(np.isfinite(a))) for nm, a in zip(names, arrays)]
    with open(path, "w", newline="") as fh:
        fh.write(",".join(names) + "\n")
        # In chunks: the text of a whole long log (millions of rows) would cost GBs at once.
        for i0 in range(0, n, CHUNK_ROWS):
            cols = []
            for a, f, ex in zip(arrays, fmts, exact_t):
                part = a[i0:i0 + CHUNK_ROWS]
                if ex and t_text is not None:
                    cols.append(t_text[i0:i0 + CHUNK_ROWS])
                elif ex:
                    cols.append([format_us(u) for u in (time_us(part) + int(t_origin_us)).tolist()])
                else:
                    cols.append(["" if not math.isfinite(x) else f.format(x) for x in part.tolist()])
            fh.write("".join(",".join(row) + "\n" for row in zip(*cols)))


# --------------------------------------------------------------------------- JSON
MAX_JSON_BYTES = 16 << 20  # a session.json or calibration is a few kB; refuse junk early


def read_json(path: Path, what: str = "JSON file"):
    """Read and parse a small JSON file a user gave. Errors: InputError naming the file (and
    line) for a missing, unreadable, oversized, non-UTF-8, malformed or too deeply nested file."""
    from .inputfile import check_input_file

    path = Path(path)
    check_input_file(path, what)  # a pipe or a device is refused before it is opened
    try:
        raw = path.read_bytes() if path.stat().st_size <= MAX_JSON_BYTES else None
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except IsADirectoryError:
        raise InputError(path, f"is a folder, not a {what}") from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}; check the permissions") from None
    if raw is None:
        raise InputError(path, f"larger than {MAX_JSON_BYTES >> 20} MiB: not a {what}")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise InputError(path, f"not UTF-8 text (byte {e.start}): not a {what}", line) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(path, f"invalid JSON: {e.msg}", e.lineno) from None
    except RecursionError:
        raise InputError(path, f"JSON nested too deeply: not a {what}") from None

_EXPECT = {float: "a finite number", dict: "a JSON object", str: "a string", list: "a list"}


def json_kind(v) -> str:
    """What a JSON value is, as a user reads it: 'a string "x"', 'a list [1, 2]', 'null'."""
    if v is None:
        return "null"
    kind = ("a boolean" if isinstance(v, bool) else
            {dict: "an object", list: "a list", str: "a string"}.get(type(v), "a number"))
    return f"{kind} {json.dumps(v)[:40]}"


def _get(d: dict, key: str, path: Path, where: str, kind=None, expect: str | None = None):
    """d[key], refused with one line naming the key (where + key), what it must be (expect, or
    the JSON type of kind) and what it is."""
    what = expect or _EXPECT.get(kind)
    if not isinstance(d, dict) or key not in d:
        raise InputError(path, f"missing key {where}{key}" + (f": expected {what}" if what else ""))
    v = d[key]
    if kind is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputError(path, f"{where}{key} must be {what}, got {json_kind(v)}")
        return float(v)
    if kind is not None and not isinstance(v, kind):
        raise InputError(path, f"{where}{key} must be {what}, got {json_kind(v)}")
    return v


def _matrix(v, shape, path: Path, name: str) -> np.ndarray:
    what = "finite numbers, a list of 3 lists of 3" if shape == (3, 3) else f"finite numbers, a list of {shape[0]}"
    try:
        if isinstance(v, (bool, str, dict)) or any(isinstance(x, (bool, str)) for x in np.ravel(np.asarray(v, dtype=object))):
            raise ValueError  # float() would take "1.5" and True
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise InputError(path, f"{name} must be {what}, got {json_kind(v)}") from None
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise InputError(path, f"{name} must be {what}, got {json_kind(v)}")
    return a


def parse_meta(d: dict, path: Path) -> dict[str, Any]:
    """Validate a session.json dict; returns the typed pieces for Session(**...)."""
    if not isinstance(d, dict):
        raise InputError(path, "session.json must hold a JSON object")
    fmt = d.get("format")
    if fmt != FORMAT:
        raise InputError(path, f"format is {fmt!r}, expected {FORMAT!r}")
    unit = _get(_get(d, "actuator", path, "", dict), "unit", path, "actuator.", expect="'mm' or 'deg'")
    if unit not in ACTUATOR_UNITS:
        raise InputError(path, f"actuator.unit must be one of {ACTUATOR_UNITS}, got {unit!r}")
    kind = _get(_get(d, "distal", path, "", dict), "kind", path, "distal.", expect="'image' or 'angle'")
    if kind not in DISTAL_KINDS:
        raise InputError(path, f"distal.kind must be one of {DISTAL_KINDS}, got {kind!r}")
    r = _get(d, "robot", path, "", dict)
    model = _get(r, "model", path, "robot.", expect="'constant_curvature'")
    if model != "constant_curvature":
        raise InputError(path, f"robot.model {model!r} not supported (only 'constant_curvature')")
    robot = Robot(model, _get(r, "bend_length_mm", path, "robot.", float),
                  _get(r, "tip_length_mm", path, "robot.", float), _get(r, "q_per_rad", path, "robot.", float))
    if robot.q_per_rad == 0 or robot.bend_length_mm <= 0:
        raise InputError(path, "robot.q_per_rad must be non-zero and robot.bend_length_mm positive")
    out: dict[str, Any] = {"actuator_unit": unit, "distal_kind": kind, "robot": robot}
    q_source = d["actuator"].get("q_source", "measured")
    if not isinstance(q_source, str):
        raise InputError(path, f"actuator.q_source must be 'measured' or 'command', got {json_kind(q_source)}")
    if q_source not in Q_SOURCES:
        raise InputError(path, f"actuator.q_source must be one of {Q_SOURCES}, got {q_source!r}")
    out["q_source"] = q_source
    if "camera" in d or kind == "image":
        c = _get(d, "camera", path, "", dict)
        K = _matrix(_get(c, "K", path, "camera.", expect="a 3x3 list of numbers"), (3, 3), path, "camera.K")
        dist = _matrix(c.get("dist", [0, 0, 0, 0, 0]), (5,), path, "camera.dist")
        w, h_px = _get(c, "width", path, "camera.", float), _get(c, "height", path, "camera.", float)
        if not (1 <= w <= MAX_IMAGE_PX and 1 <= h_px <= MAX_IMAGE_PX) or w != int(w) or h_px != int(h_px):
            raise InputError(path, f"camera.width and camera.height must be whole pixels in 1..{MAX_IMAGE_PX}, "
                             f"got {w!r} x {h_px!r}")
        out["camera"] = Camera(int(w), int(h_px), _get(c, "fps", path, "camera.", float), K, dist)
        if not 0 < out["camera"].fps <= MAX_FPS:
            raise InputError(path, f"camera.fps must be in (0, {MAX_FPS:g}] Hz, got {out['camera'].fps!r}")
        check_camera(out["camera"], path)
    if "hand_eye" in d or kind == "image":
        h = _get(d, "hand_eye", path, "", dict)
        R = _matrix(_get(h, "R", path, "hand_eye.", expect="a 3x3 list of numbers"), (3, 3), path, "hand_eye.R")
        with np.errstate(all="ignore"):  # huge entries overflow: then not a rotation either
            rotation = bool(np.allclose(R @ R.T, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0)
        if not rotation:
            raise InputError(path, "hand_eye.R is not a rotation matrix")
        out["hand_eye"] = HandEye(R, _matrix(_get(h, "t_mm", path, "hand_eye.", expect="a list of 3 numbers"), (3,), path, "hand_eye.t_mm"))
    if d.get("t_delay_s") is not None:
        out["t_delay_s"] = _get(d, "t_delay_s", path, "", float)
        if not 0 <= out["t_delay_s"] <= MAX_T_DELAY_S:
            raise InputError(path, f"t_delay_s {out['t_delay_s']!r} s outside [0, {MAX_T_DELAY_S:g}] s (the delay "
                             "from capture to time stamp of the camera or angle sensor)")
    known = {"format", "actuator", "distal", "robot", "camera", "hand_eye", "t_delay_s"}
    out["meta"] = {k: v for k, v in d.items() if k not in known}
    return out


# --------------------------------------------------------------------------- camera sanity
MAX_IMAGE_PX = 100_000   # px per side: beyond any sensor, and keeps the corner radius finite
MAX_FPS = 100_000.0      # Hz
MAX_FOV_DEG = 179.0      # deg across the image's larger side: a fisheye's is up to ~200 only with
                         # its own model, which the pinhole + radial model here is not
MAX_T_DELAY_S = 10.0     # s: the acquisition delay range calibrate --t-delay takes


def check_camera(cam: Camera, path) -> None:
    """Refuse a camera that cannot be an OpenCV pinhole + distortion model of this image.

    K must be an intrinsic matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0 (so
    invertible; finiteness is checked by the reader). The radial part of the distortion,
    r_d = r (1 + k1 r^2 + k2 r^4 + k3 r^6) in normalised coordinates (OpenCV's model,
    the one the simulator renders and the estimator inverts), must be strictly increasing
    from r = 0 until it reaches the image's farthest corner: where dr_d/dr <= 0 two scene
    points land on one pixel (the image folds) and no inverse exists. The tangential p1, p2
    do not fold an image of usual size and are not checked. Errors: InputError(path, one line).
    """
    K = np.asarray(cam.K, float)
    fx, fy = K[0, 0], K[1, 1]
    if not (fx > 0 and fy > 0) or np.any(np.abs(K[1, :1]) > 1e-9) or np.any(np.abs(K[2] - [0, 0, 1]) > 1e-9):
        raise InputError(path, f"camera.K is singular or not an intrinsic matrix (need fx > 0, fy > 0 and rows "
                         f"[0, fy, cy], [0, 0, 1]; got fx {fx:g}, fy {fy:g}, last row {K[2].tolist()})")
    # A focal length that gives a field of view of MAX_FOV_DEG or more across the image is not
    # a lens (fx = 1e-9 px would put the whole half-space into one pixel).
    f_min = max(cam.width, cam.height) / 2 / math.tan(math.radians(MAX_FOV_DEG / 2))
    if fx < f_min or fy < f_min:
        raise InputError(path, f"camera.K focal lengths fx {fx:g} px, fy {fy:g} px give a field of view of "
                         f"{MAX_FOV_DEG:g} deg or more over a {cam.width}x{cam.height} image (need >= {f_min:.3g} px); "
                         "check the calibration's units (px)")
    cx, cy = K[0, 2], K[1, 2]
    k1, k2, _, _, k3 = (float(x) for x in np.asarray(cam.dist, float))
    # Normalised radius of the farthest image corner (skew ignored: it only shears).
    r_corner = max(math.hypot((u - cx) / fx, (v - cy) / fy) for u in (0, cam.width) for v in (0, cam.height))
    if not math.isfinite(r_corner) or r_corner <= 0:
        raise InputError(path, "camera.K puts the principal point at an infinite distance from the image")
    r = np.linspace(0.0, 4.0 * r_corner, 4001)
    with np.errstate(all="ignore"):  # absurd coefficients or a principal point ~1e154 px off overflow: NaN/inf below count as a fold
        r2 = r * r
        rd = r * (1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3)
        drd = 1 + 3 * k1 * r2 + 5 * k2 * r2 ** 2 + 7 * k3 * r2 ** 3
    reach = np.nonzero(np.isfinite(rd) & (rd >= r_corner))[0]
    end = int(reach[0]) if reach.size else r.size - 1  # samples up to the corner (or all of them)
    bad = np.nonzero(~(np.isfinite(drd[: end + 1]) & (drd[: end + 1] > 0)))[0]
    if bad.size or not reach.size:
        r_fold = float(r[bad[0]]) if bad.size else float(r[int(np.nanargmax(np.where(np.isfinite(rd), rd, -np.inf)))])
        raise InputError(path, f"camera.dist (k1 {k1:g}, k2 {k2:g}, k3 {k3:g}) folds the image: the radial model "
                         f"stops increasing at normalised radius {r_fold:.3g}, before the image corner "
                         f"({r_corner:.3g}); recalibrate the camera or check the coefficients' order "
                         "(OpenCV: k1 k2 p1 p2 k3)")


# --------------------------------------------------------------------------- load / write
def load_session(folder: str | os.PathLike, progress=None) -> Session:
    """Load and validate a session folder; the encoder log thinned by thin_record.
    progress: a tqdm-like factory for a bar while a large CSV is read, or None.

    Errors: InputError naming the file (and row for CSV content): missing folder or file,
    bad JSON, unknown format, NaN/empty/non-numeric fields, non-increasing time, missing
    distal data for the declared kind.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, "is not a folder (a session is a folder holding session.json)" if folder.exists()
                         else "session folder not found")
    jpath = folder / "session.json"
    d = read_json(jpath, "session.json")
    kw = parse_meta(d, jpath)
    notes: list[str] = []
    found: dict[str, list] = {}  # table name -> [the TimeText read_csv appends]

    def tt(name: str) -> list:
        return found.setdefault(name, [])

    enc = read_csv(folder / "encoder.csv", ["t_s", "q"], ["q_cmd"], notes=notes, time_text=tt("encoder"),
                   progress=progress)
    if len(enc["t_s"]) < 2:
        raise InputError(folder / "encoder.csv", "fewer than two samples")
    check_range(enc, "q", folder / "encoder.csv", notes, q_limit(), kw["actuator_unit"])
    s = Session(encoder=enc, path=folder, notes=notes, **kw)
    if kw["distal_kind"] == "angle":
        s.distal = read_csv(folder / "distal.csv", ["t_s", "c_deg"], nullable={"c_deg"}, notes=notes,
                            time_text=tt("distal"), progress=progress)
        check_range(s.distal, "c_deg", folder / "distal.csv", notes, MAX_ABS_C_DEG, "deg")
        s.distal = _noted(drop_held(s.distal, ["c_deg"], folder / "distal.csv"), notes)
    else:
        if (folder / "marker.csv").is_file():
            s.marker = read_csv(folder / "marker.csv", ["t_s", "u_px", "v_px"], nullable={"u_px", "v_px"}, notes=notes,
                                time_text=tt("marker"))
            s.marker = _noted(drop_held(s.marker, ["u_px", "v_px"], folder / "marker.csv"), notes)
            if np.any(np.isnan(s.marker["u_px"]) != np.isnan(s.marker["v_px"])):
                k = int(np.nonzero(np.isnan(s.marker["u_px"]) != np.isnan(s.marker["v_px"]))[0][0])
                raise InputError(folder / "marker.csv", "u_px and v_px must be both present or both empty", k + 2)
        videos = sorted(p for p in folder.glob("video.*") if p.suffix.lower() in VIDEO_SUFFIXES)
        if videos:
            s.video = videos[0]
            s.frames = read_csv(folder / "frames.csv", ["frame", "t_s"], time_text=tt("frames"))
        if s.marker is None and s.video is None:
            raise InputError(folder / "marker.csv", "file not found (and no video.* with frames.csv)")
    if (folder / "truth.csv").is_file():
        s.truth = read_csv(folder / "truth.csv", ["t_s", "c_deg"], time_text=tt("truth"))
    time_origin(s, {name: lst[0] for name, lst in found.items() if lst})
    fps = s.camera.fps if s.camera is not None else None
    for name in RECORD_TABLES:
        if getattr(s, name) is not None:
            check_time_unit(getattr(s, name)["t_s"], folder / f"{name}.csv", fps if name in ("marker", "frames") else None)
    check_overlap(s, folder)
    if s.truth is not None and s.truth["t_s"].size and (s.truth["t_s"][0] > s.encoder["t_s"][-1]
                                                        or s.truth["t_s"][-1] < s.encoder["t_s"][0]):
        notes.append(f"{folder / 'truth.csv'}: its stamps ({s.truth['t_s'][0]:.6g} .. {s.truth['t_s'][-1]:.6g} s from "
                     f"the record's first sample) do not overlap encoder.csv's ({s.encoder['t_s'][0]:.6g} .. "
                     f"{s.encoder['t_s'][-1]:.6g} s): ground truth on another clock, not comparable with the record")
    for name, tab in (("encoder.csv", s.encoder), ("distal.csv", s.distal), ("marker.csv", s.marker),
                      ("frames.csv", s.frames)):
        if tab is not None:
            check_span(tab, folder / name, notes)
    check_image_size(s, folder, notes)
    return thin_record(s, folder / "encoder.csv")


def check_image_size(s: Session, folder: Path, notes: list[str]) -> None:
    """Note (a warning line) frames of another size than session.json's camera: the video's
    own size (its header, no frame decoded), and marker.csv positions outside the camera's
    image. K and the distortion are stated for camera.width x camera.height, so such a
    marker is calibrated in another camera's pixels."""
    if s.camera is None:
        return
    W, H = s.camera.width, s.camera.height
    if s.video is not None and s.video.is_file():
        import cv2

        cap = cv2.VideoCapture(str(s.video))
        try:
            vw, vh = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        finally:
            cap.release()
        if vw > 0 and vh > 0 and (vw, vh) != (W, H):
            notes.append(f"{s.video}: frames are {vw}x{vh} px but session.json says camera {W}x{H}: the marker is "
                         "calibrated in another camera's pixels; fix camera.width/height (and K) or the video")
            return
    if s.marker is not None:
        u, v = s.marker["u_px"], s.marker["v_px"]
        out = np.isfinite(u) & ((u < -0.5) | (u > W - 0.5) | (v < -0.5) | (v > H - 0.5))
        if out.any():
            k = int(np.nonzero(out)[0][0])
            notes.append(f"{folder / 'marker.csv'}: {int(out.sum())} marker position(s) outside the {W}x{H} px image "
                         f"session.json's camera has, the first ({u[k]:.1f}, {v[k]:.1f}) px at t = {s.marker['t_s'][k]:.3f} s: "
                         "tracked in frames of another size? fix camera.width/height (and K)")


def thin_record(s: Session, enc_path) -> Session:
    """The one thinning of every record read (a session folder, a recording file read in place):
    s.encoder by thin_encoder, in place, its note appended to s.notes. enc_path names the
    encoder log in the note. An image session's log is thinned by time, to ENCODER_MAX_HZ
    (thin_encoder_by_time): its onsets are timed against the frames (eq. 1 reads q at t2 - t_delay,
    and the record model runs the play on a grid at the log's median rate), so its samples must
    stay uniform in time; the rest by travel. Returns s."""
    if s.distal_kind == "image":
        s.encoder, note = thin_encoder_by_time(s.encoder, enc_path)
    else:
        s.encoder, note = thin_encoder(s.encoder, enc_path)
    if note:
        s.notes.append(note)
    return s


# Encoder logs denser than ENCODER_MAX_HZ are thinned at load by motor travel (thin_encoder), not
# by time: the model is rate-independent (the play, the PI operators and the relaxation see only
# q's path), so what a log must keep is the path, and a dense log's cost is its samples (the
# calibration holds a few kB per encoder sample, and a real encoder's noise makes nearly every
# sample a turning point of the transition fit's reduced path: a 1-hour 1 kHz log kept at 500 Hz
# took 269 s and 4.2 GB, bench/bench_long_log.py). ENCODER_MAX_HZ, the trigger, is the rate the
# method is validated at (the simulator's default; the catheter logs are ~500 Hz): logs at or
# below it are read whole, as before. THIN_TRAVEL_FRAC, of q's travel span, is the path's
# resolution delta: a fifth of the reversal detection's default hysteresis (calibration.calibrate:
# 1 % of the travel; a turn smaller than that is no reversal to the chain) and a few encoder
# counts on the instruments here (5.5 mm catheter travel: 11 um, 2-4 % of its play; the
# endoscope's +-60 deg command: 0.24 deg, about 1 % of its play). A log the rule would not
# shorten by THIN_MIN_GAIN is left whole (nothing to gain).
ENCODER_MAX_HZ = 500.0
THIN_TRAVEL_FRAC = 0.002
THIN_MIN_GAIN = 2.0


def _median_dt_above(t: np.ndarray, max_hz: float) -> float | None:
    """The log's median sample period (s) when its rate is above max_hz (1 % margin) and it has
    3 samples or more; else None (a log thin_encoder and thin_encoder_by_time leave whole)."""
    if t.size < 3:
        return None
    dt = float(np.median(np.diff(t)))
    return dt if dt > 0 and 1.0 / dt > max_hz * 1.01 else None


def thin_encoder(enc: dict, path, frac: float = THIN_TRAVEL_FRAC,
                 max_hz: float = ENCODER_MAX_HZ) -> tuple[dict, str | None]:
    """When the log's median rate is above max_hz, keep the samples its path needs at resolution
    delta = frac x q's travel span: z, q through a dead band of half-width delta (_band: encoder
    noise below delta stays inside it and moves z not at all), and kept are the first and last
    samples, every turning point of z (the extremum of q on each turn beyond 2 delta, the sample
    itself and, when q holds it, the hold's last sample: reversals keep their t1 and q1 exactly,
    fit.reversals.detect_reversals) and the first sample in each new delta cell of z
    (one sample per delta of travel while q moves). Between kept samples q stays within 3 delta
    of the line through them (within delta plus the noise while it moves steadily), and a hold
    keeps no sample. A log the rule would shorten by less than THIN_MIN_GAIN is returned
    unchanged (as are logs of fewer than 3 samples or without travel). Every column of enc is
    kept at the same rows. Returns (table, note naming path, or None)."""
    q, t = np.asarray(enc["q"], float), np.asarray(enc["t_s"], float)
    n = q.size
    span = float(np.ptp(q)) if n else 0.0
    dt = _median_dt_above(t, max_hz)
    if dt is None or not span > 0:
        return enc, None
    d = frac * span
    z = _band(q, d)
    keep = _turns(q, z)
    keep[0] = keep[-1] = True
    cell = np.floor((z - z[0]) / d)
    keep[1:] |= cell[1:] != cell[:-1]
    kept = int(keep.sum())
    if kept * THIN_MIN_GAIN > n:
        return enc, None
    note = (f"{path}: a {1 / dt:.0f} Hz encoder log, thinned by travel at load: one sample per {d:.3g} of q ({frac:.1%} of its "
            f"{span:.4g} travel) and every turn, {kept} of {n} rows kept (session.thin_encoder)")
    return {k: np.asarray(v)[keep] for k, v in enc.items()}, note


def _turns(q: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The samples (bool (N,)) where the banded path z (`_band` of q) turns: q's extremum of each
    turn (where z turns) and its last sample on that value before z moves again (a held
    extremum's end, which detect_reversals takes as t1)."""
    keep = np.zeros(q.size, bool)
    dz = np.diff(z)
    moved = np.flatnonzero(dz)
    if moved.size > 1:
        sgn = np.sign(dz[moved])
        i = np.flatnonzero(sgn[1:] != sgn[:-1])
        for a, b in zip((moved[i] + 1).tolist(), (moved[i + 1] + 1).tolist()):
            # z turns at a and moves again after b - 1: q's extremum of the turn is q[a]; keep
            # its last sample in [a, b) too, as detect_reversals takes it (a held extremum's end).
            keep[a] = keep[a + int(np.flatnonzero(q[a:b] == q[a])[-1])] = True
    return keep


def thin_encoder_by_time(enc: dict, path, max_hz: float = ENCODER_MAX_HZ,
                         frac: float = THIN_TRAVEL_FRAC) -> tuple[dict, str | None]:
    """Keep the first sample of each 1/max_hz bin of time (from the session's first stamp), and
    every turn of q's path at resolution frac x its travel span (`_turns`, as thin_encoder keeps
    them), when the log's median rate is above max_hz; else enc unchanged. Returns (table, note).
    2 ms at 500 Hz is 1/20 of a 25 fps frame, the resolution the onsets are seen at. Why the turns
    too: eq. 1 measures from the reversal's q1, and a sharp reversal's extremum falls between the
    bins' first samples half the time, lower by up to the speed times a bin: on a 30 fps triangle
    of 89 ms legs (10 mm/s; swing_render, LOCKBOX6_300's s6-swing-018) B came out 5.7 % off with
    the bins alone and 0.3 % from the whole log. The record model puts each kept extremum back on
    its uniform grid (onset_model.make_record)."""
    t = enc["t_s"]
    dt = _median_dt_above(t, max_hz)
    if dt is None:
        return enc, None
    bins = np.floor(t * max_hz).astype(np.int64)
    keep = np.r_[True, bins[1:] != bins[:-1]]
    q = np.asarray(enc["q"], float)
    span = float(np.ptp(q))
    if span > 0:
        keep |= _turns(q, _band(q, frac * span))
    note = (f"{path}: a {1 / dt:.0f} Hz log, thinned to {max_hz:.0f} Hz at load (the first sample of each "
            f"{1000 / max_hz:g} ms and every turn: {int(keep.sum())} of {t.size} rows kept)")
    return {k: np.asarray(v)[keep] for k, v in enc.items()}, note


def _band(q: np.ndarray, d: float) -> np.ndarray:
    """q through a dead band of half-width d from q[0]: z[k] = min(q[k] + d, max(q[k] - d, z[k-1]))
    (a play operator of width 2 d; written here, not imported from fit.model or base.kernels,
    because the readers, the simulator's generators among them, share no code with the fitter).
    Sequential; Python floats (~1 s for 3.6 M samples)."""
    out, p = [0.0] * q.size, float(q[0])
    for k, x in enumerate(q.tolist()):
        p = min(x + d, max(x - d, p))
        out[k] = p
    return np.asarray(out)


# Time units of stamps: seconds per unit (import --time-unit; session files hold seconds).
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
TIME_UNIT_NAMES = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}
PER_SECOND = {"s": "1", "ms": "1000", "us": "1e6", "ns": "1e9"}
# A log sampled more slowly than once a second shows no onset (swings last 0.25-0.5 s): a median
# step above this, read as seconds, is stamps in a smaller unit.
MAX_STEP_S = 1.0
# A camera stream whose median step is this many frame periods (camera.fps) is not in seconds.
MAX_STEP_FRAMES = 10.0


def guess_time_unit(step: float, fps: float | None = None) -> str | None:
    """The unit ("ms", "us", "ns") in which a median step of ``step`` (file units) is a plausible
    sample spacing: with a stated frame rate, the unit putting step nearest one frame period
    (within a factor 10); without one, the largest unit giving a step of at most MAX_STEP_S.
    None when no unit fits."""
    if fps:
        best = min(("ms", "us", "ns"), key=lambda u: abs(math.log10(step * TIME_UNITS[u] * fps)))
        return best if abs(math.log10(step * TIME_UNITS[best] * fps)) < 1 else None
    for u in ("ms", "us", "ns"):
        if step * TIME_UNITS[u] <= MAX_STEP_S:
            return u
    return None


def check_time_unit(t_s: np.ndarray, path, fps: float | None = None, scale: float = 1.0,
                    fix: str | None = None) -> None:
    """Refuse stamps whose spacing says they are not seconds (times scale): a median step above
    MAX_STEP_FRAMES frame periods of fps when the rate is stated (camera), else above MAX_STEP_S.
    The one-line InputError names the unit the spacing suggests and fix(unit) -> how to pass it
    (default: the session-file remedy)."""
    t = np.asarray(t_s, float)
    if t.size < 2:  # two rows already have a step (a 2-row log of ns stamps is no session either)
        return
    step = float(np.median(np.diff(t)))
    if not (step > 0 and math.isfinite(step)):
        return
    limit, why = ((MAX_STEP_FRAMES / fps, f"{step * fps:.4g} frame periods at camera.fps {fps:g}") if fps
                  else (MAX_STEP_S, f"{1 / step:.3g} samples/s, too slow for any log this method reads"))
    if step <= limit:
        return
    unit = guess_time_unit(step / scale, fps)
    if unit is None:
        raise InputError(path, f"the time stamps step by a median of {step:.6g} s ({why}): not seconds, and no "
                         "unit among ms, us, ns fits either; check the time column")
    rate = 1 / (step / scale * TIME_UNITS[unit])
    how = fix(unit) if fix else (f"session files hold seconds: divide t_s by {PER_SECOND[unit]} (or import "
                                 f"the log with `playscope import --time-unit {unit}`)")
    raise InputError(path, f"the time stamps step by a median of {step:.6g} s ({why}): they look like "
                     f"{TIME_UNIT_NAMES[unit]} (a {rate:.4g} Hz stream); {how}")


# A bending angle beyond ten turns is a corrupt reading, not a pose (an unwrapped multi-turn
# sensor stays far below it on a continuum section).
MAX_ABS_C_DEG = 3600.0
# The board counts time in uint32 microseconds from the session's first stamp.
MAX_SPAN_US = 2**32 - 1


def q_limit() -> float:
    """|q| (actuator units) the board's int32 Q format holds: (2^(31 - PS_FRAC_BITS) - 1),
    PS_FRAC_BITS taken from common/ps_fixed.h through the native loader, never retyped."""
    from ..base.native import core

    _, lib = core()
    return float((1 << (31 - lib.PS_FRAC_BITS)) - 1)


def _row(k: int, path, notes: list[str]) -> int | None:
    """The file row of table index k, when the loader dropped no row of that file."""
    return None if any(n.startswith(f"{path}:") for n in notes) else k + 2


def check_range(tab: dict, col: str, path, notes: list[str], limit: float, unit: str) -> None:
    """Refuse (InputError naming file and row) a value of tab[col] beyond +-limit (NaN = lost
    is left to the caller's rules)."""
    v = tab[col]
    with np.errstate(invalid="ignore"):
        bad = np.nonzero(np.abs(v) > limit)[0]
    if bad.size:
        k = int(bad[0])
        raise InputError(path, f"{col} = {v[k]:.6g} {unit} at t_s = {tab['t_s'][k]:.9g} s is beyond +-{limit:g} "
                         f"{unit} ({bad.size} such row(s)): a corrupt value or the wrong unit/column", _row(k, path, notes))


def check_span(tab: dict, path, notes: list[str]) -> None:
    """Refuse a stream reaching beyond the board's uint32 us clock (71.6 min) from the record's
    first sample (tab's t_s rebased by time_origin), stating the record's duration and naming
    the row after the largest gap: one corrupt stamp (1e9 s) looks exactly like that."""
    t = tab["t_s"]
    if t.size == 0 or t[-1] * 1e6 <= MAX_SPAN_US:
        return
    gaps = np.diff(t) if t.size > 1 else np.array([t[0]])
    k = int(np.argmax(gaps)) + 1 if t.size > 1 else 0
    raise InputError(path, f"the record lasts {t[-1]:.6g} s ({t[-1] / 60:.4g} min) from its first sample to this "
                     f"file's last, beyond the {MAX_SPAN_US / 6e7:.1f} min the board's clock holds; the largest "
                     f"gap is {gaps.max():.6g} s before t_s = {t[k]:.9g} s (a corrupt time stamp there?); otherwise "
                     "split the recording", _row(k, path, notes))


def check_overlap(s: "Session", folder: Path) -> None:
    """Refuse record streams that do not overlap in time (after time_origin): two clocks, or one
    file shifted, which no delay estimate can join. Names both files and their spans."""
    spans = [(n, getattr(s, n)["t_s"]) for n in RECORD_TABLES
             if getattr(s, n) is not None and getattr(s, n)["t_s"].size]
    for i, (a, ta) in enumerate(spans):
        for b, tb in spans[i + 1:]:
            if ta[0] > tb[-1] or tb[0] > ta[-1]:
                (x, tx), (y, ty) = ((a, ta), (b, tb)) if ta[0] > tb[-1] else ((b, tb), (a, ta))
                raise InputError(folder / f"{x}.csv", f"its stamps ({tx[0]:.6g} .. {tx[-1]:.6g} s from the "
                                 f"record's first sample) begin after {y}.csv's end ({ty[0]:.6g} .. {ty[-1]:.6g} s): "
                                 "the files do not overlap in time; were they stamped by two clocks, or one file "
                                 "shifted? give both the same clock")


def time_us(t) -> np.ndarray:
    """Time stamps in s (float64) -> int64 microseconds, rounded to the nearest. Exact for
    decimal stamps with at most 6 decimals below 2^31 s (an epoch stamp of 1.7e9 s is held
    to 1.2e-7 s by float64; x 1e6 adds <= 0.125, so the rounding recovers the decimal's us)."""
    return np.round(np.asarray(t, dtype=np.float64) * 1e6).astype(np.int64)


# Streams that make up the record (what a sensor measured); truth.csv is the simulator's
# ground truth, rebased with them but never their origin.
RECORD_TABLES = ("encoder", "distal", "marker", "frames")


def time_origin(s: "Session", texts: dict[str, TimeText] | None = None) -> "Session":
    """Make every t_s of s relative to the record's first sample (the earliest first row of
    encoder, distal, marker, frames; truth.csv follows them), in place, quantised to 1 us;
    s.t_origin_us keeps the files' time of that sample (integer us). The same motion then
    gives bit-identical times, hence the same calibration, whatever the clock's origin (0, a
    device uptime, an epoch stamp of 1.7e9 s as ROS bags carry).

    How: a record starting at 0 keeps the stamps as parsed (rel = t). Otherwise, with texts
    ({table name: TimeText} from read_csv), each stamp is rebased in decimal from its text,
    rel = float(Decimal(text) - Decimal(origin text)) * scale, so any decimal shift of the
    files gives the same rel, to the last bit, whatever the stamps' digits (float64 seconds at
    1.7e9 s hold only 0.24 us steps: rebasing the parsed floats would carry that rounding).
    The text is held as integers (TimeText.ticks: stamp = ticks / 10^D), not as Python
    objects per row, so a long log's rebase costs a few int64 arrays.
    Without texts (a Session built in memory) the parsed stamps are rebased through integer
    microseconds, exact for stamps of at most 6 decimals below 2^31 s. Then rel is quantised
    to 1 us (round(rel * 1e6) / 1e6); a repeated stamp after the quantisation keeps the last
    row (as regularize_time)."""
    from decimal import Decimal, InvalidOperation

    names = [n for n in RECORD_TABLES + ("truth",) if getattr(s, n) is not None and len(getattr(s, n)["t_s"])]
    rec = [n for n in names if n != "truth"] or names
    if not names:
        return s
    tabs = {n: getattr(s, n) for n in names}
    f0 = min(float(tabs[n]["t_s"][0]) for n in rec)
    rel: dict[str, np.ndarray] | None = None
    origin_us = 0
    if f0 == 0.0:
        rel = {n: np.asarray(tabs[n]["t_s"], float) for n in names}
    elif texts and all(n in texts and "_row" in tabs[n] for n in names) \
            and len({texts[n].scale for n in names}) == 1:
        from .csvtable import _scaled

        ticks: dict[str, tuple[np.ndarray, int]] = {}
        cache: dict[TimeText, tuple | None] = {}
        try:
            for n in names:
                tt = texts[n]
                if tt not in cache:
                    cache[tt] = tt.ticks()
                got = cache[tt]
                rows = tabs[n]["_row"]
                if got is None or got[0].size <= int(rows.max()):
                    raise ValueError
                tk = got[0][rows]
                parsed = np.array([float(x) for x in tk], float) if tk.dtype == object else tk.astype(float)
                parsed = parsed / 10.0 ** got[1] * tt.scale
                if not np.allclose(parsed, np.asarray(tabs[n]["t_s"], float), rtol=1e-15, atol=0.0):
                    raise ValueError  # not the text read_csv parsed: keep to the floats
                ticks[n] = (tk, got[1])
            d_max = max(d for _, d in ticks.values())
            exact = {n: _scaled(tk, np.full(tk.size, d_max - d, np.int64)) for n, (tk, d) in ticks.items()}
            origin = min(int(exact[n][0]) for n in rec)
            scale = texts[names[0]].scale
            rel = {}
            for n in names:
                diff = exact[n] - origin
                if diff.dtype != object and np.all(np.abs(diff) < 2**53):
                    # int64 -> float64 exact below 2^53, 10^d exact: one correctly rounded
                    # division, the same float as float(Decimal(diff) / 10^d)
                    rel[n] = diff.astype(float) / 10.0 ** d_max * scale
                else:  # Python ints: true division is correctly rounded too
                    rel[n] = np.array([int(x) / 10 ** d_max for x in diff], float) * scale
            origin_us = int((Decimal(origin).scaleb(-d_max) * Decimal(repr(scale)) * 1_000_000).to_integral_value())
        except (ValueError, InvalidOperation, OverflowError):
            rel = None
    if rel is not None:
        for n in names:
            _check_us_range(rel[n], texts[n].path if texts and n in texts else None)
        _check_us_range([origin_us / 1e6], texts[rec[0]].path if texts and rec[0] in texts else None, absolute=True)
    else:
        for n in names:
            _check_us_range(tabs[n]["t_s"], texts[n].path if texts and n in texts else None, absolute=True)
    if rel is None:  # in-memory tables: through integer microseconds
        us = {n: time_us(tabs[n]["t_s"]) for n in names}
        origin_us = min(int(us[n][0]) for n in rec)
        rel_us = {n: us[n] - origin_us for n in names}
    else:
        rel_us = {n: np.round(rel[n] * 1e6).astype(np.int64) for n in names}
    for n in names:
        tab, r = tabs[n], rel_us[n]
        tab.pop("_row", None)
        keep = np.r_[r[1:] != r[:-1], True] if r.size > 1 else np.ones(r.size, bool)
        if not keep.all():  # sub-microsecond rows: keep the last of each
            for k in list(tab):
                tab[k] = tab[k][keep]
            r = r[keep]
        tab["t_s"] = r / 1e6
    s.t_origin_us += origin_us
    return s


# Times (s) whose microseconds int64 holds with room to spare (2^62 us, 146 000 years).
MAX_ABS_TIME_S = 2.0**62 / 1e6


def _check_us_range(t, path, absolute: bool = False) -> None:
    """Refuse stamps whose microseconds would overflow int64 (they would all collapse into one
    row): nanosecond or picosecond counts read as seconds. absolute: t are the files' stamps,
    else times from the record's first sample. Errors: InputError naming the file."""
    t = np.asarray(t, float)
    big = float(np.max(np.abs(t))) if t.size else 0.0
    if big > MAX_ABS_TIME_S or not math.isfinite(big):
        what = "the stamps reach" if absolute else "the stamps span"
        raise InputError(path, f"{what} {big:.4g} s: more than int64 microseconds hold; a count of nanoseconds "
                         "read as seconds? (`playscope import --time-unit ns`, or divide t_s by 1e9)")


def _noted(result, notes: list[str]):
    tab, note = result
    if note:
        notes.append(note)
    return tab


def write_session(s: Session, folder: str | os.PathLike, overwrite: bool = False) -> Path:
    """Write ``s`` as a session folder, atomically (temporary folder, then rename).

    Errors: FileExistsError when the folder exists and overwrite is False.
    Returns the folder path. A video is not copied: write_session keeps marker.csv only.
    """
    folder = Path(folder)
    if folder.exists() and not overwrite:
        raise FileExistsError(f"{folder}: exists (use overwrite)")
    with atomic_path(folder) as tmp:
        tmp.mkdir()
        (tmp / "session.json").write_text(json.dumps(s.to_json(), indent=2) + "\n")
        o = s.t_origin_us
        write_csv(tmp / "encoder.csv", s.encoder, t_origin_us=o)
        if s.marker is not None:
            write_csv(tmp / "marker.csv", {k: s.marker[k] for k in ("t_s", "u_px", "v_px")}, t_origin_us=o)
        if s.distal is not None:
            write_csv(tmp / "distal.csv", {k: s.distal[k] for k in ("t_s", "c_deg")}, t_origin_us=o)
        if s.truth is not None:
            write_csv(tmp / "truth.csv", s.truth, t_origin_us=o)
        if s.frames is not None and s.video is not None:
            write_csv(tmp / "frames.csv", s.frames, {"frame": "{:.0f}"}, t_origin_us=o)
    return folder
