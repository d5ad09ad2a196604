"""Hull occlusion of scattered paths by ray casting (Embree through embreex), with a brute-force
Moller-Trumbore reference, and the per-path weights of mesh targets.

For every pulse and facet of a :class:`clsas.scene.targets.MeshTarget`: the facet is lit when
it faces the transmitter (at its emission position) and the segment from the facet to the
transmitter is free of the hull; it is heard by receiver h when it faces the receiver (at its
reception position) and that segment is free too (Kiang & Kiang 2022, section VI and Fig. 17:
the hull blocks scattered waves). The target moves: the rays are cast in its body frame at the
facet's scattering time (eta + t1 of :mod:`clsas.geometry`), where the hull is fixed.
Back-facing facets are dark without casting a ray. A path's weight is
lit x heard x the target's angular law (:meth:`MeshTarget.angular_gain`).

Rays start a small distance (1e-5 of the hull's size) off the facet along its normal, so that
a facet does not shadow itself; rays end at the transmitter / receiver. Outgoing and incoming
legs are solved in closed form when the motion is uniform (:func:`geometry.meet_time`).

Visibility changes slowly from pulse to pulse (at 2 km a 3 m/s platform turns the direction
from a facet by ~2e-5 rad per pulse at 80 Hz), so a facet's state is reused between two cast
pulses when both casts agree and the directions differ by at most a stated angle
(:class:`PathWeights` ``reuse_tolerance``); where they disagree the pulses between are bisected
down to the pulse where the state changes. The facing test and the angular law are computed
for every path.
"""

from __future__ import annotations

import numpy as np

from ..scene.targets import MeshTarget
from .. import geometry
from .window import has_motion_errors

METHODS = ("embree", "reference")
DEFAULT_REUSE_TOLERANCE = 5e-4  # rad: PathWeights' default angle within which visibility is reused
THREADS = 2  # pulse blocks computed at once (the machine has two cores)


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


class _Facets:
    """A mesh target's facets in its body frame, float32: unit normals (3, N) and ray origins, the
    centroids moved 1e-5 of the hull's size along the normal (so that no facet shadows itself),
    both as (N, 3) for the caster and (3, N) for the geometry."""

    def __init__(self, target: MeshTarget):
        self.normal = np.ascontiguousarray(target.mesh.face_normals.T, dtype=np.float32)
        offset = 1e-5 * float(np.linalg.norm(np.ptp(target.mesh.vertices, axis=0)))
        start = target.mesh.triangles_center + offset * target.mesh.face_normals
        self.start = np.ascontiguousarray(start, dtype=np.float32)
        self.start_t = np.ascontiguousarray(start.T, dtype=np.float32)


