/* Bench-only reference and plant generators shared by bench_m4.c and bench_desktop.c (not product code). */
#ifndef BENCH_TRAJ_H
#define BENCH_TRAJ_H

#include <stdint.h>

/* A triangle c* between -ampl and +ampl whose half-periods are drawn uniformly from
 * [half_min, half_max] ticks (xorshift32): reversals at irregular intervals, as a
 * teleoperated reference has them. The divide per leg is bench code, outside any timing. */
typedef struct {
    int32_t c_q16, target_q16, step_q16;
    uint32_t left, half_min, half_max, rng;
    uint32_t reversals;
    uint32_t hold;               /* the output is sampled and held every `hold` ticks (init: 1, every tick) */
    uint32_t hold_left;
    int32_t out_q16;
} bench_tri_t;

void bench_tri_init(bench_tri_t *g, int32_t ampl_q16, uint32_t half_min, uint32_t half_max, uint32_t seed);
int32_t bench_tri_next(bench_tri_t *g);

/* The instrument for the excitation runs: a play of width b_q16 (centre z follows q out
 * of the band |q - z| <= b/2) seen by a camera as u = 320 px + gain z, v = 240 px + gain z / 2,
 * with uniform noise of +-noise_q16 px (xorshift32). */
typedef struct {
    int32_t z_q16, half_b_q16, gain, noise_q16;
    uint32_t rng;
} bench_plant_t;

void bench_plant_init(bench_plant_t *p, int32_t q0_q16, int32_t b_q16, int32_t gain_px_per_unit, int32_t noise_q16);
void bench_plant_step(bench_plant_t *p, int32_t q_q16);
void bench_plant_marker(bench_plant_t *p, int32_t *u_q16, int32_t *v_q16);

#endif /* BENCH_TRAJ_H */
