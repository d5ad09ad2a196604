"""Property tests (hypothesis): the kernels against their NumPy references on random small scenes,
and no NaN or inf out of finite input.

Each property draws a few dozen cases at most (``deadline=None``: OpenCL builds and the loaded CI
machine make single-case timings meaningless); the whole file stays within a few seconds of
CI time a property. The bounds are ~10x the largest error measured over randomised runs of
each property (figures in each test's docstring; CLSAS_PROPERTY_EXAMPLES=N repeats them).
"""

from __future__ import annotations

import importlib
import os
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import clsas
from clsas.pulse import KAISER_BETA_MAX, TAYLOR_NBAR_MAX, TAYLOR_SLL_MAX, WINDOWS, spectral_window
from clsas.scene.scenario import Array, Medium, Platform, PulseSchedule, SamplingWarning, Scenario, Waveform
from clsas.scene.targets import PointTargets

from _tolerances import phase_error, rel_l2

# CLSAS_PROPERTY_EXAMPLES=500 makes a longer, randomised soak of the same properties
SOAK = int(os.environ.get("CLSAS_PROPERTY_EXAMPLES", "0"))
stolt_module = importlib.import_module("clsas.image.stolt")  # clsas.image.stolt is also the function's name
interpolation = importlib.import_module("clsas.interp")

PROPERTY = settings(max_examples=SOAK or 12, deadline=None, derandomize=not SOAK, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@st.composite
def scenes(draw):
    """A small random scene: 1-3 receivers on a line array, 2-8 pulses, 1-4 point targets (some
    moving) 10-60 m away; omnidirectional elements (no along-track sampling rule applies)."""
    f0 = draw(st.floats(20e3, 150e3))
    bandwidth = f0 * draw(st.floats(0.05, 0.4))
    fs = bandwidth * draw(st.floats(1.0, 2.5))
    duration = draw(st.floats(max(0.5e-3, 4 / fs), 4e-3))  # at least four samples a pulse
    n_rx = draw(st.integers(1, 3))
    offsets = [[0.0, draw(st.floats(-2.0, 2.0)), 0.0] for _ in range(n_rx)]
    n_targets = draw(st.integers(1, 4))
    positions = [[draw(st.floats(10.0, 60.0)), draw(st.floats(-5.0, 5.0)), draw(st.floats(-20.0, 0.0))]
                 for _ in range(n_targets)]
    velocity = [draw(st.floats(-3.0, 3.0)), draw(st.floats(-3.0, 3.0)), 0.0]
    return Scenario(medium=Medium(draw(st.floats(1400.0, 1600.0))),
                    waveform=Waveform(f0=f0, bandwidth=bandwidth, duration=duration, fs=fs,
                                      chirp_sign=draw(st.sampled_from([1, -1]))),
                    platform=Platform(speed=draw(st.floats(0.2, 5.0))),
                    array=Array(rx_offsets=offsets),
                    schedule=PulseSchedule(prf=draw(st.floats(1.0, 20.0)), n_pulses=draw(st.integers(2, 8))),
                    targets=(PointTargets(positions, reflectivity=draw(st.floats(0.1, 10.0)),
                                          velocity=velocity if draw(st.booleans()) else (0.0, 0.0, 0.0)),))


def _simulate(scene, backend):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SamplingWarning)
        return clsas.simulate(scene, backend=backend, progress=False)


@PROPERTY
@given(scene=scenes())
def test_simulate_kernel_matches_reference(opencl_device, scene):
    """OpenCL echo synthesis (float32 accumulation, delays in double) against the float64 NumPy
    reference: largest relative L2 measured 3.7e-6 (median 1e-7) over the random scenes tried; bound 4e-5."""
    ref = _simulate(scene, "numpy")
    got = _simulate(scene, "opencl")
    assert got.data.shape == ref.data.shape
    np.testing.assert_array_equal(got.t0, ref.t0)
    assert np.all(np.isfinite(got.data))
    assert rel_l2(got.data, ref.data) < 4e-5


@PROPERTY
@given(scene=scenes(), interp=st.sampled_from(["linear", "sinc8"]), upsample=st.integers(1, 4),
       precision=st.sampled_from(["single", "double"]))
