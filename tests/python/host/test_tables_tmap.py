"""Layout-3 tables with a threshold map (B-proportional thresholds, transition.ThresholdMap):
the fixed-point direct model and compensator (the firmware's C through cffi) against the float
chain of playscope.fit.transition, and refusals of damaged v3 blobs."""

import numpy as np
import pytest

from playscope.fit import table_build as TB
from playscope.fit import transition as T
from playscope.base.native import core
from playscope.fit.transition import ThresholdMap, Transition

Q_MIN, Q_MAX = -5.0, 5.0


def B(q):
    """Onset width varying 2x over the travel: 0.3 mm at q_min, 0.6 mm at q_max."""
    return 0.3 + 0.3 * (np.asarray(q, float) - Q_MIN) / (Q_MAX - Q_MIN)


def f(q):
    q = np.asarray(q, float)
    return 3.0 * q + 0.04 * q * q


def transition(with_map=True):
    r = T.thresholds(8, 0.8)
    w = np.r_[0.4, np.full(7, 0.6 / 7)]
    tm = ThresholdMap.from_backlash(B, Q_MIN - 0.3, Q_MAX + 0.3) if with_map else None
    return Transition(r, w, 1.0, tm)


@pytest.fixture(scope="module")
def mapped():
    tr = transition()
    tab = TB.build_table(B, f, Q_MIN, Q_MAX, "mm", transition=tr)
    return tr, tab


def test_map_is_written_in_the_header(mapped):
    tr, tab = mapped
    ffi, lib = core()
    hd = ffi.new("pst_header_v3_t *")
    ffi.memmove(hd, tab.blob, ffi.sizeof("pst_header_v3_t"))
    # The host writes layout 5 (the instrument block after the v4 fields); the map sits where v3 put it.
    assert hd.base.layout_version == 5 and hd.base.header_size == 104
    # As many entries as the other grids allow (PST_MAX_ENTRIES, power-of-two step).
    assert hd.base.b.n // 2 < hd.tmap.n <= lib.PST_MAX_ENTRIES and tab.has_map and tab.n_ops == tr.n
    # The map grid covers the play centre's range: the travel widened by max B / 2.
    assert hd.tmap.x0_q16 <= int((Q_MIN - 0.3) * 65536) + 1
    assert hd.tmap.x0_q16 + (hd.tmap.n - 1) * hd.tmap.step_q16 >= int((Q_MAX + 0.3) * 65536)
    # L = max dz/du = max B / b_ref (b_ref the median of B on the map's grid): about 4/3 here.
    assert 1.2 < tab.cal.tmap_inv_lip_q16 / 65536 < 1.5
    # Without the map the same transition writes no map grid.
    tab2 = TB.build_table(B, f, Q_MIN, Q_MAX, "mm", transition=transition(with_map=False))
    assert TB.header(tab2.blob).layout_version == 5 and not tab2.has_map


def test_fixed_point_against_the_float_chain(mapped):
    tr, tab = mapped
    err = TB.table_errors(tab, B, f, Q_MIN, Q_MAX, transition=tr)
    print("fixed vs float:", err, "comp_err bound", tab.cal.comp_err_q16 / 65536)
    # Measured: direct 4.7e-4 deg, compensator 1.2e-4 mm (sampling of f, B and g on the grids
    # and the Q16 rounding; the loader's worst-case bound comp_err is 0.019 mm). A few times that:
    assert err["direct_c_deg_max"] < 2e-3
    assert err["comp_q_max"] < 5e-4
    TB.check_precision(tab, err, f, Q_MIN, Q_MAX)
    # The map matters: the same operators without it are far from the mapped float chain.
    plain = TB.build_table(B, f, Q_MIN, Q_MAX, "mm", transition=transition(with_map=False))
    q = np.concatenate([np.linspace(Q_MIN, Q_MAX, 400), np.linspace(Q_MAX, Q_MIN + 2, 300)])
    c_map = T.direct_chain(q, B, tr, f)
    assert np.max(np.abs(plain.predict(q) - c_map)) > 20 * err["direct_c_deg_max"]
    assert np.max(np.abs(tab.predict(q) - c_map)) <= err["direct_c_deg_max"] * 3


def test_round_trip(mapped):
    tr, tab = mapped
    c = 10 * np.sin(np.linspace(0, 5 * np.pi, 2000))
    q = tab.compensate(c)
    back = tab.predict(q)
    # Once c* has moved the direct model reproduces the reference: measured 2.0e-4 deg.
    k = 100
    assert np.max(np.abs(back[k:] - c[k:])) < 1e-3


def _reseal(blob: bytes) -> bytes:
    ffi, lib = core()
    b = bytearray(blob)
    off = ffi.offsetof("pst_header_t", "crc32")
    b[off:off + 4] = bytes(4)
    crc = lib.calib_table_crc(bytes(b), len(b))
    b[off:off + 4] = int(crc).to_bytes(4, "little")
    return bytes(b)


def test_corrupted_v3_blobs_are_refused(mapped):
    _, tab = mapped
    ffi, _ = core()
    hd = ffi.new("pst_header_v3_t *")
    ffi.memmove(hd, tab.blob, ffi.sizeof("pst_header_v3_t"))
    at = hd.tmap.offset + 4 * 20
    bad = bytearray(tab.blob)
    bad[at + 2] ^= 0x01  # one map entry, CRC left stale
    with pytest.raises(TB.TableError, match="CRC"):
        TB.CalibTable(bytes(bad))
    # Resealed: entry 20 equal to entry 19, the map is no longer strictly increasing.
    bad = bytearray(tab.blob)
    bad[at:at + 4] = tab.blob[at - 4:at]
    with pytest.raises(TB.TableError, match="threshold map not strictly increasing"):
        TB.CalibTable(_reseal(bytes(bad)))
    # A v3 header relabelled as layout 2: the header size no longer matches its version.
    bad = bytearray(tab.blob)
    bad[4:6] = (2).to_bytes(2, "little")
    with pytest.raises(TB.TableError, match="unknown table layout version"):
        TB.CalibTable(_reseal(bytes(bad)))
    # The map's grid moved off B's grid.
    bad = bytearray(tab.blob)
    x0 = ffi.offsetof("pst_header_v3_t", "tmap")
    bad[x0:x0 + 4] = int(hd.tmap.x0_q16 + 4 * 65536).to_bytes(4, "little", signed=True)
    with pytest.raises(TB.TableError, match="invalid threshold map grid"):
        TB.CalibTable(_reseal(bytes(bad)))
