/* Calibration loader: validation of a table blob, then derivation of f^-1 and the envelopes. */
#include "calib.h"

#include <string.h>
#include "ps_crc32.h"
#include "ps_fixed.h"

uint32_t calib_table_crc(const uint8_t *blob, uint32_t total_size)
{
    static const uint8_t zero[4] = {0, 0, 0, 0};
    const size_t at = offsetof(pst_header_t, crc32);
    uint32_t crc = ps_crc32_update(PST_LAYOUT_VERSION, blob, at);
    crc = ps_crc32_update(crc, zero, sizeof zero);
    return ps_crc32_update(crc, blob + at + 4, total_size - at - 4);
}

/* Check one grid of the header and describe it as a lut over the blob. */
static calib_status_t grid_lut(const uint8_t *blob, const pst_header_t *hd, const pst_grid_t *gr,
                               lut_t *lut)
{
    if (gr->n < PST_MIN_ENTRIES || gr->n > PST_MAX_ENTRIES)
        return CALIB_ERR_GRID;
    if (gr->offset < sizeof(pst_header_t) || (gr->offset & 3u) != 0 ||
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

/* Validate the envelope sample range and monotonicity without writing *out. */
static calib_status_t check_envelope(const lut_t *b, int sign, int32_t *scratch)
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
    return lut_check_inverse(&g, CALIB_DERIVED_MAX) == LUT_OK ? CALIB_OK : CALIB_ERR_B_SLOPE;
}

/* Build z_up (sign +1) or z_down (sign -1) into buf; checked beforehand, cannot fail. */
static void build_envelope(const lut_t *b, int sign, int32_t *scratch, int32_t *buf, lut_t *out,
                           int32_t *err_q16)
{
    envelope_samples(b, sign, scratch);
    lut_t g;
    (void)lut_init(&g, scratch, b->n, b->x0_q16, (int32_t)1 << b->step_log2);
    (void)lut_build_inverse(&g, buf, CALIB_DERIVED_MAX, out, err_q16);
}

calib_status_t calib_load(calib_t *out, const uint8_t *blob, size_t len)
{
    pst_header_t hd;
    if (blob == NULL || len < sizeof hd)
        return CALIB_ERR_SIZE;
    memcpy(&hd, blob, sizeof hd);
    if (hd.magic != PST_MAGIC)
        return CALIB_ERR_MAGIC;
    if (hd.layout_version != PST_LAYOUT_VERSION || hd.header_size != sizeof hd)
        return CALIB_ERR_VERSION;
    if (hd.total_size < sizeof hd || hd.total_size > len || hd.total_size > PST_MAX_TABLE_SIZE)
        return CALIB_ERR_SIZE;
    if (calib_table_crc(blob, hd.total_size) != hd.crc32)
        return CALIB_ERR_CRC;
    if (hd.q_frac_bits != PS_FRAC_BITS || hd.c_frac_bits != PS_FRAC_BITS ||
        hd.q_unit > PST_Q_UNIT_DEG || hd.f_kind > PST_F_REMAIN || hd.reserved != 0)
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
    if (lut_check_inverse(&f, CALIB_DERIVED_MAX) != LUT_OK)
        return CALIB_ERR_F_NOT_MONOTONE;
    /* q* = f^-1(c*) +- B/2 must fit int32 so that comp_step adds in 32 bits. */
    int32_t b_max = 0;
    for (uint16_t i = 0; i < b.n; i++)
        b_max = b.y_q16[i] > b_max ? b.y_q16[i] : b_max;
    if ((int64_t)f.x0_q16 - b_max / 2 < INT32_MIN || (int64_t)f.x_last_q16 + b_max / 2 > INT32_MAX)
        return CALIB_ERR_GRID;
    int32_t scratch[PST_MAX_ENTRIES];
    if ((st = check_envelope(&b, +1, scratch)) != CALIB_OK || (st = check_envelope(&b, -1, scratch)) != CALIB_OK)
        return st;

    /* Everything is checked: from here on nothing can fail, so *out changes only now. */
    int32_t e_up, e_down;
    out->b = b;
    out->f = f;
    (void)lut_build_inverse(&f, out->f_inv_buf, CALIB_DERIVED_MAX, &out->f_inv, &out->f_inv_err_q16);
    build_envelope(&b, +1, scratch, out->z_up_buf, &out->z_up, &e_up);
    build_envelope(&b, -1, scratch, out->z_down_buf, &out->z_down, &e_down);
    out->z_err_q16 = e_up > e_down ? e_up : e_down;
    out->q_min_q16 = hd.q_min_q16;
    out->q_max_q16 = hd.q_max_q16;
    out->f_sign = (int8_t)(f.y_q16[1] > f.y_q16[0] ? 1 : -1);
    out->f_kind = hd.f_kind;
    out->q_unit = hd.q_unit;
    out->generation = hd.generation;
    out->crc32 = hd.crc32;
    return CALIB_OK;
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
    }
    return "unknown";
}
