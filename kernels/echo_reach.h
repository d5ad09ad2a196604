/* Where a path's echo lies in its record, shared by kernels/echo_paths.cl (UNHEARD) and
 * kernels/echo_accumulate.cl (the samples a path reaches). Needs echo_path_t declared (the launcher's
 * records preamble, clsas/synthesis/echo/records.py) and the defines of those files. */
#ifndef CLSAS_ECHO_REACH_H
#define CLSAS_ECHO_REACH_H

#define UNHEARD (1 << 30)  /* the start sample of a path that carries no echo (a facet out of the beam) */

#ifdef COMPRESSED
/* The compressed echo's centre shift delta = lin / (2 chirp) (the range-Doppler coupling,
 * clsas/synthesis/echo/compressed.py); 0 for plain paths. */
inline real_t compressed_shift(const echo_path_t v)
{
#ifdef EXTENDED
    return v.lin / ((real_t)2 * v.chirp);
#else
    return (real_t)0;
#endif
}
#endif

/* The first and last samples path v reaches (start - shift + frac + [lo, hi], rounded outwards;
 * plain paths: |d| <= half_len; compressed: the taps -COMPRESSED .. COMPRESSED + 1 about its
 * shifted centre's sample). */
inline int2 path_reach(const echo_path_t v, real_t half_len)
{
#ifdef COMPRESSED
    const real_t u = v.frac - compressed_shift(v);
    int iu = convert_int(u);
    iu -= (u < (real_t)iu);
    return (int2)(v.start + iu - COMPRESSED, v.start + iu + COMPRESSED + 1);
#else
#ifdef EXTENDED
    real_t a = v.frac + v.lo, b = v.frac + v.hi;
#else
    real_t a = v.frac - half_len, b = v.frac + half_len;
#endif
#ifdef GRID
    a -= (real_t)(TAPER + 1);  /* the grid route's tails past the pulse's edges */
    b += (real_t)(TAPER + 1);
#endif
    int ia = convert_int(a), ib = convert_int(b);
    ia -= (a < (real_t)ia);  /* floor */
    ib += (b > (real_t)ib);  /* ceil */
    return (int2)(v.start + ia, v.start + ib);
#endif
}

#endif
