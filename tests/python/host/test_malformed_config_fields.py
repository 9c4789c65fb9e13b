"""Every malformed field of a calibration JSON, of session.json's simulator parameters (the plant
`evaluate` runs) or of a config ends in one line naming the file, the key and what it must be,
exit 2; a KeyError or TypeError no loader check caught is still one line, never a traceback.
Each case: the good files with one field changed."""

from __future__ import annotations

import json

import pytest

from playscope.cli import main

from .goodfiles import copy_good


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("playscope: error: ") and "\n" not in err, err
    return err


@pytest.mark.parametrize("key,value,expect", [
    (("B", "floor"), "x", "key B.floor: expected a finite number or null, got a string \"x\""),
    (("f_remain", "floor"), {}, "key f_remain.floor: expected a finite number or null, got an object"),
    (("transition",), 1, "key transition: expected an object or null, got a number 1"),
    (("model_family",), "x", "key model_family: expected an object or null, got a string \"x\""),
    (("model_family", "choice"), [1, 2], "key model_family.choice: expected an object or null, got a list"),
    (("model_family", "choice", "relax"), {"a": 1}, "key model_family.choice.relax.kappa: expected a finite number"),
])
def test_malformed_calibration_field(key, value, expect, tmp_path, good, capsys):
    g = copy_good(good, tmp_path)
    d = json.loads(g["cal"].read_text())
    x = d
    for k in key[:-1]:
        if x.get(k) is None:
            x[k] = {}
        x = x[k]
    x[key[-1]] = value
    g["cal"].write_text(json.dumps(d))
    assert main(["tables", str(g["cal"]), "-o", str(tmp_path / "t.pstb")]) == 2
    err = _one_line(capsys)
    assert str(g["cal"]) in err and expect in err, err
    assert not (tmp_path / "t.pstb").exists()


@pytest.fixture(scope="module")
def sim_session(tmp_path_factory):
    s = tmp_path_factory.mktemp("sim") / "S"
    assert main(["simulate", str(s), "--duration", "3", "--kind", "angle", "-q"]) == 0
    return s


@pytest.mark.parametrize("key,value,expect", [
    (("effects",), "x", "key simulator.effects"),
    (("effects", "smooth_transition"), True, "key simulator.effects.smooth_transition: expected an object"),
    (("trajectory", "kind"), [], "key simulator.trajectory.kind: expected"),
    (("R",), None, "key simulator.R: expected a rotation matrix"),
])
def test_malformed_simulator_field(key, value, expect, sim_session, tmp_path, good, capsys):
    """session.json's simulator parameters, which evaluate runs as the plant: each key named."""
    import shutil

    s = tmp_path / "S"
    shutil.copytree(sim_session, s)
    d = json.loads((s / "session.json").read_text())
    x = d["simulator"]
    for k in key[:-1]:
        x = x[k]
    if value is None:
        del x[key[-1]]
    else:
        x[key[-1]] = value
    (s / "session.json").write_text(json.dumps(d))
    assert main(["evaluate", str(s), str(good["cal"]), "--comp-duration", "2"]) == 2
    err = _one_line(capsys)
    assert str(s / "session.json") in err and expect in err, err


def test_an_uncaught_key_error_is_one_line(tmp_path, good, capsys, monkeypatch):
    """A malformed field no loader check names (simulated: the loader raising KeyError/TypeError
    as Python does on a missing key or a value of another type) still ends in one line."""
    import playscope.commands.tables as P

    g = copy_good(good, tmp_path)
    for exc in (KeyError("kappa"), TypeError("'int' object is not subscriptable")):
        def boom(*a, exc=exc, **k):
            raise exc

        monkeypatch.setattr(P, "write_tables", boom)
        assert main(["tables", str(g["cal"]), "-o", str(tmp_path / "t.pstb")]) == 2
        err = _one_line(capsys)
        assert "malformed field" in err and ("'kappa' missing" in err or "not subscriptable" in err), err
