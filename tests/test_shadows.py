"""Shadows on the seafloor: an object proud of the floor casts the shadow the geometry gives (in
the image), the relief shadows itself where the geometry says, facets under an object are dark."""

from __future__ import annotations

import numpy as np
import pytest

import clsas
from clsas.scene import hulls
from clsas.scene.scenario import Array, Medium, Platform, PulseSchedule, Scenario, Waveform
from clsas.scene.seafloor import Seafloor
from clsas.scene.targets import MeshTarget
from clsas.synthesis.occlusion import PathWeights

ALTITUDE = 10.0  # m, the sonar above the flat floor
RADIUS = 0.5  # m: a cylinder 1 m high
GROUND = 30.0  # m, ground range of the cylinder's axis


def sonar(n_pulses: int, start_y: float) -> Scenario:
    """One transceiver at z = 0 with a 0.1 m element (beam +-0.15 rad at 100 kHz), 20 kHz band
    (c / 2B = 3.75 cm), stepping D / 2 = 5 cm a pulse."""
    return Scenario(Medium(1500.0), Waveform(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3),
                    Platform(speed=1.0, start=(0.0, start_y, 0.0)),
                    Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=0.1, rx_length=0.1),
                    PulseSchedule(prf=20.0, n_pulses=n_pulses))


def shadow_end(altitude: float, ground: float, radius: float) -> float:
    """Ground range where the seafloor behind a cylinder (axis along track at ``ground``, lying on
    the floor, ``radius``) comes out of its shadow, seen from a track ``altitude`` above the floor.

    In the plane across track (the cylinder is the same in every such plane, so the rays from
    any pulse over its middle graze it alike), the ray from the sonar S = (0, 0) that grazes the
    circle of centre C = (ground, -altitude + radius) on its upper side leaves S at the
    depression beta - alpha, beta = atan((altitude - radius) / ground) the depression of C and
    alpha = asin(radius / |C|); it meets the floor z = -altitude at altitude / tan(beta - alpha).
    The handbook form h R / (H - h) past the object's top (R its ground range, h = 2 radius)
    is the same ray through the cylinder's top instead of its tangent point.
    """
    beta = np.arctan2(altitude - radius, ground)
    alpha = np.arcsin(radius / np.hypot(ground, altitude - radius))
    return altitude / np.tan(beta - alpha)


def test_shadow_end_formula_is_near_the_top_edge_rule():
    exact = shadow_end(ALTITUDE, GROUND, RADIUS)
    top = GROUND + 2 * RADIUS * GROUND / (ALTITUDE - 2 * RADIUS)  # h R / (H - h) behind the top
    assert abs(exact - top) < 0.1  # the tangent point is beside the top by under a few cm here


