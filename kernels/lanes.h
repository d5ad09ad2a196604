/* Complex sums of eight lanes at once (OpenCL C 1.2, float).
 *
 * Each p_l (float16) holds eight complex partial products of lane l (re, im interleaved), e.g.
 * eight samples times eight interpolation taps. csum8 returns the eight lanes' sums (re, im
 * interleaved) by a tree across lanes: halves of two lanes, then quarters, then pairs (three
 * levels of two-source permutes and adds), instead of a horizontal sum per lane (three
 * extract-and-add levels for every lane, each of them a single lane). On PoCL / AVX-512 this
 * took the 4096^2 8-tap Stolt map from 41 to 33 ms.
 */
#ifndef CLSAS_LANES_H
#define CLSAS_LANES_H

#define CLSAS_FOLD1(A, B) ((float16)((A).lo, (B).lo) + (float16)((A).hi, (B).hi))
#define CLSAS_FOLD2(A, B) ((float16)((A).s012389ab, (B).s012389ab) + (float16)((A).s4567cdef, (B).s4567cdef))
#define CLSAS_FOLD3(A, B) ((float16)((A).s014589cd, (B).s014589cd) + (float16)((A).s2367abef, (B).s2367abef))

inline float16 csum8(const float16 p0, const float16 p1, const float16 p2, const float16 p3,
                     const float16 p4, const float16 p5, const float16 p6, const float16 p7)
{
    return CLSAS_FOLD3(CLSAS_FOLD2(CLSAS_FOLD1(p0, p1), CLSAS_FOLD1(p2, p3)),
                       CLSAS_FOLD2(CLSAS_FOLD1(p4, p5), CLSAS_FOLD1(p6, p7)));
}

#endif /* CLSAS_LANES_H */
