/* bp_tile's references (kernels/bp_tile.cl) on the device: TileKernel.references_on_device
 * (clsas/image/backprojection/tile_kernel.py; its NumPy twin TileKernel.references); the records
 * tile_ref_t, bp_ref_pulse_t and bp_ref_params_t come with TileKernel's preamble. Defines: MOVING,
 * STOP_AND_GO, MONO or SAME_LEGS, TILE_FIRST. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

/* bp_tile's references (tile_ref_t, TileKernel.reference_dtype) computed on the device, in double,
 * for pixels moving uniformly at v (or at rest) and a receiver of two position nodes (uniform
 * motion) or with stop-and-go: the closed forms of clsas/geometry.py's legs (meet_time), then the
 * record's fields as TileKernel.references (its NumPy twin) makes them. Work-item i: tile
 * t = i / n_pulses, pulse p = i % n_pulses of the job; ref[i] its reference.
 * pulse[p] (bp_ref_pulse_t): tx, eta, rx0 = the receiver at emission, v_rx = its velocity, t0 =
 * its window start and offset = the first sample of its records (samples at fs from t0): the
 * pulses of several receivers in one launch (clsas/image/backprojection/launcher.py: receiver
 * after receiver, each over the same pulses); centres[t]: the tile's reference point at t = 0;
 * TILE_FIRST (ffbp's first stage: many sub-apertures a launch): tile t's references are of
 * pulses pulse[tile_first[t] + j], j < n_pulses (one receiver), work-item i = t n_pulses + j;
 * params (bp_ref_params_t): c, f0, fs, velocity v, half_extent, rho_max and bias (samples). */
inline double meet_time(const double3 d, const double3 w, const double c)
{
    const double a = c * c - dot(w, w), b = dot(d, w);
    return (b + sqrt(b * b + a * dot(d, d))) / a;
}

#ifdef TILE_FIRST
#define TILE_FIRST_PARAM , __global const int *tile_first
#define PULSE_OF(i) (tile_first[(i) / n_pulses] + (i) % n_pulses)
#else
#define TILE_FIRST_PARAM
#define PULSE_OF(i) ((i) % n_pulses)
#endif

__kernel void bp_refs(__global const double *centres, __global const bp_ref_pulse_t *pulse, const bp_ref_params_t params,
                      const int n_pulses, const int n_refs, __global tile_ref_t *ref TILE_FIRST_PARAM)
{
    const int i = get_global_id(0);
    if (i >= n_refs)  /* the launch is padded to whole work-groups */
        return;
    const bp_ref_pulse_t pl = pulse[PULSE_OF(i)];
    const double c = params.c;
    const double3 v = vload3(0, params.velocity), tx = vload3(0, pl.tx), rx0 = vload3(0, pl.rx0);
    const double3 v_r = vload3(0, pl.v_rx), q_emit = vload3(i / n_pulses, centres) + v * pl.eta;
#ifdef STOP_AND_GO
    const double3 q = q_emit, r = rx0;
    const double t1 = length(q - tx) / c, t2 = length(r - q) / c;
    const double3 v_k = (double3)(0.0);  /* the legs see no motion */
#else
    const double t1 = meet_time(q_emit - tx, v, c);
    const double3 q = q_emit + v * t1, r_scatter = rx0 + v_r * t1;
    const double t2 = meet_time(r_scatter - q, v_r, c);
    const double3 r = r_scatter + v_r * t2, v_k = v;
#endif
    const double big_t = t1 + t2, k = (big_t - pl.t0) * params.fs, cycles = params.f0 * big_t;
    const double k_int = clamp(floor(k), -1073741824.0, 1073741824.0);
    const double3 b = q - tx;
    const double b1 = c * c * t1 - dot(b, v_k), a1 = c * c - dot(v_k, v_k);
    tile_ref_t o;
    vstore3(convert_float3(b), 0, o.leg1);
    o.b1 = (float)b1;
    o.k1 = (float)(0.5 / b1);
    o.k2 = (float)(a1 / (b1 * b1));
#ifdef MOVING
    o.poly = 0;
#else
    o.poly = params.half_extent <= params.rho_max * c * t1;
#endif
    o.k_ref = (int)k_int - pl.offset - params.bias;
    o.k_frac = (float)(fmin(k - k_int, 0.99999994) + params.bias);
    o.cycles = (float)(cycles - rint(cycles));
    o.range1 = (float)(c * t1);
#if defined(MONO)
    const double a2 = c * c - dot(v_r, v_r);
    vstore3(convert_float3(2.0 * v_r / a2), 0, o.w);
    o.alpha = (float)(2.0 * c * c / a2);
#elif !defined(SAME_LEGS)
    const double3 cc = r - q;
    vstore3(convert_float3(cc), 0, o.leg2);
    o.b2 = (float)(c * c * t2 - dot(cc, v_r));
    vstore3(convert_float3(v_r), 0, o.v_rx);
    o.a2 = (float)(c * c - dot(v_r, v_r));
#endif
    ref[i] = o;
}
