"""Input checks with a physical meaning (the per-parameter ranges are drawn in test_properties_validation.py):
overlapping pulses, a grid outside the swath, speeds near the sound speed, non-finite records."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import clsas
from clsas import Grid, Medium, Platform, PulseSchedule, Waveform
from clsas.scene.scenario import Array, SamplingWarning, Scenario
from clsas.scene.targets import PointTargets
from clsas import validate
from clsas.validate import CoverageWarning


def scene(prf: float, ranges=(30.0,)) -> Scenario:
    return Scenario(medium=Medium(1500.0), waveform=Waveform(f0=50e3, bandwidth=10e3, duration=2e-3, fs=20e3),
                    platform=Platform(speed=0.5), array=Array(rx_offsets=[[0.0, 0.0, 0.0]]),
                    schedule=PulseSchedule(prf=prf, n_pulses=6),
                    targets=(PointTargets([[r, 0.0, 0.0] for r in ranges]),))


def test_overlapping_pulses_warn_on_both_backends(opencl_device):
    """Targets at 30 and 60 m: one pulse's echoes span 2 x 30 m / 1500 m/s + 2 ms = 42 ms; at
    50 Hz (20 ms apart) they overlap the next pulse's, at 20 Hz (50 ms) they do not."""
    for backend in ("numpy", "opencl"):
        with pytest.warns(SamplingWarning, match=r"span 42 ms .* pulse interval 20 ms"):
            clsas.simulate(scene(50.0, (30.0, 60.0)), backend=backend, progress=False)
        with warnings.catch_warnings():
            warnings.simplefilter("error", SamplingWarning)
            clsas.simulate(scene(20.0, (30.0, 60.0)), backend=backend, progress=False)


def test_a_long_record_window_alone_does_not_warn():
    """One target whose range migrates over the aperture: the record window spans many pulse
    intervals, but each pulse's echo lasts one pulse length: no warning."""
    sc = scene(400.0).replace(platform=Platform(speed=5.0), targets=(PointTargets([[3.0, 0.0, 0.0]]),))
    with warnings.catch_warnings():
        warnings.simplefilter("error", SamplingWarning)
        clsas.simulate(sc, backend="numpy", progress=False)


@pytest.mark.parametrize("speed", [100.01, 1500.0, 2000.0])
def test_platform_speed_far_below_the_sound_speed(speed):
    with pytest.raises(ValueError, match=r"Platform\.speed: must be in \(0, 100\] m/s \(far below the sound speed\)"):
        Platform(speed=speed)


def test_grid_outside_the_swath_warns_on_both_backends(opencl_device):
    echo = clsas.range_compress(clsas.simulate(scene(10.0), backend="numpy", progress=False))
    far = Grid.plane([500.0, 501.0], [0.0], 0.0)
    for backend in ("numpy", "opencl"):
        with pytest.warns(CoverageWarning, match="all zeros"):
            image = clsas.backproject(echo, far, backend=backend, progress=False)
        assert not np.any(image.data)


def test_non_finite_records_are_refused():
    echo = clsas.simulate(scene(10.0), backend="numpy", progress=False)
    data = echo.data.copy()
    data[0, 1, 2] = np.nan
    with pytest.raises(ValueError, match="EchoData.data: must be finite"):
        echo.replace(data=data)


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64, np.complex64, np.complex128])
def test_all_finite_is_exact_near_each_types_largest_value(dtype):
    """Finite values whose sum overflows their type (or float64) are finite; one NaN or inf
    anywhere is not, in every float type: the one-pass sum must not answer for the elements."""
    big = np.finfo(dtype).max
    with np.errstate(over="ignore"):
        assert validate.all_finite(np.full(7, big, dtype))
        assert validate.all_finite(np.array([big, -big, big], dtype)[::2])  # a strided view
    for bad in (np.nan, np.inf, -np.inf):
        data = np.ones(1001, dtype)
        data[517] = bad
        assert not validate.all_finite(data)
        if np.dtype(dtype).kind == "c":
            data = np.ones(1001, dtype)
            data[3] = complex(1.0, bad)
            assert not validate.all_finite(data)


def test_an_overflowing_image_raises(opencl_device):
    """Finite records near complex64's largest value sum past it: both backends raise instead of
    returning inf."""
    echo = clsas.range_compress(clsas.simulate(scene(10.0), backend="numpy", progress=False))
    huge = echo.replace(data=(echo.data / np.abs(echo.data).max() * np.float32(3e38)).astype(np.complex64))
    grid = Grid.plane(np.linspace(29.5, 30.5, 5), [0.0], 0.0)  # a pixel on the target at 30 m: 6 pulses sum past the max
    for backend in ("numpy", "opencl"):
        with pytest.raises(ValueError, match="backproject: the image overflows complex64"):
            clsas.backproject(huge, grid, backend=backend, progress=False)
