"""A small set of valid inputs (angle session, calibration, table, CSV, image session) for the
issue-14 guard tests to damage one way at a time. Not a test module itself."""

from __future__ import annotations

import shutil
from pathlib import Path

from playscope.calibration import calibrate
from playscope.session import write_session
from playscope.tables import build_table

from .synth import angle_session


def make_good(root: Path) -> dict[str, Path]:
    """Write the valid inputs under root; returns name -> path (session, cal, table, csv)."""
    root.mkdir(parents=True, exist_ok=True)
    s = angle_session(noise_deg=0.01, rate_hz=100.0)
    write_session(s, root / "session")
    cal = calibrate(s, fps=25.0)
    cal.save(root / "cal.json")
    q0, q1 = cal.q_range
    tab = build_table(cal.B, cal.f, q0, q1, cal.actuator_unit, "remain", 1, 64)
    (root / "table.pstb").write_bytes(tab.blob)
    t, q, c = s.encoder["t_s"], s.encoder["q"], None
    import numpy as np

    c = np.interp(t, s.distal["t_s"], s.distal["c_deg"])
    lines = ["Time,Tendon Disp.,Angle x"] + [f"{a:.4f},{b:.5f},{d:.4f}" for a, b, d in zip(t, q, c)]
    (root / "rec.csv").write_text("\n".join(lines) + "\n")
    return {"session": root / "session", "cal": root / "cal.json", "table": root / "table.pstb",
            "csv": root / "rec.csv"}


def copy_good(good: dict[str, Path], dest: Path) -> dict[str, Path]:
    """A private copy of make_good's files under dest (each case damages its own)."""
    dest.mkdir(parents=True, exist_ok=True)
    out = {}
    for k, p in good.items():
        q = dest / p.name
        (shutil.copytree if p.is_dir() else shutil.copy2)(p, q)
        out[k] = q
    return out


def table_damages() -> list:
    """(name, damage(g)) for the table file: one field or byte each (offsets from the C header)."""
    from playscope.native import core

    ffi, _ = core()

    def flip(field: str, byte: int, mask: int):
        def f(g):
            p = g["table"]
            b = bytearray(p.read_bytes())
            b[(ffi.offsetof("pst_header_t", field) if field else 0) + byte] ^= mask
            p.write_bytes(bytes(b))
        return f

    def cut(n: int):
        def f(g):
            p = g["table"]
            p.write_bytes(p.read_bytes()[:n])
        return f

    return [("data byte", flip(None, 200, 0x10)), ("crc field", flip("crc32", 0, 0x01)),
            ("q_max bit, stale crc", flip("q_max_q16", 2, 0x40)), ("magic", flip("magic", 0, 0xFF)),
            ("layout version", flip("layout_version", 0, 0x08)), ("header size", flip("header_size", 0, 0x01)),
            ("total_size", flip("total_size", 1, 0x01)), ("truncated", cut(-4)), ("header only", cut(40))]
