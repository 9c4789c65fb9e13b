"""On-line update during use on the real catheter recordings (issue 13 item 4): prints the
table of docs/online.md. Calibrate the pure play on data_2_1, run every other file from its
start with the board's RLS on B (firmware/core/b_online.c through cffi) and the host's offset
refresh, score after its first 20 %; beside it the same model without update and a constant
play + poly5 refitted in situ on the file's first 20 %. The recordings are read in place.

Usage: .venv/bin/python bench/online_real.py [FOLDER] [--json OUT]   (about 10 s)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from playscope.online import evaluate_real_online, format_online

DEFAULT = Path(__file__).resolve().parents[1] / ".." / ".." / "shared" / "data" / "real" / "catheter"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", nargs="?", default=str(DEFAULT if DEFAULT.is_dir() else Path("/work/shared/data/real/catheter")))
    p.add_argument("--json", help="also write the result here")
    a = p.parse_args(argv)
    if not Path(a.folder).is_dir():
        print(f"online_real: no recordings folder {a.folder}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    res = evaluate_real_online(a.folder)
    print(format_online(res))
    print(f"({time.perf_counter() - t0:.1f} s)")
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
