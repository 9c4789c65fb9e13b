"""The USB path end to end in CI: the host's unmodified pyusb/libusb code (UsbTransport) against
the emulated USB board (ps_usbemu: umockdev testbed device 1209:0001, URBs answered by the
firmware's portable USB core, bulk data to ps_vboard). Flash, read back identical,
compensator bit for bit, replay refused; the CLI's `device info` / `flash --device usb`."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from playscope.base.native import NativeBuildError

CLIENT = Path(__file__).with_name("usb_emu_client.py")


def _emu_or_skip():
    try:
        import usb  # noqa: F401  (pyusb, a host dependency)
    except ImportError:
        pytest.skip("pyusb not installed")
    if not Path("/usr/lib/x86_64-linux-gnu/libumockdev-preload.so.0").exists() and \
            shutil.which("umockdev-wrapper") is None:
        pytest.skip("libumockdev-preload not installed")
    from playscope.board import usbemu
    try:
        usbemu.usbemu_path()
    except NativeBuildError as e:
        pytest.skip(str(e))
    return usbemu


def _playscope(*args) -> list[str]:
    return [sys.executable, "-c", "import sys; from playscope.cli import main; sys.exit(main())", *args]


def test_usb_emulated_flash_readback_compensator(tmp_path):
    usbemu = _emu_or_skip()
    r = usbemu.run([sys.executable, str(CLIENT), "check"], flash_file=tmp_path / "flash.bin")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["info"]["proto_version"] == 1
    assert out["info"]["board_id"].startswith("56495254")  # the virtual board behind the USB device
    assert out["flash"]["generation"] == 1 and out["flash"]["slot"] == "A"
    assert out["readback_identical"] and out["bytes"] == 2152  # the built-in table, layout 5
    assert out["comp_steps"] == 300 and out["comp_mismatches"] == 0
    assert out["replay_error"] == 4  # PSP_ERR_SEQ
    from playscope.fit.pacing import pace_v_q32

    assert out["exc_config"]["v_q32"] == pace_v_q32(0.35, 0.8, 25.0)  # the board's own pacing, host's rule
    assert out["exc_config"]["frame_period_us"] == 40000


def test_usb_emulated_cli_info_and_flash(tmp_path):
    usbemu = _emu_or_skip()
    flash_file = tmp_path / "flash.bin"
    r = usbemu.run(_playscope("flash", "builtin", "--device", "usb", "--vectors", "100"), flash_file=flash_file)
    assert r.returncode == 0, r.stderr
    assert "read back identical" in r.stdout and "bit-identical" in r.stdout
    # A second run of the emulator over the same flash file: the board kept the table.
    r = usbemu.run(_playscope("device", "info", "--device", "usb", "--json", "-"), flash_file=flash_file)
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["active_generation"] == 1 and info["active_slot"] == "A"

