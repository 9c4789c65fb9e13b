/* Calibration loader: validation of a table blob, then derivation of f^-1 and the envelopes. */
#include "calib.h"

#include <string.h>
#include "ps_crc32.h"
#include "ps_fixed.h"

uint32_t calib_table_crc(const uint8_t *blob, uint32_t total_size)
{
    static const uint8_t zero[4] = {0, 0, 0, 0};
    const size_t at = offsetof(pst_header_t, crc32);
    uint16_t version;
    memcpy(&version, blob + offsetof(pst_header_t, layout_version), sizeof version);
    uint32_t crc = ps_crc32_update(version, blob, at);
    crc = ps_crc32_update(crc, zero, sizeof zero);
    return ps_crc32_update(crc, blob + at + 4, total_size - at - 4);
}

/* Check one grid of the header and describe it as a lut over the blob. */
static calib_status_t grid_lut(const uint8_t *blob, const pst_header_t *hd, const pst_grid_t *gr,
                               lut_t *lut)
{
    if (gr->n < PST_MIN_ENTRIES || gr->n > PST_MAX_ENTRIES)
        return CALIB_ERR_GRID;
    if (gr->offset < hd->header_size || (gr->offset & 3u) != 0 ||
        (uint32_t)gr->offset + 4u * gr->n > hd->total_size)
        return CALIB_ERR_GRID;
    const uint8_t *p = blob + gr->offset;
    /* Entries are read in place as int32_t: the blob must be 4-aligned. */
    if (((uintptr_t)p & 3u) != 0)
        return CALIB_ERR_GRID;
    if (lut_init(lut, (const int32_t *)(const void *)p, gr->n, gr->x0_q16, gr->step_q16) != LUT_OK)
        return CALIB_ERR_GRID;
    return CALIB_OK;
}

/* Samples of z + sign * B(z)/2 over B's grid: the push position at which the play is
 * taken up with centre z (eq. 2). floor(B/2) keeps it integer; the slope check below
 * keeps it strictly increasing. */
static void envelope_samples(const lut_t *b, int sign, int32_t *out)
{
    for (uint16_t i = 0; i < b->n; i++) {
        int64_t x = (int64_t)b->x0_q16 + ((int64_t)i << b->step_log2);
        out[i] = (int32_t)(x + sign * (int64_t)(b->y_q16[i] >> 1));
    }
}

/* Validate the envelope sample range and monotonicity without writing *out; *err_q16
 * receives the exact error the reindexing table will have. */
static calib_status_t check_envelope(const lut_t *b, int sign, int32_t *scratch, int32_t *err_q16)
{
    for (uint16_t i = 0; i < b->n; i++) {
        int64_t x = (int64_t)b->x0_q16 + ((int64_t)i << b->step_log2);
        int64_t g = x + sign * (int64_t)(b->y_q16[i] >> 1);
        if (g > INT32_MAX || g < INT32_MIN)
            return CALIB_ERR_GRID;
    }
    envelope_samples(b, sign, scratch);
    lut_t g;
    if (lut_init(&g, scratch, b->n, b->x0_q16, (int32_t)1 << b->step_log2) != LUT_OK)
        return CALIB_ERR_GRID;
    return lut_inverse_error(&g, CALIB_DERIVED_MAX, err_q16) == LUT_OK ? CALIB_OK : CALIB_ERR_B_SLOPE;
}

/* Build z_up (sign +1) or z_down (sign -1) into buf; checked (and its error computed) by
 * check_envelope() beforehand, cannot fail. */
static void build_envelope(const lut_t *b, int sign, int32_t *scratch, int32_t *buf, lut_t *out)
{
    envelope_samples(b, sign, scratch);
    lut_t g;
    (void)lut_init(&g, scratch, b->n, b->x0_q16, (int32_t)1 << b->step_log2);
    (void)lut_build_inverse(&g, buf, CALIB_DERIVED_MAX, out, NULL);
}

/* Does [at, at + len) overlap grid gr's entries? */
static int overlaps(uint32_t at, uint32_t len, const pst_grid_t *gr)
{
    uint32_t g0 = gr->offset, g1 = gr->offset + 4u * gr->n;
    return at < g1 && g0 < at + len;
}

