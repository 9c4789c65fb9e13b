"""SIMULATION ONLY: a simulated instrument that follows a board's encoder stream, seen by a
simulated camera (`playscope run-insitu --sim-plant`), and the rendering of a board's
excitation to a video file (the camera path of run-insitu, tested without a camera).

Kept out of the product's device code: the device link only sees an object with
push(t_us, q) and frames(t_board_us), like a camera it sees a VideoCapture.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..fit import model as M


@dataclass
class SimPlantConfig:
    """SIMULATED instrument for --sim-plant: the simulator's "ideal" preset (playscope.sim:
    B(q) = base + peak exp(-((q - centre)/sigma)^2) mm, f_remain, constant curvature, pinhole
    camera with distortion), the board's default camera timing (25 Hz, t_delay 80 ms, as
    onset_default_config), a green disc of marker_radius_px drawn anti-aliased on a grey
    noisy background. time_scale: the virtual board's clock runs this much faster than the
    wall clock; exc: the board's excitation "Q0:Q1:AMP:ADV:V" (mm, mm/s)."""

    seed: int = 0
    fps: float = 25.0
    t_delay_s: float = 0.08
    marker_radius_px: float = 9.0
    time_scale: float = 4.0
    exc: str = "-3:3:1.6:0.4:1.0"
    sim_overrides: dict = field(default_factory=dict)


class SimPlant:
    """SIMULATION ONLY: a tendon-driven instrument whose actuator follows the board's streamed
    encoder samples, seen by a simulated camera. push(t_us, q) feeds (N,) board samples (q in
    mm); frames(t_board_us) yields (t_us, BGR frame) for every frame time k / fps the encoder
    stream has passed; a frame stamped t shows the tip at t - t_delay (acquisition delay)."""

    def __init__(self, cfg: SimPlantConfig | None = None):
        import cv2

        from ..fit import model
        from .core import preset

        self.cfg = cfg or SimPlantConfig()
        self.sim = preset("ideal", seed=self.cfg.seed, fps=self.cfg.fps, t_delay_s=self.cfg.t_delay_s,
                          **self.cfg.sim_overrides)
        self.B, self.f = self.sim.B_fn(), self.sim.f_fn()
        self.im = model.ImageModel(self.sim.robot(), self.sim.camera(), self.sim.hand_eye())
        # z_up/z_down (eq. 2 reindexed) tabulated once on a 0.5 um grid: the per-sample play
        # update is then two interpolations, fast enough for a board clock several times
        # real time (the bisection per batch of model.z_up costs ~3 ms).
        self.qg = np.linspace(-12.0, 12.0, 48001)
        self.zu_g, self.zd_g = model.z_up(self.qg, self.B), model.z_down(self.qg, self.B)
        self.rng = np.random.default_rng(self.cfg.seed)
        self.t_us = np.empty(0, np.int64)
        self.zs = np.empty(0)
        self.z = None
        self.period_us = int(round(1e6 / self.cfg.fps))
        self.next_us = self.period_us
        self.delay_us = int(round(self.cfg.t_delay_s * 1e6))
        W, H = self.sim.width, self.sim.height
        # A bank of noisy grey backgrounds, cycled: drawing fresh noise per frame costs ~10 ms.
        base = np.full((H, W, 3), (90, 100, 110), np.uint8)
        self.bank = [cv2.add(base, self.rng.integers(0, 12, base.shape, dtype=np.uint8)) for _ in range(16)]
        self.k = 0

    def push(self, t_us: np.ndarray, q: np.ndarray) -> None:
        q = np.asarray(q, float)
        if q.min() < self.qg[0] or q.max() > self.qg[-1]:
            raise ValueError(f"sim plant: q outside [{self.qg[0]:g}, {self.qg[-1]:g}] mm")
        zu, zd = np.interp(q, self.qg, self.zu_g), np.interp(q, self.qg, self.zd_g)
        z = M.play_on_edges(zu, zd, float(q[0]) if self.z is None else self.z)  # eq. 3
        self.z = float(z[-1])
        self.t_us = np.concatenate([self.t_us[-4000:], np.asarray(t_us, np.int64)])
        self.zs = np.concatenate([self.zs[-4000:], z])

    def tip_px(self, t_us: float) -> tuple[float, float]:
        """Marker (u, v) px at board time t_us (eqs. 2, 6: c = f_remain(z), Q = h(g(c)))."""
        z = float(np.interp(t_us, self.t_us, self.zs))
        u, v = self.im(self.f(np.array([z])))[0]
        return float(u), float(v)

    def truth_B(self, q):
        """The simulated instrument's true play width B(q) (mm) at q (any shape, mm)."""
        return self.B(q)

    def render(self, u: float, v: float) -> np.ndarray:
        """One (H, W, 3) uint8 BGR frame with the marker centred at (u, v) px (sub-pixel)."""
        import cv2

        img = self.bank[self.k % len(self.bank)].copy()
        self.k += 1
        s = 16  # cv2 draws with 4 fractional bits: sub-pixel centre
        cv2.circle(img, (round(u * s), round(v * s)), round(self.cfg.marker_radius_px * s), (60, 200, 60),
                   -1, cv2.LINE_AA, 4)
        return img

    def frames(self, t_board_us: int):
        """Yield (t_us, frame) for each camera frame due up to board time t_board_us (us): the
        scene t_delay before the frame's time stamp t_us, as the board's camera delivers it."""
        while self.t_us.size and self.next_us <= t_board_us:
            t = self.next_us
            self.next_us += self.period_us
            ta = t - self.delay_us
            if ta < self.t_us[0]:
                continue  # before the stream began: nothing to show yet
            yield t, self.render(*self.tip_px(ta))


