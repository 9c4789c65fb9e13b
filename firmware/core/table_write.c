/* Table writer: the one place that lays out and seals a calibration table. */
#include "table_write.h"

#include <string.h>
#include "calib.h"
#include "ps_fixed.h"

size_t table_write(uint8_t *buf, size_t cap, const pst_header_t *hd_in, const int32_t *b_q16,
                   const int32_t *f_q16)
{
    pst_header_t hd = *hd_in;
    if (hd.b.n > PST_MAX_ENTRIES || hd.f.n > PST_MAX_ENTRIES)
        return 0;
    size_t total = sizeof hd + 4u * hd.b.n + 4u * hd.f.n;
    if (total > cap)
        return 0;
    hd.magic = PST_MAGIC;
    hd.layout_version = PST_LAYOUT_VERSION;
    hd.header_size = sizeof hd;
    hd.total_size = (uint32_t)total;
    hd.q_frac_bits = PS_FRAC_BITS;
    hd.c_frac_bits = PS_FRAC_BITS;
    hd.reserved = 0;
    hd.b.offset = sizeof hd;
    hd.f.offset = (uint16_t)(sizeof hd + 4u * hd.b.n);
    hd.crc32 = 0;
    memcpy(buf, &hd, sizeof hd);
    memcpy(buf + hd.b.offset, b_q16, 4u * hd.b.n); /* little-endian targets only, as the layout */
    memcpy(buf + hd.f.offset, f_q16, 4u * hd.f.n);
    hd.crc32 = calib_table_crc(buf, (uint32_t)total);
    memcpy(buf + offsetof(pst_header_t, crc32), &hd.crc32, sizeof hd.crc32);
    return total;
}
