"""On-line update during use on the real catheter recordings: prints the
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

from playscope.board.online import evaluate_real_online, format_online

DEFAULT = Path(__file__).resolve().parents[1] / ".." / ".." / "shared" / "data" / "real" / "catheter"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", nargs="?", default=str(DEFAULT if DEFAULT.is_dir() else Path("/work/shared/data/real/catheter")))
    p.add_argument("--json", help="also write the result here")
    p.add_argument("--sensitivity", action="store_true",
                   help="also the on-line row with the forgetting memory tau in {4, 8, 16} reversals and the offset "
                   "refresh every 1 or 5 s (reported beside the defaults, never used to choose them)")
    a = p.parse_args(argv)
    if not Path(a.folder).is_dir():
        print(f"online_real: no recordings folder {a.folder}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    res = evaluate_real_online(a.folder)
    print(format_online(res))
    print(f"({time.perf_counter() - t0:.1f} s)")
    if a.sensitivity:
        from playscope.base.native import core
        from playscope.board.online import OnlineSettings

        _, lib = core()
        print("**Sensitivity of the on-line row (mean / worst RMSE, deg; files <= in-situ constant play)**\n")
        print("| tau (reversals) | refresh (s) | ours, on-line B + offset | ours, offset only |")
        print("|---|---|---|---|")
        for tau in (4, 8, 16):
            for refresh in (1.0, 5.0):
                bc = lib.b_online_default_config()
                bc.lambda_q30 = int(round((1 - 1 / tau) * (1 << lib.B_ONLINE_P_FRAC_BITS)))
                r = evaluate_real_online(a.folder, settings=OnlineSettings(refresh_s=refresh), b_config=bc)
                cell = []
                for m in ("online", "online_offset_only"):
                    v = [x["rmse_deg"][m] for x in r["files"].values()]
                    won = sum(x["rmse_deg"][m] <= x["rmse_deg"]["const_play_insitu"] for x in r["files"].values())
                    cell.append(f"{sum(v) / len(v):.2f} / {max(v):.2f} ({won} of {len(v)})")
                print(f"| {tau} | {refresh:g} | {cell[0]} | {cell[1]} |")
        print()
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
