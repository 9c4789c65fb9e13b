"""Base plant of the blind generator: a tendon with a clearance (backlash) of width B(q), a
bending map with a lower rate near straight, and an angle sensor (EM-tracker-like).

Deliberately not the simulator's or the diagnosis' formulas: the clearance edges are evaluated
at the actuator position q (x in [q - B(q)/2, q + B(q)/2]) instead of at the play output, B is a
Lorentzian bump over a floor, the bending map is c = c0 + g (x - s w tanh(x/w)) in deg, and the
sensor samples the tip on its own clock. An effect plugs in at one of the stages of `run`
(actuator, clearance, carrier, bend, sensor) through `variants.VARIANTS`.

Units: q, x in mm of cable; c in deg; t in s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...io.session import Robot, Session

STATE_HZ = 500.0      # state integration rate of the plant (the encoder rate)
DEG_PER_RAD = 57.29577951308232


@dataclass(frozen=True)
class Plant:
    """Base plant parameters (mm, deg, Hz). width(q) = b_floor + b_bump / (1 + ((q - q_c)/s_q)^2)."""

    b_floor: float = 0.40
    b_bump: float = 0.50
    q_c: float = 0.0
    s_q: float = 0.9
    gain: float = 1.0          # rate of c far from straight, relative to 1 rad per q_per_rad mm
    soft: float = 0.45         # relative loss of rate at straight (0..1)
    soft_w: float = 1.0        # mm
    q_per_rad: float = 3.0
    c_offset_deg: float = 0.0
    noise_deg: float = 0.05
    sensor_hz: float = 100.0

    def width(self, q: np.ndarray) -> np.ndarray:
        return self.b_floor + self.b_bump / (1.0 + ((np.asarray(q, float) - self.q_c) / self.s_q) ** 2)

    def bend(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        return self.c_offset_deg + self.gain * DEG_PER_RAD / self.q_per_rad * (x - self.soft * self.soft_w * np.tanh(x / self.soft_w))


def perturbed(rng: np.random.Generator) -> Plant:
    """A plant drawn around the nominal one (+-20-30 %), as the self-test's robots."""
    p = Plant()
    return replace(p, b_floor=p.b_floor * rng.uniform(0.8, 1.2), b_bump=p.b_bump * rng.uniform(0.7, 1.3),
                   s_q=p.s_q * rng.uniform(0.8, 1.25), soft=min(p.soft * rng.uniform(0.6, 1.3), 0.8),
                   gain=p.gain * rng.uniform(0.9, 1.1), q_c=rng.uniform(-0.3, 0.3),
                   noise_deg=p.noise_deg * rng.uniform(0.7, 1.5))


def clearance(q: np.ndarray, below: np.ndarray, above: np.ndarray, x0: float | None = None) -> np.ndarray:
    """Carrier position x (N,) mm: x stays put unless q - x leaves [-above, below] (the tendon
    takes up the slack and drags the carrier). below/above: (N,) slack on each side, mm.

    Each step clamps x to [q - below, q + above], and clamps compose into clamps ([a1, b1] then
    [a2, b2] is [clamp(a1, a2, b2), clamp(b1, a2, b2)]), so a parallel prefix of log2(N) vector
    passes gives the sequential recursion's values bit for bit (it only selects edge values; 4x
    faster on a 60 000-sample record). Where an edge pair is inverted (q - below > q + above) the
    recursion's if/elif is not a clamp: the loop is run instead (``_clearance_loop``)."""
    lo = np.asarray(q, float) - below
    hi = np.asarray(q, float) + above
    if lo.size == 0 or np.any(lo > hi):
        return _clearance_loop(q, below, above, x0)
    a, b = lo.copy(), hi.copy()
    s = 1
    while s < a.size:
        na = np.minimum(np.maximum(a[:-s], a[s:]), b[s:])
        nb = np.minimum(np.maximum(b[:-s], a[s:]), b[s:])
        a[s:], b[s:] = na, nb
        s *= 2
    return np.minimum(np.maximum(float(q[0] if x0 is None else x0), a), b)


def _clearance_loop(q: np.ndarray, below: np.ndarray, above: np.ndarray, x0: float | None = None) -> np.ndarray:
    """The sequential form of ``clearance`` (the reference; used for inverted edges)."""
    out = np.empty(q.size)
    x = float(q[0] if x0 is None else x0)
    lo_e = (q - below).tolist()
    hi_e = (q + above).tolist()
    for k in range(q.size):  # sequential: the carrier state
        if x < lo_e[k]:
            x = lo_e[k]
        elif x > hi_e[k]:
            x = hi_e[k]
        out[k] = x
    return out


def first_order(x: np.ndarray, tau_s: float, rate_hz: float = STATE_HZ) -> np.ndarray:
    """Exact discretisation of tau dy/dt = x - y (zero-order hold), y[0] = x[0]; (N,)."""
    a = np.exp(-1.0 / (tau_s * rate_hz))
    y = np.empty(x.size)
    acc = float(x[0])
    for k, v in enumerate(x.tolist()):
        acc = a * acc + (1 - a) * v
        y[k] = acc
    return y


