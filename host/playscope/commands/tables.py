"""`playscope tables`: calibration JSON -> fixed-point table blob (common/ps_table.h)."""

from __future__ import annotations

from ..atomic import write_bytes_atomic
from ..calibration import Calibration
from ..tables import build_table, table_errors
from .common import add_json_arg, dump_json


def add_parser(sub) -> None:
    p = sub.add_parser("tables", help="write the firmware's fixed-point lookup tables",
                       description="Sample B(q) and f_remain on power-of-two grids (Q16.16), add the transition "
                       "operators (r, w) when the calibration has them, write the table (common/ps_table.h) "
                       "with the firmware's table_write(), load it back with the firmware's "
                       "calib_load(), and report the measured worst-case error of the fixed-point direct model "
                       "and compensator against the float model. Example: playscope tables d21.cal.json -o d21.pstb")
    p.add_argument("calibration", help="calibration JSON from `playscope calibrate`")
    p.add_argument("-o", "--out", required=True, help="table blob to write")
    p.add_argument("--entries", type=int, help="max entries per grid (default PST_MAX_ENTRIES = 256)")
    p.add_argument("--generation", type=int, default=1, help="table generation number (default 1)")
    p.add_argument("--f-coarse", action="store_true", help="store f_coarse instead of f_remain (eq. 5 instead of 9)")
    add_json_arg(p, "table (path), bytes, crc32, entries, operators, errors {direct_c_deg_max, comp_q_max, f_inv_err, z_err}")
    p.set_defaults(func=run)


def run(a) -> int:
    cal = Calibration.load(a.calibration)
    q_min, q_max = cal.doc["q_range"]
    f = cal.f_coarse if a.f_coarse else cal.f
    tr = None if a.f_coarse else cal.transition
    B = cal.B if a.f_coarse else cal.B_model
    tab = build_table(B, f, q_min, q_max, cal.doc["actuator_unit"], "coarse" if a.f_coarse else "remain",
                      a.generation, a.entries, source=a.calibration, transition=tr)
    err = table_errors(tab, B, f, q_min, q_max, tr)
    write_bytes_atomic(a.out, tab.blob)
    print(f"{a.out}: {len(tab.blob)} bytes, crc32 {tab.cal.crc32:#010x}, {tab.cal.b.n} entries per grid, "
          f"{tab.n_ops} transition operators; "
          f"worst |c_fixed - c_float| {err['direct_c_deg_max']:.2e} deg, |q*_fixed - q*_float| {err['comp_q_max']:.2e}")
    dump_json(a.json, {"table": a.out, "bytes": len(tab.blob), "crc32": int(tab.cal.crc32),
                       "entries": int(tab.cal.b.n), "operators": tab.n_ops, "errors": err})
    return 0
