/* Physical plausibility of a calibration table: the one rule set of board and host (ps_plaus.h). */
#include "ps_plaus.h"

#include <stddef.h>

/* Out of line: one call per rule instead of the report stores at each (-Os inlined them all). */
__attribute__((noinline)) static pst_rule_t broke(pst_plaus_report_t *rep, pst_rule_t rule, int32_t index,
                                                  int64_t value, int64_t limit)
{
    if (rep != NULL) {
        rep->rule = (int32_t)rule;
        rep->index = index;
        rep->value = value;
        rep->limit = limit;
    }
    return rule;
}

static int64_t abs64(int64_t x)
{
    return x < 0 ? -x : x;
}

static int32_t sat32(int64_t x)
{
    return x > INT32_MAX ? INT32_MAX : x < INT32_MIN ? INT32_MIN : (int32_t)x;
}

/* The board's own limits that do not need the entries: unit, instrument, layout. */
static pst_rule_t check_binding(const pst_header_t *hd, const pst_instrument_t *inst, const pst_limits_t *board,
                                pst_plaus_report_t *rep)
{
    if (inst == NULL)
        return broke(rep, PST_RULE_UNBOUND, -1, hd->layout_version, 5);
    if (inst->id != board->instrument_id)
        return broke(rep, PST_RULE_BOARD_INSTRUMENT, -1, inst->id, board->instrument_id);
    if (hd->q_unit != board->q_unit)
        return broke(rep, PST_RULE_BOARD_UNIT, -1, hd->q_unit, board->q_unit);
    return PST_RULE_OK;
}

/* The rules of every layout: against the table's own travel. */
static pst_rule_t check_travel(const pst_header_t *hd, const pst_instrument_t *inst, const int32_t *b,
                               const int32_t *f, pst_plaus_report_t *rep)
{
    const int64_t travel = (int64_t)hd->q_max_q16 - hd->q_min_q16;
    if (travel < PST_PLAUS_TRAVEL_MIN_Q16)
        return broke(rep, PST_RULE_TRAVEL, -1, travel, PST_PLAUS_TRAVEL_MIN_Q16);
    for (uint16_t i = 0; i < hd->b.n; i++)
        if (b[i] > travel)
            return broke(rep, PST_RULE_B_TRAVEL, i, b[i], travel);
    for (uint16_t i = 0; i < hd->f.n; i++)
        if (abs64(f[i]) > PST_PLAUS_C_ABS_MAX_Q16)
            return broke(rep, PST_RULE_C_RANGE, i, f[i], f[i] < 0 ? -PST_PLAUS_C_ABS_MAX_Q16 : PST_PLAUS_C_ABS_MAX_Q16);
    const int64_t span = abs64((int64_t)f[hd->f.n - 1] - f[0]);
    const int64_t span_min = inst != NULL ? PST_PLAUS_C_SPAN_MIN_INST_Q16 : PST_PLAUS_C_SPAN_MIN_Q16;
    if (span < span_min)
        return broke(rep, PST_RULE_C_SPAN, -1, span, span_min);
    const int64_t step = hd->f.step_q16;
    for (uint16_t i = 0; i + 1 < hd->f.n; i++) {
        int64_t d = abs64((int64_t)f[i + 1] - f[i]);
        if (d > (int64_t)PST_PLAUS_F_SLOPE_MAX * step)
            return broke(rep, PST_RULE_F_SLOPE, i, (d << 16) / step, (int64_t)PST_PLAUS_F_SLOPE_MAX << 16);
    }
    return PST_RULE_OK;
}

/* The largest |df/dq| f may have for this travel and angle range (Q16.16 deg per unit). */
static int64_t f_slope_limit(int64_t travel, const pst_instrument_t *inst)
{
    int64_t c_span = (int64_t)inst->c_max_q16 - inst->c_min_q16;
    int64_t lim = travel > 0 ? ((int64_t)PST_PLAUS_F_GAIN * c_span << 16) / travel : 0;
    return lim < ((int64_t)PST_PLAUS_F_SLOPE_MAX << 16) ? lim : (int64_t)PST_PLAUS_F_SLOPE_MAX << 16;
}

