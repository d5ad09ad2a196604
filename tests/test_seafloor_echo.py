"""The seafloor's echo: its mean level against the sediment's law over grazing angles 10-60 deg."""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas.scene.scenario import Array, Medium, Platform, PulseSchedule, Scenario, Waveform
from clsas.scene.seafloor import Seafloor
from clsas.scene.targets import PointTargets

ALTITUDE = 10.0
HALF_WIDTH = 2.0  # m: the seafloor strip |y| <= 2 m


def transceiver() -> Scenario:
    """One omnidirectional transceiver at z = 0, one pulse (100 kHz, 20 kHz band)."""
    return Scenario(Medium(1500.0), Waveform(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3), Platform(speed=1.0),
                    Array(rx_offsets=[[0.0, 0.0, 0.0]]), PulseSchedule(prf=1.0, n_pulses=1))


def pulse_energy(scene: Scenario) -> float:
    """The compressed point response's energy, sum |s|^2 / fs, of a unit scatterer (s^2)."""
    echo = clsas.simulate(scene.replace(targets=(PointTargets([20.0, 0.0, -ALTITUDE]),)), backend="numpy",
                          progress=False)
    s = clsas.range_compress(echo).data[0, 0]
    return float(np.sum(np.abs(s) ** 2) / echo.fs)


@pytest.mark.parametrize("sediment,law", [("sand", "apl"), pytest.param("mud", "lambert", marks=pytest.mark.slow)])
def test_mean_level_follows_the_law_over_10_to_60_degrees(sediment, law):
    """E|s(tau)|^2 of the compressed echo of a flat strip of seafloor, one pulse, omnidirectional:

        E|s|^2 = sigma(theta(r)) r dphi(r) (c / 2) E_p

    (the ground area between slant ranges r and r + dr is r dphi dr, with dphi = 2 asin(Y / rho)
    the angle the strip |y| <= Y spans at ground range rho; the compressed pulse of energy E_p
    sweeps dr = c dtau / 2). Measured over four seeds in 5-degree bins of grazing angle: within
    1 dB of the law (the issue's bound; the speckle of four seeds leaves up to 0.55 dB)."""
    scene = transceiver()
    c = scene.medium.sound_speed
    energy = pulse_energy(scene)
    ground = (ALTITUDE / np.tan(np.deg2rad(62.0)), ALTITUDE / np.tan(np.deg2rad(8.0)))
    power, tau = 0.0, None
    seeds = range(4)
    for seed in seeds:
        floor = Seafloor((ground[0], ground[1], -HALF_WIDTH, HALF_WIDTH), -ALTITUDE, sediment=sediment, law=law,
                         facet_spacing=0.02, seed=seed)
        echo = clsas.simulate(scene.replace(seafloor=floor), backend="opencl", progress=False, spreading=False,
                              absorption=False, multipath=0)  # the law alone: no loss, no bounce
        compressed = clsas.range_compress(echo)
        power = power + np.abs(compressed.data[0, 0].astype(np.complex128)) ** 2 / len(seeds)
        tau = compressed.fast_time(0)
    r = c * tau / 2
    rho = np.sqrt(np.maximum(r * r - ALTITUDE**2, 1e-9))
    theta = np.arcsin(np.clip(ALTITUDE / r, 0, 1))
    sigma = floor.sediment.backscatter_cross_section(theta, scene.waveform.f0, law)
    expected = sigma * r * 2 * np.arcsin(np.minimum(1.0, HALF_WIDTH / rho)) * (c / 2) * energy
    for low in range(10, 60, 5):
        band = (np.rad2deg(theta) >= low) & (np.rad2deg(theta) < low + 5)
        error_db = 10 * np.log10(power[band].sum() / expected[band].sum())
        assert abs(error_db) < 1.0, (low, error_db)
