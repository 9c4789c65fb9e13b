"""Second independent renderer of marker sessions: fast swings at camera rate.

Written apart from playscope's estimator and simulator and from bench/marker_render.py: it
imports numpy and the standard library only (a test checks the imports) and writes a session
folder in the documented format (docs/session-format.md), so the estimator is judged from
files, as a user's data would be. What it varies is what a bench varies:

  excitation  "swings": the paper's section III-B ramp over the travel with square-ish swings of
              +-swing_mm every swing_period_s, each swing a raised-cosine move lasting swing_s
              (0.24 s in the paper: the play is taken up within one or two frames at 25 fps);
              "sine": the ramp plus a sine of +-swing_mm, period 2 swing_period_s;
              "triangle": the ramp plus a constant-speed triangle of +-swing_mm, legs of swing_s;
  plant       play of width B(q) = b_lo + (b_hi - b_lo) exp(-((q - q_c) / w)^2) (mm), the play
              centre z dragged by q at distance B/2 (1 kHz), bending c = z / q_per_rad (rad);
              tip ringing: a second-order tip mode x'' + 2 zeta w x' + w^2 x = -g c''
              (base excitation), integrated exactly per sample, added to c, the gain g set so
              that the largest excursion is about ring_px in the image;
  transition  optional (spread s in [0, 0.9], 0 by default: the single play above, bit for bit):
              a smooth take-up after each reversal, a Prandtl-Ishlinskii spread of play widths.
              The bending is driven by the mean of the centres of 41 plays of widths
              B(q) (1 + s u), u = linspace(-1, 1, 41), equal weights, each starting where the
              single play starts; after a reversal the mean starts moving once q has travelled
              (1 - s) B and is fully dragged after (1 + s) B. B(q) stays the centre width;
  camera      pinhole looking at the bending plane, frames at fps with each capture time
              jittered uniformly by +-jitter of a frame period (stamps exact: capture time + delay),
              each frame the mean over an exposure of exposure_s (4 ms unless set) centred on
              its capture time (the true delay is from that centre), Gaussian marker noise per axis;
  registration the camera frame rotated by +-reg_deg about its y axis, the sign following the
              distal direction, flipping a uniform 0..reg_lag frame period after the tip
              reverses (reg_lag 1 by default; 0: at the onset itself).

Truth: B(q) callable (the centre width), the true delay, and per reversal the scene-clock stop
and onset; render() also returns the driving play centre z and the spread.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

ENC_HZ = 1000.0
SPREAD_NODES = np.linspace(-1.0, 1.0, 41)   # play widths B (1 + spread u), equal weights


@dataclass
class Rendering:
    """One rendering. Lengths mm, angles deg, times s, image px."""

    name: str
    seed: int
    shape: str = "swings"           # "swings", "sine", "triangle"
    swing_mm: float = 0.45
    swing_s: float = 0.24           # duration of one swing (swings, triangle legs)
    swing_period_s: float = 1.5
    ramp_lo: float = -2.0
    ramp_hi: float = 2.0
    duration_s: float = 150.0
    fps: float = 25.0
    jitter: float = 0.25            # capture time jitter, +- fraction of a frame period
    noise_px: float = 0.12
    delay_s: float = 0.08
    delay_cfg_s: float | None = 0.08
    b_lo: float = 0.12
    b_hi: float = 0.30
    b_qc: float = 0.0
    b_w: float = 1.2
    ring_hz: float = 0.0
    ring_zeta: float = 0.05
    ring_px: float = 10.0           # largest ringing excursion in the image (approx.)
    reg_deg: float = 0.0
    reg_lag: float = 1.0            # the registration flips uniform 0..reg_lag frame periods late
    exposure_s: float = 0.004       # each frame the mean of the scene over this, centred on its capture time
    q_per_rad: float = 3.0
    L: float = 20.0
    tip: float = 5.0
    depth: float = 45.0
    focal: float = 600.0
    spread: float = 0.0             # transition after a reversal: play widths B (1 + spread u), u in [-1, 1]

    def B(self, q):
        """True play width at actuator position q (mm)."""
        q = np.asarray(q, float)
        return self.b_lo + (self.b_hi - self.b_lo) * np.exp(-((q - self.b_qc) / self.b_w) ** 2)


def _ramp(r: Rendering, t: np.ndarray) -> np.ndarray:
    """Slow triangle over [ramp_lo + swing, ramp_hi - swing]: up for the first half, down after."""
    lo, hi = r.ramp_lo + r.swing_mm, r.ramp_hi - r.swing_mm
    ph = t / r.duration_s
    return lo + (hi - lo) * np.where(ph < 0.5, 2 * ph, 2 - 2 * ph)


def actuator(r: Rendering) -> tuple[np.ndarray, np.ndarray]:
    """Encoder time (N,) and actuator position q (N,), mm."""
    t = np.arange(0.0, r.duration_s, 1.0 / ENC_HZ)
    base = _ramp(r, t)
    P = r.swing_period_s
    if r.shape == "sine":
        off = r.swing_mm * np.sin(np.pi * t / P)
    elif r.shape == "triangle":
        leg = r.swing_s  # constant speed 2 swing / leg
        ph = np.mod(t / leg, 2.0)
        off = r.swing_mm * np.where(ph < 1.0, -1 + 2 * ph, 3 - 2 * ph)
    elif r.shape == "swings":
        k = np.floor(t / P)
        s_now = np.where(np.mod(k, 2) == 0, 1.0, -1.0)
        d = t - k * P  # time since this period's swing began
        x = np.clip(d / r.swing_s, 0.0, 1.0)
        smooth = 0.5 - 0.5 * np.cos(np.pi * x)  # raised cosine from the previous side to this one
        off = r.swing_mm * (-s_now + 2 * s_now * smooth)
    else:
        raise ValueError(f"unknown shape {r.shape!r}")
    return t, base + off


def play(q: np.ndarray, width: np.ndarray) -> np.ndarray:
    """Play centre z: stays unless q is further than width/2 from it (sample by sample)."""
    z = np.empty(q.size)
    z[0] = q[0]
    h = 0.5 * width
    for i in range(1, q.size):
        zi = z[i - 1]
        if q[i] - zi > h[i]:
            zi = q[i] - h[i]
        elif zi - q[i] > h[i]:
            zi = q[i] + h[i]
        z[i] = zi
    return z


def play_spread(q: np.ndarray, width: np.ndarray, spread: float, block: int = 4096) -> np.ndarray:
    """Mean of the centres of plays of widths width * (1 + spread u), u on SPREAD_NODES, each
    starting at q[0] as play() does: one loop over time, numpy over the nodes."""
    f = 1.0 + spread * SPREAD_NODES
    out = np.empty(q.size)
    zn = np.full(f.size, float(q[0]))
    for a in range(0, q.size, block):
        b = min(a + block, q.size)
        h = 0.5 * width[a:b, None] * f[None, :]
        lo = q[a:b, None] - h
        hi = q[a:b, None] + h
        Z = np.empty((b - a, f.size))
        for i in range(b - a):
            if a + i > 0:  # the first sample is the start state, as in play()
                np.maximum(zn, lo[i], out=zn)
                np.minimum(zn, hi[i], out=zn)
            Z[i] = zn
        out[a:b] = Z.mean(axis=1)
    return out


def ringing(c: np.ndarray, r: Rendering) -> np.ndarray:
    """Tip mode driven by the bending's acceleration (base excitation); rad, (N,). Exact
    discretisation of the 2nd-order system with the acceleration held over each sample."""
    if r.ring_hz <= 0:
        return np.zeros(c.size)
    dt = 1.0 / ENC_HZ
    w = 2 * np.pi * r.ring_hz
    A = np.array([[0.0, 1.0], [-w * w, -2 * r.ring_zeta * w]])
    # matrix exponential by eigen-decomposition (distinct eigenvalues for zeta < 1)
    lam, V = np.linalg.eig(A)
    Ad = np.real(V @ np.diag(np.exp(lam * dt)) @ np.linalg.inv(V))
    Bd = np.real(V @ np.diag((np.exp(lam * dt) - 1) / lam) @ np.linalg.inv(V)) @ np.array([0.0, 1.0])
    acc = np.gradient(np.gradient(c, dt), dt)
    x = np.zeros(2)
    out = np.empty(c.size)
    for i in range(c.size):
        x = Ad @ x + Bd * (-acc[i])
        out[i] = x[0]
    px_per_rad = r.focal / r.depth * (r.L / 2 + r.tip)  # near straight
    return out * (r.ring_px / px_per_rad) / max(float(np.abs(out).max()), 1e-12)


def direction(z: np.ndarray) -> np.ndarray:
    """Held sign of z's motion (+1 before any motion)."""
    dz = np.diff(z, prepend=z[0])
    s = np.where(np.abs(dz) > 1e-12, np.sign(dz), 0.0)
    idx = np.maximum.accumulate(np.where(s != 0, np.arange(s.size), 0))
    out = s[idx]
    out[out == 0] = 1.0
    return out


