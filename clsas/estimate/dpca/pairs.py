"""Surge, sway and yaw between consecutive pings (Heremans et al. 2009, eqs. 50-70); see the
package docstring for the method."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.fft

from ... import budget, validate
from ...errors import EstimationError
from ...model import EchoData
from ...scene.scenario import Array
from ...kernelmath import unit_phasor
from .correlate import aligned, correlations, parabola, peak_ratio
from .geometry import (ANGLES, SUB_RANGES, SeafloorExtent, across_cosine, beam_sin2, inside_swath, look_moments,
                       main_lobe_sin2, pairing, pca_delay, scenario_extent, xlag_offset)

log = logging.getLogger("clsas")


@dataclass(frozen=True, eq=False)
class PingPairs:
    """Per ping pair (p, p + 1) estimates, arrays of shape (n_pulses - 1,).

    surge, sway : m (along-track advance beyond v PRT; cross-track displacement towards +x,
        horizontal: the blocks' delays divided by the line of sight's across-track component,
        geometry.across_cosine, with the seafloor's depression when its extent is known)
    yaw : rad (rotation about +z between the two pings; divided likewise)
    surge_std, sway_std, yaw_std : their standard errors (m, m, rad)
    coherence : the best beam's normalised correlation magnitude (0..1), median over blocks
    blocks : how many range blocks entered each estimate
    lags : the x-lags tested were -lags..lags (the couples used follow from it)
    two_way : s, the median two-way travel time of the range blocks used
    yaw_from_edges : bool (n_pulses - 1,), True where no range block of the pair kept clear of
        the seafloor's range edges (geometry.inside_swath: a swath narrower than three or four
        blocks), so that its yaw comes from blocks that hold an edge and may be
        biased by several urad the way the edge reads (near edges negative, far edges
        positive); None when not known (built by hand)
    yaw_bias : rad (n_pulses - 1,), how far the yaw may be biased a pair, the same way every pair,
        by what the phase-centre correction assumes of the look angles: without the seafloor's
        extent, D (<sin^2>_beam - <sin^2>_main lobe) / r, the difference between a seafloor that
        fills the whole beam and one that fills only its main lobe (a narrower one biases it
        more: give ``extent``); 0 with the extent; None when not known (built by hand)
    block_yaw : rad (n_pulses - 1, block), each range block's own yaw (pass 2), NaN where the
        block entered no estimate (weak, incoherent, beyond the seafloor); ``yaw`` is their mean
        over the blocks clear of the seafloor's range edges (``block_inside``) weighted by
        ``block_weight``: for seeing how the yaw depends on range (bench/bench_dpca.py --edges);
        None when built by hand
    block_inside : bool (n_pulses - 1, block), the blocks ``yaw`` was taken from (before the
        outlier cut, pooled_mean); None when built by hand
    block_range : m (block,), the blocks' centre slant ranges; None when built by hand
    block_weight : (n_pulses - 1, block), each block's weight in ``yaw`` (its coherent energy,
        pass 2's beam peak times its energy over the two pings' records; 0 where it is not in
        ``block_inside`` or was cut as an outlier): ``yaw`` is the weighted mean of
        ``block_yaw``; None when built by hand
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
    yaw_bias: np.ndarray | None = None
    yaw_from_edges: np.ndarray | None = None
    block_yaw: np.ndarray | None = None
    block_inside: np.ndarray | None = None
    block_range: np.ndarray | None = None
    block_weight: np.ndarray | None = None


