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
   :mod:`.trace`'s), its strongest straight trace (:func:`.radon.line_slope`, the whole record:
   the power of every pulse adds);
2. the whitened power sheared along that centre line, +-:data:`HALF_WIDTH` samples about it; each
   block of :data:`BLOCK` pulses averaged, correlated with the whole record's profile (the
   target's range profile on the trace) and its offset taken at the best lag; a robust parabola
   through the blocks' centres (weighted by their correlation peaks) is the new centre line
   (the trace's delay is a parabola in eta, chain module docstring); repeated
   :data:`PASSES` times;
3. the profile along the final centre line, averaged over every pulse: its cells that stand
   :data:`EXCESS_SIGMAS` standard deviations of the average over the noise and reach
   :data:`BRIGHT` of the brightest are the target's bright scatterers; the gate is those cells
   (and one resolution cell each side) on every pulse.

Why only the bright cells: the RFRT sums x_k^2 over the gate; the scatterers of a hull add there
with unrelated phases, while every noisy cell adds a term of the noise's power, so cells with
little echo lower the line's SNR (on case 5 at A a band three times wider about the true trace
drops the SoWVD's score to the noise's level: tests/test_moving_noise.py).
"""

from __future__ import annotations

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


def centre_line(power: np.ndarray) -> np.ndarray | None:
    """The trace's centre, samples (n_pulses,), in a whitened power map (steps 1-2 of the
    module docstring), or None when the record is too short for blocks."""
    n_pulses = power.shape[0]
    if n_pulses < 2 * BLOCK:
        return None
    # each cell's mean over the pulses taken off: its fluctuations (the floor's estimate) would
    # make a line of slope 0 stronger than the trace
    slope, k_mid = radon.line_slope(power - power.mean(axis=0))
    n = np.arange(n_pulses, dtype=np.float64)
    centre = k_mid + slope * (n - 0.5 * (n_pulses - 1))
    starts = np.arange(0, n_pulses - BLOCK + 1, BLOCK // 2)
    middles = starts + 0.5 * (BLOCK - 1)
    x = (middles - 0.5 * (n_pulses - 1)) / n_pulses
    for _ in range(PASSES):
        window, _, inside = _sheared(power, centre, HALF_WIDTH)
        counts = np.maximum(inside.sum(axis=0), 1)
        profile = window.sum(axis=0) / counts
        profile -= np.median(profile)  # the noise's mean: correlated, it would pull every block to lag 0
        lags = np.arange(-HALF_WIDTH // 2, HALF_WIDTH // 2 + 1)
        offsets, heights = np.empty(starts.size), np.empty(starts.size)
        for b, s in enumerate(starts):
            block = window[s:s + BLOCK].mean(axis=0)
            block -= np.median(block)
            corr = np.correlate(block, profile, mode="full")[profile.size - 1 + lags]
            j = int(np.argmax(corr))
            offsets[b], heights[b] = lags[j], max(float(corr[j]), 0.0)
        if not np.any(heights > 0):
            return centre
        at = centre[np.round(middles).astype(np.int64)] + offsets
        use = heights > 0
        for _ in range(4):
            coef = np.polyfit(x[use], at[use], 2, w=np.sqrt(heights[use]))
            residual = at - np.polyval(coef, x)
            mad = float(np.median(np.abs(residual[use]))) + 1.0
            keep = use & (np.abs(residual) <= REJECT * mad)
            if keep.sum() < 4 or np.array_equal(keep, use):
                break
            use = keep
        centre = np.polyval(coef, (n - 0.5 * (n_pulses - 1)) / n_pulses)
    return centre


def bright_gate(records: np.ndarray, upsample: int = 1) -> np.ndarray | None:
    """Bool (n_pulses, n_samples): the cells of the target's bright scatterers along its trace in
    ``records`` (range-compressed, ``upsample`` x the bandwidth; module docstring), or None when
    no cell of the profile stands out (no trace, or a noise-free record)."""
    power = _whitened(records)
    if power is None:
        return None
    centre = centre_line(power)
    if centre is None:
        return None
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
    return gate
