"""`playscope demo`: the main job end to end on an embedded default (a simulated STRAS-like
instrument), from rendered endoscopic video to flashed, verified tables and a report.

Steps (paper Fig. 4 and section V): simulate an in-situ excitation session with video
(variable B(q), non-linear f_remain, 80 ms acquisition delay, +-1.5 deg direction-dependent
registration error) -> track the marker in the video -> onsets and B(q) spline, f_remain
(calibrate) -> Q16.16 tables -> flash to the virtual board through the emulated USB device,
read back, compare compensator outputs bit for bit -> Table I and open-loop compensation on
a separate test motion (evaluate) -> HTML report. Prints one summary.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import time
from pathlib import Path

import numpy as np

from . import cli
from .calibration import Calibration

DEFAULT_OUT = "out/main"


def _run_cli(argv: list[str], quiet: bool = True) -> str:
    """Run one `playscope` subcommand in this process; its stdout is returned (and
    hidden when quiet). Raises RuntimeError naming the step when it fails."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf) if quiet else contextlib.nullcontext():
        rc = cli.main(argv)
    if rc != 0:
        raise RuntimeError(f"`playscope {' '.join(argv)}` failed (exit {rc}):\n{buf.getvalue()}")
    return buf.getvalue()


def b_error_vs_truth(cal_path: Path, session_dir: Path) -> dict:
    """|B_est(q) - B_true(q)| in actuator units over the calibrated q range (201 points),
    B_true from the simulator parameters recorded in session.json. Keys: mean, max, unit."""
    from .sim.core import SimConfig

    cal = Calibration.load(cal_path)
    sim = json.loads((session_dir / "session.json").read_text())["simulator"]
    truth = SimConfig.from_json(sim).B_fn()
    lo, hi = cal.doc["q_range"]
    q = np.linspace(lo, hi, 201)
    err = np.abs(np.asarray(cal.B(q)) - truth(q))
    return {"mean": float(err.mean()), "max": float(err.max()), "unit": cal.doc["actuator_unit"],
            "b_true_min": float(truth(q).min()), "b_true_max": float(truth(q).max())}


