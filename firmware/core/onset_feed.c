/* A recorded stream fed to the motion-onset detector in its order (onset.h: onset_feed): the
 * host's replay of a session through the board's own detector, one call instead of one per
 * encoder sample (a 3-minute record at 480 Hz is 86,000 calls from Python, 0.06 s a run). No
 * board code calls it: on the board the control loop and the frame handler feed the detector. */
#include "onset.h"

long onset_feed(onset_t *o, const uint32_t *t_us, const uint8_t *kind, const int32_t *a, const int32_t *b,
                const uint8_t *valid, long n, onset_input_t input, onset_event_t *out, long cap)
{
    long n_out = 0;
    onset_event_t ev;
    for (long i = 0; i < n; i++) {
        bool hit;
        if (kind[i] == ONSET_FEED_TICK)
            hit = onset_tick(o, t_us[i], a[i], &ev);
        else if (kind[i] == ONSET_FEED_REVERSAL)
            hit = onset_reversal(o, t_us[i], a[i], &ev);
        else if (input == ONSET_INPUT_DEG)
            hit = onset_observe_deg(o, t_us[i], a[i], valid[i] != 0, &ev);
        else
            hit = onset_observe_px(o, t_us[i], a[i], b[i], valid[i] != 0, &ev);
        if (hit) {
            if (n_out < cap)
                out[n_out] = ev;
            n_out++;
        }
    }
    return n_out;
}
