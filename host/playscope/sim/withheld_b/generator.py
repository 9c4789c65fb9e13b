"""Second withheld-effect generator (package doc): plant, excitation, sensor, effect forms, cases.

State at RATE_HZ = 200 Hz. Units: q, x in mm; c in deg; t in s.
Plant: tendon carrier x follows q through a play of total width W(q) = w0 (1 + w1 tanh(q / 2))
(x stays unless q - x leaves [-W_dn, W_up]); bend c = g1 x + g3 x^3 + c0; an angle sensor at 80 Hz
with AR(1) noise (rho 0.6) quantised to 0.01 deg.
Excitation: sine sweeps of 0.15-0.35 Hz whose amplitude and centre wander over the range, with
a 1.2 s pause every 20 s (the diagnosis' noise floor needs still periods).
Every effect is a function of (stage, ctx, k) applied at one stage: "edges" (play half-widths),
"carrier" (x), "bend" (c), "sensor" (timestamps), "reading" (sensed c).
LIBRARY / EXTRA_EFFECTS: the forms the self-test plants; RETIRED: forms no longer planted because
they leave no trace in the data (kept for the trace check, bench/diagnose_trace.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...io.session import Robot, Session

RATE_HZ = 200.0
SENSOR_HZ = 80.0


@dataclass(frozen=True)
class PlantB:
    w0_mm: float = 0.30        # play width at q = 0
    w1: float = 0.25           # its tanh slope over q
    g1_deg_per_mm: float = 11.0
    g3_deg_per_mm3: float = -0.35
    c0_deg: float = 2.0
    noise_deg: float = 0.04
    noise_rho: float = 0.6


def draw_plant(rng: np.random.Generator) -> PlantB:
    """A plant with every parameter drawn around its default (so no two records share one)."""
    u = lambda a, b: float(rng.uniform(a, b))
    return PlantB(w0_mm=u(0.22, 0.40), w1=u(-0.3, 0.3), g1_deg_per_mm=u(9.0, 13.0), g3_deg_per_mm3=u(-0.5, -0.15),
                  c0_deg=u(-3.0, 3.0), noise_deg=u(0.03, 0.06), noise_rho=u(0.4, 0.7))


def sweep_excitation(duration_s: float, rng: np.random.Generator, q_span: float = 2.8) -> tuple[np.ndarray, np.ndarray]:
    """q(t) (mm) at RATE_HZ: a sine whose frequency glides 0.15-0.35 Hz, amplitude 0.4-0.9 mm and
    centre within +-(q_span - amplitude), wandering with periods of 13, 17 and 29 s (so every quarter of a 120-s record spans the range
    the fit part saw); held 1.2 s every 20 s."""
    n = int(duration_s * RATE_HZ) + 1
    t = np.arange(n) / RATE_HZ
    # the motion's own clock: it stands still during each pause, so q holds and resumes smoothly
    moving = np.ones(n)
    pause = int(1.2 * RATE_HZ)
    for start in range(int(10 * RATE_HZ), n - pause, int(20 * RATE_HZ)):
        moving[start:start + pause] = 0.0
    tau = np.cumsum(moving) / RATE_HZ
    f = 0.25 + 0.1 * np.sin(2 * np.pi * tau / 13.0 + rng.uniform(0, 6.28))
    phase = 2 * np.pi * np.cumsum(f * moving) / RATE_HZ
    amp = 0.65 + 0.25 * np.sin(2 * np.pi * tau / 17.0 + rng.uniform(0, 6.28))
    centre = (q_span - 0.9) * np.sin(2 * np.pi * tau / 29.0 + rng.uniform(0, 6.28))
    q = centre + amp * np.sin(phase)
    return t, q


def _drag_carrier(q: np.ndarray, w_dn: np.ndarray, w_up: np.ndarray) -> np.ndarray:
    """x (N,): still unless q - x leaves [-w_dn, w_up] (then dragged by the tendon)."""
    ql, lo, hi = q.tolist(), (q - w_up).tolist(), (q + w_dn).tolist()
    x = ql[0]
    out = np.empty(len(ql))
    for k in range(len(ql)):
        if x < lo[k]:
            x = lo[k]
        elif x > hi[k]:
            x = hi[k]
        out[k] = x
    return out


def _held_sign(v: np.ndarray, eps: float) -> np.ndarray:
    """+1/-1: sign of the last step of v larger than eps, held (starts +1)."""
    d = np.diff(v, prepend=v[:1])
    s = np.where(d > eps, 1.0, np.where(d < -eps, -1.0, 0.0))
    out = np.empty(v.size)
    cur = 1.0
    for k, sk in enumerate(s.tolist()):
        cur = sk if sk != 0.0 else cur
        out[k] = cur
    return out


def simulate(plant: PlantB, t: np.ndarray, q: np.ndarray, effect, k: float, rng: np.random.Generator) -> dict:
    """Drive the plant with one effect (a function (stage, ctx, k) or None) of strength k.
    Returns {"t_s", "c_deg" (sensor rows), "clean_deg" (noise-free reading), "c_true_deg" (N,)}."""
    hook = (lambda st, ctx: effect(st, ctx, k)) if effect is not None else (lambda st, ctx: None)
    W = plant.w0_mm * (1 + plant.w1 * np.tanh(q / 2.0))
    ctx = {"t": t, "q": q, "w_up": W / 2, "w_dn": W / 2, "rng": rng, "plant": plant}
    hook("edges", ctx)
    ctx["x"] = _drag_carrier(ctx["q"], ctx["w_dn"], ctx["w_up"])
    hook("carrier", ctx)
    x = ctx["x"]
    ctx["c"] = plant.g1_deg_per_mm * x + plant.g3_deg_per_mm3 * x ** 3 + plant.c0_deg
    hook("bend", ctx)
    ts = np.arange(t[0] + rng.uniform(0, 1 / SENSOR_HZ), t[-1], 1 / SENSOR_HZ)
    ctx["ts"], ctx["t_seen"] = ts, ts.copy()
    hook("sensor", ctx)
    clean = np.interp(ctx["t_seen"], t, ctx["c"])
    ctx["cs"] = clean
    hook("reading", ctx)
    clean = ctx["cs"]
    e = rng.normal(0, plant.noise_deg * np.sqrt(1 - plant.noise_rho ** 2), ts.size)
    noise = np.empty(ts.size)
    acc = rng.normal(0, plant.noise_deg)
    for i, ei in enumerate(e.tolist()):
        acc = plant.noise_rho * acc + ei
        noise[i] = acc
    reading = np.round((clean + noise) / 0.01) * 0.01
    return {"t_s": ts, "c_deg": reading, "clean_deg": clean, "c_true_deg": ctx["c"]}


# ------------------------------------------------------------------ library effects, other forms
def loaded_side_slack(stage, ctx, a):
    """RETIRED (not planted by the self-test; kept for the trace check). One tendon stretches under
    the bending load: the slack taken up going up grows by a times its nominal value from one end of
    the travel to the other; the other side keeps its own (a constant ratio of the two slacks would
    be a shift of the band that the bend map absorbs).
    Why retired: both edges still depend on q alone, so the play is the base model under a
    relabelling (its centre the edges' mean, its width their difference, the bend map
    re-parameterised): fitted with no effect at all, the base model leaves 0.001-0.002 deg above the
    noise-only RMSE at a = 1 and 2, as on nulls (0.0002-0.0013; bench/diagnose_trace.py). No
    diagnosis can name what leaves no trace; ``turn_set_slack`` replaced it."""
    if stage == "edges":
        q = ctx["q"]
        u = (q - q.min()) / max(float(np.ptp(q)), 1e-9)
        ctx["w_up"] = ctx["w_up"] * (1 + a * u)


def turn_set_slack(stage, ctx, a):
    """The pulling-up tendon's seat is set at each turn from going down to going up: the tendon that
    pulled down unloads there and its sheath recoils by what the load at the turn had compressed, so
    the slack taken up going up is its nominal value times 1 + a v, v in [0, 1] how far down the
    turn was over the travel ((max q - q at the turn) / range of q). The slack taken up going down
    keeps its own. The set holds for the whole upward stroke and the turn after it (it changes only
    at the next down-to-up turn, where the carrier sits on the other edge, so it never jumps).
    Two strokes through the same q from different turns take up different slack: the edges follow
    the motion's history, not q alone, which no relabelling of a play on q absorbs. Fitted with no
    effect, the base model leaves 0.05-0.11 deg above the noise-only RMSE at a = 1 and 0.11-0.26 at
    a = 2 on six records, with or without the record's first 10 s and with twice the spline knots
    (bench/diagnose_trace.py; nulls at most 0.002)."""
    if stage == "edges":
        q = ctx["q"]
        s = _held_sign(q, 1e-9)
        v = (float(q.max()) - q) / max(float(np.ptp(q)), 1e-9)
        turns = np.flatnonzero((s[1:] > 0) & (s[:-1] < 0)) + 1
        # v at the last down-to-up turn (the sample before the first rise), 0 before the first one
        set_v = np.zeros(q.size)
        for i, j in zip(turns, np.r_[turns[1:], q.size]):
            set_v[i:j] = v[i - 1]
        ctx["w_up"] = ctx["w_up"] * (1 + a * set_v)


def pi_transition(stage, ctx, s):
    """Prandtl-Ishlinskii carrier: 9 plays of widths W (1 - s ... 1 + s) averaged (uniform weights)."""
    if stage == "carrier":
        out = np.zeros(ctx["q"].size)
        for f in np.linspace(1 - s, 1 + s, 9):
            out += _drag_carrier(ctx["q"], f * ctx["w_dn"], f * ctx["w_up"])
        ctx["x"] = out / 9


def softplus_deadzone(stage, ctx, w):
    """A slack distal joint near straight: the bend ignores x within about +-w mm of x = 0.1 mm,
    its edges softened by a softplus of 0.05 mm."""
    if stage == "carrier":
        u = ctx["x"] - 0.1
        sp = lambda a: 0.05 * np.logaddexp(0.0, a / 0.05)
        ctx["x"] = 0.1 + sp(u - w) - sp(-u - w)


def random_stiction(stage, ctx, lag):
    """The tip sticks until the bend has moved a random breakaway lag (mean lag deg, +-40 %),
    then jumps to 20 % of it behind; thresholds redrawn at every slip."""
    if stage == "bend":
        rng = ctx["rng"]
        c = ctx["c"].tolist()
        tip, thr = c[0], lag * rng.uniform(0.6, 1.4)
        out = np.empty(len(c))
        for i, ce in enumerate(c):
            d = ce - tip
            if abs(d) > thr:
                tip = ce - np.sign(d) * 0.2 * lag
                thr = lag * rng.uniform(0.6, 1.4)
            out[i] = tip
        ctx["c"] = out


def two_mode_creep(stage, ctx, kappa):
    """Tendon creep with two parallel time constants (0.15 s and 1.5 s, equal shares): the
    bend follows kappa of x through them, 1 - kappa at once."""
    if stage == "carrier":
        x = ctx["x"]
        out = np.empty(x.size)
        for tau in (0.15, 1.5):
            a = np.exp(-1 / (tau * RATE_HZ))
            y, acc = np.empty(x.size), x[0]
            for i, xi in enumerate(x.tolist()):
                acc = a * acc + (1 - a) * xi
                y[i] = acc
            out = out + 0.5 * y if tau > 0.15 else 0.5 * y
        ctx["x"] = (1 - kappa) * x + kappa * out


def jitter_latency(stage, ctx, d):
    """The sensor's samples are stamped d s early (late readout), with +-3 ms jitter."""
    if stage == "sensor":
        ctx["t_seen"] = ctx["ts"] - d - ctx["rng"].uniform(-0.003, 0.003, ctx["ts"].size)


