/* Sequential kernels of the diagnosis' model (kernels.c); also the cffi cdef (kernels.py drops
 * the preprocessor lines), so it holds declarations only. Arrays are double, n samples; out is written, never read. */
#ifndef PS_DIAGNOSE_KERNELS_H
#define PS_DIAGNOSE_KERNELS_H
/* Play operator on band edges: p = min(hi[k], max(lo[k], p)), p starting at z0 (eq. 3). */
void dk_play_on_edges(const double *lo, const double *hi, long n, double z0, double *out);
/* The play on band edges with its drags (the record model's columns): z as dk_play_on_edges;
 * last[k] the latest sample <= k at which z sat on an edge (-1: none yet), side[k] -0.5 when that
 * edge was the lower (a tie counts as the lower), +0.5 the upper; before the first drag, sample
 * 0's (the reference's where(z == lo, -0.5, 0.5)[max(last, 0)]). */
void dk_play_drags(const double *lo, const double *hi, long n, double z0, double *z, long *last, double *side);
/* The first sample k in [from[j], to[j]) at which z moves (z[k] != z[k - 1], k >= 1), or -1, for
 * each of m spans: the record model's onsets (onset_model._first_moves_ref, the same comparisons). */
void dk_first_moves(const double *z, long n, const long *from, const long *to, long m, long *out);
/* The band at the input, q -+ B / 2, B = max(sum_j val[k, j] c[idx[k, j]], 0) over w taps a sample
 * (the sparse B-spline design's rows, summed in scipy's csr_matvec order: bit for bit). */
void dk_band_input(const double *q, const int *idx, const double *val, long n, long w, const double *c,
                   double *lo, double *hi);
/* dk_band_input and dk_play_drags in one pass, the band never stored: the play starts at
 * z0 = lo[0] + f (hi[0] - lo[0]) (f in [0, 1]); band0 gets (lo[0], hi[0]). The same bits as the two. */
void dk_band_play_drags(const double *q, const int *idx, const double *val, long n, long w, const double *c,
                        double f, double *z, long *last, double *side, double *band0);
/* The play's gradient over B's coefficients at K grid samples (onset_model.RecordModel.z_gradient):
 * row i (nb wide) is 0 * side[i] but for vals[last[i], j] side[i] at cols[last[i], j] (w taps, distinct
 * columns), or all +0 where last[i] < 0 (no drag yet): numpy's rows of the design times side, bit for bit. */
void dk_drag_gradient(const int *cols, const double *vals, long w, const long *last, const double *side, long K,
                      long nb, double *out);
/* The tip mode's filter (onset_model._tip_filter's b = (0, b1), a = (1, a1, a2)) on u from rest:
 * scipy.signal.lfilter's transposed direct form II, bit for bit. */
void dk_tip_mode(const double *u, long n, double b1, double a1, double a2, double *y);
/* The same filter driven, for each of R coefficients, by the second differences of the edge
 * gradient on the grid times wd (n - 2): sample k's row is zero but for vals[src[k], j] scale[k]
 * at cols[src[k], j] (a table of w taps a row), or pre (R) where src[k] < 0; read at F sorted
 * positions between output samples i0[f] and i0[f] + 1: out[f, r] = y[i0[f]] w_lo[f] +
 * y[i0[f] + 1] w_hi[f] (F x R, row-major); i0[f] + 1 < n - 2; scratch holds 7 R doubles. */
void dk_tip_mode_edges(const int *cols, const double *vals, long w, const long *src, const double *scale, long n,
                       const double *pre, long R, const double *wd, double b1, double a1, double a2,
                       const long *i0, const double *w_lo, const double *w_hi, long F, double *scratch, double *out);
/* Classical play operators of m thresholds r over x (transition.play_ops): row k of out (n x m,
 * row-major) is p_i = minimum(x[k] + r_i, maximum(x[k] - r_i, p_i)), p starting at p0 (m,), with
 * numpy's tie rule (maximum(a, b) and minimum(a, b) give b on a tie, so signed zeros agree too). */
void dk_play_ops(const double *x, long n, const double *r, long m, const double *p0, double *out);
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
