"""Azimuth FM rate from the range-frequency reversal transform (RFRT) and the modified
second-order Wigner-Ville distribution (SoWVD): Kiang & Kiang 2022, eqs. (10)-(14).

RFRT at tau_0 = 0 (eqs. 10-11). For one pulse, let x_k be the range-compressed record and
X(f) its range spectrum. S_rfrt(f) = X(f) X(-f); its inverse FFT at lag 0 is

    s_rfrt(0, eta) = (1/N) sum_f X(f) X(-f) = sum_k x_k x_k        (no conjugate)

(write X(f) X(-f) = sum_{k,l} x_k x_l exp(-j 2 pi f (k - l) / N) and sum over f). For a point
target x_k = A sinc(B (t_k - tau(eta))) exp(-j 2 pi f0 tau(eta)), so

    s_rfrt(0, eta) = A^2 (sum_k sinc^2) exp(-j 4 pi f0 tau(eta)),

the range migration gone (eq. 11) and the azimuth phase doubled. ``weight`` restricts the sum to
the cells where the echo stands out of the noise (:func:`clsas.estimate.moving.trace.support`):
summed over a whole record of N cells, the noise term sum n_k^2 has a standard deviation sqrt(N)
times the noise power while the echo contributes one cell's worth, which at -15 dB SNR buries
the echo before the SoWVD sees it. The paper sums over the whole record; with the weight this is
the same sum restricted to where there is signal (all of it for noise-free echoes).

Modified SoWVD (eq. 12) with the lag offset p0 = q / PRF, on lags p = 2 m / PRF:

    s_wv[m, n] = s[n+m] s*[n-m] (s[n+m+q] s*[n-m-q])* = g[n+m] g[n-m-q],   g[k] = s[k] s*[k+q].

With s = exp(j phi), phi(eta) = -2 pi (2 f_dc eta + K eta^2) (the RFRT's doubled phase), the
phase of s_wv is phi(n+m) - phi(n-m) - phi(n+m+q) + phi(n-m-q) = 8 pi K p0 eta + 8 pi f_dc p0:
independent of the lag p and linear in eta, so its 2-D Fourier transform (eq. 13) peaks at
(f_p, f_eta) = (0, 4 p0 K) (eq. 14) and K = f_eta / (4 p0).

Azimuth aliasing. The four samples of each product are taken at whole pulses, so the product's
phase is the exact combination above whatever the azimuth chirp's bandwidth against the PRF
(Table I: K T_a ~ 390 Hz, doubled to ~780 Hz by the RFRT, against 80 Hz): the RFRT and the
SoWVD are not affected by azimuth aliasing. The only ambiguity is that of the peak itself:
f_eta = 4 p0 K is read modulo the PRF, so |K| < PRF / (8 p0) (100 Hz/s for p0 = 0.1 s at
80 Hz; 25 Hz/s at 20 Hz). K is an average over the aperture: on a hyperbolic range history
K(eta) falls off away from the closest approach (about 1 % over Table I's 80 s in case 1,
which is the paper's own 4.834 against 4.879 Hz/s).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import scipy.fft


def rfrt(records: np.ndarray, weight: np.ndarray | None = None) -> np.ndarray:
    """s_rfrt(tau_0 = 0, eta) of eq. (11) for range-compressed ``records`` (n_pulses, n_samples).

    ``weight`` (same shape, bool or real) multiplies each cell (None: every cell). Returns
    complex128 (n_pulses,).
    """
    x = np.asarray(records)
    if x.ndim != 2:
        raise ValueError(f"records must be 2-D (pulse, sample), got shape {x.shape}")
    out = np.empty(x.shape[0], dtype=np.complex128)
    for s in range(0, x.shape[0], 256):
        block = x[s:s + 256].astype(np.complex128)
        sq = block * block
        if weight is not None:
            sq *= weight[s:s + 256]
        out[s:s + 256] = sq.sum(axis=1)
    return out


@dataclass(frozen=True)
class SoWVD:
    """|S_wv(f_p, f_eta)| of eq. (13) and its strongest peak.

    magnitude : float32 (n_fp, n_feta), axes ``f_p`` (Hz, over the lag p) and ``f_eta`` (Hz),
        both ascending (FFT-shifted); ``p0`` the lag offset, s.
    peak_f_eta : Hz, the strongest peak's f_eta refined below one bin; ``fm_rate`` = that / (4 p0).
    peak_to_background : the peak over the median of ``magnitude`` (linear; noise-only maps give
        15-20 dB in 20 log10).
    """

    magnitude: np.ndarray
    f_p: np.ndarray
    f_eta: np.ndarray
    p0: float
    peak_f_eta: float
    peak_f_p: float
    peak_to_background: float

    @property
    def fm_rate(self) -> float:
        """K_a,eq = f_eta / (4 p0), Hz/s (eq. 14)."""
        return self.peak_f_eta / (4 * self.p0)


def lag_products(s: np.ndarray, q: int, n_lags: int) -> np.ndarray:
    """s_wv[m, n] = g[n+m] g[n-m-q] (eq. 12), g[k] = s[k] s*[k+q]; zero where a sample falls
    outside the record. Returns complex64 (n_lags, n_pulses)."""
    s = np.asarray(s, dtype=np.complex128)
    m_pulses = s.size
    off = n_lags + q
    g = np.zeros(m_pulses + 2 * off + 1, dtype=np.complex128)
    g[off:off + m_pulses - q] = s[:m_pulses - q] * np.conj(s[q:])
    n = np.arange(m_pulses)
    out = np.empty((n_lags, m_pulses), dtype=np.complex64)
    step = max(1, (1 << 22) // m_pulses)
    for m0 in range(0, n_lags, step):
        m = np.arange(m0, min(m0 + step, n_lags))[:, None]
        out[m0:m0 + m.shape[0]] = g[off + n + m] * g[off + n - m - q]
    return out


def _refine_peak(row: np.ndarray, prf: float, f_coarse: float, bin_hz: float) -> float:
    """The f_eta of the largest |DTFT| of ``row`` (pulse rate ``prf``) within one bin of
    ``f_coarse``: 65-point zoom, then a parabola through the best three (log magnitude)."""
    f = f_coarse + np.linspace(-bin_hz, bin_hz, 65)
    n = np.arange(row.size)
    mag = np.abs(np.exp(-2j * np.pi * np.outer(f / prf, n)) @ row)
    i = int(np.clip(np.argmax(mag), 1, f.size - 2))
    a, b, c = np.log(mag[i - 1:i + 2] + 1e-300)
    den = a - 2 * b + c
    shift = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(f[i] + shift * (f[1] - f[0]))


def modified_sowvd(s: np.ndarray, prf: float, p0: float, n_lags: int | None = None,
                   workers: int | None = None) -> SoWVD:
    """The modified SoWVD of the RFRT line ``s`` (n_pulses,) sampled at ``prf`` (eqs. 12-14).

    ``p0`` (s) is rounded to a whole number q >= 1 of pulses; lags p = 2 m / PRF for
    m < ``n_lags`` (default half the pulses: lags up to the whole aperture). The map is the
    2-D FFT over (m, n) of :func:`lag_products`; its strongest peak gives K = f_eta / (4 p0)
    after a sub-bin refinement along its f_p row. Cost O(n_lags n_pulses log), memory
    ~16 n_lags n_pulses bytes (Table I: 3200 x 6400, 0.3 GB).
    """
    s = np.asarray(s)
    m_pulses = s.size
    q = int(round(p0 * prf))
    if q < 1 or q > m_pulses // 4:
        raise ValueError(f"p0 must be between one pulse (1/PRF = {1 / prf:.4g} s) and a quarter of the "
                         f"aperture ({m_pulses // 4 / prf:.4g} s), got {p0}")
    n_lags = m_pulses // 2 if n_lags is None else int(n_lags)
    if not 2 <= n_lags <= m_pulses // 2:
        raise ValueError(f"n_lags must be in [2, {m_pulses // 2}], got {n_lags}")
    workers = os.cpu_count() if workers is None else int(workers)
    products = lag_products(s, q, n_lags)
    spectrum = scipy.fft.fft2(products, workers=workers)
    magnitude = np.abs(spectrum).astype(np.float32)
    del spectrum
    f_p = scipy.fft.fftfreq(n_lags, d=2.0 / prf)
    f_eta = scipy.fft.fftfreq(m_pulses, d=1.0 / prf)
    i_p, i_eta = np.unravel_index(int(np.argmax(magnitude)), magnitude.shape)
    background = float(np.median(magnitude[::2, ::2]))  # a quarter of the cells: same median
    ratio = float(magnitude[i_p, i_eta] / background) if background > 0 else np.inf
    p_lags = 2 * np.arange(n_lags) / prf
    row = (np.exp(-2j * np.pi * f_p[i_p] * p_lags).astype(np.complex64) @ products).astype(np.complex128)
    f_peak = _refine_peak(row, prf, float(f_eta[i_eta]), prf / m_pulses)
    order_p, order_eta = np.argsort(f_p), np.argsort(f_eta)
    return SoWVD(magnitude=magnitude[order_p][:, order_eta], f_p=f_p[order_p], f_eta=f_eta[order_eta],
                 p0=q / prf, peak_f_eta=f_peak, peak_f_p=float(f_p[i_p]), peak_to_background=ratio)
