#!/usr/bin/env python3
"""Every benchmark figure of the project, in one Markdown table
(figure | measured | target | paper or baseline | command).

Runs, in order: bench/bench_firmware.sh (M4 instructions per tick, desktop ticks/s, image
size), bench/bench_host.py (calibrate time, tracking frames/s), bench/bench_link.py (flash
time and round trip per transport), bench/fig7_replica.py and fig7_sim_pose.py (B error on
independently rendered records and the pose-based baseline, paper Fig. 7), `playscope demo`
(main job: B error, Table I and compensation ratios, time), `playscope evaluate-real`
(real-data RMSE), bench/insitu_real.py (every model on both instruments, ours / best peer),
bench/online_real.py and transfer_real.py (on-line update, a calibration used elsewhere),
bench/bench_startup.py, bench/diagnose_speed.py, the Python tests marked slow (`pytest -m
slow tests/python`: what ./tools/run-tests.sh leaves out, CONTRIBUTING.md), then with --swings
bench/swing_bench.py (development renderings) and, unless --skip-selftest,
bench/diagnose_selftest.py --quick --second (both generators). Only figures measured in this run are printed; a part that fails or
is skipped says so in its row, and the README's summary keeps a line for it.

It writes docs/results.md (machine, date, commit, time per part, the figure table, then every
bench's own tables as it printed them), the README's summary table (between the
`results:begin` and `results:end` markers) and every figures block of docs/*.md (see
bench/results_doc.py): no figure in README.md or docs/ is typed by hand.
tests/python/host/test_results_doc.py checks the README and docs blocks against
docs/results.md; test_doc_figures.py fails on a measured figure typed outside them.

Usage: .venv/bin/python bench/run_all.py [--skip-selftest] [--swings] [--catheter DIR] [--no-write]
       .venv/bin/python bench/run_all.py --docs-only   (re-fill the docs blocks from docs/results.md)
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable
PLAYSCOPE = [PY, "-m", "playscope.cli"]


sys.path.insert(0, str(ROOT / "bench"))
from results_doc import (BEGIN, END, NOT_RUN, fill_doc_blocks, insitu_rows,  # noqa: E402
                         md_table, selftest_rows, summary_block, swing_rows)

RESULTS = ROOT / "docs" / "results.md"
README = ROOT / "README.md"
# The README's excerpt of the main job's output: from its Table I to its compensation line.
EXCERPT_BEGIN, EXCERPT_END = "<!-- mainjob:begin -->", "<!-- mainjob:end -->"
EXCERPT: list[str] = []
# Every bench's own output, kept whole for docs/results.md: (title, command, stdout).
RAW: list[tuple[str, str, str]] = []


def sh(cmd: list[str], timeout: float = 1800) -> str:
    """stdout of cmd run from the repository root; raises RuntimeError with its stderr.
    The output is also kept (RAW) for docs/results.md."""
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-300:]}")
    shown = " ".join(Path(c).name if c == PY else c for c in cmd).replace(" -m playscope.cli", " playscope")
    RAW.append((shown, shown, r.stdout))
    return r.stdout


FIGURE = ROOT / "docs" / "img" / "main-job-characteristic.png"


def save_report_figure(report: Path, alt: str, dest: Path) -> None:
    """Copy the PNG embedded in the HTML report under <img alt=ALT> to dest (the README's
    picture is the main job's own figure, regenerated with the figures)."""
    import base64
    m = re.search(r'<img alt="%s" src="data:image/png;base64,([A-Za-z0-9+/=]+)"' % re.escape(alt),
                  report.read_text())
    if not m:
        raise RuntimeError(f"{report}: no figure '{alt}'")
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_bytes(base64.b64decode(m[1]))


def main_job_excerpt(out: str) -> list[str]:
    """The lines of the main job's stdout from its Table I heading to its open-loop
    compensation line (what the README shows a newcomer)."""
    lines = out.splitlines()
    i = next((k for k, ln in enumerate(lines) if ln.startswith("Table I")), None)
    j = next((k for k, ln in enumerate(lines) if ln.startswith("Open-loop compensation")), None)
    if i is None or j is None or j < i:
        raise RuntimeError("playscope demo printed no Table I / compensation lines")
    return [ln for ln in lines[i:j + 1]]


def replace_block(text: str, begin: str, end: str, block: str, where: Path) -> str:
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        raise SystemExit(f"run_all: {where} has no {begin} ... {end} block; docs/results.md written")
    return text[:i] + block + text[j + len(end):]


def machine() -> str:
    """One line: the machine the figures were measured on."""
    import os
    import platform
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{platform.system()} {platform.release()}, {cpu}, {os.cpu_count()} cores, "
            f"Python {platform.python_version()}")


