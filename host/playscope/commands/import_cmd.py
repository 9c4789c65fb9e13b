"""`playscope import`: a foreign recording (CSV, or a ROS 1/ROS 2 bag) -> a session folder."""

from __future__ import annotations

import argparse
import math
import sys

from . import argtypes as T
from ..base.errors import InputError
from ..io.importer import CATHETER
from .common import warn, add_json_arg, dump_json, progress

EPILOG = """\
examples:
  playscope import data_2_1.txt -o sessions/d21
  playscope import log.csv --t-col 1 --q-col 3 --c-col 4 --time-unit ms --unit deg -o sessions/mine
  playscope import log.csv --t-col stamp --q-col motor_cmd --c-col tip_rad --c-scale 57.29578 \
      --q-source command -o sessions/cmd   (q is the commanded position, angle in rad)
  playscope import run.bag --q-topic /joint_states:joint=bend --c-topic /em_tracker/angle:data \\
      --c-scale 57.29578 -o sessions/run            (angle in rad on the bag -> deg)
  playscope import rosbag2_run/ --q-topic /motor/position --image-topic /endoscope/image_raw \\
      --geometry sessions/sim/session.json -o sessions/cam   (then: playscope track sessions/cam)
A bag is a ROS 1 .bag file or a ROS 2 bag folder (sqlite3 .db3 or MCAP), read with `rosbags`.
TOPIC[:FIELD]: FIELD is a dotted path (pose.position.x, position[1]) or joint=NAME for
sensor_msgs/JointState; default: 'data' for std_msgs numbers, position[0] for JointState.
Time stamps come from header.stamp when present, else the bag's receive time.
"""


def _finite(kind):
    def conv(s: str) -> float:
        v = float(s)
        if not math.isfinite(v) or v == 0:
            raise ValueError
        return v
    conv.__name__ = kind
    return conv


