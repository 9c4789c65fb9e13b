/* Motion-onset detector (section III-A): B(q_mean) = |q(t2 - t_delay) - q1| (eq. 1), with
 * t2 refined below one frame period and T set from the measured still noise. */
#include "onset.h"

onset_config_t onset_default_config(void)
{
    onset_config_t c = {
        .t_delay_us = 80000,                 /* paper V-D: 2 frames at 25 Hz */
        .frame_period_us = 40000,
        .threshold_q16 = 0,                  /* automatic */
        .threshold_floor_q16 = 3277,         /* 0.05 px/frame */
        .threshold_max_q16 = 65536,          /* 1 px/frame: a still marker never jitters that much */
        .noise_k2_q16 = 9u << 16,            /* k = 3: P(false onset) ~ e^-9 per frame for 2-D Gaussian noise */
        .settle_frames = 1,
        .max_lost_frames = 10,
        .jump_ratio_q8 = 384,                /* 1.5 */
        .timeout_us = 10000000,
    };
    return c;
}

uint32_t onset_history_span_us(const onset_config_t *cfg)
{
    uint64_t frames = 4u + 2u * (uint64_t)cfg->max_lost_frames;
    uint64_t span = (uint64_t)cfg->t_delay_us + frames * cfg->frame_period_us + ONSET_HIST_MARGIN_US;
    return span > UINT32_MAX ? UINT32_MAX : (uint32_t)span;
}

void onset_init(onset_t *o, const onset_config_t *cfg)
{
    o->cfg = *cfg;
    if (o->cfg.frame_period_us == 0)
        o->cfg.frame_period_us = 1; /* avoid a divide by zero on a bad config; gaps then count in us */
    enc_hist_set_span(&o->hist, onset_history_span_us(&o->cfg));
    o->state = ONSET_ST_IDLE;
    o->noise_d2_q32 = 0;
    o->noise_count = 0;
    o->lost_run = 0;
    o->have_prev = false;
}

int64_t onset_threshold2_q32(const onset_t *o)
{
    const onset_config_t *c = &o->cfg;
    if (c->threshold_q16 > 0)
        return (int64_t)c->threshold_q16 * c->threshold_q16;
    int64_t max2 = (int64_t)c->threshold_max_q16 * c->threshold_max_q16;
    if (o->noise_count < ONSET_NOISE_LEARN_PAIRS)
        return max2; /* still learning the noise: only gross motion counts */
    int64_t t2 = ((o->noise_d2_q32 >> 8) * (int64_t)c->noise_k2_q16) >> 8;
    int64_t floor2 = (int64_t)c->threshold_floor_q16 * c->threshold_floor_q16;
    return t2 < floor2 ? floor2 : (t2 > max2 ? max2 : t2);
}

/* Fold one still frame pair into the noise estimate: the exact mean of the first
 * ONSET_NOISE_LEARN_PAIRS (a power of two, so the mean is a shift), then an EWMA of
 * weight 1/16 that follows slow changes of lighting or focus. */
static void learn_noise(onset_t *o, int64_t d2)
{
    int shift = 0;
    while ((1u << shift) < ONSET_NOISE_LEARN_PAIRS)
        shift++;
    if (o->noise_count < ONSET_NOISE_LEARN_PAIRS) {
        o->noise_d2_q32 = o->noise_count == 0 ? d2 : o->noise_d2_q32 + d2; /* running sum */
        if (++o->noise_count == ONSET_NOISE_LEARN_PAIRS)
            o->noise_d2_q32 >>= shift;
        return;
    }
    o->noise_d2_q32 += (d2 - o->noise_d2_q32) >> 4;
    if (o->noise_count < UINT32_MAX)
        o->noise_count++;
}

/* Finish the pending reversal with a reason (no B sample). */
static bool fail(onset_t *o, onset_reason_t reason, onset_event_t *ev)
{
    ev->reason = reason;
    ev->t1_us = o->t1_us;
    ev->t2_us = 0;
    ev->q1_q16 = o->q1_q16;
    ev->q2_q16 = 0;
    ev->q_mean_q16 = 0;
    ev->b_q16 = 0;
    o->state = ONSET_ST_IDLE;
    return true;
}

/* Finish with a B sample at image onset t2 (eq. 1). */
static bool emit(onset_t *o, uint32_t t2_us, onset_reason_t reason, onset_event_t *ev)
{
    int32_t q2;
    enc_hist_status_t hs = enc_hist_q_at(&o->hist, t2_us - o->cfg.t_delay_us, &q2);
    if (hs == ENC_HIST_TOO_OLD)
        return fail(o, ONSET_ERR_HISTORY_WRAPPED, ev);
    if (hs != ENC_HIST_OK)
        return fail(o, ONSET_ERR_HISTORY_MISSING, ev);
    int64_t d = (int64_t)q2 - o->q1_q16;
    ev->reason = reason;
    ev->t1_us = o->t1_us;
    ev->t2_us = t2_us;
    ev->q1_q16 = o->q1_q16;
    ev->q2_q16 = q2;
    ev->q_mean_q16 = (int32_t)(((int64_t)o->q1_q16 + q2) >> 1);
    ev->b_q16 = (int32_t)(d < 0 ? -d : d);
    o->state = ONSET_ST_IDLE;
    return true;
}

