"""Range compression: matched filtering of LFM echoes in the frequency domain.

Signal model (docs/design.md; Kiang & Kiang 2022 eq. 7): the baseband echo of a scatterer at
two-way delay tau_n is A rect((tau - tau_n)/T) exp(-j 2 pi f0 tau_n) exp(j pi K (tau - tau_n)^2).
The matched filter correlates each fast-time record with the baseband replica
p(t) = rect(t/T) exp(j pi K t^2):

    y(tau) = sum_k s(t0 + k/fs) p*(t0 + k/fs - tau)  /  g

computed as IFFT(FFT(s) conj(FFT(p)) W(f)) with zero padding (no circular wrap), so that on the
output fast-time axis ``t0 + k / fs_out`` a scatterer at delay tau_n peaks at tau_n with phase
-2 pi f0 tau_n. ``g`` makes that peak equal A for an on-grid delay, whatever the window.

This is the exact form of the range-compression filter of Kiang & Kiang 2022 eq. (8)
(H_rc = exp(j pi f^2 / K) is its stationary-phase approximation), and of Huang & Yang 2022
eq. (15) (H_cross = P*(f)).

Windows W(f) act on the band |f| <= B/2 (zero outside; ``"none"`` keeps the whole spectrum):
``hamming`` 0.54 + 0.46 cos(2 pi f/B); ``taylor`` (``taylor_nbar`` in [1, 100],
``taylor_sll_db`` in (0, 200] dB below the peak); ``kaiser`` (``kaiser_beta`` in [0, 100],
computed with the exponentially scaled Bessel function i0e, so it cannot overflow).
Upsampling zero-pads the compressed spectrum (FFT interpolation).
"""

from __future__ import annotations

import os

import numpy as np
import scipy.fft

from .. import budget
from .. import validate as v
from ..model import EchoData
from ..pulse import check_window, matched_filter

MAX_UPSAMPLE = 64


def check_workers(workers, name: str) -> int:
    """scipy.fft threads: None (all cores) or a non-zero integer (negative counts back from the
    number of cores, as scipy.fft does)."""
    if workers is None:
        return os.cpu_count() or 1
    count = v.integer(name, workers, low=-1024, high=1024, why="not 0; negative counts back from the cores")
    if count == 0:
        raise ValueError(f"{name}: must be a non-zero integer (or None), got 0")
    if count < 0:  # scipy.fft's rule (-1: every core), resolved here so that scipy never refuses it unnamed
        cores = os.cpu_count() or 1
        if cores + 1 + count < 1:
            raise ValueError(f"{name}: a negative count goes back from this machine's {cores} cores, so it must be "
                             f"between -{cores} and -1, got {count}")
        count = cores + 1 + count
    return count


