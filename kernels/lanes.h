/* Complex sums of eight lanes at once (OpenCL C 1.2, float; double where the device has fp64).
 *
 * Each p_l (float16, or double16) holds eight complex partial products of lane l (re, im
 * interleaved), e.g. eight samples times eight interpolation taps. csum8 (csum8_double) returns
 * the eight lanes' sums (re, im interleaved) by a tree across lanes: halves of two lanes, then
 * quarters, then pairs (three levels of two-source permutes and adds), instead of a horizontal
 * sum per lane (three extract-and-add levels for every lane, each of them a single lane). Lane
 * l's complex products c_0 .. c_7 are summed as ((c_0 + c_4) + (c_2 + c_6)) + ((c_1 + c_5) +
 * (c_3 + c_7)).
 */
#ifndef CLSAS_LANES_H
#define CLSAS_LANES_H

#define CLSAS_FOLD1(T, A, B) ((T)((A).lo, (B).lo) + (T)((A).hi, (B).hi))
#define CLSAS_FOLD2(T, A, B) ((T)((A).s012389ab, (B).s012389ab) + (T)((A).s4567cdef, (B).s4567cdef))
#define CLSAS_FOLD3(T, A, B) ((T)((A).s014589cd, (B).s014589cd) + (T)((A).s2367abef, (B).s2367abef))
#define CLSAS_CSUM8(NAME, T)                                                                        \
    inline T NAME(const T p0, const T p1, const T p2, const T p3, const T p4, const T p5, const T p6,  \
                  const T p7)                                                                       \
    {                                                                                               \
        return CLSAS_FOLD3(T, CLSAS_FOLD2(T, CLSAS_FOLD1(T, p0, p1), CLSAS_FOLD1(T, p2, p3)),       \
                           CLSAS_FOLD2(T, CLSAS_FOLD1(T, p4, p5), CLSAS_FOLD1(T, p6, p7)));         \
    }

CLSAS_CSUM8(csum8, float16)
#ifdef cl_khr_fp64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
CLSAS_CSUM8(csum8_double, double16)
#endif

#endif /* CLSAS_LANES_H */
