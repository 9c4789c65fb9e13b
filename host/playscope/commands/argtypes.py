"""Reusable argparse ``type=`` callables: every command-line value is range-checked here, so a
bad value is one line from argparse (exit 2), never a traceback deep in the chain.

Each factory returns a callable ``str -> value`` raising argparse.ArgumentTypeError with the
accepted range; the callables carry a readable ``__name__`` for argparse's messages.
"""

from __future__ import annotations

import argparse
import math
import os


def _named(fn, name: str):
    fn.__name__ = name
    return fn


def int_range(lo: int, hi: int):
    """An integer in lo..hi (inclusive)."""
    def parse(text: str) -> int:
        try:
            v = int(text, 0) if text.strip().lower().startswith(("0x", "-0x")) else int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer (expected {lo}..{hi})") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{v} is outside {lo}..{hi}")
        return v
    return _named(parse, f"integer {lo}..{hi}")


def float_range(lo: float | None = None, hi: float | None = None, lo_open: bool = False, hi_open: bool = False):
    """A finite float in [lo, hi] (an end None is unbounded; *_open excludes the end)."""
    span = f"{'(' if lo_open else '['}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}{')' if hi_open else ']'}"

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number (expected {span})") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{text!r} is not finite (expected {span})")
        if lo is not None and (v < lo or (lo_open and v == lo)) or hi is not None and (v > hi or (hi_open and v == hi)):
            raise argparse.ArgumentTypeError(f"{v:g} is outside {span}")
        return v
    return _named(parse, f"number in {span}")


def nonzero_float(limit: float = 1e9):
    """A finite float with 0 < |v| <= limit (a scale or a gain)."""
    def parse(text: str) -> float:
        v = float_range(-limit, limit)(text)
        if v == 0:
            raise argparse.ArgumentTypeError("must not be 0")
        return v
    return _named(parse, f"non-zero number in [-{limit:g}, {limit:g}]")


def existing_file(text: str) -> str:
    """A path to an existing regular file (not a folder)."""
    if os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text}: is a folder, not a file")
    if not os.path.isfile(text):
        raise argparse.ArgumentTypeError(f"{text}: no such file")
    return text


def elf_file(text: str) -> str:
    """An existing ELF executable (the QEMU board's firmware image): its first bytes are
    checked here, so a wrong file is named instead of failing later as a broken pipe."""
    existing_file(text)
    try:
        with open(text, "rb") as fh:
            head = fh.read(4)
    except OSError as e:
        raise argparse.ArgumentTypeError(f"{text}: cannot read: {e.strerror or e}") from None
    if head != b"\x7fELF":
        raise argparse.ArgumentTypeError(f"{text}: not an ELF firmware image (build it with "
                                         "`cmake --build --preset stm32f405`)")
    return text


def split_spec(text: str) -> str:
    """A split of a record: a fraction in (0, 1), or a time in s from its first sample with an
    s suffix ("30s", finite, > 0). Returned as given (insitu.split_time reads it)."""
    t = text.strip()
    body = t[:-1] if t.endswith("s") else t
    try:
        v = float(body)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give a fraction in (0, 1) like 0.5, or a time like 30s") from None
    if not math.isfinite(v) or v <= 0 or (not t.endswith("s") and v >= 1):
        raise argparse.ArgumentTypeError(f"{text!r}: give a fraction in (0, 1) like 0.5, or a finite time > 0 "
                                         "like 30s")
    return t


def file_path(text: str) -> str:
    """A path for a file to write: not empty, not a folder (its folder is made when missing)."""
    if not text:
        raise argparse.ArgumentTypeError("empty path")
    if os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text}: is a folder, a file path was expected")
    return text


def host_port(text: str) -> str:
    """host:port with a port in 1..65535."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not host:port (port 1..65535)")
    return text


def colon_floats(n: int, what: str, n_min: int | None = None):
    """n finite numbers separated by colons (e.g. Q0:Q1:AMP:ADV:V); n_min..n of them when n_min is given."""
    lo = n if n_min is None else n_min
    count = f"{n}" if lo == n else f"{lo} to {n}"

    def parse(text: str) -> str:
        parts = text.split(":")
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            vals = []
        if not lo <= len(vals) <= n or not all(math.isfinite(v) for v in vals):
            raise argparse.ArgumentTypeError(f"{text!r} is not {what} ({count} finite numbers separated by ':')")
        return text
    return _named(parse, what)


# Shared ranges, so the same option means the same bounds in every command.
CONTROL_POINTS = int_range(4, 64)          # cubic B-spline control points: >= 4 for a cubic; paper 14
VECTORS = int_range(1, 100_000)            # compensator test steps after a flash
SEED = int_range(0, 2**32 - 1)
GENERATION = int_range(1, 2**32 - 1)       # pst_header_t.generation (uint32; 0 = "no table")
INSTRUMENT = int_range(0, 2**32 - 1)       # pst_instrument_t.id (uint32)
FPS = float_range(0.5, 10_000.0)           # Hz: a frame rate for a sensor log
T_DELAY_S = float_range(0.0, 10.0)         # s: image acquisition delay
THRESHOLD = float_range(0.0, 10_000.0, lo_open=True)   # px or deg per frame (Q16.16 on the board)
HYSTERESIS = float_range(0.0, 10_000.0, lo_open=True)  # actuator units
DURATION_S = float_range(0.0, 86_400.0, lo_open=True)
TIME_SCALE = float_range(0.0, 100.0, lo_open=True)     # virtual board clock speed-up (ps_vboard's own bound)
