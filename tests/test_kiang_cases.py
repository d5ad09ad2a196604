"""Kiang & Kiang 2022: the moving submarine of a Table II case (the Albacore scaled down six times),
simulated with hull occlusion and focused by back-projection with its velocity."""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas import metrics
from clsas.model import Grid
from clsas.scene import presets


@pytest.mark.parametrize("case", [1, 8])
def test_submarine_case_focuses_on_its_hull(opencl_device, case):
    sc = presets.kiang2022_case(case, n_pulses=512, sections=32, stations=40)
    hull = sc.targets[0]
    echo = clsas.range_compress(clsas.simulate(sc, backend="opencl", progress=False), upsample=4)
    assert echo.provenance["hull_occlusion"]
    grid = Grid.plane(np.arange(1989.0 - 40, 1989.0 + 40, 0.5), np.arange(-40.0, 40.0, 0.5), -350.0)
    focused = clsas.backproject(echo, grid, backend="opencl", receivers=["A"], target_velocity=hull.velocity,
                                upsample=1, progress=False)
    energy = np.abs(focused.data) ** 2
    # the energy sits on the hull's footprint: within its half-length of the centre
    yy, xx = np.meshgrid(grid.axes["y"], grid.axes["x"], indexing="ij")
    on_hull = np.hypot(xx - 1989.0, yy) < 34.0
    assert energy[on_hull].sum() > 0.9 * energy.sum()
    # on a patch sampled finer than the resolution, focusing with the right velocity concentrates
    # the energy: lower entropy and a higher peak than assuming a stationary target
    patch = Grid.plane(np.arange(1980.0, 1990.0, 0.05), np.arange(-5.0, 5.0, 0.05), -350.0 + 0.7)  # the hull top
    kw = dict(backend="opencl", receivers=["A"], upsample=1, progress=False)
    sharp = clsas.backproject(echo, patch, target_velocity=hull.velocity, **kw)
    smeared = clsas.backproject(echo, patch, **kw)
    assert metrics.entropy(sharp) < metrics.entropy(smeared) - 0.5
    assert np.abs(sharp.data).max() > 1.5 * np.abs(smeared.data).max()
