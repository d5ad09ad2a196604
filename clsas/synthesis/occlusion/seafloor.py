"""The seafloor's path weights: the sediment's backscattering law at each path's grazing angle,
shadows cast by mesh targets and by the relief, and the beam's reach.

For pulse p, facet n (position q, upward unit normal nu, stationary) and receiver h:

    w = sqrt(sigma(theta, f0)) x lit x heard,   sin(theta) = nu . b / |b|,   b = u_tx + u_rx,

with u_tx, u_rx the unit vectors from the facet to the transmitter at emission and to the
receiver at reception, sigma the sediment's law (:meth:`clsas.Sediment.backscatter_cross_section`,
evaluated at the carrier f0 for every path: the monostatic law at the bistatic bisector's
grazing angle, the usual approximation for a compact array), so that a facet of reflectivity
sqrt(A) exp(i phi) returns the mean power sigma A. w = 0 where the facet faces away from the
transmitter, the receiver or the bisector, and for facets out of the beam's reach at that pulse
(:meth:`clsas.scene.seafloor.Facets.in_reach`: consistent with where they were drawn).

Shadows: a leg (facet -> transmitter, facet -> receiver) is dark when the segment from the
facet (raised 1 mm plus the relief mesh's sag along its normal) to the station hits a mesh
target or the seafloor's own relief (one Embree scene: the seafloor mesh and every stationary
mesh target in the world frame; a moving target is cast in its body frame at the time the wave
passes it). Only legs that can be blocked are cast: those passing within a target's bounding
sphere, and, for relief, those leaving the floor at an elevation below the floor's largest
slope (a ray that climbs faster than any slope of the floor cannot meet it again; a plane
never shadows itself). The receiver's position at reception is R(eta) + w (t1 + t2), with w the
secant velocity over the pulse's longest echo (exact for uniform motion; motion errors move it
by millimetres, which place a shadow edge and a grazing angle, not a phase).
"""

from __future__ import annotations

import numpy as np

from ... import geometry
from ...scene.seafloor import generate
from ...scene.targets import MeshTarget
from .rays import RayCaster

LAW_TABLE = 4097  # samples of sqrt(sigma) over sin(theta) in [0, 1]
RAY_LIFT = 1e-3  # m: the facet's ray origin above the floor, plus the relief mesh's sag


