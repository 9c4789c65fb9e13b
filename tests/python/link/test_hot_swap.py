"""A table committed while the virtual board compensates (the host refreshes
f_remain and an offset during use without stopping the loop). ps_vboard runs psa_tick between
requests all along; after the commit the board's set-points are, bit for bit, the core's
compensator that kept its state and switched to the new table: for the pure play and for a
transition table whose commit changes f only (the operators' states carry over). A commit that
changes the operators re-arms the compensator."""

from __future__ import annotations

import math

import pytest

from playscope.board.link import Link
from playscope.board.transport import virtual_transport
from playscope.base.native import core
from playscope.fit.table_build import CalibTable, write_blob


# A transition of three operators (thresholds in mm, weights summing to 1).
PI_R, PI_W = [0.0, 0.3, 0.8], [0.6, 0.25, 0.15]


def table(generation: int, offset_deg: float, pi_w=None) -> bytes:
    """The demo table's B and f, f shifted by offset_deg (what a host refresh of the offset sends);
    with pi_w, the transition operators PI_R with those weights."""
    n, step, x0 = 256, 2 ** 11, int(-4.0 * 65536)
    qs = [(x0 + i * step) / 65536 for i in range(n)]
    b = [int(round((0.4 + 0.3 * math.exp(-q * q / 2)) * 65536)) for q in qs]
    f = [int(round((10 * q + 0.3 * q ** 3 + offset_deg) * 65536)) for q in qs]
    return write_blob(x0, step, b, f, -4.0, (x0 + (n - 1) * step) / 65536, "mm", "remain", generation,
                      pi_r=PI_R if pi_w else None, pi_w=pi_w)


@pytest.fixture
def vlink(tmp_path):
    link = Link(virtual_transport(tmp_path / "flash.bin"))
    yield link
    link.close()


@pytest.mark.parametrize("pi_w", [None, PI_W], ids=["pure_play", "transition"])
def test_commit_during_compensation_carries_on(vlink, pi_w):
    ffi, lib = core()
    t1, t2 = CalibTable(table(1, 0.0, pi_w)), CalibTable(table(2, 1.5, pi_w))
    assert t1.cal.pi_inv.n == (3 if pi_w else 0)
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


def test_commit_with_other_operators_rearms(vlink):
    """Other weights: the operators' states do not carry over, the board restarts the
    compensator (the core's comp_reset on the new table, bit for bit): at the c* its ticks hold
    between requests, the last one sent before the commit."""
    ffi, lib = core()
    t1, t2 = CalibTable(table(1, 0.0, PI_W)), CalibTable(table(2, 1.5, [0.5, 0.3, 0.2]))
    vlink.upload_table(t1.blob)
    vlink.set_mode("compensation")
    cp = ffi.new("comp_t *")
    c_ref = [int(30.0 * math.sin(k * 0.05) * 65536) for k in range(160)]
    lib.comp_reset(cp, t1.cal, ffi.NULL, c_ref[0])
    kept = ffi.new("comp_t *")
    for k, c in enumerate(c_ref):
        if k == 100:
            vlink.upload_table(t2.blob)
            ffi.memmove(kept, cp, ffi.sizeof("comp_t"))
            lib.comp_rebind(kept, t2.cal)
            lib.comp_reset(cp, t2.cal, ffi.NULL, c_ref[k - 1])
        want = lib.comp_step(cp, c)
        assert vlink.comp_step(c) == want, f"step {k}"
        if k == 100:
            assert lib.comp_step(kept, c) != want  # keeping the state would have given another q*
