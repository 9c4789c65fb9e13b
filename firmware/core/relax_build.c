/* Travel-domain relaxation: load-time validation and derivation (the only divides). */
#include "relax.h"

enum { RELAX_RANGE = 1 << 30 };

relax_status_t relax_build(int32_t kappa_q16, int32_t lambda_q16, int32_t x_min_q16, int32_t x_max_q16,
                           relax_params_t *out)
{
    if (kappa_q16 < 0 || kappa_q16 > PST_RELAX_KAPPA_MAX_Q16)
        return RELAX_ERR_KAPPA;
    if (kappa_q16 == 0 ? lambda_q16 != 0 : lambda_q16 < 1)
        return RELAX_ERR_LAMBDA;
    /* Without a relaxation the range is not used (a v1-v3 table loads as it always did). */
    if (kappa_q16 != 0 && (x_min_q16 < -RELAX_RANGE || x_max_q16 > RELAX_RANGE || x_min_q16 >= x_max_q16))
        return RELAX_ERR_RANGE;
    relax_params_t p = {0};
    p.kappa_q16 = kappa_q16;
    p.lambda_q16 = lambda_q16;
    if (kappa_q16 != 0) {
        /* m = kappa / (1 - kappa) in Q24, rounded: kappa <= 0.9 keeps it below 2^28. */
        int64_t den = 65536 - (int64_t)kappa_q16;
        p.m_q24 = (int32_t)((((int64_t)kappa_q16 << 24) + den / 2) / den);
        p.inv_lam_q47 = ((uint64_t)1 << 47) / (uint64_t)lambda_q16;
        p.g_max_q31 = (int32_t)((65536 - (int64_t)kappa_q16) << 15);
    }
    p.x_min_q16 = x_min_q16;
    p.x_max_q16 = x_max_q16;
    *out = p;
    return RELAX_OK;
}
