"""Import foreign CSV recordings into sessions (column mapping, units, time base).

The EM-tracked catheter recordings (../shared/data/real/catheter/data_2_*.txt; no
licence: read in place, never copied) map as: Time -> t_s, "Tendon Disp." (mm) -> q,
"Angle x" (deg) -> c_deg of an angle session whose sensor shares the encoder's clock.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import re
from pathlib import Path

import numpy as np

from ..base.errors import InputError
from .csvtable import split_header
from .session import Robot, Session, read_csv, time_origin

CATHETER = {"t": "Time", "q": "Tendon Disp.", "c": "Angle x"}
# Nominal f_coarse for the catheter: about 63 deg of bending over 5.5 mm of tendon.
CATHETER_Q_PER_RAD = 5.0


def resolve_column(spec, header: list[str], has_header: bool, path, option: str) -> str:
    """The header name a --*-col value means: a name of the header, or a 1-based column number
    ("2"; the only way into a headerless file). Errors: InputError naming the file and option."""
    spec = str(spec).strip()
    if has_header and spec in header:
        if header.count(spec) > 1:
            raise InputError(path, f"{option} {spec!r}: the header holds that name {header.count(spec)} times "
                             f"({','.join(header)}); give the column's number instead", 1)
        return spec
    if spec.isdigit() and 1 <= int(spec) <= len(header):
        return header[int(spec) - 1]
    if spec.isdigit():
        raise InputError(path, f"{option} {spec}: the file has {len(header)} columns (1..{len(header)})", 1)
    if not has_header:
        raise InputError(path, f"{option} {spec!r}: the file has no header row (its first row is numbers): give "
                         f"a column number 1..{len(header)}", 1)
    raise InputError(path, f"missing column {spec!r} given by {option} (header: {','.join(header)}; or give a "
                     "column number)", 1)


def import_csv(path, t_col=None, q_col=None, c_col=None, time_scale: float = 1.0, q_scale: float = 1.0,
               unit: str = "mm", q_per_rad: float | None = None, bend_length_mm: float = 30.0,
               tip_length_mm: float = 0.0, c_scale: float = 1.0, t_delay_s: float | None = None,
               q_source: str = "measured", time_unit: str | None = None, progress=None) -> Session:
    """Read one CSV into an angle session (encoder and distal share rows).

    t_col, q_col, c_col: header names or 1-based column numbers (as str or int); None takes
    the catheter's names with a header, columns 1, 2, 3 without one. A file whose first row
    is all numbers has no header (noted in Session.notes). time_scale, q_scale, c_scale
    multiply the time, actuator and angle columns (1e-3 for ms or um, 57.29578 for rad ->
    deg). q_per_rad (f_coarse, actuator units per rad of bending) defaults by unit: 5 mm/rad
    (the catheter) for mm, 180/pi deg/rad (1:1) for deg. t_delay_s: the angle sensor's delay
    behind the encoder clock (None: 0, one clock; calibrate measures it from the record when
    q_source is "command"). q_source: "measured" or "command" (session.json actuator.q_source).
    time_unit: "s", "ms", "us" or "ns", the time column's unit (instead of time_scale); stamps
    whose median step says they are not seconds after the scaling are refused naming the unit
    (session.check_time_unit).
    Repeated and backward time stamps are repaired as for a session (session.regularize_time).
    Errors: InputError naming the file, the row or the option."""
    from .inputfile import MAX_CSV_BYTES, check_input_file
    from .session import Q_SOURCES, TIME_UNITS, check_range, check_time_unit, q_limit

    path = Path(path)
    check_input_file(path, "CSV file", MAX_CSV_BYTES)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:  # -sig: a spreadsheet's BOM
            first = split_header(fh.readline())
    except UnicodeDecodeError as e:
        raise InputError(path, f"not UTF-8 text (byte {e.start}): a CSV with a header row was expected", 1) from None
    except csv.Error as e:
        raise InputError(path, f"not a CSV file ({e})", 1) from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}; check the permissions") from None
    if not first:
        raise InputError(path, "empty file (no header row and no data)", 1)
    has_header = not all(_is_number(x) for x in first)
    header = first if has_header else [str(j + 1) for j in range(len(first))]
    defaults = (CATHETER["t"], CATHETER["q"], CATHETER["c"]) if has_header else ("1", "2", "3")
    cols = [resolve_column(v if v is not None else d, header, has_header, path, opt)
            for v, d, opt in zip((t_col, q_col, c_col), defaults, ("--t-col", "--q-col", "--c-col"))]
    if len(set(cols)) < 3:
        raise InputError(path, f"--t-col, --q-col and --c-col name the same column twice ({', '.join(cols)})")
    if q_source not in Q_SOURCES:
        raise InputError(None, f"--q-source must be one of {Q_SOURCES}, got {q_source!r}")
    if time_unit is not None:
        if time_unit not in TIME_UNITS:
            raise InputError(None, f"--time-unit must be one of {', '.join(TIME_UNITS)}, got {time_unit!r}")
        if time_scale != 1.0:
            raise InputError(None, f"--time-unit {time_unit} and --time-scale {time_scale:g} both say what the time "
                             "column's unit is: give one")
        time_scale = TIME_UNITS[time_unit]
    notes: list[str] = []
    if not has_header:
        notes.append(f"{path}: no header row (the first row is numbers): columns by number, t = {cols[0]}, "
                     f"q = {cols[1]}, c = {cols[2]}")
    tt: list = []
    # Only the three columns mapped are read (others=False): a spreadsheet's other columns may
    # hold anything, and a long log's memory is then three float64 columns.
    d = read_csv(path, cols, time_col=cols[0], notes=notes, header=header if not has_header else None, time_text=tt,
                 others=False, progress=progress)
    n = d[cols[0]].size
    if n < 2:
        raise InputError(path, f"{n} row(s) with a distinct time stamp after repairs: a session needs at least two "
                         "(are all stamps equal? check --t-col and --time-scale)")
    t = d[cols[0]] * time_scale
    read_as = f"--time-unit {time_unit}" if time_unit else ("seconds" if time_scale == 1.0 else f"--time-scale {time_scale:g}")
    check_time_unit(t, path, scale=time_scale,
                    fix=lambda u: f"pass --time-unit {u}" + ("" if read_as == "seconds" else f" instead of {read_as}"))
    enc = {"t_s": t, "q": d[cols[1]] * q_scale, "_row": d["_row"]}
    dist = {"t_s": t.copy(), "c_deg": d[cols[2]] * c_scale, "_row": d["_row"].copy()}
    check_range(enc, "q", path, notes, q_limit(), unit)
    if q_per_rad is None:
        q_per_rad = CATHETER_Q_PER_RAD if unit == "mm" else 180.0 / math.pi
    text = dataclasses.replace(tt[0], scale=float(time_scale))
    s = time_origin(Session(notes=notes, actuator_unit=unit, distal_kind="angle",
                            robot=Robot("constant_curvature", bend_length_mm, tip_length_mm, q_per_rad),
                            encoder=enc, distal=dist, t_delay_s=0.0 if t_delay_s is None else float(t_delay_s),
                            q_source=q_source,
                            meta={"source": {"file": str(path), "columns": cols, "header": has_header,
                                             "time_scale": time_scale, "q_scale": q_scale, "c_scale": c_scale}}),
                    {"encoder": text, "distal": text})
    if s.encoder["t_s"].size < 2:  # the stamps, scaled, fell into one microsecond
        raise InputError(path, f"{n} rows with distinct stamps, but {s.encoder['t_s'].size} after scaling them by "
                         f"{time_scale:g} to seconds and rounding to the microsecond (the session's resolution): "
                         "check --time-scale / --time-unit")
    return s


def _is_number(x: str) -> bool:
    try:
        return math.isfinite(float(x))
    except ValueError:
        return False


def import_catheter(path, progress=None) -> Session:
    """One data_2_*.txt file of the catheter set as an angle session (q in mm)."""
    return import_csv(path, CATHETER["t"], CATHETER["q"], CATHETER["c"], progress=progress)


# The endoscopic instrument's recordings (../shared/data/real/endoscope/, README there; no licence:
# read in place, never copied): headerless CSV, q = commanded bending angle (deg), c = measured
# pitch (deg). The short records (30.txt ... 240.txt) carry c in column 3, the long ones
# (conf*_60.txt) in column 5 (electromagnetic tracker).
ENDOSCOPE_T_COL, ENDOSCOPE_Q_COL = 0, 1
ENDOSCOPE_C_COL_SHORT, ENDOSCOPE_C_COL_LONG = 3, 5
# Nominal f_coarse: the commanded angle is the tip angle to first order (1 deg of c per deg of q).
ENDOSCOPE_Q_PER_RAD = float(np.degrees(1.0))


def import_endoscope(path, c_col: int | None = None) -> Session:
    """One endoscope recording as an angle session with q the commanded angle (deg).

    c_col: the measured-angle column; None: 5 when the file has at least 6 columns and its name
    starts with "conf" (the tracker records), else 3. Rows before the command first moves are
    dropped (the long records open with a block of zeros, stamps included), and so are trailing
    rows whose stamp went back to 0 for good (a logger whose clock stopped). Repeated stamps
    keep the last row (session.regularize_time, noted in Session.notes). q_source is "command":
    the servo's lag is inside the data, so `calibrate` measures it from the record.
    Errors: InputError naming the file (and row) for a missing file, a non-numeric field or a
    row with too few columns."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    try:
        rows = np.genfromtxt(path, delimiter=",", dtype=float, invalid_raise=True)
    except (ValueError, UnicodeDecodeError) as e:
        raise InputError(path, f"not a headerless numeric CSV: {e}") from None
    rows = np.atleast_2d(rows)
    if c_col is None:
        c_col = ENDOSCOPE_C_COL_LONG if path.name.startswith("conf") and rows.shape[1] > 5 else ENDOSCOPE_C_COL_SHORT
    if rows.shape[1] <= max(c_col, ENDOSCOPE_Q_COL):
        raise InputError(path, f"{rows.shape[1]} columns, the measured angle is expected in column {c_col}", 1)
    bad = ~np.isfinite(rows[:, [ENDOSCOPE_T_COL, ENDOSCOPE_Q_COL, c_col]]).all(axis=1)
    if bad.any():
        raise InputError(path, "empty or non-numeric field", int(np.argmax(bad)) + 1)
    moving = np.nonzero(rows[:, ENDOSCOPE_Q_COL] != rows[0, ENDOSCOPE_Q_COL])[0]
    start = max(int(moving[0]) - 1, 0) if moving.size else 0
    rows = rows[start:]
    notes = [f"{path}: {start} row(s) before the command first moves dropped"] if start else []
    # A logger whose clock stops writes its last rows with stamp 0 (conf90_60.txt: the last 1 099
    # rows, q held): they cannot be placed in time, so they end the record.
    t_raw = rows[:, ENDOSCOPE_T_COL]
    late = np.nonzero((t_raw == 0) & (np.arange(t_raw.size) > 0) & (np.maximum.accumulate(t_raw) > 0))[0]
    if late.size and np.all(t_raw[late[0]:] == 0):
        notes.append(f"{path}: the last {t_raw.size - late[0]} row(s) have time stamp 0 after "
                     f"{t_raw[late[0] - 1]:g} s (the logger's clock stopped): dropped")
        rows = rows[:late[0]]
    tab = {"t_s": rows[:, ENDOSCOPE_T_COL], "q": rows[:, ENDOSCOPE_Q_COL], "c_deg": rows[:, c_col]}
    from .session import regularize_time

    tab, note = regularize_time(tab, path, "t_s")
    if note:
        notes.append(note)
    t = tab["t_s"]
    return Session(notes=notes, actuator_unit="deg", distal_kind="angle",
                   robot=Robot("constant_curvature", 30.0, 0.0, ENDOSCOPE_Q_PER_RAD),
                   encoder={"t_s": t, "q": tab["q"]}, distal={"t_s": t.copy(), "c_deg": tab["c_deg"]},
                   t_delay_s=None, q_source="command",
                   meta={"source": {"file": str(path), "columns": [ENDOSCOPE_T_COL, ENDOSCOPE_Q_COL, c_col]}})


# --------------------------------------------------------------------------- a recording in place
def read_record(path, progress=None) -> Session:
    """A recording file read in place, without an import step: the catheter's CSV with a header
    (import_catheter) or the endoscope's headerless CSV (import_endoscope), told apart by the
    first line; its encoder thinned as a session folder's (session.thin_record, one rule).
    progress: a tqdm-like factory for a bar while a large file is read, or None.
    Errors: InputError naming the file (and row)."""
    from .session import thin_record

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        first = fh.readline()
    s = import_endoscope(path) if re.match(r"\s*[-0-9.]", first) else import_catheter(path, progress)
    return thin_record(s, path)


def load_recording(path, progress=None) -> Session:
    """What every command taking a session reads: a session folder (session.load_session) or a
    recording file read in place (read_record), thinned alike. Repairs made while reading are in
    Session.notes. progress: a tqdm-like factory for a bar while a large file is read, or None."""
    from .session import load_session

    return read_record(path, progress) if Path(path).is_file() else load_session(path, progress)
