"""Straight-track, uniformly sampled monostatic records: what the frequency-domain imagers take,
and the helpers all of them share (omega-k, range-Doppler, chirp scaling and the multireceiver
conversion import from here; nothing here imports them).

omega-k, range-Doppler and chirp scaling assume a monostatic sonar moving at constant speed
along a straight line (y, the nominal heading) and sampling the aperture uniformly. A
:class:`LineRecord` is such a record; :func:`line_record` makes one from a monostatic
EchoData (after checking those assumptions, so that a track with motion errors is refused
rather than imaged wrongly), and :func:`clsas.image.multireceiver.pca_record` makes one from a
multireceiver EchoData; :func:`as_record` takes either.

Non-stop-and-go: the receiver moves on while the echo travels, so a monostatic echo of a
target at closest range r behaves as if sent and received at u + v r / c (Wu et al. 2018
eq. 28; Huang & Yang 2022 eq. 4 with d_i = 0), plus a two-way path excess (2 v r / c)^2 / (4 r)
(compensated by :func:`compensate_bistatic`, which every
:func:`line_record` applies when ``nonstop``). The imagers then undo the range-dependent
along-track shift v r / c (Huang & Yang eq. 25).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.fft

from .. import validate
from ..model import MAX_ECHO_FS, EchoData, Image, Medium, Waveform
from ..interp import INTERPOLATORS, TAP_WINDOWS, resample
from ..scene.scenario import MAX_ELEMENT
from ..pulse import spectral_window

STRAIGHTNESS = 0.05  # allowed deviation of the track from a line, wavelengths


@dataclass(frozen=True, eq=False)
class LineRecord:
    """A monostatic-equivalent strip-map record on a straight, uniformly sampled track.

    data : complex (n_u, n_samples); row p was recorded at along-track position u0 + p du
        (its phase centre), sample k at two-way fast time t0 + k / fs.
    u0, du : m. t0 : s. fs : Hz.
    speed : platform speed along +y, m/s (the along-track shift v r / c uses it).
    track : (x, z) of the track line, m; the imaged side is +x (docs/design.md's convention).
    waveform, medium : the pulse and the water.
    nonstop : whether the echoes carry the non-stop-and-go shift v r / c.
    provenance : how it was made.
    """

    data: np.ndarray
    u0: float
    du: float
    t0: float
    fs: float
    speed: float
    track: tuple
    waveform: Waveform
    medium: Medium
    nonstop: bool
    provenance: dict = field(default_factory=dict)

    def __post_init__(self):
        data = validate.instance("LineRecord.data", self.data, np.ndarray, "a complex (n_u, n_samples) array")
        if data.dtype.kind != "c":
            raise TypeError(f"LineRecord.data: must be complex baseband samples, got dtype {data.dtype}")
        if data.ndim != 2:
            raise ValueError(f"LineRecord.data: must be 2-D (n_u, n_samples), got shape {data.shape}")
        bounds = {"u0": dict(low=-validate.MAX_COORDINATE, high=validate.MAX_COORDINATE, unit="m"),
                  "du": dict(low=0.0, low_open=True, high=validate.MAX_COORDINATE, unit="m"),
                  "t0": dict(low=-validate.MAX_TIME, high=validate.MAX_TIME, unit="s"),
                  "fs": dict(low=0.0, low_open=True, high=MAX_ECHO_FS, unit="Hz"),
                  "speed": dict(low=0.0, high=validate.MAX_SPEED, unit="m/s")}
        for name, bound in bounds.items():
            object.__setattr__(self, name, validate.scalar(f"LineRecord.{name}", getattr(self, name), **bound))
        track = validate.array("LineRecord.track (x, z)", self.track, (2,), bound=validate.MAX_COORDINATE)
        object.__setattr__(self, "track", (float(track[0]), float(track[1])))
        validate.instance("LineRecord.waveform", self.waveform, Waveform, "a Waveform")
        validate.instance("LineRecord.medium", self.medium, Medium, "a Medium")
        object.__setattr__(self, "nonstop", validate.flag("LineRecord.nonstop", self.nonstop))

    @property
    def n_u(self) -> int:
        return self.data.shape[0]

    @property
    def n_samples(self) -> int:
        return self.data.shape[1]

    @property
    def wavelength(self) -> float:
        return self.medium.sound_speed / self.waveform.f0

    def replace(self, **changes) -> LineRecord:
        return dataclasses.replace(self, **changes)


class Track(NamedTuple):
    """A straight, uniformly sampled transmitter track: u0, du (m) of its along-track samples,
    its cross-track position x and depth z (m), its speed (m/s) and the tolerance it was held
    to (m)."""

    u0: float
    du: float
    x: float
    z: float
    speed: float
    tolerance: float


def check_straight_track(echo: EchoData) -> Track:
    """The transmitter's track: a line along y sampled uniformly, within STRAIGHTNESS
    wavelengths; otherwise a ValueError naming what deviates."""
    if echo.n_pulses < 2:
        raise ValueError(f"a strip-map record needs at least 2 pulses, got {echo.n_pulses}")
    tol = STRAIGHTNESS * echo.medium.sound_speed / echo.waveform.f0
    tx = echo.tx_pos
    p = np.arange(echo.n_pulses)
    du, u0 = np.polyfit(p, tx[:, 1], 1)
    dev = {"x (across track)": np.ptp(tx[:, 0]), "z (depth)": np.ptp(tx[:, 2]),
           "y (along track, from uniform spacing)": np.max(np.abs(tx[:, 1] - (u0 + du * p)))}
    for what, value in dev.items():
        if value > tol:
            raise ValueError(f"the frequency-domain imagers need a straight, uniformly sampled track along y: the "
                             f"transmitter's {what} varies by {value:.3g} m > {tol:.3g} m ({STRAIGHTNESS} wavelengths); "
                             "use clsas.backproject for this geometry")
    if du <= 0:
        raise ValueError(f"the platform must move along +y (the along-track step is {du:.3g} m)")
    if not echo.eta[-1] > echo.eta[0]:
        raise ValueError(f"echo.eta: the emission times must increase along the track, got {echo.eta[0]:g} s to "
                         f"{echo.eta[-1]:g} s")
    speed = du * (echo.n_pulses - 1) / (echo.eta[-1] - echo.eta[0])
    return Track(float(u0), float(du), float(np.mean(tx[:, 0])), float(np.mean(tx[:, 2])), float(speed), tol)


def made_nonstop(echo: EchoData, stop_and_go: bool | None) -> bool:
    """Whether the echoes carry non-stop-and-go delays: ``not stop_and_go`` when given, else
    read from ``echo.provenance["stop_and_go"]`` (False when absent, as clsas.simulate's default)."""
    if stop_and_go is None:
        return not echo.provenance.get("stop_and_go", False)
    return not validate.flag("stop_and_go", stop_and_go)


def path_excess(r, d: float, speed: float, c: float, nonstop: bool = True):
    """e(r) = (2 v r / c + d)^2 / (4 r), m (Huang & Yang 2022 eq. 4; without the 2 v r / c term
    for stop-and-go echoes)."""
    r = np.asarray(r, dtype=np.float64)
    lead = 2 * speed * r / c if nonstop else 0.0
    return (lead + d) ** 2 / (4 * r)


def compensate_bistatic(data, t0: float, fs: float, d: float, speed: float, waveform, medium,
                        t0_out: float | None = None, nonstop: bool = True, backend: str | None = None,
                        reference_range: float | None = None, interp: str = "sinc8",
                        tap_window: str = "kaiser") -> np.ndarray:
    """Remove the bistatic deformation (Huang & Yang eqs. 16-17) from the compressed records
    ``data`` (n_pulses, n) of a receiver d metres ahead of the transmitter, sampled from fast
    time ``t0`` at ``fs``; the output is sampled from ``t0_out`` (default ``t0``) on the same
    number of samples; ``interp`` and ``tap_window`` (:mod:`clsas.interp`) read the shifted
    samples, on ``backend``. ``reference_range`` (m): compensate every range by the excess of
    that one range (the range-invariant correction of the classic PCA) instead of each range's
    own. complex64 (n_pulses, n)."""
    c = medium.sound_speed
    n = data.shape[1]
    t_out = (t0 if t0_out is None else t0_out) + np.arange(n) / fs
    r = c * t_out / 2
    if reference_range is not None:
        reference_range = validate.scalar("reference_range", reference_range, low=0.0, high=float(r[-1]), low_open=True,
                                          unit="m", why="a range the record reaches, or None")
    at = r if reference_range is None else np.full_like(r, float(reference_range))
    # samples before the emission (t0 may be negative) hold no echo: no excess there
    excess = np.where(r > 0, path_excess(np.where(r > 0, at, 1.0), d, speed, c, nonstop), 0.0)
    idx = (t_out + excess / c - t0) * fs  # the same for every pulse
    phase = np.exp(2j * np.pi * waveform.f0 * excess / c)
    shifted = resample(data, idx, interp, tap_window, oversampling=oversampling(fs, waveform), backend=backend)
    shifted *= phase  # in place: resample's budget check covers the result
    return shifted.astype(np.complex64, copy=False)


def oversampling(fs: float, waveform) -> float:
    """A record's sampling rate over its occupied band (the Knab window's parameter), at least 1.01."""
    return max(fs / waveform.bandwidth, 1.01)


def line_record(echo: EchoData, receiver=0, stop_and_go: bool | None = None, backend: str | None = None,
                interp: str = "sinc8", tap_window: str = "kaiser") -> LineRecord:
    """The monostatic record of ``receiver`` (index or name), which must sit with the transmitter.

    ``stop_and_go`` says how the echoes were made (default: ``echo.provenance["stop_and_go"]``,
    False when absent: clsas.simulate's exact delays). Non-stop-and-go records get the path
    excess of Huang & Yang eq. (4) compensated (:func:`compensate_bistatic` with d = 0, its
    interpolation ``interp``, ``tap_window`` on ``backend``); their along-track shift v r / c is
    left to the imagers.
    """
    validate.instance("line_record echo", echo, EchoData, "an EchoData")
    validate.choice("line_record interp", interp, sorted(INTERPOLATORS))
    validate.choice("line_record tap_window", tap_window, TAP_WINDOWS)
    if np.ndim(receiver) != 0:
        raise ValueError(f"receiver: must be one index or name, got {receiver!r}")
    h = echo.select_receivers(receiver, "receiver")[0]
    validate.compression("line_record echo", echo)
    track = check_straight_track(echo)
    offset = echo.rx_position(h, np.zeros((echo.n_pulses, 1)))[:, 0] - echo.tx_pos
    if np.max(np.abs(offset)) > track.tolerance:
        raise ValueError(f"receiver {echo.receivers[h]!r} is {np.max(np.linalg.norm(offset, axis=1)):.3g} m from the "
                         "transmitter: not monostatic; convert a multireceiver record with "
                         "clsas.image.multireceiver.pca_record, or use clsas.backproject")
    nonstop = made_nonstop(echo, stop_and_go)
    data = echo.data[h]
    if nonstop:
        data = compensate_bistatic(data, echo.t0[h], echo.fs, 0.0, track.speed, echo.waveform, echo.medium,
                                   backend=backend, interp=interp, tap_window=tap_window)
    return LineRecord(data=data, u0=track.u0, du=track.du, t0=float(echo.t0[h]), fs=echo.fs, speed=track.speed,
                      track=(track.x, track.z),
                      waveform=echo.waveform, medium=echo.medium, nonstop=nonstop,
                      provenance={"from": "line_record", "receiver": echo.receivers[h], "echo": dict(echo.provenance)})


def as_record(data, receiver=0, backend: str | None = None, interp: str = "sinc8",
              tap_window: str = "kaiser") -> LineRecord:
    """A LineRecord as is, or the monostatic record of an EchoData (:func:`line_record`,
    its interpolation ``interp``, ``tap_window`` on ``backend``)."""
    if isinstance(data, LineRecord):
        return data
    validate.instance("data", data, EchoData, "a LineRecord or a range-compressed monostatic EchoData")
    return line_record(data, receiver, backend=backend, interp=interp, tap_window=tap_window)


def element_lengths(name: str, elements) -> tuple | None:
    """(L_tx, L_rx) in metres (one number: both), each in (0, MAX_ELEMENT], or None."""
    if elements is None:
        return None
    lengths = np.broadcast_to(validate.array(name, elements, (2,) if np.ndim(elements) else (), bound=MAX_ELEMENT),
                              (2,))
    if np.any(lengths <= 0):
        raise ValueError(f"{name}: must be the positive along-track lengths (L_tx, L_rx) in m, got {elements!r}")
    return tuple(float(v) for v in lengths)


def check_elements(elements, rec: LineRecord):
    """(L_tx, L_rx) in metres (:func:`element_lengths`) or None; the along-track sampling must
    resolve the extracted band."""
    lengths = element_lengths("elements (L_tx, L_rx)", elements)
    if lengths is not None and 2 * np.pi / max(lengths) > np.pi / rec.du * (1 + 1e-9):
        raise ValueError(f"elements {lengths}: the band |k_y| <= 2 pi / D needs along-track samples at most "
                         f"D / 2 = {max(lengths) / 2:.4g} m apart, the record has {rec.du:.4g} m")
    return lengths


def azimuth_weights(ku: np.ndarray, elements, window: str, deconvolve: bool = True, **window_options) -> np.ndarray:
    """rect(k_y / B_ky) W(k_y / B_ky) / A(k_y) per row (Heremans eq. 44; without the 1 / A(k_y)
    when not ``deconvolve``); without elements only the window over the sampled band."""
    if elements is None:
        band = 2 * np.abs(ku).max() if ku.size > 1 else 1.0
        return spectral_window(ku / band, window, **window_options)
    d = max(elements)
    pattern = np.sinc(elements[0] * ku / (4 * np.pi)) * np.sinc(elements[1] * ku / (4 * np.pi)) if deconvolve else 1.0
    inside = np.abs(ku) <= 2 * np.pi / d
    return np.where(inside, spectral_window(ku / (4 * np.pi / d), window, **window_options)
                    / np.where(inside, pattern, 1.0), 0.0)


def image_of(rec: LineRecord, ku_range: np.ndarray, r: np.ndarray, algorithm: str, params: dict,
             depth: float | None = None, workers: int = -1):
    """The Image of an imager's (k_u, r) result: inverse along-track FFT, rows at
    y = u0 + j du, columns cropped to the recorded ranges and placed on the horizontal plane
    z = ``depth`` (default: the track's depth) at x = x_track + sqrt(r^2 - (depth - z_track)^2).

    ku_range : complex (n_ku, len(r)); r : slant ranges of its columns, m, increasing;
    workers : scipy.fft threads.
    """
    x_track, z_track = rec.track
    depth = z_track if depth is None else float(depth)
    c = rec.medium.sound_speed
    dz = depth - z_track
    keep = (r > abs(dz)) & (r >= c * rec.t0 / 2) & (r <= c * (rec.t0 + (rec.n_samples - 1) / rec.fs) / 2)
    if not np.any(keep):
        raise ValueError(f"depth {depth} m: no recorded range reaches that plane")
    img = scipy.fft.ifft(ku_range[:, keep], axis=0, workers=workers)
    y = rec.u0 + rec.du * np.arange(img.shape[0])
    x = x_track + np.sqrt(r[keep] ** 2 - dz ** 2)
    positions = np.empty((y.size, x.size, 3))
    positions[..., 0] = x[None, :]
    positions[..., 1] = y[:, None]
    positions[..., 2] = depth
    return Image(data=img.astype(np.complex64, copy=False), dims=("y", "x"), axes={"y": y, "x": x}, positions=positions,
                 provenance={"algorithm": algorithm, **params, "record": dict(rec.provenance)})
