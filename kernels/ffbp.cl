/* Fast factorised back-projection: the merge of child polar images into a parent polar grid
 * (PARENT_GRID) or onto explicit points (the final stage onto the user's pixels).
 *
 * NumPy twin: clsas/image/ffbp/merge.py (merge_reference); launcher merge_opencl there.
 *
 * One work-item: sixteen output samples X (double16 lanes): sixteen consecutive range samples
 * i0 .. i0 + 15 of one parent row j, X(r, v) on the reference plane (clsas/image/ffbp/polar.py,
 * PolarGrid.points; global size (ceil(n_r / 16), n_v)), or points i0 .. i0 + 15 (global size
 * ceil(n_out / 16); the last work-item repeats the last point and stores only its own). For every
 * child k: r_c = |X - C_k|, v_c = u_k . (X - C_k) / r_c, positions (r_c - r0) / dr and
 * (v_c - v0) / dv, the TAPS x TAPS windowed-sinc read of the child's image (n_v, n_r, range
 * fastest; the taps of the nearest of TAP_ROWS table rows, interp.h; nothing unless every sample
 * exists; a child none of the sixteen lanes falls in is skipped, tested first on the lanes'
 * bounding box, then lane by lane), times
 * exp(j 2 pi 2 f0 (r_c - r_p) / c) with r_p the parent's range (0 for points). Geometry,
 * positions and cycles in double (ranges of kilometres at 150 kHz need it), vectorised over the
 * lanes (phases in cycles reduced by an int conversion, |cycles| < 2^31: ranges below ~10^4 km
 * at 150 kHz; AVX2 has no double <-> long vector conversion, PoCL makes it sixteen scalar ones);
 * the interpolation, the phase factor and the sum in float: each lane's TAPS rows of
 * TAPS complex samples times the range taps, weighted by the angle taps, and the lanes' complex
 * sums formed eight at a time across lanes (lanes.h). Sixteen whole points are loaded as three
 * double16 and de-interleaved in registers, and sixteen results all stored (none past the end or
 * zeroed outside a span) go out as two float16 (interleaved in registers): the lane-by-lane loops
 * remain for the last, partial work-item and a span's edges.
 *
 * The records (declared once by clsas/image/ffbp/program.py, put in front of this source):
 * ffbp_frame_t, a polar grid's frame (PolarGrid.record): centre, axis, e1, e2 (m, unit vectors),
 * the samples r0 + i dr (i < n_r) and v0 + j dv (j < n_v); ffbp_plane_t, the reference plane
 * normal . X = offset; ffbp_item_t, the first stage's work-items (leaf, row, sample, tile); and
 * bp_pixels_t, bp_tile's pixel fields (clsas/image/backprojection/tile_kernel.py).
 * ffbp_merge: frames[k] the children's frames, images holding the children at offsets (complex
 * samples), parent the parent's frame and spans its rows' computed samples [x, y) (PARENT_GRID:
 * samples outside them are written zero, and a work-item wholly outside writes only zeros),
 * plane, cycles_per_m = 2 f0 / c; the result goes to out from out_offset on (onto points it is
 * added into out, or with POINTS_STORE written over it: the final stage's first group, which
 * so needs no zeroed image; every point of the launch is written, those no child reaches as 0).
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#include "common.h"
#include "interp.h"

#define LANE_INDEX ((double16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))

/* One lane's read of a child image: its TAPS rows of TAPS samples (re, im interleaved) from s
 * (the window's first sample, rows n_r complex samples apart) summed over the rows weighted by
 * the angle taps of row row_v; zero for a lane outside the image. TAPS = 8: the lane's eight
 * complex samples of the range window (a float16), which interp.h's sinc8_lanes weights by the
 * range taps and sums eight lanes at a time; TAPS = 4: the lane's complex sum, range taps
 * applied. */
#if TAPS == 8
inline float16 lane_window(const int ok, __global const float *s, const int n_r, __global const float *taps,
                           const int row_v)
{
    float16 p = (float16)0.0f;
    if (ok) {
        __global const float *tv = taps + 8 * row_v;
        for (int a = 0; a < 8; ++a)
            p += tv[a] * LOAD_F16(s + 2 * a * n_r);
    }
    return p;
}
#define LANE_WINDOW(L) lane_window(ok.s##L, img + 2 * (iv.s##L * n_r + ir.s##L), n_r, taps, row_v.s##L)
#elif TAPS == 4
inline float2 lane_products(const int ok, __global const float *s, const int n_r, __global const float *taps,
                            const int row_v, const int row_r)
{
    float8 p = (float8)0.0f;
    if (ok) {
        __global const float *tv = taps + 4 * row_v;
        for (int a = 0; a < 4; ++a)
            p += tv[a] * LOAD_F8(s + 2 * a * n_r);
        p *= LOAD_F4(taps + 4 * row_r).s00112233;
    }
    const float4 q = p.lo + p.hi;
    return q.lo + q.hi;
}
#define LANE_PRODUCTS(L) lane_products(ok.s##L, img + 2 * (iv.s##L * n_r + ir.s##L), n_r, taps, row_v.s##L, row_r.s##L)
#else
#error "TAPS must be 4 or 8"
#endif

/* The smallest and the largest of sixteen lanes. */
inline double hmin16(const double16 a)
{
    const double8 b = fmin(a.lo, a.hi);
    const double4 c = fmin(b.lo, b.hi);
    const double2 d = fmin(c.lo, c.hi);
    return fmin(d.x, d.y);
}

