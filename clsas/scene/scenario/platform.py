"""The platform: a straight track with motion errors (surge, sway, heave, yaw, pitch) and its attitude.

Conventions: see :mod:`clsas.scene.scenario`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Union

import numpy as np

from ... import validate as v


MotionInput = Union[None, Callable, np.ndarray, list, tuple]

MOTION_COMPONENTS = ("surge", "sway", "heave", "yaw", "pitch")


def _bound(component: str) -> float:
    """Largest |value| of a motion component: pi rad for the angles, the coordinate bound (m) else."""
    return np.pi if component in ("yaw", "pitch") else v.MAX_COORDINATE


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
            from scipy.interpolate import CubicSpline  # here: scipy.interpolate costs ~1 s to import
            for comp in sampled:
                values = v.array(f"Platform.{comp}", getattr(self, comp), (times.size,), bound=_bound(comp))
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
        out = source(t)
        if np.ndim(out) == 0:  # a constant error
            out = np.full(t.shape, v.scalar(f"Platform.{component}(t)", out))
        # the bounds of a sampled array (module docstring): a function gets no more room
        return v.array(f"Platform.{component}(t)", out, t.shape, bound=_bound(component), copy=False)

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


