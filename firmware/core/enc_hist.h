/* Encoder history: time-decimated ring of actuator samples with exact interpolation bounds, read back by time. */
#ifndef ENC_HIST_H
#define ENC_HIST_H

#include <stdint.h>
#include "ps_defs.h"

#ifndef ENC_HIST_LEN
/* ENC_HIST_LEN: samples kept, a power of two. Default 512 (10 B each: 5 KiB). The span
 * they cover does not depend on the tick rate: a sample is kept only every keep_us
 * (enc_hist_set_span), so 512 samples hold any span at 1/511 of it per sample. */
#define ENC_HIST_LEN 512
#endif
PS_STATIC_ASSERT((ENC_HIST_LEN & (ENC_HIST_LEN - 1)) == 0 && ENC_HIST_LEN >= 4,
                 "ENC_HIST_LEN must be a power of two >= 4");

/* Samples k and k+1 of the ring are keep_us or more apart; every push between them is
 * folded into spread_q16[k] = max q - min q over the pushes from k to k+1 inclusive, so
 * linear interpolation between two kept samples is within spread_q16[k] of every pushed
 * sample in that interval: an exact bound, not an estimate (it saturates at 0xFFFF, which
 * then reads "at least one actuator unit"). With keep_us = 0 every push is kept. */
typedef struct {
    /* The per-push fields first, the rings last: the M4 reaches a field at most 4095 B past
     * the loop's base address with one load (onset_t and psa_loop_t also put this last). */
    uint32_t head;               /* kept samples so far; slot of the next is head % ENC_HIST_LEN */
    uint32_t keep_us;            /* minimum spacing of kept samples */
    uint32_t next_keep_us;       /* newest kept time + keep_us: the next push at or after it is kept */
    uint32_t last_t_us;          /* newest push, kept or not: the live end of the history */
    int32_t last_q_q16;
    int32_t lo_q16, hi_q16;      /* q range over the pushes since the newest kept sample (incl.) */
    uint32_t t_us[ENC_HIST_LEN];
    int32_t q_q16[ENC_HIST_LEN];
    uint16_t spread_q16[ENC_HIST_LEN];
} enc_hist_t;

typedef enum {
    ENC_HIST_OK = 0,
    ENC_HIST_EMPTY,              /* fewer than two samples */
    ENC_HIST_TOO_OLD,            /* asked time precedes the oldest kept sample: overwritten (wrap-around) */
    ENC_HIST_TOO_NEW,            /* asked time follows the newest sample */
} enc_hist_status_t;

/* Empty the history; the spacing is kept (0, every push, after the first reset of a zeroed struct). */
void enc_hist_reset(enc_hist_t *h);

/* Size the spacing so the kept samples always cover span_us back from the newest push:
 * keep_us = ceil(span_us / (ENC_HIST_LEN - 1)). Empties the history. Init time. */
void enc_hist_set_span(enc_hist_t *h, uint32_t span_us);

/* Append one sample. Times must not decrease (modulo-2^32 arithmetic; a sample older
 * than the newest is dropped). O(1), per tick, no divide. */
#ifndef PS_CDEF
/* The push that keeps a sample (or drops an out-of-order one): out of line, since at
 * 20 kHz only about one push in 45 keeps (keep_us 2.23 ms by default). */
void enc_hist_push_slow(enc_hist_t *h, uint32_t t_us, int32_t q_q16);

/* The live end and the range since the last kept sample move on every push (fast and slow path). */
__attribute__((always_inline)) static inline void enc_hist_note_live(enc_hist_t *h, uint32_t t_us, int32_t q_q16)
{
    h->last_t_us = t_us;
    h->last_q_q16 = q_q16;
    if (q_q16 < h->lo_q16)
        h->lo_q16 = q_q16;
    if (q_q16 > h->hi_q16)
        h->hi_q16 = q_q16;
}

/* enc_hist_push() inlined for onset_tick(): same result, without the call. */
__attribute__((always_inline)) static inline void enc_hist_push_inline(enc_hist_t *h, uint32_t t_us, int32_t q_q16)
{
    /* The common push, in order and before the next kept time, in one unsigned compare:
     * with a sample kept, 0 < next_keep - last_t <= keep_us, so d < next_keep - last_t
     * holds exactly when last_t <= t < next_keep (modulo 2^32, as the slow path's signed
     * tests); with none kept (or keep_us = 0, every push kept) the gap is 0 and nothing
     * passes (enc_hist_reset sets next_keep = last_t). Only the range and the live end move. */
    uint32_t d = t_us - h->last_t_us;
    if (__builtin_expect(d < h->next_keep_us - h->last_t_us, 1)) {
        enc_hist_note_live(h, t_us, q_q16);
        return;
    }
    enc_hist_push_slow(h, t_us, q_q16);
}
#endif
void enc_hist_push(enc_hist_t *h, uint32_t t_us, int32_t q_q16);

/* q at time t_us (Q16), linearly interpolated between the two samples around it (kept,
 * or the newest push); *bound_q16 (may be NULL) receives the exact bound above: every
 * pushed sample between those two is within it of the interpolation line (0 at a sample).
 * O(log ENC_HIST_LEN) binary search: called once per detected onset, not per tick.
 * Errors: ENC_HIST_EMPTY, ENC_HIST_TOO_OLD (history wrapped past it), ENC_HIST_TOO_NEW. */
enc_hist_status_t enc_hist_q_at_bound(const enc_hist_t *h, uint32_t t_us, int32_t *q_q16, uint32_t *bound_q16);
enc_hist_status_t enc_hist_q_at(const enc_hist_t *h, uint32_t t_us, int32_t *q_q16);

#endif /* ENC_HIST_H */
