"""Simulator core: robot (play of width B(q) then f_remain, eqs. 2-3, constant curvature g),
effects of playscope.sim.effects, camera (pinhole + distortion, hand-eye, delay, noise), and the
session it writes (playscope.io.session format, with truth.csv).

Units: q in mm of cable, c in deg, t in s, lengths in mm, image in px.
"""

from __future__ import annotations

import copy
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import simpson
from scipy.signal import lfilter

from ..fit import model as M
from ..io.session import Camera, HandEye, Robot, Session
from . import trajectories as T
from .effects import EFFECTS, EffectSet


# --------------------------------------------------------------------------- configuration
@dataclass
class SimConfig:
    """Everything the simulator needs; JSON round-trips through to_json/from_json.

    B: {"base", "peak", "centre", "sigma"} mm: B(q) = base + peak exp(-((q - centre)/sigma)^2).
    f: {"gain", "soft", "soft_width", "offset_deg"}: f_remain(z) = offset + gain deg(z/q_per_rad)
       (1 - soft exp(-(z/soft_width)^2)) -- a lower rate near straight when soft > 0 (paper Fig. 2).
    trajectory: {"kind": excitation|test|ellipse|random_walk, ...} (see make_trajectory).
    effects: {name: {param: value}} (playscope.sim.effects).
    """

    name: str = "custom"
    seed: int = 0
    distal_kind: str = "image"            # "image" (marker.csv) or "angle" (distal.csv)
    encoder_hz: float = 500.0
    q_per_rad: float = 3.0                # f_coarse: c [rad] = q / q_per_rad
    bend_length_mm: float = 20.0
    tip_length_mm: float = 5.0
    B: dict = field(default_factory=lambda: {"base": 0.35, "peak": 0.45, "centre": 0.0, "sigma": 0.8})
    f: dict = field(default_factory=lambda: {"gain": 1.0, "soft": 0.45, "soft_width": 1.0, "offset_deg": 0.0})
    width: int = 720
    height: int = 576
    fps: float = 25.0
    K: list = field(default_factory=lambda: [[380.0, 0, 360.0], [0, 380.0, 288.0], [0, 0, 1]])
    dist: list = field(default_factory=lambda: [-0.25, 0.08, 0.0, 0.0, 0.0])
    R: list = field(default_factory=lambda: np.eye(3).tolist())
    t_mm: list = field(default_factory=lambda: [0.0, 5.0, 10.0])
    t_delay_s: float = 0.08               # acquisition delay, declared in session.json
    marker_noise_px: float = 0.12         # paper V-D: still-marker noise < 0.15 px
    angle_noise_deg: float = 0.05         # angle sessions (EM tracker)
    angle_rate_hz: float = 100.0
    trajectory: dict = field(default_factory=lambda: {"kind": "excitation", "q_lo": -3.0, "q_hi": 3.0,
                                                      "amp": 1.4, "speed": None, "duration_s": 120.0,
                                                      "cycles": 2})
    effects: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return copy.deepcopy(asdict(self))

    @classmethod
    def from_json(cls, d: dict) -> "SimConfig":
        return cls(**copy.deepcopy(d))

    # Model pieces as callables (playscope.fit.model convention: arrays in, arrays out).
    def B_fn(self):
        b = self.B
        return lambda q: b["base"] + b["peak"] * np.exp(-((np.asarray(q, float) - b["centre"]) / b["sigma"]) ** 2)

    def f_fn(self):
        f, qpr = self.f, self.q_per_rad
        def fr(z):
            z = np.asarray(z, float)
            return f["offset_deg"] + f["gain"] * np.degrees(z / qpr) * (1 - f["soft"] * np.exp(-(z / f["soft_width"]) ** 2))
        return fr

    def robot(self) -> Robot:
        return Robot("constant_curvature", self.bend_length_mm, self.tip_length_mm, self.q_per_rad)

    def camera(self) -> Camera:
        return Camera(self.width, self.height, self.fps, np.array(self.K, float), np.array(self.dist, float))

    def hand_eye(self) -> HandEye:
        return HandEye(np.array(self.R, float), np.array(self.t_mm, float))


