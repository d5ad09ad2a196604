"""What reflects: point scatterers (meshes come with the occlusion work).

Every target type turns into *scatterers*: a position at t = 0 (m), a constant velocity
(m/s) and a complex reflectivity, so that scatterer n is at ``p0[n] + vel[n] t`` at time t.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import budget
from .. import validate as v


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
        Positions at t = 0 (slow time zero), m, within +-1000 km.
    reflectivity : complex scalar or (N,) array
        Complex amplitude of each scatterer (default 1); finite, |A| <= 1e15.
    velocity : (3,) or (N, 3) array
        Constant velocity, m/s (default 0: stationary); |v| <= 100 m/s.
    """

    positions: np.ndarray
    reflectivity: complex | np.ndarray = 1.0
    velocity: np.ndarray = (0.0, 0.0, 0.0)

    def __post_init__(self):
        given = np.shape(self.positions) if not isinstance(self.positions, str) else ()
        pos = v.array("PointTargets.positions", self.positions, (3,) if len(given) == 1 else (-1, 3),
                      bound=v.MAX_COORDINATE).reshape(-1, 3)
        if pos.shape[0] == 0:
            raise ValueError("PointTargets.positions: must hold at least one scatterer (shape (N >= 1, 3)), got none")
        n = pos.shape[0]
        refl = v.array("PointTargets.reflectivity", self.reflectivity, (n,) if np.ndim(self.reflectivity) else (),
                       bound=v.MAX_AMPLITUDE, dtype=np.complex128)
        refl = np.full(n, refl) if refl.ndim == 0 else refl.copy()
        vel = v.array("PointTargets.velocity", self.velocity, (n, 3) if np.ndim(self.velocity) == 2 else (3,))
        vel = np.broadcast_to(vel, (n, 3)).copy()
        speed = np.linalg.norm(vel, axis=1).max()
        if speed > v.MAX_SPEED:
            raise ValueError(f"PointTargets.velocity: speeds must be at most {v.MAX_SPEED:g} m/s (far below the sound "
                             f"speed), got {speed:g} m/s")
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


def _load_mesh(source):
    """A triangle mesh from a file trimesh reads; TypeError for anything but a path, OSError
    naming the path when it is not a regular file (a FIFO would block the read), ValueError when
    trimesh cannot read it."""
    import os

    import trimesh

    if not isinstance(source, (str, os.PathLike)):
        raise TypeError(f"MeshTarget.mesh: must be a trimesh.Trimesh or the path of a mesh file, got "
                        f"{type(source).__name__}")
    path = os.fspath(source)
    if not os.path.isfile(path):
        kind = "no such file" if not os.path.exists(path) else "not a regular file"
        raise FileNotFoundError(f"MeshTarget.mesh: {path}: {kind}")
    try:
        return trimesh.load(path, force="mesh")
    except Exception as err:  # noqa: BLE001 - trimesh raises many types for unreadable files
        raise ValueError(f"MeshTarget.mesh: cannot load {path} as a triangle mesh ({type(err).__name__}: "
                         f"{err})") from err


