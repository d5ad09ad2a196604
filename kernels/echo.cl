/* Echo synthesis: exact two-way delays, path amplitudes, and accumulation of the LFM echoes.
 *
 * NumPy twin: clsas/synthesis/echo/reference.py (accumulate_reference), clsas/synthesis/paths.py
 * (paths) and clsas/geometry.py; the launcher is clsas/synthesis/echo/launch.py (OpenCLSynth).
 *
 * Three kernels per chunk of pulses:
 *   echo_paths   one work-item per (8 sorted scatterers, pulse p, receiver h) and path kind
 *                (direct, or bouncing off the sea surface / seabed: the launcher hands an image
 *                transmitter and image receiver nodes, clsas/synthesis/propagation.py): the delay
 *                tau = t1 + t2 in closed form in double (transmitter at emission, scatterer
 *                moving, receiver moving during reception, positions of the receiver linear
 *                between nodes), the amplitude (reflectivity, element patterns, spreading,
 *                reflection coefficients, absorption, path weights) times the carrier phase
 *                exp(-j 2 pi f0 tau) (double), and the echo centre as sample u = (tau - t0_h) fs
 *                split into an integer start = floor(u) and a fraction frac = u - start (so
 *                float32 keeps 1e-7 of a sample at any range). With EXTENDED paths also the
 *                path's own chirp: the echo is a exp(j 2 pi (chirp d^2 + lin d) + gamma d^2 +
 *                beta d) for lo <= d <= hi, d = k - u (samples): intra-pulse Doppler (the delay
 *                of the wavelet emitted u seconds into the pulse, D(u) = D0 + D1 u + D2 u^2,
 *                from the exact derivatives of the two legs, clsas/synthesis/paths.py) and the
 *                loss over the band (absorption and surface roughness as an envelope,
 *                clsas/synthesis/propagation.py);
 *   echo_bounds  first and last sample reached by each CHUNK consecutive (delay-sorted) paths;
 *   echo_extents, echo_spread  each path's extent over a pulse block, each record's delay spread;
 *   echo_accumulate  one work-item per ROWS x 16 output samples of one (receiver, pulse)
 *                record: loops over the chunks that can reach it and adds each path's echo
 *                (add_raw_echo) or, COMPRESSED, its compressed response (add_compressed_echo).
 *                Explicit 16-wide vectors (PoCL does not vectorise across work-items of a
 *                kernel with loops). The chirp of a path's first row is evaluated (polynomial
 *                sin/cos in float; exp for an envelope), the following rows by the exact
 *                recurrence z(d + 16) = z(d) w(d), w(d + 16) = w(d) rho with
 *                w(d) = exp(E(d + 16) - E(d)), rho = exp(E(d + 32) - 2 E(d + 16) + E(d)), E the
 *                quadratic exponent: two complex vector products a row instead of a sin/cos
 *                (rounding grows by ~1e-7 a row).
 *
 * Every kernel is launched in fixed work-groups of the launcher's size along its first dimension
 * (clsas.opencl.work_groups: PoCL compiles it once whatever the shape) and returns for the
 * work-items past the end.
 *
 * Defines: N_NODES (>= 2), SEGMENT_PASSES (node segment re-choices), CHUNK, ROWS (16-sample
 * blocks per work-item), DELAYS_ONLY (echo_paths writes the echo centres alone), STOP_AND_GO, SPREADING, PATH_WEIGHTS, EXTENDED (paths with their own
 * chirp and envelope), INTRA_PULSE (1: moving scatterers, 2: every path), ABSORPTION, BOUNCES,
 * BOTTOM_TABLE (entries of the seabed's reflection table); CLSAS_DOUBLE makes the accumulation
 * double. The records (echo_pulse_t, node_t, echo_rx_t, echo_params_t, echo_legs_t, echo_path_t)
 * and the scatterer fields (SCAT_*) are declared by the launcher
 * (clsas/synthesis/echo/records.py).
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"
#include "geometry.h"

#define PATH_START(v) ((v).start)
#define UNHEARD (1 << 30)  /* the start sample of a path that carries no echo (a facet out of the beam) */

/* The legs' bounces: the factor (re, im) and the log-amplitude terms per Hz (lnf1) and per Hz^2
 * (lnf2) of the band envelope, for grazing angles sin_g (8 lanes) off bounce b of a leg. */
#ifdef BOUNCES
inline void bounce_law(int law, double rms, double8 sin_g, __global const double2 *bottom, double f0, double c,
                       double8 *re, double8 *im, double8 *lnf1, double8 *lnf2)
{
    if (law == 1) {  /* sea surface: -exp(-q f^2), q = 2 (2 pi h sin / c)^2 */
        const double8 k = 2.0 * M_PI * rms * sin_g / c;
        const double8 q = 2.0 * k * k;
        const double8 m = -exp(-q * f0 * f0);
        *re *= m;
        *im *= m;
        *lnf1 -= 2.0 * q * f0;
        *lnf2 -= q;
    } else if (law == 2) {  /* seabed: its reflection coefficient, linear between table entries */
        double s[8], br[8], bi[8];
        vstore8(clamp(sin_g, 0.0, 1.0) * (double)(BOTTOM_TABLE - 1), 0, s);
        for (int l = 0; l < 8; ++l) {
            const int i = min(convert_int(s[l]), BOTTOM_TABLE - 2);
            const double w = s[l] - (double)i;
            const double2 v = bottom[i] * (1.0 - w) + bottom[i + 1] * w;
            br[l] = v.x;
            bi[l] = v.y;
        }
        const double8 vr = vload8(0, br), vi = vload8(0, bi);
        const double8 nr = *re * vr - *im * vi;
        *im = *re * vi + *im * vr;
        *re = nr;
    }
}
#endif

