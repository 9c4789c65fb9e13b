"""`playscope import`: a foreign CSV recording -> a session folder."""

from __future__ import annotations

from .. import argtypes as T
from ..importer import CATHETER, import_csv
from ..session import write_session
from .common import add_json_arg, dump_json


def add_parser(sub) -> None:
    p = sub.add_parser("import", help="bring a CSV recording into a session folder",
                       description="Map a CSV with one header row onto a playscope-session/1 angle session "
                       "(encoder.csv + distal.csv sharing the file's time base). Defaults fit the EM-tracked "
                       "catheter set: Time (s), 'Tendon Disp.' (mm) -> q, 'Angle x' (deg) -> c. "
                       "Example: playscope import data_2_1.txt -o sessions/d21")
    p.add_argument("csv", type=T.existing_file, help="input CSV file")
    p.add_argument("-o", "--out", required=True, help="session folder to create")
    p.add_argument("--t-col", default=CATHETER["t"], help="time column (default %(default)r)")
    p.add_argument("--q-col", default=CATHETER["q"], help="actuator column (default %(default)r)")
    p.add_argument("--c-col", default=CATHETER["c"], help="bending-angle column, deg (default %(default)r)")
    p.add_argument("--time-scale", type=T.float_range(1e-9, 1e9, lo_open=True), default=1.0, help="multiply time by this to get s (1e-3 for ms)")
    p.add_argument("--q-scale", type=T.nonzero_float(), default=1.0, help="multiply q by this to get the actuator unit")
    p.add_argument("--unit", choices=["mm", "deg"], default="mm", help="actuator unit (default mm)")
    p.add_argument("--q-per-rad", type=T.nonzero_float(1e6), default=5.0, help="f_coarse: actuator units per rad (default 5)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing session folder")
    add_json_arg(p, "session (path), rows (int), t_span_s (float)")
    p.set_defaults(func=run)


def run(a) -> int:
    s = import_csv(a.csv, a.t_col, a.q_col, a.c_col, a.time_scale, a.q_scale, a.unit, a.q_per_rad)
    write_session(s, a.out, overwrite=a.overwrite)
    t = s.encoder["t_s"]
    print(f"{a.out}: {t.size} rows, {t[-1] - t[0]:.1f} s")
    dump_json(a.json, {"session": str(a.out), "rows": int(t.size), "t_span_s": float(t[-1] - t[0])})
    return 0
