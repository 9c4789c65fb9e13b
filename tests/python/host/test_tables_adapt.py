"""`playscope tables` (pipeline.write_tables) when a table misses the precision ceiling: denser
grids first, then a refusal naming the quantity and by how much."""

import numpy as np
import pytest
from scipy.interpolate import make_interp_spline

from playscope.fit.bspline import SplineFn
from playscope.fit.calibration import calibrate
from playscope.pipeline import write_tables
from playscope.fit.table_build import TableError, f_inverse_error

from .test_families import play_record


@pytest.fixture(scope="module")
def cal():
    return calibrate(play_record(), model_kind="play")


def with_f(cal, fn, tmp_path):
    """The calibration with f_remain replaced by fn (an interpolating cubic spline on 200 points
    over the travel, linear ends), saved; returns its path."""
    lo, hi = cal.q_range
    x = np.linspace(lo - 1, hi + 1, 200)
    f = SplineFn(make_interp_spline(x, fn(x), k=3), float(x[0]), float(x[-1]), linear_ends=True)
    cal.doc["f_remain"] = {**f.to_json(), "sign": 1, "method": "lsq", "slope_floor": None}
    path = tmp_path / "cal.json"
    cal.save(path)
    return path


def test_coarse_grid_is_made_denser_until_the_table_meets_the_ceiling(cal, tmp_path):
    path = with_f(cal, lambda q: 10 * q + 2 * np.sin(3 * q), tmp_path)
    res = write_tables(path, tmp_path / "t.pstb", entries=8)
    assert res.adapted and "from 8 to" in res.adapted and res.table.cal.b.n > 8
    assert res.to_json()["adapted"] == res.adapted
    # Given enough entries at once, nothing is adapted.
    assert write_tables(path, tmp_path / "u.pstb").adapted is None


def test_refusal_names_the_quantity_and_by_how_much(cal, tmp_path):
    # f smooth, steep below 0 and nearly flat above (slope down to ~1e-3 deg per mm)
    flat = lambda q: 5 * (q - np.sqrt(q * q + 0.01)) + 1e-3 * q  # noqa: E731
    path = with_f(cal, flat, tmp_path)
    fe = f_inverse_error(cal.B, flat, *cal.q_range)
    assert fe["ratio"] > 10
    with pytest.raises(TableError, match=r"no layout the board holds meets it .*inverse f table's error .* times over") as ei:
        write_tables(path, tmp_path / "t.pstb")
    assert str(path) in str(ei.value) and f"{fe['ratio']:.1f} times" in str(ei.value)
    assert not (tmp_path / "t.pstb").exists()
