"""render_c: an independent renderer of image sessions (`playscope-session/1`) for one tendon-driven
bending DOF with pure backlash, written apart from playscope (it never read the estimator, the
project's simulator or the other renderers) and using numpy and the Python standard library only.
It models an actuator log q(t) at 1 kHz (encoder counts of 0.2 um) following the paper's slow
ramp over about [-2, 2] mm with swings, a sine or a constant-speed triangle on top; a cable
carrier x that follows q through a play (dead band) of total width B(q) (a smooth sigmoid-plus-
off-centre-bump shape per seed, rescaled to [b_min_mm, b_max_mm] over [-2, 2] mm); a mildly
cubic, offset, gain-mismatched map from x to the bending angle; a constant-curvature section
plus a rigid tip carrying the marker, seen side-on by a pinhole camera ~45 mm away; optionally a
lightly damped tip mode driven by the bending acceleration (so it rings at every take-up and
every stop) and a hand-eye registration that flips by +-reg_deg about a camera axis with the
distal direction of motion (within one frame of the reversal); a short exposure average,
jittered capture times, Gaussian pixel noise and a true delay between capture and stamp. The
written robot/hand-eye description is the nominal (coarse) one, not the truth. The truth it
exposes: `Spec.B(q)` (the play width in mm at actuator position q), `Spec.delay_s` (stamp minus
capture time), and, in the dict `write` returns, the carrier, angle, flip times and capture times.

Optional transition after each reversal (`Spec.spread` = s in [0, 0.9]; 0, the default, is the
single play above, bit for bit): a Prandtl-Ishlinskii spread of play widths. The carrier x is
then the mean of 41 plays of total widths B(q) (1 + s u), u = linspace(-1, 1, 41), equal weights,
each starting where the single play starts; after a reversal x starts moving once q has travelled
(1 - s) B and is fully dragged after (1 + s) B. `Spec.B` (and the returned `B_q`) stays the centre
width B; the returned dict carries `spread`.
"""

from __future__ import annotations

import functools
import json
import math
import os
from dataclasses import asdict, dataclass

import numpy as np

FORMAT = "playscope-session/1"
ENC_DT = 0.001            # encoder period, s
ENC_COUNT_MM = 0.0002     # encoder resolution, mm
Q_PER_RAD_NOM = 3.0       # written f_coarse, mm/rad
BEND_NOM, TIP_NOM = 20.0, 5.0
WIDTH, HEIGHT = 720, 576
TRAVEL = 2.0              # q stays within about +-TRAVEL mm
SPREAD_NODES = np.linspace(-1.0, 1.0, 41)   # play widths B (1 + spread u), equal weights


@functools.lru_cache(maxsize=256)
def _b_shape(seed: int) -> tuple:
    """The B(q) shape parameters: the first draws of default_rng(seed) (write() repeats them)."""
    g = np.random.default_rng(seed)
    return _draw_shape(g)


def _draw_shape(g) -> tuple:
    a = float(g.uniform(0.3, 0.7))                       # weight of the monotone part
    sgn = 1.0 if g.uniform() < 0.5 else -1.0             # rising or falling
    qs = float(g.uniform(-0.8, 0.8))                     # sigmoid centre
    ws = float(g.uniform(0.5, 1.0))                      # sigmoid width
    qb = float(g.uniform(0.5, 1.3)) * (1.0 if g.uniform() < 0.5 else -1.0)   # bump, off centre
    wb = float(g.uniform(0.35, 0.7))
    grid = np.linspace(-TRAVEL, TRAVEL, 2001)
    h = _h(grid, (a, sgn, qs, ws, qb, wb, 0.0, 1.0))
    return (a, sgn, qs, ws, qb, wb, float(h.min()), float(h.max()))


def _h(q, p):
    a, sgn, qs, ws, qb, wb, _lo, _hi = p
    return a * 0.5 * (1.0 + np.tanh(sgn * (q - qs) / ws)) + (1.0 - a) * np.exp(-0.5 * ((q - qb) / wb) ** 2)


