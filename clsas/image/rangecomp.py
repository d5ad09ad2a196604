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
import scipy.special

from .. import budget
from .. import validate as v
from ..model import MAX_ECHO_FS, EchoData, Waveform

WINDOWS = ("none", "hamming", "taylor", "kaiser")
WINDOW_OPTIONS = {"taylor_nbar": 4, "taylor_sll_db": 35.0, "kaiser_beta": 6.0}  # the defaults
TAYLOR_NBAR_MAX = 100  # the coefficients are a nbar x nbar product
TAYLOR_SLL_MAX = 200.0  # dB
KAISER_BETA_MAX = 100.0  # beyond ~40 the window is a narrow Gaussian, no longer a sidelobe control
MAX_UPSAMPLE = 64


def check_window(window, options: dict, caller: str) -> dict:
    """Validate a ``window`` name and its options (``taylor_nbar``, ``taylor_sll_db``,
    ``kaiser_beta``; any given option is checked, whatever the window); returns the options with
    their defaults filled in. ``caller`` prefixes the names in the messages."""
    v.choice(f"{caller} window", window, WINDOWS)
    unknown = sorted(set(options) - set(WINDOW_OPTIONS))
    if unknown:
        raise TypeError(f"{caller}: unknown window option(s) {unknown}; the options are {sorted(WINDOW_OPTIONS)}")
    opts = {**WINDOW_OPTIONS, **options}
    opts["taylor_nbar"] = v.integer(f"{caller} taylor_nbar", opts["taylor_nbar"], low=1, high=TAYLOR_NBAR_MAX)
    opts["taylor_sll_db"] = v.positive(f"{caller} taylor_sll_db", opts["taylor_sll_db"], high=TAYLOR_SLL_MAX,
                                       unit="dB", why="sidelobe level below the peak")
    opts["kaiser_beta"] = v.scalar(f"{caller} kaiser_beta", opts["kaiser_beta"], low=0.0, high=KAISER_BETA_MAX)
    if window == "taylor":
        _check_taylor_shape(opts["taylor_nbar"], opts["taylor_sll_db"], caller)
    return opts


def _check_taylor_shape(nbar: int, sll_db: float, caller: str) -> None:
    """Refuse a Taylor design that is no window: with too many nearly constant sidelobes for a
    shallow sidelobe level (e.g. nbar = 100 at 25 dB) the series rises above its peak and dips
    below zero (the design rule is nbar >= 2 A^2 + 1/2 from below; from above it is this check)."""
    u = np.linspace(0.0, 0.5, 513)
    f = taylor_coefficients(nbar, sll_db)
    w = np.ones_like(u)
    for m, fm in enumerate(f, start=1):
        w += 2 * fm * np.cos(2 * np.pi * m * u)
    w /= 1 + 2 * f.sum()
    if w.min() < -1e-9 or w.max() > 1 + 1e-9:
        raise ValueError(f"{caller} taylor_nbar: {nbar} nearly constant sidelobes at taylor_sll_db = {sll_db:g} dB give "
                         f"no window (it spans [{w.min():.3g}, {w.max():.3g}] instead of [0, 1]); use fewer "
                         "(nbar of 3 to 8 is usual) or a deeper sidelobe level")


def check_workers(workers, name: str) -> int:
    """scipy.fft threads: None (all cores) or a non-zero integer (negative counts back from the
    number of cores, as scipy.fft does)."""
    if workers is None:
        return os.cpu_count() or 1
    count = v.integer(name, workers, low=-1024, high=1024, why="not 0; negative counts back from the cores")
    if count == 0:
        raise ValueError(f"{name}: must be a non-zero integer (or None), got 0")
    return count


