"""Stolt mapping: the OpenCL kernel against its NumPy reference, and the map's own accuracy."""

from __future__ import annotations

import numpy as np
import pytest
from _band_limited import FS, band_limited
from _tolerances import rel_l2

from clsas.image.stolt import StoltAxes, stolt

C, F0 = 1500.0, 150e3


def axes(n_src=512, n_out=512):
    df = FS / n_src
    f_first = -FS / 2
    return StoltAxes(f_first=f_first, df=df, n_src=n_src, kx_first=4 * np.pi * f_first / C, dkx=4 * np.pi * df / C,
                     n_out=n_out, f0=F0, c=C)


@pytest.mark.parametrize("interp", ["linear", "sinc8", "sinc16"])
@pytest.mark.parametrize("window", ["kaiser", "knab"])
def test_kernel_matches_reference(opencl_device, rng, interp, window):
    spec = band_limited(rng, 48, 512)
    ku = np.linspace(-160.0, 160.0, 48)
    ax = axes(n_out=500)  # not a multiple of the kernel's 16 outputs a work-item
    ref = stolt(spec, ku, ax, interp, window, backend="numpy")
    out = stolt(spec, ku, ax, interp, window, backend="opencl")
    assert out.shape == ref.shape == (48, 500)
    assert np.count_nonzero(ref) > 0.5 * ref.size
    # float32 data and sums; the kernel's float index relative to its first lane is within
    # ~1e-6 sample of the reference's, which can move an output to the neighbouring tap row
    # (1/4096 sample apart): relative L2 well below 1e-4
    assert rel_l2(out, ref) < 1e-4
    assert np.array_equal(out == 0, ref == 0)


@pytest.mark.parametrize("interp", ["linear", "sinc8", "sinc16"])
def test_kernel_matches_reference_at_exact_integer_positions(opencl_device, rng, interp):
    """At k_u = 0 these axes map output column j onto source column j exactly, so every position
    is an integer up to rounding (double in one, float relative to the first lane in the other):
    both read it as that integer, so the edge columns that lack samples are the same in both."""
    spec = band_limited(rng, 3, 512)
    ku = np.array([0.0, 1e-3, 50.0])
    ref = stolt(spec, ku, axes(), interp, backend="numpy")
    out = stolt(spec, ku, axes(), interp, backend="opencl")
    assert np.array_equal(out == 0, ref == 0)
    assert rel_l2(out, ref) < 1e-4


def test_map_is_the_identity_at_zero_along_track_wavenumber(rng):
    """At k_u = 0 and dkx = 4 pi df / c the map reads source column j for output column j."""
    spec = band_limited(rng, 1, 512)
    out = stolt(spec, np.zeros(1), axes(), "sinc8", backend="numpy")
    inside = slice(4, 508)
    assert rel_l2(out[0, inside], spec[0, inside]) < 1e-6


# linear interpolation halfway between samples returns cos(pi nu) of the tone: error
# 1 - cos(pi nu) ~ (pi nu)^2 / 2 = 0.049 at nu = 0.1; the windowed sincs do far better
@pytest.mark.parametrize("interp,bound", [("linear", 0.05), ("sinc8", 3e-3), ("sinc16", 5e-4)])
def test_interpolators_resample_a_band_limited_tone(interp, bound):
    """A tone exp(j 2 pi nu idx) is resampled at the exact non-uniform source positions idx."""
    ax = axes()
    ku = np.array([0.0, 60.0, 150.0])
    nu = 0.1  # cycles a source column (a band of 20 % of the sampling rate)
    src = np.exp(2j * np.pi * nu * np.arange(ax.n_src))[None, :].repeat(3, axis=0)
    out = stolt(src, ku, ax, interp, backend="numpy")
    idx = ax.source_index(ku)
    want = np.exp(2j * np.pi * nu * idx)
    ok = out != 0
    assert ok.sum() > 0.8 * out.size
    assert np.max(np.abs(out[ok] - want[ok])) < bound


def test_bad_input(rng):
    spec = band_limited(rng, 4, 512)
    ku = np.zeros(4)
    with pytest.raises(ValueError, match="interp"):
        stolt(spec, ku, axes(), "cubic", backend="numpy")
    with pytest.raises(ValueError, match="window"):
        stolt(spec, ku, axes(), "sinc8", "hann", backend="numpy")
    with pytest.raises(ValueError, match="oversampling"):
        stolt(spec, ku, axes(), "sinc8", "knab", oversampling=1.0, backend="numpy")
    with pytest.raises(ValueError, match="spectrum"):
        stolt(spec[:, :100], ku, axes(), backend="numpy")
    with pytest.raises(ValueError, match="ku"):
        stolt(spec, np.zeros(3), axes(), backend="numpy")
    with pytest.raises(TypeError, match="axes"):
        stolt(spec, ku, {"df": 1.0}, backend="numpy")
    with pytest.raises(ValueError, match="out must be"):
        stolt(spec, ku, axes(), backend="numpy", out=np.zeros((4, 511), np.complex128))
    with pytest.raises(ValueError, match="out must be"):
        stolt(spec, ku, axes(), backend="numpy", out=np.zeros((4, 1024), np.complex128)[:, ::2])


@pytest.mark.parametrize("backend", ["numpy", "opencl"])
def test_result_written_into_a_given_output(request, rng, backend):
    """``out`` receives the result (every column, including a last partial block of the
    kernel's 64 outputs a work-item) and is returned; the wrong dtype for a backend is refused."""
    if backend == "opencl":
        request.getfixturevalue("opencl_device")
    spec = band_limited(rng, 6, 512)
    ku = np.linspace(-100.0, 100.0, 6)
    ax = axes(n_out=500)
    out = np.full((6, 500), np.nan, np.complex64)
    assert stolt(spec, ku, ax, "sinc8", backend=backend, out=out) is out
    assert rel_l2(out, stolt(spec, ku, ax, "sinc8", backend=backend)) < 1e-6
    if backend == "opencl":
        with pytest.raises(ValueError, match="complex64"):
            stolt(spec, ku, ax, "sinc8", backend=backend, out=np.zeros((6, 500), np.complex128))
