/* Random but physically plausible calibration tables for property tests. */
#ifndef RANDOM_TABLES_H
#define RANDOM_TABLES_H

#include "ref_model.h"
#include "table_fixture.h"
#include "test_rng.h"

/* Parameters of B(q) = b0 + sum a_k exp(-(q - m_k)^2 / (2 s_k^2)) and of
 * f(q) = sign * (g1 q + sum c_k tanh((q - m_k) / s_k)), strictly monotone. */
typedef struct {
    double b0, ba[3], bm[3], bs[3];
    double g1, fc[3], fm[3], fs[3];
    int f_sign;
} random_table_t;

/* Draw one table over q in [-4, 4] and build its blob; fills ref_b/ref_f (double copies of the
 * entries, so the reference sees exactly the fixed-point table's function). */
size_t random_table_build(test_rng_t *r, fixture_blob_t *blob, ref_pwl_t *ref_b, ref_pwl_t *ref_f,
                          int f_sign);

/* A random valid transition block of n operators (1..PST_MAX_OPS): r_0 = 0 and strictly
 * increasing thresholds up to r_max (actuator units), weights w_0 >= w0_min, about a
 * third of the others zero (as a non-negative least-squares fit leaves them), the raw
 * sum 65536 + d with |d| <= sum_err_raw. Fills the Q16.16 arrays and ref (double copies
 * of exactly those values, states unset). */
void random_pi_build(test_rng_t *r, int n, double r_max, double w0_min, int sum_err_raw, int32_t *r_q16,
                     int32_t *w_q16, ref_pi_t *ref);

#endif /* RANDOM_TABLES_H */
