/* Echo synthesis: exact two-way delays, path amplitudes, and accumulation of the LFM echoes.
 *
 * NumPy twin: clsas/simulate/echo.py (accumulate_reference) and clsas/simulate/geometry.py
 * (paths); the launcher is clsas/simulate/echo.py (_OpenCLSynth).
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
 *   echo_accumulate  one work-item per 16 output samples of one (receiver, pulse) record:
 *                loops over the chunks whose samples can reach the block and adds
 *                a exp(j 2 pi alpha d^2) for |d| <= half_len, d = k - u (samples),
 *                alpha = K / (2 fs^2) cycles per sample^2. Explicit 16-wide vectors (PoCL does
 *                not vectorise across work-items of a kernel with loops); in float the chirp
 *                phase uses a polynomial sin/cos of the phase reduced to [-1/2, 1/2] cycle.
 *
 * Defines: N_NODES (>= 2), SEGMENT_PASSES (node segment re-choices), CHUNK, ROWS (16-sample
 * blocks per work-item),
 * STOP_AND_GO, SPREADING, PATH_WEIGHTS; CLSAS_DOUBLE makes the accumulation double.
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"

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

/* params: c, f0, fs, wavelength, tx_length, dtau (node spacing, s), unused, unused */
#define P_C(pr) ((pr).s0)
#define P_F0(pr) ((pr).s1)
#define P_FS(pr) ((pr).s2)
#define P_LAMBDA(pr) ((pr).s3)
#define P_LTX(pr) ((pr).s4)
#define P_DTAU(pr) ((pr).s5)

inline double element_gain(double length, double3 unit_dir, double3 axis, double wavelength)
{
    if (length == 0.0) return 1.0;
    double x = length * dot(unit_dir, axis) / wavelength;
    return x == 0.0 ? 1.0 : sinpi(x) / (M_PI * x);
}

/* Linear interpolation of node field (s012 position or s345 axis) at fast time tau. */
inline double3 node_position(__global const double8 *nodes, double tau, double dtau)
{
    double x = tau / dtau;
    int seg = clamp(convert_int(x), 0, N_NODES - 2);
    double w = x - (double)seg;
    return mix(nodes[seg].s012, nodes[seg + 1].s012, w);
}

inline double3 node_axis(__global const double8 *nodes, double tau, double dtau)
{
    double x = tau / dtau;
    int seg = clamp(convert_int(x), 0, N_NODES - 2);
    double w = x - (double)seg;
    return mix(nodes[seg].s345, nodes[seg + 1].s345, w);
}

/* The time t > 0 at which a wave leaving point A at t = 0 with speed c meets a point moving
 * as A + D + W t: |D + W t| = c t, i.e. (c^2 - |W|^2) t^2 - 2 (D.W) t - |D|^2 = 0, whose positive
 * root is t = [D.W + sqrt((D.W)^2 + (c^2 - |W|^2) |D|^2)] / (c^2 - |W|^2). Exact for uniform
 * motion; no cancellation since |D.W| <= |W||D| << c |D|. (For a straight track and a stationary
 * target, applied to both legs, this is Zhang et al. 2019 eq. (1).) */
inline double meet_time(double3 d, double3 w, double c)
{
    const double a = c * c - dot(w, w), b = dot(d, w);
    return (b + sqrt(b * b + a * dot(d, d))) / a;
}

/* scat[n]: p0.xyz, vel.xyz, refl (re, im); pulse[p]: tx.xyz, eta, tx axis.xyz;
 * nodes[(h P + p) N_NODES + k]: position.xyz, axis.xyz at fast time k dtau;
 * rx[h]: t0_h fs (window start in samples, the echo centre is u = tau fs - t0_h fs), element length; order[h N + j]: scatterer at sorted position j;
 * weights[(h P + p) N + n] (PATH_WEIGHTS only). Outputs at (h P + p) N + j.
 *
 * Outgoing leg: the scatterer moves uniformly, so t1 = meet_time(Q(eta) - T, v) exactly.
 * Incoming leg: the receiver moves linearly within a node segment [k dtau, (k+1) dtau] with
 * velocity W_k, so for that segment t2 = meet_time(R_k(eta + t1) - Q, W_k) with R_k extended
 * linearly; the segment is taken where t1 + |R(t1) - Q| / c falls and re-chosen (SEGMENT_PASSES
 * times at most) if the solution lands in another one. With two nodes (uniform motion) this is
 * exact in one pass. */
