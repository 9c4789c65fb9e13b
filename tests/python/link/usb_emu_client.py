"""Runs under ps_usbemu (LD_PRELOAD=libumockdev-preload): flashes over the emulated USB device
with the host's unmodified UsbTransport (pyusb/libusb) and prints what it saw as JSON.
Used by test_usb_umockdev.py and bench/bench_link.py; not a test module itself."""

from __future__ import annotations

import json
import sys
import time

from playscope.board.flash import flash
from playscope.board.link import DeviceError, Link
from playscope.fit.table_build import CalibTable, builtin_table, set_generation, test_vector
from playscope.board.transport import UsbTransport


def check(link: Link, n_vectors: int, blob: bytes | None = None) -> dict:
    """Flash blob (default: the demo table), then read back and rerun the compensator here,
    independently of flash()'s own checks. q_board: the board's q* (Q16) for test_vector."""
    blob = builtin_table() if blob is None else blob
    r = flash(link, blob, n_vectors, log=lambda *_: None)
    sent = set_generation(blob, r["generation"])
    back = link.read_table()
    host = CalibTable(sent)
    c = test_vector(host, n_vectors)
    link.set_mode("compensation")
    q_board = [link.comp_step(x) for x in c]
    link.set_mode("idle")
    q_host = host.comp_run(c)
    out = {"flash": r, "readback_identical": back == sent, "bytes": len(back),
           "comp_steps": len(c), "comp_mismatches": sum(a != b for a, b in zip(q_board, q_host)),
           "readback_hex": back.hex(), "q_board": q_board}
    # run-insitu's paced excitation reaches the board through USB as through the UART
    out["exc_config"] = link.exc_config("-3:3:1.6:0.4", 0.35, 0.8, 25.0)
    last = link.info()["last_seq"]
    try:  # a replayed request over USB is refused like on every transport
        link.request(link.lib.PSP_MSG_SET_MODE, bytes([0, 0, 0, 0]), seq=last)
        out["replay_error"] = 0
    except DeviceError as e:
        out["replay_error"] = e.code
    return out


def bench(link: Link, repeat: int) -> dict:
    up, rb, rt = [], [], []
    for _ in range(repeat):
        r = flash(link, builtin_table(), 20, log=lambda *_: None)
        up.append(r["upload_s"])
        rb.append(r["readback_s"])
    for _ in range(200):
        t = time.perf_counter()
        link.info()
        rt.append(time.perf_counter() - t)
    return {"upload_s": up, "readback_s": rb, "info_rt_s": rt}


def main() -> int:
    mode = sys.argv[1] if len(sys.argv) > 1 else "check"
    link = Link(UsbTransport())
    try:
        info = link.info()
        if mode == "check":
            res = check(link, 300)
        elif mode == "flash":  # flash TABLE_FILE [N_VECTORS]
            with open(sys.argv[2], "rb") as f:
                res = check(link, int(sys.argv[3]) if len(sys.argv) > 3 else 300, f.read())
        else:
            res = bench(link, int(sys.argv[2]))
        res["info"] = info
    finally:
        link.close()
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
