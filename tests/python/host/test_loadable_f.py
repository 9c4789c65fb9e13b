"""calibration.loadable_f: a fitted f whose table the loader refuses for precision (f nearly flat
over a stretch, so f^-1 jumps) is refitted with the smallest slope floor that loads; an f whose
table loads is returned untouched. The refusal and the acceptance are the firmware loader's own
(calib_load through cffi), not a host-side estimate of it."""

import numpy as np
import pytest

from playscope.fit.f_remain import f_remain_lsq
from playscope.fit.calibration import F_SLOPE_FLOORS, loadable_f
from playscope.base.native import core
from playscope.fit.table_build import TableError, build_table

Q_RANGE = (0.0, 5.0)
B_MM = 0.36  # data_2_2's onset width: ceiling 0.36/16 = 0.0225 mm


def B(q):
    return np.full(np.shape(q), B_MM)


def frames(flat: bool, n=600, seed=0):
    """(z, c): c = 10 deg/mm z, with (flat=True) c held still over z in [1.5, 3.5] mm (a stretch of
    the travel where the record's tip barely moves; over 1 mm the P-spline still keeps 0.5
    deg/mm there and the table loads)."""
    z = np.linspace(Q_RANGE[0], Q_RANGE[1], n)
    c = 10.0 * z - (10.0 * np.clip(z - 1.5, 0.0, 2.0) if flat else 0.0)
    return z, c + np.random.default_rng(seed).normal(0.0, 0.02, n)


def refit_for(z, c):
    return lambda ms: f_remain_lsq(z, c, B, 14, z=z, min_slope=ms)[:2]


def test_flat_f_is_refused_then_refitted_with_the_smallest_floor_that_loads():
    _, lib = core()
    z, c = frames(flat=True)
    f0, s0 = refit_for(z, c)(0.0)
    with pytest.raises(TableError) as e:
        build_table(B, f0, *Q_RANGE, "mm")
    assert e.value.status == lib.CALIB_ERR_PRECISION
    f, sign, floor = loadable_f(refit_for(z, c), f0, s0, B, Q_RANGE, "mm")
    assert sign == 1 and floor is not None and floor["fraction_of_mean"] in F_SLOPE_FLOORS
    build_table(B, f, *Q_RANGE, "mm")  # loads
    x = np.linspace(f.lo, f.hi, 4001)
    assert np.min(np.diff(f(x)) / np.diff(x)) >= floor["min_slope"] * (1 - 1e-9)
    # The smallest: the floor before it (if any) still refuses.
    k = F_SLOPE_FLOORS.index(floor["fraction_of_mean"])
    if k > 0:
        g, _ = refit_for(z, c)(floor["min_slope"] * F_SLOPE_FLOORS[k - 1] / F_SLOPE_FLOORS[k])
        with pytest.raises(TableError):
            build_table(B, g, *Q_RANGE, "mm")
    # Outside the flat stretch the floored f still follows the data (10 deg/mm, noise 0.02).
    m = (z < 1.3) | (z > 3.7)
    assert np.sqrt(np.mean((f(z[m]) - c[m]) ** 2)) < 0.5


def test_f_that_loads_is_returned_unchanged():
    z, c = frames(flat=False)
    f0, s0 = refit_for(z, c)(0.0)
    f, sign, floor = loadable_f(refit_for(z, c), f0, s0, B, Q_RANGE, "mm")
    assert f is f0 and sign == s0 and floor is None


def test_other_refusals_are_not_mended():
    """A B whose slope the loader refuses (|dB/dq| >= 2) is not f's fault: the error stands."""
    z, c = frames(flat=False)
    f0, s0 = refit_for(z, c)(0.0)

    def steep_B(q):
        return 0.1 + 3.0 * np.clip(np.asarray(q, float) - 2.0, 0.0, 0.5)

    with pytest.raises(TableError) as e:
        loadable_f(refit_for(z, c), f0, s0, steep_B, Q_RANGE, "mm")
    assert e.value.status != core()[1].CALIB_ERR_PRECISION


@pytest.mark.parametrize("model_kind", ["play", "auto"])
def test_calibrate_whole_data_2_2_writes_tables_the_board_loads(real_catheter_dir, model_kind):
    """The case that found it: the whole of data_2_2 gives a pure-play f nearly flat at one point
    (|f'| 2e-4 deg/mm, table refused). Through calibrate, every f it returns (the product's, and
    the pure play's kept beside a PI) loads, and the floor is recorded and warned about."""
    from playscope.fit.calibration import calibrate
    from playscope.io.importer import import_catheter

    cal = calibrate(import_catheter(real_catheter_dir / "data_2_2.txt"), model_kind=model_kind)
    q0, q1 = cal.q_range
    build_table(cal.B_model, cal.f, q0, q1, cal.actuator_unit, transition=cal.transition)
    build_table(cal.B, cal.f_play, q0, q1, cal.actuator_unit)
    play_doc = cal.doc["f_remain"] if cal.transition.is_play else cal.doc["transition"]["f_remain_play"]
    assert play_doc["slope_floor"] is not None and play_doc["slope_floor"]["fraction_of_mean"] in F_SLOPE_FLOORS
    assert any("held to |f'|" in w for w in cal.warnings)