def project(c: np.ndarray, rot_rad: np.ndarray, r: Rendering) -> tuple[np.ndarray, np.ndarray]:
    """Marker (u, v) px of the tip for bending c (rad), camera rotated by rot_rad about its y."""
    cs = np.where(np.abs(c) < 1e-9, 1e-9, c)
    x = r.L * (1 - np.cos(cs)) / cs + r.tip * np.sin(c)
    zt = r.L * np.sin(cs) / cs + r.tip * np.cos(c)
    X, Y, Z = x, -(zt - 15.0), np.full(np.shape(x), r.depth)
    X, Z = np.cos(rot_rad) * X + np.sin(rot_rad) * Z, -np.sin(rot_rad) * X + np.cos(rot_rad) * Z
    return 360.0 + r.focal * X / Z, 288.0 + r.focal * Y / Z


def render(r: Rendering) -> dict:
    """Everything: encoder t, q; frame stamps t_f (encoder clock) and u, v px; the truth
    (t_stop, t_onset on the scene clock, per reversal of z); z the driving play centre (the
    mean over the spread's plays when spread > 0)."""
    if not 0.0 <= r.spread <= 0.9:
        raise ValueError(f"spread must be in [0, 0.9], not {r.spread!r}")
    rng = np.random.default_rng(r.seed)
    t, q = actuator(r)
    if r.spread == 0:
        z = play(q, r.B(q))
    else:
        z = play_spread(q, r.B(q), float(r.spread))
    c = z / r.q_per_rad
    c = c + ringing(c, r)
    dz = direction(z)
    flips = np.nonzero(np.diff(dz))[0] + 1
    T = 1.0 / r.fps
    sign = np.full(t.size, dz[0])
    for i in flips:  # the registration follows the distal direction, a little late
        j = np.searchsorted(t, t[i] + r.reg_lag * rng.uniform(0.0, T))
        sign[j:] = dz[i]
    n = int((t[-1] - 0.5 - 0.2) / T)
    tcap = 0.5 + np.arange(n) * T + rng.uniform(-r.jitter, r.jitter, n) * T
    # the exposure centred on the capture time, sampled at least every encoder sample (4 nodes at least)
    sub = np.linspace(-0.5 * r.exposure_s, 0.5 * r.exposure_s, max(4, int(np.ceil(r.exposure_s * ENC_HZ))))
    tc = tcap[:, None] + sub[None, :]
    u, v = project(np.interp(tc, t, c), np.radians(r.reg_deg) * np.interp(tc, t, sign), r)
    u = u.mean(axis=1) + rng.normal(0.0, r.noise_px, n)
    v = v.mean(axis=1) + rng.normal(0.0, r.noise_px, n)
    return {"t_enc": t, "q": q, "t_f": tcap + r.delay_s, "u": u, "v": v, "t_onset": t[flips],
            "z": z, "spread": float(r.spread)}


