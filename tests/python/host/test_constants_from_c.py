"""The firmware's constants are written once, in C: the Q16.16 scale, the operator count, the
loader's limits, the table magic and the USB ids. The host reads them through playscope.base.native
(``native.Q16_ONE``, ``lib.PST_MAX_ENTRIES``, ...), so a change in the C cannot leave a stale
Python copy behind. This test scans host/playscope's source text (code, comments and
docstrings) for literal copies of those values and fails on one outside native.py. The
patterns are built from the values the compiled C reports, so they follow the C; the planted
copies below show that each pattern finds what it is meant to find."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from playscope.base import native

PKG = Path(__file__).resolve().parents[3] / "host" / "playscope"
# The one module allowed to spell the constants: it declares their names for the C.
EXEMPT = {"base/native.py"}
# Copies still present in modules another branch is editing, as (path under host/playscope,
# the stripped line). An entry that no longer matches fails test_allowances_are_current, so
# this list can only shrink.
ALLOWED: set[tuple[str, str]] = set()


def _assign(name_re: str, value_re: str) -> str:
    # `name = value`, `name: type = value`, `name=value` (a keyword or default argument).
    return rf"(?i)\b{name_re}\b\s*(?::[^=\n]*)?=\s*{value_re}\b"


def patterns() -> dict[str, re.Pattern]:
    """{what: regex} of literal copies, from the values the C defines."""
    one, bits = native.Q16_ONE, native.FRAC_BITS
    ops, n_max, derived = native.MAX_OPS, native.MAX_ENTRIES, native.CALIB_DERIVED_MAX
    vid, pid = native.USB_VID, native.USB_PID
    c = native.constant
    assert one == 1 << bits  # the patterns below spell the scale both ways
    pats = {
        "Q16.16 scale (PS_Q16_ONE)": rf"\b{one}(?:\.0*)?\b|\b{one:#x}\b|\b\d+\s*<<\s*{bits}\b"
                                     rf"|\b2(?:\.0)?\s*\*\*\s*\(?\s*-?\s*{bits}\b|{re.escape(repr(1.0 / one))}",
        "operator count (PST_MAX_OPS)": _assign(r"\w*ops", str(ops)),
        "entries per grid (PST_MAX_ENTRIES)": rf"(?<!SHA-)\b{n_max}\b",  # SHA-256 names a hash
        "derived entries (CALIB_DERIVED_MAX)": _assign(r"\w*derived\w*", str(derived)),
        "largest table (PST_MAX_TABLE_SIZE)": rf"\b{c('PST_MAX_TABLE_SIZE')}\b",
        "table magic (PST_MAGIC)": rf"(?i)\b{c('PST_MAGIC'):#x}\b|\bb[\"']"
                                   rf"{re.escape(c('PST_MAGIC').to_bytes(4, 'little').decode())}[\"']",
        "relaxation limit (PST_RELAX_KAPPA_MAX_Q16)": rf"\b{c('PST_RELAX_KAPPA_MAX_Q16')}\b",
        "USB vendor id (PSU_VID)": rf"(?i)\b0x0*{vid:x}\b|\b{vid}\b|\b{vid:04x}\s*:\s*{pid:04x}\b",
        "USB product id (PSU_PID)": _assign(r"\w*pid", rf"(?:0x0*{pid:x}|{pid})"),
        "USB endpoints (PSU_EP_OUT/IN)": _assign(r"\w*ep_(?:in|out)\w*", r"(?:0x[0-9a-f]+|\d+)"),
    }
    return {k: re.compile(v) for k, v in pats.items()}


def find_copies(root: Path, exempt: set[str] = EXEMPT) -> list[tuple[str, int, str, str]]:
    """Literal copies in the *.py files under root: [(path under root, line number, what,
    stripped line)], files named in `exempt` (paths under root) skipped."""
    pats = patterns()
    out = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if rel in exempt:
            continue
        for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for what, rx in pats.items():
                if rx.search(line):
                    out.append((rel, no, what, line.strip()))
    return out


def test_no_literal_copies_in_the_host_package():
    found = [f for f in find_copies(PKG) if (f[0], f[3]) not in ALLOWED]
    assert not found, "constants retyped from the C (read them through playscope.base.native):\n" + "\n".join(
        f"  host/playscope/{p}:{n}: {what}: {line}" for p, n, what, line in found)


def test_allowances_are_current():
    present = {(p, line) for p, _, _, line in find_copies(PKG)}
    assert ALLOWED <= present, f"fixed, remove from ALLOWED: {sorted(ALLOWED - present)}"


# One planted copy per pattern, the way a copy has been (or would be) written.
PLANTED = {
    "Q16.16 scale (PS_Q16_ONE)": ["x = raw / 65536", "Q16 = 65536.0", "s = 1 << 16", "s = 2**16",
                                  "lsb = 2.0 ** -16", "c_max = 360 << 16", "ONE = 0x10000", "eps = 1.52587890625e-05"],
    "operator count (PST_MAX_OPS)": ["N_OPS = 16", "def f(n_ops: int = 16): pass", "g(max_ops=16)",
                                     "# PST_MAX_OPS = 16"],
    "entries per grid (PST_MAX_ENTRIES)": ["n_max = 256", "p.add_argument('--entries', help='at most 256')"],
    "derived entries (CALIB_DERIVED_MAX)": ["CALIB_DERIVED_MAX = 512"],
    "largest table (PST_MAX_TABLE_SIZE)": ["if len(blob) > 3304: pass"],
    "table magic (PST_MAGIC)": ["MAGIC = 0x42545350", "ok = head[:4] == b'PSTB'"],
    "relaxation limit (PST_RELAX_KAPPA_MAX_Q16)": ["KAPPA_MAX_Q16 = 58982"],
    "USB vendor id (PSU_VID)": ["USB_VID = 0x1209", "vid = 4617", "# device 1209:0001"],
    "USB product id (PSU_PID)": ["USB_PID = 0x0001", "def open(pid: int = 1): pass"],
    "USB endpoints (PSU_EP_OUT/IN)": ["USB_EP_OUT = 0x01", "USB_EP_IN = 0x81"],
}


@pytest.mark.parametrize("what", sorted(PLANTED))
def test_a_planted_copy_is_found(tmp_path, what):
    assert set(PLANTED) == set(patterns())  # every pattern has its planted copies
    for i, line in enumerate(PLANTED[what]):
        (tmp_path / f"m{i}.py").write_text(f'"""A module."""\n\n{line}\n')
    found = find_copies(tmp_path)
    hit = {(p, n) for p, n, w, _ in found if w == what}
    assert hit == {(f"m{i}.py", 3) for i in range(len(PLANTED[what]))}, found


def test_native_is_the_exemption_and_clean_code_passes(tmp_path):
    (tmp_path / "base").mkdir()
    (tmp_path / "base" / "native.py").write_text("Q16 = 65536\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "native.py").write_text("Q16 = 65536\n")  # only base/native.py
    (tmp_path / "ok.py").write_text("from . import native\nx = raw / native.Q16_ONE\n"
                                    "n = 16 << 20  # bytes\nsize = 512\nbuf = sock.recv(4096)\n"
                                    "fw = f'{v >> 16}.{(v >> 8) & 0xFF}'\nm = major << 16\n")
    assert [(p, w) for p, _, w, _ in find_copies(tmp_path)] == [("sub/native.py", "Q16.16 scale (PS_Q16_ONE)")]


def test_the_values_come_from_the_c():
    # Read independently of the cdef: the headers' own text.
    fixed = (native.COMMON / "ps_fixed.h").read_text()
    table = (native.COMMON / "ps_table.h").read_text()
    usb = native.USB_HEADER.read_text()
    assert re.search(rf"PS_Q16_ONE = {native.Q16_ONE}\b", fixed)
    assert re.search(rf"PST_MAX_OPS = {native.MAX_OPS}\b", table)
    assert re.search(rf"PST_MAX_ENTRIES = {native.MAX_ENTRIES}\b", table)
    assert re.search(rf"PSU_VID = {native.USB_VID:#06x}\b", usb)
    assert re.search(rf"PSU_PID = {native.USB_PID:#06x}\b", usb)
    assert re.search(rf"#define CALIB_DERIVED_MAX {native.CALIB_DERIVED_MAX}\b",
                     (native.CORE / "calib.h").read_text())


def test_relaxation_bound_is_the_loaders():
    # The fit's and the model's kappa bound is the loader's PST_RELAX_KAPPA_MAX_Q16, read from
    # the header text here (not through the cdef), and judged in the table's Q16.16 steps.
    import pytest as _pytest

    from playscope.fit import relax

    m = re.search(r"PST_RELAX_KAPPA_MAX_Q16 = (\d+)", (native.COMMON / "ps_table.h").read_text())
    bound = int(m.group(1))
    assert relax.kappa_max_q16() == bound
    assert relax.kappa_max() == bound / native.Q16_ONE
    relax.Relaxation(relax.kappa_max(), 1.0)  # the bound itself passes
    relax.Relaxation(0.9, 1.0)                # 0.9 rounds onto it in Q16.16
    with _pytest.raises(ValueError, match="kappa"):
        relax.Relaxation((bound + 1) / native.Q16_ONE, 1.0)
    assert relax.table_fields(relax.Relaxation(relax.kappa_max(), 1.0))[0] == bound
    assert not re.search(r"^\s*KAPPA_MAX\s*=", (PKG / "fit" / "relax.py").read_text(), re.M)
