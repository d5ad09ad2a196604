"""Simulating a scenario's seafloor through the public ``occlusion`` argument of clsas.simulate.

Until the echo pipeline sums ``Scenario.seafloor``'s facets itself (it takes its scatterers from
``Scenario.targets``), the tests hand them over explicitly: the facets
(:func:`clsas.synthesis.occlusion.scene_scatterers`' seafloor part) as point targets after the
scenario's own, and their path weights (:class:`clsas.synthesis.occlusion.PathWeights`'
seafloor part) as the occlusion factor (1 for the targets' paths: the pipeline weights mesh
targets itself).
"""

from __future__ import annotations

import numpy as np

import clsas
from clsas.scene.targets import PointTargets
from clsas.synthesis.occlusion import PathWeights


def simulate_with_seafloor(scenario, **options):
    """``clsas.simulate`` of ``scenario`` with its seafloor's facets and their path weights;
    returns (echo, PathWeights)."""
    weights = PathWeights(scenario)
    floor = weights.seafloor
    points = PointTargets(floor.facets.positions, reflectivity=floor.facets.refl)
    flat = scenario.replace(seafloor=None, targets=scenario.targets + (points,))
    first, n_rx = weights.seafloor_first, scenario.n_receivers

    def occlusion(pulses):
        eta = scenario.eta[pulses]
        out = np.ones((n_rx, eta.size, first + floor.count))
        floor.fill(eta, out[:, :, first:])
        return out

    return clsas.simulate(flat, occlusion=occlusion, **options), weights