def _segment_near(q: np.ndarray, d: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    """bool (n,): the segments q + t d, t in [0, 1] ((3, n) components first) pass within
    ``radius`` of ``centre`` (3,)."""
    cq = centre[:, None] - q
    dd = np.einsum("in,in->n", d, d)
    t = np.clip(np.einsum("in,in->n", cq, d) / dd, 0.0, 1.0)
    gap = cq - t * d
    return np.einsum("in,in->n", gap, gap) < radius * radius


class SeafloorPaths:
    """Path weights of a scenario's seafloor facets (module docstring).

    ``world`` is the pair of RayCasters (the seafloor's mesh, the stationary mesh targets or
    None; world frame), or None for no shadows; ``moving`` the (target, body-frame caster) pairs of moving
    mesh targets; ``backend`` computes the unshadowed weights and the flags of the paths a
    shadow may darken (kernels/seafloor.cl, or its NumPy twin); the flagged paths' rays are cast
    on the host either way.
    """

    def __init__(self, scenario, world: tuple | None, moving=(), relief_spacing: float | None = None,
                 backend: str | None = None):
        from ... import backend as _backend

        floor = scenario.seafloor
        self.scenario, self.world, self.moving = scenario, world, list(moving)
        self.backend = _backend.resolve(backend)
        self.shadows = world is not None or bool(self.moving)
        self.facets = generate(floor, scenario)
        self.count = self.facets.count
        sag = 0.0
        if floor.ripple_height > 0 and relief_spacing is not None:  # chord sag of the ripples' triangulation
            k = 2 * np.pi / floor.ripple_wavelength
            sag = 0.5 * floor.ripple_height * k * k * relief_spacing**2 / 4
        self.lift = RAY_LIFT + sag
        self.start_t = np.ascontiguousarray((self.facets.positions + self.lift * self.facets.normals).T)
        self.normal_t = np.ascontiguousarray(self.facets.normals.T.astype(np.float64))
        self.slope = floor.max_slope() * 1.01 if floor.has_relief and self.shadows else None
        theta = np.arcsin(np.linspace(0.0, 1.0, LAW_TABLE))
        sigma = floor.sediment.backscatter_cross_section(theta, scenario.waveform.f0, floor.law,
                                                         scenario.medium.sound_speed)
        self.law = np.sqrt(sigma)
        self.across = self.facets.across(scenario.tx_position(scenario.eta))  # no facet is farther across
        self.origin = self.facets.positions.mean(axis=0) if self.count else np.zeros(3)
        self.rays_cast = 0
        self._device = None

    # -- geometry shared by both backends ------------------------------------------------------

    def _stations(self, eta: np.ndarray) -> np.ndarray:
        """(P, 1 + 2H, 3): the transmitter at emission, then each receiver at emission and its
        velocity (the secant over the pulse's longest echo, 2.5 x the farthest facet's delay)."""
        sc = self.scenario
        c = sc.medium.sound_speed
        span = 2.5 * (self.across + np.ptp(self.facets.positions[:, 1]) if self.count else 0.0) / c + 1e-6
        out = np.empty((eta.size, 1 + 2 * sc.n_receivers, 3))
        out[:, 0] = sc.tx_position(eta)
        for h in range(sc.n_receivers):
            r0 = sc.receiver_position(h, eta)
            out[:, 1 + 2 * h] = r0
            out[:, 2 + 2 * h] = (sc.receiver_position(h, eta + span) - r0) / span
        return out

    def _spheres(self, eta: np.ndarray) -> np.ndarray:
        """(P, S, 4): the mesh targets' bounding spheres (centre, radius + 1 % + 1 cm) when the
        wave passes them; S = 0 without shadows."""
        targets = [t for t in self.scenario.targets if isinstance(t, MeshTarget)] if self.shadows else []
        out = np.empty((eta.size, len(targets), 4))
        c = self.scenario.medium.sound_speed
        tx = self.scenario.tx_position(eta)
        for k, target in enumerate(targets):
            at = target.position + target.velocity * eta[:, None]
            t = eta + np.linalg.norm(at - tx, axis=1) / c
            out[:, k, :3] = target.position + target.velocity * t[:, None]
            out[:, k, 3] = float(np.max(np.linalg.norm(target.mesh.vertices, axis=1))) * 1.01 + 0.01
        return out

    # -- unshadowed weights and flags: NumPy twin and OpenCL ----------------------------------

    def _unshadowed_numpy(self, stations: np.ndarray, spheres: np.ndarray, out: np.ndarray, flags: np.ndarray):
        """Weights (H, P, N) without shadows into ``out`` and the flags (P, N) of the paths a
        shadow may darken, float64 (kernels/seafloor.cl's maths)."""
        c = self.scenario.medium.sound_speed
        n_rx = self.scenario.n_receivers
        slope = -np.inf if self.slope is None else self.slope
        grid = np.float64(LAW_TABLE - 1)
        out[...] = 0.0
        flags[...] = False

        def may_block(q, d, sph):
            return (d[2] < slope * np.hypot(d[0], d[1])) | self._near_targets(q, d, sph)

        for p, st in enumerate(stations):
            tx = st[0]
            first, stop = self.facets.reach_span(tx, self.across)
            idx = first + np.flatnonzero(self.facets.in_reach(tx, first, stop))
            q, normal = self.start_t[:, idx], self.normal_t[:, idx]
            d_tx = tx[:, None] - q
            r1 = np.sqrt(np.einsum("in,in->n", d_tx, d_tx))
            u_tx = d_tx / r1
            lit = np.einsum("in,in->n", normal, u_tx) > 0
            idx, q, normal, u_tx, r1 = idx[lit], q[:, lit], normal[:, lit], u_tx[:, lit], r1[lit]
            flag = may_block(q, d_tx[:, lit], spheres[p])
            for h in range(n_rx):
                w = st[2 + 2 * h][:, None]
                d = st[1 + 2 * h][:, None] + w * (r1 / c) - q
                d += w * geometry.meet_time(d, w, c, axis=0)
                b = u_tx + d / np.sqrt(np.einsum("in,in->n", d, d))
                sin = np.einsum("in,in->n", normal, b) / np.sqrt(np.einsum("in,in->n", b, b))
                heard = (sin > 0) & (np.einsum("in,in->n", normal, d) > 0)
                out[h, p, idx] = np.where(heard, np.interp(np.clip(sin, 0.0, 1.0) * grid, np.arange(LAW_TABLE),
                                                           self.law), 0.0)
                flag |= heard & may_block(q, d, spheres[p])
            flags[p, idx] = flag

    def _unshadowed_opencl(self, stations: np.ndarray, spheres: np.ndarray, out: np.ndarray, flags: np.ndarray):
        """:meth:`_unshadowed_numpy` on the device (kernels/seafloor.cl), float32."""
        import pyopencl as cl

        from ... import opencl

        if self.count == 0:  # nothing drawn (no OpenCL buffer may be empty)
            return
        rt = opencl.runtime()
        mf = cl.mem_flags
        n16 = -(-self.count // 16) * 16
        if self._device is None:  # the facets, structure of arrays, padded with unlit (zero-normal) facets
            soa = np.zeros((6, n16), np.float32)
            soa[:3, :self.count] = (self.facets.positions - self.origin).T
            soa[3:, :self.count] = self.facets.normals.T
            self._device = tuple(cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=np.ascontiguousarray(a))
                                 for a in (*soa, self.law.astype(np.float32)))
        n_p, n_rx = stations.shape[0], self.scenario.n_receivers
        spans = self.facets.reach_spans(stations[:, 0], self.across)
        first = int(spans[:, 0].min()) // 16 * 16  # the facets any of these pulses can reach
        span = -(-(int(spans[:, 1].max()) - first) // 16) * 16
        out[...] = 0.0
        flags[...] = False
        if span <= 0:
            return
        st = np.zeros(stations.shape[:2] + (4,), np.float32)
        st[..., :3] = stations - self.origin
        st[:, 2::2, :3] = stations[:, 2::2]  # velocities are not moved
        sph = np.zeros((n_p, max(1, spheres.shape[1]), 4), np.float32)
        sph[:, :spheres.shape[1], :3] = spheres[..., :3] - self.origin
        sph[:, :spheres.shape[1], 3] = spheres[..., 3]
        weights = np.empty((n_rx, n_p, span), np.float32)
        flag = np.empty((n_p, span), np.uint8)
        w_buf = cl.Buffer(rt.context, mf.WRITE_ONLY, weights.nbytes)
        f_buf = cl.Buffer(rt.context, mf.WRITE_ONLY, flag.nbytes)
        knl = opencl.kernel("seafloor", "seafloor_weights")
        slope = np.float32(-np.inf if self.slope is None else self.slope)
        (size,), (group,) = opencl.work_groups(span // 16)  # fixed work-groups: one compilation
        knl(rt.queue, (size, n_p), (group, 1), *self._device[:6],
            cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=st),
            cl.Buffer(rt.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=sph), self._device[6],
            np.int32(LAW_TABLE), np.float32(min(self.facets.reach, 1e30)), np.float32(self.lift),
            np.float32(self.scenario.medium.sound_speed), slope, np.int32(first), np.int32(span), np.int32(n_rx),
            np.int32(spheres.shape[1]), w_buf, f_buf)
        cl.enqueue_copy(rt.queue, weights, w_buf)
        cl.enqueue_copy(rt.queue, flag, f_buf)
        stop = min(first + span, self.count)
        out[..., first:stop] = weights[..., :stop - first]
        flags[:, first:stop] = flag[:, :stop - first].view(bool)

    # -- shadows --------------------------------------------------------------------------------

    def _clear(self, start: np.ndarray, d: np.ndarray, eta: float, spheres: np.ndarray) -> np.ndarray:
        """bool (n,): the legs from ``start`` along ``d`` ((3, n), to the station) are free of the
        relief and the mesh targets (the targets' scene is cast only for legs passing near them)."""
        o, v = start.T, d.T
        dist = np.sqrt(np.einsum("ij,ij->i", v, v))
        u = v / dist[:, None]
        blocked = np.zeros(o.shape[0], dtype=bool)
        if self.world is not None:
            relief, objects = self.world
            blocked |= relief.occluded(o, u, dist)
            if objects is not None:
                near = ~blocked & self._near_targets(start, d, spheres)
                blocked[near] = objects.occluded(o[near], u[near], dist[near])
        c = self.scenario.medium.sound_speed
        tx = self.scenario.tx_position(np.array([eta]))[0]
        for target, caster in self.moving:
            t = eta + np.linalg.norm(target.position + target.velocity * eta - tx) / c
            blocked |= caster.occluded(target.to_body(o, t), u @ target.rotation, dist)
        self.rays_cast += o.shape[0]
        return ~blocked

    def _near_targets(self, q: np.ndarray, d: np.ndarray, spheres: np.ndarray) -> np.ndarray:
        near = np.zeros(d.shape[1], dtype=bool)
        for centre in spheres:
            near |= _segment_near(q, d, centre[:3], centre[3])
        return near

    def _shade(self, eta: float, station: np.ndarray, spheres: np.ndarray, idx: np.ndarray, out: np.ndarray) -> None:
        """Zero the weights ``out`` (H, N) of the flagged facets ``idx`` whose legs are blocked."""
        c = self.scenario.medium.sound_speed
        q = self.start_t[:, idx]
        d_tx = station[0][:, None] - q
        lit = self._clear(q, d_tx, eta, spheres)
        out[:, idx[~lit]] = 0.0
        idx, q, r1 = idx[lit], q[:, lit], np.sqrt(np.einsum("in,in->n", d_tx[:, lit], d_tx[:, lit]))
        for h in range(self.scenario.n_receivers):
            heard = out[h, idx] > 0
            w = station[2 + 2 * h][:, None]
            d = station[1 + 2 * h][:, None] + w * (r1[heard] / c) - q[:, heard]
            d += w * geometry.meet_time(d, w, c, axis=0)
            out[h, idx[heard][~self._clear(q[:, heard], d, eta, spheres)]] = 0.0

    def fill(self, eta: np.ndarray, out: np.ndarray) -> None:
        """The weights (H, P, N) of the facets' paths for the pulses ``eta`` (P,), into ``out``."""
        if self.count == 0:
            return
        stations, spheres = self._stations(eta), self._spheres(eta)
        flags = np.zeros((eta.size, self.count), dtype=bool)
        if self.backend == "opencl":
            self._unshadowed_opencl(stations, spheres, out, flags)
        else:
            self._unshadowed_numpy(stations, spheres, out, flags)
        if not self.shadows:
            return
        for p in range(eta.size):
            idx = np.flatnonzero(flags[p])
            if idx.size:
                self._shade(float(eta[p]), stations[p], spheres[p], idx, out[:, p])
