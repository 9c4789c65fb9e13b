"""`playscope import` of ROS bags written here with rosbags' writers: ROS 1, ROS 2 sqlite3, ROS 2 MCAP."""

from __future__ import annotations

import json

import numpy as np
import pytest

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from playscope.cli import main  # noqa: E402
from playscope.io.session import load_session  # noqa: E402

TS2 = get_typestore(Stores.ROS2_HUMBLE)
TS1 = get_typestore(Stores.ROS1_NOETIC)
T0_NS = 1_700_000_000_000_000_000


def _signals(n=200):
    t_ns = T0_NS + np.arange(n, dtype=np.int64) * 10_000_000  # 100 Hz
    q = 2.0 * np.sin(np.arange(n) * 0.05)
    c_rad = np.deg2rad(10.0 * np.sin(np.arange(n) * 0.05 - 0.2))
    return t_ns, q, c_rad


def _msgs(ts, t_ns, q, c, header_stamp=True):
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    JS, F64 = ts.types["sensor_msgs/msg/JointState"], ts.types["std_msgs/msg/Float64"]
    out = []
    for k in range(t_ns.size):
        st = Time(sec=int(t_ns[k] // 10**9), nanosec=int(t_ns[k] % 10**9)) if header_stamp else Time(sec=0, nanosec=0)
        kw = {"seq": k} if "seq" in Header.__dataclass_fields__ else {}
        hdr = Header(stamp=st, frame_id="base", **kw)
        js = JS(header=hdr, name=["roll", "bend"], position=np.array([0.0, q[k]]), velocity=np.zeros(0),
                effort=np.zeros(0))
        out.append((int(t_ns[k]), js, F64(data=float(c[k]))))
    return out


def write_ros2(path, storage, t_ns, q, c, extra=()):
    with Writer2(path, version=9, storage_plugin=storage) as w:
        cj = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=TS2)
        ca = w.add_connection("/tip/angle", "std_msgs/msg/Float64", typestore=TS2)
        for t, js, a in _msgs(TS2, t_ns, q, c):
            w.write(cj, t + 3_000_000, TS2.serialize_cdr(js, "sensor_msgs/msg/JointState"))  # 3 ms transport delay
            w.write(ca, t, TS2.serialize_cdr(a, "std_msgs/msg/Float64"))
        for t, a in extra:
            w.write(ca, t, TS2.serialize_cdr(TS2.types["std_msgs/msg/Float64"](data=a), "std_msgs/msg/Float64"))


def write_ros1(path, t_ns, q, c):
    with Writer1(path) as w:
        cj = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=TS1)
        ca = w.add_connection("/tip/angle", "std_msgs/msg/Float64", typestore=TS1)
        for t, js, a in _msgs(TS1, t_ns, q, c):
            w.write(cj, t, TS1.serialize_ros1(js, "sensor_msgs/msg/JointState"))
            w.write(ca, t, TS1.serialize_ros1(a, "std_msgs/msg/Float64"))


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_bag_to_angle_session(tmp_path, kind, capsys):
    t_ns, q, c = _signals()
    bag = tmp_path / ("run.bag" if kind == "ros1" else "run")
    if kind == "ros1":
        write_ros1(bag, t_ns, q, c)
    else:
        write_ros2(bag, StoragePlugin.SQLITE3 if kind == "sqlite3" else StoragePlugin.MCAP, t_ns, q, c)
    out = tmp_path / "s"
    rc = main(["import", str(bag), "--q-topic", "/joint_states:joint=bend", "--c-topic", "/tip/angle",
               "--c-scale", str(180 / np.pi), "-o", str(out), "--json", str(tmp_path / "r.json")])
    assert rc == 0
    s = load_session(out)
    # JointState carries header stamps: the 3 ms transport delay of the receive time is not in t.
    np.testing.assert_allclose(s.encoder["t_s"], (t_ns - T0_NS) / 1e9, atol=1e-9)
    # encoder.csv keeps 8 decimals (rounding <= 5e-9); joint selected by name, not index 0 (which is 0)
    np.testing.assert_allclose(s.encoder["q"], q, rtol=0, atol=6e-9)
    np.testing.assert_allclose(s.distal["c_deg"], np.rad2deg(c), atol=6e-9)
    notes = json.loads((tmp_path / "r.json").read_text())["streams"]
    assert any("encoder: 200 rows (header" in n for n in notes)
    assert any("distal: 200 rows (receive" in n for n in notes)  # Float64 has no header


def test_repeated_and_nonfinite_samples_are_counted(tmp_path, capsys):
    t_ns, q, c = _signals(50)
    # A slow sensor re-publishing: 5 repeated receive times (newer value kept), 2 NaN readings.
    extra = [(int(t_ns[k]), 99.0) for k in (3, 7, 11, 13, 17)] + [(int(t_ns[-1]) + 5, float("nan"))] * 2
    write_ros2(tmp_path / "b", StoragePlugin.SQLITE3, t_ns, q, c, extra)
    rc = main(["import", str(tmp_path / "b"), "--q-topic", "/joint_states:position[1]", "--c-topic",
               "/tip/angle:data", "-o", str(tmp_path / "s")])
    assert rc == 0
    err = capsys.readouterr().err
    assert "2 non-finite rows dropped" in err and "5 repeated time stamps merged" in err
    s = load_session(tmp_path / "s")
    assert s.distal["t_s"].size == 50
    assert np.all(np.diff(s.distal["t_s"]) > 0)
    assert np.count_nonzero(s.distal["c_deg"] == 99.0) == 5  # the later message of each pair kept


