/* Sequential kernels of the diagnosis' model (playscope/diagnose/fitmodel.py) and of the onsets'
 * record model (playscope/fit/onset_model.py), in double precision. Each is the line-for-line
 * translation of the Python reference kept beside it (fitmodel.py, fit/model.py, fit/onset_model.py:
 * same operations in the same order, compiled with -ffp-contract=off), so the two agree bit for
 * bit; tests/python/sim/test_diagnose_kernels.py checks that.
 * Why C: these recursions are sequential over time (each sample depends on the previous one),
 * so numpy cannot vectorise them, and they were most of a diagnosis' time in Python. */

#include "kernels.h"

#include <math.h>

/* The play's step, p = min(hi, max(lo, p)) as Python's min/max: the first argument on ties. */
static inline double play_step(double p, double lo, double hi)
{
    double m = (p > lo) ? p : lo;
    return (m < hi) ? m : hi;
}

/* The drag bookkeeping after a step to p at sample k: a drag when p sits on an edge, made by that
 * edge (the lower on a tie). */
static inline void drag_mark(double p, double lo, double hi, long k, long *lk, double *sk)
{
    if (p == lo || p == hi) {
        *lk = k;
        *sk = (p == lo) ? -0.5 : 0.5;
    }
}

/* Before the first drag (last < 0): sample 0's edge, as the reference indexes it. */
static void side_before_first_drag(const double *z, double lo0, long n, const long *last, double *side)
{
    if (n > 0 && last[0] < 0) {
        double s0 = (z[0] == lo0) ? -0.5 : 0.5;
        for (long k = 0; k < n && last[k] < 0; k++)
            side[k] = s0;
    }
}

/* B at sample k from its w taps, in csr_matvec's order (0 + v0 c0 + v1 c1 + ...), then
 * np.maximum(B, 0) (NaN stays NaN). */
static inline double band_width(const int *idx, const double *val, long w, const double *c, long k)
{
    double b = 0.0;
    for (long j = 0; j < w; j++)
        b += val[k * w + j] * c[idx[k * w + j]];
    return (b < 0.0) ? 0.0 : b;
}

void dk_play_on_edges(const double *lo, const double *hi, long n, double z0, double *out)
{
    double p = z0;
    for (long k = 0; k < n; k++) {
        p = play_step(p, lo[k], hi[k]);
        out[k] = p;
    }
}

void dk_play_drags(const double *lo, const double *hi, long n, double z0, double *z, long *last, double *side)
{
    double p = z0;
    long lk = -1;
    double sk = 0.5;
    for (long k = 0; k < n; k++) {
        p = play_step(p, lo[k], hi[k]);
        z[k] = p;
        drag_mark(p, lo[k], hi[k], k, &lk, &sk);
        last[k] = lk;
        side[k] = sk;
    }
    side_before_first_drag(z, n > 0 ? lo[0] : 0.0, n, last, side);
}

void dk_first_moves(const double *z, long n, const long *from, const long *to, long m, long *out)
{
    for (long j = 0; j < m; j++) {
        long k = (from[j] < 1) ? 1 : from[j];
        long e = (to[j] < n) ? to[j] : n;
        out[j] = -1;
        for (; k < e; k++) {
            if (z[k] != z[k - 1]) {  /* NaN moves, as numpy's != says */
                out[j] = k;
                break;
            }
        }
    }
}

void dk_band_input(const double *q, const int *idx, const double *val, long n, long w, const double *c,
                   double *lo, double *hi)
{
    for (long k = 0; k < n; k++) {
        double b = band_width(idx, val, w, c, k);
        lo[k] = q[k] - 0.5 * b;
        hi[k] = q[k] + 0.5 * b;
    }
}

void dk_band_play_drags(const double *q, const int *idx, const double *val, long n, long w, const double *c,
                        double f, double *z, long *last, double *side, double *band0)
{
    double p = 0.0;
    long lk = -1;
    double sk = 0.5;
    band0[0] = band0[1] = 0.0;
    for (long k = 0; k < n; k++) {
        double b = band_width(idx, val, w, c, k);
        double lo = q[k] - 0.5 * b, hi = q[k] + 0.5 * b;
        if (k == 0) {  /* the first state on the first sample's band (onset_model.RecordModel.play_drags) */
            band0[0] = lo;
            band0[1] = hi;
            p = lo + f * (hi - lo);
        }
        p = play_step(p, lo, hi);
        z[k] = p;
        drag_mark(p, lo, hi, k, &lk, &sk);
        last[k] = lk;
        side[k] = sk;
    }
    side_before_first_drag(z, band0[0], n, last, side);
}

void dk_drag_gradient(const int *cols, const double *vals, long w, const long *last, const double *side, long K,
                      long nb, double *out)
{
    for (long i = 0; i < K; i++) {
        double *row = out + i * nb;
        if (last[i] < 0) {
            for (long c = 0; c < nb; c++)
                row[c] = 0.0;
            continue;
        }
        double zero = 0.0 * side[i];  /* numpy's 0 * side: -0 on the lower edge */
        for (long c = 0; c < nb; c++)
            row[c] = zero;
        for (long j = 0; j < w; j++)
            row[cols[last[i] * w + j]] = vals[last[i] * w + j] * side[i];
    }
}

