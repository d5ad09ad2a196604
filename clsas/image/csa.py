"""Chirp-scaling imaging, the standard algorithm of Cumming & Wong, "Digital Processing of
Synthetic Aperture Radar Data" (Artech House, 2005), chapter 7 (eqs. 7.17-7.33 there).

Chirp scaling works on the uncompressed chirp: a range-compressed
:class:`~clsas.image.record.LineRecord` is first re-spread by the chirp's own spectral phase,
exp(-j pi f_tau^2 / K) (the stationary-phase spectrum of rect(t/T) exp(j pi K t^2), Heremans
2009 eq. 22), with the range axis zero-padded by the pulse length so the spread chirps do not
wrap. Then, with D(k_u) = sqrt(1 - (k_u / 2 k0)^2) (C&W's migration factor with
f_eta = v k_u / (2 pi)), D_ref = D(0) = 1 and R_ref the middle of the recorded ranges:

1. Along-track FFT: range-Doppler domain.
2. Chirp scaling (C&W eq. 7.30): exp(j pi K_m (D_ref / D - 1) (tau - 2 R_ref / (c D))^2), with the
   range FM rate in the range-Doppler domain K_m = K / (1 - K c R_ref f_eta^2 / (2 v^2 f0^3 D^3))
   (C&W eq. 7.18), which equalises every range's migration to that of R_ref.
3. Range FFT; range compression with SRC and bulk RCMC (C&W eq. 7.32):
   exp(j pi D / (K_m D_ref) f_tau^2) exp(j 4 pi R_ref f_tau (1 / D - 1 / D_ref) / c); range IFFT.
4. Azimuth compression and residual-phase correction (C&W eq. 7.33):
   exp(j 4 pi R0 f0 D / c) exp(-j 4 pi K_m (1 - D / D_ref) (R0 / D - R_ref / D_ref)^2 / c^2), R0 = c tau / 2;
   the Doppler band and its weighting; the non-stop-and-go along-track shift
   (Huang & Yang 2022 eq. 25); along-track IFFT.

C&W write the received signal as exp(-j 4 pi f0 R / c) exp(j pi K (tau - 2R/c)^2): the same
signs as clsas's baseband model (DESIGN.md), so their filters apply unchanged.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from .checks import check_imager
from .record import along_track_wavenumbers, as_record, azimuth_weights, check_elements, image_of, nonstop_shift


def chirp_scaling(data, receiver=0, elements=None, deconvolve: bool = True, window: str = "none", depth: float | None = None,
                  workers: int | None = None, backend: str | None = None, **window_options):
    """Focus a straight-track record with the chirp-scaling algorithm (see the module docstring).

    Parameters as :func:`clsas.image.rda.range_doppler` (no interpolator: chirp scaling needs
    none; ``backend`` runs an EchoData's path-excess interpolation). Returns an Image, dims ("y", "x").
    """
    window_options, workers = check_imager("chirp_scaling", data, window, window_options, workers, depth)
    rec = as_record(data, receiver, backend)
    elements = check_elements(elements, rec)
    c, f0, fs, v = rec.medium.sound_speed, rec.waveform.f0, rec.fs, rec.speed
    chirp_rate = rec.waveform.bandwidth / rec.waveform.duration
    k0 = 2 * np.pi * f0 / c
    n_r = scipy.fft.next_fast_len(rec.n_samples + int(np.ceil(rec.waveform.duration * fs)))
    n_ku = scipy.fft.next_fast_len(rec.n_u)
    ku = along_track_wavenumbers(rec, n_ku)
    f = np.fft.fftfreq(n_r, 1 / fs)
    tau = rec.t0 + np.arange(n_r) / fs
    r0 = c * tau / 2
    r_ref = c * (rec.t0 + rec.n_samples / (2 * fs)) / 2
    d = np.sqrt(np.clip(1 - (ku / (2 * k0)) ** 2, 1e-6, None))[:, None]
    f_eta = (v * ku / (2 * np.pi))[:, None]
    k_m = chirp_rate / (1 - chirp_rate * c * r_ref * f_eta**2 / (2 * v**2 * f0**3 * d**3))

    spectrum = scipy.fft.fft(rec.data, n=n_r, axis=1, workers=workers) * np.exp(-1j * np.pi * f**2 / chirp_rate)
    rd = scipy.fft.fft(scipy.fft.ifft(spectrum, axis=1, workers=workers), n=n_ku, axis=0, workers=workers)
    rd *= np.exp(1j * np.pi * k_m * (1 / d - 1) * (tau[None, :] - 2 * r_ref / (c * d)) ** 2)
    two_d = scipy.fft.fft(rd, axis=1, workers=workers)
    two_d *= np.exp(1j * np.pi * d / k_m * f[None, :] ** 2) * np.exp(4j * np.pi * r_ref * f[None, :] * (1 / d - 1) / c)
    rd = scipy.fft.ifft(two_d, axis=1, workers=workers)
    rd *= np.exp(4j * np.pi * f0 * r0[None, :] * d / c)
    rd *= np.exp(-4j * np.pi * k_m * (1 - d) * (r0[None, :] / d - r_ref) ** 2 / c**2)
    rd *= azimuth_weights(ku, elements, window, deconvolve, **window_options)[:, None] * nonstop_shift(rec, ku, r0)
    return image_of(rec, rd, r0, "chirp_scaling", {"elements": elements, "deconvolve": deconvolve, "window": window}, depth)
