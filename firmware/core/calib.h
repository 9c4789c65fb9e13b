/* Calibration loader: validates a common/ps_table.h blob and derives its runtime tables. */
#ifndef CALIB_H
#define CALIB_H

#include <stddef.h>
#include <stdint.h>
#include "lut.h"
#include "pi.h"
#include "relax.h"
#include "ps_plaus.h"
#include "ps_table.h"

#ifndef CALIB_DERIVED_MAX
/* CALIB_DERIVED_MAX: entries of each table the loader derives (f^-1, z_up, z_down). Default 512. */
#define CALIB_DERIVED_MAX 512
#endif

/* Why a table was refused. Every refusal leaves the calib_t it was loaded into untouched. */
typedef enum {
    CALIB_OK = 0,
    CALIB_ERR_SIZE,              /* shorter than a header, or than total_size, or above PST_MAX_TABLE_SIZE */
    CALIB_ERR_MAGIC,             /* not a playscope table */
    CALIB_ERR_VERSION,           /* layout version or header size unknown */
    CALIB_ERR_CRC,               /* CRC-32 mismatch: corrupted or truncated */
    CALIB_ERR_FORMAT,            /* Q formats, unit or f kind not supported */
    CALIB_ERR_GRID,              /* a grid: count, power-of-two step, offset or range invalid */
    CALIB_ERR_B_NEGATIVE,        /* a backlash width below zero */
    CALIB_ERR_B_SLOPE,           /* |B'| >= 2 somewhere: the envelopes f1, f2 would fold back (eq. 2) */
    CALIB_ERR_F_NOT_MONOTONE,    /* f not strictly monotone: f^-1 would not exist */
    CALIB_ERR_Q_RANGE,           /* q_min >= q_max */
    /* v2 operator block (the transition, pst_pi_t); codes of pi_build() in pi.h. */
    CALIB_ERR_PI_COUNT,          /* n > PST_MAX_OPS, or n != 0 in a v1 table */
    CALIB_ERR_PI_LAYOUT,         /* offset misaligned, inside the header or a grid, or r/w beyond total_size; offset != 0 with n = 0 */
    CALIB_ERR_PI_R0,             /* r[0] != 0 */
    CALIB_ERR_PI_R_ORDER,        /* thresholds not strictly increasing */
    CALIB_ERR_PI_R_RANGE,        /* r[n-1] > q_max - q_min (with a map: > max of that and the map's extent in u), or a grid +- twice the thresholds leaves +-2^30 raw */
    CALIB_ERR_PI_W0,             /* w[0] <= 0: no slope right after the play */
    CALIB_ERR_PI_W_NEGATIVE,     /* a weight below zero */
    CALIB_ERR_PI_W_SUM,          /* |sum w - 1| > 2^-8 */
    CALIB_ERR_PI_INVERSE,        /* an inverse weight would overflow Q16.16 (w[0] <= 2^-15), or the inverse leaves +-2^30 */
    CALIB_ERR_PRECISION,         /* a derived table's worst-case fixed-point error exceeds the precision ceiling */
    /* v3 threshold map (pst_header_v3_t.tmap, u = g(z)). */
    CALIB_ERR_TMAP_GRID,         /* map grid: count, power-of-two step, offset, alignment, overlap with another
                                    block, offset != 0 with n = 0, or abscissas not covering B's grid */
    CALIB_ERR_TMAP_MONOTONE,     /* map entries not strictly increasing: g^-1 would not exist */
    CALIB_ERR_TMAP_RANGE,        /* map values beyond +-2^30 raw, or its abscissas +- B_max/2 beyond int32 */
    /* v4 relaxation (pst_header_v4_t.relax). */
    CALIB_ERR_RELAX,             /* kappa outside 0..0.9, lambda < 1 raw with kappa != 0 (or != 0 without),
                                    or f's grid (the relaxation's input range) beyond +-2^30 */
    /* Physical plausibility (ps_table.h, PST_PLAUS_*): one code per rule. */
    CALIB_ERR_TRAVEL,            /* q_max - q_min below PST_PLAUS_TRAVEL_MIN_Q16 */
    CALIB_ERR_B_TRAVEL,          /* a backlash width above the travel q_max - q_min */
    CALIB_ERR_C_RANGE,           /* an f entry beyond +-PST_PLAUS_C_ABS_MAX_Q16 (360 deg) */
    CALIB_ERR_C_SPAN,            /* f moves less than PST_PLAUS_C_SPAN_MIN_Q16 (1 deg) over its grid */
    CALIB_ERR_F_SLOPE,           /* |df/dq| above PST_PLAUS_F_SLOPE_MAX deg per actuator unit on a segment */
    /* v5 instrument block (pst_instrument_t), then a board's own limits (pst_limits_t,
     * calib_load_guarded): CALIB_ERR_TRAVEL - PST_RULE_TRAVEL + rule, one code per pst_rule_t. */
    CALIB_ERR_TRAVEL_UNIT,       /* travel above any instrument in its unit: a unit mistake */
    CALIB_ERR_INST_C_RANGE,      /* instrument angle range empty or beyond +-360 deg */
    CALIB_ERR_INST_B_MAX,        /* instrument's largest play not within (0, travel / 2] */
    CALIB_ERR_INST_F_SLOPE,      /* instrument's largest slope of f not within (0, 360] deg/unit */
    CALIB_ERR_INST_F_INV_SLOPE,  /* instrument's largest slope of f^-1 not within (0, 16 travel / angle range] */
    CALIB_ERR_B_INST,            /* a B entry above the instrument's largest play */
    CALIB_ERR_C_INST,            /* an f entry outside the instrument's angle range */
    CALIB_ERR_F_SLOPE_INST,      /* a segment of f steeper than the instrument's largest slope */
    CALIB_ERR_F_INV_SLOPE_INST,  /* a segment of f flatter than 1 / the instrument's largest slope of f^-1 */
    CALIB_ERR_UNBOUND,           /* board: a table of layout < 5 names no instrument */
    CALIB_ERR_BOARD_INSTRUMENT,  /* board: calibrated for another instrument */
    CALIB_ERR_BOARD_UNIT,        /* board: another actuator unit */
    CALIB_ERR_BOARD_TRAVEL,      /* board: travel beyond the board's own limits */
    CALIB_ERR_BOARD_ANGLE,       /* board: angle range beyond the board's own limits */
    CALIB_ERR_BOARD_B,           /* board: largest play above the board's own limit */
} calib_status_t;

