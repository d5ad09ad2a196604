"""The moving-target chain's filters and their exact inverses (Kiang & Kiang 2022, eqs. 17-20).

Range cell migration correction and range-walk compensation are one range-frequency phase ramp
per pulse. The RCMC filter exp(j pi f_tau K eta^2 / f0) (after eq. 16) advances the record by
d_q = K eta^2 / (2 f0); the RW filter exp(j 2 pi (f0 + f_tau) (f_dc / f0) eta) (after eq. 17;
the extraction prints its sign both ways, eqs. H_rw1 and H_rw2: the sign that cancels the walk
is the one used) advances it by d_w = f_dc eta / f0 and removes the linear azimuth phase
exp(-j 2 pi f_dc eta). :func:`advance` applies both (and, with negated arguments, undoes them).

Azimuth compression (eqs. 18-20). The paper filters the azimuth spectrum with
H_ac = exp(-j pi f_eta^2 / K) (eq. 19). That is the stationary-phase form of the matched filter
and it needs the azimuth chirp to be sampled: K T_a < PRF. With Table I (K T_a ~ 390 Hz against
80 Hz) the chirp's spectrum wraps about five times; each wrapped piece, a fifth of the aperture,
is compressed by H_ac with a group delay off by k PRF / K, so the target splits into ~5 lobes of
a fifth of the coherent gain each. clsas compresses instead by deramping ("SPECAN"):

    y(f) = sum_n s(eta_n) exp(+j pi K eta_n^2) exp(-j 2 pi f eta_n),   eta = f / K.

Since sum_n s(eta_n) exp(+j pi K (eta_n - eta)^2) = exp(j pi K eta^2) y(K eta), this is the
discrete matched filter with the sampled reference chirp (any K T_a against the PRF), read at
eta = f / K. It is periodic in eta with period PRF / K: on an aliased aperture the matched filter
itself repeats there (the grating lobes of an undersampled aperture; a target and its copies
PRF / K apart give the same samples up to the aperture's ends), so one period, centred on the
target's focus at eta = 0, holds the whole image. With K T_a < PRF it is eq. (20)'s image. The
deramp and the FFT are unitary, so the inverse (:func:`decompress`) is exact.
"""

from __future__ import annotations

import os

import numpy as np
import scipy.fft


def advance(records: np.ndarray, fs: float, shift: np.ndarray, carrier_hz: np.ndarray | None = None,
            workers: int | None = None, block: int = 512) -> np.ndarray:
    """x(tau + shift[n]) for each pulse n (shift in s, (n_pulses,)), times exp(j 2 pi carrier_hz[n])
    when given: multiply the range spectrum by exp(j 2 pi f_tau shift). The FFT is zero-padded by
    the largest shift, so nothing wraps into the record; returns complex64 of the same shape."""
    workers = os.cpu_count() if workers is None else int(workers)
    n_pulses, n = records.shape
    pad = int(np.ceil(np.max(np.abs(shift)) * fs)) + 8
    n_fft = scipy.fft.next_fast_len(n + pad)
    # exp(j 2 pi shift f_k), f_k = k fs / n_fft (minus fs for the upper half), as the product of
    # a coarse and a fine table: one complex product a cell instead of one exponential
    split = int(np.ceil(np.sqrt(n_fft)))
    k = np.arange(split)
    out = np.empty(records.shape, dtype=np.complex64)
    for s in range(0, n_pulses, block):
        sl = slice(s, min(s + block, n_pulses))
        cycles = shift[sl, None] * (fs / n_fft)
        ramp = (np.exp(2j * np.pi * cycles * split * k)[:, :, None] * np.exp(2j * np.pi * cycles * k)[:, None, :])
        ramp = ramp.reshape(ramp.shape[0], -1)[:, :n_fft]
        ramp[:, (n_fft + 1) // 2:] *= np.exp(-2j * np.pi * shift[sl] * fs)[:, None]
        if carrier_hz is not None:
            ramp *= np.exp(2j * np.pi * carrier_hz[sl])[:, None]
        spec = scipy.fft.fft(records[sl], n=n_fft, axis=1, workers=workers)
        spec *= ramp
        out[sl] = scipy.fft.ifft(spec, axis=1, workers=workers)[:, :n]
    return out


def migration(eta: np.ndarray, f0: float, fm_rate: float, doppler_centroid: float,
              higher_order: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(shift, carrier phase in cycles) of RCMC + RW compensation: shift = K eta^2 / (2 f0) +
    f_dc eta / f0, cycles = f_dc eta. ``higher_order`` (n_pulses,) s, the delay's terms beyond
    the quadratic: added to the shift, and f0 times it to the cycles (its whole carrier phase:
    the quadratic's is removed by :func:`compress`'s deramp)."""
    shift, cycles = fm_rate * eta**2 / (2 * f0) + doppler_centroid * eta / f0, doppler_centroid * eta
    if higher_order is not None:
        shift, cycles = shift + higher_order, cycles + f0 * higher_order
    return shift, cycles


def compress(records: np.ndarray, eta: np.ndarray, fm_rate: float, pad: int = 2,
             workers: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Deramp-FFT azimuth compression of ``records`` (n_pulses, n_bins) after RCMC and RWC.

    Returns (image (n_eta, n_bins) complex64, eta axis (n_eta,) s, ascending): n_eta =
    ``pad`` x n_pulses bins spanning one period PRF / |K| centred on eta = 0.
    """
    workers = os.cpu_count() if workers is None else int(workers)
    n_pulses = records.shape[0]
    prf = (n_pulses - 1) / np.ptp(eta)
    n_eta = scipy.fft.next_fast_len(pad * n_pulses)
    deramped = records * np.exp(1j * np.pi * fm_rate * eta**2)[:, None]
    spec = scipy.fft.fft(deramped, n=n_eta, axis=0, workers=workers)
    # bin k is f = k prf / n_eta; the phase of eta_0 makes each bin exact: exp(-j 2 pi f eta_0)
    f = scipy.fft.fftfreq(n_eta, 1.0 / prf)
    spec *= np.exp(-2j * np.pi * f * eta[0])[:, None]
    order = np.argsort(f / fm_rate)
    return spec[order].astype(np.complex64), (f / fm_rate)[order]


def decompress(image: np.ndarray, eta: np.ndarray, fm_rate: float, workers: int | None = None) -> np.ndarray:
    """The inverse of :func:`compress` for records at slow times ``eta``: (n_pulses, n_bins) complex64."""
    workers = os.cpu_count() if workers is None else int(workers)
    n_pulses = eta.size
    n_eta = image.shape[0]
    prf = (n_pulses - 1) / np.ptp(eta)
    f = scipy.fft.fftfreq(n_eta, 1.0 / prf)
    order = np.argsort(f / fm_rate)
    spec = np.empty_like(image, dtype=np.complex128)
    spec[order] = image
    spec *= np.exp(2j * np.pi * f * eta[0])[:, None]
    records = scipy.fft.ifft(spec, axis=0, workers=workers)[:n_pulses]
    return (records * np.exp(-1j * np.pi * fm_rate * eta**2)[:, None]).astype(np.complex64)
