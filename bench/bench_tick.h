/* The per-tick control chain (encoder sample -> onset_tick -> comp_step), shared by the demo and the benches. */
#ifndef BENCH_TICK_H
#define BENCH_TICK_H

#include <stdint.h>

#include "calib.h"
#include "comp.h"
#include "onset.h"

/* Everything one control loop owns. calib_t (derived tables) and onset_t (encoder
 * history) are the big members; see bench/README.md for their sizes. */
typedef struct {
    calib_t cal;
    onset_t onset;
    comp_t comp;
    int32_t c_ref_q16;           /* reference bending angle c*, deg */
    int32_t c_step_q16;          /* its change per tick (triangle wave), deg */
    int32_t q_meas_q16;          /* simulated encoder: the motor reached last tick's q* */
    uint32_t reversals;          /* direction changes of c* so far */
    uint32_t onset_events;       /* events onset_tick/onset_reversal reported */
} ctl_loop_t;

/* Load the built-in demonstration table and reset every module; tick_hz sets the
 * smoothing limits and the reference speed. Returns the calib_load status (CALIB_OK = 0). */
int ctl_loop_init(ctl_loop_t *l, uint32_t tick_hz);

/* One control tick at time t_us: returns q* (actuator units, Q16). Integer-only. */
int32_t ctl_loop_tick(ctl_loop_t *l, uint32_t t_us);

#endif /* BENCH_TICK_H */