/* Precision ceiling (docs/firmware.md, "Precision ceiling"): a table's own arithmetic may add
 * at most 1/CALIB_PRECISION_B_DIV of its largest play width B_max to q (never less than
 * CALIB_PRECISION_FLOOR_Q16 raw, the rounding floor of a few chained lookups), because the
 * compensator exists to remove B: a table whose rounding and resampling errors approach the
 * play it corrects does more harm than good. The loader holds its exactly computed errors
 * (f^-1, z_up/z_down, transition inverse) to it; the host's `tables` holds its measured
 * error against the float model to the same figure. */
enum { CALIB_PRECISION_B_DIV = 16, CALIB_PRECISION_FLOOR_Q16 = 16 };

/* The ceiling for a table whose largest B entry is b_max_q16 (raw): max(b_max / 16, 16). */
int32_t calib_precision_ceiling_q16(int32_t b_max_q16);

/* calib_t.stages: which optional stages a table carries (derived by calib_load). */
enum {
    CALIB_STAGE_PI = 1,          /* transition operators (pi_dir.n / pi_inv.n != 0) */
    CALIB_STAGE_TMAP = 2,        /* threshold map (tmap.n != 0) */
    CALIB_STAGE_RELAX = 4,       /* travel-domain relaxation (relax.kappa_q16 != 0) */
};

