/* Time-domain back-projection of range-compressed echoes, one receiver and one block of
 * pulses a launch. Two kernels, each owned by one object of clsas/image/backprojection/ that
 * declares its records (the -D options, the structs in its preamble, its parameters and the
 * layout of its pixel fields) and launches it: bp_tile by tile_kernel.TileKernel, bp_block by
 * exact_kernel.ExactKernel. NumPy twin of both: clsas/image/backprojection/reference.py.
 *
 * bp_tile (built with BP_TILE; precision="single"): float32 geometry relative to a reference
 *   point per (tile, pulse). One work-item: ROWS vectors of 16 pixels (float16 lanes) of one
 *   spatial tile. The host gives, per (tile, pulse), the exact legs of the tile's reference
 *   point in double (rounded to float): B = q_ref - tx, C = R_ref - q_ref, the receiver
 *   velocity v_r over the tile's delay span, c^2 t1_ref - B.v, c^2 t2_ref - C.v_r, the sample
 *   index of T_ref = t1_ref + t2_ref split into an int and a fraction, and the carrier cycles
 *   f0 T_ref reduced to [-1/2, 1/2]. Per pixel (offset delta from the reference, float) the
 *   delay offsets s1 = t1 - t1_ref and s2 = t2 - t2_ref are the stable roots
 *     s1 = N1 / (b1 + sqrt(b1^2 + a1 N1)),  N1 = 2 B.delta + |delta|^2,  b1 = c^2 t1_ref - (B + delta).v,
 *     e = (v_r - v) s1 - delta,  s2 = N2 / (b2 + sqrt(b2^2 + a2 N2)),
 *     N2 = 2 C.e + |e|^2,  b2 = c^2 t2_ref - (C + e).v_r,  a1 = c^2 - |v|^2,  a2 = c^2 - |v_r|^2,
 *   so that every float error scales with |delta|, not with the range (derivation:
 *   clsas/image/backprojection/tile_kernel.py).
 * bp_block (otherwise): the exact delays in double per pixel and pulse (geometry.h), eight
 *   pixels (double8 lanes) a work-item; precision="double" (with CLSAS_DOUBLE) and the
 *   fallback of precision="single" when a receiver's motion is not linear over a tile.
 *
 * Both: the range-compressed sample at the delay by linear interpolation of the (upsampled)
 * record (INTERP_LINEAR) or by the 8-tap Kaiser-windowed sinc of interp.h on the original
 * samples (INTERP_SINC8, taps from the nearest row of the table over the fractional offset); a
 * record reads as zero where the interpolator would need samples outside it; the phase rotation
 * exp(+j 2 pi f0 tau) from cycles reduced to a fraction (polynomial sin/cos, common.h);
 * accumulation in float (double with CLSAS_DOUBLE) over the launch's pulses, added once into
 * the double image at the end (blocked sum).
 *
 * Defines: BP_TILE (with ROWS, PULSES, MOVING when the pixels move, SAME_LEGS, ROW_SHIFT, PULSE_SPAN), or
 * N_NODES and SEGMENT_PASSES (geometry.h) and STOP_AND_GO for bp_block; INTERP_LINEAR or
 * INTERP_SINC8 (with TAP_ROWS); APERTURE (keep |sin theta| off broadside <= sin(aperture / 2),
 * theta measured from the x-z plane); CLSAS_DOUBLE (bp_block's data, phases and sums in double:
 * precision="double"). Portable OpenCL C 1.2: no vendor builtins.
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"
#include "interp.h"

/* Data, interpolation and sums in float, or in double with CLSAS_DOUBLE (precision="double"). */
#ifdef CLSAS_DOUBLE
typedef double2 sample_t;
typedef double2 realv2_t;
typedef double4 realv4_t;
typedef double8 realv8;
typedef double16 realv16_t;
#define convert_realv8 convert_double8
#define SINC8_LANES sinc8_lanes_double
#define LOAD_R16 LOAD_D16
#define LOAD_R4 LOAD_D4
#else
typedef float2 sample_t;
typedef float2 realv2_t;
typedef float4 realv4_t;
typedef float8 realv8;
typedef float16 realv16_t;
#define convert_realv8 convert_float8
#define SINC8_LANES sinc8_lanes
#define LOAD_R16 LOAD_F16
#define LOAD_R4 LOAD_F4
#endif