/* The v2 operator block: layout, then shape and inverse (pi_build). Writes only the
 * three outputs, and only on success. span_q16: the largest threshold allowed, the extent
 * of the operators' input (the travel q_max - q_min; with a threshold map, the larger of
 * that and the map's extent, since the thresholds are then in u = g(z)). */
static calib_status_t load_pi(const uint8_t *blob, const pst_header_t *hd, int32_t x_lo, int32_t x_hi,
                              int64_t span_q16, const lut_t *f, pi_params_t *dir, pi_params_t *inv,
                              int32_t *err_q16)
{
    const uint16_t n = hd->pi.n;
    if (n > PST_MAX_OPS)
        return CALIB_ERR_PI_COUNT;
    int32_t r[PST_MAX_OPS], w[PST_MAX_OPS];
    if (n == 0) {
        if (hd->pi.offset != 0)
            return CALIB_ERR_PI_LAYOUT;
    } else {
        const uint32_t at = hd->pi.offset, len = 8u * n;
        if (at < hd->header_size || (at & 3u) != 0 || at + len > hd->total_size ||
            overlaps(at, len, &hd->b) || overlaps(at, len, &hd->f))
            return CALIB_ERR_PI_LAYOUT;
        memcpy(r, blob + at, 4u * n);
        memcpy(w, blob + at + 4u * n, 4u * n);
    }
    /* Inputs: the play's centre z lies on B's grid (z_up / z_down return its abscissas), or
     * with a threshold map u = g(z) within the map's entries [x_lo, x_hi];
     * y* = f^-1(c*) on f's grid. */
    static const calib_status_t map[] = {
        [PI_OK] = CALIB_OK, [PI_ERR_COUNT] = CALIB_ERR_PI_COUNT, [PI_ERR_R0] = CALIB_ERR_PI_R0,
        [PI_ERR_R_ORDER] = CALIB_ERR_PI_R_ORDER, [PI_ERR_R_RANGE] = CALIB_ERR_PI_R_RANGE,
        [PI_ERR_W0] = CALIB_ERR_PI_W0, [PI_ERR_W_NEGATIVE] = CALIB_ERR_PI_W_NEGATIVE,
        [PI_ERR_W_SUM] = CALIB_ERR_PI_W_SUM, [PI_ERR_INVERSE] = CALIB_ERR_PI_INVERSE,
    };
    pi_status_t ps = pi_build(r, w, n, span_q16, x_lo, x_hi,
                              f->x0_q16, f->x_last_q16, dir, inv, err_q16);
    return map[ps];
}

enum { CALIB_TMAP_RANGE = 1 << 30 };

/* The v3 threshold map: layout (like a grid, plus no overlap with the other blocks and
 * coverage of B's grid, where the play's centre z lives), strictly increasing entries,
 * headroom, then the exact error of its inverse table and the inverse's Lipschitz constant
 * max dz/du (Q16.16, rounded up, saturated). Writes *g, *err_q16, *lip_q16 on success only;
 * n = 0 (no map) gives g->n = 0, err 0 and lip 1.0. */
