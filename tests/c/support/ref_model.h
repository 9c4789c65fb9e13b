/* Double-precision reference of the paper's model, written independently of firmware/core:
 * piecewise-linear functions, the play operator (eqs. 2, 3) solved by bisection, and the
 * compensator (eqs. 4, 5, 9). Tests hold the fixed-point code to it within documented bounds. */
#ifndef REF_MODEL_H
#define REF_MODEL_H

#define REF_MAX_N 512

/* y(x) on x_i = x0 + i h, linearly interpolated, saturated at both ends. */
typedef struct {
    double x0, h;
    int n;
    double y[REF_MAX_N];
} ref_pwl_t;

double ref_pwl_eval(const ref_pwl_t *p, double x);

/* x with p(x) = y for a strictly monotone p; saturated to the grid ends outside its range. */
double ref_pwl_inverse(const ref_pwl_t *p, double y);

/* Largest |slope| of p. */
double ref_pwl_max_slope(const ref_pwl_t *p);

/* Play operator state: centre z (actuator units). */
typedef struct {
    const ref_pwl_t *b, *f;
    double z;
} ref_play_t;

/* One step of eq. 3: z is clamped into [z_up(q), z_down(q)], where z_up solves z + B(z)/2 = q
 * and z_down solves z - B(z)/2 = q (by bisection on B's grid, saturating at its ends). */
double ref_play_step(ref_play_t *p, double q);

/* Compensator without smoothing: eq. 4 with eq. 5 (f increasing) or eq. 9 (decreasing). */
typedef struct {
    const ref_pwl_t *b, *f;
    double q_min, q_max;
    double c_prev;
    int dir;
} ref_comp_t;

double ref_comp_step(ref_comp_t *c, double c_ref);

/* Prandtl-Ishlinskii operator y = sum_i w_i P_{r_i}[x] in double, the textbook way: every
 * operator clamped every step, p_i = min(x + r_i, max(x - r_i, p_i)). */
#define REF_PI_MAX 16
typedef struct {
    int n;
    double r[REF_PI_MAX], w[REF_PI_MAX], p[REF_PI_MAX];
} ref_pi_t;

/* All operators at rest at x0. */
void ref_pi_reset(ref_pi_t *s, double x0);

double ref_pi_step(ref_pi_t *s, double x);

/* The inverse operator of d (Krejci & Kuhnen 2001), written as the products of the
 * published formula: r'_i = sum_{j<=i} w_j (r_i - r_j), w'_0 = 1/w_0,
 * w'_i = -w_i / ((sum_{j<=i} w_j)(sum_{j<=i-1} w_j)). States are not set. */
void ref_pi_inverse(const ref_pi_t *d, ref_pi_t *inv);

#endif /* REF_MODEL_H */
