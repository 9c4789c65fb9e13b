"""The emulated USB board (ps_usbemu, umockdev): find or build it, and run commands against it.

``ps_usbemu [--flash FILE] -- COMMAND...`` makes a umockdev testbed holding one USB device
1209:0001 whose usbdevfs ioctls (URBs) are answered by the firmware's portable USB core
(firmware/link/usb) in front of a ps_vboard process, and runs COMMAND with
libumockdev-preload, so COMMAND's own libusb (``--device usb``, pyusb) talks to it:

    ps_usbemu -- playscope flash demo --device usb

The preload has to be in the process from its start, so the USB path cannot be emulated
inside an already running Python; tests and the bench run a child under the emulator.
Found as $PLAYSCOPE_USBEMU, in build/desktop-release or build/desktop, or compiled from the
sources into the cache (needs libumockdev-dev and pkg-config).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

from ..native import REPO, NativeBuildError
from .native import COMMON, DESKTOP, LINK, _cache_dir, _lock, vboard_path

USB = LINK / "usb"


def usbemu_sources() -> list[Path]:
    return [DESKTOP / "usb_emu.c", USB / "psu_device.c"]


def usbemu_path() -> Path:
    """Path of ps_usbemu, compiling it if no build has one. Raises NativeBuildError when
    umockdev's development files are missing."""
    env = os.environ.get("PLAYSCOPE_USBEMU")
    if env:
        return Path(env)
    for preset in ("desktop-release", "desktop"):
        p = REPO / "build" / preset / "link-desktop-board" / "ps_usbemu"
        if p.is_file() and all(p.stat().st_mtime >= s.stat().st_mtime for s in usbemu_sources()):
            return p
    headers = list(USB.glob("*.h")) + list(COMMON.glob("*.h"))
    target = _cache_dir("usbemu", usbemu_sources() + headers)
    exe = target / "ps_usbemu"
    with _lock:
        if not exe.is_file():
            try:
                flags = subprocess.run(["pkg-config", "--cflags", "--libs", "umockdev-1.0"],
                                       capture_output=True, text=True, check=True).stdout.split()
            except (OSError, subprocess.CalledProcessError):
                raise NativeBuildError("umockdev-1.0 not found (apt-get install libumockdev-dev pkg-config)") from None
            target.mkdir(parents=True, exist_ok=True)
            cc = os.environ.get("CC") or shutil.which("cc") or "gcc"
            tmp = target / f"ps_usbemu.{os.getpid()}"
            cmd = [cc, "-std=c11", "-O2", "-Wall", f"-I{COMMON}", f"-I{USB}", *map(str, usbemu_sources()),
                   *flags, "-lpthread", "-o", str(tmp)]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                raise NativeBuildError(f"compiling ps_usbemu failed:\n{r.stderr}")
            os.replace(tmp, exe)
    return exe


def usbemu_argv(flash_file: str | os.PathLike | None = None, trace: bool = False) -> list[str]:
    """The prefix that runs a command with the emulated board attached."""
    argv = [str(usbemu_path()), "--vboard", str(vboard_path())]
    if flash_file:
        argv += ["--flash", str(flash_file)]
    if trace:
        argv.append("--trace")
    return argv + ["--"]


def run(cmd: list[str], flash_file=None, timeout_s: float = 120.0, **kw) -> subprocess.CompletedProcess:
    """Run cmd with the emulated board; output captured as text."""
    return subprocess.run(usbemu_argv(flash_file) + cmd, capture_output=True, text=True,
                          timeout=timeout_s, **kw)
