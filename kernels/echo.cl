/* Echo synthesis: exact two-way delays, path amplitudes, and accumulation of the LFM echoes.
 *
 * NumPy twin: clsas/simulate/echo/synth.py (accumulate_reference) and clsas/geometry.py
 * (paths); the launcher is clsas/simulate/echo/synth.py (_OpenCLSynth).
 *
 * Three kernels per chunk of pulses:
 *   echo_paths   one work-item per (sorted scatterer j, pulse p, receiver h): the delay
 *                tau = t1 + t2 in closed form in double (transmitter at emission,
 *                scatterer moving, receiver moving during reception, positions of the receiver
 *                linear between nodes), the amplitude (reflectivity, element patterns, spreading,
 *                occlusion) times the carrier phase exp(-j 2 pi f0 tau) (double), and the echo
 *                centre as sample u = (tau - t0_h) fs split into an integer start = floor(u) and
 *                a fraction frac = u - start (so float32 keeps 1e-7 of a sample at any range);
 *   echo_bounds  min/max start of each CHUNK consecutive (delay-sorted) scatterers;
 *   echo_accumulate  one work-item per ROWS x 16 output samples of one (receiver, pulse)
 *                record: loops over the chunks whose samples can reach it and adds
 *                a exp(j 2 pi alpha d^2) for |d| <= half_len, d = k - u (samples),
 *                alpha = K / (2 fs^2) cycles per sample^2. Explicit 16-wide vectors (PoCL does
 *                not vectorise across work-items of a kernel with loops). The chirp of a path's
 *                first row is evaluated (polynomial sin/cos in float), the following rows by
 *                the exact recurrence z(d + 16) = z(d) w(d), w(d + 16) = w(d) rho with
 *                w(d) = exp(j 2 pi alpha (32 d + 256)), rho = exp(j 2 pi alpha 512): two complex
 *                vector products a row instead of a sin/cos (rounding grows by ~1e-7 a row).
 *
 * Defines: N_NODES (>= 2), SEGMENT_PASSES (node segment re-choices), CHUNK, ROWS (16-sample
 * blocks per work-item),
 * STOP_AND_GO, SPREADING, PATH_WEIGHTS; CLSAS_DOUBLE makes the accumulation double.
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"
#include "geometry.h"

/* One path = (start, frac, amplitude re, im) in one vector: a single 16-byte (float) or
 * 32-byte (double) load per scatterer in the accumulation. In float the integer start is
 * stored bit for bit (as_float), in double as an exact double. */
#ifdef CLSAS_DOUBLE
typedef double4 path_t;
#define PATH_START(v) convert_int((v).x)
#define MAKE_PATH(st, fr, re, im) ((double4)((double)(st), (fr), (re), (im)))
#else
typedef float4 path_t;
#define PATH_START(v) as_int((v).x)
#define MAKE_PATH(st, fr, re, im) ((float4)(as_float(st), (float)(fr), (float)(re), (float)(im)))
#endif

/* soa[((h * 8 + field) * n_pad + j]: the scatterers in receiver h's delay order j (padded to a
 * multiple of 8 with zero-reflectivity copies), fields p0.xyz, vel.xyz, refl re, im;
 * order[h n_pad + j]: their original index (for the occlusion weights);
 * pulse[p]: the transmitter at emission, the emission time and the transmitter's element axis;
 * nodes[(h P + p) N_NODES + k]: receiver h's position and element axis at fast time k dtau;
 * rx[h]: t0_h fs (window start in samples: the echo centre is u = tau fs - t0_h fs) and the
 * element length; params: c, f0, fs, wavelength, tx_length, dtau (node spacing, s);
 * weights[(h P + p) N + n] (PATH_WEIGHTS only). The records (echo_pulse_t, node_t, echo_rx_t,
 * echo_params_t) are declared by the launcher (clsas/simulate/echo/synth.py, RECORDS).
 * One work-item: paths j = 8 g .. 8 g + 7 of (pulse p, receiver h); output at (h P + p) n_pad + j. */