inline double hmax16(const double16 a)
{
    const double8 b = fmax(a.lo, a.hi);
    const double4 c = fmax(b.lo, b.hi);
    const double2 d = fmax(c.lo, c.hi);
    return fmax(d.x, d.y);
}

/* X(r, v) (PolarGrid.points) of samples (j, i) (sixteen range indices i) of the polar grid of
 * frame f on the plane, in x, y, z; returns their ranges r. */
inline double16 polar_points16(const ffbp_frame_t f, const ffbp_plane_t plane, const int j, const double16 i,
                               double16 *x, double16 *y, double16 *z)
{
    const double v = f.v0 + j * f.dv;
    const double3 cen = vload3(0, f.centre), ax = vload3(0, f.axis), e1 = vload3(0, f.e1), e2 = vload3(0, f.e2);
    const double3 m = vload3(0, plane.normal);
    const double16 r = f.r0 + i * f.dr;
    const double16 rho = r * sqrt(fmax(1.0 - v * v, 0.0));
    double16 s = (plane.offset - dot(m, cen) - r * (v * dot(m, ax))) / (rho * dot(m, e2));
    s = select((double16)0.0, clamp(s, -1.0, 1.0), rho > 0.0);
    const double16 rc = rho * sqrt(1.0 - s * s), rs = rho * s, rv = r * v;
    *x = cen.x + rv * ax.x + rc * e1.x + rs * e2.x;
    *y = cen.y + rv * ax.y + rc * e1.y + rs * e2.y;
    *z = cen.z + rv * ax.z + rc * e1.z + rs * e2.z;
    return r;
}

/* bp_tile's pixel fields (bp_pixels_t: dx, dy, dz the offset delta of a sample from its tile's
 * reference point, dd |delta|^2) for the first stage's batch of polar grids
 * (clsas/image/ffbp/leaves.py): work-item g fills fields[g], sixteen consecutive range samples of
 * one row of one tile, items[g] (leaf, row, first range sample, tile; rows and samples past the
 * grid's edge are clamped to it: the launcher drops those slots); frames[leaf], plane, centres
 * (the tiles' reference points, m). */
__kernel void ffbp_fields(__global const ffbp_item_t *items, __global const ffbp_frame_t *frames,
                          const ffbp_plane_t plane, __global const double *centres, const int n_items,
                          __global bp_pixels_t *fields)
{
    const int g = get_global_id(0);
    if (g >= n_items)  /* the launch is padded to whole work-groups */
        return;
    const ffbp_item_t t = items[g];
    const ffbp_frame_t f = frames[t.leaf];
    double16 x, y, z;
    polar_points16(f, plane, min(t.row, f.n_v - 1), fmin(t.sample + LANE_INDEX, (double16)(f.n_r - 1)), &x, &y, &z);
    const double3 centre = vload3(t.tile, centres);
    const double16 dx = x - centre.x, dy = y - centre.y, dz = z - centre.z;
    __global bp_pixels_t *o = fields + g;
    STORE_F16(convert_float16(dx), o->dx);
    STORE_F16(convert_float16(dy), o->dy);
    STORE_F16(convert_float16(dz), o->dz);
    STORE_F16(convert_float16(dx * dx + dy * dy + dz * dz), o->dd);
}

/* The first stage's demodulated leaf image from bp_tile's slots (clsas/image/ffbp/leaves.py):
 * work-item (q, j) writes the sixteen range samples 16 q .. 16 q + 15 (those < n_r) of row j of
 * the leaf's grid (frame) to out[out_offset + j * n_r + i]: bp_tile's slots 16 g .. 16 g + 15 of
 * image, g = slots[slot_first + j * ceil(n_r / 16) + q] (-1: a group no tile computed), times
 * exp(-j 2 pi cycles_per_m r) (the demodulation by its range r), complex64; zero where g = -1 and
 * outside the row's span spans[span_first + j] (the samples lo <= i < hi computed). */
