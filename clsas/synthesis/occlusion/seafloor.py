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

    ``world`` is the RayCaster of the seafloor mesh and the stationary mesh targets (world
    frame), or None for no shadows; ``moving`` the (target, body-frame caster) pairs of moving
    mesh targets.
    """

    def __init__(self, scenario, world: RayCaster | None, moving=(), relief_spacing: float | None = None):
        floor = scenario.seafloor
        self.scenario, self.world, self.moving = scenario, world, list(moving)
        self.facets = generate(floor, scenario)
        self.count = self.facets.count
        sag = 0.0
        if floor.ripple_height > 0 and relief_spacing is not None:  # chord sag of the ripples' triangulation
            k = 2 * np.pi / floor.ripple_wavelength
            sag = 0.5 * floor.ripple_height * k * k * relief_spacing**2 / 4
        lift = RAY_LIFT + sag
        self.start_t = np.ascontiguousarray((self.facets.positions + lift * self.facets.normals).T)
        self.normal_t = np.ascontiguousarray(self.facets.normals.T.astype(np.float64))
        self.slope = floor.max_slope() * 1.01 if floor.has_relief else None
        theta = np.arcsin(np.linspace(0.0, 1.0, LAW_TABLE))
        sigma = floor.sediment.backscatter_cross_section(theta, scenario.waveform.f0, floor.law,
                                                         scenario.medium.sound_speed)
        self.law = np.sqrt(sigma)
        track = scenario.tx_position(scenario.eta)
        p = self.facets.positions
        if self.count:  # no facet is farther across than this from any transmitter position
            dx = max(abs(a - b) for a in (p[:, 0].min(), p[:, 0].max()) for b in (track[:, 0].min(), track[:, 0].max()))
            dz = max(abs(a - b) for a in (p[:, 2].min(), p[:, 2].max()) for b in (track[:, 2].min(), track[:, 2].max()))
            self.across = float(np.hypot(dx, dz)) + 1.0
        else:
            self.across = 0.0
        self.rays_cast = 0

    def _clear(self, start: np.ndarray, d: np.ndarray, eta: float) -> np.ndarray:
        """bool (n,): the legs from ``start`` along ``d`` ((3, n), to the station) are free of the
        relief and the mesh targets (only those that can be blocked are cast)."""
        clear = np.ones(d.shape[1], dtype=bool)
        if self.world is None and not self.moving:
            return clear
        horizontal = np.hypot(d[0], d[1])
        near = np.zeros(d.shape[1], dtype=bool)
        if self.slope is not None:
            near |= d[2] < self.slope * horizontal
        c = self.scenario.medium.sound_speed
        tx = self.scenario.tx_position(np.array([eta]))[0]
        for target in self.scenario.targets:
            if isinstance(target, MeshTarget):
                radius = float(np.max(np.linalg.norm(target.mesh.vertices, axis=1)))
                centre = target.position + target.velocity * (eta + np.linalg.norm(target.position - tx) / c)
                near |= _segment_near(start, d, centre, radius * 1.01 + 0.01)
        idx = np.flatnonzero(near)
        if idx.size == 0:
            return clear
        o, v = start[:, idx].T, d[:, idx].T
        dist = np.sqrt(np.einsum("ij,ij->i", v, v))
        u = v / dist[:, None]
        blocked = np.zeros(idx.size, dtype=bool)
        if self.world is not None:
            blocked |= self.world.occluded(o, u, dist)
        for target, caster in self.moving:
            t = eta + np.linalg.norm(target.position + target.velocity * eta - tx) / c
            rot = target.rotation
            blocked |= caster.occluded(target.to_body(o, t), u @ rot, dist)
        self.rays_cast += idx.size
        clear[idx] = ~blocked
        return clear

    def _receiver_legs(self, eta: float, q: np.ndarray, t1: np.ndarray):
        """Per receiver, the vectors (3, n) from the facets ``q`` (3, n) to the receiver at reception."""
        sc = self.scenario
        c = sc.medium.sound_speed
        span = 2.5 * float(t1.max()) + 1e-6
        for h in range(sc.n_receivers):
            r0, r1 = sc.receiver_position(h, np.array([eta, eta + span]))
            w = ((r1 - r0) / span)[:, None]
            d = r0[:, None] + w * t1 - q
            d += w * geometry.meet_time(d, w, c, axis=0)
            yield h, d

    def fill(self, eta: np.ndarray, out: np.ndarray) -> None:
        """The weights (H, P, N) of the facets' paths for the pulses ``eta`` (P,), into ``out``."""
        sc = self.scenario
        c = sc.medium.sound_speed
        out[...] = 0.0
        tx_all = sc.tx_position(eta)
        grid = np.float64(LAW_TABLE - 1)
        for p, tx in enumerate(tx_all):
            first, stop = self.facets.reach_span(tx, self.across)
            idx = first + np.flatnonzero(self.facets.in_reach(tx, first, stop))
            if idx.size == 0:
                continue
            q, normal = self.start_t[:, idx], self.normal_t[:, idx]
            d_tx = tx[:, None] - q
            r1 = np.sqrt(np.einsum("in,in->n", d_tx, d_tx))
            u_tx = d_tx / r1
            lit = np.einsum("in,in->n", normal, u_tx) > 0
            lit[lit] = self._clear(q[:, lit], d_tx[:, lit], float(eta[p]))
            keep = np.flatnonzero(lit)
            if keep.size == 0:
                continue
            idx, q, normal, u_tx, r1 = idx[keep], q[:, keep], normal[:, keep], u_tx[:, keep], r1[keep]
            for h, d_rx in self._receiver_legs(float(eta[p]), q, r1 / c):
                r2 = np.sqrt(np.einsum("in,in->n", d_rx, d_rx))
                bisector = u_tx + d_rx / r2
                sin = np.einsum("in,in->n", normal, bisector) / np.sqrt(np.einsum("in,in->n", bisector, bisector))
                heard = (sin > 0) & (np.einsum("in,in->n", normal, d_rx) > 0)
                heard[heard] = self._clear(q[:, heard], d_rx[:, heard], float(eta[p]))
                weight = np.interp(np.clip(sin, 0.0, 1.0) * grid, np.arange(LAW_TABLE), self.law)
                out[h, p, idx] = np.where(heard, weight, 0.0)