@dataclass
class Spec:
    name: str
    seed: int
    fps: float = 25.0
    jitter_frac: float = 0.25
    excitation: str = "swings"
    swing_mm: float = 0.45
    swing_time_s: float = 0.24
    swing_period_s: float = 1.5
    duration_s: float = 120.0
    noise_px: float = 0.12
    delay_s: float = 0.08
    delay_cfg_s: float | None = 0.08
    b_min_mm: float = 0.12
    b_max_mm: float = 0.30
    tip_hz: float = 0.0
    tip_zeta: float = 0.08
    tip_px: float = 6.0
    reg_axis: str = "y"
    reg_deg: float = 0.0
    spread: float = 0.0           # transition after a reversal: play widths B (1 + spread u), u in [-1, 1]

    def B(self, q):
        """True play width (mm, total) at actuator position q (mm); constant beyond +-2 mm."""
        p = _b_shape(int(self.seed))
        qq = np.clip(np.asarray(q, dtype=float), -TRAVEL, TRAVEL)
        g = (_h(qq, p) - p[6]) / (p[7] - p[6])
        return self.b_min_mm + (self.b_max_mm - self.b_min_mm) * np.clip(g, 0.0, 1.0)


# ----------------------------------------------------------------------------- excitation

def _minjerk(s):
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def _q_of_t(sp: Spec, ph: float):
    """The true actuator position as a function of time (vectorised, closed form)."""
    D = float(sp.duration_s)
    A = max(TRAVEL - sp.swing_mm, 0.5)
    S = float(sp.swing_mm)
    kind = sp.excitation

    def ramp(t):
        return -A * np.cos(2.0 * np.pi * t / D)

    if kind == "swings":
        P, T = float(sp.swing_period_s), min(float(sp.swing_time_s), 0.9 * float(sp.swing_period_s))
        t0 = ph * P

        def osc(t):
            k = np.floor((t - t0) / P)
            tau = (t - t0 - k * P) / T
            frm = np.where(k.astype(np.int64) % 2 == 0, -1.0, 1.0)
            s = frm - 2.0 * frm * _minjerk(tau)
            return S * np.where(k < 0, -1.0, s)
    elif kind == "sine":
        P = 2.0 * float(sp.swing_period_s)

        def osc(t):
            return S * np.sin(2.0 * np.pi * (t / P + ph))
    elif kind == "triangle":
        leg = float(sp.swing_time_s)
        tc = min(0.01, leg / 4.0)                     # parabolic corner: a servo cannot reverse at once
        Ap = S / (1.0 - tc / (2.0 * leg))             # so the rounded peaks reach +-S
        V = 2.0 * Ap / leg
        t0 = ph * 2.0 * leg

        def osc(t):
            u = (t - t0) / leg
            k = np.floor(u)
            d = (u - k) * leg                         # time since corner k
            sgn = np.where(k.astype(np.int64) % 2 == 0, 1.0, -1.0)   # corner k even: bottom
            lin = sgn * (-Ap + V * d)
            # blend near the corner at the start (d small) and at the end (leg - d small)
            e = leg - d
            near0 = d < tc / 2.0
            near1 = e < tc / 2.0
            c0 = sgn * (-Ap + V * (d * d / tc + tc / 4.0))
            c1 = sgn * (Ap - V * (e * e / tc + tc / 4.0))
            return np.where(near0, c0, np.where(near1, c1, lin))
    else:
        raise ValueError(f"unknown excitation {kind!r}")
    return lambda t: ramp(np.asarray(t, float)) + osc(np.asarray(t, float))


# ----------------------------------------------------------------------------- geometry

def _rot(axis, ang):
    axis = np.asarray(axis, float)
    axis = axis / np.linalg.norm(axis)
    x, y, z = axis
    K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + math.sin(ang) * K + (1 - math.cos(ang)) * K @ K


def _tip_point(c, L, Lt):
    """Marker position (base frame, mm) at the end of a constant-curvature section of length L
    bent by c rad in the base x-z plane, plus a rigid tip Lt."""
    c = np.asarray(c, float)
    small = np.abs(c) < 1e-6
    cs = np.where(small, 1.0, c)
    px = np.where(small, L * c / 2.0, L * (1.0 - np.cos(c)) / cs)
    pz = np.where(small, L * (1.0 - c * c / 6.0), L * np.sin(c) / cs)
    return np.stack([px + Lt * np.sin(c), np.zeros_like(c), pz + Lt * np.cos(c)], axis=-1)


def _project(Pc, K):
    X, Y, Z = Pc[..., 0], Pc[..., 1], Pc[..., 2]
    u = K[0, 0] * X / Z + K[0, 1] * Y / Z + K[0, 2]
    v = K[1, 1] * Y / Z + K[1, 2]
    return u, v


