/* Transition-model bench inputs: the 16-operator table and the reversal-rate references. */
#include "bench_pi.h"

#include "ps_fixed.h"
#include "ps_table.h"
#include "psa_builtin_table.h"
#include "table_write.h"

#include <string.h>

enum {
    PI_OPS = PST_MAX_OPS,
    REF_AMPL_Q16 = 30 * PS_Q16_ONE,
};

static union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} pi_table;

/* The built-in table's grids (firmware/app/psa_builtin_table.c) with 16 operators: thresholds
 * 0.1 mm apart, w_0 = 1/4 and 15 x 1/20 (sum 1). */
static void bench_pi_ops(int32_t *r_q16, int32_t *w_q16)
{
    for (int i = 0; i < PI_OPS; i++) {
        r_q16[i] = i * (PS_Q16_ONE / 10);
        w_q16[i] = i == 0 ? PS_Q16_ONE / 4 : PS_Q16_ONE / 20;
    }
}

int bench_pi_load(calib_t *cal)
{
    int32_t r_q16[PI_OPS], w_q16[PI_OPS];
    bench_pi_ops(r_q16, w_q16);
    size_t len = psa_builtin_table_ops(pi_table.bytes, sizeof pi_table.bytes, PST_F_REMAIN, PI_OPS, r_q16, w_q16);
    return (int)calib_load(cal, pi_table.bytes, len);
}

static union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} map_table;

enum {
    MAP_N = 73,                  /* z = -18 .. +18 mm: B's grid widened by max B / 2 */
    MAP_STEP_Q16 = PS_Q16_ONE / 2,
    MAP_X0_Q16 = -18 * PS_Q16_ONE,
};

/* The 16-operator table above with a threshold map (layout v3): u = g(z) = -18 mm +
 * integral_{-18}^{z} b_ref / B, b_ref = B(0) = 1.5 mm, B held at its end values beyond the
 * grid (trapezoid rule on the map's grid; set-up only, the doubles never reach the tick). */
static int map_load(calib_t *cal, const pst_relax_t *relax)
{
    int32_t r_q16[PI_OPS], w_q16[PI_OPS];
    bench_pi_ops(r_q16, w_q16);
    size_t len = psa_builtin_table_ops(map_table.bytes, sizeof map_table.bytes, PST_F_REMAIN, PI_OPS, r_q16, w_q16);
    if (len == 0)
        return -1;
    pst_header_t h;
    memcpy(&h, map_table.bytes, sizeof h);
    static int32_t b[PST_MAX_ENTRIES], f[PST_MAX_ENTRIES], u[MAP_N];
    memcpy(b, map_table.bytes + h.b.offset, 4u * h.b.n);
    memcpy(f, map_table.bytes + h.f.offset, 4u * h.f.n);
    double acc = MAP_X0_Q16 / 65536.0, prev = 0;
    for (int i = 0; i < MAP_N; i++) {
        double z = (MAP_X0_Q16 + i * MAP_STEP_Q16) / 65536.0;
        double zc = z < -16 ? -16 : (z > 16 ? 16 : z);
        double slope = 1.5 / (1.5 + 0.02 * zc);
        if (i > 0)
            acc += 0.5 * (slope + prev) * (MAP_STEP_Q16 / 65536.0);
        prev = slope;
        u[i] = (int32_t)(acc * 65536.0 + (acc >= 0 ? 0.5 : -0.5));
    }
    h.layout_version = 0;
    pst_grid_t tm = {.x0_q16 = MAP_X0_Q16, .step_q16 = MAP_STEP_Q16, .n = MAP_N, .offset = 0};
    len = table_write_relax(map_table.bytes, sizeof map_table.bytes, &h, b, f, r_q16, w_q16, &tm, u, relax);
    return (int)calib_load(cal, map_table.bytes, len);
}

int bench_pi_map_load(calib_t *cal)
{
    return map_load(cal, NULL);
}

int bench_pi_relax_load(calib_t *cal)
{
    /* kappa 0.3, lambda 0.5 mm: a relaxation of the catheter's order (docs/method.md) */
    static const pst_relax_t rx = {.kappa_q16 = 19661, .lambda_q16 = 32768};
    return map_load(cal, &rx);
}

static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8;
}

void bench_ref_init(bench_ref_t *r, uint32_t seed, uint32_t len_min, uint32_t len_max)
{
    r->c_q16 = 0;
    r->step_q16 = 0;
    r->left = 0;
    r->rng = seed;
    r->len_min = len_min;
    r->len_span = len_max - len_min + 1u;
    r->side = 1;
}

int32_t bench_ref_next(bench_ref_t *r)
{
    if (r->left == 0) {
        /* Next target on the other side: 20..100 % of the amplitude there. */
        r->side = (int8_t)-r->side;
        int32_t target = r->side * (int32_t)((REF_AMPL_Q16 / 5) + lcg(&r->rng) % (4u * REF_AMPL_Q16 / 5));
        r->left = r->len_min + lcg(&r->rng) % r->len_span;
        r->step_q16 = (target - r->c_q16) / (int32_t)r->left;
    }
    r->left--;
    r->c_q16 += r->step_q16;
    return r->c_q16;
}