def test_backproject_kernel_matches_reference(opencl_device, scene, interp, upsample, precision):
    """Back-projection onto 8 x 8 pixels around a target, OpenCL against the NumPy reference:
    largest relative L2 measured over 77 random cases 1.9e-5 in single precision (the float32
    geometry's phase budget is 2e-3 rad by construction) and 5e-8 in double; phase at the peak
    at most 2e-5 rad. Bounds ~10x: 2e-4, 5e-7 and 2e-4 rad."""
    echo = clsas.range_compress(_simulate(scene, "numpy"))
    target = scene.targets[0].positions[0]
    grid = clsas.Grid.plane(target[0] + np.linspace(-0.5, 0.5, 8), target[1] + np.linspace(-0.5, 0.5, 8), target[2])
    kw = dict(interp=interp, upsample=upsample, progress=False, target_velocity=scene.targets[0].velocity[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", clsas.validate.CoverageWarning)
        ref = clsas.backproject(echo, grid, backend="numpy", **kw)
        got = clsas.backproject(echo, grid, backend="opencl", precision=precision, **kw)
    assert np.all(np.isfinite(got.data))
    if not np.any(ref.data):
        assert not np.any(got.data)
        return
    assert rel_l2(got.data, ref.data) < (2e-4 if precision == "single" else 5e-7)
    peak = np.unravel_index(np.argmax(np.abs(ref.data)), ref.shape)
    assert phase_error(got.data[peak], ref.data[peak]) < 2e-4


@st.composite
def stolt_cases(draw):
    n_ku = draw(st.integers(1, 6))
    n_src = draw(st.integers(16, 96))
    n_out = draw(st.integers(1, 96))
    c, f0 = 1500.0, draw(st.floats(20e3, 200e3))
    band = f0 * draw(st.floats(0.05, 0.4))
    df = band / n_src
    kx_first = 4 * np.pi * (-band / 2) / c + draw(st.floats(-1.0, 1.0))
    axes = stolt_module.StoltAxes(f_first=-band / 2, df=df, n_src=n_src, kx_first=kx_first,
                                  dkx=4 * np.pi * df / c * draw(st.floats(0.5, 2.0)), n_out=n_out, f0=f0, c=c)
    k0 = 2 * np.pi * f0 / c
    ku = np.array([draw(st.floats(-0.5 * k0, 0.5 * k0)) for _ in range(n_ku)])
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    spectrum = (rng.standard_normal((n_ku, n_src)) + 1j * rng.standard_normal((n_ku, n_src))).astype(np.complex64)
    return spectrum, ku, axes, draw(st.sampled_from(sorted(interpolation.INTERPOLATORS))), \
        draw(st.sampled_from(interpolation.TAP_WINDOWS))


@PROPERTY
@given(case=stolt_cases())
def test_stolt_kernel_matches_reference(opencl_device, case):
    """The Stolt map on random rows and axes, OpenCL against NumPy. The rows are white noise (the
    whole band, the interpolators' worst case), so where a position's float32 rounding picks the
    neighbouring tap row (1/4096 sample apart) that output moves by up to ~1e-3 of itself: relative
    L2 measured over 500 cases median 4e-7, 99th percentile 1.3e-4, largest 5.7e-4 (a sinc8 Knab
    map onto 23 columns); bound 5e-3."""
    spectrum, ku, axes, interp, window = case
    ref = stolt_module.stolt(spectrum, ku, axes, interp, window, backend="numpy")
    got = stolt_module.stolt(spectrum, ku, axes, interp, window, backend="opencl")
    assert got.shape == ref.shape == (ku.size, axes.n_out)
    assert np.all(np.isfinite(got))
    if np.any(ref):
        assert rel_l2(got, ref) < 5e-3
    else:
        assert not np.any(got)


@PROPERTY
@given(rows=st.integers(1, 5), n=st.integers(16, 80), m=st.integers(1, 64), shared=st.booleans(),
       interp=st.sampled_from(sorted(interpolation.INTERPOLATORS)), seed=st.integers(0, 2**32 - 1))
def test_resample_kernel_matches_reference(opencl_device, rows, n, m, shared, interp, seed):
    """Rows read at random positions (some outside the row: they read zero), OpenCL against NumPy:
    largest relative L2 measured over 200 cases 6.3e-7; bound 6e-6."""
    rng = np.random.default_rng(seed)
    src = (rng.standard_normal((rows, n)) + 1j * rng.standard_normal((rows, n))).astype(np.complex64)
    idx = rng.uniform(-4, n + 4, m if shared else (rows, m))
    ref = interpolation.resample(src, idx, interp, backend="numpy")
    got = interpolation.resample(src, idx, interp, backend="opencl")
    assert np.all(np.isfinite(got))
    if np.any(ref):
        assert rel_l2(got, ref) < 6e-6


@settings(max_examples=60, deadline=None, derandomize=True)
@given(window=st.sampled_from(WINDOWS), nbar=st.integers(1, TAYLOR_NBAR_MAX), sll=st.floats(0.1, TAYLOR_SLL_MAX),
       beta=st.floats(0.0, KAISER_BETA_MAX), u=st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=32))
def test_windows_are_finite_and_peak_at_one(window, nbar, sll, beta, u):
    """Any window with any allowed option: finite, 1 at u = 0, within [0, 1] on the band, 0 off it
    (Taylor designs that would leave [0, 1] are refused, naming taylor_nbar)."""
    u = np.array(u + [0.0])
    try:
        w = spectral_window(u, window, taylor_nbar=nbar, taylor_sll_db=sll, kaiser_beta=beta)
    except ValueError as err:
        assert window == "taylor" and "taylor_nbar" in str(err) and "no window" in str(err)
        return
    assert np.all(np.isfinite(w))
    assert w[-1] == pytest.approx(1.0, rel=1e-9)
    if window != "none":
        assert np.all(w[np.abs(u) > 0.5] == 0)
        assert np.all(w >= -1e-9) and np.all(w <= 1 + 1e-9)


@st.composite
def echoes(draw):
    """A raw echo of random finite samples over 40 orders of magnitude."""
    n_rx, n_p, n = draw(st.integers(1, 2)), draw(st.integers(1, 4)), draw(st.integers(1, 200))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = 10.0 ** draw(st.floats(-20, 30))
    data = (scale * (rng.standard_normal((n_rx, n_p, n)) + 1j * rng.standard_normal((n_rx, n_p, n)))).astype(
        np.complex64)
    wf = Waveform(f0=50e3, bandwidth=10e3, duration=draw(st.floats(1e-4, 5e-3)), fs=draw(st.floats(10e3, 40e3)))
    eta = np.arange(n_p) / 10.0
    tx = np.column_stack([np.zeros(n_p), eta, np.zeros(n_p)])
    return clsas.EchoData(data=data, eta=eta, t0=np.full(n_rx, 0.01), fs=wf.fs, tx_pos=tx,
                          rx_pos=np.broadcast_to(tx[None, :, None, :], (n_rx, n_p, 1, 3)), rx_tau=np.zeros((n_rx, 1)),
                          waveform=wf, medium=Medium(), receivers=tuple(f"r{h}" for h in range(n_rx)))


@settings(max_examples=40, deadline=None, derandomize=True)
@given(echo=echoes(), window=st.sampled_from(WINDOWS), upsample=st.integers(1, 4),
       beta=st.floats(0.0, KAISER_BETA_MAX), nbar=st.integers(1, 20))
def test_range_compress_of_finite_input_is_finite_or_refused(echo, window, upsample, beta, nbar):
    """Finite input gives finite output, or (when complex64 would overflow) a ValueError that says so."""
    try:
        out = clsas.range_compress(echo, window=window, upsample=upsample, kaiser_beta=beta, taylor_nbar=nbar)
    except ValueError as err:
        assert "overflows" in str(err) or (window == "taylor" and "no window" in str(err))
        return
    assert out.data.shape == echo.data.shape[:2] + (echo.n_samples * upsample,)
    assert np.all(np.isfinite(out.data))