__kernel void ffbp_leaf(__global const double2 *image, __global const int *slots, const long slot_first,
                        __global const int2 *spans, const long span_first, const ffbp_frame_t frame,
                        const double cycles_per_m, const long out_offset, __global float2 *out)
{
    const int q = get_global_id(0), j = get_global_id(1), n_r = frame.n_r;
    const int groups = (n_r + 15) / 16, i0 = 16 * q;
    if (q >= groups || j >= frame.n_v)  /* the launch is padded to whole work-groups */
        return;
    const int g = slots[slot_first + (size_t)j * groups + q];
    const int2 span = spans[span_first + j];
    const int lo = g < 0 ? 16 : max(0, span.x - i0), hi = min(min(16, span.y - i0), n_r - i0);
    __global float2 *o = out + out_offset + (size_t)j * n_r + i0;
    const int n = min(16, n_r - i0);
    if (lo >= hi) {
        for (int l = 0; l < n; ++l)
            o[l] = (float2)(0.0f, 0.0f);
        return;
    }
    const double16 cycles = cycles_per_m * (frame.r0 + (i0 + LANE_INDEX) * frame.dr);
    float16 cs, sn;
    expj_fraction16(convert_float16(cycles - convert_double16(convert_int16(cycles))), &cs, &sn);
    if (lo == 0 && hi == 16) {  /* a whole group: two double16 loads, two float16 stores (re, im interleaved) */
        __global const double *p = (__global const double *)(image + 16 * (size_t)g);
        const double16 a = LOAD_D16(p), b = LOAD_D16(p + 16);
        const float16 re = (float16)(convert_float8(a.even), convert_float8(b.even));
        const float16 im = (float16)(convert_float8(a.odd), convert_float8(b.odd));
        const float16 o_re = re * cs + im * sn, o_im = im * cs - re * sn;
        __global float *q = (__global float *)o;
        STORE_F16(((float16)(o_re.s0, o_im.s0, o_re.s1, o_im.s1, o_re.s2, o_im.s2, o_re.s3, o_im.s3, o_re.s4, o_im.s4,
                             o_re.s5, o_im.s5, o_re.s6, o_im.s6, o_re.s7, o_im.s7)), q);
        STORE_F16(((float16)(o_re.s8, o_im.s8, o_re.s9, o_im.s9, o_re.sa, o_im.sa, o_re.sb, o_im.sb, o_re.sc, o_im.sc,
                             o_re.sd, o_im.sd, o_re.se, o_im.se, o_re.sf, o_im.sf)), q + 16);
        return;
    }
    float c_out[16], s_out[16];
    vstore16(cs, 0, c_out);
    vstore16(sn, 0, s_out);
    for (int l = 0; l < n; ++l) {
        float2 a = (float2)(0.0f, 0.0f);
        if (l >= lo && l < hi) {
            const double2 v = image[16 * (size_t)g + l];
            a = (float2)((float)v.x, (float)v.y);
        }
        o[l] = (float2)(a.x * c_out[l] + a.y * s_out[l], a.y * c_out[l] - a.x * s_out[l]);
    }
}

/* A parent row's work-item (sixteen samples i0 .. i0 + 15 of row j, the first at out[first]):
 * wholly outside the row's span [span.x, span.y), it writes its n_valid zeros and returns 1. */
inline int parent_zeros(__global float2 *out, const size_t first, const int n_valid, const int i0, const int2 span)
{
    if (i0 < span.y && i0 + 16 > span.x)
        return 0;
    for (int l = 0; l < n_valid; ++l)
        out[first + l] = (float2)(0.0f, 0.0f);
    return 1;
}

/* Sixteen complex values (acc_re, acc_im) as two float16, re and im interleaved. */
inline float16 interleave_lo(const float16 re, const float16 im)
{
    return (float16)(re.s0, im.s0, re.s1, im.s1, re.s2, im.s2, re.s3, im.s3, re.s4, im.s4, re.s5, im.s5, re.s6, im.s6,
                     re.s7, im.s7);
}

inline float16 interleave_hi(const float16 re, const float16 im)
{
    return (float16)(re.s8, im.s8, re.s9, im.s9, re.sa, im.sa, re.sb, im.sb, re.sc, im.sc, re.sd, im.sd, re.se, im.se,
                     re.sf, im.sf);
}

/* A parent row's work-item's results written: the n_valid samples from out[first] on, zero
 * outside the row's span; a work-item wholly inside it in two stores. */
inline void store_parent(__global float2 *out, const size_t first, const int n_valid, const int i0, const int2 span,
                         const float16 acc_re, const float16 acc_im)
{
    if (n_valid == 16 && i0 >= span.x && i0 + 16 <= span.y) {
        __global float *o = (__global float *)(out + first);
        STORE_F16(interleave_lo(acc_re, acc_im), o);
        STORE_F16(interleave_hi(acc_re, acc_im), o + 16);
        return;
    }
    float re_out[16], im_out[16];
    vstore16(acc_re, 0, re_out);
    vstore16(acc_im, 0, im_out);
    for (int l = 0; l < n_valid; ++l) {
        const int in = i0 + l >= span.x && i0 + l < span.y;
        out[first + l] = in ? (float2)(re_out[l], im_out[l]) : (float2)(0.0f, 0.0f);
    }
}