def test_cylinder_shadow_has_the_length_the_geometry_gives():
    """A 1 m high cylinder 3 m long lying along the track at 30 m ground range, 10 m below the
    sonar: in the back-projected ground image, the floor behind it comes back at the exact
    tangent-ray range within one ground range cell (c / 2B / cos(grazing) = 3.8 cm)."""
    scene = sonar(140, -3.5).replace(
        targets=(MeshTarget(hulls.cylinder(RADIUS, 3.0, 64), position=(GROUND, 0.0, -ALTITUDE + RADIUS),
                            heading=np.pi / 2),),
        seafloor=Seafloor((27.0, 36.0, -2.0, 2.0), -ALTITUDE, sediment="sand", seed=4))
    # the direct paths only: a bottom bounce of the cylinder's echo would land in its shadow
    echo = clsas.simulate(scene, backend="opencl", progress=False, multipath=0)
    weights = PathWeights(scene)
    compressed = clsas.range_compress(echo, upsample=2, window="hamming")  # the highlight's range sidelobes down
    x, y = np.arange(29.0, 35.5, 0.01), np.arange(-1.0, 1.0, 0.01)
    image = clsas.backproject(compressed, clsas.Grid.plane(x=x, y=y, z=-ALTITUDE))
    power = (np.abs(image.data) ** 2).mean(axis=0)  # (x,): averaged over the 2 m along track
    end = shadow_end(ALTITUDE, GROUND, RADIUS)
    floor_level = power[(x > end + 0.3) & (x < end + 1.3)].mean()
    inside = power[(x > GROUND + 1.5) & (x < end - 0.2)]  # behind the cylinder's own echo, before the end
    assert inside.mean() < 0.01 * floor_level and inside.max() < 0.05 * floor_level  # only its sidelobes
    smooth = np.convolve(power, np.ones(3) / 3, mode="same")
    after = np.flatnonzero((x > end - 0.5) & (smooth > 0.5 * floor_level))[0]  # the half-power crossing
    cell = 1500 / (2 * 20e3) / np.cos(np.arctan(ALTITUDE / end))
    assert abs(x[after] - end) < cell, (x[after], end)
    # the weights agree: facets beyond the end are lit and heard, those before (behind the cylinder) are not
    f = weights.seafloor.facets.positions
    w = weights(slice(70, 71))[0, 0, weights.seafloor_first:]
    mid = np.abs(f[:, 1]) < 0.5
    assert np.all(w[mid & (f[:, 0] > GROUND + RADIUS) & (f[:, 0] < end - 0.05)] == 0)
    assert np.all(w[mid & (f[:, 0] > end + 0.05)] > 0)


def ripple_shadowed(x: np.ndarray, height: float, wavelength: float, altitude: float, z0: float) -> np.ndarray:
    """Whether the floor z0 + h/2 sin(2 pi x / L) at x (ripples along x, crests along y) is hidden
    from a sonar at x = 0, z = 0 by the ripples between: the ray to the sonar passes below the
    floor somewhere (sampled every L / 2000 over the ripples' reach)."""
    k = 2 * np.pi / wavelength
    surface = lambda s: z0 + 0.5 * height * np.sin(k * s)  # noqa: E731
    out = np.zeros(x.size, dtype=bool)
    for i, xi in enumerate(x):
        zi = surface(xi)
        rise = -zi / xi  # the ray's climb per metre towards the sonar
        s = xi - np.arange(1, int(height / rise / (wavelength / 2000)) + 2) * (wavelength / 2000)
        out[i] = np.any(surface(s) > zi + rise * (xi - s) + 1e-4)
    return out


def test_ripples_shadow_themselves_where_the_geometry_says():
    """Ripples 8 cm high, 0.5 m long (slopes up to 0.5) seen at grazing angles of 4-10 deg: the
    lit facets are those whose ray climbs clear of the ripples between (a dense 2-D march)."""
    height, wavelength = 0.08, 0.5
    scene = sonar(3, -0.05).replace(seafloor=Seafloor((60.0, 100.0, -0.3, 0.3), -7.0, ripple_wavelength=wavelength,
                                                      ripple_height=height, facet_spacing=0.01, beam_nulls=0))
    weights = PathWeights(scene)
    w = weights(slice(1, 2))[0, 0, weights.seafloor_first:]
    f = weights.seafloor.facets
    near = np.abs(f.positions[:, 1]) < 0.05  # the rays run across the crests, in the plane y ~ 0
    x = f.positions[near, 0]
    to_sonar = -f.positions[near][:, [0, 2]]  # (x, z) from the facet to the sonar at x = z = 0
    facing = np.einsum("ij,ij->i", f.normals[near][:, [0, 2]], to_sonar) > 0
    expected = ~ripple_shadowed(x, height, wavelength, 7.0, -7.0) & facing
    lit = w[near] > 0
    # the two differ only within the relief mesh's resolution of a shadow's edge (L / 8 spacing)
    disagree = lit != expected
    assert disagree.mean() < 0.03, disagree.mean()  # measured 0.0035
    assert 0.2 < (~expected).mean() < 0.8  # the test sees both lit and shadowed facets


