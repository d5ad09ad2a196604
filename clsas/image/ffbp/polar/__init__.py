"""Local polar grids of fast factorised back-projection and the rule that samples them.

A sub-aperture (a block of consecutive pulses, every selected receiver) has a *frame*: its
centre C (the mean of its phase centres, the midpoints of transmitter and receiver), its axis
u (the unit chord of the transmitter's track over the block) and the *reference plane* of the
image (the grid's plane; for a 3-D point set the plane fitted to it). A point X has the polar
coordinates

    r = |X - C|  (m),    v = u . (X - C) / r  (the sine of the angle off broadside),

and the polar sample (r, v) stands for the point of the reference plane at that range and
angle, on the scene's side of the axis:

    X(r, v) = C + r v u + r sqrt(1 - v^2) (cos phi e1 + sin phi e2),

e2 the plane normal's part perpendicular to u, e1 = e2 x u turned towards the scene, and
sin phi = (m . (X0 - C) - r v m . u) / (r sqrt(1 - v^2) |m_perp|) from m . X = m . X0 (clipped
to [-1, 1] where the circle of (r, v) misses the plane: those samples serve no pixel).
Pixels of the plane are therefore represented exactly; a pixel off the plane is read at its
own (r, v), i.e. rotated about the axis into the plane, which is exact for phase centres on
the axis (a straight track; the delay depends on r and v alone) and approximate otherwise.

Ragged rows (the wedge). A rectangular (r, v) box around a scene wider along track than its
nearest range holds samples no pixel needs: at a sine v the scene's ranges span only
[r_near(v), r_far(v)] (a rectangle's along-track ends are the lines r v = const), so about a
quarter of a wide scene's box lies outside its wedge. Each row j keeps only its *span* of range
samples [lo_j, hi_j) (:meth:`Extent.spans`): the ranges of the scene's points whose sines lie
within the box's own padding in sine of the row's, widened by the box's padding in range, so
every sample within the box's padding distance of the scene, in both coordinates, is kept as the
box keeps it; the others are not computed and read as zero. The interpolator at any point that
needs exact values (a pixel, or a parent sample within the padding of the scene) reads only
samples within taps / 2 of it, inside the spans, so the image is the box's: the merge kernel and
the leaves skip the rest (tests/test_ffbp.py compares the two on a speckle scene).

Sampling rule (the error model). After demodulation by exp(-j 4 pi f0 r / c) a sub-aperture's
image is band-limited in r and in v; its band follows from the delay of a phase centre at
axial offset a in [-L, L] (L the sub-aperture's half-length, plus its largest offset off the
axis): d(r, v, a) = sqrt(r^2 - 2 r a v + a^2). At frequency f the phase 2 pi f 2 d / c has

    dd/dv = -r a / d,               |2 f dd/dv / c| <= W_v = 2 f_max max|r a / d| / c   cycles per unit v,
    dd/dr = (r - a v) / d,          2 f dd/dr / c - 2 f0 / c in [-W_r, W_r],
                                    W_r = B / c + 2 f_max max(1 - (r - a v) / d) / c     cycles per m,

the maxima taken over a = +-L, v over the grid's span and r = r_min (the nearest scene range;
both bounds fall with r). The first term of W_r is the pulse band (f in f0 +- B/2), the second
the range curvature of a long sub-aperture (its polar image is not band-limited to B alone).
Samples every dr = 1 / (2 W_r rho) and dv = 1 / (2 W_v rho) oversample the band by rho (dv at most
1 / pad, pad the grid's padding in samples: a one-pulse monostatic sub-aperture has W_v = 0, and a
finer step only oversamples more); a
T-tap windowed sinc (Knab's window for that oversampling, :func:`clsas.interp.tap_table`)
then interpolates a band-edge component with an error e_T(rho) (amplitude and phase, relative;
tabulated by :func:`interpolation_error`). A merge tree of S interpolation stages makes 2 S
interpolation errors (range and angle at each stage): rho is
the smallest oversampling with e_T(rho) <= tolerance / (2 S), so that each sub-aperture's
contribution to a pixel keeps its phase and relative amplitude error below ``tolerance`` up to
the edge of the scene (the band edge is the component from the scene's edge). The bound adds
the errors linearly: a band-edge component's interpolation error has the same sign at every
stage (an amplitude loss), so they do not add in power (an rss rule lets a deep tree's error
exceed its tolerance).
"""

from .grids import RHO_STEPS, Plane, PolarGrid, interpolation_error, oversampling, points_at, points_of
from .sampling import (CHUNK_NODES, Extent, aperture_sines, aperture_windows, axis_tilt, extents, sample_grids,
                       within_aperture)
from .scene import Scene, frame_axes

__all__ = ["CHUNK_NODES", "RHO_STEPS", "Extent", "Plane", "PolarGrid", "Scene", "aperture_sines", "aperture_windows",
           "axis_tilt", "extents", "frame_axes", "interpolation_error", "oversampling", "points_at", "points_of",
           "sample_grids", "within_aperture"]
