"""Device link end to end: shared frame vectors through the host codec, flash to the virtual
board and to the STM32F405 link firmware under QEMU, read-back and compensator bit for bit."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from playscope.board.flash import flash
from playscope.board.link import DeviceError, Link
from playscope.base.native import frame_codec
from playscope.fit.table_build import builtin_table
from playscope.board.transport import QemuTransport, find_qemu_image, virtual_transport

VECTORS = Path(__file__).resolve().parents[2] / "link" / "vectors" / "frames.txt"


def test_shared_frame_vectors():
    ffi, lib = frame_codec()
    n = 0
    for line in VECTORS.read_text().splitlines():
        if not line or line.startswith("#"):
            continue
        t, s, pl, fr = line.split()
        pl = b"" if pl == "-" else bytes.fromhex(pl)
        out = ffi.new("uint8_t[]", lib.PSF_MAX_FRAME)
        k = lib.psf_encode(out, lib.PSF_MAX_FRAME, int(t, 16), int(s, 16), pl, len(pl))
        assert bytes(ffi.buffer(out, k)) == bytes.fromhex(fr)
        n += 1
    assert n >= 4


@pytest.fixture
def vlink(tmp_path):
    link = Link(virtual_transport(tmp_path / "flash.bin"))
    yield link
    link.close()


def test_virtual_flash_readback_compensator(vlink, tmp_path):
    r = flash(vlink, builtin_table(), 300, log=lambda *_: None)
    assert r["generation"] == 1 and r["slot"] == "A"
    r = flash(vlink, builtin_table(), 50, log=lambda *_: None)
    assert r["generation"] == 2 and r["slot"] == "B"
    vlink.close()
    # Reboot from the same flash file: the newest table comes back.
    link = Link(virtual_transport(tmp_path / "flash.bin"))
    try:
        info = link.info()
        assert info["active_generation"] == 2 and info["active_slot"] == "B"
        assert link.read_table()[60:] == builtin_table()[60:]
    finally:
        link.close()


def test_virtual_refusals(vlink):
    flash(vlink, builtin_table(), 10, log=lambda *_: None)
    with pytest.raises(DeviceError) as e:
        vlink.upload_table(builtin_table(generation=1))  # not newer than generation 1
    assert e.value.code == 8
    vlink.set_mode("excitation")
    with pytest.raises(DeviceError) as e:
        vlink.upload_table(builtin_table(generation=5))  # no commit during an excitation
    assert e.value.code == 6
    vlink.set_mode("idle")
    vlink.set_mode("compensation")  # (a commit here is taken: tests/python/link/test_hot_swap.py)
    # A replayed request (the seq of the last accepted one, SET_MODE) changes nothing.
    last = vlink.info()["last_seq"]
    with pytest.raises(DeviceError) as e:
        vlink.request(vlink.lib.PSP_MSG_SET_MODE, bytes([0, 0, 0, 0]), seq=last)
    assert e.value.code == 4
    assert vlink.info()["mode"] == "compensation"


def test_virtual_streaming(vlink):
    vlink.stream(True, 1)
    samples = []
    for _ in range(40):
        for kind, v in vlink.poll_events(0.05):
            if kind == "enc":
                samples += v
        if len(samples) >= 60:
            break
    vlink.stream(False)
    assert len(samples) >= 60
    t = [s[0] for s in samples]
    assert all(b - a == 1000 for a, b in zip(t, t[1:]))


@pytest.mark.skipif(shutil.which("qemu-system-arm") is None or find_qemu_image() is None,
                    reason="needs qemu-system-arm and the playscope-link-fw image (stm32f405 preset)")
def test_qemu_flash_readback_compensator():
    link = Link(QemuTransport())
    try:
        info = link.info()
        assert info["proto_version"] == 1 and info["board_id"].startswith("51454d55")
        r = flash(link, builtin_table(), 100, log=lambda *_: None)
        assert r["generation"] == 1
        check_learn_start_stop(link, builtin_table())
    finally:
        link.close()


@pytest.mark.skipif(shutil.which("qemu-system-arm") is None or find_qemu_image() is None,
                    reason="needs qemu-system-arm and the playscope-link-fw image (stm32f405 preset)")
def test_qemu_excitation_paced_to_the_camera():
    link = Link(QemuTransport())
    try:
        check_exc_config(link)
    finally:
        link.close()


def test_vboard_excitation_paced_to_the_camera(vlink):
    check_exc_config(vlink)


def check_exc_config(link) -> None:
    """run-insitu's excitation reaches the board on any image (PSP_MSG_EXC_CONFIG): paced to the
    camera, the board picks the host's speed (fit.pacing, the same C rule) to the bit and its
    set-points then climb at that speed (encoder stream, one sample per tick: the link images'
    motor is ideal); a play wider than the swing's down leg is refused with EXC_ERR_PACE and
    leaves the speed as it was; a given speed is run as is."""
    from playscope.base.native import core
    from playscope.fit.pacing import TICK_HZ, pace_v_q32

    lib = core()[1]
    link.set_mode("idle")
    got = link.exc_config("-3:3:1.6:0.4", 0.35, 0.8, 25.0)
    v_q32 = pace_v_q32(0.35, 0.8, 25.0)
    assert got["v_q32"] == v_q32 and got["frame_period_us"] == 40000
    # b_low x fps / EXC_PACE_FRAMES, b_low rounded to Q16 (half an LSB: 2.2e-5 of 0.35)
    assert got["v"] == pytest.approx(0.35 * 25.0 / 4, rel=3e-5)
    with pytest.raises(DeviceError) as e:
        link.exc_config("-3:3:1.6:0.4", 0.35, 1.3, 25.0)  # down leg 1.2 < widest play 1.3
    assert e.value.code == 7 and e.value.detail == lib.EXC_ERR_PACE
    assert _climb_q32_per_tick(link) == pytest.approx(v_q32, abs=2 ** 16)  # one Q16 LSB over the run
    got = link.exc_config("-3:3:1.6:0.4:1.5")
    assert got["v_q32"] == int(1.5 / TICK_HZ * 2 ** 32)
    assert _climb_q32_per_tick(link) == pytest.approx(got["v_q32"], abs=2 ** 16)


def _climb_q32_per_tick(link) -> float:
    """Run the excitation briefly with the encoder streamed; the set-point's rise per tick on the
    first (rising) leg, Q32.32 (from the first to the last streamed sample before the turn)."""
    link.stream(True, 1)
    link.set_mode("excitation")
    samples = []
    for _ in range(1200):  # up to 60 s: QEMU on a loaded machine runs the board's clock slower
        # (90 samples in 20 s beside two calibrations and the test suite; the loop ends at 200)
        for kind, v in link.poll_events(0.05):
            if kind == "enc":
                samples += v
        if len(samples) >= 200:
            break
    link.set_mode("idle")
    link.stream(False)
    link.poll_events(0.1)
    t = [a for a, _ in samples]
    q = [b for _, b in samples]
    k0 = next(i for i in range(1, len(q)) if q[i] > q[i - 1])  # the first tick of the run
    k1 = k0 + 150
    assert k1 < len(q), f"{len(q)} samples streamed, the run starting at {k0}"
    assert all(b > a for a, b in zip(q[k0:k1], q[k0 + 1:k1 + 1])), f"not a rising leg: {q[k0:k1 + 1]}"
    return (q[k1] - q[k0]) * 2 ** 16 / ((t[k1] - t[k0]) / 1000)


def check_learn_start_stop(link, blob: bytes) -> None:
    """On-line B update on a board running `blob` (PSP_MSG_LEARN): off at boot, start reports the
    table's B grid with the CRC of its flashed entries (computed here from the blob through the
    loader), nothing learnt without onsets, stop turns it off. The samples themselves are learnt
    in tests/link/test_link.c::test_learn_during_compensation."""
    from playscope.base.native import core
    from playscope.fit.table_build import CalibTable

    ffi, lib = core()
    t = CalibTable(blob)
    assert link.learn()["on"] == 0
    link.set_mode("compensation")
    st = link.learn("start")
    n = int(t.cal.b.n)
    assert st["on"] == 1 and st["n_grid"] == n and 2 <= st["n_nodes"] <= 16
    assert st["b_crc32"] == lib.ps_crc32_update(0, t.cal.b.y_q16, 4 * n)
    assert st["samples"] == 0 and st["queued"] == 0
    assert link.learn("stop")["on"] == 0
    link.set_mode("idle")


def test_vboard_learn_start_stop(vlink):
    with pytest.raises(DeviceError):
        vlink.learn("start")  # no table: refused (STATE), nothing started
    flash(vlink, builtin_table(), 20, log=lambda *_: None)
    check_learn_start_stop(vlink, builtin_table())
