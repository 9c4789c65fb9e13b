"""Implementations of the withheld effects, each a hook on one stage of plant.run.

Every effect of the diagnosis library has at least two physically different implementations here
(e.g. a dead zone in the actuator routing before the clearance, and a rounded dead zone of the
distal joint after the bending map; stick-slip as quasi-static stiction and as a mass-spring with
Coulomb/Stribeck friction), written without looking at the diagnosis' fitted forms. Two
out-of-library effects (a tip vibration rung at each reversal, a ratcheting backlash whose width
grows with the travel) must come out "unexplained".

Strengths: (moderate, strong) per variant, in the variant's own parameter (``unit``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .hidden_plant import STATE_HZ, clearance, first_order, motion_sign


@dataclass(frozen=True)
class Variant:
    """One implementation of an effect: ``effect`` (library name or out-of-library label),
    ``name``, stage hook ``fn(stage, ctx, k)`` with strength k, strengths (moderate, strong)."""

    effect: str
    name: str
    fn: Callable
    strengths: tuple
    unit: str
    doc: str

    def bind(self, k: float) -> "Bound":
        return Bound(self, float(k))


@dataclass(frozen=True)
class Bound:
    v: Variant
    k: float

    def apply(self, stage: str, ctx: dict) -> None:
        self.v.fn(stage, ctx, self.k)


# ---------------------------------------------------------------- asymmetric backlash
def _asym_edges(stage, ctx, a):
    """The slack taken up going up is (1+a) times that going down (uneven pulley seat)."""
    if stage == "clearance":
        B = ctx["below"] + ctx["above"]
        ctx["below"], ctx["above"] = (1 + a) * B / 2, (1 - a) * B / 2


def _asym_load(stage, ctx, a):
    """Antagonistic tendons of unequal preload: the extra slack of the loaded side grows with the
    bending load (|x| relative to the range), so the asymmetry is not a constant shift."""
    if stage == "clearance":
        q = ctx["qa"]
        load = np.abs(q) / max(np.max(np.abs(q)), 1e-9)
        B = ctx["below"] + ctx["above"]
        extra = a * B * (0.4 + 1.2 * load)
        ctx["below"], ctx["above"] = B / 2 + extra / 2, np.maximum(B / 2 - extra / 2, 0.02)


# ---------------------------------------------------------------- smooth transition
def _smooth_dense(stage, ctx, s):
    """Dense distribution of clearances (21 carriers, triangular weights on widths B(1 +- s)):
    the fibres of the tendon take up their slack one after the other."""
    if stage == "clearance":
        B = ctx["below"] + ctx["above"]
        u = np.linspace(-1, 1, 21)
        w = 1.0 - np.abs(u) + 0.05
        w /= w.sum()
        x = np.zeros(B.size)
        for ui, wi in zip(u, w):
            r = 1 + s * ui
            x += wi * clearance(ctx["qa"], r * B / 2, r * B / 2)
        ctx["x"] = x


def _smooth_duhem(stage, ctx, s):
    """Duhem engagement: the carrier starts to follow once the tendon has crossed (1 - s) of the
    half gap and is fully engaged at its edge, dx = h dq with h rising quadratically."""
    if stage == "clearance":
        q = ctx["qa"]
        half = ((ctx["below"] + ctx["above"]) / 2).tolist()
        x = float(q[0])
        out = np.empty(q.size)
        qp = float(q[0])
        for k, qk in enumerate(q.tolist()):
            dq = qk - qp
            qp = qk
            if dq != 0.0:
                gap = (qk - x) if dq > 0 else (x - qk)
                h0 = (1 - s) * half[k]
                h = min(max((gap - h0) / max(s * half[k], 1e-9), 0.0), 1.0) ** 2
                x += h * dq
                # never beyond the hard edge
                x = min(max(x, qk - half[k]), qk + half[k])
            out[k] = x
        ctx["x"] = out


# ---------------------------------------------------------------- dead zone
def _dz_actuator(stage, ctx, w):
    """Slack in the actuator routing near straight: the tendon does not move while the motor
    crosses [-w, w] mm around the straight position (before the clearance)."""
    if stage == "actuator":
        q = ctx["qa"]
        q0 = ctx["plant"].q_c
        ctx["qa"] = q - np.clip(q - q0, -w, w)


def _dz_distal(stage, ctx, w):
    """Rounded dead zone of the distal joint near straight (deg): the tip stays near c0 until the
    bend has moved ~w deg away, with a softplus corner of 0.15 w."""
    if stage == "bend":
        c = ctx["c"]
        c0 = float(ctx["plant"].bend(ctx["plant"].q_c))
        d = c - c0
        eps = 0.15 * w
        ctx["c"] = c0 + np.sign(d) * eps * np.logaddexp(0.0, (np.abs(d) - w) / eps)


# ---------------------------------------------------------------- stick-slip
def _ss_quasistatic(stage, ctx, step):
    """Quasi-static stiction: the tip, tied to the elastic bend by a spring, sticks until the
    spring lag reaches the static threshold (step deg), then slips to the kinetic lag (0.3 step)."""
    if stage == "bend":
        c = ctx["c"].tolist()
        out = np.empty(len(c))
        tip = c[0]
        ds, dk = step, 0.3 * step
        for k, ce in enumerate(c):
            d = ce - tip
            if d > ds:
                tip = ce - dk
            elif d < -ds:
                tip = ce + dk
            out[k] = tip
        ctx["c"] = out


def _ss_dynamic(stage, ctx, step):
    """Mass-spring-damper tip (15 Hz, damping 0.3) with Coulomb stiction (static force = spring
    at step deg lag, kinetic 0.4 of it, Stribeck decay over 5 deg/s), integrated at 4 kHz."""
    if stage == "bend":
        c = ctx["c"]
        sub = 8
        wn, zeta = 2 * np.pi * 15.0, 0.3
        Fs, Fk, vs = wn * wn * step, 0.4 * wn * wn * step, 5.0
        dt = 1.0 / (STATE_HZ * sub)
        ce_l = c.tolist()
        out = np.empty(c.size)
        pos, vel, stuck = ce_l[0], 0.0, True
        prev = ce_l[0]
        for k, ce in enumerate(ce_l):
            for j in range(sub):
                cj = prev + (ce - prev) * (j + 1) / sub
                spring = wn * wn * (cj - pos)
                if stuck:
                    if abs(spring) > Fs:
                        stuck = False
                    else:
                        continue
                fr = (Fk + (Fs - Fk) * np.exp(-abs(vel) / vs)) * (1.0 if vel > 0 else -1.0 if vel < 0 else np.sign(spring))
                acc = spring - 2 * zeta * wn * vel - fr
                nv = vel + acc * dt
                if vel != 0.0 and nv * vel < 0 and abs(spring) <= Fs:
                    vel, stuck = 0.0, True  # velocity reversal under the static threshold: sticks
                    continue
                vel = nv
                pos += vel * dt
            prev = ce
            out[k] = pos
        ctx["c"] = out


# ---------------------------------------------------------------- cable elongation
def _el_kelvin(stage, ctx, kappa):
    """Kelvin-Voigt segment in the tendon (tau 1 s): a share kappa of the carrier motion passes
    through the damped segment (acts on x, before the bending map)."""
    if stage == "carrier":
        x = ctx["x"]
        ctx["x"] = (1 - kappa) * x + kappa * first_order(x, 1.0)


def _el_burgers(stage, ctx, kappa):
    """Creep of the stretched tendon with two time constants (0.4 s and 3 s, Burgers-like), on
    the bend: c -> c - kappa (0.6 (c - LP_0.4 c) + 0.4 (c - LP_3 c))."""
    if stage == "bend":
        c = ctx["c"]
        ctx["c"] = c - kappa * (0.6 * (c - first_order(c, 0.4)) + 0.4 * (c - first_order(c, 3.0)))


# ---------------------------------------------------------------- sensor latency
def _lat_transport(stage, ctx, d):
    """Transport delay of the sensor: each sample shows the tip d seconds before its stamp."""
    if stage == "sensor":
        ctx["t_seen"] = ctx["ts"] - d


def _lat_buffered(stage, ctx, d):
    """Buffered tracker: 250 Hz internal acquisition averaged over 4 samples, delivered with a
    latency d plus a uniform 0-10 ms jitter; the stamp is the delivery time."""
    if stage == "sensor":
        t, c, rng = ctx["t"], ctx["c"], ctx["rng"]
        ts = ctx["ts"]
        lat = d + rng.uniform(0.0, 0.010, ts.size)
        acc = np.zeros(ts.size)
        for j in range(4):
            acc += np.interp(ts - lat - j / 250.0, t, c)
        ctx["cs"] = acc / 4 + 0.0 * ts
        # the averaging window adds 6 ms of lag of its own: remove it so the strength is d + 5 ms
        ctx["cs"] = acc / 4


# ---------------------------------------------------------------- direction-dependent registration
def _he_switch(stage, ctx, delta):
    """The sensor coil sits in a loose seat: its reading is offset by +-delta deg with the
    direction of distal motion, switching at once."""
    if stage == "reading":
        s = motion_sign(ctx["c"], 1e-6)
        ctx["cs"] = ctx["cs"] + delta * np.interp(ctx["t_seen"], ctx["t"], s)


def _he_channel(stage, ctx, delta):
    """The instrument is dragged in its channel by the moving section (friction): its offset
    follows the bend's increments at half rate and saturates at +-delta deg (a small play on c)."""
    if stage == "reading":
        c = ctx["c"]
        dc = np.diff(c, prepend=c[:1]).tolist()
        o = np.empty(c.size)
        acc = 0.0
        for k, v in enumerate(dc):
            acc = min(max(acc + 0.5 * v, -delta), delta)
            o[k] = acc
        ctx["cs"] = ctx["cs"] + np.interp(ctx["t_seen"], ctx["t"], o)