def _axis_rotate(Pc, axis: str, ang):
    """Rotate camera-frame points about a camera axis by per-point angles ang (rad)."""
    c, s = np.cos(ang), np.sin(ang)
    X, Y, Z = Pc[..., 0], Pc[..., 1], Pc[..., 2]
    if axis == "x":
        return np.stack([X, c * Y - s * Z, s * Y + c * Z], axis=-1)
    if axis == "y":
        return np.stack([c * X + s * Z, Y, -s * X + c * Z], axis=-1)
    if axis == "z":
        return np.stack([c * X - s * Y, s * X + c * Y, Z], axis=-1)
    raise ValueError(f"reg_axis must be x, y or z, not {axis!r}")


# ----------------------------------------------------------------------------- rendering

def _play(q, b):
    """Pure backlash: x stays while |q - x| <= b (half width), else is dragged at distance b."""
    ql, bl = q.tolist(), b.tolist()
    out = [0.0] * len(ql)
    x = None
    for i, (qi, bi) in enumerate(zip(ql, bl)):
        if x is None:
            x = qi - bi
        lo, hi = qi - bi, qi + bi
        if x < lo:
            x = lo
        elif x > hi:
            x = hi
        out[i] = x
    return np.asarray(out)


def _play_spread(q, b, spread, x0, block=4096):
    """The plays of half widths b (1 + spread u), u on SPREAD_NODES, all starting at x0 (as
    `_play` with x0 prepended at zero width): node states (N, 41), one loop over time, numpy
    over the nodes."""
    f = 1.0 + spread * SPREAD_NODES
    out = np.empty((len(q), f.size))
    xn = np.full(f.size, float(x0))
    for a in range(0, len(q), block):
        e = min(a + block, len(q))
        h = b[a:e, None] * f[None, :]
        lo = q[a:e, None] - h
        hi = q[a:e, None] + h
        for i in range(e - a):
            np.maximum(xn, lo[i], out=xn)
            np.minimum(xn, hi[i], out=xn)
            out[a + i] = xn
    return out


def _fftconv(a, h):
    n = len(a) + len(h) - 1
    m = 1 << (n - 1).bit_length()
    return np.fft.irfft(np.fft.rfft(a, m) * np.fft.rfft(h, m), m)[: len(a)]


