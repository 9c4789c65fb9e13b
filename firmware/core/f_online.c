/* On-line offset and gain of f: c = a + g f(y), learnt from the angle readings during use
 * (docs/online.md, "On-line offset and gain").
 *
 * Estimator: exponentially weighted least squares with forgetting factor lambda = 1 - 2^-k,
 *     min over (a, g) of  sum_i lambda^(n-i) (c_i - a - g x_i)^2 + prior_var (g - 1)^2,
 * which is what recursive least squares with exponential forgetting tracks (Ljung &
 * Soderstrom 1983, ch. 2), solved from its five sufficient statistics instead of a propagated
 * covariance: with two parameters the sums are cheaper to keep than P, they cannot lose
 * positive definiteness to rounding, and a stretch of readings that do not move (no
 * excitation of g) leaves the prior in charge instead of winding P up. The prior term is the
 * host's offset-and-gain refresh's (evaluate/transfer.py, _affine_refreshed), which is this
 * estimator with lambda = 1. Bounded memory: five int64 sums, whatever the session's length.
 *
 * The map is applied where the tick already looks: f^-1 of a + g f is rewritten into a spare
 * copy of the table's f^-1 and published by one pointer store, so psa_tick runs exactly the
 * instructions it ran before (the compensator's y* = f^-1(c*) of eqs. 4, 5, 9 becomes the
 * corrected model's; the transition and the play after it are untouched). */
#include "f_online.h"

#include <stdatomic.h>
#include <stddef.h>
#include <string.h>

#define ONE_Q16 ((int64_t)1 << 16)

static inline int64_t rq16(int64_t x)
{
    return (x + (ONE_Q16 >> 1)) >> 16; /* round half up (arithmetic shift, as b_online.c) */
}

static inline int64_t clamp64(int64_t x, int64_t lo, int64_t hi)
{
    return x < lo ? lo : x > hi ? hi : x;
}

/* n / d rounded to nearest, halves away from zero; d > 0. */
static int64_t div_round(int64_t n, int64_t d)
{
    return n >= 0 ? (n + d / 2) / d : -((-n + d / 2) / d);
}

f_online_config_t f_online_default_config(void)
{
    f_online_config_t c;
    c.mem_log2 = 10;
    c.publish_every = 12;
    c.prior_var_q16 = 100 * (int32_t)ONE_Q16;
    c.g_min_q16 = (int32_t)(ONE_Q16 / 2);
    c.g_max_q16 = (int32_t)(2 * ONE_Q16);
    return c;
}

static bool config_ok(const f_online_config_t *c)
{
    return c->mem_log2 >= 1 && c->mem_log2 <= F_ONLINE_MEM_LOG2_MAX && c->publish_every >= 1 &&
           c->prior_var_q16 > 0 && c->g_min_q16 > 0 && c->g_min_q16 <= ONE_Q16 && c->g_max_q16 >= ONE_Q16 &&
           c->g_max_q16 <= 4 * ONE_Q16;
}

/* f strictly monotone (the loader checked it; checked again since the learner walks it). */
static bool table_ok(const lut_t *f, const lut_t *f_inv, int8_t *sgn)
{
    if (f->n < 2 || f_inv->n < 2 || f_inv->n > CALIB_DERIVED_MAX)
        return false;
    *sgn = f->y_q16[1] > f->y_q16[0] ? 1 : -1;
    for (uint16_t i = 0; i + 1 < f->n; i++) {
        int64_t d = (int64_t)f->y_q16[i + 1] - f->y_q16[i];
        if (d == 0 || (d > 0) != (*sgn > 0))
            return false;
    }
    return true;
}

