/* Encoder history ring buffer: O(1) push per tick, binary search by time per onset. */
#include "enc_hist.h"

#define MASK (ENC_HIST_LEN - 1u)

void enc_hist_reset(enc_hist_t *h)
{
    h->head = 0;
}

void enc_hist_push(enc_hist_t *h, uint32_t t_us, int32_t q_q16)
{
    enc_hist_push_inline(h, t_us, q_q16);
}

enc_hist_status_t enc_hist_q_at(const enc_hist_t *h, uint32_t t_us, int32_t *q_q16)
{
    uint32_t count = h->head < ENC_HIST_LEN ? h->head : ENC_HIST_LEN;
    if (count < 2)
        return ENC_HIST_EMPTY;
    uint32_t first = h->head - count; /* logical index of the oldest kept sample */
    uint32_t t_old = h->t_us[first & MASK];
    uint32_t t_new = h->t_us[(h->head - 1u) & MASK];
    /* Compare as offsets from the oldest sample: correct across the 2^32 us wrap. */
    uint32_t rel = t_us - t_old;
    if ((int32_t)rel < 0)
        return ENC_HIST_TOO_OLD;
    if (rel > t_new - t_old)
        return ENC_HIST_TOO_NEW;
    /* Largest logical index lo with t[lo] <= t (offsets are non-decreasing). */
    uint32_t lo = first, hi = h->head - 1u;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo + 1u) / 2u;
        if (h->t_us[mid & MASK] - t_old <= rel)
            lo = mid;
        else
            hi = mid - 1u;
    }
    int32_t q0 = h->q_q16[lo & MASK];
    if (lo == h->head - 1u) {
        *q_q16 = q0;
        return ENC_HIST_OK;
    }
    uint32_t t0 = h->t_us[lo & MASK], t1 = h->t_us[(lo + 1u) & MASK];
    uint32_t dt = t1 - t0, dt_at = t_us - t0;
    if (dt == 0) {
        *q_q16 = q0;
        return ENC_HIST_OK;
    }
    /* Linear interpolation. dq * dt_at is 64-bit; the divide by dt is a 32-bit hardware
     * divide when dq * dt_at fits 32 bits, which holds for encoder rates above ~1 Hz;
     * otherwise fall back to halving both until it fits (exact to < 1 raw unit). */
    int64_t dq = (int64_t)h->q_q16[(lo + 1u) & MASK] - q0;
    int64_t num = dq * (int64_t)dt_at;
    uint32_t den = dt;
    while (num > INT32_MAX || num < -INT32_MAX) {
        num /= 2;
        den = (den + 1u) / 2u;
    }
    int32_t n32 = (int32_t)num;
    int32_t d32 = (int32_t)den;
    int32_t step = (n32 >= 0 ? n32 + d32 / 2 : n32 - d32 / 2) / d32;
    *q_q16 = q0 + step;
    return ENC_HIST_OK;
}