def render(sp: Spec) -> dict:
    if sp.excitation not in ("swings", "sine", "triangle"):
        raise ValueError(f"unknown excitation {sp.excitation!r}")
    if sp.reg_axis not in ("x", "y", "z"):
        raise ValueError(f"reg_axis must be x, y or z, not {sp.reg_axis!r}")
    if sp.delay_s < 0 or not (0 <= sp.jitter_frac < 0.5) or sp.fps <= 0:
        raise ValueError("delay_s >= 0, 0 <= jitter_frac < 0.5 and fps > 0 are required")
    if not 0.0 <= sp.spread <= 0.9:
        raise ValueError(f"spread must be in [0, 0.9], not {sp.spread!r}")
    g = np.random.default_rng(int(sp.seed))
    _draw_shape(g)                                    # same draws as Spec.B
    # --- fixed-order draws, whatever the options (so switching an effect keeps the rest)
    ph = float(g.uniform())                           # excitation phase
    x_start = float(g.uniform(-1.0, 1.0))             # carrier start within the play
    k_true = Q_PER_RAD_NOM * float(g.uniform(0.9, 1.1))
    x_zero = float(g.uniform(-0.15, 0.15))            # carrier position of the straight section
    kappa = float(g.uniform(-0.08, 0.08))             # cubic term of x -> c
    L = BEND_NOM * float(g.uniform(0.97, 1.03))
    Lt = TIP_NOM * float(g.uniform(0.95, 1.05))
    f = float(g.uniform(570.0, 630.0))
    K = np.array([[f, 0.0, (WIDTH - 1) / 2.0 + g.uniform(-8, 8)],
                  [0.0, f * float(g.uniform(0.99, 1.01)), (HEIGHT - 1) / 2.0 + g.uniform(-8, 8)],
                  [0.0, 0.0, 1.0]])
    R0 = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])   # side-on view of x-z
    R_true = _rot(g.normal(size=3), math.radians(g.uniform(0.0, 6.0))) @ R0
    mid = np.array([0.0, 0.0, 0.8 * (L + Lt)])
    t_true = np.array([g.uniform(-1.5, 1.5), g.uniform(-1.5, 1.5), 45.0 + g.uniform(-3, 3)]) - R_true @ mid
    R_he = _rot(g.normal(size=3), math.radians(g.uniform(0.0, 0.7))) @ R_true   # written: coarse
    t_he = t_true + g.normal(0.0, 0.3, 3)
    exposure = float(g.uniform(0.002, 0.006))
    frame_phase = float(g.uniform())
    t_origin = round(float(g.uniform(0.0, 3600.0)), 3)  # the files' clock (any origin is allowed)
    g_jit, g_reg, g_noise = (np.random.default_rng(int(s)) for s in g.integers(0, 2**63 - 1, 3))

    # --- actuator and carrier on the encoder grid
    D = float(sp.duration_s)
    n_enc = int(round(D / ENC_DT)) + 1
    t_enc = np.arange(n_enc) * ENC_DT
    qf = _q_of_t(sp, ph)
    q = qf(t_enc)
    bh = 0.5 * sp.B(q)
    x0 = q[0] + x_start * float(bh[0])               # the carrier starts anywhere in the play
    if sp.spread == 0:
        xn = None
        x = _play(np.concatenate([[x0], q]), np.concatenate([[0.0], bh]))[1:]
    else:                                             # the spread's plays, x their mean
        xn = _play_spread(q, bh, float(sp.spread), x0)
        x = xn.mean(axis=1)

    def c_of_x(xx):
        z = (xx - x_zero) / k_true
        return z + kappa * z ** 3

    c = c_of_x(x)

    # --- tip mode: eta'' + 2 zeta w eta' + w^2 eta = -c'' (base-excited), gain to tip_px
    eta = np.zeros(n_enc)
    gain = 0.0
    if sp.tip_hz > 0 and sp.tip_px > 0:
        w = 2.0 * np.pi * sp.tip_hz
        z = min(max(sp.tip_zeta, 1e-4), 0.95)
        wd = w * math.sqrt(1.0 - z * z)
        th = np.arange(n_enc) * ENC_DT
        h = np.exp(-z * w * th) * np.sin(wd * th) / wd
        vel = np.diff(c) / ENC_DT
        dv = np.concatenate([[0.0], np.diff(vel), [0.0]])     # velocity change at each sample
        eta_u = -_fftconv(dv, h)
        # image excursion per rad of bending along the record
        Pc0 = _tip_point(c, L, Lt) @ R_true.T + t_true
        Pc1 = _tip_point(c + 1e-4, L, Lt) @ R_true.T + t_true
        u0, v0 = _project(Pc0, K)
        u1, v1 = _project(Pc1, K)
        J = np.hypot(u1 - u0, v1 - v0) / 1e-4
        ex = float(np.max(np.abs(eta_u) * J))
        if ex > 0:
            gain = sp.tip_px / ex
            eta = gain * eta_u

    # --- direction of the distal motion and registration flips
    dx = np.diff(x)
    mv = np.nonzero(np.abs(dx) > 1e-12)[0]
    dirs = np.sign(dx[mv])
    ch = np.nonzero(dirs[1:] != dirs[:-1])[0] + 1
    t_rev = t_enc[mv[ch]]                             # the tip starts moving the other way
    dir0 = float(dirs[0]) if len(dirs) else 1.0
    lags = g_reg.uniform(0.0, 1.0 / sp.fps, len(t_rev))
    ramps = g_reg.uniform(0.004, 0.012, len(t_rev))   # the instrument settles in its channel
    t_flip = t_rev + lags

    def reg_sign(t):
        n = np.searchsorted(t_flip, t, side="right")
        s_new = dir0 * np.where(n % 2 == 0, 1.0, -1.0)
        i = np.maximum(n - 1, 0)
        r = np.where(n > 0, (t - t_flip[i]) / ramps[i] if len(t_flip) else 1.0, 1.0)
        r = np.clip(r, 0.0, 1.0)
        blend = 0.5 - 0.5 * np.cos(np.pi * r)
        return -s_new + 2.0 * s_new * blend

    # --- frames: jittered capture, short exposure average, noise
    fp = 1.0 / sp.fps
    t_a, t_b = 0.5, D - 0.3
    n_f = int(math.floor((t_b - t_a) / fp))
    t_cap = t_a + (frame_phase + np.arange(n_f)) * fp
    t_cap = t_cap + g_jit.uniform(-sp.jitter_frac, sp.jitter_frac, n_f) * fp
    t_cap = t_cap[(t_cap > t_a) & (t_cap < t_b)]
    n_s = 7
    off = (np.arange(n_s) / (n_s - 1) - 0.5) * exposure
    ts = t_cap[:, None] + off[None, :]
    k = np.clip(np.floor(ts / ENC_DT).astype(np.int64), 0, n_enc - 1)
    qs = qf(ts)
    bs = 0.5 * sp.B(qs)
    if xn is None:
        xs = np.clip(x[k], qs - bs, qs + bs)          # exact play output within the encoder period
    else:                                             # the same, per play of the spread
        hs = bs[..., None] * (1.0 + float(sp.spread) * SPREAD_NODES)
        xs = np.clip(xn[k], qs[..., None] - hs, qs[..., None] + hs).mean(axis=-1)
        del xn
    frac = ts / ENC_DT - k
    k1 = np.minimum(k + 1, n_enc - 1)
    cs = c_of_x(xs) + eta[k] + (eta[k1] - eta[k]) * frac
    Pc = _tip_point(cs, L, Lt) @ R_true.T + t_true
    if sp.reg_deg != 0.0:
        Pc = _axis_rotate(Pc, sp.reg_axis, math.radians(sp.reg_deg) * reg_sign(ts))
    uu, vv = _project(Pc, K)
    u = uu.mean(axis=1) + g_noise.normal(0.0, sp.noise_px, len(t_cap))
    v = vv.mean(axis=1) + g_noise.normal(0.0, sp.noise_px, len(t_cap))
    t_f = t_cap + sp.delay_s

    q_rec = np.round(q / ENC_COUNT_MM) * ENC_COUNT_MM
    return dict(t_enc=t_enc + t_origin, q=q_rec, t_f=t_f + t_origin, u=u, v=v,
                t_capture=t_cap + t_origin, t_origin=t_origin, q_true=q, x=x, c=c, eta=eta,
                B_q=2.0 * bh, t_rev=t_rev + t_origin, t_flip=t_flip + t_origin, dir0=dir0,
                exposure_s=exposure, tip_gain=gain, delay_s=sp.delay_s, K=K, R_true=R_true,
                t_true=t_true, R_he=R_he, t_he=t_he, k_true=k_true, x_zero=x_zero, kappa=kappa,
                bend_length_mm=L, tip_length_mm=Lt, spread=float(sp.spread))


