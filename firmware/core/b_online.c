/* On-line B(q): recursive least squares with forgetting on a linear B-spline correction of the
 * flashed B grid (docs/firmware.md, "On-line B update").
 *
 * Model: B(q) = B_flashed(q) + sum_i theta_i h_i(q), h_i the hat function of node i (nodes on
 * every 2^k-th grid entry, so the correction is exactly linear between grid entries and the
 * RAM grid it is written into reproduces it with no interpolation error). One sample (q, b)
 * of eq. 1 is y = b - B_flashed(q) = phi' theta + noise, phi = (.., 1 - u, u, ..) at q.
 * RLS with exponential forgetting (Ljung & Soderstrom 1983, ch. 2; Astrom & Wittenmark,
 * Adaptive Control, 2nd ed., sec. 2.2):
 *     g = P phi,  s = lambda + phi' g,  k = g / s,  theta += k (y - phi' theta),
 *     P = D (P - k g') D,  D = diag(d_i),  d_i = 1/sqrt(lambda) unless that would lift P_ii
 *     above p0, then d_i = 1.
 * With every d_i = 1/sqrt(lambda) that is the textbook P = (P - k g') / lambda. The cap is
 * the bounded-covariance guard against wind-up (Salgado, Goodwin & Middleton 1988 bound P the
 * same way): a node no sample reaches keeps P_ii <= p0 instead of growing as lambda^-k, and a
 * congruence D P D keeps P symmetric positive semi-definite. */
#include "b_online.h"

#include <stdatomic.h>
#include <stddef.h>
#include <string.h>

#define Q30 ((int64_t)1 << B_ONLINE_P_FRAC_BITS)
#define HALF30 ((int64_t)1 << (B_ONLINE_P_FRAC_BITS - 1))

/* Round half up of x / 2^30 (arithmetic shift: gcc and clang on every target we build). */
static inline int64_t rq30(int64_t x)
{
    return (x + HALF30) >> B_ONLINE_P_FRAC_BITS;
}

static inline int32_t sat32(int64_t x)
{
    return x > INT32_MAX ? INT32_MAX : x < INT32_MIN ? INT32_MIN : (int32_t)x;
}

