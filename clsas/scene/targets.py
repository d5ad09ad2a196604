"""What reflects: point scatterers (meshes come with the occlusion work).

Every target type turns into *scatterers*: a position at t = 0 (m), a constant velocity
(m/s) and a complex reflectivity, so that scatterer n is at ``p0[n] + vel[n] t`` at time t.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Scatterers:
    """Flat arrays the echo synthesis consumes: ``p0`` (N, 3) m, ``vel`` (N, 3) m/s, ``refl`` (N,) complex."""

    p0: np.ndarray
    vel: np.ndarray
    refl: np.ndarray

    @property
    def count(self) -> int:
        return self.p0.shape[0]

    @staticmethod
    def concatenate(parts) -> "Scatterers":
        parts = list(parts)
        if not parts:
            return Scatterers(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.complex128))
        return Scatterers(np.concatenate([p.p0 for p in parts]), np.concatenate([p.vel for p in parts]),
                          np.concatenate([p.refl for p in parts]))


@dataclass(frozen=True, eq=False)
class PointTargets:
    """Ideal point scatterers.

    Parameters
    ----------
    positions : (N, 3) or (3,) array
        Positions at t = 0 (slow time zero), m.
    reflectivity : complex scalar or (N,) array
        Complex amplitude of each scatterer (default 1); must be finite.
    velocity : (3,) or (N, 3) array
        Constant velocity, m/s (default 0: stationary); |v| < 100 m/s.
    """

    positions: np.ndarray
    reflectivity: complex | np.ndarray = 1.0
    velocity: np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self):
        pos = np.atleast_2d(np.asarray(self.positions, dtype=np.float64))
        if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] == 0:
            raise ValueError(f"PointTargets.positions must have shape (N >= 1, 3), got {np.shape(self.positions)}")
        if not np.all(np.isfinite(pos)):
            raise ValueError("PointTargets.positions must be finite (it has NaN or inf)")
        n = pos.shape[0]
        refl = np.asarray(self.reflectivity, dtype=np.complex128)
        if refl.ndim == 0:
            refl = np.full(n, refl)
        if refl.shape != (n,) or not np.all(np.isfinite(refl)):
            raise ValueError(f"PointTargets.reflectivity must be a finite scalar or {n} values, got shape {refl.shape}")
        vel = np.asarray(self.velocity, dtype=np.float64)
        vel = np.broadcast_to(vel, (n, 3)).copy() if vel.shape in ((3,), (n, 3)) else None
        if vel is None:
            raise ValueError(f"PointTargets.velocity must have shape (3,) or ({n}, 3), got {np.shape(self.velocity)}")
        if not np.all(np.isfinite(vel)) or np.any(np.linalg.norm(vel, axis=1) >= 100.0):
            raise ValueError("PointTargets.velocity must be finite with speed < 100 m/s")
        for arr in (pos, refl, vel):
            arr.flags.writeable = False
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "reflectivity", refl)
        object.__setattr__(self, "velocity", vel)

    def scatterers(self) -> Scatterers:
        return Scatterers(self.positions, self.velocity, self.reflectivity)


def scatterers_of(targets) -> Scatterers:
    """All scatterers of a sequence of targets (anything with a ``scatterers()`` method)."""
    parts = []
    for i, target in enumerate(targets):
        if not hasattr(target, "scatterers"):
            raise TypeError(f"targets[{i}] ({type(target).__name__}) is not a target (it has no scatterers())")
        parts.append(target.scatterers())
    return Scatterers.concatenate(parts)
