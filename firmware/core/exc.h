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
    EXC_ERR_PACE,                /* pacing: frame period, tick rate or B range invalid */
} exc_status_t;

/* Pacing rule: the swing is slow enough that the smallest play expected is taken up over
 * this many camera frames, so each reversal's onset is timed by several frames rather than
 * falling between two. The host reads it through the native module (its calibration's
 * "a slower swing would measure B better" advice and the simulator's default speed). */
enum { EXC_PACE_FRAMES = 4 };

typedef struct {
    exc_config_t cfg;
    int64_t q_q32;               /* current set-point, Q32.32 */
    int64_t target_q32;          /* next turning point */
    int64_t base_q32;            /* forward sweep: bottom of the current cycle; return sweep: its top */
    int8_t dir;                  /* +1 up, -1 down, 0 done */
    int8_t sweep;                /* +1 forward sweep, -1 return sweep */
} exc_t;

/* Swing speed of the pacing rule, v = b_low / (EXC_PACE_FRAMES x frame period), in actuator
 * units per control tick, Q32.32, rounded down (so the play takes at least that many frames).
 * b_low_q16, b_high_q16: the expected play range, actuator units Q16, 0 < b_low <= b_high
 * (b_high is checked only: the swing's shorter leg must exceed it, see exc_pace_check);
 * frame_period_us: camera period, 1000..1000000 us (1 to 1000 fps); tick_hz: control rate,
 * 1..1000000 Hz. Returns EXC_ERR_PACE for any of those out of range, EXC_ERR_SPEED when the
 * speed is below one Q32.32 LSB per tick or absurdly large; *v_q32 untouched on error.
 * Integer-only, with a 64-bit divide: configuration time, never the tick. */
exc_status_t exc_pace_speed(int32_t b_low_q16, int32_t b_high_q16, uint32_t frame_period_us,
                            uint32_t tick_hz, int64_t *v_q32);

/* cfg with its speed set by exc_pace_speed, after checking that the swing's shorter leg
 * (amplitude - advance) exceeds b_high (else the tip never moves on that leg: EXC_ERR_PACE)
 * and that the result passes exc_init's checks. cfg untouched on error. */
exc_status_t exc_pace_config(exc_config_t *cfg, int32_t b_low_q16, int32_t b_high_q16,
                             uint32_t frame_period_us, uint32_t tick_hz);

/* Validate cfg and start at q_start, moving up. */
exc_status_t exc_init(exc_t *e, const exc_config_t *cfg);

/* Advance one tick: returns the set-point q (Q16). *reversal is set true on the tick
 * that reaches a turning point (the set-point is then exactly that point, q1 of eq. 1).
 * After the end it holds q_start (or the last point) with dir = 0. O(1). */
int32_t exc_step(exc_t *e, bool *reversal);

/* True once the trajectory has ended. */
bool exc_done(const exc_t *e);

#endif /* EXC_H */
