"""A malformed `simulate --config` or session.json field ends in one line naming the file, the
key (dotted for nested keys) and what it must be, exit status 2, no traceback
(sim.config_check.check_config, session.parse_meta)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from playscope.cli import main

CONFIG_CASES = [
    ('{"B": {"base": 0.35}}', "key B.peak: expected a number (mm), missing"),
    ('{"B": {"base": "x", "peak": 0.45, "centre": 0.0, "sigma": 0.8}}', 'key B.base: expected a number >= 0 (mm), got a string "x"'),
    ('{"B": {"base": 0.3, "peak": 0.4, "centre": 0, "sigma": 0.8, "width": 1}}', "key B.width: no such key in B (known: base, peak, centre, sigma)"),
    ('{"f": {"gain": [1], "soft": 0.45, "soft_width": 1.0, "offset_deg": 0.0}}', "key f.gain: expected a number, got a list [1]"),
    ('{"trajectory": {"kind": "excitation"}}', "key trajectory.q_lo: expected a number (the excitation trajectory needs it), missing"),
    ('{"trajectory": {"duration_s": 5}}', 'key trajectory.kind: expected "excitation" or "test" or "random_walk" or "ellipse", missing'),
    ('{"trajectory": {"kind": "test", "q_lo": -3, "q_hi": 3, "amp": 1, "speed": "fast", "duration_s": 5}}',
     'key trajectory.speed: expected a number > 0 (actuator units/s), got a string "fast"'),
    ('{"effects": {"drift": {"rate_deg_per_min": "x"}}}', 'key effects.drift.rate_deg_per_min: expected a number, got a string "x"'),
    ('{"effects": {"drift": {"rate": 1}}}', "key effects.drift.rate: no such parameter of drift (known: rate_deg_per_min)"),
    ('{"K": [[1, 2], [3]]}', "key K: expected a 3x3 list of numbers, got a list [[1, 2], [3]]"),
    ('{"R": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}', "key R: expected a rotation matrix"),
    ('{"encoder_hz": 0}', "key encoder_hz: expected a number in (0, 100000] Hz, got a number 0"),
    ('{"seed": 1.5}', "key seed: expected an integer >= 0, got a number 1.5"),
]


@pytest.mark.parametrize("text,message", CONFIG_CASES, ids=[c[0][:40] for c in CONFIG_CASES])
def test_simulate_config(text, message, tmp_path, capsys):
    cfg = tmp_path / "c.json"
    cfg.write_text(text)
    rc = main(["simulate", str(tmp_path / "out"), "--kind", "angle", "--duration", "2", "--config", str(cfg)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"playscope: error: {cfg}: {message}"), err
    assert not (tmp_path / "out").exists()


def _session(root, **changes):
    """A minimal angle session whose session.json has changes applied ("a.b": value, None deletes)."""
    root.mkdir()
    meta = {"format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "angle"},
            "robot": {"model": "constant_curvature", "bend_length_mm": 20.0, "tip_length_mm": 5.0, "q_per_rad": 3.0},
            "camera": {"width": 720, "height": 576, "fps": 25.0,
                       "K": [[380.0, 0, 360.0], [0, 380.0, 288.0], [0, 0, 1]], "dist": [0, 0, 0, 0, 0]}}
    for key, v in changes.items():
        d, *path = [meta] + key.split("__")
        for k in path[:-1]:
            d = d[k]
        if v is None:
            del d[path[-1]]
        else:
            d[path[-1]] = v
    (root / "session.json").write_text(json.dumps(meta))
    k = np.arange(1000)
    (root / "encoder.csv").write_text("t_s,q\n" + "".join(f"{i / 500:.3f},{np.sin(i / 100):.5f}\n" for i in k))
    (root / "distal.csv").write_text("t_s,c_deg\n" + "".join(f"{i / 100:.2f},{np.sin(i / 20):.5f}\n" for i in k[:200]))
    return root


SESSION_CASES = [
    ({"actuator": "mm"}, 'actuator must be a JSON object, got a string "mm"'),
    ({"actuator__unit": None}, "missing key actuator.unit: expected 'mm' or 'deg'"),
    ({"actuator__q_source": 5}, "actuator.q_source must be 'measured' or 'command', got a number 5"),
    ({"robot__bend_length_mm": "20"}, 'robot.bend_length_mm must be a finite number, got a string "20"'),
    ({"robot__tip_length_mm": None}, "missing key robot.tip_length_mm: expected a finite number"),
    ({"camera__K": [[1, 2, 3], [4, 5, 6], [7, 8, "x"]]}, "camera.K must be finite numbers, a list of 3 lists of 3, got a list"),
    ({"camera__dist": None}, None),  # dist is optional: zeros
    ({"camera__fps": True}, "camera.fps must be a finite number, got a boolean true"),
    ({"t_delay_s": "0.1"}, 't_delay_s must be a finite number, got a string "0.1"'),
]


@pytest.mark.parametrize("changes,message", SESSION_CASES, ids=[next(iter(c[0])) + str(i) for i, c in enumerate(SESSION_CASES)])
def test_session_json_field(changes, message, tmp_path, capsys):
    s = _session(tmp_path / "s", **changes)
    if message is None:
        from playscope.io.session import load_session

        assert load_session(s).camera is not None
        return
    rc = main(["calibrate", str(s), "-o", str(tmp_path / "cal.json")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"playscope: error: {s / 'session.json'}: {message}"), err
