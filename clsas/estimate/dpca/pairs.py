"""Surge, sway and yaw between consecutive pings (Heremans et al. 2009, eqs. 50-70); see the
package docstring for the method."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ...data import EchoData
from ...scene.scenario import Array
from .correlate import aligned, correlations, parabola, vee
from .geometry import beam_sin2, nominal_shift, pca_delay

log = logging.getLogger("clsas")


@dataclass(frozen=True, eq=False)
class PingPairs:
    """Per ping pair (p, p + 1) estimates, arrays of shape (n_pulses - 1,).

    surge, sway : m (along-track advance beyond v PRT; cross-track displacement towards +x)
    yaw : rad (rotation about +z between the two pings)
    surge_std, sway_std, yaw_std : their standard errors (m, m, rad)
    coherence : the best beam's normalised correlation magnitude (0..1), median over blocks
    blocks : how many range blocks entered each estimate
    lags : the x-lags tested were -lags..lags (the couples used follow from it)
    two_way : s, the median two-way travel time of the range blocks used
    """

    surge: np.ndarray
    sway: np.ndarray
    yaw: np.ndarray
    surge_std: np.ndarray
    sway_std: np.ndarray
    yaw_std: np.ndarray
    coherence: np.ndarray
    blocks: np.ndarray
    lags: int
    two_way: float


# Range blocks holding less than this fraction of a ping pair's median block energy are left
# out: beyond the seafloor's swath only range sidelobes and the far edges of the beam remain,
# scatterers seen at large look angles only, whose phase-centre error (D sin^2 theta / r per
# pair as a yaw, see geometry.pca_delay) is far from the beam's mean. Measured on Heremans' nine-point
# scene: such blocks read -950 .. +860 urad of yaw where the seafloor's read 0 +- 15.
WEAK_BLOCK = 0.1
# Blocks further than this many scaled median absolute deviations from a pair's median are left
# out of its mean (see estimate).
OUTLIER = 3.0


def _check(echo, array, speed, lags, t_lags, block, min_coherence, n_angles) -> None:
    if not isinstance(echo, EchoData):
        raise TypeError(f"dpca: echo must be EchoData, got {type(echo).__name__}")
    if not echo.compressed:
        raise ValueError("dpca: echo must be range-compressed (clsas.range_compress) so the correlations are sharp")
    if not isinstance(array, Array):
        raise TypeError(f"dpca: array must be a clsas Array (the hydrophone layout), got {type(array).__name__}")
    if array.n_receivers > echo.n_rx:
        raise ValueError(f"dpca: the array has {array.n_receivers} hydrophones, the echo {echo.n_rx} receivers")
    if isinstance(speed, bool) or not isinstance(speed, (int, float, np.floating, np.integer)) \
            or not np.isfinite(speed) or speed <= 0:
        raise ValueError(f"dpca: speed must be a positive nominal speed in m/s, got {speed!r}")
    for name, value, lo in (("lags", lags, 1), ("t_lags", t_lags, 1), ("block", block, 8), ("n_angles", n_angles, 3)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
            raise ValueError(f"dpca: {name} must be an integer >= {lo}, got {value!r}")
    if not (isinstance(min_coherence, (int, float, np.floating)) and 0 <= min_coherence < 1):
        raise ValueError(f"dpca: min_coherence must be in [0, 1), got {min_coherence!r}")
    if echo.n_pulses < 2:
        raise ValueError(f"dpca needs at least 2 pings, the echo has {echo.n_pulses}")
    if echo.n_samples < block:
        raise ValueError(f"dpca: block ({block} samples) is longer than the records ({echo.n_samples} samples)")
    if not isinstance(lags, bool) and isinstance(t_lags, (int, np.integer)) and 2 * t_lags + 1 > block:
        raise ValueError(f"dpca: t_lags ({t_lags}) must leave the correlation inside a block of {block} samples")


def estimate(echo: EchoData, array: Array, speed: float, *, lags: int = 2, t_lags: int = 8, block: int = 128,
             n_angles: int = 65, min_coherence: float = 0.5) -> PingPairs:
    """Surge, sway and yaw between every pair of consecutive pings (see the package docstring, clsas.estimate.dpca).

    Parameters
    ----------
    echo : range-compressed EchoData whose first ``array.n_receivers`` receivers are the array's
        hydrophones (numbered along the track), pings at a constant PRF.
    array : the hydrophone layout (body-frame offsets, as in the Scenario).
    speed : nominal platform speed, m/s (e.g. the autopilot's), for the nominal pairing (eq. 50).
    lags : x-lags -lags..lags are tested (section 5.3: 2).
    t_lags : t-lags -t_lags..t_lags samples (section 5.4: 8).
    block : range-block length, samples.
    n_angles : look angles over +-asin(c / (f0 L)) (L the overlapping phase centres' length),
        refined by a parabola.
    min_coherence : blocks whose best beam is weaker than this are left out.
    """
    _check(echo, array, speed, lags, t_lags, block, min_coherence, n_angles)
    eta = echo.eta
    prt = np.diff(eta)
    if not np.allclose(prt, prt[0], rtol=1e-9):
        raise ValueError("dpca needs a constant pulse interval")
    prf = 1.0 / prt[0]
    s, pc = nominal_shift(array, speed, prf)
    h = array.n_receivers
    n_couples = h - s - lags
    if s < 1 or n_couples < 3:
        raise ValueError(f"dpca: at speed {speed} m/s and PRF {prf:g} Hz the platform advances {s} phase-centre "
                         f"spacings a ping: the {h} hydrophones leave {h - s} overlapping phase centres, "
                         f"{max(n_couples, 0)} couples at x-lag +-{lags} (needs >= 3); lower the speed or lags")
    c = echo.medium.sound_speed
    f0 = echo.waveform.f0
    records, start = aligned(echo, h)
    n_blocks = records.shape[-1] // block
    r_blocks = c / 2 * (start + (np.arange(n_blocks) + 0.5) * block / echo.fs)   # block centre ranges, m
    r_samples = (c / 2 * (start + np.arange(n_blocks * block) / echo.fs)).reshape(n_blocks, block)
    sin2 = beam_sin2(array, f0, c)
    data = records[..., :n_blocks * block].reshape(h, echo.n_pulses, n_blocks, block)
    step = pc[1] - pc[0]
    span = n_couples * step
    theta_max = np.arcsin(min(1.0, c / (f0 * span)))
    sin_theta = np.sin(np.linspace(-theta_max, theta_max, n_angles))
    peaks = np.empty((2 * lags + 1, echo.n_pulses - 1, n_blocks))
    delays = np.empty_like(peaks)
    yaws = np.empty_like(peaks)
    for li, lag in enumerate(range(-lags, lags + 1)):
        i = np.arange(n_couples)                         # hydrophones at ping p + 1
        j = i + s + lag                                  # hydrophones at ping p
        f = data[j][:, :-1]                              # (couple, pair, block, sample)
        pca = np.exp(2j * np.pi * f0 * pca_delay(array, i, j, r_samples, speed, c, sin2)).astype(np.complex64)
        g = data[i][:, 1:] * pca[:, None]                # ping p + 1, phase-centre errors removed sample by sample
        corr = correlations(f, g, t_lags)                # (couple, pair, block, t-lag)
        u = pc[i] - pc[i].mean()                         # couple positions along the track
        steer = np.exp(-1j * 4 * np.pi * f0 * np.outer(sin_theta, u) / c)   # (angle, couple)
        beams = (steer.astype(np.complex64) @ corr.reshape(n_couples, -1)).reshape((n_angles,) + corr.shape[1:])
        beams = np.moveaxis(beams, 0, 2) / n_couples     # (pair, block, angle, t-lag)
        mag = np.abs(beams)
        flat = mag.reshape(mag.shape[:2] + (-1,)).argmax(axis=-1)
        a, m = np.unravel_index(flat, mag.shape[2:])
        a = np.clip(a, 1, n_angles - 2)
        m = np.clip(m, 1, 2 * t_lags - 1)
        pp, bb = np.indices(a.shape)
        m_off, peak = parabola(mag[pp, bb, a, m - 1], mag[pp, bb, a, m], mag[pp, bb, a, m + 1])
        a_off, _ = parabola(mag[pp, bb, a - 1, m], mag[pp, bb, a, m], mag[pp, bb, a + 1, m])
        coarse = -((m - t_lags) + m_off) / echo.fs
        phase = np.angle(beams[pp, bb, a, m])
        cycles = np.round(coarse * f0 - phase / (2 * np.pi))
        delays[li] = (phase / (2 * np.pi) + cycles) / f0
        ds = sin_theta[1] - sin_theta[0]
        yaws[li] = -np.arcsin(np.clip(sin_theta[a] + a_off * ds, -1, 1))
        peaks[li] = peak
    best = np.argmax(peaks, axis=0)                      # (pair, block)
    best = np.clip(best, 1, 2 * lags - 1)
    pp, bb = np.indices(best.shape)
    lag_off = vee(peaks[best - 1, pp, bb], peaks[best, pp, bb], peaks[best + 1, pp, bb])
    coherence = peaks.max(axis=0)
    surge = ((best - lags) + lag_off) * step
    nearest = np.argmax(peaks, axis=0)
    sway = -c * delays[nearest, pp, bb] / 2
    yaw = yaws[nearest, pp, bb]
    good = coherence >= min_coherence
    energy = np.einsum("hpbk,hpbk->pb", data, np.conj(data)).real   # (pulse, block)
    energy = energy[:-1] + energy[1:]
    typical = np.nanmedian(np.where(good, energy, np.nan), axis=1, keepdims=True)
    good &= energy >= WEAK_BLOCK * typical
    counts = good.sum(axis=1)
    if np.any(counts == 0):
        worst = int(np.argmin(counts))
        raise ValueError(f"dpca: ping pair {worst}-{worst + 1} has no range block with a beam peak >= "
                         f"min_coherence {min_coherence} (best {coherence[worst].max():.2f}): the pings do not "
                         "correlate (too little overlap, or no seafloor return in the records)")

    def robust_mean(x):
        """The blocks' mean and its standard error, blocks beyond OUTLIER scaled MADs of the
        median left out (speckle makes a block's error roughly Gaussian; a block holding the
        edge of the swath or a lone bright echo can sit far out)."""
        masked = np.where(good, x, np.nan)
        med = np.nanmedian(masked, axis=1, keepdims=True)
        mad = 1.4826 * np.nanmedian(np.abs(masked - med), axis=1, keepdims=True)
        kept = np.where(np.abs(masked - med) <= OUTLIER * mad, masked, np.nan)
        n = np.sum(np.isfinite(kept), axis=1)
        return np.nanmean(kept, axis=1), np.nanstd(kept, axis=1) / np.sqrt(n)

    (su, su_e), (sw, sw_e), (yw, yw_e) = (robust_mean(x) for x in (surge, sway, yaw))
    coh = np.nanmedian(np.where(good, coherence, np.nan), axis=1)
    log.info("dpca: %d ping pairs, %d couples, %d range blocks; median coherence %.2f", echo.n_pulses - 1,
             n_couples, n_blocks, float(np.median(coh)))
    return PingPairs(surge=su, sway=sw, yaw=yw, surge_std=su_e, sway_std=sw_e, yaw_std=yw_e, coherence=coh,
                     blocks=counts, lags=lags, two_way=float(np.median(2 * r_blocks[good.any(axis=0)] / c)))
