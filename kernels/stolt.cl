/* Stolt mapping of a wavenumber-domain spectrum (the interpolation step of omega-k).
 *
 * NumPy twin: clsas/image/stolt.py (stolt_reference); launcher in the same module.
 *
 * For output row r (one along-track wavenumber k_u, ku2[r] = k_u^2) and output column j (the
 * uniform baseband range wavenumber k_x' = kx_first + j dkx), the source column is the exact,
 * non-uniformly spaced position
 *     idx = (c / (4 pi) sqrt((k_x' + 2 k0)^2 + k_u^2) - f0 - f_first) / df
 *         = A sqrt(K^2 + k_u^2) + Bc,   K = K0 + j dkx,
 * evaluated in double for the first output of a work-item (float would round idx ~ 2000 to
 * 1.2e-4 sample) and relative to it in float for the other fifteen (see below); the
 * interpolation and the data are float.
 *
 * INTERP_LINEAR: (1 - w) s[i] + w s[i + 1]; otherwise TAPS (8 or 16) windowed-sinc taps
 * s[i - TAPS/2 + 1 + t] weighted by the row of the tap table nearest to w (TAP_ROWS rows over
 * w in [0, 1]); i = floor(idx), w = idx - i, except that w >= 1 - 1/(2 (TAP_ROWS - 1)) reads as
 * (i + 1, w - 1) (a position a rounding error below an integer is that integer, in the kernel
 * and the reference alike). An output reads as zero unless all its source
 * samples exist.
 *
 * One work-item: sixteen consecutive outputs of a row (float16 lanes for the index), global
 * size (n_out_pad / 16, n_rows). params: K0 = kx_first + 2 k0, dkx, A = c / (4 pi df),
 * Bc = -(f0 + f_first) / df. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

/* Unaligned vector loads: PoCL builds vloadN from 8-byte pieces (eight loads for a vload16);
 * a vector type with 4-byte alignment makes clang emit one unaligned vector load. */
#ifdef __clang__
typedef float16 float16_u __attribute__((aligned(4)));
typedef float8 float8_u __attribute__((aligned(4)));
typedef float4 float4_u __attribute__((aligned(4)));
#define LOAD16(p) (*(__global const float16_u *)(p))
#define LOAD8(p) (*(__global const float8_u *)(p))
#define LOAD4(p) (*(__global const float4_u *)(p))
#else
#define LOAD16(p) vload16(0, (p))
#define LOAD8(p) vload8(0, (p))
#define LOAD4(p) vload4(0, (p))
#endif

