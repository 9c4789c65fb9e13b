"""Numeric CSV tables read in chunks: bounded memory on long logs, only the columns a caller
uses, what spreadsheets write (a UTF-8 BOM, a trailing separator, empty or NaN cells in unused
or optional columns, empty cells for lost readings), and the time column's exact decimal
value as integers (time_ticks) for the exact rebase of session.time_origin.

Each chunk of CHUNK_ROWS lines is parsed by numpy's C parser (np.loadtxt on the chunk's lines,
only the columns asked for); a chunk it refuses is read again row by row to name the first
offending row. Peak memory: the columns asked for as float64, twice during the final
concatenation, plus one chunk's text.
"""

from __future__ import annotations

import csv
import itertools
import math
import warnings
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from ..base.errors import InputError

# Lines per chunk: about 10-40 MB of text for the logs here, a few hundred ms of parsing.
CHUNK_ROWS = 200_000
# Cells read as a lost reading in a nullable column (empty, or a tracker's NaN).
NAN_TEXT = {"nan", "NaN", "NAN", "-nan", "-NaN"}
# Files above this size show a progress bar while read (stderr, a terminal only).
PROGRESS_BYTES = 20 << 20


def split_header(line: str) -> list[str]:
    """The column names of a header line (csv quoting honoured, names stripped), without the
    empty names a trailing separator leaves (a spreadsheet's "t,q,c,")."""
    names = [h.strip() for h in next(csv.reader([line]), [])]
    while names and names[-1] == "":
        names.pop()
    return names


def _blank(line: str) -> bool:
    """A line np.loadtxt skips: empty, or only a comment (#)."""
    return not line.split("#", 1)[0].strip(" \t\r\n,")


def read_table(path, required, optional=(), nullable=frozenset(), header: list[str] | None = None,
               others: bool = True, progress=None) -> tuple[dict[str, np.ndarray], list[str]]:
    """Read a numeric CSV into float64 columns (n,), in chunks.

    required: names that must be in the header (InputError otherwise); optional: names read
    when present; nullable: names whose empty or NaN cells mean "lost" (NaN); optional columns
    are nullable here too, the caller decides what a NaN in them means. others: also keep the
    header's other named columns, leniently (a cell that is not a finite number is NaN: they are
    not used by the method). header: the column names of a headerless file (its first line is
    data, row 1); None reads them from the first line (row 1, data from row 2). progress: a
    tqdm-like factory (commands.common.progress) for a bar over the bytes of a file above
    PROGRESS_BYTES, or None.
    A BOM is skipped; a trailing separator (an empty last name, empty last fields) is ignored;
    blank and comment-only (#) lines are skipped. Returns ({name: array}, header).
    Errors: InputError(path, message, row) naming the first offending row: a missing or
    duplicated column, a row without a used field, an empty, non-numeric or non-finite value in
    a used column that is not nullable, no data rows, a file that is not UTF-8 text."""
    path = Path(path)
    required, optional = list(required), list(optional)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            if header is None:
                first = fh.readline()
                if not first.strip():
                    raise InputError(path, "empty file (no header row)", 1)
                names = split_header(first)
                row0 = 2
            else:
                names, row0 = list(header), 1
            for name in required:
                if name not in names:
                    raise InputError(path, f"missing column {name!r} (header: {','.join(names)})", 1)
            dup = sorted({h for h in names if h and names.count(h) > 1})
            if dup:
                raise InputError(path, f"column {dup[0]!r} appears {names.count(dup[0])} times in the header "
                                 f"({','.join(names)}): which one is meant? rename or drop the others", 1)
            use = required + [o for o in optional if o in names and o not in required]
            extra = [h for h in names if h and h not in use] if others else []
            cols = use + extra
            idx = [names.index(c) for c in cols]
            null = set(nullable) | set(optional)
            parts: list[np.ndarray] = []
            size = path.stat().st_size
            bar = progress(total=size, desc=f"reading {path.name}", unit="B", unit_scale=True,
                           unit_divisor=1024) if progress is not None and size >= PROGRESS_BYTES else None
            base = row0  # file row of the chunk's first line
            try:
                while True:
                    lines = list(itertools.islice(fh, CHUNK_ROWS))
                    if not lines:
                        break
                    parts.append(_parse_chunk(lines, path, base, names, cols, idx, len(use), null))
                    base += len(lines)
                    if bar is not None:
                        bar.update(sum(map(len, lines)))  # a generator took 2.7 of 7.2 s (cProfile, 3.6 M rows)
            finally:
                if bar is not None:
                    bar.close()
    except UnicodeDecodeError as e:
        raise InputError(path, f"not UTF-8 text (byte {e.start}): a CSV of numbers was expected") from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}; check the permissions") from None
    data = np.concatenate(parts) if parts else np.empty((0, len(cols)))
    parts.clear()
    if data.shape[0] == 0:
        raise InputError(path, "no data rows", row0)
    return {c: np.ascontiguousarray(data[:, j]) for j, c in enumerate(cols)}, names


