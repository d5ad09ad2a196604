"""Hull occlusion of scattered paths by ray casting (Embree through embreex), with a brute-force
Moller-Trumbore reference, and the per-path weights of mesh targets.

For every pulse and facet of a :class:`clsas.scene.targets.MeshTarget`: the facet is lit when
it faces the transmitter (at its emission position) and the segment from the facet to the
transmitter is free of the hull; it is heard by receiver h when it faces the receiver (at its
reception position) and that segment is free too (Kiang & Kiang 2022, section VI and Fig. 17:
the hull blocks scattered waves). The target moves: the rays are cast in its body frame at the
facet's scattering time (eta + t1 of :mod:`clsas.simulate.geometry`), where the hull is fixed.
Back-facing facets are dark without casting a ray. A path's weight is
lit x heard x the target's angular law (:meth:`MeshTarget.angular_gain`).

Rays start a small distance (1e-5 of the hull's size) off the facet along its normal, so that
a facet does not shadow itself; rays end at the transmitter / receiver. Outgoing and incoming
legs are solved in closed form when the motion is uniform (:func:`geometry.meet_time`).
"""

from __future__ import annotations

import numpy as np

from ..scene.targets import MeshTarget
from . import geometry
from .window import has_motion_errors

METHODS = ("embree", "reference")
THREADS = 2  # pulse groups computed at once (the machine has two cores)


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
        self.rays_cast = 0  # rays queried so far (for the benchmarks)
        self._lock = threading.Lock()
        if method == "embree":
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            self.scene = rtcore_scene.EmbreeScene()
            TriangleMesh(self.scene, np.asarray(mesh.vertices, dtype=np.float32),
                         np.asarray(mesh.faces, dtype=np.int32))

    def occluded(self, origins: np.ndarray, directions: np.ndarray, tfar: np.ndarray) -> np.ndarray:
        """bool (K,): the segment origin + t direction, 0 < t < tfar, hits the mesh."""
        if origins.shape[0] == 0:
            return np.zeros(0, dtype=bool)
        with self._lock:
            self.rays_cast += origins.shape[0]
        if self.method == "reference":
            return occluded_reference(self.triangles, origins, directions, tfar)
        res = self.scene.run(np.ascontiguousarray(origins, dtype=np.float32),
                             np.ascontiguousarray(directions, dtype=np.float32),
                             dists=np.ascontiguousarray(tfar, dtype=np.float32), query="OCCLUDED")
        return np.asarray(res) != -1


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _unit(d: np.ndarray) -> np.ndarray:
    return d / np.sqrt(_dot(d, d))[:, None]