PRESETS: dict[str, dict] = {
    # STRAS-like instrument (paper V-A, V-D, Fig. 8): backlash much wider near straight, a low
    # rate near straight in f_remain, 25 Hz camera with 80 ms delay, and the smooth transition
    # after the play (paper V-F: "the transition movement between backlash and the envelope";
    # five play widths B(q)(1 +- 0.5 u), so the tip starts after 0.5 B and joins the envelope
    # after 1.5 B). The main job's default. The +-1.5 deg direction-dependent registration
    # error of section V-B is the Fig. 7 case (preset fig7), not Table I's (section V-F: there
    # the registration error acts on Qy, across the motion).
    "stras": {"name": "stras", "effects": {"smooth_transition": {"spread": 0.5}}},
    # Paper V-B / Fig. 7: constant 15 deg backlash, linear f, +-1.5 deg registration error,
    # bending velocity 15 deg/s.
    "fig7": {"name": "fig7", "B": {"base": float(np.radians(15) * 3.0), "peak": 0.0, "centre": 0.0, "sigma": 1.0},
             "f": {"gain": 1.0, "soft": 0.0, "soft_width": 1.0, "offset_deg": 0.0},
             "dist": [0.0, 0.0, 0.0, 0.0, 0.0], "marker_noise_px": 0.1,
             "trajectory": {"kind": "excitation", "q_lo": -2.6, "q_hi": 2.6, "amp": 1.6,
                            "speed": float(np.radians(15) * 3.0), "duration_s": 160.0},
             "effects": {"handeye_direction": {"delta_deg": 1.5}}},
    # No effect at all: the paper's model exactly (for tests and baselines).
    "ideal": {"name": "ideal"},
}


