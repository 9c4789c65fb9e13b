/* The production control loop: one object per actuator, run once per control tick by the
 * STM32 images, the virtual board and the benches alike (docs/firmware.md, "Control loop"). */
#ifndef PSA_LOOP_H
#define PSA_LOOP_H

#include <stdbool.h>
#include <stdint.h>

#include "b_online.h"
#include "calib.h"
#include "comp.h"
#include "exc.h"
#include "f_online.h"
#include "onset.h"

/* What the loop commands; the values are the protocol's PSP_MODE_* (ps_proto.h), checked
 * by a static assertion in psl_link.c, so the link passes the wire value straight on. */
typedef enum {
    PSA_MODE_IDLE = 0,           /* hold the last set-point */
    PSA_MODE_EXCITATION = 1,     /* excitation trajectory (section III-B), reversals to the onset detector */
    PSA_MODE_COMPENSATION = 2,   /* q* from c* through the inverse model (eqs. 4, 5/9) */
    PSA_MODE_PASSTHROUGH = 3,    /* q* = f^-1(c*) clamped to the table's q range, no backlash model */
} psa_mode_t;

/* Expected play range and control rate for pacing the excitation to the camera. */
typedef struct {
    int32_t b_low_q16;           /* smallest play expected, actuator units Q16 */
    int32_t b_high_q16;          /* widest play expected, >= b_low; 0: pacing off */
    uint32_t tick_hz;            /* control tick rate, Hz */
} exc_pace_t;

typedef struct {
    onset_config_t onset;        /* on-board onset detector (eq. 1) */
    exc_config_t exc;            /* excitation without a table (with one: the table's q range) */
    exc_pace_t pace;             /* b_high_q16 > 0: exc's speed set by the pacing rule from the
                                  * onset detector's frame period (exc_pace_config); 0: exc.v_q32 */
    comp_smoothing_t lim;        /* transition smoothing of the compensator ... */
    bool smooth;                 /* ... used when true; false: eq. 4 as written (what a host replays) */
} psa_config_t;

/* Everything the loop owns. calib_t is not in it: tables live where the caller loads them
 * (the link double-buffers two), and the loop runs whichever psa_set_table() named last. */
typedef struct {
    psa_config_t cfg;
    const calib_t *cal;          /* running table, NULL: none */
    psa_mode_t mode;
    bool comp_armed;             /* the next compensation step first resets the compensator at its c* */
    int32_t c_ref_q16;           /* last reference c*, deg */
    int32_t q_ref_q16;           /* last set-point q*, actuator units */
    comp_t comp;
    exc_t exc;
    onset_t onset;               /* detector and encoder history */
    b_online_t *learn;           /* on-line B update fed by the onset samples, NULL: off */
    f_online_t *learn_f;         /* on-line offset and gain of f fed by the angle readings, NULL: off */
    bool f_publish_due;          /* learn_f asked for a publish: psa_background runs it */
} psa_loop_t;

/* Reset: idle, no table, q* = 0, a fresh onset detector (cfg copied). Boot time. */
void psa_init(psa_loop_t *l, const psa_config_t *cfg);

/* Table commit: from the next tick the loop runs cal (already accepted by calib_load; NULL
 * = none). A running compensation whose new table has the same operator stages as the old
 * (transition operators: count, weight format, thresholds and weights; relaxation constants;
 * threshold map entries; none at all for the pure play) carries on with its state
 * (direction, offset, ramp, the operators' and relaxation's states): a commit that changes
 * f or B moves q* only by what the new table changes. Otherwise a running compensation
 * restarts at its current c* with no direction known (operator states belong to their
 * operators). O(1), O(n) with a threshold map (its entries compared).
 * Refused (false) in excitation mode, whose trajectory spans the old table's range. O(1). */
bool psa_set_table(psa_loop_t *l, const calib_t *cal);

/* Change mode. Excitation restarts the trajectory and the onset detector (range: the
 * table's, else cfg.exc; speed: the pacing rule when cfg.pace is on, else cfg.exc's); compensation and passthrough need a table. False, nothing
 * changed, when the mode is unknown, has no table or the excitation config (or its pacing:
 * frame period, tick rate, B range) is invalid. */
bool psa_set_mode(psa_loop_t *l, psa_mode_t mode);

/* c_ref_q16 of a tick with no reference yet (a host that has not sent its first c*): the
 * set-point is held and an armed compensator stays armed for the first real one. */
