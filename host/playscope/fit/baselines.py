"""The baselines the evaluation sets beside the method: a straight line (no backlash) and a
constant-width play with a degree-5 polynomial, both by least squares.

Units: q in actuator units, c in deg.
"""

from __future__ import annotations

import numpy as np

from . import model

def fit_linear(q: np.ndarray, c: np.ndarray):
    """Baseline: c = a q + b by least squares, no backlash. Returns a callable q -> c."""
    a, b = np.polyfit(q, c, 1)
    return lambda x: a * np.asarray(x, float) + b


def fit_constant_play(q_c: np.ndarray, c: np.ndarray, degree: int = 5, w_max: float | None = None):
    """Baseline: constant-width play operator + degree-5 polynomial, both by least squares.

    For a width w the centre z(q; w) is known (eq. 3), the polynomial is then linear least
    squares; w minimises the residual (bounded scalar search, after a coarse grid so a
    local minimum is not taken). q_c, c: (F,) in time order. Returns (w, f, B callable).
    """
    from scipy.optimize import minimize_scalar

    span = float(q_c.max() - q_c.min())
    w_max = 0.5 * span if w_max is None else w_max
    zsc = max(span, 1e-12)

    def fit(w):
        z = model.play_operator(q_c, model.constant(w), b_max=w)
        V = np.vander((z - q_c.min()) / zsc, degree + 1)
        coef, *_ = np.linalg.lstsq(V, c, rcond=None)
        return float(np.sum((V @ coef - c) ** 2)), coef

    grid = np.linspace(0, w_max, 41)
    costs = [fit(w)[0] for w in grid]
    i = int(np.argmin(costs))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    w = float(minimize_scalar(lambda w: fit(w)[0], bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-6 * max(span, 1)}).x) if hi > lo else float(grid[i])
    coef = fit(w)[1]
    q0 = float(q_c.min())
    return w, (lambda x: np.polyval(coef, (np.asarray(x, float) - q0) / zsc)), model.constant(w)
