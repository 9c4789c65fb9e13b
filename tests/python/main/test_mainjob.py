"""The main job end to end (playscope demo): short sessions, every stage must run and the
numbers must say the chain worked (B recovered, flash verified, compensation beats f_coarse^-1)."""

import json

from playscope import cli


def test_demo_end_to_end(tmp_path, capsys):
    out = tmp_path / "main"
    rc = cli.main(["demo", "--out", str(out), "--duration", "40", "--json", str(tmp_path / "s.json")])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    assert s == json.loads((tmp_path / "s.json").read_text())
    # B(q) from the onsets. With the STRAS preset's smooth transition (operator widths
    # B (1 +- spread u)) the tip first moves once (1 - spread) B is taken up and then creeps, so
    # eq. 1's onset lies between the first-motion width and the centre width B: measured B_est / B
    # 0.56-0.81 (mean 0.66) on the 90 s main job, seed 1, with the threshold from the record.
    b = s["b_error"]
    assert b["spread"] == 0.5
    assert 1 - b["spread"] - 0.1 < b["ratio_min"] and b["ratio_max"] < 1.0 + 0.1, b
    # Flashed over the emulated USB device, read back identical, compensator bit-exact.
    assert "read back identical" in s["flash"] and "bit-identical" in s["flash"]
    # Table I rows for the paper's three models plus the fixed-point one.
    assert {"f_coarse", "f_coarse+B", "f_remain+B"} <= set(s["prediction"])
    comp = s["compensation"]
    assert comp["f_remain+B"]["c_rmse_deg"] < 0.5 * comp["f_coarse_inv"]["c_rmse_deg"]
    # The transition model, when chosen, beats the pure play through the plant (0.33 vs 0.87 deg
    # measured on the 90 s main job, seed 1).
    if s["model"]["model"] == "pi":
        assert comp["f_remain+B+PI_fixed"]["c_rmse_deg"] < comp["f_remain+B"]["c_rmse_deg"]
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64") >= 4
    printed = capsys.readouterr().out
    assert "B(q) error against the truth" in printed and "report:" in printed