def facet_visibility(caster: "RayCaster | None", start: np.ndarray, normal: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Facets that face a point and see it unobstructed: bool ``d.shape[:-1]``.

    ``start`` are the ray origins (each facet's centroid moved a little along its normal),
    ``normal`` the facets' unit normals (both broadcast against ``d``), ``d`` (..., 3) the vectors
    from ``start`` to the point. Rays are cast only for facing facets; ``caster=None`` checks
    facing only.
    """
    visible = _dot(d, normal) > 0
    if caster is not None and visible.any():
        dv = d[visible]
        dist = np.sqrt(_dot(dv, dv))
        visible[visible] = ~caster.occluded(np.broadcast_to(start, d.shape)[visible], dv / dist[:, None], dist)
    return visible


class _Facets:
    """A mesh target's facets in its body frame, float32: centroids, normals and ray origins
    (centroids moved 1e-5 of the hull's size along the normal, so that no facet shadows itself)."""

    def __init__(self, target: MeshTarget):
        self.centre = target.mesh.triangles_center.astype(np.float32)
        self.normal = target.mesh.face_normals.astype(np.float32)
        offset = 1e-5 * float(np.linalg.norm(np.ptp(target.mesh.vertices, axis=0)))
        self.start = self.centre + np.float32(offset) * self.normal


class PathWeights:
    """The per-path weights of a scenario's targets: a callable ``weights(pulses) -> (H, P, N)``
    that :func:`clsas.simulate` takes as its ``occlusion`` (mesh facets: visibility x angular
    law; point scatterers: 1).

    ``hull_occlusion=False`` keeps only the angular law (and back-facing darkness).
    """

    def __init__(self, scenario, stop_and_go: bool = False, hull_occlusion: bool = True, method: str = "embree",
                 pulses_per_call: int = 4):
        self.scenario, self.stop_and_go, self.hull_occlusion = scenario, stop_and_go, hull_occlusion
        self.pulses_per_call = max(1, int(pulses_per_call))
        self.parts = []  # (first scatterer index, count, target or None, caster, facets or None)
        start = 0
        for target in scenario.targets:
            mesh = isinstance(target, MeshTarget)
            n = target.n_facets if mesh else target.scatterers().count
            caster = RayCaster(target.mesh, method) if mesh and hull_occlusion else None
            self.parts.append((start, n, target if mesh else None, caster, _Facets(target) if mesh else None))
            start += n
        self.n_scatterers = start

    def _uniform_motion(self) -> bool:
        return not self.stop_and_go and not (self.scenario.array.n_receivers and has_motion_errors(self.scenario.platform))

    def _weights(self, target: MeshTarget, caster, facets: _Facets, d_tx: np.ndarray, receiver_d) -> np.ndarray:
        """Path weights (H, P, N) from the vectors facet -> transmitter ``d_tx`` (P, N, 3, body
        frame) and ``receiver_d(h, flat)``, the vectors facet -> receiver h (K, 3) of the paths
        ``flat`` (indices into P * N): lit x heard x the angular law. The receivers' legs are
        asked for only where the transmitter lights the facet."""
        n_facets = facets.start.shape[0]
        flat = np.flatnonzero(facet_visibility(caster, facets.start, facets.normal, d_tx))
        u_tx = _unit(d_tx.reshape(-1, 3)[flat])
        ni = flat % n_facets
        out = np.zeros((self.scenario.n_receivers,) + d_tx.shape[:2])
        for h in range(self.scenario.n_receivers):
            d_rx = receiver_d(h, flat)
            heard = facet_visibility(caster, facets.start[ni], facets.normal[ni], d_rx)
            out[h].reshape(-1)[flat[heard]] = target.angular_gain(facets.normal[ni[heard]], u_tx[heard],
                                                                  _unit(d_rx[heard]))
        return out

    def _mesh_weights_uniform(self, target: MeshTarget, caster, facets: _Facets, eta: np.ndarray) -> np.ndarray:
        """:meth:`_mesh_weights` when every receiver moves uniformly, computed in the body frame.

        With x_b = (x - position - v t) R (R body-to-world, v the target velocity), a point moving
        uniformly is affine in time in the body frame, so the transmitter as seen from facet n at
        its scattering time eta + t1_n is tx_b(eta) - v_b t1_n, and receiver h at reception is
        r_b(eta) + (w_b - v_b) t1_n + w_b t2_n: broadcasts instead of a rotation per path. The legs
        are the closed forms of :func:`geometry.meet_time` (distances and dot products do not
        change under the rotation). Computed in float32: these delays only place the hull and the
        receivers (an error of 1e-7 s moves them by under a micrometre), and the rays are float32.
        """
        sc = self.scenario
        f32 = np.float32
        c = float(sc.medium.sound_speed)
        rot = target.rotation
        v_b = (target.velocity @ rot).astype(f32)
        tx0_b = target.to_body(sc.tx_position(eta), eta).astype(f32)  # (P, 3), the pose at emission
        t1 = geometry.meet_time(facets.centre[None] - tx0_b[:, None, :], v_b, c)  # (P, N)
        d_tx = tx0_b[:, None, :] - v_b * t1[..., None] - facets.start
        n_facets = facets.start.shape[0]

        def receiver_d(h, flat):
            pi, ni = np.divmod(flat, n_facets)
            r0 = sc.receiver_position(h, eta)
            w_b = ((sc.receiver_position(h, eta + 1.0) - r0) @ rot).astype(f32)[pi]  # uniform velocity
            r_t1 = target.to_body(r0, eta).astype(f32)[pi] + (w_b - v_b) * t1.reshape(-1)[flat][:, None]
            t2 = geometry.meet_time(r_t1 - facets.centre[ni], w_b, c)
            return r_t1 + w_b * t2[:, None] - facets.start[ni]

        return self._weights(target, caster, facets, d_tx, receiver_d)

    def _mesh_weights(self, target: MeshTarget, caster, facets: _Facets, eta: np.ndarray) -> np.ndarray:
        """Weights (H, P, N) of a mesh target's paths for the pulses ``eta``: in general (stop-and-go,
        motion errors) the positions are found in the world frame (fixed points for the receivers)
        and moved into the body frame at each facet's scattering time."""
        if self._uniform_motion():
            return self._mesh_weights_uniform(target, caster, facets, eta)
        sc = self.scenario
        c = sc.medium.sound_speed
        tol = geometry.iteration_tolerance(sc.waveform.f0)
        tx = sc.tx_position(eta)
        q_emit = target.facets_world()[0][None] + target.velocity * eta[:, None, None]
        if self.stop_and_go:
            t1, q = np.linalg.norm(q_emit - tx[:, None, :], axis=-1) / c, q_emit
        else:
            t1 = geometry.meet_time(q_emit - tx[:, None, :], target.velocity, c)
            q = q_emit + target.velocity * t1[..., None]
        t_scatter = eta[:, None] + (0.0 if self.stop_and_go else t1)  # the hull's pose time
        tx_b = target.to_body(np.broadcast_to(tx[:, None, :], q.shape), t_scatter)
        n_facets = facets.start.shape[0]

        def receiver_d(h, flat):
            r = geometry.incoming(lambda t: sc.receiver_position(h, t), eta, t1, q, c, tol, self.stop_and_go)[1]
            return target.to_body(r, t_scatter).reshape(-1, 3)[flat] - facets.start[flat % n_facets]

        return self._weights(target, caster, facets, tx_b - facets.start, receiver_d)

    def __call__(self, pulses: slice) -> np.ndarray:
        """Weights (n_rx, len(pulses), n_scatterers); pulse groups run on two threads (Embree's
        queries and NumPy's array operations release the GIL)."""
        from concurrent.futures import ThreadPoolExecutor

        eta_all = self.scenario.eta[pulses]
        out = np.ones((self.scenario.n_receivers, eta_all.size, self.n_scatterers))

        def fill(s):
            eta = eta_all[s:s + self.pulses_per_call]
            for first, n, target, caster, facets in self.parts:
                if target is not None:
                    out[:, s:s + eta.size, first:first + n] = self._mesh_weights(target, caster, facets, eta)

        with ThreadPoolExecutor(max_workers=THREADS) as pool:
            list(pool.map(fill, range(0, eta_all.size, self.pulses_per_call)))
        return out


def has_meshes(scenario) -> bool:
    return any(isinstance(t, MeshTarget) for t in scenario.targets)


def scan_image(scenario, r, y, eta: float = 0.0, receiver: int = 0):
    """The scan image of a scenario's mesh targets (Kiang & Kiang 2022 section VI, Fig. 9(d)).

    Every facet that transceiver ``receiver`` (the array's first receiver, A, by default; its
    own transmitter for the outgoing leg) sees lit and unobstructed at slow time ``eta`` is
    projected onto the r-y plane: r its one-way slant range from the receiver, y its along-track
    coordinate (both at the scattering time); its weight (area x angular law, as in the echo
    synthesis) is added into the pixel of the uniform axes ``r`` and ``y`` (m) that contains it.
    Returns an :class:`clsas.data.Image` with dims ("y", "r") and real, non-negative values.
    """
    from ..data import Image
    from ..scene.scenario import PulseSchedule

    r = np.asarray(r, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    for name, ax in (("r", r), ("y", y)):
        if ax.ndim != 1 or ax.size < 2 or not np.all(np.isfinite(ax)) or not np.allclose(np.diff(ax), ax[1] - ax[0]):
            raise ValueError(f"scan_image: {name} must be a uniform, increasing 1-D axis of >= 2 values (m)")
    if not has_meshes(scenario):
        raise ValueError("scan_image: the scenario has no mesh target")
    one = scenario.replace(schedule=PulseSchedule(prf=1.0, n_pulses=1, start=float(eta)))
    path_weights = PathWeights(one)
    weights = path_weights(slice(None))[receiver, 0]  # (n_scatterers,)
    image = np.zeros((y.size, r.size))
    tx = one.receiver_position(receiver, np.array([float(eta)]))[0]
    for first, n, target, _, _ in path_weights.parts:
        if target is None:
            continue
        centres = target.facets_world()[0] + target.velocity * eta
        w = weights[first:first + n] * target.mesh.area_faces
        ri = np.floor((np.linalg.norm(centres - tx, axis=1) - r[0]) / (r[1] - r[0]) + 0.5).astype(int)
        yi = np.floor((centres[:, 1] - y[0]) / (y[1] - y[0]) + 0.5).astype(int)
        keep = (w > 0) & (ri >= 0) & (ri < r.size) & (yi >= 0) & (yi < y.size)
        np.add.at(image, (yi[keep], ri[keep]), w[keep])
    return Image(data=image, dims=("y", "r"), axes={"y": y, "r": r},
                 provenance={"algorithm": "scan_image", "eta": float(eta), "receiver": scenario.receiver_names[receiver]})
