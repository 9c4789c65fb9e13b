"""Byte transports to a board: virtual board process, TCP (QEMU serial, vboard --listen), USB bulk."""

from __future__ import annotations

import os
import select
import socket
import subprocess
import time
from pathlib import Path

from ..base import native

# The USB ids and endpoints are the board's (firmware/link/usb/psu_device.h: a pid.codes test
# pair, see there), read through the native module when a USB transport opens.


class TransportError(OSError):
    """The link to the board failed (process exited, connection refused, USB error)."""


class Transport:
    """A duplex byte stream. read() returns b"" on timeout."""

    name = "?"

    def write(self, data: bytes) -> None:
        raise NotImplementedError

    def read(self, timeout_s: float) -> bytes:
        raise NotImplementedError

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class PipeTransport(Transport):
    """A child process speaking frames on stdin/stdout (the virtual board)."""

    def __init__(self, argv: list[str], name: str = "virtual"):
        self.name = name
        import tempfile

        # The board's stderr (it prints only start-up refusals: flash file locked or not an
        # image, bad options) goes to a file, so its reason becomes the one error line.
        self._err = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err,
                                         bufsize=0)
        except OSError as e:
            raise TransportError(f"cannot start {argv[0]}: {e}") from None

    def _why(self) -> str:
        """The board's last stderr line, if it exited saying why."""
        try:
            self.proc.wait(timeout=1)
        except subprocess.TimeoutExpired:
            pass
        self._err.seek(0)
        lines = self._err.read()[-4096:].decode("utf-8", "replace").strip().splitlines()
        return f": {lines[-1]}" if lines else ""

    def write(self, data: bytes) -> None:
        try:
            self.proc.stdin.write(data)
        except BrokenPipeError:
            raise TransportError(f"{self.name} board exited (status {self.proc.poll()}){self._why()}") from None

    def read(self, timeout_s: float) -> bytes:
        r, _, _ = select.select([self.proc.stdout], [], [], max(timeout_s, 0.0))
        if not r:
            return b""
        data = os.read(self.proc.stdout.fileno(), 4096)
        if not data:
            raise TransportError(f"{self.name} board closed the link (status {self.proc.poll()}){self._why()}")
        return data

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=3)
            except subprocess.TimeoutExpired:
                self.proc.terminate()
                self.proc.wait()
        self.proc.stdout.close()
        self._err.close()


def virtual_transport(flash_file: str | os.PathLike | None = None, extra_args=()) -> PipeTransport:
    """Start the virtual board (compiled on first use) with an optional file-backed flash.
    extra_args: more ps_vboard options (e.g. --time-scale, --exc for run-insitu --sim-plant)."""
    from ..base.native import executable

    argv = [str(executable("ps_vboard")), "--stdio"]
    if flash_file:
        argv += ["--flash", str(flash_file)]
    argv += list(extra_args)
    return PipeTransport(argv, "virtual")


class TcpTransport(Transport):
    """TCP to QEMU's USART1 (-serial tcp:...) or to ps_vboard --listen."""

    def __init__(self, host: str, port: int, name: str = "tcp", connect_timeout_s: float = 10.0):
        self.name = name
        deadline = time.monotonic() + connect_timeout_s
        while True:
            try:
                self.sock = socket.create_connection((host, port), timeout=2.0)
                break
            except OSError as e:
                if time.monotonic() > deadline:
                    raise TransportError(f"cannot connect to {host}:{port}: {e}") from None
                time.sleep(0.05)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def write(self, data: bytes) -> None:
        self.sock.sendall(data)

    def read(self, timeout_s: float) -> bytes:
        r, _, _ = select.select([self.sock], [], [], max(timeout_s, 0.0))
        if not r:
            return b""
        data = self.sock.recv(4096)
        if not data:
            raise TransportError(f"{self.name}: connection closed by the board")
        return data

    def close(self) -> None:
        self.sock.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def find_qemu_image() -> Path | None:
    from ..base.native import REPO

    env = os.environ.get("PLAYSCOPE_LINK_ELF")
    if env:
        return Path(env)
    p = REPO / "build" / "stm32f405" / "link-fw" / "playscope-link-fw.elf"
    return p if p.is_file() else None


