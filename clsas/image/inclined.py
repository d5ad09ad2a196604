"""Inclined-array correction: Wu, Tang & Zhong 2018, "A Correction Approach for the Inclined
Array of Hydrophones in SAS", eqs. (1)-(28).

Geometry (seed 002, Fig. 1, in clsas's frame): the transmitter moves along y at speed v and is
the rotation centre of the array; hydrophone i, nominally d_i ahead of it, sits at
d_i (cos p sin y, cos p cos y, sin p) for yaw y and pitch p (:mod:`clsas.scene.scenario`'s
attitude convention, Wu's Fig. 1b). A target at slant range r from the track line lies
dx = sqrt(r^2 - dz^2) across track and dz below or above it (Wu: dx = r sin(theta_r),
dz = -h). Its exact two-way path (eqs. 1-6, clsas's non-stop-and-go delay) is

    R_i* = sqrt(r^2 + v^2 t^2) + sqrt(r^2 + Q + (v t + v tau* + d_i cos p cos y)^2),
    Q = d_i^2 (cos^2 p sin^2 y + sin^2 p) - 2 d_i (dx cos p sin y + dz sin p)            (eq. 3)

Eq. (3) as printed reads "+ 2 h d_i sin(theta_yaw)" for the term -2 d_i dz sin p: the vertical
offset of the hydrophone is d_i sin(pitch), so the term belongs to the pitch (expanding
|R - P|^2 with the hydrophone above and the target h below gives + 2 h d_i sin p); clsas uses
the derived form.

Single root + offset (eqs. 11-19): R_i = 2 sqrt(r^2 + (v t + v r / c + d_i / 2)^2) + dR(r; d_i),
the ideal monostatic path from the phase centre v t + v r / c + d_i / 2, with (tau* ~ 2 r / c,
the square roots expanded to second order at the beam centre, 1 / r^3 terms dropped)

    dR(r; d_i) = (2 v r / c + d_i)^2 / (4 r) - d_i (dx cos p sin y + dz sin p) / r      (eq. 18)

(eq. 17's 2 v d_i (cos theta - 1) / c, below 1e-5 m for a few degrees, is dropped as in the
paper; with dz = -h the last term is Wu's h d_i sin p / r.) The first term is the
multireceiver's relative range offset, the second the path error of the inclination.

The correction of each hydrophone's range-compressed record (Fig. 3):

1. phase (eq. 21): every sample at fast time tau (range r = c tau / 2) is multiplied by
   exp(+j 2 pi f0 dR(r; d_i) / c), the angles those of its pulse;
2.-4. delay (eqs. 23-26): the range spectrum is multiplied by exp(+j 2 pi f dR(r_ref; d_i) / c),
   the delay at the reference range (the middle of the swath), and transformed back (the same
   linear phase aligns every hydrophone on one fast-time axis);
5. azimuth reconstruction (eqs. 27-28): the pulses' rows of all hydrophones are interleaved by
   phase centre u_p + d_i / 2 (:func:`clsas.image.multireceiver.interleave`) into one
   monostatic-equivalent :class:`~clsas.image.record.LineRecord` whose echoes follow
   R(t; r) = 2 sqrt(r^2 + (v t + v r / c)^2): omega-k, range-Doppler and chirp scaling image it
   (they undo the along-track shift v r / c).

Yaw and pitch may change from pulse to pulse (seed 002 Fig. 5: random in 1-2 degrees): they are
given per pulse, read from a Platform's attitude at the echoes' reception times, or (default)
measured from the echo's own receiver positions, which record where each hydrophone was.

Not corrected (as in the paper): the amplitude of the beam patterns, which turn with the array
(the fully corrected peak stays a fraction of a dB below that of an uninclined array), and the
attitude's change during one pulse's echoes (the angles are those at the reference range's
reception).
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from .. import budget
from .. import validate as v
from ..kernelmath import unit_phasor
from ..model import EchoData
from ..scene.scenario import Platform
from .multireceiver import interleave
from .rangecomp import check_workers
from .record import LineRecord, check_straight_track, made_nonstop

ANGLES = ("yaw", "pitch")


def nominal_offsets(echo: EchoData, chosen, track, tau: float):
    """Each hydrophone's nominal offset d_i (m, signed along the body axis) and its measured
    attitude per pulse (yaw, pitch: (n_chosen, n_pulses) rad), from the recorded receiver
    positions at fast time ``tau`` relative to the transmitter carried on along the straight
    track to the same instant. A hydrophone on the transmitter (d_i = 0) has angle 0."""
    rel = np.empty((len(chosen), echo.n_pulses, 3))
    ahead = np.array([0.0, track.speed * tau, 0.0])
    for j, h in enumerate(chosen):
        rel[j] = echo.rx_position(h, np.full((echo.n_pulses, 1), tau))[:, 0] - echo.tx_pos - ahead
    length = np.linalg.norm(rel, axis=-1)
    d = np.sign(np.mean(rel[..., 1], axis=1)) * np.mean(length, axis=1)
    if np.max(np.ptp(length, axis=1), initial=0.0) > track.tolerance:
        raise ValueError("a hydrophone's distance from the transmitter changes from pulse to pulse by "
                         f"{np.ptp(length, axis=1).max():.3g} m: the array is not rigid (yaw and pitch rotate it)")
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = rel / np.where(d[:, None, None] == 0, np.inf, d[:, None, None])
    yaw = np.arctan2(unit[..., 0], unit[..., 1])
    pitch = np.arcsin(np.clip(unit[..., 2], -1.0, 1.0))
    zero = d == 0
    yaw[zero], pitch[zero] = 0.0, 0.0
    return d, yaw, pitch


def _per_pulse(name: str, value, n_pulses: int) -> np.ndarray:
    """``value``: one angle (rad) for every pulse or one per pulse, finite within +-45 deg, as
    (n_pulses,) float64; TypeError for a wrong kind (a string, a bool, a complex number),
    ValueError for a bad value, both naming ``name``."""
    if not isinstance(value, (list, tuple)) and not (isinstance(value, np.ndarray) and value.ndim > 0):
        angle = v.scalar(name, value, low=-np.pi / 4, high=np.pi / 4, unit="rad", why="+-45 deg")
        return np.full(n_pulses, angle)
    arr = v.array(name, value, (n_pulses,), bound=np.pi / 4)
    return np.array(arr)


def path_offset(r, d, yaw, pitch, dz: float, speed: float, c: float, nonstop: bool = True) -> np.ndarray:
    """dR(r; d_i) of eq. (18), m, broadcast over ranges r (m), offsets d (m) and angles (rad):
    the relative range offset (2 v r / c + d)^2 / (4 r) (without 2 v r / c for stop-and-go
    echoes) and the inclination's path error -d (dx cos p sin y + dz sin p) / r, dx = sqrt(r^2 - dz^2)."""
    r = np.asarray(r, dtype=np.float64)
    lead = 2 * speed * r / c if nonstop else 0.0
    dx = np.sqrt(np.maximum(r * r - dz * dz, 0.0))
    return (lead + d) ** 2 / (4 * r) - d * (dx * np.cos(pitch) * np.sin(yaw) + dz * np.sin(pitch)) / r