def _parse_chunk(lines, path, base, names, cols, idx, n_use, null) -> np.ndarray:
    """(rows, len(cols)) float64 of one chunk: the C parser, checked; else row by row."""
    if idx:
        try:
            with warnings.catch_warnings():  # "no data" on a chunk of blank lines: zero rows
                warnings.simplefilter("ignore")
                a = np.loadtxt(lines, delimiter=",", usecols=idx, ndmin=2, dtype=float)
        except (ValueError, IndexError):
            a = None
        if a is not None and a.shape[1] == len(cols):
            used = a[:, :n_use]
            bad = ~np.isfinite(used)
            ok = True
            if bad.any():
                # NaN in a nullable column is a lost reading; anything else (inf, NaN elsewhere)
                # goes to the row-by-row reader for its message.
                nullable = np.array([c in null for c in cols[:n_use]])
                ok = not np.any(bad & ~(np.isnan(used) & nullable))
            if ok:
                if a.shape[1] > n_use:  # other columns: not a finite number -> NaN
                    rest = a[:, n_use:]
                    rest[~np.isfinite(rest)] = np.nan
                return a
    return _parse_rows(lines, path, base, names, cols, idx, n_use, null)


def _parse_rows(lines, path, base, names, cols, idx, n_use, null) -> np.ndarray:
    """One chunk row by row, naming the first row the C parser would not take."""
    out = np.full((len(lines), len(cols)), np.nan)
    k = 0
    try:
        rows = list(csv.reader(lines))
    except csv.Error as e:
        raise InputError(path, f"not a CSV file ({e})", base) from None
    need = max(idx[:n_use], default=-1) + 1
    for i, (line, row) in enumerate(zip(lines, rows)):
        lineno = base + i
        if _blank(line):
            continue
        if len(row) < need or (len(row) > len(names) and any(x.strip() for x in row[len(names):])):
            raise InputError(path, f"expected {len(names)} fields, found {len(row)} (truncated or malformed row)",
                             lineno)
        for j, (c, col) in enumerate(zip(cols, idx)):
            cell = row[col].split("#", 1)[0].strip() if col < len(row) else ""
            if j >= n_use:  # a column the method does not use: lenient
                try:
                    x = float(cell)
                except ValueError:
                    x = math.nan
                out[k, j] = x if math.isfinite(x) else math.nan
                continue
            if cell == "" or cell in NAN_TEXT:
                if c in null:
                    continue
                raise InputError(path, (f"empty value in column {c!r}" if cell == "" else
                                        f"non-finite value in column {c!r}: {cell!r}"), lineno)
            try:
                x = float(cell)
            except ValueError:
                raise InputError(path, f"not a number in column {c!r}: {cell!r}", lineno) from None
            if not math.isfinite(x):
                raise InputError(path, f"non-finite value in column {c!r}: {cell!r}", lineno)
            out[k, j] = x
        k += 1
    return out[:k]


