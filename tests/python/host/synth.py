"""Synthetic sessions with a known B(q) and f, built from playscope.fit.model (test helper)."""

from __future__ import annotations

import numpy as np

from playscope.fit import model
from playscope.io.session import Camera, HandEye, Robot, Session

ROBOT = Robot("constant_curvature", bend_length_mm=20.0, tip_length_mm=5.0, q_per_rad=3.0)


def true_B(q):
    """Known width: larger near the straight pose (q = 0), like the paper's Fig. 8 (mm)."""
    q = np.asarray(q, float)
    return 0.3 + 0.4 * np.exp(-(q / 1.5) ** 2)


def true_f(q):
    """Known non-linear transmission with a dead-ish zone near q = 0 (deg), increasing."""
    q = np.asarray(q, float)
    return model.f_coarse(q, ROBOT.q_per_rad) * 0.8 + 4.0 * np.tanh(q)


def excitation(q_start=-4.0, q_end=4.0, amplitude=1.5, advance=0.5, v=0.5, rate_hz=500.0, return_sweep=True):
    """Back-and-forth on a ramp (section III-B), as firmware/core/exc.h: returns (t_s, q, reversal times)."""
    pts = [q_start]
    low = q_start
    while low + amplitude <= q_end:
        pts += [low + amplitude, low + advance]
        low += advance
    if return_sweep:
        high = pts[-2]
        while high - amplitude >= q_start:
            pts += [high - amplitude, high - advance]
            high -= advance
    pts = np.array(pts)
    seg_t = np.abs(np.diff(pts)) / v
    knots_t = np.concatenate([[0.0], np.cumsum(seg_t)])
    t = np.arange(0.0, knots_t[-1], 1.0 / rate_hz)
    q = np.interp(t, knots_t, pts)
    return t, q, knots_t[1:-1]


def angle_session(noise_deg=0.02, fps=25.0, seed=0, **kw) -> Session:
    """An angle session (distal.kind 'angle') from the direct model with true_B, true_f."""
    rng = np.random.default_rng(seed)
    t, q, _ = excitation(**kw)
    c = model.direct_model(q, true_B, true_f)
    tf = np.arange(t[0], t[-1], 1.0 / fps)
    cf = np.interp(tf, t, c) + rng.normal(0, noise_deg, tf.size)
    return Session(actuator_unit="mm", distal_kind="angle", robot=ROBOT,
                   encoder={"t_s": t, "q": q}, distal={"t_s": tf, "c_deg": cf},
                   truth={"t_s": t, "c_deg": c}, t_delay_s=0.0)


def image_model_parts():
    """A camera looking at the bending plane from 60 mm in front (px, mm)."""
    cam = Camera(720, 576, 25.0, np.array([[600.0, 0, 360], [0, 600.0, 288], [0, 0, 1]]),
                 np.array([-0.1, 0.01, 0.0005, -0.0003, 0.0]))
    # Camera z axis along base -y, camera x along base x, camera y along base -z... as a rotation:
    R = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    he = HandEye(R, np.array([-5.0, 15.0, 60.0]))
    return cam, he
