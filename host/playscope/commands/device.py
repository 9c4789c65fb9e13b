"""CLI commands of the device link: `playscope flash`, `playscope device info`, `playscope run-insitu`."""

from __future__ import annotations

import contextlib
import os
import sys

from .common import add_command, add_json_arg, dump_json, progress


def _add_device_args(p) -> None:
    from . import argtypes as T

    p.add_argument("--device", choices=["virtual", "qemu", "usb"], default="virtual",
                   help="board to talk to (default: virtual, the desktop build as a process)")
    p.add_argument("--flash-file", type=T.file_path, help="virtual: file-backed A/B flash kept across runs")
    p.add_argument("--elf", type=T.elf_file, help="qemu: link firmware image (default: build/stm32f405/link-fw)")
    p.add_argument("--address", type=T.host_port, help="qemu: host:port of an already running QEMU serial")


def _open(args, vboard_args=()):
    from ..pipeline import open_board

    return open_board(args.device, args.flash_file, args.elf, args.address, vboard_args)


def cmd_info(args) -> int:
    from ..pipeline import device_info

    info = device_info(args.device, args.flash_file, args.elf, args.address)
    for k, v in info.items():
        print(f"{k:22s} {v}")
    dump_json(args.json, info)
    return 0


def cmd_flash(args) -> int:
    from ..base.errors import InputError
    from ..board.link import DeviceError
    from ..pipeline import flash_tables

    try:
        r = flash_tables(args.table, args.device, args.flash_file, args.vectors, args.elf, args.address,
                         usb_child=False)
    except (DeviceError, RuntimeError, ValueError) as e:
        if isinstance(e, InputError):  # a bad table file: the CLI's one-line error naming it
            raise
        print(f"playscope: error: flash failed: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    print(r.line())
    dump_json(args.json, r.to_json())
    return 0


def cmd_run_insitu(args) -> int:
    from ..base.errors import InputError
    from ..pipeline import pace_excitation

    vb = []
    if args.out is not None and os.path.lexists(args.out) and not os.path.isdir(args.out):
        raise InputError(args.out, "is a file; run-insitu -o takes a folder (its files: b_samples.csv, session/, "
                         "calibration.json, table.bin, result.json)")
    if not args.sim_plant:  # what the run needs, checked before the board is opened
        if args.video is None:
            raise InputError(None, "run-insitu needs --video FILE, a camera index, or --sim-plant")
        if args.geometry is None:
            raise InputError(None, "run-insitu needs --geometry session.json (robot, camera, hand-eye) to fit f")
        from ..board.insitu_run import read_geometry

        read_geometry(args.geometry)
    if args.sim_plant:
        if args.device != "virtual":
            raise InputError(None, "--sim-plant needs --device virtual (the simulated instrument follows "
                             "the virtual board's clock)")
        from ..board.insitu_run import sim_vboard_args

        vb = sim_vboard_args(args.time_scale)
    args.pace = None
    if args.sim_plant or args.video is not None:  # no source: said below
        exc4 = args.exc
        paced = pace_excitation(args.exc, args.fps, args.b_range, args.sim_plant, args.seed, args.video)
        if paced.fps is not None:
            print(paced.line(), file=sys.stderr)
            args.pace = (paced.b_low_mm, paced.b_high_mm, paced.fps)
        args.exc = paced.exc
        if args.device == "virtual":  # also at start-up (the link sends it again: every image takes it so)
            vb += ["--exc", exc4] + paced.vboard_args  # without V: the board computes it itself (--pace)
    with contextlib.closing(_open(args, vb)) as link:
        return _run_insitu(link, args)


def _run_insitu(link, args) -> int:
    """`playscope run-insitu` on an open link (the work: pipeline.run_insitu). Returns the exit status."""
    from ..base.errors import InputError
    from ..pipeline import InsituSource, run_insitu

    src = InsituSource(video=args.video, geometry=args.geometry, sim_plant=args.sim_plant, seed=args.seed,
                       time_scale=args.time_scale, exc=args.exc, pace=args.pace)
    if args.sim_plant:
        print(f"SIMULATION: --sim-plant renders a simulated instrument (simulator preset 'ideal') "
              f"from the board's encoder stream; board clock x{args.time_scale:g}", file=sys.stderr)
    bars = []

    def bar_at(board_s: float, n: int, total: float | None) -> None:
        if not bars:
            bars.append(progress(total=total, unit="s", desc="board time",
                                 bar_format=None if total else "{desc}: {n:.1f} s {postfix}"))
        _bar(bars[0], board_s, n)

    def ran(line: str) -> None:  # the run ended: close the bar, then its summary line
        if bars:
            bars[0].close()
        print(line)

    try:
        res = run_insitu(link, src, args.seconds, args.control_points, args.out, flash_after=not args.no_flash,
                         n_vectors=args.vectors, progress=bar_at, ran=ran)
    except (InputError, RuntimeError) as e:  # the fit refused the run, or the flash failed
        print(f"playscope: error: run-insitu: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    finally:
        if bars:
            bars[0].close()
    if res.sim_line():
        print(res.sim_line())
    dump_json(args.json, res.to_json())
    return 0


def _bar(bar, board_s: float, n: int) -> None:
    """Move the run's tqdm bar to board_s seconds of board time, n B samples so far."""
    bar.update(board_s - bar.n)
    bar.set_postfix_str(f"{n} B samples", refresh=False)


def add_parser(subparsers) -> None:
    from . import argtypes as T

    p = add_command(subparsers, "flash", "upload a table, commit, read back and check bit for bit",
                    "Upload a table blob to a board with generation = active + 1, commit it, read it back, "
                    "then run test steps through the board's compensator and compare them bit for bit with "
                    "the host's run of the same C (board/flash.py).",
                    examples=["playscope flash builtin --device virtual --flash-file board.flash",
                              "playscope flash d21.pstb --device virtual --flash-file board.flash --vectors 500"])
    p.add_argument("table", help="table blob (from `playscope tables`), or 'builtin' for the built-in test table "
                   "(tables.builtin_table)")
    p.add_argument("--vectors", type=T.VECTORS, default=200, help="compensator test steps (default 200)")
    add_json_arg(p, "generation, slot, bytes, crc32 (hex), upload_s, readback_s, vectors, round_trip_us")
    _add_device_args(p)
    p.set_defaults(func=cmd_flash)

    p = add_command(subparsers, "device", "board information", "Ask a board what it runs.",
                    examples=["playscope device info --device virtual --json -"])
    sub = p.add_subparsers(dest="device_command", metavar="SUBCOMMAND")
    pi = add_command(sub, "info", "firmware/protocol/layout versions, board id, active table",
                     "Firmware, protocol and table layout versions, board id and the active table "
                     "(generation, slot, CRC).", examples=["playscope device info --device virtual --json -"])
    add_json_arg(pi, "the printed fields: board_id, fw_version, proto_version, layout, active_generation, "
                 "active_slot, active_crc32, ...")
    _add_device_args(pi)
    pi.set_defaults(func=cmd_info)

    p = add_command(subparsers, "run-insitu", "in-situ calibration on the board: excitation, marker from "
                    "a camera/video, B samples from the board's onset detector, fit, tables, flash",
                    "The paper's in-situ procedure (section III) on a board: the board runs its excitation and "
                    "streams its encoder, frames come from a camera or a video (or a SIMULATED instrument with "
                    "--sim-plant), the board's onset detector answers B samples, the host fits B(q) and f_remain, "
                    "writes the tables and flashes them (pipeline.run_insitu, board/insitu_run.py).",
                    examples=["playscope run-insitu --device virtual --sim-plant -o run --json run/result.json",
                              "playscope run-insitu --device qemu --video 0 --geometry sessions/s1/session.json -o run"])
    p.add_argument("--video", help="video file or camera index for OpenCV VideoCapture")
    p.add_argument("--geometry", type=T.existing_file, help="session.json with robot, camera and hand-eye (to fit f_remain, eqs. 6-8)")
    p.add_argument("--sim-plant", action="store_true",
                   help="SIMULATION: no camera; a simulated instrument follows the virtual board's encoder "
                        "stream and is rendered to frames (simulator preset 'ideal')")
    p.add_argument("--time-scale", type=T.TIME_SCALE, default=4.0,
                   help="--sim-plant: virtual board clock speed-up over the wall clock, at most (default 4): the "
                        "board waits for a host that lags")
    p.add_argument("--exc", default="-3:3:1.6:0.4", type=T.colon_floats(5, "Q0:Q1:AMP:ADV[:V]", n_min=4),
                   help="virtual board: its excitation Q0:Q1:AMP:ADV[:V] in mm, mm/s (default -3:3:1.6:0.4); "
                        "without V the board paces the swing to the camera: V = B_low x fps / 4, the smallest "
                        "play taken up over 4 frames (see --b-range, --fps); a real board runs the excitation "
                        "it was built with")
    p.add_argument("--b-range", type=T.colon_floats(2, "LO:HI"),
                   help="expected play range LO:HI in mm, for pacing the excitation (default with --sim-plant: "
                        "the simulated instrument's)")
    p.add_argument("--fps", type=T.FPS, help="camera frame rate for pacing the excitation (default: the simulated "
                   "camera's, the video file's, else 25)")
    p.add_argument("--seed", type=T.SEED, default=0, help="--sim-plant: noise seed")
    p.add_argument("--seconds", type=T.DURATION_S, default=600.0, help="longest run in board seconds (default 600)")
    p.add_argument("-N", "--control-points", type=T.CONTROL_POINTS, default=14, help="most control points of the B(q) spline, and those of the paper's morphological f_remain (paper: 14); the least-squares f_remain takes its own by cross-validation (calibration file: f_fit)")
    p.add_argument("--vectors", type=T.VECTORS, default=200, help="compensator test steps after flashing (default 200)")
    p.add_argument("--no-flash", action="store_true", help="fit and write tables, do not flash")
    p.add_argument("-o", "--out", "--output", dest="out",
                   help="folder for b_samples.csv, session/, calibration.json, table.bin, result.json")
    add_json_arg(p, "board_s, wall_s, frames, b_samples, b_valid, q_range, sim_B_err_mm (--sim-plant), flash "
                 "(generation, slot, bytes, crc32, upload_s, readback_s, vectors, round_trip_us)")
    _add_device_args(p)
    p.set_defaults(func=cmd_run_insitu, own_progress=True)
