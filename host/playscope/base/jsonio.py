"""JSON-ready values: numpy arrays and scalars to lists and Python numbers, NaN/inf to null."""

from __future__ import annotations

import numpy as np


def plain_json(o):
    """A copy of o (dicts, lists, tuples, numpy values) that json.dumps writes as standard JSON:
    keys as strings, arrays as lists, numpy scalars as Python numbers, non-finite floats as None."""
    if isinstance(o, dict):
        return {str(k): plain_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [plain_json(v) for v in o]
    if isinstance(o, np.ndarray):
        return plain_json(o.tolist())
    if isinstance(o, np.floating):
        o = float(o)
    if isinstance(o, float) and not np.isfinite(o):
        return None
    if isinstance(o, np.integer):
        return int(o)
    return o


# The real stdout while a `--quiet` command runs with its summary lines silenced (cli.main
# pushes it): `--json -` still reaches it.
STDOUT: list = []


def write_json(path, obj, indent: int = 2) -> None:
    """Write obj (plain_json) to the file path atomically, or to stdout when path is "-" (the
    common meaning of `--json PATH`, docs/host.md); no-op when path is None or empty. A dict
    written to a file starts with "written_by": "playscope", so a later --force knows the file
    is playscope's (atomic.owned_file)."""
    import json
    import sys

    if not path:
        return
    obj = plain_json(obj)
    if path != "-" and isinstance(obj, dict):  # the mark --force checks (atomic.owned_file)
        from .atomic import WRITTEN_BY

        obj = {"written_by": WRITTEN_BY, **obj}
    text = json.dumps(obj, indent=indent) + "\n"
    if path == "-":
        out = STDOUT[-1] if STDOUT else sys.stdout
        out.write(text)
        out.flush()
        return
    from .atomic import write_text_atomic

    write_text_atomic(path, text)
