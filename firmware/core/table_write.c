/* Table writer: the one place that lays out and seals a calibration table. */
#include "table_write.h"

#include <string.h>
#include "calib.h"
#include "ps_fixed.h"

size_t table_write(uint8_t *buf, size_t cap, const pst_header_t *hd_in, const int32_t *b_q16,
                   const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16)
{
    return table_write_map(buf, cap, hd_in, b_q16, f_q16, pi_r_q16, pi_w_q16, NULL, NULL);
}

size_t table_write_map(uint8_t *buf, size_t cap, const pst_header_t *hd_in, const int32_t *b_q16,
                       const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16,
                       const pst_grid_t *tmap, const int32_t *tmap_q16)
{
    return table_write_relax(buf, cap, hd_in, b_q16, f_q16, pi_r_q16, pi_w_q16, tmap, tmap_q16, NULL);
}

size_t table_write_relax(uint8_t *buf, size_t cap, const pst_header_t *hd_in, const int32_t *b_q16,
                         const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16,
                         const pst_grid_t *tmap, const int32_t *tmap_q16, const pst_relax_t *relax)
{
    return table_write_inst(buf, cap, hd_in, b_q16, f_q16, pi_r_q16, pi_w_q16, tmap, tmap_q16, relax, NULL);
}

size_t table_write_inst(uint8_t *buf, size_t cap, const pst_header_t *hd_in, const int32_t *b_q16,
                        const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16,
                        const pst_grid_t *tmap, const int32_t *tmap_q16, const pst_relax_t *relax,
                        const pst_instrument_t *inst)
{
    pst_header_v5_t h5;
    memset(&h5, 0, sizeof h5);
    pst_header_v4_t h4;
    memset(&h4, 0, sizeof h4);
    h4.v3.base = *hd_in;
    pst_header_t *hd = &h4.v3.base;
    const int has_map = tmap != NULL && tmap->n != 0;
    const int has_relax = relax != NULL && relax->kappa_q16 != 0;
    uint16_t version = hd->layout_version;
    if (version == 0)
        version = inst ? 5u : has_relax ? 4u : has_map ? 3u : (uint16_t)PST_LAYOUT_VERSION_NO_MAP;
    const uint16_t n_ops = hd->pi.n;
    if (hd->b.n > PST_MAX_ENTRIES || hd->f.n > PST_MAX_ENTRIES || n_ops > PST_MAX_OPS ||
        version > PST_LAYOUT_VERSION || (version == 1 && n_ops != 0) ||
        (n_ops != 0 && (pi_r_q16 == NULL || pi_w_q16 == NULL)) ||
        (has_map && (version < 3 || tmap->n > PST_MAX_ENTRIES || tmap_q16 == NULL)) ||
        (has_relax && version < 4) || ((inst != NULL) != (version == 5)))
        return 0;
    const size_t hsize = version >= 5   ? sizeof(pst_header_v5_t)
                         : version == 4 ? sizeof(pst_header_v4_t)
                         : version == 3 ? sizeof(pst_header_v3_t) : sizeof(pst_header_t);
    const uint16_t n_map = has_map ? tmap->n : 0;
    size_t total = hsize + 4u * hd->b.n + 4u * hd->f.n + 8u * n_ops + 4u * n_map;
    if (total > cap)
        return 0;
    hd->magic = PST_MAGIC;
    hd->layout_version = version;
    hd->header_size = (uint16_t)hsize;
    hd->total_size = (uint32_t)total;
    hd->q_frac_bits = PS_FRAC_BITS;
    hd->c_frac_bits = PS_FRAC_BITS;
    hd->b.offset = (uint16_t)hsize;
    hd->f.offset = (uint16_t)(hsize + 4u * hd->b.n);
    const uint32_t after_f = (uint32_t)hd->f.offset + 4u * hd->f.n;
    hd->pi.offset = n_ops ? (uint16_t)after_f : 0;
    if (has_map) {
        h4.v3.tmap = *tmap;
        h4.v3.tmap.offset = (uint16_t)(after_f + 8u * n_ops);
    }
    if (has_relax)
        h4.relax = *relax;
    hd->crc32 = 0;
    h5.v4 = h4;
    if (inst != NULL)
        h5.inst = *inst;
    memcpy(buf, &h5, hsize);
    memcpy(buf + hd->b.offset, b_q16, 4u * hd->b.n); /* little-endian targets only, as the layout */
    memcpy(buf + hd->f.offset, f_q16, 4u * hd->f.n);
    if (n_ops) {
        memcpy(buf + hd->pi.offset, pi_r_q16, 4u * n_ops);
        memcpy(buf + hd->pi.offset + 4u * n_ops, pi_w_q16, 4u * n_ops);
    }
    if (has_map)
        memcpy(buf + h4.v3.tmap.offset, tmap_q16, 4u * n_map);
    hd->crc32 = calib_table_crc(buf, (uint32_t)total);
    memcpy(buf + offsetof(pst_header_t, crc32), &hd->crc32, sizeof hd->crc32);
    return total;
}