# Range blocks holding less than this fraction of a ping pair's main-lobe level (its third
# strongest block) are left out: beyond the seafloor's swath only range sidelobes and the far
# edges of the beam remain, scatterers seen at large look angles only, whose phase-centre error
# (D sin^2 theta / r per pair as a yaw, see geometry.pca_delay) is far from the beam's mean. The
# two-way pattern's first sidelobe is -26.5 dB for equal elements (lower for a longer
# transmitter); -20 dB leaves room for the seafloor's fall with range across the swath.
WEAK_BLOCK = 0.01
# Blocks holding more than this multiple of a pair's median block energy are taken as a lone
# bright echo's and left out of the surge (see estimate).
BRIGHT_BLOCK = 3.0
# Blocks holding less than this fraction of their seafloor's weight (over the two-way pattern)
# inside the main lobe are left out when the seafloor's extent is given (geometry.look_moments).
MAIN_LOBE = 0.5
# Blocks whose line of sight's across-track component (geometry.across_cosine) is below this are
# left out: seen steeper than 60 deg of depression, or with look angles reaching the depression's
# cosine (near nadir, the water column before the first bottom return), where the first-order model
# fails and dividing by the component would blow the block's sway and yaw up.
MIN_ACROSS = 0.5
# Blocks further than this many scaled median absolute deviations from a pair's median are left
# out of its mean (see estimate).
OUTLIER = 3.0
# A block whose yaw's scaled deviation (pooled_mean) lies beyond this many scaled median absolute
# deviations of the pair's is left out of its yaw, OUTLIER of them within SIDELOBE_BLOCKS of a
# bright block. The scaled deviations' tails are heavier than a Gaussian's and carry the yaw: cut
# everywhere at OUTLIER, the cut took some 4 % of a speckle seafloor's blocks, heavy ones most
# (the scaling enlarges their deviations; their yaws lean positive, so the pair's leaned negative)
# and the yaw's noise rose. Next to a bright echo its range sidelobes are what a block holds, whose
# yaws (that echo's look-angle term through the sidelobes' phase) are outliers the narrow cut takes
# (bench/bench_dpca.py --pooling, tests/test_dpca.py's focus tests).
YAW_OUTLIER = 5.0
SIDELOBE_BLOCKS = 2
# t-lags of the second pass, after each pair's delay is taken out of the envelope.
FINE_T_LAGS = 2


