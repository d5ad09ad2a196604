"""DPCA micronavigation: surge, sway and yaw between consecutive pings from the echoes of
overlapping phase centres (Heremans, Dupont & Acheroy 2009, section 5, eqs. 50-70), the
trajectory they integrate to (eqs. 71-73), and the motion compensation (eqs. 74-75).

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

Surge (eq. 68): the beam peak's magnitude is largest for the x-lag whose couples coincide; a
parabola through the best lag and its neighbours gives the fractional lag B, and the surge
(the along-track advance beyond D) is B Delta_PC = B d / 2.

Range blocks and uncertainty: the fast-time axis is cut into blocks; each block gives its own
estimate of the three quantities, the reported value is the median over blocks whose beam peak
reaches ``min_coherence``, and its uncertainty is 1.25 x (the blocks' standard deviation) /
sqrt(number of blocks) (the standard error of a median).

The hot loop, the correlations over ping pairs, x-lags, couples, t-lags and samples, is one
vectorised NumPy contraction per t-lag over every pair, couple and block at once, and the
beamforming one complex matrix product; bench/bench_dpca.py measures it (tens of ms a ping
pair for 15 hydrophones x 2048 samples). A blocked FFT correlation measured the same within
noise (it computes every lag where 2 t_lags + 1 are needed), and the work per ping pair is a
few million multiply-adds, so no OpenCL kernel: DPCA's cost is small beside the imaging.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.fft

from ..data import EchoData
from ..scene.scenario import Array, Platform, Scenario

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


@dataclass(frozen=True, eq=False)
class Trajectory:
    """The track integrated from the ping pairs (eqs. 71-73), relative to the first ping.

    eta : s (n_pulses,); along, cross : m, the platform's reference point relative to the
    nominal straight track and to its place at the first ping (along: beyond v eta, i.e.
    surge; cross: towards +x, i.e. sway); heading : rad (yaw, from heading0 at the first ping); along_std, cross_std, heading_std : propagated standard errors
    (eq. 73); pairs : the PingPairs.
    """

    eta: np.ndarray
    along: np.ndarray
    cross: np.ndarray
    heading: np.ndarray
    along_std: np.ndarray
    cross_std: np.ndarray
    heading_std: np.ndarray
    pairs: PingPairs

    @property
    def times(self) -> np.ndarray:
        """When the track holds these values, s: each ping's emission plus half the two-way
        travel time to the scene. DPCA compares transmit-and-receive paths, so it measures the
        mean of the platform's place at emission and at reception."""
        return self.eta + self.pairs.two_way / 2

    def platform(self, speed: float, start=(0.0, 0.0, 0.0), surge: bool = True) -> Platform:
        """A clsas Platform flying this track (for :func:`with_track` and back-projection):
        surge, sway and yaw sampled at :attr:`times`, held constant one ping interval beyond
        the first and the last so that every emission and reception is covered. ``surge=False``
        flies the nominal along-track advance instead of the estimated one (DPCA's surge is a
        random walk of its per-pair errors: on scenes with little seafloor it can hurt more
        than the surge it corrects)."""
        step = float(np.median(np.diff(self.eta)))
        times = np.concatenate([[self.times[0] - step], self.times, [self.times[-1] + step]])
        hold = lambda a: np.concatenate([[a[0]], a, [a[-1]]])  # noqa: E731
        along = self.along if surge else np.zeros_like(self.along)
        return Platform(speed=speed, start=start, surge=hold(along), sway=hold(self.cross),
                        yaw=hold(self.heading), error_times=times)


# Range blocks holding less than this fraction of a ping pair's median block energy are left
# out: beyond the seafloor's swath only range sidelobes and the far edges of the beam remain,
# scatterers seen at large look angles only, whose phase-centre error (D sin^2 theta / r per
# pair as a yaw, see _pca_delay) is far from the beam's mean. Measured on Heremans' nine-point
# scene: such blocks read -950 .. +860 urad of yaw where the seafloor's read 0 +- 15.
WEAK_BLOCK = 0.1
# Blocks further than this many scaled median absolute deviations from a pair's median are left
# out of its mean (see estimate).
OUTLIER = 3.0


def _parabola(y_minus, y0, y_plus):
    """Vertex offset (in samples, within [-0.5, 0.5] for a true maximum) and value of the parabola
    through (-1, y_minus), (0, y0), (1, y_plus) (Heremans et al. 2009, eq. 67)."""
    den = y_minus - 2 * y0 + y_plus
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where(den < 0, 0.5 * (y_minus - y_plus) / den, 0.0)
    off = np.clip(off, -0.5, 0.5)
    return off, y0 - 0.25 * (y_minus - y_plus) * off