/* The largest |dq/dc| f^-1 may have for this travel and angle range (Q16.16 units per deg). */
static int64_t f_inv_slope_limit(int64_t travel, const pst_instrument_t *inst)
{
    int64_t c_span = (int64_t)inst->c_max_q16 - inst->c_min_q16;
    if (c_span <= 0)
        return 0;
    int64_t mean = (travel << 16) / c_span; /* travel < 2^33: below 2^49 */
    return mean > INT32_MAX / PST_PLAUS_F_INV_GAIN ? INT32_MAX : mean * PST_PLAUS_F_INV_GAIN;
}

/* v5: the instrument block's own fields, then the entries against them. */
static pst_rule_t check_instrument(const pst_header_t *hd, const pst_instrument_t *inst, const int32_t *b,
                                   const int32_t *f, pst_plaus_report_t *rep)
{
    const int64_t travel = (int64_t)hd->q_max_q16 - hd->q_min_q16;
    const int64_t travel_max = hd->q_unit == PST_Q_UNIT_DEG ? PST_PLAUS_TRAVEL_MAX_DEG_Q16 : PST_PLAUS_TRAVEL_MAX_MM_Q16;
    if (travel > travel_max)
        return broke(rep, PST_RULE_TRAVEL_UNIT, -1, travel, travel_max);
    if (inst->c_min_q16 >= inst->c_max_q16)
        return broke(rep, PST_RULE_INST_C_RANGE, -1, inst->c_min_q16, inst->c_max_q16);
    if (inst->c_min_q16 < -PST_PLAUS_C_ABS_MAX_Q16)
        return broke(rep, PST_RULE_INST_C_RANGE, -1, inst->c_min_q16, -PST_PLAUS_C_ABS_MAX_Q16);
    if (inst->c_max_q16 > PST_PLAUS_C_ABS_MAX_Q16)
        return broke(rep, PST_RULE_INST_C_RANGE, -1, inst->c_max_q16, PST_PLAUS_C_ABS_MAX_Q16);
    if ((int64_t)inst->c_max_q16 - inst->c_min_q16 > PST_PLAUS_C_ABS_MAX_Q16)
        return broke(rep, PST_RULE_INST_C_RANGE, -1, (int64_t)inst->c_max_q16 - inst->c_min_q16, PST_PLAUS_C_ABS_MAX_Q16);
    const int64_t b_lim = travel / PST_PLAUS_B_TRAVEL_DIV;
    if (inst->b_max_q16 <= 0 || inst->b_max_q16 > b_lim)
        return broke(rep, PST_RULE_INST_B_MAX, -1, inst->b_max_q16, b_lim);
    const int64_t s_lim = f_slope_limit(travel, inst);
    if (inst->f_slope_max_q16 <= 0 || inst->f_slope_max_q16 > s_lim)
        return broke(rep, PST_RULE_INST_F_SLOPE, -1, inst->f_slope_max_q16, s_lim);
    /* INT32_MAX: f^-1 steeper somewhere than Q16.16 holds (a segment rising by a few raw over a
     * whole unit): no bound on it here; the precision ceiling judges so flat an f (calib_load). */
    const bool inv_unbounded = inst->f_inv_slope_max_q16 == INT32_MAX;
    const int64_t i_lim = f_inv_slope_limit(travel, inst);
    if (inst->f_inv_slope_max_q16 <= 0 || (!inv_unbounded && inst->f_inv_slope_max_q16 > i_lim))
        return broke(rep, PST_RULE_INST_F_INV_SLOPE, -1, inst->f_inv_slope_max_q16, i_lim);
    for (uint16_t i = 0; i < hd->b.n; i++)
        if (b[i] > inst->b_max_q16)
            return broke(rep, PST_RULE_B_INST, i, b[i], inst->b_max_q16);
    for (uint16_t i = 0; i < hd->f.n; i++) {
        if (f[i] < inst->c_min_q16)
            return broke(rep, PST_RULE_C_INST, i, f[i], inst->c_min_q16);
        if (f[i] > inst->c_max_q16)
            return broke(rep, PST_RULE_C_INST, i, f[i], inst->c_max_q16);
    }
    const int64_t step = hd->f.step_q16;
    for (uint16_t i = 0; i + 1 < hd->f.n; i++) {
        int64_t d = abs64((int64_t)f[i + 1] - f[i]);
        /* |d| / step > f_slope_max, in Q16.16: d 2^16 > f_slope_max step (below 2^56). */
        if ((d << 16) > (int64_t)inst->f_slope_max_q16 * step)
            return broke(rep, PST_RULE_F_SLOPE_INST, i, (d << 16) / step, inst->f_slope_max_q16);
        /* step / |d| > f_inv_slope_max: step 2^16 > f_inv_slope_max |d| (below 2^63). */
        if (!inv_unbounded && (step << 16) > (int64_t)inst->f_inv_slope_max_q16 * d)
            return broke(rep, PST_RULE_F_INV_SLOPE_INST, i, d ? (step << 16) / d : INT64_MAX, inst->f_inv_slope_max_q16);
    }
    return PST_RULE_OK;
}