#ifdef INTRA_PULSE
/* d/du and d2/du2 of the meeting time t(u) of |D + A u + W t| = c t (uniform motion) at u = 0,
 * with r = D + W t the separation there (implicit differentiation of |r|^2 - c^2 t^2 = 0). */
inline void meet_derivatives(vec8 r, double8 t, vec8 a, vec8 w, double c, double8 *d1, double8 *d2)
{
    const double8 ft = v8_dot(r, w) - c * c * t;
    const double8 t1 = -v8_dot(r, a) / ft;
    *d1 = t1;
    *d2 = -(v8_dot(a, a) + 2.0 * v8_dot(a, w) * t1 + (v8_dot(w, w) - c * c) * t1 * t1) / ft;
}
#endif

/* The scatterers at positions 0 .. split - 1 (the targets: tsoa[(h * SCAT_FIELDS + field) * split + j],
 * receiver h's delay order, padded to a multiple of 8 with zero-reflectivity copies; torder[h split + j]
 * their original index) and from split on (the seafloor's facets, shared by the receivers:
 * fsoa[field * n_floor + j - split], forder likewise; fields SCAT_P0 (3), SCAT_VEL (3), SCAT_REFL
 * (re, im), SCAT_ON_FLOOR (1: on the seabed)). Work-item g computes the 8 positions from
 * 8 g (8 g + jump from split on: the facets a pulse block's beam can reach, a contiguous range);
 * a facet outside active[p] (positions [x, y): the whole bands pulse p's beam can reach) or
 * outside the beam's reach itself (beam[p] = the real transmitter's position (x, y, z) and
 * tan(psi) in w, w < 0: every facet; Facets.in_reach: |y - t_y| <= tan(psi) hypot(x - t_x,
 * z - t_z)) gets no echo: start UNHEARD, amplitude 0;
 * pulse[p]: the (image) transmitter at emission, its velocity, the emission time and its element
 * axis; nodes[(h P + p) N_NODES + k]: receiver h's (image) position and element axis at fast
 * time k dtau; rx[h]: t0_h fs (window start in samples) and the element length; legs: the path
 * kind's bounces; weights[(h w_rx + p) N + n] (PATH_WEIGHTS; w_rx = 0: shared by the receivers);
 * bottom[BOTTOM_TABLE]: the seabed's reflection coefficient at sin(grazing) = i / (size - 1).
 * One work-item: paths j = 8 g .. 8 g + 7 of (pulse p, receiver h); output at (h P + p) stride +
 * offset + j (the kind's slot in records of every kind's paths). */