def preset(name: str, **overrides) -> SimConfig:
    """A named configuration (PRESETS) with keyword overrides (e.g. effects={...}, seed=3)."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
    d = SimConfig().to_json()
    d.update(copy.deepcopy(PRESETS[name]))
    d.update(overrides)
    return SimConfig.from_json(d)


# --------------------------------------------------------------------------- trajectories
def play_range(cfg: SimConfig) -> tuple[float, float]:
    """(B_low, B_high) actuator units: the play the camera sees taken up after a reversal, over
    the trajectory's [q_lo, q_hi] (what a user expects of the instrument; the simulator knows it
    exactly). That is B(q) itself, or with the smooth_transition effect the travel to the tip's
    first motion, (1 - spread) B(q): the onset detector times that, not the full width."""
    tr = cfg.trajectory
    b = cfg.B_fn()(np.linspace(tr["q_lo"], tr["q_hi"], 1201))
    spread = float(((cfg.effects or {}).get("smooth_transition") or {}).get("spread", 0.0))
    return float(b.min() * (1.0 - spread)), float(b.max())


def paced_speed(cfg: SimConfig) -> float:
    """The excitation's default swing speed, actuator units/s: the board's pacing rule
    (playscope.fit.pacing, firmware/core/exc.h) for cfg.fps and the play range of B(q), so the
    smallest play is taken up over EXC_PACE_FRAMES frames. Errors: ValueError from the rule."""
    from ..fit.pacing import swing_speed

    return swing_speed(*play_range(cfg), cfg.fps)


def make_trajectory(cfg: SimConfig) -> dict[str, np.ndarray]:
    """q(t) at cfg.encoder_hz for cfg.trajectory; returns {"t_s", "q"[, "translation_mm"]}."""
    tr = dict(cfg.trajectory)
    kind = tr.pop("kind")
    r = cfg.encoder_hz
    if kind == "excitation":
        speed = tr.get("speed")
        if speed is None:
            speed = paced_speed(cfg)
        t, q = T.excitation(tr["q_lo"], tr["q_hi"], tr["amp"], speed, tr["duration_s"], r,
                            tr.get("hold_s", 0.3), tr.get("cycles", 1))
    elif kind == "test":
        t, q = T.test_motion(tr["q_lo"], tr["q_hi"], tr["amp"], tr["speed"], tr["duration_s"], r, tr.get("hold_s", 1.0))
    elif kind == "random_walk":
        t, q = T.random_walk(tr["q_lo"], tr["q_hi"], tr["speed"], tr["duration_s"], r, cfg.seed, tr.get("corr_s", 1.5))
    elif kind == "ellipse":
        t, q, _, tz = T.ellipse_task(tr.get("a_mm", 8.0), tr.get("b_mm", 3.0), tr.get("period_s", 20.0),
                                     tr.get("cycles", 3), cfg.bend_length_mm, cfg.tip_length_mm, cfg.q_per_rad,
                                     tr.get("x0_mm", 0.0), r)
        return {"t_s": t, "q": q, "translation_mm": tz}
    else:
        raise ValueError(f"unknown trajectory kind {kind!r}")
    return {"t_s": t, "q": q}


# --------------------------------------------------------------------------- transmission
def play_asym(q: np.ndarray, B, alpha: float = 0.0, z0: float | None = None) -> np.ndarray:
    """Play operator centre z (eq. 3, playscope.fit.model convention) with direction-dependent lag:
    going up z + (1+alpha) B(z)/2 = q, going down z - (1-alpha) B(z)/2 = q. alpha = 0 is
    model.play_operator exactly. q: (N,) mm; returns z (N,) mm."""
    if alpha == 0.0:
        return M.play_operator(q, B, z0)
    zu = M.z_up(q, lambda z: (1 + alpha) * B(z))
    zd = M.z_down(q, lambda z: (1 - alpha) * B(z))
    return M.play_on_edges(zu, zd, float(q[0] if z0 is None else z0))


def stick_slip(c: np.ndarray, step: float) -> np.ndarray:
    """Hold c until the elastic configuration is ``step`` away, then slip to it. (N,) deg."""
    out = np.empty_like(c)
    held = float(c[0])
    for k in range(c.size):  # sequential hold state
        if abs(c[k] - held) >= step:
            held = float(c[k])
        out[k] = held
    return out


def lowpass(x: np.ndarray, tau_s: float, rate_hz: float) -> np.ndarray:
    """First-order low-pass (time constant tau_s) of a uniformly sampled signal, started at x[0]."""
    a = np.exp(-1.0 / (tau_s * rate_hz))
    y, _ = lfilter([1 - a], [1, -a], x, zi=[a * x[0]])
    return y


def distal_direction(c: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Sign of the last non-zero change of c (+1/-1), the direction of distal motion, held while
    still; +1 before the first motion. (N,)"""
    return M.held_direction(c, tol)


def transmission(cfg: SimConfig, t: np.ndarray, q: np.ndarray, eff: EffectSet,
                 rng: np.random.Generator) -> dict[str, np.ndarray]:
    """True configuration c(t) from q(t): play (eq. 3, with the play-stage effects), f_remain, then
    the distal-stage effects. t, q: (N,) at encoder rate. Returns {"z" mm, "c_deg", "c_elastic_deg"}."""
    B = cfg.B_fn()
    alpha = eff.get("asymmetric_backlash", "alpha")
    spread = eff.get("smooth_transition", "spread")
    if spread > 0:
        # Discrete Prandtl-Ishlinskii: equal weights, widths spread around B(q), mean width B.
        zs = [play_asym(q, (lambda r: (lambda x: r * B(x)))(1 + spread * u), alpha)
              for u in np.linspace(-1, 1, 5)]
        z = np.mean(zs, axis=0)
    else:
        z = play_asym(q, B, alpha)
    kr = eff.get("travel_relaxation", "kappa")
    if kr > 0:
        from ..fit.relax import Relaxation
        z = Relaxation(kr, eff.get("travel_relaxation", "lambda_q")).direct(z)
    c = cfg.f_fn()(z)
    w = eff.get("dead_zone", "width_deg")
    if w > 0:
        c0 = eff.get("dead_zone", "c0_deg")
        c = c - np.clip(c - c0, -w, w)
    kappa = eff.get("cable_elongation", "kappa")
    if kappa > 0:
        c = c + kappa * (lowpass(c, eff.get("cable_elongation", "tau_s"), cfg.encoder_hz) - c)
    c_el = c.copy()
    step = eff.get("stick_slip", "step_deg")
    if step > 0:
        c = stick_slip(c, step)
    c = c + eff.get("drift", "rate_deg_per_min") * t / 60.0
    amp = eff.get("breathing", "amp_deg")
    if amp > 0:
        c = c + amp * np.sin(2 * np.pi * t / eff.get("breathing", "period_s") + rng.uniform(0, 2 * np.pi))
    amp = eff.get("tissue_catch", "amp_deg")
    if amp > 0:
        rate = eff.get("tissue_catch", "rate_hz")
        flips = np.cumsum(rng.random(t.size) < rate / cfg.encoder_hz)
        level = np.where(flips % 2 == 0, 0.0, amp)
        c = c + lowpass(level, 0.1, cfg.encoder_hz)  # catches take ~0.1 s to set in
    return {"z": z, "c_deg": c, "c_elastic_deg": c_el}