def _vee(y_minus, y0, y_plus):
    """Vertex offset of the symmetric V (|slope| equal on both sides) through three
    points at -1, 0, 1: the x-lag peak. The coherence of two phase centres falls off linearly
    with their displacement (the overlap of two element apertures), rho(e) = 1 - |e| / w; from
    y0 = 1 - |e|/w and y_+- = 1 - |1 -+ e|/w follows q = (y+ - y-) / (2 y0 - y+ - y-) =
    e / (1 - |e|), so e = q / (1 + |q|). (A parabola through the same points returns q / 2:
    half the true offset for small e.)"""
    den = 2 * y0 - y_plus - y_minus
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(den > 0, (y_plus - y_minus) / den, 0.0)
    return np.clip(q / (1 + np.abs(q)), -0.5, 0.5)


def beam_sin2(array: Array, f0: float, c: float) -> float:
    """<sin^2 theta> over the two-way power pattern of the transmitter and the hydrophones,
    P(theta) = sinc^2(L_tx sin(theta) / lambda) sinc^2(L_rx sin(theta) / lambda) (clsas's element
    directivity, squared once for the transmit leg and once for the receive leg), theta the look
    angle off broadside over a seafloor that fills the beam: the weight of a scatterer at theta in
    the couples' correlations. 0 if both elements are omnidirectional (length 0: the beam is
    then the scene's, which the array cannot know). Heremans' 21.88 cm elements at 3 cm: 1.2e-3."""
    lam = c / f0
    lengths = (array.tx_length, float(np.mean(array.rx_length)))
    if max(lengths) == 0:
        return 0.0
    sin_t = np.sin(np.linspace(-np.pi / 2, np.pi / 2, 20001))
    power = np.prod([np.sinc(length * sin_t / lam) ** 2 for length in lengths], axis=0)
    return float(np.sum(sin_t**2 * power) / np.sum(power))


def _pca_delay(array: Array, i: np.ndarray, j: np.ndarray, r: np.ndarray, speed: float, c: float,
               sin2: float) -> np.ndarray:
    """dt_pca, s (couple,) + r.shape: the difference, ping p + 1 minus ping p, of the couple
    members' phase-centre errors at range r (m, any shape) (eqs. 48-49). Two-way path of a
    transmitter and a hydrophone a separation sigma apart along the track, to a scatterer at
    range r and look angle theta off broadside: 2 |S - M| + sigma^2 cos^2(theta) / (4 r), M
    their midpoint (the phase centre; the sigma^3 terms cancel between the two legs). sigma_h
    is the separation of the transmitter at emission and hydrophone h at reception,
    o_h - o_tx + v 2 r / c: the platform moves on while the echo travels. A range block
    mixes scatterers across the beam, so cos^2 is replaced by its mean over the beam,
    1 - ``sin2`` (:func:`beam_sin2`).

    Left in, the difference reads as a yaw (its part linear along the couples: 1.53 m x 2 u / r
    at Heremans' geometry, 7.7 mrad at 100 m) and as a sway (its constant part, through the
    v 2 r / c term: 0.65 mm a ping pair there). Taken at the block's centre range instead of
    each sample's, it leaves 7.7 mrad x (r_scatterer - r_block) / r: tens of urad for a bright
    point off the block centre. Left at broadside (sin2 = 0), it leaves D <sin^2 theta> / r per
    ping pair as a yaw (D = v PRT, the couples' separation; 9 urad a pair at Heremans' 100 m),
    which integrates into a quadratic cross-track error along the track."""
    sigma = (array.rx_offsets[:, 1] - array.tx_offset[1]).reshape((-1,) + (1,) * r.ndim) + speed * 2 * r / c
    return (sigma[i] ** 2 - sigma[j] ** 2) * (1 - sin2) / (4 * r * c)


def nominal_shift(array: Array, speed: float, prf: float) -> tuple[int, np.ndarray]:
    """The nominal pairing of eq. (50): (s, phase-centre along-track offsets o_h / 2 in m).

    s = v PRT / Delta_PC rounded; hydrophone i + s at ping p and i at ping p + 1 coincide."""
    pc = 0.5 * (array.rx_offsets[:, 1] + array.tx_offset[1])
    order = np.argsort(pc)
    if np.any(order != np.arange(pc.size)):
        raise ValueError("dpca: the hydrophones must be numbered along the track (increasing body y)")
    steps = np.diff(pc)
    if pc.size < 3 or not np.allclose(steps, steps[0], rtol=1e-6):
        raise ValueError(f"dpca needs a uniform line of >= 3 hydrophones, got phase-centre offsets {pc}")
    shift = speed / prf / steps[0]
    s = int(round(shift))
    return s, pc


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


