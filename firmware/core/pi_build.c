/* Load-time validation of a transition operator block and derivation of its inverse (divides). */
#include "pi.h"

#include <string.h>

enum {
    PI_W_SUM_TOL = 256,          /* |sum w - 1| <= 2^-8, in raw Q16 */
    PI_RANGE = 1 << 30,          /* inputs +- twice the thresholds and outputs stay within +-2^30 raw */
};

static int64_t round_div_pos(int64_t num, int64_t den) /* round half up, num >= 0, den > 0 */
{
    return (num + den / 2) / den;
}

/* [lo - 2r, hi + 2r] within +-2^30: operator states (input +- r) and engagement levels
 * (state +- r) then fit int32 with room to spare, so the engine adds them in 32 bits. */
static int range_ok(int32_t lo, int32_t hi, int64_t r)
{
    return (int64_t)lo - 2 * r >= -PI_RANGE && (int64_t)hi + 2 * r <= PI_RANGE;
}

pi_status_t pi_build(const int32_t *r_q16, const int32_t *w_q16, uint16_t n, int64_t span_q16,
                     int32_t z_min_q16, int32_t z_max_q16, int32_t y_min_q16, int32_t y_max_q16,
                     pi_params_t *dir, pi_params_t *inv, int32_t *inv_err_q16)
{
    pi_params_t d, v;
    memset(&d, 0, sizeof d);
    memset(&v, 0, sizeof v);
    d.w_frac = v.w_frac = 16;
    d.x_min_q16 = z_min_q16;
    d.x_max_q16 = z_max_q16;
    v.x_min_q16 = y_min_q16;
    v.x_max_q16 = y_max_q16;
    if (n > PST_MAX_OPS)
        return PI_ERR_COUNT;
    if (n == 0) {
        *dir = d;
        *inv = v;
        *inv_err_q16 = 0;
        return PI_OK;
    }

    /* Shape of the block, in the order a reader of the table would check it. */
    if (r_q16[0] != 0)
        return PI_ERR_R0;
    for (uint16_t i = 1; i < n; i++)
        if (r_q16[i] <= r_q16[i - 1])
            return PI_ERR_R_ORDER;
    if ((int64_t)r_q16[n - 1] > span_q16 || !range_ok(z_min_q16, z_max_q16, r_q16[n - 1]))
        return PI_ERR_R_RANGE;
    if (w_q16[0] <= 0)
        return PI_ERR_W0;
    int64_t w_sum = 0;
    for (uint16_t i = 0; i < n; i++) {
        if (w_q16[i] < 0)
            return PI_ERR_W_NEGATIVE;
        w_sum += w_q16[i];
    }
    if (w_sum - 65536 > PI_W_SUM_TOL || 65536 - w_sum > PI_W_SUM_TOL)
        return PI_ERR_W_SUM;

    /* Inverse weights in Q(s): the partial sums S_i = 1/W_i are positive and largest at
     * i = 0 (1/w_0), so s is the largest in 16..30 with round(2^s / w_0) in int32. */
    const int64_t w0 = w_q16[0];
    int sh = 30;
    while (sh >= 16 && round_div_pos((int64_t)1 << (sh + 16), w0) > INT32_MAX)
        sh--;
    if (sh < 16)
        return PI_ERR_INVERSE;
    int64_t W = 0, wr_sum = 0, s_prev = 0, abs_w_sum = 0;
    for (uint16_t i = 0; i < n; i++) {
        W += w_q16[i];                                     /* W_i, Q16 */
        wr_sum += (int64_t)w_q16[i] * r_q16[i];            /* sum_{j<=i} w_j r_j, Q32 */
        int64_t s_i = round_div_pos((int64_t)1 << (sh + 16), W); /* 1/W_i, Q(s) */
        int64_t rp = round_div_pos(W * r_q16[i] - wr_sum, 65536); /* r'_i >= 0, Q16 */
        v.r_q16[i] = (int32_t)rp;
        v.w[i] = (int32_t)(i == 0 ? s_i : s_i - s_prev);
        abs_w_sum += v.w[i] < 0 ? -(int64_t)v.w[i] : v.w[i];
        s_prev = s_i;
        d.r_q16[i] = r_q16[i];
        d.w[i] = w_q16[i];
        d.w_neg[i] = -d.w[i];
        v.w_neg[i] = -v.w[i]; /* |w'_i| <= S_0 <= INT32_MAX */
    }
    const int64_t rp_max = v.r_q16[n - 1];
    if (!range_ok(y_min_q16, y_max_q16, rp_max))
        return PI_ERR_R_RANGE;
    /* |z*| <= S_{n-1} |y| + sum |w'_i| r'_i (a PI output stays within its thresholds of
     * S y): keep it within 2^30 so that q* = z* +- B/2 fits int32. Terms < 2^62. */
    int64_t y_abs = -(int64_t)y_min_q16 > y_max_q16 ? -(int64_t)y_min_q16 : y_max_q16;
    int64_t z_bound = s_prev * y_abs;
    for (uint16_t i = 0; i < n; i++)
        z_bound += (v.w[i] < 0 ? -(int64_t)v.w[i] : v.w[i]) * v.r_q16[i];
    if ((z_bound >> sh) + 1 >= PI_RANGE)
        return PI_ERR_INVERSE;

    d.n = v.n = (uint8_t)n;
    v.w_frac = (uint8_t)sh;
    /* Worst case against exact arithmetic (docs/method.md, "Error bound"), raw units:
     *   1/2 (final rounding) + 1/2 sum|w'| (each r' rounded by <= 1/2)
     *   + 2^-(s+1) (|y|max + 2 r'max + 1) (partial sums 1/W_i rounded by <= 2^-(s+1)). */
    int64_t num = ((int64_t)1 << sh) + abs_w_sum + y_abs + 2 * rp_max + 1;
    int64_t den = (int64_t)1 << (sh + 1);
    *inv_err_q16 = (int32_t)((num + den - 1) / den);
    *dir = d;
    *inv = v;
    return PI_OK;
}
