/* On-line update of the backlash width B(q) from the onset samples that arrive during use
 * by recursive least squares with exponential forgetting, fixed point.
 * docs/firmware.md, "On-line B update", gives the model, the settings' rule and the cost. */
#ifndef B_ONLINE_H
#define B_ONLINE_H

#include <stdbool.h>
#include <stdint.h>

#include "lut.h"
#include "ps_fixed.h"
#include "ps_table.h"

#ifndef B_ONLINE_MAX_NODES
/* B_ONLINE_MAX_NODES: coefficients of the correction (a linear B-spline on every 2^k-th grid
 * entry); the covariance is N x N int32. 16 matches the host's B spline (N = 14 control
 * points, docs/method.md) and costs 1 KiB. */
#define B_ONLINE_MAX_NODES 16
#endif

/* Fixed-point format of lambda, p0 and the covariance P (the rest is Q16.16). */
enum { B_ONLINE_P_FRAC_BITS = 30 };

/* Settings. All dimensionless: P is the covariance of the coefficients in units of one
 * onset sample's noise variance, so neither depends on the instrument's units. */
typedef struct {
    int32_t lambda_q30;          /* forgetting factor per onset sample, in [1/2, 1], Q30 */
    int32_t p0_q30;              /* prior variance of each coefficient, in (0, 1], Q30: the flashed
                                    B counts as 1/p0 onset samples at each node; also the cap of
                                    every P_ii (no node is ever less certain than the prior) */
    int32_t slope_max_q16;       /* |dB/dq| limit of the B written, > 0 (the host fit's 1.5) */
} b_online_config_t;

/* Defaults (docs/firmware.md): lambda = 1 - 1/8 (a memory of tau = 8 onset samples, i.e. 8
 * reversals, so the steady-state standard error of a node is about 1/4 of one sample's),
 * p0 = 1 (the flashed B weighs as one sample per node), |B'| <= 1.5. */
b_online_config_t b_online_default_config(void);

typedef enum {
    B_ONLINE_OK = 0,
    B_ONLINE_ERR_CONFIG,         /* lambda outside [1/2, 1], p0 outside (0, 1], slope <= 0 */
    B_ONLINE_ERR_GRID,           /* the table's B grid: n outside 2..PST_MAX_ENTRIES */
} b_online_status_t;

typedef struct {
    b_online_config_t cfg;
    const int32_t *prior_q16;    /* the flashed B entries (the table blob), read only */
    lut_t *out;                  /* the running table's B: its y_q16 is pointed at b_q16[live] */
    /* Two copies of the B entries the loop runs (prior + correction, bounded): a sample is
     * written into the copy the loop does not read, then published by one aligned pointer
     * store (out->y_q16), so a tick that preempts the update reads either the old or the
     * new grid, never a half-written one (the A/B idea of the table commit, for B alone). */
    int32_t b_q16[2][PST_MAX_ENTRIES];
    uint8_t live;                /* index of the copy out->y_q16 points to */
    int32_t theta_q16[B_ONLINE_MAX_NODES]; /* correction at each node, actuator units Q16 */
    int32_t p_q30[B_ONLINE_MAX_NODES][B_ONLINE_MAX_NODES]; /* covariance / noise variance, Q30, symmetric */
    int64_t inv_lambda_q30;      /* 1/lambda */
    int64_t inv_sqrt_lambda_q30; /* 1/sqrt(lambda) */
    int64_t lambda_p0_q30;       /* lambda * p0: a row whose P_ii exceeds it is not inflated */
    int32_t x0_q16;              /* abscissa of node 0 (= of grid entry 0) */
    uint16_t n_grid;             /* B grid entries */
    uint8_t n_nodes;             /* coefficients in use, 2..B_ONLINE_MAX_NODES */
    uint8_t grid_log2;           /* grid step 2^s raw */
    uint8_t node_log2;           /* node spacing 2^k grid steps */
    uint32_t samples;            /* samples learnt since init (saturating) */
} b_online_t;

/* Start learning on a loaded table's B: the RAM copy starts as the flashed entries,
 * theta = 0, P = p0 I, and b->y_q16 is re-pointed to it, so whatever evaluates *b (the
 * compensator, eq. 4) runs the learnt B from then on (b must outlive the learner, or be
 * replaced by b_online_rebind / b_online_stop). A compensator that caches a cell of *b
 * (comp_t) must drop it after every call that publishes (comp_b_changed). The flashed entries stay the prior
 * (the table blob must stay valid, as calib_load already requires). Nodes: every 2^k-th
 * grid entry, k the smallest giving <= B_ONLINE_MAX_NODES. On error nothing is changed.
 * Init time (one integer square root); call it after calib_load, before psa_set_table. */
b_online_status_t b_online_init(b_online_t *bo, const b_online_config_t *cfg, lut_t *b);

/* A table committed during use (psa_set_table's hot swap) whose B is what this board learnt:
 * the host mirrors b_online bit for bit on the B samples the board reports and flashes the
 * current entries (b_q16) with its refreshed f_remain and offset. b (the new table's B, same
 * grid: n, x0 and step) becomes the prior, theta = 0 (the correction is now in the prior),
 * P is kept (the estimate's uncertainty is unchanged by moving it into the prior), and
 * b->y_q16 is re-pointed to the RAM copy (b is the learner's table from then on). B_ONLINE_ERR_GRID, nothing changed, for another
 * grid (then b_online_init). Init time, O(n_grid). */
b_online_status_t b_online_rebind(b_online_t *bo, lut_t *b);

/* Learn one B sample of eq. 1 (q_mean, b from an onset_event_t with reason ONSET_OK or
 * ONSET_OK_COARSE), actuator units Q16: one RLS step on theta and P with forgetting
 * (regressor: the two linear B-spline weights at q_mean, clamped to the grid; target
 * b - prior(q_mean)), then the entries rewritten as prior + correction, floored at 0 and
 * replaced by their largest lower envelope with |dB/dq| <= slope_max (exact, two passes),
 * written into the copy the loop does not read and then published (one pointer store).
 * Integer-only; one 64-bit divide (1/s of the gain) per sample: it runs when an onset
 * completes (a camera frame or angle reading, about once per reversal), never per tick.
 * O(N^2 + n_grid); bench/bench_firmware.sh gives its cost. */
void b_online_sample(b_online_t *bo, int32_t q_mean_q16, int32_t b_q16);

/* The B entries the loop runs now (n_grid of them, Q16): the published copy. */
const int32_t *b_online_entries(const b_online_t *bo);

/* Stop learning: the bound table's B is pointed back at the flashed entries (one pointer
 * store). The learner keeps its state but publishes nothing until b_online_init/_rebind. */
void b_online_stop(b_online_t *bo);

#endif /* B_ONLINE_H */
