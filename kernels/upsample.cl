/* Upsampling of complex records by a polyphase Kaiser-windowed-sinc FIR (OpenCL C 1.2).
 *
 * NumPy twin: clsas/image/upsample.py (upsample_reference; the tap table and the launcher are
 * there too). Defines: FACTOR (the upsampling factor, 2..64), TAPS (even: the original samples
 * each output reads), PHASE_VECS = ceil(FACTOR / 8) (the float16 vectors of one original
 * sample's outputs).
 *
 * Output q = FACTOR (j - first) + p of a row is the record at original position j + p / FACTOR:
 * p = 0 is the sample itself (copied), p > 0 is sum_t taps[p][t] s[j - HALF + t], samples outside
 * the record read as zero. Every output is the same chain of fma() in t's order, whichever
 * work-item and lane computes it, so a record upsampled over any span gives the same samples,
 * bit for bit.
 *
 * Work-item: 8 consecutive original samples j of one row. Lanes run over the phases: vector v of
 * sample j holds outputs FACTOR j + 8 v .. FACTOR j + 8 v + 7, (real, imaginary) interleaved as
 * in the output, so each is one contiguous store; a step t multiplies the sample s[j - HALF + t],
 * broadcast to every lane, by the step's tap vector (each phase's tap twice, zero past the last
 * phase: ``taps``, made by clsas/image/upsample.py's phase_vectors). Explicit float16 vectors
 * (PoCL does not vectorise a looping kernel across work-items: POCL_NOTES.md).
 */
#include "loads.h"

#define HALF (TAPS / 2 - 1) /* an output between j and j + 1 reads samples j - HALF .. j - HALF + TAPS - 1 */
#define TAIL (2 * FACTOR - 16 * (PHASE_VECS - 1)) /* floats of the last vector that are outputs */

/* sample i of a row of n as (re, im) in every lane pair; zero outside [0, n) when GUARD */
#define SAMPLE(i) (GUARD ? ((i) >= 0 && (i) < n_src ? (float16)(row[2 * (i)], row[2 * (i) + 1], row[2 * (i)], row[2 * (i) + 1], \
                                                                 row[2 * (i)], row[2 * (i) + 1], row[2 * (i)], row[2 * (i) + 1], \
                                                                 row[2 * (i)], row[2 * (i) + 1], row[2 * (i)], row[2 * (i) + 1], \
                                                                 row[2 * (i)], row[2 * (i) + 1], row[2 * (i)], row[2 * (i) + 1]) \
                                                      : (float16)0.0f)                                              \
                           : as_float16((double8)(pairs[(i) - s0])))

/* The 8 samples' outputs of phase vector v, over taps t in order (acc[k] for sample j0 + k) */
#define PHASE_VECTOR(GUARD_)                                                                          \
    {                                                                                                 \
        const int GUARD = (GUARD_);                                                                   \
        float16 acc[8];                                                                               \
        _Pragma("unroll") for (int k = 0; k < 8; ++k) acc[k] = (float16)0.0f;                        \
        for (int t = 0; t < TAPS; ++t) {                                                              \
            const float16 h = LOAD_F16(taps + 16 * (v * TAPS + t));                                   \
            _Pragma("unroll") for (int k = 0; k < 8; ++k) acc[k] = fma(h, SAMPLE(s0 + k + t), acc[k]); \
        }                                                                                             \
        if (v == 0) /* phase 0: the sample itself */                                                 \
            _Pragma("unroll") for (int k = 0; k < 8; ++k) {                                           \
                const float16 x = SAMPLE(s0 + k + HALF);                                              \
                acc[k] = select(acc[k], x, (int16)(-1, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0));  \
            }                                                                                         \
        _Pragma("unroll") for (int k = 0; k < 8; ++k) {                                               \
            if (k < count) {                                                                          \
                __global float *o = out + 2 * FACTOR * k + 16 * v;                                    \
                if (v < PHASE_VECS - 1 || TAIL == 16) {                                               \
                    STORE_F16(acc[k], o);                                                             \
                } else {                                                                              \
                    float part[16];                                                                   \
                    vstore16(acc[k], 0, part);                                                        \
                    for (int i = 0; i < TAIL; ++i)                                                    \
                        o[i] = part[i];                                                               \
                }                                                                                     \
            }                                                                                         \
        }                                                                                             \
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
        if (inside)
            PHASE_VECTOR(0)
        else
            PHASE_VECTOR(1)
    }
}
