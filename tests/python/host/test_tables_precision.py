"""The precision ceiling: `tables` and the board's loader refuse a table
whose fixed-point error would approach the play it corrects (docs/firmware.md)."""

import numpy as np
import pytest

from playscope.fit import table_build as T
from playscope.base.native import core


def B(q):
    return 0.4 + 0.4 * np.exp(-np.asarray(q, float) ** 2 / 2.0)  # 0.4..0.8 units, as the demo's


def f(q):
    q = np.asarray(q, float)
    return 10.0 * q + 0.3 * q ** 3  # deg


def test_ceiling_is_the_loaders_rule():
    _, lib = core()
    tab = T.build_table(B, f, -4.0, 4.0, "mm", "remain", 1)
    b_max_raw = int(round(0.8 * 65536))
    # The loader's figure is max(B_max / 16, 16 raw) over the table's entries (B_max sampled
    # on the grid, so within a few raw units of 0.8).
    assert abs(tab.cal.precision_ceiling_q16 - b_max_raw // 16) <= 2
    assert lib.calib_precision_ceiling_q16(0) == 16
    assert lib.calib_precision_ceiling_q16(16 * 1000) == 1000


def test_a_fine_table_passes_and_a_coarse_one_is_refused():
    tab = T.build_table(B, f, -4.0, 4.0, "mm", "remain", 1)
    err = T.table_errors(tab, B, f, -4.0, 4.0)
    T.check_precision(tab, err, f, -4.0, 4.0)
    ceiling = tab.cal.precision_ceiling_q16 / 65536
    assert err["comp_q_max"] < ceiling / 10  # fine grid: measured ~1e-4 against 0.05
    # Four entries: linear interpolation of the cubic f leaves an error of tenths of a unit.
    coarse = T.build_table(B, f, -4.0, 4.0, "mm", "remain", 1, 4)
    err = T.table_errors(coarse, B, f, -4.0, 4.0)
    assert err["comp_q_max"] > coarse.cal.precision_ceiling_q16 / 65536
    with pytest.raises(T.TableError, match="CALIB_ERR_PRECISION"):
        T.check_precision(coarse, err, f, -4.0, 4.0, source="cal.json")


def test_nan_error_is_refused():
    tab = T.build_table(B, f, -4.0, 4.0, "mm", "remain", 1)
    err = dict(T.table_errors(tab, B, f, -4.0, 4.0), direct_c_deg_max=float("nan"))
    with pytest.raises(T.TableError, match="precision ceiling"):
        T.check_precision(tab, err, f, -4.0, 4.0)
