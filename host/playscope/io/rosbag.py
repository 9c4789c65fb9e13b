"""Import ROS bags (ROS 1 ``.bag``, ROS 2 sqlite3 or MCAP) into sessions, through ``rosbags``.

Robot logs mostly live in bags. A topic is named on the command line as ``TOPIC[:FIELD]``:
- FIELD is a dotted path into the message with optional indices (``position[1]``,
  ``pose.position.x``) or, for sensor_msgs/JointState, a joint name (``joint=bend``);
- without FIELD: std_msgs Float32/Float64/Int* -> ``data``; JointState -> ``position[0]``.
Time stamps: the message's ``header.stamp`` when it has a non-zero one (the sensor's own
clock), else the bag's receive time. Both are shifted so the first sample of the bag is t = 0.
Rows with a non-finite value are dropped; samples are sorted by time and a repeated time stamp
keeps its last sample (documented choice: the later message is the newer reading). Both counts
are reported in ``ImportReport``.

Image topics (sensor_msgs/Image bgr8/rgb8/mono8 or CompressedImage) become ``video.avi`` +
``frames.csv`` of an image session, to be tracked by ``playscope track``; the robot, camera and
hand-eye come from a geometry file (a session.json), since a bag rarely holds a hand-eye.
"""

from __future__ import annotations

import dataclasses
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.errors import InputError

_FIELD_RE = re.compile(r"^([A-Za-z_]\w*)((?:\[\d+\])*)$")
_DEFAULT_FIELD = {"sensor_msgs/msg/JointState": "position[0]"}


@dataclass
class TopicSpec:
    """One ``TOPIC[:FIELD]`` argument: topic name, field path (or None for the default),
    joint name for JointState selection by name."""

    topic: str
    field: str | None = None
    joint: str | None = None

    @classmethod
    def parse(cls, spec: str) -> "TopicSpec":
        if not spec or not spec.startswith("/"):
            raise ValueError(f"topic {spec!r}: expected /TOPIC[:FIELD], e.g. /joint_states:joint=bend")
        topic, _, fld = spec.partition(":")
        if fld.startswith("joint="):
            return cls(topic, None, fld[len("joint="):])
        if fld:
            for part in fld.split("."):
                if not _FIELD_RE.match(part):
                    raise ValueError(f"topic {spec!r}: field {fld!r} is not a dotted path like pose.position.x or position[1]")
        return cls(topic, fld or None)


@dataclass
class ImportReport:
    """What the import did to each stream: kept rows, dropped non-finite rows, repeated time
    stamps merged, and which clock the time stamps came from."""

    rows: dict = field(default_factory=dict)
    dropped_nonfinite: dict = field(default_factory=dict)
    duplicate_t: dict = field(default_factory=dict)
    clock: dict = field(default_factory=dict)

    def lines(self) -> list[str]:
        out = []
        for k in self.rows:
            s = f"{k}: {self.rows[k]} rows ({self.clock[k]} time stamps)"
            if self.dropped_nonfinite.get(k):
                s += f", {self.dropped_nonfinite[k]} non-finite rows dropped"
            if self.duplicate_t.get(k):
                s += f", {self.duplicate_t[k]} repeated time stamps merged (last kept)"
            out.append(s)
        return out


