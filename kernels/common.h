/* clsas kernels: shared helpers (OpenCL C 1.2).
 *
 * NumPy twins: clsas/kernelmath.py (expj_cycles, sinc, kaiser_sinc_tap), checked by
 * tests/test_kernelmath.py through kernels/kernelmath.cl.
 *
 * Precision: build with -DCLSAS_DOUBLE=1 to make real_t / complex_t double precision
 * (clsas.opencl.program(..., double=True)); the default is float.
 */
#ifndef CLSAS_COMMON_H
#define CLSAS_COMMON_H

#ifdef CLSAS_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#define PYOPENCL_DEFINE_CDOUBLE
#endif
#include <pyopencl-complex.h>

#ifdef CLSAS_DOUBLE
typedef double real_t;
typedef cdouble_t complex_t;
#define complex_new cdouble_new
#define complex_add cdouble_add
#define complex_mul cdouble_mul
#define complex_rmul cdouble_rmul
#define complex_conj cdouble_conj
#define REAL_PI M_PI
#define REAL_EPS DBL_EPSILON
#else
typedef float real_t;
typedef cfloat_t complex_t;
#define complex_new cfloat_new
#define complex_add cfloat_add
#define complex_mul cfloat_mul
#define complex_rmul cfloat_rmul
#define complex_conj cfloat_conj
#define REAL_PI M_PI_F
#define REAL_EPS FLT_EPSILON
#endif

/* Fractional part of a phase given in cycles, in (-1, 1): truncation by conversion
 * (PoCL's floor/rint are slow emulations); |cycles| < 2^31 in float builds.
 * Never take sin/cos of a large radian argument: reduce the cycles first, then use
 * sinpi/cospi. */
inline real_t reduce_cycles(real_t cycles)
{
#ifdef CLSAS_DOUBLE
    return cycles - (real_t)convert_long(cycles);
#else
    return cycles - (real_t)convert_int(cycles);
#endif
}

/* exp(j 2 pi cycles) */
inline complex_t expj_cycles(real_t cycles)
{
    real_t f = reduce_cycles(cycles);
    return complex_new(cospi((real_t)2 * f), sinpi((real_t)2 * f));
}

/* exp(j 2 pi r) in float for a phase r in (-1, 1) cycles (already reduced by truncation), as
 * (cos, sin): r is folded into [-1/2, 1/2]; with s = pi r in [-pi/2, pi/2], sin s = s P(s^2) and
 * cos s = Q(s^2) with P of degree 4 and Q of degree 5, least-squares fits on Chebyshev nodes
 * (max errors 3.4e-9 and 2.2e-10), then sin 2s = 2 sin s cos s and cos 2s = 1 - 2 sin^2 s:
 * |error| < 1.4e-8 before float32 rounding (so the result is as good as float allows: the
 * echo kernel's row recurrence multiplies these values up to ROWS times), and cheaper than
 * sinpi/cospi on PoCL. Works for float and floatN (T). Checked against NumPy by
 * tests/test_kernelmath.py (kernels/kernelmath.cl: expj_fractions). */
#define CLSAS_EXPJ_FRACTION(T, r_in, cs_out, sn_out)                                              \
    do {                                                                                          \
        T r_ = (r_in);                                                                            \
        r_ = r_ - select((T)0.0f, (T)1.0f, r_ > 0.5f) + select((T)0.0f, (T)1.0f, r_ < -0.5f);     \
        const T s_ = M_PI_F * r_, q_ = s_ * s_;                                                   \
        const T sin_ = s_ * (9.999999765e-01f + q_ * (-1.666664759e-01f + q_ * (8.332899165e-03f  \
                       + q_ * (-1.980086171e-04f + q_ * 2.590422739e-06f))));                     \
        const T cos_ = 9.999999998e-01f + q_ * (-4.999999936e-01f + q_ * (4.166663620e-02f        \
                       + q_ * (-1.388836078e-03f + q_ * (2.476013213e-05f + q_ * -2.605101538e-07f)))); \
        *(sn_out) = 2.0f * sin_ * cos_;                                                           \
        *(cs_out) = 1.0f - 2.0f * sin_ * sin_;                                                    \
    } while (0)

inline void expj_fraction(float r, float *cs, float *sn) { CLSAS_EXPJ_FRACTION(float, r, cs, sn); }
inline void expj_fraction8(float8 r, float8 *cs, float8 *sn) { CLSAS_EXPJ_FRACTION(float8, r, cs, sn); }
inline void expj_fraction16(float16 r, float16 *cs, float16 *sn) { CLSAS_EXPJ_FRACTION(float16, r, cs, sn); }

/* sinc(x) = sin(pi x) / (pi x), sinc(0) = 1 */
inline real_t sinc(real_t x)
{
    return x == (real_t)0 ? (real_t)1 : sinpi(x) / (REAL_PI * x);
}

/* Modified Bessel function I0 by its power series (converges for the window betas used,
 * |x| <= 40, to the working precision). */
inline real_t bessel_i0(real_t x)
{
    real_t q = (real_t)0.25 * x * x;
    real_t term = (real_t)1;
    real_t sum = (real_t)1;
    for (int k = 1; k < 64; ++k) {
        term *= q / (real_t)(k * k);
        sum += term;
        if (term < sum * REAL_EPS) break;
    }
    return sum;
}

/* Kaiser-windowed sinc interpolation tap for a sample at offset x (samples) from the
 * interpolation point: sinc(x) * I0(beta sqrt(1 - (x/half_width)^2)) / I0(beta) for
 * |x| < half_width, else 0. An N-tap interpolator uses half_width = N/2. */
inline real_t kaiser_sinc_tap(real_t x, real_t half_width, real_t beta)
{
    real_t u = x / half_width;
    if (fabs(u) >= (real_t)1) return (real_t)0;
    return sinc(x) * bessel_i0(beta * sqrt((real_t)1 - u * u)) / bessel_i0(beta);
}

#endif /* CLSAS_COMMON_H */
