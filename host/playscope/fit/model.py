"""Double-precision reference models of the paper: play operator with B(q) (eqs. 2, 3),
inverse compensator (eqs. 4, 5, 9), f_coarse, constant-curvature g and camera h (eqs. 6-8).

Conventions: q in actuator units (mm of cable or deg of command), B in the same units,
c in degrees unless a name says _rad, image points in px, lengths in mm. Functions take
callables B(q) and f(q) that accept and return float64 arrays of any shape, so a spline,
a constant or a lookup table can be plugged in. These are the float references the
fixed-point firmware (firmware/core, reached through playscope.base.native) is checked against.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

ArrayFn = Callable[[np.ndarray], np.ndarray]


# --------------------------------------------------------------------------- helpers

def piecewise_linear(x: np.ndarray, y: np.ndarray) -> ArrayFn:
    """y(x) by linear interpolation of samples (x increasing, shape (n,)), held beyond the ends
    (the on-line B grid of online.py, as the board's lookup table holds it)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    return lambda q: np.interp(q, x, y)


def constant(value: float) -> ArrayFn:
    """B(q) = value for every q (constant play, the model of Reilink et al.)."""
    return lambda q: np.full(np.shape(q), float(value))


def held_direction(x: np.ndarray, tol: float = 0.0, before: float = 1.0) -> np.ndarray:
    """Direction of motion of x (N,): the sign (+1/-1) of its last change larger than tol, held
    while x is still (eq. 4, third case); ``before`` until x first moves. The one copy of the
    direction hold of the compensator, the simulator and the diagnosis."""
    x = np.asarray(x, float)
    dx = np.diff(x, prepend=x[:1])
    d = np.where(np.abs(dx) > tol, np.sign(dx), 0.0)
    idx = np.where(d != 0, np.arange(d.size), 0)
    np.maximum.accumulate(idx, out=idx)
    out = d[idx]
    out[out == 0] = before
    return out


FREEZE_FROM = 40  # bisection step from which brackets that stopped moving are left out


def _solve_increasing(fn: ArrayFn, target: np.ndarray, lo: np.ndarray, hi: np.ndarray, iters: int = 64) -> np.ndarray:
    """Vectorised bisection for fn(z) = target with fn increasing on [lo, hi]; 64 halvings
    reach the float64 resolution of any bracket narrower than 2^11 units. fn acts element by
    element (B(q) and the like). A bracket that a step leaves unchanged (it reached the float
    resolution) would be left unchanged by every later step (the same mid, the same fn(mid)),
    so from step FREEZE_FROM on only the brackets still moving are evaluated: the same result,
    bit for bit, with about a fifth fewer evaluations of fn (on the bench session most
    brackets stop moving between steps 48 and 60 of the 64)."""
    lo = np.array(lo, float, copy=True)
    hi = np.array(hi, float, copy=True)
    tgt = np.broadcast_to(np.asarray(target, float), lo.shape)
    shape = lo.shape
    lo, hi, tgt = lo.ravel(), hi.ravel(), tgt.ravel()
    act = None  # flat indices of the brackets still moving (None: all)
    for it in range(iters):
        if act is None:
            mid = 0.5 * (lo + hi)
            up = fn(mid) < tgt
            new_lo = np.where(up, mid, lo)
            new_hi = np.where(up, hi, mid)
            if it >= FREEZE_FROM:
                moved = (new_lo != lo) | (new_hi != hi)
                if not moved.all():
                    act = np.flatnonzero(moved)
            lo, hi = new_lo, new_hi
        else:
            if act.size == 0:
                break
            a_lo, a_hi = lo[act], hi[act]
            mid = 0.5 * (a_lo + a_hi)
            up = fn(mid) < tgt[act]
            new_lo = np.where(up, mid, a_lo)
            new_hi = np.where(up, a_hi, mid)
            lo[act], hi[act] = new_lo, new_hi
            act = act[(new_lo != a_lo) | (new_hi != a_hi)]
    return (0.5 * (lo + hi)).reshape(shape)


def _b_bound(B: ArrayFn, q: np.ndarray, b_max: float | None) -> float:
    if b_max is not None:
        return float(b_max)
    # Sample B over a margin around the data: the brackets only need an upper bound.
    lo, hi = float(np.min(q)), float(np.max(q))
    span = max(hi - lo, 1.0)
    grid = np.linspace(lo - span, hi + span, 4097)
    return float(np.max(np.abs(B(grid)))) * 1.01 + 1e-9


def _on_distinct(q: np.ndarray, solve: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """solve(q) for an element-wise solve, run on q's distinct values only and scattered back
    (np.unique): the same values bit for bit, since each element's bisection reads only its own
    target and bracket (_solve_increasing). An encoder's q is counts (a 1-hour 1 kHz log thinned
    to 143,000 samples holds ~5,500 values of 1 um), so the play's z_up/z_down at the encoder
    rate bisect ~25x fewer points. q without repeats (a simulated q) is solved as it is."""
    flat = q.ravel()
    u, inv = np.unique(flat, return_inverse=True)
    if 2 * u.size > flat.size:
        return solve(q)
    return solve(u)[inv.ravel()].reshape(q.shape)


# --------------------------------------------------------------------------- eq. 2, 3
def z_up(q: np.ndarray, B: ArrayFn, b_max: float | None = None) -> np.ndarray:
    """Centre position reached going up: z with z + B(z)/2 = q (eq. 2 reindexing, f2 = f(z_up)).

    q: array, actuator units. B: width callable, >= 0 with |B'| < 2 so the solution is
    unique. b_max: an upper bound of B (found by sampling when None). Returns z, shape of q.
    """
    q = np.asarray(q, float)
    bm = _b_bound(B, q, b_max)
    return _on_distinct(q, lambda v: _solve_increasing(lambda z: z + 0.5 * B(z), v, v - 0.5 * bm - 1e-9, v + 1e-9))


def z_down(q: np.ndarray, B: ArrayFn, b_max: float | None = None) -> np.ndarray:
    """Centre position reached going down: z with z - B(z)/2 = q (f1 = f(z_down)). See z_up."""
    q = np.asarray(q, float)
    bm = _b_bound(B, q, b_max)
    return _on_distinct(q, lambda v: _solve_increasing(lambda z: z - 0.5 * B(z), v, v - 1e-9, v + 0.5 * bm + 1e-9))


def envelopes(q: np.ndarray, B: ArrayFn, f: ArrayFn) -> tuple[np.ndarray, np.ndarray]:
    """Envelope functions of eq. 2 at actuator positions q: (f2(q), f1(q)) = (f(z_up(q)), f(z_down(q))).

    f2 is followed while q increases, f1 while it decreases. Shapes of q, in the unit of f."""
    return f(z_up(q, B)), f(z_down(q, B))


def play_operator(q: np.ndarray, B: ArrayFn, z0: float | None = None, b_max: float | None = None) -> np.ndarray:
    """Centre trajectory of the play operator (eq. 3 in actuator space).

    z[k] = min(z_down(q[k]), max(z_up(q[k]), z[k-1])), z[-1] = z0 (default: q[0], the
    play centred). q: (N,) actuator units. Returns z (N,); the direct model is c = f(z).
    """
    q = np.asarray(q, float).ravel()
    return play_edges(z_up(q, B, b_max), z_down(q, B, b_max), float(q[0] if z0 is None else z0))


def play_edges(z_lo, z_hi, z0: float) -> np.ndarray:
    """play_on_edges (eq. 3) through the C kernel when it is compiled (base/kernels.c, bit for bit
    the same: tests/python/sim/test_diagnose_kernels.py), else play_on_edges itself. The one
    dispatch the model, the record model and the diagnosis call. z_lo, z_hi: (N,); returns z (N,)."""
    from ..base import kernels

    return kernels.play_on_edges(z_lo, z_hi, z0) if kernels.available() else play_on_edges(z_lo, z_hi, z0)


def play_on_edges(z_lo, z_hi, z0: float) -> np.ndarray:
    """The play operator's recursion on precomputed band edges: z[k] = min(z_hi[k], max(z_lo[k],
    z[k-1])), z[-1] = z0 (eq. 3; z_lo = z_up(q), z_hi = z_down(q) for the paper's play). The one
    kernel of the model, the simulator and the diagnosis. z_lo, z_hi: (N,) with z_lo <= z_hi.
    Returns z (N,). Sequential by nature; Python floats (~5x faster here than numpy scalars)."""
    lo = np.asarray(z_lo, float).tolist()
    hi = np.asarray(z_hi, float).tolist()
    out = [0.0] * len(lo)
    p = float(z0)
    for k in range(len(lo)):
        p = min(hi[k], max(lo[k], p))
        out[k] = p
    return np.asarray(out)


def direct_model(q: np.ndarray, B: ArrayFn, f: ArrayFn, z0: float | None = None) -> np.ndarray:
    """Predicted configuration c[k] = f(z[k]) with z from play_operator (eqs. 2, 3).

    q: (N,) actuator units; returns c (N,) in the unit of f (deg for the models here)."""
    return f(play_operator(q, B, z0))


# --------------------------------------------------------------------------- eq. 4, 5, 9
def compensator(c_ref: np.ndarray, B: ArrayFn, f_inv: ArrayFn, f_sign: int) -> np.ndarray:
    """Inverse model q*[k] for a reference c*[k] (eq. 4 with eq. 5 for f_coarse, eq. 9 for f_remain).

    q*[k] = f^-1(c*[k]) + dir[k] * f_sign * B(f^-1(c*[k])) / 2, with dir = sign(c*[k] - c*[k-1])
    held when c* does not change (eq. 4, third case) and 0 before c* first moves. f_sign =
    sign(f'): +1 gives eq. 5's signs, -1 turns them into eq. 9's. c_ref: (N,) deg; returns
    q* (N,) actuator units. This is the unsmoothed step of comp_step() (firmware/core/comp.h).
    """
    c_ref = np.asarray(c_ref, float).ravel()
    if f_sign not in (1, -1):
        raise ValueError("f_sign must be +1 or -1")
    # Hold the last non-zero direction (eq. 4: q*[k] = q*[k-1] when c* is still).
    dirs = held_direction(c_ref, 0.0, before=0.0)
    qc = f_inv(c_ref)
    return qc + dirs * f_sign * 0.5 * B(qc)


# --------------------------------------------------------------------------- f_coarse
def f_coarse(q: np.ndarray, q_per_rad: float) -> np.ndarray:
    """Nominal transmission: c [deg] = degrees(q / q_per_rad). q: actuator units, any shape."""
    return np.degrees(np.asarray(q, float) / q_per_rad)


def f_coarse_inv(c_deg: np.ndarray, q_per_rad: float) -> np.ndarray:
    """Inverse of f_coarse: q = radians(c) * q_per_rad."""
    return np.radians(np.asarray(c_deg, float)) * q_per_rad


# --------------------------------------------------------------------------- g, h (eq. 6)
def constant_curvature(c_deg: np.ndarray, bend_length_mm: float, tip_length_mm: float) -> np.ndarray:
    """g(c): tip marker position in the base frame for a planar constant-curvature bend.

    The section leaves the base along +z and bends in the x-z plane by angle c (positive
    towards +x): end of the arc at (L/c (1 - cos c), 0, L/c sin c), then a rigid tip of
    length l along the end tangent (sin c, 0, cos c). Series used for |c| < 1e-4 rad so
    g is smooth through the straight pose. c_deg: any shape; returns (..., 3) in mm.
    """
    c = np.radians(np.asarray(c_deg, float))
    L = float(bend_length_mm)
    small = np.abs(c) < 1e-4
    cs = np.where(small, 1.0, c)
    x_over_L = np.where(small, c / 2 - c**3 / 24, (1 - np.cos(cs)) / cs)
    z_over_L = np.where(small, 1 - c**2 / 6, np.sin(cs) / cs)
    x = L * x_over_L + tip_length_mm * np.sin(c)
    z = L * z_over_L + tip_length_mm * np.cos(c)
    return np.stack([x, np.zeros_like(x), z], axis=-1)


def project(P_base: np.ndarray, R: np.ndarray, t_mm: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """h(P): pinhole projection with OpenCV's distortion (k1 k2 p1 p2 k3), as cv2.projectPoints.

    P_base: (..., 3) mm in the base frame; R (3, 3), t_mm (3,): cam_T_base; K (3, 3) px;
    dist (5,). Returns (..., 2) px. Points behind the camera give NaN.
    """
    P = np.asarray(P_base, float) @ np.asarray(R, float).T + np.asarray(t_mm, float)
    Z = P[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(Z > 0, P[..., 0] / Z, np.nan)
        y = np.where(Z > 0, P[..., 1] / Z, np.nan)
    k1, k2, p1, p2, k3 = np.asarray(dist, float)
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    K = np.asarray(K, float)
    u = K[0, 0] * xd + K[0, 1] * yd + K[0, 2]
    v = K[1, 1] * yd + K[1, 2]
    return np.stack([u, v], axis=-1)


class ImageModel:
    """Q_hat = h(g(c)) (eq. 6) and its interaction matrix J = d(h o g)/dc (eq. 7).

    Built from a session's robot, camera and hand-eye (playscope.io.session). c in deg,
    Q in px; J in px/deg.
    """

    def __init__(self, robot, camera, hand_eye):
        self.L = robot.bend_length_mm
        self.l = robot.tip_length_mm
        self.R = np.asarray(hand_eye.R, float)
        self.t = np.asarray(hand_eye.t_mm, float)
        self.K = np.asarray(camera.K, float)
        self.dist = np.asarray(camera.dist, float)

    def __call__(self, c_deg: np.ndarray) -> np.ndarray:
        """Q_hat (..., 2) px for c (...) deg (eq. 6)."""
        return project(constant_curvature(c_deg, self.L, self.l), self.R, self.t, self.K, self.dist)

    def jacobian(self, c_deg: np.ndarray, h: float = 1e-4) -> np.ndarray:
        """J (..., 2) px/deg by central differences (eq. 7): g and h are smooth, and a
        1e-4 deg step keeps truncation (~h^2) and rounding (~1e-16/h) both below 1e-8 px/deg."""
        c = np.asarray(c_deg, float)
        return (self(c + h) - self(c - h)) / (2 * h)

    def estimate_c(self, Q: np.ndarray, c0: np.ndarray, iters: int = 30, lam0: float = 1e-3,
                   tol: float = 1e-10) -> tuple[np.ndarray, np.ndarray]:
        """Levenberg-Marquardt estimate of c per frame minimising ||Q - h(g(c))||^2 (eq. 8).

        One scalar unknown per frame, so J^T J is a scalar and eq. 8 reads
        c_j = c_{j-1} + J^T (Q - Q_hat) / ((1 + lambda) J^T J); all frames iterate together
        (vectorised), each with its own lambda (x10 on a rejected step, /10 on an accepted one).
        Q: (N, 2) px, NaN rows skipped; c0: (N,) deg initial guesses (e.g. f_coarse(q)).
        Returns (c (N,) deg, residual norm (N,) px); NaN where Q is NaN.
        """
        Q = np.asarray(Q, float)
        c = np.array(np.broadcast_to(c0, Q.shape[:1]), float)
        ok = np.all(np.isfinite(Q), axis=-1)
        lam = np.full(c.shape, lam0)
        r = Q - self(c)
        cost = np.sum(r * r, axis=-1)
        for _ in range(iters):
            J = self.jacobian(c)
            JtJ = np.sum(J * J, axis=-1)
            Jtr = np.sum(J * r, axis=-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(ok & (JtJ > 0), Jtr / ((1 + lam) * JtJ), 0.0)
            c_new = c + step
            r_new = Q - self(c_new)
            cost_new = np.sum(r_new * r_new, axis=-1)
            better = ok & (cost_new < cost)
            c = np.where(better, c_new, c)
            r = np.where(better[:, None], r_new, r)
            cost = np.where(better, cost_new, cost)
            lam = np.where(better, lam / 10, lam * 10)
            if np.all(np.abs(step[ok]) < tol):
                break
        c = np.where(ok, c, np.nan)
        return c, np.where(ok, np.sqrt(cost), np.nan)
