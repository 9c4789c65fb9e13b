"""Table preparation and the host's own run of the C compensator, for bit-for-bit checks."""

from __future__ import annotations

import math

from ..native import core


def set_generation(blob: bytes, generation: int) -> bytes:
    """Return blob with pst_header_t.generation set and the CRC resealed (calib_table_crc)."""
    ffi, lib = core()
    if len(blob) < ffi.sizeof("pst_header_t"):
        raise ValueError("table shorter than its header")
    b = bytearray(blob)
    off_gen = ffi.offsetof("pst_header_t", "generation")
    off_crc = ffi.offsetof("pst_header_t", "crc32")
    b[off_gen:off_gen + 4] = generation.to_bytes(4, "little")
    crc = lib.calib_table_crc(ffi.from_buffer(b), len(b))
    b[off_crc:off_crc + 4] = crc.to_bytes(4, "little")
    return bytes(b)


class HostCalib:
    """calib_load() of a blob on the host; keeps the aligned copy alive as the C side requires."""

    def __init__(self, blob: bytes):
        ffi, lib = core()
        self.ffi, self.lib = ffi, lib
        self.buf = ffi.new("uint32_t[]", (len(blob) + 3) // 4)
        ffi.memmove(self.buf, blob, len(blob))
        self.cal = ffi.new("calib_t *")
        st = lib.calib_load(self.cal, ffi.cast("uint8_t *", self.buf), len(blob))
        if st != lib.CALIB_OK:
            raise ValueError(f"table refused by calib_load: {ffi.string(lib.calib_status_str(st)).decode()}")

    def c_range_q16(self) -> tuple[int, int]:
        a = self.lib.lut_eval(self.ffi.addressof(self.cal.f), self.cal.q_min_q16)
        b = self.lib.lut_eval(self.ffi.addressof(self.cal.f), self.cal.q_max_q16)
        return min(a, b), max(a, b)

    def comp_run(self, c_q16: list[int]) -> list[int]:
        """comp_reset at c[0], then comp_step over c: what the board does in compensation mode."""
        cp = self.ffi.new("comp_t *")
        self.lib.comp_reset(cp, self.cal, self.ffi.NULL, c_q16[0])
        return [self.lib.comp_step(cp, c) for c in c_q16]


def test_vector(cal: HostCalib, n: int = 200) -> list[int]:
    """c* reference: two sine periods with reversals of varying amplitude over 90 % of f's range."""
    lo, hi = cal.c_range_q16()
    mid, amp = (lo + hi) / 2, 0.45 * (hi - lo)
    return [int(mid + amp * math.sin(2 * math.pi * 2 * k / n) * (0.6 + 0.4 * math.cos(7.0 * k / n)))
            for k in range(n)]


def demo_table(n: int = 256, q0: float = -4.0, step_log2: int = 11, generation: int = 1) -> bytes:
    """A valid table of n entries per grid (B bump, cubic f_remain): for tests, benches and
    a first flash before any calibration. Layout comes from the C header through cffi."""
    ffi, lib = core()
    hdr = ffi.new("pst_header_t *")
    hsize = ffi.sizeof("pst_header_t")
    step = 2 ** step_log2
    x0 = int(q0 * 65536)
    qs = [(x0 + i * step) / 65536 for i in range(n)]
    b = [int(round((0.4 + 0.3 * math.exp(-q * q / 2)) * 65536)) for q in qs]
    f = [int(round((10 * q + 0.3 * q ** 3) * 65536)) for q in qs]
    hdr.magic, hdr.layout_version, hdr.header_size = lib.PST_MAGIC, lib.PST_LAYOUT_VERSION, hsize
    hdr.total_size = hsize + 8 * n
    hdr.generation = generation
    hdr.q_frac_bits = hdr.c_frac_bits = 16  # Q16.16, the only format of layout v1 (ps_fixed.h)
    hdr.q_unit, hdr.f_kind = lib.PST_Q_UNIT_MM, lib.PST_F_REMAIN
    hdr.q_min_q16, hdr.q_max_q16 = x0, x0 + (n - 1) * step
    for g, off in ((hdr.b, hsize), (hdr.f, hsize + 4 * n)):
        g.x0_q16, g.step_q16, g.n, g.offset = x0, step, n, off
    body = b"".join(v.to_bytes(4, "little", signed=True) for v in b + f)
    return set_generation(bytes(ffi.buffer(hdr)) + body, generation)