__kernel void ffbp_merge(__global const float2 *images, __global const long *offsets,
                         __global const ffbp_frame_t *frames, __global const float *taps,
                         __global const double *points, const ffbp_frame_t parent, __global const int2 *spans,
                         const ffbp_plane_t plane, const double cycles_per_m, const int n_children, const int n_out,
                         const long out_offset, __global float2 *out)
{
    out += out_offset;
    double16 x, y, z, r_p;
    int n_valid;
    size_t first;
#ifdef PARENT_GRID
    /* X(r, v) of the parent samples (PolarGrid.points) */
    const int j = get_global_id(1), i0 = 16 * get_global_id(0);
    n_valid = min(16, parent.n_r - i0);
    if (n_valid <= 0 || j >= parent.n_v)  /* the launch is padded to whole work-groups */
        return;
    first = (size_t)j * parent.n_r + i0;
    const int2 span = spans[j];  /* the row's computed samples [span.x, span.y): zero elsewhere */
    if (parent_zeros(out, first, n_valid, i0, span))
        return;
    r_p = polar_points16(parent, plane, j, i0 + LANE_INDEX, &x, &y, &z);
#else
    const int i0 = 16 * get_global_id(0);
    n_valid = min(16, n_out - i0);
    if (n_valid <= 0)  /* past the points (the launch is padded to whole work-groups) */
        return;
    first = i0;
    if (n_valid == 16) {  /* sixteen points' 48 coordinates in three loads, de-interleaved in registers */
        __global const double *p = points + 3 * (size_t)i0;
        const double16 a = LOAD_D16(p), b = LOAD_D16(p + 16), c = LOAD_D16(p + 32);
        x = (double16)(a.s0369, a.scf, b.s258b, b.se, c.s147a, c.sd);
        y = (double16)(a.s147a, a.sd, b.s0369, b.scf, c.s258b, c.se);
        z = (double16)(a.s258b, a.se, b.s147a, b.sd, c.s0369, c.scf);
    } else {
        double px[16], py[16], pz[16];
        for (int l = 0; l < 16; ++l) {
            const double3 q = vload3(i0 + min(l, n_valid - 1), points);
            px[l] = q.x;
            py[l] = q.y;
            pz[l] = q.z;
        }
        x = vload16(0, px);
        y = vload16(0, py);
        z = vload16(0, pz);
    }
    r_p = (double16)0.0;
#endif
    /* the lanes' bounding box: its centre and half-diagonal, for a cheap test of each child */
    const double3 lo = (double3)(hmin16(x), hmin16(y), hmin16(z)), hi = (double3)(hmax16(x), hmax16(y), hmax16(z));
    const double3 mid = 0.5 * (lo + hi);
    const double radius = 0.5 * length(hi - lo);
    float16 acc_re = (float16)0.0f, acc_im = (float16)0.0f;
    for (int k = 0; k < n_children; ++k) {
        const ffbp_frame_t f = frames[k];
        const double3 cen = vload3(0, f.centre), ax = vload3(0, f.axis);
        /* skip a child whose grid no lane can fall in: the box's range from the child's centre
         * within radius of the middle's, its sine within radius / (range - radius) (|grad v| <= 1 / r) */
        const double3 dm = mid - cen;
        const double rm = length(dm);
        if (rm + radius < f.r0 || rm - radius > f.r0 + (f.n_r - 1.0) * f.dr)
            continue;
        if (rm > radius) {
            const double vm = dot(dm, ax) / rm, slack = radius / (rm - radius);
            if (vm + slack < f.v0 || vm - slack > f.v0 + (f.n_v - 1.0) * f.dv)
                continue;
        }
        const double16 dx = x - cen.x, dy = y - cen.y, dz = z - cen.z;
        const double16 rc = sqrt(dx * dx + dy * dy + dz * dz);
        /* positions in samples, bounded before the conversion (out-of-range converts are undefined) */
        const double per_dv = 1.0 / f.dv, per_dr = 1.0 / f.dr;  /* one scalar division, not sixteen */
        const double16 pv = clamp(((dx * ax.x + dy * ax.y + dz * ax.z) / rc - f.v0) * per_dv, -1.0, 1e9);
        const double16 pr = clamp((rc - f.r0) * per_dr, -1.0, 1e9);
        const int n_r = f.n_r, n_v = f.n_v;
        const int16 fv = convert_int16(pv), fr = convert_int16(pr);  /* floor where >= 0 (PoCL's floor() is slow) */
        const int16 iv = fv - (TAPS / 2 - 1), ir = fr - (TAPS / 2 - 1);
        const int16 ok = convert_int16(pv >= 0.0 && pr >= 0.0) & (iv >= 0 && iv <= n_v - TAPS && ir >= 0 && ir <= n_r - TAPS);
        const int8 ok8 = ok.lo | ok.hi;
        const int4 ok4 = ok8.lo | ok8.hi;
        const int2 ok2 = ok4.lo | ok4.hi;
        if (!(ok2.x | ok2.y))  /* no lane reads this child */
            continue;
        const int16 row_v = NEAREST_TAP_ROW(convert_int16, pv - convert_double16(fv));
        /* the range taps' rows (row 0 for a lane outside the image, which reads zeros: its own row
         * may lie outside the table) */
        const int16 row_r = select((int16)0, NEAREST_TAP_ROW(convert_int16, pr - convert_double16(fr)), ok);
        __global const float *img = (__global const float *)(images + offsets[k]);
        const double16 cycles = cycles_per_m * (rc - r_p);
        float16 cs, sn;
        expj_fraction16(convert_float16(cycles - convert_double16(convert_int16(cycles))), &cs, &sn);
#if TAPS == 8
        const float16 lo = sinc8_lanes(taps, row_r.lo, LANE_WINDOW(0), LANE_WINDOW(1), LANE_WINDOW(2), LANE_WINDOW(3),
                                       LANE_WINDOW(4), LANE_WINDOW(5), LANE_WINDOW(6), LANE_WINDOW(7));
        const float16 hi = sinc8_lanes(taps, row_r.hi, LANE_WINDOW(8), LANE_WINDOW(9), LANE_WINDOW(a), LANE_WINDOW(b),
                                       LANE_WINDOW(c), LANE_WINDOW(d), LANE_WINDOW(e), LANE_WINDOW(f));
#else
        const float16 lo = (float16)(LANE_PRODUCTS(0), LANE_PRODUCTS(1), LANE_PRODUCTS(2), LANE_PRODUCTS(3),
                                     LANE_PRODUCTS(4), LANE_PRODUCTS(5), LANE_PRODUCTS(6), LANE_PRODUCTS(7));
        const float16 hi = (float16)(LANE_PRODUCTS(8), LANE_PRODUCTS(9), LANE_PRODUCTS(a), LANE_PRODUCTS(b),
                                     LANE_PRODUCTS(c), LANE_PRODUCTS(d), LANE_PRODUCTS(e), LANE_PRODUCTS(f));
#endif
        const float16 re = (float16)(lo.even, hi.even), im = (float16)(lo.odd, hi.odd);
        acc_re += re * cs - im * sn;
        acc_im += re * sn + im * cs;
    }
#ifdef PARENT_GRID
    store_parent(out, first, n_valid, i0, span, acc_re, acc_im);
#else
    if (n_valid == 16) {  /* the sixteen complex results interleaved in registers, two stores */
        __global float *o = (__global float *)(out + first);
#ifdef POINTS_STORE
        STORE_F16(interleave_lo(acc_re, acc_im), o);
        STORE_F16(interleave_hi(acc_re, acc_im), o + 16);
#else
        STORE_F16(LOAD_F16(o) + interleave_lo(acc_re, acc_im), o);
        STORE_F16(LOAD_F16(o + 16) + interleave_hi(acc_re, acc_im), o + 16);
#endif
        return;
    }
    float re_out[16], im_out[16];
    vstore16(acc_re, 0, re_out);
    vstore16(acc_im, 0, im_out);
    for (int l = 0; l < n_valid; ++l) {
#ifdef POINTS_STORE
        out[first + l] = (float2)(re_out[l], im_out[l]);
#else
        out[first + l] += (float2)(re_out[l], im_out[l]);
#endif
    }
#endif
}

