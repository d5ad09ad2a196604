/* Time-domain back-projection with the exact delays in double per pixel and pulse, one receiver and
 * one block of pulses a launch: bp_block, owned by clsas/image/backprojection/exact_kernel.ExactKernel
 * (its records and -D options). NumPy twin: clsas/image/backprojection/reference.py. The tiled float
 * path is bp_tile (kernels/bp_tile.cl); interpolation, phase and sums: kernels/bp_common.h.
 *
 * The receiver's position by its nodes (geometry.h); eight pixels (double8 lanes) a work-item;
 * precision="double" (with CLSAS_DOUBLE) and the fallback of precision="single" when a receiver's
 * motion is not linear over a tile.
 *
 * Defines: N_NODES and SEGMENT_PASSES (geometry.h), STOP_AND_GO, SCATTER; INTERP_LINEAR or INTERP_SINC8
 * (with TAP_ROWS); APERTURE (keep |sin theta| off broadside <= sin(aperture / 2), theta measured from
 * the x-z plane); CLSAS_DOUBLE (data, phases and sums in double: precision="double"). Portable OpenCL C 1.2. */
#include "bp_common.h"
#include "geometry.h"

/* pix[g] (bp_points_t, ExactKernel.POINTS): work-item g's eight pixels m = 8 g + lane at t = 0 (x, y, z);
 * pulse[p] (bp_pulse_t): tx, the transmitter at emission; eta; t0_fs, the window start in
 * samples of the data; first, the records' first sample (counted from t0 at the data's rate);
 * nodes[p N_NODES + k] (node_t): the receiver's position at fast time k dtau;
 * params (bp_block_params_t): c, f0, fs (of the data), dtau (node spacing), velocity (of the
 * pixels), half_sin = sin(aperture / 2) (APERTURE);
 * data[p n + i]: the receiver's range-compressed record of pulse p;
 * pulses p_first .. p_first + p_count - 1 of the buffers are summed by this launch;
 * taps: the 8-tap table (interp.h);
 * image[m] += the block's sum. */
__kernel void bp_block(__global const bp_points_t *pix, __global const bp_pulse_t *pulse,
                       __global const node_t *nodes, __global const sample_t *data,
                       __global const float *taps, const bp_block_params_t params,
                       const int p_first, const int p_count, const int n, const int n_items,
                       __global double2 *image SCATTER_PARAM)
{
    const int g = get_global_id(0);
    if (g >= n_items)  /* the launch is padded to whole work-groups */
        return;
    const int m0 = 8 * g;
    const double c = params.c, f0 = params.f0, fs = params.fs, dtau = params.dtau;
    const vec8 p0 = v8(vload8(0, pix[g].x), vload8(0, pix[g].y), vload8(0, pix[g].z));
    const double3 velocity = vload3(0, params.velocity);
    const vec8 vel = v8_splat(velocity);
    realv8 acc_re = (realv8)0, acc_im = (realv8)0;
    for (int p = p_first; p < p_first + p_count; ++p) {
        const bp_pulse_t pl = pulse[p];
        const vec8 tx = v8_splat(vload3(0, pl.tx));
        const vec8 q_emit = v8_add(p0, v8_scale(vel, (double8)pl.eta));
        __global const node_t *nd = nodes + (size_t)p * N_NODES;
#ifndef STOP_AND_GO
        const double8 t1 = meet_time8_uniform(v8_sub(q_emit, tx), velocity, c);
        const vec8 q = v8_add(q_emit, v8_scale(vel, t1));
        const double8 tau = reception8(nd, t1, q, c, dtau);
#else
        const vec8 q = q_emit;
        const vec8 out = v8_sub(q, tx), back = v8_sub(q, node_field(nd, (double8)0.0, dtau, 0));
        const double8 tau = (sqrt(v8_dot(out, out)) + sqrt(v8_dot(back, back))) / c;
#endif
        /* fractional sample index in the record, split in double into integer and fraction */
        const double8 k = tau * fs - pl.t0_fs;
        long8 kl = convert_long8(k);
        kl += (k < convert_double8(kl));  /* floor (a true compare is -1) */
        const realv8 frac = convert_realv8(k - convert_double8(kl));
        kl -= (long)pl.first;  /* the records start pl.first samples into the window (after the split: exact) */
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
            const realv8 keep = convert_realv8(select((double8)0.0, (double8)1.0, fabs(s) <= params.half_sin));
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
#define LOAD2(L) const realv4_t w##L = LOAD_R4(rec + 2 * ic.s##L);
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
        const int8 row = NEAREST_TAP_ROW(convert_int8, frac);
#define W(L) LOAD_R16(rec + 2 * ic.s##L)
        const realv16_t vv = SINC8_LANES(taps, row, W(0), W(1), W(2), W(3), W(4), W(5), W(6), W(7));
#undef W
        const realv8 dr = keep * vv.even, di = keep * vv.odd;
#endif
        acc_re += dr * cs - di * sn;
        acc_im += dr * sn + di * cs;
    }
    real_t re[8], im[8];
    vstore8(acc_re, 0, re);
    vstore8(acc_im, 0, im);
    for (int l = 0; l < 8; ++l) {
#ifdef SCATTER
        if (index[m0 + l] >= 0)
            image[index[m0 + l]] += (double2)(re[l], im[l]);
#else
        image[m0 + l] += (double2)(re[l], im[l]);
#endif
    }
}