static bool finish_early(onset_t *o, onset_event_t *ev);

bool onset_tick_timed_out(onset_t *o, onset_event_t *ev)
{
    if (o->state >= ONSET_ST_CANDIDATE)
        return finish_early(o, ev);
    return fail(o, ONSET_ERR_TIMEOUT, ev);
}

bool onset_tick(onset_t *o, uint32_t t_us, int32_t q_q16, onset_event_t *ev)
{
    return onset_tick_inline(o, t_us, q_q16, ev);
}

bool onset_reversal(onset_t *o, uint32_t t1_us, int32_t q1_q16, onset_event_t *ev)
{
    bool pending = o->state != ONSET_ST_IDLE;
    if (pending)
        (void)fail(o, ONSET_ERR_REVERSAL, ev);
    o->t1_us = t1_us;
    o->q1_q16 = q1_q16;
    o->state = ONSET_ST_SETTLING;
    o->settle_left = o->cfg.settle_frames;
    o->lost_run = 0;
    o->have_prev = false;
    return pending;
}

static int32_t abs32(int32_t x)
{
    return x < 0 ? -x : x;
}

/* Sub-frame onset: the line through two moving samples (t_a, s_a), (t_b, s_b) of the L1
 * distance from the still level crosses s = 0 at t_a - s_a (t_b - t_a) / (s_b - s_a).
 * L1 distance grows linearly in time along any straight image motion, so no sqrt is
 * needed. The result is clamped to [t_lo, t_a]. 32-bit divide only. */
static uint32_t extrapolate_onset(uint32_t t_a, int32_t s_a_q16, uint32_t t_b, int32_t s_b_q16,
                                  uint32_t t_lo, uint32_t frames_back, uint32_t jump_ratio_q8)
{
    uint32_t span_ab = t_b - t_a;
    uint32_t span_still = t_a - t_lo;
    uint32_t s_a = (uint32_t)s_a_q16;
    uint32_t den = (uint32_t)(s_b_q16 - s_a_q16); /* > 0, checked by the caller */
    /* Moving at a steady rate from an onset at most frames_back frames before t_a, the
     * marker cannot be further from the still level at t_a than it moves in that many
     * frames. Clearly more (jump_ratio, 1.5 by default) is a jump at the onset, such as the
     * instrument shifting in its channel (the paper's V-B registration error): the line
     * would point far too early, and the middle of the last frame interval is the unbiased
     * guess. An angle sensor has no such shift; there a fast start is real motion. */
    if (jump_ratio_q8 != 0 && ((uint64_t)s_a << 8) > (uint64_t)den * jump_ratio_q8 * frames_back) {
        uint32_t half = span_ab / 2u;
        return half > span_still ? t_lo : t_a - half;
    }
    while (s_a >= (1u << 15)) { /* keep s_a << 16 within 31 bits, ratio unchanged */
        s_a >>= 1;
        den >>= 1;
    }
    uint64_t back = span_still + 1ull; /* den lost to the scaling: far back, clamped below */
    if (den != 0) {
        uint32_t r_q16 = (s_a << 16) / den;
        back = ((uint64_t)r_q16 * span_ab) >> 16;
    }
    return back > span_still ? t_lo : t_a - (uint32_t)back;
}

/* Earliest admissible onset: two frames before the first moving frame A (the last frame
 * judged still may already hold sub-threshold motion), never before the image can show
 * the reversal at t1 + t_delay. */
static uint32_t onset_floor(const onset_t *o)
{
    uint32_t two = 2u * o->cfg.frame_period_us;
    uint32_t earliest = o->t1_us + o->cfg.t_delay_us;
    uint32_t t = o->cand_t_us - two;
    return (int32_t)(t - earliest) < 0 ? earliest : t;
}

/* The pending onset ends without its refining frame(s): use what was seen. */
static bool finish_early(onset_t *o, onset_event_t *ev)
{
    if (o->state == ONSET_ST_CONFIRMED)
        return emit(o, extrapolate_onset(o->cand_t_us, o->cand_s_q16, o->conf_t_us, o->conf_s_q16,
                                         onset_floor(o), 1u, o->cfg.jump_ratio_q8), ONSET_OK, ev);
    return emit(o, o->cand_t_us, ONSET_OK_COARSE, ev);
}

