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

from . import budget, validate

MAX_UPSAMPLE = 1024  # FFT interpolation factor of a cut
CUT_BYTES_PER_SAMPLE = 64  # complex128 upsampled cut, its magnitude and temporaries, per output sample


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
    x, peak = _cut("upsample_cut x", x)
    factor = validate.integer("upsample_cut factor", factor, 1, MAX_UPSAMPLE)
    budget.check_bytes(f"upsample_cut of {x.size} samples with factor={factor}", CUT_BYTES_PER_SAMPLE * x.size * factor,
                       "a shorter cut or a smaller factor")
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
    y *= peak * np.exp(2j * np.pi * shift * (np.arange(n * factor) / factor) / n)
    validate.finite_result("upsample_cut: the interpolated cut", y, "scale x down")
    return y


def _cut(name: str, x) -> tuple[np.ndarray, float]:
    """A finite 1-D complex128 cut of >= 4 samples scaled so that its peak is 1, and that peak
    (metrics are ratios and locations: the scale cannot change them, and it keeps |x|^2 and the
    FFTs finite for any finite input)."""
    cut = validate.array(name, x, (-1,), dtype=np.complex128)
    if cut.size < 4:
        raise ValueError(f"{name}: must be a 1-D cut with >= 4 samples, got {cut.size}")
    peak = float(np.abs(cut).max())
    return (cut / peak if peak > 0 else cut), peak


def _crossing(mag: np.ndarray, start: int, step: int, level: float) -> float:
    """Fractional index where |x| first falls below ``level`` walking from ``start`` by ``step``."""
    j = start
    while 0 <= j + step < mag.size and mag[j + step] >= level:
        j += step
    if not 0 <= j + step < mag.size:
        raise ValueError("point_response x: the cut ends before the peak's main lobe falls to -3 dB: give a longer cut "
                         "(or, with near, a peak inside it)")
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
    x, scale = _cut("point_response x", x)
    if not scale > 0:
        raise ValueError("point_response x: is all zeros: there is no peak to measure")
    upsample = validate.integer("point_response upsample", upsample, 1, MAX_UPSAMPLE)
    n = x.size
    coords = np.arange(n, dtype=np.float64) if axis is None else validate.array("point_response axis", axis, (n,))
    spacing = (coords[-1] - coords[0]) / (n - 1)
    if spacing == 0 or (n > 2 and not np.allclose(np.diff(coords), spacing, rtol=1e-6, atol=0)):
        raise ValueError(f"point_response axis: must be uniformly spaced and not constant, got {coords[:4]}...")
    extent = validate.scalar("point_response extent", extent, low=1.0, low_open=True, high=1e6, unit="IRW")
    if near is not None:
        near = validate.scalar("point_response near", near, low=0.0, high=n - 1.0, unit="samples (an index of the cut)")
    radius = validate.positive("point_response radius", radius, high=1e9, unit="samples")
    y = upsample_cut(x, upsample)  # x's peak is 1 (_cut): |y|^2 stays finite
    mag = np.abs(y)
    if near is None:
        i = int(np.argmax(mag))
    else:
        lo_s = max(0, int(np.floor((near - radius) * upsample)))
        hi_s = min(mag.size, int(np.ceil((near + radius) * upsample)) + 1)
        if lo_s >= hi_s:
            raise ValueError(f"point_response near: {near} with radius={radius} lies outside the cut of {n} samples")
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
        raise ValueError("point_response x: no side-lobe samples within the side-lobe region (extent IRWs): give a "
                         "longer cut")
    main_energy = np.sum(mag[lo:hi + 1] ** 2)
    index = (i + delta) / upsample
    return PointResponse(
        location=float(coords[0] + index * spacing),
        index=float(index),
        peak=complex(y[i] * scale),
        irw=float(irw_up / upsample * abs(spacing)),
        pslr_db=float(20 * np.log10(mag[side].max() / mag[i])),
        islr_db=float(10 * np.log10(np.sum(mag[side] ** 2) / main_energy)),
    )


def peak_index(data, near=None, radius=None) -> tuple:
    """Index of the largest |data|, optionally only within ``radius`` samples of index ``near``.

    ``radius`` is one number of samples or one per axis.
    """
    data = _numbers("peak_index data", data)
    if data.size == 0:
        raise ValueError("peak_index data: is empty")
    if near is None:
        return np.unravel_index(int(np.argmax(np.abs(data))), data.shape)
    if radius is None:
        raise ValueError("peak_index radius: give it together with near")
    near = _indices("peak_index near", near, data.ndim)
    if any(not 0 <= c < s for c, s in zip(near, data.shape)):
        raise ValueError(f"peak_index near: {near} lies outside the array of shape {data.shape}")
    radii = _indices("peak_index radius", np.broadcast_to(radius, (data.ndim,)) if np.ndim(radius) == 0 else radius,
                     data.ndim)
    if min(radii) < 0:
        raise ValueError(f"peak_index radius: must be >= 0, got {radius}")
    lo = [max(0, c - r) for c, r in zip(near, radii)]
    hi = [min(s, c + r + 1) for c, r, s in zip(near, radii, data.shape)]
    window = np.abs(data[tuple(slice(a, b) for a, b in zip(lo, hi))])
    local = np.unravel_index(int(np.argmax(window)), window.shape)
    return tuple(a + b for a, b in zip(lo, local))


