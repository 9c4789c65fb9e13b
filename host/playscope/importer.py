"""Import foreign CSV recordings into sessions (column mapping, units, time base).

The EM-tracked catheter recordings (../shared/data/real/catheter/data_2_*.txt; no
licence: read in place, never copied) map as: Time -> t_s, "Tendon Disp." (mm) -> q,
"Angle x" (deg) -> c_deg of an angle session whose sensor shares the encoder's clock.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from .errors import InputError
from .session import Robot, Session, read_csv

CATHETER = {"t": "Time", "q": "Tendon Disp.", "c": "Angle x"}
# Nominal f_coarse for the catheter: about 63 deg of bending over 5.5 mm of tendon.
CATHETER_Q_PER_RAD = 5.0


def import_csv(path, t_col: str, q_col: str, c_col: str, time_scale: float = 1.0, q_scale: float = 1.0,
               unit: str = "mm", q_per_rad: float = CATHETER_Q_PER_RAD, bend_length_mm: float = 30.0,
               tip_length_mm: float = 0.0) -> Session:
    """Read one CSV with a header into an angle session (encoder and distal share rows).

    t_col, q_col, c_col: header names; time_scale, q_scale multiply the raw columns (e.g.
    1e-3 for ms, 1e-3 for um). Repeated and backward time stamps are repaired as for a
    session (session.regularize_time; what was done is in Session.notes). Errors: InputError
    naming the file and row (missing column, NaN, a clock reset)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            header = [h.strip() for h in next(csv.reader(fh), [])]
    except UnicodeDecodeError as e:
        raise InputError(path, f"not UTF-8 text (byte {e.start}): a CSV with a header row was expected", 1) from None
    except csv.Error as e:
        raise InputError(path, f"not a CSV file ({e})", 1) from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}; check the permissions") from None
    for col in (t_col, q_col, c_col):
        if col not in header:
            raise InputError(path, f"missing column {col!r} (header: {','.join(header)})", 1)
    notes: list[str] = []
    d = read_csv(path, [t_col, q_col, c_col], time_col=t_col, notes=notes)  # repeated/backward stamps repaired
    t = d[t_col] * time_scale
    return Session(notes=notes, actuator_unit=unit, distal_kind="angle",
                   robot=Robot("constant_curvature", bend_length_mm, tip_length_mm, q_per_rad),
                   encoder={"t_s": t, "q": d[q_col] * q_scale}, distal={"t_s": t.copy(), "c_deg": d[c_col]},
                   t_delay_s=0.0, meta={"source": {"file": str(path), "columns": [t_col, q_col, c_col]}})


def import_catheter(path) -> Session:
    """One data_2_*.txt file of the catheter set as an angle session (q in mm)."""
    return import_csv(path, CATHETER["t"], CATHETER["q"], CATHETER["c"])


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