__kernel void echo_paths(__global const double *soa, __global const echo_pulse_t *pulse,
                         __global const node_t *nodes, __global const echo_rx_t *rx,
                         __global const int *order, __global const float *weights,
                         const echo_params_t params, const int n_scat, const int n_pad, const int n_pulses,
                         __global path_t *paths)
{
    const int g = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    const int j0 = 8 * g;
    const double c = params.c, dtau = params.dtau;
    __global const double *f = soa + (size_t)h * 8 * n_pad + j0;
    const vec8 p0 = v8(vload8(0, f), vload8(0, f + n_pad), vload8(0, f + 2 * n_pad));
    const vec8 vel = v8(vload8(0, f + 3 * n_pad), vload8(0, f + 4 * n_pad), vload8(0, f + 5 * n_pad));
    const double8 refl_re = vload8(0, f + 6 * n_pad), refl_im = vload8(0, f + 7 * n_pad);
    const echo_pulse_t pl = pulse[p];
    const vec8 tx = v8_splat(vload3(0, pl.tx));
    const vec8 q_emit = v8_add(p0, v8_scale(vel, (double8)pl.eta));
    __global const node_t *nd = nodes + ((size_t)h * n_pulses + p) * N_NODES;
#ifndef STOP_AND_GO
    const double8 t1 = meet_time8(v8_sub(q_emit, tx), vel, c);
    const vec8 q = v8_add(q_emit, v8_scale(vel, t1));
    const double8 t_rx = reception8(nd, t1, q, c, dtau);
    const vec8 r = node_field(nd, t_rx, dtau, 0);
#else
    const vec8 q = q_emit;
    const double8 t_rx = (double8)0.0;
    const vec8 r = node_field(nd, t_rx, dtau, 0);
#endif
    const vec8 out_dir = v8_sub(q, tx), back_dir = v8_sub(q, r);
    const double8 r1 = sqrt(v8_dot(out_dir, out_dir)), r2 = sqrt(v8_dot(back_dir, back_dir));
#ifndef STOP_AND_GO
    const double8 tau = t_rx;
#else
    const double8 tau = (r1 + r2) / c;
#endif
    const echo_rx_t rxh = rx[h];
    double8 gain = element_gain8(params.tx_length, out_dir, r1, v8_splat(vload3(0, pl.tx_axis)), params.wavelength)
                 * element_gain8(rxh.length, back_dir, r2, node_field(nd, t_rx, dtau, 1), params.wavelength);
#ifdef SPREADING
    gain /= r1 * r2;
#endif
#ifdef PATH_WEIGHTS
    {
        double wl[8];
        for (int l = 0; l < 8; ++l)
            wl[l] = (double)weights[((size_t)h * n_pulses + p) * n_scat + order[h * n_pad + j0 + l]];
        gain *= vload8(0, wl);
    }
#endif
    /* carrier exp(-j 2 pi f0 tau): cycles reduced in double, then sin/cos of the fraction */
    double8 cyc = -params.f0 * tau;
    cyc -= convert_double8(convert_long8(cyc));
#ifdef CLSAS_DOUBLE
    const double8 cs = cospi(2.0 * cyc), sn = sinpi(2.0 * cyc);
#else
    float8 csf, snf;
    expj_fraction8(convert_float8(cyc), &csf, &snf);
    const double8 cs = convert_double8(csf), sn = convert_double8(snf);
#endif
    const double8 re = gain * (refl_re * cs - refl_im * sn), im = gain * (refl_re * sn + refl_im * cs);
    const double8 u = tau * params.fs - rxh.t0_fs;
    long8 fl = convert_long8(u);
    fl += (u < convert_double8(fl));  /* floor by truncation and fix-up (a true compare is -1) */
    const double8 fr = u - convert_double8(fl);
    double a_re[8], a_im[8], a_fr[8];
    long a_fl[8];
    vstore8(re, 0, a_re);
    vstore8(im, 0, a_im);
    vstore8(fr, 0, a_fr);
    vstore8(fl, 0, a_fl);
    __global path_t *o = paths + ((size_t)h * n_pulses + p) * n_pad + j0;
    for (int l = 0; l < 8; ++l) o[l] = MAKE_PATH((int)a_fl[l], a_fr[l], a_re[l], a_im[l]);
}

/* extent[h n_pad + j] = (min, max) over the block's pulses of the start sample of path j
 * (the host turns them into the recording window without copying every path back). */
__kernel void echo_extents(__global const path_t *paths, const int n_pad, const int n_pulses,
                           __global int2 *extent)
{
    const int j = get_global_id(0), h = get_global_id(1);
    __global const path_t *col = paths + (size_t)h * n_pulses * n_pad + j;
    int lo = PATH_START(col[0]), hi = lo;
    for (int p = 1; p < n_pulses; ++p) {
        const int v = PATH_START(col[(size_t)p * n_pad]);
        lo = min(lo, v);
        hi = max(hi, v);
    }
    extent[(size_t)h * n_pad + j] = (int2)(lo, hi);
}

/* bounds[(h P + p) n_chunks + c] = (min, max) of start over the chunk's CHUNK scatterers. */
__kernel void echo_bounds(__global const path_t *paths, const int n_scat, const int n_pulses,
                          __global int2 *bounds)
{
    const int c = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    const int n_chunks = (n_scat + CHUNK - 1) / CHUNK;
    if (c >= n_chunks) return;
    const size_t rec = (size_t)h * n_pulses + p;
    const int j0 = c * CHUNK, j1 = min(n_scat, j0 + CHUNK);
    int lo = PATH_START(paths[rec * n_scat + j0]), hi = lo;
    for (int j = j0 + 1; j < j1; ++j) {
        const int v = PATH_START(paths[rec * n_scat + j]);
        lo = min(lo, v);
        hi = max(hi, v);
    }
    bounds[rec * n_chunks + c] = (int2)(lo, hi);
}

