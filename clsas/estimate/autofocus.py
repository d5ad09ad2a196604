"""Phase gradient autofocus (PGA; Wahl, Eichel, Ghiglia & Jakowatz, IEEE TAES 30(3), 1994), as
Kiang & Kiang 2022 (section VII-D) use it on blurred SAS images.

Error model and where the correction is applied
------------------------------------------------
PGA assumes one phase error phi(k), the same in every range bin, multiplying the image's
azimuth spectrum: with g(y) one range bin of the image and G(k) = FFT_y g, the blurred bin is
IFFT[G(k) exp(j phi(k))]. In spotlight mode G is the slow-time phase history; in strip-map SAS
it is the azimuth-wavenumber (Doppler) domain, where a track error that changes slowly across
one synthetic aperture acts as a phase error common to the scatterers of an image patch (for
a long strip with errors that change faster, apply PGA patch by patch). clsas estimates phi on
the azimuth-frequency axis of the image, in increasing frequency order (``fftshift`` order),
and corrects by G(k) exp(-j phi(k)).

One iteration (Wahl et al. 1994, section II)
--------------------------------------------
1. Dominant scatterers: the range bins whose brightest pixel lies within ``select_db`` of the
   image's brightest; each is circularly shifted so that pixel is at the bin's centre.
2. Windowing: a centred window whose width is twice the contiguous span around the centre over
   which the incoherent sum of the shifted bins stays within ``window_db`` of its peak, never wider than the previous
   iteration's (the window shrinks as the image focuses), never below ``min_window`` pixels.
3. Phase gradient, the maximum-likelihood kernel (Jakowatz & Wahl 1993):
   dphi(k) = arg sum_n G_n(k) G_n*(k - 1).
4. Integration phi(k) = sum_{k' <= k} dphi(k'), then the constant and the linear trend are
   removed (a linear phase only shifts the image), fitted over the occupied band only: the
   frequencies where the windowed bins' summed power is within OCCUPIED_DB (20 dB) of its
   peak. An image sampled finer than its resolution (e.g. back-projected at an eighth of the
   element length) leaves most of its azimuth band empty; there the gradient estimate is
   noise, its integral wanders, and a fit over the whole band turned that wander into a shift
   of the image: 20-33 cm (2-3 cells) on the DPCA-compensated seed-004 scene at d / 8, within
   1 mm with the fit over the occupied band (tests/test_dpca.py).
5. Correction of the whole image; repeat until the RMS of the iteration's phi over the
   occupied band falls below ``tolerance`` (rad) or ``max_iterations`` is reached. An
   iteration whose correction would raise the image entropy is not applied and ends the loop: the residual error is then beyond
   what the windowed bins can estimate (e.g. fast random phase errors spread into a low
   pedestal), and further estimates would add noise.

The FFTs run on the host (scipy.fft with workers); the per-bin work is a handful of vectorised
NumPy operations, so PGA has no OpenCL kernel (its cost is the FFTs: see bench/bench_dpca.py).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.fft

from .. import budget, metrics, validate
from ..errors import EstimationError
from ..metrics import contrast
from ..model import Image

log = logging.getLogger("clsas")

AZIMUTH_DIMS = ("y", "eta", "u")
# The occupied azimuth band: frequencies where the selected, windowed range bins' summed power
# is within this many dB of its peak (module docstring, step 4).
OCCUPIED_DB = 20.0
#: bytes a pixel of the image that PGA holds at once: the image, its corrected copy, the
#: spectrum of the correction and the power maps (tests/test_autofocus.py measures the peak)
PGA_BYTES_PER_PIXEL = 64
CORRECTION_BYTES_PER_PIXEL = 24  # apply_phase_correction: the spectrum and the result
MAX_WORKERS = 1024


@dataclass(frozen=True, eq=False)
class AutofocusResult:
    """What :func:`pga` returns.

    image : Image, the corrected image (same dims, axes and positions as the input)
    phase_error : float64 (n_azimuth,), rad: the estimated error phi(k) in increasing azimuth
        frequency order (``frequencies``), constant and linear trend removed over the occupied band
    frequencies : float64 (n_azimuth,), cycles per unit of the azimuth axis (1/m or Hz)
    iterations : int, the iterations applied
    rms : tuple of float, rad: RMS of each applied iteration's phase correction over the occupied band
    entropy_before, entropy_after : float, nats (:func:`clsas.metrics.entropy`)
    contrast_before, contrast_after : float, std/mean of the pixel power
    """

    image: Image
    phase_error: np.ndarray
    frequencies: np.ndarray
    iterations: int
    rms: tuple
    entropy_before: float
    entropy_after: float
    contrast_before: float
    contrast_after: float


__all__ = ["AutofocusResult", "apply_phase_correction", "contrast", "pga"]


def _azimuth_axis(image: Image, axis: str | None) -> int:
    if axis is None:
        found = [d for d in image.dims if d in AZIMUTH_DIMS]
        if len(found) != 1:
            raise ValueError(f"pga axis: cannot tell the azimuth axis of an image with dims {image.dims}; "
                             f"give axis= one of them")
        axis = found[0]
    if not isinstance(axis, str):
        raise TypeError(f"pga axis: must be the name of one of the image's dims {image.dims}, got {axis!r}")
    if axis not in image.dims:
        raise ValueError(f"pga axis: must be one of the image's dims {image.dims}, got {axis!r}")
    return image.dims.index(axis)


def _azimuth_step(image: Image, ax: int) -> float:
    """The azimuth axis's spacing (axis units); ValueError unless it is uniform and not zero:
    PGA's azimuth spectrum (and ``frequencies``) needs evenly spaced samples."""
    name = image.dims[ax]
    coords = image.axes[name]
    step = (coords[-1] - coords[0]) / (coords.size - 1)
    if not (step != 0 and np.allclose(np.diff(coords), step, rtol=1e-6, atol=0)):
        raise ValueError(f"pga image: its azimuth axis {name!r} must be evenly spaced and not constant "
                         f"(PGA works on its spectrum), got {coords[:3]}...")
    return float(step)


