"""The C core through cffi: same sources as the firmware, layouts from the headers."""

import zlib

import numpy as np

from playscope.base.native import core, from_q16, to_q16


def test_layout_sizes_pinned_by_headers():
    ffi, lib = core()
    assert ffi.sizeof("pst_header_t") == 60
    assert ffi.sizeof("psp_frame_header_t") == 8
    assert ffi.sizeof("psp_table_chunk_t") == 236
    assert ffi.offsetof("pst_header_t", "pi") == 56 and ffi.sizeof("pst_pi_t") == 4  # layout v2
    assert lib.PST_MAX_TABLE_SIZE == 104 + 3 * 4 * lib.PST_MAX_ENTRIES + 2 * 4 * lib.PST_MAX_OPS  # layout v5
    assert ffi.sizeof("pst_header_v5_t") == 104 and ffi.offsetof("pst_header_v5_t", "inst") == 80
    assert ffi.sizeof("pst_instrument_t") == 24 and ffi.sizeof("pst_limits_t") == 28


def test_crc_is_zlibs():
    ffi, lib = core()
    data = bytes(range(256)) * 3
    buf = ffi.from_buffer(data)
    assert lib.ps_crc32_update(0, buf, len(data)) == zlib.crc32(data)
    assert lib.ps_crc32_update(7, buf, len(data)) == zlib.crc32(data, 7)


def test_q16_round_trip_and_overflow():
    x = np.array([-1.5, 0.0, 1 / 65536, 32767.0])
    np.testing.assert_array_equal(from_q16(to_q16(x)), x)
    import pytest

    with pytest.raises(OverflowError, match="Q16.16 overflow"):
        to_q16([1.0, 40000.0])
