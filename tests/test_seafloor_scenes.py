"""The seafloor presets: the mine-like scene (a cylinder and a truncated cone on rippled sand),
imaged by back-projection and omega-k; the Heremans DPCA scene on a seafloor."""

from __future__ import annotations

import dataclasses

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


X_AXIS, Y_AXIS = np.arange(21.0, 33.0, 0.02), np.arange(-5.0, 5.0, 0.02)  # m, the image's pixels

# Boxes (x0, x1, y0, y1), m. The shadows from the geometry: the cylinder's axis crosses y at
# x = 25 - (y + 2.5) tan 20 deg, its section there an ellipse 0.282 m across and 0.265 m high
# above the plane 8 m below the sonar; the ray from the sonar grazing its far top meets the
# plane at 26.70 m (y = -2.2) to 26.93 m (y = -2.8), and its far base edge lies at 25.17-25.39 m.
# The cone's top edge (29.25 m, 0.45 m high) casts to 31.0 m.
SAND = (21.5, 23.5, -5.0, 5.0)  # near-range sand, brighter than at the shadows' ranges
CYLINDER, CONE = (24.6, 25.4, -3.0, -2.0), (28.5, 29.5, 1.7, 2.3)
CYLINDER_SHADOW = (26.1, 26.6, -2.8, -2.2)  # its far part: the objects' own echo fills 25.2-26.0 m
CYLINDER_BESIDE, CYLINDER_BEYOND = (26.1, 26.6, -5.0, -4.0), (26.95, 27.5, -2.8, -2.2)
CONE_SHADOW, CONE_BESIDE, CONE_BEYOND = (30.3, 30.9, 1.85, 2.15), (30.3, 30.9, 3.5, 5.0), (31.1, 31.6, 1.85, 2.15)


@pytest.fixture(scope="module")
def mine_echo():
    scene = presets.mine_scene()
    return scene, clsas.simulate(scene, progress=False, multipath=0)  # direct paths: bounces land in the shadows


def _power(scene, echo):
    """Back-projected power on the seafloor's plane, over the beam (aperture 0.15 rad)."""
    compressed = clsas.range_compress(echo, window="hamming", upsample=2)
    grid = clsas.Grid.plane(x=X_AXIS, y=Y_AXIS, z=scene.seafloor.z)
    return np.abs(clsas.backproject(compressed, grid, aperture=0.15, progress=False).data) ** 2


def _mean(power, box):
    x0, x1, y0, y1 = box
    return power[np.ix_((Y_AXIS >= y0) & (Y_AXIS < y1), (X_AXIS >= x0) & (X_AXIS < x1))].mean()


@pytest.mark.slow
def test_mine_scene_images_show_highlights_and_shadows(mine_echo):
    """Back-projection on the seafloor plane: each object's highlight stands 10 dB above the sand,
    and its shadow, where the geometry puts it (the boxes above), is 10 dB below both the near
    sand and the seabed beside it at the same ranges, which is lit again beyond the shadow's end
    (measured: shadows -15.2 and -17.2 dB re the near sand, -12.6 and -11.9 dB re the seabed
    beside them); omega-k of the same record puts the cylinder's highlight at its slant range."""
    scene, echo = mine_echo
    power = _power(scene, echo)
    sand = _mean(power, SAND)
    assert _mean(power, CYLINDER) > 10 * sand
    assert _mean(power, CONE) > 10 * sand
    for shadow, beside, beyond in ((CYLINDER_SHADOW, CYLINDER_BESIDE, CYLINDER_BEYOND),
                                   (CONE_SHADOW, CONE_BESIDE, CONE_BEYOND)):
        level = _mean(power, shadow)
        assert level < 0.1 * sand and level < 0.1 * _mean(power, beside)
        assert _mean(power, beyond) > 0.5 * _mean(power, beside)  # the shadow ends where the geometry says
    slant = clsas.omega_k(clsas.line_record(clsas.range_compress(echo, window="hamming")))
    rows = np.abs(slant.axes["y"] + 2.5) < 0.8
    profile = (np.abs(slant.data[rows]) ** 2).sum(axis=0)
    expected = np.hypot(25.0, scene.seafloor.z + 0.3)  # the cylinder's near side
    near = np.abs(slant.axes["x"] - expected) < 1.0
    assert profile[near].max() > 10 * np.median(profile[(slant.axes["x"] > 21.0) & (slant.axes["x"] < 23.0)])


@pytest.mark.slow
def test_mine_shadow_is_the_seabeds_own(mine_echo):
    """What the cylinder's shadow holds, the echo split in two by linearity: the seabed with the
    objects still casting their shadows but echoing 120 dB less, and the objects alone (the
    difference). Measured: in the shadow box the objects' own echo (range response, layover) is
    -23 dB re the near sand, the seabed's -15.8 dB; in the near part of the shadow (25.3-25.9 m)
    the objects' echo is -5.5 dB and the seabed's -16.5 dB; the seabed from 26.7 m to 26.95 m,
    beyond the grazing ray's end, is lit (the old box 26.2-26.9 m reached into it: -8.8 dB)."""
    scene, echo = mine_echo
    faint = tuple(dataclasses.replace(t, gain=t.gain * 1e-6) for t in scene.targets)
    seabed = clsas.simulate(scene.replace(targets=faint), progress=False, multipath=0)
    objects = echo.replace(data=echo.data - seabed.data)
    floor_power, object_power = _power(scene, seabed), _power(scene, objects)
    sand = _mean(_power(scene, echo), SAND)
    assert _mean(object_power, CYLINDER_SHADOW) < 10 ** -1.8 * sand      # measured -23 dB
    assert _mean(floor_power, CYLINDER_SHADOW) < 10 ** -1.3 * sand       # measured -15.8 dB
    assert _mean(object_power, (25.3, 25.9, -2.8, -2.2)) > 10 ** -1.0 * sand   # measured -5.5 dB: not a shadow there
    assert _mean(floor_power, (26.8, 26.95, -2.8, -2.2)) > 10 ** -0.5 * _mean(floor_power, CYLINDER_BESIDE)
