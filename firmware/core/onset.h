/* Motion-onset detector: backlash width from the first image motion after a reversal (section III-A, eq. 1). */
#ifndef ONSET_H
#define ONSET_H

#include <stdbool.h>
#include <stdint.h>
#include "enc_hist.h"

/* Outcome of one commanded reversal. Values travel in psp_b_sample_t.reason. */
typedef enum {
    ONSET_OK = 0,                /* B sample valid, t2 refined below one frame period */
    ONSET_OK_COARSE = 1,         /* B sample valid, t2 = first moving frame (the frames that refine it were lost) */
    ONSET_ERR_MARKER_LOST = 2,   /* more than max_lost_frames consecutive frames without a marker */
    ONSET_ERR_REVERSAL = 3,      /* another reversal was commanded before motion appeared */
    ONSET_ERR_TIMEOUT = 4,       /* no motion within timeout_us of the reversal */
    ONSET_ERR_HISTORY_WRAPPED = 5, /* q(t2 - t_delay) already overwritten in the encoder history */
    ONSET_ERR_HISTORY_MISSING = 6, /* no encoder sample at or after t2 - t_delay */
    ONSET_ERR_NO_STILL = 7,      /* moving from the first settled frame: no still period to measure */
} onset_reason_t;

/* Observation kind: a marker point in the image, or a direct angle from an external sensor. */
typedef enum {
    ONSET_INPUT_PX = 0,          /* u, v in px (Q16) */
    ONSET_INPUT_DEG = 1,         /* c in deg (Q16); v unused */
} onset_input_t;

#ifndef ONSET_NOISE_LEARN_PAIRS
/* ONSET_NOISE_LEARN_PAIRS: still frame pairs averaged before the automatic T is used (power of two). Default 8. */
#define ONSET_NOISE_LEARN_PAIRS 8
#endif

#ifndef ONSET_HIST_MARGIN_US
/* ONSET_HIST_MARGIN_US: history kept beyond the longest look-back an onset needs, for
 * observations that reach the board late (link and tracking latency). Default 100 ms. */
#define ONSET_HIST_MARGIN_US 100000u
#endif

typedef struct {
    uint32_t t_delay_us;         /* image acquisition + processing delay (eq. 1) */
    uint32_t frame_period_us;    /* nominal camera period, > 0 (normalises gaps over lost frames) */
    int32_t threshold_q16;       /* T in px (or deg) per frame; 0: automatic from the still noise */
    int32_t threshold_floor_q16; /* automatic T never goes below this */
    int32_t threshold_max_q16;   /* ...nor above this; also T while the noise is being learnt */
    uint32_t noise_k2_q16;       /* automatic T^2 = k^2 * mean |dQ|^2 over still frame pairs */
    uint16_t settle_frames;      /* frames skipped after t1 + t_delay (exposure straddling the reversal) */
    uint16_t max_lost_frames;    /* consecutive lost frames tolerated */
    uint16_t jump_ratio_q8;      /* first moving frame further from the still level than this
                                    many frames of motion = a jump at the onset (image
                                    registration shift); Q8, 0 = never (external angle sensors) */
    uint32_t timeout_us;         /* give up if no motion this long after t1 */
} onset_config_t;

/* Defaults from the paper's setup (V-D): 25 Hz camera, t_delay 80 ms; T automatic with
 * k = 3 between 0.05 and 1 px/frame (the paper fixed T = 0.2 px/frame for a still noise
 * under 0.15 px); timeout 10 s. */
onset_config_t onset_default_config(void);

/* One B sample (eq. 1) or the reason there is none. */
typedef struct {
    onset_reason_t reason;
    uint32_t t1_us;              /* commanded reversal */
    uint32_t t2_us;              /* image onset (refined), image clock = board clock */
    int32_t q1_q16;              /* q at t1 */
    int32_t q2_q16;              /* q(t2 - t_delay), interpolated from the history */
    int32_t q_mean_q16;          /* (q1 + q2) / 2 */
    int32_t b_q16;               /* |q2 - q1| */
} onset_event_t;

typedef enum {
    ONSET_ST_IDLE = 0,           /* no reversal pending */
    ONSET_ST_SETTLING,           /* waiting for frames taken after t1 + t_delay */
    ONSET_ST_STILL,              /* marker still; watching for the first motion */
    ONSET_ST_CANDIDATE,          /* one moving frame (A); the next (B) must confirm it */
    ONSET_ST_CONFIRMED,          /* A and B moving away; the next (C) gives the slope for t2 */
} onset_state_t;

