/* Transition-model bench inputs: a table with 16 play operators and c* references with
 * reversals at a chosen rate (bench/bench_m4.c times comp_step and the tick on them). */
#ifndef BENCH_PI_H
#define BENCH_PI_H

#include <stdint.h>

#include "calib.h"

/* The demonstration table's B and f (bench_tick.c: B = 1.5 mm + 0.02 q, f = 3 q + 0.04 q^2
 * deg over q = -16..16 mm) with the transition: 16 operators, r_i = 0.1 i mm (0..1.5 mm),
 * w_0 = 0.25, w_1..15 = 0.05. Returns the calib_load status (CALIB_OK = 0). */
int bench_pi_load(calib_t *cal);

/* The same table with a threshold map (layout v3, B-proportional thresholds): u = g(z) on
 * 73 entries over z = -18..18 mm, g' = 1.5 mm / B(z). Returns the calib_load status. */
int bench_pi_map_load(calib_t *cal);

/* The threshold-map table above plus the travel-domain relaxation (layout 4, kappa 0.3,
 * lambda 0.5 mm): the costliest model the board runs. Returns calib_load's status. */
int bench_pi_relax_load(calib_t *cal);

/* c* in +-30 deg: straight segments of len_min..len_max ticks (uniform, LCG), each to a
 * random target on the other side of the last one, so every segment end is a reversal.
 * At 20 kHz, 5000..10000 ticks is a reversal every 0.25-0.5 s (teleoperation); 512 ticks
 * is the stress case. The per-segment divide is the generator's, not the firmware's. */
typedef struct {
    int32_t c_q16, step_q16;
    uint32_t left, rng, len_min, len_span;
    int8_t side;
} bench_ref_t;

void bench_ref_init(bench_ref_t *r, uint32_t seed, uint32_t len_min, uint32_t len_max);
int32_t bench_ref_next(bench_ref_t *r);

#endif /* BENCH_PI_H */
