"""The sea surface: a horizontal plane at height z, flat or with Rayleigh roughness.

Its plane-wave reflection coefficient is -1 for a flat pressure-release surface; a rough one
(Gaussian heights of rms h) reflects coherently

    R(theta) = -exp(-2 (k h sin theta)^2)

(the Rayleigh parameter g = 2 k h sin theta: R = -exp(-g^2 / 2); Eckart, JASA 25, 1953;
Jensen et al., Computational Ocean Acoustics, 2nd ed., eq. (1.54)), theta the grazing angle and
k = 2 pi f / c.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validate as v

MAX_FREQUENCY = 1e7  # Hz


@dataclass(frozen=True)
class SeaSurface:
    """The sea surface: height ``z`` (m, the plane z = const) and ``rms_height`` (m, >= 0)."""

    z: float = 0.0
    rms_height: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "z", v.scalar("SeaSurface.z", self.z, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE,
                                               unit="m"))
        object.__setattr__(self, "rms_height", v.scalar("SeaSurface.rms_height", self.rms_height, low=0.0, high=100.0,
                                                        unit="m"))

    def reflection_coefficient(self, grazing_rad, f_hz, sound_speed: float = 1500.0) -> np.ndarray:
        """R(theta) at grazing angles ``grazing_rad`` (rad in [0, pi/2], any shape) and frequency
        ``f_hz`` (Hz), real (module docstring); ``sound_speed`` of the water, m/s."""
        theta = v.array("SeaSurface.reflection_coefficient grazing_rad", grazing_rad,
                        tuple(-1 for _ in range(np.ndim(grazing_rad))), copy=False)
        if theta.size and (theta.min() < 0 or theta.max() > np.pi / 2 + 1e-12):
            raise ValueError("SeaSurface.reflection_coefficient grazing_rad: grazing angles must be in [0, pi/2] rad, "
                             f"got {theta.min():g} .. {theta.max():g}")
        f = v.positive("SeaSurface.reflection_coefficient f_hz", f_hz, high=MAX_FREQUENCY, unit="Hz")
        c = v.scalar("SeaSurface.reflection_coefficient sound_speed", sound_speed, low=1000.0, high=2000.0, unit="m/s")
        k = 2 * np.pi * f / c
        return -np.exp(-2.0 * (k * self.rms_height * np.sin(theta)) ** 2)