def correlations(f: np.ndarray, g: np.ndarray, t_lags: int) -> np.ndarray:
    """Normalised cross-correlations of eq. (51) over range blocks.

    f, g : complex (..., n_blocks, block) — the ping-p and ping-(p + 1) records of each couple;
    returns complex64 (..., n_blocks, 2 t_lags + 1): c[m] = sum_k f[k + m] g*[k] /
    sqrt(sum |f|^2 sum |g|^2), m = -t_lags..t_lags, samples beyond the block ignored (the grey
    bins of Fig. 17)."""
    n = f.shape[-1]
    norm = np.sqrt(np.sum(np.abs(f) ** 2, axis=-1) * np.sum(np.abs(g) ** 2, axis=-1))
    g_conj = np.conj(g)
    out = np.empty(f.shape[:-1] + (2 * t_lags + 1,), dtype=np.complex64)
    for i, m in enumerate(range(-t_lags, t_lags + 1)):
        lo, hi = max(0, -m), min(n, n - m)
        out[..., i] = np.einsum("...k,...k->...", f[..., lo + m:hi + m], g_conj[..., lo:hi])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm[..., None] > 0, out / norm[..., None], 0).astype(np.complex64)


def _aligned(echo: EchoData, h: int) -> tuple[np.ndarray, float]:
    """The first ``h`` receivers' records on one fast-time grid: (complex64 (h, pulse, sample),
    fast time of sample 0 in s). Records whose windows start whole samples apart are shifted
    into place (zeros outside a window); other offsets are refused."""
    start = float(echo.t0[:h].min())
    offset = (echo.t0[:h] - start) * echo.fs
    shift = np.round(offset).astype(int)
    if np.any(np.abs(offset - shift) > 1e-6):
        raise ValueError("dpca needs the hydrophones' records to start a whole number of samples apart "
                         f"(echo.t0 offsets {offset} samples)")
    if not shift.any():
        return echo.data[:h], start
    out = np.zeros((h, echo.n_pulses, echo.n_samples + shift.max()), dtype=np.complex64)
    for k in range(h):
        out[k, :, shift[k]:shift[k] + echo.n_samples] = echo.data[k]
    return out, start


