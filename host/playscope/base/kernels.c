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
