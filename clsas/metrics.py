"""Point-response metrics: peak location, IRW, PSLR, ISLR, and 1-D cuts through a 2-D peak (NumPy only).

Definitions (applied to one 1-D cut through a peak, after FFT upsampling, see
:func:`upsample_cut`):

- **peak location**: the maximum of the upsampled magnitude, refined by a parabola through it
  and its two neighbours; reported in axis units (and as a fractional sample index).
- **IRW** (impulse response width): the width of the main lobe at -3 dB (|x| = peak / sqrt 2),
  crossings found by linear interpolation between upsampled samples.
- **main lobe**: from the first minimum of |x| left of the peak to the first minimum right of it
  (null to null for a sinc).
- **side-lobe region**: everything outside the main lobe within ``extent`` IRWs of the peak
  (default 10, as in Cumming & Wong's ISLR convention), clipped to the cut.
- **PSLR** = 20 log10(max side-lobe magnitude / peak magnitude), dB.
- **ISLR** = 10 log10(side-lobe energy / main-lobe energy), dB.

For an unweighted sinc: PSLR -13.26 dB, IRW 0.886 samples per 1/B, ISLR about -10 dB.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PointResponse:
    """Metrics of one 1-D point response.

    ``location`` and ``irw`` are in axis units; ``index`` is the fractional sample index of
    the peak; ``peak`` is the complex value at the upsampled maximum.
    """

    location: float
    index: float
    peak: complex
    irw: float
    pslr_db: float
    islr_db: float


def _zero_pad_middle(spec: np.ndarray, factor: int) -> np.ndarray:
    n = spec.size
    if factor == 1:  # nothing to insert; splitting the Nyquist bin would halve it
        return spec.astype(np.complex128, copy=True)
    out = np.zeros(n * factor, dtype=np.complex128)
    pos = (n + 1) // 2
    out[:pos] = spec[:pos]
    out[n * factor - (n - pos):] = spec[pos:]
    if n % 2 == 0:
        out[n // 2] = 0.5 * spec[n // 2]
        out[n * factor - n // 2] = 0.5 * spec[n // 2]
    return out


def upsample_cut(x, factor: int = 16) -> np.ndarray:
    """Trigonometric (FFT) interpolation of a complex 1-D cut to ``factor`` times as many samples.

    Output sample j sits at input position j / factor. The spectrum's band is chosen where the
    signal lives: the zeros are inserted at the weakest part of the spectrum (found on a
    smoothed power spectrum), not blindly at the Nyquist bin, so responses whose spectrum is
    not centred on DC (a residual linear phase) interpolate correctly.
    """
    x = np.asarray(x, dtype=np.complex128)
    if x.ndim != 1 or x.size < 4:
        raise ValueError(f"a cut must be 1-D with >= 4 samples, got shape {x.shape}")
    if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 1:
        raise ValueError(f"factor must be an integer >= 1, got {factor!r}")
    n = x.size
    spec = np.fft.fft(x)
    width = max(1, n // 16)
    kernel = np.ones(width) / width
    power = np.abs(spec) ** 2
    smooth = np.convolve(np.concatenate([power[-width:], power, power[:width]]), kernel, "same")[width:-width]
    shift = int(np.argmin(smooth)) - n // 2  # move the gap to the Nyquist position
    rolled = np.roll(spec, -shift)
    y = np.fft.ifft(_zero_pad_middle(rolled, factor)) * factor
    # undo the demodulation implied by the roll: x[k] = x_rolled[k] exp(j 2 pi shift k / n)
    return y * np.exp(2j * np.pi * shift * (np.arange(n * factor) / factor) / n)


def _crossing(mag: np.ndarray, start: int, step: int, level: float) -> float:
    """Fractional index where |x| first falls below ``level`` walking from ``start`` by ``step``."""
    j = start
    while 0 <= j + step < mag.size and mag[j + step] >= level:
        j += step
    if not 0 <= j + step < mag.size:
        raise ValueError("the cut ends before the main lobe falls to -3 dB: give a longer cut")
    a, b = mag[j], mag[j + step]
    return j + step * (a - level) / (a - b)


def _first_minimum(mag: np.ndarray, start: int, step: int) -> int:
    j = start
    while 0 <= j + step < mag.size and mag[j + step] < mag[j]:
        j += step
    if not 0 <= j + step < mag.size:
        raise ValueError("the cut ends inside the main lobe: give a longer cut")
    return j


def point_response(x, axis=None, upsample: int = 16, extent: float = 10.0, near: float | None = None,
                   radius: float = 1.0) -> PointResponse:
    """Metrics of the strongest peak of the 1-D complex cut ``x`` (see the module docstring).

    Parameters
    ----------
    x : 1-D complex array
    axis : 1-D array, optional
        Uniformly spaced coordinates of the samples (default: sample indices).
    upsample : int
        FFT interpolation factor before measuring.
    extent : float
        Half-width of the side-lobe region, in IRWs.
    near, radius : float, optional
        Measure the strongest peak within ``radius`` samples of sample index ``near``
        (default: the strongest peak of the whole cut).
    """
    x = np.asarray(x)
    if x.ndim != 1 or x.size < 4:
        raise ValueError(f"x must be a 1-D cut with >= 4 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x must be finite everywhere; it has NaN or inf")
    if not np.any(x):
        raise ValueError("x is all zeros: there is no peak to measure")
    if isinstance(upsample, bool) or not isinstance(upsample, (int, np.integer)) or upsample < 1:
        raise ValueError(f"upsample must be an integer >= 1, got {upsample!r}")
    n = x.size
    coords = np.arange(n, dtype=np.float64) if axis is None else np.asarray(axis, dtype=np.float64)
    if coords.shape != (n,):
        raise ValueError(f"axis must have the cut's length {n}, got shape {coords.shape}")
    spacing = (coords[-1] - coords[0]) / (n - 1) if n > 1 else 1.0
    if n > 2 and not np.allclose(np.diff(coords), spacing, rtol=1e-6, atol=0):
        raise ValueError("axis must be uniformly spaced")
    if not extent > 1:
        raise ValueError(f"extent must be > 1 IRW, got {extent}")
    y = upsample_cut(x, upsample)
    mag = np.abs(y)
    if near is None:
        i = int(np.argmax(mag))
    else:
        lo_s = max(0, int(np.floor((near - radius) * upsample)))
        hi_s = min(mag.size, int(np.ceil((near + radius) * upsample)) + 1)
        if lo_s >= hi_s:
            raise ValueError(f"near={near} with radius={radius} lies outside the cut of {n} samples")
        i = lo_s + int(np.argmax(mag[lo_s:hi_s]))
    if 0 < i < mag.size - 1:
        a, b, c = mag[i - 1], mag[i], mag[i + 1]
        denom = a - 2 * b + c
        delta = 0.5 * (a - c) / denom if denom != 0 else 0.0
    else:
        delta = 0.0
    level = mag[i] / np.sqrt(2)
    left = _crossing(mag, i, -1, level)
    right = _crossing(mag, i, +1, level)
    irw_up = right - left
    lo = _first_minimum(mag, i, -1)
    hi = _first_minimum(mag, i, +1)
    k = np.arange(mag.size)
    region = np.abs(k - i) <= extent * irw_up
    side = region & ((k < lo) | (k > hi))
    if not side.any():
        raise ValueError("no side-lobe samples within the side-lobe region: give a longer cut")
    main_energy = np.sum(mag[lo:hi + 1] ** 2)
    index = (i + delta) / upsample
    return PointResponse(
        location=float(coords[0] + index * spacing),
        index=float(index),
        peak=complex(y[i]),
        irw=float(irw_up / upsample * abs(spacing)),
        pslr_db=float(20 * np.log10(mag[side].max() / mag[i])),
        islr_db=float(10 * np.log10(np.sum(mag[side] ** 2) / main_energy)),
    )


def peak_index(data, near=None, radius=None) -> tuple:
    """Index of the largest |data|, optionally only within ``radius`` samples of index ``near``.

    ``radius`` is one number of samples or one per axis.
    """
    data = np.asarray(data)
    if data.size == 0:
        raise ValueError("peak_index of an empty array")
    mag = np.abs(data)
    if near is None:
        return np.unravel_index(int(np.argmax(mag)), data.shape)
    if radius is None or len(near) != data.ndim:
        raise ValueError(f"near must give one index per axis ({data.ndim}) together with radius")
    near = tuple(int(c) for c in near)
    if any(not 0 <= c < s for c, s in zip(near, data.shape)):
        raise ValueError(f"near={near} lies outside the array of shape {data.shape}")
    radii = np.broadcast_to(np.asarray(radius, dtype=int), (data.ndim,))
    if np.any(radii < 0):
        raise ValueError(f"radius must be >= 0, got {radius}")
    lo = [max(0, int(c) - int(r)) for c, r in zip(near, radii)]
    hi = [min(s, int(c) + int(r) + 1) for c, r, s in zip(near, radii, data.shape)]
    window = mag[tuple(slice(a, b) for a, b in zip(lo, hi))]
    if window.size == 0:
        raise ValueError(f"near={near} with radius={radius} lies outside the array of shape {data.shape}")
    local = np.unravel_index(int(np.argmax(window)), window.shape)
    return tuple(a + b for a, b in zip(lo, local))


def cuts(data, index=None) -> list:
    """1-D cuts through ``index`` (default: the peak) of an N-D array, one per axis."""
    data = np.asarray(data)
    index = peak_index(data) if index is None else tuple(int(i) for i in index)
    if len(index) != data.ndim or any(not 0 <= i < s for i, s in zip(index, data.shape)):
        raise ValueError(f"index must give one in-range index per axis of shape {data.shape}, got {index}")
    out = []
    for ax in range(data.ndim):
        sl = list(index)
        sl[ax] = slice(None)
        out.append(data[tuple(sl)])
    return out


def analyse_point(image, near=None, radius: float | None = None, upsample: int = 16,
                  extent: float = 10.0) -> dict:
    """Metrics of a point response in a 2-D :class:`clsas.model.Image` along each of its axes.

    ``near`` (one coordinate per dim, axis units) with ``radius`` (axis units) picks the
    strongest peak within that box; by default the global peak. Returns ``{dim: PointResponse}``
    plus ``"location"``: the refined peak coordinates, one per dim.
    """
    dims = image.dims
    axes = [image.axes[d] for d in dims]
    if near is None:
        idx = peak_index(image.data)
    else:
        if radius is None or len(near) != len(dims):
            raise ValueError(f"near must give one coordinate per dim {dims} together with radius")
        centre = [int(np.argmin(np.abs(ax - c))) for ax, c in zip(axes, near)]
        radii = [max(1, int(np.ceil(radius / abs(ax[1] - ax[0])))) if ax.size > 1 else 0 for ax in axes]
        idx = peak_index(image.data, near=centre, radius=radii)
    result = {}
    for k, (dim, ax, cut) in enumerate(zip(dims, axes, cuts(image.data, idx))):
        # the peak found above, not the strongest peak elsewhere on the same line
        result[dim] = point_response(cut, ax, upsample=upsample, extent=extent, near=idx[k], radius=1.0)
    result["location"] = tuple(result[d].location for d in dims)
    return result


def entropy(data) -> float:
    """Image entropy -sum(p log p) with p = |x|^2 / sum |x|^2 (nats): lower when the energy is
    concentrated, i.e. when the image is better focused (the autofocus criterion)."""
    power = np.abs(np.asarray(data.data if hasattr(data, "data") else data)) ** 2
    total = power.sum()
    if not total > 0:
        raise ValueError("entropy of an all-zero image is undefined")
    p = power[power > 0] / total
    return float(-np.sum(p * np.log(p)))


def ssim(a, b, sigma: float = 1.5) -> float:
    """Structural similarity (Wang et al. 2004) of two images' magnitudes, each normalised to its
    peak (so [0, 1], constants C1 = 0.01^2, C2 = 0.03^2), with a Gaussian window of ``sigma``
    pixels; the mean SSIM map. Images must have the same shape (e.g. two imagers on one grid;
    Kiang & Kiang 2022 compare their images with RDA, CSA and omega-k this way)."""
    from scipy.ndimage import gaussian_filter

    x = np.abs(np.asarray(getattr(a, "data", a)))
    y = np.abs(np.asarray(getattr(b, "data", b)))
    if x.shape != y.shape or x.ndim != 2:
        raise ValueError(f"ssim needs two 2-D images of one shape, got {x.shape} and {y.shape}")
    if not (x.max() > 0 and y.max() > 0):
        raise ValueError("ssim: an image is all zeros")
    x, y = x / x.max(), y / y.max()
    c1, c2 = 0.01**2, 0.03**2
    mx, my = gaussian_filter(x, sigma), gaussian_filter(y, sigma)
    sxx = gaussian_filter(x * x, sigma) - mx * mx
    syy = gaussian_filter(y * y, sigma) - my * my
    sxy = gaussian_filter(x * y, sigma) - mx * my
    return float(np.mean((2 * mx * my + c1) * (2 * sxy + c2) / ((mx * mx + my * my + c1) * (sxx + syy + c2))))
