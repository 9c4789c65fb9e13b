/* Encoder history: ring buffer of timestamped actuator samples, read back by time. */
#ifndef ENC_HIST_H
#define ENC_HIST_H

#include <stdint.h>
#include "ps_defs.h"

#ifndef ENC_HIST_LEN
/* ENC_HIST_LEN: samples kept, a power of two. Default 1024 (8 KiB); with a 1 kHz push
 * rate that is 1.02 s of history, which must exceed t_delay + one frame period. */
#define ENC_HIST_LEN 1024
#endif
PS_STATIC_ASSERT((ENC_HIST_LEN & (ENC_HIST_LEN - 1)) == 0 && ENC_HIST_LEN >= 4,
                 "ENC_HIST_LEN must be a power of two >= 4");

typedef struct {
    uint32_t t_us[ENC_HIST_LEN];
    int32_t q_q16[ENC_HIST_LEN];
    uint32_t head;               /* total pushes; slot of the next push is head % ENC_HIST_LEN */
} enc_hist_t;

typedef enum {
    ENC_HIST_OK = 0,
    ENC_HIST_EMPTY,              /* fewer than two samples */
    ENC_HIST_TOO_OLD,            /* asked time precedes the oldest kept sample: overwritten (wrap-around) */
    ENC_HIST_TOO_NEW,            /* asked time follows the newest sample */
} enc_hist_status_t;

void enc_hist_reset(enc_hist_t *h);

/* Append one sample. Times must not decrease (modulo-2^32 arithmetic; a sample older
 * than the newest is dropped). O(1), per tick. */
void enc_hist_push(enc_hist_t *h, uint32_t t_us, int32_t q_q16);

/* q at time t_us, linearly interpolated between the kept samples around it (Q16).
 * O(log ENC_HIST_LEN) binary search: called once per detected onset, not per tick.
 * Errors: ENC_HIST_EMPTY, ENC_HIST_TOO_OLD (history wrapped past it), ENC_HIST_TOO_NEW. */
#ifndef PS_CDEF
/* enc_hist_push() inlined for onset_tick(): same code, without the call. */
__attribute__((always_inline)) static inline void enc_hist_push_inline(enc_hist_t *h, uint32_t t_us, int32_t q_q16)
{
    if (h->head > 0) {
        uint32_t last = h->t_us[(h->head - 1u) & (ENC_HIST_LEN - 1u)];
        if ((int32_t)(t_us - last) < 0)
            return; /* out of order: keep the history sorted */
    }
    h->t_us[h->head & (ENC_HIST_LEN - 1u)] = t_us;
    h->q_q16[h->head & (ENC_HIST_LEN - 1u)] = q_q16;
    h->head++;
}
#endif

enc_hist_status_t enc_hist_q_at(const enc_hist_t *h, uint32_t t_us, int32_t *q_q16);

#endif /* ENC_HIST_H */