f_online_status_t f_online_init(f_online_t *fo, const f_online_config_t *cfg, const lut_t *f, lut_t *f_inv)
{
    int8_t sgn;
    if (!config_ok(cfg))
        return F_ONLINE_ERR_CONFIG;
    if (!table_ok(f, f_inv, &sgn))
        return F_ONLINE_ERR_TABLE;
    memset(fo, 0, sizeof *fo);
    fo->cfg = *cfg;
    fo->f = f;
    fo->out = f_inv;
    fo->prior_q16 = f_inv->y_q16;
    fo->live = 2;
    fo->f_sign = sgn;
    fo->f_lo_q16 = sgn > 0 ? f->y_q16[0] : f->y_q16[f->n - 1];
    fo->f_hi_q16 = sgn > 0 ? f->y_q16[f->n - 1] : f->y_q16[0];
    fo->ref_q16 = f->y_q16[(f->n - 1) / 2];
    fo->g_q16 = (int32_t)ONE_Q16;
    return F_ONLINE_OK;
}

bool f_online_sample(f_online_t *fo, int32_t x_q16, int32_t c_q16)
{
    const uint32_t k = fo->cfg.mem_log2;
    const int64_t half = (int64_t)1 << (k - 1);
    int64_t d = clamp64((int64_t)x_q16 - fo->ref_q16, -F_ONLINE_DEV_MAX_Q16, F_ONLINE_DEV_MAX_Q16);
    int64_t e = clamp64((int64_t)c_q16 - fo->ref_q16, -F_ONLINE_DEV_MAX_Q16, F_ONLINE_DEV_MAX_Q16);
    /* Forgetting: every sum times lambda = 1 - 2^-k (rounded), then the new reading. */
    fo->s_w += ONE_Q16 - ((fo->s_w + half) >> k);
    fo->s_x += d - ((fo->s_x + half) >> k);
    fo->s_c += e - ((fo->s_c + half) >> k);
    fo->s_xx += rq16(d * d) - ((fo->s_xx + half) >> k);
    fo->s_xc += rq16(d * e) - ((fo->s_xc + half) >> k);
    if (fo->samples != UINT32_MAX)
        fo->samples++;
    if (fo->since_publish != UINT16_MAX)
        fo->since_publish++;
    return fo->since_publish >= fo->cfg.publish_every;
}

/* (a, g) from the sums: centred moments (Q16 per unit weight), the prior on g, the clamp. */
static void solve(f_online_t *fo)
{
    if (fo->s_w <= 0)
        return;
    const int64_t w = fo->s_w;
    int64_t mx = div_round(fo->s_x * ONE_Q16, w), my = div_round(fo->s_c * ONE_Q16, w);
    int64_t vxx = div_round(fo->s_xx * ONE_Q16, w) - rq16(mx * mx);
    int64_t vxc = div_round(fo->s_xc * ONE_Q16, w) - rq16(mx * my);
    if (vxx < 0)
        vxx = 0; /* rounding only */
    int64_t pr = div_round((int64_t)fo->cfg.prior_var_q16 * ONE_Q16, w); /* prior_var / weight, > 0 */
    if (pr < 1)
        pr = 1;
    int64_t g = div_round((vxc + pr) * ONE_Q16, vxx + pr);
    g = clamp64(g, fo->cfg.g_min_q16, fo->cfg.g_max_q16);
    /* Back from the centred frame: c - ref = a' + g (x - ref), a' = my - g mx. */
    int64_t a = my - rq16(g * mx) + fo->ref_q16 - rq16(g * fo->ref_q16);
    fo->a_q16 = (int32_t)clamp64(a, -F_ONLINE_DEV_MAX_Q16, F_ONLINE_DEV_MAX_Q16);
    fo->g_q16 = (int32_t)g;
}

/* x where the segment (x0, y0)-(x0 + h, y1) reaches y, rounded to nearest (the loader's rule,
 * lut_build.c segment_solve, so the identity map reproduces its entries). */
static int32_t segment_solve(int64_t x0, int64_t h, int32_t y0, int32_t y1, int64_t y)
{
    int64_t num = (y - y0) * h;
    int64_t den = (int64_t)y1 - y0;
    if (den < 0) {
        num = -num;
        den = -den;
    }
    return (int32_t)(x0 + (num + den / 2) / den);
}