def _fmt_t(t):
    return [f"{x:.6f}" for x in t]


def write(spec: Spec, folder) -> dict:
    """Render `spec` and write the session folder (session.json, encoder.csv, marker.csv)."""
    r = render(spec)
    folder = os.fspath(folder)
    os.makedirs(folder, exist_ok=True)
    meta = {
        "format": FORMAT,
        "source": f"render_c {spec.name}",
        "actuator": {"unit": "mm", "q_source": "measured"},
        "distal": {"kind": "image"},
        "robot": {"model": "constant_curvature", "bend_length_mm": BEND_NOM,
                  "tip_length_mm": TIP_NOM, "q_per_rad": Q_PER_RAD_NOM},
        "camera": {"width": WIDTH, "height": HEIGHT, "fps": float(spec.fps),
                   "K": [[float(a) for a in row] for row in r["K"]], "dist": [0.0] * 5},
        "hand_eye": {"R": [[float(a) for a in row] for row in r["R_he"]],
                     "t_mm": [float(a) for a in r["t_he"]]},
    }
    if spec.delay_cfg_s is not None:
        meta["t_delay_s"] = float(spec.delay_cfg_s)
    with open(os.path.join(folder, "session.json"), "w") as fh:
        json.dump(meta, fh, indent=2)
        fh.write("\n")
    # the written values are the returned ones
    q_txt = [f"{x:.4f}" for x in r["q"]]
    r["q"] = np.array([float(s) for s in q_txt])
    with open(os.path.join(folder, "encoder.csv"), "w") as fh:
        fh.write("t_s,q\n")
        fh.write("".join(f"{a},{b}\n" for a, b in zip(_fmt_t(r["t_enc"]), q_txt)))
    tf_txt = _fmt_t(r["t_f"])
    u_txt = [f"{x:.5f}" for x in r["u"]]
    v_txt = [f"{x:.5f}" for x in r["v"]]
    r["t_f"] = np.array([float(s) for s in tf_txt])
    r["u"] = np.array([float(s) for s in u_txt])
    r["v"] = np.array([float(s) for s in v_txt])
    with open(os.path.join(folder, "marker.csv"), "w") as fh:
        fh.write("t_s,u_px,v_px\n")
        fh.write("".join(f"{a},{b},{c}\n" for a, b, c in zip(tf_txt, u_txt, v_txt)))
    r["spec"] = asdict(spec)
    return r