def _check(image, tolerance, max_iterations, select_db, window_db, min_window, min_contrast, workers) -> None:
    if not isinstance(image, Image):
        raise TypeError(f"pga image: must be a clsas Image, got {type(image).__name__}")
    if image.data.ndim != 2:
        raise ValueError(f"pga image: must be 2-D (azimuth x range), got shape {image.shape}")
    validate.positive("pga tolerance", tolerance, high=10.0, unit="rad")
    validate.positive("pga select_db", select_db, high=400.0, unit="dB")
    validate.positive("pga window_db", window_db, high=400.0, unit="dB")
    validate.scalar("pga min_contrast", min_contrast, low=1.0, low_open=True, high=1e30)
    validate.integer("pga max_iterations", max_iterations, 1, 10_000)
    validate.integer("pga min_window", min_window, 3, 2**31)
    if workers is not None:
        validate.integer("pga workers", workers, -MAX_WORKERS, MAX_WORKERS)
    if not validate.all_finite(image.data):
        raise ValueError("pga image: has NaN or inf pixels")


def _dominant_bins(g: np.ndarray, select_db: float, min_contrast: float) -> np.ndarray:
    """Rows (range bins) of ``g`` [bin, azimuth] whose peak power is within ``select_db`` of the
    brightest; raises EstimationError when not even the brightest stands out of its bin."""
    power = np.abs(g) ** 2
    peak = power.max(axis=1)
    best = int(np.argmax(peak))
    mean = power[best].mean()
    ratio = peak[best] / mean if mean > 0 else 0.0
    if not ratio >= min_contrast:
        raise EstimationError(f"pga: no dominant scatterer: the brightest range bin's peak-to-mean power is "
                              f"{ratio:.1f} ({10 * np.log10(max(ratio, 1e-30)):.1f} dB), needs >= {min_contrast:g}")
    return np.flatnonzero(peak >= peak[best] * 10 ** (-select_db / 10))


