"""One receiver's range-compressed records for the moving-target chain (:mod:`.chain`): the
:class:`Records` a receiver's echo becomes (step 1 of the chain: range compression, upsampled by
:data:`UPSAMPLE`), and the range band an echo with intra-pulse Doppler wraps into
(:func:`wrapped_band`, zeroed by :func:`without_wrapped_band` before the focus)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.fft

from ... import validate
from ...image.rangecomp import range_compress
from ...model import EchoData
from .layout import range_doppler

#: Range upsampling of the compressed records.
UPSAMPLE = 2
#: The band :func:`wrapped_band` zeroes reaches this fraction of the bandwidth beyond the
#: target's largest Doppler centroid over the aperture.
WRAP_MARGIN = 0.01


@dataclass(frozen=True)
class Records:
    """One receiver's range-compressed record: x (n_pulses, n_samples) at fast times
    t0 + k / fs after each emission eta (n_pulses,); f0 the carrier and bandwidth the chirp's, Hz;
    range_doppler (s/Hz) the layout's (:func:`.layout.range_doppler`: 0 for an echo synthesized
    without intra-pulse Doppler); fs_raw the raw echo's sampling rate, Hz (fs / :data:`UPSAMPLE`);
    pulse_length the transmitted pulse's duration T, s (nan when not known)."""

    x: np.ndarray
    eta: np.ndarray
    t0: float
    fs: float
    f0: float
    bandwidth: float
    name: str
    range_doppler: float = 0.0
    pulse_length: float = float("nan")

    @property
    def fs_raw(self) -> float:
        return self.fs / UPSAMPLE

    @property
    def prf(self) -> float:
        return (self.eta.size - 1) / float(np.ptp(self.eta))

    @property
    def eta_ref(self) -> float:
        """The middle of the record, s: the slow time the chain expands the delay about (the
        layout's default eta_ref, where the closed forms give their Taylor coefficients)."""
        return 0.5 * float(self.eta[0] + self.eta[-1])

    @property
    def d(self) -> np.ndarray:
        """eta - eta_ref (n_pulses,), s."""
        return self.eta - self.eta_ref


def check_pulse_times(echo: EchoData) -> None:
    """ValueError unless ``echo`` holds >= 64 pulses emitted at one PRF (eta increasing,
    uniformly spaced)."""
    if echo.n_pulses < 64:
        raise ValueError(f"echo has {echo.n_pulses} pulses; the moving-target chain needs at least 64")
    step = np.diff(echo.eta)
    if not np.all(step > 0):
        raise ValueError(f"echo.eta must increase from pulse to pulse (one PRF), got steps from {step.min():g} to "
                         f"{step.max():g} s")
    if np.ptp(step) > 1e-6 * np.mean(step):
        raise ValueError("echo.eta must be uniformly spaced (one PRF) for the moving-target chain")


def compressed_receiver(echo: EchoData, receiver: str) -> EchoData:
    """``receiver``'s record of a raw ``echo`` as a one-receiver EchoData, range-compressed (eq. 8)
    and upsampled :data:`UPSAMPLE` times, after checking the echo (raw, >= 64 uniformly spaced
    pulses)."""
    if not isinstance(echo, EchoData):
        raise TypeError(f"echo must be an EchoData, got {type(echo).__name__}")
    validate.compression("echo", echo, compressed=False, advice="the chain range-compresses it itself (eq. 8)")
    if not isinstance(receiver, str):
        raise TypeError(f"receiver must be a receiver name (one of {echo.receivers}), got {receiver!r}")
    (r,) = echo.select_receivers(receiver, parameter="receiver")
    check_pulse_times(echo)
    one = echo.replace(data=echo.data[r:r + 1], t0=echo.t0[r:r + 1], rx_pos=echo.rx_pos[r:r + 1],
                       rx_tau=echo.rx_tau[r:r + 1], receivers=(receiver,))
    return range_compress(one, upsample=UPSAMPLE)