def excitation_q(exc: str, rate_hz: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """The board's excitation "Q0:Q1:AMP:ADV:V" (mm, mm/s) from its start, computed by the
    firmware's own exc_step (firmware/core/exc.h, through cffi) at rate_hz:
    (t_us (N,) int64 from 0, q (N,) mm). Ends when the trajectory is done."""
    from ..base.native import core, from_q16, to_q16

    ffi, lib = core()
    q0, q1, amp, adv, v = (float(x) for x in exc.split(":"))
    cfg = ffi.new("exc_config_t *")
    cfg.q_start_q16, cfg.q_end_q16 = int(to_q16(q0)), int(to_q16(q1))
    cfg.amplitude_q16, cfg.advance_q16 = int(to_q16(amp)), int(to_q16(adv))
    cfg.v_q32 = int(v / rate_hz * 2**32)
    cfg.return_sweep = True
    e = ffi.new("exc_t *")
    st = lib.exc_init(e, cfg)
    if st != lib.EXC_OK:
        raise ValueError(f"excitation {exc!r} refused by exc_init (status {st})")
    rev = ffi.new("bool *")
    q = []
    while not lib.exc_done(e):
        q.append(lib.exc_step(e, rev))
    q.append(lib.exc_step(e, rev))
    t_us = (np.arange(len(q), dtype=np.int64) * 1e6 / rate_hz).astype(np.int64)
    return t_us, from_q16(np.array(q, np.int64))


def render_excitation_video(path, exc: str, cfg: SimPlantConfig | None = None, lead_s: float = 0.0,
                            tail_s: float = 1.0) -> dict:
    """Write the SIMULATED instrument of SimPlant running the excitation `exc` as a video file
    (MJPG AVI at cfg.fps): frame k is the camera's image at k / fps after the excitation starts
    (the tip as it was t_delay earlier, eq. 1's delay), preceded by lead_s of the tip at rest.
    What `playscope run-insitu --video FILE` then reads as if it were a camera. Returns
    {"frames", "duration_s", "plant"} (the plant holds the truth, plant.truth_B)."""
    from ..io.videofile import video_writer

    plant = SimPlant(cfg)
    t_us, q = excitation_q(exc)
    t_end = int(t_us[-1] + tail_s * 1e6)
    t_us = np.append(t_us, t_end)
    q = np.append(q, q[-1])
    plant.push(t_us, q)
    fps = plant.cfg.fps
    n_lead = int(round(lead_s * fps))
    n = int(t_end / 1e6 * fps) + 1
    W, H = plant.sim.width, plant.sim.height
    with video_writer(path, fps, (W, H)) as vw:
        u0, v0 = plant.tip_px(0)
        for _ in range(n_lead):
            vw.write(plant.render(u0, v0))
        for k in range(n):
            ta = k * 1e6 / fps - plant.delay_us
            vw.write(plant.render(*plant.tip_px(max(ta, 0.0))))
    return {"frames": n_lead + n, "duration_s": (n_lead + n) / fps, "plant": plant}


NO_PLANT = ("no plant: the session records no simulator parameters (a real recording); "
            "run the commands on the robot and track the result instead")


def session_plant(s):
    """A plant q(t) -> c(t) deg from the simulator parameters a simulated session records in
    session.json, or (None, reason) for a real recording: what `evaluate` runs its open-loop
    compensation test through. Lives with the simulator so that the product never imports it."""
    from .core import SimConfig, transmission
    from .effects import EffectSet

    from ..base.errors import InputError
    from .config_check import check_config

    cfg_d = s.meta.get("simulator") if s.meta else None
    if not cfg_d:
        return None, NO_PLANT
    where = (s.path / "session.json") if s.path is not None else "session.json"
    if not isinstance(cfg_d, dict):
        raise InputError(where, f"key simulator: expected an object (the simulator's parameters), got "
                         f"{type(cfg_d).__name__}")
    try:  # the same check as simulate --config's: each key named with what it must be
        check_config(cfg_d, where)
    except InputError as e:
        raise InputError(where, e.message.replace("key ", "key simulator.", 1)) from None
    cfg = SimConfig.from_json(cfg_d)
    blind = "effects" not in cfg_d
    eff = EffectSet({k: dict(v) for k, v in cfg.effects.items()})

    def plant(t, q):
        return transmission(cfg, t, q, eff, np.random.default_rng(cfg.seed))["c_deg"]

    note = "simulator truth model from session.json" + (" (blind session: effects unknown, left out)" if blind else "")
    return plant, note
