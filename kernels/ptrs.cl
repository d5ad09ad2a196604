/* The two 2-D phase multiplies of numerical PTRS imaging (Zhang, Tan & Ying 2019, eqs. 12-14).
 *
 * NumPy twins: clsas/image/ptrs/phase.py (decouple_reference, compress_azimuth_reference);
 * launchers and the host-side preparation (_decouple_tables, compress_azimuth_opencl) there.
 *
 * Everything per element is float: the host splits each phase into terms that depend on the
 * row only, on the column only (both reduced to a fraction of a cycle in double on the host)
 * and a small remainder (a few hundred cycles at most, ~2e-5 cycle of float rounding).
 *
 * ptrs_decouple: element (row i, column j) of a 2-D spectrum (rows f_t, columns f_tau) is
 * multiplied by exp(+j 2 pi [f_j H(s) - row_i - col_j]), s = -f_t / f_j, f_j = f0 + f_tau_j:
 * H is the difference table D less its tangent at s = 0 (D0 + D1 s), read by cubic Hermite
 * interpolation from table[k] = (H_k, ds H'_k, H_k+1, ds H'_k+1) at the position
 * pos = a_i / f_j + b of s on the table's uniform slopes (a_i = -f_t,i / ds, b = -s_first / ds;
 * the host checks that every position lies inside the table, so truncation is a floor).
 * Columns: inv_f[j] = 1 / f_j, f[j], col[j]; rows: row[i] = (a_i, row_i).
 *
 * ptrs_compress_azimuth: element (i, j) of a range-Doppler array is multiplied by
 * exp(+j 2 pi [A_i,m + w_j dA_i,m]) with nodes[i, m] = (frac(A_i,m), A_i,m+1 - A_i,m) (A: the
 * azimuth modulation f0 G(-f_t / f0; r) at range node m), m = column_node[j] (non-decreasing
 * in j: the host checks), w = column_weight[j].
 *
 * A work-item does 16 consecutive columns of one row as float16 (PoCL does not vectorise
 * across work-items by itself here): the 16 complex samples are two contiguous float16 loads,
 * the phasors a polynomial on the reduced cycles (CLSAS_EXPJ_FRACTION, common.h). Over 16
 * columns the slope s moves by ~4e-4 of itself, so the 16 lanes nearly always read one table
 * interval (one load for all; else a load per lane), and the range nodes (~17 columns apart)
 * at most two. Global size (n_rows, ceil(n_cols / 16) padded to whole work-groups: the host's
 * clsas.opencl.work_groups_2d); the last work-item of a row does the remaining columns one by one,
 * those past the row's end none. */
#include "common.h"
#include "loads.h"

#define INTERLEAVE_LO(a, b) (float16)(a.s0, b.s0, a.s1, b.s1, a.s2, b.s2, a.s3, b.s3, \
                                      a.s4, b.s4, a.s5, b.s5, a.s6, b.s6, a.s7, b.s7)
#define INTERLEAVE_HI(a, b) (float16)(a.s8, b.s8, a.s9, b.s9, a.sa, b.sa, a.sb, b.sb, \
                                      a.sc, b.sc, a.sd, b.sd, a.se, b.se, a.sf, b.sf)

/* d[0..31] (16 complex samples, re/im interleaved) times exp(j 2 pi cycles) */
inline void rotate16(__global float *d, const float16 cycles)
{
    const float16 r = cycles - convert_float16(convert_int16(cycles));
    float16 cs, sn;
    CLSAS_EXPJ_FRACTION(float16, r, &cs, &sn);
    const float16 lo = LOAD_F16(d), hi = LOAD_F16(d + 16);
    const float16 re = (float16)(lo.even, hi.even), im = (float16)(lo.odd, hi.odd);
    const float16 nre = re * cs - im * sn, nim = re * sn + im * cs;
    STORE_F16(INTERLEAVE_LO(nre, nim), d);
    STORE_F16(INTERLEAVE_HI(nre, nim), d + 16);
}

inline void rotate1(__global float *d, const float cycles)
{
    const float r = cycles - (float)convert_int(cycles);
    float cs, sn;
    CLSAS_EXPJ_FRACTION(float, r, &cs, &sn);
    const float re = d[0], im = d[1];
    d[0] = re * cs - im * sn;
    d[1] = re * sn + im * cs;
}