#if TAPS == 8
/* The two-pass merge (clsas/image/ffbp/merge.py, _two_pass and its docstring; children on the
 * parent's axis, sampled for it). Geometry: a row's and a child's scalars (a, the child ranges of
 * the row's span, one lane's position) in double; the other lanes' offsets from that lane in
 * float (an offset of at most sixteen samples, so its float rounding is ~1e-7 of a sample), added
 * to it in double. */
#define LANE_FLOAT ((float16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))

/* a = u . (C_c - C_p), the child's centre along the parent's axis. */
inline double child_offset(const ffbp_frame_t f, const ffbp_frame_t parent)
{
    return dot(vload3(0, parent.axis), vload3(0, f.centre) - vload3(0, parent.centre));
}

/* The child range of parent range r on the row of sine v (r_c^2 = r^2 - 2 a v r + a^2). */
inline double child_range(const double r, const double a, const double v)
{
    return sqrt(r * r - 2.0 * a * v * r + a * a);
}

/* Whether pass 1 can give a parent row (sine v, computed samples span) anything of child f: the
 * child columns pass 2 reads there ([*lo, *hi] from the child ranges of the span's ends, taps / 2
 * + 1 either side: r_c grows with r_p along a row, as r_p > |a|) meet child rows at sines (v_c
 * monotonic along the row) with a whole window of taps, within a sample's slack. Both passes
 * decide alike from the same numbers (pass 1 writes nothing, pass 2 reads nothing, where not). */
inline int row_meets_child(const ffbp_frame_t f, const ffbp_frame_t parent, const int2 span, const double v,
                           const double a, double *lo, double *hi)
{
    if (span.x >= span.y)
        return 0;
    *lo = (child_range(parent.r0 + span.x * parent.dr, a, v) - f.r0) / f.dr - (TAPS / 2 + 1);
    *hi = (child_range(parent.r0 + (span.y - 1) * parent.dr, a, v) - f.r0) / f.dr + (TAPS / 2 + 1);
    const double k = a * a * (1.0 - v * v), r_a = f.r0 + *lo * f.dr, r_b = f.r0 + *hi * f.dr;
    if (r_a * r_a <= k)
        return 1;  /* the row meets a range so near only on its far side: not decided here */
    const double v_a = ((a * v + sqrt(r_a * r_a - k)) * v - a) / r_a, v_b = ((a * v + sqrt(r_b * r_b - k)) * v - a) / r_b;
    const double p_lo = (fmin(v_a, v_b) - f.v0) / f.dv, p_hi = (fmax(v_a, v_b) - f.v0) / f.dv;
    return p_hi >= TAPS / 2 - 2 && p_lo < f.n_v - TAPS / 2 + 1;
}

#define SPREAD_MAX 3  /* window starts of one half's eight columns at most this far apart: the vector path */

/* The taps of eight lanes (t_L, eight taps each) transposed: w_A holds tap A of the eight lanes,
 * each twice (re, im interleaved), three rounds of two-source permutes. */