__kernel void echo_paths(__global const double *tsoa, __global const double *fsoa, __global const echo_pulse_t *pulse,
                         __global const node_t *nodes, __global const echo_rx_t *rx,
                         __global const int *torder, __global const int *forder, __global const float *weights,
                         __global const double2 *bottom, const echo_params_t params, const echo_legs_t legs,
                         const int n_scat, const int split, const int n_floor, const int jump,
                         __global const int2 *active, __global const double4 *beam, const int n_pulses, const int w_rx, const int stride,
                         const int offset, const int n_items, __global echo_path_t *paths)
{
    const int g = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    if (g >= n_items) return;  /* the launch is padded to whole work-groups */
    const int j0 = 8 * g;
    const int pos0 = j0 < split ? j0 : j0 + jump;  /* the first of the work-item's 8 positions */
    const int facets = pos0 >= split;
    const int n_pad = facets ? n_floor : split;  /* the field stride */
    __global const double *f = facets ? fsoa + (pos0 - split) : tsoa + (size_t)h * SCAT_FIELDS * split + pos0;
    __global const int *order = facets ? forder + (pos0 - split) : torder + (size_t)h * split + pos0;
    const double c = params.c, dtau = params.dtau;
    const vec8 p0 = v8(vload8(0, f + (SCAT_P0 + 0) * n_pad), vload8(0, f + (SCAT_P0 + 1) * n_pad),
                       vload8(0, f + (SCAT_P0 + 2) * n_pad));
    const vec8 vel = v8(vload8(0, f + (SCAT_VEL + 0) * n_pad), vload8(0, f + (SCAT_VEL + 1) * n_pad),
                        vload8(0, f + (SCAT_VEL + 2) * n_pad));
    const double8 refl_re = vload8(0, f + SCAT_REFL * n_pad), refl_im = vload8(0, f + (SCAT_REFL + 1) * n_pad);
    const int2 act = active[p];
    const double4 bm = beam[p];
    long in_beam[8];  /* -1: lane l's facet is in pulse p's reach (targets: always) */
    vstore8(bm.w < 0.0 ? (long8)(-1) : (fabs(p0.y - bm.y) <= bm.w * hypot(p0.x - bm.x, p0.z - bm.z)), 0,
            in_beam);
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
#ifdef DELAYS_ONLY
    {   /* the echo centres alone: all that echo_extents, echo_spread and the delays read */
        const double8 u = tau * params.fs - rxh.t0_fs;
        long8 fl = convert_long8(u);
        fl += (u < convert_double8(fl));  /* floor by truncation and fix-up (a true compare is -1) */
        double x_fr[8];
        long x_fl[8];
        vstore8(u - convert_double8(fl), 0, x_fr);
        vstore8(fl, 0, x_fl);
        __global echo_path_t *o = paths + ((size_t)h * n_pulses + p) * stride + offset + j0;
        for (int l = 0; l < 8; ++l) {
            const int heard = !facets || (pos0 + l >= act.x && pos0 + l < act.y && in_beam[l]);
            o[l].start = heard ? (int)x_fl[l] : UNHEARD;
            o[l].frac = (real_t)x_fr[l];
        }
        return;
    }
#endif
    double8 gain = element_gain8(params.tx_length, out_dir, r1, v8_splat(vload3(0, pl.tx_axis)), params.wavelength)
                 * element_gain8(rxh.length, back_dir, r2, node_field(nd, t_rx, dtau, 1), params.wavelength);
#ifdef SPREADING
    gain /= r1 * r2;
#endif
#ifdef PATH_WEIGHTS
    {
        double wl[8];
        for (int l = 0; l < 8; ++l)
            wl[l] = (double)weights[((size_t)h * w_rx + p) * n_scat + order[l]];
        gain *= vload8(0, wl);
    }
#endif
    if (legs.touches_floor)  /* a bounce off the seabed next to a scatterer on it: its direct path */
        gain = select(gain, (double8)0.0, vload8(0, f + SCAT_ON_FLOOR * n_pad) != 0.0);
    double8 fac_re = gain, fac_im = (double8)0.0, lnf1 = (double8)0.0, lnf2 = (double8)0.0;
#ifdef BOUNCES
    for (int b = 0; b < legs.n_out; ++b) {
        const vec8 n = v8_splat(vload3(b, legs.out_normal));
        bounce_law(legs.out_law[b], legs.out_rms[b], fabs(v8_dot(n, out_dir)) / r1, bottom, params.f0, c,
                   &fac_re, &fac_im, &lnf1, &lnf2);
    }
    for (int b = 0; b < legs.n_back; ++b) {
        const vec8 n = v8_splat(vload3(b, legs.back_normal));
        bounce_law(legs.back_law[b], legs.back_rms[b], fabs(v8_dot(n, back_dir)) / r2, bottom, params.f0, c,
                   &fac_re, &fac_im, &lnf1, &lnf2);
    }
#endif
#ifdef ABSORPTION
    {
        const double8 length = c * tau;  /* r1 + r2: the path's length */
        const double8 m = exp(-params.abs_a0 * length);
        fac_re *= m;
        fac_im *= m;
        lnf1 -= params.abs_a1 * length;
        lnf2 -= params.abs_a2 * length;
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
    const double8 a_re = fac_re * refl_re - fac_im * refl_im, a_im = fac_re * refl_im + fac_im * refl_re;
    const double8 re = a_re * cs - a_im * sn, im = a_re * sn + a_im * cs;
    const double8 u = tau * params.fs - rxh.t0_fs;
    long8 fl = convert_long8(u);
    fl += (u < convert_double8(fl));  /* floor by truncation and fix-up (a true compare is -1) */
    const double8 fr = u - convert_double8(fl);
    double x_re[8], x_im[8], x_fr[8];
    long x_fl[8];
    vstore8(re, 0, x_re);
    vstore8(im, 0, x_im);
    vstore8(fr, 0, x_fr);
    vstore8(fl, 0, x_fl);
#ifdef EXTENDED
    double8 d1 = (double8)0.0, d2 = (double8)0.0;
#if defined(INTRA_PULSE) && !defined(STOP_AND_GO)
    {
        /* D(u) = t1(u) + t2(u) for the wavelet emitted u seconds into the pulse: the outgoing leg
         * |Q(u + t1) - T(u)| = c t1, the return leg |R(s + t2) - Q(s)| = c t2 with s = u + t1 */
        double8 t1d, t1dd, t2s, t2ss;
        const vec8 txv = v8_splat(vload3(0, pl.tx_vel));
        meet_derivatives(out_dir, t1, v8_sub(vel, txv), vel, c, &t1d, &t1dd);
        const vec8 rv = node_velocity(nd, t_rx, dtau);
        meet_derivatives(v8_scale(back_dir, -1.0), t_rx - t1, v8_sub(rv, vel), rv, c, &t2s, &t2ss);
        const double8 sd = 1.0 + t1d;
        d1 = t1d + t2s * sd;
        d2 = 0.5 * (t1dd + t2ss * sd * sd + t2s * t1dd);
#if INTRA_PULSE == 1
        const long8 moving = (vel.x != 0.0) | (vel.y != 0.0) | (vel.z != 0.0);
        d1 = select((double8)0.0, d1, moving);
        d2 = select((double8)0.0, d2, moving);
#endif
    }
#endif
    const double K = params.chirp_rate, fs = params.fs, f0 = params.f0, half_t = 0.5 * params.duration;
    const double8 sc = 1.0 / (1.0 + d1);
    const double8 kfs = K * sc / fs;  /* Hz a sample along the received chirp */
    const double8 chirp = (0.5 * K * sc * sc - f0 * d2 * sc * sc * sc) / (fs * fs);
    const double8 lin = -f0 * d1 * sc / fs;
    const double8 beta = lnf1 * kfs, gamma = lnf2 * kfs * kfs;
    const double8 centre = d2 * half_t * half_t;
    const double8 lo = (centre - half_t * (1.0 + d1)) * fs, hi = (centre + half_t * (1.0 + d1)) * fs;
    /* the envelope's largest log over the support, folded into the amplitude (so that the float
     * accumulation evaluates exp of at most 0 there: no overflow however steep the band loss) */
    const double8 at_lo = (gamma * lo + beta) * lo, at_hi = (gamma * hi + beta) * hi;
    const double8 top = clamp(-beta / (2.0 * gamma), lo, hi);
    double8 level = fmax(at_lo, at_hi);
    level = select(level, fmax(level, (gamma * top + beta) * top), gamma < 0.0);
#ifdef GRID
    level = (double8)0.0;  /* the grid route expands the envelope itself: the amplitude stays whole */
#endif
    {
        const double8 m = exp(level);
        double x_m[8];
        vstore8(m, 0, x_m);
        for (int l = 0; l < 8; ++l) {
            x_re[l] *= x_m[l];
            x_im[l] *= x_m[l];
        }
    }
    double x_ch[8], x_li[8], x_be[8], x_ga[8], x_lo[8], x_hi[8], x_lv[8];
    vstore8(level, 0, x_lv);
    vstore8(chirp, 0, x_ch);
    vstore8(lin, 0, x_li);
    vstore8(beta, 0, x_be);
    vstore8(gamma, 0, x_ga);
    vstore8(lo, 0, x_lo);
    vstore8(hi, 0, x_hi);
#endif
    __global echo_path_t *o = paths + ((size_t)h * n_pulses + p) * stride + offset + j0;
    for (int l = 0; l < 8; ++l) {
        const int heard = !facets || (pos0 + l >= act.x && pos0 + l < act.y && in_beam[l]);
        if (!heard) {
            x_fl[l] = UNHEARD;
            x_re[l] = x_im[l] = 0.0;
        }
        echo_path_t v;
        v.start = (int)x_fl[l];
        v.frac = (real_t)x_fr[l];
        v.amp[0] = (real_t)x_re[l];
        v.amp[1] = (real_t)x_im[l];
#ifdef EXTENDED
        v.chirp = (real_t)x_ch[l];
        v.lin = (real_t)x_li[l];
        v.beta = (real_t)x_be[l];
        v.gamma = (real_t)x_ga[l];
        v.lo = (real_t)x_lo[l];
        v.hi = (real_t)x_hi[l];
        v.level = (real_t)x_lv[l];
#endif
        o[l] = v;
    }
}

/* extent[h n_pad + j] = (min, max) over the block's pulses of the start sample of path j, its
 * unheard pulses left out (the host turns them into the recording window without copying every
 * path back). */
__kernel void echo_extents(__global const echo_path_t *paths, const int n_pad, const int n_pulses,
                           __global int2 *extent)
{
    const int j = get_global_id(0), h = get_global_id(1);
    if (j >= n_pad) return;
    __global const echo_path_t *col = paths + (size_t)h * n_pulses * n_pad + j;
    int lo = UNHEARD, hi = -UNHEARD;  /* (UNHEARD, -UNHEARD): no pulse of the block hears it */
    for (int p = 0; p < n_pulses; ++p) {
        const int v = PATH_START(col[(size_t)p * n_pad]);
        if (v == UNHEARD) continue;
        lo = min(lo, v);
        hi = max(hi, v);
    }
    extent[(size_t)h * n_pad + j] = (int2)(lo, hi);
}

/* spread[h P + p] = (min, max) of the heard paths' echo centres start + frac (samples) among the
 * first n of each record (one path kind): the delay spread a pulse's echoes have at a receiver. */
__kernel void echo_spread(__global const echo_path_t *paths, const int n, const int stride, const int n_pulses,
                          __global double2 *spread)
{
    const int p = get_global_id(0), h = get_global_id(1);
    if (p >= n_pulses) return;
    const size_t rec = (size_t)h * n_pulses + p;
    __global const echo_path_t *row = paths + rec * stride;
    double lo = INFINITY, hi = -INFINITY;
    for (int j = 0; j < n; ++j) {
        const echo_path_t v = row[j];
        if (v.start == UNHEARD) continue;
        const double u = (double)v.start + (double)v.frac;
        lo = fmin(lo, u);
        hi = fmax(hi, u);
    }
    spread[rec] = (double2)(lo, hi);
}

#ifdef COMPRESSED
/* The compressed echo's centre shift delta = lin / (2 chirp) (the range-Doppler coupling,
 * clsas/synthesis/echo/compressed.py); 0 for plain paths. */
inline real_t compressed_shift(const echo_path_t v)
{
#ifdef EXTENDED
    return v.lin / ((real_t)2 * v.chirp);
#else
    return (real_t)0;
#endif
}
#endif

/* The first and last samples path v reaches (start - shift + frac + [lo, hi], rounded outwards;
 * plain paths: |d| <= half_len; compressed: the taps -COMPRESSED .. COMPRESSED + 1 about its
 * shifted centre's sample). */
inline int2 path_reach(const echo_path_t v, real_t half_len)
{
#ifdef COMPRESSED
    const real_t u = v.frac - compressed_shift(v);
    int iu = convert_int(u);
    iu -= (u < (real_t)iu);
    return (int2)(v.start + iu - COMPRESSED, v.start + iu + COMPRESSED + 1);
#else
#ifdef EXTENDED
    real_t a = v.frac + v.lo, b = v.frac + v.hi;
#else
    real_t a = v.frac - half_len, b = v.frac + half_len;
#endif
#ifdef GRID
    a -= (real_t)(TAPER + 1);  /* the grid route's tails past the pulse's edges */
    b += (real_t)(TAPER + 1);
#endif
    int ia = convert_int(a), ib = convert_int(b);
    ia -= (a < (real_t)ia);  /* floor */
    ib += (b > (real_t)ib);  /* ceil */
    return (int2)(v.start + ia, v.start + ib);
#endif
}

/* bounds[(h P + p) n_chunks + c] = (first, last) sample reached by the chunk's CHUNK paths. */
__kernel void echo_bounds(__global const echo_path_t *paths, const real_t half_len, const int n_scat,
                          const int n_pulses, __global int2 *bounds)
{
    const int c = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    const int n_chunks = (n_scat + CHUNK - 1) / CHUNK;
    if (c >= n_chunks) return;
    const size_t rec = (size_t)h * n_pulses + p;
    const int j0 = c * CHUNK, j1 = min(n_scat, j0 + CHUNK);
    int2 bd = (int2)(UNHEARD, -UNHEARD);  /* reaches nothing unless a path is heard */
    for (int j = j0; j < j1; ++j) {
        const echo_path_t v = paths[rec * n_scat + j];
        if (v.start == UNHEARD) continue;
        const int2 r = path_reach(v, half_len);
        bd = (int2)(min(bd.x, r.x), max(bd.y, r.y));
    }
    bounds[rec * n_chunks + c] = bd;
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

/* Add the raw echo of path v to the work-item's ROWS x 16 samples from k0 (echo_accumulate): s its
 * start sample and reach the first and last samples it reaches, in the output window; plain paths
 * share the chirp alpha (cycles a sample^2), the support |d| <= half_len and the row step's own
 * step (rho_c, rho_s) = exp(j 2 pi alpha 512). */
inline void add_raw_echo(const echo_path_t v, const int2 reach, const int s, const int k0, const real_t alpha,
                         const real_t half_len, const real_t rho_plain_c, const real_t rho_plain_s,
                         realv_t *acc_re, realv_t *acc_im)
{
    const realv_t lane = (realv_t)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const real_t first = (real_t)(k0 - s) - v.frac;  /* d of the work-item's first sample */
    /* rows r_lo..r_hi hold the samples the path reaches (integer arithmetic: PoCL's
     * floor/ceil are slow); rows with a pulse edge are masked below */
    const int a = reach.x - k0, e = reach.y - k0;
    const int r_lo = a <= 0 ? 0 : a / 16;
    const int r_hi = min(ROWS - 1, e / 16);
    if (r_lo > r_hi) return;
    realv_t d = lane + (first + (real_t)(16 * r_lo));
    realv_t c0, s0, wc, ws;
#ifdef EXTENDED
    /* E(d) = j 2 pi (chirp d^2 + lin d) + gamma d^2 + beta d; the row step
     * E(d + 16) - E(d) = j 2 pi (chirp (32 d + 256) + 16 lin) + gamma (32 d + 256) + 16 beta,
     * its own step E(d + 32) - 2 E(d + 16) + E(d) = 512 (j 2 pi chirp + gamma) */
    const real_t lo = v.lo, hi = v.hi;
    /* the envelope re its level (<= 0 on the support); exponents clamped to +-80 so that
     * the rows outside the support (masked) cannot overflow */
    expj_cycles_v((v.chirp * d + v.lin) * d, &c0, &s0);
    const realv_t e0 = exp(clamp((v.gamma * d + v.beta) * d - v.level, (real_t)-80, (real_t)80));
    c0 *= e0;
    s0 *= e0;
    const realv_t step = (real_t)32 * d + (real_t)256;
    expj_cycles_v(v.chirp * step + (real_t)16 * v.lin, &wc, &ws);
    const realv_t ew = exp(clamp(v.gamma * step + (real_t)16 * v.beta, (real_t)-80, (real_t)80));
    wc *= ew;
    ws *= ew;
    real_t rho_c, rho_s;
    {
        real_t r512 = v.chirp * (real_t)512;
        r512 -= (real_t)convert_int(r512);
        const real_t m = exp(fmax(v.gamma * (real_t)512, (real_t)-80));
        rho_c = m * cospi((real_t)2 * r512);
        rho_s = m * sinpi((real_t)2 * r512);
    }
#else
    const real_t lo = -half_len, hi = half_len;
    const real_t rho_c = rho_plain_c, rho_s = rho_plain_s;
    expj_cycles_v(alpha * d * d, &c0, &s0);
    expj_cycles_v(alpha * ((real_t)32 * d + (real_t)256), &wc, &ws);
#endif
    realv_t zc = v.amp[0] * c0 - v.amp[1] * s0, zs = v.amp[0] * s0 + v.amp[1] * c0;  /* amplitude folded in */
    for (int r = 0; r < ROWS; ++r) {
        if (r < r_lo) continue;
        if (r > r_hi) break;
        const real_t row0 = first + (real_t)(16 * r);
        if (row0 < lo || row0 + (real_t)15 > hi) {  /* a pulse edge in the row */
            const realv_t dd = lane + row0;
            const realv_t m = select((realv_t)0, (realv_t)1, (dd >= lo) & (dd <= hi));
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

#ifdef COMPRESSED
/* Synthesis into the range-compressed domain (clsas/synthesis/echo/compressed.py, NumPy twin
 * CompressedResponse.accumulate): path v adds c0 Y0 + c1 Y1 + c2 Y2 over the taps about its
 * (shifted) centre u' = start + frac - delta, the tables Y linear between the PHASES + 1
 * fractions. table[((t (PHASES + 1) + i) 2 + part) row + PAD + L + m]: table t, fraction i / PHASES,
 * real / imaginary part, tap m (zeros in the PAD columns): the response of the pulse's core
 * samples; the edge samples edge_lo and edge_hi (about the centre's sample), inside the pulse for
 * some fractions only, add their value x impulse[part imp_len + PAD + lag0 + m - k] (the matched
 * filter's impulse response). N_TABLES: 1 (plain paths: c0 = amp) or 3. reach: the taps
 * -COMPRESSED .. COMPRESSED + 1 about the shifted centre's sample, in the output window. */
inline void add_compressed_echo(const echo_path_t v, const int2 reach, const int k0, __global const real_t *table,
                                const int row, __global const real_t *impulse, const int imp_len, const int lag0,
                                const int edge_lo, const int edge_hi, const real_t alpha, const real_t half_len,
                                realv_t *acc_re, realv_t *acc_im)
{
    const int s = reach.x + COMPRESSED;  /* the shifted centre's sample */
    const real_t frac = v.frac - compressed_shift(v);
    const real_t pos = (frac - floor(frac)) * (real_t)PHASES;
    const int i = min(convert_int(pos), PHASES - 1);
    const real_t w = pos - (real_t)i;
    real_t cre[N_TABLES], cim[N_TABLES];
    cre[0] = v.amp[0];
    cim[0] = v.amp[1];
#if N_TABLES == 3
    {
        /* c0 = a', c1 = a' b', c2 = a' (b'^2 / 2 + q): compressed.py, module docstring */
        const real_t delta = compressed_shift(v);
        const real_t cyc = -v.lin * v.lin / ((real_t)4 * v.chirp);
        const real_t m = exp(v.gamma * delta * delta - v.beta * delta - v.level);
        const real_t red = cyc - (real_t)convert_int(cyc);
        const real_t pc = m * cospi((real_t)2 * red), ps = m * sinpi((real_t)2 * red);
        const real_t ar = v.amp[0] * pc - v.amp[1] * ps, ai = v.amp[0] * ps + v.amp[1] * pc;
        const real_t b1 = v.beta - (real_t)2 * v.gamma * delta;
        const real_t qr = (real_t)0.5 * b1 * b1 + v.gamma, qi = (real_t)2 * REAL_PI * (v.chirp - alpha);
        cre[0] = ar;
        cim[0] = ai;
        cre[1] = ar * b1;
        cim[1] = ai * b1;
        cre[2] = ar * qr - ai * qi;
        cim[2] = ar * qi + ai * qr;
    }
#endif
    /* the edge samples' values (compressed.py, CompressedResponse.edge_weights) */
    real_t ere[2], eim[2];
    for (int q = 0; q < 2; ++q) {
        const real_t d = (real_t)(q == 0 ? edge_lo : edge_hi) - (frac - floor(frac));
        real_t pr = cre[0], pi = cim[0];
#if N_TABLES == 3
        pr += d * (cre[1] + d * cre[2]);
        pi += d * (cim[1] + d * cim[2]);
#endif
        real_t cyc = alpha * d * d;
        cyc -= (real_t)convert_int(cyc);
        const real_t in = fabs(d) <= half_len ? (real_t)1 : (real_t)0;
        const real_t cs = in * cospi((real_t)2 * cyc), sn = in * sinpi((real_t)2 * cyc);
        ere[q] = pr * cs - pi * sn;
        eim[q] = pr * sn + pi * cs;
    }
    const int a = reach.x - k0, e = reach.y - k0;
    const int r_lo = a <= 0 ? 0 : a / 16;
    const int r_hi = min(ROWS - 1, e / 16);
    for (int r = r_lo; r <= r_hi; ++r) {
        const int m0 = k0 + 16 * r - s;  /* the row's first tap */
        const int col = PAD + COMPRESSED + m0;
        for (int q = 0; q < 2; ++q) {
            if (ere[q] == (real_t)0 && eim[q] == (real_t)0) continue;
            __global const real_t *ip = impulse + PAD + lag0 + m0 - (q == 0 ? edge_lo : edge_hi);
            const realv_t yr = vload16(0, ip), yi = vload16(0, ip + imp_len);
            acc_re[r] += ere[q] * yr - eim[q] * yi;
            acc_im[r] += ere[q] * yi + eim[q] * yr;
        }
        for (int t = 0; t < N_TABLES; ++t) {
            __global const real_t *t0 = table + ((size_t)(t * (PHASES + 1) + i) * 2) * row + col;
            const realv_t y0r = vload16(0, t0), y0i = vload16(0, t0 + row);
            const realv_t y1r = vload16(0, t0 + 2 * row), y1i = vload16(0, t0 + 3 * row);
            const realv_t yr = y0r + w * (y1r - y0r), yi = y0i + w * (y1i - y0i);
            acc_re[r] += cre[t] * yr - cim[t] * yi;
            acc_im[r] += cre[t] * yi + cim[t] * yr;
        }
    }
}
#endif

/* out[(h P + p) n_pad + k] for the ROWS x 16 samples k of the work-item; records of n_pad samples
 * (a multiple of 16 ROWS); samples at k >= n_valid are zero. A path's echo centre is
 * start + frac (samples of the output window). Each path that reaches the work-item's samples adds its raw echo
 * (add_raw_echo) or, COMPRESSED, its compressed response (add_compressed_echo). */
__kernel void echo_accumulate(__global const echo_path_t *paths, __global const int2 *bounds,
                              const real_t alpha, const real_t half_len,
#ifdef COMPRESSED
                              __global const real_t *table, const int row, __global const real_t *impulse,
                              const int imp_len, const int lag0, const int edge_lo, const int edge_hi,
#endif
                              const int n_scat, const int n_pulses, const int n_pad, const int n_valid,
                              __global complex_t *out)
{
    const int b = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    const int k0 = 16 * ROWS * b, k_last = k0 + 16 * ROWS - 1;
    if (k0 >= n_pad) return;
    const size_t rec = (size_t)h * n_pulses + p;
    const int n_chunks = (n_scat + CHUNK - 1) / CHUNK;
#ifndef COMPRESSED
    real_t rho_c = (real_t)0, rho_s = (real_t)0;  /* exp(j 2 pi alpha 512): plain paths' row step's own step */
#ifndef EXTENDED
    {
        real_t r512 = alpha * (real_t)512;
        r512 -= (real_t)convert_int(r512);
        rho_c = cospi((real_t)2 * r512);
        rho_s = sinpi((real_t)2 * r512);
    }
#endif
#endif
    realv_t acc_re[ROWS], acc_im[ROWS];
    for (int r = 0; r < ROWS; ++r) acc_re[r] = acc_im[r] = (realv_t)0;
    __global const echo_path_t *rp = paths + rec * n_scat;
    for (int c = 0; c < n_chunks; ++c) {
        const int2 bd = bounds[rec * n_chunks + c];
        if (bd.y < k0 || bd.x > k_last) continue;
        const int j1 = min(n_scat, (c + 1) * CHUNK);
        for (int j = c * CHUNK; j < j1; ++j) {
            const echo_path_t v = rp[j];
            const int2 reach = path_reach(v, half_len);
            if (reach.y < k0 || reach.x > k_last) continue;
            if (v.amp[0] == (real_t)0 && v.amp[1] == (real_t)0) continue;  /* dark (shadowed, padding) */
#ifdef COMPRESSED
            add_compressed_echo(v, reach, k0, table, row, impulse, imp_len, lag0, edge_lo, edge_hi, alpha, half_len,
                                acc_re, acc_im);
#else
            add_raw_echo(v, reach, v.start, k0, alpha, half_len, rho_c, rho_s, acc_re, acc_im);
#endif
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

#ifdef GRID
#ifdef CLSAS_DOUBLE
typedef double8 real8_t;
#define convert_real8 convert_double8
inline void expj_cycles8(real8_t cyc, real8_t *cs, real8_t *sn)
{
    const real8_t r = cyc - convert_double8(convert_long8(cyc));
    *cs = cospi((real8_t)2.0 * r);
    *sn = sinpi((real8_t)2.0 * r);
}
#else
typedef float8 real8_t;
#define convert_real8 convert_float8
inline void expj_cycles8(real8_t cyc, real8_t *cs, real8_t *sn)
{
    expj_fraction8(cyc - convert_float8(convert_int8(cyc)), cs, sn);
}
#endif

/* The grid route (clsas/synthesis/echo/grid.py, NumPy twin GridPlan.spread): one work-item per
 * GRID_BLOCK samples of one (receiver, pulse) record, covering the grid points GRID_RATE t .. of the
 * samples t = GRID_BLOCK b - GRID_PAD .. + GRID_BLOCK - 1 (output window coordinates) and the tail entries
 * of those samples. Each path that reaches them adds its impulse, spread by the kernel phi over the
 * GRID_TAPS grid points about GRID_RATE u (taps[k 8 + l]: lane l's polynomial, degree GRID_DEGREE), to
 * each of the GRID terms (its amplitude times 1, b, b^2 / 2 + g: the band envelope's Taylor
 * series), and subtracts what the tapered pulse adds outside its edges (h < |d| < h + TAPER, 8
 * lanes either side). grid[((h P + p) GRID + j) GRID_RATE n_grid + m], tails[(h P + p) n_grid + i]. */
__kernel void echo_grid(__global const echo_path_t *paths, __global const int2 *bounds, const real_t alpha,
                        const real_t half_len, __global const real_t *taps, const int n_scat,
                        const int n_pulses, const int n_grid, __global complex_t *grid,
                        __global complex_t *tails)
{
    const int b = get_global_id(0), p = get_global_id(1), h = get_global_id(2);
    const int k0 = GRID_BLOCK * b;  /* the block's first sample, grid coordinates (sample + GRID_PAD) */
    if (k0 >= n_grid) return;
    const int t_first = k0 - GRID_PAD, t_last = t_first + GRID_BLOCK - 1;  /* output window coordinates */
    const size_t rec = (size_t)h * n_pulses + p;
    const int n_chunks = (n_scat + CHUNK - 1) / CHUNK;
    const real8_t lane = (real8_t)(0, 1, 2, 3, 4, 5, 6, 7);
    const int left0 = -(int)(half_len + (real_t)TAPER), right0 = (int)half_len + 1;  /* ceil, floor of positives */
    real_t acc_re[GRID][GRID_RATE * GRID_BLOCK], acc_im[GRID][GRID_RATE * GRID_BLOCK];
    real_t tail_re[GRID_BLOCK], tail_im[GRID_BLOCK];
    for (int j = 0; j < GRID; ++j)
        for (int m = 0; m < GRID_RATE * GRID_BLOCK; ++m) acc_re[j][m] = acc_im[j][m] = (real_t)0;
    for (int m = 0; m < GRID_BLOCK; ++m) tail_re[m] = tail_im[m] = (real_t)0;
    __global const echo_path_t *rp = paths + rec * n_scat;
    for (int c = 0; c < n_chunks; ++c) {
        const int2 bd = bounds[rec * n_chunks + c];
        if (bd.y < t_first || bd.x > t_last) continue;
        const int j1 = min(n_scat, (c + 1) * CHUNK);
        for (int q = c * CHUNK; q < j1; ++q) {
            const echo_path_t v = rp[q];
            const int2 reach = path_reach(v, half_len);
            if (reach.y < t_first || reach.x > t_last) continue;
            if (v.amp[0] == (real_t)0 && v.amp[1] == (real_t)0) continue;  /* dark (shadowed, padding) */
            const int s = v.start;  /* the centre's sample, output window coordinates */
            const real_t fr = v.frac;
            real_t cr[GRID], ci[GRID];
            cr[0] = v.amp[0];  /* the grid route's paths carry no level (echo_paths) */
            ci[0] = v.amp[1];
#if GRID == 3
            {   /* the band envelope exp(b d + g d^2) ~= 1 + b d + (b^2 / 2 + g) d^2 */
                const real_t e1 = v.beta, e2 = (real_t)0.5 * v.beta * v.beta + v.gamma;
                cr[1] = cr[0] * e1;
                ci[1] = ci[0] * e1;
                cr[2] = cr[0] * e2;
                ci[2] = ci[0] * e2;
            }
#endif
            /* the impulse: grid points GRID_RATE (s - t_first) + first + l, l = 0..7, the taps
             * polynomials in t = first - x + GRID_TAPS / 2 (Horner, 8 lanes) */
            if (s + 2 >= t_first && s - 1 <= t_last) {
                const real_t a = (real_t)GRID_RATE * fr - (real_t)(0.5 * GRID_TAPS);
                int first = convert_int(a);
                first += (a > (real_t)first);  /* ceil by truncation and fix-up */
                const real_t t = (real_t)first - a;
                real8_t phi = vload8(GRID_DEGREE, taps);
                for (int k = GRID_DEGREE - 1; k >= 0; --k) phi = phi * t + vload8(k, taps);
                real_t ph[8];
                vstore8(phi, 0, ph);
                const int m0 = GRID_RATE * (s - t_first) + first;
                for (int l = 0; l < GRID_TAPS; ++l) {
                    const int m = m0 + l;
                    if (m < 0 || m >= GRID_RATE * GRID_BLOCK) continue;
                    for (int j = 0; j < GRID; ++j) {
                        acc_re[j][m] += cr[j] * ph[l];
                        acc_im[j][m] += ci[j] * ph[l];
                    }
                }
            }
            /* the tails: minus the tapered pulse at the samples s + offset outside the pulse */
            for (int side = 0; side < 2; ++side) {
                const int o0 = side == 0 ? left0 : right0;
                if (s + o0 + 7 < t_first || s + o0 > t_last) continue;
                const real8_t d = lane + (real_t)o0 - fr;
                const real8_t x = fabs(d) - half_len;
                real8_t cs, sn;
                expj_cycles8(alpha * d * d, &cs, &sn);
                real8_t hc, hs;  /* the half Hann taper 0.5 (1 + cos(pi x / TAPER)) */
                expj_cycles8(fmin(fmax(x, (real8_t)0), (real8_t)TAPER) * (real_t)(0.5 / TAPER), &hc, &hs);
                real8_t w = (real_t)-0.5 * ((real_t)1 + hc);
                w = select((real8_t)0, w, (x > (real_t)0) & (x < (real_t)TAPER));
                real8_t pr = (real8_t)cr[0], pi = (real8_t)ci[0];
#if GRID == 3
                pr += d * (cr[1] + d * cr[2]);
                pi += d * (ci[1] + d * ci[2]);
#endif
                const real8_t vr = w * (pr * cs - pi * sn), vi = w * (pr * sn + pi * cs);
                real_t xr[8], xi[8];
                vstore8(vr, 0, xr);
                vstore8(vi, 0, xi);
                for (int l = 0; l < 8; ++l) {
                    const int k = s + o0 + l - t_first;
                    if (k < 0 || k >= GRID_BLOCK) continue;
                    tail_re[k] += xr[l];
                    tail_im[k] += xi[l];
                }
            }
        }
    }
    for (int j = 0; j < GRID; ++j) {
        __global complex_t *o = grid + (rec * GRID + j) * (size_t)(GRID_RATE * n_grid) + GRID_RATE * k0;
        for (int m = 0; m < GRID_RATE * GRID_BLOCK; ++m) o[m] = complex_new(acc_re[j][m], acc_im[j][m]);
    }
    __global complex_t *o = tails + rec * n_grid + k0;
    for (int m = 0; m < GRID_BLOCK; ++m) o[m] = complex_new(tail_re[m], tail_im[m]);
}
#endif

