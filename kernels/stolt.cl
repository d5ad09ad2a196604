/* Stolt mapping of a wavenumber-domain spectrum (the interpolation step of omega-k), and the
 * same interpolators at explicit positions (range-cell migration, micro-range shifts).
 *
 * NumPy twins: clsas/image/stolt.py (stolt_reference, resample_rows); launchers in the same
 * module.
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
 * INTERP_LINEAR: (1 - w) s[i] + w s[i + 1]; otherwise TAPS (8 or 16) windowed-sinc taps
 * s[i - TAPS/2 + 1 + t] weighted by the row of the tap table nearest to w (TAP_ROWS rows over
 * w in [0, 1]); i = floor(idx), w = idx - i, except that w >= 1 - 1/(2 (TAP_ROWS - 1)) reads as
 * (i + 1, w - 1) (a position a rounding error below an integer is that integer, in the kernel
 * and the reference alike). An output reads as zero unless all its source
 * samples exist.
 *
 * One work-item: BLOCKS x 16 consecutive outputs of a row (float16 lanes, one block of 16 at a
 * time), global size (ceil(n_out / (16 BLOCKS)), n_rows); all of its positions are computed before
 * any interpolation, so that the long position chain overlaps the loads (4 blocks: 23 ms for a
 * 4096^2 sinc8 map where one block a work-item took 30 ms).
 * params: K0 = kx_first + 2 k0, dkx, A = c / (4 pi df), Bc = -(f0 + f_first) / df. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#define BLOCKS 4  /* blocks of 16 outputs a work-item (OUTPUTS_PER_ITEM = 16 BLOCKS in stolt.py) */

#include "loads.h"
#include "lanes.h"

/* Sample index of floor fl and fraction frac in [0, 1): a fraction within half a tap row of 1
 * reads as (fl + 1, frac - 1), as in the reference, so that exact integers decide the edge
 * test the same way in both; the fraction goes to *w. */
inline int16 snapped(const int16 fl, const float16 frac, float16 *w)
{
    const int16 up = frac >= 1.0f - 0.5f / (TAP_ROWS - 1);  /* -1 where true */
    *w = select(frac, frac - 1.0f, up);
    return fl - up;
}

/* Store sixteen complex outputs (lo: the first eight, hi: the rest, re/im interleaved) at o,
 * or only the first n_left of them at the end of a row. */
inline void store16(const float16 lo, const float16 hi, __global float *o, const int n_left)
{
    if (n_left >= 16) {
        STORE_F16(lo, o);
        STORE_F16(hi, o + 16);
        return;
    }
    float part[32];
    vstore16(lo, 0, part);
    vstore16(hi, 1, part);
    for (int k = 0; k < 2 * n_left; ++k)
        o[k] = part[k];
}