#define TRANSPOSE_TAPS(t0, t1, t2, t3, t4, t5, t6, t7)                                                     \
    const float8 u0 = (float8)(t0.s0, t1.s0, t0.s2, t1.s2, t0.s4, t1.s4, t0.s6, t1.s6),                    \
                 u1 = (float8)(t0.s1, t1.s1, t0.s3, t1.s3, t0.s5, t1.s5, t0.s7, t1.s7),                    \
                 u2 = (float8)(t2.s0, t3.s0, t2.s2, t3.s2, t2.s4, t3.s4, t2.s6, t3.s6),                    \
                 u3 = (float8)(t2.s1, t3.s1, t2.s3, t3.s3, t2.s5, t3.s5, t2.s7, t3.s7),                    \
                 u4 = (float8)(t4.s0, t5.s0, t4.s2, t5.s2, t4.s4, t5.s4, t4.s6, t5.s6),                    \
                 u5 = (float8)(t4.s1, t5.s1, t4.s3, t5.s3, t4.s5, t5.s5, t4.s7, t5.s7),                    \
                 u6 = (float8)(t6.s0, t7.s0, t6.s2, t7.s2, t6.s4, t7.s4, t6.s6, t7.s6),                    \
                 u7 = (float8)(t6.s1, t7.s1, t6.s3, t7.s3, t6.s5, t7.s5, t6.s7, t7.s7);                    \
    const float8 y0 = (float8)(u0.s01, u2.s01, u0.s45, u2.s45), y2 = (float8)(u0.s23, u2.s23, u0.s67, u2.s67), \
                 y1 = (float8)(u1.s01, u3.s01, u1.s45, u3.s45), y3 = (float8)(u1.s23, u3.s23, u1.s67, u3.s67), \
                 y4 = (float8)(u4.s01, u6.s01, u4.s45, u6.s45), y6 = (float8)(u4.s23, u6.s23, u4.s67, u6.s67), \
                 y5 = (float8)(u5.s01, u7.s01, u5.s45, u7.s45), y7 = (float8)(u5.s23, u7.s23, u5.s67, u7.s67); \
    const float16 w0 = ((float16)(y0.lo, y4.lo, y0.lo, y4.lo)).s08192a3b4c5d6e7f,                           \
                  w4 = ((float16)(y0.hi, y4.hi, y0.hi, y4.hi)).s08192a3b4c5d6e7f,                           \
                  w2 = ((float16)(y2.lo, y6.lo, y2.lo, y6.lo)).s08192a3b4c5d6e7f,                           \
                  w6 = ((float16)(y2.hi, y6.hi, y2.hi, y6.hi)).s08192a3b4c5d6e7f,                           \
                  w1 = ((float16)(y1.lo, y5.lo, y1.lo, y5.lo)).s08192a3b4c5d6e7f,                           \
                  w5 = ((float16)(y1.hi, y5.hi, y1.hi, y5.hi)).s08192a3b4c5d6e7f,                           \
                  w3 = ((float16)(y3.lo, y7.lo, y3.lo, y7.lo)).s08192a3b4c5d6e7f,                           \
                  w7 = ((float16)(y3.hi, y7.hi, y3.hi, y7.hi)).s08192a3b4c5d6e7f

/* Pass 1 for eight consecutive columns (col: the first's sample of row 0; rows n_r complex
 * samples apart) of one child: lane L read down its column at rows iv.sL .. iv.sL + 7 with the
 * taps of table row row.sL (ok.sL: every tap exists, else 0), re/im interleaved. Where the lanes'
 * first rows lie within SPREAD_MAX of each other and all eight columns exist (whole), the rows
 * are read whole (eight contiguous complex samples each, for every lane at once) and weighted by
 * the lanes' own taps (transposed in registers), once for each first row among the lanes (each
 * lane keeps the sum from its own); otherwise lane by lane. */
inline float16 angle_half(const int8 ok, const int8 iv, const int8 row, __global const float *col, const int n_r,
                          __global const float *taps, const int whole)
{
    const int8 first = select((int8)INT_MAX, iv, ok), last = select((int8)INT_MIN, iv, ok);
    const int4 f4 = min(first.lo, first.hi), l4 = max(last.lo, last.hi);
    const int2 f2 = min(f4.lo, f4.hi), l2 = max(l4.lo, l4.hi);
    const int base = min(f2.x, f2.y);
    if (base == INT_MAX)  /* no lane reads */
        return (float16)0.0f;
    const int spread = max(l2.x, l2.y) - base;
    const int16 ok2 = ((int16)(ok, ok)).s08192a3b4c5d6e7f;  /* each lane twice: re and im */
    if (whole && spread <= SPREAD_MAX) {
        const float8 t0 = LOAD_F8(taps + 8 * row.s0), t1 = LOAD_F8(taps + 8 * row.s1), t2 = LOAD_F8(taps + 8 * row.s2),
                     t3 = LOAD_F8(taps + 8 * row.s3), t4 = LOAD_F8(taps + 8 * row.s4), t5 = LOAD_F8(taps + 8 * row.s5),
                     t6 = LOAD_F8(taps + 8 * row.s6), t7 = LOAD_F8(taps + 8 * row.s7);
        TRANSPOSE_TAPS(t0, t1, t2, t3, t4, t5, t6, t7);
        const size_t step = 2 * (size_t)n_r;
        __global const float *p = col + base * step;
#define WINDOW8(q) (w0 * LOAD_F16(q) + w1 * LOAD_F16((q) + step) + w2 * LOAD_F16((q) + 2 * step)                 \
                    + w3 * LOAD_F16((q) + 3 * step) + w4 * LOAD_F16((q) + 4 * step) + w5 * LOAD_F16((q) + 5 * step) \
                    + w6 * LOAD_F16((q) + 6 * step) + w7 * LOAD_F16((q) + 7 * step))
        float16 acc = WINDOW8(p);
        if (spread > 0) {  /* the lanes whose window starts d rows lower take the window from there */
            const int16 shift = ((int16)(iv, iv)).s08192a3b4c5d6e7f - base;
            for (int d = 1; d <= spread; ++d)
                acc = select(acc, WINDOW8(p + d * step), shift == d);
        }
#undef WINDOW8
        return select((float16)0.0f, acc, ok2);
    }
    int ivs[8], rows[8], oks[8];
    vstore8(iv, 0, ivs);
    vstore8(row, 0, rows);
    vstore8(ok, 0, oks);
    float o[16];
    for (int l = 0; l < 8; ++l) {
        float re = 0.0f, im = 0.0f;
        if (oks[l]) {
            __global const float *p = col + 2 * ((size_t)ivs[l] * n_r + l);
            for (int a = 0; a < 8; ++a) {
                const float t = taps[8 * rows[l] + a];
                re += t * p[2 * (size_t)a * n_r];
                im += t * p[2 * (size_t)a * n_r + 1];
            }
        }
        o[2 * l] = re;
        o[2 * l + 1] = im;
    }
    return vload16(0, o);
}

