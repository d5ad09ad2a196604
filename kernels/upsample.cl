/* Upsampling of complex records by a polyphase Kaiser-windowed-sinc FIR (OpenCL C 1.2).
 *
 * NumPy twin: clsas/image/upsample.py (upsample_reference; the tap table and the launcher are
 * there too). Defines: FACTOR (the upsampling factor, 2..64), TAPS (even: the original samples
 * each output reads), PHASE_VECS = ceil(FACTOR / 8) (the float16 vectors of one original
 * sample's outputs), MIRROR (1 for FACTOR <= 8: the mirrored phases' pass, below), MIRROR_PASS (optional:
 * the mirrored pairs a pass, chosen by the target when not given; the tests force each).
 *
 * Output q = FACTOR (j - first) + p of a row is the record at original position j + p / FACTOR:
 * p = 0 is the sample itself (copied), p > 0 is sum_t taps[p][t] s[j - HALF + t], samples outside
 * the record read as zero. Every output is the same chain of fma() in t's order, whichever
 * work-item and lane computes it, so a record upsampled over any span gives the same samples,
 * bit for bit.
 *
 * Work-item: 8 consecutive original samples j0 .. j0 + 7 of one row, phase vector v (phases
 * 8 v .. 8 v + 7) at a time. Accumulator q holds phase 8 v + q of the 8 samples, (real,
 * imaginary) interleaved: a step t multiplies the 8 consecutive samples s[j0 - HALF + t + k] (one
 * unaligned vector load) by the phase's tap (a scalar, broadcast), so a step is 8 FMAs and
 * 9 loads and no lane shuffle (a broadcast of each sample to every phase's lane cost a shuffle an
 * FMA: the kernel was bound by them); phase 0 is the sample itself (no FMA). The accumulators
 * (phases x samples) are transposed (three rounds of two-source permutes of the complex samples
 * as doubles) into each sample's FACTOR outputs, one contiguous store a sample and phase vector
 * as before. Explicit float16 vectors (PoCL does not vectorise a looping kernel across
 * work-items: POCL_NOTES.md). ``taps``: phase_vectors' table (vector v at step t, lane 2 q, is
 * phase 8 v + q's tap), read a lane at a time.
 *
 * MIRROR (FACTOR <= 8, one phase vector): phase FACTOR - q's taps are phase q's reversed
 * (h_{FACTOR - q}[t] = h_q[TAPS - 1 - t]: the windowed sinc is even), so both come from one pass over
 * the sample pairs a = s[j - HALF + t], b = s[j - HALF + TAPS - 1 - t], t < TAPS / 2: S_q (a + b) and
 * D_q (a - b) summed by fma() in t's order (S_q, D_q = (h_q[t] +- h_q[TAPS - 1 - t]) / 2, rounded
 * from double: mirror_vectors' table, lane 2 q and 2 q + 1 of row t), phase q their sum, phase
 * FACTOR - q their difference, phase FACTOR / 2 the S sum alone: half the FMAs (within float
 * rounding of the direct form and of the twin, and still the same operations for an output whichever
 * work-item computes it).
 */
#include "loads.h"

#define HALF (TAPS / 2 - 1) /* an output between j and j + 1 reads samples j - HALF .. j - HALF + TAPS - 1 */
#define TAIL (2 * FACTOR - 16 * (PHASE_VECS - 1)) /* floats of the last vector that are outputs */
#ifndef MIRROR_PASS /* mirrored pairs a pass (1, 2 or 4: the same sums in the same order whichever): by the target */
#if defined(__AVX512F__)
#define MIRROR_PASS 4 /* all seven accumulators, in 32 vector registers */
#else
#define MIRROR_PASS 2 /* 16 vector registers (AVX2: a float16 is two): two pairs a pass, no spills */
#endif
#endif

/* samples i .. i + 7 of a row of n_src as (re, im) pairs: pairs[i - s0] in place when the work-item's
 * samples all lie inside the row, else one at a time, zero outside [0, n_src) */
