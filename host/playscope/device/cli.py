"""CLI commands of the device link: `playscope flash`, `playscope device info`, `playscope run-insitu`."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from ..errors import InputError


def _add_device_args(p) -> None:
    p.add_argument("--device", choices=["virtual", "qemu", "usb"], default="virtual",
                   help="board to talk to (default: virtual, the desktop build as a process)")
    p.add_argument("--flash-file", help="virtual: file-backed A/B flash kept across runs")
    p.add_argument("--elf", help="qemu: link firmware image (default: build/stm32f405/link-fw)")
    p.add_argument("--address", help="qemu: host:port of an already running QEMU serial")


def _open(args, vboard_args=()):
    from .link import Link
    from .transport import open_transport

    return Link(open_transport(args.device, flash_file=args.flash_file, elf=args.elf, address=args.address,
                               vboard_args=vboard_args))


def cmd_info(args) -> int:
    with _closing(_open(args)) as link:
        info = link.info()
    if args.json:
        print(json.dumps(info, indent=1))
    else:
        for k, v in info.items():
            print(f"{k:22s} {v}")
    return 0


class _closing:
    def __init__(self, link):
        self.link = link

    def __enter__(self):
        return self.link

    def __exit__(self, *exc):
        self.link.close()


def flash(link, blob: bytes, n_vectors: int = 200, log=print) -> dict:
    """Upload with generation = active + 1, commit, read back, then run the test vector
    through the board's compensator and compare with the host's run of the same C code.
    Returns timings and the check results; raises RuntimeError when a check fails."""
    from ..tables import CalibTable, set_generation, test_vector

    before = link.info()
    blob = set_generation(blob, before["active_generation"] + 1)
    host = CalibTable(blob)  # refuses a bad table before anything is sent
    t0 = time.perf_counter()
    after = link.upload_table(blob)
    t_upload = time.perf_counter() - t0
    back = link.read_table()
    t_read = time.perf_counter() - t0 - t_upload
    if back != blob:
        raise RuntimeError("read-back differs from the uploaded table")
    c = test_vector(host, n_vectors)
    link.set_mode("compensation")
    t1 = time.perf_counter()
    q_board = [link.comp_step(x) for x in c]
    t_vec = time.perf_counter() - t1
    link.set_mode("idle")
    q_host = host.comp_run(c)
    bad = [k for k in range(len(c)) if q_board[k] != q_host[k]]
    if bad:
        k = bad[0]
        raise RuntimeError(f"compensator mismatch at step {k}: board {q_board[k]}, host {q_host[k]} "
                           f"({len(bad)} of {len(c)} differ)")
    r = {"generation": after["active_generation"], "slot": after["active_slot"], "bytes": len(blob),
         "crc32": f"{after['active_crc32']:08x}", "upload_s": t_upload, "readback_s": t_read,
         "vectors": len(c), "round_trip_us": t_vec / len(c) * 1e6}
    log(f"flashed {len(blob)} B as generation {r['generation']} into slot {r['slot']} "
        f"(crc {r['crc32']}) in {t_upload * 1e3:.1f} ms; read back identical in {t_read * 1e3:.1f} ms; "
        f"{len(c)} compensator steps bit-identical to the host ({r['round_trip_us']:.0f} us per round trip)")
    return r


def cmd_flash(args) -> int:
    from .link import DeviceError
    from ..tables import demo_table

    if args.table == "demo":
        blob = demo_table()
    else:
        p = Path(args.table)
        if not p.is_file():
            raise InputError(p, "no such table file")
        blob = p.read_bytes()
    with _closing(_open(args)) as link:
        try:
            flash(link, blob, args.vectors)
        except (DeviceError, RuntimeError, ValueError) as e:
            print(f"playscope: flash failed: {e}", file=sys.stderr)
            return 1
    return 0


def cmd_run_insitu(args) -> int:
    from .insitu import run_insitu

    vb = []
    if args.sim_plant:
        if args.device != "virtual":
            print("playscope: --sim-plant needs --device virtual (the simulated instrument follows "
                  "the virtual board's clock)", file=sys.stderr)
            return 2
        vb = ["--time-scale", f"{args.time_scale:g}", "--exc", args.exc]
    with _closing(_open(args, vb)) as link:
        return run_insitu(link, args)


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("flash", help="upload a table, commit, read back and check bit for bit")
    p.add_argument("table", help="table blob (from `playscope tables`), or 'demo' for a built-in one")
    p.add_argument("--vectors", type=int, default=200, help="compensator test steps (default 200)")
    _add_device_args(p)
    p.set_defaults(func=cmd_flash)

    p = subparsers.add_parser("device", help="board information")
    sub = p.add_subparsers(dest="device_command", metavar="SUBCOMMAND")
    pi = sub.add_parser("info", help="firmware/protocol/layout versions, board id, active table")
    pi.add_argument("--json", action="store_true")
    _add_device_args(pi)
    pi.set_defaults(func=cmd_info)

    p = subparsers.add_parser("run-insitu", help="in-situ calibration on the board: excitation, marker from "
                              "a camera/video, B samples from the board's onset detector, fit, tables, flash")
    p.add_argument("--video", help="video file or camera index for OpenCV VideoCapture")
    p.add_argument("--geometry", help="session.json with robot, camera and hand-eye (to fit f_remain, eqs. 6-8)")
    p.add_argument("--sim-plant", action="store_true",
                   help="SIMULATION: no camera; a simulated instrument follows the virtual board's encoder "
                        "stream and is rendered to frames (simulator preset 'ideal')")
    p.add_argument("--time-scale", type=float, default=4.0,
                   help="--sim-plant: virtual board clock speed-up over the wall clock (default 4)")
    p.add_argument("--exc", default="-3:3:1.6:0.4:1.0",
                   help="--sim-plant: virtual board excitation Q0:Q1:AMP:ADV:V in mm, mm/s (default -3:3:1.6:0.4:1.0)")
    p.add_argument("--seed", type=int, default=0, help="--sim-plant: noise seed")
    p.add_argument("--seconds", type=float, default=600.0, help="longest run in board seconds (default 600)")
    p.add_argument("-N", "--control-points", type=int, default=14, help="B-spline control points (paper: 14)")
    p.add_argument("--vectors", type=int, default=200, help="compensator test steps after flashing (default 200)")
    p.add_argument("--no-flash", action="store_true", help="fit and write tables, do not flash")
    p.add_argument("-o", "--output", help="folder for b_samples.csv, session/, calibration.json, table.bin, result.json")
    p.add_argument("--json", action="store_true", help="print the result as JSON on the last line")
    _add_device_args(p)
    p.set_defaults(func=cmd_run_insitu)
