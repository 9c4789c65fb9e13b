"""The board's onset detector fed a recorded session in one C call (onsets.feed, firmware
onset_feed) gives what the calls one by one give (onsets._feed_ref), for marker frames and for an
angle sensor, and with less room for outcomes than there are (fed again from the state on entry)."""

import numpy as np
import pytest

from playscope.base.native import core
from playscope.fit import onsets as ON
from playscope.fit.reversals import detect_reversals
from playscope.fit import model

from .synth import ROBOT, excitation, image_model_parts, true_B, true_f


def _record(kind: str, duration_s: float = 30.0):
    """(t, q, rt, rq, t_f, obs) of a 25 Hz session from the direct model: marker pixels through the
    camera model with 0.05 px noise and a few lost frames, or the angle itself (deg, column 0)."""
    t, q, _ = excitation(v=0.4, rate_hz=1000.0)
    t, q = t[t < duration_s], q[t < duration_s]
    c = model.direct_model(q, true_B, true_f)
    tf = np.arange(0.0, t[-1], 1 / 25.0)
    if kind == "image":
        cam, he = image_model_parts()
        obs = model.ImageModel(ROBOT, cam, he)(np.interp(tf - 0.08, t, c))
        obs = obs + np.random.default_rng(1).normal(0, 0.05, obs.shape)
        obs[200:203] = np.nan
    else:
        obs = np.column_stack([np.interp(tf - 0.08, t, c), np.zeros(tf.size)])
    rt, rq, _ = detect_reversals(t, q, 0.01 * np.ptp(q))
    return t, q, rt, rq, tf, obs


@pytest.mark.parametrize("kind", ["image", "angle"])
def test_the_stream_in_one_call_is_the_calls_in_turn(monkeypatch, kind):
    args = _record(kind)
    cfg = ON.OnsetConfig(t_delay_s=0.08, fps=25.0)
    seen = {}
    real = ON.feed

    def spy(o, stream, input_kind, cap=64):
        seen["stream"], seen["input"] = stream, input_kind
        return real(o, stream, input_kind, cap)

    monkeypatch.setattr(ON, "feed", spy)
    got = ON.run_onsets(*args, kind, cfg)
    monkeypatch.setattr(ON, "feed", lambda o, stream, input_kind, cap=64: ON._feed_ref(o, stream, input_kind))
    want = ON.run_onsets(*args, kind, cfg)
    assert got.b.size >= 6 and got.reasons == want.reasons
    for f in ("t1_s", "t2_s", "q1", "q2", "q_mean", "b"):
        assert np.array_equal(getattr(got, f), getattr(want, f)), f
    # with room for one outcome: counted, then fed again from the detector's state on entry
    ffi, lib = core()
    fresh = lambda: ffi.new("onset_t *")  # noqa: E731
    o1, o2 = fresh(), fresh()
    for o in (o1, o2):
        lib.onset_init(o, ffi.new("onset_config_t *", cfg.to_c(ffi, lib)))
    many, one = real(o1, seen["stream"], seen["input"], cap=10_000), real(o2, seen["stream"], seen["input"], cap=1)
    assert len(many) > 1 and one == many
    assert bytes(ffi.buffer(o1)) == bytes(ffi.buffer(o2))  # and the detector ends in the same state


def test_a_stream_of_the_wrong_types_is_refused():
    ffi, lib = core()
    o = ffi.new("onset_t *")
    good = (np.zeros(3, np.uint32), np.zeros(3, np.uint8), np.zeros(3, np.int32), np.zeros(3, np.int32),
            np.ones(3, np.uint8))
    assert ON.feed(o, good, lib.ONSET_INPUT_PX) == []
    with pytest.raises(TypeError):
        ON.feed(o, (good[0].astype(np.int64),) + good[1:], lib.ONSET_INPUT_PX)
    with pytest.raises(ValueError):
        ON.feed(o, good[:2] + (np.zeros(2, np.int32),) + good[3:], lib.ONSET_INPUT_PX)
