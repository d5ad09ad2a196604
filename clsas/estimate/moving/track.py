"""A moving target's trace followed through heavy noise, and the range cells of its brightest
scatterers on it: the RFRT gate of :mod:`.sowvd` where :mod:`.trace`'s cell-by-cell support
fails.

Not in Kiang & Kiang 2022; like :mod:`.trace` it only looks at |s(tau, eta)|. Why it is needed:
:func:`.trace.support` averages the power of each range cell over :data:`.trace.PULSES` pulses,
so it finds a trace only where the echo keeps its cell over those pulses and stands out of the
noise there. On the scaled hull at the paper's -15 dB (Table II cases 5 and 6: a range walk of
about one upsampled sample a pulse and the echo spread over metres of range) it stands out in a
few cells of some of the pulses, the band fitted to them misses the trace, and the RFRT sums
noise over the whole record: the SoWVD scores the noise's level (tests/test_moving_noise.py).

Here the trace is followed over the whole record instead:

1. the power whitened per range cell (over its noise floor, :func:`.trace.floor`), less each
   cell's mean over the pulses (what a target that keeps its range cell leaves is
   :mod:`.trace`'s), its strongest straight trace (:func:`.radon.line_slope`) over the middle
   :data:`SEED` pulses (or :data:`SHORT_SEED`; the whole record when shorter: the power of every pulse adds; over longer
   records the trace bends away from any straight line: ~1000 samples over Table I's 6400
   pulses at receiver A, Table II case 1, where a straight line over the whole record found
   something else and the EstimationError of tests/test_moving_noise.py's 6400-pulse test
   followed);
2. the whitened power sheared along that centre line, +-:data:`HALF_WIDTH` samples about it; each
   block of :data:`BLOCK` pulses averaged, correlated with the whole record's profile (the
   target's range profile on the trace) and its offset taken at the best lag; a robust parabola
   through the blocks' centres (weighted by their correlation peaks) is the new centre line
   (the trace's delay is a parabola in eta, chain module docstring); repeated
   :data:`PASSES` times; then (records longer than :data:`SEED`) over a stretch :data:`GROW`
   times longer about the middle, the line extrapolated into it and each block's offset searched
   within :data:`LAG_SIGMAS` standard deviations of the extrapolation at the stretch's ends (the
   blocks' scatter about the fit propagated through the polynomial), a cubic from then on (the
   delay's higher-order terms show over long apertures), :data:`GROWN_PASSES` times, until the
   stretch is the whole record: the trace is followed however far it walks;
4. the profile along the final centre line, averaged over every pulse: its cells that stand
   :data:`EXCESS_SIGMAS` standard deviations of the average over the noise and reach
   :data:`BRIGHT` of the brightest are the target's bright scatterers; the gate is those cells
   (and one resolution cell each side) on every pulse. The centre line's tangent at the middle
   pulse is a Doppler centroid measured on the trace itself (:func:`.chain.with_rate` tries it
   beside the Radon lines of the RCMC'd record), and its curvature an azimuth FM rate
   (:func:`trace_rate`; :func:`.chain.estimate_records` tries it when the SoWVD's best candidate
   is not confirmed by its focus).

Why only the bright cells: the RFRT sums x_k^2 over the gate; the scatterers of a hull add there
with unrelated phases, while every noisy cell adds a term of the noise's power, so cells with
little echo lower the line's SNR (on case 5 at A a band three times wider about the true trace
drops the SoWVD's score to the noise's level: tests/test_moving_noise.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d

from . import radon, trace

#: Half-width of the window about the centre line followed, samples (of the upsampled record).
HALF_WIDTH = 200
#: Pulses per block of step 2 (half-overlapping blocks).
BLOCK = 256
#: Refinements of the centre line (step 2).
PASSES = 3
#: Blocks whose offset is this many median absolute deviations off the parabola are dropped.
REJECT = 4.0
#: Pulses in the middle of the record on which the trace is first found as a straight line (step
#: 1): over them the trace bends little (it bends as the square of the stretch's length).
SEED = 2048
#: A shorter seed stretch, tried (:func:`.gated.sowvd`) when the trace followed from :data:`SEED`
#: does not hold the target: a trace that walks fast bends away from the whole record's straight
#: line by more than the blocks search (Table II case 6 at A, 2048 pulses: 1.7 samples a pulse,
#: 130-340 samples off the line at the ends against +-100; from the middle 512 pulses' line the
#: stretches grow onto it to within a sample).
SHORT_SEED = 512
#: Each further stretch is this many times longer than the last (step 3).
GROW = 2.0
#: A longer stretch's blocks search offsets this many standard deviations of the extrapolated
#: line at its ends (at least :data:`HALF_WIDTH` / 2 samples, at most :data:`MAX_LAG`).
LAG_SIGMAS = 6.0
#: Samples.
MAX_LAG = 1000
#: The polynomial followed beyond the seed's stretch: over long records the delay's cubic term
#: shows (its higher-order terms: :func:`.closedforms.higher_order_delay`).
GROWN_DEGREE = 3
#: Blocks a stretch needs for a parabola (fewer: a line) in its first refinements.
MIN_PARABOLA_BLOCKS = 7
#: Refinements at each longer stretch.
GROWN_PASSES = 2
#: A gated cell's profile stands this many standard deviations of the average over the noise.
EXCESS_SIGMAS = 10.0
#: ... and reaches this fraction of the brightest cell's excess.
BRIGHT = 0.3


def _whitened(records: np.ndarray) -> np.ndarray | None:
    """|x|^2 over each range cell's noise floor, float32, or None when the floor is 0."""
    power = np.abs(records).astype(np.float32) ** 2
    level = trace.floor(power)
    if not np.all(level > 0):
        return None
    power /= level
    return power


