/* Fast factorised back-projection: the merge of child polar images into a parent polar grid
 * (PARENT_GRID) or onto explicit points (the final stage onto the user's pixels).
 * Also: the first stage's pixel fields (ffbp_fields) and demodulation (ffbp_leaf), and the
 * planner's reductions over the scene's skeleton (ffbp_extremes, ffbp_seen, ffbp_envelope, at the end).
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
 * the angle taps (TAPS = 8: tv, the lane's row of the table; the lanes' offsets of s and tv are
 * formed as int16 vectors and taken lane by lane, fewer extracts than four ints a lane; TAPS = 4:
 * row row_v); zero for a lane outside the image. TAPS = 8: the lane's eight
 * complex samples of the range window (a float16), which interp.h's sinc8_lanes weights by the
 * range taps and sums eight lanes at a time; TAPS = 4: the lane's complex sum, range taps
 * applied. */
#if TAPS == 8
inline float16 lane_window(const int ok, __global const float *s, const int n_r, __global const float *tv)
{
    float16 p = (float16)0.0f;
    if (ok) {
        for (int a = 0; a < 8; ++a)
            p += tv[a] * LOAD_F16(s + 2 * a * n_r);
    }
    return p;
}
#define LANE_WINDOW(L) lane_window(ok.s##L, img + at.s##L, n_r, taps + tap_at.s##L)
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
 * (the tiles' reference points, m); dd_max[g] the largest of its sixteen dd (as stored, float:
 * the launcher's tile budget check reads these, not the fields; fmax skips a NaN: the geometry is
 * finite, clsas/image/ffbp/polar/scene.py's Scene.of refuses a non-finite pixel). Also the images' slots
 * (clsas/image/ffbp/layout.py, _slots is the NumPy twin): for g < n_slotted (the work-items
 * bp_tile computes) and a row inside its grid, slots[slot_firsts[leaf] + row * ceil(n_r / 16) +
 * sample / 16] = g; the launcher fills slots with -1 first (groups no work-item holds). */
__kernel void ffbp_fields(__global const ffbp_item_t *items, __global const ffbp_frame_t *frames,
                          const ffbp_plane_t plane, __global const double *centres, const int n_items,
                          __global bp_pixels_t *fields, __global float *dd_max, __global int *slots,
                          __global const long *slot_firsts, const int n_slotted)
{
    const int g = get_global_id(0);
    if (g >= n_items)  /* the launch is padded to whole work-groups */
        return;
    const ffbp_item_t t = items[g];
    const ffbp_frame_t f = frames[t.leaf];
    if (g < n_slotted && t.row < f.n_v)
        slots[slot_firsts[t.leaf] + (long)t.row * ((f.n_r + 15) / 16) + t.sample / 16] = g;
    double16 x, y, z;
    polar_points16(f, plane, min(t.row, f.n_v - 1), fmin(t.sample + LANE_INDEX, (double16)(f.n_r - 1)), &x, &y, &z);
    const double3 centre = vload3(t.tile, centres);
    const double16 dx = x - centre.x, dy = y - centre.y, dz = z - centre.z;
    __global bp_pixels_t *o = fields + g;
    STORE_F16(convert_float16(dx), o->dx);
    STORE_F16(convert_float16(dy), o->dy);
    STORE_F16(convert_float16(dz), o->dz);
    const float16 dd = convert_float16(dx * dx + dy * dy + dz * dz);
    STORE_F16(dd, o->dd);
    const float8 m8 = fmax(dd.lo, dd.hi);
    const float4 m4 = fmax(m8.lo, m8.hi);
    const float2 m2 = fmax(m4.lo, m4.hi);
    dd_max[g] = fmax(m2.x, m2.y);
}

/* The first stage's demodulated leaf images from bp_tile's slots (clsas/image/ffbp/leaves.py),
 * leaf k = get_global_id(2) of a launch: work-item (q, j, k) writes the sixteen range samples
 * 16 q .. 16 q + 15 (those < n_r) of row j of the leaf's grid (frames[k]) to
 * out[out_offsets[k] + j * n_r + i]: bp_tile's slots 16 g .. 16 g + 15 of image,
 * g = slots[slot_firsts[k] + j * ceil(n_r / 16) + q] (-1: a group no tile computed), times
 * exp(-j 2 pi cycles_per_m r) (the demodulation by its range r), complex64; zero where g = -1 and
 * outside the row's span spans[span_firsts[k] + j] (the samples lo <= i < hi computed). */
__kernel void ffbp_leaf(__global const double2 *image, __global const int *slots, __global const long *slot_firsts,
                        __global const int2 *spans, __global const long *span_firsts,
                        __global const ffbp_frame_t *frames, const double cycles_per_m,
                        __global const long *out_offsets, __global float2 *out)
{
    const int k = get_global_id(2);
    const ffbp_frame_t frame = frames[k];
    const long slot_first = slot_firsts[k], span_first = span_firsts[k], out_offset = out_offsets[k];
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
    if (i0 >= span.y || i0 + 16 <= span.x) {
        for (int l = 0; l < n_valid; ++l)
            out[first + l] = (float2)(0.0f, 0.0f);
        return;
    }
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
#if TAPS == 8
        const int16 at = 2 * (iv * n_r + ir), tap_at = 8 * row_v;  /* each lane's window and angle taps, as vectors */
#endif
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
    const int whole = n_valid == 16 && i0 >= span.x && i0 + 16 <= span.y;  /* every lane stored, none zeroed */
#else
    const int whole = n_valid == 16;
#endif
    if (whole) {  /* the sixteen complex results interleaved in registers, two stores */
        __global float *o = (__global float *)(out + first);
        const float16 lo = (float16)(acc_re.s0, acc_im.s0, acc_re.s1, acc_im.s1, acc_re.s2, acc_im.s2, acc_re.s3,
                                     acc_im.s3, acc_re.s4, acc_im.s4, acc_re.s5, acc_im.s5, acc_re.s6, acc_im.s6,
                                     acc_re.s7, acc_im.s7);
        const float16 hi = (float16)(acc_re.s8, acc_im.s8, acc_re.s9, acc_im.s9, acc_re.sa, acc_im.sa, acc_re.sb,
                                     acc_im.sb, acc_re.sc, acc_im.sc, acc_re.sd, acc_im.sd, acc_re.se, acc_im.se,
                                     acc_re.sf, acc_im.sf);
#if defined(PARENT_GRID) || defined(POINTS_STORE)
        STORE_F16(lo, o);
        STORE_F16(hi, o + 16);
#else
        STORE_F16(LOAD_F16(o) + lo, o);
        STORE_F16(LOAD_F16(o + 16) + hi, o + 16);
#endif
        return;
    }
    float re_out[16], im_out[16];
    vstore16(acc_re, 0, re_out);
    vstore16(acc_im, 0, im_out);
    for (int l = 0; l < n_valid; ++l) {
#if defined(PARENT_GRID)
        const int in = i0 + l >= span.x && i0 + l < span.y;
        out[first + l] = in ? (float2)(re_out[l], im_out[l]) : (float2)(0.0f, 0.0f);
#elif defined(POINTS_STORE)
        out[first + l] = (float2)(re_out[l], im_out[l]);
#else
        out[first + l] += (float2)(re_out[l], im_out[l]);
#endif
    }
}

/* The planner's reductions over the scene's skeleton (clsas/image/ffbp/polar/offsets.py, whose
 * NumPy twin is the reference: both give the same values, bit for bit): work-item n is
 * sub-aperture n (its origin O = origins[n] and unit axis u = axes[n], about the scene's centroid;
 * dots[n] = u . O), looping over the K skeleton points X eight at a time (points: the x row, the
 * y row, the z row, each of stride = K rounded up to eight, the padding repeating the last point;
 * lanes past K are masked out). A point's range r = |X - O| and sine v = (u . X - u . O) / r (0 at
 * r = 0) are formed operation by operation as polar.Scene.offsets forms them, with no contraction
 * into fused multiply-adds (so every value is NumPy's: IEEE sums, products, square roots and
 * quotients, correctly rounded in double); minima and maxima are exact in any order. */
#define SKELETON_ARGS __global const double *points, const int K, const int stride, __global const double *origins, \
                      __global const double *axes, __global const double *dots, const int n_nodes

/* Declares r, v (double8) and valid (long8, -1 for the lanes < K) of the eight points from i on,
 * for sub-aperture n. */
#define SKELETON_RV8                                                                                          \
    const double3 o = vload3(n, origins), u = vload3(n, axes);                                               \
    const double8 x = vload8(0, points + i), y = vload8(0, points + stride + i),                             \
                  z = vload8(0, points + 2 * stride + i);                                                     \
    const double8 dx = x - o.x, dy = y - o.y, dz = z - o.z;                                                   \
    double8 sq = dx * dx;                                                                                     \
    sq = sq + dy * dy;                                                                                        \
    sq = sq + dz * dz;                                                                                        \
    const double8 r = sqrt(sq);                                                                               \
    double8 along = u.x * x;                                                                                  \
    along = along + u.y * y;                                                                                  \
    along = along + u.z * z;                                                                                  \
    along = along - dots[n];                                                                                  \
    const double8 v = select(along / r, (double8)0.0, r == 0.0);                                             \
    const long8 valid = (i + (long8)(0, 1, 2, 3, 4, 5, 6, 7)) < (long)K;

/* The smallest and largest lane of a and b (double8) into lo and hi, lane 0 first (named lanes: a
 * vector subscripted by a runtime index is a clang extension, not OpenCL C 1.2). */
#define LANE_MIN_MAX(a, b, lo, hi, s)                                                                         \
    lo = a.s < lo ? a.s : lo;                                                                                 \
    hi = b.s > hi ? b.s : hi;
#define LANES_MIN_MAX(a, b, lo, hi)                                                                           \
    LANE_MIN_MAX(a, b, lo, hi, s0) LANE_MIN_MAX(a, b, lo, hi, s1) LANE_MIN_MAX(a, b, lo, hi, s2)              \
    LANE_MIN_MAX(a, b, lo, hi, s3) LANE_MIN_MAX(a, b, lo, hi, s4) LANE_MIN_MAX(a, b, lo, hi, s5)              \
    LANE_MIN_MAX(a, b, lo, hi, s6) LANE_MIN_MAX(a, b, lo, hi, s7)

/* out[n] = (min r, max r, min v, max v) over the skeleton. */
__kernel void ffbp_extremes(SKELETON_ARGS, __global double4 *out)
{
#pragma OPENCL FP_CONTRACT OFF
    const int n = get_global_id(0);
    if (n >= n_nodes)
        return;
    double8 r8_lo = INFINITY, r8_hi = -INFINITY, v8_lo = INFINITY, v8_hi = -INFINITY;
    for (int i = 0; i < K; i += 8) {
        SKELETON_RV8
        r8_lo = select(r8_lo, r, valid && r < r8_lo);
        r8_hi = select(r8_hi, r, valid && r > r8_hi);
        v8_lo = select(v8_lo, v, valid && v < v8_lo);
        v8_hi = select(v8_hi, v, valid && v > v8_hi);
    }
    double r_lo = INFINITY, r_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY;
    LANES_MIN_MAX(r8_lo, r8_hi, r_lo, r_hi)
    LANES_MIN_MAX(v8_lo, v8_hi, v_lo, v_hi)
    out[n] = (double4)(r_lo, r_hi, v_lo, v_hi);
}

/* Over the skeleton points whose sines lie in windows[n] = (lo, hi, a, b), lo <= v <= hi:
 * out[n] = (min r, max r (inf, -inf: none), their count, the count of a <= v <= b). */
__kernel void ffbp_seen(SKELETON_ARGS, __global const double4 *windows, __global double4 *out)
{
#pragma OPENCL FP_CONTRACT OFF
    const int n = get_global_id(0);
    if (n >= n_nodes)
        return;
    const double4 w = windows[n];
    double8 r8_lo = INFINITY, r8_hi = -INFINITY;
    long8 seen8 = 0, reach8 = 0;
    for (int i = 0; i < K; i += 8) {
        SKELETON_RV8
        const long8 in = valid && v >= w.x && v <= w.y;  /* -1 where true */
        r8_lo = select(r8_lo, r, in && r < r8_lo);
        r8_hi = select(r8_hi, r, in && r > r8_hi);
        seen8 -= in;
        reach8 -= valid && v >= w.z && v <= w.w;
    }
    double r_lo = INFINITY, r_hi = -INFINITY;
    LANES_MIN_MAX(r8_lo, r8_hi, r_lo, r_hi)
    const long seen = seen8.s0 + seen8.s1 + seen8.s2 + seen8.s3 + seen8.s4 + seen8.s5 + seen8.s6 + seen8.s7;
    const long reach = reach8.s0 + reach8.s1 + reach8.s2 + reach8.s3 + reach8.s4 + reach8.s5 + reach8.s6 + reach8.s7;
    out[n] = (double4)(r_lo, r_hi, (double)seen, (double)reach);
}

/* The range envelope: envelope[n][b] = (min r, max r) (inf, -inf: empty) of the skeleton points
 * in sine bin b = floor((v - start) / width) (bins[n] = (start, width)), 0 <= b < n_bins: the
 * quotient t = (v - start) / width lies in [0, n_bins) exactly when floor(t) does, and there
 * floor(t) is t truncated (no floor(), which PoCL emulates slowly). */
__kernel void ffbp_envelope(SKELETON_ARGS, __global const double2 *bins, const int n_bins, __global double2 *envelope)
{
#pragma OPENCL FP_CONTRACT OFF
    const int n = get_global_id(0);
    if (n >= n_nodes)
        return;
    const double2 s = bins[n];
    __global double2 *env = envelope + (long)n * n_bins;
    for (int b = 0; b < n_bins; ++b)
        env[b] = (double2)(INFINITY, -INFINITY);
    for (int i = 0; i < K; i += 8) {
        SKELETON_RV8
        const double8 t = (v - s.x) / s.y;
        const long8 ok = valid && t >= 0.0 && t < (double)n_bins;
        const int8 bin = convert_int8(select((double8)0.0, t, ok));
        double r_[8];  /* the lanes in private arrays, indexed in the loop (a vector subscripted by a */
        int bin_[8];   /* runtime index is a clang extension, not OpenCL C 1.2) */
        long ok_[8];
        vstore8(r, 0, r_);
        vstore8(bin, 0, bin_);
        vstore8(ok, 0, ok_);
        for (int k = 0; k < 8; ++k) {
            if (ok_[k]) {
                __global double2 *e = env + bin_[k];
                double2 b = *e;
                b.x = r_[k] < b.x ? r_[k] : b.x;
                b.y = r_[k] > b.y ? r_[k] : b.y;
                *e = b;
            }
        }
    }
}
