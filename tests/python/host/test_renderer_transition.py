"""The renderers' optional transition after a reversal (`spread`, a Prandtl-Ishlinskii spread of
play widths: the bending driven by the mean of 41 plays of widths B (1 + spread u), u on
linspace(-1, 1, 41)), checked against the renderers alone (bench/swing_render.py and
bench/render_c.py): spread 0 is the old rendering bit for bit, the vectorised plays are a
brute-force loop per play, and the mean starts moving (1 - s) B after a reversal and is fully
dragged, on the centre play, once the widest play of (1 + s) B moves."""

import hashlib
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[3] / "bench"


def _load(name):
    spec = importlib.util.spec_from_file_location(f"_transition_{name}", BENCH / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod                  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


sw = _load("swing_render")
rc = _load("render_c")

U = np.linspace(-1.0, 1.0, 41)

# the keys render() returned before the option, and the sha1 of their values (float64 bytes, in
# this order) and of the written files, recorded before the option was added
SW_KEYS = ["q", "t_enc", "t_f", "t_onset", "u", "v"]
RC_KEYS = ["B_q", "K", "R_he", "R_true", "bend_length_mm", "c", "delay_s", "dir0", "eta",
           "exposure_s", "k_true", "kappa", "q", "q_true", "t_capture", "t_enc", "t_f", "t_flip",
           "t_he", "t_origin", "t_rev", "t_true", "tip_gain", "tip_length_mm", "u", "v", "x",
           "x_zero"]
PINNED = {
    "sw default": "4c572111eddaa61657a990746dc78717b8117af6",
    "rc default": "6efd3c0873da91f59d11411e59b32f2ba656a06a",
    "sw effects": "74f5ff37c633afb9f6dd5d754ca8b994ce04e686",
    "rc effects": "670226f692c104285093e6cb31c2fc7fb9112410",
    "sw files": "8ff9e7cc3c9f86b4612a42980cee9ecc8d37f960",
    "rc files": "017866153754bab9486bb45526e3b9e329ec311a",
}


def _sha(d, keys):
    m = hashlib.sha1()
    for k in keys:
        m.update(k.encode())
        m.update(np.ascontiguousarray(np.asarray(d[k], dtype=float)).tobytes())
    return m.hexdigest()


def _files_sha(folder):
    m = hashlib.sha1()
    for f in ("session.json", "encoder.csv", "marker.csv"):
        m.update((Path(folder) / f).read_bytes())
    return m.hexdigest()


def _sw(**kw):
    return sw.Rendering(**{"name": "h", "seed": 3, "duration_s": 12.0, **kw})


def _rc(**kw):
    return rc.Spec(**{"name": "h", "seed": 3, "duration_s": 12.0, **kw})


def _same_dicts(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(np.asarray(a[k]), np.asarray(b[k])), k


# ----------------------------------------------------------------------------- 1. spread 0 is the old rendering

@pytest.mark.parametrize("mk, mod", [(_sw, "sw"), (_rc, "rc")])
def test_spread_zero_is_the_rendering_without_the_argument(mk, mod):
    render = sw.render if mod == "sw" else rc.render
    _same_dicts(render(mk()), render(mk(spread=0.0)))


def test_default_renderings_did_not_move(tmp_path):
    assert _sha(sw.render(_sw()), SW_KEYS) == PINNED["sw default"]
    assert _sha(rc.render(_rc()), RC_KEYS) == PINNED["rc default"]
    fx_sw = _sw(seed=5, shape="triangle", ring_hz=9.0, reg_deg=2.0)
    fx_rc = _rc(seed=5, excitation="triangle", tip_hz=9.0, reg_deg=1.5, reg_axis="x")
    assert _sha(sw.render(fx_sw), SW_KEYS) == PINNED["sw effects"]
    assert _sha(rc.render(fx_rc), RC_KEYS) == PINNED["rc effects"]
    sw.write(_sw(), tmp_path / "sw")
    rc.write(_rc(), tmp_path / "rc")
    assert _files_sha(tmp_path / "sw") == PINNED["sw files"]
    assert _files_sha(tmp_path / "rc") == PINNED["rc files"]


def test_the_spread_is_written(tmp_path):
    d = sw.write(_sw(spread=0.4), tmp_path / "sw")
    assert d["spread"] == 0.4
    assert json.loads((tmp_path / "sw" / "session.json").read_text())["rendering"]["spread"] == 0.4
    r = rc.write(_rc(spread=0.4), tmp_path / "rc")
    assert r["spread"] == 0.4 and r["spec"]["spread"] == 0.4
    assert sw.render(_sw())["spread"] == 0.0 and rc.render(_rc())["spread"] == 0.0


@pytest.mark.parametrize("bad", [-0.1, 0.95])
def test_spread_out_of_range_is_refused(bad):
    with pytest.raises(ValueError):
        sw.render(_sw(spread=bad))
    with pytest.raises(ValueError):
        rc.render(_rc(spread=bad))


def test_a_tiny_spread_renders_the_single_play():
    """The spread path (render_c's per-play exposure samples included) tends to the single play."""
    for render, mk, keys in ((sw.render, _sw, ("z", "u", "v")), (rc.render, _rc, ("x", "c", "u", "v"))):
        a, b = render(mk()), render(mk(spread=1e-9))
        for k in keys:
            assert np.max(np.abs(a[k] - b[k])) < 1e-6, k


# ----------------------------------------------------------------------------- 2. brute force

def _brute_mean(q, half, start, s):
    """Mean over the 41 plays, each a plain loop: the play of half width half (1 + s u) from start."""
    q, half = q.tolist(), half.tolist()
    total = [0.0] * len(q)
    for un in U.tolist():
        f = 1.0 + s * un
        z = start
        for i in range(len(q)):
            h = half[i] * f
            if z < q[i] - h:
                z = q[i] - h
            elif z > q[i] + h:
                z = q[i] + h
            total[i] += z
    return np.array(total) / len(U)


@pytest.mark.parametrize("s", [0.3, 0.9])
def test_swing_render_drive_is_the_mean_of_41_plays(s):
    r = _sw(duration_s=6.0, spread=s)
    d = sw.render(r)
    q = d["q"]
    ref = _brute_mean(q, 0.5 * r.B(q), float(q[0]), s)   # every play starts at q[0], as the single one
    assert np.max(np.abs(d["z"] - ref)) < 1e-12
    # B is the centre width still, and the rest of the rendering is driven by z
    assert np.max(np.abs(d["z"] - sw.render(_sw(duration_s=6.0))["z"])) > 1e-3


@pytest.mark.parametrize("s", [0.3, 0.9])
def test_render_c_drive_is_the_mean_of_41_plays(s):
    d = rc.render(_rc(duration_s=6.0, spread=s))
    d0 = rc.render(_rc(duration_s=6.0))
    q = d["q_true"]
    assert np.array_equal(d["B_q"], d0["B_q"]) and np.array_equal(d["B_q"], _rc().B(q))
    # the single play's first output is its start state (the start lies within the play)
    ref = _brute_mean(q, 0.5 * d["B_q"], float(d0["x"][0]), s)
    assert np.max(np.abs(d["x"] - ref)) < 1e-12
    assert np.max(np.abs(d["x"] - d0["x"])) > 1e-3


# ----------------------------------------------------------------------------- 3. the physics

def _reversals(q):
    """Indices where q's (held) direction of motion changes."""
    dq = np.diff(q)
    mv = np.nonzero(np.abs(dq) > 1e-12)[0] + 1
    sg = np.sign(dq[mv - 1])
    return mv[np.nonzero(sg[1:] != sg[:-1])[0] + 1] - 1   # the last sample before the new direction


def _first_move(x, a, b):
    """First index in (a, b) where x moves, or None."""
    mv = np.nonzero(np.abs(np.diff(x[a:b])) > 1e-12)[0]
    return a + 1 + int(mv[0]) if mv.size else None


def _check_transition(q, x_s, x_c, x_w, B, s):
    """x_s the spread plant, x_c the single centre play (width B), x_w the single play of width
    (1 + s) B, all on the motor path q with constant B."""
    rev = _reversals(q)
    bounds = np.concatenate([[0], rev, [q.size - 1]])
    checked = 0
    for j in range(1, len(rev)):                  # the first leg's start states differ: skip it
        r, a, b = rev[j], bounds[j], bounds[j + 2]
        if abs(q[r] - q[a]) < 1.2 * (1 + s) * B or abs(q[b] - q[r]) < 1.2 * (1 + s) * B:
            continue                              # every play engaged before, the widest taken up after
        travel = np.abs(q[r:b + 1] - q[r])
        step = np.abs(np.diff(q[r:b + 1]))
        m = _first_move(x_s, r, b + 1)
        i = m - r
        # first motion once the motor has travelled (1 - s) B, to within one sample's travel
        assert travel[i - 1] <= (1 - s) * B + 1e-12
        assert travel[i] >= (1 - s) * B - 1e-12
        assert abs(travel[i] - (1 - s) * B) <= step[i - 1] + 1e-12
        # on the centre play again exactly from where the widest play, of (1 + s) B, moves
        w = _first_move(x_w, r, b + 1)
        assert abs(abs(q[w] - q[r]) - (1 + s) * B) <= abs(q[w] - q[w - 1]) + 1e-12
        off = np.nonzero(np.abs(x_s[r:b + 1] - x_c[r:b + 1]) >= 1e-12)[0]
        assert off.size and r + int(off[0]) == m     # it leaves the centre play at the first motion
        joined = r + int(off[-1]) + 1
        assert abs(joined - w) <= 1
        # in between, a smooth take-up: never faster than the motor, off the centre play throughout
        assert np.all(np.abs(np.diff(x_s[m - 1:w + 1])) <= np.abs(np.diff(q[m - 1:w + 1])) + 1e-12)
        assert joined - m >= 0.9 * 2 * s * B / np.max(step)
        checked += 1
    assert checked >= 3
    return checked


@pytest.mark.parametrize("s", [0.25, 0.6])
def test_swing_render_transition_starts_at_1_minus_s_B(s):
    B = 0.2
    kw = dict(shape="triangle", swing_s=0.3, ramp_lo=-0.45, ramp_hi=0.45, duration_s=6.0)
    d = sw.render(_sw(b_lo=B, b_hi=B, spread=s, **kw))
    dc = sw.render(_sw(b_lo=B, b_hi=B, **kw))
    dw = sw.render(_sw(b_lo=(1 + s) * B, b_hi=(1 + s) * B, **kw))
    _check_transition(d["q"], d["z"], dc["z"], dw["z"], B, s)


@pytest.mark.parametrize("s", [0.25, 0.6])
def test_render_c_transition_starts_at_1_minus_s_B(s):
    B = 0.2
    kw = dict(excitation="triangle", swing_time_s=0.3, duration_s=6.0)
    d = rc.render(_rc(b_min_mm=B, b_max_mm=B, spread=s, **kw))
    dc = rc.render(_rc(b_min_mm=B, b_max_mm=B, **kw))
    dw = rc.render(_rc(b_min_mm=(1 + s) * B, b_max_mm=(1 + s) * B, **kw))
    assert np.all(d["B_q"] == B)
    _check_transition(d["q_true"], d["x"], dc["x"], dw["x"], B, s)