# ---------------------------------------------------------------- drift
def _dr_linear(stage, ctx, r):
    """Offset growing linearly in time, r deg/min (sensor base moving)."""
    if stage == "reading":
        ctx["cs"] = ctx["cs"] + r * (ctx["t_seen"] - ctx["t"][0]) / 60.0


def _dr_thermal(stage, ctx, r):
    """Thermal settling: offset A (1 - exp(-t / 150 s)) with A set so the mean slope over two
    minutes is about r deg/min."""
    if stage == "reading":
        A = 2.0 * r / (1 - np.exp(-120.0 / 150.0))
        ctx["cs"] = ctx["cs"] + A * (1 - np.exp(-(ctx["t_seen"] - ctx["t"][0]) / 150.0))


# ---------------------------------------------------------------- viscous (rate-dependent) hysteresis
def _visc_friction(stage, ctx, beta):
    """Sheath friction with a viscous part: the slack taken up grows with the tendon speed,
    beta * v / (1 + v / 2 mm/s) mm each side (v: actuator speed, smoothed over 20 ms)."""
    if stage == "clearance":
        q = ctx["qa"]
        v = np.abs(np.gradient(q, 1.0 / STATE_HZ))
        v = first_order(v, 0.02)
        extra = beta * v / (1 + v / 2.0)
        ctx["below"], ctx["above"] = ctx["below"] + extra, ctx["above"] + extra