class QemuTransport(TcpTransport):
    """The STM32F405 link firmware under qemu-system-arm (netduinoplus2), USART1 on TCP.
    qemu_args: more qemu-system-arm options (tests: `-device loader` filling the table sectors,
    `-d unimp -D LOG`)."""

    def __init__(self, elf: str | os.PathLike | None = None, qemu_args: list[str] | tuple[str, ...] = ()):
        elf = Path(elf) if elf else find_qemu_image()
        if not elf or not elf.is_file():
            raise TransportError("no link firmware image: build the stm32f405 preset "
                                 "(target playscope-link-fw) or set PLAYSCOPE_LINK_ELF")
        port = _free_port()
        argv = ["qemu-system-arm", "-M", "netduinoplus2", "-nographic", "-monitor", "none",
                "-semihosting-config", "enable=on,target=native",
                "-kernel", str(elf), "-serial", f"tcp:127.0.0.1:{port},server=on,wait=on,nodelay=on",
                *qemu_args]
        try:
            self.proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                         stderr=subprocess.PIPE)
        except OSError as e:
            raise TransportError(f"cannot start qemu-system-arm: {e}") from None
        try:
            super().__init__("127.0.0.1", port, name="qemu")
        except TransportError:
            self.proc.kill()
            raise

    def close(self) -> None:
        super().close()
        self.proc.terminate()
        try:
            self.proc.wait(timeout=3)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class UsbTransport(Transport):
    """Vendor-class interface 0 with the board's bulk OUT / IN endpoints, through pyusb/libusb.
    vid, pid: the board's USB ids (None: the firmware's PSU_VID / PSU_PID)."""

    name = "usb"

    def __init__(self, vid: int | None = None, pid: int | None = None, serial: str | None = None):
        vid = native.USB_VID if vid is None else vid
        pid = native.USB_PID if pid is None else pid
        self._ep_out, self._ep_in = native.USB_EP_OUT, native.USB_EP_IN
        try:
            import usb.core
            import usb.util
        except ImportError:
            raise TransportError("pyusb is not installed") from None
        self._usb = usb
        kw = {"idVendor": vid, "idProduct": pid}
        if serial:
            kw["serial_number"] = serial
        try:
            self.dev = usb.core.find(**kw)
        except usb.core.NoBackendError:
            raise TransportError("libusb not found (install libusb-1.0)") from None
        if self.dev is None:
            raise TransportError(f"no USB device {vid:04x}:{pid:04x} (udev rule installed? "
                                 "see tools/udev/99-playscope.rules)")
        try:
            if self.dev.is_kernel_driver_active(0):
                self.dev.detach_kernel_driver(0)
        except (NotImplementedError, usb.core.USBError):
            pass
        usb.util.claim_interface(self.dev, 0)

    def write(self, data: bytes) -> None:
        try:
            self.dev.write(self._ep_out, data, timeout=2000)
        except self._usb.core.USBError as e:
            raise TransportError(f"usb write: {e}") from None

    def read(self, timeout_s: float) -> bytes:
        try:
            return bytes(self.dev.read(self._ep_in, 512, timeout=max(1, int(timeout_s * 1000))))
        except self._usb.core.USBTimeoutError:
            return b""
        except self._usb.core.USBError as e:
            if getattr(e, "errno", None) == 110:
                return b""
            raise TransportError(f"usb read: {e}") from None

    def close(self) -> None:
        try:
            self._usb.util.release_interface(self.dev, 0)
            self._usb.util.dispose_resources(self.dev)
        except Exception:
            pass


def open_transport(kind: str, *, flash_file=None, elf=None, address: str | None = None,
                   vboard_args=()) -> Transport:
    """kind: 'virtual' | 'qemu' | 'usb' | 'tcp' (address host:port). vboard_args: extra
    ps_vboard options, virtual only."""
    if kind == "virtual":
        return virtual_transport(flash_file, vboard_args)
    if kind == "qemu":
        if address:
            host, port = address.rsplit(":", 1)
            return TcpTransport(host, int(port), name="qemu")
        return QemuTransport(elf)
    if kind == "usb":
        return UsbTransport()
    if kind == "tcp":
        host, port = (address or "127.0.0.1:5555").rsplit(":", 1)
        return TcpTransport(host, int(port))
    raise ValueError(f"unknown device kind {kind!r}")
