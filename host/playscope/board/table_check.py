"""Integrity check of a table file before anything is sent to a board (common/ps_table.h).

``check_blob`` reads the header through the C layout (cffi, nothing retyped) and names the
first field that disagrees: size, magic, layout_version, header_size, total_size, the Q
formats, the actuator range q_min/q_max (against the grids, so one flipped bit in q_max is
named even when the CRC was left stale), the grids, then the CRC-32 (calib_table_crc, the
board's own function), and last the firmware loader calib_load_guarded() for the physical
rules (common/ps_plaus.h) and, given a board's limits (PSP_MSG_BOARD), the board's own: the
same C the board runs, the refusal worded with its numbers (table_build.refusal).
A table that fails is never resealed or sent: `flash` calls this first.
"""

from __future__ import annotations

import os

from ..base.errors import InputError
from ..base.native import core

_REBUILD = "rebuild it with `playscope tables`"


class TableFileError(InputError):
    """A table file that is not what `playscope tables` wrote; ``field`` names the culprit."""

    def __init__(self, source, field: str, what: str):
        self.field = field
        super().__init__(source, f"{field}: {what}; refusing to flash it, {_REBUILD}")


def _grid_end(g) -> int:
    return g.x0_q16 + (g.n - 1) * g.step_q16


def check_blob(blob: bytes, source=None, limits=None):
    """Check a table blob as a file on disk must be before it goes to a board.

    blob: the file's bytes; source: its path, for the message; limits: the board's pst_limits_t
    (a cffi pointer, Link.board_limits()) to hold the table to, or None. Returns the header (a cffi
    ``pst_header_t *`` copy). Errors: TableFileError (an InputError, one line naming the
    file and the field). Order: structural fields, q range, grids, CRC, then calib_load."""
    ffi, lib = core()
    hsize = ffi.sizeof("pst_header_t")
    if len(blob) < hsize:
        raise TableFileError(source, "size", f"{len(blob)} bytes, shorter than the {hsize}-byte header")
    hd = ffi.new("pst_header_t *")
    ffi.memmove(hd, blob, hsize)
    if hd.magic != lib.PST_MAGIC:
        raise TableFileError(source, "magic", f"{hd.magic:#010x} is not 'PSTB' (not a playscope table)")
    if not 1 <= hd.layout_version <= lib.PST_LAYOUT_VERSION:
        raise TableFileError(source, "layout_version",
                             f"{hd.layout_version}, this host reads 1..{lib.PST_LAYOUT_VERSION}")
    if hd.layout_version >= 3:  # v3: the map's grid follows (pst_header_v3_t); v4: the relaxation; v5: the instrument
        hsize = ffi.sizeof({3: "pst_header_v3_t", 4: "pst_header_v4_t"}.get(hd.layout_version, "pst_header_v5_t"))
        if len(blob) < hsize:
            raise TableFileError(source, "size", f"{len(blob)} bytes, shorter than the {hsize}-byte "
                                 f"v{hd.layout_version} header")
    if hd.header_size != hsize:
        raise TableFileError(source, "header_size", f"{hd.header_size}, expected {hsize}")
    if hd.total_size != len(blob):
        raise TableFileError(source, "total_size", f"header says {hd.total_size} bytes, the file has {len(blob)}"
                             + (" (truncated)" if hd.total_size > len(blob) else ""))
    if hd.total_size > lib.PST_MAX_TABLE_SIZE:
        raise TableFileError(source, "total_size", f"{hd.total_size} bytes, above PST_MAX_TABLE_SIZE "
                             f"{lib.PST_MAX_TABLE_SIZE}")
    if hd.q_frac_bits != lib.PS_FRAC_BITS or hd.c_frac_bits != lib.PS_FRAC_BITS:  # the only Q format (ps_fixed.h)
        raise TableFileError(source, "q_frac_bits/c_frac_bits", f"Q{hd.q_frac_bits}/Q{hd.c_frac_bits}, expected Q16")
    if hd.q_min_q16 >= hd.q_max_q16:
        raise TableFileError(source, "q_min/q_max", f"empty actuator range [{hd.q_min_q16 / lib.PS_Q16_ONE:g}, "
                             f"{hd.q_max_q16 / lib.PS_Q16_ONE:g}]")
    for name, g in (("b", hd.b), ("f", hd.f)):
        if not lib.PST_MIN_ENTRIES <= g.n <= lib.PST_MAX_ENTRIES or g.step_q16 <= 0 \
                or g.step_q16 & (g.step_q16 - 1) or g.offset < hsize or g.offset % 4 \
                or g.offset + 4 * g.n > hd.total_size:
            raise TableFileError(source, f"{name} grid", f"n {g.n}, step {g.step_q16}, offset {g.offset} "
                                 f"do not fit a {hd.total_size}-byte table")
    if hd.layout_version >= 3:
        h3 = ffi.new("pst_header_v3_t *")
        ffi.memmove(h3, blob, ffi.sizeof("pst_header_v3_t"))
        g = h3.tmap
        if g.n == 0:
            if g.offset != 0:
                raise TableFileError(source, "tmap grid", f"offset {g.offset} without entries")
        elif not lib.PST_MIN_ENTRIES <= g.n <= lib.PST_MAX_ENTRIES or g.step_q16 <= 0 \
                or g.step_q16 & (g.step_q16 - 1) or g.offset < hsize or g.offset % 4 \
                or g.offset + 4 * g.n > hd.total_size:
            raise TableFileError(source, "tmap grid", f"n {g.n}, step {g.step_q16}, offset {g.offset} "
                                 f"do not fit a {hd.total_size}-byte table")
    # The table covers its travel: tables writes grids that span [q_min, q_max], so a q bound
    # outside them is a damaged field even when the CRC was left stale.
    lo = max(hd.b.x0_q16, hd.f.x0_q16)
    hi = min(_grid_end(hd.b), _grid_end(hd.f))
    if hd.q_min_q16 < lo:
        raise TableFileError(source, "q_min", f"{hd.q_min_q16 / lib.PS_Q16_ONE:g} lies below the grids' start "
                             f"{lo / lib.PS_Q16_ONE:g}")
    if hd.q_max_q16 > hi:
        raise TableFileError(source, "q_max", f"{hd.q_max_q16 / lib.PS_Q16_ONE:g} lies beyond the grids' end "
                             f"{hi / lib.PS_Q16_ONE:g}")
    crc = lib.calib_table_crc(blob, hd.total_size)
    if crc != hd.crc32:
        raise TableFileError(source, "crc32", f"stored {hd.crc32:#010x}, the bytes give {crc:#010x} "
                             "(the file was corrupted or edited after `playscope tables` wrote it)")
    buf = ffi.new("uint32_t[]", (len(blob) + 3) // 4)  # calib_load reads entries in place, 4-aligned
    ffi.memmove(buf, blob, len(blob))
    cal = ffi.new("calib_t *")
    rep = ffi.new("pst_plaus_report_t *")
    st = lib.calib_load_guarded(cal, ffi.cast("uint8_t *", buf), len(blob), limits if limits is not None else ffi.NULL, rep)
    if st != lib.CALIB_OK:
        from ..fit.table_build import refusal

        who = "the board's limits" if limits is not None and lib.calib_status_of_rule(rep.rule) == st \
            and rep.rule >= lib.PST_RULE_UNBOUND else "the firmware loader calib_load"
        raise TableFileError(source, "contents", f"refused by {who}: {refusal(st, rep, blob)}")
    return hd


def read_table_file(path) -> bytes:
    """Read and check a table file. Errors: InputError (missing, a folder, unreadable,
    or any check_blob refusal)."""
    from ..io.inputfile import check_input_file

    check_input_file(path, "table file")  # a pipe or a device is refused before it is opened
    try:
        with open(path, "rb") as fh:
            data = fh.read(max_table_size() + 1)
    except IsADirectoryError:
        raise InputError(path, "is a folder, not a table file") from None
    except FileNotFoundError:
        raise InputError(path, "no such table file") from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}") from None
    if len(data) > max_table_size():
        raise TableFileError(path, "size", f"file larger than the largest table ({max_table_size()} bytes)")
    check_blob(data, os.fspath(path))
    return data


def max_table_size() -> int:
    """Largest table the C layout allows, bytes (PST_MAX_TABLE_SIZE)."""
    return int(core()[1].PST_MAX_TABLE_SIZE)