#ifdef CLSAS_DOUBLE
typedef double16 realv_t;
/* exp(j 2 pi cyc) lane-wise, full double precision */
inline void expj_cycles_v(realv_t cyc, realv_t *cs, realv_t *sn)
{
    const realv_t r = cyc - convert_double16(convert_long16(cyc));
    *cs = cospi((realv_t)2.0 * r);
    *sn = sinpi((realv_t)2.0 * r);
}
#else
typedef float16 realv_t;
/* exp(j 2 pi cyc) lane-wise: truncation (PoCL's rint/floor are slow), then the polynomial */
inline void expj_cycles_v(realv_t cyc, realv_t *cs, realv_t *sn)
{
    expj_fraction16(cyc - convert_float16(convert_int16(cyc)), cs, sn);
}
#endif

/* out[(h P + p) n_pad + k] for the ROWS x 16 samples k of the work-item; records of n_pad samples
 * (a multiple of 16 ROWS); samples at k >= n_valid are zero. The echo centres are
 * start - shift[h] + frac (shift: integer samples between the window the starts were computed
 * for and the output window). */
__kernel void echo_accumulate(__global const path_t *paths, __global const int2 *bounds,
                              const real_t alpha, const real_t half_len, const int n_scat,
                              const int n_pulses, const int n_pad, const int n_valid,
                              __global const int *shift, __global complex_t *out)
{
    const int b = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    const int k0 = 16 * ROWS * b, k_last = k0 + 16 * ROWS - 1;
    if (k0 >= n_pad) return;
    const size_t rec = (size_t)h * n_pulses + p;
    const int n_chunks = (n_scat + CHUNK - 1) / CHUNK;
    const int span = (int)half_len + 2;  /* a path reaches samples start - span .. start + span */
    const int sh = shift[h];
    const realv_t lane = (realv_t)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    real_t rho_c, rho_s;  /* exp(j 2 pi alpha 512): the row step's own step */
    {
        real_t r512 = alpha * (real_t)512;
        r512 -= (real_t)convert_int(r512);
        rho_c = cospi((real_t)2 * r512);
        rho_s = sinpi((real_t)2 * r512);
    }
    realv_t acc_re[ROWS], acc_im[ROWS];
    for (int r = 0; r < ROWS; ++r) acc_re[r] = acc_im[r] = (realv_t)0;
    __global const path_t *rp = paths + rec * n_scat;
    for (int c = 0; c < n_chunks; ++c) {
        const int2 bd = bounds[rec * n_chunks + c] - sh;
        if (bd.y + span < k0 || bd.x - span > k_last) continue;
        const int j1 = min(n_scat, (c + 1) * CHUNK);
        for (int j = c * CHUNK; j < j1; ++j) {
            const path_t v = rp[j];
            const int s = PATH_START(v) - sh;
            if (s + span < k0 || s - span > k_last) continue;
            const real_t first = (real_t)(k0 - s) - v.y;  /* d of the work-item's first sample */
            /* rows r_lo..r_hi hold the samples s - span .. s + span (integer arithmetic: PoCL's
             * floor/ceil are slow); rows with a pulse edge are masked below */
            const int a = s - span - k0, e = s + span - k0;
            const int r_lo = a <= 0 ? 0 : a / 16;
            const int r_hi = min(ROWS - 1, e / 16);
            if (r_lo > r_hi) continue;
            /* chirp of the first row, and its step to the next row: alpha ((d + 16)^2 - d^2)
             * = alpha (32 d + 256) cycles; the step itself advances by alpha 512 cycles a row */
            realv_t d = lane + (first + (real_t)(16 * r_lo));
            realv_t c0, s0, wc, ws;
            expj_cycles_v(alpha * d * d, &c0, &s0);
            expj_cycles_v(alpha * ((real_t)32 * d + (real_t)256), &wc, &ws);
            realv_t zc = v.z * c0 - v.w * s0, zs = v.z * s0 + v.w * c0;  /* amplitude folded in */
            for (int r = 0; r < ROWS; ++r) {
                if (r < r_lo) continue;
                if (r > r_hi) break;
                const real_t lo = first + (real_t)(16 * r);
                if (lo < -half_len || lo + (real_t)15 > half_len) {  /* a pulse edge in the row */
                    const realv_t m = select((realv_t)0, (realv_t)1, fabs(lane + lo) <= half_len);
                    acc_re[r] += m * zc;
                    acc_im[r] += m * zs;
                } else {
                    acc_re[r] += zc;
                    acc_im[r] += zs;
                }
                const realv_t nc = zc * wc - zs * ws;  /* z <- z w, w <- w rho */
                zs = zc * ws + zs * wc;
                zc = nc;
                const realv_t mc = wc * rho_c - ws * rho_s;
                ws = wc * rho_s + ws * rho_c;
                wc = mc;
            }
        }
    }
    for (int r = 0; r < ROWS; ++r) {
        real_t re[16], im[16];
        vstore16(acc_re[r], 0, re);
        vstore16(acc_im[r], 0, im);
        const int kr = k0 + 16 * r;
        __global complex_t *o = out + rec * n_pad + kr;
        for (int l = 0; l < 16; ++l)
            o[l] = (kr + l < n_valid) ? complex_new(re[l], im[l]) : complex_new((real_t)0, (real_t)0);
    }
}
