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

# the keys render() returned before the option, and the sha1 of the written files, recorded before
# the option was added
SW_KEYS = ["q", "t_enc", "t_f", "t_onset", "u", "v"]
RC_KEYS = ["B_q", "K", "R_he", "R_true", "bend_length_mm", "c", "delay_s", "dir0", "eta",
           "exposure_s", "k_true", "kappa", "q", "q_true", "t_capture", "t_enc", "t_f", "t_flip",
           "t_he", "t_origin", "t_rev", "t_true", "tip_gain", "tip_length_mm", "u", "v", "x",
           "x_zero"]
PINNED = {
    "sw files": "8ff9e7cc3c9f86b4612a42980cee9ecc8d37f960",
    "rc files": "017866153754bab9486bb45526e3b9e329ec311a",
}
# The returned values' fingerprints (`_fingerprint`: per key, the norm and a projection on a seeded
# Gaussian vector), taken 2026-11-30 from the renderers as they were then. Not a hash of the float
# bytes, which were pinned here before: numpy's transcendental kernels differ in the last bit between
# CPUs (the same renderers and numpy gave other bytes on an AVX2-only EPYC than where they were pinned,
# while the written files, rounded to their CSV digits, kept their hashes above). A change of the
# rendering moves a fingerprint by far more than the tolerance (FP_RTOL of the key's norm).
FP_RTOL = 1e-9
FINGERPRINTS = {
    "sw default": {
        "q": (108.83749599236877, 126.1139317826395),
        "t_enc": (758.8992041107963, -988.4868630585013),
        "t_f": (117.60740013733445, -119.44089457210215),
        "t_onset": (16.64157621741402, -27.99062112291936),
        "u": (6230.347734253226, 9047.868209101733),
        "v": (2727.920919109453, -1133.253481854687),
    },
    "rc default": {
        "B_q": (20.878304001030862, 22.41910916971648),
        "K": (984.8745349353184, 1016.977622131977),
        "R_he": (1.7320508075688772, -2.26699377515439),
        "R_true": (1.7320508075688772, -0.5065871328985256),
        "bend_length_mm": (19.916753624497012, -12.981563801193955),
        "c": (46.28066042272237, 49.27795100579696),
        "delay_s": (0.08, 0.08424926035894066),
        "dir0": (1.0, 0.0012301533574825742),
        "eta": (0.0, 0.0),
        "exposure_s": (0.005725855418965418, -0.0045969282204431465),
        "k_true": (2.768203211952842, -3.054265038574273),
        "kappa": (0.002678429219418188, 9.158290690369384e-05),
        "q": (129.1537303399325, -27.32681167845804),
        "q_true": (129.15373905444332, 76.61581554796793),
        "t_capture": (38058.255141264824, 34355.80004953794),
        "t_enc": (249150.49078359775, 95458.6031397075),
        "t_f": (38059.593795955065, 7193.764438762528),
        "t_flip": (6017.075112133847, -6940.723071380889),
        "t_he": (51.04903666579537, 41.29375876470913),
        "t_origin": (2268.325, -839.3364348768706),
        "t_rev": (6017.003980174103, 3558.16963457211),
        "t_true": (51.24555786045576, -92.10497742530661),
        "tip_gain": (0.0, 0.0),
        "tip_length_mm": (5.043399285719071, 2.7903140588179776),
        "u": (6890.226702602813, -15896.166694360223),
        "v": (5048.440028566108, 2346.0885195071887),
        "x": (127.95602290999035, 62.64226924177408),
        "x_zero": (0.03263154285130139, -0.04093458192409313),
    },
    "sw effects": {
        "q": (102.12226480493317, 119.92845722168127),
        "t_enc": (758.8992041107963, -988.4868630585013),
        "t_f": (117.59455014084176, -119.3877126850911),
        "t_onset": (48.642089531598046, 11.695048389048605),
        "u": (6233.765745098635, 8460.953896083874),
        "v": (2714.0420793168696, -1168.2773245974458),
    },
    "rc effects": {
        "B_q": (27.5557760093978, 10.002829833570134),
        "K": (996.2703845899921, 1028.4563635789016),
        "R_he": (1.7320508075688772, -2.056001152278052),
        "R_true": (1.7320508075688772, -0.2911834555610851),
        "bend_length_mm": (19.92193706267017, -12.98494232033533),
        "c": (37.11948236404777, 17.155523027136205),
        "delay_s": (0.08, 0.08424926035894066),
        "dir0": (1.0, 0.0012301533574825742),
        "eta": (1.2450463494626014, -2.023125775393135),
        "exposure_s": (0.004013455862214658, -0.0032221506071229305),
        "k_true": (3.299505669039043, -3.6404714675604684),
        "kappa": (0.04247836773282817, -0.001452452941183762),
        "q": (123.53987493275197, 120.9581027140784),
        "q_true": (123.53988542733501, -3.9853006681500958),
        "t_capture": (12345.996624670284, 11193.94619523405),
        "t_enc": (80816.33981594378, 30777.362475743375),
        "t_f": (12347.335267862722, 2293.9596541344417),
        "t_flip": (5164.803039629787, -8494.774415781601),
        "t_he": (49.63115006455564, 40.58874129062739),
        "t_origin": (731.71, -270.75082396206676),
        "t_rev": (5164.645951244965, -10757.294424919437),
        "t_true": (49.59677355280182, -90.04547041915296),
        "tip_gain": (1.0303879495612838, -1.4400891828998703),
        "tip_length_mm": (5.2370930966296285, 2.8974772107064566),
        "u": (7362.912457601714, -17142.519171089636),
        "v": (4712.559825279305, 2069.2217113087772),
        "x": (123.39411724669026, 95.08119668360311),
        "x_zero": (0.045710733476396315, 0.05734174975503212),
    },
}


def _fingerprint(d, keys):
    """{key: (the values' 2-norm, their dot product with a standard normal vector seeded by the key's
    index)} over the keys' values as float64, flattened."""
    out = {}
    for i, k in enumerate(keys):
        a = np.asarray(d[k], dtype=float).ravel()
        out[k] = (float(np.linalg.norm(a)), float(a @ np.random.default_rng(i).standard_normal(a.size)))
    return out


def _same_fingerprint(d, keys, name):
    """Each key's norm and projection within FP_RTOL of its pinned norm (a last-bit change moves both by
    about 1e-16 of it; a key pinned at zero stays exactly zero)."""
    got, want = _fingerprint(d, keys), FINGERPRINTS[name]
    assert got.keys() == want.keys()
    for k, (n, p) in got.items():
        n0, p0 = want[k]
        tol = FP_RTOL * n0
        assert abs(n - n0) <= tol and abs(p - p0) <= tol, (name, k, n, n0, p, p0)


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
    _same_fingerprint(sw.render(_sw()), SW_KEYS, "sw default")
    _same_fingerprint(rc.render(_rc()), RC_KEYS, "rc default")
    fx_sw = _sw(seed=5, shape="triangle", ring_hz=9.0, reg_deg=2.0)
    fx_rc = _rc(seed=5, excitation="triangle", tip_hz=9.0, reg_deg=1.5, reg_axis="x")
    _same_fingerprint(sw.render(fx_sw), SW_KEYS, "sw effects")
    _same_fingerprint(rc.render(fx_rc), RC_KEYS, "rc effects")
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
