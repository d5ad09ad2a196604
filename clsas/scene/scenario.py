"""What is simulated: medium, pulse, platform and array, sonobuoys, pulse schedule, recording.

Conventions (DESIGN.md): SI units, radians; right-handed x, y, z with y along track (the
platform's nominal heading), x across track towards the imaged side, z up (depth is negative
z). Slow time ``eta`` is the emission time of a pulse; fast time ``tau`` is measured from it.

Attitude: the body frame has x_b across track, y_b forward (along the array), z_b up. A body
offset ``o`` sits in the world at ``position(t) + R(t) o`` with ``R = R_yaw @ R_pitch``:

- positive yaw turns the bow (+y_b) towards +x, clockwise seen from above — the convention of
  Wu et al. 2018 (Fig. 1b, hydrophone at (d cos(pitch) sin(yaw), d cos(pitch) cos(yaw),
  d sin(pitch)) in eqs. 2-3) and of Heremans et al. 2009 eq. (36);
- positive pitch raises the bow (+y_b towards +z).

The rotation centre is the platform's reference point (Wu et al.: the transmitter), so
attitude moves offsets, not the reference point.

Every dataclass here is frozen and validated on construction (:mod:`clsas.validate`): a bad
field raises ValueError (or TypeError) naming the field, its value and the allowed range.
Beyond each field's own range: positions within +-1000 km, speeds at most 100 m/s (far below
the sound speed, as the delay model needs), times within +-1e6 s, and sizes (pulses,
receivers, samples) within the memory budget (:mod:`clsas.budget`).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import Callable, Union

import numpy as np
from scipy.interpolate import CubicSpline

from .. import budget
from .. import validate as v

MotionInput = Union[None, Callable, np.ndarray, list, tuple]

MOTION_COMPONENTS = ("surge", "sway", "heave", "yaw", "pitch")


class SamplingWarning(UserWarning):
    """The scene is sampled too coarsely: along track (the D/2 rule), or in time (one pulse's
    echoes outlast the pulse interval, so a real recording would overlap them with the next
    pulse's)."""

MAX_F0 = 1e8  # Hz
MAX_FS = 1e9  # Hz
MAX_DURATION = 10.0  # s, one pulse
MAX_PRF = 1e5  # Hz
MAX_ELEMENT = 100.0  # m, element length


@dataclass(frozen=True)
class Medium:
    """The water. ``sound_speed`` in m/s, allowed [1000, 2000] (water is 1400-1600)."""

    sound_speed: float = 1500.0

    def __post_init__(self):
        object.__setattr__(self, "sound_speed", v.scalar("Medium.sound_speed", self.sound_speed, low=1000.0, high=2000.0,
                                                         unit="m/s"))


@dataclass(frozen=True)
class Waveform:
    """A linear FM pulse: rect(tau/T) exp(j 2 pi f0 tau) exp(j pi K tau^2), centred on tau = 0.

    Parameters
    ----------
    f0 : float
        Carrier frequency, Hz (> 0).
    bandwidth : float
        Swept bandwidth B, Hz; 0 < B < 2 f0 so that the lowest frequency f0 - B/2 is positive.
    duration : float
        Pulse length T, s (> 0).
    fs : float
        Complex baseband sampling rate, Hz; fs >= B (Nyquist for complex samples).
    chirp_sign : {+1, -1}
        +1 for an up-chirp, -1 for a down-chirp; the chirp rate is K = chirp_sign B / T.
    """

    f0: float
    bandwidth: float
    duration: float
    fs: float
    chirp_sign: int = 1

    def __post_init__(self):
        f0 = v.positive("Waveform.f0", self.f0, high=MAX_F0, unit="Hz")
        bw = v.scalar("Waveform.bandwidth", self.bandwidth, low=0.0, high=2 * f0, low_open=True, high_open=True,
                      unit="Hz", why="0 < B < 2 f0")
        dur = v.positive("Waveform.duration", self.duration, high=MAX_DURATION, unit="s")
        fs = v.scalar("Waveform.fs", self.fs, low=bw, high=MAX_FS, unit="Hz", why="at least the bandwidth")
        if dur * fs < 1:
            raise ValueError(f"Waveform.duration: a pulse of {dur:g} s sampled at fs = {fs:g} Hz spans {dur * fs:.3g} "
                             "samples; it needs at least one (duration >= 1 / fs)")
        if isinstance(self.chirp_sign, (bool, np.bool_)) or not v.is_number(self.chirp_sign, "iuf") \
                or self.chirp_sign not in (1, -1):
            raise ValueError(f"Waveform.chirp_sign: must be +1 or -1, got {self.chirp_sign!r}")
        for name, value in (("f0", f0), ("bandwidth", bw), ("duration", dur), ("fs", fs)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "chirp_sign", int(self.chirp_sign))

    @property
    def chirp_rate(self) -> float:
        """K = chirp_sign B / T, Hz/s."""
        return self.chirp_sign * self.bandwidth / self.duration

    @property
    def time_bandwidth(self) -> float:
        """B T, the compression gain."""
        return self.bandwidth * self.duration

    def wavelength(self, medium: Medium) -> float:
        """Carrier wavelength c / f0, m."""
        return medium.sound_speed / self.f0

    def baseband(self, tau) -> np.ndarray:
        """rect(tau/T) exp(j pi K tau^2): the pulse without its carrier at fast times ``tau`` (s)."""
        tau = np.asarray(tau, dtype=np.float64)
        inside = np.abs(tau) <= 0.5 * self.duration
        return np.where(inside, np.exp(1j * np.pi * self.chirp_rate * tau * tau), 0.0)


def _rotation(yaw: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """R = R_yaw @ R_pitch, shape (..., 3, 3), with the sign conventions of the module docstring."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    zero, one = np.zeros_like(cy), np.ones_like(cy)
    r_yaw = np.stack([np.stack([cy, sy, zero], -1), np.stack([-sy, cy, zero], -1), np.stack([zero, zero, one], -1)], -2)
    r_pitch = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, cp, -sp], -1), np.stack([zero, sp, cp], -1)], -2)
    return r_yaw @ r_pitch


@dataclass(frozen=True, eq=False)
class Platform:
    """The vehicle: a straight track along +y at ``speed`` plus optional motion errors.

    Reference point at time t: ``start + (sway(t), speed t + surge(t), heave(t))``; attitude
    ``yaw(t)``, ``pitch(t)`` (radians) rotates body offsets about it.

    Each motion component (surge, sway, heave in m; yaw, pitch in rad) is ``None`` (zero), a
    callable ``f(t) -> array like t``, or an array sampled at ``error_times`` (s, strictly
    increasing), interpolated by a cubic spline. Sampled errors are only defined inside
    ``[error_times[0], error_times[-1]]``; asking outside raises (nothing is extrapolated):
    cover every emission and reception time.
    """

    speed: float
    start: np.ndarray = (0.0, 0.0, 0.0)
    surge: MotionInput = None
    sway: MotionInput = None
    heave: MotionInput = None
    yaw: MotionInput = None
    pitch: MotionInput = None
    error_times: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "speed", v.positive("Platform.speed", self.speed, high=v.MAX_SPEED, unit="m/s",
                                                     why="far below the sound speed"))
        object.__setattr__(self, "start", v.vector3("Platform.start", self.start))
        sampled = [c for c in MOTION_COMPONENTS if getattr(self, c) is not None and not callable(getattr(self, c))]
        splines = {}
        if sampled:
            if self.error_times is None:
                raise ValueError(f"Platform.error_times is required when {sampled} are given as sampled arrays")
            times = v.array("Platform.error_times", self.error_times, (-1,), bound=v.MAX_TIME)
            if times.size < 2 or np.any(np.diff(times) <= 0):
                raise ValueError("Platform.error_times must hold >= 2 strictly increasing times (s)")
            object.__setattr__(self, "error_times", times)
            for comp in sampled:
                values = v.array(f"Platform.{comp}", getattr(self, comp), (times.size,),
                                 bound=np.pi if comp in ("yaw", "pitch") else v.MAX_COORDINATE)
                object.__setattr__(self, comp, values)
                splines[comp] = CubicSpline(times, values)
        elif self.error_times is not None:
            raise ValueError("Platform.error_times given but no motion component is a sampled array")
        object.__setattr__(self, "_splines", splines)

    def motion_error(self, component: str, t) -> np.ndarray:
        """One motion component (m or rad) at times ``t`` (s), shape of ``t``."""
        if component not in MOTION_COMPONENTS:
            raise ValueError(f"component must be one of {MOTION_COMPONENTS}, got {component!r}")
        t = np.asarray(t, dtype=np.float64)
        if not np.all(np.isfinite(t)):
            raise ValueError(f"Platform.{component} asked at non-finite times (NaN or inf)")
        source = getattr(self, component)
        if source is None:
            return np.zeros_like(t)
        if component in self._splines:
            lo, hi = self.error_times[0], self.error_times[-1]
            if t.size and (t.min() < lo or t.max() > hi):
                raise ValueError(
                    f"Platform.{component} is sampled on [{lo:g}, {hi:g}] s but is needed on "
                    f"[{t.min():g}, {t.max():g}] s; extend Platform.error_times to cover every "
                    "emission and reception time"
                )
            return self._splines[component](t)
        out = np.asarray(source(t), dtype=np.float64)
        if out.ndim == 0:  # a constant error
            out = np.full(t.shape, float(out))
        if out.shape != t.shape or not np.all(np.isfinite(out)):
            raise ValueError(f"Platform.{component}(t) must return finite values shaped like t {t.shape}, got {out.shape}")
        return out

    def position(self, t) -> np.ndarray:
        """Reference point at times ``t`` (s): shape ``t.shape + (3,)``, m."""
        t = np.asarray(t, dtype=np.float64)
        offset = np.stack(
            [self.motion_error("sway", t), self.speed * t + self.motion_error("surge", t), self.motion_error("heave", t)],
            axis=-1,
        )
        return self.start + offset

    def rotation(self, t) -> np.ndarray:
        """Body-to-world rotation at times ``t``: shape ``t.shape + (3, 3)``."""
        return _rotation(self.motion_error("yaw", t), self.motion_error("pitch", t))

    def locate(self, offset, t) -> np.ndarray:
        """World position of the body offset ``offset`` (3,) at times ``t``: ``t.shape + (3,)``."""
        offset = np.asarray(offset, dtype=np.float64)
        return self.position(t) + self.rotation(t) @ offset


@dataclass(frozen=True, eq=False)
class Array:
    """Transmitter and hydrophones fixed to the platform (body-frame offsets from its reference point).

    Parameters
    ----------
    rx_offsets : (M, 3) array
        Hydrophone phase centres in the body frame, m (M >= 0; a scenario may use only sonobuoys).
    tx_offset : (3,) array
        Transmitter phase centre in the body frame, m.
    tx_length, rx_length : float or (M,) array
        Along-track (body y) element lengths, m, for the element directivity
        sinc(L sin(theta) / lambda); 0 means omnidirectional.
    names : tuple of str, optional
        Receiver names (default ``h0, h1, ...``).
    """

    rx_offsets: np.ndarray
    tx_offset: np.ndarray = (0.0, 0.0, 0.0)
    tx_length: float = 0.0
    rx_length: float | np.ndarray = 0.0
    names: tuple | None = None

    def __post_init__(self):
        rx = v.array("Array.rx_offsets", self.rx_offsets, (-1, 3), bound=v.MAX_COORDINATE)
        object.__setattr__(self, "rx_offsets", rx)
        object.__setattr__(self, "tx_offset", v.vector3("Array.tx_offset", self.tx_offset))
        object.__setattr__(self, "tx_length", v.scalar("Array.tx_length", self.tx_length, low=0.0, high=MAX_ELEMENT,
                                                       unit="m"))
        if np.ndim(self.rx_length) == 0:
            lengths = np.full(rx.shape[0], v.scalar("Array.rx_length", self.rx_length, low=0.0, high=MAX_ELEMENT,
                                                    unit="m"))
        else:
            lengths = self.rx_length
        lengths = v.array("Array.rx_length", lengths, (rx.shape[0],), nonnegative=True, bound=MAX_ELEMENT)
        object.__setattr__(self, "rx_length", lengths)
        names = tuple(f"h{i}" for i in range(rx.shape[0])) if self.names is None else tuple(self.names)
        if len(names) != rx.shape[0] or not all(isinstance(n, str) and n for n in names):
            raise ValueError(f"Array.names must be {rx.shape[0]} non-empty strings, got {self.names!r}")
        object.__setattr__(self, "names", names)

    @property
    def n_receivers(self) -> int:
        return self.rx_offsets.shape[0]

    @classmethod
    def uniform_line(cls, n_receivers: int, spacing: float, first: float, *, tx_along: float = 0.0,
                     tx_length: float = 0.0, rx_length: float | None = None, names=None) -> "Array":
        """Hydrophones on the body y axis at ``first + i * spacing`` (i = 0..n-1), transmitter at ``tx_along``.

        ``rx_length`` defaults to ``spacing`` (contiguous elements).
        """
        n = v.integer("Array.uniform_line n_receivers", n_receivers, high=2**53)
        budget.check_bytes(f"Array.uniform_line with n_receivers={n}", 200.0 * n, "fewer receivers")
        step = v.positive("Array.uniform_line spacing", spacing, high=v.MAX_COORDINATE, unit="m")
        y = v.scalar("Array.uniform_line first", first, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE, unit="m") \
            + step * np.arange(n)
        offsets = np.column_stack([np.zeros(n), y, np.zeros(n)])
        tx_y = v.scalar("Array.uniform_line tx_along", tx_along, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE, unit="m")
        return cls(rx_offsets=offsets, tx_offset=(0.0, tx_y, 0.0), tx_length=tx_length,
                   rx_length=step if rx_length is None else rx_length, names=names)


@dataclass(frozen=True, eq=False)
class Sonobuoy:
    """A stationary, omnidirectional receiver at ``position`` (m)."""

    position: np.ndarray
    name: str = "buoy"

    def __post_init__(self):
        object.__setattr__(self, "position", v.vector3(f"Sonobuoy({self.name!r}).position", self.position))
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"Sonobuoy.name must be a non-empty string, got {self.name!r}")


@dataclass(frozen=True)
class PulseSchedule:
    """When pulses are emitted: every 1/prf seconds, ``n_pulses`` of them or for ``exposure`` seconds.

    Give exactly one of ``n_pulses`` and ``exposure`` (then n_pulses = floor(exposure prf),
    at least 1). ``start`` is the first emission time (s); by default the pulses are centred
    on eta = 0, as in Kiang & Kiang 2022 (rect(eta / T_a)).
    """

    prf: float
    n_pulses: int | None = None
    exposure: float | None = None
    start: float | None = None

    def __post_init__(self):
        prf = v.positive("PulseSchedule.prf", self.prf, high=MAX_PRF, unit="Hz")
        object.__setattr__(self, "prf", prf)
        if (self.n_pulses is None) == (self.exposure is None):
            raise ValueError("PulseSchedule needs exactly one of n_pulses and exposure")
        if self.exposure is not None:
            exposure = v.positive("PulseSchedule.exposure", self.exposure, high=v.MAX_TIME, unit="s")
            n = int(np.floor(exposure * prf + 1e-9))
            if n < 1:
                raise ValueError(f"PulseSchedule.exposure: {exposure:g} s at prf {prf:g} Hz holds no pulse; need >= 1/prf")
            object.__setattr__(self, "exposure", exposure)
            object.__setattr__(self, "n_pulses", n)
        else:
            object.__setattr__(self, "n_pulses", v.integer("PulseSchedule.n_pulses", self.n_pulses, high=2**53))
        what = "PulseSchedule.exposure" if self.exposure is not None else "PulseSchedule.n_pulses"
        budget.check_bytes(f"{what} ({self.n_pulses} pulses: their emission times)", 8.0 * self.n_pulses,
                           "fewer pulses")
        if self.start is not None:
            object.__setattr__(self, "start", v.scalar("PulseSchedule.start", self.start, low=-v.MAX_TIME,
                                                       high=v.MAX_TIME, unit="s"))
        first = -0.5 * (self.n_pulses - 1) / prf if self.start is None else self.start
        last = first + (self.n_pulses - 1) / prf
        if max(abs(first), abs(last)) > v.MAX_TIME:
            raise ValueError(f"{what}: {self.n_pulses} pulses at prf {prf:g} Hz span [{first:g}, {last:g}] s; "
                             f"emission times must lie within +-{v.MAX_TIME:g} s")

    @property
    def eta(self) -> np.ndarray:
        """Emission times, s, shape (n_pulses,)."""
        first = -0.5 * (self.n_pulses - 1) / self.prf if self.start is None else self.start
        return first + np.arange(self.n_pulses) / self.prf


@dataclass(frozen=True, eq=False)
class Recording:
    """Fast-time recording window per receiver: ``n_samples`` samples from ``t0`` s after emission.

    ``t0`` (s, finite; fast time is measured from the centre of the transmitted pulse, so an
    echo from very close by starts at a negative fast time) and ``n_samples`` (>= 1) are
    scalars (same for every receiver) or one value per receiver.
    """

    t0: float | np.ndarray
    n_samples: int | np.ndarray

    def __post_init__(self):
        t0 = self.t0 if np.ndim(self.t0) else [self.t0]
        object.__setattr__(self, "t0", v.array("Recording.t0", t0, (-1,), bound=v.MAX_TIME))
        try:
            n = np.atleast_1d(np.asarray(self.n_samples))
        except (TypeError, ValueError, OverflowError):
            n = np.zeros(0, object)
        if n.dtype.kind not in "iu":
            raise TypeError(f"Recording.n_samples: must be an integer >= 1 or one per receiver, got {self.n_samples!r}")
        if n.ndim != 1 or n.size == 0:
            raise ValueError(f"Recording.n_samples: must be an integer >= 1 or one per receiver, got {self.n_samples!r}")
        if np.any(n < 1):
            raise ValueError(f"Recording.n_samples: must be integers >= 1, got {self.n_samples!r}")
        budget.check_bytes(f"Recording.n_samples={int(n.max())} (one record of complex64 samples)", 8.0 * n.max(),
                           "a shorter recording window")
        n = n.astype(np.int64)
        n.flags.writeable = False
        object.__setattr__(self, "n_samples", n)

    def for_receivers(self, n_receivers: int) -> tuple[np.ndarray, np.ndarray]:
        """(t0, n_samples), each shaped (n_receivers,)."""
        out = []
        for name, arr in (("t0", self.t0), ("n_samples", self.n_samples)):
            if arr.size not in (1, n_receivers):
                raise ValueError(f"Recording.{name} has {arr.size} values; give 1 or one per receiver ({n_receivers})")
            out.append(np.broadcast_to(arr, (n_receivers,)))
        return out[0], out[1]


def phase_centre_gap(array: Array, step: float) -> float:
    """Largest along-track gap between the array's phase centres over consecutive pings, m.

    The phase centre of hydrophone i is midway between transmitter and hydrophone,
    (tx_y + rx_y_i) / 2 (body y); ping n shifts every centre by n * step (step = V / PRF).
    """
    if array.n_receivers == 0:
        return step
    centres = np.sort(np.mod(0.5 * (array.tx_offset[1] + array.rx_offsets[:, 1]), step))
    gaps = np.diff(centres, append=centres[0] + step)
    return float(gaps.max())


@dataclass(frozen=True, eq=False)
class Scenario:
    """A complete sonar set-up: medium, waveform, platform with its array, sonobuoys, schedule.

    Receivers are numbered array hydrophones first, then sonobuoys. ``targets`` is a tuple of
    target objects (:mod:`clsas.scene.targets`: point scatterers, meshes), empty by default.

    On construction, the along-track sampling of the array is checked against the D/2 rule:
    the largest gap between phase centres over consecutive pings (:func:`phase_centre_gap`)
    should not exceed D/2, with D the shortest non-zero element length (the widest beam sets
    the Doppler band to sample: Huang & Yang 2022 and Wu et al. 2018 sample at exactly
    D_rx/2). A coarser sampling gives a :class:`SamplingWarning`. Omnidirectional elements
    (length 0) have no D/2 limit and are not checked.
    """

    medium: Medium
    waveform: Waveform
    platform: Platform
    array: Array
    schedule: PulseSchedule
    sonobuoys: tuple = ()
    recording: Recording | None = None
    targets: tuple = ()

    def __post_init__(self):
        for name, cls in (("medium", Medium), ("waveform", Waveform), ("platform", Platform),
                          ("array", Array), ("schedule", PulseSchedule)):
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"Scenario.{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}")
        buoys = tuple(self.sonobuoys)
        if not all(isinstance(b, Sonobuoy) for b in buoys):
            raise TypeError("Scenario.sonobuoys must hold Sonobuoy objects")
        object.__setattr__(self, "sonobuoys", buoys)
        targets = (self.targets,) if hasattr(self.targets, "scatterers") else tuple(self.targets)
        for i, target in enumerate(targets):
            if not hasattr(target, "scatterers"):
                raise TypeError(f"Scenario.targets[{i}] ({type(target).__name__}) is not a target: give "
                                "PointTargets or mesh targets")
        object.__setattr__(self, "targets", targets)
        if self.n_receivers == 0:
            raise ValueError("Scenario has no receivers: give Array.rx_offsets or at least one Sonobuoy")
        names = self.receiver_names
        if len(set(names)) != len(names):
            raise ValueError(f"receiver names must be unique, got {names}")
        if self.recording is not None:
            if not isinstance(self.recording, Recording):
                raise TypeError("Scenario.recording must be a Recording or None")
            self.recording.for_receivers(self.n_receivers)
        self._check_along_track_sampling()

    def _check_along_track_sampling(self) -> None:
        arr = self.array
        lengths = np.concatenate([[arr.tx_length], arr.rx_length]) if arr.n_receivers else np.array([])
        nonzero = lengths[lengths > 0]
        if arr.n_receivers == 0 or nonzero.size == 0:
            return
        step = self.platform.speed / self.schedule.prf
        gap = phase_centre_gap(arr, step)
        limit = 0.5 * nonzero.min()
        if gap > limit * (1 + 1e-9):
            warnings.warn(
                f"along-track undersampling: phase centres are up to {gap * 1e3:.2f} mm apart "
                f"(platform step V/PRF = {step * 1e3:.2f} mm) but the D/2 rule asks for <= "
                f"{limit * 1e3:.2f} mm (D = {nonzero.min() * 1e3:.2f} mm); expect azimuth ambiguities "
                "(grating lobes). Raise the PRF, slow the platform or add hydrophones.",
                SamplingWarning,
                stacklevel=3,
            )

    @property
    def n_receivers(self) -> int:
        return self.array.n_receivers + len(self.sonobuoys)

    @property
    def receiver_names(self) -> tuple:
        return tuple(self.array.names) + tuple(b.name for b in self.sonobuoys)

    @property
    def eta(self) -> np.ndarray:
        """Pulse emission times, s, shape (n_pulses,)."""
        return self.schedule.eta

    def tx_position(self, eta) -> np.ndarray:
        """Transmitter phase centre at emission times ``eta`` (s): ``eta.shape + (3,)``."""
        return self.platform.locate(self.array.tx_offset, eta)

    def _check_receiver(self, index) -> None:
        n = self.n_receivers
        if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < n:
            raise ValueError(f"receiver index must be an integer in [0, {n - 1}], got {index!r}")

    def receiver_position(self, index: int, t) -> np.ndarray:
        """Receiver ``index`` at times ``t`` (s): ``t.shape + (3,)``."""
        self._check_receiver(index)
        t = np.asarray(t, dtype=np.float64)
        if index < self.array.n_receivers:
            return self.platform.locate(self.array.rx_offsets[index], t)
        buoy = self.sonobuoys[index - self.array.n_receivers]
        return np.broadcast_to(buoy.position, t.shape + (3,)).copy()

    def receiver_axis(self, index: int, t) -> np.ndarray:
        """World direction of receiver ``index``'s element axis (body y) at times ``t``: ``t.shape + (3,)``.

        Sonobuoys are omnidirectional; their axis is +y and unused (element length 0).
        """
        self._check_receiver(index)
        t = np.asarray(t, dtype=np.float64)
        if index < self.array.n_receivers:
            return self.platform.rotation(t)[..., :, 1]
        return np.broadcast_to(np.array([0.0, 1.0, 0.0]), t.shape + (3,)).copy()

    @property
    def receiver_lengths(self) -> np.ndarray:
        """Along-track element length of every receiver, m (sonobuoys: 0, omnidirectional)."""
        return np.concatenate([self.array.rx_length, np.zeros(len(self.sonobuoys))])

    def rx_positions(self, t) -> np.ndarray:
        """Every receiver at times ``t``: shape ``(n_receivers,) + t.shape + (3,)``."""
        return np.stack([self.receiver_position(i, t) for i in range(self.n_receivers)])

    def replace(self, **changes) -> "Scenario":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)
