/* Calibration-table binary layout (v5): one header and int32 Q16.16 entry arrays.
 *
 * Little-endian, packed. A v1/v2 table is  [pst_header_t][b entries][f entries][r[n]][w[n]],
 * a v3 table  [pst_header_v3_t][b entries][f entries][r[n]][w[n]][g entries],
 * a v4 table  [pst_header_v4_t][b entries][f entries][r[n]][w[n]][g entries],
 * a v5 table  [pst_header_v5_t][b entries][f entries][r[n]][w[n]][g entries],
 * and is self-describing: each grid and the operator block give their own byte offset.
 * The CRC-32 covers all total_size bytes with the crc32 field taken as zero, seeded with
 * the table's own layout_version (ps_crc32_update(layout_version, ...)), so a table whose
 * version field was altered fails its check instead of loading as garbage, and a v1
 * table keeps its v1 CRC. f^-1 and the inverse operator weights are not stored: the
 * loader derives them (firmware/core/calib.h).
 *
 * Version 2 adds the smooth transition after the play (docs/method.md, "Transition
 * model"): y = sum_i w_i P_{r_i}[z], n <= PST_MAX_OPS classical play operators
 * (Prandtl-Ishlinskii) between the centre z of the play of eq. 3 and f. Version 1 is
 * version 2 with n = 0 (the v1 header's last field `reserved` is the zero pst_pi_t),
 * and still loads, as the pure play of the paper.
 *
 * Version 3 adds the threshold map g (docs/method.md, "B-proportional thresholds"): the
 * operators run on u = g(z) instead of z, g strictly increasing, sampled on its own
 * power-of-two grid over z (pst_header_v3_t.tmap). Its header is pst_header_t followed by
 * that grid (header_size 72); v1 and v2 headers stop after pst_header_t (header_size 60).
 * table_write() writes v3 only for a table with a map, so map-less tables and their CRCs
 * are the v2 ones.
 *
 * Version 4 adds the travel-domain relaxation (docs/method.md, "Travel-domain relaxation"):
 * two header fields (pst_relax_t) after the v3 header (header_size 80), no entry block. The
 * relaxation acts on the transition's output y before f: c = f(R[y]). table_write_relax()
 * writes v4 only for a table with a relaxation (kappa != 0), so every other table and its CRC
 * is the v2 or v3 one.
 *
 * Version 5 binds the table to its instrument (docs/robustness.md, "The board guards its
 * instrument"): pst_instrument_t after the v4 header (header_size 104) names the instrument
 * (an id) and carries the figures a board needs to judge the table against it (the angle
 * range it can reach, the largest play it can have, the largest slope of f and of f^-1);
 * the unit it was calibrated in is the base header's q_unit. The host writes v5 only;
 * calib_load still reads v1..v4 (their own rules), and a board (calib_load_guarded with its
 * pst_limits_t) takes v5 only, for its own instrument and unit, inside its own limits.
 * The rules, one definition for board and host: common/ps_plaus.h.
 * Used by: firmware/core/calib.c (loader), host (writer, through cffi). */
#ifndef PS_TABLE_H
#define PS_TABLE_H

#include <stddef.h>
#include <stdint.h>
#include "ps_defs.h"