def run(out: Path, duration_s: float = 90.0, seed: int = 1, device: str = "usb") -> dict:
    """Run the whole job into out/ (created; existing outputs are replaced). Returns the
    summary dict also written to out/summary.json."""
    out.mkdir(parents=True, exist_ok=True)
    cal_s, test_s = out / "session_excitation", out / "session_test"
    cal_json, table, ev_json, report = out / "calibration.json", out / "tables.pstb", out / "evaluate.json", out / "report.html"
    # This job's own outputs from an earlier run are replaced (calibrate and tables refuse
    # to overwrite on their own; the session folders are rewritten with --overwrite).
    for f in (cal_json, table, ev_json, report, out / "board.flash", out / "summary.json"):
        f.unlink(missing_ok=True)
    steps: list[tuple[str, float]] = []
    t_all = time.perf_counter()

    def step(name: str, argv: list[str]) -> str:
        print(f"[main] {name} ...", flush=True)
        t0 = time.perf_counter()
        text = _run_cli(argv)
        steps.append((name, time.perf_counter() - t0))
        return text

    step("simulate excitation with video (STRAS-like preset)",
         ["simulate", str(cal_s), "--preset", "stras", "--trajectory", "excitation", "--video",
          "--duration", str(duration_s), "--seed", str(seed), "--overwrite"])
    step("track the marker in the video", ["track", str(cal_s), "--overwrite"])
    cal_text = step("calibrate: onsets, B(q) spline, f_remain", ["calibrate", str(cal_s), "-o", str(cal_json)])
    tab_text = step("fixed-point tables", ["tables", str(cal_json), "-o", str(table)])

    print("[main] flash to the virtual board over the emulated USB device ...", flush=True)
    t0 = time.perf_counter()
    flash_text = _flash(table, out / "board.flash", device)
    steps.append((f"flash over {device}, read back, bit-exact check", time.perf_counter() - t0))

    step("simulate a separate test motion", ["simulate", str(test_s), "--preset", "stras", "--trajectory", "test",
                                            "--duration", str(duration_s), "--seed", str(seed + 1), "--overwrite"])
    step("evaluate: Table I and compensation", ["evaluate", str(test_s), str(cal_json), "--table", str(table),
                                                "--json", str(ev_json)])
    step("HTML report", ["report", str(cal_json), str(test_s), "-o", str(report), "--eval", str(ev_json)])

    ev = json.loads(ev_json.read_text())
    summary = {
        "format": "playscope-main/1",
        "out": str(out),
        "b_error": b_error_vs_truth(cal_json, cal_s),
        "calibrate": cal_text.strip().splitlines()[-1] if cal_text.strip() else "",
        "tables": tab_text.strip().splitlines()[-1] if tab_text.strip() else "",
        "flash": flash_text.strip().splitlines()[-1] if flash_text.strip() else "",
        "prediction": ev.get("prediction", {}),
        "compensation": ev.get("compensation", {}).get("methods", {}),
        "report": str(report),
        "steps_s": {name: round(t, 2) for name, t in steps},
        "total_s": round(time.perf_counter() - t_all, 2),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def _flash(table: Path, flash_file: Path, device: str) -> str:
    """Flash through `playscope flash` (upload, commit, read back, compensator test vectors);
    for usb, under the emulated USB device (ps_usbemu), since libusb's preload must be in the
    process from its start."""
    exe = [sys.executable, "-m", "playscope.cli"]
    if device == "usb":
        from .device import usbemu
        r = usbemu.run(exe + ["flash", str(table), "--device", "usb"], flash_file=str(flash_file))
    else:
        import subprocess
        r = subprocess.run(exe + ["flash", str(table), "--device", device, "--flash-file", str(flash_file)],
                           capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        raise RuntimeError(f"flash over {device} failed (exit {r.returncode}):\n{r.stdout}\n{r.stderr}")
    return r.stdout


def format_summary(s: dict) -> str:
    """The short human summary printed at the end."""
    b = s["b_error"]
    lines = ["", "playscope main job: simulated STRAS-like instrument, in-situ calibration", "",
             f"B(q) error against the truth: mean {b['mean']:.4f} {b['unit']}, max {b['max']:.4f} {b['unit']}"
             f" (true B {b['b_true_min']:.2f}..{b['b_true_max']:.2f} {b['unit']})",
             f"tables: {s['tables']}", f"flash:  {s['flash']}", "",
             "Table I on the test motion (image errors, px; bending angle vs truth, deg):",
             "| model | Qx mean ± std | Qy mean ± std | distance mean ± std | max | c RMSE |",
             "|---|---|---|---|---|---|"]
    for name, m in s["prediction"].items():
        def ms(k):
            v = m.get(k)
            return f"{v['mean']:.1f} ± {v['std']:.1f}" if v else "-"
        mx = m.get("dist_px", {}).get("max")
        c = m.get("c_rmse_truth_deg", m.get("c_rmse_deg"))
        lines.append(f"| {name} | {ms('Qx_px')} | {ms('Qy_px')} | {ms('dist_px')} | "
                     f"{'-' if mx is None else f'{mx:.1f}'} | {'-' if c is None else f'{c:.2f}'} |")
    if s["compensation"]:
        lines += ["", "Open-loop compensation through the plant (bending-angle RMSE, deg): " +
                  ", ".join(f"{k} {v['c_rmse_deg']:.2f}" for k, v in s["compensation"].items())]
    lines += ["", f"report: {s['report']}", f"total {s['total_s']:.1f} s (" +
              ", ".join(f"{k.split(':')[0].split(' (')[0]} {v:.1f}" for k, v in s["steps_s"].items()) + ")"]
    return "\n".join(lines)


def cmd_demo(args) -> int:
    try:
        s = run(Path(args.out), args.duration, args.seed, args.device)
    except RuntimeError as e:
        print(f"playscope: error: {e}", file=sys.stderr)
        return 1
    print(format_summary(s))
    if args.json:
        Path(args.json).write_text(json.dumps(s, indent=1) + "\n")
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", help="the main job on the built-in simulated instrument, end to end",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    p.add_argument("--duration", type=float, default=90.0, help="length of each simulated session, s (default 90)")
    p.add_argument("--seed", type=int, default=1, help="random seed of the excitation session (test uses seed+1)")
    p.add_argument("--device", choices=["usb", "virtual", "qemu"], default="usb",
                   help="board to flash: usb = virtual board behind the emulated USB device (default)")
    p.add_argument("--json", metavar="PATH", help="also write the summary (keys of out/summary.json) to PATH")
    p.set_defaults(func=cmd_demo)
