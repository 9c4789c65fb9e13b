"""The image path's onset threshold from the record (issue 13 item 3, estimate.image_onset_settings):
k from the false-alarm rate in 2-D (sqrt(ln(n / alpha))), the noise floor measured on still
segments, at two marker noise levels; nothing taken from the C detector's constant k = 3 and its
0.05 / 1 px floor and ceiling."""

import numpy as np
import pytest

from playscope import estimate as E
from playscope import model
from playscope.calibration import calibrate
from playscope.session import Session

from .synth import ROBOT, excitation, image_model_parts, true_B, true_f


def _image_session(noise_px: float, duration_s: float = 60.0, seed: int = 0) -> Session:
    """A 25 Hz marker session from the direct model through the camera model, Gaussian pixel noise
    of noise_px on each axis (the generator of bench/bench_host.py, shorter)."""
    t, q, _ = excitation(v=0.4, rate_hz=1000.0)
    t, q = t[t < duration_s], q[t < duration_s]
    cam, he = image_model_parts()
    c = model.direct_model(q, true_B, true_f)
    tf = np.arange(0.0, t[-1], 1 / 25.0)
    Q = model.ImageModel(ROBOT, cam, he)(np.interp(tf - 0.08, t, c))
    Q = Q + np.random.default_rng(seed).normal(0, noise_px, Q.shape)
    return Session("mm", "image", ROBOT, {"t_s": t, "q": q}, cam, he, 0.08,
                   marker={"t_s": tf, "u_px": Q[:, 0], "v_px": Q[:, 1]})


@pytest.mark.parametrize("noise_px", [0.05, 0.1])
def test_image_threshold_follows_the_marker_noise(noise_px):
    s = _image_session(noise_px)
    cal = calibrate(s, model_kind="play")
    d = cal.doc["onset"]["rule"]
    assert d["rule"] == "T = k x min(still noise, diff2_noise) (2-D)" and d["still_pairs"] > 300
    # A still frame difference has rms 2 sigma in 2-D (sqrt(2) per axis, two axes); both noise
    # figures find it. Measured 0.1026 and 0.100 at 0.05 px.
    assert d["still_noise_px"] / (2 * noise_px) == pytest.approx(1.0, abs=0.1)
    assert d["diff2_noise_px"] / (2 * noise_px) == pytest.approx(1.0, abs=0.1)
    assert d["noise_k"] == pytest.approx(E.onset_noise_k(d["fps"] * d["stroke_s"], dims=2))
    assert d["threshold_px"] == pytest.approx(d["noise_k"] * min(d["still_noise_px"], d["diff2_noise_px"]))
    # The detector ran with it (the calibration file records the configuration it used).
    assert cal.onset_config["threshold"] == pytest.approx(d["threshold_px"], abs=2 / 65536)
    assert cal.n_b_samples >= 0.8 * cal.reversals


def test_a_threshold_given_by_the_caller_is_kept():
    cal = calibrate(_image_session(0.05), model_kind="play", onset_cfg={"threshold": 0.5})
    assert cal.doc["onset"]["rule"] is None
    assert cal.onset_config["threshold"] == pytest.approx(0.5, abs=2 / 65536)


def test_noisy_marker_on_a_slow_motion_keeps_the_record_bound():
    """At 0.2 px the marker moves less per frame than k x noise on most strokes: the bootstrap's
    few onsets come late and their 'still' segments hold motion (measured 0.64 px against the
    0.40 px bound); the threshold then uses the whole record's diff2 bound (0.40 px, the true 2
    sigma), and the host refinement still gives B samples."""
    cal = calibrate(_image_session(0.2), model_kind="play")
    d = cal.doc["onset"]["rule"]
    assert d["still_noise_px"] > 1.3 * d["diff2_noise_px"]  # motion in the 'still' segments
    assert d["diff2_noise_px"] / 0.4 == pytest.approx(1.0, abs=0.1)
    assert d["threshold_px"] == pytest.approx(d["noise_k"] * d["diff2_noise_px"])
    assert cal.n_b_samples >= 0.8 * cal.reversals