static calib_status_t load_tmap(const uint8_t *blob, const pst_header_t *hd, const pst_grid_t *gr,
                                const lut_t *b, int32_t b_max, lut_t *g_out, int32_t *err_q16,
                                int32_t *lip_q16)
{
    lut_t g;
    memset(&g, 0, sizeof g);
    if (gr->n == 0) {
        if (gr->offset != 0 || gr->x0_q16 != 0 || gr->step_q16 != 0)
            return CALIB_ERR_TMAP_GRID;
        *g_out = g;
        *err_q16 = 0;
        *lip_q16 = 65536;
        return CALIB_OK;
    }
    if (grid_lut(blob, hd, gr, &g) != CALIB_OK)
        return CALIB_ERR_TMAP_GRID;
    const uint32_t at = gr->offset, len = 4u * gr->n;
    if (overlaps(at, len, &hd->b) || overlaps(at, len, &hd->f) ||
        (hd->pi.n != 0 && at < (uint32_t)hd->pi.offset + 8u * hd->pi.n && hd->pi.offset < at + len))
        return CALIB_ERR_TMAP_GRID;
    /* z runs over B's grid (the envelopes' abscissas): g must be defined there. */
    if (g.x0_q16 > b->x0_q16 || g.x_last_q16 < b->x_last_q16)
        return CALIB_ERR_TMAP_GRID;
    int64_t min_du = INT64_MAX;
    for (uint16_t i = 0; i + 1 < g.n; i++) {
        int64_t du = (int64_t)g.y_q16[i + 1] - g.y_q16[i];
        if (du <= 0)
            return CALIB_ERR_TMAP_MONOTONE;
        min_du = du < min_du ? du : min_du;
    }
    /* u = g(z) feeds the operators (their input +- twice the thresholds is checked by
     * pi_build on this range), z* = g^-1(u*) + B/2 must fit int32. */
    if (g.y_q16[0] < -CALIB_TMAP_RANGE || g.y_q16[g.n - 1] > CALIB_TMAP_RANGE ||
        (int64_t)g.x0_q16 - b_max / 2 < INT32_MIN || (int64_t)g.x_last_q16 + b_max / 2 > INT32_MAX)
        return CALIB_ERR_TMAP_RANGE;
    int32_t e;
    if (lut_inverse_error(&g, CALIB_DERIVED_MAX, &e) != LUT_OK)
        return CALIB_ERR_TMAP_GRID;
    /* Exact g^-1 is piecewise linear with slopes step / du: max at the smallest du. */
    int64_t step = (int64_t)1 << g.step_log2;
    int64_t lip = ((step << 16) + min_du - 1) / min_du; /* load time: divide */
    *g_out = g;
    *err_q16 = e;
    *lip_q16 = lip > INT32_MAX ? INT32_MAX : (int32_t)lip;
    return CALIB_OK;
}

PS_STATIC_ASSERT(CALIB_ERR_BOARD_B - CALIB_ERR_TRAVEL == PST_RULE_BOARD_B - PST_RULE_TRAVEL,
                 "one calib_status_t per plausibility rule, in pst_rule_t's order");

calib_status_t calib_status_of_rule(pst_rule_t rule)
{
    if (rule <= PST_RULE_OK || rule >= PST_RULE_COUNT)
        return CALIB_OK;
    return (calib_status_t)((int)CALIB_ERR_TRAVEL + ((int)rule - (int)PST_RULE_TRAVEL));
}

/* ceil(a * b / 2^sh), a, b >= 0, saturated at INT32_MAX. */
static int32_t mul_shift_up_sat(int64_t a, int64_t b, unsigned sh)
{
    if (a != 0 && b > (INT64_MAX >> 1) / a)
        return INT32_MAX;
    int64_t p = (a * b + (((int64_t)1 << sh) - 1)) >> sh;
    return p > INT32_MAX ? INT32_MAX : (int32_t)p;
}

calib_status_t calib_load(calib_t *out, const uint8_t *blob, size_t len)
{
    return calib_load_guarded(out, blob, len, NULL, NULL);
}