def _visc_damper(stage, ctx, tau):
    """Viscous contact: once the tendon is past the clearance edge the carrier is pulled through a
    damper, tau dx/dt = (edge - x) (a Kelvin-Voigt contact with time constant tau s)."""
    if stage == "clearance":
        q = ctx["qa"]
        lo_e = (q - ctx["below"]).tolist()
        hi_e = (q + ctx["above"]).tolist()
        a = 1.0 - np.exp(-1.0 / (tau * STATE_HZ))
        x = float(q[0])
        out = np.empty(q.size)
        for k in range(q.size):
            if x < lo_e[k]:
                x += a * (lo_e[k] - x)
            elif x > hi_e[k]:
                x += a * (hi_e[k] - x)
            out[k] = x
        ctx["x"] = out


# ---------------------------------------------------------------- out of library
def _ool_vibration(stage, ctx, amp):
    """Tip vibration: a 6 Hz mode (decay 0.4 s) rung by each reversal of the bend, amp deg."""
    if stage == "bend":
        c, t = ctx["c"], ctx["t"]
        s = motion_sign(c, 1e-6)
        flips = np.flatnonzero(np.diff(s) != 0) + 1
        add = np.zeros(c.size)
        for i in flips:
            tt = t[i:] - t[i]
            m = tt < 3.0
            add[i:][m] += s[i] * amp * np.exp(-tt[m] / 0.4) * np.sin(2 * np.pi * 6.0 * tt[m])
        ctx["c"] = c + add


