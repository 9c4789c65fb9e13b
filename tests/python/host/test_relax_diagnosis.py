"""The diagnosis tells the travel-domain relaxation from the time-domain lag on records at two
speeds: fitted on each speed alone, the lag's tau moves with the speed and the relaxation's lambda
does not; fitted on a record holding both speeds, the planted one wins (lower residual), both ways.
Synthetic records of the diagnosis' own Data (play of constant width, a cubic f, angle noise)."""

import numpy as np
import pytest

from playscope.fit import model
from playscope.diagnose.fitmodel import INTERNAL_HZ, Data, Model, lowpass
from playscope.fit.relax import Relaxation

B_MM = 0.4
SPAN = 4.0


def f(z):
    return 12.0 * z + 0.3 * z ** 3


def path(periods_s, cycles=3):
    """Triangle waves of amplitude SPAN/2, cycles at each period in turn; t, q at INTERNAL_HZ."""
    qs = []
    for p in periods_s:
        t = np.arange(0, cycles * p, 1 / INTERNAL_HZ)
        ph = (t / p + 0.25) % 1.0
        qs.append(SPAN / 2 * (4 * np.abs(ph - 0.5) - 1))
    q = np.concatenate(qs)
    return np.arange(q.size) / INTERNAL_HZ, q


def record(periods_s, planted: str, seed=0) -> Data:
    t, q = path(periods_s)
    z = model.play_operator(q, lambda x: np.full_like(np.asarray(x, float), B_MM))
    if planted == "relax":
        c = f(Relaxation(0.5, 0.6).direct(z))
    else:  # a creep of fixed time constant after f (the diagnosis' cable_elongation)
        c = f(z)
        c = c + 0.5 * (lowpass(c, 0.8, INTERNAL_HZ) - c)
    y = c + np.random.default_rng(seed).normal(0, 0.05, c.size)
    return Data(t, q, t.copy(), y, 0.0, f"{planted} at {periods_s} s")


def fitted(d: Data, effect: str):
    m = Model(d, [effect])
    fit = m.fit(np.ones(d.t_m.size, bool), uncertainty=False)
    p = dict(zip(fit.names, fit.theta))
    return fit, p


@pytest.mark.parametrize("planted", ["relax", "lag"])
def test_two_speeds_tell_them_apart(planted):
    slow, fast = record([20.0], planted), record([5.0], planted)
    tau = [np.exp(fitted(d, "cable_elongation")[1]["cable_elongation.log_tau"]) for d in (slow, fast)]
    lam = [np.exp(fitted(d, "travel_relaxation")[1]["travel_relaxation.log_lambda_q"]) for d in (slow, fast)]
    print(planted, "tau slow/fast", tau, "lambda slow/fast", lam)
    if planted == "relax":
        # a lag fitted to a travel creep: tau tracks the period (4x here); lambda stays
        assert tau[0] / tau[1] > 2.5
        assert abs(np.log(lam[0] / lam[1])) < np.log(1.25)
        assert abs(lam[0] - 0.6) / 0.6 < 0.2
    else:
        # a true time constant: tau stays, while lambda (a travel) moves with the speed
        assert abs(np.log(tau[0] / tau[1])) < np.log(1.25)
        assert lam[0] / lam[1] < 1 / 2.5
    both = record([20.0, 5.0], planted, seed=1)
    f_lag, _ = fitted(both, "cable_elongation")
    f_rel, _ = fitted(both, "travel_relaxation")
    print(planted, "both speeds: rss lag", f_lag.rss, "relax", f_rel.rss)
    winner = "relax" if f_rel.bic < f_lag.bic else "lag"
    assert winner == planted
