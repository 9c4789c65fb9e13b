"""Start-up time of the `playscope` command: --version, --help, a subcommand's --help, each
run N times as a fresh process (the installed entry point's interpreter with this tree's
host/ on PYTHONPATH). Prints one row per command line: mean and worst wall time.

    PYTHONPATH=host python bench/bench_startup.py [N]
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

LINES = [["--version"], ["--help"], ["calibrate", "--help"], ["flash", "--help"]]


def main(n: int = 10) -> None:
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "host"))
    print(f"| command (n = {n}) | mean s | worst s |\n|---|---|---|")
    for argv in LINES:
        ts = []
        for _ in range(n):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "playscope.cli", *argv], env=env, capture_output=True, check=True)
            ts.append(time.perf_counter() - t0)
        print(f"| playscope {' '.join(argv)} | {sum(ts) / n:.3f} | {max(ts):.3f} |")


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("n", nargs="?", type=int, default=10, help="runs per command line (default 10)")
    main(ap.parse_args().n)
