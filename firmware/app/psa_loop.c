/* The production control loop: excitation or compensation set-point per tick, encoder history
 * and onset detection (section III), table switch on commit. One code path for every image. */
#include "psa_loop.h"

#include <string.h>

#include "lut.h"

void psa_init(psa_loop_t *l, const psa_config_t *cfg)
{
    memset(l, 0, sizeof *l);
    l->cfg = *cfg;
    l->mode = PSA_MODE_IDLE;
    l->c_ref_q16 = PSA_NO_REFERENCE;
    onset_init(&l->onset, &l->cfg.onset);
}

/* The operator stages of two tables are the same model: same transition operators (count,
 * weight format, thresholds, weights), same relaxation constants, same threshold map. Their
 * states (comp_t.pi, .relax) are then valid under either table. O(n) with a map: commit time. */
static bool same_operators(const calib_t *a, const calib_t *b)
{
    const pi_params_t *p = &a->pi_inv, *q = &b->pi_inv;
    if (p->n != q->n || p->w_frac != q->w_frac || a->relax.kappa_q16 != b->relax.kappa_q16 ||
        a->relax.lambda_q16 != b->relax.lambda_q16 || a->tmap.n != b->tmap.n)
        return false;
    if (memcmp(p->r_q16, q->r_q16, p->n * sizeof(int32_t)) != 0 || memcmp(p->w, q->w, p->n * sizeof(int32_t)) != 0)
        return false;
    if (a->tmap.n != 0 &&
        (a->tmap.x0_q16 != b->tmap.x0_q16 || a->tmap.step_log2 != b->tmap.step_log2 ||
         memcmp(a->tmap.y_q16, b->tmap.y_q16, a->tmap.n * sizeof(int32_t)) != 0))
        return false;
    return true;
}

bool psa_set_table(psa_loop_t *l, const calib_t *cal)
{
    if (l->mode == PSA_MODE_EXCITATION)
        return false;
    if (l->mode == PSA_MODE_COMPENSATION && !l->comp_armed && cal != NULL && l->cal != NULL &&
        same_operators(cal, l->cal)) {
        /* Hot swap during use (a host refresh of f_remain, an offset or B, under the same
         * transition operators, relaxation and map): the compensator keeps its direction,
         * offset, ramp and the operators' and relaxation's states, and runs the new table
         * from the next tick. Tables with other operators re-arm (their states belong to
         * their own operators). */
        l->cal = cal;
        comp_rebind(&l->comp, cal); /* the cached cells held the previous table's entries */
        return true;
    }
    l->cal = cal;
    if (cal == NULL && l->mode != PSA_MODE_IDLE)
        l->mode = PSA_MODE_IDLE; /* nothing left to compensate with: hold */
    l->comp_armed = true;
    return true;
}

bool psa_set_mode(psa_loop_t *l, psa_mode_t mode)
{
    switch (mode) {
    case PSA_MODE_IDLE:
        break;
    case PSA_MODE_EXCITATION: {
        exc_config_t c = l->cfg.exc;
        if (l->cal != NULL) {
            c.q_start_q16 = l->cal->q_min_q16;
            c.q_end_q16 = l->cal->q_max_q16;
        }
        /* Pace the swing to the camera: the divide happens here, once per run. */
        if (l->cfg.pace.b_high_q16 != 0 &&
            exc_pace_config(&c, l->cfg.pace.b_low_q16, l->cfg.pace.b_high_q16, l->cfg.onset.frame_period_us,
                            l->cfg.pace.tick_hz) != EXC_OK)
            return false;
        if (exc_init(&l->exc, &c) != EXC_OK)
            return false;
        /* A fresh detector per run; the noise estimate restarts with the run. */
        onset_init(&l->onset, &l->cfg.onset);
        break;
    }
    case PSA_MODE_COMPENSATION:
    case PSA_MODE_PASSTHROUGH:
        if (l->cal == NULL)
            return false;
        l->comp_armed = true;
        l->c_ref_q16 = PSA_NO_REFERENCE;
        break;
    default:
        return false;
    }
    l->mode = mode;
    return true;
}

/* q* for c* in compensation or passthrough (the caller checked the mode and the table). */
static int32_t setpoint_for(psa_loop_t *l, int32_t c_ref_q16)
{
    const calib_t *cal = l->cal;
    if (l->mode == PSA_MODE_COMPENSATION) {
        if (l->comp_armed) {
            comp_reset(&l->comp, cal, l->cfg.smooth ? &l->cfg.lim : NULL, c_ref_q16);
            l->comp_armed = false;
        }
        return comp_step(&l->comp, c_ref_q16);
    }
    int32_t q = lut_eval(&cal->f_inv, c_ref_q16);
    /* A threshold map (table v3) puts f over u = g(z): back to actuator units. */
    if (cal->tmap.n != 0)
        q = lut_eval(&cal->tmap_inv, q);
    return q < cal->q_min_q16 ? cal->q_min_q16 : q > cal->q_max_q16 ? cal->q_max_q16 : q;
}