def motion_sign(c: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """+1/-1: sign of the last change of c larger than tol, held while still; (N,)."""
    d = np.diff(c, prepend=c[:1])
    s = np.zeros(c.size)
    cur = 1.0
    for k, v in enumerate(d.tolist()):
        if v > tol:
            cur = 1.0
        elif v < -tol:
            cur = -1.0
        s[k] = cur
    return s


def run(plant: Plant, t: np.ndarray, q: np.ndarray, effect=None, rng: np.random.Generator | None = None) -> dict:
    """Drive the plant: q (N,) at STATE_HZ -> sensor record. effect: None or a variants.Variant
    bound to its strength (``effect.apply(stage, ctx)`` hooks). Returns {"t_s", "c_deg" (sensor),
    "c_true_deg" (N,), "x_mm" (N,)}."""
    rng = rng or np.random.default_rng(0)
    ctx = {"t": t, "q": q, "plant": plant, "rng": rng}
    hook = (lambda stage: effect.apply(stage, ctx)) if effect is not None else (lambda stage: None)
    ctx["qa"] = q.copy()
    hook("actuator")
    B = plant.width(ctx["qa"])
    ctx["below"], ctx["above"] = B / 2, B / 2
    ctx["x"] = None
    hook("clearance")          # may set below/above, or x directly
    if ctx["x"] is None:
        ctx["x"] = clearance(ctx["qa"], ctx["below"], ctx["above"])
    hook("carrier")
    ctx["c"] = plant.bend(ctx["x"])
    hook("bend")
    # Sensor: its own clock (random phase), samples of the true tip angle, then noise.
    ts = np.arange(t[0] + rng.uniform(0, 1 / plant.sensor_hz), t[-1], 1 / plant.sensor_hz)
    ctx["ts"] = ts
    ctx["t_seen"] = ts.copy()
    ctx["cs"] = None
    hook("sensor")
    if ctx["cs"] is None:
        ctx["cs"] = np.interp(ctx["t_seen"], t, ctx["c"])
    hook("reading")
    cs = ctx["cs"] + rng.normal(0, plant.noise_deg, ts.size)
    return {"t_s": ts, "c_deg": cs, "clean_deg": ctx["cs"], "c_true_deg": ctx["c"], "x_mm": ctx["x"]}


def excitation_q(duration_s: float, q_lo: float, q_hi: float, amp: float, speed: float, cycles: int,
                 hold_s: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """The paper's excitation (section III-B), written for this generator: back-and-forth legs of
    peak-to-peak amp mm at speed mm/s, holding hold_s at each turn, around a centre that ramps
    over [q_lo + amp/2, q_hi - amp/2] up and down ``cycles`` times. Returns (t (N,), q (N,))."""
    n = int(round(duration_s * STATE_HZ)) + 1
    t = np.arange(n) / STATE_HZ
    period = duration_s / cycles
    ph = (t % period) / period
    centre = q_lo + amp / 2 + (q_hi - q_lo - amp) * (1 - np.abs(2 * ph - 1))
    q = np.empty(n)
    pos, d, hold = float(centre[0]), 1.0, 0.0
    step = speed / STATE_HZ
    for k in range(n):  # sequential: each turn depends on where the previous leg ended
        if hold > 0:
            hold -= 1.0 / STATE_HZ
        else:
            pos += d * step
            if d * (pos - centre[k]) >= amp / 2:
                d, hold = -d, hold_s
        q[k] = pos
    return t, q


def record(plant: Plant, effect=None, seed: int = 0, duration_s: float = 120.0, q_lo: float = -3.0,
           q_hi: float = 3.0, amp: float = 1.4, speed: float = 0.8, cycles: int = 2) -> Session:
    """A blind angle session: excitation (paper III-B) on the plant, the effect's identity not
    recorded anywhere in the session. truth: c_deg at the encoder rate."""
    rng = np.random.default_rng(seed)
    t, q = excitation_q(duration_s, q_lo, q_hi, amp, speed, cycles)
    r = run(plant, t, q, effect, rng)
    s = Session(actuator_unit="mm", distal_kind="angle", robot=Robot("constant_curvature", 20.0, 5.0, plant.q_per_rad),
                   encoder={"t_s": t, "q": q, "q_cmd": q.copy()}, t_delay_s=0.0,
                   distal={"t_s": r["t_s"], "c_deg": r["c_deg"]},
                   truth={"t_s": t, "c_deg": r["c_true_deg"]}, meta={"source": "playscope blind generator"})
    # The noise-free sensor reading: what a perfect model of plant + effect would predict (the
    # generator's truth for the recoverable shrink). Not part of the session files.
    s.meta["clean_reading_deg"] = r["clean_deg"]
    return s
