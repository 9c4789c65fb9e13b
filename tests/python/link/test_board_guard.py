"""The board guards its instrument (docs/robustness.md, "The board guards its instrument"): its own
limits (ps_vboard --instrument / --unit / --q-limit / --b-max, psb_config.h on the STM32), which
no table widens, refuse a table for another instrument, in another unit or beyond them, through
`flash` (the host checks first with the same C and sends nothing) and through the raw link frames
(the board's loader); the generation counter is stepped, so 0xFFFFFFFF from a host is refused,
and a board left at 0xFFFFFFFF (by an older firmware) takes no table until the physical path
(--recover, the STM32's recovery pin) erases its slots. On the virtual board and under QEMU, whose
image boots on what `-device loader` puts in the table sectors 10/11 (the programming port's
part); QEMU 7.2 models no GPIO, so the pin's path is the virtual board's alone."""

from __future__ import annotations

import re
import shutil
import struct

import pytest

from playscope.base.native import core
from playscope.board.flash import flash
from playscope.board.link import DeviceError, Link
from playscope.board.table_check import TableFileError
from playscope.board.transport import QemuTransport, find_qemu_image, open_transport
from playscope.fit.table_build import builtin_table, set_generation, write_blob

SLOT = 128 * 1024  # ps_vboard's slot (VB_SLOT_SIZE), the STM32F405's sectors 10 and 11
TABLE_SECTORS = 0x080C0000  # sector 10 (stm32f405.ld __table_slot_a)


def _board(*args, flash_file=None) -> Link:
    return Link(open_transport("virtual", flash_file=flash_file, vboard_args=list(args)))


def _refused_raw(link: Link, blob: bytes) -> int:
    """Upload blob over the raw frames (no host check); returns the TABLE refusal's detail."""
    ffi, lib = core()
    with pytest.raises(DeviceError) as e:
        link.upload_table(blob)
    assert e.value.code == lib.PSP_ERR_TABLE
    return e.value.detail


@pytest.mark.parametrize("args,code", [
    (["--instrument", "2"], "CALIB_ERR_BOARD_INSTRUMENT"),
    (["--unit", "deg"], "CALIB_ERR_BOARD_UNIT"),
    (["--q-limit", "3"], "CALIB_ERR_BOARD_TRAVEL"),  # the table spans [-4, 4] mm
    (["--c-limit", "45"], "CALIB_ERR_BOARD_ANGLE"),  # its f reaches about +-59 deg
    (["--b-max", "0.5"], "CALIB_ERR_BOARD_B"),       # its instrument's largest play is 1.4 mm
])
def test_board_refuses_beyond_its_own_limits(args, code):
    ffi, lib = core()
    blob = builtin_table()
    link = _board(*args)
    try:
        with pytest.raises(TableFileError, match=code):  # the host checks first: nothing sent
            flash(link, blob)
        assert link.info()["active_generation"] == 0
        assert _refused_raw(link, set_generation(blob, 1)) == getattr(lib, code)  # the board itself
        assert link.info()["active_generation"] == 0
    finally:
        link.close()


def test_board_refuses_a_table_naming_no_instrument():
    """A layout-4-or-older table (what hosts wrote before the instrument block) is refused."""
    ffi, lib = core()
    hd = ffi.new("pst_header_t *")
    v5 = builtin_table()
    ffi.memmove(hd, v5, ffi.sizeof("pst_header_t"))
    b = list(ffi.cast("int32_t *", ffi.from_buffer(v5) + hd.b.offset)[0:hd.b.n])
    f = list(ffi.cast("int32_t *", ffi.from_buffer(v5) + hd.f.offset)[0:hd.f.n])
    hd.generation, hd.layout_version = 1, 0  # 0: table_write's own choice, layout 2 here
    buf = ffi.new("uint8_t[]", lib.PST_MAX_TABLE_SIZE)
    n = lib.table_write(buf, lib.PST_MAX_TABLE_SIZE, hd, ffi.new("int32_t[]", b), ffi.new("int32_t[]", f),
                        ffi.NULL, ffi.NULL)
    assert n > 0
    v2 = bytes(ffi.buffer(buf, n))
    link = _board()
    try:
        assert _refused_raw(link, v2) == lib.CALIB_ERR_UNBOUND
        with pytest.raises(TableFileError, match="CALIB_ERR_UNBOUND"):
            flash(link, v2)
    finally:
        link.close()


def _exhausted_image(path, blob: bytes) -> None:
    """A virtual board's flash file whose slot A holds blob as generation 0xFFFFFFFF, as an older
    firmware (which took any newer generation) left it: the store's record written as
    firmware/storage/pss_store.c does (docs/protocol.md, the slot table)."""
    ffi, lib = core()
    blob = set_generation(blob, 0xFFFFFFFF)
    crc = lambda b: int(lib.ps_crc32_update(1, b, len(b)))  # noqa: E731  (seeded with PSS_LAYOUT_VERSION)
    head = struct.pack("<4I", 0x4C535350, 0xFFFFFFFF, len(blob), crc(blob))
    rec = head + struct.pack("<I", crc(head)) + struct.pack("<I", 0xC0DEC0DE)
    slot = rec + b"\xff" * (32 - len(rec)) + blob
    img = slot + b"\xff" * (SLOT - len(slot)) + b"\xff" * SLOT
    path.write_bytes(img)