int32_t psa_tick(psa_loop_t *l, uint32_t t_us, int32_t c_ref_q16, int32_t q_meas_q16,
                 onset_event_t *ev, bool *ev_ready)
{
    bool ready = false;
    int32_t q_ref_q16 = l->q_ref_q16;
    if (l->mode == PSA_MODE_COMPENSATION && !l->comp_armed && c_ref_q16 != PSA_NO_REFERENCE) {
        /* The hot path, every tick while compensating: eq. 4 and nothing else. */
        q_ref_q16 = comp_step_inline(&l->comp, c_ref_q16);
        l->c_ref_q16 = c_ref_q16;
    } else if (l->mode >= PSA_MODE_COMPENSATION) {
        if (c_ref_q16 != PSA_NO_REFERENCE) {
            l->c_ref_q16 = c_ref_q16;
            q_ref_q16 = setpoint_for(l, c_ref_q16);
        }
    } else if (l->mode == PSA_MODE_EXCITATION) {
        bool rev = false;
        q_ref_q16 = exc_step(&l->exc, &rev);
        /* The commanded set-point at the turning point is q1 of eq. 1. */
        if (rev)
            ready = onset_reversal(&l->onset, t_us, q_ref_q16, ev);
        if (exc_done(&l->exc))
            l->mode = PSA_MODE_IDLE;
    }
    l->q_ref_q16 = q_ref_q16;
    /* A reversal on this tick restarted the detector, so its timeout cannot also end
     * here: at most one event per tick. */
    if (onset_tick_inline(&l->onset, t_us, q_meas_q16, ev))
        ready = true;
    *ev_ready = ready;
    return q_ref_q16;
}

int32_t psa_set_reference(psa_loop_t *l, int32_t c_ref_q16)
{
    if (l->mode < PSA_MODE_COMPENSATION || l->cal == NULL || c_ref_q16 == PSA_NO_REFERENCE)
        return INT32_MIN;
    l->c_ref_q16 = c_ref_q16;
    l->q_ref_q16 = setpoint_for(l, c_ref_q16);
    return l->q_ref_q16;
}

void psa_b_changed(psa_loop_t *l)
{
    comp_b_changed(&l->comp);
}

bool psa_reversal(psa_loop_t *l, uint32_t t1_us, int32_t q1_q16, onset_event_t *ev)
{
    return onset_reversal(&l->onset, t1_us, q1_q16, ev);
}

void psa_set_learning(psa_loop_t *l, b_online_t *bo)
{
    l->learn = bo;
}

/* The one hook of the on-line B update: an observation completed an onset. */
static bool learn(psa_loop_t *l, bool hit, const onset_event_t *ev)
{
    if (hit && l->learn != NULL && (ev->reason == ONSET_OK || ev->reason == ONSET_OK_COARSE)) {
        b_online_sample(l->learn, ev->q_mean_q16, ev->b_q16);
        comp_b_changed(&l->comp);
    }
    return hit;
}

bool psa_observe_px(psa_loop_t *l, uint32_t t_us, int32_t u_q16, int32_t v_q16, bool valid,
                    onset_event_t *ev)
{
    return learn(l, onset_observe_px(&l->onset, t_us, u_q16, v_q16, valid, ev), ev);
}

bool psa_f_regressor(const psa_loop_t *l, bool valid, int32_t *x_q16)
{
    if (!valid || l->mode != PSA_MODE_COMPENSATION || l->comp_armed || l->cal == NULL ||
        l->c_ref_q16 == PSA_NO_REFERENCE)
        return false;
    /* The model's tip for the reference being tracked, before the learnt map: the compensator
     * aims y* = f'^-1(c*) (f' = a + g f, the running f^-1), whose uncorrected angle is f(y*). */
    *x_q16 = lut_eval(&l->cal->f, lut_eval(&l->cal->f_inv, l->c_ref_q16));
    return true;
}

bool psa_observe_deg(psa_loop_t *l, uint32_t t_us, int32_t c_q16, bool valid, onset_event_t *ev)
{
    int32_t x_q16;
    if (l->learn_f != NULL && psa_f_regressor(l, valid, &x_q16) && f_online_sample(l->learn_f, x_q16, c_q16))
        l->f_publish_due = true;
    return learn(l, onset_observe_deg(&l->onset, t_us, c_q16, valid, ev), ev);
}

void psa_set_f_learning(psa_loop_t *l, f_online_t *fo)
{
    l->learn_f = fo;
    l->f_publish_due = false;
}

void psa_f_changed(psa_loop_t *l)
{
    /* The compensator's cached cell of f^-1 held the previous map's entries: empty it (one
     * word store; an interrupt-driven tick refills it from the published copy). comp.h's
     * comp_b_changed does the same for B's cell. */
    *(volatile uint32_t *)&l->comp.f_inv_cell.width = 0;
}

bool psa_background(psa_loop_t *l)
{
    if (!l->f_publish_due || l->learn_f == NULL)
        return false;
    l->f_publish_due = false;
    f_online_publish(l->learn_f);
    psa_f_changed(l);
    return true;
}