void dk_tip_mode(const double *u, long n, double b1, double a1, double a2, double *y)
{
    /* transposed direct form II of b = (0, b1, 0), a = (1, a1, a2), each product and sum in
     * scipy.signal.lfilter's order, so that the two agree bit for bit */
    double z0 = 0.0, z1 = 0.0;
    for (long k = 0; k < n; k++) {
        double x = u[k];
        double yk = z0 + 0.0 * x;
        z0 = (z1 + x * b1) - yk * a1;
        z1 = x * 0.0 - yk * a2;
        y[k] = yk;
    }
}

/* Row k of the edge gradient on the grid (dk_tip_mode_edges): zero but for its table row's taps. */
static void edge_row(const int *cols, const double *vals, long w, const long *src, const double *scale,
                     const double *pre, long R, long k, double *row)
{
    if (src[k] < 0) {
        for (long r = 0; r < R; r++)
            row[r] = pre[r];
        return;
    }
    for (long r = 0; r < R; r++)
        row[r] = 0.0;
    for (long j = 0; j < w; j++)
        row[cols[src[k] * w + j]] = vals[src[k] * w + j] * scale[k];
}

void dk_tip_mode_edges(const int *cols, const double *vals, long w, const long *src, const double *scale, long n,
                       const double *pre, long R, const double *wd, double b1, double a1, double a2,
                       const long *i0, const double *w_lo, const double *w_hi, long F, double *scratch, double *out)
{
    double *za = scratch, *zb = scratch + R, *zc = scratch + 2 * R;      /* rows k, k + 1, k + 2 */
    double *s0 = scratch + 3 * R, *s1 = scratch + 4 * R;                 /* the filters' delays */
    double *y_prev = scratch + 5 * R, *y_cur = scratch + 6 * R;
    long f = 0;
    if (n < 3)
        return;
    for (long r = 0; r < R; r++)
        s0[r] = s1[r] = y_prev[r] = 0.0;
    edge_row(cols, vals, w, src, scale, pre, R, 0, za);
    edge_row(cols, vals, w, src, scale, pre, R, 1, zb);
    for (long k = 0; k + 2 < n && f < F; k++) {
        edge_row(cols, vals, w, src, scale, pre, R, k + 2, zc);
        for (long r = 0; r < R; r++) {
            /* the drive: numpy's diff twice, times the sample's weight; then lfilter's order */
            double x = ((zc[r] - zb[r]) - (zb[r] - za[r])) * wd[k];
            double yk = s0[r] + 0.0 * x;
            s0[r] = (s1[r] + x * b1) - yk * a1;
            s1[r] = x * 0.0 - yk * a2;
            y_cur[r] = yk;
        }
        while (f < F && i0[f] + 1 == k) {  /* a frame between output samples k - 1 and k */
            for (long r = 0; r < R; r++)
                out[f * R + r] = y_prev[r] * w_lo[f] + y_cur[r] * w_hi[f];
            f++;
        }
        double *t = za; za = zb; zb = zc; zc = t;
        t = y_prev; y_prev = y_cur; y_cur = t;
    }
}

void dk_play_ops(const double *x, long n, const double *r, long m, const double *p0, double *out)
{
    for (long k = 0; k < n; k++) {
        const double *prev = k ? out + (k - 1) * m : p0;
        double *row = out + k * m;
        for (long i = 0; i < m; i++) {
            double lo = x[k] - r[i], hi = x[k] + r[i], p = prev[i];
            double a = (lo > p) ? lo : p;   /* np.maximum(lo, p) */
            row[i] = (hi < a) ? hi : a;     /* np.minimum(hi, a) */
        }
    }
}

void dk_viscous_play(const double *lo, const double *hi, long n, double z0, double a, double *out)
{
    double p = z0;
    for (long k = 0; k < n; k++) {
        double c = (p < lo[k]) ? lo[k] : ((p > hi[k]) ? hi[k] : p);
        p += a * (c - p);
        out[k] = p;
    }
}

void dk_switch(const double *z, long n, double g, double *out)
{
    double st = 1.0;
    if (n <= 0)
        return;
    for (long k = 1; k < n; k++) {
        st += g * (z[k] - z[k - 1]);
        st = (st > 1.0) ? 1.0 : ((st < -1.0) ? -1.0 : st);
        out[k] = st;
    }
    out[0] = (n > 1) ? out[1] : 1.0;
}

void dk_karnopp(const double *z, long n, double w2, double c2, double Fs, double Fc, double h,
                double band, long substeps, double *out)
{
    if (n <= 0)
        return;
    double p = z[0], v = 0.0, zp = z[0];
    for (long k = 0; k < n; k++) {
        double zk = z[k];
        if (v == 0.0 && fabs(w2 * (zk - p)) <= Fs && fabs(w2 * (zp - p)) <= Fs) {
            out[k] = p;
            zp = zk;
            continue;
        }
        for (long j = 1; j <= substeps; j++) {
            double zj = zp + (zk - zp) * (double)j / (double)substeps;
            double F = w2 * (zj - p);
            double vn;
            if (-band < v && v < band) {
                if (-Fs <= F && F <= Fs) {
                    v = 0.0;
                    continue;
                }
                vn = v + h * (F - (F > 0 ? Fs : -Fs));
            } else {
                vn = (v + h * (F - (v > 0 ? Fc : -Fc))) / (1.0 + h * c2);
            }
            if (v != 0.0 && vn * v <= 0.0 && fabs(F) <= Fs)
                vn = 0.0;
            v = vn;
            p += h * v;
        }
        out[k] = p;
        zp = zk;
    }
}