def test_facets_under_an_object_are_dark():
    box = MeshTarget(hulls.box((2.0, 2.0, 1.0)), position=(20.0, 0.0, -ALTITUDE + 0.4))  # 0.1 m sunk in the floor
    scene = sonar(3, -0.05).replace(targets=(box,), seafloor=Seafloor((17.0, 23.0, -2.0, 2.0), -ALTITUDE,
                                                                       facet_spacing=0.05, beam_nulls=0))
    weights = PathWeights(scene)
    w = weights(slice(1, 2))[0, 0, weights.seafloor_first:]
    p = weights.seafloor.facets.positions
    under = (np.abs(p[:, 0] - 20.0) < 0.95) & (np.abs(p[:, 1]) < 0.95)
    assert under.sum() > 100 and np.all(w[under] == 0)
    in_front = (p[:, 0] < 18.9) & (np.abs(p[:, 1]) < 0.5)
    assert np.all(w[in_front] > 0)


@pytest.mark.parametrize("hull", [True, False])
def test_no_shadows_without_hull_occlusion(hull):
    box = MeshTarget(hulls.box((2.0, 2.0, 2.0)), position=(20.0, 0.0, -ALTITUDE + 1.0))
    scene = sonar(3, -0.05).replace(targets=(box,), seafloor=Seafloor((17.0, 26.0, -1.0, 1.0), -ALTITUDE,
                                                                       facet_spacing=0.1, beam_nulls=0))
    weights = PathWeights(scene, hull_occlusion=hull)
    w = weights(slice(1, 2))[0, 0, weights.seafloor_first:]
    behind = weights.seafloor.facets.positions[:, 0] > 21.5
    assert np.all(w[behind] == 0) if hull else np.all(w[behind] > 0)


def test_weights_kernel_matches_its_numpy_twin(opencl_device):
    """kernels/seafloor.cl against the float64 NumPy twin on rippled sand with a box, four
    receivers and a sonobuoy, moving with sway: the weights agree within float32 (the paths whose
    reach or facing test flips at float32 rounding aside), and so do the shadow flags."""
    from clsas.scene.scenario import Sonobuoy

    base = sonar(6, -0.2)
    scene = base.replace(
        platform=Platform(speed=1.0, start=(0.0, -0.2, 0.0), sway=lambda t: 0.02 * np.sin(t)),
        array=Array(rx_offsets=[[0.0, 0.1 * k, 0.0] for k in range(4)], tx_length=0.1, rx_length=0.1),
        sonobuoys=(Sonobuoy((5.0, 3.0, -2.0), name="buoy"),),
        targets=(MeshTarget(hulls.box((1.0, 1.0, 1.0)), position=(20.0, 0.0, -ALTITUDE + 0.4)),),
        seafloor=Seafloor((15.0, 25.0, -1.5, 1.5), -ALTITUDE, ripple_wavelength=0.6, ripple_height=0.05,
                          ripple_direction=0.5, facet_spacing=0.03))
    eta = scene.eta[1:5]
    results = {}
    for backend in ("numpy", "opencl"):
        paths = PathWeights(scene, backend=backend).seafloor
        stations, spheres = paths._stations(eta), paths._spheres(eta)
        out = np.zeros((scene.n_receivers, eta.size, paths.count))
        flags = np.zeros((eta.size, paths.count), dtype=bool)
        getattr(paths, f"_unshadowed_{backend}")(stations, spheres, out, flags)
        results[backend] = out, flags
    (w64, f64), (w32, f32) = results["numpy"], results["opencl"]
    both = (w64 > 0) & (w32 > 0)
    assert both.mean() > 0.3 and ((w64 > 0) != (w32 > 0)).mean() < 1e-4
    assert np.max(np.abs(w32[both] - w64[both]) / w64[both]) < 1e-5  # measured 9e-7
    assert f64.any() and (f64 != f32).mean() < 1e-4
