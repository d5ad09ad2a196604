/* Time-domain back-projection of range-compressed echoes, one receiver and one block of
 * pulses a launch.
 *
 * NumPy twin: clsas/image/backprojection.py (backproject_reference); launcher in the same module.
 *
 * One work-item: eight pixels (double8 lanes). For every pulse of the block: the exact two-way
 * delay tau (transmitter at emission; pixel moving at the target velocity, P0 + v t; receiver
 * moving during reception, linear between position nodes), in double (geometry8.h); the
 * range-compressed sample at tau by linear interpolation of the FFT-upsampled record
 * (INTERP_LINEAR) or by an 8-tap Kaiser-windowed sinc on the original samples (INTERP_SINC8,
 * taps from the nearest row of a table over the fractional offset); a record reads as zero
 * where the interpolator would need samples outside it;
 * the phase rotation exp(+j 2 pi f0 tau) with the cycles reduced in double; accumulation in
 * float over the block (blocked sum), added once into the double image at the end.
 *
 * Defines: N_NODES, SEGMENT_PASSES (geometry8.h), INTERP_LINEAR or INTERP_SINC8 (with
 * TAP_ROWS, the tap table resolution), STOP_AND_GO, APERTURE (limit |sin theta| off broadside,
 * theta measured from the x-z plane, to params.s7), CLSAS_DOUBLE (data, phases and sums in
 * double: precision="double").
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"
#include "geometry8.h"

/* params: c, f0, fs (of the data), dtau (node spacing), vx, vy, vz (target velocity),
 * sin of half the integration angle (APERTURE) */

/* Data, interpolation and sums in float, or in double with CLSAS_DOUBLE (precision="double"). */
#ifdef CLSAS_DOUBLE
typedef double2 sample_t;
typedef double8 realv8;
typedef double4 realv4_t;
typedef double16 realv16_t;
#define convert_realv8 convert_double8
#define CONVERT_TAPS convert_double8
#define VLOAD4 vload4
#define VLOAD16 vload16
#else
typedef float2 sample_t;
typedef float8 realv8;
typedef float4 realv4_t;
typedef float16 realv16_t;
#define convert_realv8 convert_float8
#define CONVERT_TAPS(x) (x)
#define VLOAD4 vload4
#define VLOAD16 vload16
#endif


/* pix[f * m_pad + m]: pixel m's x, y, z at t = 0 (f = 0, 1, 2);
 * pulse[p]: tx.xyz, eta, t0 fs (window start in samples of the data);
 * nodes[p N_NODES + k]: receiver position.xyz (and axis) at fast time k dtau;
 * data[p n + i]: the receiver's range-compressed record of pulse p;
 * pulses p_first .. p_first + p_count - 1 of the buffers are summed by this launch;
 * taps[r * 8 + j]: sinc8 taps for fractional offset r / (TAP_ROWS - 1), sample i - 3 + j (the
 * row nearest to the pixel's offset is used);
 * image[m] += the block's sum. */