/* Pass 1 for one work-item's sixteen columns i0 .. i0 + 15 (those < n_r) of child f (its image
 * img) on the parent row of sine v (a, k = a^2 (1 - v^2)), written to o (the row's column i0).
 * The lanes' sines from the last lane's (double): with r the child range, s = sqrt(r^2 - k) and
 * r_p = a v + s, a lane delta from it has s' - s = delta (2 r + delta) / (s' + s) and
 * v_c' - v_c = ((s' - s) v - v_c delta) / r'. */
inline void angle_columns(const ffbp_frame_t f, __global const float2 *img, const int i0, const double v,
                          const double a, const double k, __global const float *taps, __global float2 *o)
{
    const int n_r = f.n_r;
    const double r15 = f.r0 + (i0 + 15) * f.dr, disc15 = r15 * r15 - k;
    if (disc15 <= 0.0) {  /* no lane's range meets the row */
        for (int l = 0; l < min(16, n_r - i0); ++l)
            o[l] = (float2)(0.0f, 0.0f);
        return;
    }
    const double s15 = sqrt(disc15), vc15 = ((a * v + s15) * v - a) / r15;
    const float16 delta = (LANE_FLOAT - 15.0f) * (float)f.dr;
    const float16 grow = delta * (2.0f * (float)r15 + delta), disc = (float)disc15 + grow;
    const float16 ds = grow / (sqrt(fmax(disc, 0.0f)) + (float)s15);
    const float16 step = ((float)v * ds - (float)vc15 * delta) / (((float)r15 + delta) * (float)f.dv);
    const double16 pv = clamp((vc15 - f.v0) / f.dv + convert_double16(step), -1.0, 1e9);
    const int16 fv = convert_int16(pv), iv = fv - (TAPS / 2 - 1);  /* floor where >= 0 */
    const int16 lane = convert_int16(LANE_INDEX);
    const int16 ok = (disc >= 0.0f) & convert_int16(pv >= 0.0) & (iv >= 0 && iv <= f.n_v - TAPS) & (i0 + lane < n_r);
    const int16 row = select((int16)0, NEAREST_TAP_ROW(convert_int16, convert_float16(pv - convert_double16(fv))), ok);
    __global const float *col = (__global const float *)(img + i0);
    const float16 lo = angle_half(ok.lo, iv.lo, row.lo, col, n_r, taps, i0 + 8 <= n_r);
    const float16 hi = angle_half(ok.hi, iv.hi, row.hi, col + 16, n_r, taps, i0 + 16 <= n_r);
    if (i0 + 16 <= n_r) {
        STORE_F16(lo, (__global float *)o);
        STORE_F16(hi, (__global float *)o + 16);
        return;
    }
    float out[32];
    vstore16(lo, 0, out);
    vstore16(hi, 1, out);
    for (int l = 0; l < n_r - i0; ++l)
        o[l] = (float2)(out[2 * l], out[2 * l + 1]);
}

/* Pass 1: work-item (j, k) writes child k's columns read down to parent row j's sines (merge.py:
 * T_c[j, i]) to rows[starts[k] + j n_r + i], sixteen columns at a time (angle_columns), only
 * those pass 2 reads (row_meets_child: none on a row it does not reach). images holds the
 * children at offsets, frames their frames, parent the parent's frame and spans its rows'
 * computed samples. */
__kernel void ffbp_angle(__global const float2 *images, __global const long *offsets,
                         __global const ffbp_frame_t *frames, __global const float *taps, const ffbp_frame_t parent,
                         __global const int2 *spans, __global const long *starts, __global float2 *rows)
{
    const int j = get_global_id(0), k = get_global_id(1);
    if (j >= parent.n_v)  /* the launch is padded to whole work-groups */
        return;
    const ffbp_frame_t f = frames[k];
    const double v = parent.v0 + j * parent.dv, a = child_offset(f, parent);
    double c_lo, c_hi;
    if (!row_meets_child(f, parent, spans[j], v, a, &c_lo, &c_hi))
        return;
    const int q_lo = max(0, (int)floor(c_lo) / 16), q_hi = min((f.n_r - 1) / 16, (int)fmin(c_hi, 1e9) / 16);
    __global const float2 *img = images + offsets[k];
    __global float2 *o = rows + starts[k] + (size_t)j * f.n_r;
    for (int q = q_lo; q <= q_hi; ++q)
        angle_columns(f, img, 16 * q, v, a, a * a * (1.0 - v * v), taps, o + 16 * q);
}

/* One lane's eight complex samples of pass 1's row t from column ir.sL on (zero if not ok.sL). */
#define ROW_WINDOW(L) (ok.s##L ? LOAD_F16(t + 2 * ir.s##L) : (float16)0.0f)

#define MAX_CHILDREN 16  /* ffbp's largest factor */

