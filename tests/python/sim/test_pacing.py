"""The excitation's pacing rule: simulate's default swing speed follows it, the host and the
board compute the same speed, and bad frame rates or play ranges are refused with a reason."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

from playscope.fit import pacing
from playscope.cli import main
from playscope.sim.core import make_trajectory, play_range
from playscope.sim.record import sim_config


def test_rule_constant_comes_from_the_board():
    from playscope.base.native import core

    assert pacing.pace_frames() == core()[1].EXC_PACE_FRAMES == 4


@pytest.mark.parametrize("fps", [25.0, 30.0, 60.0])
def test_simulate_default_speed_follows_the_rule(fps):
    cfg = sim_config("stras", trajectory="excitation", duration_s=30.0, seed=3)
    cfg.fps = fps
    cfg.trajectory["speed"] = None
    # The play the camera sees taken up: the stras preset's B(q) = 0.35 + 0.45 exp(..) >= 0.35 mm on
    # [-3, 3], and its smooth transition (spread 0.5) moves the tip from 0.5 B on.
    b_low, b_high = play_range(cfg)
    b_min_true = 0.35 + 0.45 * np.exp(-(3.0 / 0.8) ** 2)
    assert b_low == pytest.approx(0.5 * b_min_true, rel=1e-4)
    assert b_high == pytest.approx(0.80, rel=1e-4)
    traj = make_trajectory(cfg)
    t, q = traj["t_s"], traj["q"]
    v = np.abs(np.diff(q)) * cfg.encoder_hz
    speed = np.median(v[v > 0])
    assert speed == pytest.approx(b_low * fps / 4, rel=2e-4)  # rule in double precision (Q16 rounding)
    # On the trajectory itself: after each reversal the set-point needs >= 4 frame periods to
    # travel b_low (one encoder sample of slack).
    d = np.sign(np.diff(q))
    moving = np.flatnonzero(d != 0)  # the turns hold hold_s: the motion restarts at these samples
    turns = moving[1:][d[moving[1:]] != d[moving[:-1]]]
    assert turns.size > 10
    for k in turns[:-1]:
        after = np.flatnonzero(np.abs(q[k:] - q[k]) >= b_low)
        if after.size:
            assert t[k + after[0]] - t[k] >= 4 / fps - 1.5 / cfg.encoder_hz
    # sim_config records the speed used, the same number as the rule gives.
    cfg2 = sim_config("stras", trajectory="excitation")
    assert cfg2.trajectory["speed"] == pacing.swing_speed(*play_range(cfg2), cfg2.fps)


def test_explicit_speed_is_kept():
    cfg = sim_config("fig7")
    assert cfg.trajectory["speed"] == pytest.approx(np.radians(15) * 3.0)


@pytest.mark.parametrize("b_low,b_high,fps", [(0.35, 0.8, 25.0), (0.12, 0.3, 30.0), (0.05, 0.2, 60.0),
                                              (0.2, 0.5, 29.97)])
def test_host_and_board_pick_the_same_speed(b_low, b_high, fps):
    from playscope.base.native import executable

    v_host = pacing.pace_v_q32(b_low, b_high, fps)
    period_us = pacing.frame_period_us(fps)
    r = subprocess.run([str(executable("ps_vboard")), "--exc", "-3:3:1.6:0.4", "--pace",
                        f"{b_low!r}:{b_high!r}:{period_us}"], stdin=subprocess.DEVNULL, capture_output=True,
                       text=True, timeout=30)
    m = re.search(r"paced to (\S+) units/s \(v_q32 (\d+) per tick\)", r.stderr)
    assert m, r.stderr
    assert int(m.group(2)) == v_host
    # And both are the rule b_low fps / 4 up to the 1 us frame period and Q16 play.
    assert float(m.group(1)) == pytest.approx(b_low * fps / 4, rel=5e-5)


@pytest.mark.parametrize("args,msg", [((0.3, 0.1, 25.0), "b_low <= b_high"), ((0.0, 0.1, 25.0), "b_low <= b_high"),
                                      ((0.1, 0.3, 2000.0), "1..1000 frames/s"), ((0.1, 0.3, 0.0), "positive"),
                                      ((0.1, 0.3, float("nan")), "positive")])
def test_bad_rate_or_range_refused(args, msg):
    with pytest.raises(ValueError, match=re.escape(msg)):
        pacing.swing_speed(*args)


def test_paced_exc_checks_the_leg():
    assert pacing.paced_exc("-3:3:1.6:0.4", 0.35, 0.8, 25.0).startswith("-3:3:1.6:0.4:2.1875")
    with pytest.raises(ValueError, match="down leg"):
        pacing.paced_exc("-3:3:1.6:0.4", 0.35, 1.3, 25.0)


def test_run_insitu_refuses_a_bad_play_range(capsys, tmp_path):
    assert main(["run-insitu", "--device", "virtual", "--sim-plant", "--b-range", "0.5:0.1"]) == 2
    assert "b_low <= b_high" in capsys.readouterr().err
    # a video source needs the play's range to pace the swings (the geometry, checked first, is
    # a valid session.json: a 2-s simulated session's)
    from playscope.io.session import write_session
    from playscope.sim.core import preset, simulate

    write_session(simulate(preset("ideal", trajectory={"kind": "excitation", "q_lo": -1.0, "q_hi": 1.0, "amp": 0.5, "speed": 0.8, "duration_s": 2.0})), tmp_path / "s")
    geometry = str(tmp_path / "s" / "session.json")
    assert main(["run-insitu", "--device", "virtual", "--video", "nofile.avi", "--geometry", geometry]) == 2
    assert "--b-range" in capsys.readouterr().err