def correct_inclined_array(echo: EchoData, yaw=None, pitch=None, receivers=None, correct=ANGLES,
                           depth: float | None = None, r_ref: float | None = None, stop_and_go: bool | None = None,
                           workers: int | None = None) -> LineRecord:
    """Correct an inclined hydrophone array and reconstruct the monostatic-equivalent record
    (see the module docstring).

    Parameters
    ----------
    echo : EchoData, range-compressed, the transmitter on a straight uniformly sampled track.
    yaw, pitch : the array's attitude, rad: one value per pulse (or one for all), or a
        :class:`~clsas.scene.scenario.Platform` whose attitude is read at each pulse's reception
        time eta + 2 r_ref / c; None (default) measures both from the echo's receiver positions.
    receivers : indices or names (default all); their phase centres u_p + d_i / 2 must
        interleave uniformly.
    correct : the angles whose path error is corrected: ("yaw", "pitch") (the paper's method),
        ("yaw",), ("pitch",) or () (only the multireceiver range offset): Table 2's four cases.
    depth : z of the imaged plane, m (default: the track's; then pitch has no first-order effect).
    r_ref : reference range of the delay correction, m (default: the middle of the swath).
    stop_and_go : how the echoes were made (default ``echo.provenance["stop_and_go"]``).
    workers : scipy.fft threads (default: all cores).

    Returns
    -------
    LineRecord (n_pulses x len(receivers) rows, every v PRI / M), for omega_k, range_doppler,
    chirp_scaling.
    """
    v.instance("correct_inclined_array echo", echo, EchoData, "an EchoData")
    v.compression("correct_inclined_array echo", echo)
    correct = tuple(correct) if isinstance(correct, (tuple, list)) else (correct,)
    if any(not isinstance(a, str) or a not in ANGLES for a in correct):
        raise ValueError(f"correct_inclined_array correct: must name angles among {ANGLES}, got {correct!r}")
    if stop_and_go is not None:
        v.flag("correct_inclined_array stop_and_go", stop_and_go)
    if r_ref is not None:
        r_ref = v.positive("correct_inclined_array r_ref", r_ref, high=v.MAX_COORDINATE, unit="m",
                           why="the delay correction's reference range, or None for the swath's middle")
    if depth is not None:
        depth = v.scalar("correct_inclined_array depth", depth, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE,
                         unit="m")
    workers = check_workers(workers, "correct_inclined_array workers")
    chosen = echo.select_receivers(receivers)
    track = check_straight_track(echo)
    c, f0, fs = echo.medium.sound_speed, echo.waveform.f0, echo.fs
    t0 = float(np.min(echo.t0[chosen]))
    n = echo.n_samples
    r_first, r_last = c * t0 / 2, c * (float(np.max(echo.t0[chosen])) + (n - 1) / fs) / 2
    if r_ref is None:
        r_ref = (max(r_first, 0.0) + r_last) / 2
    dz = 0.0 if depth is None else depth - track.z
    if abs(dz) >= r_ref:
        raise ValueError(f"correct_inclined_array depth: {depth!r} m must lie closer to the track (z = {track.z:g} m) "
                         f"than r_ref = {r_ref:.4g} m")
    d, yaw_m, pitch_m = nominal_offsets(echo, chosen, track, 2 * r_ref / c)
    yaw_p, pitch_p = (_attitude(name, value, measured, echo, r_ref)
                      for name, value, measured in (("yaw", yaw, yaw_m), ("pitch", pitch, pitch_m)))
    yaw_c = yaw_p if "yaw" in correct else np.zeros_like(yaw_p)
    pitch_c = pitch_p if "pitch" in correct else np.zeros_like(pitch_p)
    nonstop = made_nonstop(echo, stop_and_go)
    order, u0, step = interleave(track, d, echo.n_pulses)

    n_fft = scipy.fft.next_fast_len(n + int(np.ceil((np.max(echo.t0[chosen]) - t0) * fs)) + 64)
    budget.check_bytes(f"correct_inclined_array of {len(chosen)} hydrophones x {echo.n_pulses} pulses x {n} samples",
                       16.0 * echo.n_pulses * len(chosen) * n + 48.0 * echo.n_pulses * n_fft,
                       "correct fewer hydrophones or pulses at a time")
    for h in chosen:
        v.bounded_gain("correct_inclined_array echo.data", echo.data[h], float(n_fft),
                       advice="scale the echo down (the range FFT amplifies it)")
    f = np.fft.fftfreq(n_fft, 1 / fs)
    rows = np.empty((echo.n_pulses, len(chosen), n), dtype=np.complex64)
    for j, h in enumerate(chosen):
        r = c * (echo.t0[h] + np.arange(n) / fs) / 2
        yaw_j, pitch_j = yaw_c[j if yaw_c.ndim == 2 else slice(None)], pitch_c[j if pitch_c.ndim == 2 else slice(None)]
        offset = np.where(r[None, :] > abs(dz), path_offset(np.maximum(r, abs(dz) + 1e-3)[None, :], d[j],
                                                               yaw_j[:, None], pitch_j[:, None], dz, track.speed, c,
                                                               nonstop), 0.0)
        data = echo.data[h] * unit_phasor(2 * np.pi * f0 * offset / c)  # eq. (21)
        advance = path_offset(r_ref, d[j], yaw_j, pitch_j, dz, track.speed, c, nonstop) / c + (t0 - echo.t0[h])
        spec = scipy.fft.fft(data, n=n_fft, axis=1, workers=workers)
        spec *= unit_phasor(2 * np.pi * advance[:, None] * f[None, :])  # eq. (24)
        rows[:, j] = scipy.fft.ifft(spec, axis=1, workers=workers)[:, :n]
    v.finite_result("correct_inclined_array record", rows, "scale the echo down")
    return LineRecord(data=rows.reshape(-1, n)[order], u0=u0, du=step, t0=t0, fs=fs, speed=track.speed,
                      track=(track.x, track.z), waveform=echo.waveform, medium=echo.medium, nonstop=nonstop,
                      provenance={"from": "correct_inclined_array", "receivers": [echo.receivers[h] for h in chosen],
                                  "corrected": list(correct), "r_ref": float(r_ref), "depth": depth,
                                  "echo": dict(echo.provenance)})


def _attitude(name: str, value, measured: np.ndarray, echo: EchoData, r_ref: float) -> np.ndarray:
    """The angle per pulse (n_pulses,), or per hydrophone and pulse when measured."""
    if value is None:
        return measured
    if isinstance(value, Platform):
        return value.motion_error(name, echo.eta + 2 * r_ref / echo.medium.sound_speed)
    return _per_pulse(f"correct_inclined_array {name}", value, echo.n_pulses)
