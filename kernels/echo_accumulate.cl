/* Echo synthesis, the accumulation of the paths' echoes (made by kernels/echo_paths.cl) into the
 * records.
 *
 * NumPy twin: clsas/synthesis/echo/reference.py (accumulate_reference), clsas/synthesis/echo/compressed.py
 * and clsas/synthesis/echo/grid.py; the launcher is clsas/synthesis/echo/launch.py (OpenCLSynth).
 *
 * Per chunk of pulses, after echo_paths:
 *   echo_bounds  first and last sample reached by each CHUNK consecutive (delay-sorted) paths;
 *   echo_accumulate  one work-item per ROWS x 16 output samples of one (receiver, pulse)
 *                record: loops over the chunks that can reach it and adds each path's echo
 *                (add_raw_echo) or, COMPRESSED, its compressed response (add_compressed_echo).
 *                Explicit 16-wide vectors (PoCL does not vectorise across work-items of a
 *                kernel with loops). The chirp of a path's first row is evaluated (polynomial
 *                sin/cos in float; exp for an envelope), the following rows by the exact
 *                recurrence z(d + 16) = z(d) w(d), w(d + 16) = w(d) rho with
 *                w(d) = exp(E(d + 16) - E(d)), rho = exp(E(d + 32) - 2 E(d + 16) + E(d)), E the
 *                quadratic exponent: two complex vector products a row instead of a sin/cos
 *                (rounding grows by ~1e-7 a row);
 *   echo_grid    the grid route (clsas/synthesis/echo/grid.py): each path's impulse spread on a
 *                fine grid, one work-item per GRID_BLOCK samples of a record.
 *
 * Every kernel is launched in fixed work-groups of the launcher's size along its first dimension
 * (clsas.opencl.work_groups: PoCL compiles it once whatever the shape) and returns for the
 * work-items past the end.
 *
 * Defines: CHUNK (paths a bound covers), ROWS (16-sample blocks per work-item), EXTENDED (paths with
 * their own chirp and envelope), COMPRESSED (taps either side; with N_TABLES, PHASES, PAD: the
 * compressed response's tables, clsas/synthesis/echo/compressed.py), GRID (terms; with GRID_RATE,
 * GRID_TAPS, GRID_DEGREE, TAPER, GRID_BLOCK, GRID_PAD: the grid route); CLSAS_DOUBLE makes the
 * accumulation double. The records (echo_path_t) are declared by the launcher
 * (clsas/synthesis/echo/records.py).
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"
#include "echo_reach.h"

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