def _upsample_spectrum(spec: np.ndarray, factor: int) -> np.ndarray:
    """Zero-pad the last axis of an FFT spectrum to ``factor`` times its length (Nyquist bin split)."""
    n = spec.shape[-1]
    out = np.zeros(spec.shape[:-1] + (n * factor,), dtype=spec.dtype)
    pos = (n + 1) // 2  # bins 0 .. pos-1 are non-negative frequencies
    out[..., :pos] = spec[..., :pos]
    out[..., n * factor - (n - pos):] = spec[..., pos:]
    if n % 2 == 0:  # split the Nyquist bin between +fs/2 and -fs/2
        out[..., n // 2] = 0.5 * spec[..., n // 2]
        out[..., n * factor - n // 2] = 0.5 * spec[..., n // 2]
    return out


def upsample_records(records: np.ndarray, factor: int, workers: int | None = None) -> np.ndarray:
    """FFT (band-limited) interpolation of complex records along the last axis by ``factor``.

    Output sample j sits at input position j / factor. The records are zero-padded before the
    FFT (by a quarter of their length, at least 16 samples) so that nothing wraps around from
    one end of a record to the other. Returns complex64 ``records.shape[:-1] + (n * factor,)``.
    """
    factor = v.integer("upsample factor", factor, low=1, high=MAX_UPSAMPLE)
    records = np.asarray(records)
    if records.dtype.kind not in "iufc":
        raise TypeError(f"upsample_records records: must be an array of numbers, got dtype {records.dtype}")
    if records.ndim < 1 or records.shape[-1] < 1:
        raise ValueError(f"upsample_records records: must have samples along the last axis, got shape {records.shape}")
    if not v.all_finite(records):
        raise ValueError("upsample_records records: must be finite everywhere; they have NaN or inf")
    n = records.shape[-1]
    if factor == 1:
        return np.asarray(records, dtype=np.complex64)
    workers = check_workers(workers, "upsample_records workers")
    n_fft = scipy.fft.next_fast_len(n + max(16, n // 4), real=False)
    spec = scipy.fft.fft(records, n=n_fft, axis=-1, workers=workers)
    out = scipy.fft.ifft(_upsample_spectrum(spec, factor), axis=-1, workers=workers)[..., :n * factor]
    return (out * factor).astype(np.complex64)


def range_compress(echo: EchoData, window: str = "none", upsample: int = 1, workers: int | None = None,
                   block_bytes: int = 256 * 2**20, **window_options) -> EchoData:
    """Matched-filter every fast-time record of ``echo``; returns range-compressed EchoData.

    Parameters
    ----------
    echo : EchoData
        Raw (not yet compressed) echoes.
    window : {"none", "hamming", "taylor", "kaiser"}
        Spectral weighting for sidelobe control (``taylor_nbar``, ``taylor_sll_db``,
        ``kaiser_beta`` tune it).
    upsample : int
        Output sampling rate = upsample * echo.fs (FFT interpolation), >= 1.
    workers : int, optional
        scipy.fft threads (default: all cores).
    block_bytes : int
        Memory bound of one FFT block (the cube is processed a block of records at a time).

    Returns
    -------
    EchoData with ``compressed=True``, ``fs = upsample * echo.fs``, the same ``t0`` and
    geometry; ``data[r, p, k]`` is the matched-filter output at fast time
    ``t0[r] + k / fs`` (a scatterer at delay tau_n peaks at tau_n).
    """
    v.instance("range_compress echo", echo, EchoData, "an EchoData")
    v.compression("range_compress echo", echo, compressed=False, advice="an echo is range-compressed once")
    window_options = check_window(window, window_options, "range_compress")
    upsample = v.integer("range_compress upsample", upsample, low=1, high=MAX_UPSAMPLE)
    workers = check_workers(workers, "range_compress workers")
    block_bytes = budget.parse_bytes(block_bytes, "range_compress block_bytes")
    if echo.n_samples < 1 or echo.n_pulses < 1:
        raise ValueError(f"range_compress echo: has no samples to compress (shape {echo.data.shape})")
    if not v.all_finite(echo.data):
        raise ValueError("range_compress echo: echo.data has NaN or inf samples")

    n = echo.n_samples
    replica_size = 2 * int(np.floor(0.5 * echo.waveform.duration * echo.fs + 1e-9)) + 1
    n_fft = scipy.fft.next_fast_len(n + replica_size, real=False)
    n_out = n * upsample
    per_record = 8 * n_fft * (2 + upsample)
    budget.check_bytes(f"range_compress of {echo.n_rx} x {echo.n_pulses} records of {n} samples with upsample="
                       f"{upsample} (and a pulse of {replica_size} samples)",
                       8.0 * echo.n_rx * echo.n_pulses * n_out + 16.0 * n_fft * 4 + min(block_bytes, per_record * 1.0
                                                                                     * echo.n_rx * echo.n_pulses),
                       "fewer pulses or receivers at a time, or a smaller upsample")
    h = matched_filter(echo.waveform, echo.fs, n_fft, window, **window_options).astype(np.complex64)

    out = np.empty(echo.data.shape[:2] + (n_out,), dtype=np.complex64)
    records = echo.data.reshape(-1, n)
    flat_out = out.reshape(-1, n_out)
    block = max(1, int(block_bytes // per_record))
    for start in range(0, records.shape[0], block):
        stop = min(start + block, records.shape[0])
        spec = scipy.fft.fft(records[start:stop], n=n_fft, axis=-1, workers=workers)
        spec *= h
        if upsample > 1:
            spec = _upsample_spectrum(spec, upsample)
            spec *= upsample
        flat_out[start:stop] = scipy.fft.ifft(spec, axis=-1, workers=workers)[:, :n_out]

    v.finite_result("range_compress: the compressed echo", out, "scale echo.data down")
    provenance = dict(echo.provenance)
    provenance["range_compression"] = {"window": window, "upsample": upsample, **window_options}
    return echo.replace(data=out, fs=echo.fs * upsample, compressed=True, provenance=provenance)