/* Pass 2 for one work-item's sixteen parent samples i0 .. i0 + 15 of the row of sine v (its
 * span): for every child k with meets[k] (row_meets_child; offset a[k]), pass 1's row (rows from
 * starts[k] + row n_r) read at the child range r_c of each sample by the range taps, times
 * exp(j 2 pi cycles_per_m (r_c - r_p)), summed, written to out[first ..]. The lanes' r_c from the
 * first lane's (double): a lane delta further has r_c' = r_c + delta + e, e (2 r_c + 2 delta + e)
 * = 2 delta g with g = r_p - a v - r_c (from r_c'^2 - r_c^2 = delta (2 r_p - 2 a v + delta)), e
 * by one fixed-point step from e0 = g delta / (r_c + delta) (its error ~e0^2 / r_c); the phase
 * moves by e alone, and the position by delta in double (a float position's rounding would pick
 * a neighbouring tap row of the table now and then) and e in float. */
inline void range_samples(__global const float2 *rows, __global const long *starts, __global const ffbp_frame_t *frames,
                          __global const float *taps, const ffbp_frame_t parent, const int2 span, const int row,
                          const double v, const double *a, const int *meets, const int n_children, const int i0,
                          const double cycles_per_m, __global float2 *out, const size_t first)
{
    const int n_valid = min(16, parent.n_r - i0);
    if (parent_zeros(out, first, n_valid, i0, span))
        return;
    const double r0 = parent.r0 + i0 * parent.dr;
    const float16 delta = LANE_FLOAT * (float)parent.dr;
    float16 acc_re = (float16)0.0f, acc_im = (float16)0.0f;
    for (int k = 0; k < n_children; ++k) {
        if (!meets[k])
            continue;
        const ffbp_frame_t f = frames[k];
        const double rc0 = child_range(r0, a[k], v), g = r0 - a[k] * v - rc0;
        const float16 e0 = (float)g * delta / ((float)rc0 + delta);
        const float16 e = 2.0f * (float)g * delta / (2.0f * ((float)rc0 + delta) + e0);  /* r_c - rc0 - delta */
        if (rc0 + delta.sf + e.sf < f.r0 || rc0 > f.r0 + (f.n_r - 1.0) * f.dr)
            continue;
        const double16 pr = clamp((rc0 - f.r0) / f.dr + LANE_INDEX * (parent.dr / f.dr)
                                  + convert_double16(e * (float)(1.0 / f.dr)), -1.0, 1e9);
        const int16 fr = convert_int16(pr), ir = fr - (TAPS / 2 - 1);  /* floor where >= 0 */
        const int16 ok = convert_int16(pr >= 0.0) & (ir >= 0 && ir <= f.n_r - TAPS);
        const int8 ok8 = ok.lo | ok.hi;
        const int4 ok4 = ok8.lo | ok8.hi;
        const int2 ok2 = ok4.lo | ok4.hi;
        if (!(ok2.x | ok2.y))
            continue;
        const int16 row_r = select((int16)0, NEAREST_TAP_ROW(convert_int16, convert_float16(pr - convert_double16(fr))), ok);
        __global const float *t = (__global const float *)(rows + starts[k] + (size_t)row * f.n_r);
        const double c0 = cycles_per_m * (rc0 - r0);
        const float16 cycles = (float)(c0 - (double)(long)c0) + (float)cycles_per_m * e;
        float16 cs, sn;
        expj_fraction16(cycles - convert_float16(convert_int16(cycles)), &cs, &sn);
        const float16 lo = sinc8_lanes(taps, row_r.lo, ROW_WINDOW(0), ROW_WINDOW(1), ROW_WINDOW(2), ROW_WINDOW(3),
                                       ROW_WINDOW(4), ROW_WINDOW(5), ROW_WINDOW(6), ROW_WINDOW(7));
        const float16 hi = sinc8_lanes(taps, row_r.hi, ROW_WINDOW(8), ROW_WINDOW(9), ROW_WINDOW(a), ROW_WINDOW(b),
                                       ROW_WINDOW(c), ROW_WINDOW(d), ROW_WINDOW(e), ROW_WINDOW(f));
        const float16 re = (float16)(lo.even, hi.even), im = (float16)(lo.odd, hi.odd);
        acc_re += re * cs - im * sn;
        acc_im += re * sn + im * cs;
    }
    store_parent(out, first, n_valid, i0, span, acc_re, acc_im);
}

/* Pass 2: work-item j writes parent row j (zero outside its span) to out[out_offset + j n_r ..],
 * sixteen samples at a time (range_samples), each child's offset and reach of the row found once. */
__kernel void ffbp_range(__global const float2 *rows, __global const long *starts,
                         __global const ffbp_frame_t *frames, __global const float *taps, const ffbp_frame_t parent,
                         __global const int2 *spans, const double cycles_per_m, const int n_children,
                         const long out_offset, __global float2 *out)
{
    const int j = get_global_id(0);
    if (j >= parent.n_v)  /* the launch is padded to whole work-groups */
        return;
    const int2 span = spans[j];
    const double v = parent.v0 + j * parent.dv;
    double a[MAX_CHILDREN], c_lo, c_hi;
    int meets[MAX_CHILDREN];
    for (int k = 0; k < n_children; ++k) {
        a[k] = child_offset(frames[k], parent);
        meets[k] = row_meets_child(frames[k], parent, span, v, a[k], &c_lo, &c_hi);
    }
    for (int i0 = 0; i0 < parent.n_r; i0 += 16)
        range_samples(rows, starts, frames, taps, parent, span, j, v, a, meets, n_children, i0, cycles_per_m,
                      out + out_offset, (size_t)j * parent.n_r + i0);
}
#endif
