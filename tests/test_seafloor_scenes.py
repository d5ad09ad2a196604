"""The seafloor presets: the mine-like scene (a cylinder and a truncated cone on rippled sand),
imaged by back-projection and omega-k; the Heremans DPCA scene on a seafloor."""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas.scene import presets


def test_mine_scene_objects_lie_on_the_rippled_sand():
    scene = presets.mine_scene(n_pulses=4)
    floor = scene.seafloor
    assert floor.ripple_height == 0.04 and floor.sediment.name == "sand"
    for target in scene.targets:
        lowest = (target.mesh.vertices @ target.rotation.T + target.position)[:, 2].min()
        assert lowest == pytest.approx(floor.z, abs=1e-9)  # resting on the mean plane
        refl = np.abs(target.scatterers().refl) ** 2
        assert refl.sum() / target.mesh.area == pytest.approx(10 ** -0.5, rel=0.05)  # sigma A, -5 dB
    with pytest.raises(ValueError, match="mine_scene altitude"):
        presets.mine_scene(altitude=0.0)


@pytest.mark.slow
def test_mine_scene_images_show_highlights_and_shadows():
    """Back-projection on the seafloor plane: each object's highlight stands 10 dB above the sand,
    and the far part of its shadow (its near part holds the object's own range sidelobes: the
    highlight is ~35 dB over the sand) is 10 dB below the sand; omega-k of the same record puts
    the cylinder's highlight at its slant range."""
    scene = presets.mine_scene()
    echo = clsas.simulate(scene, progress=False, multipath=0)  # direct paths: bounces would land in the shadows
    compressed = clsas.range_compress(echo, window="hamming", upsample=2)
    x, y = np.arange(21.0, 33.0, 0.02), np.arange(-5.0, 5.0, 0.02)
    grid = clsas.Grid.plane(x=x, y=y, z=scene.seafloor.z)
    power = np.abs(clsas.backproject(compressed, grid, aperture=0.15, progress=False).data) ** 2  # over the beam

    def mean(x0, x1, y0, y1):
        return power[np.ix_((y >= y0) & (y < y1), (x >= x0) & (x < x1))].mean()

    sand = mean(21.5, 23.5, -5.0, 5.0)
    assert mean(24.6, 25.4, -3.0, -2.0) > 10 * sand  # the cylinder
    assert mean(28.5, 29.5, 1.7, 2.3) > 10 * sand  # the cone
    assert mean(26.2, 26.9, -2.8, -2.2) < 0.1 * sand  # the cylinder's shadow: 25.3 to 27.0 m at y = -2.5
    assert mean(30.6, 31.1, 1.85, 2.15) < 0.1 * sand  # the cone's: 29.5 to 31.3 m at y = 2
    slant = clsas.omega_k(clsas.line_record(clsas.range_compress(echo, window="hamming")))
    rows = np.abs(slant.axes["y"] + 2.5) < 0.8
    profile = (np.abs(slant.data[rows]) ** 2).sum(axis=0)
    expected = np.hypot(25.0, scene.seafloor.z + 0.3)  # the cylinder's near side
    near = np.abs(slant.axes["x"] - expected) < 1.0
    assert profile[near].max() > 10 * np.median(profile[(slant.axes["x"] > 21.0) & (slant.axes["x"] < 23.0)])