def _numbers(name: str, data) -> np.ndarray:
    """An Image's data or an array of numbers (not copied)."""
    try:
        values = np.asarray(getattr(data, "data", data))
    except (ValueError, TypeError) as err:  # ragged nested lists
        raise TypeError(f"{name}: must be an Image or an array of numbers, got {type(data).__name__} ({err})") from None
    if values.ndim == 0:
        raise TypeError(f"{name}: must be an Image or an array of numbers, got one {type(data).__name__}")
    if values.dtype.kind not in "iufc":
        raise TypeError(f"{name}: must be an Image or an array of numbers, got {type(data).__name__} "
                        f"of dtype {values.dtype}")
    return values


def _indices(name: str, values, ndim: int) -> tuple:
    """One integer per axis (Python or NumPy integers)."""
    if isinstance(values, (str, bytes)) or np.ndim(values) != 1 or len(values) != ndim:
        raise ValueError(f"{name}: must give one integer per axis ({ndim}), got {values!r}")
    return tuple(validate.integer(name, v, low=-2**62, high=2**62) for v in values)


def cuts(data, index=None) -> list:
    """1-D cuts through ``index`` (default: the peak) of an N-D array, one per axis."""
    data = _numbers("cuts data", data)
    index = peak_index(data) if index is None else _indices("cuts index", index, data.ndim)
    if any(not 0 <= i < s for i, s in zip(index, data.shape)):
        raise ValueError(f"cuts index: must give one in-range index per axis of shape {data.shape}, got {index}")
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
    if not all(hasattr(image, name) for name in ("data", "dims", "axes")):
        raise TypeError(f"analyse_point image: must be a clsas Image, got {type(image).__name__}")
    dims = image.dims
    axes = [image.axes[d] for d in dims]
    if near is None:
        if radius is not None:
            raise ValueError(f"analyse_point radius: applies with near (the box around a point), got radius={radius!r} "
                             "without near")
        idx = peak_index(image.data)
    else:
        if radius is None:
            raise ValueError("analyse_point radius: give it together with near")
        near = validate.array("analyse_point near", near, (len(dims),))
        radius = validate.positive("analyse_point radius", radius, high=validate.MAX_COORDINATE, unit="axis units")
        centre = [int(np.argmin(np.abs(ax - c))) for ax, c in zip(axes, near)]
        radii = [max(1, int(np.ceil(min(radius / abs(ax[1] - ax[0]), ax.size)))) if ax.size > 1 and ax[1] != ax[0]
                 else 0 for ax in axes]
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
    power = relative_power("entropy data", data)
    p = power[power > 0] / power.sum()
    return float(-np.sum(p * np.log(p)))


def contrast(data) -> float:
    """Image contrast std(|x|^2) / mean(|x|^2) (no unit): higher when the image is better focused."""
    power = relative_power("contrast data", data)
    return float(power.std() / power.mean())


def relative_power(name: str, data) -> np.ndarray:
    """|x|^2 / max |x|^2 of an image or array of any finite values (float64, the shape of the
    data): the entropy and the contrast do not depend on the scale, and |x|^2 of values near
    float64's largest would overflow. ValueError for an empty, non-finite or all-zero image."""
    values = _numbers(name, data)
    if values.size == 0:
        raise ValueError(f"{name}: is empty")
    budget.check_bytes(f"{name} of {values.size} pixels", 24.0 * values.size, "a smaller image")
    mag = np.abs(values).astype(np.float64, copy=False)
    if not validate.all_finite(mag):
        raise ValueError(f"{name}: must be finite everywhere; it has NaN or inf")
    peak = mag.max()
    if not peak > 0:
        raise ValueError(f"{name}: is all zeros: its entropy and contrast are undefined")
    mag /= peak
    return np.square(mag, out=mag)


def ssim(a, b, sigma: float = 1.5) -> float:
    """Structural similarity (Wang et al. 2004) of two images' magnitudes, each normalised to its
    peak (so [0, 1], constants C1 = 0.01^2, C2 = 0.03^2), with a Gaussian window of ``sigma``
    pixels; the mean SSIM map. Images must have the same shape (e.g. two imagers on one grid;
    Kiang & Kiang 2022 compare their images with RDA, CSA and omega-k this way)."""
    from scipy.ndimage import gaussian_filter

    sigma = validate.positive("ssim sigma", sigma, high=1e4, unit="pixels")
    shapes = np.shape(getattr(a, "data", a)), np.shape(getattr(b, "data", b))
    if shapes[0] != shapes[1] or len(shapes[0]) != 2:
        raise ValueError(f"ssim a, b: must be two 2-D images of one shape, got {shapes[0]} and {shapes[1]}")
    budget.check_bytes(f"ssim of two {shapes[0][0]} x {shapes[0][1]} images", 96.0 * np.prod(shapes[0], dtype=float),
                       "smaller images")
    x = np.sqrt(relative_power("ssim a", a))  # |a| / max |a|
    y = np.sqrt(relative_power("ssim b", b))
    c1, c2 = 0.01**2, 0.03**2
    mx, my = gaussian_filter(x, sigma), gaussian_filter(y, sigma)
    sxx = gaussian_filter(x * x, sigma) - mx * mx
    syy = gaussian_filter(y * y, sigma) - my * my
    sxy = gaussian_filter(x * y, sigma) - mx * my
    return float(np.mean((2 * mx * my + c1) * (2 * sxy + c2) / ((mx * mx + my * my + c1) * (sxx + syy + c2))))
