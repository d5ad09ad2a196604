"""Synthesis straight into the range-compressed domain: each path's compressed point response
written around its exact delay, only the taps that matter.

``range_compress(simulate(...))`` correlates every raw record with the replica p: a path of
amplitude a centred at sample u = s + phi (s integer, 0 <= phi < 1) whose raw echo is
a exp(E(d)), d = k - u, becomes, at output sample s + m,

    y(m) = a sum_k exp(E(k - u)) conj(p(k - s - m)) W / g         (the matched filter of
                                                                  clsas.pulse)

For the plain echo E(d) = j 2 pi alpha d^2 (|d| <= T fs / 2) this is a function Y0(m; phi) of
the tap m and the fraction phi alone: clsas tabulates it once per waveform, window and rate (at
PHASES + 1 fractions, linear between them: the response is band-limited to B / fs, so the
interpolation error is about (pi B / fs / PHASES)^2 / 8, below 1e-4 of the peak) over the taps
|m| <= L where it exceeds ``level_db`` (re its peak; beyond them it is dropped, and the share of
the response's energy dropped is reported: for a dense scene that is the relative L2 error).

A path with its own chirp (:mod:`clsas.synthesis.paths`: E(d) = j 2 pi (c d^2 + l d) + g d^2 +
b d, the intra-pulse Doppler and the loss over the band) is brought to the table's form by
completing the square: with delta = l / (2 c) and d = d' - delta,

    E = j 2 pi alpha d'^2 + [j 2 pi (c - alpha) + g] d'^2 + b' d' - j 2 pi l^2 / (4 c) + g delta^2 - b delta,
    b' = b - 2 g delta,

i.e. the echo of a path centred at u - delta (the range-Doppler coupling of the LFM: a Doppler
shift f moves the compressed peak by -f / K) times exp(b' d' + q d'^2), q = g + j 2 pi (c - alpha),
expanded to second order: 1 + b' d' + (b'^2 / 2 + q) d'^2. The tables Y1 and Y2 are Y0 with the
raw echo weighted by d and d^2, so a path adds c0 Y0 + c1 Y1 + c2 Y2 with c0 = a', c1 = a' b',
c2 = a' (b'^2 / 2 + q). Left out: the third-order terms (b' h)^3 / 6, |q| h^2 b' h and (|q| h^2)^2 / 2
and beyond, h = T fs / 2, and the shift of the support by delta against the chirp (the echo's
edges; relative error about delta / (2 h)). The band losses of sonar scenes keep b' h small, but
the chirp mismatch of a moving path is not: |q| h^2 ~ pi (2 v_r / c) B T / 2 rad, 0.9 rad at
2.2 m/s radial with B T = 200 (-32 dB measured). So paths with intra-pulse Doppler take the raw
route once the bound of that mismatch over the scene's speeds exceeds 0.1 rad
(:attr:`clsas.synthesis.echo.physics.Physics.compress_raw`).

Two routes, chosen by their work per path (:attr:`clsas.synthesis.echo.physics.Physics.compress_raw`):
the taps above (N_TABLES (2 L + 2) table values a path, N_TABLES = 3 for paths with their own
laws), or the raw echo (T fs samples a path) range-compressed afterwards record by record
(:meth:`CompressedResponse.compress`: exactly ``range_compress``'s matched filter, so that route
drops nothing) when the taps would cost more: a short pulse sampled near its bandwidth (Heremans's
T fs = 125 against 2 L + 2 = 250 taps at -40 dB) or paths with their own laws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft

from ...pulse import check_window, matched_filter
from ...model import Waveform

PHASES = 64  # fractions tabulated between two samples
DEFAULT_LEVEL_DB = -40.0  # taps kept: where the response exceeds this, re its peak
PAD = 16  # zero taps either side of a table row (the kernel reads 16 lanes at once)


@dataclass(frozen=True)
class CompressedResponse:
    """The tabulated compressed point responses of one waveform (module docstring).

    taps : L, the response kept at m = -L .. L + 1 about the centre's integer sample.
    tables : complex128 (3, PHASES + 1, 2 L + 2 + 2 PAD): Y0, Y1, Y2 at phi = i / PHASES, tap m at
    column PAD + m + L (zeros in the PAD columns either side).
    window, level_db : what was tabulated. alpha : the replica's chirp, cycles a sample^2;
    half_len : T fs / 2. discarded_db : the largest share of a response's energy beyond the taps
    (over the fractions), dB: the relative L2 error of a dense scene's compressed echo (many
    paths whose dropped sidelobes add incoherently). The tables hold the response of the
    pulse's core samples (those inside it whatever the fraction); the two ``edges`` samples (about
    the centre's integer sample) that enter or leave it with the fraction add
    x ``impulse``[PAD + lag0 + m - k] (the matched filter's impulse response) at tap m.
    """

    taps: int
    tables: np.ndarray
    window: str
    level_db: float
    alpha: float
    half_len: float
    discarded_db: float
    impulse: np.ndarray
    lag0: int
    edges: tuple

    @staticmethod
    def of(waveform: Waveform, window: str = "none", level_db: float = DEFAULT_LEVEL_DB,
           **window_options) -> "CompressedResponse":
        options = check_window(window, window_options, "simulate compressed")
        fs = waveform.fs
        half = 0.5 * waveform.duration * fs
        reach = int(np.ceil(half)) + 1
        k = np.arange(-reach, reach + 1)  # input samples about the centre's integer sample
        n_rep = 2 * int(np.floor(half + 1e-9)) + 1
        n_fft = scipy.fft.next_fast_len(k.size + 2 * n_rep + 2, real=False)
        h = matched_filter(waveform, fs, n_fft, window, **options)
        alpha = 0.5 * waveform.chirp_rate / fs ** 2
        phi = np.arange(PHASES + 1) / PHASES
        d = k[None, :] - phi[:, None]
        # the core: samples inside the pulse for every fraction in [0, 1] (the response is smooth
        # in phi); the two edge samples that enter or leave are added one by one (:meth:`edges`)
        core = (k >= np.ceil(1.0 - half)) & (k <= np.floor(half))
        whole = np.abs(d) <= half
        m_full = np.arange(-reach - n_rep, reach + 1 + n_rep)

        def filtered(x):
            y = scipy.fft.ifft(scipy.fft.fft(x, n=n_fft, axis=-1) * h, axis=-1)
            # output index i is fast-time sample i - reach about the centre's integer sample
            return np.concatenate([y[..., n_fft - n_rep:], y[..., :k.size + n_rep]], axis=-1)

        chirp = np.exp(2j * np.pi * alpha * d * d)
        full = [filtered(np.where(core[None, :], chirp * d ** power, 0.0)) for power in range(3)]
        mag = np.abs(filtered(np.where(whole, chirp, 0.0)))  # the whole response, to choose the taps
        mag /= mag.max(axis=1, keepdims=True)  # each fraction's response re its own peak
        above = np.flatnonzero(np.max(mag, axis=0) > 10 ** (level_db / 20))
        taps = int(min(max(-m_full[above[0]], m_full[above[-1]] - 1, 1), m_full[-1] - 1))
        keep = (m_full >= -taps) & (m_full <= taps + 1)
        energy = np.sum(mag ** 2, axis=1)
        discarded = float(np.max(1.0 - np.sum(mag[:, keep] ** 2, axis=1) / energy))
        tables = np.zeros((3, phi.size, 2 * taps + 2 + 2 * PAD), np.complex128)
        for power in range(3):
            tables[power, :, PAD:PAD + 2 * taps + 2] = full[power][:, keep]
        # the filter's impulse response at lags -(taps + reach) .. taps + reach + 1 (an edge
        # sample x at k adds x imp(m - k) at tap m)
        spike = np.zeros(n_fft, np.complex128)
        spike[0] = 1.0
        imp_full = scipy.fft.ifft(scipy.fft.fft(spike) * h)
        lags = np.arange(-(taps + reach), taps + reach + 2)
        impulse = np.zeros(lags.size + 2 * PAD, np.complex128)
        impulse[PAD:PAD + lags.size] = imp_full[lags % n_fft]
        edges = (int(np.ceil(1.0 - half)) - 1, int(np.floor(half)) + 1)
        return CompressedResponse(taps, tables, window, float(level_db), float(alpha), float(half),
                                  10 * np.log10(max(discarded, 1e-30)), impulse, taps + reach, edges)

    def edge_weights(self, phi, coeff) -> np.ndarray:
        """(2,) + phi.shape complex: what the lower and upper edge samples (:attr:`edges`) add at
        fractions ``phi`` when inside the pulse (|k - phi| <= T fs / 2, the raw echo's rule):
        sum_j c_j d^j exp(j 2 pi alpha d^2), d = k - phi."""
        out = []
        for k in self.edges:
            d = k - phi
            value = coeff[0] + coeff[1] * d + coeff[2] * d * d
            out.append(np.where(np.abs(d) <= self.half_len, value * np.exp(2j * np.pi * self.alpha * d * d), 0.0))
        return np.stack(out)

    def coefficients(self, amp, laws: dict | None):
        """(centre shift delta (samples), (3,) + amp.shape complex coefficients c0, c1, c2) of paths
        with amplitudes ``amp`` and, when given, their own laws (:func:`.reference.in_pulse_laws`)."""
        amp = np.asarray(amp, np.complex128)
        if laws is None:
            zero = np.zeros(amp.shape)
            return zero, np.stack([amp, 0 * amp, 0 * amp])
        c, lin, b, g = laws["chirp"], laws["lin"], laws["beta"], laws["gamma"]
        delta = lin / (2 * c)
        a = amp * np.exp(-2j * np.pi * lin * lin / (4 * c) + g * delta * delta - b * delta)
        b1 = b - 2 * g * delta
        q = g + 2j * np.pi * (c - self.alpha)
        return delta, np.stack([a, a * b1, a * (0.5 * b1 * b1 + q)])

    def accumulate(self, start, frac, amp, n_samples: int, laws: dict | None = None) -> np.ndarray:
        """The compressed records (R, n_samples) complex128 of R records of N paths (the NumPy
        twin of kernels/echo_accumulate.cl ``add_compressed_echo``): ``start``, ``frac`` (R, N) the
        raw echo centres, ``amp`` (R, N) with the carrier phase, ``laws`` as for
        :func:`.reference.accumulate_reference`."""
        delta, coeff = self.coefficients(amp, laws)
        u = np.asarray(start) + np.asarray(frac) - delta
        s = np.floor(u)
        pos = (u - s) * PHASES
        i = np.minimum(pos.astype(np.int64), PHASES - 1)
        w = pos - i
        m = np.arange(-self.taps, self.taps + 2)
        out = np.zeros((u.shape[0], n_samples), np.complex128)
        cols = PAD + self.taps + m
        for r in range(u.shape[0]):
            resp = 0.0
            for power in range(3):
                lo, hi = self.tables[power, i[r]][:, cols], self.tables[power, i[r] + 1][:, cols]
                resp = resp + coeff[power, r][:, None] * (lo + w[r][:, None] * (hi - lo))
            phi = u[r] - s[r]
            weights = self.edge_weights(phi, coeff[:, r])
            for e, k_edge in enumerate(self.edges):
                resp = resp + weights[e][:, None] * self.impulse[PAD + self.lag0 + m - k_edge][None, :]
            k = s[r].astype(np.int64)[:, None] + m[None, :]
            keep = (k >= 0) & (k < n_samples)
            out[r] = np.bincount(k[keep], weights=resp.real[keep], minlength=n_samples) \
                + 1j * np.bincount(k[keep], weights=resp.imag[keep], minlength=n_samples)
        return out

    def compress(self, records: np.ndarray, waveform: Waveform) -> np.ndarray:
        """Raw ``records`` (..., n) range-compressed as :func:`clsas.range_compress` does (the
        matched filter with this response's window over an FFT of next_fast_len(n + pulse) points,
        the first n outputs), in the records' dtype."""
        n = records.shape[-1]
        replica = 2 * int(np.floor(self.half_len + 1e-9)) + 1
        n_fft = scipy.fft.next_fast_len(n + replica, real=False)
        h = matched_filter(waveform, waveform.fs, n_fft, self.window)
        if records.dtype == np.complex64:
            h = h.astype(np.complex64)
        spec = scipy.fft.fft(records, n=n_fft, axis=-1)
        spec *= h
        return scipy.fft.ifft(spec, axis=-1)[..., :n].astype(records.dtype, copy=False)

    def planar(self, real) -> tuple[np.ndarray, np.ndarray]:
        """The tables as the kernel reads them: (3, PHASES + 1, 2 parts, row) and the impulse
        response (2 parts, lags) of ``real``."""
        tables = np.stack([self.tables.real, self.tables.imag], axis=2).astype(real)
        return np.ascontiguousarray(tables), np.ascontiguousarray(np.stack([self.impulse.real, self.impulse.imag])
                                                                  .astype(real))