def tilted_registration(stage, ctx, delta):
    """A registration error that flips with the direction of distal motion, +-delta deg about one
    camera axis: its projection on the bend angle scales with cos(c) and switches over 0.05 deg of
    bend travel (tanh)."""
    if stage == "reading":
        c, t = ctx["c"], ctx["t"]
        # a direction state that travels between -1 and 1 with the bend's increments (soft switch)
        dc = np.diff(c, prepend=c[:1]).tolist()
        s, st = np.empty(c.size), 1.0
        for i, v in enumerate(dc):
            st = float(np.clip(st + v / 0.05, -1.0, 1.0))
            s[i] = st
        off = delta * np.tanh(2.5 * s) / np.tanh(2.5) * np.cos(np.deg2rad(c))
        ctx["cs"] = ctx["cs"] + np.interp(ctx["t_seen"], t, off)


def wander_drift(stage, ctx, r):
    """A sensor offset that creeps at r deg/min on average along a slow sine (warm-up)."""
    if stage == "reading":
        ts = ctx["ts"]
        T = ts[-1] - ts[0]
        ctx["cs"] = ctx["cs"] + r * T / 60.0 * (0.5 * (ts - ts[0]) / T + 0.5 * np.sin(np.pi * (ts - ts[0]) / (2 * T)))


