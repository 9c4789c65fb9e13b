/* Table writer: lays out a common/ps_table.h blob from entry arrays (host tools, demo, tests). */
#ifndef TABLE_WRITE_H
#define TABLE_WRITE_H

#include <stddef.h>
#include <stdint.h>
#include "ps_table.h"

/* Write [header][B entries][f entries][r[n]][w[n]] into buf (cap bytes) and seal it with
 * its CRC. From *hd the caller sets generation, q_unit, f_kind, q_min/q_max, for each
 * grid x0_q16, step_q16 and n, pi.n (transition operators, 0 for none) and
 * layout_version: 1 (pi.n must be 0), 2, 3, or 0 for the default (2 here: table_write
 * writes no threshold map; 3 with table_write_map and a map).
 * Magic, sizes, offsets and crc32 are filled here. pi_r_q16 / pi_w_q16 hold pi.n
 * thresholds (actuator units) and weights, Q16.16; they may be NULL when pi.n = 0.
 * Returns the table size in bytes, or 0 (nothing written) if cap is too small, a count
 * exceeds PST_MAX_ENTRIES or PST_MAX_OPS, the version is unknown, or a v1 table is given
 * operators. Validation of the contents is calib_load()'s job. */
size_t table_write(uint8_t *buf, size_t cap, const pst_header_t *hd, const int32_t *b_q16,
                   const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16);

/* table_write() plus the threshold map of layout v3: *tmap gives its grid (x0_q16, step_q16,
 * n; offset is filled here) and tmap_q16 its n entries u = g(z), Q16.16, written after the
 * operator block. tmap NULL or tmap->n = 0: no map, exactly table_write() (a v2 table for
 * layout_version 0, byte for byte). With a map layout_version must be 0 or 3, and the
 * header is pst_header_v3_t (72 bytes). Returns the size, or 0 as table_write(). */
size_t table_write_map(uint8_t *buf, size_t cap, const pst_header_t *hd, const int32_t *b_q16,
                       const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16,
                       const pst_grid_t *tmap, const int32_t *tmap_q16);

/* table_write_map() plus the travel-domain relaxation of layout v4 (*relax: kappa_q16,
 * lambda_q16, written in the header after the map's grid; no entry block). relax NULL or
 * relax->kappa_q16 = 0: exactly table_write_map() (v2 or v3, byte for byte). With a
 * relaxation layout_version must be 0 or 4; the header is pst_header_v4_t (80 bytes), the map
 * optional (grid n = 0). Returns the size, or 0 as table_write(). */
size_t table_write_relax(uint8_t *buf, size_t cap, const pst_header_t *hd, const int32_t *b_q16,
                         const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16,
                         const pst_grid_t *tmap, const int32_t *tmap_q16, const pst_relax_t *relax);

/* table_write_relax() bound to an instrument: layout v5 (pst_header_v5_t, 104 bytes) with
 * *inst after the v4 fields (map and relaxation optional, as in v4). inst NULL: exactly
 * table_write_relax(). With an instrument layout_version must be 0 or 5. What `playscope
 * tables` writes (inst from pst_instrument_derive, or the instrument's own figures). Returns
 * the size, or 0 as table_write(). */
size_t table_write_inst(uint8_t *buf, size_t cap, const pst_header_t *hd, const int32_t *b_q16,
                        const int32_t *f_q16, const int32_t *pi_r_q16, const int32_t *pi_w_q16,
                        const pst_grid_t *tmap, const int32_t *tmap_q16, const pst_relax_t *relax,
                        const pst_instrument_t *inst);

#endif /* TABLE_WRITE_H */