static bool observe(onset_t *o, uint32_t t_us, int32_t u, int32_t v, bool valid, onset_event_t *ev)
{
    const onset_config_t *c = &o->cfg;
    /* Nothing pending, or a frame taken before the reversal (late delivery): no news. */
    if (o->state == ONSET_ST_IDLE || (int32_t)(t_us - o->t1_us) < 0)
        return false;
    if (t_us - o->t1_us > c->timeout_us) {
        if (o->state >= ONSET_ST_CANDIDATE)
            return finish_early(o, ev);
        return fail(o, ONSET_ERR_TIMEOUT, ev);
    }
    if (!valid) {
        if (++o->lost_run <= c->max_lost_frames)
            return false;
        if (o->state >= ONSET_ST_CANDIDATE)
            return finish_early(o, ev);
        return fail(o, ONSET_ERR_MARKER_LOST, ev);
    }
    o->lost_run = 0;

    if (o->state == ONSET_ST_SETTLING) {
        /* Frames before t1 + t_delay still show the motion from before the reversal. */
        if ((int32_t)(t_us - (o->t1_us + c->t_delay_us)) < 0)
            return false;
        if (o->settle_left > 0) {
            o->settle_left--;
            return false;
        }
        o->state = ONSET_ST_STILL;
        o->have_prev = false;
    }
    if (!o->have_prev) {
        o->have_prev = true;
        o->prev_t_us = o->still_t_us = t_us;
        o->prev_u_q16 = o->ref_u_q16 = u;
        o->prev_v_q16 = o->ref_v_q16 = v;
        o->still_pairs = 0;
        return false;
    }

    /* Frame difference normalised to whole frame periods, so a gap of lost frames does
     * not look like a jump: moving iff |dQ|^2 > T^2 n^2. */
    uint32_t n = (t_us - o->prev_t_us + c->frame_period_us / 2u) / c->frame_period_us;
    if (n == 0)
        n = 1;
    int64_t du = (int64_t)u - o->prev_u_q16, dv = (int64_t)v - o->prev_v_q16;
    int64_t d2 = du * du + dv * dv;
    int64_t n2 = (int64_t)n * n;
    bool moving = d2 > onset_threshold2_q32(o) * n2;
    int32_t s = abs32(u - o->ref_u_q16) + abs32(v - o->ref_v_q16);
    o->prev_t_us = t_us;
    o->prev_u_q16 = u;
    o->prev_v_q16 = v;

    if (o->state == ONSET_ST_STILL) {
        if (!moving) {
            /* Still: refine the level (EWMA 1/4) and the noise (per-frame pairs only). */
            o->ref_u_q16 += (u - o->ref_u_q16) >> 2;
            o->ref_v_q16 += (v - o->ref_v_q16) >> 2;
            o->still_t_us = t_us;
            if (n == 1)
                learn_noise(o, d2);
            if (o->still_pairs < UINT16_MAX)
                o->still_pairs++;
            return false;
        }
        if (o->still_pairs == 0)
            return fail(o, ONSET_ERR_NO_STILL, ev); /* never saw it still: cannot place the onset */
        o->cand_t_us = t_us;
        o->cand_s_q16 = s;
        o->state = ONSET_ST_CANDIDATE;
        return false;
    }

    if (o->state == ONSET_ST_CANDIDATE) {
        /* B confirms A if the marker keeps moving away from the still level. */
        if (moving && s > o->cand_s_q16) {
            /* A well clear of the noise (over 2 T from the still level) anchors the line
             * closest to the onset; a marginal A may be noise, so wait for C. */
            int64_t s_a = o->cand_s_q16;
            if (s_a * s_a > 4 * onset_threshold2_q32(o))
                return emit(o, extrapolate_onset(o->cand_t_us, o->cand_s_q16, t_us, s, onset_floor(o), 1u,
                                                 o->cfg.jump_ratio_q8),
                            ONSET_OK, ev);
            o->conf_t_us = t_us;
            o->conf_s_q16 = s;
            o->state = ONSET_ST_CONFIRMED;
            return false;
        }
        /* A lone outlier (specular flash, tracking glitch): back to watching. */
        o->state = ONSET_ST_STILL;
        o->still_t_us = t_us;
        return false;
    }

    /* CONFIRMED: the slope comes from B and C, both past the onset, rather than from A,
     * which may be a noise excursion just before it; the line is then extrapolated back
     * to the still level. */
    if (s > o->conf_s_q16)
        return emit(o, extrapolate_onset(o->conf_t_us, o->conf_s_q16, t_us, s, onset_floor(o), 2u, o->cfg.jump_ratio_q8), ONSET_OK, ev);
    return finish_early(o, ev);
}

bool onset_observe_px(onset_t *o, uint32_t t_us, int32_t u_q16, int32_t v_q16, bool valid,
                      onset_event_t *ev)
{
    return observe(o, t_us, u_q16, v_q16, valid, ev);
}

bool onset_observe_deg(onset_t *o, uint32_t t_us, int32_t c_q16, bool valid, onset_event_t *ev)
{
    return observe(o, t_us, c_q16, 0, valid, ev);
}
