"""Phase gradient autofocus (clsas.estimate.autofocus.pga) on a back-projected image with a
known azimuth phase error injected in its azimuth spectrum."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

import clsas
from clsas import metrics
from clsas.errors import EstimationError
from clsas.estimate.autofocus import apply_phase_correction, contrast, pga
from clsas.scene import presets

CENTRE = (0.0, 100.0)  # (y, x) of Heremans 2009's centre point, m


@pytest.fixture(scope="module")
def focused():
    """Heremans 2009's nine points, back-projected on a plane (azimuth spacing d/4); the pixel
    spacing along track d/4 and the azimuth extent keep the three points of a range bin apart."""
    scene = presets.point_scene("heremans2009", n_pulses=96)
    scene = scene.replace(waveform=dataclasses.replace(scene.waveform, fs=2 * scene.waveform.bandwidth))
    compressed = clsas.range_compress(clsas.simulate(scene, progress=False), upsample=4)
    d = scene.array.rx_length[0]
    rres = scene.medium.sound_speed / (2 * scene.waveform.bandwidth)
    grid = clsas.Grid.plane(np.arange(93.0, 107.0, rres / 2), np.arange(-12.0, 12.0, d / 4), 0.0)
    return clsas.backproject(compressed, grid, progress=False), d


def _phase_error(n: int, seed: int) -> np.ndarray:
    """Quadratic (6 rad at the band edges) plus a smooth random error (1 rad RMS, correlation
    n/5), without constant and linear trend (rad, increasing-frequency order)."""
    k = np.linspace(-1, 1, n)
    rng = np.random.default_rng(seed)
    smooth = gaussian_filter1d(rng.normal(0, 1, n), n / 5 / 2.355, mode="wrap")
    phi = 6 * k**2 + smooth / smooth.std()
    return phi - np.polyval(np.polyfit(np.arange(n), phi, 1), np.arange(n))


@pytest.mark.parametrize("seed", [1, 2])
def test_pga_recovers_an_injected_phase_error(focused, seed):
    image, d = focused
    blurred = image.replace(data=apply_phase_correction(image.data, -_phase_error(image.shape[0], seed), 0))
    result = pga(blurred)
    truth = metrics.analyse_point(image, near=CENTRE, radius=d)["y"]
    before = metrics.analyse_point(blurred, near=CENTRE, radius=d)["y"]
    after = metrics.analyse_point(result.image, near=CENTRE, radius=d)["y"]
    # measured (seeds 1-6): truth PSLR -34.0 dB, ISLR -30.2; blurred PSLR -4.7 / -6.9 (seeds 1, 2);
    # after PGA PSLR -33.22 .. -33.28, ISLR -29.49 .. -29.83: the issue asks for PSLR within 1 dB.
    # With the trend fitted over the occupied band (seeds 1-3): PSLR -33.26, -33.29, -33.16,
    # peaks 0.9, 4.5, 8.0 mm off: the injected error, detrended over the whole band, keeps a
    # linear part over the occupied half, a shift no autofocus can tell from the scene's place
    assert before.pslr_db > truth.pslr_db + 20
    assert abs(after.pslr_db - truth.pslr_db) < 1.0
    assert abs(after.islr_db - truth.islr_db) < 1.0
    assert abs(after.location - truth.location) < 0.1 * d / 2
    assert result.entropy_after < result.entropy_before
    assert result.contrast_after > result.contrast_before
    assert result.iterations >= 1 and result.phase_error.shape == (image.shape[0],)


def test_pga_leaves_a_focused_image_focused(focused):
    image, d = focused
    result = pga(image)
    truth = metrics.analyse_point(image, near=CENTRE, radius=d)["y"]
    after = metrics.analyse_point(result.image, near=CENTRE, radius=d)["y"]
    assert abs(after.pslr_db - truth.pslr_db) < 0.5
    assert result.entropy_after <= result.entropy_before


def test_pga_refuses_an_image_without_a_dominant_scatterer():
    rng = np.random.default_rng(0)
    noise = clsas.Image(rng.normal(size=(256, 64)) + 1j * rng.normal(size=(256, 64)), ("y", "x"),
                        {"y": np.arange(256) * 0.01, "x": np.arange(64) * 0.01})
    with pytest.raises(EstimationError, match="no dominant scatterer"):
        pga(noise)


@pytest.mark.parametrize("changes, message", [
    ({"tolerance": 0.0}, "tolerance"), ({"tolerance": float("nan")}, "tolerance"),
    ({"max_iterations": 0}, "max_iterations"), ({"min_window": 2}, "min_window"),
    ({"axis": "x2"}, "axis"), ({"min_window": 300}, "min_window"),
])
def test_pga_bad_arguments(focused, changes, message):
    image, _ = focused
    with pytest.raises(ValueError, match=message):
        pga(image, **changes)


def test_contrast_and_type_errors():
    with pytest.raises(TypeError, match="Image"):
        pga(np.ones((64, 64)))
    assert contrast(np.ones(10)) == 0.0
