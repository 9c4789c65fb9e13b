"""`playscope tables`: calibration JSON -> fixed-point table blob (common/ps_table.h)."""

from __future__ import annotations

from . import argtypes as T
from ..pipeline import write_tables
from .common import add_command, add_json_arg, emit


DESCRIPTION = """\
Sample B(q) and f_remain on power-of-two grids (Q16.16), add the transition operators (r, w)
when the calibration has them, write the table (common/ps_table.h) with the firmware's
table_write_inst() (layout 5: bound to the instrument, with the angle range, largest play and
slopes it can have), load it back with the firmware's calib_load() (the board's physical
plausibility rules, common/ps_plaus.h; a refusal names the rule and the numbers), and report the measured worst-case
error of the fixed-point direct model and compensator against the float model; a table whose
error is above the precision ceiling (1/16 of its largest play, docs/firmware.md) is refused, as
the board's loader would.
"""


def _entries(text: str) -> int:
    """--entries: an integer within the loader's limits, read from the C when the option is
    given (so `playscope tables --help` does not compile the core)."""
    from ..base import native

    return T.int_range(native.MIN_ENTRIES, native.MAX_ENTRIES)(text)


_entries.__name__ = "entries"


def add_parser(sub) -> None:
    p = add_command(sub, "tables", "write the firmware's fixed-point lookup tables", DESCRIPTION,
                    examples=["playscope tables d21.cal.json -o d21.pstb"])
    p.add_argument("calibration", help="calibration JSON from `playscope calibrate`")
    p.add_argument("-o", "--out", required=True, type=T.file_path, help="table blob to write")
    p.add_argument("--entries", type=_entries, help="max entries per grid, PST_MIN_ENTRIES..PST_MAX_ENTRIES "
                   "(default PST_MAX_ENTRIES, firmware common/ps_table.h)")
    p.add_argument("--generation", type=T.GENERATION, default=1, help="table generation number (default 1)")
    p.add_argument("--f-coarse", action="store_true", help="store f_coarse instead of f_remain (eq. 5 instead of 9)")
    p.add_argument("--instrument", type=T.INSTRUMENT, help="id of the instrument the session was recorded on "
                   "(table layout 5; a board configured for another refuses the table); default "
                   "PST_INSTRUMENT_DEFAULT (1), what a board takes unless configured otherwise")
    add_json_arg(p, "table (path), bytes, crc32, entries, operators, errors {direct_c_deg_max, comp_q_max, f_inv_err, z_err}")
    p.set_defaults(func=run)


def run(a) -> int:
    return emit(a, write_tables(a.calibration, a.out, a.entries, a.generation, a.f_coarse, a.instrument))
