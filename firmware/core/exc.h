/* Excitation trajectory: small back-and-forth motions on a ramp over the motor range (section III-B). */
#ifndef EXC_H
#define EXC_H

#include <stdbool.h>
#include <stdint.h>

/* Turning points: up to low_k + amplitude, down to low_{k+1} = low_k + advance, from
 * q_start until the up-turn would pass q_end; then, if return_sweep, the mirror image
 * back down to q_start (so both reversal directions are seen at every q), then hold.
 * Every turning point is a commanded reversal for the onset detector. The amplitude
 * must exceed the largest backlash width expected, or no motion is ever seen. */
typedef struct {
    int32_t q_start_q16;         /* actuator units */
    int32_t q_end_q16;           /* > q_start */
    int32_t amplitude_q16;       /* > advance > 0 */
    int32_t advance_q16;         /* ramp advance per back-and-forth cycle */
    int64_t v_q32;               /* speed, actuator units per tick, Q32.32, > 0 */
    bool return_sweep;
} exc_config_t;

typedef enum {
    EXC_OK = 0,
    EXC_ERR_RANGE,               /* q_end <= q_start */
    EXC_ERR_SHAPE,               /* not amplitude > advance > 0 */
    EXC_ERR_SPEED,               /* v <= 0, or one tick crosses a whole cycle */
} exc_status_t;

typedef struct {
    exc_config_t cfg;
    int64_t q_q32;               /* current set-point, Q32.32 */
    int64_t target_q32;          /* next turning point */
    int64_t base_q32;            /* forward sweep: bottom of the current cycle; return sweep: its top */
    int8_t dir;                  /* +1 up, -1 down, 0 done */
    int8_t sweep;                /* +1 forward sweep, -1 return sweep */
} exc_t;

/* Validate cfg and start at q_start, moving up. */
exc_status_t exc_init(exc_t *e, const exc_config_t *cfg);

/* Advance one tick: returns the set-point q (Q16). *reversal is set true on the tick
 * that reaches a turning point (the set-point is then exactly that point, q1 of eq. 1).
 * After the end it holds q_start (or the last point) with dir = 0. O(1). */
int32_t exc_step(exc_t *e, bool *reversal);

/* True once the trajectory has ended. */
bool exc_done(const exc_t *e);

#endif /* EXC_H */
