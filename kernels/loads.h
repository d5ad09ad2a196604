/* Unaligned vector loads and stores (OpenCL C 1.2).
 *
 * PoCL builds vloadN out of 8-byte pieces (eight loads and inserts for a vload16 of floats);
 * through a vector type whose alignment is lowered to its element's, clang emits one unaligned
 * vector load instead (faster: bench/bench_stolt.py). Other compilers get vloadN.
 * LOAD_F16(p) etc. read the vector at p (a __global float / double pointer); STORE_F16(v, p)
 * writes one (vstore16 is split into three stores).
 */
#ifndef CLSAS_LOADS_H
#define CLSAS_LOADS_H

#ifdef __clang__
typedef float16 clsas_float16_u __attribute__((aligned(4)));
typedef float8 clsas_float8_u __attribute__((aligned(4)));
typedef float4 clsas_float4_u __attribute__((aligned(4)));
#define LOAD_F16(p) (*(__global const clsas_float16_u *)(p))
#define LOAD_F8(p) (*(__global const clsas_float8_u *)(p))
#define LOAD_F4(p) (*(__global const clsas_float4_u *)(p))
#define STORE_F16(v, p) (*(__global clsas_float16_u *)(p) = (v))
#ifdef cl_khr_fp64
typedef double16 clsas_double16_u __attribute__((aligned(8)));
typedef double8 clsas_double8_u __attribute__((aligned(8)));
typedef double4 clsas_double4_u __attribute__((aligned(8)));
#define LOAD_D16(p) (*(__global const clsas_double16_u *)(p))
#define LOAD_D8(p) (*(__global const clsas_double8_u *)(p))
#define LOAD_D4(p) (*(__global const clsas_double4_u *)(p))
#define STORE_D8(v, p) (*(__global clsas_double8_u *)(p) = (v))
#endif
#else
#define LOAD_F16(p) vload16(0, (p))
#define LOAD_F8(p) vload8(0, (p))
#define LOAD_F4(p) vload4(0, (p))
#define STORE_F16(v, p) vstore16((v), 0, (p))
#define LOAD_D16(p) vload16(0, (p))
#define LOAD_D8(p) vload8(0, (p))
#define LOAD_D4(p) vload4(0, (p))
#define STORE_D8(v, p) vstore8((v), 0, (p))
#endif

#endif /* CLSAS_LOADS_H */
