"""Multireceiver to monostatic: the phase-centre approximation with the bistatic deformation compensated.

Huang & Yang 2022, eqs. (3)-(4): the two-way path of receiver i, d_i ahead of the transmitter,
to a target at closest range r is, to second order,

    R_i(t; r) ~ 2 sqrt(r^2 + (v t + v r / c + d_i / 2)^2) + (2 v r / c + d_i)^2 / (4 r),

a monostatic path seen from the phase centre u = v t + d_i / 2 (plus the non-stop-and-go
shift v r / c, common to all receivers) and a path excess e_i(r) = (2 v r / c + d_i)^2 / (4 r)
(Heremans 2009 eq. 49's sigma^2 / (4 r) at broadside, with the motion during the echo's travel
added). Its phase (eq. 12, first term) and its delay (second term) are the bistatic
deformation; :func:`clsas.image.record.compensate_bistatic` removes both on the range-compressed record
(eqs. 16-17): each sample at fast time tau (range r = c tau / 2) is read at tau + e_i(r) / c
(a windowed-sinc interpolation: the micro-range migration is range-variant) and multiplied by
exp(+j 2 pi f0 e_i(r) / c) (eq. 16; the printed exponent lacks its j). The third term of
eq. (12), the Doppler phase pi f_t d_i / v, is the slow-time offset of receiver i's phase
centre, d_i / (2 v): instead of the Doppler-domain filter of eq. (18), :func:`pca_record`
places every receiver's rows at their phase centres u_p + d_i / 2 and interleaves the
receivers into one uniformly sampled monostatic record (Wu et al. 2018 eq. 27), which
omega-k, range-Doppler and chirp scaling image.

What remains approximate: e_i(r) is evaluated at broadside (Heremans eq. 49 has cos^2 of the
bearing: within a beam of +-lambda / D the excess is off by at most (lambda / D)^2 of itself)
and at the range of the sample, and fourth-order terms (sigma^4 / (64 r^3)) are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import budget, validate
from ..model import EchoData
from .record import LineRecord, Track, check_straight_track, compensate_bistatic, made_nonstop

BYTES_PER_SAMPLE = 16  # the interleaved rows and their reordered copy, complex64, per input sample


def line_offsets(echo: EchoData, chosen, track) -> np.ndarray:
    """Along-track offsets d_i (m, ahead of the transmitter) of receivers ``chosen``, which must
    sit on the transmitter's track line at fixed offsets (within ``track.tolerance``)."""
    tol = track.tolerance
    offsets = []
    for h in chosen:
        off = echo.rx_position(h, np.zeros((echo.n_pulses, 1)))[:, 0] - echo.tx_pos
        if np.ptp(off, axis=0).max() > tol or np.abs(off[:, [0, 2]]).max() > tol:
            raise ValueError(f"receiver {echo.receivers[h]!r} must sit on the transmitter's track line at a fixed "
                             f"along-track offset (found offsets {off[0]} m varying by {np.ptp(off, axis=0).max():.3g} m)")
        offsets.append(float(np.mean(off[:, 1])))
    return np.asarray(offsets)


def interleave(track, offsets, n_pulses: int) -> tuple[np.ndarray, float, float]:
    """Order of the (pulse, receiver) rows by phase centre u_p + d_i / 2 (Wu et al. 2018 eq. 27),
    and the uniform grid they form (first centre u0 and spacing, m); a ValueError when the
    centres are not uniform within ``track.tolerance``."""
    tol = track.tolerance
    centres = (track.u0 + track.du * np.arange(n_pulses))[:, None] + np.asarray(offsets)[None, :] / 2
    order = np.argsort(centres, axis=None, kind="stable")
    u = centres.ravel()[order]
    step = (u[-1] - u[0]) / (u.size - 1)
    if step <= 0 or np.max(np.abs(u - (u[0] + step * np.arange(u.size)))) > tol:
        raise ValueError("the receivers' phase centres u_p + d_i / 2 do not interleave into a uniform grid "
                         f"(mean spacing {step:.4g} m, largest deviation "
                         f"{np.max(np.abs(u - (u[0] + step * np.arange(u.size)))):.3g} m > {tol:.3g} m): the "
                         "along-track sampling is not uniform; use clsas.backproject")
    return order, float(u[0]), float(step)