#ifdef BP_TILE
#define FOR_ROWS _Pragma("unroll") for (int r = 0; r < ROWS; ++r)
#define CHAINS (ROWS * PULSES)
#define FOR_CHAINS _Pragma("unroll") for (int j = 0, r = 0; j < CHAINS; ++j, r = j % ROWS)
#define RJ R[j / ROWS]

/* SAME_LEGS (stop-and-go with the receiver at the transmitter: a monostatic sonar): t2 = t1, so
 * s = 2 s1 and leg 2 is not computed.
 * pix[ROWS g + r] (bp_pixels_t, TileKernel.PIXELS): work-item g's row r of sixteen pixels (image
 *   slots m = 16 (ROWS g + r) + lane): delta (the pixel at t = 0 minus its tile's reference point,
 *   m: dx, dy, dz), dd = |delta|^2 and (MOVING) dv = delta . v;
 * tile_of[g]: the tile of work-item g;
 * ref[t * ref_stride + p - ref_first] (tile_ref_t): the reference of (tile t, pulse p): leg1 = B,
 *   b1 = c^2 t1_ref - B.v, leg2 = C, b2 = c^2 t2_ref - C.v_r, v_rx = v_r, a2, k_ref the integer
 *   sample index of T_ref in the records, k_frac its fraction, cycles = f0 T_ref reduced,
 *   range1 = c t1_ref;
 * params (tile_params_t): a1, fs (of the data), f0, velocity v, half_sin = sin(aperture / 2), c;
 * data[p n + i]: the receiver's range-compressed record of pulse p; taps: the 8-tap table (interp.h);
 * image[m] += the sum over pulses p_first .. p_first + p_count - 1.
 * ROW_SHIFT (ffbp's first stage, clsas/image/ffbp/leaves.py: many sub-apertures a launch): pulse p
 *   of tile t reads record row p + row_shift[t] (its reference stays ref[t * ref_stride + p - ref_first]). */
#ifdef ROW_SHIFT
#define ROW_SHIFT_PARAM , __global const int *row_shift
#define TILE_ROW_SHIFT row_shift[tile_of[g]]
#else
#define ROW_SHIFT_PARAM
#define TILE_ROW_SHIFT 0
#endif
/* PULSE_SPAN (back-projection with an aperture, clsas/image/backprojection/tiles.py): span[t] = the
 * pulses [x, y) tile t can see within it (a conservative bound from its references); the tile
 * sums only those of p_first .. p_first + p_count - 1, and the aperture mask decides per pixel. */
