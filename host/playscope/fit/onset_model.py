"""Eq. 1 from one model of the whole image record (paper section III-A).

The marker at frame j, stamped t_j on the encoder's clock, shows the scene at tau_j = t_j - t_delay:

    Q_j = G(z_j) + G'(z_j) (g_stop x_stop(tau_j) + g_start x_start(tau_j))   image path; tip mode
          + S_tip(tau_j) R(Q_j; a_tip) + S_motor(tau_j) R(Q_j; a_motor)             registration terms
          + e_j                                                                   noise

  z       the play's output (eq. 3): the encoder's q through a play of width B, B a cubic
          B-spline over the travel; z_j = z(tau_j). No pose is estimated: G, a cubic B-spline
          curve in the image per axis, absorbs f_remain and the camera (eq. 1 needs no pose).
          Where the width is read is a property of the plant, chosen by the same criterion as
          the terms: at the input, the band q -+ B(q) / 2 (a play whose width follows the motor's
          side, e.g. the cable's slack at the drum), or at the output, z -+ B(z) / 2 = q, the
          paper's eq. 2 (f_1,2(q -+ B(q) / 2) = f(q): a width that follows the bending section's
          configuration). They differ by B' B / 2 along each leg, where a narrow bump of B is read
          a fraction of its height low in the wrong form. At the output, eq. 1 is exact:
          |q2 - q1| = B(z_hold) with z_hold = (q1 + q2) / 2.
  z0      the play's first state (eq. 3's z[-1]): where in its band the output sits when the
          record starts is unknown (a carrier left anywhere by the last motion), so it is a
          parameter of every fit, z0 = lo_0 + expit(x0) (hi_0 - lo_0) on the first sample's band
          (x0 = 0: the middle). It sets z until the first drag, and the first onset when that
          drag follows a reversal. Held at the motor's position instead, the frames of a first
          hold off it found no level of the path to sit on, and a tip registration switch was
          the term that gave them one (render_c, no effect rendered: BIC 7,314 -> 7,274 with the
          switch, B 5.5 % off; with z0 7,044 and no switch, B 0.4 %).
  x_stop, x_start
          a damped tip mode (frequency f, damping ratio zeta, shared by the record) driven by the
          play output's acceleration (base excitation, x'' + 2 zeta w x' + w^2 x = -z''), split
          into the part that slows the tip (a stop) and the part that starts it (an onset), each
          with its own gain; along the path's tangent G'. Which deceleration drives a stop is a term,
          ring_motor (entering, as every term, by the BIC, only onto the ring): the play output's
          (base excitation through the play), or the motor's, its whole velocity change at the
          reversal (a tip kicked by the same amount at every reversal, whatever the play's width
          there). Where the width varies along the travel they differ: the output moves at the
          motor's speed times 1 -+ B'(q) / 2 while dragged (read at the input), so its stops' drives
          differ by up to B' / 2 of the ring from leg to leg and direction to direction, which B's
          own slope then takes up. On s7-marker-096 of LOCKBOX7_300 (a constant-speed triangle, a
          5.65 Hz mode kicked at each reversal by a fixed amount, B' / 2 up to 8 %, the ring building
          up to 26 px over legs 1.5 of its periods long): with the output's drive B was 13.4 % off;
          re-rendered with the kick following the output's speed, 3.4 % (measured beside a change
          to the ring's direction that was not kept, CHANGELOG.md); with ring_motor on the record as
          drawn, 2.4 %.
  S_tip, S_motor
          +-1 with the direction the tip (resp. the motor) last moved in: a registration that
          switches with the bending direction. R is the image motion of a small rotation
          a = (a_x, a_y, a_z) rad of the camera frame (the rotational motion field, Longuet-Higgins
          & Prazdny 1980): with x = (u - c_u) / f, y = (v - c_v) / f the point's normalised image
          position (principal point c and focal length f from the session's K),
          R = f [a_x (x y, 1 + y^2) + a_y (-(1 + x^2), -x y) + a_z (y, -x)]. Three coefficients
          shared by both image axes, evaluated at the observed point (the offset moves it by a few
          px: a second-order change). Why this form and not a free offset per axis: a
          registration offset along the path is a change of B at the image's level, and a free
          offset (or one linear along the path) takes up B's own variation wherever the path is
          straight or a parabola; the rigid form is what tells the two apart where the path
          curves, and the onsets' timing does the rest.
  the shift
          A translation of the instrument in its channel moves the whole image by one amount; a
          rotation about the perpendicular axis moves it so only to x^2 of it, and at a jump of
          tens of px its perspective parts (x^2, x y) are px along the path against a noise of
          tenths (s6-marker-045 of LOCKBOX6_300, a 2.8 deg channel translation at 25 fps: B
          5.9 % off with the rotation alone). So a switch term's shift_tip / shift_motor puts the
          image's translation (t_u, t_v) px in its rotation's place (linear: two coefficients),
          entering, as every term, by the BIC and only onto its switch (B 0.6 % off there). A
          translation is as rigid as the rotation, one vector for the whole path, so it is told
          from B as the rotation is. Why in the rotation's place and not beside it: the two
          together leave the jump's x^2 part free along the path, which is B's own variation at
          the image's level (dev-reg0-swings25-fast, a rotation switching at the onset: the BIC
          admitted the pair and B was 7.1 % off; with the forms exclusive, 4.6 %).
          A registration that follows the image can switch only once a frame shows the reversal,
          so within one frame period of it; with the switch time unknown and uniform within a
          lag L, a frame in that window shows the old or the new registration, the new one with
          probability p (its share of the window): a two-point mixture, fitted by EM (Dempster,
          Laird & Rubin 1977). The E-step gives each frame within a frame period of a window its
          posterior share gamma = expit(logit p + rho_old - rho_new) (rho: the frame's Huber loss
          at each level; p clipped into [EPS_SHARE, 1 - EPS_SHARE]). The M-step's least squares:
          the frame at the expected sign s_prev + gamma (s_new - s_prev), the rotation under the
          levels' spread sum w (s_new - s_prev)^2 gamma (1 - gamma) (R a)^2 (the two levels'
          squares, Var = E x^2 - (E x)^2), and one row per frame sign(p - gamma) sqrt(2 KL(gamma
          || p)): the one place the frame's timing enters, smooth in the onset, the delay and L
          (the log of a share linear in them is concave, so each switch has one optimum). The
          BIC scores the frame's marginal likelihood, -2 ln(p e^-rho_new + (1 - p) e^-rho_old).
          Before a model's first E-step (the start's scoring), the frame has the Gaussian stand-in:
          the expected share p as its mean (a linear ramp), p (1 - p) J^2 added to its variance.
          The slide: a registration that comes from the instrument settling in its channel, or a
          camera mount that gives way, moves over tens of ms rather than stepping, so a frame can
          show it mid way, between the two levels, where the two-point mixture can only call it an
          outlier of both and its timing follows whichever level is nearer (16 % off in B on a
          channel rendering). A switch term slide_tip / slide_motor (entering, as every term, by the
          BIC, only onto its switch) lets the switch, started at u ~ U(0, L), slide for a duration
          ~ U(0, D), D fitted up to SLIDE_MAX_S (or a frame period if longer: a settling is time,
          and at 60 fps a one-frame bound took a 40 ms channel slide only in part, B 5-6 % off on
          three rows of marker_render). Why no longer: a slide the frames
          resolve as a motion runs along the image path wherever the registration does (the
          common case), where it is the plant's own take-up after the play; offered up to half the
          interval between reversals, it took the main job's transition (a 0.48 s slide along
          the path, 0.333 deg against 0.211). The shares of frames still at the old
          level, u >= since, and already at the new one, u + duration <= since, are closed-form
          (`_switch_shares`; D = 0 gives the stepped switch's), and the rest are mid slide, at a
          level h in (0, 1) of their own whose likelihood is integrated over h (`_mid_level`:
          uniform in h, Gaussian along the jump, the Occam factor that keeps a frame at either
          level from reading as mid slide). The E-step then shares a frame among three levels, the
          M-step's expected sign and second moment are the three-level ones, and the timing rows
          split 2 KL(gamma || p) by the chain rule into new-or-not and old-or-mid (`_kl_rows`).
  e_j     Huber noise (k = 1.345 sigma_j, 95 % efficiency at the Gaussian; Huber 1964), sigma_j^2
          = sigma^2 (the record's model-free noise; plus the stand-in's share variance above), by
          iteratively reweighted least squares.

Fit: variable projection (Golub & Pereyra 1973): G, the gains and the registration offsets are
linear and solved exactly for each value of the nonlinear parameters theta = (t_delay, B's
coefficients[, the tip mode's frequency and damping][, the switches' lags and slides], z0), which
scipy.optimize.least_squares fits (Levenberg-Marquardt, MINPACK) with Kaufman's variable-projection
Jacobian (`RecordModel.jacobian`: the play's, the onsets', the switches' and the tip mode's
derivatives in closed form; the tip mode's frequency and damping by central differences). The
configured delay enters as a Gaussian prior of sd one frame period / sqrt(12) (a delay measured in
whole frames is known to that), not as a value a rule overrides.

The exposure. A camera integrates the scene over its exposure e (0 <= e <= T, the frame period),
so the image's mean lag behind the encoder, the t_delay of the model above, is the delay to the
exposure's end plus e / 2 (the mean of a motion over the window is its value at the window's
middle). The corner of an onset is rounded besides: second order where the play is taken up over
several frames, but the onset's whole signal where a swing takes it up within a frame or so and the
exposure is a sizeable part of the frame. A 20 ms exposure at 25 fps (half a frame: an endoscope's
camera in dim light) took a tip mode, a tip switch and its slide in its stead, B 7.7 % off on a 90 s
rendering. So the blur is a term, expo: each frame's z is its mean over [tau - e / 2, tau + e / 2]
(the midpoint rule on EXPO_NODES nodes; its gradients the nodes' mean), e in [T / 20, T] fitted,
entering by the same BIC as every term (with it, that rendering's B is 0.6 % off). Held on for
every record, an earlier fit of e was drawn to a whole frame by the other terms' misfits on 3 of
50 development rows; by evidence it enters where the blur is worth its parameter. The tip mode stays
read at tau. A switch is blurred as well: a step at u is seen as a ramp from u - e / 2 to
u + e / 2, so with the term a switch's window opens e / 2 before its reversal or onset and the
switch takes e plus its slide to cross (`_switch_shares`' E), which places frames part way
(a registration switching at the onset itself, dev-reg0-swings25-fast: read at tau, the frames a
few ms before each onset already show part of the new level through their exposure, and the fit
moved the onsets early, B 8.8 % off with the shift withheld; with the shift beside the rotation,
the model held B at the truth 217 worse in the BIC).
The fitted e is reported; the delay reported stays the split below. Eq. 1's
t2 - t_delay is the instant a motion starts, and the first frame to show it is the first whose
exposure ends after it, so the delay a user configures and the board's detector uses is the one
to the exposure's end, d_end = t_delay - e / 2. The record cannot tell d_end and e apart, so the
configured delay is compared with d_end, e unknown in [0, T]: the prior's residual is the
distance of t_delay from [d_cfg, d_cfg + T / 2] (the Gaussian prior on d_end with e profiled out)
and the delay reported is the d_end nearest d_cfg, clip(d_cfg, t_delay - T / 2, t_delay), its
exposure 2 (t_delay - d_end). Without a configured delay, or with one the record contradicts
(DELAY_DISAGREE_Z: wrong, so silent on the exposure), nothing splits them: the mean lag is
reported (the exposure's end is up to T / 2 earlier). The contradiction is judged against the
exposures the record allows, [0, e_max] (onset_fit.exposure_bound; e_max = T where it allows any):
a record whose swings take the play up within a frame shows a long exposure's blur at every
onset, so there a configured delay well short of the mean lag cannot be read as a long exposure.
The bound only judges: it is a conditional one that can rule out the true exposure (it did on
3 of 19 renderings exposed 8 ms with a tip mode), so it does not place the exposure's end; and it
cannot contradict a right configured delay, which lies within T / 2 of the mean lag, less than
DELAY_DISAGREE_Z prior sds (T / sqrt 12) from any band.

The spread. A tendon-sheath plant often takes its play up smoothly: after a reversal the tip first
moves once the narrowest of its strands' plays is taken up and creeps to the full drag once the
widest is (a Prandtl-Ishlinskii operator of play widths spread about B). One play has no such creep,
and the camera terms took it up in its stead: on the main job's session (the product's simulator,
widths spread by half of B, no camera effect) the search took a tip mode, both switches, their
slides and the exposure, and B came out 20 % short of the centre width. So the spread is a term,
spread: z is the mean of the plays of widths m B, m = 1 + s u, u the midpoints of SPREAD_NODES equal
parts of [-1, 1] (equal weights: a uniform spread), all from the same first state, s in
[0, SPREAD_MAX] fitted, entering by the same BIC as every term (on that session it enters alone but
for a small exposure, B within 1 % of the centre width). B is the centre width. The onsets that
time a switch which follows the tip are the narrowest play's, the tip's first motion; eq. 1's
samples are read off the centre width's play (onset_fit.samples), as without the term. Each node's
play is B's coefficients times m (B is linear in them), so its gradients are the single play's at
m cB: over cB the nodes' mean of m g, over s the mean of u g cB.

Which terms and which size of B a record takes, and from where each fit starts, is
onset_search's; fitting one model and reading eq. 1's samples off it, onset_fit's.

Units: t in s, q and B in actuator units, image points in px.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline
from scipy.special import expit, log_ndtr, logit
from scipy.signal import lfilter

from ..base import kernels
from .model import play_edges

HUBER_K = 1.345        # Huber's tuning constant, in sigma (95 % efficiency at the Gaussian; Huber 1964)
GRID_HZ_MAX = 1000.0   # the play runs on a uniform grid at the encoder's rate, at most this (1 ms timing)
RING_HZ_LO = 1.0       # the tip mode searched from this (Hz) ...
RING_NYQUIST = 0.45    # ... to this share of the frame rate (below Nyquist, with the exposure's margin)
TERMS = ("ring", "ring_motor", "reg_tip", "reg_motor", "slide_tip", "slide_motor", "shift_tip", "shift_motor", "expo",
         "spread")
                       # a slide_ or shift_ term needs its reg_ term, ring_motor the ring
EXPO_NODES = 8         # the exposure's average (module doc: the exposure) by the midpoint rule on this many
                       # nodes: a fixed count, so the image moves smoothly with e (a count growing with e would
                       # step it); the rule's own error against the exact mean over the window is not measured
WIDTH_AT = ("input", "output")  # where the play's width is read: B(q) or B(z) (module doc)
DELAY_DISAGREE_Z = 3.0  # a configured delay this many combined standard errors from the record's disagrees
                       # with it (a two-sided 0.3 % test: on a right one, a false alarm in 370 records)
Z_GRID = 4001          # points of the output grid the band's edges are inverted on (B at the output)
G_PENALTY = 1e-6       # G's second-difference penalty, of its block's mean pivot (`RecordModel.solve`): a
                       # continuation where no frame reaches; a curvature of 10 px per knot then costs what
                       # 1e-4 of one frame's squared noise-scale residual does
EPS_SHARE = 1e-3       # the least share the mixture gives a level (module doc): a frame beside a switch window
                       # may show the other level at this probability, so a misplaced window costs
                       # 2 ln(1 / EPS_SHARE) = 14 (a 3.7-sigma residual), not an infinite one, and the fit can move it
SLIDE_MAX_S = 0.1      # a slide's longest duration at least this, s (module doc: the slide): a settling of
                       # tens of ms is physical time, not frames; a tenth of a second stays well below the
                       # plant's take-up that a half-interval bound took (0.48 s on the main job)
SPREAD_NODES = 8       # the spread's mean over its widths (module doc: the spread) by the midpoint rule on this many
                       # nodes, as the exposure's: a fixed count, so the output moves smoothly with s
SPREAD_MAX = 0.9       # the spread's largest s: the narrowest width (1 - s) B stays above a tenth of B
N_REG = 3              # the registration's rotation (rad) about the camera's x, y and optical axes (module doc: R)
N_SHIFT = 2            # or, with a shift_ term, its translation (px) along the image's u and v (module doc: the shift)


@dataclass
class Record:
    """What the model sees. t (N,) s uniform scene grid, q (N,) on it; t_f (F,) s frame stamps,
    obs (F, 2) px (finite rows only); rt, rq (M,) reversals, s_new (M,) the motor's new direction
    (+1 / -1), i1 (M,) their grid index; period_s the frame period; reg_gen (F, N_REG + N_SHIFT, 2)
    the image motions of the camera's rotations at the observed points (px per rad), then of the
    image's translations (px per px) (module doc: R)."""

    t: np.ndarray
    q: np.ndarray
    t_f: np.ndarray
    obs: np.ndarray
    rt: np.ndarray
    rq: np.ndarray
    s_new: np.ndarray
    i1: np.ndarray
    period_s: float
    reg_gen: np.ndarray
    _bases: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    def width_basis(self, n: int, at: str = "grid"):
        """B's design, n cubic B-splines on q's range, as a CSR matrix (`_sparse_basis`), at the grid's q
        (at "grid": (N, n)) or on the output's z grid (at "z": (Z_GRID, n), `RecordModel.edges`); built
        once a record and shared by every model of that size, which only read it. Why: a model's own
        was 5.7 ms to build on the bench record's 86,250 samples, and 4.5 MB of each model pickled
        between the processes (`__getstate__`). Errors: ValueError for another at."""
        if at not in ("grid", "z"):
            raise ValueError(f"at must be 'grid' or 'z', not {at!r}")
        key = (n, at)
        if key not in self._bases:
            lo, hi = float(self.q.min()), float(self.q.max())
            x = self.q if at == "grid" else output_grid(lo, hi)
            self._bases[key] = _sparse_basis(x, lo, hi, n)
        return self._bases[key]

    def __getstate__(self) -> dict:
        """Pickled without its designs (`width_basis`), which the receiving process builds again."""
        return {k: v for k, v in self.__dict__.items() if k != "_bases"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._bases = {}


def output_grid(q_lo: float, q_hi: float) -> np.ndarray:
    """The play output's grid (Z_GRID,) the edges are inverted on when B is read at the output
    (module doc): q's range [q_lo, q_hi] widened by half its span at each end."""
    span = q_hi - q_lo
    return np.linspace(q_lo - 0.5 * span, q_hi + 0.5 * span, Z_GRID)


def registration_generators(obs: np.ndarray, centre_px, focal_px: float) -> np.ndarray:
    """The image motions (F, N_REG + N_SHIFT, 2) at the points obs (F, 2) px: of small rotations of
    the camera about its x, y and optical axes, px per rad, for the principal point centre_px (2,)
    px and focal length focal_px (module doc: R; Longuet-Higgins & Prazdny 1980, the rotational
    motion field); then of the image's translations along u and v, px per px (the shift terms)."""
    x = (obs[:, 0] - centre_px[0]) / focal_px
    y = (obs[:, 1] - centre_px[1]) / focal_px
    fields = ((x * y, 1.0 + y * y), (-(1.0 + x * x), -x * y), (y, -x))
    rot = focal_px * np.stack([np.column_stack(uv) for uv in fields], axis=1)
    one, zero = np.ones_like(x), np.zeros_like(x)
    shift = np.stack([np.column_stack((one, zero)), np.column_stack((zero, one))], axis=1)
    return np.concatenate([rot, shift], axis=1)


def make_record(t_enc, q, rt, rq, t_f, obs, fps: float, centre_px=None, focal_px: float | None = None) -> Record:
    """Resample the encoder onto a uniform grid at its own median rate (at most GRID_HZ_MAX) and
    keep the finite frames. Shapes as in Record; centre_px (2,) and focal_px the camera's principal
    point and focal length, px (None: the frames' bounding box's centre and a focal length of twice
    its larger side; they place the registration's perspective parts, second-order in the
    registration).
    Errors: ValueError with fewer than 2 reversals or 20 frames."""
    t_enc, q = np.asarray(t_enc, float), np.asarray(q, float)
    ok = np.all(np.isfinite(obs), axis=1)
    if rt.size < 2 or ok.sum() < 20:
        raise ValueError(f"the record model needs >= 2 reversals and 20 frames ({rt.size}, {int(ok.sum())})")
    rate = min(GRID_HZ_MAX, 1.0 / float(np.median(np.diff(t_enc))))
    t = np.arange(t_enc[0], t_enc[-1], 1.0 / rate)
    qg = np.interp(t, t_enc, q)
    # each reversal's extremum on the grid point nearest it: a sharp reversal between two grid
    # points is otherwise cut to their interpolation, up to the speed times a grid step below q1,
    # and eq. 1 measures from q1 (io.session.thin_encoder_by_time keeps the extremum's sample)
    rt, rq = np.asarray(rt, float), np.asarray(rq, float)
    qg[np.clip(np.rint((rt - t[0]) * rate).astype(np.int64), 0, t.size - 1)] = rq
    i1 = np.clip(np.searchsorted(t, rt), 1, t.size - 2)
    # the new direction: towards the next reversal's extreme (reversals alternate); not from q
    # just before the reversal, which a motor dwelling at its extreme holds level
    s_new = np.sign(np.diff(rq))
    s_new = np.r_[s_new, -s_new[-1:]]
    for k in range(s_new.size):  # a level pair of extremes (a repeated reversal): the other's opposite
        if s_new[k] == 0:
            s_new[k] = -s_new[k - 1] if k else 1.0
    o = np.asarray(obs, float)[ok]
    if centre_px is None:
        centre_px = 0.5 * (o.min(axis=0) + o.max(axis=0))
    if focal_px is None:
        focal_px = 2.0 * max(float(np.ptp(o, axis=0).max()), 1.0)
    return Record(t, qg, np.asarray(t_f, float)[ok], o, np.asarray(rt, float),
                  np.asarray(rq, float), s_new, i1, 1.0 / fps, registration_generators(o, centre_px, float(focal_px)))


def _first_moves_ref(z: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """For each span j, the first grid sample k in [start[j], stop[j]) at which z (N,) moves (z[k] !=
    z[k - 1], k >= 1), else -1: (M,) int64 (the reference of base.kernels.first_moves)."""
    mv = np.flatnonzero(z[1:] != z[:-1]) + 1
    if mv.size == 0:
        return np.full(np.shape(start), -1, np.int64)
    k = np.searchsorted(mv, np.maximum(start, 1))
    kk = mv[np.minimum(k, mv.size - 1)]
    return np.where((k < mv.size) & (kk < stop), kk, -1).astype(np.int64)


def play_drags_ref(lo: np.ndarray, hi: np.ndarray, z0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The play on band edges lo, hi (N,) from z0 (eq. 3) with its drags: (z, last, side) (N,) each,
    last[k] the latest sample <= k at which z sat on an edge (-1: none yet), side -0.5 when that
    edge was the lower (a tie: the lower), +0.5 the upper; before the first drag, sample 0's. The
    reference of base/kernels.c's dk_play_drags (bit for bit: tests/python/sim/test_diagnose_kernels.py)."""
    z = play_edges(lo, hi, z0)
    drag = (z == lo) | (z == hi)
    last = np.maximum.accumulate(np.where(drag, np.arange(z.size), -1))
    side = np.where(z == lo, -0.5, 0.5)[np.maximum(last, 0)]
    return z, last, side


@functools.lru_cache(maxsize=64)
def _basis_splines(lo: float, hi: float, n: int) -> tuple[BSpline, BSpline]:
    """The n cubic clamped B-splines on [lo, hi] as one vector-valued BSpline (identity coefficients),
    and its derivative: evaluated at x they give `_basis`' and `_dbasis`' rows. Why not
    BSpline.design_matrix: it builds a sparse matrix per call, which on the fits' few hundred frames
    cost twice the evaluation (the same values bit for bit: a row is the same de Boor sum, plus
    exact zeros; a test checks it)."""
    inner = np.linspace(lo, hi, n - 2)
    knots = np.r_[[lo] * 3, inner, [hi] * 3]
    spl = BSpline(knots, np.eye(n), 3, extrapolate=True)
    return spl, spl.derivative()


def _basis(x: np.ndarray, lo: float, hi: float, n: int) -> np.ndarray:
    """Cubic clamped B-spline basis (len(x), n) on [lo, hi] (dense; x clipped into the range)."""
    return _basis_splines(lo, hi, n)[0](np.clip(x, lo, np.nextafter(hi, -np.inf)))


def _sparse_basis(x: np.ndarray, lo: float, hi: float, n: int):
    """`_basis` as a CSR matrix (4 non-zeros a row): the play's width over the whole grid."""
    inner = np.linspace(lo, hi, n - 2)
    knots = np.r_[[lo] * 3, inner, [hi] * 3]
    return BSpline.design_matrix(np.clip(x, lo, np.nextafter(hi, -np.inf)), knots, 3, extrapolate=True).tocsr()


def _dbasis(x: np.ndarray, lo: float, hi: float, n: int) -> np.ndarray:
    """Derivative of `_basis` with respect to x, (len(x), n): the quadratic basis on the same knots t,
    B_i,3' = 3 B_i,2 / (t_i+3 - t_i) - 3 B_i+1,2 / (t_i+4 - t_i+1), a term of zero knot span being 0
    (de Boor, A Practical Guide to Splines, 1978, ch. X), as scipy's BSpline.derivative evaluates it."""
    return _basis_splines(lo, hi, n)[1](np.clip(x, lo, np.nextafter(hi, -np.inf)))


def _tip_filter(f_hz: float, zeta: float, dt: float) -> tuple[list, list]:
    """(b, a) of the tip mode x'' + 2 zeta w x' + w^2 x = u sampled every dt, by impulse
    invariance: h[n] = r^n sin(n theta) / w_d, r = exp(-zeta w dt), theta = w_d dt."""
    w = 2 * np.pi * f_hz
    wd = w * np.sqrt(max(1.0 - zeta * zeta, 1e-6))
    r, th = np.exp(-zeta * w * dt), wd * dt
    return [0.0, dt * r * np.sin(th) / wd], [1.0, -2 * r * np.cos(th), r * r]


def _tip_mode(u: np.ndarray, f_hz: float, zeta: float, dt: float) -> np.ndarray:
    """Response x of the tip mode (`_tip_filter`) to u sampled every dt (in C when compiled: the
    same bits, base/kernels.c)."""
    b, a = _tip_filter(f_hz, zeta, dt)
    return kernels.tip_mode(u, b[1], a[1], a[2]) if kernels.available() else lfilter(b, a, u)


def _share_var(tau: np.ndarray, t_ev: np.ndarray, T: float) -> np.ndarray:
    """p (1 - p) at each tau (F,): p its share of the switch window [t_ev[k], t_ev[k] + T] it
    falls in (0 outside every window); the Bernoulli variance of a switch at a uniform time."""
    if t_ev.size == 0:
        return np.zeros(tau.size)
    e = np.searchsorted(t_ev, tau, side="right") - 1
    p = np.where(e >= 0, (tau - t_ev[np.maximum(e, 0)]) / T, 1.0)
    p = np.clip(p, 0.0, 1.0)
    return p * (1.0 - p)


def _ramp_sign(tau: np.ndarray, t_ev: np.ndarray, s_ev: np.ndarray, s0: float, T: float) -> np.ndarray:
    """+-1 held between events, switching to s_ev[k] over [t_ev[k], t_ev[k] + T] linearly (the
    switch's expected share in a frame period that may or may not have seen it). t_ev increasing."""
    if t_ev.size == 0:
        return np.full(tau.size, s0)
    tk = np.column_stack([t_ev, t_ev + T]).ravel()
    prev = np.r_[s0, s_ev[:-1]]
    vk = np.column_stack([prev, s_ev]).ravel()
    tk = np.maximum.accumulate(tk + np.arange(tk.size) * 1e-12)  # strictly increasing for interp
    return np.interp(tau, tk, vk, left=s0, right=s_ev[-1])


def _ramp_int(y: np.ndarray, L: float) -> tuple[np.ndarray, np.ndarray]:
    """(R(y), dR/dL) (K,): R(y) = the integral of clip(x / L, 0, 1) from -inf to y."""
    a = np.clip(y, 0.0, L)
    R = 0.5 * a * a / L + np.maximum(y - L, 0.0)
    dRdL = np.where(y <= 0.0, 0.0, np.where(y < L, -0.5 * (a / L) ** 2, -0.5))
    return R, dRdL


def _switch_shares(since: np.ndarray, L: float, D: float, E: float = 0.0):
    """The switch's level shares at frames since s after its window opens (module doc: the switch, the
    slide and the exposure): it starts at u ~ U(0, L) and moves for a duration E + U(0, D) (E s the
    exposure, through which a step is seen as a ramp of exactly E; D s the longest slide; both 0: a
    step). since (K,) s; L > 0 s. Returns (p_old, p_new, dp_old, dp_new): the shares of frames still at the old level,
    u >= since, and already at the new one, u + duration <= since ((K,) each; the rest,
    1 - p_old - p_new, is mid way), and their derivatives over (since, L, D, E), (4, K) each."""
    since = np.asarray(since, float)
    inside = (since > 0.0) & (since < L)
    c = np.clip(since / L, 0.0, 1.0)
    p_old = 1.0 - c
    zero = np.zeros(since.size)
    dp_old = np.vstack([np.where(inside, -1.0 / L, 0.0), np.where(inside, since / L ** 2, 0.0), zero, zero])
    x = since - E  # the new level is reached E later than a slide alone would reach it
    if D <= 0.0:
        inx = (x > 0.0) & (x < L)
        p_new = np.clip(x / L, 0.0, 1.0)
        dx = np.where(inx, 1.0 / L, 0.0)
        return p_old, p_new, dp_old, np.vstack([dx, np.where(inx, -x / L ** 2, 0.0), zero, -dx])
    R1, dR1 = _ramp_int(x, L)
    R0, dR0 = _ramp_int(x - D, L)
    p_new = (R1 - R0) / D
    c1 = np.clip(x / L, 0.0, 1.0)
    c0 = np.clip((x - D) / L, 0.0, 1.0)
    dx = (c1 - c0) / D
    dp_new = np.vstack([dx, (dR1 - dR0) / D, (c0 - p_new) / D, -dx])
    return p_old, p_new, dp_old, dp_new


def _onto(x: float, lo: float, hi: float) -> tuple[float, float]:
    """(v, dv/dx): theta's part x mapped onto [lo, hi] by the logistic (a bounded part of theta: a clip
    would stall LM on the bound, its slope zero there)."""
    e = float(expit(x))
    return lo + (hi - lo) * e, (hi - lo) * e * (1.0 - e)


def _onto_x(v: float, lo: float, hi: float) -> float:
    """The inverse of `_onto`, v clipped to within 1e-3 of the range's ends."""
    return float(logit(np.clip((v - lo) / (hi - lo), 1e-3, 1 - 1e-3)))


def _log_ndtr_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """ln(Phi(b) - Phi(a)) for a <= b (K,), the standard normal's mass between them, without
    cancellation in either tail."""
    flip = a > 0.0  # both in the upper tail: the same mass between -b and -a
    a, b = np.where(flip, -b, a), np.where(flip, -a, b)
    la, lb = log_ndtr(a), log_ndtr(b)
    return lb + np.log1p(-np.exp(np.minimum(la - lb, -1e-300)))


def _mid_level(ro_u, ro_v, j_u, j_v, sigma: float):
    """A frame caught mid slide (module doc: the slide): its level h in [0, 1] between the old (h = 0)
    and the new (h = 1) one, whose residuals are ro - h J ((K,) each axis; ro at the old level, J the
    jump, px). Returns (h, ln of the level's likelihood integrated over h in [0, 1]): h the least
    squares level clipped into [0, 1]; the integral with the Huber loss of the residual across the
    jump and the Gaussian one along it (its scale sigma / |J| in h)."""
    jj = np.maximum(j_u * j_u + j_v * j_v, 1e-24)
    hh = (ro_u * j_u + ro_v * j_v) / jj
    s_h = sigma / np.sqrt(jj)
    rho = huber_rho(ro_u - hh * j_u, sigma) + huber_rho(ro_v - hh * j_v, sigma)
    ln_int = np.log(s_h * np.sqrt(2.0 * np.pi)) + _log_ndtr_diff(-hh / s_h, (1.0 - hh) / s_h) - rho
    return np.clip(hh, 0.0, 1.0), ln_int


def _kl_row_grad(gamma: np.ndarray, p: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(`_kl_row`, its derivative over p) (K,) each; the derivative 0 where p is clipped (not free)."""
    rr = _kl_row(gamma, p)
    slope = (p - gamma) / (p * (1 - p))           # d KL / d p
    big = np.abs(rr) > 1e-6
    drdp = np.where(big, slope / np.where(big, rr, 1.0), 1.0 / np.sqrt(p * (1 - p)))
    return rr, np.where(free, drdp, 0.0)


@dataclass
class Terms:
    """Which camera terms a model carries (module doc): the tip mode (ring), a registration
    switching with the tip's direction (reg_tip) or with the motor's (reg_motor), each switch's
    slide, and the exposure's blur of each frame (expo)."""

    ring: bool = False
    ring_motor: bool = False   # the tip mode's stops driven by the motor's deceleration (module doc: the tip mode)
    reg_tip: bool = False
    reg_motor: bool = False
    slide_tip: bool = False    # the tip's switch slides rather than steps (module doc: the slide)
    slide_motor: bool = False
    shift_tip: bool = False    # the tip's switch also translates the image (module doc: R, the shift)
    shift_motor: bool = False
    expo: bool = False         # each frame the mean of the scene over its exposure (module doc: the exposure)
    spread: bool = False       # the plant's widths spread about B: a smooth take-up (module doc: the spread)

    def names(self) -> list[str]:
        return [n for n in TERMS if getattr(self, n)]

    def offered(self) -> list[str]:
        """The terms the search may add next: those not on, a slide or a shift only to its switch, the
        ring's motor drive only to the ring."""
        return [n for n in TERMS if not getattr(self, n)
                and (not n.startswith(("slide_", "shift_")) or getattr(self, "reg_" + n.split("_")[1]))
                and (n != "ring_motor" or self.ring)]

    def with_(self, name: str) -> "Terms":
        d = {n: getattr(self, n) for n in TERMS}
        d[name] = True
        return Terms(**d)

    def without_(self, name: str) -> "Terms | None":
        """These terms with name off, or None when another term on needs it (a switch's slide or
        shift, the ring's motor drive)."""
        d = {n: getattr(self, n) for n in TERMS}
        d[name] = False
        t = Terms(**d)
        needs = {"reg_" + k.split("_")[1] for k in t.names() if k.startswith(("slide_", "shift_"))}
        needs |= {"ring"} if t.ring_motor else set()
        return None if needs - set(t.names()) else t


@dataclass
class Eval:
    """One evaluation of the model at theta: residuals (2F,) px (u then v), the onsets t_on (M,)
    scene s (NaN: the play not taken up before the next reversal), beta the linear parameters."""

    resid: np.ndarray
    t_on: np.ndarray
    beta: np.ndarray
    cols: dict
    z_f: np.ndarray
    state: dict


class RecordModel:
    """The model of one record for given terms, B and G sizes (module doc). theta: `layout`."""

    def __init__(self, rec: Record, n_b: int, n_g: int, terms: Terms, prior: tuple[float, float] | None,
                 d_fixed: float | None = None, width_at: str = "input"):
        if width_at not in WIDTH_AT:
            raise ValueError(f"width_at must be one of {WIDTH_AT}, not {width_at!r}")
        self.rec, self.n_b, self.n_g, self.terms = rec, n_b, n_g, terms
        self.prior, self.d_fixed, self.width_at = prior, d_fixed, width_at
        q = rec.q
        self.q_lo, self.q_hi = float(q.min()), float(q.max())
        span = self.q_hi - self.q_lo
        self.Phi_B = rec.width_basis(n_b) if n_b > 1 else None
        self._taps = self._band_taps()
        if width_at == "output":  # the play's output grid the edges are inverted on (module doc)
            self.z_grid = output_grid(self.q_lo, self.q_hi)
            self.Phi_Bz = rec.width_basis(n_b, "z") if n_b > 1 else None
        self.z_lo, self.z_hi = self.q_lo - 0.25 * span, self.q_hi + 0.25 * span
        self.w = np.ones(2 * rec.t_f.size)  # IRLS weights
        # a slide's longest duration (module doc: the slide): a frame period, and at least SLIDE_MAX_S
        self.slide_max_s = max(rec.period_s, SLIDE_MAX_S)
        self.slope = None  # G' at the frames from the previous round: (F, 2), for the ring's direction
        self.mix = {}      # the switch mixture's E-step per term ("tip", "motor"): `e_step`
        self._memo = None  # `_play_part`'s last arguments and result

    # ---- theta layout: [t_delay, B's coefficients (n_b)[, ring (2)][, lag_tip][, lag_motor][, slide_tip]
    # [, slide_motor][, expo], z0]. The bounded parts enter through logistic maps onto their ranges (a
    # clip would stall the fit on a bound, its slope zero there): the tip mode's log frequency over its
    # band and its damping ratio over [0.005, 0.7]; a switch lag over [T / 20, T]; a slide over
    # [T / 20, slide_max_s]; the exposure over [T / 20, T]; the first state over its band.
    ZETA_LO, ZETA_HI = 0.005, 0.7

    def ring_band(self) -> tuple[float, float]:
        """The tip mode's search band (low, high) Hz: RING_HZ_LO to RING_NYQUIST of the frame rate."""
        return RING_HZ_LO, RING_NYQUIST / self.rec.period_s

    def ring_theta(self, f_hz: float, zeta: float) -> np.ndarray:
        """The ring's part of theta (2,) for a tip mode (f_hz, zeta), each clipped into its range."""
        lo, hi = np.log(self.ring_band())
        a = np.clip((np.log(f_hz) - lo) / (hi - lo), 1e-3, 1 - 1e-3)
        b = np.clip((zeta - self.ZETA_LO) / (self.ZETA_HI - self.ZETA_LO), 1e-3, 1 - 1e-3)
        return np.array([logit(a), logit(b)])

    def lag_map(self, x: float) -> tuple[float, float]:
        """(L s, dL/dx) for a switch lag's part of theta x: L in [T / 20, T]."""
        return _onto(x, self.rec.period_s / 20, self.rec.period_s)

    def lag_x(self, L: float) -> float:
        """A switch lag's part of theta for the lag L s (the inverse of `lag_map`, clipped)."""
        return _onto_x(L, self.rec.period_s / 20, self.rec.period_s)

    def slide_map(self, x: float) -> tuple[float, float]:
        """(D s, dD/dx) for a slide's part of theta x: the longest slide D in [T / 20, slide_max_s]."""
        return _onto(x, self.rec.period_s / 20, self.slide_max_s)

    def slide_x(self, D: float) -> float:
        """A slide's part of theta for the longest slide D s (the inverse of `slide_map`, clipped)."""
        return _onto_x(D, self.rec.period_s / 20, self.slide_max_s)

    def expo_map(self, x: float) -> tuple[float, float]:
        """(e s, de/dx) for the exposure's part of theta x: e in [T / 20, T] (a blur shorter than T / 20
        is a grid step or two, nothing the frames tell from none; longer than T, no camera exposes)."""
        return _onto(x, self.rec.period_s / 20, self.rec.period_s)

    def expo_x(self, e: float) -> float:
        """The exposure's part of theta for e s (the inverse of `expo_map`, clipped)."""
        return _onto_x(e, self.rec.period_s / 20, self.rec.period_s)

    def spread_map(self, x: float) -> tuple[float, float]:
        """(s, ds/dx) for the spread's part of theta x: s in [0, SPREAD_MAX] (module doc: the spread)."""
        return _onto(x, 0.0, SPREAD_MAX)

    def spread_x(self, s: float) -> float:
        """The spread's part of theta for s (the inverse of `spread_map`, clipped)."""
        return _onto_x(s, 0.0, SPREAD_MAX)

    def spread(self, th: np.ndarray) -> float:
        """The spread s of the plant's widths about B (0: the term is off, one play)."""
        lay = self.layout()
        return self.spread_map(th[lay["spread"]][0])[0] if "spread" in lay else 0.0

    def spread_factors(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """The spread's nodes: (width factors m (K,) = 1 + s u, u (K,)), u the midpoints of SPREAD_NODES
        equal parts of [-1, 1]; ((1,), (0,)) without the term."""
        if not self.terms.spread:
            return np.ones(1), np.zeros(1)
        u = 2.0 * (np.arange(SPREAD_NODES) + 0.5) / SPREAD_NODES - 1.0
        return 1.0 + s * u, u

    def exposure(self, th: np.ndarray) -> float:
        """The exposure e s that blurs each frame (0: the term is off, each frame an instant)."""
        lay = self.layout()
        return self.expo_map(th[lay["expo"]][0])[0] if "expo" in lay else 0.0

    def expo_offsets(self, e: float) -> np.ndarray:
        """The exposure's nodes about each frame's scene time (EXPO_NODES,) s: the midpoints of
        EXPO_NODES equal parts of [-e / 2, e / 2]; (0,) without the term."""
        if e <= 0.0:
            return np.zeros(1)
        return e * ((np.arange(EXPO_NODES) + 0.5) / EXPO_NODES - 0.5)

    def layout(self) -> dict[str, slice]:
        """Where each named part of theta sits."""
        out, i = {"d": slice(0, 1), "B": slice(1, 1 + self.n_b)}, 1 + self.n_b
        for name, size, on in (("ring", 2, self.terms.ring), ("lag_tip", 1, self.terms.reg_tip),
                               ("lag_motor", 1, self.terms.reg_motor), ("slide_tip", 1, self.terms.slide_tip),
                               ("slide_motor", 1, self.terms.slide_motor), ("expo", 1, self.terms.expo),
                               ("spread", 1, self.terms.spread), ("z0", 1, True)):
            if on:
                out[name], i = slice(i, i + size), i + size
        return out

    def n_theta(self) -> int:
        return max(sl.stop for sl in self.layout().values())

    def theta(self, parts: dict) -> np.ndarray:
        """theta from named parts; a part not given starts at the tip mode (3 Hz, zeta 0.1), a
        switch lag in the middle of its range, a slide of up to half a frame period or the play's
        first state in the middle of its band."""
        th = np.empty(self.n_theta())
        x_slide = np.array([self.slide_x(0.5 * self.rec.period_s)])
        dflt = {"ring": self.ring_theta(3.0, 0.1), "lag_tip": np.zeros(1), "lag_motor": np.zeros(1),
                "slide_tip": x_slide, "slide_motor": x_slide, "expo": np.array([self.expo_x(0.5 * self.rec.period_s)]),
                "spread": np.array([self.spread_x(0.3)]), "z0": np.zeros(1)}
        for name, sl in self.layout().items():
            th[sl] = parts[name] if name in parts else dflt[name]
        return th

    def parts(self, th: np.ndarray) -> dict:
        return {name: np.array(th[sl]) for name, sl in self.layout().items()}

    def unpack(self, th: np.ndarray):
        """(t_delay s, B's coefficients, (f_hz, zeta) or None, {"tip": L, "motor": L} s), each in
        its admissible region (LM is unbounded): d >= 0 and B >= 0 clipped (neither bound is
        reached by a fit that means anything), the tip mode in its band and a switch lag L in
        [T / 20, T] by their logistic maps (a switch the registration makes within a frame of the
        reversal it follows; T / 20, a step to the frame's resolution)."""
        lay = self.layout()
        d = self.d_fixed if self.d_fixed is not None else max(float(th[0]), 0.0)
        cB = np.maximum(th[lay["B"]], 0.0)
        ring = None
        if "ring" in lay:
            lo, hi = np.log(self.ring_band())
            a, b = expit(th[lay["ring"]])
            ring = (float(np.exp(lo + (hi - lo) * a)), float(self.ZETA_LO + (self.ZETA_HI - self.ZETA_LO) * b))
        lags = {n: self.lag_map(th[lay["lag_" + n]][0])[0] for n in ("tip", "motor") if "lag_" + n in lay}
        return float(d), cB, ring, lags

    def slides(self, th: np.ndarray) -> dict:
        """{"tip": D, "motor": D} s: each switch's longest slide (0: it steps)."""
        lay = self.layout()
        return {n: (self.slide_map(th[lay["slide_" + n]][0])[0] if "slide_" + n in lay else 0.0) for n in ("tip", "motor")}

    def prior_residual(self, lag: float) -> tuple[float, float]:
        """The configured delay's prior residual (sigma units) at the image's mean lag lag s, and
        its slope over lag (module doc, the exposure): the distance of lag from
        [d_cfg, d_cfg + T / 2] in prior sds. (0, 0) without a prior or with the delay held."""
        if self.prior is None or self.d_fixed is not None:
            return 0.0, 0.0
        gap = lag - self.prior[0]
        gap = min(gap, 0.0) + max(gap - 0.5 * self.rec.period_s, 0.0)
        return gap / self.prior[1], (1.0 / self.prior[1] if gap != 0.0 else 0.0)

    def exposure_end(self, lag: float, se: float, e_max: float | None = None) -> tuple[float, float | None]:
        """(d_end s, e s): the delay to the exposure's end and the exposure for the image's mean lag
        lag s, of standard error se s (module doc, the exposure). e None where nothing splits
        them, d_end then the lag: no configured delay, the delay held, or a configured delay the
        record contradicts (more than DELAY_DISAGREE_Z combined standard errors from every d_end
        the record allows, [lag - e_max / 2, lag], e_max s the longest exposure it allows, None: a
        frame period T; the configured delay is then wrong, and says nothing of the exposure)."""
        if self.prior is None or self.d_fixed is not None:
            return float(lag), None
        T = self.rec.period_s
        e_max = T if e_max is None else min(float(e_max), T)
        if abs(np.clip(self.prior[0], lag - 0.5 * e_max, lag) - self.prior[0]) > self.disagree_s(se):
            return float(lag), None
        d_end = float(np.clip(self.prior[0], lag - 0.5 * T, lag))
        return d_end, 2.0 * (lag - d_end)

    def disagree_s(self, se: float) -> float:
        """How far s a configured delay may lie from every d_end the record allows before the
        record contradicts it: DELAY_DISAGREE_Z combined standard errors (the mean lag's se s and
        the prior's sd)."""
        return float(DELAY_DISAGREE_Z * np.hypot(se, self.prior[1]))

    def B_of(self, cB: np.ndarray, q: np.ndarray) -> np.ndarray:
        if self.n_b == 1:
            return np.full(np.shape(q), float(cB[0]))
        return _basis(np.asarray(q, float), self.q_lo, self.q_hi, self.n_b) @ cB

    # ---- forward model
    def edges(self, cB: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The play's band (lo, hi) (N,) on the grid for B's coefficients cB (module doc: B at the
        input, q -+ B(q) / 2; at the output, the z with z +- B(z) / 2 = q, by inverting
        z -> z +- B(z) / 2 on z_grid, kept increasing where B' would pass -+2)."""
        rec = self.rec
        if self.width_at == "input":
            if self._taps is not None and kernels.available():  # the same sums in one pass (bit for bit)
                return kernels.band_input(rec.q, self._taps[0], self._taps[1], cB)
            B = np.maximum(self.Phi_B @ cB if self.Phi_B is not None else np.full(rec.q.size, cB[0]), 0.0)
            return rec.q - 0.5 * B, rec.q + 0.5 * B
        zg = self.z_grid
        Bz = np.maximum(self.Phi_Bz @ cB if self.Phi_Bz is not None else np.full(zg.size, cB[0]), 0.0)
        q_up = np.maximum.accumulate(zg + 0.5 * Bz)  # the lower edge drags z up: q = z + B(z) / 2
        q_dn = np.maximum.accumulate(zg - 0.5 * Bz)  # the upper edge drags z down: q = z - B(z) / 2
        return np.interp(rec.q, q_up, zg), np.interp(rec.q, q_dn, zg)

    def play(self, cB: np.ndarray, x0: float = 0.0, edges: bool = False):
        """z on the grid (N,) for B's coefficients cB and the play's first state x0 (theta's "z0"
        part: z[-1] = lo + expit(x0) (hi - lo) on the first sample's band, module doc); with edges,
        also (lo, hi) (N,) each."""
        lo, hi = self.edges(cB)
        z = play_edges(lo, hi, float(lo[0] + expit(x0) * (hi[0] - lo[0])))
        return (z, lo, hi) if edges else z

    def play_drags(self, cB: np.ndarray, x0: float = 0.0):
        """`play` with its drags: (z (N,), the band's first sample (lo_0, hi_0), last (N,), side (N,)),
        last[k] the latest sample <= k at which z sat on an edge (-1: none yet) and side the edge's
        (-0.5 the lower, +0.5 the upper; before the first drag, sample 0's): the bookkeeping of every
        gradient, which reads the band itself at its first sample only (`z_gradient`). B at the input
        with its taps: the band and the play in one pass (base.kernels.band_play_drags, the same
        bits as `edges` then the play), so the band's two grid arrays are never built."""
        f = expit(x0)
        if self.width_at == "input" and self._taps is not None and kernels.available():
            z, last, side, lo0, hi0 = kernels.band_play_drags(self.rec.q, self._taps[0], self._taps[1], cB, float(f))
            return z, (lo0, hi0), last, side
        lo, hi = self.edges(cB)
        z0 = float(lo[0] + f * (hi[0] - lo[0]))
        z, last, side = kernels.play_drags(lo, hi, z0) if kernels.available() else play_drags_ref(lo, hi, z0)
        return z, (float(lo[0]), float(hi[0])), last, side

    def z0_of(self, th: np.ndarray) -> float:
        """The play's first state's part of theta (module doc: z0)."""
        return float(th[self.layout()["z0"]][0])

    def z_gradient(self, cB: np.ndarray, st: dict, k: np.ndarray, x0: float) -> tuple[np.ndarray, np.ndarray]:
        """(d z / d (B's coefficients) (len(k), n_b), d z / d x0 (len(k),)) at grid samples k: z moves
        with the band edge that last dragged it (`edge_gradient`); before the first drag it is the
        first state, z0 = lo_0 + f (hi_0 - lo_0), f = expit(x0), which moves with both edges of the
        first sample's band and with x0 by (hi_0 - lo_0) f (1 - f)."""
        last, side = st["last"][k], st["side"][k]
        pre = last < 0
        dx = np.zeros(k.size)
        if self.width_at == "input" and self._taps is not None and kernels.available():
            # `edge_gradient`'s rows at the input, written in place in C (the same bits)
            g = kernels.drag_gradient(self._taps[0], self._taps[1], last, side, self.n_b)
        else:
            g = np.zeros((k.size, self.n_b))
            if (~pre).any():
                lk = last[~pre]
                g[~pre] = self.edge_gradient(cB, lk, st["z"][lk], side[~pre])
        if pre.any():
            f = float(expit(x0))
            lo0, hi0 = st["band0"]
            e = self.edge_gradient(cB, np.zeros(2, int), np.array([lo0, hi0]), np.array([-0.5, 0.5]))
            g[pre] = (1.0 - f) * e[0] + f * e[1]
            dx[pre] = (hi0 - lo0) * f * (1.0 - f)
        return g, dx

    def spread_gradient(self, cB: np.ndarray, st: dict, k: np.ndarray, x0: float):
        """`z_gradient` of the frames' z with the spread (module doc: the spread): (d z / d (B's
        coefficients) (len(k), n_b), d z / d x0 (len(k),), d z / d s (len(k),) or None without the
        term). z is the mean of the nodes' plays, node j the play of B's coefficients m_j cB (B is
        linear in them), m_j = 1 + s u_j: with g_j its gradient over those coefficients, dz/dcB is
        the mean of m_j g_j and dz/ds the mean of u_j g_j cB."""
        nodes = st.get("nodes")
        if not nodes:
            g, dx = self.z_gradient(cB, st, k, x0)
            return g, dx, None
        G, X, S = 0.0, 0.0, 0.0
        for m, u, nst in nodes:
            g, dx = self.z_gradient(m * cB, nst, k, x0)
            G, X, S = G + m * g, X + dx, S + u * (g @ cB)
        n = len(nodes)
        return G / n, X / n, S / n

    def edge_gradient(self, cB: np.ndarray, k: np.ndarray, z: np.ndarray, side: np.ndarray) -> np.ndarray:
        """d z / d (B's coefficients), (len(k), n_b), where z (len(k),) lies on the band's edge
        side (-0.5 the lower, +0.5 the upper) at grid samples k: z = q + side B(q) at the input,
        so side phi_i(q); z = q + side B(z) at the output, so side phi_i(z) / (1 - side B'(z))."""
        if self.width_at == "input":
            if self.Phi_B is None:
                return np.ones((k.size, 1)) * side[:, None]
            if self._taps is None:
                return self.Phi_B[k].toarray() * side[:, None]
            # the design's rows from its taps: a sparse matrix's row indexing cost more than the rest of
            # the gradient (the same values: a row's 4 columns are distinct)
            cols, vals = self._taps
            phi = np.zeros((k.size, self.n_b))
            phi[np.arange(k.size)[:, None], cols[k]] = vals[k]
            return phi * side[:, None]
        if self.n_b == 1:  # a constant width: B' = 0, phi = 1
            return side[:, None].astype(float)
        phi = _basis(z, self.q_lo, self.q_hi, self.n_b)
        dB = _dbasis(z, self.q_lo, self.q_hi, self.n_b) @ cB
        return phi * (side / np.maximum(1.0 - side * dB, 0.05))[:, None]

    def onsets(self, z: np.ndarray) -> np.ndarray:
        """Scene time (M,) at which z starts to move after each reversal (linear within the grid
        step), NaN when it does not before the next reversal."""
        rec = self.rec
        # the hold starts at the reversal; the first move after the grid point past it, before the next
        start, stop = rec.i1 + 1, np.r_[rec.i1[1:], rec.t.size]
        kk = kernels.first_moves(z, start, stop) if kernels.available() else _first_moves_ref(z, start, stop)
        out = np.full(rec.rt.size, np.nan)
        has = kk >= 0
        kk = kk[has]
        dz = np.abs(z[kk] - z[kk - 1])
        dq = np.maximum(np.abs(rec.q[kk] - rec.q[kk - 1]), 1e-15)
        out[has] = rec.t[kk] - rec.dt * np.clip(dz / dq, 0.0, 1.0)
        return out

    def _play_part(self, d: float, cB: np.ndarray, x0: float, e: float = 0.0, s: float = 0.0) -> tuple:
        """What `columns` computes from the delay, B, the first state, the exposure and the spread
        alone: (z (N,), the band's first sample (lo_0, hi_0), last, side (N,), the onsets (M,), tau, z
        at the frames (F,), G's columns (F, n_g), with the tip mode its parts' masks and drives
        ((N - 2,) x 2 each), else None, and with the spread its nodes [(m, u, {"z", "band0", "last",
        "side"})], else None: z is then their mean, and the band, last, side and the onsets the
        narrowest node's, the tip's first motion; the gradients read each node's own,
        `spread_gradient`). Kept for the last
        arguments: the tip mode's frequency scan, a settle's three evaluations and the fit's
        repeated ones at one theta change none of them (the arrays are never written in place)."""
        key = (d, cB.tobytes(), x0, e, s)
        if self._memo is not None and self._memo[0] == key:
            return self._memo[1]
        rec = self.rec
        nodes = None
        if self.terms.spread:  # module doc: the spread; each node a play of width m B from the same first state
            nodes = []
            for m, u in zip(*self.spread_factors(s)):
                zk, bk, lastk, sidek = self.play_drags(m * cB, x0)
                nodes.append((float(m), float(u), {"z": zk, "band0": bk, "last": lastk, "side": sidek}))
            z = np.mean([n[2]["z"] for n in nodes], axis=0)
            band0, last, side = (nodes[0][2][k] for k in ("band0", "last", "side"))
        else:
            z, band0, last, side = self.play_drags(cB, x0)
        tau = rec.t_f - d
        # the frame's image of the play: z at its scene time, or its mean over the exposure (module doc)
        z_f = np.mean([np.interp(tau + o, rec.t, z) for o in self.expo_offsets(e)], axis=0)
        drive = None
        if self.terms.ring:
            v = np.diff(z) / rec.dt
            a = np.diff(v) / rec.dt
            stop = a * v[:-1] < 0.0  # slowing the tip down (a stop); the rest starts it
            mask = (stop, ~stop)
            drive = (mask, [np.where(m, -a, 0.0) for m in mask])
            if self.terms.ring_motor:  # a stop's drive the motor's deceleration, not the play output's:
                # over the stop's sample and the next, as a reversal between two grid samples spreads the
                # motor's second difference over both (the play output stops on the first)
                q_acc = np.diff(rec.q, 2) / (rec.dt * rec.dt)
                drive[1][0] = np.where(stop | np.r_[False, stop[:-1]], -q_acc, 0.0)
        t_on = self.onsets(z if nodes is None else nodes[0][2]["z"])
        out = (z, band0, last, side, t_on, tau, z_f, _basis(z_f, self.z_lo, self.z_hi, self.n_g), drive, nodes)
        self._memo = (key, out)
        return out

    def _band_taps(self):
        """B's taps on the grid for the band kernel (base/kernels.c), views of the design: (cols
        (N, 4), vals (N, 4)), the constant width's (N, 1), or None when a row has other than 4."""
        if self.Phi_B is not None:
            ok = np.all(np.diff(self.Phi_B.indptr) == 4)
            return (self.Phi_B.indices.reshape(-1, 4), self.Phi_B.data.reshape(-1, 4)) if ok else None
        return (np.zeros((self.rec.q.size, 1), np.int32), np.ones((self.rec.q.size, 1))) if self.n_b == 1 else None

    def __getstate__(self) -> dict:
        """Pickled without `_play_part`'s memo (the grid's arrays: tens of MB a model), the taps (views
        of the design, which a pickle would copy), B's designs (the record's, `Record.width_basis`:
        4.5 MB a model on the bench record) nor the last linear solve (`solve`; a model that comes
        through the pipe is evaluated again before its Jacobian is read, onset_fit._unslim)."""
        return {**self.__dict__, "_memo": None, "_taps": None, "_lin": None, "Phi_B": None,
                **({"Phi_Bz": None} if "Phi_Bz" in self.__dict__ else {})}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if self.n_b > 1:
            self.Phi_B = self.rec.width_basis(self.n_b)
            if self.width_at == "output":
                self.Phi_Bz = self.rec.width_basis(self.n_b, "z")
        self._taps = self._band_taps()

    def columns(self, th: np.ndarray) -> tuple[dict, np.ndarray, np.ndarray, dict]:
        """The linear model's columns at theta: {"G": (F, n_g), "ring": [(F,) x 2] or absent,
        "tip", "motor": (F, `n_reg`, 2) each or absent (S times the rigid registration's motions)},
        the onsets t_on (M,), z at the frames (F,) and what `jacobian` needs (a dict; "pvar_tip",
        "pvar_motor" (F,): each frame's switch-share variance p (1 - p))."""
        rec = self.rec
        d, cB, ring, lags = self.unpack(th)
        slides = self.slides(th)
        e = self.exposure(th)
        z, band0, last, side, t_on, tau, z_f, G, drive, nodes = self._play_part(d, cB, self.z0_of(th), e, self.spread(th))
        cols = {"G": G}
        zn = (2 * z_f - (self.q_lo + self.q_hi)) / max(self.q_hi - self.q_lo, 1e-12)
        st = {"z": z, "band0": band0, "tau": tau, "zn": zn, "ring": ring, "last": last, "side": side, "expo": e,
              "nodes": nodes}
        if self.terms.ring:
            st["mask"], st["u"] = drive
            st["x"] = [_tip_mode(u, ring[0], ring[1], rec.dt) for u in st["u"]]
            cols["ring"] = [np.interp(tau, rec.t[1:-1], x) for x in st["x"]]
        if self.terms.reg_tip:
            ok = np.isfinite(t_on)
            s_ev = rec.s_new[ok]
            keep = np.r_[True, s_ev[1:] != s_ev[:-1]][:s_ev.size]  # a direction the tip already moves in is no switch
            s0 = -s_ev[0] if s_ev.size else 1.0
            # seen through the exposure (module doc: the exposure), a switch's window opens e / 2
            # before it and its move takes e longer
            t_ev, s_ev, r_ev = t_on[ok][keep] - 0.5 * e, s_ev[keep], np.flatnonzero(ok)[keep]
            L, D = lags["tip"], slides["tip"]
            S = _ramp_sign(tau, t_ev, s_ev, s0, L + D + e)  # the stand-in's window: the whole switch
            pv = _share_var(tau, t_ev, L + D + e)
            self._mix_columns("tip", S, pv, tau, t_on - 0.5 * e, L, D, e, st)
            cols["tip"] = S[:, None, None] * self.generators("tip")
            st["tip"] = (S, t_ev, s_ev, np.r_[s0, s_ev[:-1]], L, r_ev, D)
            st["pvar_tip"] = pv
        if self.terms.reg_motor:
            s0 = -rec.s_new[0]
            L, D = lags["motor"], slides["motor"]
            t_ev = rec.rt - 0.5 * e
            S = _ramp_sign(tau, t_ev, rec.s_new, s0, L + D + e)
            pv = _share_var(tau, t_ev, L + D + e)
            self._mix_columns("motor", S, pv, tau, t_ev, L, D, e, st)
            cols["motor"] = S[:, None, None] * self.generators("motor")
            st["motor"] = (S, t_ev, rec.s_new, np.r_[s0, rec.s_new[:-1]], L, np.arange(rec.rt.size), D)
            st["pvar_motor"] = pv
        return cols, t_on, z_f, st

    # ---- the switch as a two-point mixture (module doc): an EM whose E-step gives each frame near a
    # switch its posterior share gamma of the new level and whose M-step is the least squares below
    def _mix_columns(self, name: str, S: np.ndarray, pvar: np.ndarray, tau: np.ndarray, t_rev: np.ndarray,
                     L: float, D: float, E: float, st: dict) -> None:
        """Apply the E-step's shares to a term's sign S and share variance pvar (F,) in place: a frame
        with shares gamma_new, gamma_mid at level h_mid has the expected sign s_prev + h_bar (s_new -
        s_prev), h_bar = gamma_new + gamma_mid h_mid, and no share variance (its spread is the linear
        parameters' penalty, `solve`); st[name + "_mix"] gets the frames, their shares, the prior shares
        at this theta (`_switch_shares`, lag L, longest slide D, exposure E; clipped into [EPS_SHARE, 1 - EPS_SHARE]),
        where each is unclipped and their derivatives, and each frame's spread (s_new - s_prev)^2
        Var(h), the weight of its penalty on the rotation (`solve`, `mix_rows`). t_rev (M,) the term's
        switch starts per reversal (NaN: none)."""
        mx = self.mix.get(name)
        if not mx:
            return
        j, g, gm, hm, rev, sp, sn = mx["j"], mx["gamma"], mx["gamma_mid"], mx["h_mid"], mx["rev"], mx["sp"], mx["sn"]
        hbar = g + gm * hm
        S[j] = sp + hbar * (sn - sp)
        pvar[j] = 0.0
        since = tau[j] - t_rev[rev]
        ok = np.isfinite(since)
        since = np.where(ok, since, -1.0)  # no switch at this theta: the frame is at the old level
        po, pn, dpo, dpn = _switch_shares(since, L, D, E)
        shares = {}
        for lvl, pr, dp in (("old", po, dpo), ("new", pn, dpn)):
            shares["p_" + lvl] = np.clip(pr, EPS_SHARE, 1.0 - EPS_SHARE)
            shares["free_" + lvl] = ok & (pr > EPS_SHARE) & (pr < 1.0 - EPS_SHARE)
            shares["dp_" + lvl] = dp
        st[name + "_mix"] = {"j": j, "gamma": g, "gamma_mid": gm, "h_mid": hm, **shares, "rev": rev, "ds": sn - sp,
                             "L": L, "D": D, "E": E, "spread": (sn - sp) ** 2 * np.maximum(g + gm * hm * hm - hbar * hbar, 0.0)}

    def e_step(self, ev: "Eval", sigma: float) -> bool:
        """The mixture's E-step at an evaluation (module doc): for each switch term, the frames within
        a frame period of a switch window [t_ev, t_ev + L + D] get their posterior shares of the
        levels, gamma ~ p e^-rho (p the prior shares, `_switch_shares`, clipped into [EPS_SHARE,
        1 - EPS_SHARE]; rho the Huber loss of the frame's two residuals at each level, at sigma px;
        mid slide, the level's integrated likelihood, `_mid_level`). The frames and their switches
        are then fixed for the M-step. Returns False when the model had no mixture and still has none
        (no switch term, or no frame near a switch): its evaluations are then what they were, bit for
        bit, and a caller need not evaluate it again."""
        st = ev.state
        new = {}
        T = self.rec.period_s
        for name in ("tip", "motor"):
            if name not in st:
                continue
            S, t_ev, s_ev, s_prev, L, r_ev, D = st[name]
            E = st["expo"]  # the exposure (0: none), which opened the window t_ev e / 2 early
            tau = st["tau"]
            if t_ev.size == 0:
                continue
            e = np.searchsorted(t_ev, tau + T, side="right") - 1
            e0 = np.maximum(e, 0)
            near = (e >= 0) & (tau < t_ev[e0] + L + D + E + T)
            j = np.flatnonzero(near)
            if j.size == 0:
                continue
            e = e0[j]
            du, dv = self.reg_offset(ev, name)
            F = tau.size
            ru, rv = ev.resid[j], ev.resid[F + j]
            rho = {}
            for lvl, sgn in (("new", s_ev[e]), ("old", s_prev[e])):
                k = sgn - S[j]
                rho[lvl] = huber_rho(ru - k * du[j], sigma) + huber_rho(rv - k * dv[j], sigma)
            po, pn = (np.clip(x, EPS_SHARE, 1.0 - EPS_SHARE) for x in _switch_shares(tau[j] - t_ev[e], L, D, E)[:2])
            if D + E > 0.0:
                k = s_prev[e] - S[j]
                ds = s_ev[e] - s_prev[e]
                hm, ln_mid = _mid_level(ru - k * du[j], rv - k * dv[j], ds * du[j], ds * dv[j], sigma)
                lw = np.vstack([np.log(po) - rho["old"], np.log(pn) - rho["new"],
                                np.log(np.maximum(1.0 - po - pn, 1e-300)) + ln_mid])
                lw = np.exp(lw - lw.max(axis=0))
                g, gm = lw[1] / lw.sum(axis=0), lw[2] / lw.sum(axis=0)
            else:
                g = expit(logit(pn) + np.clip(rho["old"] - rho["new"], -50.0, 50.0))
                gm, hm = np.zeros(j.size), np.zeros(j.size)
            keep = ~np.isin(j, new["tip"]["j"]) if "tip" in new else np.ones(j.size, bool)  # one mixture a frame
            new[name] = {"j": j[keep], "gamma": g[keep], "gamma_mid": gm[keep], "h_mid": hm[keep], "rev": r_ev[e][keep],
                         "sp": s_prev[e][keep].astype(float), "sn": s_ev[e][keep].astype(float)}
        changed = bool(new) or bool(self.mix)
        self.mix = new
        return changed

    def mix_rows(self, ev: "Eval", sigma: float) -> tuple[np.ndarray, np.ndarray]:
        """The M-step's extra residuals, sigma units: per mixture frame the prior shares' divergence
        (`_kl_rows`), then the levels' spread, sqrt(w (s_new - s_prev)^2 Var(h)) times the term's
        offset at the frame, u then v (`solve`'s penalty)."""
        kl, pen = [], []
        for name in ("tip", "motor"):
            mx = ev.state.get(name + "_mix")
            if mx is None:
                continue
            kl += [r for r, _ in self._kl_rows(mx)]
            du, dv = self.reg_offset(ev, name)
            j, c = mx["j"], mx["spread"]
            F = self.rec.t_f.size
            pen += [-np.sqrt(c * self.w[j]) * du[j] / sigma, -np.sqrt(c * self.w[F + j]) * dv[j] / sigma]
        cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(0))
        return cat(kl), cat(pen)

    @staticmethod
    def _kl_rows(mx: dict) -> list:
        """The timing rows of a term's mixture frames and their derivatives over (since, L, D, E):
        [(row (K,), d row / d (since, L, D, E) (4, K))]. Their squares sum to 2 KL(gamma || p) over the
        levels, split by the chain rule (new or not; then old or mid slide, weighted by 1 - gamma_new):
        each a signed square root, smooth through its minimum (module doc)."""
        g, pn = mx["gamma"], mx["p_new"]
        r1, d1 = _kl_row_grad(g, pn, mx["free_new"])
        rows = [(r1, d1 * mx["dp_new"])]
        if mx["D"] + mx["E"] > 0.0:
            po, rest = mx["p_old"], 1.0 - pn
            cp_raw = po / rest
            cp = np.clip(cp_raw, EPS_SHARE, 1.0 - EPS_SHARE)
            w = np.sqrt(np.maximum(1.0 - g, 0.0))
            cg = np.clip((1.0 - g - mx["gamma_mid"]) / np.maximum(1.0 - g, 1e-300), 0.0, 1.0)
            r2, d2 = _kl_row_grad(cg, cp, (cp_raw > EPS_SHARE) & (cp_raw < 1.0 - EPS_SHARE))
            dcp = (np.where(mx["free_old"], 1.0, 0.0) * mx["dp_old"] * rest
                   + po * np.where(mx["free_new"], 1.0, 0.0) * mx["dp_new"]) / rest ** 2
            rows.append((w * r2, w * d2 * dcp))
        return rows

    def shared_columns(self, cols: dict) -> list:
        """The columns whose coefficient both image axes share, as (u, v) pairs of (F,): the tip
        mode's two along the path's tangent (from the previous round's G'), then the tip's and the
        motor's registration (`n_reg` each). beta = [G_u (n_g), G_v (n_g), these in this order]."""
        F = self.rec.obs.shape[0]
        out = []
        if "ring" in cols:
            sl = self.slope if self.slope is not None else np.zeros((F, 2))
            out += [(sl[:, 0] * x, sl[:, 1] * x) for x in cols["ring"]]
        for k in ("tip", "motor"):
            if k in cols:
                out += [(cols[k][:, i, 0], cols[k][:, i, 1]) for i in range(cols[k].shape[1])]
        return out

    def reg_offset(self, ev: "Eval", name: str) -> tuple[np.ndarray, np.ndarray]:
        """The registration term name's ("tip" or "motor") offset at S = +1, (u, v) (F,) px each,
        from an evaluation's beta (its rotation, rad): half the jump a switch makes."""
        k = 2 * self.n_g + self.mix_block(name)
        a = ev.beta[k:k + self.n_reg(name)]
        g = self.generators(name)
        return g[:, :, 0] @ a, g[:, :, 1] @ a

    def n_reg(self, name: str) -> int:
        """The registration term name's ("tip", "motor") coefficients: its rotation's N_REG, or with
        the shift_ term its translation's N_SHIFT in their place (module doc: the shift)."""
        return N_SHIFT if getattr(self.terms, "shift_" + name) else N_REG

    def generators(self, name: str) -> np.ndarray:
        """The registration term name's image motions (F, `n_reg`, 2): Record.reg_gen's rotations, or
        with the shift_ term its translations."""
        if getattr(self.terms, "shift_" + name):
            return self.rec.reg_gen[:, N_REG:N_REG + N_SHIFT]
        return self.rec.reg_gen[:, :N_REG]

    def scales(self, ev: "Eval", sigma: float) -> np.ndarray:
        """Each residual's scale sigma_j (2F,) px: sigma with the switch-share variance added
        (module doc)."""
        F = self.rec.obs.shape[0]
        var = np.full(2 * F, sigma * sigma)
        for name in ("tip", "motor"):
            if "pvar_" + name in ev.state:
                du, dv = self.reg_offset(ev, name)
                pv = ev.state["pvar_" + name]
                var += np.r_[pv * (2 * du) ** 2, pv * (2 * dv) ** 2]
        return np.sqrt(var)

    def weights(self, ev: "Eval", sigma: float) -> np.ndarray:
        """IRLS weights (2F,) relative to sigma: Huber's psi(r)/r at each residual's own scale,
        times sigma^2 / sigma_j^2."""
        sj = self.scales(ev, sigma)
        r = ev.resid.copy()
        F = self.rec.t_f.size
        for name, j, lv in self._branches(ev):
            mx = ev.state[name + "_mix"]
            g, gm = mx["gamma"], mx["gamma_mid"]
            # the likelier level's residual sets a mixture frame's weight
            best = np.argmax(np.vstack([1.0 - g - gm, g, gm]), axis=0)
            for ax in range(2):
                r[ax * F + j] = np.choose(best, [lv["old"][ax], lv["new"][ax], lv["mid"][ax]])
        return huber_weights(r, sj) * (sigma / sj) ** 2

    def _branches(self, ev: "Eval"):
        """Per switch term with mixture frames: (name, frames j, {"old", "new", "mid": the residuals
        (u, v) at that level}), from the expected-sign residuals; "mid" at the E-step's h_mid."""
        F = self.rec.t_f.size
        out = []
        for name in ("tip", "motor"):
            mx = ev.state.get(name + "_mix")
            if mx is None:
                continue
            j, ds = mx["j"], mx["ds"]
            hbar = mx["gamma"] + mx["gamma_mid"] * mx["h_mid"]
            du, dv = self.reg_offset(ev, name)
            ru, rv = ev.resid[j], ev.resid[F + j]
            lv = {}
            for lvl, h in (("new", 1.0), ("old", 0.0), ("mid", mx["h_mid"])):
                lv[lvl] = (ru - (h - hbar) * ds * du[j], rv - (h - hbar) * ds * dv[j])
            out.append((name, j, lv))
        return out

    def objective(self, ev: "Eval", sigma: float) -> float:
        """2 sum rho(r_j / sigma_j) + 2 sum ln(sigma_j / sigma): the robust objective the BIC
        uses (module doc)."""
        sj = self.scales(ev, sigma)
        rho = huber_rho(ev.resid, sj)
        F = self.rec.t_f.size
        out = 2.0 * float(np.sum(rho)) + 2.0 * float(np.sum(np.log(sj / sigma)))
        for name, j, lv in self._branches(ev):
            # a mixture frame: -2 ln(sum over levels of p e^-rho) in place of its expected-sign loss
            mx = ev.state[name + "_mix"]
            a = [np.log(mx["p_new"]) - huber_rho(lv["new"][0], sigma) - huber_rho(lv["new"][1], sigma),
                 np.log(mx["p_old"]) - huber_rho(lv["old"][0], sigma) - huber_rho(lv["old"][1], sigma)]
            if mx["D"] + mx["E"] > 0.0:
                ds = mx["ds"]
                du, dv = self.reg_offset(ev, name)
                ln_mid = _mid_level(*lv["old"], ds * du[j], ds * dv[j], sigma)[1]
                a.append(np.log(np.maximum(1.0 - mx["p_new"] - mx["p_old"], 1e-300)) + ln_mid)
            out += float(np.sum(-2.0 * np.logaddexp.reduce(np.vstack(a), axis=0) - 2.0 * (rho[j] + rho[F + j])))
        return out

    def mix_block(self, name: str) -> int:
        """Where the term name's ("tip", "motor") rotation starts among the shared columns."""
        return 2 * self.terms.ring + (self.n_reg("tip") if (name == "motor" and self.terms.reg_tip) else 0)

    def solve(self, cols: dict, st: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Weighted least squares of the stacked [u; v] on the columns, by the normal equations, G's
        coefficients under a small second-difference penalty (G_PENALTY), each switch's rotation under
        its mixture frames' spread (st's "<term>_mix": sum w (s_new - s_prev)^2 gamma (1 - gamma)
        (R a)^2, the M-step's second moment): (beta, residuals (2F,))."""
        o = self.rec.obs
        F = o.shape[0]
        A1 = cols["G"]
        p = A1.shape[1]
        wu, wv = self.w[:F], self.w[F:]
        ring = self.shared_columns(cols)
        P = 2 * p + len(ring)
        M = np.zeros((P, P))
        rhs = np.zeros(P)
        M[:p, :p] = A1.T @ (wu[:, None] * A1)
        M[p:2 * p, p:2 * p] = A1.T @ (wv[:, None] * A1)
        rhs[:p] = A1.T @ (wu * o[:, 0])
        rhs[p:2 * p] = A1.T @ (wv * o[:, 1])
        if ring:
            Ru = np.column_stack([r[0] for r in ring])
            Rv = np.column_stack([r[1] for r in ring])
            M[:p, 2 * p:] = A1.T @ (wu[:, None] * Ru)
            M[p:2 * p, 2 * p:] = A1.T @ (wv[:, None] * Rv)
            M[2 * p:, :2 * p] = M[:2 * p, 2 * p:].T
            M[2 * p:, 2 * p:] = Ru.T @ (wu[:, None] * Ru) + Rv.T @ (wv[:, None] * Rv)
            rhs[2 * p:] = Ru.T @ (wu * o[:, 0]) + Rv.T @ (wv * o[:, 1])
        # G's coefficients beyond the frames' reach: a second-difference penalty (a P-spline, Eilers &
        # Marx 1996) continues G linearly there, G_PENALTY of its block's mean pivot, too small to bend it
        # where frames are. A ridge pulled them towards 0 px instead, scaled by a trace the registration's
        # columns (px per rad) dominate: at the travel's ends, which few frames reach, G fell tens of px
        # off them and the Huber reweighting then dropped them for good (the weighted sum of squares rose
        # with each round).
        DtD = _second_difference_gram(p)
        for blk in (slice(0, p), slice(p, 2 * p)):
            M[blk, blk] += G_PENALTY * (np.trace(M[blk, blk]) / p + 1e-30) * DtD
        for name in ("tip", "motor"):
            mx = None if st is None else st.get(name + "_mix")
            if mx is None:
                continue
            j, c = mx["j"], mx["spread"]
            g = self.generators(name)[j]
            a = slice(2 * p + self.mix_block(name), 2 * p + self.mix_block(name) + self.n_reg(name))
            M[a, a] += g[:, :, 0].T @ ((c * wu[j])[:, None] * g[:, :, 0]) + g[:, :, 1].T @ ((c * wv[j])[:, None] * g[:, :, 1])
        M[np.diag_indices(P)] *= 1.0 + 1e-12  # scale-free: an absent column's zero pivot stays harmless
        M[np.diag_indices(P)] += 1e-30
        beta = np.linalg.solve(M, rhs)
        fu = A1 @ beta[:p] + sum(b * r[0] for b, r in zip(beta[2 * p:], ring))
        fv = A1 @ beta[p:2 * p] + sum(b * r[1] for b, r in zip(beta[2 * p:], ring))
        self._lin = (A1, ring, M, p)
        return beta, np.r_[o[:, 0] - fu, o[:, 1] - fv]

    def project(self, Gu: np.ndarray, Gv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(I - A (A'WA)^-1 A'W) applied to the stacked columns [Gu; Gv] ((F, k) each), A and W
        those of the last `solve`: the part of a change of the prediction the linear
        parameters cannot take up (variable projection)."""
        A1, ring, M, p = self._lin
        F = A1.shape[0]
        wu, wv = self.w[:F, None], self.w[F:, None]
        rhs = [A1.T @ (wu * Gu), A1.T @ (wv * Gv)]
        rhs += [(wu[:, 0] * ru) @ Gu + (wv[:, 0] * rv) @ Gv for ru, rv in ring]
        X = np.linalg.solve(M, np.vstack([np.atleast_2d(r) for r in rhs]))
        self._X = X
        Au = A1 @ X[:p] + sum(np.outer(ru, X[2 * p + i]) for i, (ru, _) in enumerate(ring))
        Av = A1 @ X[p:2 * p] + sum(np.outer(rv, X[2 * p + i]) for i, (_, rv) in enumerate(ring))
        return Gu - Au, Gv - Av

    def onset_gradient(self, cB: np.ndarray, st: dict, t_on: np.ndarray, s_new: np.ndarray,
                       x0: float) -> tuple[np.ndarray, np.ndarray]:
        """(d t_on / d (B's coefficients) (E, n_b) s per actuator unit, d t_on / d x0 (E,) s) for
        onsets t_on (E,) of the play in st (`columns`: z, its band and drags) for B's coefficients
        cB and first state x0, whose new directions are s_new (E,): the new edge e (side -s / 2)
        meets the held z within the grid step k where z first moves, t_on = t_k - dt (e_k -
        z_hold) / (q_k - q_k-1) (`onsets`), so t_on moves by (dz_hold/dc_i - de_k/dc_i) / q'(t_k)
        (`edge_gradient`); the held z moves with the edge that last dragged it, or with the first
        state before any did (`z_gradient`)."""
        rec, z = self.rec, st["z"]
        kk = np.clip(np.searchsorted(rec.t, t_on), 1, z.size - 1)
        g_h, dx = self.z_gradient(cB, st, kk - 1, x0)
        g_on = self.edge_gradient(cB, kk, z[kk], -0.5 * s_new)  # z[kk]: the new edge, where it caught z
        qdot = (rec.q[kk] - rec.q[kk - 1]) / rec.dt
        qdot = np.where(np.abs(qdot) > 1e-12, qdot, 1e-12)
        return (g_h - g_on) / qdot[:, None], dx / qdot

    def tip_onset_gradient(self, cB: np.ndarray, st: dict, t_on: np.ndarray, s_new: np.ndarray,
                           x0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """`onset_gradient` of the onsets t_on (E,) s at which a switch that follows the tip starts: (d t_on
        / d (B's coefficients) (E, n_b) s per actuator unit, d t_on / d x0 (E,) s, d t_on / d s (E,) s, or
        None without the spread). With the spread they are the narrowest node's first motions (module
        doc: the spread), its play that of m_0 cB: with g its gradient there, m_0 g over cB and u_0 g cB
        over s."""
        nodes = st.get("nodes")
        if not nodes:
            return (*self.onset_gradient(cB, st, t_on, s_new, x0), None)
        m0, u0, nst0 = nodes[0]
        g0, dx = self.onset_gradient(m0 * cB, {**st, **nst0}, t_on, s_new, x0)
        return m0 * g0, dx, u0 * (g0 @ cB)

    def _edge_rows(self, cB: np.ndarray, k: np.ndarray, z: np.ndarray, side: np.ndarray):
        """`edge_gradient` in sparse form: (cols (len(k), w) int, vals (len(k), w)), row r of the
        dense gradient holding vals[r] at cols[r] (w = 4, a cubic's non-zeros; 1 for a constant
        width). For the whole grid at once (`ring_gradient`), where the dense rows cost more than the
        filtering they feed."""
        if self.n_b == 1:
            return np.zeros((k.size, 1), int), side[:, None].astype(float)
        if self.width_at == "input":
            ind = self.Phi_B.indices.reshape(-1, 4)[k]
            return ind, self.Phi_B.data.reshape(-1, 4)[k] * side[:, None]
        phi = _sparse_basis(z, self.q_lo, self.q_hi, self.n_b)
        inner = np.linspace(self.q_lo, self.q_hi, self.n_b - 2)
        knots = np.r_[[self.q_lo] * 3, inner, [self.q_hi] * 3]
        dB = BSpline(knots, cB, 3).derivative()(np.clip(z, self.q_lo, np.nextafter(self.q_hi, -np.inf)))
        fac = side / np.maximum(1.0 - side * dB, 0.05)
        return phi.indices.reshape(-1, 4), phi.data.reshape(-1, 4) * fac[:, None]

    def ring_gradient(self, cB: np.ndarray, st: dict, x0: float, gains: np.ndarray) -> np.ndarray:
        """d (g_stop x_stop + g_start x_start) / d (B's coefficients) at the frames (F, n_b), gains
        (g_stop, g_start) the tip mode's two gains. The mode is linear in its drive u = -z'' (each
        part on its fixed mask, `columns`), so the gains' sum of its derivatives is the mode's
        response to -(dz/dc)'' weighted by the part's gain at each sample: one filtering of the
        n_b rows rather than one per part. With ring_motor the stop's part is the motor's, which
        does not move with B: its gain weighs nothing here. dz/dc on the grid is the edge gradient
        of the drag that last set z (`edge_gradient`), which jumps at each onset by the new edge's speed times the
        onset's shift, so the response carries the start's shift in time (a dipole through the
        filter). Without it a 10 px ring moved by a millisecond per onset went unseen: the gradient
        over B came out a third of the differences' on a fast 60 fps triangle and the fit stopped
        in a B 25 % low."""
        rec = self.rec
        dt = rec.dt
        last = st["last"]
        N = last.size
        pre_row = self.z_gradient(cB, st, np.zeros(1, int), x0)[0][0]  # before the first drag: the first state's
        # -u's part gains, the second difference's scale; a stop driven by the motor does not move with B
        wd = np.where(st["mask"][0], 0.0 if self.terms.ring_motor else -gains[0], -gains[1]) / (dt * dt)
        b, a = _tip_filter(st["ring"][0], st["ring"][1], dt)
        pos = np.clip((st["tau"] - rec.t[1]) / dt, 0.0, N - 2 - 1.000001)
        i0 = pos.astype(int)
        wgt = pos - i0
        if kernels.available() and np.all(np.diff(i0) >= 0):  # in one pass, the gradient built row by row (bit for bit)
            if self.width_at == "input" and self._taps is not None:  # the band's own taps at the last drag
                return kernels.tip_mode_edges(self._taps[0], self._taps[1], last, st["side"][np.maximum(last, 0)],
                                              pre_row, wd, b[1], a[1], a[2], i0, 1.0 - wgt, wgt)
            drag = last == np.arange(N)
            ks = np.flatnonzero(drag)
            cols, vals = self._edge_rows(cB, ks, st["z"][ks], st["side"][ks])
            src = np.where(last >= 0, np.cumsum(drag) - 1, -1)
            return kernels.tip_mode_edges(cols, vals, src, np.ones(N), pre_row, wd, b[1], a[1], a[2], i0, 1.0 - wgt, wgt)
        ks = np.flatnonzero(last == np.arange(N))  # the drag samples themselves
        cols, vals = self._edge_rows(cB, ks, st["z"][ks], st["side"][ks])
        Zg = np.zeros((self.n_b, N))  # dz/dc on the grid: held samples keep their last drag's
        held = np.flatnonzero(last >= 0)
        r = np.searchsorted(ks, last[held])
        for j in range(cols.shape[1]):  # a row's columns are distinct: plain assignment
            Zg[cols[r, j], held] = vals[r, j]
        Zg[:, last < 0] = pre_row[:, None]
        x = lfilter(b, a, np.diff(Zg, 2, axis=1) * wd, axis=1)
        return (x[:, i0] * (1.0 - wgt) + x[:, i0 + 1] * wgt).T

    def jacobian(self, th: np.ndarray, ev: "Eval", sigma: float) -> np.ndarray:
        """d residual / d theta (2F [+ 1 prior row], n_theta) of `_residual_fn`'s residuals, by
        Kaufman's variable-projection Jacobian (Kaufman 1975, BIT 15: the prediction's
        derivative at fixed linear parameters, projected off the linear columns). The play's
        derivative: z moves with the band edge that last dragged it, dz/dc_i = -+ phi_i(q) / 2 at
        that sample; an onset moves by (dz_hold/dc_i + s phi_i(q_on) / 2) / q'(t_on) (s: the new
        direction); the delay moves every frame's tau by -dd. The tip mode's response to B is
        its response to the drive's derivative (`ring_gradient`); its frequency and damping are
        differenced. Same units as the residuals (sigma)."""
        rec, st = self.rec, ev.state
        d, cB, ring, lags = self.unpack(th)
        lay = self.layout()
        z, tau = st["z"], st["tau"]
        F = tau.size
        A1, rcols, M, p = self._lin
        beta = ev.beta
        bu, bv, gr = beta[:p], beta[p:2 * p], beta[2 * p:]
        ng = self.n_g
        dBas = _dbasis(ev.z_f, self.z_lo, self.z_hi, ng)
        dz_u, dz_v = dBas @ bu[:ng], dBas @ bv[:ng]          # dP/dz at fixed beta
        reg = {name: self.reg_offset(ev, name) for name in ("tip", "motor") if name in st}
        dt = rec.dt
        offs = self.expo_offsets(st["expo"])
        zd_nodes = [np.interp(tau + o, rec.t[:-1] + 0.5 * dt, np.diff(z) / dt) for o in offs]
        zdot = np.mean(zd_nodes, axis=0)  # d z_f / d tau: z's slope averaged over the exposure's nodes
        Gu = np.zeros((F, th.size))
        Gv = np.zeros((F, th.size))
        # the delay: tau = t_f - d
        Gu[:, 0] = -dz_u * zdot
        Gv[:, 0] = -dz_v * zdot
        if "expo" in lay:  # the nodes sit at e c_k, so d z_f / d e = mean of z'(tau + e c_k) c_k
            i = lay["expo"].start
            dzf_de = np.mean([zd * (o / st["expo"]) for zd, o in zip(zd_nodes, offs)], axis=0) * self.expo_map(th[i])[1]
            Gu[:, i] = dz_u * dzf_de
            Gv[:, i] = dz_v * dzf_de
        if self.terms.ring:  # the gains' sum of the two parts, differenced once
            sl = self.slope
            xdot = np.interp(tau, rec.t[1:-2] + 0.5 * dt, np.diff(gr[0] * st["x"][0] + gr[1] * st["x"][1]) / dt)
            Gu[:, 0] -= sl[:, 0] * xdot
            Gv[:, 0] -= sl[:, 1] * xdot
        ramps = {}
        for name, val in reg.items():
            t_ev, s_ev, s_prev, L = st[name][1:5]
            Lw = L + st[name][6] + st["expo"]  # the stand-in's window: lag, longest slide and exposure
            if t_ev.size == 0:  # no switch at this theta (a B no swing takes up): nothing moves with tau
                continue
            e = np.searchsorted(t_ev, tau, side="right") - 1
            e0 = np.maximum(e, 0)
            inr = (e >= 0) & (tau < t_ev[e0] + Lw)
            if name + "_mix" in st:  # a mixture frame's sign is the E-step's: its timing is in the KL rows
                inr[st[name + "_mix"]["j"]] = False
            dS = np.where(inr, (s_ev[e0] - s_prev[e0]) / Lw, 0.0)     # dS / dtau inside a switch
            Gu[:, 0] -= dS * val[0]
            Gv[:, 0] -= dS * val[1]
            dW = -dS * np.where(inr, tau - t_ev[e0], 0.0) / Lw  # dS / d(the window)
            for part, dmap in (("lag_", self.lag_map), ("slide_", self.slide_map)):
                if part + name in lay:
                    i = lay[part + name].start
                    Gu[:, i] = dW * dmap(th[i])[1] * val[0]
                    Gv[:, i] = dW * dmap(th[i])[1] * val[1]
            if "expo" in lay:  # the window opens e / 2 earlier and is e longer
                i = lay["expo"].start
                dSe = (0.5 * dS + dW) * self.expo_map(th[i])[1]
                Gu[:, i] += dSe * val[0]
                Gv[:, i] += dSe * val[1]
            ramps[name] = (e, inr, dS)
        # B's coefficients and the first state: through z at each frame (the last drag, or the
        # first state before any), and the tip switch's onsets. The tip mode's drive through the
        # first state (its first start moved in time) is left out: one start of the record's many.
        x0, i_z0 = self.z0_of(th), lay["z0"].start
        nodes = st.get("nodes")
        i_s = lay["spread"].start if nodes else None
        ds_dx = self.spread_map(th[i_s])[1] if nodes else 0.0
        Zc, Zx, Zs = 0.0, 0.0, 0.0
        for o in offs:  # z_f is the mean of z over the exposure's nodes, and so is its gradient
            zc, zx, zs = self.spread_gradient(cB, st, np.clip(np.searchsorted(rec.t, tau + o), 0, z.size - 1), x0)
            Zc, Zx = Zc + zc / offs.size, Zx + zx / offs.size
            if zs is not None:
                Zs = Zs + zs / offs.size
        sl_b = slice(1, 1 + self.n_b)
        Gu[:, sl_b] = dz_u[:, None] * Zc
        Gv[:, sl_b] = dz_v[:, None] * Zc
        Gu[:, i_z0] = dz_u * Zx
        Gv[:, i_z0] = dz_v * Zx
        if nodes:
            Gu[:, i_s] = dz_u * Zs * ds_dx
            Gv[:, i_s] = dz_v * Zs * ds_dx
        if self.terms.ring:  # the tip mode's drive through B: an onset moves the start it excites
            if nodes:  # each node's play drives the mode by its share (the mode is linear in its drive)
                dx, dxs = 0.0, 0.0
                for m, u, nst in nodes:
                    r = self.ring_gradient(m * cB, {**st, **nst}, x0, gr[:2])
                    dx, dxs = dx + m * r / len(nodes), dxs + u * (r @ cB) / len(nodes)
                Gu[:, i_s] += self.slope[:, 0] * dxs * ds_dx
                Gv[:, i_s] += self.slope[:, 1] * dxs * ds_dx
            else:
                dx = self.ring_gradient(cB, st, x0, gr[:2])
            Gu[:, sl_b] += self.slope[:, 0, None] * dx
            Gv[:, sl_b] += self.slope[:, 1, None] * dx
        if "tip" in ramps:
            e, inr, dS = ramps["tip"]
            dton, dton_x, dton_s = self.tip_onset_gradient(cB, st, st["tip"][1] + 0.5 * st["expo"],
                                                           rec.s_new[st["tip"][5]], x0)
            fr = np.flatnonzero(inr)
            val = reg["tip"]
            Gu[fr, sl_b] += (-dS[fr] * val[0][fr])[:, None] * dton[e[fr]]
            Gv[fr, sl_b] += (-dS[fr] * val[1][fr])[:, None] * dton[e[fr]]
            Gu[fr, i_z0] += -dS[fr] * val[0][fr] * dton_x[e[fr]]
            Gv[fr, i_z0] += -dS[fr] * val[1][fr] * dton_x[e[fr]]
            if nodes:
                Gu[fr, i_s] += -dS[fr] * val[0][fr] * dton_s[e[fr]] * ds_dx
                Gv[fr, i_s] += -dS[fr] * val[1][fr] * dton_s[e[fr]] * ds_dx
        if self.terms.ring:
            sl = self.slope
            i0 = lay["ring"].start
            # central differences: the gradient's cosine to small steps' 0.99997 -> 1.0000; the columns stay
            # about 0.98 off them away from the optimum, Kaufman's dropped term, not the differencing
            h = 0.01
            u = gr[0] * st["u"][0] + gr[1] * st["u"][1]  # the gains' sum of the parts' drives (the mode is linear)
            for j in range(2):
                tp, tm = th.copy(), th.copy()
                tp[i0 + j] += h
                tm[i0 + j] -= h
                fp, fm = self.unpack(tp)[2], self.unpack(tm)[2]
                dx = np.interp(tau, rec.t[1:-1], _tip_mode(u, fp[0], fp[1], dt) - _tip_mode(u, fm[0], fm[1], dt)) / (2 * h)
                Gu[:, i0 + j] += sl[:, 0] * dx
                Gv[:, i0 + j] += sl[:, 1] * dx
        if self.d_fixed is not None:
            Gu[:, 0] = Gv[:, 0] = 0.0
        Pu, Pv = self.project(Gu, Gv)
        # the rows stacked as `_residual_fn` stacks the residuals: the frames' u then v (weighted, in
        # sigma units), the prior's row, the mixture's rows; filled in place rather than stacked (each
        # stacking copied the 2F rows again: 0.5 of the bench record's 3.4 ms a Jacobian), the same bits
        mix = self._mix_jacobian(th, ev, sigma)
        prior = self.prior is not None and self.d_fixed is None
        J = np.empty((2 * F + prior + sum(r.shape[0] for r in mix), th.size))
        msw = -np.sqrt(self.w)
        for rows, P in ((slice(0, F), Pu), (slice(F, 2 * F), Pv)):
            np.multiply(msw[rows, None], P, out=J[rows])
            J[rows] /= sigma
        if prior:
            J[2 * F] = 0.0
            J[2 * F, 0] = self.prior_residual(d)[1]
        i = 2 * F + prior
        for r in mix:
            J[i:i + r.shape[0]] = r
            i += r.shape[0]
        return J

    def _mix_jacobian(self, th: np.ndarray, ev: "Eval", sigma: float) -> list:
        """The rows of `mix_rows` over theta: the divergences through the shares' time since the
        switch's window opened (the delay moves tau, B the tip's onsets), the lag L and the longest
        slide D (`_kl_rows`); the spread's rows through the rotation's projection (Kaufman's, as
        `jacobian`)."""
        rec, st = self.rec, ev.state
        cB = self.unpack(th)[1]
        lay = self.layout()
        kl, pen = [], []
        p = self._lin[3]
        F = rec.t_f.size
        for name in ("tip", "motor"):
            mx = st.get(name + "_mix")
            if mx is None:
                continue
            dton = None
            if name == "tip":
                t_on = ev.t_on
                rev = mx["rev"]
                ok = np.isfinite(t_on[rev])
                if ok.any():
                    u_rev, inv = np.unique(rev[ok], return_inverse=True)
                    dton, dton_x, dton_s = self.tip_onset_gradient(cB, st, t_on[u_rev], rec.s_new[u_rev], self.z0_of(th))
                    dton, dton_x = dton[inv], dton_x[inv]
                    dton_s = None if dton_s is None else dton_s[inv]
            for _, dr in self._kl_rows(mx):
                Jk = np.zeros((dr.shape[1], th.size))
                if self.d_fixed is None:
                    Jk[:, 0] = -dr[0]                      # since = t_f - d - t_switch
                i = lay["lag_" + name].start
                Jk[:, i] = dr[1] * self.lag_map(th[i])[1]
                if "slide_" + name in lay:
                    i = lay["slide_" + name].start
                    Jk[:, i] = dr[2] * self.slide_map(th[i])[1]
                if "expo" in lay:                          # the window opens e / 2 earlier: since grows by it
                    i = lay["expo"].start
                    Jk[:, i] = (0.5 * dr[0] + dr[3]) * self.expo_map(th[i])[1]
                if dton is not None:                       # the tip's switch starts at its onset
                    Jk[np.flatnonzero(ok), 1:1 + self.n_b] = -dr[0][ok][:, None] * dton
                    Jk[np.flatnonzero(ok), lay["z0"].start] = -dr[0][ok] * dton_x
                    if "spread" in lay:
                        i = lay["spread"].start
                        Jk[np.flatnonzero(ok), i] = -dr[0][ok] * dton_s * self.spread_map(th[i])[1]
                kl.append(Jk)
            j, c = mx["j"], mx["spread"]
            a = slice(2 * p + self.mix_block(name), 2 * p + self.mix_block(name) + self.n_reg(name))
            Xa = self._X[a]                                # d rotation / d theta = -Xa (Kaufman)
            gen = self.generators(name)[j]
            for ax in range(2):
                wj = self.w[ax * F + j]
                pen.append(np.sqrt(c * wj)[:, None] * (gen[:, :, ax] @ Xa) / sigma)
        rows = kl + pen
        if self.d_fixed is not None:
            for r in rows:
                r[:, 0] = 0.0
        return rows

    def evaluate(self, th: np.ndarray) -> Eval:
        cols, t_on, z_f, st = self.columns(th)
        beta, r = self.solve(cols, st)
        return Eval(r, t_on, beta, cols, z_f, st)

    def n_linear(self) -> int:
        return 2 * self.n_g + 2 * self.terms.ring + sum(self.n_reg(n) for n in ("tip", "motor")
                                                         if getattr(self.terms, "reg_" + n))

    def G_slope(self, ev: Eval) -> np.ndarray:
        """G'(z) at the frames (F, 2), px per actuator unit, from an evaluation's beta."""
        p = self.n_g
        dB = _dbasis(ev.z_f, self.z_lo, self.z_hi, self.n_g)
        return np.column_stack([dB @ ev.beta[:self.n_g], dB @ ev.beta[p:p + self.n_g]])


@functools.lru_cache(maxsize=None)
def _second_difference_gram(p: int) -> np.ndarray:
    """D2' D2 (p, p), D2 the second differences of p coefficients ((p - 2, p)): `solve`'s penalty,
    built once a size (read-only)."""
    D2 = np.diff(np.eye(p), 2, axis=0)
    out = D2.T @ D2
    out.flags.writeable = False
    return out


def _kl_row(gamma: np.ndarray, p: np.ndarray) -> np.ndarray:
    """sign(p - gamma) sqrt(2 KL(gamma || p)) per frame (K,), dimensionless: the mixture's timing row
    (module doc), gamma the E-step's shares, p the prior shares in (0, 1)."""
    g = gamma
    d = g * np.log(np.maximum(g, 1e-300) / p) + (1 - g) * np.log(np.maximum(1 - g, 1e-300) / (1 - p))
    return np.sign(p - g) * np.sqrt(2.0 * np.maximum(d, 0.0))


def huber_weights(r: np.ndarray, sigma: float) -> np.ndarray:
    """IRLS weights psi(r)/r of Huber's loss at k = HUBER_K sigma."""
    a = np.abs(r) / (HUBER_K * sigma)
    return np.where(a <= 1.0, 1.0, 1.0 / np.maximum(a, 1e-12))


def huber_rho(r: np.ndarray, sigma: float) -> np.ndarray:
    """Huber's loss of r / sigma (quadratic to HUBER_K, linear beyond), in squared-sigma units / 2."""
    a = np.abs(r) / sigma
    return np.where(a <= HUBER_K, 0.5 * a * a, HUBER_K * a - 0.5 * HUBER_K ** 2)


def noise_sigma(obs: np.ndarray) -> float:
    """The marker's noise per axis (px), model-free: 1.4826 MAD of the second differences of
    consecutive frames over sqrt(6) (white noise e gives Var(e[j+1] - 2 e[j] + e[j-1]) = 6 Var e;
    the motion's own curvature is small between frames on most of a record, and the MAD ignores
    the rest). Pooled over both axes."""
    d2 = np.diff(obs, 2, axis=0).ravel()
    return float(1.4826 * np.median(np.abs(d2)) / np.sqrt(6.0)) + 1e-9


def robust_sigma(r: np.ndarray) -> float:
    """1.4826 MAD: the Gaussian-consistent robust scale."""
    return float(1.4826 * np.median(np.abs(r - np.median(r)))) + 1e-9
