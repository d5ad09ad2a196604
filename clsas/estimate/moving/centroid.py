"""Steps 3 and 4 of the chain (Kiang & Kiang 2022, sections III-C and III-D): range cell
migration correction with the azimuth FM rate (eq. 17) and the Doppler centroid from the slope of
the target's straight trace in the corrected record (the Radon transform, :mod:`.radon`), with
the variants :func:`.chain.with_rate` tries when noise or a long aperture's bent noise floor can
fool the plain line: the mean-removed power (:func:`doppler_centroid_walking`) and the record
whitened before the RCMC (:func:`doppler_centroid_whitened`, when :func:`bent`)."""

from __future__ import annotations

import numpy as np

from . import filters, radon, trace
from .records import Records

#: :func:`bent`: the RCMC's largest shift, in pulse lengths, beyond which the record's bent noise
#: floor can fool the Radon lines.
PULSE_SPANS = 1.0


def rcmc(rec: Records, fm_rate: float) -> np.ndarray:
    """Step 3: ``rec`` after range cell migration correction with ``fm_rate`` (eq. 17)."""
    return filters.advance(rec.x, rec.fs, fm_rate * rec.d**2 / (2 * rec.f0))


#: A Radon slope beyond this fraction of its search span (a trace crossing the whole record) is
#: at the search's edge: no straight trace was found.
SLOPE_LIMIT = 0.95


def doppler_centroid_radon(rec: Records, rcmc: np.ndarray) -> tuple[float, float, bool]:
    """Step 4: (f_dc, tau at eta_ref, at the search's edge) of the straight trace in |s_rcmc|
    (:mod:`.radon`): the slope s in samples a pulse is f_dc fs / (f0 PRF), f_dc at eta_ref (the
    RCMC's reference, the middle of the record). The noise floor of each range cell is taken off
    first. The flag is True when the slope is beyond :data:`SLOPE_LIMIT` of the slopes searched."""
    image = np.abs(rcmc).astype(np.float32)
    image -= trace.floor(image)  # the noise's range profile would be a trace of slope 0
    np.maximum(image, 0, out=image)
    return _line(rec, image)


def _line(rec: Records, image: np.ndarray) -> tuple[float, float, bool]:
    """(f_dc, tau at eta_ref, at the search's edge) of ``image``'s strongest straight trace."""
    slope, k_mid = radon.line_slope(image)
    limited = abs(slope) > SLOPE_LIMIT * image.shape[1] / max(image.shape[0] - 1, 1)
    return slope * rec.f0 * rec.prf / rec.fs, rec.t0 + k_mid / rec.fs, bool(limited)  # k_mid: the middle pulse's


def doppler_centroid_walking(rec: Records, rcmc: np.ndarray) -> tuple[float, float, bool]:
    """:func:`doppler_centroid_radon` on the power |s_rcmc|^2 less each range cell's mean over the
    pulses. In heavy noise the floor-subtracted magnitude's cells keep a mean that differs from
    cell to cell (the floor's estimate, the window's uneven noise), which adds up to a line of
    slope 0 stronger than a walking trace (Table II case 5 at A, -15 dB: tests/test_moving_noise.py);
    with the means removed the walking trace is the strongest line. A trace that keeps its
    range cell (f_dc ~ 0) is removed with them: :func:`.chain.with_rate` keeps whichever focuses."""
    power = np.abs(rcmc).astype(np.float32) ** 2
    power -= power.mean(axis=0)
    return _line(rec, power)


def bent(rec: Records, fm_rate: float) -> bool:
    """Whether the RCMC with ``fm_rate`` moves the record's ends by more than a pulse length
    (the span over which the compressed noise floor changes near a window's ends): then the
    Radon lines of |s_rcmc| can follow the bent floor (:func:`doppler_centroid_whitened`) and
    :func:`.chain.with_rate` also tries the whitened record's line and the followed trace's tangent.
    Over Table I's 2048 pulses the RCMC moves the ends by up to ~160 upsampled samples (Table II
    case 6) against a pulse's 200; over 6400 pulses by ~1000 (case 1)."""
    shift = abs(fm_rate) * float(np.max(rec.d**2)) / (2 * rec.f0)
    return bool(shift > PULSE_SPANS * rec.pulse_length)  # False when either is nan


def doppler_centroid_whitened(rec: Records, fm_rate: float) -> tuple[float, float, bool]:
    """:func:`doppler_centroid_walking` on the record whitened per range cell *before* the RCMC
    with ``fm_rate``. The RCMC shifts every pulse by K d^2 / (2 f0): over long apertures
    hundreds of samples (~950 at Table I's 6400 pulses, receiver A), so whatever the record's
    noise floor does across its window (~10x weaker within a pulse length of its ends) and the
    samples shifted in from beyond the record (zeros) become parabolas in |s_rcmc| that no
    per-cell floor taken after the shift removes, and whose tangents are strong straight lines
    (in heavy noise the Radon slope then runs to its search's edge). Here each cell is divided
    by its noise floor (:func:`.trace.floor`) first, and the samples the shift brings in from
    beyond the recorded cells are set to the mean power of the others."""
    power = np.abs(rec.x).astype(np.float32) ** 2
    level = np.median(power[::2], axis=0)
    live = np.flatnonzero(level > trace.RECORDING * float(level.max())) if power.size else np.zeros(0, int)
    if live.size == 0:
        return _line(rec, power)
    shift = fm_rate * rec.d**2 / (2 * rec.f0)
    scale = (1.0 / np.sqrt(trace.floor(power))).astype(np.float32)
    del power
    power = np.abs(filters.advance(rec.x * scale[None, :], rec.fs, shift)) ** 2
    source = np.arange(rec.x.shape[1])[None, :] + (shift * rec.fs)[:, None]  # advance reads x(tau + shift)
    beyond = (source < live[0]) | (source > live[-1])
    power[beyond] = float(power[~beyond].mean()) if np.any(~beyond) else 0.0
    power -= power.mean(axis=0)
    return _line(rec, power)