#define PSA_NO_REFERENCE INT32_MIN

/* One control tick at board time t_us: reference c_ref_q16 (deg, Q16; used in compensation
 * and passthrough; PSA_NO_REFERENCE holds), measured actuator position q_meas_q16 (encoder, Q16) in; the motor
 * set-point q* (Q16) out. The encoder sample goes into the onset history in every mode.
 * *ev_ready is set true with *ev filled when an onset ended on this tick (a B sample of
 * eq. 1, or a reason: timeout, reversal superseded); at most one per tick.
 * Integer-only, no divide, O(1) (docs/firmware.md gives the measured worst case). */
int32_t psa_tick(psa_loop_t *l, uint32_t t_us, int32_t c_ref_q16, int32_t q_meas_q16,
                 onset_event_t *ev, bool *ev_ready);

/* A set-point request outside the tick (host-driven PSP_MSG_COMP_STEP): c* becomes
 * c_ref_q16 and the compensation step runs now; the ticks that follow hold c*, which the
 * rate-independent model leaves unchanged. Returns q*, or INT32_MIN (nothing changed) when
 * not in compensation or passthrough mode. */
int32_t psa_set_reference(psa_loop_t *l, int32_t c_ref_q16);

/* A reversal commanded by someone else (the host's own excitation) at t1_us with q1_q16.
 * True with *ev = ONSET_ERR_REVERSAL when it supersedes a pending one. O(1). */
bool psa_reversal(psa_loop_t *l, uint32_t t1_us, int32_t q1_q16, onset_event_t *ev);

/* One camera frame (marker at u, v px, Q16) or angle-sensor reading (c deg, Q16) taken at
 * t_us on the board clock; valid = false when the marker was lost. True with *ev when the
 * pending onset ended (section III-A). O(log ENC_HIST_LEN) on that frame, O(1) otherwise. */
bool psa_observe_px(psa_loop_t *l, uint32_t t_us, int32_t u_q16, int32_t v_q16, bool valid,
                    onset_event_t *ev);
bool psa_observe_deg(psa_loop_t *l, uint32_t t_us, int32_t c_q16, bool valid, onset_event_t *ev);

/* On-line B update during use (b_online.h): every B sample that psa_observe_px/_deg completes
 * is learnt by bo (b_online_sample, on the observation call, never in psa_tick); bo must have
 * been initialised (b_online_init) on the B of the table the loop runs. NULL stops learning.
 * A sample that a tick completes (the rare finish on timeout) is not learnt. */
void psa_set_learning(psa_loop_t *l, b_online_t *bo);

/* On-line offset and gain of f during compensation (f_online.h): every valid angle reading
 * psa_observe_deg receives while a reference is tracked is learnt by fo (f_online_sample,
 * O(1), on the observation call) against the regressor psa_f_regressor gives; when a publish
 * is due, psa_background (the main loop's, never psa_tick) runs it. fo must have been
 * initialised (f_online_init) on the f and f^-1 of the table the loop runs. NULL stops. */
void psa_set_f_learning(psa_loop_t *l, f_online_t *fo);

/* The regressor of an angle reading: f(f^-1(c*)), the uncorrected model angle of the
 * position the compensator aims at for the last reference c* (f^-1 the running one, which
 * carries the learnt map). False (nothing written) unless valid, compensating, armed off and
 * a reference known. Two table lookups, outside the tick. */
bool psa_f_regressor(const psa_loop_t *l, bool valid, int32_t *x_q16);

/* Background work of the loop, for the main loop between ticks: a due publish of the learnt
 * offset and gain (f_online_publish: the solve and the f^-1 rewrite into the spare copy, one
 * pointer store), then the compensator's cached f^-1 cell is emptied. True if it published. */
bool psa_background(psa_loop_t *l);

/* The running table's f^-1 entries changed outside the loop (f_online_publish / _stop / a
 * rebind): the compensator drops its cached cell of f^-1. One word store, O(1). */
void psa_f_changed(psa_loop_t *l);

/* The running table's B entries changed outside the loop (an on-line B sample published by a
 * background step, b_online_sample / b_online_stop): the compensator drops its cached cell of
 * B. Safe to call from outside an interrupt-driven tick (one word store). O(1). */
void psa_b_changed(psa_loop_t *l);

#endif /* PSA_LOOP_H */