def sqrt_rate_band(stage, ctx, beta):
    """The play widens with the square root of the actuator speed, beta mm per sqrt(mm/s)
    (a sheath friction with a shear-thinning lubricant), speed averaged over 0.2 s."""
    if stage == "edges":
        v = np.abs(np.gradient(ctx["q"], 1 / RATE_HZ))
        n = int(0.2 * RATE_HZ)
        v = np.convolve(v, np.ones(n) / n, mode="same")
        ctx["w_up"] = ctx["w_up"] + beta * np.sqrt(v)
        ctx["w_dn"] = ctx["w_dn"] + beta * np.sqrt(v)


# ------------------------------------------------------------------ out of library
def light_ringing(stage, ctx, amp):
    """A lightly damped tip mode (3.2 Hz, damping ratio 0.04) rung by each reversal of the bend,
    amp deg at the first peak."""
    if stage == "bend":
        c, t = ctx["c"], ctx["t"]
        s = _held_sign(c, 1e-7)
        add = np.zeros(c.size)
        wn, z = 2 * np.pi * 3.2, 0.04
        for i in np.flatnonzero(np.diff(s) != 0) + 1:
            tt = t[i:] - t[i]
            m = tt < 8.0
            add[i:][m] += s[i] * amp * np.exp(-z * wn * tt[m]) * np.sin(wn * np.sqrt(1 - z * z) * tt[m])
        ctx["c"] = c + add


