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
 * w in [0, 1]); i = floor(idx), w = idx - i. An output reads as zero unless all its source
 * samples exist.
 *
 * One work-item: sixteen consecutive outputs of a row (float16 lanes for the index), global
 * size (n_out_pad / 16, n_rows). params: K0 = kx_first + 2 k0, dkx, A = c / (4 pi df),
 * Bc = -(f0 + f_first) / df. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

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
    const float16 w = x - convert_float16(fl);
    const int16 i = i_first + fl;
    __global const float *row = (__global const float *)(src + (size_t)r * n_src);
    float out[32];
#ifdef INTERP_LINEAR
    const int16 ok = i >= 0 && i < n_src - 1;
#define LANE(L, N) {                                                               \
        const float4 s = ok.s##L ? vload4(0, row + 2 * i.s##L) : (float4)0.0f;      \
        out[2 * N] = mix(s.s0, s.s2, w.s##L);                                      \
        out[2 * N + 1] = mix(s.s1, s.s3, w.s##L); }
#else
    const int16 first_raw = i - (TAPS / 2 - 1);
    const int16 ok = first_raw >= 0 && first_raw <= n_src - TAPS;
    const int16 first = clamp(first_raw, 0, n_src - TAPS);
    float keep[16];
    vstore16(select((float16)0.0f, (float16)1.0f, ok), 0, keep);
    const int16 t_row = convert_int16(w * (float)(TAP_ROWS - 1) + 0.5f);
#if TAPS == 8
#define PRODUCTS(L)                                                                \
            const float16 s = vload16(0, row + 2 * first.s##L);                    \
            const float8 t = vload8(t_row.s##L, taps);                             \
            const float8 pr = s.even * t, pi = s.odd * t;
#elif TAPS == 16
#define PRODUCTS(L)                                                                \
            const float16 a = vload16(0, row + 2 * first.s##L);                    \
            const float16 b = vload16(0, row + 2 * first.s##L + 16);               \
            const float16 t = vload16(t_row.s##L, taps);                           \
            const float8 pr = a.even * t.lo + b.even * t.hi;                       \
            const float8 pi = a.odd * t.lo + b.odd * t.hi;
#else
#error "TAPS must be 8 or 16"
#endif
#define LANE(L, N) {                                                               \
        PRODUCTS(L)                                                                \
        const float4 qr = pr.lo + pr.hi, qi = pi.lo + pi.hi;                       \
        const float2 hr = qr.lo + qr.hi, hi = qi.lo + qi.hi;                       \
        out[2 * N] = keep[N] * (hr.x + hr.y);                                      \
        out[2 * N + 1] = keep[N] * (hi.x + hi.y); }
#endif
    LANE(0, 0) LANE(1, 1) LANE(2, 2) LANE(3, 3) LANE(4, 4) LANE(5, 5) LANE(6, 6) LANE(7, 7)
    LANE(8, 8) LANE(9, 9) LANE(a, 10) LANE(b, 11) LANE(c, 12) LANE(d, 13) LANE(e, 14) LANE(f, 15)
#undef LANE
    __global float *o = (__global float *)(dst + (size_t)r * n_out_pad + j0);
    vstore16(vload16(0, out), 0, o);
    vstore16(vload16(1, out), 1, o);
}
