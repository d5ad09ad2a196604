/* bp_tile's pixel fields, the image put in the grid's order, and two lanes' sums added: the small
 * kernels of clsas/image/backprojection/ (tile_kernel.TileKernel.fields, launcher.py) around bp_tile
 * (kernels/bp_tile.cl); bp_pixels_t and ROWS come with TileKernel's preamble and defines. */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

/* bp_tile's pixel fields (bp_pixels_t) of a grid's tiles (clsas/image/backprojection/tiles.py):
 * work-item g fills fields[g], row g of sixteen slots, whose pixels are index[16 g + lane] among
 * positions (x, y, z, m; -1: padding, which gets its tile's reference point), of work-item
 * g / ROWS's tile tile_of[g / ROWS] with reference point centres[tile]: delta = pixel - centre
 * (rounded to float after the subtraction in double), dd = |delta|^2 and (MOVING) dv = delta . v. */
__kernel void bp_fields(__global const double *positions, __global const int *index, __global const int *tile_of,
                        __global const double *centres, const double vx, const double vy, const double vz,
                        const int n_rows, __global bp_pixels_t *fields)
{
    const int g = get_global_id(0);
    if (g >= n_rows)  /* the launch is padded to whole work-groups */
        return;
    const double3 centre = vload3(tile_of[g / ROWS], centres);
    __global bp_pixels_t *o = fields + g;
    for (int l = 0; l < 16; ++l) {
        const int m = index[16 * g + l];
        const double3 d = (m >= 0 ? vload3(m, positions) : centre) - centre;
        o->dx[l] = (float)d.x;
        o->dy[l] = (float)d.y;
        o->dz[l] = (float)d.z;
        o->dd[l] = (float)dot(d, d);
#ifdef MOVING
        o->dv[l] = (float)(d.x * vx + d.y * vy + d.z * vz);
#endif
    }
}

/* The image in the grid's order (clsas/image/backprojection/launcher.py, a grid of one chunk): pixel
 * m's sum, its slot slot_of[m]'s double2 in sums, rounded once to float2 (round to nearest even, as
 * numpy's astype(complex64); past float's range: inf). Work-item g orders pixels run g .. run (g + 1) - 1
 * and writes seen[g]: bit 1 when one of them is not zero, bit 2 when one is not finite (the call's
 * checks of the image, without another pass over it on the host). */
__kernel void bp_order(__global const double2 *sums, __global const int *slot_of, const int n, const int run,
                       __global float2 *out, __global int *seen)
{
    const int g = get_global_id(0), first = run * g;
    if (first >= n)  /* the launch is padded to whole work-groups */
        return;
    const int stop = min(first + run, n);
    int flags = 0;
    for (int m = first; m < stop; ++m) {
        const float2 v = convert_float2(sums[slot_of[m]]);
        out[m] = v;
        flags |= (v.x != 0.0f || v.y != 0.0f) | ((!isfinite(v.x) || !isfinite(v.y)) << 1);
    }
    seen[g] = flags;
}

/* The second lane's slot sums (clsas/image/backprojection/launcher.py, _Chunk.lane: bp_tile
 * launches of every other job, run on a second queue) added into the first lane's */
__kernel void bp_add_sums(__global double2 *sums, __global const double2 *other, const int n)
{
    const int m = get_global_id(0);
    if (m < n)  /* the launch is padded to whole work-groups */
        sums[m] += other[m];
}
