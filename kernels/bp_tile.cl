/* Time-domain back-projection of range-compressed echoes by tiles, one receiver and one block of
 * pulses a launch: bp_tile, owned by clsas/image/backprojection/tile_kernel.TileKernel (which
 * declares its records: the -D options, the structs in its preamble, its parameters and the layout of
 * its pixel fields) and launched by clsas/image/backprojection/launcher.py and clsas/image/ffbp/leaves.py.
 * NumPy twin: clsas/image/backprojection/reference.py. Its inputs are made by kernels/bp_fields.cl
 * (pixel fields) and kernels/bp_refs.cl (references); bp_block (kernels/bp_block.cl) is the exact
 * double path. Interpolation, phase and sums: kernels/bp_common.h.
 *
 * bp_tile (precision="single"): float32 geometry relative to a reference
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
 *
 * Defines: ROWS, PULSES, MOVING when the pixels move, SAME_LEGS or MONO, ROW_SHIFT, PULSE_SPAN, BP_STORE, CARRY,
 * SCATTER; INTERP_LINEAR or INTERP_SINC8 (with TAP_ROWS); APERTURE (keep |sin theta| off broadside <=
 * sin(aperture / 2), theta measured from the x-z plane); CLSAS_NO_READ16 (the portable reads where
 * CLSAS_READ16 would be built: the tests build both on an AVX-512 machine).
 * Portable OpenCL C 1.2: no vendor builtins (clang's inline assembly and __builtin_shufflevector
 * only behind the x86-64 guards of CLSAS_OPAQUE and CLSAS_READ16, each with a portable path).
 */
#include "bp_common.h"

#define FOR_ROWS _Pragma("unroll") for (int r = 0; r < ROWS; ++r)

/* The return leg (TileKernel.legs):
 * SAME_LEGS (stop-and-go, the receiver at the transmitter: a monostatic sonar): t2 = t1, s = 2 s1;
 * MONO (exact delays, the receiver at the transmitter at emission and moving uniformly at v_r,
 *   pixels at rest): s = alpha s1 - w . delta with alpha = 2 c^2 / (c^2 - |v_r|^2) and
 *   w = 2 v_r / (c^2 - |v_r|^2) (derivation: clsas/image/backprojection/tile_kernel.py);
 * otherwise two legs: s2 = N2 / (b2 + sqrt(b2^2 + a2 N2)) as in the header.
 * Leg 1 of a reference with poly set (pixels at rest, every pixel of the tile within RHO_MAX of
 * the reference's range): s1 = (N1 k1) g(N1 k2), k1 = 1 / (2 b1), k2 = a1 / b1^2, g(x) =
 * 2 / (1 + sqrt(1 + x)) by its polynomial on [-0.3, 0.33] (tile_kernel.py): no square root, no
 * division (LEG_POLY(x), the polynomial's Horner form, comes with the preamble from
 * tile_kernel.LEG_POLY); otherwise the stable root.
 * pix[ROWS g + r] (bp_pixels_t, TileKernel.PIXELS): work-item g's row r of sixteen pixels (image
 *   slots m = 16 (ROWS g + r) + lane): delta (the pixel at t = 0 minus its tile's reference point,
 *   m: dx, dy, dz), dd = |delta|^2 and (MOVING) dv = delta . v;
 * tile_of[g]: the tile of work-item g;
 * ref[t * ref_stride + p - ref_first] (tile_ref_t, TileKernel.reference_dtype): the reference of
 *   (tile t, pulse p): leg1 = B, b1 = c^2 t1_ref - B.v, k1, k2 and poly (above), k_ref + k_frac =
 *   the sample index of T_ref in the records (k_ref an integer less BIAS, k_frac its fraction plus
 *   BIAS: k_frac + s fs is positive, so that truncation is the floor), cycles = f0 T_ref reduced,
 *   range1 = c t1_ref; two legs: leg2 = C, b2 = c^2 t2_ref - C.v_r, v_rx = v_r, a2 = c^2 - |v_r|^2;
 *   MONO: alpha, w and w_run (how many of the following pulses have a w of the same bits);
 * params (tile_params_t): a1, fs (of the data), f0, velocity v, half_sin = sin(aperture / 2), c;
 * data[p n + i]: the receiver's range-compressed record of pulse p; taps: the 8-tap table (interp.h);
 * image[m] += the sum over pulses p_first .. p_first + p_count - 1 (BP_STORE, without SCATTER:
 *   image[m] = that sum, for a launch whose sums start the image).
 * ROW_SHIFT (ffbp's first stage, clsas/image/ffbp/leaves.py: many sub-apertures a launch): pulse p
 *   of tile t reads record row p + row_shift[t] (its reference stays ref[t * ref_stride + p - ref_first]).
 * CARRY (direct back-projection, clsas/image/backprojection/launcher.py: a block of pulses summed in
 *   float over several launches, each reading fewer records, which then stay in cache): carry[32 (ROWS g
 *   + r) + lane] and [... + 16 + lane] hold row r's float sums (re, im) between launches; carry_mode
 *   bit 1: the sums start from carry (else from zero), bit 2: they are stored into carry (else added
 *   into the image as without CARRY). The same float operations in the same order as one launch over
 *   the whole block: the image is bit-identical. */
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
#ifdef CARRY
#define CARRY_PARAM , __global float *carry, const int carry_mode
#else
#define CARRY_PARAM
#endif
#ifdef PULSE_SPAN
#define PULSE_SPAN_PARAM , __global const int2 *span
#define TILE_BEGIN max(p_first, span[tile_of[g]].x)
#define TILE_END min(p_first + p_count, span[tile_of[g]].y)
#else
#define PULSE_SPAN_PARAM
#define TILE_BEGIN p_first
#define TILE_END (p_first + p_count)
#endif

