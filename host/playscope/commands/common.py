"""Helpers shared by the subcommands: --json output and progress bars."""

from __future__ import annotations

import json
import sys

import numpy as np

from ..atomic import write_text_atomic


def add_json_arg(p, keys_doc: str) -> None:
    """Add --json PATH; keys_doc lists the keys written, shown in --help."""
    from ..argtypes import file_path

    p.add_argument("--json", metavar="PATH", type=file_path,
                   help=f"also write machine-readable results to PATH. Keys: {keys_doc}")


Q16_LIMIT = 32767.0  # |q| a Q16.16 int32 holds (common/ps_fixed.h), actuator units


def load_calibration(path):
    """Calibration.load behind a file-level check (readable, UTF-8, a JSON object, a q_range of
    two finite numbers q_min < q_max inside Q16.16): one-line InputError naming the file."""
    import math

    from ..calibration import FORMAT, Calibration
    from ..errors import InputError
    from ..session import read_json

    d = read_json(path, "calibration JSON")
    if not isinstance(d, dict):
        raise InputError(path, f"a calibration is a JSON object, this file holds a {type(d).__name__}; "
                         "make one with `playscope calibrate`")
    if d.get("format") != FORMAT:
        raise InputError(path, f"format is {d.get('format')!r}, not a calibration ({FORMAT!r}); "
                         "make one with `playscope calibrate`")
    qr = d.get("q_range")
    if not (isinstance(qr, list) and len(qr) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                           and math.isfinite(x) for x in qr)):
        raise InputError(path, f"q_range must be two finite numbers [q_min, q_max], got {qr!r}")
    if not -Q16_LIMIT <= qr[0] < qr[1] <= Q16_LIMIT:
        raise InputError(path, f"q_range {qr} must satisfy -{Q16_LIMIT:g} <= q_min < q_max <= {Q16_LIMIT:g} "
                         "(actuator units in Q16.16)")
    return Calibration.load(path)


def _plain(o):
    if isinstance(o, dict):
        return {str(k): _plain(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_plain(v) for v in o]
    if isinstance(o, np.ndarray):
        return _plain(o.tolist())
    if isinstance(o, (np.floating,)):
        o = float(o)
    if isinstance(o, float) and not np.isfinite(o):
        return None
    if isinstance(o, np.integer):
        return int(o)
    return o


def dump_json(path: str | None, obj: dict) -> None:
    """Write obj as JSON (NaN -> null, numpy -> lists) atomically; no-op when path is None."""
    if path:
        write_text_atomic(path, json.dumps(_plain(obj), indent=2) + "\n")


def progress(iterable=None, **kw):
    """tqdm on stderr, silent when stderr is not a terminal (logs, tests)."""
    from tqdm import tqdm

    kw.setdefault("disable", not sys.stderr.isatty())
    kw.setdefault("leave", False)
    return tqdm(iterable, file=sys.stderr, **kw)
