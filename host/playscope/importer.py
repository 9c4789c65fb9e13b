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
from .session import Robot, Session, read_csv, time_origin

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
    return time_origin(Session(notes=notes, actuator_unit=unit, distal_kind="angle",
                   robot=Robot("constant_curvature", bend_length_mm, tip_length_mm, q_per_rad),
                   encoder={"t_s": t, "q": d[q_col] * q_scale}, distal={"t_s": t.copy(), "c_deg": d[c_col]},
                   t_delay_s=0.0, meta={"source": {"file": str(path), "columns": [t_col, q_col, c_col]}}))


def import_catheter(path) -> Session:
    """One data_2_*.txt file of the catheter set as an angle session (q in mm)."""
    return import_csv(path, CATHETER["t"], CATHETER["q"], CATHETER["c"])
