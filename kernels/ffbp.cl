/* Fast factorised back-projection: the merge of child polar images into a parent polar grid
 * (PARENT_GRID) or onto explicit points (the final stage onto the user's pixels).
 *
 * NumPy twin: clsas/image/ffbp/merge.py (merge_reference); launcher merge_opencl there.
 *
 * One work-item per output sample X: a parent sample (i, j) -> X(r, v) on the reference plane
 * (clsas/image/ffbp/polar.py, PolarGrid.points), or points[id]. For every child k:
 * r_c = |X - C_k|, v_c = u_k . (X - C_k) / r_c, positions (r_c - r0) / dr and (v_c - v0) / dv,
 * the TAPS x TAPS windowed-sinc read of the child's image (n_v, n_r, range fastest; taps from
 * the nearest of TAP_ROWS table rows; nothing unless every sample exists), times
 * exp(j 2 pi 2 f0 (r_c - r_p) / c) with r_p the parent's range (0 for points). Geometry,
 * positions and cycles in double (ranges of kilometres at 150 kHz need it), the interpolation
 * and the sum in float.
 *
 * frames (double, 20 a child): centre 0-2, axis 3-5, e1 6-8, e2 9-11, r0 12, dr 13, v0 14,
 * dv 15, n_r 16, n_v 17. params (double): the parent's frame 0-19 (PARENT_GRID), the plane's
 * normal 20-22 and offset 23, 2 f0 / c (cycles per metre) 24.
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#include "common.h"
#include "loads.h"

#define FRAME 20

#ifdef PARENT_GRID
/* X(r, v) of parent sample (i, j) (PolarGrid.points) */
inline double3 parent_point(__global const double *p, const int i, const int j, double *r_out)
{
    const double r = p[12] + i * p[13], v = p[14] + j * p[15];
    const double3 cen = vload3(0, p), ax = vload3(1, p), e1 = vload3(2, p), e2 = vload3(3, p);
    const double3 m = vload3(0, p + 20);
    const double rho = r * sqrt(fmax(1.0 - v * v, 0.0));
    double s = rho > 0.0 ? (p[23] - dot(m, cen) - r * v * dot(m, ax)) / (rho * dot(m, e2)) : 0.0;
    s = clamp(s, -1.0, 1.0);
    *r_out = r;
    return cen + (r * v) * ax + (rho * sqrt(1.0 - s * s)) * e1 + (rho * s) * e2;
}
#endif

__kernel void ffbp_merge(__global const float2 *images, __global const long *offsets,
                         __global const double *frames, __global const float *taps,
                         __global const double *points, __global const double *params,
                         const int n_children, const int n_out, __global float2 *out)
{
    const int id = get_global_id(0);
    if (id >= n_out)
        return;
    double r_p = 0.0;
#ifdef PARENT_GRID
    const int n_r_parent = (int)params[16];
    const int j = id / n_r_parent;
    const double3 x = parent_point(params, id - j * n_r_parent, j, &r_p);
#else
    const double3 x = vload3(id, points);
#endif
    const double cycles_per_m = params[24];
    float2 acc = (float2)(0.0f, 0.0f);
    for (int k = 0; k < n_children; ++k) {
        __global const double *f = frames + FRAME * k;
        const double3 d = x - vload3(0, f);
        const double rc = sqrt(dot(d, d));
        const double pv = (dot(d, vload3(1, f)) / rc - f[14]) / f[15], pr = (rc - f[12]) / f[13];
        if (!(pv >= 0.0 && pr >= 0.0))  /* outside the image (every read needs a whole window) */
            continue;
        const int fv = convert_int(pv), fr = convert_int(pr);  /* floor of a non-negative value
                                                                    (PoCL's floor() is a slow emulation) */
        const int iv = fv - (TAPS / 2 - 1), ir = fr - (TAPS / 2 - 1);
        const int n_r = (int)f[16], n_v = (int)f[17];
        if (iv < 0 || iv > n_v - TAPS || ir < 0 || ir > n_r - TAPS)
            continue;
        const int row_v = convert_int((pv - fv) * (TAP_ROWS - 1) + 0.5);
        const int row_r = convert_int((pr - fr) * (TAP_ROWS - 1) + 0.5);
        __global const float *img = (__global const float *)(images + offsets[k] + (long)iv * n_r + ir);
        __global const float *tv = taps + TAPS * row_v;
#if TAPS == 8
        const float16 tr = LOAD_F8(taps + 8 * row_r).s0011223344556677;
        float16 sum = (float16)0.0f;
        for (int a = 0; a < 8; ++a)
            sum += tv[a] * (LOAD_F16(img + 2 * a * n_r) * tr);
        const float8 h = sum.lo + sum.hi;
#elif TAPS == 4
        const float8 tr = LOAD_F4(taps + 4 * row_r).s00112233;
        float8 h = (float8)0.0f;
        for (int a = 0; a < 4; ++a)
            h += tv[a] * (LOAD_F8(img + 2 * a * n_r) * tr);
#else
#error "TAPS must be 4 or 8"
#endif
        const float4 q = h.lo + h.hi;
        const float2 val = q.lo + q.hi;
        const double cycles = cycles_per_m * (rc - r_p);
        float cs, sn;
        expj_fraction((float)(cycles - (double)convert_long(cycles)), &cs, &sn);
        acc += (float2)(val.x * cs - val.y * sn, val.x * sn + val.y * cs);
    }
#ifdef PARENT_GRID
    out[id] = acc;
#else
    out[id] += acc;
#endif
}
