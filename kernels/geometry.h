/* clsas kernels: exact two-way geometry for eight lanes at once (double8), shared by
 * kernels/echo.cl (eight scatterers a work-item) and kernels/bp_block.cl (eight pixels).
 * NumPy twin: clsas/geometry.py (fixed-point iteration; the closed forms here agree
 * with it to its 1e-6-period tolerance, tests/test_echo.py and tests/test_backprojection.py).
 *
 * Needs N_NODES (receiver position nodes a pulse, >= 2) and SEGMENT_PASSES defined, cl_khr_fp64
 * enabled, and the receiver node record node_t (fields pos[3], axis[3]: clsas.geometry.NODE,
 * declared in the kernel's preamble by the launcher).
 */
#ifndef CLSAS_GEOMETRY_H
#define CLSAS_GEOMETRY_H

/* Eight lanes as double8 (PoCL does not vectorise these kernels across work-items by
 * itself): a 3-vector of lanes is three double8. */
typedef struct { double8 x, y, z; } vec8;

inline vec8 v8(double8 x, double8 y, double8 z) { vec8 r = {x, y, z}; return r; }
inline vec8 v8_add(vec8 a, vec8 b) { return v8(a.x + b.x, a.y + b.y, a.z + b.z); }
inline vec8 v8_sub(vec8 a, vec8 b) { return v8(a.x - b.x, a.y - b.y, a.z - b.z); }
inline vec8 v8_scale(vec8 a, double8 k) { return v8(a.x * k, a.y * k, a.z * k); }
inline double8 v8_dot(vec8 a, vec8 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline vec8 v8_splat(double3 a) { return v8((double8)a.x, (double8)a.y, (double8)a.z); }

/* sinc(L sin(theta) / lambda) with sin(theta) = dir . axis / |dir| (Heremans 2009 eq. 33) */
inline double8 element_gain8(double length, vec8 dir, double8 dist, vec8 axis, double wavelength)
{
    if (length == 0.0) return (double8)1.0;
    const double8 x = length * v8_dot(dir, axis) / (dist * wavelength);
    return select(sinpi(x) / (M_PI * x), (double8)1.0, x == 0.0);
}

/* The time t > 0 at which a wave leaving point A at t = 0 with speed c meets a point moving
 * as A + D + W t: |D + W t| = c t, i.e. (c^2 - |W|^2) t^2 - 2 (D.W) t - |D|^2 = 0, whose positive
 * root is t = [D.W + sqrt((D.W)^2 + (c^2 - |W|^2) |D|^2)] / (c^2 - |W|^2). Exact for uniform
 * motion; no cancellation since |D.W| <= |W||D| << c |D|. (For a straight track and a stationary
 * target, applied to both legs, this is Zhang et al. 2019 eq. (1).) */
inline double8 meet_time8(vec8 d, vec8 w, double c)
{
    const double8 a = c * c - v8_dot(w, w), b = v8_dot(d, w);
    return (b + sqrt(b * b + a * v8_dot(d, d))) / a;
}

/* meet_time8 for a velocity W shared by all lanes: a = c^2 - |W|^2 and 1/a are scalars, so no
 * division per lane. */
inline double8 meet_time8_uniform(vec8 d, double3 w, double c)
{
    const double a = c * c - dot(w, w);
    const double8 b = d.x * w.x + d.y * w.y + d.z * w.z;
    return (b + sqrt(b * b + a * v8_dot(d, d))) * (1.0 / a);
}

/* A node's position (field 0) or element axis (field 1) as a vector. */
#define NODE_POS(n) vload3(0, (n).pos)
#define NODE_FIELD(n, field) ((field) == 0 ? vload3(0, (n).pos) : vload3(0, (n).axis))

/* Receiver node field (position: 0, element axis: 1) at fast times tau, linear between nodes
 * k dtau; with two nodes the single segment serves every lane. */
inline vec8 node_field(__global const node_t *nd, double8 tau, double dtau, int field)
{
#if N_NODES == 2
    const double8 w = tau / dtau;
    const double3 a = NODE_FIELD(nd[0], field), b = NODE_FIELD(nd[1], field);
    return v8(a.x + (b.x - a.x) * w, a.y + (b.y - a.y) * w, a.z + (b.z - a.z) * w);
#else
    double t[8], x[8], y[8], z[8];
    vstore8(tau, 0, t);
    for (int l = 0; l < 8; ++l) {
        const int seg = clamp(convert_int(t[l] / dtau), 0, N_NODES - 2);
        const double w = t[l] / dtau - (double)seg;
        const double3 a = NODE_FIELD(nd[seg], field);
        const double3 b = NODE_FIELD(nd[seg + 1], field);
        const double3 r = mix(a, b, w);
        x[l] = r.x; y[l] = r.y; z[l] = r.z;
    }
    return v8(vload8(0, x), vload8(0, y), vload8(0, z));
#endif
}

/* Receiver velocity (m/s) at fast times tau: its node segment's (uniform within a segment). */
inline vec8 node_velocity(__global const node_t *nd, double8 tau, double dtau)
{
#if N_NODES == 2
    return v8_splat((NODE_POS(nd[1]) - NODE_POS(nd[0])) / dtau);
#else
    double t[8], x[8], y[8], z[8];
    vstore8(tau, 0, t);
    for (int l = 0; l < 8; ++l) {
        const int seg = clamp(convert_int(t[l] / dtau), 0, N_NODES - 2);
        const double3 w = (NODE_POS(nd[seg + 1]) - NODE_POS(nd[seg])) / dtau;
        x[l] = w.x; y[l] = w.y; z[l] = w.z;
    }
    return v8(vload8(0, x), vload8(0, y), vload8(0, z));
#endif
}

/* The receiver at reception, eta + t1 + t2: the receiver moves linearly within a node segment
 * [k dtau, (k+1) dtau] with velocity W_k, so for that segment t2 = meet_time(R_k(t1) - Q, W_k)
 * with R_k extended linearly; the segment is taken where t1 + |R(t1) - Q| / c falls and
 * re-chosen (SEGMENT_PASSES times) if the solution lands in another one. Exact in one pass
 * for two nodes (uniform motion). Returns the fast time of reception t1 + t2. */
inline double8 reception8(__global const node_t *nd, double8 t1, vec8 q, double c, double dtau)
{
    const vec8 r_t1 = node_field(nd, t1, dtau, 0);
#if N_NODES == 2
    return t1 + meet_time8_uniform(v8_sub(r_t1, q), (NODE_POS(nd[1]) - NODE_POS(nd[0])) / dtau, c);
#else
    double8 t_rx = t1 + sqrt(v8_dot(v8_sub(r_t1, q), v8_sub(r_t1, q))) / c;
    for (int pass = 0; pass < SEGMENT_PASSES; ++pass) {
        double tr[8], wx[8], wy[8], wz[8], rx_[8], ry[8], rz[8], t1s[8];
        vstore8(t_rx, 0, tr);
        vstore8(t1, 0, t1s);
        for (int l = 0; l < 8; ++l) {
            const int seg = clamp(convert_int(tr[l] / dtau), 0, N_NODES - 2);
            const double3 w3 = (NODE_POS(nd[seg + 1]) - NODE_POS(nd[seg])) / dtau;
            const double3 r3 = NODE_POS(nd[seg]) + w3 * (t1s[l] - (double)seg * dtau);
            wx[l] = w3.x; wy[l] = w3.y; wz[l] = w3.z;
            rx_[l] = r3.x; ry[l] = r3.y; rz[l] = r3.z;
        }
        const vec8 w = v8(vload8(0, wx), vload8(0, wy), vload8(0, wz));
        const vec8 r = v8(vload8(0, rx_), vload8(0, ry), vload8(0, rz));
        t_rx = t1 + meet_time8(v8_sub(r, q), w, c);
    }
    return t_rx;
#endif
}

#endif /* CLSAS_GEOMETRY_H */
