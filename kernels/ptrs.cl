/* The two 2-D phase multiplies of numerical PTRS imaging (Zhang, Tan & Ying 2019, eqs. 12-14).
 *
 * NumPy twins: clsas/image/ptrs/phase.py (decouple_reference, compress_azimuth_reference);
 * launchers in the same module.
 *
 * ptrs_decouple: element (row i, column j) of a 2-D spectrum (rows f_t = ft[i], columns
 * f_tau = ftau[j]) is multiplied by exp(-j 2 pi cycles) with
 *     cycles = -(f0 + f_tau) D(s) + row_term[i] + kappa f_tau,   s = -f_t / (f0 + f_tau),
 * D read from the table (D_k, T_k) at slopes s_first + k ds by cubic Hermite interpolation with
 * the derivative dD/ds = -T (the host checks that every s lies inside the table, so the
 * truncating conversion is a floor). params = (f0, s_first, ds, kappa); inv_f[j] =
 * 1 / (f0 + ftau[j]) and inv_ds = 1 / ds come from the host (no division per element).
 *
 * ptrs_compress_azimuth: element (i, j) of a range-Doppler array is multiplied by
 * exp(+j 2 pi cycles), cycles = (1 - w_j) A[i, m_j] + w_j A[i, m_j + 1] (A: the azimuth
 * modulation f0 G(-f_t / f0; r) at range nodes, m_j and w_j: column j's node and weight).
 *
 * Phases are double (the bulk term is ~1e5 cycles), reduced to a fraction by truncation and
 * turned into a float phasor by CLSAS_EXPJ_FRACTION (common.h); data are float. One
 * work-item per element, global size (n_cols, n_rows): no loop, so PoCL vectorises across
 * work-items. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#include "common.h"

inline float2 rotate(const float2 z, const double cycles)
{
    const float r = (float)(cycles - (double)convert_long(cycles));
    float cs, sn;
    CLSAS_EXPJ_FRACTION(float, r, &cs, &sn);
    return (float2)(z.x * cs - z.y * sn, z.x * sn + z.y * cs);
}

__kernel void ptrs_decouple(__global float2 *data, __global const double *ft, __global const double *ftau,
                            __global const double *inv_f, __global const double *row_term,
                            __global const double2 *table, const double4 params, const double inv_ds,
                            const int n_s, const int n_cols)
{
    const int j = get_global_id(0);
    const int i = get_global_id(1);
    if (j >= n_cols)
        return;
    const double f = params.s0 + ftau[j];
    const double pos = (-ft[i] * inv_f[j] - params.s1) * inv_ds;
    const int k = min(convert_int(pos), n_s - 2);
    const double u = pos - k, u2 = u * u, u3 = u2 * u;
    const double2 a = table[k], b = table[k + 1];
    const double d = (2 * u3 - 3 * u2 + 1) * a.x + (-2 * u3 + 3 * u2) * b.x
                     - params.s2 * ((u3 - 2 * u2 + u) * a.y + (u3 - u2) * b.y);
    const size_t at = (size_t)i * n_cols + j;
    data[at] = rotate(data[at], f * d - row_term[i] - params.s3 * ftau[j]);
}

__kernel void ptrs_compress_azimuth(__global float2 *data, __global const double *at_nodes,
                                    __global const int *column_node, __global const double *column_weight,
                                    const int n_nodes, const int n_cols)
{
    const int j = get_global_id(0);
    const int i = get_global_id(1);
    if (j >= n_cols)
        return;
    const int m = column_node[j];
    const double w = column_weight[j];
    const __global double *row = at_nodes + (size_t)i * n_nodes;
    const size_t at = (size_t)i * n_cols + j;
    data[at] = rotate(data[at], (1 - w) * row[m] + w * row[m + 1]);
}
