"""What spreadsheets and trackers write, read correctly on the smallest input: a UTF-8 BOM, a
trailing separator on every line, empty or NaN cells in unused or optional columns, tracker
dropouts (NaN or empty marker coordinates) as lost frames; nanosecond epoch stamps read
exactly with --time-unit ns and refused without it (never a silent 1-row session); a CSV read
in place thinned as a session folder; the chunked reader names the right row past a chunk."""

from __future__ import annotations

import json

import numpy as np
import pytest

from playscope.base.errors import InputError
from playscope.io import csvtable
from playscope.io.importer import import_csv, read_record
from playscope.io.session import load_session, thin_encoder

META = {"format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "angle"},
        "robot": {"model": "constant_curvature", "bend_length_mm": 20.0, "tip_length_mm": 5.0, "q_per_rad": 3.0}}


def _session(root, enc: str, distal: str = "t_s,c_deg\n0,1\n0.01,2\n0.02,3\n", meta=META):
    root.mkdir()
    (root / "session.json").write_text(json.dumps(meta))
    (root / "encoder.csv").write_bytes(enc.encode("utf-8"))
    (root / "distal.csv").write_text(distal)
    return root


ENC = "t_s,q\n0,0.1\n0.01,0.2\n0.02,0.3\n"


def test_bom_read(tmp_path):
    s = load_session(_session(tmp_path / "s", "\ufeff" + ENC))
    assert s.encoder["q"].tolist() == [0.1, 0.2, 0.3]
    p = tmp_path / "a.csv"
    p.write_text("\ufefft,q,c\n0,0.1,1\n0.01,0.2,2\n0.02,0.3,3\n")
    assert import_csv(p, "t", "q", "c").encoder["q"].tolist() == [0.1, 0.2, 0.3]


def test_trailing_separator_read(tmp_path):
    s = load_session(_session(tmp_path / "s", "t_s,q,\n0,0.1,\n0.01,0.2,\n0.02,0.3,\n",
                              "t_s,c_deg,\n0,1,\n0.01,2,\n0.02,3,\n"))
    assert s.encoder["q"].tolist() == [0.1, 0.2, 0.3] and s.distal["c_deg"].tolist() == [1, 2, 3]
    p = tmp_path / "h.csv"  # headerless, trailing separator: still three columns
    p.write_text("0,0.1,1,\n0.01,0.2,2,\n0.02,0.3,3,\n")
    assert import_csv(p).distal["c_deg"].tolist() == [1, 2, 3]


def test_empty_and_nan_in_unused_columns_read(tmp_path):
    s = load_session(_session(tmp_path / "s", "t_s,q,note\n0,0.1,\n0.01,0.2,NaN\n0.02,0.3,x\n"))
    assert s.encoder["q"].tolist() == [0.1, 0.2, 0.3] and np.isnan(s.encoder["note"]).all()
    p = tmp_path / "c.csv"  # the catheter's layout, a sensor column left empty
    p.write_text("Time,Tendon Disp.,Motor Curr.,Angle x\n0,0.1,,1\n0.01,0.2,nan,2\n0.02,0.3,,3\n")
    s = import_csv(p)
    assert s.encoder["q"].tolist() == [0.1, 0.2, 0.3] and s.distal["c_deg"].tolist() == [1, 2, 3]


def test_empty_optional_column_left_out_with_a_note(tmp_path):
    s = load_session(_session(tmp_path / "s", "t_s,q,q_cmd\n0,0.1,0.1\n0.01,0.2,\n0.02,0.3,\n"))
    assert "q_cmd" not in s.encoder and s.encoder["q"].tolist() == [0.1, 0.2, 0.3]
    assert any("'q_cmd' is empty or NaN in 2 of 3 rows (the first at row 3): left out" in n for n in s.notes)


@pytest.mark.parametrize("lost", ["NaN,NaN", "nan,nan", ","])
def test_tracker_dropouts_are_lost_frames(tmp_path, lost):
    meta = json.loads(json.dumps(META))
    meta["distal"]["kind"] = "image"
    meta["camera"] = {"width": 720, "height": 576, "fps": 25.0,
                      "K": [[600.0, 0, 360.0], [0, 600.0, 288.0], [0, 0, 1]], "dist": [0, 0, 0, 0, 0]}
    meta["hand_eye"] = {"R": np.eye(3).tolist(), "t_mm": [0.0, 0.0, 60.0]}
    root = _session(tmp_path / "s", ENC, meta=meta)
    (root / "distal.csv").unlink()
    (root / "marker.csv").write_text(f"t_s,u_px,v_px\n0,300,200\n0.04,{lost}\n0.08,301,201\n")
    s = load_session(root)
    assert np.isnan(s.marker["u_px"][1]) and np.isnan(s.marker["v_px"][1]) and s.marker["u_px"][2] == 301


def test_ns_epoch_stamps_read_exactly_with_the_unit(tmp_path):
    p = tmp_path / "ns.csv"
    t0 = 1_700_000_000_123_456_789  # 19 digits: beyond float64's 16, within int64
    p.write_text("t,q,c\n" + "".join(f"{t0 + k * 1_000_000},{k % 7 / 10},{k % 7}\n" for k in range(20)))
    s = import_csv(p, "t", "q", "c", time_unit="ns")
    assert s.encoder["t_s"].size == 20 and s.t_origin_us == 1_700_000_000_123_457
    assert np.array_equal(s.encoder["t_s"], np.arange(20) / 1000.0)


def test_ns_epoch_stamps_without_the_unit_refused(tmp_path):
    p = tmp_path / "ns.csv"
    p.write_text("t,q,c\n1700000000000000000,0,0\n1700000000002000000,0.1,1\n")
    with pytest.raises(InputError, match=r"look like nanoseconds .* pass --time-unit ns$"):
        import_csv(p, "t", "q", "c")


def test_record_read_in_place_is_thinned_as_a_session(tmp_path):
    p = tmp_path / "dense.csv"
    t = np.arange(0, 4.0, 1 / 2000.0)
    rows = "".join(f"{a:.6f},{np.sin(a):.5f},{np.cos(a):.5f}\n" for a in t)
    p.write_text("Time,Tendon Disp.,Angle x\n" + rows)
    s = read_record(p)
    want, _ = thin_encoder(import_csv(p).encoder, p)  # the rule load_session applies
    assert s.encoder["t_s"].size == want["t_s"].size < t.size / 2
    assert np.array_equal(s.encoder["t_s"], want["t_s"]) and np.array_equal(s.encoder["q"], want["q"])
    assert any("thinned by travel" in n for n in s.notes)


def test_error_row_counted_across_chunks(tmp_path, monkeypatch):
    monkeypatch.setattr(csvtable, "CHUNK_ROWS", 4)
    lines = [f"{k / 100},{k}" for k in range(10)]
    lines[6] = "0.06,abc"  # file row 8 (header = row 1), in the second chunk
    root = _session(tmp_path / "s", "t_s,q\n" + "\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"encoder.csv:8: not a number in column 'q'"):
        load_session(root)
