/* Element-wise checks of the common.h helpers.
 * NumPy twin: clsas/kernelmath.py (rotate_phase, kaiser_sinc_taps).
 */
#include "common.h"

/* y[i] = x[i] * exp(j 2 pi cycles[i]) */
__kernel void rotate_phase(__global const complex_t *x, __global const real_t *cycles,
                           __global complex_t *y)
{
    size_t i = get_global_id(0);
    y[i] = complex_mul(x[i], expj_cycles(cycles[i]));
}

/* taps[i] = kaiser_sinc_tap(offsets[i], half_width, beta) */
__kernel void kaiser_sinc_taps(__global const real_t *offsets, const real_t half_width,
                               const real_t beta, __global real_t *taps)
{
    size_t i = get_global_id(0);
    taps[i] = kaiser_sinc_tap(offsets[i], half_width, beta);
}

/* (cs[i], sn[i]) = exp(j 2 pi r[i]) by the float polynomial of common.h, r in (-1, 1) */
__kernel void expj_fractions(__global const float *r, __global float2 *out)
{
    size_t i = get_global_id(0);
    float cs, sn;
    expj_fraction(r[i], &cs, &sn);
    out[i] = (float2)(cs, sn);
}
