/* Double-precision reference model (see ref_model.h); deliberately plain, not fast. */
#include "ref_model.h"

#include <math.h>

double ref_pwl_eval(const ref_pwl_t *p, double x)
{
    double t = (x - p->x0) / p->h;
    if (t <= 0)
        return p->y[0];
    if (t >= p->n - 1)
        return p->y[p->n - 1];
    int i = (int)floor(t);
    double fr = t - i;
    return p->y[i] + (p->y[i + 1] - p->y[i]) * fr;
}

double ref_pwl_inverse(const ref_pwl_t *p, double y)
{
    int up = p->y[p->n - 1] > p->y[0];
    double lo = up ? p->y[0] : p->y[p->n - 1], hi = up ? p->y[p->n - 1] : p->y[0];
    if (y <= lo)
        return up ? p->x0 : p->x0 + (p->n - 1) * p->h;
    if (y >= hi)
        return up ? p->x0 + (p->n - 1) * p->h : p->x0;
    for (int i = 0; i + 1 < p->n; i++) {
        double a = p->y[i], b = p->y[i + 1];
        if ((y - a) * (y - b) <= 0 && a != b)
            return p->x0 + (i + (y - a) / (b - a)) * p->h;
    }
    return NAN;
}

double ref_pwl_max_slope(const ref_pwl_t *p)
{
    double m = 0;
    for (int i = 0; i + 1 < p->n; i++)
        m = fmax(m, fabs(p->y[i + 1] - p->y[i]) / p->h);
    return m;
}

/* z in [x0, x_last] with z + sign B(z)/2 = q, saturating; g is strictly increasing. */
static double solve_centre(const ref_pwl_t *b, double q, int sign)
{
    double lo = b->x0, hi = b->x0 + (b->n - 1) * b->h;
    if (lo + sign * ref_pwl_eval(b, lo) / 2 >= q)
        return lo;
    if (hi + sign * ref_pwl_eval(b, hi) / 2 <= q)
        return hi;
    for (int k = 0; k < 80; k++) {
        double mid = 0.5 * (lo + hi);
        if (mid + sign * ref_pwl_eval(b, mid) / 2 < q)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

double ref_play_step(ref_play_t *p, double q)
{
    double z_up = solve_centre(p->b, q, +1), z_down = solve_centre(p->b, q, -1);
    if (p->z < z_up)
        p->z = z_up;
    if (p->z > z_down)
        p->z = z_down;
    return ref_pwl_eval(p->f, p->z);
}

double ref_comp_step(ref_comp_t *c, double c_ref)
{
    if (c_ref > c->c_prev)
        c->dir = 1;
    else if (c_ref < c->c_prev)
        c->dir = -1;
    c->c_prev = c_ref;
    double qc = ref_pwl_inverse(c->f, c_ref);
    int sf = c->f->y[c->f->n - 1] > c->f->y[0] ? 1 : -1;
    /* eq. 5 (sf = +1): F2inv = f^-1 + B/2 when c* rises; eq. 9 (sf = -1): the opposite. */
    double q = qc + c->dir * sf * ref_pwl_eval(c->b, qc) / 2;
    return fmin(fmax(q, c->q_min), c->q_max);
}

void ref_pi_reset(ref_pi_t *s, double x0)
{
    for (int i = 0; i < s->n; i++)
        s->p[i] = x0;
}

double ref_pi_step(ref_pi_t *s, double x)
{
    double y = 0;
    for (int i = 0; i < s->n; i++) {
        s->p[i] = fmin(x + s->r[i], fmax(x - s->r[i], s->p[i]));
        y += s->w[i] * s->p[i];
    }
    return y;
}

void ref_pi_inverse(const ref_pi_t *d, ref_pi_t *inv)
{
    inv->n = d->n;
    for (int i = 0; i < d->n; i++) {
        double ri = 0, wi = 0, wj = 0;
        for (int j = 0; j <= i; j++) {
            ri += d->w[j] * (d->r[i] - d->r[j]);
            wi += d->w[j];
        }
        wj = wi - d->w[i];
        inv->r[i] = ri;
        inv->w[i] = i == 0 ? 1.0 / d->w[0] : -d->w[i] / (wi * wj);
    }
}
