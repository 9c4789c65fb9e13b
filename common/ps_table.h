/* Calibration-table binary layout (v1): one header and int32 Q16.16 entry arrays.
 *
 * Little-endian, packed. A table is  [pst_header_t][b entries][f entries]  and is
 * self-describing: each grid gives its own byte offset. The CRC-32 covers all
 * total_size bytes with the crc32 field taken as zero, seeded with the layout version
 * (ps_crc32_update(PST_LAYOUT_VERSION, ...)), so a table of another layout fails its
 * check instead of loading as garbage. f^-1 is not stored: the loader derives it from
 * f, which must be strictly monotone (firmware/core/calib.h).
 * Used by: firmware/core/calib.c (loader), host (writer, through cffi). */
#ifndef PS_TABLE_H
#define PS_TABLE_H

#include <stdint.h>
#include "ps_defs.h"

enum {
    PST_MAGIC = 0x42545350,      /* bytes "PSTB" */
    PST_LAYOUT_VERSION = 1,
    PST_MAX_ENTRIES = 256,       /* per grid; bounds the loader's RAM */
    PST_MIN_ENTRIES = 2,
};

/* Actuator unit of q and B (session.json actuator.unit). */
enum pst_q_unit {
    PST_Q_UNIT_MM = 0,           /* mm of cable */
    PST_Q_UNIT_DEG = 1,          /* deg of commanded angle */
};

/* Which function the f grid holds (paper section II-A). */
enum pst_f_kind {
    PST_F_COARSE = 0,            /* f_coarse: nominal kinematics, eq. 5 */
    PST_F_REMAIN = 1,            /* f_remain: estimated centre line, eq. 9 */
};

/* A uniform grid x_i = x0 + i*step, i = 0..n-1, of int32 Q16.16 entries. */
typedef struct PS_PACKED pst_grid {
    int32_t x0_q16;              /* abscissa of entry 0 (actuator units, Q16.16) */
    int32_t step_q16;            /* spacing; a power of two >= 1 raw unit, so lookups shift, never divide */
    uint16_t n;                  /* entry count, PST_MIN_ENTRIES..PST_MAX_ENTRIES */
    uint16_t offset;             /* byte offset of entry 0 from the start of the table, 4-aligned */
} pst_grid_t;
PS_STATIC_ASSERT(sizeof(pst_grid_t) == 12, "pst_grid_t must be 12 bytes");

typedef struct PS_PACKED pst_header {
    uint32_t magic;              /* PST_MAGIC */
    uint16_t layout_version;     /* PST_LAYOUT_VERSION */
    uint16_t header_size;        /* sizeof(pst_header_t) = 60 */
    uint32_t total_size;         /* bytes, header + all entries */
    uint32_t crc32;              /* see file comment */
    uint32_t generation;         /* +1 per commit; at boot the newest valid slot wins */
    uint8_t q_frac_bits;         /* PS_FRAC_BITS (16); anything else is refused in v1 */
    uint8_t c_frac_bits;         /* PS_FRAC_BITS (16) */
    uint8_t q_unit;              /* enum pst_q_unit */
    uint8_t f_kind;              /* enum pst_f_kind */
    int32_t q_min_q16;           /* actuator travel: the compensator saturates q* to it */
    int32_t q_max_q16;
    pst_grid_t b;                /* B(q): backlash width (actuator units), over q */
    pst_grid_t f;                /* f(q): bending angle (deg), over q; strictly monotone */
    uint32_t reserved;           /* 0 */
} pst_header_t;
PS_STATIC_ASSERT(sizeof(pst_header_t) == 60, "pst_header_t must be 60 bytes");

/* Largest table the v1 layout allows, in bytes. */
enum { PST_MAX_TABLE_SIZE = 60 + 2 * 4 * PST_MAX_ENTRIES };

#endif /* PS_TABLE_H */
