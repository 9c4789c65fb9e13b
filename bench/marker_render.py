"""Independent renderer of marker records for checking the onset estimator.

Written apart from playscope: it imports numpy and the standard library only, and shares no
code with the onset detector, playscope.fit.onset_model or playscope.sim (a test checks the
imports). It writes a session folder in the documented format (docs/session-format.md), so
the estimator is judged from files, as a user's data would be.

The robot: a cable-driven bending section of arc length L with a rigid tip, a play of width
B(q) between actuator q and the section (the play centre z is dragged by q at distance B/2,
evaluated sample by sample at 1 kHz), bending c = z / q_per_rad rad, constant curvature. The
camera: pinhole at 45 mm looking at the bending plane, 25 Hz with a random phase, the scene of
frame k captured at t_k - t_delay, averaged over a short exposure, Gaussian noise per axis.

Registration forms (size in deg, the +- amplitude; the paper's V-B case is 1.5):
  rot_distal   the camera frame rotated by +-size about its y axis, the sign following the
               direction of distal motion (paper V-B), flipping a random time within one
               frame period after the distal direction changes;
  rot_motor    the same rotation, its sign following the motor direction, flipping a random
               time within one frame period after the motor reverses;
  channel      the instrument translated in its channel along the bending plane's x axis by
               +-depth tan(size) (the same image shift as the rotation), sign following the
               distal direction, sliding over a random 0-40 ms starting within a frame
               period of the distal direction change.
Ringing: after each distal stop the tip overshoots in the old direction and rings,
A e^(-zeta w t) sin(w_d t) in bending, scaled so that the image amplitude is ``ring_px``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

FORMS = ("none", "rot_distal", "rot_motor", "channel")


@dataclass
class Scene:
    """Everything the renderer needs. Lengths mm, angles deg, times s, image px."""

    seed: int = 0
    B_kind: str = "fig7"            # "fig7": constant 15 deg of bending (0.785 mm); "stras": 0.12..0.31 mm, wide at straight
    q_per_rad: float = 3.0          # mm of cable per rad of bending
    L: float = 20.0
    tip: float = 5.0
    q_lo: float = -2.6
    q_hi: float = 2.6
    amp: float = 1.6                # back-and-forth amplitude, mm (> B so the tip moves each leg)
    speed: float = 0.785            # mm/s (15 deg/s of bending for q_per_rad 3)
    duration: float = 160.0
    enc_hz: float = 1000.0
    fps: float = 25.0
    t_delay_true: float = 0.08
    t_delay_config: float | None = 0.08
    noise_px: float = 0.12
    exposure: float = 0.008
    focal_px: float = 600.0
    depth: float = 45.0
    form: str = "none"
    size_deg: float = 0.0
    ring_px: float = 0.0
    ring_hz: float = 3.0
    ring_zeta: float = 0.08
    extra: dict = field(default_factory=dict)

    def B(self, q):
        """True width at actuator position q (mm)."""
        q = np.asarray(q, float)
        if self.B_kind == "fig7":
            return np.full(q.shape, np.radians(15.0) * self.q_per_rad)
        return 0.12 + 0.19 * np.exp(-(q / 1.0) ** 2)


def excitation(sc: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Section III-B: back-and-forth of amplitude amp at constant speed on a ramp up then
    down over [q_lo, q_hi], no hold at the turns. Returns (t (N,), q (N,))."""
    t = np.arange(0.0, sc.duration, 1.0 / sc.enc_hz)
    half = sc.duration / 2
    ph = np.where(t < half, t / half, 2 - t / half)
    mid = sc.q_lo + sc.amp / 2 + (sc.q_hi - sc.q_lo - sc.amp) * ph
    q = np.empty(t.size)
    q[0] = mid[0]
    d, dt = 1.0, 1.0 / sc.enc_hz
    for k in range(1, t.size):  # turn when the offset from the ramp reaches amp/2
        q[k] = q[k - 1] + d * sc.speed * dt
        if d * (q[k] - mid[k]) >= sc.amp / 2:
            d = -d
    return t, q


def drag(q: np.ndarray, B) -> np.ndarray:
    """Play centre z dragged by q: z stays unless q is further than B(q)/2 from it."""
    z = np.empty(q.size)
    z[0] = q[0]
    b = B(q)
    for k in range(1, q.size):
        z[k] = min(max(z[k - 1], q[k] - b[k] / 2), q[k] + b[k] / 2)
    return z


def held_sign(x: np.ndarray) -> np.ndarray:
    """Sign of the last non-zero increment of x, held while x stays (+1 at the start)."""
    dx = np.diff(x, prepend=x[0])
    s = np.sign(np.where(np.abs(dx) > 1e-12, dx, 0.0))
    last = np.where(s != 0, np.arange(s.size), 0)
    last = np.maximum.accumulate(last)
    out = s[last]
    out[out == 0] = 1.0
    return out