def add_parser(sub) -> None:
    p = sub.add_parser("import", help="bring a CSV recording or a ROS bag into a session folder",
                       description="Map a CSV (with a header row, or without one: columns by number) onto a "
                       "playscope-session/1 angle session (encoder.csv + distal.csv sharing the file's time base), "
                       "or topics of a ROS bag onto an angle or image session. CSV defaults fit the EM-tracked "
                       "catheter set: Time (s), 'Tendon Disp.' (mm) -> q, 'Angle x' (deg) -> c. Every option "
                       "applies to the input given or is refused (docs/your-robot.md walks a CSV through).",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source", help="input CSV file, ROS 1 .bag file or ROS 2 bag folder")
    p.add_argument("-o", "--out", required=True, help="session folder to create")
    g = p.add_argument_group("CSV input")
    g.add_argument("--t-col", help=f"time column: a header name or a 1-based number (default {CATHETER['t']!r}, "
                   "or 1 in a file without a header row)")
    g.add_argument("--q-col", help=f"actuator column: name or number (default {CATHETER['q']!r}, or 2)")
    g.add_argument("--c-col", help=f"bending-angle column, deg after --c-scale: name or number "
                   f"(default {CATHETER['c']!r}, or 3)")
    g.add_argument("--time-unit", choices=["s", "ms", "us", "ns"], default=None,
                   help="unit of the time column (default s; stamps whose spacing says ms, us or ns are refused "
                   "naming the unit to pass)")
    g.add_argument("--time-scale", type=T.float_range(0.0, 1e9, lo_open=True), default=1.0,
                   help="multiply time by this to get s (any factor; --time-unit for a unit)")
    b = p.add_argument_group("ROS bag input")
    b.add_argument("--q-topic", metavar="TOPIC[:FIELD]", help="actuator position topic (required for a bag)")
    b.add_argument("--c-topic", metavar="TOPIC[:FIELD]", help="distal bending angle topic: an angle session")
    b.add_argument("--image-topic", metavar="TOPIC", help="camera topic (Image or CompressedImage): an image session")
    b.add_argument("--geometry", metavar="SESSION_JSON", type=T.existing_file, help="image sessions: robot, camera and hand_eye from this file")
    p.add_argument("--c-scale", type=_finite("non-zero number"), default=1.0,
                   help="multiply the angle by this to get deg (57.29578 for rad); CSV and bag")
    p.add_argument("--t-delay", type=T.T_DELAY_S, default=None,
                   help="acquisition delay of the angle sensor or camera behind the actuator clock, s "
                   "(CSV: default 0, one clock; bag image sessions: else estimated)")
    p.add_argument("--q-scale", type=_finite("non-zero number"), default=1.0,
                   help="multiply q by this to get the actuator unit")
    p.add_argument("--unit", choices=["mm", "deg"], default="mm", help="actuator unit (default mm)")
    p.add_argument("--q-per-rad", type=_finite("non-zero number"), default=None,
                   help="f_coarse: actuator units per rad of bending (default: 5 for mm, the catheter's; "
                   "57.29578 for deg, 1:1)")
    p.add_argument("--q-source", choices=["measured", "command"], default="measured",
                   help="what q is: the encoder's reading (default) or the position commanded to the servo "
                   "(session.json actuator.q_source; calibrate then measures the command-to-tip delay)")
    p.add_argument("--force", "--overwrite", dest="force", action="store_true",
                   help="replace an existing session folder (only one holding nothing but session files)")
    add_json_arg(p, "session (path), rows (int), t_span_s (float), streams (per-stream import notes, bags)")
    p.set_defaults(func=run)


def run(a) -> int:
    from ..io.rosbag import is_bag
    from ..pipeline import import_recording

    if is_bag(a.source):
        if not a.q_topic:
            print("playscope: error: a bag needs --q-topic (and --c-topic or --image-topic)", file=sys.stderr)
            return 2
        q_per_rad = a.q_per_rad if a.q_per_rad is not None else (5.0 if a.unit == "mm" else 180.0 / math.pi)
        csv_only = [o for o, v in (("--t-col", a.t_col), ("--q-col", a.q_col), ("--c-col", a.c_col),
                                   ("--time-scale", a.time_scale != 1.0), ("--time-unit", a.time_unit)) if v]
        if csv_only:
            raise InputError(a.source, f"{', '.join(csv_only)}: CSV options, and this is a ROS bag (give topics: "
                             "--q-topic, --c-topic, --image-topic)")
        bag = dict(q=a.q_topic, c=a.c_topic, image=a.image_topic, geometry=a.geometry,
                   unit=a.unit, q_scale=a.q_scale, c_scale=a.c_scale, q_per_rad=q_per_rad, t_delay_s=a.t_delay)
        try:
            res = import_recording(a.source, a.out, bag=bag, q_source=a.q_source, overwrite=a.force)
        except ValueError as e:
            if isinstance(e, InputError):
                raise
            print(f"playscope: error: {e}", file=sys.stderr)
            return 2
        for line in res.notes:
            print(f"{a.source}: {line}", file=sys.stderr)
    else:
        bag_only = [o for o, v in (("--q-topic", a.q_topic), ("--c-topic", a.c_topic),
                                   ("--image-topic", a.image_topic), ("--geometry", a.geometry)) if v]
        if bag_only:
            raise InputError(a.source, f"{', '.join(bag_only)}: ROS bag options, and this is a CSV (use --t-col, "
                             "--q-col, --c-col)")
        csv = dict(t_col=a.t_col, q_col=a.q_col, c_col=a.c_col, time_scale=a.time_scale, time_unit=a.time_unit,
                   q_scale=a.q_scale,
                   unit=a.unit, q_per_rad=a.q_per_rad, c_scale=a.c_scale, t_delay_s=a.t_delay, q_source=a.q_source)
        res = import_recording(a.source, a.out, csv=csv, overwrite=a.force, progress=progress)
        warn(res.notes)
    print(res.line())
    dump_json(a.json, res.to_json())
    return 0
