"""The diagnosis recovers a planted effect, finds nothing on a null, and explains the catheter gap."""

from __future__ import annotations

import numpy as np
import pytest

from playscope.diagnose.attribute import attribute, halves, noise_floor
from playscope.diagnose.fitmodel import from_session
from playscope.diagnose.selftest import cases, format_report, run_case, score
from playscope.sim.core import preset, simulate

TRAJ = {"kind": "excitation", "q_lo": -3.0, "q_hi": 3.0, "amp": 1.4, "speed": 0.8, "duration_s": 60.0, "cycles": 2}


def diagnose(effects, seed=3):
    s = simulate(preset("stras", effects=effects, seed=seed, trajectory=dict(TRAJ)), blind=True)
    d = from_session(s)
    fm, em = halves(d)
    return attribute(d, fm, em, candidates=("smooth_transition", "camera_delay", "handeye_direction", "drift"))


def test_planted_delay_is_found_with_its_value_and_shrink():
    res = diagnose({"camera_delay": {"delay_s": 0.08}})
    assert res["verdict"] == "camera_delay"
    k = res["kept"][0]
    v, sd = k["params"]["camera_delay.delay_s"]
    assert abs(v - 0.08) < 0.01 and 0 < sd < 0.02
    assert k["share_of_excess_removed"] > 0.7
    assert res["final"]["rmse_heldout_deg"] < 0.5 * res["base"]["rmse_heldout_deg"]


def test_null_gives_no_discovery():
    res = diagnose({})
    assert res["kept"] == [] and res["verdict"] == "none"
    assert res["excess_before_deg"] < 0.1


def test_out_of_library_is_unexplained():
    res = diagnose({"breathing": {"amp_deg": 1.5, "period_s": 4.0}})
    assert res["verdict"] == "unexplained"


def test_selftest_small_scores():
    cl = [c for c in cases(1, 1, 0, seed=1, effects=("handeye_direction",))]
    small = ("smooth_transition", "camera_delay", "handeye_direction", "drift")
    results = [run_case(c, 60.0, small) for c in cl]
    sc = score(results)
    assert sc["top1"] == 1.0 and sc["false_discovery_nulls"] == 0.0
    assert sc["shrink_within_25pct"] == 1.0
    assert "confusion" in format_report(sc)


def test_catheter_gap_explained_in_situ(real_catheter_dir):
    from playscope.importer import import_catheter
    d = from_session(import_catheter(real_catheter_dir / "data_2_5.txt"))
    fm, em = halves(d)
    res = attribute(d, fm, em, candidates=("smooth_transition", "camera_delay", "drift"))
    assert res["base"]["rmse_heldout_deg"] > 1.0
    assert res["final"]["rmse_heldout_deg"] < 0.8
    assert res["kept"]


@pytest.mark.parametrize("effect,param,value", [("lens_distortion", "dk1", -0.15), ("nonconstant_curvature", "gamma", 0.4)])
def test_geometry_screen_recovers_image_only_effects(effect, param, value):
    from playscope.diagnose.geometry import screen
    s = simulate(preset("stras", effects={effect: {param: value}}, seed=5, trajectory=dict(TRAJ)))
    d = from_session(s)
    fm, em = halves(d)
    g = screen(s, d, fm, em)
    assert g["kept"] == [effect]
    assert next(x["value"] for x in g["screen"] if x["effect"] == effect) == pytest.approx(value, abs=0.03)
    s0 = simulate(preset("stras", effects={}, seed=5, trajectory=dict(TRAJ)))
    d0 = from_session(s0)
    assert screen(s0, d0, *halves(d0))["kept"] == []
