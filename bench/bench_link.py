"""Device-link bench: time to flash a full-size table (256 entries per grid, 2108 B) and
round-trip latency per frame, over each transport that is available here.

Usage: .venv/bin/python bench/bench_link.py [--repeat N]   (~15 s with QEMU)
Transports: virtual (ps_vboard over pipes), qemu (link firmware, USART1 over TCP),
usb-emulated (pyusb/libusb -> umockdev testbed device -> firmware USB core -> ps_vboard; run
as a child under ps_usbemu, because libumockdev-preload must be there from process start).
Real USB hardware is not measured: there is none here."""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from playscope.board.flash import flash
from playscope.board.link import Link
from playscope.fit.table_build import builtin_table
from playscope.board.transport import QemuTransport, TransportError, find_qemu_image, virtual_transport


def report(name, up, rb, rt):
    """One line per transport: median and worst of every flash (upload_ms), read-back and
    INFO round trip (p95 too), over all repeats, none dropped."""
    print(f"{name:8s} flash 2108 B (begin+10 chunks+commit): median {statistics.median(up):7.1f} ms "
          f"(worst {max(up):.1f} ms, n = {len(up)}), read-back {statistics.median(rb):6.1f} ms "
          f"(worst {max(rb):.1f} ms), INFO round trip median {statistics.median(rt):7.0f} us "
          f"(p95 {sorted(rt)[int(0.95 * len(rt))]:.0f} us, worst {max(rt):.0f} us, n = {len(rt)})")


def measure(name, make, repeat):
    try:
        link = Link(make())
    except TransportError as e:
        print(f"{name:8s} skipped: {e}")
        return
    try:
        up, rb, rt = [], [], []
        for _ in range(repeat):
            r = flash(link, builtin_table(), 50, log=lambda *_: None)
            up.append(r["upload_s"] * 1e3)
            rb.append(r["readback_s"] * 1e3)
        for _ in range(200):
            t = time.perf_counter()
            link.info()
            rt.append((time.perf_counter() - t) * 1e6)
        report(name, up, rb, rt)
    finally:
        link.close()


def measure_usb_emulated(repeat):
    from playscope.board import usbemu
    from playscope.base.native import NativeBuildError

    client = Path(__file__).resolve().parents[1] / "tests" / "python" / "link" / "usb_emu_client.py"
    try:
        r = usbemu.run([sys.executable, str(client), "bench", str(repeat)], timeout_s=300)
    except (NativeBuildError, OSError) as e:
        print(f"usb-emu  skipped: {e}")
        return
    if r.returncode != 0:
        print(f"usb-emu  failed: {r.stderr.strip()[-300:]}")
        return
    d = json.loads(r.stdout.strip().splitlines()[-1])
    up = [x * 1e3 for x in d["upload_s"]]
    rb = [x * 1e3 for x in d["readback_s"]]
    rt = [x * 1e6 for x in d["info_rt_s"]]
    report("usb-emu", up, rb, rt)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=10)
    a = ap.parse_args()
    measure("virtual", virtual_transport, a.repeat)
    if find_qemu_image():
        measure("qemu", QemuTransport, a.repeat)
    else:
        print("qemu     skipped: no playscope-link-fw image")
    measure_usb_emulated(a.repeat)


if __name__ == "__main__":
    main()