def _weighted_median(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per row of ``x`` (pair, block): the weighted median, the midpoint of the lowest value
    below which half the row's weight ``w`` (>= 0, 0 for blocks left out) lies and the highest
    value above which half lies (the two differ where the cumulative weight meets exactly one
    half, e.g. an even count of equal weights: taking the lower one biased a trim around it
    towards the upper tail); NaN for a row without weight."""
    def lower(values):
        values = np.where(w > 0, values, np.inf)
        order = np.argsort(values, axis=1)
        xs, ws = np.take_along_axis(values, order, axis=1), np.take_along_axis(np.where(w > 0, w, 0.0), order, axis=1)
        cw = np.cumsum(ws, axis=1)
        k = np.argmax(cw >= 0.5 * cw[:, -1:], axis=1)
        return xs[np.arange(x.shape[0]), k]

    total = np.sum(np.where(w > 0, w, 0.0), axis=1)
    with np.errstate(invalid="ignore"):
        middle = 0.5 * (lower(x) - lower(-x))
    return np.where(total > 0, middle, np.nan)


def pooled_mean(x: np.ndarray, use: np.ndarray, weight: np.ndarray,
                cut: float | np.ndarray = YAW_OUTLIER) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row (ping pair) of the blocks' values ``x`` (pair, block): their mean weighted by
    ``weight`` (pair, block; > 0, a block's coherent energy), its standard error, and which
    blocks entered it (``use`` and not cut). The cut: a block whose deviation from the
    ``weight``-weighted median, scaled by sqrt(weight / the row's median weight), lies beyond
    ``cut`` (a number, or one per block: shape of ``x``) scaled median absolute deviations of the
    row's scaled deviations. A block's yaw is a
    ratio whose spread goes as 1 / sqrt(weight): scaled so, the deviations are nearly symmetric,
    where the plain ones are skewed (see the package docstring) and a cut on them moves the mean.
    The standard error is over the effective number of blocks, sum(w)^2 / sum(w^2)."""
    w = np.where(use, weight, 0.0)
    x = np.where(use, x, 0.0)
    med = _weighted_median(x, w)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        typical = np.nanmedian(np.where(use, w, np.nan), axis=1, keepdims=True)
        z = (x - med) * np.sqrt(w / typical)
    ones = use.astype(float)
    centre = _weighted_median(z, ones)[:, None]
    mad = 1.4826 * _weighted_median(np.abs(z - centre), ones)[:, None]
    kept = use & (np.abs(z - centre) <= cut * mad)
    w = np.where(kept, w, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.sum(w * x, axis=1) / np.sum(w, axis=1)
        var = np.sum(w * (x - mean[:, None]) ** 2, axis=1) / np.sum(w, axis=1)
        return mean, np.sqrt(var * np.sum(w**2, axis=1)) / np.sum(w, axis=1), kept


def _check(echo, array, speed, lags, t_lags, block, min_coherence, n_angles, extent) -> None:
    if not isinstance(echo, EchoData):
        raise TypeError(f"dpca.estimate echo: must be EchoData, got {type(echo).__name__}")
    validate.compression("dpca.estimate echo", echo, advice="call clsas.range_compress(echo) first, so that the "
                         "correlations are sharp")
    if not isinstance(array, Array):
        raise TypeError(f"dpca.estimate array: must be a clsas Array (the hydrophone layout), got {type(array).__name__}")
    if array.n_receivers > echo.n_rx:
        raise ValueError(f"dpca.estimate array: has {array.n_receivers} hydrophones, the echo {echo.n_rx} receivers")
    validate.positive("dpca.estimate speed", speed, unit="m/s", why="the nominal platform speed")
    validate.integer("dpca.estimate lags", lags, low=1, high=echo.n_rx)
    validate.integer("dpca.estimate block", block, low=8, high=max(8, echo.n_samples),
                     why="range-block length in samples, at most the records' length")
    validate.integer("dpca.estimate t_lags", t_lags, low=1, high=(block - 1) // 2,
                     why="the correlation must stay inside a block")
    validate.integer("dpca.estimate n_angles", n_angles, low=3, high=2**31)
    validate.scalar("dpca.estimate min_coherence", min_coherence, low=0.0, high=1.0, high_open=True)
    if isinstance(extent, str):
        validate.choice("dpca.estimate extent", extent, ("auto",))
    elif extent is not None and not isinstance(extent, SeafloorExtent):
        raise TypeError(f"dpca.estimate extent: must be a dpca.SeafloorExtent, \"auto\" or None, got "
                        f"{type(extent).__name__}")
    if echo.n_pulses < 2:
        raise ValueError(f"dpca.estimate echo: needs at least 2 pings, the echo has {echo.n_pulses}")


def _check_budget(n_couples: int, pairs: int, blocks: int, block: int, t_lags: int, n_angles: int,
                  records: int = 0, extent: bool = False) -> None:
    """Refuse before allocating what the scans need at their peak: the carrier-corrected records
    and the delayed correlations' spectra (complex64 and their float64 phases, per couple, pair,
    block and padded sample), and the beams over the look angles (complex64, magnitudes); with
    an ``extent``, look_moments' tables (about eight float64 arrays of SUB_RANGES x ANGLES per
    block, two dozen of SUB_RANGES per pair and block); besides the records aligned on one fast-time grid (``records`` samples, complex64)."""
    padded = scipy.fft.next_fast_len(2 * block - 1)
    cells = n_couples * pairs * blocks
    nbytes = max(cells * (block * 24 + padded * 32 + (2 * t_lags + 1) * 8),
                 n_angles * pairs * blocks * 3 * 24 + n_angles * n_couples * 16,
                 8 * blocks * SUB_RANGES * (8 * ANGLES + 24 * pairs) if extent else 0) + 8 * records
    budget.check_bytes(f"dpca.estimate with {pairs} ping pairs, {blocks} blocks of {block} samples, "
                       f"{n_couples} couples, n_angles={n_angles}", nbytes,
                       "fewer pings or samples a call, or fewer n_angles")


@dataclass(frozen=True)
class _Setup:
    """What :func:`_scan` needs of the array, the pairing and the look angles (see estimate)."""

    array: Array
    s: int
    lags: int
    n_couples: int
    pc: np.ndarray
    r_samples: np.ndarray
    r_blocks: np.ndarray
    speed: float
    c: float
    f0: float
    fs: float
    sin_theta: np.ndarray
    cos2: np.ndarray

    def couples(self, lag: int, every: bool) -> np.ndarray:
        """Hydrophones i at ping p + 1 of the couples of x-lag ``lag`` (their partners at ping p
        are i + s + lag): the n_couples common to every x-lag, or ``every`` couple the lag allows."""
        if not every:
            return np.arange(self.n_couples)
        return np.arange(max(0, -(self.s + lag)), self.pc.size - max(0, self.s + lag))


def _scan(setup: _Setup, prev: np.ndarray, nxt: np.ndarray, offset: np.ndarray, t_lags: int, lags=None,
          every: bool = False):
    """Beam peaks over the x-lags: (peak magnitude, delay in s, yaw in rad), each of shape
    (x-lag, pair, block) (NaN at x-lags not in ``lags``, by default all). prev, nxt :
    (hydrophone, pair, block, sample), the records of pings p and p + 1; offset : s (pair,), a
    delay to take out of nxt's envelope (not its phase) before correlating; ``every``: all the
    couples each x-lag allows (Setup.couples), the delay then referred to the common couples'
    centre through the yaw."""
    st = setup
    n_angles = st.sin_theta.size
    shape = (2 * st.lags + 1,) + prev.shape[1:3]
    peaks, delays, yaws = np.full(shape, np.nan), np.full(shape, np.nan), np.full(shape, np.nan)
    for li, lag in enumerate(range(-st.lags, st.lags + 1)):
        if lags is not None and lag not in lags:
            continue
        i = st.couples(lag, every)                       # hydrophones at ping p + 1
        j = i + st.s + lag                               # hydrophones at ping p
        # Phase-centre errors out (geometry.pca_delay): the carrier phase sample by sample, the
        # envelope at each block's centre range, together with the pair's known delay, each
        # with the block's mean cos^2 of the look angle (1 - sin2). Left in the envelope, they
        # made the couples' correlation phases depend on the speckle.
        dt_pca = pca_delay(st.array, i, j, st.r_samples, st.speed, st.c, 0.0)     # (couple, block, sample)
        g = nxt[i] * unit_phasor(2 * np.pi * st.f0 * dt_pca[:, None] * st.cos2[None, :, :, None])
        envelope = pca_delay(st.array, i, j, st.r_blocks, st.speed, st.c, 0.0)[:, None, :] * st.cos2[None] \
            + offset[:, None]
        corr = correlations(prev[j], g, t_lags, delay=envelope, fs=st.fs)   # (couple, pair, block, t-lag)
        # The t-lag of the peak is the couples' common delay (a yaw moves it by a hundredth of a
        # sample across them): found on their incoherent sum, the beams are formed at it and
        # its two neighbours only.
        m = np.clip(np.abs(corr).sum(axis=0).argmax(axis=-1), 1, 2 * t_lags - 1)          # (pair, block)
        near = np.take_along_axis(corr, (m[None, ..., None] + np.arange(-1, 2)), axis=-1)
        u = st.pc[i] - st.pc[i].mean()                   # couple positions along the track
        steer = np.exp(-1j * 4 * np.pi * st.f0 * np.outer(st.sin_theta, u) / st.c)   # (angle, couple)
        beams = (steer.astype(np.complex64) @ near.reshape(i.size, -1)).reshape((n_angles,) + near.shape[1:])
        beams = np.moveaxis(beams, 0, 2) / i.size        # (pair, block, angle, t-lag m-1 .. m+1)
        mag = np.abs(beams)
        a = np.clip(mag[..., 1].argmax(axis=-1), 1, n_angles - 2)
        pp, bb = np.indices(a.shape)
        m_off, peak = parabola(mag[pp, bb, a, 0], mag[pp, bb, a, 1], mag[pp, bb, a, 2])
        a_off, _ = parabola(mag[pp, bb, a - 1, 1], mag[pp, bb, a, 1], mag[pp, bb, a + 1, 1])
        # The parabola through the grid's three angles reads a peak short of the beam's (the beam
        # is not a parabola over a grid step: 0.3-0.4 % of the yaw at Heremans' geometry): the beam
        # formed again at the vertex and a quarter step either side, and the parabola through those
        # (its error shrinks as the step squared).
        ds = st.sin_theta[1] - st.sin_theta[0]
        probe = (st.sin_theta[a] + a_off * ds)[..., None] + 0.25 * ds * np.arange(-1, 2)     # (pair, block, 3)
        local = np.abs(np.einsum("pbkn,npb->pbk", np.exp(-1j * 4 * np.pi * st.f0 * probe[..., None] * u / st.c),
                                 near[..., 1]))
        fine_off, _ = parabola(local[..., 0], local[..., 1], local[..., 2])
        coarse = offset[:, None] - ((m - t_lags) + m_off) / st.fs
        phase = np.angle(beams[pp, bb, a, 1])
        cycles = np.round(coarse * st.f0 - phase / (2 * np.pi))
        yaws[li] = -np.arcsin(np.clip(probe[..., 1] + 0.25 * ds * fine_off, -1, 1))
        # the delay at these couples' centre, referred to the common couples' centre: a couple
        # at u moves u xi across track (dpca.integrate), a delay -2 u xi / c
        centre_shift = st.pc[i].mean() - st.pc[:st.n_couples].mean()
        delays[li] = (phase / (2 * np.pi) + cycles) / st.f0 + 2 * centre_shift * yaws[li] / st.c
        peaks[li] = peak
    return peaks, delays, yaws


def estimate(echo: EchoData, array: Array, speed: float, *, lags: int = 2, t_lags: int = 8, block: int = 128,
             n_angles: int = 65, min_coherence: float = 0.5,
             extent: SeafloorExtent | str | None = "auto") -> PingPairs:
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
    extent : where the seafloor scatters (:class:`SeafloorExtent`); None for a seafloor that
        fills the beam (a real one); "auto" (default): the seafloor of the scenario a simulated
        echo carries (``echo.scenario``, :func:`geometry.scenario_extent`: its clsas Seafloor,
        or the rectangle of its random point scatterers), None without one (recorded data).
        The phase-centre correction takes each range block's mean sin^2 of the look angle over
        the part of the beam the seafloor fills (geometry.look_moments): a patch narrower than
        the beam, or cut off inside its sidelobes, read as one that fills it biases the yaw by
        D (<sin^2>_patch - <sin^2>_beam) / r a pair (PingPairs.yaw_bias bounds it then). With
        an extent, blocks holding less than half their seafloor's weight in the main lobe are
        left out.
    """
    _check(echo, array, speed, lags, t_lags, block, min_coherence, n_angles, extent)
    if isinstance(extent, str):
        extent = scenario_extent(echo.scenario)
        log.info("dpca.estimate: the seafloor %s", "fills the beam (no simulated seafloor in echo.scenario)"
                 if extent is None else f"from echo.scenario: {extent}")
    eta = echo.eta
    prt = np.diff(eta)
    if not np.allclose(prt, prt[0], rtol=1e-9):
        raise ValueError("dpca.estimate echo: its pings must be at a constant pulse interval (echo.eta evenly spaced)")
    prf = 1.0 / prt[0]
    s, pc, n_couples = pairing(array, speed, prf, lags)
    h = array.n_receivers
    c = echo.medium.sound_speed
    f0 = echo.waveform.f0
    _check_budget(h - s, echo.n_pulses - 1, echo.n_samples // block + 1, block, t_lags, n_angles,
                  records=h * echo.n_pulses * echo.n_samples if np.ptp(echo.t0[:h]) > 0 else 0,
                  extent=extent is not None)
    records, start = aligned(echo, h)
    n_blocks = records.shape[-1] // block
    r_blocks = c / 2 * (start + (np.arange(n_blocks) + 0.5) * block / echo.fs)   # block centre ranges, m
    r_samples = (c / 2 * (start + np.arange(n_blocks * block) / echo.fs)).reshape(n_blocks, block)
    # where the couples' phase centres are when a block's echo returns: hydrophone i at ping p + 1
    # (its partner i + s at ping p coincides), halfway through the two-way travel
    ahead = pc[:n_couples].mean() - array.tx_offset[1] + speed * float(np.median(r_blocks)) / c
    centre = echo.tx_pos[1:].copy()
    centre[:, 1] += ahead
    block_span = c / 2 * block / echo.fs
    sin2, main_fraction, content = look_moments(array, f0, c, r_blocks, centre, extent, block_span, ahead)
    # blocks that hold the seafloor's near or far edge are left out of the yaw (see below)
    # and those next to them (a block's length from them: the bias reaches that far, inside_swath)
    # a horizontal displacement moves the couples' paths by its product with the line of sight's
    # across-track component (depression and look angle): the blocks' sway and yaw are divided by it
    across = across_cosine(r_blocks, centre, extent, sin2)                    # (pair, block)
    whole = inside_swath(array, f0, c, r_blocks, centre, extent, block_span, ahead, content, guard=block_span)
    data = records[..., :n_blocks * block].reshape(h, echo.n_pulses, n_blocks, block)
    step = pc[1] - pc[0]
    span = n_couples * step
    theta_max = np.arcsin(min(1.0, c / (f0 * span)))
    setup = _Setup(array=array, s=s, lags=lags, n_couples=n_couples, pc=pc, r_samples=r_samples, r_blocks=r_blocks,
                   speed=speed, c=c, f0=f0, fs=echo.fs, sin_theta=np.sin(np.linspace(-theta_max, theta_max, n_angles)),
                   cos2=1 - np.nan_to_num(sin2, nan=0.0))
    # Pass 1: every t-lag, on the records as they are.
    peaks, delays, yaws = _scan(setup, data[:, :-1], data[:, 1:], np.zeros(echo.n_pulses - 1), t_lags)
    best = np.argmax(peaks, axis=0)                      # (pair, block)
    best = np.clip(best, 1, 2 * lags - 1)
    pp, bb = np.indices(best.shape)
    lag_off = xlag_offset(peak_ratio(peaks[best - 1, pp, bb], peaks[best, pp, bb], peaks[best + 1, pp, bb]),
                          array, f0, c, step)
    coherence = peaks.max(axis=0)
    surge = ((best - lags) + lag_off) * step
    nearest = np.argmax(peaks, axis=0)
    good = (coherence >= min_coherence) & (content > 0) & (main_fraction >= MAIN_LOBE) & (across >= MIN_ACROSS)
    energy = np.einsum("hpbk,hpbk->pb", data, np.conj(data)).real   # (pulse, block)
    energy = energy[:-1] + energy[1:]
    # The main lobe's level: the third strongest coherent block (one or two bright echoes do not
    # set it). Blocks far below it can hold only off-beam returns (beyond the seafloor's swath,
    # its far along-track ends seen at wide look angles) or range sidelobes, however many of
    # them there are: referred to the median block instead, a seafloor much longer than the
    # beam whose records reach far beyond its swath let them in (they were the majority) and
    # read hundreds of urad a pair (tests/test_dpca_bias.py).
    ranked = np.sort(np.where(good, energy, 0.0), axis=1)[:, ::-1]
    level = ranked[np.arange(ranked.shape[0]), np.clip(np.sum(good, axis=1) - 1, 0, 2)]
    good &= energy >= WEAK_BLOCK * level[:, None]
    counts = good.sum(axis=1)
    if np.any(counts == 0):
        worst = int(np.argmin(counts))
        raise EstimationError(f"dpca: ping pair {worst}-{worst + 1} has no range block with a beam peak >= "
                         f"min_coherence {min_coherence} (best {coherence[worst].max():.2f}) that holds the seafloor "
                         f"in its main lobe ({int(np.sum(main_fraction[worst] >= MAIN_LOBE))} of {n_blocks} blocks "
                         "do, by the extent): the pings do not correlate (too little overlap, or no seafloor return "
                         "in the records), or the seafloor's extent does not reach the beam")
    typical = np.nanmedian(np.where(good, energy, np.nan), axis=1, keepdims=True)

    # Surge: a block dominated by a lone bright echo stays coherent at every x-lag (a single
    # scatterer decorrelates only over its whole beam), so its beam peaks hardly change with the
    # displacement and read a surge near zero; such blocks are left out of the surge where
    # seafloor blocks remain (on Heremans' nine points they shrank the surge).
    seafloor = good & (energy <= BRIGHT_BLOCK * typical)
    seafloor[seafloor.sum(axis=1) == 0] = good[seafloor.sum(axis=1) == 0]

    def robust_mean(x, use=good, weight=None):
        """The blocks' mean and its standard error, blocks beyond OUTLIER scaled MADs of the
        median left out (speckle makes a block's error roughly Gaussian; a block holding the
        edge of the swath, off-beam returns or a lone bright echo can sit far out); median and
        MAD weighted by the blocks' energy up to the median block's (weak blocks, off-beam
        returns among them, count for little; a bright echo's block counts as one seafloor
        block); the mean weighted by ``weight`` (pair, block)
        if given, the standard error then over the effective number of blocks."""
        votes = np.where(use, np.minimum(energy, typical), 0.0)
        med = _weighted_median(x, votes)[:, None]
        mad = 1.4826 * _weighted_median(np.abs(x - med), votes)[:, None]
        kept = use & (np.abs(x - med) <= OUTLIER * mad)
        w = np.where(kept, 1.0 if weight is None else weight, 0.0)
        x = np.where(kept, x, 0.0)
        mean = np.sum(w * x, axis=1) / np.sum(w, axis=1)
        var = np.sum(w * (x - mean[:, None]) ** 2, axis=1) / np.sum(w, axis=1)
        return mean, np.sqrt(var * np.sum(w**2, axis=1)) / np.sum(w, axis=1)

    # Pass 2: ping p + 1's envelope advanced by the pair's delay, so that the couples' phases are
    # read at the correlation peak (see the package docstring: a fractional-sample misalignment
    # turns speckle into yaw noise), over FINE_T_LAGS, at the x-lags nearest for some block and
    # with every couple each of them allows (a longer baseline for the yaw).
    shift, _ = robust_mean(delays[nearest, pp, bb])
    fine, delays, yaws = _scan(setup, data[:, :-1], data[:, 1:], shift, FINE_T_LAGS,
                               lags={int(k) - lags for k in np.unique(nearest[good])}, every=True)
    across = np.maximum(across, MIN_ACROSS)  # the blocks below it are not good: no division by ~0
    sway = -c * delays[nearest, pp, bb] / 2 / across
    yaw = yaws[nearest, pp, bb] / across
    # The sway's blocks weighted by their coherence rho (pass 2's beam peak): the phase of a
    # correlation over N samples at coherence rho has variance (1 - rho^2) / (2 N rho^2), the same
    # N in every block. Not the yaw's: a block's coherence and its yaw error are correlated (the
    # blocks that hold more of the seafloor's wide look angles decorrelate more and read a more
    # negative yaw), so weighting by it biased the yaw positive on a motionless platform
    # (bench/bench_dpca.py --bias).
    rho = np.clip(fine[nearest, pp, bb], 0.0, 1 - 1e-9)
    weight = rho**2 / (1 - rho**2)
    # The yaw from the blocks clear of the seafloor's range edges (geometry.inside_swath), unless a
    # pair has none left (a swath narrower than three or four blocks: flagged in
    # PingPairs.yaw_from_edges); the sway and surge keep the edge blocks (the bias measured there
    # is the yaw's).
    inside = good & whole
    lacking = ~inside.any(axis=1)
    if np.any(lacking):
        log.warning("dpca.estimate: %d ping pairs have no usable range block clear of the seafloor's range edges "
                    "(its swath is narrower than three or four blocks): their yaw comes from the edge "
                    "blocks and may be biased (PingPairs.yaw_from_edges)", int(lacking.sum()))
        inside[lacking] = good[lacking]
    # The yaw: the blocks' yaws pooled, weighted by their coherent energy (why: the package
    # docstring, "Pooling the blocks' yaws"); a block holding a bright echo (over BRIGHT_BLOCK
    # typical blocks' energy) counts as one typical block, as in the medians' votes.
    bright = energy > BRIGHT_BLOCK * typical
    coherent = rho * np.where(bright, typical, energy)
    # the narrow cut within SIDELOBE_BLOCKS of a bright block (its range sidelobes), the wide one elsewhere
    near = np.zeros_like(bright)
    for k in range(1, SIDELOBE_BLOCKS + 1):
        near[:, k:] |= bright[:, :-k]
        near[:, :-k] |= bright[:, k:]
    (su, su_e), (sw, sw_e) = robust_mean(surge, seafloor), robust_mean(sway, good, weight)
    yw, yw_e, kept = pooled_mean(yaw, inside, coherent, cut=np.where(near & ~bright, OUTLIER, YAW_OUTLIER))
    coh = np.nanmedian(np.where(good, coherence, np.nan), axis=1)
    log.info("dpca: %d ping pairs, %d couples, %d range blocks; median coherence %.2f", echo.n_pulses - 1,
             n_couples, n_blocks, float(np.median(coh)))
    two_way = float(np.median(2 * r_blocks[good.any(axis=0)] / c))
    bias = 0.0 if extent is not None else s * step * (beam_sin2(array, f0, c) - main_lobe_sin2(array, f0, c)) \
        / (c * two_way / 2)
    return PingPairs(surge=su, sway=sw, yaw=yw, surge_std=su_e, sway_std=sw_e, yaw_std=yw_e, coherence=coh,
                     blocks=counts, lags=lags, two_way=two_way, yaw_bias=np.full(su.shape, abs(bias)),
                     yaw_from_edges=lacking, block_yaw=np.where(good, yaw, np.nan), block_inside=inside,
                     block_range=r_blocks, block_weight=np.where(kept, coherent, 0.0))