enum {
    PST_MAGIC = 0x42545350,      /* bytes "PSTB" */
    PST_LAYOUT_VERSION = 5,      /* highest loaded; the host writes 5 (table_write_inst); table_write(): 4 with a
                                    relaxation, else 3 with a threshold map, else 2; 1 still loads */
    PST_LAYOUT_VERSION_NO_MAP = 2, /* what table_write() writes for a table without a threshold map */
    PST_MAX_ENTRIES = 256,       /* per grid; bounds the loader's RAM */
    PST_MIN_ENTRIES = 2,
    PST_MAX_OPS = 16,            /* play operators of the transition; bounds the per-tick cost */
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

/* The transition's operator block (v2): r[n] then w[n], int32 Q16.16, at byte offset.
 * r: thresholds in actuator units, r[0] = 0 < r[1] < ... < r[n-1] <= q_max - q_min (v3 with a
 * threshold map: thresholds in u = g(z), r[n-1] <= the larger of that and the map's extent).
 * w: weights (dimensionless), w[0] > 0, w[i] >= 0, |sum w - 1| <= 2^-8.
 * n = 0: no transition (pure play, offset 0); n = 1 with w = 1 is the same model. */
typedef struct PS_PACKED pst_pi {
    uint16_t n;                  /* operator count, 0..PST_MAX_OPS */
    uint16_t offset;             /* byte offset of r[0] from the start of the table, 4-aligned; 0 when n = 0 */
} pst_pi_t;
PS_STATIC_ASSERT(sizeof(pst_pi_t) == 4, "pst_pi_t must be 4 bytes");

typedef struct PS_PACKED pst_header {
    uint32_t magic;              /* PST_MAGIC */
    uint16_t layout_version;     /* PST_LAYOUT_VERSION */
    uint16_t header_size;        /* v1, v2: sizeof(pst_header_t) = 60; v3: 72 (pst_header_v3_t); v4: 80 (pst_header_v4_t) */
    uint32_t total_size;         /* bytes, header + all entries */
    uint32_t crc32;              /* see file comment */
    uint32_t generation;         /* +1 per commit; at boot the newest valid slot wins */
    uint8_t q_frac_bits;         /* PS_FRAC_BITS (16); anything else is refused */
    uint8_t c_frac_bits;         /* PS_FRAC_BITS (16) */
    uint8_t q_unit;              /* enum pst_q_unit */
    uint8_t f_kind;              /* enum pst_f_kind */
    int32_t q_min_q16;           /* actuator travel: the compensator saturates q* to it */
    int32_t q_max_q16;
    pst_grid_t b;                /* B(q): backlash width (actuator units), over q */
    pst_grid_t f;                /* f(q): bending angle (deg), over q; strictly monotone */
    pst_pi_t pi;                 /* v2: transition operators; v1: `reserved`, must be all zero */
} pst_header_t;
PS_STATIC_ASSERT(sizeof(pst_header_t) == 60, "pst_header_t must be 60 bytes");
PS_STATIC_ASSERT(offsetof(pst_header_t, pi) == 56, "pi sits where v1 had `reserved`");

/* The v3 header: the v1/v2 header, then the threshold map's grid.
 * tmap: u = g(z) (actuator units, Q16.16) over the play's centre z, strictly increasing;
 * its abscissas must cover B's grid (where z can be) and it is read in place like B and f.
 * n = 0 and offset 0: no map (u = z), as in a v1 or v2 table. */
typedef struct PS_PACKED pst_header_v3 {
    pst_header_t base;           /* base.layout_version = 3, base.header_size = 72 */
    pst_grid_t tmap;             /* the threshold map g */
} pst_header_v3_t;
PS_STATIC_ASSERT(sizeof(pst_header_v3_t) == 72, "pst_header_v3_t must be 72 bytes");

/* The travel-domain relaxation (v4): v = y + kappa (r - y), r relaxing towards y over a
 * travel lambda (firmware/core/relax.h). kappa = 0 and lambda = 0: none (the v3 model). */
typedef struct PS_PACKED pst_relax {
    int32_t kappa_q16;           /* creeping share of the output, Q16.16, 0..PST_RELAX_KAPPA_MAX_Q16 */
    int32_t lambda_q16;          /* travel constant, actuator units Q16.16, >= 1 raw when kappa != 0 */
} pst_relax_t;
PS_STATIC_ASSERT(sizeof(pst_relax_t) == 8, "pst_relax_t must be 8 bytes");

enum {
    PST_RELAX_KAPPA_MAX_Q16 = 58982, /* 0.9: the inverse's gain 1/(1 - kappa) stays <= 10 */
};

/* The v4 header: the v3 header, then the relaxation's fields. */
typedef struct PS_PACKED pst_header_v4 {
    pst_header_v3_t v3;          /* v3.base.layout_version = 4, v3.base.header_size = 80 */
    pst_relax_t relax;
} pst_header_v4_t;
PS_STATIC_ASSERT(sizeof(pst_header_v4_t) == 80, "pst_header_v4_t must be 80 bytes");
PS_STATIC_ASSERT(offsetof(pst_header_v4_t, relax) == 72, "the relaxation follows the v3 header");

/* The instrument a v5 table was calibrated on, and what it can physically do (Q16.16). */
typedef struct PS_PACKED pst_instrument {
    uint32_t id;                 /* instrument id; a board takes only its own (pst_limits_t.instrument_id) */
    int32_t c_min_q16;           /* angle range the instrument can reach, deg: every f entry lies inside */
    int32_t c_max_q16;
    int32_t b_max_q16;           /* largest play it can have, actuator units: every B entry lies below */
    int32_t f_slope_max_q16;     /* largest |df/dq|, deg per actuator unit, over every f segment */
    int32_t f_inv_slope_max_q16; /* largest |dq/dc| (slope of f^-1), actuator units per deg; INT32_MAX: beyond
                                    Q16.16 (f rises a few raw over a unit somewhere), not bounded here */
} pst_instrument_t;
PS_STATIC_ASSERT(sizeof(pst_instrument_t) == 24, "pst_instrument_t must be 24 bytes");

/* The v5 header: the v4 header, then the instrument. */
typedef struct PS_PACKED pst_header_v5 {
    pst_header_v4_t v4;          /* v4.v3.base.layout_version = 5, header_size = 104 */
    pst_instrument_t inst;
} pst_header_v5_t;
PS_STATIC_ASSERT(sizeof(pst_header_v5_t) == 104, "pst_header_v5_t must be 104 bytes");
PS_STATIC_ASSERT(offsetof(pst_header_v5_t, inst) == 80, "the instrument follows the v4 header");

/* A board's own limits (firmware/boards/<board>/psb_config.h), independent of any table: the
 * instrument it drives, the unit of its actuator, the travel and angle it may command and the
 * largest play its instrument can have. No table may widen them. Also the answer of
 * PSP_MSG_BOARD (common/ps_proto.h), so a host checks a table against them before sending it. */
typedef struct PS_PACKED pst_limits {
    uint32_t instrument_id;      /* pst_instrument_t.id a table must carry */
    uint8_t q_unit;              /* enum pst_q_unit a table must be in */
    uint8_t reserved[3];         /* 0 */
    int32_t q_min_q16;           /* a table's travel [q_min, q_max] must lie inside */
    int32_t q_max_q16;
    int32_t c_min_q16;           /* a table's angle range [c_min, c_max] (deg) must lie inside */
    int32_t c_max_q16;
    int32_t b_max_q16;           /* a table's largest play must not exceed it */
} pst_limits_t;
PS_STATIC_ASSERT(sizeof(pst_limits_t) == 28, "pst_limits_t must be 28 bytes");

enum {
    PST_INSTRUMENT_DEFAULT = 1,  /* the id `playscope tables` writes and a board takes unless configured otherwise */
};

/* Physical plausibility (calib_load, CALIB_ERR_TRAVEL .. CALIB_ERR_F_SLOPE): a table passes
 * these from the fields it already has (q range, grids, B and f entries), so a table
 * with a valid CRC but nonsense physics (a play wider than the travel, a bending angle of
 * thousands of degrees, an f that barely moves) is refused by the board and by the host,
 * which runs the same loader. Values in Q16.16 of the table's own units (q: mm or deg of
 * the actuator, f: deg of bending).
 *  - travel q_max - q_min >= PST_PLAUS_TRAVEL_MIN_Q16 (1/16 unit): a travel of a few raw
 *    units is a damaged field, not an instrument;
 *  - B(q) <= q_max - q_min on every entry: a play wider than the travel is never taken up,
 *    the tip would not move after a reversal;
 *  - |f(q)| <= PST_PLAUS_C_ABS_MAX_Q16 (360 deg) on every entry: one full turn bounds any
 *    bending angle of a continuum section;
 *  - |f(q_last) - f(q_0)| >= PST_PLAUS_C_SPAN_MIN_Q16 (1 deg) over f's grid: a bending DOF
 *    that moves less than a degree over its whole travel has no f to invert;
 *  - |f(q_{i+1}) - f(q_i)| <= PST_PLAUS_F_SLOPE_MAX x step on every segment (360 deg per
 *    actuator unit): a turn per mm of cable or per degree of motor is no instrument. */
enum {
    PST_PLAUS_TRAVEL_MIN_Q16 = 1 << 12,
    PST_PLAUS_C_ABS_MAX_Q16 = 360 << 16,
    PST_PLAUS_C_SPAN_MIN_Q16 = 1 << 16,
    PST_PLAUS_F_SLOPE_MAX = 360,
};

/* v5: the rules against the instrument block (common/ps_plaus.h, PST_RULE_INST_* and after).
 *  - travel <= PST_PLAUS_TRAVEL_MAX_MM_Q16 (mm) or _DEG_Q16 (deg of motor): a tendon stroke of
 *    more than 200 mm, or a motor of more than 20 turns, is a unit mistake (a session in um
 *    calibrated as mm), not an instrument;
 *  - c_min < c_max within +-PST_PLAUS_C_ABS_MAX_Q16, at most one turn apart, and f spans at least
 *    PST_PLAUS_C_SPAN_MIN_INST_Q16 (5 deg) over its grid: a bending DOF that moves less is no DOF;
 *  - 0 < b_max <= travel / PST_PLAUS_B_TRAVEL_DIV: a play of half the travel leaves no motion;
 *  - 0 < f_slope_max <= PST_PLAUS_F_SLOPE_MAX deg per unit and <= PST_PLAUS_F_GAIN x
 *    (c_max - c_min) / travel: f may be at most 16 times steeper than its mean over the
 *    instrument's range (a step of f inside one grid segment is no bending);
 *  - 0 < f_inv_slope_max <= PST_PLAUS_F_INV_GAIN x travel / (c_max - c_min): a bound on the
 *    field itself, wide (real f_remain flatten to 1/500 of their mean slope and less near
 *    straight; how flat f may be is the precision ceiling's business, CALIB_ERR_PRECISION);
 *  - every B entry <= b_max, every f entry in [c_min, c_max], every f segment's slope within
 *    [1 / f_inv_slope_max, f_slope_max]. */
enum {
    PST_PLAUS_TRAVEL_MAX_MM_Q16 = 200 << 16,
    PST_PLAUS_TRAVEL_MAX_DEG_Q16 = 7200 << 16,
    PST_PLAUS_C_SPAN_MIN_INST_Q16 = 5 << 16,
    PST_PLAUS_B_TRAVEL_DIV = 2,
    PST_PLAUS_F_GAIN = 16,
    PST_PLAUS_F_INV_GAIN = 65536,
};

/* Largest table the layout allows, in bytes: a v5 header, three full grids and a full
 * operator block. */
enum { PST_MAX_TABLE_SIZE = 104 + 3 * 4 * PST_MAX_ENTRIES + 2 * 4 * PST_MAX_OPS };

#endif /* PS_TABLE_H */