def lfm_replica(waveform: Waveform, fs: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The baseband replica sampled at ``t = k / fs`` for every k with |t| <= T/2.

    Returns ``(t, p)``: times (s) and samples (complex128), symmetric about t = 0.
    """
    v.instance("lfm_replica waveform", waveform, Waveform, "a Waveform")
    fs = waveform.fs if fs is None else v.positive("lfm_replica fs", fs, high=MAX_ECHO_FS, unit="Hz")
    half = int(np.floor(0.5 * waveform.duration * fs + 1e-9))
    t = np.arange(-half, half + 1) / fs
    return t, waveform.baseband(t)


def taylor_coefficients(nbar: int, sll_db: float) -> np.ndarray:
    """Coefficients F_1..F_{nbar-1} of the Taylor window w(u) = 1 + 2 sum_m F_m cos(2 pi m u).

    Carrara, Goodman & Majewski (1995), eq. (A.12): with A = acosh(10^(sll/20)) / pi and
    sigma^2 = nbar^2 / (A^2 + (nbar - 1/2)^2),
    F_m = (-1)^(m+1) prod_{n=1}^{nbar-1} (1 - m^2 / (sigma^2 (A^2 + (n - 1/2)^2)))
          / (2 prod_{n != m} (1 - m^2 / n^2)).
    """
    nbar = v.integer("taylor nbar", nbar, low=1, high=TAYLOR_NBAR_MAX)
    sll_db = v.positive("taylor sidelobe level (dB below the peak)", sll_db, high=TAYLOR_SLL_MAX)
    a = np.arccosh(10 ** (sll_db / 20)) / np.pi
    sigma2 = nbar**2 / (a**2 + (nbar - 0.5) ** 2)
    ms = np.arange(1, nbar, dtype=np.float64)
    m, n = ms[:, None], ms[None, :]  # (nbar - 1)^2 products at most 99^2
    num = np.prod(1 - m**2 / (sigma2 * (a**2 + (n - 0.5) ** 2)), axis=1)
    ratio = np.where(m == n, 0.0, m**2 / n**2)  # the n = m factor is left out (1 - 0 = 1)
    den = 2 * np.prod(1 - ratio, axis=1)
    return np.where(ms % 2 == 1, 1.0, -1.0) * num / den


def spectral_window(u: np.ndarray, window: str = "none", *, taylor_nbar: int = 4, taylor_sll_db: float = 35.0,
                    kaiser_beta: float = 6.0) -> np.ndarray:
    """Window value at normalised frequencies ``u = f / B``: defined on |u| <= 1/2, 0 outside, peak 1.

    ``"none"`` returns ones everywhere (the matched filter keeps the whole spectrum).
    """
    opts = check_window(window, dict(taylor_nbar=taylor_nbar, taylor_sll_db=taylor_sll_db, kaiser_beta=kaiser_beta),
                        "spectral_window")
    u = np.asarray(u, dtype=np.float64)
    if window == "none":
        return np.ones_like(u)
    inside = np.abs(u) <= 0.5
    if window == "hamming":
        w = 0.54 + 0.46 * np.cos(2 * np.pi * u)
    elif window == "taylor":
        f = taylor_coefficients(opts["taylor_nbar"], opts["taylor_sll_db"])
        w = np.ones_like(u)
        for m, fm in enumerate(f, start=1):  # at most 99 terms, memory of one u
            w += 2 * fm * np.cos(2 * np.pi * m * u)
        w /= 1 + 2 * f.sum()
    else:  # kaiser: I0(beta s) / I0(beta) = i0e(beta s) exp(beta (s - 1)), s = sqrt(1 - (2u)^2) <= 1
        beta = opts["kaiser_beta"]
        s = np.sqrt(np.clip(1 - (2 * u) ** 2, 0, None))
        w = scipy.special.i0e(beta * s) / scipy.special.i0e(beta) * np.exp(beta * (s - 1))
    return np.where(inside, w, 0.0)


def matched_filter(waveform: Waveform, fs: float, n_fft: int, window: str = "none", **window_options) -> np.ndarray:
    """The frequency response conj(FFT(p)) W(f) / g for an ``n_fft``-point FFT at rate ``fs`` (complex128).

    The replica is laid out circularly (sample k at index k mod n_fft), so that the filter
    has no bulk delay; ``g = sum |P|^2 W / n_fft`` normalises an on-grid echo's peak to its amplitude.
    """
    _, p = lfm_replica(waveform, fs)
    half = (p.size - 1) // 2
    n_fft = v.integer("matched_filter n_fft", n_fft, low=p.size, why="the replica's samples at least")
    budget.check_bytes(f"matched_filter of {n_fft} points", 48.0 * n_fft, "a shorter FFT")
    circ = np.zeros(n_fft, dtype=np.complex128)
    circ[: half + 1] = p[half:]
    circ[n_fft - half:] = p[:half]
    spectrum = np.fft.fft(circ)
    w = spectral_window(np.fft.fftfreq(n_fft, 1 / fs) / waveform.bandwidth, window, **window_options)
    h = np.conj(spectrum) * w
    gain = np.sum(np.abs(spectrum) ** 2 * w) / n_fft
    return h / gain


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
