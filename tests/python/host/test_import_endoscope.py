"""The endoscope recordings' reader (importer.import_endoscope) on files written here: headerless
CSV, repeated stamps, a leading block of zeros and a logger whose clock stops."""

import numpy as np
import pytest

from playscope.base.errors import InputError
from playscope.io.importer import import_endoscope


def write(path, t, q, c, c_col=3, ncol=8):
    rows = np.zeros((t.size, ncol))
    rows[:, 0], rows[:, 1], rows[:, c_col] = t, q, c
    path.write_text("\n".join(", ".join(f"{v:.6f}" for v in r) + " " for r in rows) + "\n")
    return path


def test_short_record_columns_units_and_repeated_stamps(tmp_path):
    t = np.repeat(np.arange(1, 101) * 0.025, 3)  # every stamp written three times
    q = np.linspace(-60, 60, t.size)
    s = import_endoscope(write(tmp_path / "30.txt", t, q, 0.5 * q))
    assert s.actuator_unit == "deg" and s.q_source == "command" and s.distal_kind == "angle"
    assert s.encoder["t_s"].size == 100 and np.all(np.diff(s.encoder["t_s"]) > 0)
    # the last row of each stamp is kept
    np.testing.assert_allclose(s.encoder["q"], q[2::3], atol=1e-6)
    np.testing.assert_allclose(s.distal["c_deg"], 0.5 * q[2::3], atol=1e-6)
    assert any("repeat an earlier time stamp" in n for n in s.notes)


def test_tracker_record_leading_zeros_and_stopped_clock(tmp_path):
    t = np.r_[np.zeros(5), np.arange(1, 201) * 0.01, np.zeros(7)]
    q = np.r_[np.zeros(5), np.sin(np.arange(1, 201) * 0.05) * 60, np.full(7, 33.0)]
    c = 0.8 * q
    s = import_endoscope(write(tmp_path / "conf0_60.txt", t, q, c, c_col=5, ncol=10))
    # The last rest row is kept (the state the motion starts from), the zeros before it dropped.
    assert s.encoder["t_s"].size == 201 and s.encoder["q"][0] == 0 and s.encoder["t_s"][-1] == pytest.approx(2.0)
    assert any("4 row(s) before the command first moves" in n for n in s.notes)
    np.testing.assert_allclose(s.distal["c_deg"], 0.8 * s.encoder["q"], atol=1e-5)
    assert any("clock stopped" in n and "7 row(s)" in n for n in s.notes)


def test_bad_field_names_the_file_and_row(tmp_path):
    p = tmp_path / "60.txt"
    p.write_text("0.1, 1.0, 0, 2.0\n0.2, x, 0, 2.0\n")
    with pytest.raises(InputError, match="60.txt"):
        import_endoscope(p)


def test_evaluate_insitu_reads_a_recording_file_in_place(tmp_path):
    """A headerless endoscope file given to `evaluate-insitu` directly: every row scored or
    refused by name, exit 0 (a user gets a table, not an error, from a real recording's layout).
    The record is synthetic (a constant play of 8 deg + a cubic), written in the endoscope layout."""
    import json
    import subprocess
    import sys

    t = np.arange(1, 601) * 0.02  # 12 s at 50 Hz, 2 cycles of +-60 deg (4 reversals), as the real files
    q = 60 * np.sin(2 * np.pi * t / 6)
    z, c = 0.0, np.empty_like(q)
    for k, qk in enumerate(q):  # play of half-width 4 deg, written out here (not the project's model)
        z = min(max(z, qk - 4), qk + 4)
        c[k] = 0.8 * z + 1e-5 * z ** 3
    f = write(tmp_path / "60.txt", t, q, c)
    r = subprocess.run([sys.executable, "-m", "playscope.cli", "evaluate-insitu", str(f), "--split", "0.5",
                        "--json", str(tmp_path / "r.json")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "r.json").read_text())
    ours = doc["rows"]["ours"]["rmse_deg"]
    assert ours is not None and ours < 0.2, ours  # a play + cubic is in the product's families (measured 0.043; linear 2.97)