inline float hermite1(const float u, const float4 t)
{
    const float u2 = u * u, u3 = u2 * u;
    return (2 * u3 - 3 * u2 + 1) * t.x + (u3 - 2 * u2 + u) * t.y + (3 * u2 - 2 * u3) * t.z + (u3 - u2) * t.w;
}

/* 1 where any lane of v is non-zero */
inline int any16(const int16 v)
{
    const int8 a = v.lo | v.hi;
    const int4 b = a.lo | a.hi;
    const int2 c = b.lo | b.hi;
    return (c.x | c.y) != 0;
}

__kernel void ptrs_decouple(__global float *data, __global const float *inv_f, __global const float *f,
                            __global const float *col, __global const float2 *row, __global const float4 *table,
                            const float b, const int n_s, const int n_cols)
{
    const int i = get_global_id(0), j0 = 16 * get_global_id(1);
    const float2 rw = row[i];
    __global float *d = data + 2 * ((size_t)i * n_cols + j0);
    if (j0 + 16 > n_cols) {
        for (int j = j0; j < n_cols; ++j) {
            const float pos = fma(rw.x, inv_f[j], b);
            const int k = min(convert_int(pos), n_s - 2);
            rotate1(d + 2 * (j - j0), f[j] * hermite1(pos - (float)k, table[k]) - rw.y - col[j]);
        }
        return;
    }
    const float16 pos = fma((float16)rw.x, LOAD_F16(inv_f + j0), (float16)b);
    const int16 k = min(convert_int16(pos), (int16)(n_s - 2));
    const float16 u = pos - convert_float16(k), u2 = u * u, u3 = u2 * u;
    float16 t0, t1, t2, t3;
    if (!any16(k - (int16)k.s0)) {
        const float4 t = table[k.s0];
        t0 = (float16)t.x; t1 = (float16)t.y; t2 = (float16)t.z; t3 = (float16)t.w;
    } else {
        float a0[16], a1[16], a2[16], a3[16];
        int kk[16];
        vstore16(k, 0, kk);
        for (int l = 0; l < 16; ++l) {
            const float4 t = table[kk[l]];
            a0[l] = t.x; a1[l] = t.y; a2[l] = t.z; a3[l] = t.w;
        }
        t0 = vload16(0, a0); t1 = vload16(0, a1); t2 = vload16(0, a2); t3 = vload16(0, a3);
    }
    const float16 h = (2 * u3 - 3 * u2 + 1) * t0 + (u3 - 2 * u2 + u) * t1 + (3 * u2 - 2 * u3) * t2 + (u3 - u2) * t3;
    rotate16(d, LOAD_F16(f + j0) * h - rw.y - LOAD_F16(col + j0));
}

__kernel void ptrs_compress_azimuth(__global float *data, __global const float2 *nodes,
                                    __global const int *column_node, __global const float *column_weight,
                                    const int n_nodes, const int n_cols)
{
    const int i = get_global_id(0), j0 = 16 * get_global_id(1);
    __global const float2 *row = nodes + (size_t)i * n_nodes;
    __global float *d = data + 2 * ((size_t)i * n_cols + j0);
    if (j0 + 16 > n_cols) {
        for (int j = j0; j < n_cols; ++j) {
            const float2 a = row[column_node[j]];
            rotate1(d + 2 * (j - j0), fma(column_weight[j], a.y, a.x));
        }
        return;
    }
    const int16 m = vload16(0, column_node + j0);
    float16 base, step;
    if (m.sf - m.s0 <= 1) {
        const float2 a = row[m.s0], c = row[min(m.s0 + 1, n_nodes - 1)];
        const int16 next = m != (int16)m.s0;  /* -1 where the lane reads the second node */
        base = select((float16)a.x, (float16)c.x, next);
        step = select((float16)a.y, (float16)c.y, next);
    } else {
        float a0[16], a1[16];
        int mm[16];
        vstore16(m, 0, mm);
        for (int l = 0; l < 16; ++l) {
            const float2 a = row[mm[l]];
            a0[l] = a.x; a1[l] = a.y;
        }
        base = vload16(0, a0); step = vload16(0, a1);
    }
    rotate16(d, fma(LOAD_F16(column_weight + j0), step, base));
}
