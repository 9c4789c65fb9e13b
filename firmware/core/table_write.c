/* Table writer: the one place that lays out and seals a calibration table. */
#include "table_write.h"

#include <string.h>
#include "calib.h"
#include "ps_fixed.h"

size_t table_write(uint8_t *buf, size_t cap, const pst_header_t *hd_in, const int32_t *b_q16,
                   const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16)
{
    pst_header_t hd = *hd_in;
    const uint16_t version = hd.layout_version == 0 ? (uint16_t)PST_LAYOUT_VERSION : hd.layout_version;
    const uint16_t n_ops = hd.pi.n;
    if (hd.b.n > PST_MAX_ENTRIES || hd.f.n > PST_MAX_ENTRIES || n_ops > PST_MAX_OPS ||
        version > PST_LAYOUT_VERSION || (version == 1 && n_ops != 0) ||
        (n_ops != 0 && (pi_r_q16 == NULL || pi_w_q16 == NULL)))
        return 0;
    size_t total = sizeof hd + 4u * hd.b.n + 4u * hd.f.n + 8u * n_ops;
    if (total > cap)
        return 0;
    hd.magic = PST_MAGIC;
    hd.layout_version = version;
    hd.header_size = sizeof hd;
    hd.total_size = (uint32_t)total;
    hd.q_frac_bits = PS_FRAC_BITS;
    hd.c_frac_bits = PS_FRAC_BITS;
    hd.b.offset = sizeof hd;
    hd.f.offset = (uint16_t)(sizeof hd + 4u * hd.b.n);
    hd.pi.offset = n_ops ? (uint16_t)(hd.f.offset + 4u * hd.f.n) : 0;
    hd.crc32 = 0;
    memcpy(buf, &hd, sizeof hd);
    memcpy(buf + hd.b.offset, b_q16, 4u * hd.b.n); /* little-endian targets only, as the layout */
    memcpy(buf + hd.f.offset, f_q16, 4u * hd.f.n);
    if (n_ops) {
        memcpy(buf + hd.pi.offset, pi_r_q16, 4u * n_ops);
        memcpy(buf + hd.pi.offset + 4u * n_ops, pi_w_q16, 4u * n_ops);
    }
    hd.crc32 = calib_table_crc(buf, (uint32_t)total);
    memcpy(buf + offsetof(pst_header_t, crc32), &hd.crc32, sizeof hd.crc32);
    return total;
}
