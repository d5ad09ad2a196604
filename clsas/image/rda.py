"""Range-Doppler imaging with sub-block secondary range compression: Huang & Yang 2022, eqs. (19)-(25).

On a range-compressed :class:`~clsas.image.record.LineRecord` (monostatic, or a multireceiver
record converted by :func:`clsas.image.multireceiver.pca_record`), with
beta(k_u) = sqrt(1 - (k_u / 2 k0)^2) (eq. 20 with f_t = v k_u / (2 pi), so that
lambda f_t / (2 v) = k_u / (2 k0)):

1. Along-track FFT: the range-Doppler domain (tau, k_u).
2. Secondary range compression (eqs. 21-22): the residual range modulation, the third term of
   eq. 19, 2 pi r lambda / c^2 (1 / beta^3 - 1 / beta) f_tau^2 (the chirp itself is already
   compressed, so eq. 22's 1 / gamma is gone), is removed in the 2-D frequency domain with r the
   centre r_n of each range sub-block; the sub-blocks are as wide as the paper's criterion
   allows (the phase error within half a block below pi / 16 at the band edge f_tau = B / 2).
3. Range-cell-migration correction (eq. 23): a target at closest range r lies at
   tau = 2 r / (c beta); column tau_out = 2 r / c reads tau_out / beta (windowed-sinc interpolation,
   :func:`clsas.interp.resample`).
4. Azimuth compression (eq. 24): exp(+j 2 k0 beta r), with r = c tau_out / 2 (the data carry
   exp(-j sqrt(4 k0^2 - k_u^2) r - j k_u y) = exp(-j 2 k0 beta r - j k_u y)); the
   non-stop-and-go along-track shift (eq. 25); the inverse along-track FFT.

Approximations (those of the paper): the quasi-monostatic phase is expanded to second order in
f_tau (eq. 19); the SRC is exact only at each sub-block's centre.
"""

from __future__ import annotations

import itertools

import numpy as np
import scipy.fft

from ..interp import resample
from .checks import check_imager
from .record import along_track_wavenumbers, as_record, azimuth_weights, check_elements, image_of, nonstop_shift


def src_block_width(rec, beta_min: float) -> float:
    """Widest range sub-block (m) whose SRC phase error stays below pi / 16 within half a block at
    f_tau = B / 2 (Huang & Yang 2022, after eq. 22)."""
    c, lam = rec.medium.sound_speed, rec.wavelength
    slope = 2 * np.pi * lam / c**2 * (1 / beta_min**3 - 1 / beta_min) * (rec.waveform.bandwidth / 2) ** 2
    return np.inf if slope == 0 else 2 * (np.pi / 16) / slope


def range_doppler(data, receiver=0, elements=None, deconvolve: bool = True, window: str = "none", interp: str = "sinc8",
                  depth: float | None = None, workers: int | None = None, backend: str | None = None,
                  **window_options):
    """Focus a straight-track record with the range-Doppler algorithm (see the module docstring).

    Parameters are those of :func:`clsas.image.omegak.omega_k`: ``elements`` (L_tx, L_rx) limit
    the processed Doppler band to |k_u| <= 2 pi / max(L) and (``deconvolve``) undo the element pattern,
    ``window`` weights that band (the range weighting is the range compression's),
    ``interp`` is the RCMC interpolator ("linear", "sinc8", "sinc16") and ``backend`` where it
    (and an EchoData's path-excess interpolation) runs.

    Returns
    -------
    Image, dims ("y", "x").
    """
    window_options, workers = check_imager("range_doppler", data, window, window_options, workers, depth)
    rec = as_record(data, receiver, backend)
    elements = check_elements(elements, rec)
    c, f0, fs = rec.medium.sound_speed, rec.waveform.f0, rec.fs
    k0 = 2 * np.pi * f0 / c
    n_r = rec.n_samples
    n_ku = scipy.fft.next_fast_len(rec.n_u)
    ku = along_track_wavenumbers(rec, n_ku)
    beta = np.sqrt(np.clip(1 - (ku / (2 * k0)) ** 2, 1e-6, None))
    tau = rec.t0 + np.arange(n_r) / fs
    r = c * tau / 2

    rd = scipy.fft.fft(rec.data, n=n_ku, axis=0, workers=workers)
    # secondary range compression by sub-blocks (eqs. 21-22)
    f = np.fft.fftfreq(n_r, 1 / fs)
    two_d = scipy.fft.fft(rd, axis=1, workers=workers)
    width = src_block_width(rec, beta.min())
    n_blocks = max(1, int(np.ceil((r[-1] - r[0]) / width)))
    edges = np.linspace(0, n_r, n_blocks + 1).astype(int)
    coupling = (1 / beta**3 - 1 / beta)[:, None] * f[None, :] ** 2
    for lo, hi in itertools.pairwise(edges):
        r_n = r[(lo + hi - 1) // 2]
        src = np.exp(-2j * np.pi * r_n * rec.wavelength / c**2 * coupling)
        rd[:, lo:hi] = scipy.fft.ifft(two_d * src, axis=1, workers=workers)[:, lo:hi]
    # range-cell-migration correction (eq. 23)
    idx = (tau[None, :] / beta[:, None] - rec.t0) * fs
    rd = resample(rd, idx, interp, oversampling=max(fs / rec.waveform.bandwidth, 1.01), backend=backend)
    # azimuth compression (eq. 24), Doppler band and weighting, along-track shift (eq. 25)
    rd *= np.exp(2j * k0 * np.outer(beta, r)) * azimuth_weights(ku, elements, window, deconvolve, **window_options)[:, None]
    rd *= nonstop_shift(rec, ku, r)
    return image_of(rec, rd, r, "range_doppler", {"elements": elements, "deconvolve": deconvolve, "window": window, "interp": interp,
                                                  "src_blocks": n_blocks}, depth)