calib_status_t calib_load_guarded(calib_t *out, const uint8_t *blob, size_t len, const pst_limits_t *board,
                                  pst_plaus_report_t *rep)
{
    pst_header_t hd;
    if (rep != NULL)
        *rep = (pst_plaus_report_t){.rule = PST_RULE_OK, .index = -1, .value = 0, .limit = 0};
    if (blob == NULL || len < sizeof hd)
        return CALIB_ERR_SIZE;
    memcpy(&hd, blob, sizeof hd);
    if (hd.magic != PST_MAGIC)
        return CALIB_ERR_MAGIC;
    /* v1, v2: the 60-byte header; v3: the 72-byte one (the map's grid after it); v4: 80 bytes
     * (the relaxation's fields after that); v5: 104 (the instrument after that). */
    const size_t hsize = hd.layout_version >= 5   ? sizeof(pst_header_v5_t)
                         : hd.layout_version == 4 ? sizeof(pst_header_v4_t)
                         : hd.layout_version == 3 ? sizeof(pst_header_v3_t) : sizeof hd;
    if (hd.layout_version < 1 || hd.layout_version > PST_LAYOUT_VERSION || hd.header_size != hsize)
        return CALIB_ERR_VERSION;
    if (len < hsize || hd.total_size < hsize || hd.total_size > len || hd.total_size > PST_MAX_TABLE_SIZE)
        return CALIB_ERR_SIZE;
    pst_grid_t tmap_grid;
    memset(&tmap_grid, 0, sizeof tmap_grid);
    if (hd.layout_version >= 3)
        memcpy(&tmap_grid, blob + offsetof(pst_header_v3_t, tmap), sizeof tmap_grid);
    pst_relax_t relax_f = {0, 0};
    if (hd.layout_version >= 4)
        memcpy(&relax_f, blob + offsetof(pst_header_v4_t, relax), sizeof relax_f);
    pst_instrument_t inst;
    if (hd.layout_version >= 5)
        memcpy(&inst, blob + offsetof(pst_header_v5_t, inst), sizeof inst);
    if (calib_table_crc(blob, hd.total_size) != hd.crc32)
        return CALIB_ERR_CRC;
    if (hd.q_frac_bits != PS_FRAC_BITS || hd.c_frac_bits != PS_FRAC_BITS ||
        hd.q_unit > PST_Q_UNIT_DEG || hd.f_kind > PST_F_REMAIN)
        return CALIB_ERR_FORMAT;
    /* v1: the field was `reserved` and must be zero (n = 0 is the pure play). */
    if (hd.layout_version == 1 && (hd.pi.n != 0 || hd.pi.offset != 0))
        return CALIB_ERR_FORMAT;
    if (hd.q_min_q16 >= hd.q_max_q16)
        return CALIB_ERR_Q_RANGE;

    lut_t b, f;
    calib_status_t st = grid_lut(blob, &hd, &hd.b, &b);
    if (st == CALIB_OK)
        st = grid_lut(blob, &hd, &hd.f, &f);
    if (st != CALIB_OK)
        return st;

    const int64_t step = (int64_t)1 << b.step_log2;
    for (uint16_t i = 0; i < b.n; i++) {
        if (b.y_q16[i] < 0)
            return CALIB_ERR_B_NEGATIVE;
        /* |dB/dq| < 2 keeps z +- B(z)/2 strictly increasing, i.e. the envelopes f1, f2
         * of eq. 2 single-valued; the 2 raw units absorb the floor in B/2. */
        if (i + 1 < b.n) {
            int64_t d = (int64_t)b.y_q16[i + 1] - b.y_q16[i];
            if (d > 2 * step - 2 || d < -(2 * step - 2))
                return CALIB_ERR_B_SLOPE;
        }
    }
    int32_t e_f_inv;
    if (lut_inverse_error(&f, CALIB_DERIVED_MAX, &e_f_inv) != LUT_OK)
        return CALIB_ERR_F_NOT_MONOTONE;
    if ((st = calib_status_of_rule(pst_plaus_check(&hd, hd.layout_version >= 5 ? &inst : NULL, b.y_q16, f.y_q16,
                                                    board, rep))) != CALIB_OK)
        return st;
    /* q* = f^-1(c*) +- B/2 must fit int32 so that comp_step adds in 32 bits. */
    int32_t b_max = 0;
    for (uint16_t i = 0; i < b.n; i++)
        b_max = b.y_q16[i] > b_max ? b.y_q16[i] : b_max;
    if ((int64_t)f.x0_q16 - b_max / 2 < INT32_MIN || (int64_t)f.x_last_q16 + b_max / 2 > INT32_MAX)
        return CALIB_ERR_GRID;
    int32_t scratch[PST_MAX_ENTRIES];
    int32_t e_up, e_down;
    if ((st = check_envelope(&b, +1, scratch, &e_up)) != CALIB_OK ||
        (st = check_envelope(&b, -1, scratch, &e_down)) != CALIB_OK)
        return st;
    lut_t g;
    int32_t e_g_inv, lip;
    if ((st = load_tmap(blob, &hd, &tmap_grid, &b, b_max, &g, &e_g_inv, &lip)) != CALIB_OK)
        return st;
    /* The operators' input: z on B's grid, or u = g(z) within the map's entries. */
    const int32_t x_lo = g.n ? g.y_q16[0] : b.x0_q16, x_hi = g.n ? g.y_q16[g.n - 1] : b.x_last_q16;
    pi_params_t pi_dir, pi_inv;
    int32_t pi_err;
    /* Thresholds in u with a map: u's extent can exceed the travel where B is below b_ref. */
    int64_t span = (int64_t)hd.q_max_q16 - hd.q_min_q16;
    if (g.n && (int64_t)x_hi - x_lo > span)
        span = (int64_t)x_hi - x_lo;
    if ((st = load_pi(blob, &hd, x_lo, x_hi, span, &f, &pi_dir, &pi_inv, &pi_err)) != CALIB_OK)
        return st;
    /* The compensator's centre error (docs/firmware.md, "Precision ceiling"): in u,
     * E_u = f_inv_err sum|w'| + pi_inv_err (PI^-1 is sum|w'|-Lipschitz); a map adds
     * L E_u + g^-1's own error, L = max dz/du. */
    int64_t abs_w = 0;
    for (uint8_t i = 0; i < pi_inv.n; i++)
        abs_w += pi_inv.w[i] < 0 ? -(int64_t)pi_inv.w[i] : pi_inv.w[i];
    /* The relaxation (v4) on y before f: the compensator's R^-1 gains 1 + m on y*'s error,
     * plus its own rounding (1 raw); the direct model's R is a convex combination (gain 1). */
    relax_params_t relax;
    if (relax_build(relax_f.kappa_q16, relax_f.lambda_q16, f.x0_q16, f.x_last_q16, &relax) != RELAX_OK)
        return CALIB_ERR_RELAX;
    int64_t e_y = relax.kappa_q16 ? (int64_t)mul_shift_up_sat(e_f_inv, ((int64_t)1 << 24) + relax.m_q24, 24) + 1
                                  : e_f_inv;
    int64_t e_u = pi_inv.n ? (int64_t)mul_shift_up_sat(e_y, abs_w, pi_inv.w_frac) + pi_err : e_y;
    int64_t e_comp = g.n ? (int64_t)mul_shift_up_sat(lip, e_u, 16) + e_g_inv : e_u;
    if (e_comp > INT32_MAX)
        e_comp = INT32_MAX;
    /* Each derived table is held to the ceiling on its own: they enter q* and z one at a
     * time (eqs. 2 and 4/5/9), and the chained bound of docs/firmware.md follows from them
     * (e_comp, reported, not held: as without a map). */
    const int32_t ceiling = calib_precision_ceiling_q16(b_max);
    if (e_f_inv > ceiling || e_up > ceiling || e_down > ceiling || pi_err > ceiling)
        return CALIB_ERR_PRECISION;
    if (g.n) {
        /* With a map the u-side errors reach z* scaled by L, plus g^-1's own: each held as
         * above, so a map never refuses a table for what its map-less twin is allowed. */
        int32_t e_in_u = e_f_inv > pi_err ? e_f_inv : pi_err;
        if (e_g_inv > ceiling || (int64_t)mul_shift_up_sat(lip, e_in_u, 16) + e_g_inv > ceiling)
            return CALIB_ERR_PRECISION;
    }

    /* Everything is checked: from here on nothing can fail, so *out changes only now. */
    out->b = b;
    out->f = f;
    (void)lut_build_inverse(&f, out->f_inv_buf, CALIB_DERIVED_MAX, &out->f_inv, NULL);
    build_envelope(&b, +1, scratch, out->z_up_buf, &out->z_up);
    build_envelope(&b, -1, scratch, out->z_down_buf, &out->z_down);
    out->f_inv_err_q16 = e_f_inv;
    out->z_err_q16 = e_up > e_down ? e_up : e_down;
    out->pi_dir = pi_dir;
    out->pi_inv = pi_inv;
    out->pi_inv_err_q16 = pi_err;
    out->precision_ceiling_q16 = ceiling;
    out->tmap = g;
    memset(&out->tmap_inv, 0, sizeof out->tmap_inv);
    if (g.n)
        (void)lut_build_inverse(&g, out->tmap_inv_buf, CALIB_DERIVED_MAX, &out->tmap_inv, NULL);
    out->tmap_inv_err_q16 = e_g_inv;
    out->tmap_inv_lip_q16 = lip;
    out->comp_err_q16 = (int32_t)e_comp;
    out->relax = relax;
    out->stages = (uint8_t)((pi_inv.n ? CALIB_STAGE_PI : 0) | (g.n ? CALIB_STAGE_TMAP : 0) |
                            (relax.kappa_q16 ? CALIB_STAGE_RELAX : 0));
    out->q_min_q16 = hd.q_min_q16;
    out->q_max_q16 = hd.q_max_q16;
    out->f_sign = (int8_t)(f.y_q16[1] > f.y_q16[0] ? 1 : -1);
    out->f_kind = hd.f_kind;
    out->q_unit = hd.q_unit;
    out->generation = hd.generation;
    out->crc32 = hd.crc32;
    return CALIB_OK;
}

