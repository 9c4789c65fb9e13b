/* Test fixture: builds calibration-table blobs (common/ps_table.h) from double functions. */
#ifndef TABLE_FIXTURE_H
#define TABLE_FIXTURE_H

#include <stddef.h>
#include <stdint.h>
#include "ps_table.h"

/* A double function of q with a context, e.g. B(q) in actuator units or f(q) in deg. */
typedef double (*fixture_fn)(double q, const void *ctx);

typedef struct {
    double q0;                   /* first grid abscissa, actuator units */
    int step_log2;               /* grid step = 2^step_log2 / 65536 units */
    uint16_t n;                  /* entries per grid (B and f share the grid here) */
    double q_min, q_max;         /* actuator travel */
    uint8_t f_kind;              /* enum pst_f_kind */
    uint32_t generation;
} fixture_grid_t;

/* Storage with the alignment calib_load() requires. */
typedef union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} fixture_blob_t;

/* Fill blob with B and f sampled on the grid (rounded to Q16) and a valid CRC.
 * Returns the table size in bytes. */
size_t fixture_build(fixture_blob_t *blob, const fixture_grid_t *g, fixture_fn b, const void *b_ctx,
                     fixture_fn f, const void *f_ctx);

/* Same with layout version (0: current, 1: v1) and n_ops transition operators:
 * thresholds r_q16 and weights w_q16 (Q16.16; NULL when n_ops = 0). */
size_t fixture_build_pi(fixture_blob_t *blob, const fixture_grid_t *g, fixture_fn b, const void *b_ctx,
                        fixture_fn f, const void *f_ctx, uint16_t version, uint16_t n_ops,
                        const int32_t *r_q16, const int32_t *w_q16);

/* Rewrite the table in blob with layout version (0: current, 1: v1) and another
 * operator block (n_ops operators, r_q16 / w_q16; NULL when 0), same header fields and
 * grids otherwise. Returns the new size, 0 if the writer refuses. */
size_t fixture_with_ops(fixture_blob_t *blob, uint16_t version, uint16_t n_ops, const int32_t *r_q16,
                        const int32_t *w_q16);

/* Rewrite the table in blob (v1/v2/v3, its grids and operators kept) as layout v3 with the
 * threshold map u = g(z): n entries u_q16 on z = x0_q16 + i step_q16 (n = 0: a v3 table
 * without a map). Returns the new size, 0 if the writer refuses. */
size_t fixture_with_tmap(fixture_blob_t *blob, int32_t x0_q16, int32_t step_q16, uint16_t n,
                         const int32_t *u_q16);

/* Rewrite the table in blob (v1-v4, its grids, operators and map kept) as layout v4 with the
 * relaxation (kappa_q16, lambda_q16). Returns the new size, 0 if the writer refuses. */
size_t fixture_with_relax(fixture_blob_t *blob, int32_t kappa_q16, int32_t lambda_q16);

/* Rewrite the table in blob (v1-v4, its grids, operators, map and relaxation kept) as layout v5
 * bound to instrument id, with the instrument block *inst, or (inst NULL) the one
 * pst_instrument_derive gives its entries. Returns the new size, 0 if the writer refuses. */
size_t fixture_with_instrument(fixture_blob_t *blob, uint32_t id, const pst_instrument_t *inst);

/* Recompute the CRC after a test edited the blob on purpose. */
void fixture_reseal(fixture_blob_t *blob);

/* Entry i of the B or f grid, as double (units, deg). */
double fixture_b(const fixture_blob_t *blob, int i);
double fixture_f(const fixture_blob_t *blob, int i);

#endif /* TABLE_FIXTURE_H */
