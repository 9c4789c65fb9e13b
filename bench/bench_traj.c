/* Bench-only generators: irregular triangle reference, a play plant with a noisy marker. */
#include "bench_traj.h"

static uint32_t xorshift32(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return *s = x;
}

static void new_leg(bench_tri_t *g)
{
    uint32_t span = g->half_max - g->half_min + 1u;
    g->left = g->half_min + xorshift32(&g->rng) % span;
    g->step_q16 = (g->target_q16 - g->c_q16) / (int32_t)g->left;
}

void bench_tri_init(bench_tri_t *g, int32_t ampl_q16, uint32_t half_min, uint32_t half_max, uint32_t seed)
{
    g->c_q16 = -ampl_q16;
    g->target_q16 = ampl_q16;
    g->half_min = half_min;
    g->half_max = half_max;
    g->rng = seed ? seed : 1u;
    g->reversals = 0;
    g->hold = 1;
    g->hold_left = 0;
    new_leg(g);
}

static int32_t tri_advance(bench_tri_t *g)
{
    if (--g->left == 0) {
        g->c_q16 = g->target_q16; /* land exactly on the turning point */
        g->target_q16 = -g->target_q16;
        g->reversals++;
        new_leg(g);
        return g->c_q16;
    }
    g->c_q16 += g->step_q16;
    return g->c_q16;
}

/* The triangle advances every tick; a host slower than the tick (hold > 1) sends its value
 * every `hold` ticks and the loop sees it held in between. */
int32_t bench_tri_next(bench_tri_t *g)
{
    int32_t c = tri_advance(g);
    if (g->hold_left == 0) {
        g->out_q16 = c;
        g->hold_left = g->hold;
    }
    g->hold_left--;
    return g->out_q16;
}

void bench_plant_init(bench_plant_t *p, int32_t q0_q16, int32_t b_q16, int32_t gain_px_per_unit, int32_t noise_q16)
{
    p->half_b_q16 = b_q16 / 2;
    p->z_q16 = q0_q16 - p->half_b_q16;
    p->gain = gain_px_per_unit;
    p->noise_q16 = noise_q16;
    p->rng = 12345u;
}

void bench_plant_step(bench_plant_t *p, int32_t q_q16)
{
    if (q_q16 - p->z_q16 > p->half_b_q16)
        p->z_q16 = q_q16 - p->half_b_q16;
    else if (p->z_q16 - q_q16 > p->half_b_q16)
        p->z_q16 = q_q16 + p->half_b_q16;
}

void bench_plant_marker(bench_plant_t *p, int32_t *u_q16, int32_t *v_q16)
{
    uint32_t span = 2u * (uint32_t)p->noise_q16 + 1u;
    int32_t nu = (int32_t)(xorshift32(&p->rng) % span) - p->noise_q16;
    int32_t nv = (int32_t)(xorshift32(&p->rng) % span) - p->noise_q16;
    *u_q16 = 320 * 65536 + p->gain * p->z_q16 + nu;
    *v_q16 = 240 * 65536 + p->gain * p->z_q16 / 2 + nv;
}
