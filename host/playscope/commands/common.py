"""Helpers shared by the subcommands: --json output and progress bars."""

from __future__ import annotations

import json
import sys

import numpy as np

from ..atomic import write_text_atomic


def add_json_arg(p, keys_doc: str) -> None:
    """Add --json PATH; keys_doc lists the keys written, shown in --help."""
    p.add_argument("--json", metavar="PATH", help=f"also write machine-readable results to PATH. Keys: {keys_doc}")


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
