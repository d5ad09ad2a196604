/* The interpolators of clsas on the kernel side: the nearest row of the shared tap table, the
 * one 8-tap windowed-sinc loop every kernel uses (sinc8_lanes), and sixteen lanes of rows read at
 * fractional positions (linear or a TAPS-tap windowed sinc) with the row kernels' work-item.
 *
 * NumPy twin: clsas/interp.py (tap_table, resample_rows; the launchers and the definitions are
 * there). Used by kernels/interp.cl (resample_map), kernels/stolt.cl (stolt_map),
 * kernels/bp_tile.cl and kernels/bp_block.cl (their records read at the pixels' delays) and
 * kernels/ffbp.cl (the merge's range taps).
 *
 * Defines: TAP_ROWS (rows of the tap table over the fractional offset [0, 1]); for the row
 * kernels (ROW_ITEM, interpolate16, interpolate_blocks) INTERP_LINEAR or TAPS (8 or 16), and
 * BLOCKS (blocks of 16 outputs a work-item), all from clsas/interp.py. Includes loads.h and
 * lanes.h (and enables fp64).
 *
 * Tap table (clsas.interp.kernel_taps): float, row m = nearest to the fractional offset
 * m / (TAP_ROWS - 1), TAPS taps of samples i - TAPS/2 + 1 .. i + TAPS/2, each row of unit sum.
 */
#ifndef CLSAS_INTERP_H
#define CLSAS_INTERP_H

#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "loads.h"
#include "lanes.h"

#ifndef TAP_ROWS
#error "TAP_ROWS must be defined (clsas.interp.TAP_ROWS)"
#endif

/* The tap-table row nearest to fractional offsets w in [0, 1] (float or double, scalar or
 * vector; cvt the conversion to the matching int type, e.g. convert_int16). */
#define NEAREST_TAP_ROW(cvt, w) cvt((w) * (float)(TAP_ROWS - 1) + 0.5f)

/* The eight taps of row `row` of an 8-tap table, each repeated for the real and the imaginary
 * part of a complex sample (re, im interleaved): one float16 to multiply eight samples by. */
#define TAP_ROW8(taps, row) (LOAD_F8((taps) + 8 * (row)).s0011223344556677)

/* The 8-tap windowed sinc of eight lanes, the one tap loop of clsas's kernels: lane L's eight
 * complex samples wL (re, im interleaved: the samples i - 3 .. i + 4 around its position i + w)
 * times the taps of its row rows.sL of the 8-tap table (each tap applied to re and im), summed
 * across the lanes by csum8 (lanes.h): the eight lanes' interpolated values, re/im interleaved.
 * sinc8_lanes_double: the same for double samples (the float taps converted). */
#define CLSAS_SINC8_LANES(NAME, T, CSUM, CVT)                                                        \
    inline T NAME(__global const float *taps, const int8 rows, const T w0, const T w1, const T w2,    \
                  const T w3, const T w4, const T w5, const T w6, const T w7)                         \
    {                                                                                                \
        return CSUM(w0 * CVT(TAP_ROW8(taps, rows.s0)), w1 * CVT(TAP_ROW8(taps, rows.s1)),            \
                    w2 * CVT(TAP_ROW8(taps, rows.s2)), w3 * CVT(TAP_ROW8(taps, rows.s3)),            \
                    w4 * CVT(TAP_ROW8(taps, rows.s4)), w5 * CVT(TAP_ROW8(taps, rows.s5)),            \
                    w6 * CVT(TAP_ROW8(taps, rows.s6)), w7 * CVT(TAP_ROW8(taps, rows.s7)));           \
    }

CLSAS_SINC8_LANES(sinc8_lanes, float16, csum8, )
#ifdef cl_khr_fp64
CLSAS_SINC8_LANES(sinc8_lanes_double, double16, csum8_double, convert_double16)
#endif

/* Sample index of floor fl and fraction frac in [0, 1): a fraction within half a tap row of 1
 * reads as (fl + 1, frac - 1), as in the reference, so that exact integers decide the edge
 * test the same way in both; the fraction goes to *w. */
inline int16 snapped(const int16 fl, const float16 frac, float16 *w)
{
    const int16 up = frac >= 1.0f - 0.5f / (TAP_ROWS - 1);  /* -1 where true */
    *w = select(frac, frac - 1.0f, up);
    return fl - up;
}

#ifdef BLOCKS
/* A row kernel's work-item (global size (ceil(n_out / (16 BLOCKS)), n_rows padded to whole
 * work-groups: opencl.work_groups_2d, so that the kernel is compiled once whatever the rows;
 * src, dst complex rows of n_src and n_out samples): its first output j0 of row r, that row's
 * source samples (float re, im) and its outputs from j0 on; a work-item past the last row returns. */
#define ROW_ITEM(src, dst, n_src, n_out, n_rows)                                                     \
    const int j0 = 16 * BLOCKS * get_global_id(0), r = get_global_id(1);                             \
    if (r >= (n_rows))                                                                               \
        return;                                                                                      \
    __global const float *row = (__global const float *)((src) + (size_t)r * (n_src));               \
    __global float *o = (__global float *)((dst) + (size_t)r * (n_out) + j0)

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
    const int16 t_row = NEAREST_TAP_ROW(convert_int16, w);
#if TAPS == 8
#define W(L) LOAD_F16(row + first.s##L)
    const float16 lo = sinc8_lanes(taps, t_row.lo, W(0), W(1), W(2), W(3), W(4), W(5), W(6), W(7));
    const float16 hi = sinc8_lanes(taps, t_row.hi, W(8), W(9), W(a), W(b), W(c), W(d), W(e), W(f));
#undef W
#elif TAPS == 16
    /* lane L's complex products: its 16 samples (re, im interleaved) times the row's taps, each
     * tap repeated for re and im, the second half added first */
#define P(L) (LOAD_F16(row + first.s##L) * LOAD_F16(taps + 16 * t_row.s##L).lo.s0011223344556677      \
              + LOAD_F16(row + first.s##L + 16) * LOAD_F16(taps + 16 * t_row.s##L).hi.s0011223344556677)
    const float16 lo = csum8(P(0), P(1), P(2), P(3), P(4), P(5), P(6), P(7));
    const float16 hi = csum8(P(8), P(9), P(a), P(b), P(c), P(d), P(e), P(f));
#undef P
#else
#error "TAPS must be 8 or 16"
#endif
    store16(select((float16)0.0f, lo, ok.s0011223344556677), select((float16)0.0f, hi, ok.s8899aabbccddeeff),
            o, n_left);
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
#endif /* BLOCKS */

#endif /* CLSAS_INTERP_H */