typedef struct {
    onset_config_t cfg;
    onset_state_t state;
    uint32_t t1_us;
    int32_t q1_q16;
    uint16_t settle_left;
    uint16_t lost_run;           /* consecutive lost frames */
    uint16_t still_pairs;        /* still frame pairs seen since the reversal */
    bool have_prev;              /* a previous valid frame in this episode */
    uint32_t prev_t_us;
    int32_t prev_u_q16, prev_v_q16;
    int32_t ref_u_q16, ref_v_q16; /* still level (EWMA of still frames) */
    uint32_t still_t_us;         /* time of the last still frame */
    uint32_t cand_t_us;          /* first moving frame A */
    int32_t cand_s_q16;          /* its L1 distance from the still level */
    uint32_t conf_t_us;          /* confirming frame B */
    int32_t conf_s_q16;
    int64_t noise_d2_q32;        /* mean |dQ|^2 over still frame pairs, Q32: plain mean of the
                                    first ONSET_NOISE_LEARN_PAIRS, then EWMA 1/16 */
    uint32_t noise_count;        /* still frame pairs seen (saturating) */
    enc_hist_t hist;             /* last: its rings are 5 KiB (see enc_hist_t) */
} onset_t;

/* The encoder history span an onset can need: the frame that completes it (C) comes at
 * most 2 (max_lost_frames + 1) frame periods after the first moving frame (A), t2 lies at
 * most 2 frame periods before A, and q is read at t2 - t_delay; plus ONSET_HIST_MARGIN_US.
 * onset_init() sizes the history spacing from it (enc_hist_set_span). Saturates at 2^32-1. */
uint32_t onset_history_span_us(const onset_config_t *cfg);

/* Reset everything, including the history and the noise estimate. cfg is copied. */
void onset_init(onset_t *o, const onset_config_t *cfg);

/* Per control tick: record the encoder sample and check the timeout.
 * Returns true and fills *ev when a pending reversal times out. O(1). */
bool onset_tick(onset_t *o, uint32_t t_us, int32_t q_q16, onset_event_t *ev);

/* The pending reversal of onset_tick() timed out: end it (finish early or ONSET_ERR_TIMEOUT).
 * Out of line: the rare path. */
bool onset_tick_timed_out(onset_t *o, onset_event_t *ev);

#ifndef PS_CDEF
/* onset_tick() inlined for the control loop (psa_tick): the same code, so the same bits,
 * without the call: the history push and the timeout test inline, the timeout out of line. */
__attribute__((always_inline)) static inline bool onset_tick_inline(onset_t *o, uint32_t t_us, int32_t q_q16,
                                                                    onset_event_t *ev)
{
    enc_hist_push_inline(&o->hist, t_us, q_q16);
    if (o->state == ONSET_ST_IDLE || t_us - o->t1_us <= o->cfg.timeout_us)
        return false;
    return onset_tick_timed_out(o, ev);
}
#endif

/* A direction change is commanded now: remember (t1, q1) and start watching.
 * If one was still pending, returns true with *ev = ONSET_ERR_REVERSAL for it. O(1). */
bool onset_reversal(onset_t *o, uint32_t t1_us, int32_t q1_q16, onset_event_t *ev);

/* One camera frame at t_us (board clock, delay not removed): marker at (u, v) px, or
 * valid = false when lost. Returns true and fills *ev when the pending reversal ends,
 * with a B sample or a reason. O(log ENC_HIST_LEN) on the frame that completes an onset,
 * O(1) otherwise. */
bool onset_observe_px(onset_t *o, uint32_t t_us, int32_t u_q16, int32_t v_q16, bool valid,
                      onset_event_t *ev);

/* Same with a direct angle measurement c (deg) from an external sensor. */
bool onset_observe_deg(onset_t *o, uint32_t t_us, int32_t c_q16, bool valid, onset_event_t *ev);

/* What one entry of a recorded stream is (onset_feed). */
typedef enum {
    ONSET_FEED_TICK = 0,         /* an encoder sample: a = q (Q16) */
    ONSET_FEED_REVERSAL = 1,     /* a commanded reversal: a = q1 (Q16) */
    ONSET_FEED_FRAME = 2,        /* a camera frame: a = u or c, b = v (Q16), valid */
} onset_feed_kind_t;

/* A recorded stream of n entries fed in its order, each as onset_tick, onset_reversal or
 * onset_observe_px / _deg (input) would take it live (t_us[i], kind[i], a[i], b[i], valid[i]):
 * the same calls, so the same outcomes. Each outcome (the detector returned true) is copied to
 * out while fewer than cap are there; returns how many there were (more than cap: the rest were
 * dropped). For replays on the host (onset_feed.c); not a board path. */
long onset_feed(onset_t *o, const uint32_t *t_us, const uint8_t *kind, const int32_t *a, const int32_t *b,
                const uint8_t *valid, long n, onset_input_t input, onset_event_t *out, long cap);

/* Current threshold T^2 in (px or deg per frame)^2, Q32: fixed, or from the still noise. */
int64_t onset_threshold2_q32(const onset_t *o);

#endif /* ONSET_H */