/* f^-1 of a + g f on the grid of out into dst: entry j is the exact inverse of the f table at
 * u_j = (c_j - a) / g, u_j saturated to f's range (as lut_eval saturates); the f segments and
 * the (increasing) u_j are walked together, as lut_build_inverse walks them. */
static void bake(const f_online_t *fo, int32_t *dst)
{
    const lut_t *f = fo->f;
    const lut_t *o = fo->out;
    const uint16_t n = f->n;
    const int32_t *y = f->y_q16;
    const int64_t inv_g_q30 = (((int64_t)1 << 46) + fo->g_q16 / 2) / fo->g_q16;
    const int64_t h = (int64_t)1 << f->step_log2;
    uint16_t seg = 0;
    for (uint16_t j = 0; j < o->n; j++) {
        int64_t c = (int64_t)o->x0_q16 + ((int64_t)j << o->step_log2);
        int64_t u = ((c - fo->a_q16) * inv_g_q30 + ((int64_t)1 << 29)) >> 30;
        u = clamp64(u, fo->f_lo_q16, fo->f_hi_q16);
        for (;;) {
            uint16_t b = fo->f_sign > 0 ? (uint16_t)(seg + 1) : (uint16_t)(n - 2 - seg);
            if (u <= y[b] || seg + 2 >= n)
                break;
            seg++;
        }
        uint16_t s = fo->f_sign > 0 ? seg : (uint16_t)(n - 2 - seg);
        dst[j] = segment_solve((int64_t)f->x0_q16 + (int64_t)s * h, h, y[s], y[s + 1], u);
    }
}

void f_online_publish(f_online_t *fo)
{
    solve(fo);
    const uint8_t idx = fo->live == 0 ? 1 : 0;
    bake(fo, fo->inv_q16[idx]);
    /* The entries are complete before the pointer moves (the fence keeps the compiler from
     * sinking their stores below it; one core, so the tick interrupt sees program order). */
    atomic_signal_fence(memory_order_release);
    fo->out->y_q16 = fo->inv_q16[idx];
    fo->live = idx;
    fo->since_publish = 0;
    if (fo->publishes != UINT32_MAX)
        fo->publishes++;
}

bool f_online_step(f_online_t *fo, int32_t x_q16, int32_t c_q16)
{
    if (!f_online_sample(fo, x_q16, c_q16))
        return false;
    f_online_publish(fo);
    return true;
}

f_online_status_t f_online_rebind(f_online_t *fo, const lut_t *f, lut_t *f_inv)
{
    int8_t sgn;
    if (!table_ok(f, f_inv, &sgn))
        return F_ONLINE_ERR_TABLE;
    const lut_t *old = fo->f;
    bool same = old->n == f->n && old->x0_q16 == f->x0_q16 && old->step_log2 == f->step_log2 &&
                memcmp(old->y_q16, f->y_q16, (size_t)f->n * sizeof(int32_t)) == 0;
    if (!same) {
        f_online_config_t c = fo->cfg;
        return f_online_init(fo, &c, f, f_inv);
    }
    fo->f = f;
    fo->out = f_inv;
    fo->prior_q16 = f_inv->y_q16;
    /* Republish the current map into the new table (no solve: the sums did not change). */
    const uint8_t idx = fo->live == 0 ? 1 : 0;
    bake(fo, fo->inv_q16[idx]);
    atomic_signal_fence(memory_order_release);
    f_inv->y_q16 = fo->inv_q16[idx];
    fo->live = idx;
    return F_ONLINE_OK;
}

const int32_t *f_online_entries(const f_online_t *fo)
{
    return fo->out->y_q16;
}

void f_online_stop(f_online_t *fo)
{
    if (fo->out != NULL)
        fo->out->y_q16 = fo->prior_q16;
    fo->live = 2;
}
