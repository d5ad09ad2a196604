"""The wavenumber (omega-k) imager: Heremans, Dupont & Acheroy 2009, section 4, eqs. (40)-(47).

On a :class:`~clsas.image.record.LineRecord` s(tau, u) (range-compressed, so the P_b^* of
eq. 42 is already applied), with k = 2 pi (f0 + f_b) / c:

1. 2-D FFT (scipy.fft, ``workers`` threads): S(f_b, k_u). The range FFT starts at the record's
   fast time t0, so exp(-j 2 pi f_b t0) restores absolute delays; a target at (r, y) then has
   S ~ sqrt(pi r / (i k)) exp(-i sqrt(4k^2 - k_u^2) r - i k_u y) (eq. 40).
2. Reference-range matched filter (eq. 42): sqrt(k / k0) exp(+i sqrt(4k^2 - k_u^2) r0), r0 the
   middle of the recorded ranges; evanescent components (4k^2 < k_u^2) are dropped. (Eq. 42's
   "- 2k" in the exponent belongs to data whose time origin is 2 r0 / c; with absolute times
   it is not needed.)
3. Stolt mapping (eq. 41, :mod:`clsas.image.stolt`) onto the uniform baseband
   k_x' = sqrt(4k^2 - k_u^2) - 2 k0, spaced 4 pi df / c (one output column per input one).
4. Extraction and weighting (eqs. 44-45): the rectangle |k_y| <= B_ky / 2 = 2 pi / D and
   2 k_min - 2 k0 <= k_x' <= sqrt(4 k_max^2 - (2 pi / D)^2) - 2 k0, a 2-D window over it
   (``window``: "none", "hamming", "taylor", "kaiser"; :func:`clsas.pulse.spectral_window`,
   whose Hamming 0.54 + 0.46 cos is eq. 46's 0.5386 - 0.46164 cos to 0.2 %; over k_y it is the
   template's band weighting, :mod:`clsas.image.strip`), and the element-pattern deconvolution
   1 / A(k_y) with A = sinc(L_tx k_y / 4 pi) sinc(L_rx k_y / 4 pi) (the one-way pattern
   sinc(L sin(theta) / lambda) with sin(theta) = k_y / 2k, eq. 33, does not depend on k).
   Without ``elements`` the whole sampled k_y band is kept, unweighted by the pattern.
5. Inverse FFT over k_x' (column j at r = r0 + (j - n/2) c / (2 fs)), the phase
   exp(+i (k_x'_first + 2 k0)(r - r0)) that makes a focused point's phase zero (as
   back-projection's); the non-stop-and-go along-track shift (Huang & Yang 2022 eq. 25) and
   the inverse FFT over k_y are the template's (:func:`clsas.image.strip.strip_image`).

Resolution (eq. 47): delta x = alpha_w c / (2 B), delta y = alpha_w D / 2, alpha_w = 0.886 for
no window and 1.30 for Hamming.

What stays approximate with non-stop-and-go data: the receiver's motion during the echo is
taken as the constant shift v r / c at the target's range and the path excess of
:func:`clsas.image.record.path_excess` at the sample's range (second order in v / c).
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from ..kernelmath import unit_phasor
from ..model import Image
from ..pulse import spectral_window
from .stolt import StoltAxes, stolt
from .strip import follows_template, strip_image, strip_job


@follows_template
def omega_k(data, **options) -> Image:
    """Focus a straight-track strip-map record with the wavenumber algorithm (see the module docstring).

    ``options`` are the strip-map template's (:func:`clsas.image.strip.strip_job`): ``window``
    weights the whole extracted rectangle (k_x' and k_y), ``interp`` and ``tap_window`` are the
    Stolt interpolator's (:func:`clsas.image.stolt.stolt`). Returns an Image, dims ("y", "x"):
    along-track by across-track on the plane z = depth.
    """
    job = strip_job("omega_k", data, **options)
    rec, workers = job.record, job.workers
    c, f0, fs = rec.medium.sound_speed, rec.waveform.f0, rec.fs
    bandwidth = rec.waveform.bandwidth
    n_r = scipy.fft.next_fast_len(rec.n_samples)
    f = (np.arange(n_r) - n_r // 2) * fs / n_r
    k0 = 2 * np.pi * f0 / c
    k = 2 * np.pi * (f0 + f) / c
    r0 = c * (rec.t0 + rec.n_samples / (2 * fs)) / 2

    spec = scipy.fft.fftshift(scipy.fft.fft(job.doppler(rec.data), n=n_r, axis=1, workers=workers), axes=1)
    kx2 = 4 * k[None, :] ** 2 - job.ku[:, None] ** 2
    spec *= unit_phasor(np.sqrt(np.maximum(kx2, 0.0)) * r0)  # eq. 42
    spec *= np.where(kx2 > 0, (np.sqrt(k / k0) * np.exp(-2j * np.pi * f * rec.t0))[None, :], 0).astype(np.complex64)

    dkx = 4 * np.pi * fs / n_r / c
    axes = StoltAxes(f_first=f[0], df=fs / n_r, n_src=n_r, kx_first=4 * np.pi * f[0] / c, dkx=dkx, n_out=n_r,
                     f0=f0, c=c)
    mapped = stolt(spec, job.ku, axes, job.interp, job.tap_window, oversampling=job.oversampling,
                   backend=job.backend)  # eq. 41

    ky_edge = 2 * np.pi / max(job.elements) if job.elements is not None else np.pi / rec.du
    kx_lo = 2 * (2 * np.pi * (f0 - bandwidth / 2) / c) - 2 * k0
    kx_hi = np.sqrt(4 * (2 * np.pi * (f0 + bandwidth / 2) / c) ** 2 - ky_edge ** 2) - 2 * k0
    kxp = axes.kx_first + dkx * np.arange(n_r)
    range_w = np.where((kxp >= kx_lo) & (kxp <= kx_hi),
                       spectral_window((kxp - (kx_lo + kx_hi) / 2) / (kx_hi - kx_lo), job.window,
                                       **job.window_options), 0.0)  # eqs. 44-45 over k_x'
    mapped *= range_w[None, :]

    ku_r = scipy.fft.fftshift(scipy.fft.ifft(mapped, axis=1, workers=workers), axes=1)
    r = r0 + (np.arange(n_r) - n_r // 2) * c / (2 * fs)
    ku_r *= np.exp(1j * (axes.kx_first + 2 * k0) * (r - r0)).astype(np.complex64)[None, :]
    return strip_image(job, ku_r, r)
