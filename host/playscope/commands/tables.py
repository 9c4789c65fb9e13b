"""`playscope tables`: calibration JSON -> fixed-point table blob (common/ps_table.h)."""

from __future__ import annotations

from .. import argtypes as T
from ..atomic import write_bytes_atomic
from ..tables import build_table, check_physical, check_precision, table_errors
from ..errors import InputError
from .common import add_json_arg, dump_json, load_calibration


def add_parser(sub) -> None:
    p = sub.add_parser("tables", help="write the firmware's fixed-point lookup tables",
                       description="Sample B(q) and f_remain on power-of-two grids (Q16.16), add the transition "
                       "operators (r, w) when the calibration has them, write the table (common/ps_table.h) "
                       "with the firmware's table_write(), load it back with the firmware's "
                       "calib_load(), and report the measured worst-case error of the fixed-point direct model "
                       "and compensator against the float model; a table whose error is above the precision ceiling (1/16 of "
                       "its largest play, docs/firmware.md) is refused, as the board's loader would. Example: playscope tables d21.cal.json -o d21.pstb")
    p.add_argument("calibration", help="calibration JSON from `playscope calibrate`")
    p.add_argument("-o", "--out", required=True, type=T.file_path, help="table blob to write")
    p.add_argument("--entries", type=T.int_range(2, 256), help="max entries per grid (default PST_MAX_ENTRIES = 256)")
    p.add_argument("--generation", type=T.GENERATION, default=1, help="table generation number (default 1)")
    p.add_argument("--f-coarse", action="store_true", help="store f_coarse instead of f_remain (eq. 5 instead of 9)")
    add_json_arg(p, "table (path), bytes, crc32, entries, operators, errors {direct_c_deg_max, comp_q_max, f_inv_err, z_err}")
    p.set_defaults(func=run)


def run(a) -> int:
    cal = load_calibration(a.calibration)
    q_min, q_max = cal.doc["q_range"]
    f = cal.f_coarse if a.f_coarse else cal.f
    tr = None if a.f_coarse else cal.transition
    B = cal.B if a.f_coarse else cal.B_model
    try:
        check_physical(B, f, q_min, q_max, source=a.calibration)
        tab = build_table(B, f, q_min, q_max, cal.doc["actuator_unit"], "coarse" if a.f_coarse else "remain",
                          a.generation, a.entries, source=a.calibration, transition=tr)
        err = table_errors(tab, B, f, q_min, q_max, tr)
        check_precision(tab, err, f, q_min, q_max, source=a.calibration)
    except (ValueError, OverflowError) as e:  # InputError passes through with its own file
        if isinstance(e, InputError):
            raise
        raise InputError(a.calibration, f"cannot make a table of it: {' '.join(str(e).split())}") from None
    write_bytes_atomic(a.out, tab.blob)
    print(f"{a.out}: {len(tab.blob)} bytes, crc32 {tab.cal.crc32:#010x}, {tab.cal.b.n} entries per grid, "
          f"{tab.n_ops} transition operators; "
          f"worst |c_fixed - c_float| {err['direct_c_deg_max']:.2e} deg, |q*_fixed - q*_float| {err['comp_q_max']:.2e}")
    dump_json(a.json, {"table": a.out, "bytes": len(tab.blob), "crc32": int(tab.cal.crc32),
                       "entries": int(tab.cal.b.n), "operators": tab.n_ops, "errors": err})
    return 0