inline float16 eight_samples(__global const float *row, __global const double *pairs, int inside, int i, int s0,
                             int n_src)
{
    if (inside)
        return as_float16(LOAD_D8(pairs + (i - s0)));
    double8 x = (double8)0.0;
    __global const double *at = (__global const double *)row;
#define GUARDED(k) x.s##k = (i + k >= 0 && i + k < n_src) ? at[i + k] : 0.0;
    GUARDED(0) GUARDED(1) GUARDED(2) GUARDED(3) GUARDED(4) GUARDED(5) GUARDED(6) GUARDED(7)
#undef GUARDED
    return as_float16(x);
}

/* src: n_rows rows of n_src complex samples; dst: n_rows rows of n_kept FACTOR outputs, the
 * upsampled original samples first .. first + n_kept - 1; taps: PHASE_VECS x TAPS float16 tap
 * vectors. Global size (ceil(n_kept / 8), rows padded). */
__kernel void upsample_fir(__global const float2 *src, const int n_src, const int n_rows, const int first,
                           const int n_kept, __global const float *taps, __global float2 *dst)
{
    const int j0 = 8 * get_global_id(0), r = get_global_id(1);
    if (r >= n_rows || j0 >= n_kept)
        return;
    __global const float *row = (__global const float *)(src + (size_t)r * n_src);
    __global float *out = (__global float *)(dst + ((size_t)r * n_kept + j0) * FACTOR);
    const int s0 = first + j0 - HALF, count = min(8, n_kept - j0);
    const int inside = s0 >= 0 && s0 + 7 + TAPS - 1 < n_src;
    __global const double *pairs = (__global const double *)row + (inside ? s0 : 0); /* sample s0 + i at pairs[i] */
    for (int v = 0; v < PHASE_VECS; ++v) {
        const int phases = min(8, FACTOR - 8 * v); /* phases of this vector that are outputs */
        float16 acc[8];
        _Pragma("unroll") for (int q = 0; q < 8; ++q) acc[q] = (float16)0.0f;
#if MIRROR
        /* phases q and FACTOR - q read the same samples with mirrored taps: a step pairs samples t
         * and TAPS - 1 - t (a = s[s0 + t], b = s[s0 + TAPS - 1 - t]) and sums S_q (a + b) and
         * D_q (a - b); phase q is their sum, FACTOR - q their difference (FACTOR / 2: S alone) */
        (void)phases;
        /* MIRROR_PASS pairs (q, FACTOR - q) a pass over the samples: one pass of all of them where
         * the target has 32 vector registers, two (q = 1, 2 then 3, 4) with 16 (AVX2, where one pass
         * spilled and was slower than the direct form) */
        _Pragma("unroll") for (int pass = 0; pass < 4 / MIRROR_PASS; ++pass) {
            if (2 * MIRROR_PASS * pass + 2 > FACTOR)
                continue;
            float16 acc_s[MIRROR_PASS], acc_d[MIRROR_PASS];
            _Pragma("unroll") for (int k = 0; k < MIRROR_PASS; ++k) acc_s[k] = acc_d[k] = (float16)0.0f;
            for (int t = 0; t < TAPS / 2; ++t) {
                const float16 a = eight_samples(row, pairs, inside, s0 + t, s0, n_src);
                const float16 b = eight_samples(row, pairs, inside, s0 + TAPS - 1 - t, s0, n_src);
                const float16 sum = a + b, dif = a - b;
                _Pragma("unroll") for (int k = 0; k < MIRROR_PASS; ++k) {
                    const int q = MIRROR_PASS * pass + k + 1;
                    if (2 * q <= FACTOR)
                        acc_s[k] = fma((float16)taps[16 * t + 2 * q], sum, acc_s[k]);
                    if (2 * q < FACTOR)
                        acc_d[k] = fma((float16)taps[16 * t + 2 * q + 1], dif, acc_d[k]);
                }
            }
            _Pragma("unroll") for (int k = 0; k < MIRROR_PASS; ++k) {
                const int q = MIRROR_PASS * pass + k + 1;
                if (2 * q < FACTOR) {
                    acc[q] = acc_s[k] + acc_d[k];
                    acc[FACTOR - q] = acc_s[k] - acc_d[k];
                } else if (2 * q == FACTOR) {
                    acc[q] = acc_s[k];
                }
            }
        }
#else
        __global const float *h = taps + 16 * v * TAPS;
        for (int t = 0; t < TAPS; ++t) {
            const float16 x = eight_samples(row, pairs, inside, s0 + t, s0, n_src);
            _Pragma("unroll") for (int q = 0; q < 8; ++q) if ((v > 0 || q > 0) && q < phases)
                acc[q] = fma((float16)h[16 * t + 2 * q], x, acc[q]);
        }
#endif
        if (v == 0) /* phase 0: the sample itself */
            acc[0] = eight_samples(row, pairs, inside, s0 + HALF, s0, n_src);
        /* transpose: a[q].sk (phase q, sample k) -> o[k].sq */
        double8 a0 = as_double8(acc[0]), a1 = as_double8(acc[1]), a2 = as_double8(acc[2]), a3 = as_double8(acc[3]);
        double8 a4 = as_double8(acc[4]), a5 = as_double8(acc[5]), a6 = as_double8(acc[6]), a7 = as_double8(acc[7]);
        const double8 b0 = (double8)(a0.s0, a1.s0, a0.s2, a1.s2, a0.s4, a1.s4, a0.s6, a1.s6);
        const double8 b1 = (double8)(a0.s1, a1.s1, a0.s3, a1.s3, a0.s5, a1.s5, a0.s7, a1.s7);
        const double8 b2 = (double8)(a2.s0, a3.s0, a2.s2, a3.s2, a2.s4, a3.s4, a2.s6, a3.s6);
        const double8 b3 = (double8)(a2.s1, a3.s1, a2.s3, a3.s3, a2.s5, a3.s5, a2.s7, a3.s7);
        const double8 b4 = (double8)(a4.s0, a5.s0, a4.s2, a5.s2, a4.s4, a5.s4, a4.s6, a5.s6);
        const double8 b5 = (double8)(a4.s1, a5.s1, a4.s3, a5.s3, a4.s5, a5.s5, a4.s7, a5.s7);
        const double8 b6 = (double8)(a6.s0, a7.s0, a6.s2, a7.s2, a6.s4, a7.s4, a6.s6, a7.s6);
        const double8 b7 = (double8)(a6.s1, a7.s1, a6.s3, a7.s3, a6.s5, a7.s5, a6.s7, a7.s7);
        const double8 c0 = (double8)(b0.s01, b2.s01, b0.s45, b2.s45), c1 = (double8)(b1.s01, b3.s01, b1.s45, b3.s45);
        const double8 c2 = (double8)(b0.s23, b2.s23, b0.s67, b2.s67), c3 = (double8)(b1.s23, b3.s23, b1.s67, b3.s67);
        const double8 c4 = (double8)(b4.s01, b6.s01, b4.s45, b6.s45), c5 = (double8)(b5.s01, b7.s01, b5.s45, b7.s45);
        const double8 c6 = (double8)(b4.s23, b6.s23, b4.s67, b6.s67), c7 = (double8)(b5.s23, b7.s23, b5.s67, b7.s67);
        double8 o[8];
        o[0] = (double8)(c0.lo, c4.lo);
        o[1] = (double8)(c1.lo, c5.lo);
        o[2] = (double8)(c2.lo, c6.lo);
        o[3] = (double8)(c3.lo, c7.lo);
        o[4] = (double8)(c0.hi, c4.hi);
        o[5] = (double8)(c1.hi, c5.hi);
        o[6] = (double8)(c2.hi, c6.hi);
        o[7] = (double8)(c3.hi, c7.hi);
        _Pragma("unroll") for (int k = 0; k < 8; ++k) {
            if (k < count) {
                __global float *dest = out + 2 * FACTOR * k + 16 * v;
#if TAIL == 16
                STORE_F16(as_float16(o[k]), dest);
#else
                if (v < PHASE_VECS - 1) {
                    STORE_F16(as_float16(o[k]), dest);
                } else {
                    float part[16];
                    vstore16(as_float16(o[k]), 0, part);
                    for (int i = 0; i < TAIL; ++i)
                        dest[i] = part[i];
                }
#endif
            }
        }
    }
}
