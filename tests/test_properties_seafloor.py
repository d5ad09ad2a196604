"""Property tests (hypothesis) of the seafloor: any valid sediment gives a passive reflection and
finite, non-negative backscatter; any valid seafloor has unit normals and draws its facets
inside its extent; nonsense is refused with TypeError/ValueError naming the field."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_properties import PROPERTY

from clsas.scene import presets
from clsas.scene.seafloor import LAWS, Seafloor, Sediment, generate

finite = dict(allow_nan=False, allow_infinity=False)


@st.composite
def sediments(draw):
    return Sediment(density_ratio=draw(st.floats(0.5, 3.0)), sound_speed_ratio=draw(st.floats(0.8, 3.0)),
                    loss=draw(st.floats(0.0, 0.1)), spectral_exponent=draw(st.floats(2.2, 3.8)),
                    spectral_strength=draw(st.floats(0.0, 0.5)), volume_ratio=draw(st.floats(0.0, 0.01)),
                    lambert_mu_db=draw(st.one_of(st.none(), st.floats(-60.0, -5.0))))


@PROPERTY
@given(sediments(), st.floats(1e3, 1e6), st.sampled_from(LAWS))
def test_reflection_is_passive_and_backscatter_finite(sediment, f, law):
    theta = np.linspace(0.0, np.pi / 2, 181)
    v = sediment.reflection_coefficient(theta, f)
    assert np.all(np.isfinite(v)) and np.all(np.abs(v) <= 1 + 1e-9)
    sigma = sediment.backscatter_cross_section(theta[1:], f, law=law)
    assert np.all(np.isfinite(sigma)) and np.all(sigma >= 0)


@st.composite
def floors(draw):
    x0, y0 = draw(st.floats(5.0, 50.0)), draw(st.floats(-30.0, 0.0))
    extent = (x0, x0 + draw(st.floats(0.5, 5.0)), y0, y0 + draw(st.floats(0.5, 5.0)))
    ripple = draw(st.floats(0.0, 0.1))
    return Seafloor(extent, draw(st.floats(-30.0, -2.0)), slope=(draw(st.floats(-0.3, 0.3)), draw(st.floats(-0.3, 0.3))),
                    ripple_wavelength=draw(st.floats(0.2, 2.0)) if ripple else 0.0, ripple_height=ripple,
                    ripple_direction=draw(st.floats(-3.0, 3.0)), facet_spacing=draw(st.floats(0.05, 0.3)),
                    beam_nulls=draw(st.integers(0, 3)), seed=draw(st.integers(0, 2**40)))


@PROPERTY
@given(floors())
def test_facets_lie_on_the_floor_inside_the_extent(floor):
    facets = generate(floor, presets.heremans2009(n_pulses=4))
    p = facets.positions
    ext = floor.extent
    assert np.all((p[:, 0] >= ext[0]) & (p[:, 0] <= ext[1]) & (p[:, 1] >= ext[2]) & (p[:, 1] <= ext[3]))
    np.testing.assert_allclose(p[:, 2], floor.height(p[:, 0], p[:, 1]))
    np.testing.assert_allclose(np.linalg.norm(facets.normals, axis=1), 1.0, rtol=1e-6)
    assert np.all(facets.normals[:, 2] > 0) and np.all(np.isfinite(facets.refl))


BAD = [np.nan, np.inf, -np.inf, 1e300, -1e300, "1", None, [1.0, 2.0], True]


@pytest.mark.parametrize("field", ["z", "spacing", "ripple_wavelength", "ripple_height", "ripple_direction",
                                   "scatterers_per_cell", "facet_spacing", "beam_nulls", "seed"])
@pytest.mark.parametrize("value", BAD, ids=repr)
def test_seafloor_refuses_nonsense_by_name(field, value):
    if value is None and field == "facet_spacing":
        return  # None is its default
    with pytest.raises((TypeError, ValueError), match=f"Seafloor.{field}"):
        Seafloor(**{"extent": (0.0, 1.0, 0.0, 1.0), "z": -5.0, field: value})


@pytest.mark.parametrize("field", ["density_ratio", "sound_speed_ratio", "loss", "spectral_exponent",
                                   "spectral_strength", "volume_ratio", "lambert_mu_db"])
@pytest.mark.parametrize("value", BAD, ids=repr)
def test_sediment_refuses_nonsense_by_name(field, value):
    if value is None and field == "lambert_mu_db":
        return
    with pytest.raises((TypeError, ValueError), match=f"Sediment.{field}"):
        Sediment(**{field: value})


@pytest.mark.filterwarnings("ignore::clsas.scene.scenario.SamplingWarning")  # sampling is not under test
@PROPERTY
@given(floors(), st.integers(1, 3), st.floats(-0.5, 0.5))
def test_weights_kernel_matches_its_twin_on_random_floors(opencl_device, floor, n_rx, sway):
    """kernels/seafloor.cl against its float64 NumPy twin on random floors and arrays: the weights
    agree to 1e-5 relative (measured below 2e-6) where both are non-zero, and the paths that one
    darkens and the other lights (reach or facing tests at float32 rounding) are under 1e-3."""
    from clsas.scene.scenario import Array, Platform
    from clsas.synthesis.occlusion import PathWeights

    base = presets.heremans2009(n_pulses=4)
    scene = base.replace(array=Array(rx_offsets=[[0.0, 0.2 * k, 0.0] for k in range(n_rx)], tx_length=0.2,
                                     rx_length=0.2),
                         platform=Platform(speed=1.0, sway=lambda t: sway * 0.01 * t), seafloor=floor)
    eta = scene.eta[1:3]
    results = []
    for backend in ("numpy", "opencl"):
        paths = PathWeights(scene, backend=backend).seafloor
        out = np.zeros((scene.n_receivers, eta.size, paths.count))
        flags = np.zeros((eta.size, paths.count), dtype=bool)
        getattr(paths, f"_unshadowed_{backend}")(paths._stations(eta), paths._spheres(eta), out, flags)
        results.append(out)
    w64, w32 = results
    both = (w64 > 0) & (w32 > 0)
    if both.any():
        assert np.max(np.abs(w32[both] - w64[both]) / w64[both]) < 1e-5
    assert np.count_nonzero((w64 > 0) != (w32 > 0)) <= 1e-3 * w64.size
