"""The step a long computation is in, for whoever shows progress: the fitting code names its
steps (`stage("record model")`), the command line's busy line shows them beside the elapsed time
(commands.common.busy). No sink: a no-op, so library callers and tests see nothing.

Why a sink and not a callback through every signature: the steps are deep in the chain (the
calibration's onset stage, its pose estimation, its model choice) and the fitting code must not
import the command line's tqdm."""

from __future__ import annotations

import contextlib
from contextvars import ContextVar
from typing import Callable

_SINK: ContextVar[Callable[[str], None] | None] = ContextVar("playscope_stage_sink", default=None)


def stage(name: str) -> None:
    """Report that the computation has reached step name (a few words, no trailing period)."""
    sink = _SINK.get()
    if sink is not None:
        sink(name)


@contextlib.contextmanager
def stage_sink(fn: Callable[[str], None]):
    """Within the block, stage(name) calls fn(name)."""
    tok = _SINK.set(fn)
    try:
        yield
    finally:
        _SINK.reset(tok)
