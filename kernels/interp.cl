/* Rows of samples read at explicit fractional positions (range-cell migration, micro-range
 * shifts): the interpolators of kernels/interp.h.
 *
 * NumPy twin: clsas/interp.py (resample_rows); the launcher is in the same module (resample).
 *
 * Defines: INTERP_LINEAR or TAPS (8 or 16), TAP_ROWS, BLOCKS (kernels/interp.h). One work-item:
 * BLOCKS x 16 consecutive outputs of a row (interp.h's ROW_ITEM, as stolt_map's).
 */
#include "interp.h"

/* Rows of src (n_src complex samples each) read at explicit fractional columns idx (double):
 * row r's positions start at idx + r * idx_row_stride (0: one row of positions shared by every
 * row). Same interpolators, edges and work-item layout as stolt_map. */
__kernel void resample_map(__global const float2 *src, __global const float *taps,
                           __global const double *idx, const int idx_row_stride, const int n_src,
                           const int n_out, const int n_rows, __global float2 *dst)
{
    ROW_ITEM(src, dst, n_src, n_out, n_rows);
    __global const double *pos = idx + (size_t)r * idx_row_stride + j0;
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