# --------------------------------------------------------------------------- exact time stamps
def time_ticks(path, col: int, has_header: bool = True) -> tuple[np.ndarray, int] | None:
    """The time column's exact decimal values as integers: (ticks (n,), D) with value = ticks /
    10^D, D the most decimals of any stamp, one entry per data row in read_table's order (blank
    and comment lines skipped). ticks is int64, or an object array of Python ints when a value
    does not fit (e.g. a 19-digit nanosecond epoch stamp with decimals). Fixed-format stamps are
    converted by numpy per group of equal layout (sign, digits before and after the point);
    others (an exponent) through Decimal. None when the file cannot be read again or a stamp is
    not a decimal number."""
    chunks: list[tuple[np.ndarray, np.ndarray]] = []  # (integer digits as int, decimals) per chunk
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            if has_header:
                fh.readline()
            while True:
                lines = list(itertools.islice(fh, CHUNK_ROWS))
                if not lines:
                    break
                fields = [ln.split("#", 1)[0].split(",")[col].strip() if col < ln.count(",") + 1 else ""
                          for ln in lines if not _blank(ln)]
                chunks.append(_ticks_of(fields))
    except (OSError, UnicodeDecodeError, InvalidOperation, ValueError, IndexError):
        return None
    if not chunks:
        return np.empty(0, np.int64), 0
    D = max(int(d.max(initial=0)) for _, d in chunks)
    out = [_scaled(v, D - d) for v, d in chunks]
    if any(o.dtype == object for o in out):
        return np.concatenate([o.astype(object) for o in out]), D
    return np.concatenate(out), D


def _scaled(v: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """v * 10^shift, int64 when every product fits, else Python ints (object)."""
    if v.dtype != object and int(shift.max(initial=0)) <= 18:
        p10 = 10 ** shift.astype(np.int64)
        if np.all(np.abs(v) <= np.iinfo(np.int64).max // p10):
            return v * p10
    return np.array([int(a) * 10 ** int(s) for a, s in zip(v, shift)], dtype=object)


def _ticks_of(fields: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(digits as integers, decimals) of decimal texts: "-12.0450" -> (-120450, 4). Texts of one
    layout are converted together from their bytes; an exponent or an overlong number goes
    through Decimal. Errors: ValueError / InvalidOperation for a text that is not a number."""
    n = len(fields)
    vals = np.zeros(n, np.int64)
    decs = np.zeros(n, np.int64)
    if n == 0:
        return vals, decs
    b = np.array(fields, dtype="S")
    w = b.dtype.itemsize
    m = b.view(np.uint8).reshape(n, w)
    length = (m != 0).sum(1)
    dot = np.where((m == 46).any(1), (m == 46).argmax(1), length)
    neg = m[:, 0] == 45
    digit = (m >= 48) & (m <= 57)
    # A plain decimal: every byte a digit except one leading sign and one point, < 19 digits.
    plain = (digit.sum(1) + neg + (dot < length)) == length
    plain &= (digit.sum(1) > 0) & (digit.sum(1) <= 18)
    slow = np.flatnonzero(~plain)
    obj = None
    for key in np.unique(np.stack([length, dot, neg], 1)[plain], axis=0):
        L, d, s = (int(x) for x in key)
        sel = np.flatnonzero(plain & (length == L) & (dot == d) & (neg == s))
        pos = np.arange(w)
        ex = np.where(pos < d, d - 1 - pos, d - pos)  # power of ten of each byte (the point: unused)
        ex = ex + (L - d - 1 if d < L else 0)
        wgt = np.where((pos >= int(s)) & (pos < L) & (pos != d), 10 ** np.clip(ex, 0, 18), 0).astype(np.int64)
        v = (m[sel].astype(np.int64) - 48) @ wgt
        vals[sel] = -v if s else v
        decs[sel] = L - d - 1 if d < L else 0
    if slow.size:
        obj = vals.astype(object)
        for i in slow:
            x = Decimal(fields[i])
            if not x.is_finite():
                raise ValueError(fields[i])
            sign, digits, exp = x.as_tuple()
            k = max(0, -exp)
            obj[i] = int(x.scaleb(k))
            decs[i] = k
        if all(abs(int(a)) <= np.iinfo(np.int64).max for a in obj):
            return obj.astype(np.int64), decs
        return obj, decs
    return vals, decs

