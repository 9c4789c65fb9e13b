/* Physical plausibility of a calibration table, the one rule set of board and host.
 *
 * The board's loader (firmware/core/calib.c, calib_load / calib_load_guarded) and the host's
 * `playscope tables` / `flash` (through cffi, host/playscope/base/native.py) call these same
 * functions: a table is judged against its own travel (every layout), against the instrument
 * block of a v5 header (common/ps_table.h, pst_instrument_t), and on a board against the board's
 * own limits (pst_limits_t). Each refusal names its rule and the numbers that broke it
 * (pst_plaus_report_t), so a refusal can say "B = 7.6 mm at entry 12 is above the instrument's
 * largest play 1.4 mm". Init time only (a divide or two): never per tick. */
#ifndef PS_PLAUS_H
#define PS_PLAUS_H

#include <stdbool.h>
#include <stdint.h>
#include "ps_table.h"

/* One rule per value, in the order they are checked. The rules' limits: ps_table.h PST_PLAUS_*. */
typedef enum {
    PST_RULE_OK = 0,
    /* Every layout: against the table's own travel. */
    PST_RULE_TRAVEL,             /* travel q_max - q_min below PST_PLAUS_TRAVEL_MIN_Q16 (value: travel) */
    PST_RULE_B_TRAVEL,           /* a B entry above the travel (value: B, limit: travel) */
    PST_RULE_C_RANGE,            /* an |f| entry beyond PST_PLAUS_C_ABS_MAX_Q16 (value: f) */
    PST_RULE_C_SPAN,             /* f spans less than PST_PLAUS_C_SPAN_MIN_Q16 (v5: _INST_Q16) over its grid */
    PST_RULE_F_SLOPE,            /* |df/dq| above PST_PLAUS_F_SLOPE_MAX on a segment (value: slope, deg/unit) */
    /* v5: the instrument block. */
    PST_RULE_TRAVEL_UNIT,        /* travel above what any instrument in its unit has (200 mm, 7200 deg): a unit mistake */
    PST_RULE_INST_C_RANGE,       /* c_min >= c_max, beyond +-360 deg, or wider than 360 deg (one turn) */
    PST_RULE_INST_B_MAX,         /* b_max <= 0 or above travel / PST_PLAUS_B_TRAVEL_DIV (value: b_max, limit) */
    PST_RULE_INST_F_SLOPE,       /* f_slope_max <= 0, above PST_PLAUS_F_SLOPE_MAX deg/unit or PST_PLAUS_F_GAIN x (c_max - c_min) / travel */
    PST_RULE_INST_F_INV_SLOPE,   /* f_inv_slope_max <= 0 or above PST_PLAUS_F_INV_GAIN x travel / (c_max - c_min) */
    PST_RULE_B_INST,             /* a B entry above the instrument's b_max */
    PST_RULE_C_INST,             /* an f entry outside the instrument's [c_min, c_max] */
    PST_RULE_F_SLOPE_INST,       /* a segment of f steeper than f_slope_max (value, limit: deg/unit) */
    PST_RULE_F_INV_SLOPE_INST,   /* a segment of f flatter than 1 / f_inv_slope_max (value, limit: |dq/dc|, unit/deg) */
    /* A board's own limits (pst_limits_t). */
    PST_RULE_UNBOUND,            /* a table of layout < 5: it names no instrument (value: its layout version) */
    PST_RULE_BOARD_INSTRUMENT,   /* the table's instrument id is not the board's (value: table's, limit: board's) */
    PST_RULE_BOARD_UNIT,         /* the table's unit is not the board's (enum pst_q_unit) */
    PST_RULE_BOARD_TRAVEL,       /* the table's q_min or q_max outside the board's travel */
    PST_RULE_BOARD_ANGLE,        /* the table's c_min or c_max outside the board's angle limits */
    PST_RULE_BOARD_B,            /* the table's b_max above the board's */
    PST_RULE_COUNT
} pst_rule_t;

/* What broke a rule, in raw units: Q16.16 of the quantity (slopes Q16.16 per unit, ids and
 * versions as integers), so a message can print value and limit in the table's units. */
typedef struct {
    int32_t rule;                /* pst_rule_t */
    int32_t index;               /* entry or segment index in its grid, -1 for a header field */
    int64_t value;               /* what the table has */
    int64_t limit;               /* what the rule allows (the bound that was crossed) */
} pst_plaus_report_t;

/* Judge a table whose structure is already checked (grids valid, entries in place):
 * hd its base header, inst its instrument block (NULL for layout < 5: only the travel rules),
 * b / f the entries of hd->b / hd->f, board the board's limits (NULL on the host without a
 * board: the table's own rules only). Returns the first rule broken, PST_RULE_OK if none;
 * *rep (may be NULL) receives the numbers. */
pst_rule_t pst_plaus_check(const pst_header_t *hd, const pst_instrument_t *inst, const int32_t *b_q16,
                           const int32_t *f_q16, const pst_limits_t *board, pst_plaus_report_t *rep);

/* The instrument block a producer writes for entries b (over hd->b) and f (over hd->f) that
 * carry no better knowledge of the instrument: the angle range of f widened by 1/16 of its span
 * on each side (within +-360 and one turn), b_max twice the largest B (at most travel / 2), slopes twice the
 * largest of f and of f^-1 on the grid (each within its rule's limit when the entries are). A
 * table so stamped passes the instrument rules exactly when its entries pass the absolute ones. */
void pst_instrument_derive(const pst_header_t *hd, const int32_t *b_q16, const int32_t *f_q16, uint32_t id,
                           pst_instrument_t *out);

enum {
    PST_GENERATION_STEP_MAX = 16, /* a commit may skip at most 15 generations (tables built, never flashed) */
};

/* The generations a board takes next: above the running table's (0 with no table) by at most
 * PST_GENERATION_STEP_MAX, and none once the running one is 0xFFFFFFFF. Stepping so, the
 * counter cannot be run to its end from the link (2^28 commits wear any flash out first: a
 * sector lasts some 10^4 erases); a board already there (an older firmware took any newer
 * generation, up to 0xFFFFFFFF) recovers only by its board's physical path (docs/robustness.md:
 * a boot-time pin, a flag of the virtual board standing for it, an erase on the programming
 * port). */
bool pst_generation_ok(bool have_table, uint32_t active_generation, uint32_t generation);

/* A short English statement of a rule, for logs and messages. */
const char *pst_rule_str(pst_rule_t rule);

#endif /* PS_PLAUS_H */