class PathWeights:
    """The per-path weights of a scenario's targets: a callable ``weights(pulses) -> (H, P, N)``
    that :func:`clsas.simulate` takes as its ``occlusion`` (mesh facets: visibility x angular
    law; point scatterers: 1).

    ``hull_occlusion=False`` keeps only the angular law (and back-facing darkness).
    ``reuse_tolerance`` (rad, default 5e-4): a facet's lit / heard state is reused for the pulses
    between two cast pulses whose states agree and whose directions from the facet (body frame)
    differ by at most this angle (:func:`_reused`); the approximation: an occluder that crosses
    the ray and leaves again between two such pulses is missed. Seen from a facet, such an
    occluder is narrower than its distance x the tolerance (3 cm at the far end of a 62 m hull at
    5e-4 rad, three wavelengths at 150 kHz). 0 casts every ray.
    Pulses are handled in blocks of ``pulses_per_block`` (the span of the reuse), two blocks at
    a time on two threads (NumPy's array operations release the GIL; Embree's casts hold it).
    """

    def __init__(self, scenario, stop_and_go: bool = False, hull_occlusion: bool = True, method: str = "embree",
                 reuse_tolerance: float = DEFAULT_REUSE_TOLERANCE, pulses_per_block: int = 32):
        if not (np.isfinite(reuse_tolerance) and reuse_tolerance >= 0):
            raise ValueError(f"reuse_tolerance must be a finite angle >= 0 (rad), got {reuse_tolerance}")
        if int(pulses_per_block) < 1:
            raise ValueError(f"pulses_per_block must be >= 1, got {pulses_per_block}")
        self.scenario, self.stop_and_go, self.hull_occlusion = scenario, stop_and_go, hull_occlusion
        self.reuse_tolerance, self.pulses_per_block = float(reuse_tolerance), int(pulses_per_block)
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

    def _weights(self, target: MeshTarget, caster, facets: _Facets, d_tx: np.ndarray, receiver_d, out: np.ndarray):
        """Path weights into ``out`` (H, P, N) from the vectors facet -> transmitter ``d_tx`` and
        ``receiver_d(h)``, facet -> receiver h, both (3, P, N) float32 from the ray origins (body
        frame): lit x heard x the angular law. A receiver's rays are cast only where the facet is lit."""
        normal = facets.normal[:, None, :]
        nu_tx = _dot(normal, d_tx)
        lit = visibility(caster, facets.start, d_tx, nu_tx > 0, self.reuse_tolerance)
        dist = np.sqrt(_dot(d_tx, d_tx))
        d_tx /= dist  # unit, towards the transmitter
        nu_tx /= dist
        for h in range(self.scenario.n_receivers):
            d_rx = receiver_d(h)
            cos = _dot(normal, d_rx)
            heard = visibility(caster, facets.start, d_rx, lit & (cos > 0), self.reuse_tolerance)
            # the bisector b = u_tx + u_rx: n.b = n.u_tx + n.d_rx / |d_rx|, |b|^2 = 2 + 2 u_tx.d_rx / |d_rx|
            dist = np.sqrt(_dot(d_rx, d_rx))
            size = _dot(d_tx, d_rx)
            size /= dist
            size += 1
            cos /= dist
            cos += nu_tx
            cos /= np.sqrt(np.maximum(2 * size, np.float32(1e-30)))
            np.multiply(target.lobe(cos), heard, out=out[h])

    def _mesh_weights_uniform(self, target: MeshTarget, caster, facets: _Facets, eta: np.ndarray, out: np.ndarray):
        """:meth:`_mesh_weights` when every receiver moves uniformly, computed in the body frame.

        With x_b = (x - position - v t) R (R body-to-world, v the target velocity), a point moving
        uniformly is affine in time in the body frame, so the transmitter as seen from facet n at
        its scattering time eta + t1_n is tx_b(eta) - v_b t1_n, and receiver h at reception is
        r_b(eta) + (w_b - v_b) t1_n + w_b t2_n: broadcasts instead of a rotation per path. The legs
        are the closed forms of :func:`geometry.meet_time` (distances and dot products do not
        change under the rotation). Computed in float32, components first (3, P, N): these delays
        only place the hull and the receivers (an error of 1e-7 s moves them by under a
        micrometre), positions are relative to the hull (float32 error ~0.2 mm at 2 km, 1e-7 rad
        in direction), and the rays are float32. The legs are solved from the ray origins, 1e-5
        of the hull's size off the centroids (0.6 mm on a 62 m hull): the times change by < 1e-6 s,
        which moves the hull and the receivers by < 1e-4 m.
        """
        sc = self.scenario
        f32 = np.float32
        c = f32(sc.medium.sound_speed)
        rot = target.rotation
        v_b = (target.velocity @ rot).astype(f32)[:, None, None]
        tx0_b = target.to_body(sc.tx_position(eta), eta).T.astype(f32)[:, :, None]  # (3, P, 1), pose at emission
        d_tx = facets.start_t[:, None, :] - tx0_b  # (3, P, N) transmitter at emission -> ray origin
        t1 = geometry.meet_time(d_tx, v_b, c, axis=0)  # (P, N)
        d_tx *= -1
        d_tx -= v_b * t1  # ray origin -> transmitter at the scattering time

        def receiver_d(h):
            r0 = sc.receiver_position(h, eta)
            w_b = ((sc.receiver_position(h, eta + 1.0) - r0) @ rot).T.astype(f32)[:, :, None]  # uniform velocity
            d = (w_b - v_b) * t1
            d += target.to_body(r0, eta).T.astype(f32)[:, :, None]
            d -= facets.start_t[:, None, :]  # ray origin -> receiver at the scattering time
            d += w_b * geometry.meet_time(d, w_b, c, axis=0)
            return d

        self._weights(target, caster, facets, d_tx, receiver_d, out)

    def _mesh_weights(self, target: MeshTarget, caster, facets: _Facets, eta: np.ndarray, out: np.ndarray):
        """Weights (H, P, N) of a mesh target's paths for the pulses ``eta``, into ``out``: in general
        (stop-and-go, motion errors) the positions are found in the world frame (fixed points for
        the receivers) and moved into the body frame at each facet's scattering time."""
        if self._uniform_motion():
            return self._mesh_weights_uniform(target, caster, facets, eta, out)
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

        def body(points):  # world points (P, N, 3) at the scattering time -> ray origin -> point (3, P, N)
            d = np.moveaxis(target.to_body(points, t_scatter), -1, 0).astype(np.float32)
            d -= facets.start_t[:, None, :]
            return d

        def receiver_d(h):
            return body(geometry.incoming(lambda t: sc.receiver_position(h, t), eta, t1, q, c, tol, self.stop_and_go)[1])

        self._weights(target, caster, facets, body(np.broadcast_to(tx[:, None, :], q.shape)), receiver_d, out)

    def __call__(self, pulses: slice) -> np.ndarray:
        """Weights (n_rx, len(pulses), n_scatterers) float64; blocks of pulses run on two threads."""
        from concurrent.futures import ThreadPoolExecutor

        eta_all = self.scenario.eta[pulses]
        out = np.ones((self.scenario.n_receivers, eta_all.size, self.n_scatterers))
        step = self.pulses_per_block

        def fill(s):
            eta = eta_all[s:s + step]
            for first, n, target, caster, facets in self.parts:
                if target is not None:
                    self._mesh_weights(target, caster, facets, eta, out[:, s:s + eta.size, first:first + n])

        with ThreadPoolExecutor(max_workers=THREADS) as pool:
            list(pool.map(fill, range(0, eta_all.size, step)))
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
    Returns an :class:`clsas.model.Image` with dims ("y", "r") and real, non-negative values.
    """
    from ..model import Image
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
