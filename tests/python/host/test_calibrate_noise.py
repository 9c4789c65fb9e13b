"""`calibrate` refuses a record whose fit is no better than a memoryless line (noise, or the wrong
column): one line, exit 2, nothing written; a real record passes the same rule."""

from __future__ import annotations

import numpy as np
import pytest

from playscope import cli
from playscope.base.errors import InputError
from playscope.fit.calibration import check_not_noise
from playscope.io.session import write_session

from .synth import angle_session


def _noise_session():
    """The good angle session (138 s, 100 Hz encoder) with its angle replaced by a smooth random
    signal of the same spread, independent of q: it moves after the reversals (so onsets are
    found and B fitted, as on a record of the wrong column) but does not follow the actuator."""
    s = angle_session(noise_deg=0.01, rate_hz=100.0)
    t = s.distal["t_s"]
    rng = np.random.default_rng(2)
    c = sum(np.sin(2 * np.pi * rng.uniform(0.05, 2.0) * t + rng.uniform(0, 6)) for _ in range(8))
    s.distal["c_deg"] = c / np.std(c) * float(np.std(s.distal["c_deg"]))
    return s


def test_noise_is_refused_with_one_line(tmp_path, capsys):
    write_session(_noise_session(), tmp_path / "S")
    rc = cli.main(["calibrate", str(tmp_path / "S"), "-o", str(tmp_path / "cal.json")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("playscope: error: "), err
    assert "no better than a memoryless line" in err[0] and "held-out RMSE" in err[0]
    assert not (tmp_path / "cal.json").exists()


def test_rule_on_small_inputs():
    """The rule itself: a line plus play passes, a plain line passes (the line explains it), a
    signal independent of q is refused, in-sample and held out."""
    rng = np.random.default_rng(0)
    q = np.tile(np.r_[np.linspace(-3, 3, 200), np.linspace(3, -3, 200)], 3)
    z = q - 0.4 * np.sign(np.gradient(q))  # the play's centre lags the actuator
    c_play = 10 * z + rng.normal(0, 0.05, q.size)
    check_not_noise(q, c_play, 10 * z)  # the model beats the line
    check_not_noise(q, 10 * q, 10 * q)  # the line explains it all
    noise = rng.normal(0, 10, q.size)
    with pytest.raises(InputError, match="no better than a memoryless line"):
        check_not_noise(q, noise, 0.01 * q)
    folds = [(np.arange(q.size) < k, (np.arange(q.size) >= k) & (np.arange(q.size) < k + 200))
             for k in (400, 600, 800)]
    with pytest.raises(InputError, match="held-out RMSE"):
        check_not_noise(q, noise, 0.01 * q, splits=folds, model_cv_rmse=10.0)
    check_not_noise(q, c_play, 10 * z, splits=folds, model_cv_rmse=0.05)
