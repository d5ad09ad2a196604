/* bp_tile's references (kernels/bp_tile.cl) on the device: TileKernel.references_on_device
 * (clsas/image/backprojection/tile_kernel.py; its NumPy twin TileKernel.references); the records
 * tile_ref_t and bp_ref_params_t come with TileKernel's preamble. Defines: MOVING, STOP_AND_GO,
 * MONO or SAME_LEGS, TILE_FIRST. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

/* bp_tile's references (tile_ref_t, TileKernel.reference_dtype) computed on the device, in double,
 * for pixels moving uniformly at v (or at rest) and a receiver of two position nodes (uniform
 * motion) or with stop-and-go: the closed forms of clsas/geometry.py's legs (meet_time), then the
 * record's fields as TileKernel.references (its NumPy twin) makes them.
 * Work-item i: tile t = i / n_chunks and the REF_LANES consecutive pulses j = REF_LANES (i % n_chunks) + l
 * (l < REF_LANES) of the job's n_pulses, computed side by side in double vectors (the lanes past n_pulses
 * are computed and not stored); ref[t n_pulses + j] is the reference of (tile t, pulse j).
 * pulse (REF_FIELDS rows of `stride` doubles, TileKernel.references_on_device: a row a field, a column a
 * pulse): tx (x, y, z), eta, rx0 = the receiver at emission (x, y, z), v_rx = its velocity (x, y, z),
 * t0 = its window start, offset = the first sample of its records (samples at fs from t0) and (MONO)
 * w = 2 v_rx / a2 (x, y, z), alpha = 2 c^2 / a2, a2 = c^2 - |v_rx|^2, and w_run = how many of the receiver's
 * following pulses have a w of the same float bits (per pulse: made once on the host, tile_kernel.w_runs); the
 * pulses of several receivers in one launch (clsas/image/backprojection/launcher.py: receiver after
 * receiver, each over the same pulses); centres[t]: the tile's reference point at t = 0;
 * TILE_FIRST (ffbp's first stage: many sub-apertures a launch): tile t's references are of the
 * pulses in columns tile_first[t] + j, j < n_pulses (one receiver);
 * params (bp_ref_params_t): c, f0, fs, velocity v, half_extent, rho_max and bias (samples). */
#define REF_LANES 8
typedef double8 dv;
typedef struct {
    dv x, y, z;
} dv3;

inline dv3 v3_add(const dv3 a, const dv3 b) { return (dv3){a.x + b.x, a.y + b.y, a.z + b.z}; }
inline dv3 v3_sub(const dv3 a, const dv3 b) { return (dv3){a.x - b.x, a.y - b.y, a.z - b.z}; }
/* a + u s (contracted to fused multiply-adds as the scalar double3 expression is) */
inline dv3 v3_fma(const dv3 u, const dv s, const dv3 a) { return (dv3){a.x + u.x * s, a.y + u.y * s, a.z + u.z * s}; }
/* the products, then their sum in the order (x + y) + z, unfused (as dot() of double3 is built) */
inline dv v3_dot(const dv3 a, const dv3 b)
{
    const dv x = a.x * b.x, y = a.y * b.y, z = a.z * b.z;
    return (x + y) + z;
}

/* meet_time of each lane: the root of |d + w t| = c t, t > 0 */
inline dv meet_time(const dv3 d, const dv3 w, const double c)
{
    const dv a = c * c - v3_dot(w, w), b = v3_dot(d, w);
    return (b + sqrt(b * b + a * v3_dot(d, d))) / a;
}

#ifdef TILE_FIRST
#define TILE_FIRST_PARAM , __global const int *tile_first
#define FIRST_COLUMN(t) tile_first[t]
#else
#define TILE_FIRST_PARAM
#define FIRST_COLUMN(t) 0
#endif
#define ROW(f) vload8(0, pulse + (f) * stride + column)
#define ROW3(f) ((dv3){ROW(f), ROW((f) + 1), ROW((f) + 2)})
#define SPLAT3(a) ((dv3){(dv)((a)[0]), (dv)((a)[1]), (dv)((a)[2])})
#define X_ROUND_MAGIC 6755399441055744.0 /* 1.5 * 2^52: (x + M) - M = rint(x) for |x| < 2^51 */

