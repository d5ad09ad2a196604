"""What is simulated: medium, pulse, platform and array, sonobuoys, pulse schedule, recording.

Conventions (docs/design.md): SI units, radians; right-handed x, y, z with y along track (the
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

import numpy as np

from ...model import ScenarioRecord
from ..seafloor import Seafloor
from ..surface import SeaSurface
from .platform import MOTION_COMPONENTS, Platform
from .sonar import (
    MAX_ELEMENT,
    Array,
    Medium,
    PulseSchedule,
    Recording,
    SamplingWarning,
    Sonobuoy,
    Waveform,
    phase_centre_gap,
)

__all__ = ["MAX_ELEMENT", "MOTION_COMPONENTS", "Array", "Medium", "Platform", "PulseSchedule", "Recording",
           "SamplingWarning", "Scenario", "Sonobuoy", "Waveform", "phase_centre_gap"]


@dataclass(frozen=True, eq=False)
class Scenario(ScenarioRecord):
    """A complete sonar set-up: medium, waveform, platform with its array, sonobuoys, schedule.

    Receivers are numbered array hydrophones first, then sonobuoys. ``targets`` is a tuple of
    target objects (:mod:`clsas.scene.targets`: point scatterers, meshes), empty by default.
    ``seafloor`` (a :class:`clsas.Seafloor`) and ``surface`` (a :class:`clsas.SeaSurface`) are
    the environment, None by default; the surface must lie above the seafloor's highest point
    and above the platform's start.

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
    seafloor: Seafloor | None = None
    surface: SeaSurface | None = None

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
        self._check_environment()
        self._check_along_track_sampling()

    def _check_environment(self) -> None:
        if self.seafloor is not None and not isinstance(self.seafloor, Seafloor):
            raise TypeError(f"Scenario.seafloor must be a Seafloor or None, got {type(self.seafloor).__name__}")
        if self.surface is None:
            return
        if not isinstance(self.surface, SeaSurface):
            raise TypeError(f"Scenario.surface must be a SeaSurface or None, got {type(self.surface).__name__}")
        start = float(self.platform.start[2])
        if start >= self.surface.z:
            raise ValueError(f"Scenario.surface: the sea surface (z = {self.surface.z:g} m) must lie above the "
                             f"platform's start (z = {start:g} m)")
        if self.seafloor is not None and self.seafloor.height_range()[1] >= self.surface.z:
            raise ValueError(f"Scenario.surface: the sea surface (z = {self.surface.z:g} m) must lie above the "
                             f"seafloor's highest point (z = {self.seafloor.height_range()[1]:g} m)")

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