#ifdef INTERP_LINEAR
/* Sixteen outputs by linear interpolation at samples i + w (complex samples of row). */
inline void interpolate16(__global const float *row, __global const float *taps, const int16 i,
                          const float16 w, const int n_src, __global float *o, const int n_left)
{
    const int16 ok = i >= 0 && i < n_src - 1;
#define V(L) (ok.s##L ? mix(LOAD_F4(row + 2 * i.s##L).lo, LOAD_F4(row + 2 * i.s##L).hi, w.s##L) : (float2)0.0f)
    store16((float16)(V(0), V(1), V(2), V(3), V(4), V(5), V(6), V(7)),
            (float16)(V(8), V(9), V(a), V(b), V(c), V(d), V(e), V(f)), o, n_left);
#undef V
}
#else
/* Sixteen outputs by the TAPS-tap windowed sinc at samples i + w. */
inline void interpolate16(__global const float *row, __global const float *taps, const int16 i,
                          const float16 w, const int n_src, __global float *o, const int n_left)
{
    const int16 first_raw = i - (TAPS / 2 - 1);
    const int16 ok = first_raw >= 0 && first_raw <= n_src - TAPS;
    const int16 first = 2 * clamp(first_raw, 0, n_src - TAPS);
    const int16 t_row = convert_int16(w * (float)(TAP_ROWS - 1) + 0.5f);
    /* lane L's complex products: its TAPS samples (re, im interleaved) times the row's taps,
     * each tap repeated for re and im; TAPS = 16 adds the second half first */
#if TAPS == 8
#define P(L) (LOAD_F16(row + first.s##L) * LOAD_F8(taps + 8 * t_row.s##L).s0011223344556677)
#elif TAPS == 16
#define P(L) (LOAD_F16(row + first.s##L) * LOAD_F16(taps + 16 * t_row.s##L).lo.s0011223344556677      \
              + LOAD_F16(row + first.s##L + 16) * LOAD_F16(taps + 16 * t_row.s##L).hi.s0011223344556677)
#else
#error "TAPS must be 8 or 16"
#endif
    const float16 lo = csum8(P(0), P(1), P(2), P(3), P(4), P(5), P(6), P(7));
    const float16 hi = csum8(P(8), P(9), P(a), P(b), P(c), P(d), P(e), P(f));
    store16(select((float16)0.0f, lo, ok.s0011223344556677), select((float16)0.0f, hi, ok.s8899aabbccddeeff),
            o, n_left);
#undef P
}
#endif

/* A work-item's BLOCKS x 16 outputs from its positions i + w (n_left: outputs left in the row). */
inline void interpolate_blocks(__global const float *row, __global const float *taps, const int16 *i,
                               const float16 *w, const int n_src, __global float *o, const int n_left)
{
#pragma unroll
    for (int b = 0; b < BLOCKS; ++b)
        interpolate16(row, taps, i[b], w[b], n_src, o + 32 * b, n_left - 16 * b);
}

__kernel void stolt_map(__global const float2 *src, __global const float *taps,
                        __global const double *ku2, const double4 params, const int n_src,
                        const int n_out, __global float2 *dst)
{
    const int j0 = 16 * BLOCKS * get_global_id(0), r = get_global_id(1);
    /* the first output exactly in double; output l of the work-item relative to it in float,
     * d = l dkx: sqrt((K + d)^2 + k_u^2) - sqrt(K^2 + k_u^2) = d (2K + d) / (s_l + s_0), no
     * cancellation, so x = idx - floor(idx_0) is a small float (< 16 BLOCKS + 1) with error
     * ~1e-5 sample */
    const double k_first = params.s0 + j0 * params.s1;
    const double s_first = sqrt(k_first * k_first + ku2[r]), idx_first = s_first * params.s2 + params.s3;
    const int i_first = convert_int(idx_first) - (idx_first < 0.0 ? 1 : 0);
    const float kf = (float)k_first, ku2f = (float)ku2[r], sf = (float)s_first;
    const float frac = (float)(idx_first - (double)i_first), a = (float)params.s2, dkx = (float)params.s1;
    __global const float *row = (__global const float *)(src + (size_t)r * n_src);
    __global float *o = (__global float *)(dst + (size_t)r * n_out + j0);
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

/* Rows of src (n_src complex samples each) read at explicit fractional columns idx (double):
 * row r's positions start at idx + r * idx_row_stride (0: one row of positions shared by every
 * row). Same interpolators, edges and work-item layout as stolt_map. */
__kernel void resample_map(__global const float2 *src, __global const float *taps,
                           __global const double *idx, const int idx_row_stride, const int n_src,
                           const int n_out, __global float2 *dst)
{
    const int j0 = 16 * BLOCKS * get_global_id(0), r = get_global_id(1);
    __global const double *pos = idx + (size_t)r * idx_row_stride + j0;
    __global const float *row = (__global const float *)(src + (size_t)r * n_src);
    __global float *o = (__global float *)(dst + (size_t)r * n_out + j0);
    int16 i[BLOCKS];
    float16 w[BLOCKS];
#pragma unroll
    for (int b = 0; b < BLOCKS; ++b) {
        double16 p;
        if (n_out - j0 - 16 * b >= 16) {
            p = LOAD_D16(pos + 16 * b);
        } else {  /* the end of a row: repeat its last position */
            double part[16];
            for (int k = 0; k < 16; ++k)
                part[k] = pos[min(16 * b + k, n_out - 1 - j0)];
            p = vload16(0, part);
        }
        int16 fl = convert_int16(p);
        fl += convert_int16(p < convert_double16(fl));  /* floor (a true compare is -1) */
        i[b] = snapped(fl, convert_float16(p - convert_double16(fl)), &w[b]);
    }
    interpolate_blocks(row, taps, i, w, n_src, o, n_out - j0);
}