__kernel void bp_refs(__global const double *centres, __global const double *pulse, const int stride,
                      const bp_ref_params_t params, const int n_pulses, const int n_chunks, const int n_items,
                      __global tile_ref_t *ref TILE_FIRST_PARAM)
{
    const int i = get_global_id(0);
    if (i >= n_items)  /* the launch is padded to whole work-groups */
        return;
    const int t = i / n_chunks, j0 = REF_LANES * (i - t * n_chunks), column = FIRST_COLUMN(t) + j0;
    const double c = params.c;
    const dv3 tx = ROW3(0), rx0 = ROW3(4), v_r = ROW3(7);
    const dv eta = ROW(3), t0 = ROW(10), offset = ROW(11);
    const dv3 v = SPLAT3(params.velocity), centre = SPLAT3(centres + 3 * t);
    const dv3 q_emit = v3_fma(v, eta, centre);
#ifdef STOP_AND_GO
    const dv3 q = q_emit, r = rx0;
    const dv t1 = sqrt(v3_dot(v3_sub(q, tx), v3_sub(q, tx))) / c, t2 = sqrt(v3_dot(v3_sub(r, q), v3_sub(r, q))) / c;
    const dv3 v_k = {(dv)0.0, (dv)0.0, (dv)0.0};  /* the legs see no motion */
#else
    const dv t1 = meet_time(v3_sub(q_emit, tx), v, c);
    const dv3 q = v3_fma(v, t1, q_emit), r_scatter = v3_fma(v_r, t1, rx0);
    const dv t2 = meet_time(v3_sub(r_scatter, q), v_r, c);
    const dv3 r = v3_fma(v_r, t2, r_scatter), v_k = v;
#endif
    const dv big_t = t1 + t2, k = (big_t - t0) * params.fs, cycles = params.f0 * big_t;
    const dv k_int = clamp(floor(k), -1073741824.0, 1073741824.0);
    const dv3 b = v3_sub(q, tx);
    const dv b1 = c * c * t1 - v3_dot(b, v_k), a1 = c * c - v3_dot(v_k, v_k);
    /* each field of the REF_LANES references as floats (ints) */
    const float8 bx = convert_float8(b.x), by = convert_float8(b.y), bz = convert_float8(b.z);
    const float8 f_b1 = convert_float8(b1), f_k1 = convert_float8(0.5 / b1), f_k2 = convert_float8(a1 / (b1 * b1));
#ifdef MOVING
    const int8 poly = (int8)0;
#else
    const int8 poly = -convert_int8(params.half_extent <= params.rho_max * c * t1);
#endif
    const int8 k_ref = convert_int8(k_int) - convert_int8(offset) - params.bias;
    const float8 k_frac = convert_float8(fmin(k - k_int, 0.99999994) + params.bias);
    const float8 f_cycles = convert_float8(cycles - ((cycles + X_ROUND_MAGIC) - X_ROUND_MAGIC));
    const float8 range1 = convert_float8(c * t1);
#if defined(MONO)
    const float8 wx = convert_float8(ROW(12)), wy = convert_float8(ROW(13)), wz = convert_float8(ROW(14));
    const float8 alpha = convert_float8(ROW(15));
    /* within the tile's row of n_pulses (TILE_FIRST: as a launch on the tile's own pulses gives it) */
    const int8 w_run = min(convert_int8(ROW(16)), n_pulses - 1 - j0 - (int8)(0, 1, 2, 3, 4, 5, 6, 7));
#elif !defined(SAME_LEGS)
    const dv3 cc = v3_sub(r, q);
    const float8 cx = convert_float8(cc.x), cy = convert_float8(cc.y), cz = convert_float8(cc.z);
    const float8 b2 = convert_float8(c * c * t2 - v3_dot(cc, v_r));
    const float8 vx = convert_float8(v_r.x), vy = convert_float8(v_r.y), vz = convert_float8(v_r.z);
    const float8 a2 = convert_float8(c * c - v3_dot(v_r, v_r));
#endif
    __global tile_ref_t *out = ref + (size_t)t * n_pulses + j0;
    const int lanes = min(REF_LANES, n_pulses - j0);
#if defined(MONO)
#define LEG2(l) o.w[0] = wx.s##l; o.w[1] = wy.s##l; o.w[2] = wz.s##l; o.alpha = alpha.s##l; o.w_run = w_run.s##l;
#elif !defined(SAME_LEGS)
#define LEG2(l)                                                                      \
    o.leg2[0] = cx.s##l; o.leg2[1] = cy.s##l; o.leg2[2] = cz.s##l; o.b2 = b2.s##l; \
    o.v_rx[0] = vx.s##l; o.v_rx[1] = vy.s##l; o.v_rx[2] = vz.s##l; o.a2 = a2.s##l;
#else
#define LEG2(l)
#endif
#define STORE(l)                                                                                   \
    if (l < lanes) {                                                                               \
        tile_ref_t o;                                                                              \
        o.leg1[0] = bx.s##l; o.leg1[1] = by.s##l; o.leg1[2] = bz.s##l;                             \
        o.b1 = f_b1.s##l; o.k1 = f_k1.s##l; o.k2 = f_k2.s##l; o.poly = poly.s##l;                  \
        o.k_ref = k_ref.s##l; o.k_frac = k_frac.s##l; o.cycles = f_cycles.s##l; o.range1 = range1.s##l; \
        LEG2(l)                                                                                    \
        out[l] = o;                                                                                \
    }
    STORE(0) STORE(1) STORE(2) STORE(3) STORE(4) STORE(5) STORE(6) STORE(7)
}