def cogging(stage, ctx, amp):
    """Actuator cogging: the tendon end sits amp mm off the commanded q with a period of 0.4 mm of q."""
    if stage == "edges":
        ctx["q"] = ctx["q"] + amp * np.sin(2 * np.pi * ctx["q"] / 0.4)


def anchor_slips(stage, ctx, step):
    """The tendon anchor slips now and then (Poisson, one per 25 s): a lasting offset of
    +-step deg each time."""
    if stage == "bend":
        t, rng = ctx["t"], ctx["rng"]
        n = rng.poisson((t[-1] - t[0]) / 25.0)
        off = np.zeros(t.size)
        for tt in np.sort(rng.uniform(t[0], t[-1], n)):
            off[t >= tt] += step * rng.choice((-1.0, 1.0))
        ctx["c"] = ctx["c"] + off


# library name -> (form, (moderate, strong), unit); out-of-library label -> (form, strength, unit)
LIBRARY = {
    "asymmetric_backlash": (turn_set_slack, (1.0, 2.0), "1"),
    "smooth_transition": (pi_transition, (0.5, 0.8), "1"),
    "dead_zone": (softplus_deadzone, (0.2, 0.4), "mm"),
    "stick_slip": (random_stiction, (0.8, 1.5), "deg"),
    "cable_elongation": (two_mode_creep, (0.3, 0.6), "1"),
    "camera_delay": (jitter_latency, (0.05, 0.1), "s"),
    "handeye_direction": (tilted_registration, (1.0, 1.5), "deg"),
    "drift": (wander_drift, (0.6, 1.2), "deg/min"),
    "viscous_hysteresis": (sqrt_rate_band, (0.08, 0.15), "mm/sqrt(mm/s)"),
}
# Forms no longer planted by the self-test, kept for the trace check (bench/diagnose_trace.py):
# form name -> (form, (moderate, strong), unit); session() plants one when a case's variant names it.
RETIRED = {"loaded_side_slack": (loaded_side_slack, (1.0, 2.0), "1")}
EXTRA_EFFECTS = {
    "light_ringing": (light_ringing, 1.0, "deg"),
    "cogging": (cogging, 0.04, "mm"),
    "anchor_slips": (anchor_slips, 0.6, "deg"),
}


def cases(seed: int, effects=tuple(LIBRARY), nulls: int = 10, ool: bool = True, strengths: str = "both") -> list[dict]:
    """{"id", "truth", "effect", "variant", "strength", "unit", "seed"} per case; truth "none" for nulls,
    "unexplained" for out-of-library effects."""
    rng = np.random.default_rng(seed)
    out = []
    for e in effects:
        fn, ks, unit = LIBRARY[e]
        for k in (ks if strengths == "both" else ks[-1:]):
            out.append({"truth": e, "effect": e, "variant": fn.__name__, "strength": k, "unit": unit,
                        "seed": int(rng.integers(1 << 30))})
    if ool:
        for name, (fn, k, unit) in EXTRA_EFFECTS.items():
            out.append({"truth": "unexplained", "effect": name, "variant": fn.__name__, "strength": k, "unit": unit,
                        "seed": int(rng.integers(1 << 30))})
    for _ in range(nulls):
        out.append({"truth": "none", "effect": None, "variant": None, "strength": 0.0, "unit": "",
                    "seed": int(rng.integers(1 << 30))})
    for i, c in enumerate(out):
        c["id"] = i
    return out


def session(case: dict, duration_s: float = 120.0) -> Session:
    """The blind angle session of a case; the noise-free reading under meta["clean_reading_deg"]."""
    rng = np.random.default_rng(case["seed"])
    plant = draw_plant(rng)
    t, q = sweep_excitation(duration_s, rng)
    e = case["effect"]
    if case.get("variant") in RETIRED:
        fn = RETIRED[case["variant"]][0]
    else:
        fn = LIBRARY[e][0] if e in LIBRARY else (EXTRA_EFFECTS[e][0] if e else None)
    r = simulate(plant, t, q, fn, case["strength"], rng)
    s = Session(actuator_unit="mm", distal_kind="angle",
                robot=Robot("constant_curvature", 20.0, 5.0, float(180.0 / np.pi / plant.g1_deg_per_mm)),
                encoder={"t_s": t, "q": q, "q_cmd": q.copy()}, t_delay_s=0.0,
                distal={"t_s": r["t_s"], "c_deg": r["c_deg"]}, truth={"t_s": t, "c_deg": r["c_true_deg"]},
                meta={"source": "playscope second blind generator"})
    s.meta["clean_reading_deg"] = r["clean_deg"]
    return s
