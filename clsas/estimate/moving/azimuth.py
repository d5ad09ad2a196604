"""Steps 4-5 of one receiver's moving-target chain (:mod:`.chain`; Kiang & Kiang 2022 eqs. 17-20):
the record aligned with a quadratic delay model (RCMC + RWC, and the delay's higher-order terms)
and compressed in azimuth, optionally sharpened (the residual phase and range walk the quadratic
focus leaves over long apertures, :mod:`.sharpen`).
"""

from __future__ import annotations

import numpy as np

from ...kernelmath import unit_phasor
from . import filters
from .records import Records
from .sharpen import polynomial_phase, residual_phase

#: Samples shifted beyond those a focus window needs (:func:`focus_bins`): the band-limited shift
#: of a record cut there reaches the window attenuated by ~1 / (pi MARGIN) (-46 dB).
MARGIN = 64


def align_bins(rec: Records, fm_rate: float, doppler_centroid: float, bins: slice,
               higher_order: np.ndarray | None = None, walk: float = 0.0) -> np.ndarray:
    """RCMC + RWC of the record (and ``higher_order`` (n_pulses,) s, the delay's terms beyond
    the quadratic: :func:`.filters.migration`) cut to the range ``bins``: (n_pulses, n_bins)
    complex64. ``walk`` (s/s) is a range walk about the middle of the record compensated in
    range only, its phase left (:func:`sharpened_bins`). Only the samples the shifts bring into
    ``bins`` are shifted (and :data:`MARGIN` more each side)."""
    shift, cycles = filters.migration(rec.d, rec.f0, fm_rate, doppler_centroid, higher_order)
    if walk:
        shift = shift + walk * rec.d
    n = rec.x.shape[1]
    start, stop, _ = bins.indices(n)
    lo = int(np.clip(start + np.floor(shift.min() * rec.fs) - MARGIN, 0, n))
    hi = int(np.clip(stop + np.ceil(shift.max() * rec.fs) + MARGIN, lo + 1, n))
    return filters.advance(rec.x[:, lo:hi], rec.fs, shift, cycles)[:, start - lo:stop - lo]


def compress(rec: Records, aligned: np.ndarray, fm_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth compression (:func:`.filters.compress`) of ``aligned`` rows of ``rec`` about its
    eta_ref: (image, eta axis (n_eta,) s of slow time, one period centred on eta_ref)."""
    image, axis = filters.compress(aligned, rec.d, fm_rate)
    return image, axis + rec.eta_ref


def focus_bins(rec: Records, fm_rate: float, doppler_centroid: float, bins: slice,
               higher_order: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Step 5: :func:`align_bins`, then azimuth compression of the range ``bins``:
    (image (n_eta, n_bins), eta axis (n_eta,) s)."""
    return compress(rec, align_bins(rec, fm_rate, doppler_centroid, bins, higher_order), fm_rate)


#: Alignments of :func:`sharpened_bins` at most (each followed by a sharpness search).
SHARPEN_ALIGNMENTS = 3


def sharpened_bins(rec: Records, fm_rate: float, doppler_centroid: float, bins: slice,
                   higher_order: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`focus_bins` with the target's residual phase found by sharpness and removed
    (:mod:`.sharpen`): (image, eta axis, (p2, p3, p4) cycles at the aperture's ends); see
    :func:`sharpened_window`."""
    image, eta_axis, total, _ = sharpened_window(rec, fm_rate, doppler_centroid, bins, higher_order)
    return image, eta_axis, total


def sharpened_window(rec: Records, fm_rate: float, doppler_centroid: float, bins: slice,
                     higher_order: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(image, eta axis, (p2, p3, p4) cycles at the aperture's ends, the aligned window
    (n_pulses, n_bins) that was compressed with ``fm_rate`` into the image): :func:`focus_bins`
    with the target's residual phase found by sharpness and removed (:mod:`.sharpen`).

    The residual is a delay error: its polynomial part phi / f0 (from the sharpness search) and
    its linear part, which the search leaves to move the image (the centroid's error df: the
    target focuses at eta_p = -df / K), so a range walk df / f0 = -K eta_p / f0 with eta_p the
    image's peak. Both are compensated in range too (the walk in range only, keeping the image
    where the centroid puts it); when they moved the record by more than a tenth of a range
    cell 1 / B at the aperture's ends, the record is aligned again with them and searched again
    (at most :data:`SHARPEN_ALIGNMENTS` times). On an extended target the peak is its strongest
    scatterer, whose walk differs from the centre's (the chain's RCMC is the reference
    point's); a walk that would move the record by more than half the window's margin
    (:data:`MARGIN` / 2 samples at the aperture's ends) is not applied. The Taylor terms are taken about the middle of the record (the layout's default
    eta_ref)."""
    eta_ref, d = rec.eta_ref, rec.d
    half = 0.5 * float(np.ptp(rec.eta))
    n = rec.x.shape[1]
    start, stop, _ = bins.indices(n)
    # the record aligned once with the model over the bins and a margin; the corrections
    # (a few range cells at most) then shift this window only
    wide = slice(max(0, start - MARGIN), min(n, stop + MARGIN))
    aligned = align_bins(rec, fm_rate, doppler_centroid, wide, higher_order)
    inner = slice(start - wide.start, stop - wide.start)
    span = rec.f0 * float(np.max(np.abs(higher_order))) if higher_order is not None else 0.0
    delay, total, walk = np.zeros(rec.eta.shape), np.zeros(3), 0.0

    def window():  # the walk in range only: its phase is where the image lies, not an error
        if not np.any(delay) and walk == 0.0:
            return aligned[:, inner].copy()
        return filters.advance(aligned, rec.fs, delay + walk * d, rec.f0 * delay)[:, inner]

    for _ in range(SHARPEN_ALIGNMENTS):
        win = window()
        p = residual_phase(win, rec.eta, fm_rate, eta_ref, span)
        total += p
        step = polynomial_phase(rec.eta, eta_ref, p) / rec.f0
        win *= unit_phasor(2 * np.pi * rec.f0 * step)[:, None]
        image, eta_axis = compress(rec, win, fm_rate)
        row = np.unravel_index(int(np.argmax(np.abs(image))), image.shape)[0]
        new_walk = -fm_rate * float(eta_axis[row] - eta_ref) / rec.f0
        if abs(new_walk) * half * rec.fs > MARGIN / 2:  # beyond the window's margin: a far glint
            new_walk = walk
        moved = float(np.max(np.abs(step))) + abs(new_walk - walk) * half
        delay, walk = delay + step, new_walk
        if moved * rec.bandwidth <= 0.1:
            return image, eta_axis, total, win
    win = window()
    image, eta_axis = compress(rec, win, fm_rate)
    return image, eta_axis, total, win