def _sheared(power: np.ndarray, centre: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(window (n_pulses, 2 half + 1) of ``power`` about ``centre`` (n_pulses,) samples, its
    columns' sample indices, which of them lie in the record)."""
    n_pulses, n_samples = power.shape
    idx = np.round(centre).astype(np.int64)[:, None] + np.arange(-half, half + 1)[None, :]
    inside = (idx >= 0) & (idx < n_samples)
    window = np.where(inside, power[np.arange(n_pulses)[:, None], np.clip(idx, 0, n_samples - 1)], 0.0)
    return window.astype(np.float32), idx, inside


def _excess(sums: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The mean of a sheared window's columns (:func:`_sheared`; ``sums`` of its cells that lie
    in the record, ``counts`` of them, each (n_columns,)) less the median of those means, and 0
    where no cell of a column lies in the record. The noise's mean taken off: correlated, it
    would pull every block to lag 0; and the columns beyond the record's ends (a fast-walking
    trace's window leaves the record near its ends) add nothing: as the noise's mean less a
    median they were a step at the record's edge that every block and the profile shared."""
    live = counts > 0
    mean = np.where(live, sums / np.maximum(counts, 1), 0.0)
    if np.any(live):
        mean[live] -= np.median(mean[live])
    return mean


def _refined(power: np.ndarray, stretch: slice, centre: np.ndarray, lag_half: int, degree: int
             ) -> tuple[np.ndarray, float, np.ndarray] | None:
    """One pass of step 2 over the pulses ``stretch`` about ``centre`` (n_pulses,) samples: the
    blocks' offsets within +-``lag_half`` samples, a robust polynomial of ``degree`` through
    them. (coefficients over x = (pulse - middle pulse) / n_pulses, the fit's residual standard
    deviation scaled to one block (samples), the x of the blocks' middles), or None when no block
    correlates with the profile."""
    n_pulses = power.shape[0]
    lo, hi, _ = stretch.indices(n_pulses)
    starts = np.arange(lo, hi - BLOCK + 1, BLOCK // 2)
    middles = starts + 0.5 * (BLOCK - 1)
    x = (middles - 0.5 * (n_pulses - 1)) / n_pulses
    window, _, inside = _sheared(power[lo:hi], centre[lo:hi], HALF_WIDTH // 2 + lag_half)
    sums, counts = window.sum(axis=0), inside.sum(axis=0)
    lags = np.arange(-lag_half, lag_half + 1)
    offsets, heights = np.empty(starts.size), np.empty(starts.size)
    for b, s in enumerate(starts - lo):
        block_sums, block_counts = window[s:s + BLOCK].sum(axis=0), inside[s:s + BLOCK].sum(axis=0)
        block = _excess(block_sums, block_counts)
        # the profile of the other pulses: with the block's own, the block's noise correlated with
        # itself at lag 0 and outweighed a trace that had walked off the line (a fast-walking
        # trace's straight seed line: every block kept lag 0)
        profile = _excess(sums - block_sums, counts - block_counts)
        corr = np.correlate(block, profile, mode="full")[profile.size - 1 + lags]
        j = int(np.argmax(corr))
        offsets[b], heights[b] = lags[j], max(float(corr[j]), 0.0)
    if not np.any(heights > 0):
        return None
    at = centre[np.round(middles).astype(np.int64)] + offsets
    coef, use = trace.robust_polyfit(x, at, np.sqrt(heights), heights > 0, reject=REJECT, mad_floor=1.0,
                                     passes=4, min_points=4, too_few="keep", readmit=False, degree=degree)
    spread = float(np.std(at[use] - np.polyval(coef, x[use]))) if use.sum() > degree + 1 else float(lag_half)
    return coef, spread, x[use]


def _extrapolation_sigma(x_fit: np.ndarray, spread: float, degree: int, x_new: np.ndarray) -> float:
    """Samples: the largest standard deviation, at ``x_new``, of a polynomial of ``degree``
    fitted with equal weights to points at ``x_fit`` scattered by ``spread`` samples (the lag
    window of the next stretch: :func:`centre_line`)."""
    basis = np.vander(x_fit, degree + 1)
    cov = spread**2 * np.linalg.pinv(basis.T @ basis)
    at = np.vander(np.atleast_1d(x_new), degree + 1)
    return float(np.sqrt(np.max(np.einsum("ij,jk,ik->i", at, cov, at))))


def centre_line(power: np.ndarray, seed: int = SEED) -> tuple[np.ndarray, int] | None:
    """(the trace's centre, samples (n_pulses,), in a whitened power map (steps 1-2 of the
    module docstring; the first straight line over the middle ``seed`` pulses); the degree of the
    polynomial it is: 1 when no block correlated with the profile beyond the first straight line or
    a line's fit, 2 or :data:`GROWN_DEGREE` after a parabola's or a cubic's), or None when the
    record is too short for blocks."""
    n_pulses = power.shape[0]
    if n_pulses < 2 * BLOCK:
        return None
    n = np.arange(n_pulses, dtype=np.float64)
    x_all = (n - 0.5 * (n_pulses - 1)) / n_pulses
    length = min(n_pulses, seed)
    stretch = slice((n_pulses - length) // 2, (n_pulses - length) // 2 + length)
    # each cell's mean over the pulses taken off: its fluctuations (the floor's estimate) would
    # make a line of slope 0 stronger than the trace. The mean over the whole record: over the
    # seed's pulses alone it would take off the bottom of a trace that bends back (it keeps its
    # cells there for much of the seed, but not of the record)
    slope, k_mid = radon.line_slope(power[stretch] - power.mean(axis=0))
    centre = k_mid + slope * (n - 0.5 * (n_pulses - 1))
    # a parabola needs blocks to spare for its rejections: a short seed (:data:`SHORT_SEED`, three
    # blocks) takes a line, and over it the trace bends by a few samples
    degree = 2 if (length - BLOCK) // (BLOCK // 2) + 1 >= MIN_PARABOLA_BLOCKS else 1
    lag_half, passes, fitted = HALF_WIDTH // 2, PASSES, 1
    while True:
        for _ in range(passes):
            fit = _refined(power, stretch, centre, lag_half, degree)
            if fit is None:
                return centre, fitted
            coef, spread, x_fit = fit
            centre, fitted = np.polyval(coef, x_all), degree
        if length == n_pulses:
            return centre, fitted
        # step 3: a longer stretch about the middle; where the line is extrapolated into it the
        # blocks search as far as it may be off there
        length = min(n_pulses, int(GROW * length))
        stretch = slice((n_pulses - length) // 2, (n_pulses - length) // 2 + length)
        # the cubic only beyond :data:`SEED` pulses: from a short seed, over up to SEED pulses, it
        # extrapolated a few blocks' noise thousands of samples off
        degree, passes = (GROWN_DEGREE if length > SEED else 2), GROWN_PASSES
        ends = x_all[[stretch.start, stretch.stop - 1]]
        lag_half = max(HALF_WIDTH // 2, int(np.ceil(LAG_SIGMAS * _extrapolation_sigma(x_fit, spread, degree, ends))))
        lag_half = min(lag_half, MAX_LAG)


def trace_rate(curvature: float, f0: float, prf: float, fs: float) -> float:
    """K_a,eq (Hz/s) from the curvature of a followed trace, ``curvature`` samples a pulse^2 of
    a record sampled at ``fs`` Hz (the upsampled rate) with pulses at ``prf`` Hz, carrier ``f0`` Hz.

    The derivation (Kiang & Kiang 2022). The scatterer's forward and backward ranges are
    quadratic in the slow time eta, eqs. (1)-(2) at transceiver A:
    R'(eta) = R'_10 + c_s f'_dc1 / (2 f0) eta + c_s K'_a1 / (4 f0) eta^2, and R'' alike (receiver
    B: R''_2n of eq. (21) with eqs. (23), (25); sonobuoy C: R''_3n with eq. (32)). The echo of
    eq. (7) lies at the two-way delay tau(eta) = (R' + R'') / c_s, so
    tau(eta) = tau_0 + (f'_dc + f''_dc) / (2 f0) eta + (K'_a + K''_a) / (4 f0) eta^2
    = tau_0 + (f_dc,eq / f0) eta + (K_a,eq / (2 f0)) eta^2 with eqs. (15)-(16) (B: eq. (28) and
    K_a2,eq = (K'_a1 + K''_a2) / 2 after eq. (26)), and d^2 tau / d eta^2 = K_a,eq / f0. In the
    range-compressed spectrum that is the phase exp{-j pi (f0 + f_tau) K_a,eq eta^2 / f0} of eq.
    (26) (eq. (9) at A), whose f_tau-linear part the RCMC filter H_rcmc removes: the compressed
    envelope's peak lies at tau(eta) (before RCMC; eq. (27)'s sinc after it). The trace's sample
    index at pulse n is k(n) = (tau(n / prf) - t0) fs, so
    d^2 k / dn^2 = fs / prf^2 d^2 tau / d eta^2 and K_a,eq = f0 prf^2 / fs d^2 k / dn^2 (the
    linear term likewise gives f_dc,eq = f0 prf / fs dk / dn, :func:`.chain.with_rate`'s tangent).

    Its precision: over T_a the quadratic term walks K T_a^2 / (8 f0) s at the record's ends
    (Table I, 25.6 s: 240 upsampled samples at K = 11 Hz/s, 7 at 0.33 Hz/s), and the followed
    line holds the trace to a sample or so
    (tests/test_moving_noise.py::test_the_followed_trace_holds_a_fast_walker): a sample of error
    at the ends is 8 f0 / (fs T_a^2) = 0.046 Hz/s, ~8 focus steps 4 / T_a^2, less than the
    SoWVD's bin, and :func:`.located.focused_rate` refines it. With the delay's higher-order terms
    (:func:`.closedforms.higher_order_delay`) the least-squares parabola's coefficient is the
    aperture's P2 part, the rate the focus reads (:func:`.located.focused_rate`). In heavy noise
    the followed line can follow something else and the rate be anything: it is a candidate,
    confirmed or refused by the focus like the SoWVD's (:func:`.chain.estimate_records`).
    The range-Doppler coupling of intra-pulse Doppler shifts the peak by f_dc(eta) / K_r, linear
    in eta (f_dc(eta) = f_dc,eq + K_a,eq eta): it tilts the trace, not its curvature."""
    return float(f0 * prf**2 / fs * curvature)


@dataclass(frozen=True)
class FollowedTrace:
    """:func:`bright_gate`'s result: gate bool (n_pulses, n_samples), the bright scatterers'
    cells along the followed trace; slope (samples a pulse) of the trace's centre line at the
    middle pulse and sample of its brightest cell there (its tangent: the delay's linear term
    f_dc / f0, chain module docstring); curvature (samples a pulse^2): twice the x^2 coefficient of
    the least-squares parabola through the centre line over every pulse (its Legendre P2 part: the
    delay's second derivative K / f0 averaged as :func:`.located.focused_rate` reads a rate;
    :func:`trace_rate` turns it into K_a,eq), nan when the centre line is a straight line
    (:func:`centre_line`'s degree below 2: its parabola's coefficient would be rounding, ~1e-16,
    not a curvature the trace was followed to)."""

    gate: np.ndarray
    slope: float
    sample: float
    curvature: float


def bright_gate(records: np.ndarray, upsample: int = 1, seed: int = SEED) -> FollowedTrace | None:
    """The cells of the target's bright scatterers along its trace in ``records``
    (range-compressed, ``upsample`` x the bandwidth; module docstring; the trace first found
    over the middle ``seed`` pulses) and the trace's tangent at the middle pulse, or None when
    no cell of the profile stands out (no trace, or a noise-free record)."""
    power = _whitened(records)
    if power is None:
        return None
    line = centre_line(power, seed)
    if line is None:
        return None
    centre, degree = line
    window, idx, inside = _sheared(power, centre, HALF_WIDTH)
    counts = inside.sum(axis=0)
    profile = window.sum(axis=0) / np.maximum(counts, 1)
    base = float(np.median(profile[counts > 0])) if np.any(counts > 0) else 0.0
    # the whitened noise's power is exponential: its standard deviation is its mean
    excess = (profile - base) / (base / np.sqrt(np.maximum(counts, 1)))
    bright = (excess > EXCESS_SIGMAS) & (excess >= BRIGHT * float(excess.max()))
    if not np.any(bright):
        return None
    bright = maximum_filter1d(bright, 1 + 2 * upsample)
    gate = np.zeros(records.shape, bool)
    rows = np.broadcast_to(np.arange(records.shape[0])[:, None], idx.shape)
    take = inside & bright[None, :]
    gate[rows[take], idx[take]] = True
    middle = 0.5 * (records.shape[0] - 1)
    below, above = int(np.floor(middle)), int(np.ceil(middle))
    ends = slice(max(below - 1, 0), above + 2)  # the centre line is a low-order polynomial
    slope = float(np.mean(np.diff(centre[ends])))
    # the centre line is followed up to a constant (the blocks' lags are relative to the profile):
    # the brightest cell of the profile is where the trace is
    brightest = int(np.argmax(np.where(bright, excess, -np.inf))) - HALF_WIDTH
    u = (np.arange(centre.size) - middle) / max(middle, 1.0)  # in [-1, 1]: a well-conditioned fit
    # a straight centre line bends nowhere: its parabola's x^2 coefficient is rounding, no candidate rate
    curvature = float("nan") if degree < 2 else 2.0 * float(np.polyfit(u, centre, 2)[0]) / max(middle, 1.0) ** 2
    return FollowedTrace(gate=gate, slope=slope,
                         sample=float(np.interp(middle, np.arange(centre.size), centre)) + brightest,
                         curvature=curvature)