#ifdef PULSE_SPAN
#define PULSE_SPAN_PARAM , __global const int2 *span
#define TILE_BEGIN max(p_first, span[tile_of[g]].x)
#define TILE_END min(p_first + p_count, span[tile_of[g]].y)
#else
#define PULSE_SPAN_PARAM
#define TILE_BEGIN p_first
#define TILE_END (p_first + p_count)
#endif
__kernel void bp_tile(__global const bp_pixels_t *pix, __global const int *tile_of, __global const tile_ref_t *ref,
                      const int ref_stride, const int ref_first, __global const sample_t *data, __global const float *taps,
                      const tile_params_t params, const int p_first, const int p_count, const int n,
                      const int n_items, __global double2 *image ROW_SHIFT_PARAM PULSE_SPAN_PARAM)
{
    const int g = get_global_id(0);
    if (g >= n_items)  /* the launch is padded to whole work-groups */
        return;
    __global const tile_ref_t *tref = ref + (size_t)tile_of[g] * ref_stride;
    const int row_first = TILE_ROW_SHIFT;
    const float a1 = params.a1, fs = params.fs, f0 = params.f0;
    const float3 vel = vload3(0, params.velocity);
    float16 dx[ROWS], dy[ROWS], dz[ROWS], dd[ROWS], acc_re[ROWS], acc_im[ROWS];
#ifdef MOVING
    float16 dv[ROWS];
#endif
    FOR_ROWS {
        __global const bp_pixels_t *px = pix + ROWS * g + r;
        dx[r] = vload16(0, px->dx);
        dy[r] = vload16(0, px->dy);
        dz[r] = vload16(0, px->dz);
        dd[r] = vload16(0, px->dd);
#ifdef MOVING
        dv[r] = vload16(0, px->dv);
#endif
        acc_re[r] = (float16)0.0f;
        acc_im[r] = (float16)0.0f;
    }
    const int p_end = TILE_END;
    for (int p = TILE_BEGIN; p < p_end; p += PULSES) {
        /* PULSES pulses x ROWS rows = CHAINS independent dependency chains, each step done for all
         * of them before the next (the out-of-order core overlaps them); a pulse past the block's
         * end repeats the last one with weight 0 */
        tile_ref_t R[PULSES];
        __global const float *rec[PULSES];
        float live[PULSES];
        _Pragma("unroll") for (int j = 0; j < PULSES; ++j) {
            const int pj = min(p + j, p_end - 1);
            R[j] = tref[pj - ref_first];
            rec[j] = (__global const float *)(data + (size_t)(pj + row_first) * n);
            live[j] = p + j < p_end ? 1.0f : 0.0f;
        }
        float16 s1[CHAINS], s[CHAINS], frac[CHAINS], cs[CHAINS], sn[CHAINS];
        int16 ki[CHAINS];
        FOR_CHAINS {  /* leg 1: s1 = t1 - t1_ref */
            const float3 b = vload3(0, RJ.leg1);
            const float16 n1 = 2.0f * (b.x * dx[r] + b.y * dy[r] + b.z * dz[r]) + dd[r];
#ifdef MOVING
            const float16 b1 = RJ.b1 - dv[r];
#else
            const float16 b1 = (float16)RJ.b1;
#endif
            s1[j] = n1 / (b1 + sqrt(b1 * b1 + a1 * n1));
        }
#ifdef SAME_LEGS
        FOR_CHAINS  /* monostatic stop-and-go: the echo returns along the outgoing leg, s2 = s1 */
            s[j] = 2.0f * s1[j];
#else
        FOR_CHAINS {  /* leg 2: s2 = t2 - t2_ref, e = (v_r - v) s1 - delta; s = s1 + s2 */
            const float3 v_r = vload3(0, RJ.v_rx), cc = vload3(0, RJ.leg2), u = v_r - vel;  /* u = v_r - v */
            const float16 ex = u.x * s1[j] - dx[r], ey = u.y * s1[j] - dy[r], ez = u.z * s1[j] - dz[r];
            const float16 n2 = 2.0f * (cc.x * ex + cc.y * ey + cc.z * ez) + (ex * ex + ey * ey + ez * ez);
            const float16 b2 = RJ.b2 - (v_r.x * ex + v_r.y * ey + v_r.z * ez);
            s[j] = s1[j] + n2 / (b2 + sqrt(b2 * b2 + RJ.a2 * n2));
        }
#endif
        FOR_CHAINS {  /* sample index K_ref + (frac_ref + s fs), split by truncation (floor is slow) */
            const float16 kf = RJ.k_frac + s[j] * fs;
            int16 k = convert_int16(kf);
            k += kf < convert_float16(k);  /* floor (a true compare is -1) */
            frac[j] = kf - convert_float16(k);
            ki[j] = k + RJ.k_ref;
        }
        FOR_CHAINS {  /* carrier exp(+j 2 pi f0 tau): cycles f0 T_ref (reduced) + f0 s, reduced again */
            float16 cyc = RJ.cycles + f0 * s[j];
            cyc -= convert_float16(convert_int16(cyc));
            expj_fraction16(cyc, &cs[j], &sn[j]);
            cs[j] *= live[j / ROWS];
            sn[j] *= live[j / ROWS];
        }
#ifdef APERTURE
        FOR_CHAINS {  /* sin theta = (q - tx).y / (c t1), q - tx = B + delta + v s1 */
            const float16 keep = select((float16)0.0f, (float16)1.0f, fabs(vload3(0, RJ.leg1).y + dy[r] + vel.y * s1[j])
                                        <= params.half_sin * (RJ.range1 + params.c * s1[j]));
            cs[j] *= keep;
            sn[j] *= keep;
        }
#endif
        FOR_CHAINS {
            __global const float *recj = rec[j / ROWS];
#ifdef INTERP_LINEAR
            /* samples i and i + 1 of each lane in one 4-wide load, transposed in registers */
            const int16 ic = clamp(ki[j], (int16)0, (int16)(n - 2));
            const float16 keep = select((float16)0.0f, (float16)1.0f, ki[j] >= (int16)0 && ki[j] < (int16)(n - 1));
#define W(L) LOAD_F4(recj + 2 * ic.s##L)
            const float16 w0 = (float16)(W(0), W(1), W(2), W(3)), w1 = (float16)(W(4), W(5), W(6), W(7));
            const float16 w2 = (float16)(W(8), W(9), W(a), W(b)), w3 = (float16)(W(c), W(d), W(e), W(f));
#undef W
            const float16 a_re = (float16)(w0.s048c, w1.s048c, w2.s048c, w3.s048c);
            const float16 a_im = (float16)(w0.s159d, w1.s159d, w2.s159d, w3.s159d);
            const float16 b_re = (float16)(w0.s26ae, w1.s26ae, w2.s26ae, w3.s26ae);
            const float16 b_im = (float16)(w0.s37bf, w1.s37bf, w2.s37bf, w3.s37bf);
            const float16 dr = keep * mix(a_re, b_re, frac[j]), di = keep * mix(a_im, b_im, frac[j]);
#else
            /* samples i - 3 .. i + 4 of each lane, the taps of the nearest fractional-offset row */
            const int16 ic = clamp(ki[j] - 3, (int16)0, (int16)(n - 8));
            const float16 keep = select((float16)0.0f, (float16)1.0f, ki[j] >= (int16)3 && ki[j] < (int16)(n - 4));
            const int16 row = NEAREST_TAP_ROW(convert_int16, frac[j]);
#define W(L) LOAD_F16(recj + 2 * ic.s##L)
            const float16 lo = sinc8_lanes(taps, row.lo, W(0), W(1), W(2), W(3), W(4), W(5), W(6), W(7));
            const float16 hi = sinc8_lanes(taps, row.hi, W(8), W(9), W(a), W(b), W(c), W(d), W(e), W(f));
#undef W
            const float16 dr = keep * (float16)(lo.even, hi.even), di = keep * (float16)(lo.odd, hi.odd);
#endif
            acc_re[r] += dr * cs[j] - di * sn[j];
            acc_im[r] += dr * sn[j] + di * cs[j];
        }
    }
    for (int r = 0; r < ROWS; ++r) {
        float re[16], im[16];
        vstore16(acc_re[r], 0, re);
        vstore16(acc_im[r], 0, im);
        const int m = 16 * (ROWS * g + r);
        for (int l = 0; l < 16; ++l) image[m + l] += (double2)(re[l], im[l]);
    }
}

#else /* bp_block: exact double geometry */
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
                       __global double2 *image)
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
    for (int l = 0; l < 8; ++l) image[m0 + l] += (double2)(re[l], im[l]);
}
#endif /* BP_TILE */
