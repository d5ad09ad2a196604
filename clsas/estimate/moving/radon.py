"""Slope of a straight echo trace by the Radon transform (Kiang & Kiang 2022, section III-D).

After RCMC (eq. 17) a target's trace in |s_rcmc(tau, eta)| is the line
tau = tau_0 + (f_dc / f0) eta: in pixels (pulse n, sample k), k = k0 + s n with
s = (f_dc / f0) fs / PRF samples a pulse. The Radon transform is taken in its slope-intercept
form (the "slant stack"),

    P(s, k0) = sum_n I[n, k0 + s n]          (linear interpolation in k),

the Radon transform at the pixel angle atan(s) on an intercept axis sheared to n = 0; the line's
projection is sharpest at its slope. The search maximises the projection's energy
J(s) = sum_k0 P(s, k0)^2, which is smooth in s (unlike the peak of a sampled projection):

1. over every slope that keeps a trace inside the record (|s| <= n_samples / n_pulses), through
   the projection-slice theorem: J(s) = sum_nu |I^(u = -s nu, nu)|^2 (2-D FFT of the image,
   u read modulo one cycle a pulse, so a trace walking several samples a pulse is no problem),
   on a grid a quarter of a sample of walk over the aperture apart;
2. then directly on P with bounded Brent iterations to far below one grid step (the paper's
   "sub-degree" refinement); the intercept k0 comes from the best projection's peak.

The trace is an envelope feature: the slope is unambiguous whatever the azimuth aliasing (the
Doppler centroid may exceed the PRF: Table II, case 8, 593 Hz at 80 Hz).
"""

from __future__ import annotations

import os

import numpy as np
import scipy.fft
from scipy.optimize import minimize_scalar

#: The slice search works on the image summed over blocks of samples so that it has at most
#: this many columns (a few MB of spectrum even for Table I's 6400 pulses).
SLICE_COLUMNS = 512


def projection(image: np.ndarray, slope: float, k0: np.ndarray, cells: int = 1 << 21) -> np.ndarray:
    """P(k0) = sum_n image[n, k0 + slope (n - n_c)] with n_c the middle pulse (slope in samples a
    pulse, linear interpolation, zero outside the image), float64 (len(k0),). Computed over blocks
    of intercepts of at most ``cells`` (pulse, intercept) pairs: at once, every intercept of a
    Table I record (6400 pulses x 12900 samples) took ~3 GB of index and weight arrays."""
    n_pulses, n_samples = image.shape
    k0 = np.asarray(k0, dtype=np.float64)
    offsets = slope * (np.arange(n_pulses) - 0.5 * (n_pulses - 1))[:, None]
    rows = np.arange(n_pulses)[:, None]
    out = np.empty(k0.size)
    step = max(1, cells // n_pulses)
    for s in range(0, k0.size, step):
        pos = k0[None, s:s + step] + offsets
        i = np.floor(pos).astype(np.int64)
        w = pos - i
        lo = np.where((i >= 0) & (i < n_samples), image[rows, np.clip(i, 0, n_samples - 1)], 0.0)
        hi = np.where((i >= -1) & (i + 1 < n_samples), image[rows, np.clip(i + 1, 0, n_samples - 1)], 0.0)
        out[s:s + step] = ((1 - w) * lo + w * hi).sum(axis=0)
    return out


def _slice_search(image: np.ndarray, workers: int) -> tuple[float, float]:
    """(slope, its uncertainty) in samples a pulse from the projection-slice energy."""
    n_pulses, n_samples = image.shape
    block = int(np.ceil(n_samples / SLICE_COLUMNS))
    cols = n_samples // block
    coarse = image[:, :cols * block].reshape(n_pulses, cols, block).sum(axis=2)
    n_u = scipy.fft.next_fast_len(4 * n_pulses)
    power = np.abs(scipy.fft.rfft2(coarse, s=(n_u, cols), axes=(0, 1), workers=workers)) ** 2
    nu = np.arange(power.shape[1]) / cols  # cycles a (coarse) sample, >= 0 (the image is real)
    nu_idx = np.arange(1, power.shape[1])  # DC carries no slope

    def energy(slopes: np.ndarray) -> np.ndarray:
        out = np.empty(slopes.size)
        for s in range(0, slopes.size, 256):
            u = (-np.outer(slopes[s:s + 256], nu[nu_idx]) * n_u) % n_u
            i = np.floor(u).astype(np.int64)
            w = u - i
            out[s:s + 256] = ((1 - w) * power[i, nu_idx] + w * power[(i + 1) % n_u, nu_idx]).sum(axis=1)
        return out

    step = 0.25 / n_pulses  # coarse samples a pulse: a quarter sample of walk over the aperture
    limit = cols / max(n_pulses - 1, 1)
    grid = np.arange(-limit, limit + step, 4 * step)
    best = grid[np.argmax(energy(grid))]
    fine = best + np.arange(-8, 9) * step
    best = fine[np.argmax(energy(fine))]
    return best * block, step * block


def line_slope(image: np.ndarray, workers: int | None = None, k_halfwidth: int = 32) -> tuple[float, float]:
    """The slope (samples a pulse) and intercept (sample, at the middle pulse) of the strongest
    straight trace in ``image`` (n_pulses, n_samples; a real non-negative map such as |s_rcmc|)."""
    workers = os.cpu_count() if workers is None else int(workers)
    slope, step = _slice_search(image, workers)
    k_all = np.arange(image.shape[1], dtype=np.float64)
    k_peak = float(np.argmax(projection(image, slope, k_all)))
    k0 = np.arange(k_peak - k_halfwidth, k_peak + k_halfwidth + 1)

    def energy(s: float) -> float:
        p = projection(image, s, k0)
        return float(p @ p)

    lo, hi = slope - 2 * step, slope + 2 * step
    slope = float(minimize_scalar(lambda s: -energy(s), bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-3 * step}).x)
    p = projection(image, slope, k0)
    j = int(np.clip(np.argmax(p), 1, p.size - 2))
    a, b, c = p[j - 1:j + 2]
    den = a - 2 * b + c
    return slope, float(k0[j] + (0.5 * (a - c) / den if den < 0 else 0.0))