/* floor(sqrt(x)), bit by bit: init time only. */
static uint64_t isqrt64(uint64_t x)
{
    uint64_t r = 0, bit = (uint64_t)1 << 62;
    while (bit > x)
        bit >>= 2;
    while (bit != 0) {
        if (x >= r + bit) {
            x -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    return r;
}

b_online_config_t b_online_default_config(void)
{
    b_online_config_t c;
    c.lambda_q30 = (int32_t)(Q30 - (Q30 >> 3)); /* tau = 8 samples: lambda = 1 - 1/8 */
    c.p0_q30 = (int32_t)Q30;                     /* one sample's worth of prior per node */
    c.slope_max_q16 = 3 * (PS_Q16_ONE / 2);      /* |B'| <= 1.5, as the host's fit */
    return c;
}

/* Make copy `idx` the one the loop reads: the entries are complete before the pointer moves
 * (the fence keeps the compiler from sinking their stores below it; one core, so the tick
 * interrupt sees program order), and the pointer is one aligned word store. */
static void publish(b_online_t *bo, uint8_t idx)
{
    atomic_signal_fence(memory_order_release);
    if (bo->out != NULL)
        bo->out->y_q16 = bo->b_q16[idx];
    bo->live = idx;
}

/* Rewrite the entries from the prior and theta into the copy the loop does not read: floor
 * at 0, then the largest lower envelope with slope <= slope_max (forward then backward
 * min-plus pass); then publish it. */
static void write_grid(b_online_t *bo)
{
    const uint8_t idx = (uint8_t)(bo->live ^ 1u);
    int32_t *out = bo->b_q16[idx];
    const uint32_t k = bo->node_log2;
    const int64_t half_k = k ? ((int64_t)1 << (k - 1)) : 0;
    const int64_t lip = ((int64_t)bo->cfg.slope_max_q16 << bo->grid_log2) >> 16;
    int64_t prev = 0;
    for (uint32_t j = 0; j < bo->n_grid; j++) {
        uint32_t i = j >> k, r = j & ((1u << k) - 1u);
        int64_t corr = bo->theta_q16[i];
        if (r != 0)
            corr += ((int64_t)(bo->theta_q16[i + 1] - (int64_t)bo->theta_q16[i]) * r + half_k) >> k;
        int64_t b = (int64_t)bo->prior_q16[j] + corr;
        if (b < 0)
            b = 0;
        if (j > 0 && b > prev + lip)
            b = prev + lip;
        b = b > INT32_MAX ? INT32_MAX : b;
        out[j] = (int32_t)b;
        prev = b;
    }
    for (uint32_t j = bo->n_grid - 1u; j-- > 0;) {
        int64_t cap = (int64_t)out[j + 1] + lip;
        if (out[j] > cap)
            out[j] = (int32_t)cap;
    }
    publish(bo, idx);
}

b_online_status_t b_online_init(b_online_t *bo, const b_online_config_t *cfg, lut_t *b)
{
    if (cfg->lambda_q30 < (int32_t)(Q30 / 2) || cfg->lambda_q30 > (int32_t)Q30 || cfg->p0_q30 <= 0 ||
        cfg->p0_q30 > (int32_t)Q30 || cfg->slope_max_q16 <= 0)
        return B_ONLINE_ERR_CONFIG;
    if (b->n < 2 || b->n > PST_MAX_ENTRIES || b->step_log2 > 24)
        return B_ONLINE_ERR_GRID;
    uint32_t k = 0;
    while ((((uint32_t)(b->n - 1) + (1u << k) - 1u) >> k) + 1u > B_ONLINE_MAX_NODES)
        k++;
    memset(bo, 0, sizeof *bo);
    bo->cfg = *cfg;
    bo->prior_q16 = b->y_q16;
    bo->n_grid = b->n;
    bo->grid_log2 = b->step_log2;
    bo->node_log2 = (uint8_t)k;
    bo->n_nodes = (uint8_t)((((uint32_t)(b->n - 1) + (1u << k) - 1u) >> k) + 1u);
    bo->x0_q16 = b->x0_q16;
    int64_t lam = cfg->lambda_q30;
    bo->inv_lambda_q30 = ((int64_t)1 << 60) / lam;
    int64_t sq = (int64_t)isqrt64((uint64_t)lam << 30); /* sqrt(lambda), Q30 */
    bo->inv_sqrt_lambda_q30 = ((int64_t)1 << 60) / sq;
    bo->lambda_p0_q30 = rq30(lam * cfg->p0_q30);
    for (uint32_t i = 0; i < bo->n_nodes; i++)
        bo->p_q30[i][i] = cfg->p0_q30;
    memcpy(bo->b_q16[0], b->y_q16, (size_t)b->n * sizeof(int32_t));
    bo->out = b;
    publish(bo, 0);
    return B_ONLINE_OK;
}

b_online_status_t b_online_rebind(b_online_t *bo, lut_t *b)
{
    if (b->n != bo->n_grid || b->x0_q16 != bo->x0_q16 || b->step_log2 != bo->grid_log2)
        return B_ONLINE_ERR_GRID;
    bo->prior_q16 = b->y_q16;
    memset(bo->theta_q16, 0, sizeof bo->theta_q16);
    bo->out = b;
    write_grid(bo);
    return B_ONLINE_OK;
}

const int32_t *b_online_entries(const b_online_t *bo)
{
    return bo->b_q16[bo->live];
}

void b_online_stop(b_online_t *bo)
{
    if (bo->out != NULL)
        bo->out->y_q16 = bo->prior_q16;
    bo->out = NULL;
}

void b_online_sample(b_online_t *bo, int32_t q_mean_q16, int32_t b_q16)
{
    const uint32_t n = bo->n_nodes;
    const uint32_t shift = (uint32_t)bo->grid_log2 + bo->node_log2; /* node spacing 2^shift raw */
    const uint32_t span_grid = (uint32_t)(bo->n_grid - 1u) << bo->grid_log2;

    /* Regressor: node i and its weight u at q (Q30), clamped to the grid. */
    int64_t off = (int64_t)q_mean_q16 - bo->x0_q16;
    if (off < 0)
        off = 0;
    if (off > (int64_t)span_grid)
        off = span_grid;
    uint32_t i = (uint32_t)((uint64_t)off >> shift);
    uint64_t frac = (uint64_t)off & ((((uint64_t)1) << shift) - 1u);
    if (i >= n - 1u) {
        i = n - 2u;
        frac = (uint64_t)1 << shift;
    }
    int64_t u = shift <= 30 ? (int64_t)(frac << (30 - shift)) : (int64_t)(frac >> (shift - 30));
    int64_t a = Q30 - u;

    /* Target: the sample minus the flashed B at q (exact linear interpolation of the prior
     * entries, as lut_eval does it, on the grid cell of q), minus the current correction. */
    uint32_t j = (uint32_t)((uint64_t)off >> bo->grid_log2);
    int64_t prior;
    if (j >= bo->n_grid - 1u) {
        prior = bo->prior_q16[bo->n_grid - 1u];
    } else {
        int64_t fr = off & ((((int64_t)1) << bo->grid_log2) - 1);
        int64_t d = (int64_t)bo->prior_q16[j + 1] - bo->prior_q16[j];
        prior = bo->prior_q16[j] + ((d * fr + (((int64_t)1 << bo->grid_log2) >> 1)) >> bo->grid_log2);
    }
    int64_t model = rq30(a * bo->theta_q16[i] + u * bo->theta_q16[i + 1]);
    int64_t e = (int64_t)b_q16 - prior - model;
    if (e > Q30)
        e = Q30;
    if (e < -Q30)
        e = -Q30;

    /* g = P phi (Q30), s = lambda + phi' g (Q30), 1/s (Q30): the one divide of a sample. */
    int64_t g[B_ONLINE_MAX_NODES], kq[B_ONLINE_MAX_NODES];
    for (uint32_t r = 0; r < n; r++)
        g[r] = rq30((int64_t)bo->p_q30[r][i] * a + (int64_t)bo->p_q30[r][i + 1] * u);
    int64_t s = bo->cfg.lambda_q30 + rq30(a * g[i] + u * g[i + 1]);
    int64_t inv_s = (((int64_t)1 << 60) + s / 2) / s;
    for (uint32_t r = 0; r < n; r++) {
        kq[r] = rq30(g[r] * inv_s);
        int64_t th = (int64_t)bo->theta_q16[r] + rq30(kq[r] * e);
        bo->theta_q16[r] = sat32(th > Q30 ? Q30 : th < -Q30 ? -Q30 : th);
    }

    /* P - k g' on the upper triangle (mirrored: exactly symmetric), then the forgetting. */
    bool inflate[B_ONLINE_MAX_NODES];
    for (uint32_t r = 0; r < n; r++) {
        for (uint32_t c = r; c < n; c++) {
            int64_t p = (int64_t)bo->p_q30[r][c] - rq30(kq[r] * g[c]);
            if (c == r && p < 0)
                p = 0; /* rounding only: P_ii >= 0 exactly in exact arithmetic */
            bo->p_q30[r][c] = sat32(p);
        }
        inflate[r] = bo->p_q30[r][r] <= bo->lambda_p0_q30;
    }
    for (uint32_t r = 0; r < n; r++) {
        for (uint32_t c = r; c < n; c++) {
            int64_t m = inflate[r] && inflate[c] ? bo->inv_lambda_q30
                        : (inflate[r] || inflate[c]) ? bo->inv_sqrt_lambda_q30 : Q30;
            int32_t p = sat32(rq30((int64_t)bo->p_q30[r][c] * m));
            bo->p_q30[r][c] = p;
            bo->p_q30[c][r] = p;
        }
    }
    if (bo->samples != UINT32_MAX)
        bo->samples++;
    write_grid(bo);
}