int32_t calib_precision_ceiling_q16(int32_t b_max_q16)
{
    int32_t c = b_max_q16 / CALIB_PRECISION_B_DIV; /* load time only (a constant divide: a shift) */
    return c > CALIB_PRECISION_FLOOR_Q16 ? c : CALIB_PRECISION_FLOOR_Q16;
}

const char *calib_status_str(calib_status_t st)
{
    switch (st) {
    case CALIB_OK: return "ok";
    case CALIB_ERR_SIZE: return "table size wrong or truncated";
    case CALIB_ERR_MAGIC: return "not a playscope table (bad magic)";
    case CALIB_ERR_VERSION: return "unknown table layout version";
    case CALIB_ERR_CRC: return "CRC-32 mismatch (corrupted table)";
    case CALIB_ERR_FORMAT: return "unsupported Q format, unit or f kind";
    case CALIB_ERR_GRID: return "invalid grid (count, step, offset or range)";
    case CALIB_ERR_B_NEGATIVE: return "negative backlash width";
    case CALIB_ERR_B_SLOPE: return "backlash width varies too fast (|dB/dq| >= 2)";
    case CALIB_ERR_F_NOT_MONOTONE: return "f is not strictly monotone";
    case CALIB_ERR_Q_RANGE: return "actuator range empty (q_min >= q_max)";
    case CALIB_ERR_PI_COUNT: return "too many transition operators";
    case CALIB_ERR_PI_LAYOUT: return "transition operator block misplaced (offset or size)";
    case CALIB_ERR_PI_R0: return "first transition threshold is not 0";
    case CALIB_ERR_PI_R_ORDER: return "transition thresholds not strictly increasing";
    case CALIB_ERR_PI_R_RANGE: return "transition threshold beyond the actuator range";
    case CALIB_ERR_PI_W0: return "first transition weight is not positive";
    case CALIB_ERR_PI_W_NEGATIVE: return "negative transition weight";
    case CALIB_ERR_PI_W_SUM: return "transition weights do not sum to 1 (+-2^-8)";
    case CALIB_ERR_PI_INVERSE: return "transition not invertible in Q16.16 (first weight too small)";
    case CALIB_ERR_PRECISION: return "fixed-point error above the precision ceiling (1/16 of the largest play)";
    case CALIB_ERR_TMAP_GRID: return "invalid threshold map grid (count, step, offset, overlap or not covering B's grid)";
    case CALIB_ERR_TMAP_MONOTONE: return "threshold map not strictly increasing";
    case CALIB_ERR_TMAP_RANGE: return "threshold map values or range beyond the fixed-point headroom";
    case CALIB_ERR_RELAX: return "relaxation fields invalid (kappa outside 0..0.9, lambda below 1 raw, or input range)";
    default: break;
    }
    if (st >= CALIB_ERR_TRAVEL && st <= CALIB_ERR_BOARD_B)
        return pst_rule_str((pst_rule_t)((int)PST_RULE_TRAVEL + ((int)st - (int)CALIB_ERR_TRAVEL)));
    return "unknown";
}