/* x - round(x) in [-1/2, 1/2] for |x| < 2^22 (rounding by the float format: PoCL's rint is slow) */
#define ROUND_MAGIC 12582912.0f /* 1.5 * 2^23 */
#define NEAR_FRACTION(x) ((x) - (((x) + ROUND_MAGIC) - ROUND_MAGIC))

/* exp(j 2 pi r) for r in [-1/2, 1/2] cycles by doubling the angle a = pi r / 2 twice: S = k sin(a) and
 * C = k cos(a), k = 2^(3/4), by their polynomials in r (odd of degree 7, even of degree 6; least-squares
 * fits made minimax by Lawson's reweighting, the factors pi / 2 and k inside the coefficients), then
 * P = S C = sqrt(2) sin(2a) and T = sqrt(2) - S^2 = sqrt(2) cos(2a), so that sin(2 pi r) = P T and
 * cos(2 pi r) = 1 - P^2: four operations for the two doublings and none for pi r / 2, one operation fewer
 * than one doubling of pi r (whose polynomials need degrees 9 and 10). Error in float32 over [-1/2, 1/2]
 * below 1.5e-6 (sin 5.1e-7, cos 1.2e-6: float rounding, doubled by the second doubling; one doubling
 * gave 2.9e-7, 7.7e-7); the kernel-versus-reference tests hold the images to it. */
#define EXPJ_NEAR16(r_in, cs_out, sn_out)                                                                      \
    do {                                                                                                      \
        const float16 r_ = (r_in), q_ = r_ * r_;                                                              \
        const float16 s_ = r_ * (2.6417539641e+00f + q_ * (-1.0863758382e+00f + q_ * (1.3399836232e-01f       \
                           + q_ * -7.7232786966e-03f)));                                                       \
        const float16 c_ = 1.6817927841e+00f + q_ * (-2.0748227936e+00f + q_ * (4.2650038123e-01f            \
                           + q_ * -3.4322620142e-02f));                                                        \
        const float16 p_ = s_ * c_, t_ = fma(-s_, s_, 1.4142135624e+00f);                                    \
        *(sn_out) = p_ * t_;                                                                                  \
        *(cs_out) = fma(-p_, p_, 1.0f);                                                                       \
    } while (0)

/* Linear interpolation's samples of eight lanes: lane L's four floats w_L = (re, im of sample i,
 * re, im of sample i + 1) -> four float8 (a_re, a_im, b_re, b_im) of lanes 0-7. Lanes L and L + 4
 * share an 8-lane vector (y_L, its 128-bit halves; two 4-wide loads), then two stages of unpacks
 * within 128-bit halves (unpcklps/unpckhps, then unpcklpd/unpckhpd: eight one-uop shuffles). On
 * AVX2, two-source permutes across halves become vpermps + vblendps pairs, and AVX-512 codes the
 * unpacks as fast as its vpermt2ps. CLSAS_OPAQUE (an empty asm that holds y_L in a register) keeps
 * LLVM from folding the loads into the unpacks: it then makes scalar broadcast loads and blends. */
