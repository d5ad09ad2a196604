"""Simulating a scenario's seafloor in the tests: clsas.simulate of the scenario with its facets
handed over explicitly (:func:`clsas.synthesis.occlusion.seafloor_as_targets`: the echo pipeline
takes its scatterers from ``Scenario.targets``)."""

from __future__ import annotations

import clsas
from clsas.synthesis.occlusion import seafloor_as_targets


def simulate_with_seafloor(scenario, **options):
    """``clsas.simulate`` of ``scenario`` with its seafloor; returns (echo, PathWeights)."""
    flat, occlusion = seafloor_as_targets(scenario)
    return clsas.simulate(flat, occlusion=occlusion, **options), occlusion.path_weights
