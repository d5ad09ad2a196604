"""DPCA's building blocks on the records: normalised correlations over range blocks (eq. 51),
the hydrophones' records on one fast-time grid, and the three-point peak finders (eq. 67)."""

from __future__ import annotations

import numpy as np
import scipy.fft

from ... import validate
from ...model import EchoData
from ...kernelmath import unit_phasor


def parabola(y_minus, y0, y_plus):
    """Vertex offset (in samples, within [-0.5, 0.5] for a true maximum) and value of the parabola
    through (-1, y_minus), (0, y0), (1, y_plus) (Heremans et al. 2009, eq. 67)."""
    den = y_minus - 2 * y0 + y_plus
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where(den < 0, 0.5 * (y_minus - y_plus) / den, 0.0)
    off = np.clip(off, -0.5, 0.5)
    return off, y0 - 0.25 * (y_minus - y_plus) * off


def peak_ratio(y_minus, y0, y_plus):
    """q = (y+ - y-) / (2 y0 - y+ - y-) of three samples at -1, 0, 1 around a maximum (0 where
    the middle one is not above the mean of its neighbours): odd in the vertex offset, which
    :func:`clsas.estimate.dpca.geometry.xlag_offset` reads from it for the x-lag peak."""
    den = 2 * y0 - y_plus - y_minus
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, (y_plus - y_minus) / den, 0.0)


# Up to this many t-lags the correlations are summed lag by lag, beyond it computed by FFT
# (the crossing measured by bench/bench_dpca.py, its dpca-correlations cases).
DIRECT_T_LAGS = 9


def correlations(f: np.ndarray, g: np.ndarray, t_lags: int, method: str = "auto", delay=None,
                 fs: float | None = None) -> np.ndarray:
    """Normalised cross-correlations of eq. (51) over range blocks.

    f, g : complex (..., n_blocks, block) — the ping-p and ping-(p + 1) records of each couple;
    returns complex64 (..., n_blocks, 2 t_lags + 1): c[m] = sum_k f[k + m] g*[k] /
    sqrt(sum |f|^2 sum |g|^2), m = -t_lags..t_lags, samples beyond the block ignored (the grey
    bins of Fig. 17). method : "direct" (one multiply-add pass a t-lag), "fft" (each block
    zero-padded to block + t_lags, every lag computed, 2 t_lags + 1 kept) or "auto" (direct up
    to DIRECT_T_LAGS t-lags).

    delay : s, broadcastable to f.shape[:-1], or None: correlate with g's envelope advanced by
    ``delay``, g(t) -> g(t + delay) over its baseband spectrum (its phase kept: the carrier
    part of a delay is the caller's), ``fs`` the sampling rate in Hz. A fraction of a sample
    counts: computed by FFT with the blocks zero-padded to at least 2 block - 1 samples, so
    that the whole linear correlation is held without wrap-around and the shift interpolates
    it band-limited (``method`` must then be "auto" or "fft")."""
    if method not in ("auto", "direct", "fft"):
        raise ValueError(f"correlations: method must be 'auto', 'direct' or 'fft', got {method!r}")
    if delay is not None and (method == "direct" or fs is None):
        raise ValueError("correlations: a delay needs method 'auto' or 'fft' and the sampling rate fs")
    if delay is not None:
        fs = validate.positive("correlations fs", fs, unit="Hz")
        delay = np.asarray(delay, dtype=np.float64)
        if not np.all(np.isfinite(delay)):
            raise ValueError(f"correlations delay: must be finite seconds, got {delay[~np.isfinite(delay)].flat[0]}")
    n = f.shape[-1]
    norm = np.sqrt(np.sum(np.abs(f) ** 2, axis=-1) * np.sum(np.abs(g) ** 2, axis=-1))
    if delay is not None or method == "fft" or (method == "auto" and 2 * t_lags + 1 > DIRECT_T_LAGS):
        size = scipy.fft.next_fast_len(n + t_lags if delay is None else 2 * n - 1)
        cross = scipy.fft.fft(f, size, axis=-1) * np.conj(scipy.fft.fft(g, size, axis=-1))
        if delay is not None:
            freq = scipy.fft.fftfreq(size, 1 / fs)
            cross *= unit_phasor(-2 * np.pi * delay[..., None] * freq)
        out = scipy.fft.ifft(cross, axis=-1)[..., np.arange(-t_lags, t_lags + 1) % size]
    else:
        g_conj = np.conj(g)
        out = np.empty(f.shape[:-1] + (2 * t_lags + 1,), dtype=np.complex64)
        for i, m in enumerate(range(-t_lags, t_lags + 1)):
            lo, hi = max(0, -m), min(n, n - m)
            out[..., i] = np.einsum("...k,...k->...", f[..., lo + m:hi + m], g_conj[..., lo:hi])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm[..., None] > 0, out / norm[..., None], 0).astype(np.complex64)


def aligned(echo: EchoData, h: int) -> tuple[np.ndarray, float]:
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
