/* What bp_tile (kernels/bp_tile.cl) and bp_block (kernels/bp_block.cl) share: double precision on,
 * common.h and interp.h, the types of the data, interpolation and sums, and SCATTER.
 *
 * Both: the range-compressed sample at the delay by linear interpolation of the (upsampled)
 * record (INTERP_LINEAR) or by the 8-tap Kaiser-windowed sinc of interp.h on the original
 * samples (INTERP_SINC8, taps from the nearest row of the table over the fractional offset); a
 * record reads as zero where the interpolator would need samples outside it; the phase rotation
 * exp(+j 2 pi f0 tau) from cycles reduced to a fraction (polynomial sin/cos, common.h);
 * accumulation in float (double with CLSAS_DOUBLE) over the launch's pulses, added once into
 * the double image at the end (blocked sum).
 */
#ifndef CLSAS_BP_COMMON_H
#define CLSAS_BP_COMMON_H
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#include "common.h"
#include "interp.h"

/* Data, interpolation and sums in float, or in double with CLSAS_DOUBLE (precision="double"). */
#ifdef CLSAS_DOUBLE
typedef double2 sample_t;
typedef double2 realv2_t;
typedef double4 realv4_t;
typedef double8 realv8;
typedef double16 realv16_t;
#define convert_realv8 convert_double8
#define SINC8_LANES sinc8_lanes_double
#define LOAD_R16 LOAD_D16
#define LOAD_R4 LOAD_D4
#else
typedef float2 sample_t;
typedef float2 realv2_t;
typedef float4 realv4_t;
typedef float8 realv8;
typedef float16 realv16_t;
#define convert_realv8 convert_float8
#define SINC8_LANES sinc8_lanes
#define LOAD_R16 LOAD_F16
#define LOAD_R4 LOAD_F4
#endif

/* SCATTER (bp_tile and bp_block in direct back-projection, clsas/image/backprojection/launcher.py): slot m's sum goes to
 * image[index[m]], its pixel in the grid's order (-1: padding, dropped), not to image[m]. */
#ifdef SCATTER
#define SCATTER_PARAM , __global const int *index
#else
#define SCATTER_PARAM
#endif

#endif /* CLSAS_BP_COMMON_H */
