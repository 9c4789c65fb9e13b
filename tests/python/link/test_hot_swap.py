"""A table committed while the virtual board compensates (the host refreshes
f_remain and an offset during use without stopping the loop). ps_vboard runs psa_tick between
requests all along; after the commit the board's set-points are, bit for bit, the core's
compensator that kept its state and switched to the new table."""

from __future__ import annotations

import math

import pytest

from playscope.board.link import Link
from playscope.board.transport import virtual_transport
from playscope.base.native import core
from playscope.fit.table_build import CalibTable, write_blob


def table(generation: int, offset_deg: float) -> bytes:
    """The demo table's B and f, f shifted by offset_deg (what a host refresh of the offset sends)."""
    n, step, x0 = 256, 2 ** 11, int(-4.0 * 65536)
    qs = [(x0 + i * step) / 65536 for i in range(n)]
    b = [int(round((0.4 + 0.3 * math.exp(-q * q / 2)) * 65536)) for q in qs]
    f = [int(round((10 * q + 0.3 * q ** 3 + offset_deg) * 65536)) for q in qs]
    return write_blob(x0, step, b, f, -4.0, (x0 + (n - 1) * step) / 65536, "mm", "remain", generation)


@pytest.fixture
def vlink(tmp_path):
    link = Link(virtual_transport(tmp_path / "flash.bin"))
    yield link
    link.close()


def test_commit_during_compensation_carries_on(vlink):
    ffi, lib = core()
    t1, t2 = CalibTable(table(1, 0.0)), CalibTable(table(2, 1.5))
    vlink.upload_table(t1.blob)
    vlink.set_mode("compensation")
    cp = ffi.new("comp_t *")
    c_ref = [int(30.0 * math.sin(k * 0.05) * 65536) for k in range(240)]
    lib.comp_reset(cp, t1.cal, ffi.NULL, c_ref[0])
    swapped_at = 100  # mid-stroke: c* rising, the compensator's direction known
    rearmed = ffi.new("comp_t *")
    differs = 0
    for k, c in enumerate(c_ref):
        if k == swapped_at:
            info = vlink.upload_table(t2.blob)
            assert info["active_generation"] == 2
            assert vlink.info()["mode"] == "compensation"
            lib.comp_rebind(cp, t2.cal)  # the board's hot swap: state kept, cached cells emptied
            lib.comp_reset(rearmed, t2.cal, ffi.NULL, c)  # what a stop-and-restart would do
        want = lib.comp_step(cp, c)
        assert vlink.comp_step(c) == want, f"step {k}"
        if swapped_at <= k < swapped_at + 3:
            differs += lib.comp_step(rearmed, c) != want
    assert differs > 0  # carrying the state is not what a restart gives
