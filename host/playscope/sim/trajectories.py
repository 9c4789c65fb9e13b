"""Actuator trajectories q(t) for the simulator: excitation (paper III-B), test motion (Fig. 10),
task-space ellipse (Fig. 12) and random walk.

All return (t_s (N,), q (N,)) sampled at ``rate_hz``; q in actuator units (mm of cable).
"""

from __future__ import annotations

import numpy as np


def back_and_forth(duration_s: float, rate_hz: float, mean, amp: float, speed: float,
                   hold_s: float = 0.0, q0: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Back-and-forth at constant |dq/dt| = speed around a moving mean, holding hold_s at each turn.

    mean: callable t_s -> q (the ramp or slow mean); amp: peak-to-peak amplitude of the
    back-and-forth; speed: actuator units/s. A turn happens when q - mean(t) reaches +-amp/2.
    With hold_s > 0 the motion is trapezoidal (the paper's test motion, Fig. 10); with a ramp
    mean it is the excitation of section III-B. Returns (t (N,), q (N,)).
    """
    n = int(round(duration_s * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    m = np.asarray([mean(x) for x in t], float)
    q = np.empty(n)
    q[0] = m[0] if q0 is None else q0
    d, hold_until, dt = 1.0, -1.0, 1.0 / rate_hz
    for k in range(1, n):  # sequential: each turn depends on where the previous leg ended
        if t[k] < hold_until:
            q[k] = q[k - 1]
            continue
        q[k] = q[k - 1] + d * speed * dt
        if d * (q[k] - m[k]) >= amp / 2:
            d = -d
            hold_until = t[k] + hold_s
    return t, q


def excitation(q_lo: float, q_hi: float, amp: float, speed: float, duration_s: float,
               rate_hz: float = 500.0, hold_s: float = 0.3, cycles: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Section III-B: small back-and-forth motions (amp > B so the tip moves at each leg) superposed
    on a ramp covering [q_lo, q_hi] up then down, ``cycles`` times (each reversal gives one onset,
    i.e. a B sample at q_mean). Holds of hold_s at the turns give still periods for the noise
    floor. With cycles >= 2 each half of the record covers the whole range (held-out tests)."""
    half = duration_s / (2 * cycles)

    def mean(t):
        ph = (t / half) % 2.0
        s = ph if ph < 1 else 2 - ph
        return q_lo + amp / 2 + (q_hi - q_lo - amp) * s

    return back_and_forth(duration_s, rate_hz, mean, amp, speed, hold_s)


def test_motion(q_lo: float, q_hi: float, amp: float, speed: float, duration_s: float,
                rate_hz: float = 500.0, hold_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 10: periodic trapezoidal back-and-forth (hold_s at each end) on a mean varying linearly
    from q_lo + amp/2 to q_hi - amp/2."""
    def mean(t):
        return q_lo + amp / 2 + (q_hi - q_lo - amp) * t / duration_s

    return back_and_forth(duration_s, rate_hz, mean, amp, speed, hold_s)


def random_walk(q_lo: float, q_hi: float, speed: float, duration_s: float, rate_hz: float = 500.0,
                seed: int = 0, corr_s: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """Random walk: velocity is low-pass filtered white noise (time constant corr_s) scaled to an
    RMS of ``speed``, reflected at [q_lo, q_hi]. Gives reversals at random places and amplitudes."""
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * rate_hz)) + 1
    dt = 1.0 / rate_hz
    a = np.exp(-dt / corr_s)
    w = rng.standard_normal(n) * np.sqrt(1 - a * a)
    v = np.empty(n)
    v[0] = 0.0
    for k in range(1, n):  # AR(1) velocity
        v[k] = a * v[k - 1] + w[k]
    v *= speed / max(np.std(v), 1e-12)
    q = np.empty(n)
    q[0] = 0.5 * (q_lo + q_hi)
    for k in range(1, n):  # reflect at the ends of the range
        x = q[k - 1] + v[k] * dt
        if x > q_hi or x < q_lo:
            v[k:] = -v[k:]
            x = q[k - 1] + v[k] * dt
        q[k] = x
    return np.arange(n) / rate_hz, q


def ellipse_task(a_mm: float, b_mm: float, period_s: float, cycles: float, L: float, l_tip: float,
                 q_per_rad: float, x0_mm: float = 0.0, rate_hz: float = 500.0):
    """Fig. 12: an ellipse in the bending plane of the tip, x = x0 + a cos(wt), z = z_mid + b sin(wt).

    The bending angle c*(t) is found from x by inverting g (constant curvature, monotone in c on
    [-120, 120] deg), and the translation DOF is scripted so the tip z follows the ellipse.
    q(t) = f_coarse^-1(c*) (open loop, no compensation). Returns (t, q, c_ref_deg, translation_mm).
    """
    from ..fit.model import constant_curvature

    n = int(round(cycles * period_s * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    w = 2 * np.pi / period_s
    grid = np.linspace(-120, 120, 4801)
    P = constant_curvature(grid, L, l_tip)
    x = x0_mm + a_mm * np.cos(w * t)
    c_ref = np.interp(x, P[:, 0], grid)
    z_mid = float(np.interp(x0_mm, P[:, 0], P[:, 2]))
    z_tip = np.interp(c_ref, grid, P[:, 2])
    translation = z_mid + b_mm * np.sin(w * t) - z_tip
    q = np.radians(c_ref) * q_per_rad
    return t, q, c_ref, translation