def _window_width(centred: np.ndarray, window_db: float, previous: int, min_window: int) -> int:
    """Twice the contiguous span around the centre where the bins' summed power stays within
    window_db of its peak (other scatterers of the same bins further out do not widen it), no
    wider than ``previous``, at least ``min_window``."""
    n = centred.shape[1]
    profile = (np.abs(centred) ** 2).sum(axis=0)
    below = profile < profile[n // 2] * 10 ** (-window_db / 10)
    right = np.flatnonzero(below[n // 2:])
    left = np.flatnonzero(below[n // 2::-1])
    half = max(right[0] if right.size else n - n // 2, left[0] if left.size else n // 2 + 1)
    return int(np.clip(2 * (2 * half - 1), min_window, previous))


def _phase_gradient_step(g: np.ndarray, bins: np.ndarray, width: int, window_db: float, min_window: int,
                         workers: int | None):
    """One PGA estimate from the dominant ``bins`` of ``g`` [bin, azimuth]: (phi, window width,
    the occupied azimuth frequencies as a bool mask)."""
    n = g.shape[1]
    rows = g[bins]
    shift = n // 2 - np.argmax(np.abs(rows), axis=1)
    cols = (np.arange(n)[None, :] - shift[:, None]) % n
    centred = np.take_along_axis(rows, cols, axis=1)
    width = _window_width(centred, window_db, width, min_window)
    lo = n // 2 - width // 2
    windowed = np.zeros_like(centred)
    windowed[:, lo:lo + width] = centred[:, lo:lo + width]
    spec = scipy.fft.fftshift(scipy.fft.fft(scipy.fft.ifftshift(windowed, axes=1), axis=1, workers=workers), axes=1)
    dphi = np.angle(np.sum(spec[:, 1:] * np.conj(spec[:, :-1]), axis=0))
    phi = np.concatenate([[0.0], np.cumsum(dphi)])
    power = np.sum(np.abs(spec) ** 2, axis=0)
    occupied = power >= power.max() * 10 ** (-OCCUPIED_DB / 10)
    k = np.arange(n, dtype=np.float64)
    phi -= np.polyval(np.polyfit(k[occupied], phi[occupied], 1), k)
    return phi, width, occupied


def apply_phase_correction(data: np.ndarray, phi: np.ndarray, axis: int, workers: int | None = None) -> np.ndarray:
    """``data`` with exp(-j phi) applied to its azimuth spectrum along ``axis`` (phi in
    increasing-frequency order, length ``data.shape[axis]``); complex64."""
    given = data
    try:
        data = np.asarray(data)
    except (ValueError, TypeError):  # ragged nested lists
        data = np.empty(0, dtype=object)
    if data.dtype.kind not in "iufc" or data.ndim == 0:
        raise TypeError(f"apply_phase_correction data: must be an array of numbers (at least 1-D), got "
                        f"{type(given).__name__} of dtype {data.dtype}")
    axis = validate.integer("apply_phase_correction axis", axis, -data.ndim, data.ndim - 1,
                            why=f"an axis of the {data.ndim}-D data")
    phi = validate.array("apply_phase_correction phi", phi, (data.shape[axis],), bound=1e12)
    if workers is not None:
        validate.integer("apply_phase_correction workers", workers, -MAX_WORKERS, MAX_WORKERS)
    budget.check_bytes(f"apply_phase_correction of {data.size} samples", CORRECTION_BYTES_PER_PIXEL * data.size,
                       "a smaller image")
    shape = [1] * data.ndim
    shape[axis] = -1
    ramp = np.exp(-1j * scipy.fft.ifftshift(phi)).astype(np.complex64).reshape(shape)
    spec = scipy.fft.fft(data.astype(np.complex64, copy=False), axis=axis, workers=workers)
    spec *= ramp
    out = scipy.fft.ifft(spec, axis=axis, workers=workers, overwrite_x=True)
    validate.finite_result("apply_phase_correction: the corrected data", out, "scale the data down")
    return out

def pga(image: Image, axis: str | None = None, *, tolerance: float = 0.01, max_iterations: int = 20,
        select_db: float = 20.0, window_db: float = 10.0, min_window: int = 32, min_contrast: float = 20.0,
        workers: int | None = -1) -> AutofocusResult:
    """Phase gradient autofocus of ``image`` along its azimuth axis (see the module docstring).

    Parameters
    ----------
    image : Image, 2-D (azimuth x range in either order), from any imager.
    axis : name of the azimuth dim; by default the one of "y", "eta", "u" that the image has.
    tolerance : rad; stop when an iteration's correction has RMS below it.
    max_iterations : at most this many iterations.
    select_db : dB; range bins whose brightest pixel is within this of the image's brightest are
        the dominant scatterers used.
    window_db : dB; the window spans twice the width over which the shifted bins' summed power
        stays within this of its peak.
    min_window : pixels; the narrowest window.
    min_contrast : the brightest range bin's peak-to-mean power must reach this, or there is no
        dominant scatterer to estimate from (EstimationError). White noise over n pixels has a
        peak-to-mean near ln(n) (about 6 for 512 pixels).
    workers : scipy.fft workers (-1: all cores).

    Returns
    -------
    AutofocusResult (the corrected image, the phase error, entropy and contrast before and after).

    Raises
    ------
    EstimationError when the image has no dominant scatterer (see ``min_contrast``).
    """
    _check(image, tolerance, max_iterations, select_db, window_db, min_window, min_contrast, workers)
    ax = _azimuth_axis(image, axis)
    n = image.shape[ax]
    if n < 2 * min_window:
        raise ValueError(f"pga min_window: the azimuth axis has {n} pixels, needs >= 2 x min_window = {2 * min_window}")
    step = _azimuth_step(image, ax)
    budget.check_bytes(f"pga of a {image.shape[0]} x {image.shape[1]} image", PGA_BYTES_PER_PIXEL * image.data.size,
                       "autofocus a smaller patch of the image")
    data = image.data
    total = np.zeros(n)
    history = []
    width = n
    entropy = metrics.entropy(data)
    for _ in range(max_iterations):
        g = np.moveaxis(data, ax, -1)
        bins = _dominant_bins(g, select_db, min_contrast)
        phi, width, occupied = _phase_gradient_step(g, bins, width, window_db, min_window, workers)
        corrected = apply_phase_correction(data, phi, ax, workers)
        rms = float(np.sqrt(np.mean(phi[occupied] ** 2)))
        after = metrics.entropy(corrected)
        log.debug("pga iteration %d: %d range bins, window %d px, RMS correction %.4f rad, entropy %.4f -> %.4f",
                  len(history) + 1, bins.size, width, rms, entropy, after)
        if after > entropy:
            break  # the estimate is now noise: it defocuses; keep the previous image
        data, entropy = corrected, after
        total += phi
        history.append(rms)
        if rms < tolerance:
            break
    result = AutofocusResult(
        image=image.replace(data=data, provenance={**image.provenance, "autofocus": {
            "algorithm": "pga", "iterations": len(history), "tolerance": tolerance, "select_db": select_db,
            "window_db": window_db, "min_window": min_window}}),
        phase_error=total, frequencies=scipy.fft.fftshift(scipy.fft.fftfreq(n, step)), iterations=len(history),
        rms=tuple(history), entropy_before=metrics.entropy(image), entropy_after=entropy,
        contrast_before=contrast(image), contrast_after=contrast(data))
    log.info("pga: %d iterations, entropy %.3f -> %.3f nats, contrast %.2f -> %.2f", result.iterations,
             result.entropy_before, result.entropy_after, result.contrast_before, result.contrast_after)
    return result
