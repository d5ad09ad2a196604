/* Seafloor path weights before shadows: the beam's reach, the facing tests and the sediment's
 * law at each path's bistatic grazing angle; and a flag on the paths a shadow may darken (the
 * host casts their rays).
 *
 * NumPy twin: clsas/synthesis/occlusion/seafloor.py (SeafloorPaths._unshadowed_numpy, the maths
 * in float64); the launcher is in the same module (SeafloorPaths._unshadowed_opencl).
 *
 * One work-item: 16 consecutive facets (float16 lanes: PoCL vectorises explicit vector types,
 * not loops across work-items, docs/POCL_NOTES) at pulse p; global size (span16 / 16, P) over
 * the facets first16 .. first16 + span16 (those the beam can reach at these pulses: the facets
 * are sorted along track), a loop over the receivers. Facets are structure-of-arrays (x, y, z,
 * normal x, y, z), padded to a multiple of 16 with zero normals (never lit). Positions are
 * float32 relative to an origin near the facets (1e-5 m at 100 m: they place a ray and a
 * grazing angle). stations[p]: the transmitter at emission, then for each receiver its position
 * at emission and its velocity (float4 .xyz).
 * The launch is padded to whole work-groups along the facets (clsas.opencl.work_groups).
 * spheres[p]: the mesh targets' bounding spheres (centre .xyz, radius .w) at that pulse.
 * out (H, P, span16), flag (P, span16).
 */

#define LANES 16
typedef float16 floatv;
typedef int16 intv;

inline floatv meet_time(const floatv dx, const floatv dy, const floatv dz, const float4 w, const float c)
{
    /* the t > 0 with |d + w t| = c t (clsas.geometry.meet_time) */
    const float a = c * c - (w.x * w.x + w.y * w.y + w.z * w.z);
    const floatv b = dx * w.x + dy * w.y + dz * w.z;
    return (b + sqrt(b * b + a * (dx * dx + dy * dy + dz * dz))) / a;
}

inline intv may_block(const floatv qx, const floatv qy, const floatv qz, const floatv dx, const floatv dy,
                      const floatv dz, const float slope, __global const float4 *spheres, const int n_spheres)
{
    /* the leg q -> q + d climbs slower than the floor's steepest slope, or passes a sphere */
    intv hit = dz < slope * sqrt(dx * dx + dy * dy);
    const floatv dd = dx * dx + dy * dy + dz * dz;
    for (int k = 0; k < n_spheres; ++k) {
        const float4 s = spheres[k];
        const floatv cx = s.x - qx, cy = s.y - qy, cz = s.z - qz;
        const floatv t = clamp((cx * dx + cy * dy + cz * dz) / dd, 0.0f, 1.0f);
        const floatv gx = cx - t * dx, gy = cy - t * dy, gz = cz - t * dz;
        hit |= gx * gx + gy * gy + gz * gz < s.w * s.w;
    }
    return hit;
}

__kernel void seafloor_weights(__global const float *px, __global const float *py, __global const float *pz,
                               __global const float *nx, __global const float *ny, __global const float *nz,
                               __global const float4 *stations, __global const float4 *spheres,
                               __global const float *law, const int n_law, const float reach,
                               const float lift, const float c, const float slope, const int first16,
                               const int span16, const int n_rx, const int n_spheres, __global float *out,
                               __global uchar *flag)
{
    const int item = get_global_id(0);
    if (item >= span16 / LANES) return;  /* the launch is padded to whole work-groups */
    const int g = first16 / LANES + item;
    const int p = get_global_id(1);
    const size_t n_pulses = get_global_size(1);
    const floatv x = vload16(g, px), y = vload16(g, py), z = vload16(g, pz);
    const floatv ux = vload16(g, nx), uy = vload16(g, ny), uz = vload16(g, nz);
    __global const float4 *st = stations + (size_t)p * (1 + 2 * n_rx);
    __global const float4 *sph = spheres + (size_t)p * n_spheres;
    const float4 tx = st[0];
    const floatv ex = tx.x - x, ey = tx.y - y, ez = tx.z - z;
    const intv reached = fabs(ey) <= reach * sqrt(ex * ex + ez * ez);
    const floatv qx = x + lift * ux, qy = y + lift * uy, qz = z + lift * uz;
    const floatv dx = tx.x - qx, dy = tx.y - qy, dz = tx.z - qz;
    const floatv r1 = sqrt(dx * dx + dy * dy + dz * dz);
    const floatv tx_x = dx / r1, tx_y = dy / r1, tx_z = dz / r1;
    const intv lit = reached & (ux * tx_x + uy * tx_y + uz * tx_z > 0.0f);
    intv flagged = lit & may_block(qx, qy, qz, dx, dy, dz, slope, sph, n_spheres);
    const floatv t1 = r1 / c;
    const float top = (float)(n_law - 1);
    for (int h = 0; h < n_rx; ++h) {
        const float4 r0 = st[1 + 2 * h], w = st[2 + 2 * h];
        floatv rx = r0.x + w.x * t1 - qx, ry = r0.y + w.y * t1 - qy, rz = r0.z + w.z * t1 - qz;
        const floatv t2 = meet_time(rx, ry, rz, w, c);
        rx += w.x * t2;
        ry += w.y * t2;
        rz += w.z * t2;
        const floatv r2 = sqrt(rx * rx + ry * ry + rz * rz);
        const floatv bx = tx_x + rx / r2, by = tx_y + ry / r2, bz = tx_z + rz / r2;
        const floatv s = (ux * bx + uy * by + uz * bz) / sqrt(bx * bx + by * by + bz * bz);
        const intv heard = lit & (s > 0.0f) & (ux * rx + uy * ry + uz * rz > 0.0f);
        const floatv u = clamp(s, 0.0f, 1.0f) * top;
        const intv k = min(convert_int16(u), n_law - 2);
        const floatv f = u - convert_float16(k);
        int at[LANES];
        float lo[LANES], hi[LANES];
        vstore16(k, 0, at);
        for (int j = 0; j < LANES; ++j) {  /* the table's gathers, lane by lane */
            lo[j] = law[at[j]];
            hi[j] = law[at[j] + 1];
        }
        const floatv a = vload16(0, lo), b = vload16(0, hi);
        vstore16(select((floatv)(0.0f), a + f * (b - a), heard), item, out + ((size_t)h * n_pulses + p) * span16);
        flagged |= heard & may_block(qx, qy, qz, rx, ry, rz, slope, sph, n_spheres);
    }
    vstore16(convert_uchar16(flagged & 1), item, flag + (size_t)p * span16);
}