__kernel void stolt_map(__global const float2 *src, __global const float *taps,
                        __global const double *ku2, const double4 params, const int n_src,
                        const int n_out_pad, __global float2 *dst)
{
    const int j0 = 16 * get_global_id(0), r = get_global_id(1);
    /* lane 0 exactly in double; lane l relative to it in float, d = l dkx:
     * sqrt((K + d)^2 + k_u^2) - sqrt(K^2 + k_u^2) = d (2K + d) / (s_l + s_0), no cancellation,
     * so x = idx - floor(idx_0) is a small float (< 17) with error ~1e-6 sample */
    const double k_first = params.s0 + j0 * params.s1;
    const double s_first = sqrt(k_first * k_first + ku2[r]), idx_first = s_first * params.s2 + params.s3;
    const int i_first = convert_int(idx_first) - (idx_first < 0.0 ? 1 : 0);
    const float16 d = (float)params.s1 * (float16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const float kf = (float)k_first, ku2f = (float)ku2[r];
    const float16 s_l = sqrt((kf + d) * (kf + d) + ku2f);
    const float16 x = (float)(idx_first - (double)i_first)
                      + (float)params.s2 * (d * (2.0f * kf + d) / (s_l + (float)s_first));
    int16 fl = convert_int16(x);
    fl += convert_int16(x < convert_float16(fl));  /* floor (a true compare is -1) */
    float16 w = x - convert_float16(fl);
    /* a position within half a tap row below an integer reads as that integer (as the
     * reference does), so that exact integers decide the edge test the same way */
    const int16 up = w >= 1.0f - 0.5f / (TAP_ROWS - 1);  /* -1 where true */
    fl -= up;
    w = select(w, w - 1.0f, up);
    const int16 i = i_first + fl;
    __global const float *row = (__global const float *)(src + (size_t)r * n_src);
    __global float *o = (__global float *)(dst + (size_t)r * n_out_pad + j0);
#ifdef INTERP_LINEAR
    const int16 ok = i >= 0 && i < n_src - 1;
    float out[32];
#define LANE(L, N) {                                                               \
        const float4 s = ok.s##L ? LOAD4(row + 2 * i.s##L) : (float4)0.0f;          \
        out[2 * N] = mix(s.s0, s.s2, w.s##L);                                      \
        out[2 * N + 1] = mix(s.s1, s.s3, w.s##L); }
    LANE(0, 0) LANE(1, 1) LANE(2, 2) LANE(3, 3) LANE(4, 4) LANE(5, 5) LANE(6, 6) LANE(7, 7)
    LANE(8, 8) LANE(9, 9) LANE(a, 10) LANE(b, 11) LANE(c, 12) LANE(d, 13) LANE(e, 14) LANE(f, 15)
    vstore16(vload16(0, out), 0, o);
    vstore16(vload16(1, out), 1, o);
#else
    const int16 first_raw = i - (TAPS / 2 - 1);
    const int16 ok = first_raw >= 0 && first_raw <= n_src - TAPS;
    const int16 first = 2 * clamp(first_raw, 0, n_src - TAPS);
    const int16 t_row = convert_int16(w * (float)(TAP_ROWS - 1) + 0.5f);
    /* lane L's complex products: its TAPS samples (re, im interleaved) times the row's taps,
     * each tap repeated for re and im; TAPS = 16 adds the second half first */
#if TAPS == 8
#define P(L) (LOAD16(row + first.s##L) * LOAD8(taps + 8 * t_row.s##L).s0011223344556677)
#elif TAPS == 16
#define P(L) (LOAD16(row + first.s##L) * LOAD16(taps + 16 * t_row.s##L).lo.s0011223344556677      \
              + LOAD16(row + first.s##L + 16) * LOAD16(taps + 16 * t_row.s##L).hi.s0011223344556677)
#else
#error "TAPS must be 8 or 16"
#endif
    /* sum each lane's eight complex partials with a tree across lanes (no per-lane horizontal
     * sums): two lanes' halves, then quarters, then pairs, leaving 8 complex outputs a vector */
#define FOLD1(A, B) ((float16)((A).lo, (B).lo) + (float16)((A).hi, (B).hi))
#define FOLD2(A, B) ((float16)((A).s012389ab, (B).s012389ab) + (float16)((A).s4567cdef, (B).s4567cdef))
#define FOLD3(A, B) ((float16)((A).s014589cd, (B).s014589cd) + (float16)((A).s2367abef, (B).s2367abef))
    const float16 p0 = P(0), p1 = P(1), p2 = P(2), p3 = P(3), p4 = P(4), p5 = P(5), p6 = P(6), p7 = P(7);
    const float16 p8 = P(8), p9 = P(9), pa = P(a), pb = P(b), pc = P(c), pd = P(d), pe = P(e), pf = P(f);
    const float16 q0 = FOLD1(p0, p1), q1 = FOLD1(p2, p3), q2 = FOLD1(p4, p5), q3 = FOLD1(p6, p7);
    const float16 q4 = FOLD1(p8, p9), q5 = FOLD1(pa, pb), q6 = FOLD1(pc, pd), q7 = FOLD1(pe, pf);
    const float16 lo = FOLD3(FOLD2(q0, q1), FOLD2(q2, q3)), hi = FOLD3(FOLD2(q4, q5), FOLD2(q6, q7));
    const int16 keep_lo = ok.s0011223344556677, keep_hi = ok.s8899aabbccddeeff;
    vstore16(select((float16)0.0f, lo, keep_lo), 0, o);
    vstore16(select((float16)0.0f, hi, keep_hi), 1, o);
#endif
}
