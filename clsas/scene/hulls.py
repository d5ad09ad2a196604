"""Procedural target meshes: a submarine modelled on the USS Albacore, and simple shapes for tests.

Body frame of every hull here: x_b forward (the bow), y_b to port, z_b up, origin at the hull's
centre of length on its axis. All meshes are closed (watertight) trimesh objects, m.
"""

from __future__ import annotations

import numpy as np
import trimesh

from .. import validate as v


def _profile(length: float, radius: float, n: int) -> np.ndarray:
    """Albacore-like body-of-revolution radius along the axis (bow at s = 0): an elliptical bow
    to the widest section at 0.35 L, then a tail tapering as 1 - u^2 to a blunt 4 % stern."""
    s = length * (1 - np.cos(np.linspace(0, np.pi, n))) / 2  # denser at the ends
    widest = 0.35 * length
    bow = radius * np.sqrt(np.clip(1 - ((s - widest) / widest) ** 2, 0, None))
    u = (s - widest) / (length - widest)
    tail = radius * (1 - 0.96 * u**2)
    r = np.where(s < widest, bow, tail)
    r[0] = r[-1] = 0.0
    return np.column_stack([r, s])


def submarine(length: float = 62.1, beam: float = 8.4, sections: int = 64, stations: int = 80) -> trimesh.Trimesh:
    """A submarine after the USS Albacore (Kiang & Kiang 2022, Fig. 2): teardrop body of revolution
    of ``length`` and maximum diameter ``beam``, a sail, cruciform stern planes and rudders, and a
    propeller disc; bow along +x_b.

    Proportions (assumed from Albacore drawings; the paper gives L = 62.1 m, B = 8.4 m): widest
    section at 0.35 L from the bow; sail 0.13 L long centred 0.28 L from the bow, 0.09 B thick,
    rising 0.45 B above the hull; four stern surfaces (planes and rudders) 0.06 L long centred
    0.88 L from the bow, reaching 0.4 B beyond the hull; propeller disc of 0.35 B diameter
    behind the stern.

    ``sections`` (around the axis) and ``stations`` (along it) set the facet count of the body
    (about 2 sections x stations); the appendages add a few hundred facets. Use
    :class:`clsas.scene.targets.MeshTarget`'s ``max_facet`` to subdivide further.
    """
    length = v.positive("submarine length", length, high=v.MAX_COORDINATE, unit="m")
    beam = v.positive("submarine beam", beam, high=v.MAX_COORDINATE, unit="m")
    sections = v.integer("submarine sections", sections, low=8, high=4096)
    stations = v.integer("submarine stations", stations, low=8, high=4096)
    radius = beam / 2
    body = trimesh.creation.revolve(_profile(length, radius, stations), sections=sections)
    # revolve turns the profile (radius, s) about z: map s to -x, then put the bow at x = +L/2
    body.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [0, 1, 0]))
    body.apply_translation([length / 2 - body.bounds[1, 0], 0, 0])
    parts = [body]
    s_sail = 0.28 * length
    x_sail = length / 2 - s_sail
    r_sail = np.interp(s_sail, *_profile(length, radius, 400)[:, ::-1].T)
    sail = trimesh.creation.box(extents=[0.13 * length, 0.09 * beam, 0.45 * beam + r_sail])
    sail.apply_translation([x_sail, 0, (0.45 * beam + r_sail) / 2 + 0.2 * r_sail])
    parts.append(sail)
    s_planes = 0.88 * length
    r_planes = np.interp(s_planes, *_profile(length, radius, 400)[:, ::-1].T)
    span = r_planes + 0.4 * beam
    for angle in (0, np.pi / 2, np.pi, 3 * np.pi / 2):
        fin = trimesh.creation.box(extents=[0.06 * length, 0.02 * beam, span])
        fin.apply_translation([length / 2 - s_planes, 0, span / 2])
        fin.apply_transform(trimesh.transformations.rotation_matrix(angle, [1, 0, 0]))
        parts.append(fin)
    prop = trimesh.creation.cylinder(radius=0.175 * beam, height=0.01 * length, sections=sections // 2)
    prop.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    prop.apply_translation([-length / 2 - 0.01 * length, 0, 0])
    parts.append(prop)
    return trimesh.util.concatenate(parts)


def sphere(radius: float = 1.0, subdivisions: int = 3) -> trimesh.Trimesh:
    """Icosphere of ``radius`` m (20 x 4^subdivisions facets)."""
    return trimesh.creation.icosphere(subdivisions=v.integer("sphere subdivisions", subdivisions, low=0, high=8),
                                      radius=v.positive("sphere radius", radius, high=v.MAX_COORDINATE, unit="m"))


def cylinder(radius: float = 1.0, length: float = 4.0, sections: int = 32, segments: int = 1) -> trimesh.Trimesh:
    """Closed cylinder along x_b, centred on the origin: ``sections`` around the axis and
    ``segments`` along it (short facets subdivide evenly: :class:`MeshTarget`'s ``max_facet``)."""
    radius = v.positive("cylinder radius", radius, high=v.MAX_COORDINATE, unit="m")
    length = v.positive("cylinder length", length, high=v.MAX_COORDINATE, unit="m")
    sections = v.integer("cylinder sections", sections, low=3, high=2**20)
    segments = v.integer("cylinder segments", segments, low=1, high=2**20)
    if segments == 1:
        c = trimesh.creation.cylinder(radius=radius, height=length, sections=sections)
    else:  # the side as a profile of segments + 1 rings, revolved about z, with the end caps
        z = np.linspace(-length / 2, length / 2, segments + 1)
        profile = np.concatenate([[[0.0, -length / 2]], np.column_stack([np.full(z.size, radius), z]),
                                  [[0.0, length / 2]]])
        c = trimesh.creation.revolve(profile, sections=sections)
    c.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    return c


def box(extents=(1.0, 1.0, 1.0)) -> trimesh.Trimesh:
    """Box with the given x, y, z extents, m, centred on the origin."""
    ext = v.vector3("box extents", extents)
    if np.any(ext <= 0):
        raise ValueError(f"box extents: must be positive, got {ext}")
    return trimesh.creation.box(extents=ext)


def truncated_cone(bottom_radius: float = 0.5, top_radius: float = 0.25, height: float = 0.5,
                   sections: int = 48) -> trimesh.Trimesh:
    """Closed truncated cone along z_b, base on z_b = 0 (a Manta-like mine), m."""
    r0 = v.positive("truncated_cone bottom_radius", bottom_radius, high=v.MAX_COORDINATE, unit="m")
    r1 = v.scalar("truncated_cone top_radius", top_radius, low=0.0, high=v.MAX_COORDINATE, unit="m")
    h = v.positive("truncated_cone height", height, high=v.MAX_COORDINATE, unit="m")
    n = v.integer("truncated_cone sections", sections, low=3, high=2**20)
    profile = np.array([[0.0, 0.0], [r0, 0.0], [r1, h], [0.0, h]])  # (radius, z) from the base's centre
    return trimesh.creation.revolve(profile, sections=n)