def _extract(msg, spec: TopicSpec, msgtype: str, path: Path) -> float:
    """The scalar value spec names in msg. Errors: InputError naming the bag and topic."""
    if spec.joint is not None:
        names = list(getattr(msg, "name", []))
        if spec.joint not in names:
            raise InputError(path, f"{spec.topic}: no joint {spec.joint!r} (joints: {', '.join(names)})")
        return float(msg.position[names.index(spec.joint)])
    fld = spec.field or _DEFAULT_FIELD.get(msgtype) or ("data" if hasattr(msg, "data") else None)
    if fld is None:
        raise InputError(path, f"{spec.topic} ({msgtype}): name the field, e.g. {spec.topic}:pose.position.x")
    v = msg
    for part in fld.split("."):
        name, idx = _FIELD_RE.match(part).groups()
        if not hasattr(v, name):
            raise InputError(path, f"{spec.topic} ({msgtype}): no field {name!r} in {fld!r}")
        v = getattr(v, name)
        for i in re.findall(r"\[(\d+)\]", idx):
            try:
                v = v[int(i)]
            except (IndexError, TypeError):
                raise InputError(path, f"{spec.topic} ({msgtype}): index [{i}] out of range in {fld!r}") from None
    try:
        return float(v)
    except (TypeError, ValueError):
        raise InputError(path, f"{spec.topic} ({msgtype}): field {fld!r} is not a number") from None


def _stamp_ns(msg) -> int | None:
    h = getattr(msg, "header", None)
    st = getattr(h, "stamp", None)
    if st is None:
        return None
    ns = int(st.sec) * 1_000_000_000 + int(st.nanosec)
    return ns if ns > 0 else None


def _clean(name: str, t_ns: list, v: list, report: ImportReport, clock: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t_ns, np.int64)
    x = np.asarray(v, float)
    ok = np.isfinite(x)
    report.dropped_nonfinite[name] = int((~ok).sum())
    t, x = t[ok], x[ok]
    order = np.argsort(t, kind="stable")
    t, x = t[order], x[order]
    last = np.append(t[1:] != t[:-1], True)  # keep the last of each run of equal stamps
    report.duplicate_t[name] = int((~last).sum())
    report.rows[name] = int(last.sum())
    report.clock[name] = clock
    return t[last], x[last]


def _open(path: Path):
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:  # pragma: no cover - a dependency of the host package
        raise InputError(path, "the rosbags package is missing (pip install rosbags)") from None
    if not path.exists():
        raise InputError(path, "bag not found (a ROS 1 .bag file or a ROS 2 bag folder)")
    return AnyReader([path])


def read_topics(path, specs: dict[str, TopicSpec], report: ImportReport) -> dict[str, tuple]:
    """Scalar series of each named topic: {name: (t_ns (N,) int64, value (N,) float)}.

    Errors: InputError naming the bag: unreadable bag, missing topic (listing those present),
    a field that is not there or not a number, no sample left."""
    path = Path(path)
    try:
        reader = _open(path)
        with reader:
            conns = {c.topic: c for c in reader.connections}
            for name, sp in specs.items():
                if sp.topic not in conns:
                    raise InputError(path, f"no topic {sp.topic!r} for {name} (topics: {', '.join(sorted(conns))})")
            acc = {name: ([], [], []) for name in specs}
            by_topic = {}
            for name, sp in specs.items():
                by_topic.setdefault(sp.topic, []).append(name)
            wanted = [conns[t] for t in by_topic]
            for conn, t_log, raw in reader.messages(connections=wanted):
                msg = reader.deserialize(raw, conn.msgtype)
                st = _stamp_ns(msg)
                for name in by_topic[conn.topic]:
                    t_list, v_list, clocks = acc[name]
                    t_list.append(st if st is not None else t_log)
                    clocks.append(st is not None)
                    v_list.append(_extract(msg, specs[name], conn.msgtype, path))
    except InputError:
        raise
    except Exception as e:  # rosbags raises its own reader errors for damaged bags
        raise InputError(path, f"cannot read the bag: {type(e).__name__}: {e}") from None
    out = {}
    for name, (t_list, v_list, clocks) in acc.items():
        if not t_list:
            raise InputError(path, f"topic {specs[name].topic!r} ({name}) has no messages")
        clock = "header" if all(clocks) else "receive" if not any(clocks) else "mixed header/receive"
        out[name] = _clean(name, t_list, v_list, report, clock)
        if out[name][0].size < 2:
            raise InputError(path, f"topic {specs[name].topic!r} ({name}): fewer than two usable samples")
    return out


