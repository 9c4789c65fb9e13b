"""The 3-minute 25 Hz image session the host speed benches time `calibrate` on (bench/bench_host.py,
bench/onset_cost.py): the simulator's robot on its excitation (a 1 kHz encoder log), the marker
seen 80 ms late with 0.05 px noise, written and loaded back as a user's session is, so that
load_session thins the encoder to io.session.ENCODER_MAX_HZ as it does every image session's."""

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
from host.synth import ROBOT, excitation, image_model_parts, true_B, true_f  # noqa: E402

from playscope.fit import model  # noqa: E402
from playscope.io.session import Session, load_session, write_session  # noqa: E402


def image_session(duration_s: float = 180.0) -> Session:
    """The bench session in memory (not yet thinned): encoder at 1 kHz, marker at 25 Hz, t_delay 0.08 s."""
    t, q, _ = excitation(v=0.4, rate_hz=1000.0)
    t, q = t[t < duration_s], q[t < duration_s]
    cam, he = image_model_parts()
    c = model.direct_model(q, true_B, true_f)
    tf = np.arange(0.0, t[-1], 1 / 25.0)
    im = model.ImageModel(ROBOT, cam, he)
    Q = im(np.interp(tf - 0.08, t, c)) + np.random.default_rng(0).normal(0, 0.05, (tf.size, 2))
    return Session("mm", "image", ROBOT, {"t_s": t, "q": q}, cam, he, 0.08,
                   marker={"t_s": tf, "u_px": Q[:, 0], "v_px": Q[:, 1]})


def loaded_session(duration_s: float = 180.0) -> Session:
    """`image_session` written to a temporary directory and read back with load_session (thinned)."""
    with tempfile.TemporaryDirectory() as d:
        write_session(image_session(duration_s), Path(d) / "s")
        return load_session(Path(d) / "s")
