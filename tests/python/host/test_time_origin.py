"""Time-origin invariance: the same motion gives the same calibration whatever its clock's
origin. Every t_s of a session is shifted by a constant, written as exact decimal text (as a
logger with that origin would have written it), and calibrate -> tables must give the same
table bytes as the unshifted session (session.time_origin: times made relative to the
session's first stamp through integer microseconds at load).

The session is the test helper's angle session over half the travel (58 s, 22 reversals, the
B spline and the model choice as on a full record): every stage of calibrate -> tables is
checked at a third of the cost of the 138-s session of goodfiles.make_good."""

from __future__ import annotations

import shutil
from decimal import Decimal

import numpy as np
import pytest

from playscope.cli import main
from playscope.io.session import load_session, write_session

from .synth import angle_session

SHIFTS_S = ["0", "1", "100", "5000", "1700000000", "1700000000.123457"]


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("time_origin") / "session"
    write_session(angle_session(noise_deg=0.01, rate_hz=100.0, q_start=-2.0, q_end=2.0), d)
    return d


def _shift_folder(src, dst, shift: str) -> None:
    shutil.copytree(src, dst)
    for p in dst.glob("*.csv"):
        lines = p.read_text().splitlines()
        col = lines[0].split(",").index("t_s")
        out = [lines[0]]
        for line in lines[1:]:
            f = line.split(",")
            f[col] = str(Decimal(f[col]) + Decimal(shift))
            out.append(",".join(f))
        p.write_text("\n".join(out) + "\n")


def _table(session, tmp_path, name) -> bytes:
    cal, tab = tmp_path / f"{name}.json", tmp_path / f"{name}.pstb"
    assert main(["calibrate", str(session), "-o", str(cal), "--fps", "25", "-q"]) == 0
    assert main(["tables", str(cal), "-o", str(tab), "-q"]) == 0
    return tab.read_bytes()


@pytest.fixture(scope="module")
def reference(session_dir, tmp_path_factory):
    return _table(session_dir, tmp_path_factory.mktemp("ref"), "ref")


@pytest.mark.parametrize("shift", SHIFTS_S)
def test_shifted_clock_gives_identical_tables(shift, session_dir, reference, tmp_path):
    s = tmp_path / "s"
    _shift_folder(session_dir, s, shift)
    first = Decimal(session_dir.joinpath("encoder.csv").read_text().splitlines()[1].split(",")[0])
    loaded = load_session(s)
    assert loaded.encoder["t_s"][0] == 0.0
    assert loaded.t_origin_us == int((first + Decimal(shift)) * 1_000_000)
    assert _table(s, tmp_path, "shifted") == reference


def test_write_keeps_the_files_clock(session_dir, tmp_path):
    """A loaded session written back holds its files' time stamps to the microsecond (an
    epoch stamp is not rounded to whole seconds), and loads to the same relative times."""
    s = tmp_path / "s"
    _shift_folder(session_dir, s, "1700000000")
    a = load_session(s)
    write_session(a, tmp_path / "w")
    t_file = [line.split(",")[0] for line in (tmp_path / "w" / "encoder.csv").read_text().splitlines()[1:4]]
    t_src = [line.split(",")[0] for line in (s / "encoder.csv").read_text().splitlines()[1:4]]
    assert [Decimal(x) for x in t_file] == [Decimal(x) for x in t_src]
    b = load_session(tmp_path / "w")
    assert np.array_equal(a.encoder["t_s"], b.encoder["t_s"]) and a.t_origin_us == b.t_origin_us
