/* Stolt mapping of a wavenumber-domain spectrum (the interpolation step of omega-k).
 *
 * NumPy twin: clsas/image/stolt.py (stolt_reference, on clsas/interp.py's resample_rows); the
 * launcher is in the same module. The interpolators are kernels/interp.h's.
 *
 * For output row r (one along-track wavenumber k_u, ku2[r] = k_u^2) and output column j (the
 * uniform baseband range wavenumber k_x' = kx_first + j dkx), the source column is the exact,
 * non-uniformly spaced position
 *     idx = (c / (4 pi) sqrt((k_x' + 2 k0)^2 + k_u^2) - f0 - f_first) / df
 *         = A sqrt(K^2 + k_u^2) + Bc,   K = K0 + j dkx,
 * evaluated in double for the first output of a work-item (float would round idx ~ 2000 to
 * 1.2e-4 sample) and relative to it in float for the other fifteen (see below); the
 * interpolation and the data are float.
 *
 * The interpolation (INTERP_LINEAR or TAPS taps from the nearest of TAP_ROWS tap rows, positions
 * a rounding error below an integer read as that integer, zero unless all source samples
 * exist) is kernels/interp.h's; BLOCKS comes from clsas/interp.py.
 *
 * One work-item: BLOCKS x 16 consecutive outputs of a row (float16 lanes, one block of 16 at a
 * time), global size (ceil(n_out / (16 BLOCKS)), n_rows padded to whole work-groups: interp.h's
 * ROW_ITEM); all of its positions are computed before any interpolation, so that the long
 * position chain overlaps the loads (bench/bench_stolt.py times it).
 * params: K0 = kx_first + 2 k0, dkx, A = c / (4 pi df), Bc = -(f0 + f_first) / df. */
#include "interp.h"

__kernel void stolt_map(__global const float2 *src, __global const float *taps,
                        __global const double *ku2, const double4 params, const int n_src,
                        const int n_out, const int n_rows, __global float2 *dst)
{
    ROW_ITEM(src, dst, n_src, n_out, n_rows);
    /* the first output exactly in double; output l of the work-item relative to it in float,
     * d = l dkx: sqrt((K + d)^2 + k_u^2) - sqrt(K^2 + k_u^2) = d (2K + d) / (s_l + s_0), no
     * cancellation, so x = idx - floor(idx_0) is a small float (< 16 BLOCKS + 1) with error
     * ~1e-5 sample */
    const double k_first = params.s0 + j0 * params.s1;
    const double s_first = sqrt(k_first * k_first + ku2[r]), idx_first = s_first * params.s2 + params.s3;
    const int i_first = convert_int(idx_first) - (idx_first < 0.0 ? 1 : 0);
    const float kf = (float)k_first, ku2f = (float)ku2[r], sf = (float)s_first;
    const float frac = (float)(idx_first - (double)i_first), a = (float)params.s2, dkx = (float)params.s1;
    /* all positions first, then the interpolations: the position chain (sqrt, divide,
     * floor) of one block then overlaps the loads and sums of the others */
    int16 i[BLOCKS];
    float16 w[BLOCKS];
#pragma unroll
    for (int b = 0; b < BLOCKS; ++b) {
        const float16 d = dkx * ((float16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15) + 16.0f * b);
        const float16 s_l = sqrt((kf + d) * (kf + d) + ku2f);
        const float16 x = frac + a * (d * (2.0f * kf + d) / (s_l + sf));
        int16 fl = convert_int16(x);
        fl += convert_int16(x < convert_float16(fl));  /* floor (a true compare is -1) */
        i[b] = i_first + snapped(fl, x - convert_float16(fl), &w[b]);
    }
    interpolate_blocks(row, taps, i, w, n_src, o, n_out - j0);
}
