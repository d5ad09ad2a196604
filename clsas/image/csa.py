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
   exp(j 4 pi R0 f0 D / c) exp(-j 4 pi K_m (1 - D / D_ref) ((R0 - R_ref) / D)^2 / c^2), R0 = c tau / 2
   (derivation: a target at R0 lies at tau_c = 2 R0 / (c D), Delta = tau_c - 2 R_ref / (c D) from
   the scaling's centre; the scaling adds pi q2 (t + Delta)^2 to its pi K_m t^2, t = tau - tau_c,
   q2 = K_m (D_ref / D - 1); completing the square leaves pi q2 Delta^2 (1 - q2 / (K_m + q2)) =
   pi K_m (1 - D / D_ref) Delta^2 at the compressed peak. The form (R0 / D - R_ref / D_ref)^2
   differs from it by a phase linear in R0 on every Doppler row and defocuses points far from
   R_ref: tests/test_csa.py);
   the Doppler band's weights, the non-stop-and-go along-track shift (Huang & Yang 2022
   eq. 25) and the along-track IFFT are the template's (:mod:`clsas.image.strip`).

C&W write the received signal as exp(-j 4 pi f0 R / c) exp(j pi K (tau - 2R/c)^2): the same
signs as clsas's baseband model (docs/design.md), so their filters apply unchanged.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from ..kernelmath import unit_phasor
from ..model import Image
from .strip import follows_template, strip_image, strip_job

BYTES_PER_SAMPLE = 64  # per padded range sample: the 2-D arrays (complex64) and the phase screens (float64)


@follows_template
def chirp_scaling(data, **options) -> Image:
    """Focus a straight-track record with the chirp-scaling algorithm (see the module docstring).

    ``options`` are the strip-map template's (:func:`clsas.image.strip.strip_job`); chirp
    scaling itself interpolates nothing (``interp`` serves an EchoData's path-excess
    compensation). Returns an Image, dims ("y", "x").
    """
    job = strip_job("chirp_scaling", data, **options)
    rec, workers = job.record, job.workers
    c, f0, fs, v = rec.medium.sound_speed, rec.waveform.f0, rec.fs, rec.speed
    chirp_rate = rec.waveform.bandwidth / rec.waveform.duration
    k0 = 2 * np.pi * f0 / c
    n_r = scipy.fft.next_fast_len(rec.n_samples + int(np.ceil(rec.waveform.duration * fs)))
    job.check_budget(n_r, BYTES_PER_SAMPLE)
    f = np.fft.fftfreq(n_r, 1 / fs)
    tau = rec.t0 + np.arange(n_r) / fs
    r0 = c * tau / 2
    r_ref = c * (rec.t0 + rec.n_samples / (2 * fs)) / 2
    d = np.sqrt(np.clip(1 - (job.ku / (2 * k0)) ** 2, 1e-6, None))[:, None]
    f_eta = (v * job.ku / (2 * np.pi))[:, None]
    k_m = chirp_rate / (1 - chirp_rate * c * r_ref * f_eta**2 / (2 * v**2 * f0**3 * d**3))  # C&W eq. 7.18

    # re-spread the chirp (a filter along range: it commutes with the along-track FFT)
    spectrum = scipy.fft.fft(job.doppler(rec.data), n=n_r, axis=1, workers=workers)
    spectrum *= unit_phasor(-np.pi * f**2 / chirp_rate)
    rd = scipy.fft.ifft(spectrum, axis=1, workers=workers)
    rd *= unit_phasor(np.pi * k_m * (1 / d - 1) * (tau[None, :] - 2 * r_ref / (c * d)) ** 2)  # eq. 7.30
    two_d = scipy.fft.fft(rd, axis=1, workers=workers)
    two_d *= unit_phasor(np.pi * d / k_m * f[None, :] ** 2 + 4 * np.pi * r_ref * f[None, :] * (1 / d - 1) / c)  # eq. 7.32
    rd = scipy.fft.ifft(two_d, axis=1, workers=workers)
    rd *= unit_phasor(4 * np.pi * f0 * r0[None, :] * d / c
                      - 4 * np.pi * k_m * (1 - d) * ((r0[None, :] - r_ref) / d) ** 2 / c**2)  # eq. 7.33
    return strip_image(job, rd, r0)
