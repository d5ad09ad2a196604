/* Upsampling of complex records by a polyphase Kaiser-windowed-sinc FIR (OpenCL C 1.2).
 *
 * NumPy twin: clsas/image/upsample.py (upsample_reference; the tap table and the launcher are
 * there too). Defines: FACTOR (the upsampling factor, 2..64), TAPS (even: the original samples
 * each output reads).
 *
 * Output q = FACTOR (j - first) + p of a row is the record at original position j + p / FACTOR:
 * p = 0 is the sample itself (copied), p > 0 is sum_t taps[p][t] s[j - HALF + t], samples outside
 * the record read as zero. Every output is the same chain of fma() in t's order, whichever
 * work-item and lane computes it, so a record upsampled over any span gives the same samples,
 * bit for bit.
 *
 * Work-item: 8 consecutive original samples of one row (16 floats: real and imaginary parts
 * interleaved, filtered alike by the real taps), explicit float16 vectors (PoCL does not
 * vectorise a looping kernel across work-items: POCL_NOTES.md).
 */
#include "loads.h"

#define HALF (TAPS / 2 - 1) /* an output between j and j + 1 reads samples j - HALF .. j - HALF + TAPS - 1 */

/* The 8 complex samples s .. s + 7 of a row of n (zeros outside [0, n)), as 16 floats. */
inline float16 window8(__global const float *row, const int s, const int n)
{
    if (s >= 0 && s + 8 <= n)
        return LOAD_F16(row + 2 * s);
    float part[16];
    for (int k = 0; k < 8; ++k) {
        const int i = s + k;
        const int inside = i >= 0 && i < n;
        part[2 * k] = inside ? row[2 * i] : 0.0f;
        part[2 * k + 1] = inside ? row[2 * i + 1] : 0.0f;
    }
    return vload16(0, part);
}

/* src: n_rows rows of n_src complex samples; dst: n_rows rows of n_kept FACTOR outputs, the
 * upsampled original samples first .. first + n_kept - 1; taps: FACTOR x TAPS floats (row 0
 * unused: phase 0 copies). Global size (ceil(n_kept / 8), rows padded). */
__kernel void upsample_fir(__global const float2 *src, const int n_src, const int n_rows, const int first,
                           const int n_kept, __constant float *taps, __global float2 *dst)
{
    const int j0 = 8 * get_global_id(0), r = get_global_id(1);
    if (r >= n_rows || j0 >= n_kept)
        return;
    __global const float *row = (__global const float *)(src + (size_t)r * n_src);
    const int s0 = first + j0 - HALF;
    float16 acc[FACTOR];
#pragma unroll
    for (int p = 1; p < FACTOR; ++p)
        acc[p] = (float16)(0.0f);
#pragma unroll
    for (int t = 0; t < TAPS; ++t) {
        const float16 x = window8(row, s0 + t, n_src);
        if (t == HALF)
            acc[0] = x;
#pragma unroll
        for (int p = 1; p < FACTOR; ++p)
            acc[p] = fma((float16)(taps[p * TAPS + t]), x, acc[p]);
    }
    /* lane 2k + c of acc[p] is output FACTOR k + p (its real part for c = 0): interleave */
    float out[16 * FACTOR];
#pragma unroll
    for (int p = 0; p < FACTOR; ++p) {
        float lanes[16];
        vstore16(acc[p], 0, lanes);
#pragma unroll
        for (int k = 0; k < 8; ++k) {
            out[2 * (FACTOR * k + p)] = lanes[2 * k];
            out[2 * (FACTOR * k + p) + 1] = lanes[2 * k + 1];
        }
    }
    __global float *o = (__global float *)(dst + ((size_t)r * n_kept + j0) * FACTOR);
    if (j0 + 8 <= n_kept) {
#pragma unroll
        for (int q = 0; q < FACTOR; ++q)
            STORE_F16(vload16(q, out), o + 16 * q);
    } else {  /* the row's last, partial block */
        for (int i = 0; i < 2 * FACTOR * (n_kept - j0); ++i)
            o[i] = out[i];
    }
}