def _ool_ratchet(stage, ctx, g):
    """Ratcheting backlash: the clearance widens with the accumulated tendon travel (wear / seat
    deformation), by a factor 1 + g over the record."""
    if stage == "clearance":
        q = ctx["qa"]
        trav = np.cumsum(np.abs(np.diff(q, prepend=q[:1])))
        f = 1 + g * trav / max(trav[-1], 1e-9)
        ctx["below"], ctx["above"] = ctx["below"] * f, ctx["above"] * f


def _variants() -> dict[str, list[Variant]]:
    V = Variant
    out = [
        V("asymmetric_backlash", "edge_ratio", _asym_edges, (0.35, 0.6), "1", _asym_edges.__doc__),
        V("asymmetric_backlash", "antagonist_load", _asym_load, (0.35, 0.6), "1", _asym_load.__doc__),
        V("smooth_transition", "dense_clearances", _smooth_dense, (0.5, 0.8), "1", _smooth_dense.__doc__),
        V("smooth_transition", "duhem", _smooth_duhem, (0.5, 0.8), "1", _smooth_duhem.__doc__),
        V("dead_zone", "actuator_side", _dz_actuator, (0.3, 0.6), "mm", _dz_actuator.__doc__),
        V("dead_zone", "distal_side", _dz_distal, (4.0, 8.0), "deg", _dz_distal.__doc__),
        V("stick_slip", "quasistatic_stiction", _ss_quasistatic, (0.8, 1.6), "deg", _ss_quasistatic.__doc__),
        V("stick_slip", "mass_spring_coulomb", _ss_dynamic, (0.8, 1.6), "deg", _ss_dynamic.__doc__),
        V("cable_elongation", "kelvin_voigt", _el_kelvin, (0.3, 0.6), "1", _el_kelvin.__doc__),
        V("cable_elongation", "burgers_creep", _el_burgers, (0.3, 0.6), "1", _el_burgers.__doc__),
        V("camera_delay", "transport", _lat_transport, (0.04, 0.08), "s", _lat_transport.__doc__),
        V("camera_delay", "buffered", _lat_buffered, (0.04, 0.08), "s", _lat_buffered.__doc__),
        V("handeye_direction", "loose_seat", _he_switch, (1.0, 1.5), "deg", _he_switch.__doc__),
        V("handeye_direction", "channel_drag", _he_channel, (1.0, 1.5), "deg", _he_channel.__doc__),
        V("drift", "linear", _dr_linear, (0.6, 1.2), "deg/min", _dr_linear.__doc__),
        V("drift", "thermal", _dr_thermal, (0.6, 1.2), "deg/min", _dr_thermal.__doc__),
        V("viscous_hysteresis", "viscous_friction", _visc_friction, (0.1, 0.2), "s", _visc_friction.__doc__),
        V("viscous_hysteresis", "damped_contact", _visc_damper, (0.1, 0.2), "s", _visc_damper.__doc__),
    ]
    d: dict[str, list[Variant]] = {}
    for v in out:
        d.setdefault(v.effect, []).append(v)
    return d


VARIANTS = _variants()
OUT_OF_LIBRARY = [
    Variant("tip_vibration", "reversal_ringing", _ool_vibration, (1.5,), "deg", _ool_vibration.__doc__),
    Variant("ratcheting_backlash", "travel_widening", _ool_ratchet, (0.8,), "1", _ool_ratchet.__doc__),
]
