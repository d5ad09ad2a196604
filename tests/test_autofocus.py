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


def _small_blurred_image(ny=256, nx=64, axis_step=0.01):
    """A few bright points in weak noise, blurred by a quadratic azimuth phase error."""
    rng = np.random.default_rng(3)
    data = (0.01 * (rng.standard_normal((ny, nx)) + 1j * rng.standard_normal((ny, nx)))).astype(np.complex64)
    data[::64, ::16] += 10.0
    k = np.linspace(-1, 1, ny)
    return clsas.Image(apply_phase_correction(data, -2 * k**2, 0), ("y", "x"),
                       {"y": np.arange(ny) * axis_step, "x": np.arange(nx) * 0.01})


def test_contrast_and_entropy_of_huge_finite_values_are_finite():
    """|x|^2 of 1e200 overflows float64: both measures are of the power relative to the peak."""
    values = np.full(4, 1e200) * np.arange(1, 5)
    assert contrast(values) == pytest.approx(contrast(np.arange(1, 5.0)), rel=1e-12)
    assert metrics.entropy(values) == pytest.approx(metrics.entropy(np.arange(1, 5.0)), rel=1e-12)
    assert contrast(np.full(4, 1e200)) == 0.0
    for bad, error in ((np.zeros(4), ValueError), (np.array([1.0, np.nan]), ValueError), (np.array([]), ValueError),
                       (np.array(["a"]), TypeError)):
        with pytest.raises(error, match="contrast data"):
            contrast(bad)


def test_pga_refuses_a_constant_or_uneven_azimuth_axis():
    image = _small_blurred_image()
    for y in (np.zeros(256), np.arange(256) ** 2 * 0.01):
        with pytest.raises(ValueError, match="pga image: its azimuth axis 'y' must be evenly spaced"):
            pga(image.replace(axes={"y": y, "x": image.axes["x"]}))
    assert pga(image).iterations >= 1  # the same image on an even axis is focused


@pytest.mark.parametrize("args, error, message", [
    ((np.ones((4, 4)), np.zeros(4), 5), ValueError, "apply_phase_correction axis: must be an integer in \\[-2, 1\\]"),
    ((np.ones((4, 4)), np.zeros(4), 1.0), TypeError, "apply_phase_correction axis"),
    ((np.ones((4, 4)), np.zeros(3), 0), ValueError, "apply_phase_correction phi: must have shape \\(4,\\)"),
    ((np.ones((4, 4)), np.full(4, np.nan), 0), ValueError, "apply_phase_correction phi: must be finite"),
    ((np.ones((4, 4)), "a", 0), TypeError, "apply_phase_correction phi"),
    (("abc", np.zeros(4), 0), TypeError, "apply_phase_correction data"),
])
def test_apply_phase_correction_names_bad_arguments(args, error, message):
    with pytest.raises(error, match=message):
        apply_phase_correction(*args)


@pytest.mark.parametrize("changes, error", [
    ({"tolerance": "a"}, TypeError), ({"max_iterations": 2.0}, TypeError), ({"select_db": None}, TypeError),
    ({"workers": "all"}, TypeError), ({"axis": 0}, TypeError), ({"min_contrast": 1.0}, ValueError),
    ({"window_db": -3.0}, ValueError), ({"workers": 10**6}, ValueError),
])
def test_pga_wrong_kinds_and_values_name_the_parameter(changes, error):
    image = _small_blurred_image()
    with pytest.raises(error, match=f"pga {next(iter(changes))}"):
        pga(image, **changes)


def test_pga_checks_the_budget_before_allocating_and_stays_within_it():
    import tracemalloc

    image = _small_blurred_image(512, 256)
    with clsas.use_memory_budget(image.data.size * 8):  # the image alone: PGA needs more
        with pytest.raises(clsas.errors.MemoryBudgetError, match="pga of a 512 x 256 image"):
            pga(image)
    tracemalloc.start()
    try:
        pga(image, max_iterations=3)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    from clsas.estimate.autofocus import PGA_BYTES_PER_PIXEL

    assert peak < PGA_BYTES_PER_PIXEL * image.data.size  # measured ~40 bytes a pixel