def _raw_image(msg, path: Path, topic: str) -> np.ndarray:
    """sensor_msgs/Image -> BGR uint8 (H, W, 3); rows may be padded (step >= width * channels)."""
    import cv2

    enc = str(msg.encoding)
    ch = {"bgr8": 3, "rgb8": 3, "mono8": 1}.get(enc)
    if ch is None:
        raise InputError(path, f"{topic}: image encoding {enc!r} not supported (bgr8, rgb8, mono8)")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    a = np.frombuffer(bytes(msg.data), np.uint8)
    if a.size < h * step or step < w * ch:
        raise InputError(path, f"{topic}: a frame holds {a.size} bytes, expected {h} rows of {step}")
    img = a[: h * step].reshape(h, step)[:, : w * ch].reshape(h, w, ch)
    if enc == "mono8":
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return img[..., ::-1] if enc == "rgb8" else img


def read_images(path, topic: str, report: ImportReport) -> tuple[np.ndarray, list]:
    """Frames of an image topic: (t_ns (N,) int64, [BGR uint8 arrays]), sorted, repeated stamps
    merged. Errors: InputError for an unknown topic or an encoding that is not bgr8/rgb8/mono8."""
    import cv2

    path = Path(path)
    t, imgs, clocks = [], [], []
    try:
        reader = _open(path)
        with reader:
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns:
                raise InputError(path, f"no image topic {topic!r}")
            bad = [c.msgtype for c in conns if not c.msgtype.endswith(("/Image", "/CompressedImage"))]
            if bad:
                raise InputError(path, f"{topic} is {bad[0]}, not sensor_msgs Image or CompressedImage")
            for conn, t_log, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                if conn.msgtype.endswith("CompressedImage"):
                    img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
                    if img is None:
                        raise InputError(path, f"{topic}: a compressed frame does not decode")
                else:
                    img = _raw_image(msg, path, topic)
                st = _stamp_ns(msg)
                t.append(st if st is not None else t_log)
                clocks.append(st is not None)
                imgs.append(np.ascontiguousarray(img))
    except InputError:
        raise
    except Exception as e:
        raise InputError(path, f"cannot read the bag: {type(e).__name__}: {e}") from None
    if len(t) < 2:
        raise InputError(path, f"image topic {topic!r}: fewer than two frames")
    tt, idx = _clean("frames", t, list(range(len(t))), report, "header" if all(clocks) else "receive")
    return tt, [imgs[int(i)] for i in idx]


