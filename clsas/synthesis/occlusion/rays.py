"""Ray casting: Embree (embreex) occlusion queries with a brute-force Moller-Trumbore reference,
and the reuse of a facet's visibility between nearby pulses (see the package docstring)."""

from __future__ import annotations

import numpy as np

METHODS = ("embree", "reference")
DEFAULT_REUSE_TOLERANCE = 5e-4  # rad: PathWeights' default angle within which visibility is reused


def occluded_reference(triangles: np.ndarray, origins: np.ndarray, directions: np.ndarray,
                       tfar: np.ndarray, margin: float = 0.0, eps: float = 1e-12) -> np.ndarray:
    """Brute-force Moller-Trumbore: does each ray hit any triangle at 0 < t < tfar? (small meshes)

    ``triangles`` (F, 3, 3), ``origins`` / ``directions`` (K, 3) (directions unit), ``tfar`` (K,).
    ``margin`` grows (> 0) or shrinks (< 0) every triangle by that much in barycentric terms
    and the segment by that much in t, to tell grazing rays apart. Returns bool (K,). float64.
    """
    v0, v1, v2 = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = v1 - v0, v2 - v0
    out = np.zeros(origins.shape[0], dtype=bool)
    step = max(1, int(2**22 // max(1, triangles.shape[0])))
    for s in range(0, origins.shape[0], step):
        o, d, tf = origins[s:s + step, None, :], directions[s:s + step, None, :], tfar[s:s + step, None]
        p = np.cross(d, e2[None])
        det = np.sum(e1[None] * p, axis=-1)
        ok = np.abs(det) > eps
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = o - v0[None]
        u = np.sum(tv * p, axis=-1) * inv
        q = np.cross(tv, e1[None])
        w = np.sum(d * q, axis=-1) * inv
        t = np.sum(e2[None] * q, axis=-1) * inv
        hit = (ok & (u >= -margin) & (w >= -margin) & (u + w <= 1 + margin) & (t > -margin)
               & (t < tf + margin))
        out[s:s + step] = hit.any(axis=1)
    return out


class RayCaster:
    """Occlusion queries against one mesh (body frame) with Embree or the reference."""

    def __init__(self, mesh, method: str = "embree"):
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        import threading

        self.method = method
        self.triangles = np.asarray(mesh.triangles, dtype=np.float64)
        self.bounds = np.array([self.triangles.reshape(-1, 3).min(axis=0), self.triangles.reshape(-1, 3).max(axis=0)])
        self.rays_cast = 0  # rays cast so far (for the benchmarks)
        self.queries = 0  # paths answered so far, by a cast or by reuse (:func:`visibility`)
        self._lock = threading.Lock()
        if method == "embree":
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            self.scene = rtcore_scene.EmbreeScene()
            TriangleMesh(self.scene, np.asarray(mesh.vertices, dtype=np.float32),
                         np.asarray(mesh.faces, dtype=np.int32))

    def count_queries(self, n: int) -> None:
        with self._lock:
            self.queries += n

    def occluded(self, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> np.ndarray:
        """bool (K,): the segment origin + t direction, 0 < t < tfar, hits the mesh. Segments end
        where they leave the mesh's bounding box for good (nothing lies beyond: a long ray
        over a large mesh is not traversed past it)."""
        if origins.shape[0] == 0:
            return np.zeros(0, dtype=bool)
        with self._lock:
            self.rays_cast += origins.shape[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            exits = np.where(directions > 0, (self.bounds[1] - origins) / directions,
                             np.where(directions < 0, (self.bounds[0] - origins) / directions, np.inf))
        tfar = np.minimum(tfar, np.maximum(exits.min(axis=1), 0.0) * (1 + 1e-6) + 1e-6)
        if self.method == "reference":
            return occluded_reference(self.triangles, origins, directions, tfar)
        res = self.scene.run(np.ascontiguousarray(origins, dtype=np.float32),
                             np.ascontiguousarray(directions, dtype=np.float32),
                             dists=np.ascontiguousarray(tfar, dtype=np.float32), query="OCCLUDED")
        return np.asarray(res) != -1


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products over the first axis (components first, (3, ...) arrays that broadcast)."""
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


def _cast_clear(caster: RayCaster, start: np.ndarray, d: np.ndarray, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """bool (K,): the segments from ``start[n]`` ((N, 3) ray origins) along ``d[:, p, n]`` ((3, P, N),
    origin -> point) are free of the mesh."""
    v = d[:, p, n].T
    dist = np.sqrt(np.einsum("ij,ij->i", v, v))
    return ~caster.occluded(start[n], v / dist[:, None], dist)


def _reused(caster: RayCaster, start: np.ndarray, d: np.ndarray, needed: np.ndarray, tolerance: float) -> np.ndarray:
    """Visibility (P, N) of the ``needed`` paths, casting only where nearby pulses disagree.

    Casts at the first and last pulse, then bisects: a facet's pulses strictly between two cast
    pulses a < b take their state when both casts agree and the directions ``d[:, a, n]`` and
    ``d[:, b, n]`` differ by at most ``tolerance`` (rad); otherwise the middle pulse is cast and
    both halves are examined in turn. Every needed path is thus cast or lies between two casts
    that agree within the tolerance (a facet lit -> shadowed is cast at the pulse it changes).
    """
    n_p, n_f = needed.shape
    known = np.zeros((n_p, n_f), dtype=bool)
    clear = np.zeros((n_p, n_f), dtype=bool)

    def cast(p, n):
        keep = needed[p, n]
        p, n = p[keep], n[keep]
        clear[p, n] = _cast_clear(caster, start, d, p, n)
        known[p, n] = True

    n = np.flatnonzero(needed.any(axis=0))
    a, b = np.zeros(n.size, dtype=np.intp), np.full(n.size, n_p - 1, dtype=np.intp)
    cast(a, n)
    cast(b, n)
    chord = 2.0 * np.sin(0.5 * tolerance)  # |u_a - u_b| of unit vectors at that angle
    while n.size:
        live = b - a >= 2
        a, b, n = a[live], b[live], n[live]
        ua, ub = d[:, a, n].astype(np.float64), d[:, b, n].astype(np.float64)
        ua /= np.sqrt(_dot(ua, ua))
        ub /= np.sqrt(_dot(ub, ub))
        ua -= ub
        split = ~(known[a, n] & known[b, n] & (clear[a, n] == clear[b, n]) & (_dot(ua, ua) <= chord * chord))
        a, b, n = a[split], b[split], n[split]
        m = (a + b) // 2
        cast(m, n)
        a, b, n = np.concatenate([a, m]), np.concatenate([m, b]), np.concatenate([n, n])
    for p in range(1, n_p):  # the state of the last cast pulse at or before each pulse
        np.copyto(clear[p], clear[p - 1], where=~known[p])
    return needed & clear


def visibility(caster: "RayCaster | None", start: np.ndarray, d: np.ndarray, paths: np.ndarray,
               tolerance: float = 0.0) -> np.ndarray:
    """Which of the ``paths`` see their point unobstructed, pulse by pulse: bool (P, N).

    ``start`` (N, 3) are the ray origins (each facet's centroid moved a little along its normal),
    ``d`` (3, P, N) float32 the vectors from ``start`` to the point at each of P pulses
    (components first), ``paths`` bool (P, N) the paths to answer (facing ones; the rest are
    False). ``caster=None`` returns ``paths``. ``tolerance`` (rad) > 0 reuses a facet's state
    between pulses (:func:`_reused`); 0 casts every answered path. The caster counts the paths
    answered (``queries``) and the rays cast.
    """
    if tolerance < 0 or not np.isfinite(tolerance):
        raise ValueError(f"tolerance must be a finite angle >= 0 (rad), got {tolerance}")
    if caster is None:
        return paths
    caster.count_queries(int(np.count_nonzero(paths)))
    if tolerance > 0 and paths.shape[0] > 2:
        return _reused(caster, start, d, paths, tolerance)
    p, n = np.nonzero(paths)
    seen = np.zeros_like(paths)
    seen[p, n] = _cast_clear(caster, start, d, p, n)
    return seen


class WorldView(RayCaster):
    """A stationary mesh target's body-frame rays cast against shared world-frame scenes (its
    hull and everything else there: the seafloor, other targets; a ray is blocked when any
    scene blocks it): ``occluded`` moves the rays by ``rotation`` (body to world) and
    ``position``, and keeps its own counts."""

    def __init__(self, worlds, rotation: np.ndarray, position: np.ndarray):
        import threading

        self.worlds = list(worlds)
        self.method = self.worlds[0].method
        self.rotation, self.position = np.asarray(rotation, dtype=np.float64), np.asarray(position, dtype=np.float64)
        self.rays_cast = self.queries = 0
        self._lock = threading.Lock()

    def occluded(self, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> np.ndarray:
        with self._lock:
            self.rays_cast += origins.shape[0]
        o, d = origins @ self.rotation.T + self.position, directions @ self.rotation.T
        blocked = self.worlds[0].occluded(o, d, tfar)
        for world in self.worlds[1:]:
            open_ = ~blocked
            blocked[open_] = world.occluded(o[open_], d[open_], tfar[open_])
        return blocked