def records_of(comp: EchoData) -> Records:
    """The :class:`Records` of a one-receiver range-compressed EchoData (:func:`compressed_receiver`)."""
    return Records(x=comp.data[0], eta=comp.eta, t0=float(comp.t0[0]), fs=comp.fs, f0=comp.waveform.f0,
                   bandwidth=comp.waveform.bandwidth, name=comp.receivers[0], range_doppler=range_doppler(comp),
                   pulse_length=float(comp.waveform.duration))


def wrapped_band(rec: Records, doppler_centroid: float, fm_rate: float) -> list[tuple[float, float]]:
    """[(lo, hi), ...], Hz: the range-frequency bands of ``rec`` where the target's echo lands
    wrapped around the raw sampling rate (none, one or both edges of the sampled band).

    With intra-pulse Doppler (``rec.range_doppler`` != 0) the echo is the chirp shifted in
    frequency by -f_D (:mod:`.layout`; f_D = f_dc + K d over the aperture): its band
    [-B / 2 - f_D, B / 2 - f_D]. Where the raw sampling rate F_r leaves less than |f_D| beyond
    B / 2 (Table I: F_r = B), the band's far edge wraps to the opposite edge of the sampled band,
    [-F_r / 2, -F_r / 2 + B / 2 + |f_D| - F_r / 2] for f_D < 0 (mirrored for f_D > 0: the
    band's lower edge wraps to the top). The matched filter compresses that sliver T after (or
    before) the target, and its slow-time phase is that of the carrier f0 -+ F_r: a Doppler
    f_dc F_r / f0 (aliased by the PRF) away from the target's, so it focuses as a ghost T away
    in range and seconds away in eta, which the extent took for part of the target (Table II
    speeds with |f_dc| > ~600 Hz at 512 pulses). The real echo holds nothing in that band. A
    guard band (F_r > B + 2 max |f_D|) would keep the echo unwrapped, but Table I fixes F_r = B_r
    = 20 kHz, so :func:`clsas.scene.presets.kiang2022` keeps the paper's rate and the chain and
    :func:`clsas.focus_moving` zero the band instead.

    f_D runs over f_dc -+ |K| T_a / 2: when that interval holds both signs (a small centroid over
    a long aperture) both edges wrap, each by its own extreme. Each band reaches
    :data:`WRAP_MARGIN` x B beyond its extreme (the scatterers' centroids differ by a few Hz)."""
    if rec.range_doppler == 0.0:
        return []
    sweep = 0.5 * abs(fm_rate) * float(np.ptp(rec.eta))
    margin = WRAP_MARGIN * rec.bandwidth
    edge = 0.5 * rec.fs_raw
    bands = []
    # f_D > 0: the band moves down, its lower edge -B/2 - f_D passes -F_r/2 and lands at the top
    for extreme, top in ((doppler_centroid + sweep, True), (doppler_centroid - sweep, False)):
        reach = (extreme if top else -extreme) + margin
        excess = 0.5 * rec.bandwidth + reach - edge
        if not np.isfinite(excess) or excess <= 0.0 or reach <= margin:
            continue
        excess = min(excess, rec.fs_raw)
        bands.append((edge - excess, edge) if top else (-edge, -edge + excess))
    return bands


def without_wrapped_band(rec: Records, doppler_centroid: float, fm_rate: float) -> Records:
    """``rec`` with its :func:`wrapped_band` s zeroed in range frequency (the ghost of the echo's
    wrapped band edges removed), or ``rec`` itself when there is none."""
    bands = wrapped_band(rec, doppler_centroid, fm_rate)
    if not bands:
        return rec
    n = rec.x.shape[1]
    f = scipy.fft.fftfreq(n, 1.0 / rec.fs)
    keep = np.ones(n, bool)
    for lo, hi in bands:
        keep &= ~((f >= lo) & (f <= hi))
    spec = scipy.fft.fft(rec.x, axis=1, workers=-1)
    spec *= keep[None, :]
    return dataclasses.replace(rec, x=scipy.fft.ifft(spec, axis=1, workers=-1).astype(np.complex64))


def records(echo: EchoData, receiver: str) -> Records:
    """Step 1: ``receiver``'s record of a raw ``echo``, range-compressed (eq. 8) and upsampled
    :data:`UPSAMPLE` times (:func:`compressed_receiver`)."""
    return records_of(compressed_receiver(echo, receiver))
