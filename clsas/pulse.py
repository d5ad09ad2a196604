"""The pulse's matched filter: the LFM replica, the spectral windows and the filter's frequency
response, which range compression (:mod:`clsas.image.rangecomp`) applies to recorded echoes and
the compressed echo synthesis (:mod:`clsas.synthesis.echo.compressed`) tabulates.

The replica is p(t) = rect(t/T) exp(j pi K t^2) (docs/design.md; Kiang & Kiang 2022 eq. 7);
the matched filter conj(FFT(p)) W(f) / g is the exact form of Kiang & Kiang 2022 eq. (8)
(H_rc = exp(j pi f^2 / K) is its stationary-phase approximation) and of Huang & Yang 2022
eq. (15) (H_cross = P*(f)). Windows W(f) act on the band |f| <= B/2 (zero outside; ``"none"``
keeps the whole spectrum): ``hamming`` 0.54 + 0.46 cos(2 pi f/B); ``taylor`` (``taylor_nbar``
in [1, 100], ``taylor_sll_db`` in (0, 200] dB below the peak); ``kaiser`` (``kaiser_beta`` in
[0, 100], computed with the exponentially scaled Bessel function i0e, so it cannot overflow).
"""

from __future__ import annotations

import numpy as np
import scipy.special

from . import budget
from . import validate as v
from .model import MAX_ECHO_FS, Waveform

WINDOWS = ("none", "hamming", "taylor", "kaiser")
WINDOW_OPTIONS = {"taylor_nbar": 4, "taylor_sll_db": 35.0, "kaiser_beta": 6.0}  # the defaults
TAYLOR_NBAR_MAX = 100  # the coefficients are a nbar x nbar product
TAYLOR_SLL_MAX = 200.0  # dB
KAISER_BETA_MAX = 100.0  # beyond ~40 the window is a narrow Gaussian, no longer a sidelobe control


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
