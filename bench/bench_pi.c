/* Transition-model bench inputs: the 16-operator table and the reversal-rate references. */
#include "bench_pi.h"

#include <string.h>

#include "ps_fixed.h"
#include "ps_table.h"
#include "table_write.h"

enum {
    PI_N = 33,                   /* grid entries, q = -16 .. +16 mm, 1 mm apart */
    PI_X0_Q16 = -16 * PS_Q16_ONE,
    PI_OPS = PST_MAX_OPS,
    REF_AMPL_Q16 = 30 * PS_Q16_ONE,
};

static union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} pi_table;

int bench_pi_load(calib_t *cal)
{
    int32_t b_q16[PI_N], f_q16[PI_N], r_q16[PI_OPS], w_q16[PI_OPS];
    for (int i = 0; i < PI_N; i++) {
        int32_t q_mm = i - 16;
        b_q16[i] = 3 * PS_Q16_ONE / 2 + q_mm * (PS_Q16_ONE / 50);
        f_q16[i] = 3 * q_mm * PS_Q16_ONE + q_mm * q_mm * (PS_Q16_ONE / 25);
    }
    for (int i = 0; i < PI_OPS; i++) {
        r_q16[i] = i * (PS_Q16_ONE / 10);
        w_q16[i] = i == 0 ? PS_Q16_ONE / 4 : PS_Q16_ONE / 20;
    }
    pst_header_t h;
    memset(&h, 0, sizeof h);
    h.generation = 1;
    h.q_unit = PST_Q_UNIT_MM;
    h.f_kind = PST_F_REMAIN;
    h.q_min_q16 = PI_X0_Q16;
    h.q_max_q16 = PI_X0_Q16 + (PI_N - 1) * PS_Q16_ONE;
    h.b = (pst_grid_t){.x0_q16 = PI_X0_Q16, .step_q16 = PS_Q16_ONE, .n = PI_N};
    h.f = h.b;
    h.pi.n = PI_OPS;
    size_t len = table_write(pi_table.bytes, sizeof pi_table.bytes, &h, b_q16, f_q16, r_q16, w_q16);
    return (int)calib_load(cal, pi_table.bytes, len);
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