/* A board's travel, angle and play limits against the table's. */
static pst_rule_t check_board_limits(const pst_header_t *hd, const pst_instrument_t *inst, const pst_limits_t *board,
                                     pst_plaus_report_t *rep)
{
    if (hd->q_min_q16 < board->q_min_q16)
        return broke(rep, PST_RULE_BOARD_TRAVEL, -1, hd->q_min_q16, board->q_min_q16);
    if (hd->q_max_q16 > board->q_max_q16)
        return broke(rep, PST_RULE_BOARD_TRAVEL, -1, hd->q_max_q16, board->q_max_q16);
    if (inst->c_min_q16 < board->c_min_q16)
        return broke(rep, PST_RULE_BOARD_ANGLE, -1, inst->c_min_q16, board->c_min_q16);
    if (inst->c_max_q16 > board->c_max_q16)
        return broke(rep, PST_RULE_BOARD_ANGLE, -1, inst->c_max_q16, board->c_max_q16);
    if (inst->b_max_q16 > board->b_max_q16)
        return broke(rep, PST_RULE_BOARD_B, -1, inst->b_max_q16, board->b_max_q16);
    return PST_RULE_OK;
}

pst_rule_t pst_plaus_check(const pst_header_t *hd, const pst_instrument_t *inst, const int32_t *b_q16,
                           const int32_t *f_q16, const pst_limits_t *board, pst_plaus_report_t *rep)
{
    pst_rule_t r = PST_RULE_OK;
    if (board != NULL && (r = check_binding(hd, inst, board, rep)) != PST_RULE_OK)
        return r;
    if ((r = check_travel(hd, inst, b_q16, f_q16, rep)) != PST_RULE_OK)
        return r;
    if (inst != NULL && (r = check_instrument(hd, inst, b_q16, f_q16, rep)) != PST_RULE_OK)
        return r;
    if (board != NULL && (r = check_board_limits(hd, inst, board, rep)) != PST_RULE_OK)
        return r;
    return broke(rep, PST_RULE_OK, -1, 0, 0);
}

void pst_instrument_derive(const pst_header_t *hd, const int32_t *b_q16, const int32_t *f_q16, uint32_t id,
                           pst_instrument_t *out)
{
    const int64_t travel = (int64_t)hd->q_max_q16 - hd->q_min_q16;
    int64_t f_lo = f_q16[0], f_hi = f_q16[0], b_hi = 0, d_hi = 0, d_lo = INT64_MAX;
    for (uint16_t i = 0; i < hd->f.n; i++) {
        f_lo = f_q16[i] < f_lo ? f_q16[i] : f_lo;
        f_hi = f_q16[i] > f_hi ? f_q16[i] : f_hi;
        if (i + 1 < hd->f.n) {
            int64_t d = abs64((int64_t)f_q16[i + 1] - f_q16[i]);
            d_hi = d > d_hi ? d : d_hi;
            d_lo = d < d_lo ? d : d_lo;
        }
    }
    for (uint16_t i = 0; i < hd->b.n; i++)
        b_hi = b_q16[i] > b_hi ? b_q16[i] : b_hi;
    /* The margin keeps the range within one turn when f's span is (a table whose f spans more
     * is refused for its own entries). */
    int64_t m = (f_hi - f_lo) / 16, room = (PST_PLAUS_C_ABS_MAX_Q16 - (f_hi - f_lo)) / 2;
    m = m < room ? m : (room > 0 ? room : 0);
    int64_t c_lo = f_lo - m, c_hi = f_hi + m;
    c_lo = c_lo < -PST_PLAUS_C_ABS_MAX_Q16 && f_lo >= -PST_PLAUS_C_ABS_MAX_Q16 ? -PST_PLAUS_C_ABS_MAX_Q16 : c_lo;
    c_hi = c_hi > PST_PLAUS_C_ABS_MAX_Q16 && f_hi <= PST_PLAUS_C_ABS_MAX_Q16 ? PST_PLAUS_C_ABS_MAX_Q16 : c_hi;
    /* Twice the largest, within the rule's limit but never below what the entries have. */
    int64_t b_max = 2 * b_hi, b_lim = travel / PST_PLAUS_B_TRAVEL_DIV;
    b_max = b_max > b_lim ? (b_hi > b_lim ? b_hi : b_lim) : b_max;
    const int64_t step = hd->f.step_q16 > 0 ? hd->f.step_q16 : 1;
    int64_t s_act = (d_hi << 16) / step;
    if ((s_act * step) < (d_hi << 16))
        s_act++; /* rounded up: the largest segment passes its own figure */
    int64_t i_act = d_lo > 0 && d_lo != INT64_MAX ? ((step << 16) + d_lo - 1) / d_lo : INT32_MAX;
    out->id = id;
    out->c_min_q16 = sat32(c_lo);
    out->c_max_q16 = sat32(c_hi);
    out->b_max_q16 = sat32(b_max > 0 ? b_max : 1);
    int64_t s_lim = f_slope_limit(travel, out);
    int64_t s_max = 2 * s_act > s_lim ? (s_act > s_lim ? s_act : s_lim) : 2 * s_act;
    out->f_slope_max_q16 = sat32(s_max > 0 ? s_max : 1);
    int64_t i_lim = f_inv_slope_limit(travel, out);
    int64_t i_max = 2 * i_act > i_lim ? (i_act > i_lim ? i_act : i_lim) : 2 * i_act;
    if (i_act >= INT32_MAX)
        i_max = INT32_MAX; /* beyond Q16.16: the unbounded mark, not a bound the entries break */
    out->f_inv_slope_max_q16 = sat32(i_max > 0 ? i_max : 1);
}