/* Everything the direct model and the compensator read, derived once per load. */
typedef struct {
    lut_t b;                     /* B(q): backlash width, actuator units (Q16) over q */
    lut_t f;                     /* f(q): deg over q (f_coarse or f_remain) */
    lut_t f_inv;                 /* f^-1(c): q over deg */
    lut_t z_up;                  /* centre z with z + B(z)/2 = q: the play taken up going up (eq. 2 reindexing) */
    lut_t z_down;                /* centre z with z - B(z)/2 = q: going down */
    int32_t q_min_q16;           /* actuator travel */
    int32_t q_max_q16;
    int8_t f_sign;               /* +1: f increasing, -1: decreasing (selects eq. 5 or eq. 9 signs) */
    uint8_t f_kind;              /* enum pst_f_kind */
    uint8_t q_unit;              /* enum pst_q_unit */
    uint32_t generation;         /* from the header */
    uint32_t crc32;              /* from the header */
    int32_t f_inv_err_q16;       /* worst-case |f^-1 table - exact inverse of the f table| (raw) */
    int32_t z_err_q16;           /* same for z_up / z_down (raw, max of the two) */
    pi_params_t pi_dir;          /* transition y = PI[z] of the direct model (n = 0: none, y = z) */
    pi_params_t pi_inv;          /* its inverse z* = PI^-1[y*] for the compensator (Krejci-Kuhnen) */
    int32_t pi_inv_err_q16;      /* worst-case |pi_inv - exact inverse| (raw); pi_dir's is 1/2 raw */
    int32_t precision_ceiling_q16; /* calib_precision_ceiling_q16(max B entry): what the errors above were held to */
    lut_t tmap;                  /* v3 threshold map u = g(z) over z, read in place; n = 0: no map (u = z) */
    lut_t tmap_inv;              /* its inverse z = g^-1(u) over u (derived; n = 0 without a map) */
    int32_t tmap_inv_err_q16;    /* worst-case |g^-1 table - exact inverse of the g table| (raw); 0 without a map */
    int32_t tmap_inv_lip_q16;    /* Lipschitz constant of the exact g^-1, max over segments of dz/du, Q16.16
                                    (saturated at INT32_MAX); 65536 without a map */
    int32_t comp_err_q16;        /* worst-case |z* - exact| of the compensator's centre (docs/firmware.md):
                                    E_u = E_y sum|w'| + pi_inv_err, E_y = f_inv_err (with a relaxation
                                    ceil(f_inv_err (1 + m)) + 1), then with a map
                                    ceil(L E_u) + tmap_inv_err (held to the ceiling); raw, saturated */
    relax_params_t relax;        /* v4 travel-domain relaxation on y before f; kappa_q16 = 0: none */
    uint8_t stages;              /* CALIB_STAGE_* bits of the stages between f^-1 and B/2 this table has:
                                    0 is the pure play, whose tick tests this one byte instead of three */
    int32_t f_inv_buf[CALIB_DERIVED_MAX];
    int32_t z_up_buf[CALIB_DERIVED_MAX];
    int32_t z_down_buf[CALIB_DERIVED_MAX];
    int32_t tmap_inv_buf[CALIB_DERIVED_MAX];
} calib_t;

/* Compute the CRC a table of total_size bytes must carry in its header (crc32 field
 * taken as zero, seeded with the table's own layout_version field, so v1 tables keep
 * their v1 CRC). blob must hold total_size >= sizeof(pst_header_t) bytes. */
uint32_t calib_table_crc(const uint8_t *blob, uint32_t total_size);

/* Validate blob[0..len) (layout version 1, 2, 3 or 4) and derive f^-1, the reindexed envelopes
 * and, for a v2/v3 table with operators, the transition and its inverse (pi_build) into *out;
 * for a v3 table with a threshold map, g^-1 (the operators then run on u = g(z)); for a v4
 * table with a relaxation, its derived constants (relax_build: m = kappa/(1-kappa), 1/lambda).
 * The B, f and map entries are read in place: blob must stay valid (and 4-aligned) while
 * *out is in use (the operator block is copied). On any error *out is left unchanged, so
 * a running calibration survives a bad upload. Not per tick: O(n) with 64-bit divides. */
calib_status_t calib_load(calib_t *out, const uint8_t *blob, size_t len);

/* calib_load, then the board's own binding and limits (board != NULL: the table must be v5, for
 * board->instrument_id in board->q_unit, its travel, angle range and largest play inside the
 * board's). rep (may be NULL) receives the numbers of a plausibility refusal (common/ps_plaus.h;
 * rule PST_RULE_OK for any other outcome). calib_load(out, blob, len) is
 * calib_load_guarded(out, blob, len, NULL, NULL). */
calib_status_t calib_load_guarded(calib_t *out, const uint8_t *blob, size_t len, const pst_limits_t *board,
                                  pst_plaus_report_t *rep);

/* The calib_status_t of a plausibility rule (CALIB_OK for PST_RULE_OK). */
calib_status_t calib_status_of_rule(pst_rule_t rule);

/* A short English name for a status, for logs and error frames. */
const char *calib_status_str(calib_status_t st);

#endif /* CALIB_H */
