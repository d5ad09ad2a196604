/* The interpolators of clsas on the kernel side: the nearest row of the shared tap table, and
 * sixteen lanes of rows read at fractional positions (linear or a TAPS-tap windowed sinc).
 *
 * NumPy twin: clsas/interp.py (tap_table, resample_rows; the launchers and the definitions are
 * there). Used by kernels/interp.cl (resample_map), kernels/stolt.cl (stolt_map) and
 * kernels/backprojection.cl (its records read at the pixels' delays).
 *
 * Defines: TAP_ROWS (rows of the tap table over the fractional offset [0, 1]); for the row
 * kernels (interpolate16, interpolate_blocks) INTERP_LINEAR or TAPS (8 or 16), and BLOCKS
 * (blocks of 16 outputs a work-item), all from clsas/interp.py. Needs loads.h and lanes.h.
 *
 * Tap table (clsas.interp.kernel_taps): float, row m = nearest to the fractional offset
 * m / (TAP_ROWS - 1), TAPS taps of samples i - TAPS/2 + 1 .. i + TAPS/2, each row of unit sum.
 */
#ifndef CLSAS_INTERP_H
#define CLSAS_INTERP_H

#ifndef TAP_ROWS
#error "TAP_ROWS must be defined (clsas.interp.TAP_ROWS)"
#endif

/* The tap-table row nearest to fractional offsets w in [0, 1] (float or double, scalar or
 * vector; cvt the conversion to the matching int type, e.g. convert_int16). */
#define NEAREST_TAP_ROW(cvt, w) cvt((w) * (float)(TAP_ROWS - 1) + 0.5f)

/* The eight taps of row `row` of an 8-tap table, each repeated for the real and the imaginary
 * part of a complex sample (re, im interleaved): one float16 to multiply eight samples by. */
#define TAP_ROW8(taps, row) (LOAD_F8((taps) + 8 * (row)).s0011223344556677)

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
    /* lane L's complex products: its TAPS samples (re, im interleaved) times the row's taps,
     * each tap repeated for re and im; TAPS = 16 adds the second half first */
#if TAPS == 8
#define P(L) (LOAD_F16(row + first.s##L) * TAP_ROW8(taps, t_row.s##L))
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
#endif /* BLOCKS */

#endif /* CLSAS_INTERP_H */