#if defined(__clang__) && defined(__x86_64__) && defined(__AVX__)
#define CLSAS_OPAQUE(v) __asm__("" : "+v"(v))
#else
#define CLSAS_OPAQUE(v) ((void)0)
#endif
#define UNPACK_LO(x, y) (float8)(x.s0, y.s0, x.s1, y.s1, x.s4, y.s4, x.s5, y.s5)
#define UNPACK_HI(x, y) (float8)(x.s2, y.s2, x.s3, y.s3, x.s6, y.s6, x.s7, y.s7)
#define UNPACK_LO2(x, y) (float8)(x.s01, y.s01, x.s45, y.s45)
#define UNPACK_HI2(x, y) (float8)(x.s23, y.s23, x.s67, y.s67)
#define TRANSPOSE8(w0, w1, w2, w3, w4, w5, w6, w7, a_re, a_im, b_re, b_im)                                     \
    do {                                                                                                     \
        float8 y0 = (float8)(w0, w4), y1 = (float8)(w1, w5), y2 = (float8)(w2, w6), y3 = (float8)(w3, w7);   \
        CLSAS_OPAQUE(y0);                                                                                    \
        CLSAS_OPAQUE(y1);                                                                                    \
        CLSAS_OPAQUE(y2);                                                                                    \
        CLSAS_OPAQUE(y3);                                                                                    \
        const float8 t0 = UNPACK_LO(y0, y1), t1 = UNPACK_HI(y0, y1);                                         \
        const float8 t2 = UNPACK_LO(y2, y3), t3 = UNPACK_HI(y2, y3);                                         \
        *(a_re) = UNPACK_LO2(t0, t2);                                                                        \
        *(a_im) = UNPACK_HI2(t0, t2);                                                                        \
        *(b_re) = UNPACK_LO2(t1, t3);                                                                        \
        *(b_im) = UNPACK_HI2(t1, t3);                                                                        \
    } while (0)

/* The same on AVX-512 (CLSAS_READ16: clang, x86-64, AVX512F, and AVX512VL for the xmm16-31 that the
 * "v" constraint may pick), sixteen lanes at once: lanes L, L + 4, L + 8 and L + 12 share a 16-lane
 * vector y_L (READ16: each lane's index reloaded as a scalar, then one 4-wide load and three 4-wide
 * inserts from memory, which run on either vector port), then the
 * two stages of unpacks within 128-bit blocks on whole 512-bit vectors (UNPACK16_*), whose block b
 * then holds lanes 4b .. 4b + 3 in order: eight one-uop shuffles for sixteen lanes, where
 * TRANSPOSE8 takes sixteen 256-bit unpacks and four 512-bit inserts, all on the one shuffle port.
 * The same values (bit-identical images). READ16 is inline assembly because LLVM 15, given the
 * loads in C, builds y_L by inserts from registers (shuffle-port uops) and merges the unpacks
 * into two-source permutes and blends (more instructions than TRANSPOSE8: the commit gives the
 * figures; bench/bench_backprojection.py --only loop counts them).
 * rec_: the records of the pulse (floats, two a sample), i_: the 16 lanes' sample indices
 * (contiguous ints; the "m" input orders the asm after their stores). */
#if !defined(CLSAS_NO_READ16) && defined(__clang__) && defined(__x86_64__) && defined(__AVX512F__) && defined(__AVX512VL__)
#define CLSAS_READ16 1
#define READ16_Y(y, L)                                                                                        \
    "movslq " #L "*4(%[idx]), %%rax\n\t"                                                                    \
    "vmovups (%[rec],%%rax,8), %x[" #y "]\n\t"                                                              \
    "movslq (" #L "+4)*4(%[idx]), %%rax\n\t"                                                                \
    "vinsertf32x4 $1, (%[rec],%%rax,8), %[" #y "], %[" #y "]\n\t"                                           \
    "movslq (" #L "+8)*4(%[idx]), %%rax\n\t"                                                                \
    "vinsertf32x4 $2, (%[rec],%%rax,8), %[" #y "], %[" #y "]\n\t"                                           \
    "movslq (" #L "+12)*4(%[idx]), %%rax\n\t"                                                               \
    "vinsertf32x4 $3, (%[rec],%%rax,8), %[" #y "], %[" #y "]\n\t"
#define READ16(rec_, i_, y0, y1, y2, y3)                                                                      \
    __asm__(READ16_Y(a, 0) READ16_Y(b, 1) READ16_Y(c, 2) READ16_Y(d, 3)                                       \
            : [a] "=&v"(y0), [b] "=&v"(y1), [c] "=&v"(y2), [d] "=&v"(y3)                                    \
            : [rec] "r"(rec_), [idx] "r"(i_), "m"(*(const int(*)[16])(i_))                                   \
            : "rax")
