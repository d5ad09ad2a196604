"""What a pulse block of a synthesis hears, for both backends: the seafloor facets its beam
reaches and the path weights (occlusion)."""

from __future__ import annotations

import numpy as np

from ...scene.scenario import Scenario
from ...scene.seafloor import generate
from ...scene.targets import Scatterers
from .physics import Physics


class BlockSynth:
    """What both backends provide: the delays of a pulse block (pass A, which also gives the
    recording window) and its records (pass B)."""

    def __init__(self, scenario: Scenario, scat: Scatterers, occlusion, physics: Physics):
        self.args = (scenario, scat, occlusion, physics)
        self.scenario, self.scat, self.occlusion, self.physics = scenario, scat, occlusion, physics
        self.eta = scenario.eta
        self.n_rx = scenario.n_receivers
        wf = scenario.waveform
        self.alpha = 0.5 * wf.chirp_rate / wf.fs**2
        self.half_len = 0.5 * wf.duration * wf.fs
        self.floor_first = scat.count if physics.floor_first is None else physics.floor_first
        self.facets = None if physics.floor_first is None else generate(scenario.seafloor, scenario)
        self.across = 0.0 if self.facets is None else self.facets.across(scenario.tx_position(scenario.eta))

    def reach(self, pulses: slice, cull: bool = True):
        """int64 (P, 2): per pulse of the block, the seafloor facets [first, stop) (indices among
        the facets) that its beam can reach (:meth:`clsas.scene.seafloor.Facets.reach_span`; every
        facet unless ``cull``); None without a seafloor. The facets outside carry no echo at that
        pulse (their path weights are 0): both backends leave them out of the recording window
        (exactly those in reach count there: :meth:`heard`)."""
        if self.facets is None:
            return None
        eta = self.eta[pulses]
        if not cull:
            return np.tile(np.array([0, self.facets.count], np.int64), (eta.size, 1))
        return self.facets.reach_spans(self.scenario.tx_position(eta), self.across)

    def beam(self, pulses: slice, cull: bool = True) -> np.ndarray:
        """float64 (P, 4): per pulse of the block, the transmitter's position (m) and tan(psi) of
        its beam's reach (:meth:`clsas.scene.seafloor.Facets.in_reach`), or -1 where every facet
        counts (not ``cull``, no seafloor, an omnidirectional transmitter)."""
        eta = self.eta[pulses]
        out = np.full((eta.size, 4), -1.0)
        out[:, :3] = self.scenario.tx_position(eta)
        if cull and self.facets is not None and np.isfinite(self.facets.reach):
            out[:, 3] = self.facets.reach
        return out

    def heard(self, pulses: slice) -> np.ndarray:
        """bool (P, N): the scatterers that can carry an echo at each pulse of the block: every
        target, and the facets in the beam's reach then (:meth:`Facets.in_reach`, searched within
        :meth:`reach`). Exactly these, not the whole bands :meth:`reach` gives, so that the
        recording window does not depend on which facets a pulse block drew (a block of a
        distributed run draws those its own pulses can reach)."""
        n_p = len(range(*pulses.indices(self.eta.size)))
        out = np.ones((n_p, self.scat.count), dtype=bool)
        spans = self.reach(pulses)
        if spans is not None:
            out[:, self.floor_first:] = False
            for p, ((a, b), tx) in enumerate(zip(spans, self.beam(pulses)[:, :3])):
                out[p, self.floor_first + a:self.floor_first + b] = self.facets.in_reach(tx, a, b)
        return out

    def weights(self, pulses: slice):
        """The path weights of a pulse block: (H, P, N), or (1, P, N) shared by the receivers."""
        if self.occlusion is None:
            return None
        if callable(self.occlusion):
            w = np.asarray(self.occlusion(pulses), dtype=np.float64)
        else:
            w = self.occlusion[:, pulses]
        n_p = len(range(*pulses.indices(self.eta.size)))
        shapes = ((self.n_rx, n_p, self.scat.count), (1, n_p, self.scat.count))
        if w.shape not in shapes or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError(f"occlusion for pulses {pulses} must be finite, >= 0, with shape {shapes[0]} (or "
                             f"{shapes[1]}: shared by the receivers), got {w.shape}")
        return w

