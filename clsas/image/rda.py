"""Range-Doppler imaging with sub-block secondary range compression: Huang & Yang 2022, eqs. (19)-(25).

On a range-compressed :class:`~clsas.image.record.LineRecord` (monostatic, or a multireceiver
record converted by :func:`clsas.image.multireceiver.pca_record`), with
beta(k_u) = sqrt(1 - (k_u / 2 k0)^2) (eq. 20 with f_t = v k_u / (2 pi), so that
lambda f_t / (2 v) = k_u / (2 k0)):

1. Along-track FFT: the range-Doppler domain (tau, k_u), the rows of the processed band
   (:mod:`clsas.image.strip`).
2. Secondary range compression (eqs. 21-22): the residual range modulation, the third term of
   eq. 19, 2 pi r lambda / c^2 (1 / beta^3 - 1 / beta) f_tau^2 (the chirp itself is already
   compressed, so eq. 22's 1 / gamma is gone), is removed in the 2-D frequency domain with r the
   centre r_n of each range sub-block; the sub-blocks are as wide as the paper's criterion
   allows (the phase error within half a block below pi / 16 at the band edge f_tau = B / 2,
   at the largest sampled |k_u|). Each sub-block is filtered by overlap-save
   (:func:`compress_secondary`): its columns and a margin on each side as long as the filter's
   impulse response, range FFT, filter, IFFT, keep the block's columns. The filter
   exp(-j 2 pi r_n a f_tau^2), a = lambda / c^2 (1 / beta^3 - 1 / beta), delays frequency f_tau
   by its group delay 2 r_n a f_tau, at most r_n a fs at |f_tau| = fs / 2: a margin of
   r_n a fs^2 samples (plus a guard) holds the whole response, so each block costs its own span
   instead of the whole record (the record stays circular in range, as one FFT of it is).
3. Range-cell-migration correction (eq. 23): a target at closest range r lies at
   tau = 2 r / (c beta); column tau_out = 2 r / c reads tau_out / beta (the template's
   interpolator, :func:`clsas.interp.resample`).
4. Azimuth compression (eq. 24): exp(+j 2 k0 beta r), with r = c tau_out / 2 (the data carry
   exp(-j sqrt(4 k0^2 - k_u^2) r - j k_u y) = exp(-j 2 k0 beta r - j k_u y)); the band's
   weights, the non-stop-and-go along-track shift (eq. 25) and the inverse along-track FFT are
   the template's (:func:`clsas.image.strip.strip_image`).

Approximations (those of the paper): the quasi-monostatic phase is expanded to second order in
f_tau (eq. 19); the SRC is exact only at each sub-block's centre.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from ..interp import resample
from ..kernelmath import unit_phasor
from ..model import Image
from .strip import block_segment, follows_template, range_blocks, strip_image, strip_job

SRC_TOLERANCE = np.pi / 16  # rad: the SRC phase error allowed within half a sub-block (Huang & Yang 2022, after eq. 22)
SRC_GUARD = 32  # samples added to each side of a sub-block beyond the SRC filter's longest group delay


def src_block_width(wavelength: float, c: float, bandwidth: float, beta_min: float) -> float:
    """Widest range sub-block (m) whose SRC phase error stays below pi / 16 within half a block at
    f_tau = B / 2 (Huang & Yang 2022, after eq. 22), for the smallest beta of the Doppler rows."""
    slope = 2 * np.pi * wavelength / c**2 * (1 / beta_min**3 - 1 / beta_min) * (bandwidth / 2) ** 2
    return np.inf if slope == 0 else 2 * SRC_TOLERANCE / slope


def compress_secondary(rd: np.ndarray, coupling: np.ndarray, blocks, fs: float, workers: int) -> np.ndarray:
    """Secondary range compression of range-Doppler rows ``rd`` (n_rows, n), sub-block by
    sub-block by overlap-save (module docstring, step 2): columns [lo, hi) of block (lo, hi, r_n)
    filtered by exp(-j 2 pi r_n coupling f_tau^2), ``coupling`` (n_rows,) in s^2 / m.
    complex (n_rows, n)."""
    n = rd.shape[1]
    longest = max(r_n for _, _, r_n in blocks) * np.abs(coupling).max() * fs**2  # samples of group delay
    margin = int(np.ceil(longest)) + SRC_GUARD
    out = np.empty_like(rd)
    for lo, hi, r_n in blocks:
        columns, pad = block_segment(lo, hi, margin, n)
        f = np.fft.fftfreq(columns.size, 1 / fs)
        segment = scipy.fft.fft(rd[:, columns], axis=1, workers=workers)
        segment *= unit_phasor(np.outer(-2 * np.pi * r_n * coupling, f**2))
        out[:, lo:hi] = scipy.fft.ifft(segment, axis=1, workers=workers)[:, pad:pad + hi - lo]
    return out


@follows_template
def range_doppler(data, **options) -> Image:
    """Focus a straight-track record with the range-Doppler algorithm (see the module docstring).

    ``options`` are the strip-map template's (:func:`clsas.image.strip.strip_job`: receiver,
    elements, deconvolve, window, interp, tap_window, depth, workers, backend); ``interp`` also
    runs the migration correction. Returns an Image, dims ("y", "x").
    """
    job = strip_job("range_doppler", data, **options)
    rec = job.record
    c, f0, fs = rec.medium.sound_speed, rec.waveform.f0, rec.fs
    k0 = 2 * np.pi * f0 / c
    beta = np.sqrt(np.clip(1 - (job.ku / (2 * k0)) ** 2, 1e-6, None))
    tau = rec.t0 + np.arange(rec.n_samples) / fs
    r = c * tau / 2
    beta_min = np.sqrt(max(1 - (job.ku_nyquist / (2 * k0)) ** 2, 1e-6))
    blocks = range_blocks(r, src_block_width(rec.wavelength, c, rec.waveform.bandwidth, beta_min))
    rd = compress_secondary(job.doppler(rec.data), rec.wavelength / c**2 * (1 / beta**3 - 1 / beta), blocks, fs,
                            job.workers)
    idx = (tau[None, :] / beta[:, None] - rec.t0) * fs  # eq. 23
    rd = resample(rd, idx, job.interp, job.tap_window, job.oversampling, backend=job.backend)
    rd *= unit_phasor(2 * k0 * np.outer(beta, r))  # eq. 24
    return strip_image(job, rd, r, src_blocks=len(blocks))
