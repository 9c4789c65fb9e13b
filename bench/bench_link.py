"""Device-link bench: time to flash a full-size table (256 entries per grid, 2108 B) and
round-trip latency per frame, over each transport that is available here.

Usage: .venv/bin/python bench/bench_link.py [--repeat N]   (~15 s with QEMU)
Transports: virtual (ps_vboard over pipes), qemu (link firmware, USART1 over TCP).
USB is not measured: there is no hardware and the emulated device is not built yet."""

from __future__ import annotations

import argparse
import statistics
import time

from playscope.device.cli import flash
from playscope.device.link import Link
from playscope.device.tables import demo_table
from playscope.device.transport import QemuTransport, TransportError, find_qemu_image, virtual_transport


def measure(name, make, repeat):
    try:
        link = Link(make())
    except TransportError as e:
        print(f"{name:8s} skipped: {e}")
        return
    try:
        up, rb, rt = [], [], []
        for _ in range(repeat):
            r = flash(link, demo_table(), 50, log=lambda *_: None)
            up.append(r["upload_s"] * 1e3)
            rb.append(r["readback_s"] * 1e3)
        for _ in range(200):
            t = time.perf_counter()
            link.info()
            rt.append((time.perf_counter() - t) * 1e6)
        print(f"{name:8s} flash 2108 B (begin+10 chunks+commit): median {statistics.median(up):7.1f} ms, "
              f"read-back {statistics.median(rb):6.1f} ms, INFO round trip median "
              f"{statistics.median(rt):7.0f} us (p95 {sorted(rt)[int(0.95 * len(rt))]:.0f} us)")
    finally:
        link.close()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=10)
    a = ap.parse_args()
    measure("virtual", virtual_transport, a.repeat)
    if find_qemu_image():
        measure("qemu", QemuTransport, a.repeat)
    else:
        print("qemu     skipped: no playscope-link-fw image")


if __name__ == "__main__":
    main()