def test_bag_errors_are_one_line(tmp_path, capsys):
    t_ns, q, c = _signals(20)
    write_ros2(tmp_path / "b", StoragePlugin.MCAP, t_ns, q, c)
    cases = [
        (["--q-topic", "/nope", "--c-topic", "/tip/angle"], "no topic '/nope'"),
        (["--q-topic", "/joint_states:joint=wrist", "--c-topic", "/tip/angle"], "no joint 'wrist'"),
        (["--q-topic", "/joint_states:position[5]", "--c-topic", "/tip/angle"], "index [5] out of range"),
        (["--q-topic", "/joint_states:name", "--c-topic", "/tip/angle"], "is not a number"),
        (["--q-topic", "/joint_states"], "exactly one distal source"),
        (["--q-topic", "/joint_states", "--image-topic", "/tip/angle"], "needs --geometry"),
        (["--q-topic", "joint_states", "--c-topic", "/tip/angle"], "expected /TOPIC"),
    ]
    for args, msg in cases:
        rc = main(["import", str(tmp_path / "b"), *args, "-o", str(tmp_path / "s")])
        err = capsys.readouterr().err.strip()
        assert rc == 2, args
        assert msg in err and "\n" not in err, (args, err)
        assert not (tmp_path / "s").exists()
    (tmp_path / "broken.bag").write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 40)
    rc = main(["import", str(tmp_path / "broken.bag"), "--q-topic", "/a", "--c-topic", "/b", "-o", str(tmp_path / "s")])
    assert rc == 2 and "cannot read the bag" in capsys.readouterr().err


def test_image_topic_becomes_a_trackable_video(tmp_path, capsys):
    """An image bag -> video.avi + frames.csv, which `playscope track` turns into marker.csv."""
    import cv2

    W, H = 320, 240
    geo = tmp_path / "geo.json"
    geo.write_text(json.dumps({
        "format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "image"},
        "robot": {"model": "constant_curvature", "bend_length_mm": 20.0, "tip_length_mm": 3.0, "q_per_rad": 4.0},
        "camera": {"width": W, "height": H, "fps": 25.0, "K": [[300, 0, 160], [0, 300, 120], [0, 0, 1]]},
        "hand_eye": {"R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t_mm": [0, 0, 40]}}))
    n = 30
    t_ns = T0_NS + np.arange(n, dtype=np.int64) * 40_000_000  # 25 fps
    us = 0.3 * W + 0.4 * W * np.arange(n) / n
    Img = TS2.types["sensor_msgs/msg/Image"]
    Header, Time = TS2.types["std_msgs/msg/Header"], TS2.types["builtin_interfaces/msg/Time"]
    with Writer2(tmp_path / "cam", version=9) as w:
        ci = w.add_connection("/endoscope/image_raw", "sensor_msgs/msg/Image", typestore=TS2)
        cq = w.add_connection("/motor", "std_msgs/msg/Float64", typestore=TS2)
        for k in range(n):
            img = np.full((H, W, 3), (90, 100, 110), np.uint8)
            cv2.circle(img, (int(us[k]), H // 2), 9, (60, 200, 60), -1, cv2.LINE_AA)
            rgb = np.ascontiguousarray(img[..., ::-1])
            hdr = Header(stamp=Time(sec=int(t_ns[k] // 10**9), nanosec=int(t_ns[k] % 10**9)), frame_id="cam")
            msg = Img(header=hdr, height=H, width=W, encoding="rgb8", is_bigendian=0, step=W * 3,
                      data=rgb.reshape(-1))
            w.write(ci, int(t_ns[k]), TS2.serialize_cdr(msg, "sensor_msgs/msg/Image"))
            for j in range(4):
                tq = int(t_ns[k]) + j * 10_000_000
                w.write(cq, tq, TS2.serialize_cdr(TS2.types["std_msgs/msg/Float64"](data=0.01 * k), "std_msgs/msg/Float64"))
    out = tmp_path / "s"
    rc = main(["import", str(tmp_path / "cam"), "--q-topic", "/motor", "--image-topic", "/endoscope/image_raw",
               "--geometry", str(geo), "-o", str(out)])
    assert rc == 0, capsys.readouterr().err
    s = load_session(out)
    assert s.video is not None and s.frames["t_s"].size == n
    assert main(["track", str(out)]) == 0
    m = load_session(out).marker
    # MJPG and the tracker together: measured worst error 0.09 px here; bound about 3x that.
    np.testing.assert_allclose(m["u_px"], us.astype(int), atol=0.3)
    np.testing.assert_allclose(m["v_px"], H // 2, atol=0.3)


def test_bag_records_its_time_origin(tmp_path, capsys):
    """The bag's epoch stamps are kept as the session's origin (Session.t_origin_us, written back
    into the files; calibrate records it as t_origin_s), as a CSV import keeps it: before, the
    stamps started at 0 and the origin was lost."""
    t_ns, q, c = _signals(50)
    t_ns = t_ns + 123_456_789  # not a whole microsecond: the origin is kept to the us
    write_ros2(tmp_path / "b", StoragePlugin.SQLITE3, t_ns, q, c)
    assert main(["import", str(tmp_path / "b"), "--q-topic", "/joint_states:position[1]", "--c-topic",
                 "/tip/angle:data", "-o", str(tmp_path / "s")]) == 0
    s = load_session(tmp_path / "s")
    assert s.t_origin_us == (int(t_ns[0]) + 500) // 1000  # to the nearest microsecond
    np.testing.assert_allclose(s.encoder["t_s"], (t_ns - t_ns[0]) / 1e9, atol=1e-6)
    first = (tmp_path / "s" / "encoder.csv").read_text().splitlines()[1].split(",")[0]
    assert first == "1700000000.123457"
