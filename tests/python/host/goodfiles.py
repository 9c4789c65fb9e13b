"""A small set of valid inputs (angle session, calibration, table, CSV, image session) for the
issue-14 guard tests to damage one way at a time. Not a test module itself."""

from __future__ import annotations

import shutil
from pathlib import Path

from playscope.fit.calibration import calibrate
from playscope.io.session import write_session
from playscope.fit.table_build import build_table

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
    return good_paths(root)


def good_paths(root: Path) -> dict[str, Path]:
    """name -> path of the files make_good wrote under root."""
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
    from playscope.base.native import core

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


def reseal(blob: bytes, q_range=None, b=None, f=None) -> bytes:
    """A copy of a v2 table blob with the actuator range (q_min, q_max; raw Q16.16 ints), the
    B and f entries (arrays of raw Q16.16 ints, same count) replaced and the CRC-32 made
    valid again: a table whose structure is intact and whose physics is whatever was put in."""
    import numpy as np

    from playscope.base.native import core

    ffi, lib = core()
    out = bytearray(blob)
    hd = ffi.new("pst_header_t *")
    ffi.memmove(hd, bytes(out[:ffi.sizeof("pst_header_t")]), ffi.sizeof("pst_header_t"))
    if q_range is not None:
        at = ffi.offsetof("pst_header_t", "q_min_q16")
        out[at:at + 8] = np.array(q_range, "<i4").tobytes()
    for grid, v in ((hd.b, b), (hd.f, f)):
        if v is not None:
            v = np.asarray(v, dtype=np.int64)
            assert v.size == grid.n and np.all(np.abs(v) < 2**31)
            out[grid.offset:grid.offset + 4 * grid.n] = v.astype("<i4").tobytes()
    crc = lib.calib_table_crc(ffi.from_buffer(out), hd.total_size)
    at = ffi.offsetof("pst_header_t", "crc32")
    out[at:at + 4] = int(crc).to_bytes(4, "little")
    return bytes(out)


def table_nonsense() -> list:
    """(name, expected calib_status name, damage(g)): tables with a valid CRC and an intact
    structure whose physics is impossible (ps_table.h, PST_PLAUS_*), each made from the good
    table (travel [-4, 4] mm, 33 entries of B ~0.3-0.7 mm and f ~+-65 deg, step 0.25 mm)."""
    import numpy as np

    from playscope.base.native import core

    ffi, _ = core()
    Q = 65536

    def entries(blob, name):
        hd = ffi.new("pst_header_t *")
        ffi.memmove(hd, blob[:ffi.sizeof("pst_header_t")], ffi.sizeof("pst_header_t"))
        g = getattr(hd, name)
        return np.frombuffer(blob, "<i4", g.n, g.offset).astype(np.int64)

    def edit(**kw):
        def f(g):
            p = g["table"]
            blob = p.read_bytes()
            args = {k: (v(blob) if callable(v) else v) for k, v in kw.items()}
            p.write_bytes(reseal(blob, **args))
        return f

    travel_55 = (int(-2.75 * Q), int(2.75 * Q))
    n = lambda blob: entries(blob, "f").size  # noqa: E731
    return [
        ("B 100 mm on a 5.5 mm travel", "CALIB_ERR_B_TRAVEL",
         edit(q_range=travel_55, b=lambda bl: np.full(n(bl), 100 * Q))),
        ("B 20000 mm on a 5.5 mm travel", "CALIB_ERR_B_TRAVEL",
         edit(q_range=travel_55, b=lambda bl: np.full(n(bl), 20000 * Q))),
        ("B 8.1 mm on an 8 mm travel", "CALIB_ERR_B_TRAVEL", edit(b=lambda bl: np.full(n(bl), int(8.1 * Q)))),
        ("B 1 raw above a 2 mm travel", "CALIB_ERR_B_TRAVEL",
         edit(q_range=(-Q, Q), b=lambda bl: np.full(n(bl), 2 * Q + 1))),
        ("f x500", "CALIB_ERR_C_RANGE", edit(f=lambda bl: entries(bl, "f") * 500)),
        ("f x6 (+-390 deg)", "CALIB_ERR_C_RANGE", edit(f=lambda bl: entries(bl, "f") * 6)),
        ("f rising 1 raw per entry", "CALIB_ERR_C_SPAN", edit(f=lambda bl: np.arange(n(bl)))),
        ("f spanning 0.5 deg", "CALIB_ERR_C_SPAN",
         edit(f=lambda bl: np.round(np.linspace(-0.25, 0.25, n(bl)) * Q).astype(np.int64))),
        ("f falling 1 raw per entry", "CALIB_ERR_C_SPAN", edit(f=lambda bl: 1000 - np.arange(n(bl)))),
        ("f jumping 100 deg in one 0.25 mm step", "CALIB_ERR_F_SLOPE",
         edit(f=lambda bl: (np.arange(n(bl)) + np.where(np.arange(n(bl)) >= 16, 100 * Q, 0)
                            - 50 * Q).astype(np.int64))),
        # The instrument block of a layout-5 table (its largest play 2 x the calibrated one, its
        # angle range f's widened by 1/16, its slopes 2 x f's and f^-1's), CRC resealed:
        ("B equal to the whole 8 mm travel", "CALIB_ERR_B_INST", edit(b=lambda bl: np.full(n(bl), 8 * Q))),
        ("B at 95 % of the travel", "CALIB_ERR_B_INST", edit(b=lambda bl: np.full(n(bl), int(0.95 * 8 * Q)))),
        ("B ten times the calibrated one", "CALIB_ERR_B_SLOPE", edit(b=lambda bl: entries(bl, "b") * 10)),
        ("B three times the calibrated one", "CALIB_ERR_B_INST", edit(b=lambda bl: entries(bl, "b") * 3)),
        ("f spanning 710 deg", "CALIB_ERR_C_INST",
         edit(f=lambda bl: np.round(np.linspace(-355, 355, n(bl)) * Q).astype(np.int64))),
        ("f spanning 1 deg over the travel", "CALIB_ERR_C_SPAN",
         edit(f=lambda bl: np.round(np.linspace(-0.5, 0.5, n(bl)) * Q).astype(np.int64))),
        ("a 359 deg step inside f", "CALIB_ERR_F_SLOPE",
         edit(f=lambda bl: entries(bl, "f") // 10 + np.where(np.arange(n(bl)) >= 16, 359 * Q, 0) - 180 * Q)),
        ("f ten times flatter (the instrument's f^-1 slope)", "CALIB_ERR_F_INV_SLOPE_INST",
         edit(f=lambda bl: entries(bl, "f") // 10)),
        ("q_max = q_min + 1 raw", "CALIB_ERR_TRAVEL", edit(q_range=(0, 1))),
        ("travel 1/32 mm", "CALIB_ERR_TRAVEL", edit(q_range=(0, Q // 32))),
    ]
