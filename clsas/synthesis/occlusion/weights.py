"""Per-path weights: mesh targets (hull visibility x angular law) and the seafloor's facets
(:mod:`.seafloor`), the callable :func:`clsas.simulate` takes as its ``occlusion``."""

from __future__ import annotations

import numpy as np

from ... import geometry
from ...scene.seafloor import facet_spacing
from ...scene.targets import MeshTarget, Scatterers, scatterers_of
from ..window import has_motion_errors
from .rays import DEFAULT_REUSE_TOLERANCE, RayCaster, WorldView, _dot, visibility
from .seafloor import SeafloorPaths

THREADS = 2  # pulse blocks computed at once (the machine has two cores)


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
    """The per-path weights of a scenario's scatterers (:func:`scene_scatterers`: the targets',
    then the seafloor's facets): a callable ``weights(pulses) -> (H, P, N)`` that
    :func:`clsas.simulate` takes as its ``occlusion`` (mesh facets: visibility x angular law;
    point scatterers: 1; seafloor facets: :mod:`.seafloor`).

    With a seafloor, the rays of every stationary mesh target and of the seafloor's facets are
    cast against one world-frame scene: the seafloor's mesh and the stationary targets (so a
    target hides the seafloor behind it and the others, and the relief hides what lies behind
    it); a moving target's own facets are cast against its hull in its body frame.

    ``hull_occlusion=False`` keeps only the angular law (and back-facing darkness).
    ``reuse_tolerance`` (rad, default 5e-4): a facet's lit / heard state is reused for the pulses
    between two cast pulses whose states agree and whose directions from the facet (body frame)
    differ by at most this angle (:func:`_reused`); the approximation: an occluder that crosses
    the ray and leaves again between two such pulses is missed. Seen from a facet, such an
    occluder is narrower than its distance x the tolerance (3 cm at the far end of a 62 m hull at
    5e-4 rad, three wavelengths at 150 kHz). 0 casts every ray.
    Pulses are handled in blocks of ``pulses_per_block`` (the span of the reuse), two blocks at
    a time on two threads (NumPy's array operations release the GIL; Embree's casts hold it).
    ``backend`` computes the seafloor's weights (kernels/seafloor.cl or its NumPy twin).
    """

    def __init__(self, scenario, stop_and_go: bool = False, hull_occlusion: bool = True, method: str = "embree",
                 reuse_tolerance: float = DEFAULT_REUSE_TOLERANCE, pulses_per_block: int = 32,
                 backend: str | None = None):
        if not (np.isfinite(reuse_tolerance) and reuse_tolerance >= 0):
            raise ValueError(f"reuse_tolerance must be a finite angle >= 0 (rad), got {reuse_tolerance}")
        if int(pulses_per_block) < 1:
            raise ValueError(f"pulses_per_block must be >= 1, got {pulses_per_block}")
        self.scenario, self.stop_and_go, self.hull_occlusion = scenario, stop_and_go, hull_occlusion
        self.reuse_tolerance, self.pulses_per_block = float(reuse_tolerance), int(pulses_per_block)
        self.parts = []  # (first scatterer index, count, target or None, caster, facets or None)
        floor = scenario.seafloor
        world = _world(scenario, method) if floor is not None and hull_occlusion else None
        moving = []
        start = 0
        for target in scenario.targets:
            mesh = isinstance(target, MeshTarget)
            n = target.n_facets if mesh else target.scatterers().count
            caster = None
            if mesh and hull_occlusion:
                if world is not None and not np.any(target.velocity):
                    caster = WorldView([c for c in world[:2] if c is not None], target.rotation, target.position)
                else:
                    caster = RayCaster(target.mesh, method)
                    moving.append((target, caster))
            self.parts.append((start, n, target if mesh else None, caster, _Facets(target) if mesh else None))
            start += n
        self.seafloor = None
        if floor is not None:
            self.seafloor = SeafloorPaths(scenario, None if world is None else world[:2], moving if hull_occlusion else (),
                                          None if world is None else world[2], backend)
            self.seafloor_first = start
            start += self.seafloor.count
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
            if self.seafloor is not None:
                self.seafloor.fill(eta, out[:, s:s + eta.size, self.seafloor_first:])

        with ThreadPoolExecutor(max_workers=THREADS) as pool:
            list(pool.map(fill, range(0, eta_all.size, step)))
        return out


def has_meshes(scenario) -> bool:
    return any(isinstance(t, MeshTarget) for t in scenario.targets)


def needs_path_weights(scenario) -> bool:
    """The scenario has paths weighted by :class:`PathWeights` (mesh targets or a seafloor)."""
    return has_meshes(scenario) or scenario.seafloor is not None


def scene_scatterers(scenario) -> Scatterers:
    """Every scatterer the echo synthesis sums, in :class:`PathWeights`' order: the targets', then
    the seafloor's facets (:func:`clsas.scene.seafloor.generate`, drawn where the beam reaches)."""
    from ...scene.seafloor import generate

    parts = [scatterers_of(scenario.targets)]
    if scenario.seafloor is not None:
        parts.append(generate(scenario.seafloor, scenario).scatterers())
    return Scatterers.concatenate(parts)


def relief_spacing(scenario) -> float:
    """The grid spacing of the seafloor's mesh, m: the facet spacing, or finer where the relief
    asks (an eighth of the ripples' wavelength, half the height map's spacing)."""
    floor = scenario.seafloor
    spacing = facet_spacing(floor, scenario)
    if floor.ripple_height > 0:
        spacing = min(spacing, floor.ripple_wavelength / 8)
    if floor.heights is not None and not callable(floor.heights):
        spacing = min(spacing, floor.spacing / 2)
    return spacing


def _world(scenario, method: str) -> tuple:
    """The world-frame scenes of a scenario with a seafloor: (the seafloor's mesh, the stationary
    mesh targets or None, the seafloor mesh's grid spacing). Two scenes, so that a ray that only
    the relief can block is traced over the relief alone, and ends where it climbs above it."""
    import trimesh

    spacing = relief_spacing(scenario)
    hulls = []
    for target in scenario.targets:
        if isinstance(target, MeshTarget) and not np.any(target.velocity):
            hull = target.mesh.copy()
            hull.apply_transform(np.block([[target.rotation, target.position[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
            hulls.append(hull)
    objects = RayCaster(trimesh.util.concatenate(hulls), method) if hulls else None
    return RayCaster(scenario.seafloor.mesh(spacing), method), objects, spacing