# --------------------------------------------------------------------------- camera
def tip_position(c_deg: np.ndarray, L: float, l_tip: float, gamma: float = 0.0) -> np.ndarray:
    """Tip position (..., 3) mm in the base frame. gamma = 0: model.constant_curvature (g).
    gamma != 0: curvature kappa(s) = c/L (1 + gamma (2 s/L - 1)), same total bend c, integrated
    numerically along the arc (Simpson, 64 intervals)."""
    if gamma == 0.0:
        return M.constant_curvature(c_deg, L, l_tip)
    c = np.radians(np.asarray(c_deg, float))[..., None]
    s = np.linspace(0.0, L, 65)
    theta = c / L * (s + gamma * (s * s / L - s))
    x = simpson(np.sin(theta), x=s, axis=-1)
    z = simpson(np.cos(theta), x=s, axis=-1)
    c = c[..., 0]
    return np.stack([x + l_tip * np.sin(c), np.zeros_like(x), z + l_tip * np.cos(c)], axis=-1)


def rot_y(deg: np.ndarray) -> np.ndarray:
    """Rotations about y, (..., 3, 3), angles in deg."""
    a = np.radians(np.asarray(deg, float))
    ca, sa, o, i = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([ca, o, sa], -1), np.stack([o, i, o], -1), np.stack([-sa, o, ca], -1)], -2)


def observe_image(cfg: SimConfig, truth: dict, eff: EffectSet, rng: np.random.Generator,
                  with_noise: bool = True) -> dict[str, np.ndarray]:
    """Marker track one row per frame: stamped times t_k = k/fps, scene captured at
    t_k - t_delay_s - delay_extra + N(0, jitter). Returns {"t_s", "u_px", "v_px", "t_capture_s", "c_deg"}."""
    t, c = truth["t_s"], truth["c_deg"]
    # The camera runs on its own clock: a random phase of its frames against the encoder's.
    phase = rng.uniform(0, 1.0 / cfg.fps)
    tk = np.arange(np.ceil((t[0] + 0.2) * cfg.fps), np.floor(t[-1] * cfg.fps)) / cfg.fps + phase
    tcap = tk - cfg.t_delay_s - eff.get("camera_delay", "delay_s")
    jit = eff.get("camera_delay", "jitter_s")
    if jit > 0:
        tcap = tcap + rng.normal(0, jit, tk.size)
    tcap = np.clip(tcap, t[0], t[-1])
    ck = np.interp(tcap, t, c)
    P = tip_position(ck, cfg.bend_length_mm, cfg.tip_length_mm, eff.get("nonconstant_curvature", "gamma"))
    if "translation_mm" in truth:
        P[:, 2] += np.interp(tcap, t, truth["translation_mm"])
    delta = eff.get("handeye_direction", "delta_deg")
    R, tt = np.array(cfg.R, float), np.array(cfg.t_mm, float)
    if delta != 0:
        s = np.interp(tcap, t, truth["dir"])
        s = np.where(s >= 0, 1.0, -1.0)
        Ry = rot_y(s * delta)
        Pc = np.einsum("nij,nj->ni", Ry, P @ R.T + tt)
        R_, t_ = np.eye(3), np.zeros(3)
    else:
        Pc, R_, t_ = P, R, tt
    dist = np.array(cfg.dist, float)
    dist[0] += eff.get("lens_distortion", "dk1")
    Q = M.project(Pc, R_, t_, np.array(cfg.K, float), dist)
    if with_noise:
        Q = Q + rng.normal(0, cfg.marker_noise_px, Q.shape)
    lost = ~np.all(np.isfinite(Q), 1) | (Q[:, 0] < 0) | (Q[:, 0] > cfg.width - 1) | (Q[:, 1] < 0) | (Q[:, 1] > cfg.height - 1)
    Q[lost] = np.nan
    return {"t_s": tk, "u_px": Q[:, 0], "v_px": Q[:, 1], "t_capture_s": tcap, "c_deg": ck}