#define UNPACK16_LO(x, y) __builtin_shufflevector(x, y, 0, 16, 1, 17, 4, 20, 5, 21, 8, 24, 9, 25, 12, 28, 13, 29)
#define UNPACK16_HI(x, y) __builtin_shufflevector(x, y, 2, 18, 3, 19, 6, 22, 7, 23, 10, 26, 11, 27, 14, 30, 15, 31)
#define UNPACK16_LO2(x, y) __builtin_shufflevector(x, y, 0, 1, 16, 17, 4, 5, 20, 21, 8, 9, 24, 25, 12, 13, 28, 29)
#define UNPACK16_HI2(x, y) __builtin_shufflevector(x, y, 2, 3, 18, 19, 6, 7, 22, 23, 10, 11, 26, 27, 14, 15, 30, 31)
#endif

/* A pixel row's fields: loaded where used (the pulse loop then holds no more than they need) */
#define FIELD(f) LOAD_F16(px[r].f)

/* Row r's first samples into first[r], two halves of 8 lanes: on AVX-512 CPUs a 16-lane store
 * does not forward to the scalar loads of its upper half (those wait until the store reaches
 * the cache), whereas an 8-lane store forwards to all of its lanes */
#define STORE_FIRST(r, v)     \
    do {                      \
        const int16 v_ = (v); \
        first[r][0] = v_.lo;  \
        first[r][1] = v_.hi;  \
    } while (0)

