"""Physical plausibility of a table (ps_table.h, PST_PLAUS_*; calib_load's check_plausible):
tables with a valid CRC and an intact structure but impossible physics are refused, by the
host's check before a flash and by the board itself, each with its rule's reason code; and
a random table with a valid CRC is accepted only when it obeys every rule, checked against
a float64 re-statement of the rules written here from the header's documentation (the good
table is layout 5: its instrument block's rules apply too)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from playscope.base.native import core
from playscope.board.table_check import TableFileError, check_blob

from .goodfiles import reseal, table_nonsense

NONSENSE = table_nonsense()
Q = 65536.0


def _load(blob: bytes) -> int:
    ffi, lib = core()
    buf = ffi.new("uint32_t[]", (len(blob) + 3) // 4)
    ffi.memmove(buf, blob, len(blob))
    return int(lib.calib_load(ffi.new("calib_t *"), ffi.cast("uint8_t *", buf), len(blob)))


@pytest.mark.parametrize("name,code,damage", NONSENSE, ids=[c[0] for c in NONSENSE])
def test_nonsense_refused_by_host_and_board(name, code, damage, good, tmp_path):
    import shutil

    from playscope.board.link import DeviceError, Link
    from playscope.board.transport import open_transport

    ffi, lib = core()
    g = {"table": tmp_path / "t.pstb"}
    shutil.copy(good["table"], g["table"])
    damage(g)
    blob = g["table"].read_bytes()
    assert _load(blob) == getattr(lib, code)
    import re

    with pytest.raises(TableFileError, match=re.escape(ffi.string(lib.calib_status_str(getattr(lib, code))).decode())):
        check_blob(blob, g["table"])
    # The board's own loader, sent the blob without the host's check.
    link = Link(open_transport("virtual"))
    try:
        with pytest.raises(DeviceError) as e:
            link.upload_table(blob)
        assert (e.value.code, e.value.detail) == (lib.PSP_ERR_TABLE, getattr(lib, code))
        assert link.info()["active_generation"] == 0  # nothing committed
    finally:
        link.close()


def _instrument(blob: bytes):
    """The v5 header's instrument block (c_min, c_max, b_max, f_slope_max, f_inv_slope_max) as floats."""
    ffi, _ = core()
    h = ffi.new("pst_header_v5_t *")
    ffi.memmove(h, blob[:ffi.sizeof("pst_header_v5_t")], ffi.sizeof("pst_header_v5_t"))
    i = h.inst
    return tuple(v / Q for v in (i.c_min_q16, i.c_max_q16, i.b_max_q16, i.f_slope_max_q16, i.f_inv_slope_max_q16))


def _plausible(q_min, q_max, step_q16, b, f, inst=None) -> bool:
    """The rules of ps_table.h in float64 units (mm or deg, deg); inst: a v5 table's instrument
    block (_instrument), whose rules then apply too (the good table is in mm)."""
    travel = (q_max - q_min) / Q
    if travel < 1 / 16:
        return False
    if np.max(b) / Q > travel:
        return False
    fd = f / Q
    step = step_q16 / Q
    if np.max(np.abs(fd)) > 360 or abs(fd[-1] - fd[0]) < (1 if inst is None else 5):
        return False
    slopes = np.abs(np.diff(fd)) / step
    if np.max(slopes) > 360:
        return False
    if inst is None:
        return True
    c_min, c_max, b_max, s_max, i_max = inst
    if travel > 200 or c_max - c_min > 360 or not 0 < b_max <= travel / 2:
        return False
    unbounded = i_max == (2**31 - 1) / Q  # f^-1 beyond Q16.16: not bounded by the block
    if not 0 < s_max <= min(360, 16 * (c_max - c_min) / travel) or \
            not (0 < i_max <= 65536 * travel / (c_max - c_min) or unbounded):
        return False
    if np.max(b) / Q > b_max or np.min(fd) < c_min or np.max(fd) > c_max:
        return False
    return bool(np.max(slopes) <= s_max and (unbounded or np.min(slopes) * i_max >= 1))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_valid_crc_tables_pass_only_within_the_rules(good, data):
    """Random travel, B and f over the good table's grids (33 entries, step 0.25 mm), CRC
    resealed: whenever calib_load accepts, the rules hold; whenever a rule fails, it refuses
    (with a plausibility code, or an earlier structural one)."""
    ffi, lib = core()
    blob = good["table"].read_bytes()
    n = 33
    lo = data.draw(st.sampled_from([-4.0, -2.75, -1.0])) if data.draw(st.booleans()) else data.draw(st.floats(-4, 3.9))
    travel = data.draw(st.sampled_from([1 / 65536, 1 / 32, 0.0625, 0.5, 2.0, 5.5, 8.0, 2.0, 5.5, 8.0, 8.0, 5.5]))
    hi = min(lo + travel, 4.0)
    q_range = (int(round(lo * Q)), int(round(hi * Q)))
    if q_range[1] <= q_range[0]:
        q_range = (q_range[0], q_range[0] + 1)
    b_level = data.draw(st.sampled_from([0.05, 0.5, 1.0, 0.3, 0.5, 1.0, 3.0, 7.9, 8.1, 100.0, 20000.0]))
    b_wiggle = data.draw(st.floats(0, 0.2))
    b = np.round((b_level + b_wiggle * np.sin(np.arange(n))) * Q).astype(np.int64)
    b = np.clip(b, 0, 2**31 - 1)
    f_scale = data.draw(st.sampled_from([1e-6, 1e-3, 0.02, 1.0, 1.0, 2.0, 0.5, 5.0, 6.0, 100.0, 500.0]))
    base = np.linspace(-65.0, 65.0, n)
    f_shape = data.draw(st.sampled_from(["linear", "linear", "jump", "cubic"]))
    if f_shape == "jump":
        base = base + np.where(np.arange(n) >= n // 2, data.draw(st.floats(1.0, 150.0)), 0.0)
    elif f_shape == "cubic":
        base = base ** 3 / 65.0 ** 2
    f = np.round(base * f_scale * Q).astype(np.int64)
    f = np.clip(f, -2**31 + 1, 2**31 - 1)
    f[1:] = np.maximum(f[1:], f[:-1] + 1) if np.all(np.diff(f) >= 0) else f[1:]  # keep it strictly monotone
    if np.any(np.abs(f) >= 2**31):
        return
    t = reseal(blob, q_range=q_range, b=b, f=f)
    st_ = _load(t)
    ok = _plausible(*q_range, 0.25 * Q, b, f, _instrument(blob))
    event(f"{'within' if ok else 'outside'} the rules, {'accepted' if st_ == lib.CALIB_OK else 'refused'}")
    if st_ == lib.CALIB_OK:
        assert ok, (q_range, b_level, f_scale, f_shape)
    if not ok:
        assert st_ != lib.CALIB_OK


def test_micrometres_calibrated_as_millimetres_refused_by_tables():
    """A session in micrometres read as millimetres: a 6000 "mm" travel and a 500 "mm" play. The
    table is built (valid CRC, valid structure) and refused by the loader `tables` runs, naming
    the rule and its numbers."""
    from playscope.fit.table_build import TableError, build_table

    with pytest.raises(TableError, match=r"CALIB_ERR_TRAVEL_UNIT: .*6000 mm against the limit 200 mm"):
        build_table(lambda q: np.full(np.shape(q), 500.0), lambda q: 0.01 * np.asarray(q), -3000.0, 3000.0, "mm")
