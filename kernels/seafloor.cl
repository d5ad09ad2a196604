/* Seafloor path weights before shadows: the beam's reach, the facing tests and the sediment's
 * law at each path's bistatic grazing angle; and a flag on the paths a shadow may darken (the
 * host casts their rays).
 *
 * NumPy twin: clsas/synthesis/occlusion/seafloor.py (SeafloorPaths._unshadowed_numpy, the maths
 * in float64); the launcher is in the same module (SeafloorPaths._unshadowed_opencl).
 *
 * One work-item: facet i at pulse p (global size (n, P)); a loop over the receivers. Positions
 * are float32 relative to an origin near the facets (1e-5 m at 100 m: they place a ray and a
 * grazing angle). stations[p]: the transmitter at emission, then for each receiver its position
 * at emission and its velocity (float4 .xyz). spheres[p]: the mesh targets' bounding spheres
 * (centre .xyz, radius .w) at that pulse.
 */

inline float meet_time(const float3 d, const float3 w, const float c)
{
    /* the t > 0 with |d + w t| = c t (clsas.geometry.meet_time) */
    const float a = c * c - dot(w, w);
    const float b = dot(d, w);
    return (b + sqrt(b * b + a * dot(d, d))) / a;
}

inline int may_block(const float3 q, const float3 d, const float slope, __global const float4 *spheres,
                     const int n_spheres)
{
    /* the leg q -> q + d climbs slower than the floor's steepest slope, or passes a sphere */
    if (d.z < slope * sqrt(d.x * d.x + d.y * d.y))
        return 1;
    for (int k = 0; k < n_spheres; ++k) {
        const float3 cq = spheres[k].xyz - q;
        const float t = clamp(dot(cq, d) / dot(d, d), 0.0f, 1.0f);
        const float3 gap = cq - t * d;
        if (dot(gap, gap) < spheres[k].w * spheres[k].w)
            return 1;
    }
    return 0;
}

__kernel void seafloor_weights(__global const float4 *pos, __global const float4 *normal,
                               __global const float4 *stations, __global const float4 *spheres,
                               __global const float *law, const int n_law, const float reach,
                               const float lift, const float c, const float slope, const int n,
                               const int n_rx, const int n_spheres, __global float *out,
                               __global uchar *flag)
{
    const int i = get_global_id(0);
    const int p = get_global_id(1);
    if (i >= n)
        return;
    const size_t n_pulses = get_global_size(1);
    const size_t at = (size_t)p * n + i;
    const float3 x = pos[i].xyz;
    const float3 nu = normal[i].xyz;
    __global const float4 *st = stations + (size_t)p * (1 + 2 * n_rx);
    __global const float4 *sph = spheres + (size_t)p * n_spheres;
    const float3 tx = st[0].xyz;
    const float3 d0 = tx - x;
    const int reached = fabs(d0.y) <= reach * sqrt(d0.x * d0.x + d0.z * d0.z);
    const float3 q = x + lift * nu;
    const float3 d_tx = tx - q;
    const float r1 = length(d_tx);
    const float3 u_tx = d_tx / r1;
    const int lit = reached && dot(nu, u_tx) > 0.0f;
    int flagged = lit ? may_block(q, d_tx, slope, sph, n_spheres) : 0;
    const float t1 = r1 / c;
    for (int h = 0; h < n_rx; ++h) {
        float weight = 0.0f;
        if (lit) {
            const float3 w = st[2 + 2 * h].xyz;
            float3 d = st[1 + 2 * h].xyz + w * t1 - q;
            d += w * meet_time(d, w, c);
            const float3 b = u_tx + d / length(d);
            const float s = dot(nu, b) / length(b);
            if (s > 0.0f && dot(nu, d) > 0.0f) {
                const float u = min(s, 1.0f) * (float)(n_law - 1);
                const int k = min((int)u, n_law - 2);
                weight = law[k] + (u - (float)k) * (law[k + 1] - law[k]);
                flagged |= may_block(q, d, slope, sph, n_spheres);
            }
        }
        out[(size_t)h * n_pulses * n + at] = weight;
    }
    flag[at] = (uchar)flagged;
}
