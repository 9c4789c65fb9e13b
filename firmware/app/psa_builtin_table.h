/* The built-in table for images that run without a host (the USART image playscope-fw, benches). */
#ifndef PSA_BUILTIN_TABLE_H
#define PSA_BUILTIN_TABLE_H

#include <stddef.h>
#include <stdint.h>

/* Lay out the built-in table in buf (4-aligned, cap >= PST_MAX_TABLE_SIZE): 33 grid
 * points over q = -16..16 mm, B(q) = 1.5 mm + 0.02 q, f(q) = 3 deg/mm q + 0.04 deg/mm^2 q^2
 * (f' >= 1.7 deg/mm on the grid: strictly increasing). Returns its size in bytes, 0 if cap
 * is too small. Generation 1, PST_F_COARSE. Boot time (table_write divides). */
size_t psa_builtin_table(uint8_t *buf, size_t cap);

/* The same grids with f_kind (enum pst_f_kind) and n_ops transition operators (thresholds
 * r_q16, weights w_q16, Q16.16; NULL when n_ops = 0), e.g. the transition bench's table. */
size_t psa_builtin_table_ops(uint8_t *buf, size_t cap, uint8_t f_kind, uint16_t n_ops, const int32_t *r_q16,
                             const int32_t *w_q16);

#endif /* PSA_BUILTIN_TABLE_H */
