/* Echo synthesis, the paths (kernels/echo_accumulate.cl adds their echoes to the records): exact
 * two-way delays, path amplitudes, and where each path's echo lies.
 *
 * NumPy twin: clsas/synthesis/paths.py (paths) and clsas/geometry.py; the launcher is
 * clsas/synthesis/echo/launch.py (OpenCLSynth), which builds this file and echo_accumulate.cl with the
 * same defines.
 *
 * Per chunk of pulses:
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
 *   echo_extents, echo_spread  each path's extent over a pulse block, each record's delay spread.
 *
 * Every kernel is launched in fixed work-groups of the launcher's size along its first dimension
 * (clsas.opencl.work_groups: PoCL compiles it once whatever the shape) and returns for the
 * work-items past the end.
 *
 * Defines: N_NODES (>= 2), SEGMENT_PASSES (node segment re-choices), DELAYS_ONLY (echo_paths
 * writes the echo centres alone), STOP_AND_GO, SPREADING, PATH_WEIGHTS, EXTENDED (paths with their own
 * chirp and envelope), INTRA_PULSE (1: moving scatterers, 2: every path), ABSORPTION, BOUNCES,
 * BOTTOM_TABLE (entries of the seabed's reflection table), GRID (the grid route's paths). The records
 * (echo_pulse_t, node_t, echo_rx_t, echo_params_t, echo_legs_t, echo_path_t) and the scatterer fields
 * (SCAT_*) are declared by the launcher (clsas/synthesis/echo/records.py).
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"
#include "geometry.h"
#include "echo_reach.h"

#define PATH_START(v) ((v).start)

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
