"""The emulated USB board (ps_usbemu, umockdev): find or build it, and run commands against it.

``ps_usbemu [--flash FILE] -- COMMAND...`` makes a umockdev testbed holding one USB device with
the board's ids (PSU_VID:PSU_PID, firmware/link/usb/psu_device.h) whose usbdevfs ioctls (URBs) are answered by the firmware's portable USB core
(firmware/link/usb) in front of a ps_vboard process, and runs COMMAND with
libumockdev-preload, so COMMAND's own libusb (``--device usb``, pyusb) talks to it:

    ps_usbemu -- playscope flash builtin --device usb

The preload has to be in the process from its start, so the USB path cannot be emulated
inside an already running Python; tests and the bench run a child under the emulator.
Found as $PLAYSCOPE_USBEMU or built by CMake (playscope.base.native.executable; needs
libumockdev-dev and pkg-config).
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from ..base.native import executable


def usbemu_path() -> Path:
    """Path of ps_usbemu (built by CMake on first use). Raises NativeBuildError when
    umockdev's development files are missing."""
    return executable("ps_usbemu")


def usbemu_argv(flash_file: str | os.PathLike | None = None, trace: bool = False) -> list[str]:
    """The prefix that runs a command with the emulated board attached."""
    argv = [str(usbemu_path()), "--vboard", str(executable("ps_vboard"))]
    if flash_file:
        argv += ["--flash", str(flash_file)]
    if trace:
        argv.append("--trace")
    return argv + ["--"]


def run(cmd: list[str], flash_file=None, timeout_s: float = 120.0, **kw) -> subprocess.CompletedProcess:
    """Run cmd with the emulated board; output captured as text."""
    return subprocess.run(usbemu_argv(flash_file) + cmd, capture_output=True, text=True,
                          timeout=timeout_s, **kw)