bool pst_generation_ok(bool have_table, uint32_t active_generation, uint32_t generation)
{
    uint32_t active = have_table ? active_generation : 0u;
    return generation > active && generation - active <= PST_GENERATION_STEP_MAX;
}

const char *pst_rule_str(pst_rule_t rule)
{
    switch (rule) {
    case PST_RULE_OK: return "ok";
    case PST_RULE_TRAVEL: return "actuator travel q_max - q_min below 1/16 unit (a damaged q range)";
    case PST_RULE_B_TRAVEL: return "backlash width B wider than the actuator travel q_max - q_min";
    case PST_RULE_C_RANGE: return "bending angle f beyond +-360 deg";
    case PST_RULE_C_SPAN: return "bending angle f spans too little over its grid (1 deg; 5 deg for an instrument-bound table)";
    case PST_RULE_F_SLOPE: return "bending angle f steeper than 360 deg per actuator unit";
    case PST_RULE_TRAVEL_UNIT: return "travel beyond any instrument in its unit (200 mm, 7200 deg): a unit mistake";
    case PST_RULE_INST_C_RANGE: return "instrument angle range empty, beyond +-360 deg or wider than one turn";
    case PST_RULE_INST_B_MAX: return "instrument's largest play not within (0, travel / 2]";
    case PST_RULE_INST_F_SLOPE: return "instrument's largest slope of f not within (0, min(360 deg per unit, 16 x angle range / travel)]";
    case PST_RULE_INST_F_INV_SLOPE: return "instrument's largest slope of f^-1 not within (0, 65536 x travel / angle range]";
    case PST_RULE_B_INST: return "backlash width B above the instrument's largest play";
    case PST_RULE_C_INST: return "bending angle f outside the instrument's angle range";
    case PST_RULE_F_SLOPE_INST: return "f steeper than the instrument's largest slope";
    case PST_RULE_F_INV_SLOPE_INST: return "f flatter than the instrument allows (f^-1 steeper than its largest slope)";
    case PST_RULE_UNBOUND: return "table names no instrument (layout below 5)";
    case PST_RULE_BOARD_INSTRUMENT: return "table calibrated for another instrument than the board's";
    case PST_RULE_BOARD_UNIT: return "table's actuator unit is not the board's";
    case PST_RULE_BOARD_TRAVEL: return "table's travel beyond the board's own travel limits";
    case PST_RULE_BOARD_ANGLE: return "table's angle range beyond the board's own angle limits";
    case PST_RULE_BOARD_B: return "table's largest play above the board's own limit";
    case PST_RULE_COUNT: break;
    }
    return "unknown";
}