def estimate(echo: EchoData, array: Array, speed: float, *, lags: int = 2, t_lags: int = 8, block: int = 128,
             n_angles: int = 65, min_coherence: float = 0.5) -> PingPairs:
    """Surge, sway and yaw between every pair of consecutive pings (see the module docstring).

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
    records, start = _aligned(echo, h)
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
        pca = np.exp(2j * np.pi * f0 * _pca_delay(array, i, j, r_samples, speed, c, sin2)).astype(np.complex64)
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
        m_off, peak = _parabola(mag[pp, bb, a, m - 1], mag[pp, bb, a, m], mag[pp, bb, a, m + 1])
        a_off, _ = _parabola(mag[pp, bb, a - 1, m], mag[pp, bb, a, m], mag[pp, bb, a + 1, m])
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
    lag_off = _vee(peaks[best - 1, pp, bb], peaks[best, pp, bb], peaks[best + 1, pp, bb])
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


def integrate(pairs: PingPairs, eta: np.ndarray, speed: float, array: Array, heading0: float = 0.0) -> Trajectory:
    """The platform track from the ping pairs (eqs. 71-72) and its errors (eq. 73), relative to
    the first ping; positions of the platform's reference point (its centre of rotation).

    DPCA measures changes of heading only: ``heading0`` (rad) is the yaw at the first ping, from
    the vehicle's compass or INS. An error e in it tilts the whole track by e (a cross-track
    drift of D e a ping), which rotates the image slightly but does not defocus it.

    Derivation (clsas's axes and Platform.rotation: a body offset b along the track sits at
    b sin(yaw) across track). Couple n pairs hydrophone j at ping p with hydrophone i at ping
    p + 1, body phase-centre offsets pc_j = pc_i + D (D = v PRT). Its measured cross-track
    displacement is gamma_n = X_{p+1} - X_p + pc_i sin(theta_{p+1}) - pc_j sin(theta_p)
    = dX_p + pc_i xi_p - D theta_p (small angles), so the slope along the couples is the yaw
    step xi_p, and at the couples' centre u (mean pc_i) the sway reads gamma_p = dX_p + u xi_p
    - D theta_p. Hence
        theta_{p+1} = theta_p + xi_p,
        X_{p+1} = X_p + gamma_p - u xi_p + D theta_p,
        Y_{p+1} = Y_p + D + surge_p,
    which is eq. (71) written for the centre of rotation instead of the phase-centre group.
    Errors accumulate as in eq. (73): var X_p = sum_l var gamma_l + sum_l (D (p - l - 1) - u)^2
    var xi_l (the yaw of pair l enters through theta for every later pair), var theta_p =
    sum_l var xi_l.
    """
    eta = np.asarray(eta, dtype=np.float64)
    if eta.shape != (pairs.sway.size + 1,):
        raise ValueError(f"integrate: eta must have {pairs.sway.size + 1} pings, got {eta.shape}")
    prf = 1.0 / float(np.median(np.diff(eta)))
    s, pc = nominal_shift(array, speed, prf)
    u = pc[:array.n_receivers - s - pairs.lags].mean()
    d = speed / prf
    if not np.isfinite(heading0) or abs(heading0) > 0.5:
        raise ValueError(f"integrate: heading0 must be a finite yaw in [-0.5, 0.5] rad, got {heading0!r}")
    heading = heading0 + np.concatenate([[0.0], np.cumsum(pairs.yaw)])
    cross = np.concatenate([[0.0], np.cumsum(pairs.sway - u * pairs.yaw + d * heading[:-1])])
    along = np.concatenate([[0.0], np.cumsum(pairs.surge)])
    n = eta.size
    p = np.arange(n)[:, None]
    l_ = np.arange(n - 1)[None, :]
    before = (l_ < p).astype(np.float64)
    arm = before * (d * (p - l_ - 1) - u)
    cross_std = np.sqrt(before @ pairs.sway_std**2 + arm**2 @ pairs.yaw_std**2)
    heading_std = np.sqrt(before @ pairs.yaw_std**2)
    along_std = np.sqrt(before @ pairs.surge_std**2)
    return Trajectory(eta=eta, along=along, cross=cross, heading=heading, along_std=along_std, cross_std=cross_std,
                      heading_std=heading_std, pairs=pairs)


def with_track(echo: EchoData, scenario: Scenario) -> EchoData:
    """``echo`` with its geometry (transmitter at emission, receiver nodes) recomputed for the
    sonar and platform of ``scenario`` (e.g. a Platform from :meth:`Trajectory.platform`), so that
    :func:`clsas.backproject` images along that track; the samples are unchanged."""
    if scenario.n_receivers != echo.n_rx or scenario.eta.shape != echo.eta.shape or \
            not np.allclose(scenario.eta, echo.eta):
        raise ValueError("with_track: the scenario must have the echo's receivers and emission times")
    tx = scenario.tx_position(echo.eta)
    t = echo.eta[None, :, None] + echo.rx_tau[:, None, :]
    rx = np.stack([scenario.receiver_position(h, t[h]) for h in range(echo.n_rx)])
    return echo.replace(tx_pos=tx, rx_pos=rx, provenance={**echo.provenance, "track": "replaced (dpca.with_track)"})


def compensate(echo: EchoData, trajectory: Trajectory, scenario: Scenario, workers: int | None = -1) -> EchoData:
    """Motion compensation of eqs. (74)-(75): each hydrophone's record delayed back by
    dt = dt_sway + dt_yaw{h} (eqs. 34, 38: dt_sway = -2 sway / c, dt_yaw{h} = -(o_h - o_tx) sin(yaw) / c,
    the receiver's cross-track move under yaw with the transmitter at the centre of rotation), by
    the phase exp(+j 2 pi (f0 + f) dt) over the record's baseband frequencies f; the geometry is
    replaced by the nominal straight track of ``scenario`` so that omega_k, range_doppler and
    chirp_scaling accept the result. Surge (along-track) is not corrected by this delay model."""
    h = scenario.array.n_receivers
    if trajectory.eta.shape != echo.eta.shape:
        raise ValueError("compensate: the trajectory must have one value per ping of the echo")
    c = echo.medium.sound_speed
    lever = scenario.array.rx_offsets[:, 1] - scenario.array.tx_offset[1]
    dt = (-2 * trajectory.cross[None, :] - lever[:, None] * np.sin(trajectory.heading)[None, :]) / c  # (h, pulse)
    f = scipy.fft.fftfreq(echo.n_samples, 1 / echo.fs)
    spec = scipy.fft.fft(echo.data[:h], axis=-1, workers=workers)
    spec *= np.exp(2j * np.pi * (echo.waveform.f0 + f)[None, None, :] * dt[..., None])
    data = echo.data.copy()
    data[:h] = scipy.fft.ifft(spec, axis=-1, workers=workers)
    straight = scenario.replace(platform=Platform(speed=scenario.platform.speed, start=scenario.platform.start))
    out = with_track(echo.replace(data=data), straight)
    return out.replace(provenance={**echo.provenance, "motion_compensation": "dpca (Heremans et al. 2009, eqs. 74-75)"})