def _assert_stuck_at_exhausted(link, blob) -> None:
    """A board at generation 0xFFFFFFFF: `flash` stops before sending (naming the physical path)
    and the board itself refuses a commit at any generation (0x80)."""
    assert link.info()["active_generation"] == 0xFFFFFFFF
    with pytest.raises(RuntimeError, match="physical path"):
        flash(link, blob, log=lambda s: None)
    for gen in (0, 1, 0xFFFFFFFF):
        assert _refused_raw(link, set_generation(blob, gen)) == 0x80


def test_exhausted_generation_recovers_only_by_presence(tmp_path):
    ffi, lib = core()
    blob = builtin_table()
    # A host sending 0xFFFFFFFF today is refused: the counter steps by at most 16.
    link = _board()
    try:
        assert _refused_raw(link, set_generation(blob, 0xFFFFFFFF)) == 0x80
        assert _refused_raw(link, set_generation(blob, 17)) == 0x80
        flash(link, blob, n_vectors=4, log=lambda s: None)
        assert link.info()["active_generation"] == 1
    finally:
        link.close()
    # A board an older firmware left at 0xFFFFFFFF.
    img = tmp_path / "board.img"
    _exhausted_image(img, blob)
    for _ in range(2):  # a restart alone changes nothing
        link = _board(flash_file=img)
        try:
            _assert_stuck_at_exhausted(link, blob)
        finally:
            link.close()
    link = _board("--recover", flash_file=img)  # the recovery pin held at reset
    try:
        assert link.info()["active_generation"] == 0
        r = flash(link, blob, n_vectors=4, log=lambda s: None)
        assert r["generation"] == 1
    finally:
        link.close()
    link = _board(flash_file=img)
    try:
        assert link.info()["active_generation"] == 1
    finally:
        link.close()


@pytest.mark.skipif(shutil.which("qemu-system-arm") is None or find_qemu_image() is None,
                    reason="needs qemu-system-arm and the playscope-link-fw image (stm32f405 preset)")
def test_qemu_board_guards_its_instrument():
    """The STM32F405 link firmware (psb_config.h defaults: instrument 1, mm, +-20 mm, +-180 deg,
    play <= 5 mm) answers its limits, refuses another instrument's table and 0xFFFFFFFF."""
    ffi, lib = core()
    link = Link(QemuTransport())
    try:
        lim = link.board_limits()
        assert (lim.instrument_id, lim.q_unit, lim.q_max_q16, lim.b_max_q16) == \
            (lib.PST_INSTRUMENT_DEFAULT, lib.PST_Q_UNIT_MM, 20 << 16, 5 << 16)
        blob = builtin_table()
        hd = ffi.new("pst_header_t *")
        ffi.memmove(hd, blob, ffi.sizeof("pst_header_t"))
        b = list(ffi.cast("int32_t *", ffi.from_buffer(blob) + hd.b.offset)[0:hd.b.n])
        f = list(ffi.cast("int32_t *", ffi.from_buffer(blob) + hd.f.offset)[0:hd.f.n])
        q0, q1 = hd.q_min_q16 / 65536, hd.q_max_q16 / 65536
        other = write_blob(hd.b.x0_q16, hd.b.step_q16, b, f, q0, q1, instrument=7)
        with pytest.raises(TableFileError, match="CALIB_ERR_BOARD_INSTRUMENT"):
            flash(link, other)
        assert _refused_raw(link, other) == lib.CALIB_ERR_BOARD_INSTRUMENT
        assert _refused_raw(link, set_generation(blob, 0xFFFFFFFF)) == 0x80
        assert link.info()["active_generation"] == 0
        r = flash(link, blob, n_vectors=4, log=lambda s: None)
        assert r["generation"] == 1
    finally:
        link.close()


def _qemu_board(img) -> tuple[Link, object]:
    """The STM32F405 link firmware booted with sectors 10/11 holding the file img (2 x 128 KiB), as
    the programming port would leave them; QEMU's unimplemented-device accesses logged to the
    returned path."""
    log = img.with_suffix(".log")
    args = ["-device", f"loader,file={img},addr={TABLE_SECTORS:#x}", "-d", "unimp", "-D", str(log)]
    return Link(QemuTransport(qemu_args=args)), log


@pytest.mark.skipif(shutil.which("qemu-system-arm") is None or find_qemu_image() is None,
                    reason="needs qemu-system-arm and the playscope-link-fw image (stm32f405 preset)")
def test_qemu_exhausted_generation_recovers_only_by_the_erase(tmp_path):
    """Booted on sectors an older firmware left at generation 0xFFFFFFFF, the STM32F405 image
    refuses every commit; booted after the programming port's erase of sectors 10 and 11
    (`st-flash erase 0x080C0000 0x40000`: all 0xFF) it takes a table as generation 1. The
    recovery pin cannot be held under QEMU: the log shows its read answered by GPIOA's
    unimplemented-device stub (always 0)."""
    blob = builtin_table()
    _exhausted_image(tmp_path / "exhausted.bin", blob)
    link, log = _qemu_board(tmp_path / "exhausted.bin")
    try:
        _assert_stuck_at_exhausted(link, blob)
        assert link.info()["active_generation"] == 0xFFFFFFFF
    finally:
        link.close()
    # The pin's input register (GPIOA_IDR, offset 0x10) read at boot, by a stub QEMU does not model.
    assert re.search(r"GPIOA: unimplemented device read\s+\(size 4, offset 0x010\)", log.read_text())
    (tmp_path / "erased.bin").write_bytes(b"\xff" * (2 * SLOT))
    link, _ = _qemu_board(tmp_path / "erased.bin")
    try:
        assert link.info()["active_generation"] == 0
        r = flash(link, blob, n_vectors=4, log=lambda s: None)
        assert r["generation"] == 1
        assert link.info()["active_generation"] == 1
    finally:
        link.close()