def import_bag(path, q: str, c: str | None = None, image: str | None = None, geometry=None,
               unit: str = "mm", q_scale: float = 1.0, c_scale: float = 1.0, q_per_rad: float = 5.0,
               t_delay_s: float | None = None):
    """A bag as a session: (Session, ImportReport, frames or None).

    q, c, image: ``TOPIC[:FIELD]`` specs (module docstring) for the actuator position, the
    distal bending angle (deg after c_scale; an angle session) and the camera (an image
    session, needs ``geometry``: a session.json giving robot, camera and hand_eye). Exactly one
    of c and image. q_scale / c_scale multiply the raw values (e.g. 1e3 for m -> mm,
    180/pi for rad -> deg). frames: (t_ns, images) to be written as video.avi + frames.csv.
    Errors: InputError naming the bag or the geometry file; ValueError for a malformed spec."""
    from .session import Robot, Session, parse_meta, time_origin

    path = Path(path)
    if (c is None) == (image is None):
        raise ValueError("give exactly one distal source: --c-topic (angle sensor) or --image-topic (camera)")
    if image is not None and geometry is None:
        raise InputError(path, "an image session needs --geometry SESSION.json (robot, camera, hand_eye)")
    report = ImportReport()
    specs = {"encoder": TopicSpec.parse(q)}
    if c is not None:
        specs["distal"] = TopicSpec.parse(c)
    series = read_topics(path, specs, report)
    frames = None
    if image is not None:
        frames = read_images(path, image, report)
    t0 = min(v[0][0] for v in series.values())
    if frames is not None:
        t0 = min(t0, frames[0][0])
    # Stamps relative to the first sample in integer ns (exact), the origin kept in whole us
    # (Session.t_origin_us: written back into the files, recorded by calibrate as t_origin_s),
    # as a CSV import keeps it (session.time_origin); t0 is rounded down to the microsecond so
    # relative + origin gives the bag's stamps to the microsecond.
    origin_us = int(t0) // 1000
    t0 = origin_us * 1000
    sec = lambda t_ns: (np.asarray(t_ns, np.int64) - t0) / 1e9  # noqa: E731
    t_q, v_q = series["encoder"]
    enc = {"t_s": sec(t_q), "q": v_q * q_scale}
    meta = {"source": {"bag": str(path), "q": q, "c": c, "image": image}}
    if c is not None:
        t_c, v_c = series["distal"]
        s = Session(actuator_unit=unit, distal_kind="angle", robot=Robot("constant_curvature", 30.0, 0.0, q_per_rad),
                    encoder=enc, distal={"t_s": sec(t_c), "c_deg": v_c * c_scale}, t_delay_s=t_delay_s or 0.0,
                    meta=meta, t_origin_us=origin_us)
        return time_origin(s), report, None
    gpath = Path(geometry)
    try:
        d = json.loads(gpath.read_text())
    except OSError as e:
        raise InputError(gpath, f"cannot read: {e.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise InputError(gpath, f"invalid JSON: {e}") from None
    if not isinstance(d, dict):
        raise InputError(gpath, "expected a JSON object (a session.json)")
    d = dict(d, distal={"kind": "image"}, actuator={"unit": unit})
    kw = parse_meta(d, gpath)
    kw.pop("meta", None)
    if t_delay_s is not None:
        kw["t_delay_s"] = t_delay_s
    t_f = sec(frames[0])
    s = Session(encoder=enc, frames={"frame": np.arange(t_f.size, dtype=float), "t_s": t_f}, meta=meta,
                t_origin_us=origin_us, **kw)
    return time_origin(s), report, frames


def write_bag_session(s, frames, folder, overwrite: bool = False) -> Path:
    """Write the session and, for an image session, its frames as video.avi (MJPG) + frames.csv,
    atomically (the folder appears complete or not at all)."""
    from ..base.atomic import atomic_path
    from .session import write_csv, write_session
    from .videofile import video_writer

    folder = Path(folder)
    if folder.exists() and not overwrite:
        raise FileExistsError(f"{folder}: exists (use --force)")
    with atomic_path(folder) as tmp:
        if frames is None:
            write_session(s, tmp)
            return folder
        s_plain = dataclasses.replace(s, frames=None, video=None)
        write_session(s_plain, tmp)
        imgs = frames[1]
        h, w = imgs[0].shape[:2]
        fps = s.camera.fps if s.camera is not None else 25.0
        with video_writer(tmp / "video.avi", fps, (w, h)) as vw:
            for img in imgs:
                if img.shape[:2] != (h, w):
                    raise InputError(s.meta["source"]["bag"], f"frame size changes within the image topic "
                                     f"({img.shape[1]}x{img.shape[0]} after {w}x{h})")
                vw.write(img)
        write_csv(tmp / "frames.csv", s.frames, {"frame": "{:.0f}"}, t_origin_us=s.t_origin_us)
    return folder


def is_bag(path) -> bool:
    """True for a ROS 1 .bag file, or a folder holding a ROS 2 bag (metadata.yaml, .db3 or .mcap)."""
    p = Path(path)
    if p.is_file():
        return p.suffix in (".bag", ".db3", ".mcap")
    return p.is_dir() and ((p / "metadata.yaml").is_file() or any(p.glob("*.db3")) or any(p.glob("*.mcap")))

