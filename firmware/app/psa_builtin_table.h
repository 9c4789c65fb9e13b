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

#endif /* PSA_BUILTIN_TABLE_H */
