/* Sequential kernels of the diagnosis' model (playscope/diagnose/fitmodel.py), in double
 * precision. Each is the line-for-line translation of the Python reference kept beside it in
 * fitmodel.py (same operations in the same order, compiled with -ffp-contract=off), so the two
 * agree bit for bit; tests/python/sim/test_diagnose_kernels.py checks that.
 * Why C: these recursions are sequential over time (each sample depends on the previous one),
 * so numpy cannot vectorise them, and they were most of a diagnosis' time in Python. */

#include "kernels.h"

#include <math.h>

void dk_play_on_edges(const double *lo, const double *hi, long n, double z0, double *out)
{
    double p = z0;
    for (long k = 0; k < n; k++) {
        /* p = min(hi, max(lo, p)) as Python's min/max: the first argument on ties */
        double m = (p > lo[k]) ? p : lo[k];
        p = (m < hi[k]) ? m : hi[k];
        out[k] = p;
    }
}

void dk_play_drags(const double *lo, const double *hi, long n, double z0, double *z, long *last, double *side)
{
    double p = z0;
    long lk = -1;
    double sk = 0.5;
    for (long k = 0; k < n; k++) {
        double m = (p > lo[k]) ? p : lo[k];
        p = (m < hi[k]) ? m : hi[k];
        z[k] = p;
        if (p == lo[k] || p == hi[k]) {  /* a drag: the edge it sits on made it (the lower on a tie) */
            lk = k;
            sk = (p == lo[k]) ? -0.5 : 0.5;
        }
        last[k] = lk;
        side[k] = sk;
    }
    if (n > 0 && last[0] < 0) {  /* before the first drag: sample 0's edge, as the reference indexes it */
        double s0 = (z[0] == lo[0]) ? -0.5 : 0.5;
        for (long k = 0; k < n && last[k] < 0; k++)
            side[k] = s0;
    }
}

void dk_band_input(const double *q, const int *idx, const double *val, long n, long w, const double *c,
                   double *lo, double *hi)
{
    for (long k = 0; k < n; k++) {
        double b = 0.0;  /* csr_matvec's order: 0 + v0 c0 + v1 c1 + ... */
        for (long j = 0; j < w; j++)
            b += val[k * w + j] * c[idx[k * w + j]];
        b = (b < 0.0) ? 0.0 : b;  /* np.maximum(b, 0): NaN stays NaN */
        lo[k] = q[k] - 0.5 * b;
        hi[k] = q[k] + 0.5 * b;
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
