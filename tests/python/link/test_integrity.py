"""Integrity end to end: a damaged table file is refused before anything reaches a
board, with a message naming the field (flipped data byte, flipped CRC, flipped q_max bit with
a stale CRC), on the virtual board, through the CLI, and over the emulated USB device."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from playscope.board.flash import flash
from playscope.board.link import Link
from playscope.fit.table_build import builtin_table
from playscope.board.transport import virtual_transport
from playscope.base.native import core
from playscope.board.table_check import TableFileError, check_blob

GUARD_CLIENT = Path(__file__).with_name("usb_guard_client.py")


def _off(field: str) -> int:
    ffi, _ = core()
    return ffi.offsetof("pst_header_t", field)


def corruptions() -> dict[str, tuple[bytes, str]]:
    """name -> (damaged blob, the field the refusal must name)."""
    good = builtin_table()
    out = {}
    b = bytearray(good)
    b[700] ^= 0x10                      # one data byte (an f entry), CRC left as written
    out["data_byte"] = (bytes(b), "crc32")
    b = bytearray(good)
    b[_off("crc32")] ^= 0x01            # the CRC field itself
    out["crc_field"] = (bytes(b), "crc32")
    b = bytearray(good)
    b[_off("q_max_q16") + 2] ^= 0x04    # q_max + 4 units, past the grids, CRC stale
    out["q_max_bit"] = (bytes(b), "q_max")
    b = bytearray(good)
    b[_off("q_max_q16") + 1] ^= 0x08    # q_max - 2048 raw: still inside the grids, so the CRC catches it
    out["q_max_low_bit"] = (bytes(b), "crc32")
    b = bytearray(good)
    b[0] ^= 0xFF
    out["magic"] = (bytes(b), "magic")
    out["truncated"] = (good[:-4], "total_size")
    out["short"] = (good[:20], "size")
    b = bytearray(good)
    b[_off("layout_version")] = 9
    out["version"] = (bytes(b), "layout_version")
    return out


CASES = corruptions()


@pytest.mark.parametrize("name", sorted(CASES))
def test_check_names_the_field(name):
    blob, field = CASES[name]
    with pytest.raises(TableFileError) as e:
        check_blob(blob, "t.pstb")
    assert e.value.field == field
    msg = str(e.value)
    assert msg.startswith("t.pstb: ") and "\n" not in msg and "playscope tables" in msg


def test_every_q_max_bit_flip_refused():
    good = builtin_table()
    for bit in range(32):
        b = bytearray(good)
        b[_off("q_max_q16") + bit // 8] ^= 1 << (bit % 8)
        with pytest.raises(TableFileError) as e:
            check_blob(bytes(b))
        assert e.value.field in ("q_max", "q_min/q_max", "crc32")


def test_good_table_passes():
    hd = check_blob(builtin_table())
    assert hd.total_size == len(builtin_table())


@pytest.mark.parametrize("name", ["data_byte", "crc_field", "q_max_bit"])
def test_virtual_board_nothing_sent(name, tmp_path):
    blob, field = CASES[name]
    link = Link(virtual_transport(tmp_path / "flash.bin"))
    try:
        flash(link, builtin_table(), 10, log=lambda *_: None)
        before = link.info()
        n0 = link.n_requests
        with pytest.raises(TableFileError) as e:
            flash(link, blob, 10, log=lambda *_: None)
        assert e.value.field == field
        assert link.n_requests == n0  # not one request went out
        after = link.info()
        assert (after["active_generation"], after["active_crc32"]) == \
            (before["active_generation"], before["active_crc32"])
    finally:
        link.close()


@pytest.mark.parametrize("name", ["data_byte", "crc_field", "q_max_bit"])
def test_cli_refuses_before_opening_the_board(name, tmp_path):
    blob, field = CASES[name]
    path = tmp_path / "bad.pstb"
    path.write_bytes(blob)
    flash_file = tmp_path / "flash.bin"
    r = subprocess.run([sys.executable, "-c", "import sys; from playscope.cli import main; sys.exit(main())",
                        "flash", str(path), "--flash-file", str(flash_file)], capture_output=True, text=True)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"playscope: error: {path}: {field}"), r.stderr
    assert not flash_file.exists()  # the board was never started
    assert path.read_bytes() == blob


def test_usb_emulated_nothing_sent(tmp_path):
    from .test_usb_umockdev import _emu_or_skip  # same skip rules as the USB path tests

    usbemu = _emu_or_skip()
    files = []
    for name in ("data_byte", "crc_field", "q_max_bit"):
        p = tmp_path / f"{name}.pstb"
        p.write_bytes(CASES[name][0])
        files.append(str(p))
    r = usbemu.run([sys.executable, str(GUARD_CLIENT), "corrupt", *files], flash_file=tmp_path / "flash.bin")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert [x["field"] for x in out["refused"]] == ["crc32", "crc32", "q_max"]
    assert all(x["requests_sent"] == 0 for x in out["refused"])
    assert out["generation_before"] == out["generation_after"] == 1



def test_generation_counter_at_maximum(tmp_path):
    """The board refuses generation 0xFFFFFFFF (it steps by 1..16); a board an older firmware left
    there is refused by the host before any upload request (test_board_guard.py: its recovery)."""
    from playscope.board.link import DeviceError, Link as L

    from .test_board_guard import _exhausted_image

    link = L(virtual_transport(tmp_path / "flash.bin"))
    try:
        with pytest.raises(DeviceError, match="generation not the next one"):
            link.upload_table(builtin_table(generation=0xFFFFFFFF))
        assert link.info()["active_generation"] == 0
    finally:
        link.close()
    _exhausted_image(tmp_path / "old.bin", builtin_table())
    link = L(virtual_transport(tmp_path / "old.bin"))
    try:
        n0 = link.n_requests
        with pytest.raises(RuntimeError, match="generation counter is at its end"):
            flash(link, builtin_table(), 5, log=lambda *_: None)
        assert link.n_requests == n0 + 2  # only the BOARD and INFO that read the limits and the counter
    finally:
        link.close()


def test_cli_qemu_without_image_and_usb_without_device(tmp_path):
    import os

    env = dict(os.environ, PLAYSCOPE_LINK_ELF=str(tmp_path / "missing.elf"))
    for extra in (["--device", "qemu"], ["--device", "usb"]):
        r = subprocess.run([sys.executable, "-c", "import sys; from playscope.cli import main; sys.exit(main())",
                            "flash", "builtin", *extra], capture_output=True, text=True, env=env)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("playscope: error: "), r.stderr
