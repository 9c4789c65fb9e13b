/* Encoder history: O(1) time-decimated push per tick, binary search by time per onset. */
#include "enc_hist.h"

#include <stddef.h>

#define MASK (ENC_HIST_LEN - 1u)

/* next_keep = last_t closes enc_hist_push_inline's fast path until the first sample is kept. */
void enc_hist_reset(enc_hist_t *h)
{
    h->head = 0;
    h->next_keep_us = h->last_t_us;
}

void enc_hist_set_span(enc_hist_t *h, uint32_t span_us)
{
    /* 32-bit divide (one UDIV on the M4); 64-bit sum so span_us near 2^32 cannot wrap. */
    uint64_t keep = ((uint64_t)span_us + (ENC_HIST_LEN - 2u)) / (ENC_HIST_LEN - 1u);
    h->keep_us = (uint32_t)keep;
    enc_hist_reset(h);
}

void enc_hist_push(enc_hist_t *h, uint32_t t_us, int32_t q_q16)
{
    enc_hist_push_inline(h, t_us, q_q16);
}

void enc_hist_push_slow(enc_hist_t *h, uint32_t t_us, int32_t q_q16)
{
    if ((int32_t)(t_us - h->last_t_us) < 0 && h->head != 0)
        return; /* out of order: keep the history sorted */
    enc_hist_note_live(h, t_us, q_q16);
    if ((int32_t)(t_us - h->next_keep_us) < 0 && h->head != 0)
        return; /* between kept samples: only the range above changes */
    /* Keep this push; the interval it closes gets its spread (none before the first). */
    uint32_t spread = (uint32_t)h->hi_q16 - (uint32_t)h->lo_q16;
    h->spread_q16[(h->head - 1u) & MASK] = (uint16_t)(spread > 0xFFFFu ? 0xFFFFu : spread);
    uint32_t slot = h->head & MASK;
    h->t_us[slot] = t_us;
    h->q_q16[slot] = q_q16;
    h->lo_q16 = h->hi_q16 = q_q16;
    h->next_keep_us = t_us + h->keep_us;
    h->head++;
}

/* Linear interpolation at t between (t0, q0) and (t1, q1), t0 <= t <= t1, rounded to
 * nearest. dq * dt_at is 64-bit; the divide is a 32-bit hardware divide when it fits 32
 * bits, which holds for encoder rates above ~1 Hz; otherwise both halve until it fits
 * (exact to < 1 raw unit). The result stays between q0 and q1. */
static int32_t interpolate(uint32_t t0, int32_t q0, uint32_t t1, int32_t q1, uint32_t t_us)
{
    uint32_t dt = t1 - t0, dt_at = t_us - t0;
    if (dt == 0 || dt_at == 0)
        return q0;
    int64_t num = ((int64_t)q1 - q0) * (int64_t)dt_at;
    uint32_t den = dt;
    while (num > INT32_MAX || num < -INT32_MAX) {
        num /= 2;
        den = (den + 1u) / 2u;
    }
    int32_t n32 = (int32_t)num;
    int32_t d32 = (int32_t)den;
    return q0 + (n32 >= 0 ? n32 + d32 / 2 : n32 - d32 / 2) / d32;
}

enc_hist_status_t enc_hist_q_at_bound(const enc_hist_t *h, uint32_t t_us, int32_t *q_q16, uint32_t *bound_q16)
{
    uint32_t count = h->head < ENC_HIST_LEN ? h->head : ENC_HIST_LEN;
    if (count == 0)
        return ENC_HIST_EMPTY;
    uint32_t newest = h->head - 1u;      /* logical index of the newest kept sample */
    uint32_t t_kept = h->t_us[newest & MASK];
    int live = h->last_t_us != t_kept;   /* the newest push was not kept: one more point */
    if (count + (uint32_t)live < 2u)
        return ENC_HIST_EMPTY;
    uint32_t first = h->head - count;    /* logical index of the oldest kept sample */
    uint32_t t_old = h->t_us[first & MASK];
    /* Compare as offsets from the oldest sample: correct across the 2^32 us wrap. */
    uint32_t rel = t_us - t_old;
    if ((int32_t)rel < 0)
        return ENC_HIST_TOO_OLD;
    if (rel > h->last_t_us - t_old)
        return ENC_HIST_TOO_NEW;
    uint32_t bound = 0;
    if (rel > t_kept - t_old) {
        /* Between the newest kept sample and the newest push. */
        *q_q16 = interpolate(t_kept, h->q_q16[newest & MASK], h->last_t_us, h->last_q_q16, t_us);
        bound = (uint32_t)h->hi_q16 - (uint32_t)h->lo_q16;
    } else {
        /* Largest logical index lo with t[lo] <= t (offsets are non-decreasing). */
        uint32_t lo = first, hi = newest;
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo + 1u) / 2u;
            if (h->t_us[mid & MASK] - t_old <= rel)
                lo = mid;
            else
                hi = mid - 1u;
        }
        uint32_t t0 = h->t_us[lo & MASK];
        if (lo == newest || t0 == t_us) {
            *q_q16 = h->q_q16[lo & MASK];
        } else {
            *q_q16 = interpolate(t0, h->q_q16[lo & MASK], h->t_us[(lo + 1u) & MASK], h->q_q16[(lo + 1u) & MASK], t_us);
            bound = h->spread_q16[lo & MASK];
        }
    }
    if (bound_q16)
        *bound_q16 = bound;
    return ENC_HIST_OK;
}

enc_hist_status_t enc_hist_q_at(const enc_hist_t *h, uint32_t t_us, int32_t *q_q16)
{
    return enc_hist_q_at_bound(h, t_us, q_q16, NULL);
}