__kernel void bp_block(__global const double *pix, __global const double8 *pulse,
                       __global const double8 *nodes, __global const sample_t *data,
                       __global const float *taps, const double8 params,
                       const int p_first, const int p_count, const int n, const int m_pad,
                       __global double2 *image)
{
    const int g = get_global_id(0);
    const int m0 = 8 * g;
    const double c = params.s0, f0 = params.s1, fs = params.s2, dtau = params.s3;
    const vec8 p0 = v8(vload8(0, pix + m0), vload8(0, pix + m_pad + m0), vload8(0, pix + 2 * m_pad + m0));
    const vec8 vel = v8_splat(params.s456);
    realv8 acc_re = (realv8)0, acc_im = (realv8)0;
    for (int p = p_first; p < p_first + p_count; ++p) {
        const double8 pl = pulse[p];
        const vec8 tx = v8_splat(pl.s012);
        const vec8 q_emit = v8_add(p0, v8_scale(vel, (double8)pl.s3));
        __global const double8 *nd = nodes + (size_t)p * N_NODES;
#ifndef STOP_AND_GO
        const double8 t1 = meet_time8_uniform(v8_sub(q_emit, tx), params.s456, c);
        const vec8 q = v8_add(q_emit, v8_scale(vel, t1));
        const double8 tau = reception8(nd, t1, q, c, dtau);
#else
        const vec8 q = q_emit;
        const vec8 out = v8_sub(q, tx), back = v8_sub(q, node_field(nd, (double8)0.0, dtau, 0));
        const double8 tau = (sqrt(v8_dot(out, out)) + sqrt(v8_dot(back, back))) / c;
#endif
        /* fractional sample index in the record, split in double into integer and fraction */
        const double8 k = tau * fs - pl.s4;
        long8 kl = convert_long8(k);
        kl += (k < convert_double8(kl));  /* floor (a true compare is -1) */
        const realv8 frac = convert_realv8(k - convert_double8(kl));
        /* carrier exp(+j 2 pi f0 tau), cycles reduced in double */
        double8 cyc = f0 * tau;
        cyc -= convert_double8(convert_long8(cyc));
#ifdef CLSAS_DOUBLE
        realv8 cs = cospi(2.0 * cyc), sn = sinpi(2.0 * cyc);
#else
        realv8 cs, sn;
        expj_fraction8(convert_float8(cyc), &cs, &sn);
#endif
#ifdef APERTURE
        {
            const vec8 d = v8_sub(q, tx);
            const double8 s = d.y / sqrt(v8_dot(d, d));  /* sin of the angle off broadside (y: heading) */
            const realv8 keep = convert_realv8(select((double8)0.0, (double8)1.0, fabs(s) <= params.s7));
            cs *= keep;
            sn *= keep;
        }
#endif
        __global const real_t *rec = (__global const real_t *)(data + (size_t)p * n);
#ifdef INTERP_LINEAR
        /* samples i and i + 1 of each lane in one 4-wide load (lanes unrolled, no branches);
         * outside [0, n - 1) the record reads as zero */
        const long8 ic = clamp(kl, (long8)0, (long8)(n - 2));
        const realv8 keep = convert_realv8(select((double8)0.0, (double8)1.0, kl >= 0 && kl < (long8)(n - 1)));
#define LOAD2(L) const realv4_t w##L = VLOAD4(0, rec + 2 * ic.s##L);
        LOAD2(0) LOAD2(1) LOAD2(2) LOAD2(3) LOAD2(4) LOAD2(5) LOAD2(6) LOAD2(7)
#undef LOAD2
        const realv8 a_re = (realv8)(w0.s0, w1.s0, w2.s0, w3.s0, w4.s0, w5.s0, w6.s0, w7.s0);
        const realv8 a_im = (realv8)(w0.s1, w1.s1, w2.s1, w3.s1, w4.s1, w5.s1, w6.s1, w7.s1);
        const realv8 b_re = (realv8)(w0.s2, w1.s2, w2.s2, w3.s2, w4.s2, w5.s2, w6.s2, w7.s2);
        const realv8 b_im = (realv8)(w0.s3, w1.s3, w2.s3, w3.s3, w4.s3, w5.s3, w6.s3, w7.s3);
        const realv8 dr = keep * mix(a_re, b_re, frac), di = keep * mix(a_im, b_im, frac);
#else
        /* samples i - 3 .. i + 4 of each lane in one 16-wide load, the taps of the nearest
         * fractional-offset row; zero unless all eight samples exist */
        const long8 ic = clamp(kl - 3, (long8)0, (long8)(n - 8));
        const realv8 keep = convert_realv8(select((double8)0.0, (double8)1.0, kl >= 3 && kl < (long8)(n - 4)));
        const int8 row = convert_int8(frac * (real_t)(TAP_ROWS - 1) + (real_t)0.5);
        real_t vr[8], vi[8];
#define TAPS8(L) {                                                                   \
            const realv16_t s8 = VLOAD16(0, rec + 2 * ic.s##L);                         \
            const realv8 t = CONVERT_TAPS(vload8(row.s##L, taps));                      \
            const realv8 pr = s8.even * t, pi = s8.odd * t;                             \
            vr[L] = pr.s0 + pr.s1 + pr.s2 + pr.s3 + pr.s4 + pr.s5 + pr.s6 + pr.s7;      \
            vi[L] = pi.s0 + pi.s1 + pi.s2 + pi.s3 + pi.s4 + pi.s5 + pi.s6 + pi.s7; }
        TAPS8(0) TAPS8(1) TAPS8(2) TAPS8(3) TAPS8(4) TAPS8(5) TAPS8(6) TAPS8(7)
#undef TAPS8
        const realv8 dr = keep * vload8(0, vr), di = keep * vload8(0, vi);
#endif
        acc_re += dr * cs - di * sn;
        acc_im += dr * sn + di * cs;
    }
    real_t re[8], im[8];
    vstore8(acc_re, 0, re);
    vstore8(acc_im, 0, im);
    for (int l = 0; l < 8; ++l) image[m0 + l] += (double2)(re[l], im[l]);
}
