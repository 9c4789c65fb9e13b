"""Runs under ps_usbemu (LD_PRELOAD=libumockdev-preload): the issue-14 guards over the emulated
USB device with the host's unmodified UsbTransport. Prints what it saw as JSON on the last line.
Modes:  corrupt FILE...  flash the demo table, then try each damaged file: field named, requests sent.
        session          host A opens an upload and vanishes mid-way; host B is busy until the
                         board's session times out, then flashes.
Used by test_integrity.py; not a test module itself."""

from __future__ import annotations

import json
import sys
import time

from playscope.board.flash import flash
from playscope.board.link import DeviceError, Link
from playscope.fit.table_build import builtin_table
from playscope.board.transport import UsbTransport
from playscope.board.table_check import TableFileError


def corrupt(link: Link, files: list[str]) -> dict:
    flash(link, builtin_table(), 10, log=lambda *_: None)
    out = {"generation_before": link.info()["active_generation"], "refused": []}
    for path in files:
        with open(path, "rb") as f:
            blob = f.read()
        n0 = link.n_requests
        try:
            flash(link, blob, 10, log=lambda *_: None)
            out["refused"].append({"file": path, "field": None, "requests_sent": link.n_requests - n0})
        except TableFileError as e:
            out["refused"].append({"file": path, "field": e.field, "message": str(e),
                                   "requests_sent": link.n_requests - n0})
    out["generation_after"] = link.info()["active_generation"]
    return out


def session() -> dict:
    a = Link(UsbTransport())
    t1 = builtin_table(generation=1)
    s = a.begin_upload(len(t1), int.from_bytes(t1[12:16], "little"))
    t_last = time.monotonic()
    a.close()  # host A killed after BEGIN: its session stays open on the board
    b = Link(UsbTransport())
    out = {"busy_messages": [], "waited_s": None}
    try:
        while time.monotonic() - t_last < 30:
            try:
                r = flash(b, builtin_table(), 20, log=lambda *_: None)
                out["waited_s"] = time.monotonic() - t_last
                out["generation"] = r["generation"]
                break
            except DeviceError as e:
                if not e.busy:
                    raise
                out["busy_messages"].append(str(e))
                time.sleep(0.5)
        out["session_token_nonzero"] = s != 0
    finally:
        b.close()
    return out


def main() -> int:
    mode = sys.argv[1]
    if mode == "session":
        print(json.dumps(session()))
        return 0
    link = Link(UsbTransport())
    try:
        if mode == "corrupt":
            res = corrupt(link, sys.argv[2:])
        else:
            raise SystemExit(f"unknown mode {mode}")
    finally:
        link.close()
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
