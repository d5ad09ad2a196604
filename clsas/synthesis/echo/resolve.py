"""What the paths of a synthesis carry, resolved from its options and its scenario: the path kinds,
propagation, compressed response and the route the records take (:class:`.physics.Physics`)."""

from __future__ import annotations


import numpy as np

from ...scene.scenario import Scenario
from ...scene.targets import Scatterers, scatterers_of
from ..propagation import BandAbsorption, boundaries, path_kinds
from .compressed import CompressedResponse
from .grid import ENVELOPE_BOUND, GridPlan, envelope_bound
from .options import AUTO, SynthesisOptions
from .physics import Physics, on_floor

GRID_AUTO_PATHS = 100_000  # paths a record from which accumulation="auto" takes the grid route


def delay_bound(scenario: Scenario, scat: Scatterers, physics: Physics) -> float:
    """An upper bound guess of every delay (s) for the node span, from the first/middle/last
    pulses, over every path kind (image transmitters and receivers): the scatterers' bounding
    box's farthest corner on each leg."""
    eta = scenario.eta[[0, scenario.eta.size // 2, -1]]
    c = scenario.medium.sound_speed
    worst = 0.0
    for p in range(eta.size):
        q = scat.p0 + scat.vel * eta[p]
        corners = np.array(np.meshgrid(*np.stack([q.min(axis=0), q.max(axis=0)], axis=1), indexing="ij")).reshape(3, -1).T
        for kind in physics.kinds:  # the farthest point of the scatterers' box is one of its corners
            tx = kind.out.image.points(scenario.tx_position(eta[p:p + 1]))[0]
            out = np.max(np.linalg.norm(corners - tx, axis=1))
            back = max(np.max(np.linalg.norm(corners - kind.back.image.points(scenario.receiver_position(h, eta[p])),
                                             axis=1)) for h in range(scenario.n_receivers))
            worst = max(worst, out + back)
    return 1.2 * worst / c + scenario.waveform.duration


def resolve_physics(scenario: Scenario, opts: SynthesisOptions, scat: Scatterers, prune: bool = True) -> Physics:
    """What the paths carry for ``scenario`` under ``opts`` (the "auto" options resolved: spreading
    and absorption on, and first-order multipath, in a scene with a seafloor; multipath also with
    a sea surface). ``scat``: every scatterer, the seafloor's facets last. ``prune``: leave out
    the path kinds that are dark for every scatterer (a bounce off the seabed next to a scatterer
    that lies on it, :func:`.physics.on_floor`: a scene of seafloor facets alone)."""
    floor = getattr(scenario, "seafloor", None) is not None
    planes = boundaries(scenario)
    order = (1 if planes else 0) if opts.multipath == AUTO else opts.multipath
    kinds = path_kinds(planes, order)
    floor_first = scatterers_of(scenario.targets).count if floor else None
    if prune and floor and np.all(on_floor(scat, floor_first, kinds)):
        kinds = tuple(kind for kind in kinds if not Physics.touches_floor(kind))
    spreading = floor if opts.spreading == AUTO else opts.spreading
    absorbing = floor if opts.absorption == AUTO else opts.absorption
    absorption = BandAbsorption.of(scenario.medium, scenario.waveform) if absorbing else None
    response = None if opts.compressed is False else \
        CompressedResponse.of(scenario.waveform, opts.compressed, opts.compressed_level_db)
    wf = scenario.waveform
    speed = float(np.max(np.linalg.norm(scat.vel, axis=1), initial=0.0)) + scenario.platform.speed
    mismatch = np.pi * speed / scenario.medium.sound_speed * wf.bandwidth * wf.duration
    return Physics(opts, kinds=kinds, absorption=absorption, spreading=spreading,
                   moving=bool(np.any(scat.vel != 0)), response=response, floor_first=floor_first,
                   doppler_mismatch=float(mismatch))


def grid_plan(scenario: Scenario, opts: SynthesisOptions, scat: Scatterers, physics: Physics) -> GridPlan | None:
    """The grid route's plan (:mod:`.grid`) when ``opts.accumulation`` asks for it, or is "auto" and the
    scene has at least GRID_AUTO_PATHS paths a record; None for the direct route. ValueError when
    "grid" is asked for paths it cannot make: paths with their own chirp (intra-pulse Doppler),
    compressed synthesis by taps, or a band envelope too steep for its second-order series."""
    if opts.accumulation == "direct" or (opts.accumulation == "auto" and scat.count * len(physics.kinds) < GRID_AUTO_PATHS):
        return None
    why = None
    if physics.doppler:
        why = "paths with intra-pulse Doppler have their own chirp (give intra_pulse='none' or stop_and_go=True)"
    elif physics.writes_taps:
        why = "synthesis into the compressed domain writes each path's taps here"
    else:
        wf, c = scenario.waveform, scenario.medium.sound_speed
        longest = c * delay_bound(scenario, scat, physics)
        bound = max(envelope_bound(physics.absorption, kind.out.planes + kind.back.planes, longest, wf, c)
                    for kind in physics.kinds)
        if bound > ENVELOPE_BOUND:
            why = (f"the band envelope (absorption, surface roughness) reaches |b| h + |g| h^2 = {bound:.3g} over "
                   f"the pulse, above {ENVELOPE_BOUND} (its second-order series would be off by ~{bound ** 3 / 6:.1e})")
    if why is not None:
        if opts.accumulation == "grid":
            raise ValueError(f"simulate accumulation: 'grid' cannot make these paths: {why}; use accumulation='direct' or 'auto'")
        return None
    wf = scenario.waveform
    return GridPlan(0.5 * wf.chirp_rate / wf.fs ** 2, 0.5 * wf.duration * wf.fs, 3 if physics.extended else 1)