def observe_angle(cfg: SimConfig, truth: dict, eff: EffectSet, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Angle-sensor record (EM tracker-like) at cfg.angle_rate_hz with the camera-stage timing
    effects (delay/jitter) and noise; hand-eye and lens effects do not apply to such a sensor."""
    t, c = truth["t_s"], truth["c_deg"]
    tk = np.arange(np.ceil(t[0] * cfg.angle_rate_hz), np.floor(t[-1] * cfg.angle_rate_hz) + 1) / cfg.angle_rate_hz
    tcap = tk - eff.get("camera_delay", "delay_s") - (cfg.t_delay_s or 0.0)
    jit = eff.get("camera_delay", "jitter_s")
    if jit > 0:
        tcap = tcap + rng.normal(0, jit, tk.size)
    ck = np.interp(np.clip(tcap, t[0], t[-1]), t, c) + rng.normal(0, cfg.angle_noise_deg, tk.size)
    return {"t_s": tk, "c_deg": ck}


# --------------------------------------------------------------------------- session
def simulate(cfg: SimConfig, blind: bool = False) -> Session:
    """Run the simulator; returns an in-memory Session (write it with session.write_session).

    The session's camera, hand-eye and t_delay_s are the nominal (calibrated) ones; the effects
    make the truth differ from them. truth.csv columns: t_s, c_deg (true bending), z_mm (play
    centre, eq. 3), B_mm (true width at q), dir (distal motion direction), c_elastic_deg (before
    stick-slip). blind=True leaves the effect list out of session.json (blind self-test).
    """
    from .config_check import check_config

    # the parameters session.json will record, checked as `evaluate` will read them back (a key
    # the simulator would ignore, such as a test trajectory's cycles, is refused here, not there)
    check_config(cfg.to_json(), "the simulator's configuration")
    rng = np.random.default_rng(cfg.seed)
    eff = EffectSet({k: dict(v) for k, v in cfg.effects.items()})
    for name in eff.on:
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}")
    traj = make_trajectory(cfg)
    t, q = traj["t_s"], traj["q"]
    tr = transmission(cfg, t, q, eff, rng)
    truth = {"t_s": t, "c_deg": tr["c_deg"], "z_mm": tr["z"], "B_mm": cfg.B_fn()(q),
             "dir": distal_direction(tr["c_deg"]), "c_elastic_deg": tr["c_elastic_deg"]}
    if "translation_mm" in traj:
        truth["translation_mm"] = traj["translation_mm"]
    meta: dict[str, Any] = {"source": "playscope simulate"}
    cj = cfg.to_json()
    if blind:
        cj.pop("effects")
    meta["simulator"] = cj
    s = Session(actuator_unit="mm", distal_kind=cfg.distal_kind, robot=cfg.robot(),
                encoder={"t_s": t, "q": q, "q_cmd": q.copy()}, camera=cfg.camera(), hand_eye=cfg.hand_eye(),
                t_delay_s=cfg.t_delay_s, truth=truth, meta=meta)
    if cfg.distal_kind == "image":
        obs = observe_image(cfg, truth, eff, rng)
        s.marker = {k: obs[k] for k in ("t_s", "u_px", "v_px")}
    else:
        s.distal = observe_angle(cfg, truth, eff, rng)
    return s