__kernel void echo_paths(__global const double8 *scat, __global const double8 *pulse,
                         __global const double8 *nodes, __global const double2 *rx,
                         __global const int *order, __global const float *weights,
                         const double8 params, const int n_scat, const int n_pulses,
                         __global path_t *paths)
{
    const int j = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    if (j >= n_scat) return;
    const int n = order[h * n_scat + j];
    const double c = P_C(params), dtau = P_DTAU(params);
    const double8 s = scat[n];
    const double8 pl = pulse[p];
    const double3 tx = pl.s012, vel = s.s345;
    const double3 q_emit = s.s012 + vel * pl.s3;
    __global const double8 *nd = nodes + ((size_t)h * n_pulses + p) * N_NODES;
#ifndef STOP_AND_GO
    const double t1 = meet_time(q_emit - tx, vel, c);
    const double3 q = q_emit + vel * t1;
    double t_rx = t1 + length(node_position(nd, t1, dtau) - q) / c;
    for (int pass = 0; pass < SEGMENT_PASSES; ++pass) {
        const int seg = clamp(convert_int(t_rx / dtau), 0, N_NODES - 2);
        const double3 w = (nd[seg + 1].s012 - nd[seg].s012) / dtau;
        const double3 r_t1 = nd[seg].s012 + w * (t1 - (double)seg * dtau);
        t_rx = t1 + meet_time(r_t1 - q, w, c);
    }
#else
    const double3 q = q_emit;
    const double t_rx = 0.0;
#endif
    const double3 r = node_position(nd, t_rx, dtau);
    const double r1 = length(q - tx), r2 = length(q - r);
#ifndef STOP_AND_GO
    const double tau = t_rx;
#else
    const double tau = (r1 + r2) / c;
#endif
    const double2 rxh = rx[h];
    double gain = element_gain(P_LTX(params), (q - tx) / r1, pl.s456, P_LAMBDA(params))
                * element_gain(rxh.s1, (q - r) / r2, node_axis(nd, t_rx, dtau), P_LAMBDA(params));
#ifdef SPREADING
    gain /= r1 * r2;
#endif
#ifdef PATH_WEIGHTS
    gain *= (double)weights[((size_t)h * n_pulses + p) * n_scat + n];
#endif
    /* carrier exp(-j 2 pi f0 tau): cycles reduced in double, then sin/cos of the fraction */
    double cyc = -P_F0(params) * tau;
    cyc -= (double)convert_long(cyc);
#ifdef CLSAS_DOUBLE
    const double cs = cospi(2.0 * cyc), sn = sinpi(2.0 * cyc);
#else
    float csf, snf;
    expj_fraction((float)cyc, &csf, &snf);
    const double cs = csf, sn = snf;
#endif
    const double re = gain * (s.s6 * cs - s.s7 * sn), im = gain * (s.s6 * sn + s.s7 * cs);
    const double u = tau * P_FS(params) - rxh.s0;
    long fl = convert_long(u);
    fl -= (u < (double)fl);  /* floor by truncation and fix-up (PoCL's floor is slow) */
    paths[((size_t)h * n_pulses + p) * n_scat + j] = MAKE_PATH((int)fl, u - (double)fl, re, im);
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
            for (int r = 0; r < ROWS; ++r) {
                const real_t lo = first + (real_t)(16 * r), hi = lo + (real_t)15;
                if (hi < -half_len || lo > half_len) continue;  /* the pulse misses this row */
                const realv_t d = lane + lo;
                realv_t cs, sn;
                expj_cycles_v(alpha * d * d, &cs, &sn);
                if (lo < -half_len || hi > half_len) {  /* a pulse edge inside the row: mask */
                    const realv_t m = select((realv_t)0, (realv_t)1, fabs(d) <= half_len);
                    cs *= m;
                    sn *= m;
                }
                acc_re[r] += v.z * cs - v.w * sn;
                acc_im[r] += v.z * sn + v.w * cs;
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