def commit() -> str:
    """HEAD's short hash, with '+ uncommitted changes' when the tree differs from it."""
    try:
        h = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True).stdout.strip()
        return h + (" + uncommitted changes" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"


# Rough time of each part on a quiet 2-core machine, for --help (the time each part took in the
# last run is in docs/results.md, "time per part").
PART_TIME = (
    ("firmware", "~1 min (builds, then M4 instruction counts under QEMU)"),
    ("host", "~1 min (calibrate x3, tracking)"),
    ("link", "~0.5 min (three transports)"),
    ("Fig. 7 replica", "~2 min (renders, then calibrates every record)"),
    ("main job", "~0.5 min"),
    ("real data", "~0.5 min"),
    ("in-situ real data", "~1.5-4 min (two instruments, four splits)"),
    ("memoryless term", "~2.5 min (development files, two splits)"),
    ("choice across regimes", "~2 min (development files, two splits)"),
    ("on-line update", "~1.5 min (includes a second bench_firmware.sh)"),
    ("transfer", "~4 min (every endoscope pair, the ceilings of each learner)"),
    ("no regression with the learner on", "~1 min (reuses the main job's folder)"),
    ("start-up", "~5 s"),
    ("diagnosis speed", "~1 min"),
    ("asymmetric-play trace", "~4 min (base-model fits on the generators' asymmetric cases and nulls)"),
    ("slow tests", "the Python tests marked slow, in parallel (none marked at present: seconds)"),
    ("fast-swing onsets", "~10-20 min; only with --swings (development renderings)"),
    ("long logs", "only with --long-logs: generates ~0.5 GB of logs under build/long-logs once, then import, "
                  "calibrate and evaluate-insitu on them (tens of minutes while calibrate misses its limit)"),
    ("diagnosis self-test", "~15-40 min (both generators, quick form), the slowest part; --skip-selftest leaves it out"),
)


def docs_pages() -> list[Path]:
    """The pages whose figures blocks run_all fills: docs/*.md except results.md itself."""
    return [p for p in sorted((ROOT / "docs").glob("*.md")) if p.name != RESULTS.name]


def write_doc_blocks(results: str) -> list[str]:
    """Re-fill every figures block of docs/*.md from the text of docs/results.md; returns the
    pages rewritten."""
    changed = []
    for page in docs_pages():
        text = page.read_text()
        new = fill_doc_blocks(text, results, where=str(page.relative_to(ROOT)))
        if new != text:
            page.write_text(new)
            changed.append(str(page.relative_to(ROOT)))
    return changed


def write_results(table, wall_s: float, times: list[tuple[str, float]], skipped: list[str], code: str) -> None:
    """docs/results.md from this run, the README's summary block (which must already hold
    the two markers: the README's prose around it is not generated) and the docs' figures
    blocks. code: `commit()` as the run began."""
    import datetime
    stamp = f"{datetime.date.today().isoformat()}, commit {code}"
    block = summary_block(table, stamp, skipped)
    parts = [
        "# Results",
        "",
        "Generated by `bench/run_all.py`; do not edit by hand (run it again). Every figure in the "
        "README and in docs/ comes from this page.",
        "",
        f"- date and commit: {stamp}",
        f"- machine: {machine()}",
        f"- wall time of the run: {wall_s:.0f} s",
        "- time per part: " + ", ".join(f"{n} {s:.0f} s" for n, s in times)
        + "".join(f"; {n}: {NOT_RUN}" for n in skipped),
        "",
        "## Summary (the README's table)",
        "",
        block,
        "",
        "## Every figure",
        "",
        md_table(table),
        "",
        "## Each bench as it printed",
        "",
    ]
    for title, cmd, out in RAW:
        parts += [f"### `{cmd}`", "", out.strip(), ""]
    RESULTS.write_text("\n".join(parts) + "\n")
    text = replace_block(README.read_text(), BEGIN, END, block, README)
    if EXCERPT:
        text = replace_block(text, EXCERPT_BEGIN, EXCERPT_END,
                             EXCERPT_BEGIN + "\n```\n" + "\n".join(EXCERPT) + "\n```\n" + EXCERPT_END, README)
    README.write_text(text)
    # last: a malformed block in a page is the page's fault, and results.md and the README
    # already hold this run
    try:
        write_doc_blocks(RESULTS.read_text())
    except ValueError as e:
        raise SystemExit(f"run_all: {e}; docs/results.md and the README written, fix the page and run --docs-only")


def md_rows(text: str) -> dict[str, list[str]]:
    """Rows of the Markdown tables in text, keyed by their first cell."""
    rows = {}
    for line in text.splitlines():
        if line.startswith("|") and not line.startswith("|---"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            rows[cells[0]] = cells[1:]
    return rows


def find(rows: dict, prefix: str) -> list[str]:
    for k, v in rows.items():
        if k.startswith(prefix):
            return v
    raise KeyError(prefix)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="time of each part, quiet 2-core machine (the last run's own times are in docs/results.md):\n"
        + "\n".join(f"  {n:<20} {s}" for n, s in PART_TIME)
        + "\nwhole run ~25-50 min with the self-test, ~10 min with --skip-selftest")
    ap.add_argument("--skip-selftest", action="store_true", help="leave out the diagnosis self-test (the slowest part)")
    ap.add_argument("--catheter", default=str(ROOT.parent / "shared/data/real/catheter"),
                    help="folder of the real catheter recordings (read in place)")
    ap.add_argument("--swings", action="store_true",
                    help="also run bench/swing_bench.py on the development fast-swing renderings (slow; the "
                         "set-aside group is run once by hand)")
    ap.add_argument("--long-logs", action="store_true",
                    help="also run bench/bench_long_log.py (import, calibrate, evaluate-insitu on a 1-h 1 kHz log and a "
                         "27-min 5 kHz log read in place: wall time and peak RSS against the long-log limits)")
    ap.add_argument("--no-write", action="store_true",
                    help="print the table only; leave docs/results.md and the README as they are")
    ap.add_argument("--docs-only", action="store_true",
                    help="run no bench: re-fill the figures blocks of docs/*.md from docs/results.md (seconds)")
    a = ap.parse_args(argv)
    if a.docs_only:
        try:
            changed = write_doc_blocks(RESULTS.read_text())
        except ValueError as e:
            raise SystemExit(f"run_all: {e}")
        print(f"[bench] figures blocks re-filled from {RESULTS.relative_to(ROOT)}: "
              f"{', '.join(changed) or 'none changed'}", file=sys.stderr)
        return 0
    t_run = time.perf_counter()
    # The code measured, taken before any part runs: the main job's part writes the README's figure
    # (docs/img), so a tree clean at the start read "+ uncommitted changes" at the end.
    code = commit()
    times: list[tuple[str, float]] = []
    skipped: list[str] = []
    table: list[tuple[str, str, str, str, str]] = []

    def part(name, fn):
        t0 = time.perf_counter()
        print(f"[bench] {name} ...", file=sys.stderr, flush=True)
        try:
            fn()
        except (RuntimeError, KeyError, ValueError, subprocess.TimeoutExpired, OSError) as e:
            table.append((name, f"not measured: {e}".replace("|", "/")[:160], "", "", ""))
        times.append((name, time.perf_counter() - t0))
        print(f"[bench] {name}: {times[-1][1]:.0f} s", file=sys.stderr, flush=True)

    def firmware():
        r = md_rows(sh(["bench/bench_firmware.sh"]))
        c = "bench/bench_firmware.sh"
        # Every per-call row of the firmware bench, in its order: the label is the bench's own
        # (it names the exact function timed and the trajectory), the measured cell keeps the
        # average and the worst single call, the target cell its verdicts.
        timed = [(k, v) for k, v in r.items() if " avg, " in v[0] and " worst" in v[0]]
        if not timed:
            raise RuntimeError("bench/bench_firmware.sh printed no per-call rows")
        for label, row in timed:
            table.append((f"M4 instructions per call: {label}", row[0].split(" (n =")[0], row[1], "", c))
        row = find(r, "desktop throughput")
        table.append(("desktop ticks per second", row[0].split(" (")[0], "", "", c))
        row = find(r, "playscope-fw.elf flash")
        table.append(("USART image flash, everything", row[0], "<= 24 KiB", "", c))
        row = find(r, "playscope-fw.elf RAM, everything")
        table.append(("USART image RAM, everything (static, tables, history, stack)", row[0], "<= 24 KiB", "", c))

    def host():
        r = md_rows(sh([PY, "bench/bench_host.py"]))
        c = "bench/bench_host.py (one core)"
        lc = find(r, "load + calibrate")
        # calibrate shares its independent fits with a forked child (base.forkmap): two cores, not one
        table.append(("calibrate a 3-min 25 Hz session (load_session + calibrate): median / worst of 3",
                      f"{lc[0]} / {lc[1]} s", "< 3 s", "", "bench/bench_host.py (two cores)"))
        table.append(("marker tracking 720x576, ROI", find(r, "tracker, ROI")[0] + " frames/s", ">= 800", "", c))
        table.append(("tracking end to end with MJPEG decode", find(r, "track_video end to end")[0] + " frames/s", "", "", c))

    def link():
        out = sh([PY, "bench/bench_link.py"])
        for m in re.finditer(r"^(\S+)\s+flash (\d+) B.*?median\s+([\d.]+) ms \(worst ([\d.]+) ms, n = (\d+)\), "
                             r"read-back\s+([\d.]+) ms \(worst ([\d.]+) ms\), INFO round trip median\s+(\d+) us "
                             r"\(p95 (\d+) us, worst (\d+) us", out, re.M):
            table.append((f"flash a {m[2]} B table, {m[1]}: median (worst of {m[5]})",
                          f"{m[3]} ms ({m[4]} ms); read-back {m[6]} ms ({m[7]} ms); round trip {m[8]} us "
                          f"(p95 {m[9]} us, worst {m[10]} us)", "", "", "bench/bench_link.py"))

    def fig7():
        # Fig. 7 replica on independently rendered records (bench/marker_render.py).
        # It exits 1 when its acceptance is not met; the summary line is read either way.
        out = subprocess.run([PY, "bench/fig7_replica.py"], cwd=ROOT, capture_output=True, text=True,
                             timeout=3600).stdout
        m = re.search(r"worst B error: registration (\S+) % .*?delay off (\S+) % .*?ringing (\S+) % "
                      r".*?B negative: (\w+); acceptance ([A-Z ]+)", out)
        if not m:
            raise RuntimeError("bench/fig7_replica.py printed no summary")
        c = "bench/fig7_replica.py"
        for val, label, tgt in ((m[1], "3 registration forms x 0.5/1.5/3 deg", "<= 5 %"),
                                (m[2], "configured t_delay off by +-0.1 s", "<= 10 %, no refusal"),
                                (m[3], "ringing 2-5 Hz, 10 px", "<= 10 %, no refusal")):
            table.append((f"B error, independent Fig. 7 replica, {label}: worst case", f"{val} %", tgt,
                          "paper 0.7 deg (4.7 %)", c))
        table.append(("B negative in a fitted spline or table (Fig. 7 replica)", m[4], "no", "", c))
        out = sh([PY, "bench/fig7_sim_pose.py"])
        m = re.search(r"two-step ([\d.]+) deg \(([\d.]+) %\), single-step ([\d.]+) deg", out)
        table.append(("B error, Fig. 7 on playscope's simulator: two-step (ours) / single-step pose-based",
                      f"{m[1]} deg / {m[3]} deg", "< 0.35 deg", "paper 0.7 deg / 6.6 deg", "bench/fig7_sim_pose.py"))

    # The main job's output folder stays for the run: bench/online_noregress.py reuses it.
    keep = tempfile.TemporaryDirectory(prefix="playscope-run_all-")
    main_dir = Path(keep.name) / "main"

    def mainjob():
        tmp = keep.name
        t0 = time.perf_counter()
        out = sh(PLAYSCOPE + ["demo", "--out", str(main_dir), "--json", f"{tmp}/s.json"])
        wall = time.perf_counter() - t0
        EXCERPT[:] = main_job_excerpt(out)
        s = json.loads(Path(f"{tmp}/s.json").read_text())
        if not a.no_write:
            save_report_figure(main_dir / "report.html", "characteristic", FIGURE)
        c = "playscope demo"
        b = s["b_error"]
        table.append(("main job: B(q) error vs the simulator's centre width, mean / max", f"{b['mean']:.4f} / {b['max']:.4f} mm", "", "", c))
        if b.get("spread"):
            table.append(("main job: B_est / B_true, min / mean / max (the onset lies between the first motion "
                          f"{1 - b['spread']:g} B and the centre width B)",
                          f"{b['ratio_min']:.2f} / {b['ratio_mean']:.2f} / {b['ratio_max']:.2f}",
                          f"{1 - b['spread']:g} .. 1", "", c))
        p = s["prediction"]
        ratio = p["f_remain+B"]["c_rmse_truth_deg"] / p["f_coarse"]["c_rmse_truth_deg"]
        table.append(("main job: Table I, f_remain+B / f_coarse, bending-angle RMSE",
                      f"{p['f_remain+B']['c_rmse_truth_deg']:.2f} / {p['f_coarse']['c_rmse_truth_deg']:.2f} deg ({ratio:.2f})",
                      "", "paper, image distance: 40 / 89 px (0.45)", c))
        qx = p["f_remain+B"]["Qx_px"]["mean"] / p["f_coarse"]["Qx_px"]["mean"]
        table.append(("main job: Table I, f_remain+B / f_coarse, mean abs(Qx)",
                      f"{p['f_remain+B']['Qx_px']['mean']:.1f} / {p['f_coarse']['Qx_px']['mean']:.1f} px ({qx:.2f})",
                      "", "paper 17 / 78 px (0.22)", c))
        comp = s["compensation"]
        table.append(("main job: open-loop compensation RMSE, f_remain+B vs f_coarse^-1",
                      f"{comp['f_remain+B']['c_rmse_deg']:.2f} vs {comp['f_coarse_inv']['c_rmse_deg']:.2f} deg", "", "", c))
        if "f_remain+B+PI_fixed" in comp:
            table.append(("main job: open-loop compensation RMSE with the transition, fixed-point tables",
                          f"{comp['f_remain+B+PI_fixed']['c_rmse_deg']:.3f} deg (pure play "
                          f"{comp['f_remain+B']['c_rmse_deg']:.3f})", "<= 0.3 deg", "", c))
        table.append(("main job wall time, already installed", f"{wall:.1f} s", "< 30 s", "", c))

    def real():
        if not Path(a.catheter).is_dir():
            raise RuntimeError(f"{a.catheter} not found")
        with tempfile.TemporaryDirectory() as tmp:
            sh(PLAYSCOPE + ["evaluate-real", a.catheter, "--json", f"{tmp}/r.json"])
            r = json.loads(Path(f"{tmp}/r.json").read_text())
        c = "playscope evaluate-real"
        for key, label in (("in_situ", "in situ"), ("across", "across sessions")):
            rows = r[key].values()
            mean = {m: sum(x[m] for x in rows) / len(rows) for m in ("linear", "const_play", "ours")}
            worse = sum(x["ours"] > x["const_play"] for x in rows)
            table.append((f"real catheter data, {label}: mean RMSE ours", f"{mean['ours']:.2f} deg "
                          f"(worse than constant play on {worse} of {len(rows)} files)",
                          "<= constant play on every file, in situ" if key == "in_situ" else "",
                          f"linear {mean['linear']:.2f}, constant play {mean['const_play']:.2f} deg", c))

    def selftest():
        with tempfile.TemporaryDirectory() as tmp:
            sh([PY, "bench/diagnose_selftest.py", "--quick", "--second", "--catheter", a.catheter,
                "--json", f"{tmp}/d.json"], timeout=7200)
            d = json.loads(Path(f"{tmp}/d.json").read_text())
        c = "bench/diagnose_selftest.py --quick --second"
        # Both generators' per-effect confusion (every planted case counts, identifiable in situ?
        # from each generator's own oracle) go to docs/results.md as the bench printed them.
        table.extend(selftest_rows(d, c))
        cat = d.get("catheter", {}).get("in_situ", {})
        if cat:
            worst = max(v["kept_model"]["test"] for v in cat.values())
            base = [v["base"]["test"] for v in cat.values()]
            table.append(("catheter, test quarter (no fit, no selection) with the effects kept on validation (worst file)",
                          f"{worst:.2f} deg", "< 0.8 deg on every file",
                          f"play + f_remain {min(base):.2f}-{max(base):.2f} deg", c))
            prod = [v["product_test"] for v in cat.values() if v.get("product_test")]
            if prod:
                table.append(("catheter, test quarter: the product's calibrate with the kept effects it can represent (worst file)",
                              f"{max(p['with_kept'] for p in prod):.2f} deg", "",
                              f"calibrate --model play {min(p['play'] for p in prod):.2f}-{max(p['play'] for p in prod):.2f} deg", c))

    part("firmware", firmware)

    # The transition model's rows (16 operators, realistic and stress) come with
    # the firmware part above, from the same bench_firmware.sh run.
    part("host", host)
    part("link", link)
    part("Fig. 7 replica", fig7)
    part("main job", mainjob)
    part("real data", real)

    # -- in situ with state carried, every model on the same split (bench/insitu_real.py)
    def insitu_real():
        with tempfile.TemporaryDirectory() as tmp:
            printed = sh([PY, "bench/insitu_real.py", "--catheter", a.catheter, "--json", f"{tmp}/i.json"])
            r = json.loads(Path(f"{tmp}/i.json").read_text())
        # ours / best peer per instrument and split, geometric mean beside the worst file
        table.extend(insitu_rows(r, printed))
        for key, summ in r.get("summary", {}).items():  # the invertible peers and the best row, per split
            dv = summ.get("development")
            if dv and "ours_le_best_invertible_files" in dv:
                inst, split = key.split("@")
                table.append((f"in situ, {inst} (development files), split {split}: ours <= the best invertible peer; "
                              "ours within 1.1 x the best row", f"{dv['ours_le_best_invertible_files']} of {dv['files']}; "
                              f"{dv['ours_within_best_files']} of {dv['files']} files",
                              "every file", f"ours <= constant play + poly5 on {dv['ours_le_const_play_files']} of "
                              f"{dv['files']}", "bench/insitu_real.py"))
        c, acc = "bench/insitu_real.py", r["acceptance"]
        files = list(r["in_situ"])
        per_file = lambda m: " / ".join(f"{r['in_situ'][f][m]:.2f}" for f in files)
        table.append((f"catheter in situ, state carried, ours per file ({', '.join(files)})", per_file("ours") + " deg",
                      "<= generalized PI on every file", f"generalized PI {per_file('gpi')} deg", c))
        table.append(("catheter in situ, state carried, ours mean / worst",
                      f"{acc['ours_mean_deg']:.2f} / {acc['ours_worst_deg']:.2f} deg "
                      f"(<= generalized PI on {acc['ours_le_gpi_files']} of {acc['files']} files)",
                      f"mean <= {acc['target_mean_deg']} deg", f"generalized PI mean {acc['gpi_mean_deg']:.2f} deg", c))

    part("in-situ real data", insitu_real)

    # -- why the board carries no memoryless term (bench/memoryless_members.py; docs/method.md)
    def memoryless():
        out = sh([PY, "bench/memoryless_members.py", "--splits", "0.5,0.75", "--families"])
        for inst, fr, m in re.findall(r"\*\*Memoryless term in q, (\w+), split ([\d.]+).*?\n(geomean ours.*?)\n", out, re.S):
            orc = re.search(r"oracle of [^/]+/ best peer ([\d.]+) \(worst ([\d.]+)\)", m)
            ours = re.search(r"geomean ours / best peer ([\d.]+) \(worst ([\d.]+)\)", m)
            if orc and ours:
                table.append((f"{inst} split {fr}: oracle of the invertible members with a memoryless term (best per file "
                              "by test error) / best peer, geomean (worst)", f"{orc.group(1)} ({orc.group(2)})",
                              "what any rule over these members could reach", f"ours {ours.group(1)} ({ours.group(2)})",
                              "bench/memoryless_members.py --families"))

    part("memoryless term", memoryless)

    # -- can a criterion on the calibration part see the judged part's winner (bench/choice_regimes.py; docs/method.md)
    def regimes():
        out = sh([PY, "bench/choice_regimes.py", "--splits", "0.5,0.75"])
        for inst, fr, short, n, cv, last, ins, orc, ours in re.findall(
                r"\n(\w+), split ([\d.]+): judged strokes all shorter than every calibration stroke on (\d+) of (\d+); the "
                r"pick is the oracle's on (\d+) \(CV\), (\d+) \(last fold\), (\d+) \(in sample\) of \d+; oracle within "
                r"1.1 x the best row on (\d+) of \d+, ours on (\d+) of \d+", out):
            table.append((f"{inst} (development files), split {fr}: ours within 1.1 x the best row of its in-situ table; "
                          "the oracle over the families (best judged family)",
                          f"ours on {ours} of {n}; oracle on {orc} of {n}",
                          "every file, or measured why no criterion on the calibration part gets there",
                          f"criteria picking the oracle's family: CV {cv}, last fold {last}, in sample {ins} of {n}; "
                          f"judged strokes all shorter than the calibration part's on {short} of {n}",
                          "bench/choice_regimes.py"))
        for inst, fr, allr, n, norep, orc_l, orc_r, win_l, win_r in re.findall(
                r"\n(\w+), split ([\d.]+), re-pass folds only: (\d+) of (\d+) file-splits have every fold a re-pass, "
                r"(\d+) none; the pick is the oracle's on (\d+) \(re-pass CV\), (\d+) \(the product's rule on the re-pass "
                r"CV\) of \d+; within 1.1 x the best row \(the product's choice where no fold is a re-pass\): the re-pass "
                r"CV's pick on (\d+) of \d+, the product's rule on the re-pass CV on (\d+) of \d+", out):
            table.append((f"{inst} (development files), split {fr}: the choice on the re-pass folds only (branches the "
                          "fold's training part has passed), within 1.1 x the best row",
                          f"lowest re-pass CV on {win_l} of {n}; the product's rule on the re-pass CV on {win_r} of {n}",
                          "every file, or measured why no criterion on the calibration part gets there",
                          f"every fold a re-pass on {allr} of {n}, none on {norep}; picking the oracle's family: "
                          f"{orc_l} / {orc_r} of {n}", "bench/choice_regimes.py"))

    part("choice across regimes", regimes)

    # -- on-line update during use (bench/online_real.py; docs/online.md)
    def online_real():
        with tempfile.TemporaryDirectory() as tmp:
            sh([PY, "bench/online_real.py", a.catheter, "--json", f"{tmp}/o.json"])
            r = json.loads(Path(f"{tmp}/o.json").read_text())
        files = list(r["files"])
        per = lambda m: " / ".join(f"{r['files'][f]['rmse_deg'][m]:.2f}" for f in files)
        won = sum(r["files"][f]["rmse_deg"]["online"] <= r["files"][f]["rmse_deg"]["const_play_insitu"] for f in files)
        table.append((f"catheter across sessions with on-line update, ours per file ({', '.join(files)})",
                      per("online") + f" deg (<= in-situ constant play on {won} of {len(files)} files)",
                      "<= constant play refitted in situ on every file",
                      f"constant play in situ {per('const_play_insitu')}; without update {per('static')}; "
                      f"constant play of data_2_1 + same offset refresh {per('const_play_ref_offset')} deg",
                      "bench/online_real.py"))
        fw = md_rows(sh(["bench/bench_firmware.sh"]))
        table.append(("M4 instructions of b_online_sample (on-line B), built-in table / costliest grid (16 nodes): average / worst",
                      f"{find(fw, 'b_online_sample (')[0]}; {find(fw, 'b_online_sample, costliest')[0]}",
                      "off the tick (on the observation that completes an onset)", "", "bench/bench_firmware.sh"))

    part("on-line update", online_real)

    # -- a calibration used in another session or configuration (bench/transfer_real.py)
    def transfer():
        out = sh([PY, "bench/transfer_real.py"])
        rows = md_rows(out.split("\n**")[0])  # the first table: the catheter, calibrated on data_2_1
        ref = find(rows, "constant play + poly5 of the calibration record + offset refresh")
        ours = find(rows, "transferred with transition + offset refresh")
        table.append(("catheter calibrated on data_2_1, run on data_2_2..5: transition + offset refresh, mean (worst)",
                      f"{ours[-2]} ({ours[-1]}) deg", "<= 0.8 x constant play with the same refresh",
                      f"constant play of data_2_1 + offset refresh {ref[-2]} ({ref[-1]}) deg", "bench/transfer_real.py"))
        ref_b = find(rows, "constant play + poly5 of the calibration record + the board's offset and gain learner")
        ours_b = find(rows, "transferred with transition + the board's offset and gain learner")
        per = lambda r: " / ".join(r[:-2])
        table.append(("catheter calibrated on data_2_1, run on data_2_2..5: transition + the board's offset and gain "
                      "learner (f_online.c), per file; mean (worst)",
                      f"{per(ours_b)}; {ours_b[-2]} ({ours_b[-1]}) deg",
                      "mean <= 0.8 x, and every file <=, the constant play with the same learner",
                      f"constant play of data_2_1 + the same learner {per(ref_b)}; {ref_b[-2]} ({ref_b[-1]}) deg",
                      "bench/transfer_real.py"))
        # Ours against the textbook peers calibrated on the same record and given the same learner (both catheter sets).
        for cal_on, block in re.findall(r"\*\*Calibrated on (data_\d_\d), (.*?)(?=\n\*\*|\Z)", out, re.S):
            m = re.search(r"Ours with the transition \+ the board's offset and gain learner: mean ([\d.]+) deg; best peer "
                          r"given the same, (.*?): ([\d.]+) deg; ours <= every peer: (\w+)", block)
            if m:
                table.append((f"catheter calibrated on {cal_on}, run on the other records of its set: transition + the "
                              "board's learner against every textbook peer (generalized / modified PI and their invertible "
                              "forms) given the same learner, mean", f"{m.group(1)} deg (ours <= every peer: {m.group(4)})",
                              "<= every peer", f"best peer, {m.group(2)}: {m.group(3)} deg", "bench/transfer_real.py"))
        pairs = re.search(r"transferred with transition \+ the board's offset and gain learner / in situ: (.*)", out)
        if pairs:
            table.append(("endoscope development pairs (calibrated in one sheath configuration, run in another): "
                          "transition + the board's learner / in situ", pairs.group(1).strip(), "within 1.5 x on each", "",
                          "bench/transfer_real.py"))

    part("transfer", transfer)

    def noregress():
        out = sh([PY, "bench/online_noregress.py"] + (["--main", str(main_dir)] if main_dir.is_dir() else []))
        rows = md_rows(out)
        mj = find(rows, "main job")
        cat = [(k, v) for k, v in rows.items() if k.startswith("data_2_") or "catheter in situ" in k]
        worst = max(cat, key=lambda kv: float(kv[1][-1].rstrip(" %")))
        table.append(("the board's offset and gain learner where nothing drifts: main job compensation RMSE off / on",
                      f"{mj[0]} / {mj[1]} deg ({mj[2]})", "<= +2 %", "", "bench/online_noregress.py"))
        table.append(("the board's offset and gain learner where nothing drifts: catheter in situ, worst change",
                      f"{worst[1][-1]} ({worst[0].replace('catheter in situ, ', '')})", "<= +2 %", "",
                      "bench/online_noregress.py"))

    part("no regression with the learner on", noregress)

    def startup():
        out = sh([PY, "bench/bench_startup.py", "10"])
        for key in ("playscope --version", "playscope --help"):
            r = find(md_rows(out), key)
            table.append((f"start-up `{key}`: mean / worst of 10", f"{r[0]} / {r[1]} s", "< 0.3 s", "",
                          "bench/bench_startup.py"))

    part("start-up", startup)

    def diagnose_speed():
        out = sh([PY, "bench/diagnose_speed.py", "--runs", "5"])
        m = re.search(r"median ([\d.]+) s\s+worst ([\d.]+) s", out)
        if not m:
            raise RuntimeError("bench/diagnose_speed.py printed no median")
        table.append(("diagnose a 275-s record (attribution and atlas): median / worst of 5", f"{m[1]} / {m[2]} s",
                      "median <= 20 s", "", "bench/diagnose_speed.py"))

    part("diagnosis speed", diagnose_speed)

    # -- does a planted asymmetric play leave a trace at all? (bench/diagnose_trace.py; docs/diagnosis.md)
    def asym_trace():
        out = sh([PY, "bench/diagnose_trace.py", "--nulls", "6"])
        ways = "fit from the start / without the first 10 s / twice the knots"
        groups: dict[tuple[str, str], list[list[float]]] = {}
        for g, what, cells in re.findall(r"^(first|second)\s+(\S+)\s+\(seed \d+\)\s+[\d.]+ \|(.*)$", out, re.M):
            ex = [float(a) for a, _ in re.findall(r"(-?[\d.]+)\s+(-?[\d.]+)", cells)]  # (excess noisy, clean) per way
            key = (g, "nulls" if what.startswith("null") else what.split("@")[0].split("/")[-1])
            groups.setdefault(key, []).append(ex)
        if not groups:
            raise RuntimeError("bench/diagnose_trace.py printed no case rows")
        for (g, form), rows in groups.items():
            if any(len(r) != 3 for r in rows):
                raise RuntimeError(f"bench/diagnose_trace.py: unexpected row for {g} {form}")
            rng = " / ".join(f"{min(r[i] for r in rows):.4f}-{max(r[i] for r in rows):.4f}" for i in range(3))
            target = ("the base model's own misfit: what a trace must clear" if form == "nulls"
                      else "a trace: above the nulls in all three ways")
            table.append((f"asymmetric play, base-model trace, {g} generator, {form} ({len(rows)} records): "
                          f"excess over the noise-only RMSE, {ways}", f"{rng} deg", target, "",
                          "bench/diagnose_trace.py --nulls 6"))

    part("asymmetric-play trace", asym_trace)

    # -- the Python tests marked slow: too long for the README's test command, run here (and by
    # ./tools/run-tests.sh --all); CONTRIBUTING.md says which and why. Exit 5: none is marked.
    def slow_tests():
        cmd = [PY, "-m", "pytest", "-q", "-n", "auto", "--dist", "loadfile", "-m", "slow", "tests/python"]
        shown = "python -m pytest -q -n auto --dist loadfile -m slow tests/python"
        r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=7200)
        RAW.append((shown, shown, r.stdout))
        last = next((ln.strip("= ") for ln in reversed(r.stdout.splitlines()) if ln.strip()), "")
        if r.returncode == 5:
            measured = "none marked slow"
        elif r.returncode in (0, 1):
            measured = last
        else:
            raise RuntimeError(f"pytest -m slow exited {r.returncode}: {last}")
        table.append(("Python tests marked slow (left out of ./tools/run-tests.sh)", measured, "all pass", "",
                      "pytest -m slow tests/python"))

    part("slow tests", slow_tests)

    def swings():
        # The development renderings only: the set-aside group is run once, by hand, after the
        # rules are settled (bench/swing_cases.py). The bench exits 1 when a rendering misses its
        # limit; its output is read either way.
        cmd = [PY, "bench/swing_bench.py", "--group", "development"]
        out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=7200).stdout
        RAW.append(("swing", "python bench/swing_bench.py --group development", out))
        table.extend(swing_rows(out, "development", "bench/swing_bench.py --group development"))

    def long_logs():
        # One row per command the bench times, labelled with the exact command line; the
        # measured cell keeps the mean beside the worst run, the target cell the limit.
        c = "bench/bench_long_log.py"
        out = subprocess.run([PY, c], cwd=ROOT, capture_output=True, text=True, timeout=7200).stdout
        RAW.append(("long logs", f"python {c}", out))
        rows = [r for r in md_rows(out).items() if r[0].startswith("playscope ")]
        if not rows:
            raise RuntimeError(f"{c} printed no rows")
        for label, r in rows:
            table.append((f"{label}: wall time mean / worst, peak RSS mean / worst",
                          f"{r[0]} / {r[1]} s, {r[2]} / {r[3]} MiB ({r[5]})", r[4], "", c))

    if a.long_logs:
        part("long logs", long_logs)
    else:
        skipped.append("long logs")
    if a.swings:
        part("fast-swing onsets", swings)
    else:
        skipped.append("fast-swing onsets")
    if not a.skip_selftest:
        part("diagnosis self-test", selftest)
    else:
        skipped.append("diagnosis self-test")

    print(md_table(table))
    if not a.no_write:
        write_results(table, time.perf_counter() - t_run, times, skipped, code)
        print(f"[bench] wrote {RESULTS.relative_to(ROOT)} and the README's summary", file=sys.stderr)
    keep.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
