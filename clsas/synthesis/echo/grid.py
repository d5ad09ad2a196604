"""The grid route of echo synthesis: each path as a fractional-delay impulse on an oversampled
fast-time grid, one FFT filter per record (the pulse), then the record's samples.

The raw record of R paths without intra-pulse Doppler (:mod:`.reference`) is

    y[k] = sum_n a_n E_n(d) c(d) [|d| <= h],   d = k - u_n,  c(d) = exp(j 2 pi alpha d^2),

u_n the echo centre (samples), h = T fs / 2 and E_n(d) = exp(b_n d + g_n d^2) the path's loss over
the band (absorption, surface roughness; 1 for plain paths). The route writes it as

    y = sum_j (G_j * s_j)[k]  -  sum_n a_n P_n(d) c(d) taper(|d| - h) [h < |d| < h + TAPER],

1. **the envelope as a polynomial**: E_n(d) ~= P_n(d) = sum_j e_j,n d^j with e_0 = 1, e_1 = b,
   e_2 = b^2 / 2 + g (the second-order Taylor series; left out: (b h)^3 / 6 + b g h^3 and
   smaller, :func:`envelope_bound` keeps it below ``ENVELOPE_BOUND``^3 / 6);
2. **the pulse smoothed past its edges**: s_j(d) = d^j c(d) taper(|d| - h) with taper = 1 inside
   the pulse and a half Hann window over TAPER samples outside, a smooth function whose spectrum
   is confined to |f| < BAND RATE cycles a sample (the chirp's own band B / fs plus the taper's);
   the samples the taper adds outside the pulse (at most TAPER on either side of a path) are
   subtracted exactly, path by path (the second sum: the *tails*);
3. **the impulses G_j = sum_n a_n e_j,n delta(t - u_n) on a grid of RATE points a sample**,
   spread by an "exponential of semicircle" kernel phi(x) = exp(BETA (sqrt(1 - (2 x / TAPS)^2) - 1))
   over TAPS grid points (Barnett, Magland & af Klinteberg 2019, the non-uniform FFT of type 1);
   the grid's DFT divided by phi's Fourier transform is G_j's spectrum over |f| < BAND RATE
   (the aliases of phi are below ~1e-4 of it there);
4. **one FFT filter per record**: Y = sum_j DFT(grid_j) S_j / Phi over |f| < BAND RATE (zero
   beyond), the inverse FFT at the grid's rate, then every RATE-th point: y at the samples. The
   grid spans PAD samples either side of the record, so the circular convolution wraps nothing
   into it.

The delays are untouched (each path's exact centre u_n places its impulse); what differs from the
direct route is the band-limited interpolation (measured against the float64 reference in
tests/test_echo_grid.py and bench/bench_echo.py). Work per path: TAPS grid points per term and
two 8-lane evaluations for the tails, instead of the pulse's T fs samples; per record: one FFT of
the grid per term and one inverse FFT.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import scipy.fft

RATE = 4  # grid points a sample
TAPS = 6  # width of the spreading kernel, grid points
BETA = 2.3 * TAPS  # the kernel's shape (exponential of semicircle)
TAPER = 4  # samples the pulse is smoothed over past each edge (the tails)
BAND = 0.3  # the filter keeps |f| < BAND RATE cycles a sample
LANES = 8  # the kernel evaluates a path's taps, and each tail, on 8 lanes
BLOCK = 64  # samples a work-item of kernels/echo_accumulate.cl echo_grid makes; grids span whole blocks
ENVELOPE_BOUND = 0.2  # the largest |b| h + |g| h^2 the second-order envelope is used for (x^3 / 6 <= 1.3e-3)
QUADRATURE = 256  # Gauss-Legendre nodes for phi's Fourier transform
DEGREE = 7  # the taps' polynomials in the fraction (their largest error ~1.4e-6 of the peak, at phi's edge)


def kernel(x):
    """phi(x), x in grid points (zero for |x| >= TAPS / 2)."""
    z = 2.0 * np.asarray(x, dtype=np.float64) / TAPS
    inside = np.abs(z) < 1.0
    return np.where(inside, np.exp(BETA * (np.sqrt(np.where(inside, 1.0 - z * z, 1.0)) - 1.0)), 0.0)


def kernel_transform(nu) -> np.ndarray:
    """Phi(nu) = integral of phi(x) exp(-j 2 pi nu x) dx (real: phi is even), nu in cycles a grid point."""
    x, w = np.polynomial.legendre.leggauss(QUADRATURE)
    x, w = 0.5 * TAPS * x, 0.5 * TAPS * w
    nu = np.asarray(nu, dtype=np.float64)
    return (np.cos(2.0 * np.pi * nu[..., None] * x) * (w * kernel(x))).sum(axis=-1)


@functools.cache
def tap_polynomials() -> np.ndarray:
    """(DEGREE + 1, LANES): the taps phi(l - TAPS / 2 + t), l = 0 .. LANES - 1, as polynomials in
    t in [0, 1) (coefficient k of t^k in row k; fitted at Chebyshev nodes): a path whose grid
    position is x puts phi(first + l - x) on grid point first + l, first = ceil(x - TAPS / 2),
    t = first - x + TAPS / 2 (the Horner form kernels/echo_accumulate.cl evaluates on 8 lanes)."""
    t = 0.5 - 0.5 * np.cos(np.pi * (np.arange(64) + 0.5) / 64)
    out = np.zeros((DEGREE + 1, LANES))
    for lane in range(TAPS):
        out[:, lane] = np.polynomial.polynomial.polyfit(t, kernel(lane - 0.5 * TAPS + t), DEGREE)
    return out


def taps(t) -> np.ndarray:
    """(..., LANES) the taps at fractions ``t`` (...,) (:func:`tap_polynomials`)."""
    coef = tap_polynomials()
    t = np.asarray(t, dtype=np.float64)[..., None]
    out = np.zeros(t.shape[:-1] + (LANES,)) + coef[DEGREE]
    for k in range(DEGREE - 1, -1, -1):
        out = out * t + coef[k]
    return out


def taper(x) -> np.ndarray:
    """1 for x <= 0 (inside the pulse; x = |d| - h), a half Hann window to 0 at x = TAPER."""
    t = np.clip(np.asarray(x, dtype=np.float64) / TAPER, 0.0, 1.0)
    return 0.5 * (1.0 + np.cos(np.pi * t))


def pad_samples(half_len: float) -> int:
    """Samples the grid spans either side of the record (the pulse, its taper and the kernel)."""
    return int(np.ceil(half_len + TAPER)) + -(-TAPS // RATE) + 1


def envelope_bound(absorption, planes, path_length: float, waveform, sound_speed: float) -> float:
    """An upper bound of |b| h + |g| h^2 over the paths (how far the band envelope departs from 1
    over the pulse, :mod:`clsas.synthesis.propagation`): absorption's a1, a2 over ``path_length``
    (m, the longest path) and each rough sea-surface bounce's -exp(-q f^2), q = 2 (2 pi sigma
    sin(grazing) / c)^2, at its largest (normal incidence)."""
    lnf1 = lnf2 = 0.0
    if absorption is not None:
        lnf1 += abs(absorption.a1) * path_length
        lnf2 += abs(absorption.a2) * path_length
    for plane in planes:
        q = 2.0 * (2.0 * np.pi * plane.rms_height / sound_speed) ** 2
        lnf1 += 2.0 * q * waveform.f0
        lnf2 += q
    half_hz = 0.5 * waveform.bandwidth  # b d = lnf1 (K d / fs): K d / fs is the frequency offset, |.| <= B / 2
    return lnf1 * half_hz + lnf2 * half_hz ** 2


@dataclass(eq=False)
class GridPlan:
    """The grid route for one waveform (module docstring): ``terms`` 1 (plain paths) or 3 (paths
    with their own band envelope), ``alpha`` cycles a sample^2, ``half_len`` h samples; the
    record filters are made once per record length."""

    alpha: float
    half_len: float
    terms: int
    filters: dict = field(default_factory=dict, repr=False)

    @property
    def pad(self) -> int:
        return pad_samples(self.half_len)

    def grid_samples(self, n_samples: int) -> int:
        """Samples the grid covers for records of ``n_samples`` (the record and PAD either side),
        in whole BLOCKs (both backends: the same grids, the same filters)."""
        n = n_samples + 2 * self.pad
        return -(-n // BLOCK) * BLOCK

    def filter(self, n_grid: int) -> tuple[int, np.ndarray]:
        """(FFT length M, (terms, M) complex128 S_j / Phi over the kept band) for grids of
        ``n_grid`` samples (RATE n_grid points)."""
        if n_grid not in self.filters:
            m = scipy.fft.next_fast_len(RATE * n_grid, real=False)
            f = np.fft.fftfreq(m, 1.0 / RATE)  # cycles a sample
            t = np.fft.fftfreq(m, 1.0 / m) / RATE  # the grid's times about 0, samples
            pulse = np.exp(2j * np.pi * self.alpha * t * t) * taper(np.abs(t) - self.half_len)
            keep = np.abs(f) < BAND * RATE
            phi = kernel_transform(f[keep] / RATE)
            out = np.zeros((self.terms, m), np.complex128)
            for j in range(self.terms):
                out[j, keep] = scipy.fft.fft(t ** j * pulse)[keep] / phi
            self.filters[n_grid] = (m, out)
        return self.filters[n_grid]

    def coefficients(self, amp, laws: dict | None) -> np.ndarray:
        """(terms,) + amp.shape complex: a e_j of paths with amplitudes ``amp`` and, when given, their
        band envelopes (``laws``: beta, gamma, :func:`.reference.in_pulse_laws`)."""
        amp = np.asarray(amp, np.complex128)
        if self.terms == 1:
            return amp[None]
        b, g = laws["beta"], laws["gamma"]
        return np.stack([amp, amp * b, amp * (0.5 * b * b + g)])

    def spread(self, start, frac, amp, n_samples: int, laws: dict | None = None):
        """The NumPy twin of kernels/echo_accumulate.cl ``echo_grid``: (grids (R, terms, RATE n_grid), tails
        (R, n_grid)) complex128 of R records of N paths (``start``, ``frac``, ``amp`` (R, N) as for
        :func:`.reference.accumulate_reference`); grid point m is at sample m / RATE - PAD, tail
        entry i at sample i - PAD."""
        start, frac = np.asarray(start, np.int64), np.asarray(frac, np.float64)
        coeff = self.coefficients(amp, laws)
        n_grid, pad, h = self.grid_samples(n_samples), self.pad, self.half_len
        n_rec = start.shape[0]
        grids = np.zeros((n_rec, self.terms, RATE * n_grid), np.complex128)
        tails = np.zeros((n_rec, n_grid), np.complex128)
        lanes = np.arange(LANES)
        left = int(np.ceil(-h - TAPER)) + lanes  # candidate offsets of the tails from the start sample
        right = int(np.floor(h)) + 1 + lanes
        for r in range(n_rec):
            s = start[r] + pad
            reach = (s + int(np.ceil(h + TAPER)) + 1 >= 0) & (s - int(np.ceil(h + TAPER)) - 1 < n_grid) \
                & (amp[r] != 0)
            s, fr, c = s[reach], frac[r][reach], coeff[:, r][:, reach]
            xf = RATE * fr
            first = np.ceil(xf - 0.5 * TAPS).astype(np.int64)
            m = RATE * s[:, None] + first[:, None] + lanes  # (n, LANES) grid points
            phi = taps(first - xf + 0.5 * TAPS)
            ok = (m >= 0) & (m < RATE * n_grid) & (lanes < TAPS)
            for j in range(self.terms):
                vals = c[j][:, None] * phi
                grids[r, j] = np.bincount(m[ok], vals.real[ok], RATE * n_grid) \
                    + 1j * np.bincount(m[ok], vals.imag[ok], RATE * n_grid)
            for offsets in (left, right):
                d = offsets[None, :] - fr[:, None]
                x = np.abs(d) - h
                k = s[:, None] + offsets[None, :]
                ok = (x > 0) & (x < TAPER) & (k >= 0) & (k < n_grid)
                poly = c[0][:, None] + (c[1][:, None] + c[2][:, None] * d) * d if self.terms == 3 else c[0][:, None]
                vals = -poly * np.exp(2j * np.pi * self.alpha * d * d) * taper(x)
                tails[r] += np.bincount(k[ok], vals.real[ok], n_grid) + 1j * np.bincount(k[ok], vals.imag[ok], n_grid)
        return grids, tails

    def finish(self, grids: np.ndarray, tails: np.ndarray, n_samples: int) -> np.ndarray:
        """The records (..., n_samples) from the grids (..., terms, RATE n_grid) and the tails
        (..., n_grid) of :meth:`spread` (or the kernel): the FFT filter, then every RATE-th point,
        in the grids' precision (complex64 stays complex64)."""
        n_grid = tails.shape[-1]
        m, filt = self.filter(n_grid)
        if grids.dtype == np.complex64:
            filt = filt.astype(np.complex64)
        spec = scipy.fft.fft(grids[..., 0, :], n=m, axis=-1)
        spec *= filt[0]
        for j in range(1, self.terms):
            spec += scipy.fft.fft(grids[..., j, :], n=m, axis=-1) * filt[j]
        y = scipy.fft.ifft(spec, axis=-1)
        pad = self.pad
        return y[..., RATE * pad:RATE * (pad + n_samples):RATE] + tails[..., pad:pad + n_samples]
