"""DPCA micronavigation: surge, sway and yaw between consecutive pings from the echoes of
overlapping phase centres (Heremans, Dupont & Acheroy 2009, section 5, eqs. 50-70), the
trajectory they integrate to (eqs. 71-73), and the motion compensation (eqs. 74-75: per
hydrophone at broadside, track.compensate; over the whole beam on the interleaved
monostatic-equivalent record for the frequency-domain imagers, record.compensate_record).

Geometry (clsas axes: y along track, x across track towards the imaged side)
-----------------------------------------------------------------------------
The phase centre of hydrophone h is midway between the transmitter and h: along-track offset
o_h / 2 from the transmitter, spacing Delta_PC = d / 2 for hydrophones d apart. Between two
pings the platform advances D = v PRT; for D = (H - n) Delta_PC (eq. 50) the phase centres of
hydrophones j = i + s at ping p coincide with those of hydrophones i at ping p + 1, with
s = D / Delta_PC (the nominal pairing, s = 7 for Heremans' 15-hydrophone array). The
couples of x-lag l are (j = i + s + l at ping p, i at ping p + 1) (section 5.3, Fig. 14); clsas
uses the same H - s - lags couples i = 0 .. H - s - lags - 1 at every x-lag (the paper uses all
couples a lag allows, 6, 7, 8, 7, 6), so the beam peaks of the lags compare like with like.

What each couple sees
---------------------
Two coinciding phase centres see the same scatterers over the same two-way paths, so their
range-compressed echoes f (ping p) and g (ping p + 1) differ only by the motion between the
pings. With the ping-(p + 1) echo delayed by dt_n relative to ping p at couple n,
g(t) = f(t - dt_n) exp(-j 2 pi f0 dt_n) at baseband, and the normalised cross-correlation of
eq. (51), c_n[m] = sum_k f[k + m] g*[k] / sqrt(sum |f|^2 sum |g|^2), peaks at m = -dt_n fs
with phase +2 pi f0 dt_n. A sway gamma (the phase centres moved by gamma along +x, towards
the scene) shortens both legs: dt = -2 gamma / c for every couple. A yaw xi (rotation about
+z, clsas's Platform.yaw) moves a phase centre at along-track position u by -u xi along x:
dt_n = 2 u_n xi / c, a delay that grows linearly along the couples.

Beamforming over the couples (eqs. 52-65)
-----------------------------------------
A linear delay across the couples is a plane wave arriving at look angle theta: eq. (64)
steers the couples' correlations with phase 2 pi f0 (2 u_n sin theta) / c and sums them,
V(theta, m) = (1/N) sum_n c_n[m] exp(-j 4 pi f0 u_n sin theta / c). The best beam (the
(theta, m) of the largest |V|, refined by the three-point parabola of eq. 67 in m and in theta)
gives the yaw xi = sin theta and the delay. The delay is taken to a fraction of the carrier
period from the phase of V at the best beam, resolved against the envelope's parabolic peak:
dt = (arg V + 2 pi k) / (2 pi f0) with the integer k that lands nearest -m_peak / fs. Then
sway gamma = -c dt / 2 (eq. 69, with clsas's sign of x) and yaw xi = sin theta (eq. 70).
The parabola through three grid angles reads the peak short of the beam's (a beam is not a
parabola over a grid step: 0.3-0.4 % of the yaw at Heremans' geometry, the same sign every pair,
an error in the heading proportional to the heading's excursion); the beam is formed again at
the vertex and a quarter step either side and the parabola through those taken (its error
shrinks as the step squared).

Eqs. (69)-(70) hold in the plane of the track. Over a seafloor h below it, a scatterer at slant
range r, ground range rho and ground azimuth phi is seen along the line of sight l, and a
horizontal move across the track of the phase centres (gamma, or -u xi under a yaw) changes
the two-way path by -2 gamma (x . l), x . l = rho cos(phi) / r = sqrt(a^2 - sin^2 theta) with
a = rho / r the depression's cosine: the delays read gamma and xi times the block's mean
x . l (geometry.across_cosine: sqrt(a^2 - <sin^2 theta>), the same moments as the phase-centre
correction below), and each block's sway and yaw are divided by it. At Heremans' 15 m over
88-112 m that is 0.986-0.991: left in, the yaw read short by it and the parabola's part (a
heading error proportional to the heading's excursion, most of the reproduction's heading error:
bench/bench_dpca.py --pooling) and the sway short by it. Without the
seafloor's extent (``extent=None``, recorded data) the seafloor is taken at the track's depth
(a = 1: only the look angle's part, 1 - <sin^2 theta> / 2).

Two passes. Pass 1 scans t-lags -t_lags..t_lags on the records as they are. A fractional-
sample misalignment of f and g makes the correlation's phase at the integer t-lag depend on
the speckle, differently at every couple: yaw noise that grows with the sway between the pings
(tests/test_dpca.py). Pass 2 advances ping p + 1's envelope (not its carrier phase) by the
pair's pass-1 delay and scans +-FINE_T_LAGS again, at the x-lags nearest for some block, with
every couple each allows (8 at x-lag 0 where pass 1 compares 6 at every lag: a longer baseline
for the yaw; the delay is referred back to the common couples' centre): yaw and sway come from
it. Both passes take the delays out of the envelope inside the correlation
(correlate.correlations, ``delay=``: a band-limited fractional shift of the zero-padded
blocks), per couple and block: the pair's delay and the couple's phase-centre error (below).

Surge (eq. 68): the beam peak's magnitude is largest for the x-lag whose couples coincide;
the fractional lag B comes from the best lag and its neighbours through the coherence the
beam predicts for a displaced pair of phase centres (geometry.xlag_offset: the Fourier
transform of the two-way power pattern; a parabola reads half the offset, a V 0.85 of it),
and the surge (the along-track advance beyond D) is B Delta_PC = B d / 2. A single bright
scatterer stays coherent at every x-lag: surge is unobservable from blocks that a point
dominates, which are left out of it (pairs.BRIGHT_BLOCK); from points alone it is not
observable at all (fly Trajectory.platform(surge=False) then).

Phase-centre errors (eqs. 48-49, geometry.pca_delay): their carrier phase is removed sample
by sample at each sample's range, their envelope delay at each block's centre range, with the
beam's mean cos^2 of the look angle. The envelope part matters: left in, it makes the couples' phases depend on the speckle
(yaw noise a ping pair several times larger, tests/test_dpca.py). What is left is inherent to the
phase-centre approximation: D (sin^2 theta - <sin^2 theta>) / r of yaw per scatterer. The mean
<sin^2 theta> is taken per range block over the part of the two-way beam the seafloor fills
(geometry.look_moments): the arcs of each block's ring inside the seafloor's rectangle
(``extent``, geometry.SeafloorExtent; by default read from the scenario a simulated echo
carries, geometry.scenario_extent), or the whole beam out to +-90 deg (a real seafloor: recorded
data, ``extent=None``): a patch narrower than the beam, or cut off in its sidelobes, read with
the whole beam's mean is a yaw bias a pair that integrates into a heading drift, a rotated image
(tests/test_dpca_bias.py); without the extent PingPairs.yaw_bias bounds it. A bright point off broadside reads its own look angle's term.

Range blocks and uncertainty: the fast-time axis is cut into blocks; each block gives its own
estimate of the three quantities. Blocks whose beam peak is below ``min_coherence``, whose
energy is below pairs.WEAK_BLOCK of the pair's main-lobe level (beyond the seafloor's swath) are
left out, and of the yaw also those that hold the seafloor's near or far edge or lie next to
it (geometry.inside_swath, with an extent: such blocks read a yaw bias of either sign, whatever
the beam, that does not cancel; a pair left with none takes the edge blocks and is flagged,
PingPairs.yaw_from_edges). The surge and sway are the means of their blocks within
pairs.OUTLIER scaled median absolute deviations of their median (energy-weighted: off-beam
blocks count for little), the sway's weighted by rho^2 / (1 - rho^2) (rho the block's pass-2
beam peak: the phase variance of a correlation at coherence rho); the yaw is pooled over the
blocks (below, pairs.pooled_mean); each with its standard error.

Pooling the blocks' yaws
------------------------
After the phase-centre correction with a block's <sin^2 theta> = m (eqs. 48-49, look_moments),
a scatterer k of the block (reflectivity a_k, along-track direction cosine s_k, two-way power
pattern P) leaves a phase linear along the couples, the yaw e_k = -D (s_k^2 - m) / r. The
beam of eq. (64) sums the scatterers' contributions with their powers w_k = |a_k|^2 P(s_k),
and to first order in their phases (small inside the main lobe) it peaks (eqs. 67, 70) at

    xi_b = N_b / W_b,    N_b = sum_k w_k e_k,    W_b = sum_k w_k,

a ratio. m is the geometric ratio of expectations, E[sum w s^2] / E[sum w], so E[N_b] = 0; but
the expectation of a ratio is not the ratio of expectations: for n_b independent scatterers,
E[N / W] ~ -cov(N, W) / E[W]^2 = (D / r) (E|a|^4 / E|a|^2^2) E[P^2 (s^2 - m)] / (n_b E[P]^2),
negative (P^2 is narrower than P, so E[P^2 (s^2 - m)] < 0) and of order 1 / n_b: a seafloor's
discreteness. The same makes a block's yaw depend on its coherence: a block whose broadside
scatterers happen to be weak (W small) reads its wide-angle ones' negative yaw and decorrelates
more (the wide angles' residual phases differ along the couples), one with a strong broadside
scatterer reads positive and stays coherent; the blocks' yaws are skewed negative. So an
unweighted mean of the blocks keeps the whole 1 / n_b bias, weights rising with coherence
(rho^2 / (1 - rho^2)) over-weight the positive blocks, and a symmetric outlier cut of the skewed
yaws takes their negative tail (each a bias of the same order, of either sign). Weighted by
W_b, the blocks' yaws pool into sum N_b / sum W_b, the ratio over all the pair's scatterers,
whose bias is B times smaller for B blocks. W_b is the magnitude of the block's unnormalised
correlations at the beam peak: rho_b E_b, E_b the block's energy over the two pings' records (a
block holding a bright echo, over pairs.BRIGHT_BLOCK typical blocks' energy, counts as one
typical block: its yaw is that echo's own look-angle term, not the seafloor's). Outliers
(point sidelobes, edges) are cut on the deviations from the weighted median scaled by
sqrt(W_b / median W), the ratio's spread going as 1 / sqrt(W_b): so scaled they are nearly
symmetric and the cut moves the mean little (tests/test_dpca_bias.py and
bench/bench_dpca.py --ratio have the figures). Their tails are still heavier than a Gaussian's
and belong to the seafloor, so the cut is wide (pairs.YAW_OUTLIER scaled MADs): at three it took
blocks that carry the yaw, heavy ones most (the scaling enlarges their deviations; their yaws lean
positive), and the yaw leaned negative and was noisier. Within pairs.SIDELOBE_BLOCKS of a bright
block, whose range sidelobes are what a weak seafloor's blocks there hold, the cut is pairs.OUTLIER
(bench/bench_dpca.py --pooling compares the rules).
A real seafloor, many scatterers a resolution cell, has n_b large; a simulated one of random
points, or a real one of a few strong scatterers (rocks, shells), does not.

Errors and the track (eqs. 71-73): sway errors integrate into the track as a random walk, yaw
errors as an integrated random walk; what defocuses is the part of the resulting cross-track
error that is not linear over a synthetic aperture, i.e. the yaw errors' low frequencies and
bias. Smoothing the yaw sequence with its uncertainties (a second-difference penalised fit,
weights 1 / yaw_std^2) removes high frequencies that the double integration already
suppresses: it lowered the yaw's RMS error but not the PSLR on the seed-004 scene, so the
per-pair estimates are integrated as they are. The heading's standard error grows as a random
walk of the per-pair ones (Trajectory.heading_std; Trajectory.trusted: how many pings stay
within a tolerance).

The hot loop, the correlations over ping pairs, x-lags, couples, t-lags and samples, runs over
every pair, couple and block at once, by FFTs of the blocks zero-padded to twice their length
with the envelope delays applied as a phase ramp over their spectra (correlate.correlations,
``delay=``). The beams are one complex matrix product, formed only at the t-lag of the
couples' incoherent peak and its two neighbours (forming them at every t-lag took half the
time); pass 2 runs only at the x-lags some block found nearest (bench/bench_dpca.py times the
estimator and the correlations' forms side by side). No OpenCL kernel: a free correlation would at most halve DPCA's time, and the fractional delay that made the yaw 3x more precise
needs the spectra, which scipy.fft computes at near memory speed.
"""

from __future__ import annotations

from .correlate import correlations
from .geometry import SeafloorExtent, beam_sin2, look_moments, nominal_shift, scenario_extent
from .pairs import PingPairs, estimate
from .record import beam_correction, compensate_record
from .track import Trajectory, compensate, delay_records, integrate, with_track

__all__ = ["PingPairs", "SeafloorExtent", "Trajectory", "beam_correction", "beam_sin2", "compensate",
           "compensate_record", "correlations", "delay_records", "estimate", "integrate", "look_moments",
           "nominal_shift", "scenario_extent", "with_track"]
