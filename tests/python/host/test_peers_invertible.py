"""The invertible forms of the textbook peers (playscope.fit.peers): the generalized PI with its
memoryless cubic held increasing (IncreasingGPI) and the modified PI with a monotone output
(ModifiedPI(monotone=True)). Each on one short synthetic path whose fitted unconstrained peer
turns back, so the constraint has something to do."""

from __future__ import annotations

import numpy as np

from playscope.fit.peers import GeneralizedPI, IncreasingGPI, ModifiedPI


def _path(n_per=200):
    """Three strokes of decreasing size about q = 0..5 and a last full one: every play threshold
    of the peers' rule closes a loop, and the first branch after each reversal is visited."""
    pts = [0.0, 5.0, 1.0, 4.0, 2.0, 5.0, 0.0]
    seg = np.linspace(0, 1, n_per, endpoint=False)
    return np.concatenate([a + (b - a) * 0.5 * (1 - np.cos(np.pi * seg)) for a, b in zip(pts[:-1], pts[1:])] + [[0.0]])


def _plant(q):
    """A play of width 1.6 then a curve that flattens: right after a reversal only a falling
    memoryless term can follow c, so the unconstrained generalized PI's cubic turns back."""
    from playscope.fit.transition import play_ops

    z = play_ops(q, np.array([0.8]))[:, 0]
    return 30.0 + 12.0 * z - 1.2 * z ** 2


def test_increasing_gpi_is_increasing_in_q_where_the_peer_is_not():
    q = _path()
    c = _plant(q)
    g = GeneralizedPI.fit(q, c)
    x = np.linspace(-1.5, 1.5, 301)  # beyond the calibration range too: m is continued linearly
    slope_peer = np.polynomial.polynomial.polyval(x, np.polynomial.polynomial.polyder(g.poly))
    m = IncreasingGPI.fit(q, c)
    assert slope_peer.min() < 0  # the peer's memoryless part turns back: it has no inverse
    dm = np.diff(m.memoryless(x))
    assert np.all(dm > 0), dm.min()
    assert np.all(m.w >= 0)
    # Each branch from any play state is increasing: the operators' sum only moves with q, and m does.
    c_hat = m.predict(q)
    dq, dc = np.diff(q), np.diff(c_hat)
    moving = np.abs(dq) > 1e-9
    assert np.all(dc[moving] * np.sign(dq[moving]) > 0)
    # It still follows the plant about as well as the peer (measured 1.01 deg against the peer's
    # 0.91 and a straight line's 4.2).
    assert np.sqrt(np.mean((c_hat - c) ** 2)) < 1.25 * np.sqrt(np.mean((g.predict(q) - c) ** 2))


def test_modified_pi_monotone_option_gives_a_monotone_output():
    q = _path()
    from playscope.fit.transition import play_ops

    z = play_ops(q, np.array([0.8]))[:, 0]
    c = 30.0 + 12.0 * z - 2.2 * z ** 2  # turns back at z = 2.7: the free output spline follows it
    free, mono = ModifiedPI.fit(q, c), ModifiedPI.fit(q, c, monotone=True)

    def slopes(m):
        y = play_ops(q, m.r) @ m.w
        return np.diff(m.g(np.linspace(y.min(), y.max(), 401)))

    d_free, d_mono = slopes(free), slopes(mono)
    assert d_free.min() < 0 < d_free.max()  # the free output turns back: no inverse
    assert np.all(d_mono >= -1e-9) and d_mono.max() > 0  # non-decreasing (flat where c turns back)
    assert mono.w[0] > 0 and np.all(mono.w >= 0)  # w_0 > 0: the inverse PI exists
