"""The image path's onset threshold from the record (onset_settings.image_onset_settings):
k from the false-alarm rate in 2-D (sqrt(ln(n / alpha))), the noise floor measured on still
segments, at two marker noise levels. Not wired into `calibrate` (docs/robustness.md: on the
demo's creeping STRAS-like preset it made B worse), so it is tested on its own here."""

import numpy as np
import pytest

from playscope.fit.onset_settings import _axis_noise, image_onset_settings, onset_noise_k
from playscope.fit.onsets import OnsetConfig, run_onsets
from playscope.fit.reversals import detect_reversals
from playscope.fit import model
from playscope.io.session import Session

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


def _settings(s: Session):
    t, q = s.encoder["t_s"], s.encoder["q"]
    rt, rq, _ = detect_reversals(t, q, 0.01 * np.ptp(q))
    t_f, obs = s.observations()
    over, doc = image_onset_settings(t, q, rt, rq, t_f, obs, 0.08, 25.0)
    on = run_onsets(t, q, rt, rq, t_f, obs, "image", OnsetConfig(t_delay_s=0.08, fps=25.0, **over))
    return over, doc, on, rt


@pytest.mark.parametrize("noise_px", [0.05, 0.1])
def test_image_threshold_follows_the_marker_noise(noise_px):
    over, d, on, rt = _settings(_image_session(noise_px))
    assert d["rule"] == "T = k x min(still noise, diff2_noise) (2-D)" and d["still_pairs"] > 300
    # A still frame difference has rms 2 sigma in 2-D (sqrt(2) per axis, two axes); both noise
    # figures find it. Measured 0.1026 and 0.100 at 0.05 px.
    assert d["still_noise_px"] / (2 * noise_px) == pytest.approx(1.0, abs=0.1)
    assert d["diff2_noise_px"] / (2 * noise_px) == pytest.approx(1.0, abs=0.1)
    assert d["noise_k"] == pytest.approx(onset_noise_k(d["fps"] * d["stroke_s"], dims=2))
    assert over["threshold"] == pytest.approx(d["noise_k"] * min(d["still_noise_px"], d["diff2_noise_px"]))
    assert on.b.size >= 0.8 * rt.size  # the detector with that threshold finds the onsets


def test_noisy_marker_on_a_slow_motion_keeps_the_record_bound():
    """At 0.2 px the marker moves less per frame than k x noise on most strokes: the bootstrap's
    few onsets come late and their 'still' segments hold motion (measured 0.64 px against the
    0.40 px bound); the threshold then uses the whole record's diff2 bound (the true 2 sigma)."""
    over, d, _, _ = _settings(_image_session(0.2))
    assert d["still_noise_px"] > 1.3 * d["diff2_noise_px"]
    assert d["diff2_noise_px"] / 0.4 == pytest.approx(1.0, abs=0.1)
    assert over["threshold"] == pytest.approx(d["noise_k"] * d["diff2_noise_px"])


def test_a_tracker_that_repeats_its_position_gets_the_rms():
    """Still differences mostly exactly 0 (MAD 0) with rare jitter: the rms counts the jitter."""
    d = np.zeros(200)
    d[::10] = 0.5
    assert _axis_noise(d) == pytest.approx(np.sqrt(0.1 * 0.25), rel=1e-12)  # median 0: rms about it
    assert _axis_noise(np.random.default_rng(1).normal(0, 0.1, 4000)) == pytest.approx(0.1, rel=0.05)