@dataclass(frozen=True)
class LineArray:
    """A multireceiver record on a straight track: the transmitter's track, the chosen
    receivers (indices) and their along-track offsets d_i (m, ahead of the transmitter), the
    pulse repetition interval (s)."""

    track: Track
    receivers: list
    offsets: np.ndarray
    pri: float


def line_array(echo: EchoData, receivers=None) -> LineArray:
    """Check that ``echo`` is a range-compressed record of receivers on the transmitter's
    straight track line (fixed along-track offsets) and describe it."""
    validate.instance("echo", echo, EchoData, "an EchoData")
    validate.compression("echo", echo)
    chosen = echo.select_receivers(receivers)
    track = check_straight_track(echo)
    offsets = line_offsets(echo, chosen, track)
    pri = (echo.eta[-1] - echo.eta[0]) / (echo.n_pulses - 1)
    return LineArray(track, chosen, offsets, float(pri))


def pca_record(echo: EchoData, receivers=None, compensate: bool = True, stop_and_go: bool | None = None,
               backend: str | None = None, reference_range: float | None = None) -> LineRecord:
    """Interleave the receivers of a line array into one monostatic-equivalent record.

    Parameters
    ----------
    echo : EchoData, range-compressed, from a straight uniformly sampled track, receivers on the
        transmitter's track line (along-track offsets d_i only).
    receivers : indices or names (default all); their phase centres u_p + d_i / 2 over all
        pulses must interleave into a uniform grid (e.g. Huang & Yang's 32 contiguous receivers
        with v PRI = M d / 2); overlapping or gapped phase centres are refused.
    compensate : apply :func:`compensate_bistatic` (False shows the uncompensated PCA error).
    stop_and_go : how the echoes were made (default ``echo.provenance["stop_and_go"]``).
    backend : where the micro-range interpolation runs (:func:`clsas.interp.resample`).
    reference_range : m; compensate the path excess of this one range at every range (the
        classic range-invariant PCA correction, e.g. the baseline of Zhang et al. 2019, whose
        residual grows away from it); None (default) compensates each range's own.

    Returns
    -------
    LineRecord with n_pulses x len(receivers) rows.
    """
    arr = line_array(echo, receivers)
    compensate = validate.flag("pca_record compensate", compensate)
    chosen, track, offsets = arr.receivers, arr.track, arr.offsets
    nonstop = made_nonstop(echo, stop_and_go)
    order, u0, step = interleave(track, offsets, echo.n_pulses)
    budget.check_bytes(f"pca_record of {len(chosen)} receivers x {echo.n_pulses} pulses x {echo.n_samples} samples",
                       BYTES_PER_SAMPLE * float(len(chosen)) * echo.n_pulses * echo.n_samples,
                       "fewer receivers or pulses at a time")
    t0 = float(np.min(echo.t0[chosen]))
    rows = np.empty((echo.n_pulses, len(chosen), echo.n_samples), dtype=np.complex64)
    for j, (h, d) in enumerate(zip(chosen, offsets)):
        # uncompensated: no path excess (d = v = 0), only the common time axis
        d, speed, lead = (d, track.speed, nonstop) if compensate else (0.0, 0.0, False)
        rows[:, j] = compensate_bistatic(echo.data[h], echo.t0[h], echo.fs, d, speed, echo.waveform, echo.medium,
                                         t0_out=t0, nonstop=lead, backend=backend, reference_range=reference_range)
    data = rows.reshape(-1, echo.n_samples)[order]
    return LineRecord(data=data, u0=u0, du=step, t0=t0, fs=echo.fs, speed=track.speed,
                      track=(track.x, track.z),
                      waveform=echo.waveform, medium=echo.medium, nonstop=nonstop,
                      provenance={"from": "pca_record", "receivers": [echo.receivers[h] for h in chosen],
                                  "compensated": bool(compensate), "reference_range": reference_range,
                                  "echo": dict(echo.provenance)})
