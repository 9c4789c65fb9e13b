/* Sequential kernels of the diagnosis' model (kernels.c); also the cffi cdef (kernels.py drops
 * the preprocessor lines), so it holds declarations only. Arrays are double, n samples; out is written, never read. */
#ifndef PS_DIAGNOSE_KERNELS_H
#define PS_DIAGNOSE_KERNELS_H
/* Play operator on band edges: p = min(hi[k], max(lo[k], p)), p starting at z0 (eq. 3). */
void dk_play_on_edges(const double *lo, const double *hi, long n, double z0, double *out);
/* Viscous play: p += a (clip(p, lo[k], hi[k]) - p), p starting at z0. */
void dk_viscous_play(const double *lo, const double *hi, long n, double z0, double a, double *out);
/* Direction state: st += g (z[k] - z[k-1]) clipped to [-1, 1], from +1; out[0] = out[1]. */
void dk_switch(const double *z, long n, double g, double *out);
/* Karnopp stick-slip carrier driven through a spring by z (fitmodel._karnopp_carrier's
 * recursion; w2 = wn^2, c2 = 2 zeta wn, Fs / Fc static / kinetic force per unit mass, h the
 * step, band Karnopp's zero-velocity band, substeps steps per sample). */
void dk_karnopp(const double *z, long n, double w2, double c2, double Fs, double Fc, double h,
                double band, long substeps, double *out);
#endif