def flip_times(sign: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Times where a held sign changes. (n,)"""
    return t[1:][np.diff(sign) != 0]


def delayed_sign(t: np.ndarray, sign: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """The held sign with each flip postponed by its lag (lags: one per flip)."""
    out = np.full(t.size, sign[0])
    for tf, lag in zip(flip_times(sign, t), lags):
        out[t >= tf + lag] = sign[np.searchsorted(t, tf)]
    return out


def tip_xz(c_rad: np.ndarray, L: float, tip: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-curvature section then a straight tip, bending in the x-z plane (mm)."""
    c = np.asarray(c_rad, float)
    small = np.abs(c) < 1e-6
    cs = np.where(small, 1.0, c)
    x = np.where(small, L * c / 2, L * (1 - np.cos(c)) / cs) + tip * np.sin(c)
    z = np.where(small, L, L * np.sin(c) / cs) + tip * np.cos(c)
    return x, z


def render(sc: Scene) -> dict:
    """Encoder log, marker frames and truth. Returns {"t_enc", "q", "t_f", "u", "v", "t_onset_img"
    (image-clock onset after each reversal), "t_stop_img", "B" (callable)}."""
    rng = np.random.default_rng(sc.seed)
    t, q = excitation(sc)
    z = drag(q, sc.B)
    c = z / sc.q_per_rad
    dist_dir = held_sign(z)
    mot_dir = held_sign(q)
    T = 1.0 / sc.fps
    # Ringing: each distal stop (z stops; the motor reversed) starts one, continuing the old motion.
    t_turn = flip_times(mot_dir, t)
    if sc.ring_px > 0:
        w = 2 * np.pi * sc.ring_hz
        wd = w * np.sqrt(1 - sc.ring_zeta ** 2)
        gain = sc.focal_px / sc.depth * (sc.L / 2 + sc.tip)  # px per rad of bending near straight
        ring = np.zeros(t.size)
        for tt in t_turn:
            i = np.searchsorted(t, tt)
            old = mot_dir[i - 1]
            d = t[i:] - tt
            ring[i:] += old * (sc.ring_px / gain) * np.exp(-sc.ring_zeta * w * d) * np.sin(wd * d)
        c = c + ring
    # Registration sign per encoder sample.
    if sc.form in ("rot_distal", "channel"):
        sgn = delayed_sign(t, dist_dir, rng.uniform(0, T, flip_times(dist_dir, t).size))
    elif sc.form == "rot_motor":
        sgn = delayed_sign(t, mot_dir, rng.uniform(0, T, t_turn.size))
    else:
        sgn = np.ones(t.size)
    if sc.form == "channel":  # slide over 0-40 ms instead of jumping
        slide = np.zeros(t.size)
        for tf in flip_times(sgn, t):
            n = max(1, int(rng.uniform(0, 0.04) * sc.enc_hz))
            i = np.searchsorted(t, tf)
            ramp = np.linspace(-1, 0, n, endpoint=False) * (sgn[i] - sgn[i - 1])
            slide[i:i + n] = ramp[:t.size - i]  # a flip within the slide of the record's end: cut there
        sgn_eff = sgn + slide
    else:
        sgn_eff = sgn
    # Frames: random camera phase, scene at t_k - t_delay averaged over the exposure.
    tk = np.arange(0.5 + rng.uniform(0, T), t[-1] - 0.1, T)
    # 5 nodes over the exposure (its renderings as drawn); a longer exposure one node per encoder sample,
    # so the frame is the scene's mean over its exposure, not a few flashes of it
    sub = np.linspace(-sc.exposure, 0.0, 5 if sc.exposure <= 0.008 else int(np.ceil(sc.exposure * sc.enc_hz)) + 1)
    tcap = (tk - sc.t_delay_true)[:, None] + sub[None, :]
    ck = np.interp(tcap, t, c)
    sk = np.interp(tcap, t, sgn_eff)
    x, zt = tip_xz(ck, sc.L, sc.tip)
    a = np.radians(sc.size_deg)
    if sc.form == "channel":
        x = x + sk * sc.depth * np.tan(a)
    # Camera frame: x right, y down (base z up), depth along base y at sc.depth.
    X, Y, Z = x, -(zt - 15.0), np.full(x.shape, sc.depth)
    if sc.form in ("rot_distal", "rot_motor"):
        th = sk * a
        X, Z = np.cos(th) * X + np.sin(th) * Z, -np.sin(th) * X + np.cos(th) * Z
    u = 360.0 + sc.focal_px * X / Z
    v = 288.0 + sc.focal_px * Y / Z
    u = u.mean(axis=1) + rng.normal(0, sc.noise_px, tk.size)
    v = v.mean(axis=1) + rng.normal(0, sc.noise_px, tk.size)
    t_on = flip_times(dist_dir, t)  # distal motion resumes (scene clock)
    return {"t_enc": t, "q": q, "t_f": tk, "u": u, "v": v, "t_onset_img": t_on + sc.t_delay_true,
            "t_stop_img": t_turn + sc.t_delay_true, "B": sc.B}


def write(sc: Scene, folder: Path) -> dict:
    """Render and write a playscope-session/1 folder (session.json, encoder.csv, marker.csv).
    Returns the render dict."""
    r = render(sc)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    K = [[sc.focal_px, 0.0, 360.0], [0.0, sc.focal_px, 288.0], [0.0, 0.0, 1.0]]
    meta = {"format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "image"},
            "robot": {"model": "constant_curvature", "bend_length_mm": sc.L, "tip_length_mm": sc.tip,
                      "q_per_rad": sc.q_per_rad},
            "camera": {"width": 720, "height": 576, "fps": sc.fps, "K": K, "dist": [0.0] * 5},
            "hand_eye": {"R": [[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]], "t_mm": [0.0, 15.0, sc.depth]},
            "source": "bench/marker_render.py"}
    if sc.t_delay_config is not None:
        meta["t_delay_s"] = sc.t_delay_config
    (folder / "session.json").write_text(json.dumps(meta, indent=1))
    with open(folder / "encoder.csv", "w") as f:
        f.write("t_s,q\n")
        f.writelines(f"{a:.6f},{b:.7f}\n" for a, b in zip(r["t_enc"], r["q"]))
    with open(folder / "marker.csv", "w") as f:
        f.write("t_s,u_px,v_px\n")
        f.writelines(f"{a:.6f},{b:.4f},{c:.4f}\n" for a, b, c in zip(r["t_f"], r["u"], r["v"]))
    return r
