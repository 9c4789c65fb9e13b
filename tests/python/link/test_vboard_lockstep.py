"""ps_vboard --lockstep-ms: during the excitation the virtual board runs at most L ms of board
time past the later of the excitation's start and the last marker observation, then waits for the
host; without it the clock runs free. This is what keeps run-insitu --sim-plant's onsets
independent of the machine's load (a lagging host slows the board instead of sending
observations the board's encoder history has already dropped)."""

from __future__ import annotations

import time

from playscope.pipeline import open_board

LEAD_MS = 100
TICK_US = 1000  # ps_vboard's default 1 kHz


def _stream_until_quiet(link, quiet_s: float = 0.4, limit_s: float = 5.0) -> int:
    """Largest board time (us) in the encoder stream once no sample has arrived for quiet_s
    (wall), or after limit_s."""
    t_last, t_end, t_quiet = None, time.monotonic() + limit_s, time.monotonic() + quiet_s
    while time.monotonic() < min(t_end, t_quiet):
        for kind, ev in link.poll_events(0.02):
            if kind == "enc" and ev:
                t_last = max(tu for tu, _ in ev)
                t_quiet = time.monotonic() + quiet_s
    return t_last


def _start_excitation(link) -> int:
    """Excitation on with the stream; the board time of its first streamed sample (us)."""
    link.set_mode("idle")
    link.stream(True, 1)
    link.set_mode("excitation")
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        for kind, ev in link.poll_events(0.02):
            if kind == "enc" and ev:
                return min(tu for tu, _ in ev)
    raise AssertionError("no encoder stream from the virtual board")


def test_lockstep_board_waits_for_the_host_and_resumes_on_an_observation():
    link = open_board("virtual", vboard_args=["--time-scale", "4", "--lockstep-ms", str(LEAD_MS)])
    try:
        t0 = _start_excitation(link)
        held = _stream_until_quiet(link)
        # Held at the excitation's start + L (the first tick past it is not run); the stream's
        # last batch may stop a few ticks short of it (batches of PSP_ENC_BATCH samples).
        assert t0 + LEAD_MS * 1000 - 40 * TICK_US <= held <= t0 + LEAD_MS * 1000 + TICK_US, (t0, held)
        time.sleep(0.3)  # wall time while held is not counted: still held
        assert _stream_until_quiet(link, quiet_s=0.2) in (None, held)
        t_obs = held - 20 * TICK_US  # an observation stamped in the past moves the limit to it + L
        link.marker(t_obs, 100 << 16, 100 << 16, valid=True)
        held2 = _stream_until_quiet(link)
        assert t_obs + LEAD_MS * 1000 - 40 * TICK_US <= held2 <= t_obs + LEAD_MS * 1000 + TICK_US, (t_obs, held2)
        # No tick was dropped while waiting: the stream's clock advanced exactly as far as allowed.
        link.set_mode("idle")  # lock-step applies to the excitation only: the clock runs again
        assert _stream_until_quiet(link, quiet_s=0.2, limit_s=0.6) > held2 + 50 * TICK_US
    finally:
        link.close()


def test_free_running_board_does_not_wait():
    link = open_board("virtual", vboard_args=["--time-scale", "4"])
    try:
        t0 = _start_excitation(link)
        t = _stream_until_quiet(link, quiet_s=0.2, limit_s=0.6)
        assert t > t0 + 3 * LEAD_MS * 1000, (t0, t)  # 0.6 s wall x4 >> L: never held
    finally:
        link.close()
