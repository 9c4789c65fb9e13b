"""Time as an origin-free quantity: every stamp is rebased to the record's first sample on load
(session.time_origin), in decimal from the stamps' text, so a constant shift of every stamp
(+1000 s, +1e6 s, epoch stamps of 1.7e9 s, ns digits) loads to bit-identical times and gives a
calibration JSON identical apart from its t_origin_s; the board-clock limit applies to the
record's duration and its message says the duration."""

from __future__ import annotations

import json
import shutil
from decimal import Decimal

import numpy as np
import pytest

from playscope.base.errors import InputError
from playscope.io.importer import import_csv
from playscope.io.session import load_session

SHIFTS_S = ["1000", "1000000", "1700000000", "1700000000.000123"]


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A 12-s simulated angle session (encoder 500 Hz, distal 100 Hz, truth), stamps from 0."""
    from playscope.sim.record import sim_config, write_simulated

    out = tmp_path_factory.mktemp("rebase") / "base"
    write_simulated(sim_config("stras", trajectory="excitation", duration_s=12.0, seed=1, kind="angle"), out)
    return out


def shift_folder(src, dst, shift: str, files=("encoder.csv", "distal.csv", "truth.csv")):
    """Copy a session, adding shift to the t_s column of files, in exact decimal text."""
    shutil.copytree(src, dst)
    for name in files:
        p = dst / name
        lines = p.read_text().splitlines()
        out = [lines[0]]
        for line in lines[1:]:
            t, _, rest = line.partition(",")
            out.append(f"{Decimal(t) + Decimal(shift)},{rest}")
        p.write_text("\n".join(out) + "\n")
    return dst


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("shift", SHIFTS_S)
def test_shifted_session_loads_bit_identical(base, shift, tmp_path):
    ref = load_session(base)
    s = load_session(shift_folder(base, tmp_path / "s", shift))
    for name in ("encoder", "distal", "truth"):
        a, b = getattr(ref, name), getattr(s, name)
        assert list(a) == list(b)
        for k in a:
            assert same_bits(a[k], b[k]), (name, k)
    assert s.t_origin_us == int(Decimal(shift) * 1_000_000) and ref.t_origin_us == 0
    assert s.notes == ref.notes


def test_only_record_streams_shifted(base, tmp_path):
    """encoder.csv and distal.csv shifted, the simulator's truth.csv not (the issue's case): the
    record loads as before; truth is on another clock, which a note says."""
    ref = load_session(base)
    s = load_session(shift_folder(base, tmp_path / "s", "1700000000", ("encoder.csv", "distal.csv")))
    assert same_bits(ref.encoder["t_s"], s.encoder["t_s"]) and same_bits(ref.distal["t_s"], s.distal["t_s"])
    assert any("truth.csv" in n and "another clock" in n for n in s.notes)


def test_calibration_identical_apart_from_origin(base, tmp_path):
    from playscope.fit.calibration import calibrate

    a, b = (calibrate(load_session(p)).doc for p in (base, shift_folder(base, tmp_path / "s", "1700000000")))
    assert (a["t_origin_s"], b["t_origin_s"]) == ("0", "1700000000")
    strip = lambda d: json.dumps({k: v for k, v in d.items() if k not in ("source", "t_origin_s")})  # noqa: E731
    assert strip(a) == strip(b)


def _csv(path, stamps, header="t,q,c"):
    rng = np.random.default_rng(0)
    rows = [f"{t},{q:.6f},{c:.6f}" for t, q, c in zip(stamps, rng.normal(size=len(stamps)), rng.normal(size=len(stamps)))]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("shift", ["0", "1000", "1000000", "1700000000", "1700000000.000000001"])
def test_nanosecond_digits_rebased_exactly(shift, tmp_path):
    """Stamps with nine decimals (a ROS or EM-tracker log), ties at half a microsecond among
    them: the rebased times are the same bits for every shift (float64 rounding of the shifted
    text would move some of them by 1 us)."""
    base = [Decimal(k) * Decimal("0.001951694") + Decimal(k % 7) * Decimal("0.000000500") for k in range(400)]
    ref = import_csv(_csv(tmp_path / "a.csv", base), "t", "q", "c")
    s = import_csv(_csv(tmp_path / "b.csv", [t + Decimal(shift) for t in base]), "t", "q", "c")
    assert same_bits(ref.encoder["t_s"], s.encoder["t_s"]) and same_bits(ref.distal["t_s"], s.distal["t_s"])


def test_span_message_states_the_duration(base, tmp_path):
    """A record longer than the board's clock (a 2-h gap in the encoder log) is refused with its
    duration; epoch stamps alone are not (test_shifted_session_loads_bit_identical)."""
    s = tmp_path / "s"
    shutil.copytree(base, s)
    lines = (s / "encoder.csv").read_text().splitlines()
    t, _, rest = lines[-1].partition(",")
    lines[-1] = f"{Decimal(t) + 7200},{rest}"
    (s / "encoder.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"the record lasts 7212 s \(120.2 min\) from its first sample .* beyond "
                                         r"the 71.6 min the board's clock holds; the largest gap is 7200"):
        load_session(s)


def test_streams_on_two_clocks_refused(base, tmp_path):
    s = shift_folder(base, tmp_path / "s", "1700000000", ("distal.csv",))
    with pytest.raises(InputError, match=r"distal.csv: its stamps \(1.7e\+09 .* begin after encoder.csv's end .* "
                                         r"two clocks"):
        load_session(s)
