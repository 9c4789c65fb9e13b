/* Table writer: lays out a common/ps_table.h blob from entry arrays (host tools, demo, tests). */
#ifndef TABLE_WRITE_H
#define TABLE_WRITE_H

#include <stddef.h>
#include <stdint.h>
#include "ps_table.h"

/* Write [header][B entries][f entries] into buf (cap bytes) and seal it with its CRC.
 * From *hd the caller sets generation, q_unit, f_kind, q_min/q_max and, for each grid,
 * x0_q16, step_q16 and n; magic, version, sizes, offsets and crc32 are filled here.
 * Returns the table size in bytes, or 0 if cap is too small or a count exceeds
 * PST_MAX_ENTRIES (nothing is written then). Validation is calib_load()'s job. */
size_t table_write(uint8_t *buf, size_t cap, const pst_header_t *hd, const int32_t *b_q16,
                   const int32_t *f_q16);

#endif /* TABLE_WRITE_H */