__kernel void bp_tile(__global const bp_pixels_t *pix, __global const int *tile_of, __global const tile_ref_t *ref,
                      const int ref_stride, const int ref_first, __global const sample_t *data, __global const float *taps,
                      const tile_params_t params, const int p_first, const int p_count, const int n,
                      const int n_items, __global double2 *image SCATTER_PARAM ROW_SHIFT_PARAM PULSE_SPAN_PARAM CARRY_PARAM)
{
    const int g = get_global_id(0);
    if (g >= n_items)  /* the launch is padded to whole work-groups */
        return;
    __global const tile_ref_t *tref = ref + (size_t)tile_of[g] * ref_stride - ref_first;
    __global const bp_pixels_t *px = pix + ROWS * g;
    __global const float *records = (__global const float *)(data + (size_t)TILE_ROW_SHIFT * n);
    const float a1 = params.a1, f0 = params.f0;
#ifdef SAME_LEGS
    const float fs = 2.0f * params.fs, f0s = 2.0f * f0;  /* s = 2 s1 */
#else
    const float fs = params.fs, f0s = f0;
#endif
    const float3 vel = vload3(0, params.velocity);
    float16 acc_re[ROWS], acc_im[ROWS];
#ifdef MONO
    /* w . delta of each row, made once for each run of pulses whose w has the same bits (R.w_run: how
     * many pulses follow with them; a receiver at constant velocity: one run a launch), so that the
     * pulse loop itself neither checks w nor remakes the products (the same float operations on the
     * same values: the same s) */
    float16 wd[ROWS];
#endif
    FOR_ROWS {
        acc_re[r] = (float16)0.0f;
        acc_im[r] = (float16)0.0f;
    }
#ifdef CARRY
    __global float *held = carry + 32 * ROWS * g;
    if (carry_mode & 1) {
        FOR_ROWS {
            acc_re[r] = LOAD_F16(held + 32 * r);
            acc_im[r] = LOAD_F16(held + 32 * r + 16);
        }
    }
#endif
    const int p_begin = TILE_BEGIN, p_end = TILE_END;
#ifdef MONO
    for (int p = p_begin; p < p_end;) {
        const int run_end = min(p_end, p + 1 + tref[p].w_run);
        FOR_ROWS {
            wd[r] = tref[p].w[0] * FIELD(dx) + tref[p].w[1] * FIELD(dy) + tref[p].w[2] * FIELD(dz);
        }
    for (; p < run_end; ++p) {
#else
    for (int p = p_begin; p < p_end; ++p) {
#endif
        /* each step for all ROWS rows before the next: ROWS independent dependency chains side by
         * side in program order, which the out-of-order core overlaps */
        const tile_ref_t R = tref[p];
        __global const float *rec = records + (size_t)2 * p * n;
        const float3 b = vload3(0, R.leg1), b2 = 2.0f * b;  /* N1 = 2 B.delta + |delta|^2 */
        float16 s1[ROWS], s[ROWS], frac[ROWS], cs[ROWS], sn[ROWS];
        int16 keep[ROWS];
        volatile int8 first[ROWS][2];  /* the lanes' first samples, read back one by one as scalars */
#ifndef MOVING
        if (R.poly) {
            FOR_ROWS {  /* leg 1 without a square root or a division */
                const float16 n1 = fma(b2.x, FIELD(dx), fma(b2.y, FIELD(dy), fma(b2.z, FIELD(dz), FIELD(dd))));
                const float16 x = n1 * R.k2;
#if defined(MONO) && !defined(APERTURE)
                /* s = alpha s1 - w . delta, alpha taken into k1 (s1 itself is not needed) */
                s[r] = fma(n1 * (R.k1 * R.alpha), LEG_POLY(x), -wd[r]);
#else
                s1[r] = (n1 * R.k1) * LEG_POLY(x);
#endif
            }
        } else
#endif
        {
            FOR_ROWS {  /* leg 1: the stable root */
                const float16 n1 = fma(b2.x, FIELD(dx), fma(b2.y, FIELD(dy), fma(b2.z, FIELD(dz), FIELD(dd))));
#ifdef MOVING
                const float16 b1 = R.b1 - FIELD(dv);
#else
                const float16 b1 = (float16)R.b1;
#endif
                s1[r] = n1 / (b1 + sqrt(b1 * b1 + a1 * n1));
#if defined(MONO) && !defined(APERTURE)
                s[r] = R.alpha * s1[r] - wd[r];  /* each arm makes s (with APERTURE: below, from s1) */
#endif
            }
        }
        FOR_ROWS {
#if defined(SAME_LEGS)
            s[r] = s1[r];  /* fs and f0s carry the factor 2 */
#elif defined(MONO)
#ifdef APERTURE
            s[r] = R.alpha * s1[r] - wd[r];
#endif
#else
            /* leg 2: s2 = t2 - t2_ref, e = (v_r - v) s1 - delta; s = s1 + s2 */
            const float3 v_r = vload3(0, R.v_rx), cc = vload3(0, R.leg2), u = v_r - vel;
            const float16 ex = u.x * s1[r] - FIELD(dx), ey = u.y * s1[r] - FIELD(dy), ez = u.z * s1[r] - FIELD(dz);
            const float16 n2 = 2.0f * (cc.x * ex + cc.y * ey + cc.z * ez) + (ex * ex + ey * ey + ez * ez);
            const float16 b2 = R.b2 - (v_r.x * ex + v_r.y * ey + v_r.z * ez);
            s[r] = s1[r] + n2 / (b2 + sqrt(b2 * b2 + R.a2 * n2));
#endif
        }
        FOR_ROWS {  /* sample index K_ref + (k_frac + s fs), positive: truncation is the floor */
            const float16 kf = R.k_frac + s[r] * fs;
            const int16 k = convert_int16(kf);
            frac[r] = kf - convert_float16(k);
            const int16 ki = k + R.k_ref;
#ifdef INTERP_LINEAR
            keep[r] = as_uint16(ki) < (uint16)(n - 1);  /* samples ki and ki + 1 exist */
            STORE_FIRST(r, select((int16)0, ki, keep[r]));
#else
            keep[r] = as_uint16(ki - 3) <= (uint16)(n - 8);  /* samples ki - 3 .. ki + 4 exist */
            STORE_FIRST(r, select((int16)0, ki - 3, keep[r]));
#endif
#ifdef APERTURE
            /* sin theta = (q - tx).y / (c t1), q - tx = B + delta + v s1 */
            keep[r] &= fabs(b.y + FIELD(dy) + vel.y * s1[r]) <= params.half_sin * (R.range1 + params.c * s1[r]);
#endif
        }
        FOR_ROWS {  /* carrier exp(+j 2 pi f0 tau): cycles f0 T_ref (reduced) + f0 s, reduced to [-1/2, 1/2] */
            const float16 cyc = R.cycles + s[r] * f0s;
            EXPJ_NEAR16(NEAR_FRACTION(cyc), &cs[r], &sn[r]);
        }
        FOR_ROWS {
            const volatile int *i = (const volatile int *)&first[r][0];
#ifdef INTERP_LINEAR
            /* samples i and i + 1 of each lane in one 4-wide load, transposed in registers (READ16 and
             * UNPACK16 on AVX-512, else TRANSPOSE8) */
#ifdef CLSAS_READ16
            float16 y0, y1, y2, y3;
            READ16(rec, i, y0, y1, y2, y3);
            const float16 t0 = UNPACK16_LO(y0, y1), t1 = UNPACK16_HI(y0, y1);
            const float16 t2 = UNPACK16_LO(y2, y3), t3 = UNPACK16_HI(y2, y3);
            const float16 a_re = UNPACK16_LO2(t0, t2), a_im = UNPACK16_HI2(t0, t2);
            const float16 b_re = UNPACK16_LO2(t1, t3), b_im = UNPACK16_HI2(t1, t3);
#else
            float8 ar[2], ai[2], br[2], bi[2];
#define W(L) LOAD_F4(rec + 2 * i[0x##L])
            TRANSPOSE8(W(0), W(1), W(2), W(3), W(4), W(5), W(6), W(7), &ar[0], &ai[0], &br[0], &bi[0]);
            TRANSPOSE8(W(8), W(9), W(a), W(b), W(c), W(d), W(e), W(f), &ar[1], &ai[1], &br[1], &bi[1]);
#undef W
            const float16 a_re = (float16)(ar[0], ar[1]), a_im = (float16)(ai[0], ai[1]);
            const float16 b_re = (float16)(br[0], br[1]), b_im = (float16)(bi[0], bi[1]);
#endif
            const float16 dr = select((float16)0.0f, fma(b_re - a_re, frac[r], a_re), keep[r]);
            const float16 di = select((float16)0.0f, fma(b_im - a_im, frac[r], a_im), keep[r]);
#else
            /* samples i - 3 .. i + 4 of each lane, the taps of the nearest fractional-offset row */
            const int16 row = NEAREST_TAP_ROW(convert_int16, frac[r]);
#define W(L) LOAD_F16(rec + 2 * i[0x##L])
            const float16 lo = sinc8_lanes(taps, row.lo, W(0), W(1), W(2), W(3), W(4), W(5), W(6), W(7));
            const float16 hi = sinc8_lanes(taps, row.hi, W(8), W(9), W(a), W(b), W(c), W(d), W(e), W(f));
#undef W
            const float16 dr = select((float16)0.0f, (float16)(lo.even, hi.even), keep[r]);
            const float16 di = select((float16)0.0f, (float16)(lo.odd, hi.odd), keep[r]);
#endif
            /* a lane not kept adds zeros (its sample zeroed where it is made: no blend of the sums) */
            acc_re[r] = acc_re[r] + dr * cs[r] - di * sn[r];
            acc_im[r] = acc_im[r] + dr * sn[r] + di * cs[r];
        }
    }
#ifdef MONO
    }  /* the run of pulses */
#endif
#ifdef CARRY
    if (carry_mode & 2) {
        FOR_ROWS {
            STORE_F16(acc_re[r], held + 32 * r);
            STORE_F16(acc_im[r], held + 32 * r + 16);
        }
        return;
    }
#endif
    for (int r = 0; r < ROWS; ++r) {
        const int m = 16 * (ROWS * g + r);
#ifdef SCATTER
        float re[16], im[16];
        vstore16(acc_re[r], 0, re);
        vstore16(acc_im[r], 0, im);
        for (int l = 0; l < 16; ++l) {
            if (index[m + l] >= 0)
                image[index[m + l]] += (double2)(re[l], im[l]);
        }
#else
        /* the row's 16 slots are contiguous: four vectors of 4 (re, im) pairs, the same double
         * additions as slot by slot (BP_STORE: stored, the launch's sums starting the image; the
         * same values as added to zeros, since a float sum from +0 is never -0) */
        const float16 re = acc_re[r], im = acc_im[r];
        __global double *o = (__global double *)(image + m);
#ifdef BP_STORE
#define SUM_INTO(at, v) STORE_D8((v), (at))
#else
#define SUM_INTO(at, v) STORE_D8(LOAD_D8(at) + (v), (at))
#endif
        SUM_INTO(o, convert_double8((float8)(re.s0, im.s0, re.s1, im.s1, re.s2, im.s2, re.s3, im.s3)));
        SUM_INTO(o + 8, convert_double8((float8)(re.s4, im.s4, re.s5, im.s5, re.s6, im.s6, re.s7, im.s7)));
        SUM_INTO(o + 16, convert_double8((float8)(re.s8, im.s8, re.s9, im.s9, re.sa, im.sa, re.sb, im.sb)));
        SUM_INTO(o + 24, convert_double8((float8)(re.sc, im.sc, re.sd, im.sd, re.se, im.se, re.sf, im.sf)));
#undef SUM_INTO
#endif
    }
}