def pose_rotation(heading: float, pitch: float, roll: float) -> np.ndarray:
    """Body-to-world rotation of a target: R = R_z(heading) R_y(-pitch) R_x(roll).

    Body frame: x_b the bow, y_b port, z_b up. ``heading`` turns the bow from world +x towards
    +y (counter-clockwise seen from above), ``pitch`` raises the bow, ``roll`` turns the sail
    from up towards starboard; radians.
    """
    ch, sh = np.cos(heading), np.sin(heading)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    rz = np.array([[ch, -sh, 0.0], [sh, ch, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, -sp], [0.0, 1.0, 0.0], [sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


REFLECTIVITY_LAWS = ("lambertian", "specular")


@dataclass(frozen=True, eq=False)
class MeshTarget:
    """A rigid target made of flat facets, each a scatterer at its centroid.

    Parameters
    ----------
    mesh : trimesh.Trimesh, or a path of any file trimesh loads (STL, OBJ, PLY, GLB, ...)
        In the body frame (x_b bow, y_b port, z_b up), m.
    position : (3,) world position of the body origin at t = 0, m.
    heading, pitch, roll : float, radians (see :func:`pose_rotation`).
    velocity : (3,) constant velocity, m/s (< 100).
    max_facet : float, optional
        Subdivide until no facet edge is longer than this, m. Rule of thumb: a facet should not
        be larger than about half the finest resolution cell (c / 2B in range, D / 2 along
        track), so that each cell holds several independent scatterers; larger facets image as
        sparse bright points.
    law : {"lambertian", "specular"}
        Angular law of a facet's echo towards the bistatic bisector b (the unit sum of the
        directions to transmitter and receiver): ``max(0, n.b)`` (Lambertian) or
        ``max(0, n.b) ** exponent`` (a specular lobe); applied per path by the echo synthesis.
    exponent : float
        Sharpness of the specular lobe.
    speckle_seed : int, optional
        Give each facet a random phase (seeded): rough-surface speckle.
    gain : float
        Overall amplitude; a facet reflects ``gain x area`` (x the angular law).

    Meshes with degenerate (zero-area) faces are cleaned with a warning; a mesh that is not
    watertight gives a warning (occlusion then has holes); an empty mesh raises.
    """

    mesh: object
    position: np.ndarray = (0.0, 0.0, 0.0)
    heading: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    velocity: np.ndarray = (0.0, 0.0, 0.0)
    max_facet: float | None = None
    law: str = "lambertian"
    exponent: float = 10.0
    speckle_seed: int | None = None
    gain: float = 1.0

    def __post_init__(self):
        import warnings

        import trimesh

        mesh = self.mesh
        if not isinstance(mesh, trimesh.Trimesh):
            mesh = _load_mesh(mesh)
        mesh = mesh.copy()
        if len(mesh.faces) == 0:
            raise ValueError("MeshTarget.mesh is empty: it has no faces")
        v.array("MeshTarget.mesh vertices", mesh.vertices, (-1, 3), bound=v.MAX_COORDINATE, copy=False)
        areas = mesh.area_faces
        degenerate = ~(areas > 1e-12 * max(1.0, float(areas.max())))
        if degenerate.any():
            warnings.warn(f"MeshTarget.mesh: removed {int(degenerate.sum())} degenerate (zero-area) faces",
                          UserWarning, stacklevel=3)
            mesh.update_faces(~degenerate)
            mesh.remove_unreferenced_vertices()
        if len(mesh.faces) == 0:
            raise ValueError("MeshTarget.mesh has only degenerate faces")
        if self.max_facet is not None:
            edge = v.positive("MeshTarget.max_facet", self.max_facet, unit="m")
            # subdivision to edges <= max_facet leaves about 2 area / (sqrt(3)/4 max_facet^2) facets
            facets = len(mesh.faces) + 8 * float(mesh.area) / (np.sqrt(3) * edge * edge)
            budget.check_bytes(f"MeshTarget.max_facet={edge:g} m (~{facets:.3g} facets)", 400.0 * facets,
                               "a larger max_facet")
            verts, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=edge, max_iter=20)
            mesh = trimesh.Trimesh(verts, faces, process=False)
        if not mesh.is_watertight:
            warnings.warn("MeshTarget.mesh is not watertight: hull occlusion will let rays through its holes",
                          UserWarning, stacklevel=3)
        v.choice("MeshTarget.law", self.law, REFLECTIVITY_LAWS)
        if self.speckle_seed is not None:
            v.integer("MeshTarget.speckle_seed", self.speckle_seed, low=0, high=2**63 - 1, why="or None")
        object.__setattr__(self, "mesh", mesh)
        object.__setattr__(self, "position", v.vector3("MeshTarget.position", self.position))
        for name in ("heading", "pitch", "roll"):
            object.__setattr__(self, name, v.scalar(f"MeshTarget.{name}", getattr(self, name)))
        vel = v.vector3("MeshTarget.velocity", self.velocity)
        if np.linalg.norm(vel) > v.MAX_SPEED:
            raise ValueError(f"MeshTarget.velocity: must be at most {v.MAX_SPEED:g} m/s (far below the sound speed), "
                             f"got {np.linalg.norm(vel):g} m/s")
        object.__setattr__(self, "velocity", vel)
        object.__setattr__(self, "exponent", v.positive("MeshTarget.exponent", self.exponent))
        object.__setattr__(self, "gain", v.positive("MeshTarget.gain", self.gain, high=v.MAX_AMPLITUDE))

    @property
    def rotation(self) -> np.ndarray:
        """Body-to-world rotation (3, 3)."""
        return pose_rotation(self.heading, self.pitch, self.roll)

    @property
    def n_facets(self) -> int:
        return len(self.mesh.faces)

    def to_body(self, points: np.ndarray, t) -> np.ndarray:
        """World points (..., 3) at times t (broadcast to points[..., 0]) in the body frame."""
        origin = self.position + np.asarray(t, dtype=np.float64)[..., None] * self.velocity
        return (np.asarray(points) - origin) @ self.rotation

    def facets_world(self) -> tuple[np.ndarray, np.ndarray]:
        """Facet centroids at t = 0 (N, 3) and unit normals (N, 3) in the world frame."""
        rot = self.rotation
        return self.mesh.triangles_center @ rot.T + self.position, self.mesh.face_normals @ rot.T

    def angular_gain(self, normals: np.ndarray, to_tx: np.ndarray, to_rx: np.ndarray) -> np.ndarray:
        """The angular law for unit normals and unit directions facet -> transmitter / receiver (..., 3)
        (0 where the directions cancel or are zero)."""
        bisector = to_tx + to_rx
        size = np.sqrt(np.einsum("...i,...i->...", bisector, bisector))
        dot = np.einsum("...i,...i->...", normals, bisector)
        return self.lobe(np.divide(dot, size, out=np.zeros_like(dot), where=size > 0))

    def lobe(self, cos: np.ndarray) -> np.ndarray:
        """The angular law of the cosines ``cos`` between the normals and the bisectors (any shape):
        max(0, cos) (Lambertian) or max(0, cos) ** exponent (specular)."""
        cos = np.maximum(cos, 0)
        return cos if self.law == "lambertian" else cos ** self.exponent

    def scatterers(self) -> Scatterers:
        centres, _ = self.facets_world()
        refl = self.gain * self.mesh.area_faces.astype(np.complex128)
        if self.speckle_seed is not None:
            refl = refl * np.exp(2j * np.pi * np.random.default_rng(self.speckle_seed).random(refl.size))
        return Scatterers(centres, np.broadcast_to(self.velocity, centres.shape).copy(), refl)
