"""The sonar's parts: hydrophone array, sonobuoys, pulse schedule, recording window (the medium
and the pulse are model types, :mod:`clsas.model.medium`).

Conventions: see :mod:`clsas.scene.scenario`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import budget
from ... import validate as v
from ...model import Medium, Waveform


class SamplingWarning(UserWarning):
    """The scene is sampled too coarsely: along track (the D/2 rule), or in time (one pulse's
    echoes outlast the pulse interval, so a real recording would overlap them with the next
    pulse's)."""

MAX_PRF = 1e5  # Hz
MAX_ELEMENT = 100.0  # m, element length


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


