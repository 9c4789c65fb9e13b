"""Effect library: the unmodelled behaviours the simulator can switch on and the diagnosis screens.

Each effect is a small add-on with one to three parameters, off by default (all parameters at
their "off" value). The same registry drives ``playscope simulate --effect NAME:p=v`` and the
attribution step of ``playscope diagnose``; ``signature`` is the pattern the effect leaves in the
residuals of the paper's model (pure play of width B(q) followed by f_remain, eqs. 2-3), which
docs/simulator.md lists and tests/python/sim/test_effects.py checks.

Stages (where the effect acts in the chain q -> z -> c -> observation):
  play      changes the play operator (asymmetry, smooth transition)
  distal    acts on the configuration c after f_remain (dead zone, stick-slip, elongation, drift)
  camera    acts on the image formation (hand-eye, delay/jitter, lens, curvature)
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Param:
    """One effect parameter: name, unit, value that switches the effect off, bounds, and the
    strengths the blind self-test draws from (moderate, strong)."""

    name: str
    unit: str
    off: float
    lo: float
    hi: float
    strengths: tuple[float, ...] = ()


@dataclass(frozen=True)
class Effect:
    """An effect of the library. ``params`` in order; ``stage`` see module doc; ``image_only``
    effects are invisible in a bending-angle record (they act on h or g only)."""

    name: str
    title: str
    stage: str
    params: tuple[Param, ...]
    signature: str
    image_only: bool = False
    in_library: bool = True

    def off(self) -> dict[str, float]:
        return {p.name: p.off for p in self.params}

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"effect {self.name} has no parameter {name!r}")


EFFECTS: dict[str, Effect] = {}


def _reg(e: Effect) -> Effect:
    EFFECTS[e.name] = e
    return e


_reg(Effect(
    "asymmetric_backlash", "asymmetric backlash", "play",
    (Param("alpha", "1", 0.0, -0.8, 0.8, (0.35, 0.6)),),
    "Lag behind q differs by direction: going up z = q - (1+alpha) B/2, going down z = q + (1-alpha) B/2. "
    "Residual: a direction-dependent offset proportional to alpha*B(q)*f_remain'(q), largest where B is "
    "wide; with a constant B it is a pure shift of the centre line (absorbed by f_remain).",
))
_reg(Effect(
    "smooth_transition", "smooth transition after a reversal", "play",
    (Param("spread", "1", 0.0, 0.0, 0.95, (0.5, 0.8)),),
    "Five weighted play operators of widths B(q)(1 + spread*u), u in [-1, 1] (a discrete "
    "Prandtl-Ishlinskii operator): the tip starts moving before the nominal onset and joins the "
    "envelope later. Residual: a bump of alternating sign confined to motor travel < (1+spread)B "
    "after each reversal, zero on the envelope.",
))
_reg(Effect(
    "dead_zone", "dead zone near straight", "distal",
    (Param("width_deg", "deg", 0.0, 0.0, 20.0, (4.0, 8.0)), Param("c0_deg", "deg", 0.0, -90.0, 120.0)),
    "c' = c - clip(c - c0, -w, w): the tip stays at c0 while |c - c0| < w. Residual: localised in c "
    "around c0 (by q, a plateau of width ~2w/f'), same sign pattern in both directions, none far from c0.",
))
_reg(Effect(
    "stick_slip", "stick-slip", "distal",
    (Param("step_deg", "deg", 0.0, 0.0, 5.0, (0.8, 1.6)),),
    "The tip sticks until the elastic configuration has moved step_deg away, then slips to it. "
    "Residual: sawtooth of amplitude ~step during motion (period = step / |dc/dt|), a lag of step/2 "
    "against the direction of motion, zero mean per direction after the fit absorbs the lag.",
))
_reg(Effect(
    "cable_elongation", "cable elongation (load-dependent gain, creep)", "distal",
    (Param("kappa", "1", 0.0, 0.0, 0.9, (0.3, 0.6)), Param("tau_s", "s", 1.0, 0.05, 10.0)),
    "The cable stretch follows the load with a first-order lag: c' = c + kappa (LP_tau(c) - c). "
    "Residual: proportional to -kappa*tau*dc/dt while moving (a speed-dependent gain), decaying "
    "exponentially with tau after each stop (creep); no jump at reversals.",
))
_reg(Effect(
    "travel_relaxation", "creep over the travel (rate-independent relaxation)", "play",
    (Param("kappa", "1", 0.0, 0.0, 0.9, (0.3, 0.6)), Param("lambda_q", "mm", 0.5, 0.01, 20.0)),
    "The play output relaxes towards q over a travel lambda_q, kappa of it creeping (Dahl / Duhem "
    "type, playscope.fit.relax): z' = R[z] before f_remain. Residual: a rounded extra lag of about "
    "kappa*lambda against the direction of motion, taken up over a few lambda of travel after each "
    "reversal, the same at every speed (a time-domain lag grows with speed); nothing while q holds.",
))
_reg(Effect(
    "handeye_direction", "direction-dependent hand-eye offset", "camera",
    (Param("delta_deg", "deg", 0.0, -5.0, 5.0, (1.0, 1.5)),),
    "The instrument shifts in its channel with the direction of distal motion: cam_T_base rotated "
    "by +-delta about the camera y axis (paper V-B). Residual in c: a step of ~2*delta (converted "
    "through J) at each motion onset, constant between onsets; in the image a jump along u.",
))
_reg(Effect(
    "camera_delay", "camera delay and frame jitter", "camera",
    (Param("delay_s", "s", 0.0, -0.2, 0.5, (0.04, 0.08)), Param("jitter_s", "s", 0.0, 0.0, 0.05)),
    "Frames show the scene delay_s (+ N(0, jitter_s)) earlier than their time stamp says, beyond "
    "the declared t_delay_s. Residual: proportional to dc/dt (peaks in cross-correlation with "
    "image velocity at lag delay_s); jitter adds variance growing with speed^2.",
))
_reg(Effect(
    "lens_distortion", "unmodelled lens distortion", "camera",
    (Param("dk1", "1", 0.0, -0.5, 0.5, (-0.15, -0.3)),),
    "True radial k1 differs from the calibrated one by dk1. Residual: image-plane error growing "
    "with the radius from the principal point, radial direction; in c only a monotone re-mapping "
    "that f_remain absorbs.",
    image_only=True,
))
_reg(Effect(
    "nonconstant_curvature", "non-constant curvature", "camera",
    (Param("gamma", "1", 0.0, -0.9, 0.9, (0.4, 0.7)),),
    "Curvature varies linearly along the section, kappa(s) = c/L (1 + gamma (2s/L - 1)), the total "
    "bend c unchanged. Residual: the marker leaves the constant-curvature path h(g(c)) (error "
    "across the path, growing with |c|); in c a re-mapping that f_remain absorbs.",
    image_only=True,
))
_reg(Effect(
    "drift", "slow drift over time", "distal",
    (Param("rate_deg_per_min", "deg/min", 0.0, -10.0, 10.0, (0.6, 1.2)),),
    "A configuration offset growing linearly with wall-clock time. Residual: a trend over time, "
    "independent of q, c, direction and travel since reversal; grows on held-out data after the fit.",
))

# Out of library: used by the blind self-test to check that the diagnosis says "unexplained".
_reg(Effect(
    "breathing", "periodic disturbance (breathing-like)", "distal",
    (Param("amp_deg", "deg", 0.0, 0.0, 10.0, (1.5,)), Param("period_s", "s", 4.0, 0.5, 20.0)),
    "Sinusoidal offset in time. Not in the diagnosis library (out-of-library case).",
    in_library=False,
))
_reg(Effect(
    "tissue_catch", "random catches on tissue", "distal",
    (Param("amp_deg", "deg", 0.0, 0.0, 10.0, (1.5,)), Param("rate_hz", "1/s", 0.1, 0.0, 2.0)),
    "Random offset steps (telegraph process) in time. Not in the diagnosis library.",
    in_library=False,
))

LIBRARY = [e for e in EFFECTS.values() if e.in_library]


def parse_effect(spec: str) -> tuple[str, dict[str, float]]:
    """Parse ``NAME[:p=v[,p=v]]`` (CLI form) into (name, params). Unknown names or parameters raise
    ValueError. A bare NAME takes the first self-test strength of its first parameter."""
    name, _, rest = spec.partition(":")
    if name not in EFFECTS:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}")
    e = EFFECTS[name]
    params = e.off()
    if not rest:
        p0 = e.params[0]
        params[p0.name] = p0.strengths[0] if p0.strengths else p0.hi
        return name, params
    for item in rest.split(","):
        k, _, v = item.partition("=")
        e.param(k.strip())
        try:
            x = float(v)
        except ValueError:
            raise ValueError(f"--effect {spec}: {k.strip()}={v!r} is not a number") from None
        if not math.isfinite(x):
            raise ValueError(f"--effect {spec}: {k.strip()} must be a finite number, got {v!r}")
        params[k.strip()] = x
    return name, params


@dataclass
class EffectSet:
    """Effects switched on in a simulation: {name: {param: value}}."""

    on: dict[str, dict[str, float]] = field(default_factory=dict)

    def get(self, name: str, param: str) -> float:
        """Value of ``param`` of effect ``name``; its "off" value when the effect is not on."""
        e = EFFECTS[name]
        return float(self.on.get(name, {}).get(param, e.param(param).off))

    def active(self, name: str) -> bool:
        if name not in self.on:
            return False
        e = EFFECTS[name]
        p0 = e.params[0]
        return self.on[name].get(p0.name, p0.off) != p0.off