def write(r: Rendering, folder: Path) -> dict:
    """Render and write a playscope-session/1 folder; returns render()'s dict."""
    d = render(r)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    meta = {"format": "playscope-session/1", "actuator": {"unit": "mm"}, "distal": {"kind": "image"},
            "robot": {"model": "constant_curvature", "bend_length_mm": r.L, "tip_length_mm": r.tip,
                      "q_per_rad": r.q_per_rad},
            "camera": {"width": 720, "height": 576, "fps": r.fps,
                       "K": [[r.focal, 0.0, 360.0], [0.0, r.focal, 288.0], [0.0, 0.0, 1.0]], "dist": [0.0] * 5},
            "hand_eye": {"R": [[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]], "t_mm": [0.0, 15.0, r.depth]},
            "source": "bench/swing_render.py", "rendering": asdict(r)}
    if r.spread == 0:  # no spread: the session.json of before the option, byte for byte
        del meta["rendering"]["spread"]
    if r.delay_cfg_s is not None:
        meta["t_delay_s"] = r.delay_cfg_s
    (folder / "session.json").write_text(json.dumps(meta, indent=1))
    with open(folder / "encoder.csv", "w") as f:
        f.write("t_s,q\n")
        f.writelines(f"{a:.6f},{b:.7f}\n" for a, b in zip(d["t_enc"], d["q"]))
    with open(folder / "marker.csv", "w") as f:
        f.write("t_s,u_px,v_px\n")
        f.writelines(f"{a:.6f},{b:.4f},{c:.4f}\n" for a, b, c in zip(d["t_f"], d["u"], d["v"]))
    return d
