"""The FIR upsampler of back-projection's records (clsas.image.upsample): kernel vs NumPy twin,
span independence, its departure from exact band-limited (FFT) upsampling, and its use by
clsas.image.backprojection.records."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from _tolerances import rel_l2

import clsas
from clsas.errors import MemoryBudgetError
from clsas.image import upsample as fir
from clsas.image.backprojection import GridPlan, backproject, prepare
from clsas.image.backprojection import records as records_module
from clsas.image.rangecomp import _upsample_spectrum, upsample_records
from clsas.model import Grid
from clsas.scene import presets


@pytest.fixture(scope="module")
def huang_echo():
    """Huang & Yang 2022's sonar (fs = 1.25 B: the FIR's band edge), range-compressed."""
    scene = presets.point_scene("huang2022", n_pulses=16)
    return clsas.range_compress(clsas.simulate(scene, backend="opencl", progress=False))


def noise(rng, rows, n):
    return (rng.standard_normal((rows, n)) + 1j * rng.standard_normal((rows, n))).astype(np.complex64)


def band_limited(rng, rows, n, band):
    """Complex noise with no energy beyond |f| > ``band`` cycles a sample."""
    spec = np.fft.fft(noise(rng, rows, n), axis=1)
    spec[:, np.abs(np.fft.fftfreq(n)) > band] = 0
    return np.fft.ifft(spec, axis=1).astype(np.complex64)


# ---------------------------------------------------------------- kernel vs twin

@pytest.mark.parametrize("factor", [2, 3, 5, 6, 8, 64])
@pytest.mark.parametrize("span", [(0, 203), (3, 200), (190, 203), (0, 5)])
def test_kernel_matches_its_twin(opencl_device, rng, factor, span):
    """Every output within float32 rounding of the twin (measured <= 9.4e-8 relative L2 and
    9.6e-7 largest difference on unit-variance noise), edges and partial blocks included."""
    records = noise(rng, 5, 203)
    got = fir.upsample_fir(records, factor, *span)
    ref = fir.upsample_reference(records, factor, *span)
    assert got.shape == ref.shape == (5, (span[1] - span[0]) * factor) and got.dtype == np.complex64
    assert rel_l2(got, ref) < 1e-6
    assert np.max(np.abs(got - ref)) < 1e-5


@pytest.mark.parametrize("factor", [2, 3, 5, 8])
def test_every_mirrored_pass_width_gives_the_same_samples(opencl_device, rng, factor):
    """The mirrored pass built with 1, 2 and 4 pairs a pass (the target picks 4 on AVX-512 and 2
    on AVX2, so one machine's default runs only one of them): the same sums in the same order,
    hence the same samples bit for bit, and each within float32 rounding of the twin."""
    records = noise(rng, 3, 61)
    ref = fir.upsample_reference(records, factor, 2, 59)
    got = {n: fir.upsample_fir(records, factor, 2, 59, mirror_pass=n) for n in fir.MIRROR_PASSES}
    for n, samples in got.items():
        assert np.array_equal(samples, got[4]), n
        assert rel_l2(samples, ref) < 1e-6, n
    with pytest.raises(ValueError, match="mirror_pass: must be one of"):
        fir.upsample_fir(records, factor, 2, 59, mirror_pass=3)


@pytest.mark.parametrize("implementation", ["kernel", "twin"])
def test_any_span_gives_the_same_samples(opencl_device, rng, implementation):
    """An output depends on the samples around it only: a span's samples are the whole record's,
    bit for bit, and phase 0 is the record itself."""
    run = fir.upsample_fir if implementation == "kernel" else fir.upsample_reference
    records = noise(rng, 3, 150)
    whole = run(records, 8, 0, 150)
    for first, stop in ((1, 149), (13, 14), (141, 150), (0, 9)):
        assert np.array_equal(run(records, 8, first, stop), whole[:, 8 * first:8 * stop])
    assert np.array_equal(whole[:, ::8], records)


# ---------------------------------------------------------------- departure from band-limited upsampling

def test_tone_departure_within_the_band():
    """The design bound (module docstring): per unit tone within |f| <= 0.4 cycles a sample, at
    most 3.2e-4 (measured 3.1e-4 at x8), a quarter of the linear interpolator's own x8 error
    ((2 pi 0.4 / 8)^2 / 8 = 1.2e-2) being the requirement; smaller at narrower bands."""
    linear_own = (2 * np.pi * 0.4 / 8) ** 2 / 8
    for factor in (4, 8, 16):
        assert fir.worst_tone_error(factor) < 3.2e-4 < linear_own / 4
    assert fir.worst_tone_error(8, band=0.25) < 1.5e-4  # measured 9.4e-5 (fs = 2 B)


def test_departure_on_band_limited_records(rng):
    """A record band-limited to 0.4 cycles a sample as a periodic sequence, tiled three times, its
    middle copy FIR-upsampled against its exact periodic (FFT) upsampling: measured 7.0e-5
    relative L2."""
    n = 512
    records = band_limited(rng, 8, n, fir.MAX_BAND)
    exact = 8 * np.fft.ifft(_upsample_spectrum(np.fft.fft(records, axis=1), 8), axis=1)
    got = fir.upsample_reference(np.tile(records, (1, 3)), 8, n, 2 * n)
    assert rel_l2(got, exact) < 7e-4


def test_departure_on_simulated_records(huang_echo):
    """Range-compressed chirp echoes at fs = 1.25 B also hold a little energy beyond B / 2 (the
    spectral skirts), which the FIR passes less faithfully than one whole-record FFT: measured
    2.4e-3 relative L2, under the 3e-3 the records' design allows and under half the linear
    interpolator's own error at mid-sample on the same x8 records (5.2e-3)."""
    records = huang_echo.data[0]
    exact = upsample_records(records, 8)
    departure = rel_l2(fir.upsample_reference(records, 8, 0, records.shape[1]), exact)
    fine = upsample_records(records, 16)
    mid, linear = fine[:, 1:-2:2], 0.5 * (exact[:, :-1] + exact[:, 1:])
    assert departure < 3e-3
    assert departure < 0.5 * rel_l2(linear, mid)


# ---------------------------------------------------------------- bad input

def test_bad_input(rng):
    records = noise(rng, 2, 40)
    with pytest.raises(TypeError, match="records"):
        fir.upsample_reference(records.real, 8, 0, 40)
    with pytest.raises(TypeError, match="records"):
        fir.upsample_reference([[1j, 2j]], 8, 0, 2)
    for factor in (1, 65):
        with pytest.raises(ValueError, match="factor"):
            fir.upsample_reference(records, factor, 0, 40)
    with pytest.raises(TypeError, match="factor"):
        fir.upsample_reference(records, 8.0, 0, 40)
    for first, stop in ((5, 5), (-1, 4), (0, 41)):
        with pytest.raises(ValueError, match="first, stop"):
            fir.upsample_reference(records, 8, first, stop)
    with clsas.use_memory_budget("1M"), pytest.raises(MemoryBudgetError, match="upsample"):
        fir.upsample_reference(noise(rng, 64, 400), 8, 0, 400)


# ---------------------------------------------------------------- back-projection's records

def test_records_choose_their_upsampler(huang_echo):
    """The FIR for records sampled at fs >= 1.25 B, block FFTs nearer the Nyquist rate (Kiang &
    Kiang's fs = B), nothing for sinc8 or upsample=1."""
    assert prepare(huang_echo, grid=(0.05, 0.06)).upsampler == "fir"
    critical = huang_echo.replace(waveform=dataclasses.replace(huang_echo.waveform, bandwidth=huang_echo.fs))
    assert prepare(critical, grid=(0.05, 0.06)).upsampler == "fft"
    assert prepare(huang_echo, interp="sinc8").upsampler is None
    assert prepare(huang_echo, upsample=1).upsampler is None


@pytest.mark.parametrize("default", ["numpy", "opencl"])
def test_prepared_fir_records_give_the_identical_image(opencl_device, huang_echo, backend, default):
    """Whichever backend upsamples (the default one) and whichever back-projects, records prepared
    once (whole or for the grid) give a plain call's image bit for bit; on the OpenCL default the
    plain OpenCL call upsamples on the device into device buffers, and those samples are the
    host's."""
    grid = Grid.plane(np.linspace(57.0, 63.0, 24), np.linspace(-3.0, 3.0, 20), 0.0)
    kw = dict(backend=backend, progress=False)
    with clsas.use_backend(default):
        plain = backproject(huang_echo, grid, **kw)
        whole = prepare(huang_echo)
        patch = prepare(huang_echo, grid=grid)
        assert whole.upsampler == "fir" and whole.fir_on_device == (default == "opencl")
        assert np.all(patch.length < whole.length)
        for records in (whole, patch):
            assert np.array_equal(backproject(records, GridPlan(grid), **kw).data, plain.data)


def test_fir_image_close_to_the_fft_image(opencl_device, huang_echo, monkeypatch):
    """A patch around a target imaged from FIR-upsampled records against records upsampled by one
    FFT of each whole record: measured 2.9e-3 relative L2 here (8 receivers, 16 pulses; 9.8e-3
    with all 32, 2.2e-3 on a finer 128^2 grid of 64 pulses), below the linear interpolator's own
    x8 error on the same patch (x8 against x64, both by FFT: 5.0e-3 here, 1.19e-2 with 32). The departure is the FIR's, not the interpolator's
    (x64 FIR records depart from x64 FFT ones alike), and it sits in the records' energy beyond
    B / 2: measured once, FIR and FFT images of the finer patch lie equally far (2.77e-2) from the
    image of the same scene simulated at 4 fs."""
    grid = Grid.plane(np.linspace(57.0, 63.0, 64), np.linspace(-3.0, 3.0, 64), 0.0)
    kw = dict(backend="opencl", progress=False, receivers=range(8))
    image = backproject(huang_echo, grid, **kw).data
    monkeypatch.setattr(records_module, "upsampler_for", lambda echo, factor: None if factor == 1 else "fft")
    monkeypatch.setattr(records_module, "upsample_blocks", lambda block, factor, first, stop, workers=None:
                        upsample_records(block, factor)[:, factor * first:factor * stop])
    exact = backproject(huang_echo, grid, **kw).data
    finer = backproject(huang_echo, grid, upsample=64, **kw).data
    departure = rel_l2(image, exact)
    assert departure < 6e-3
    assert departure < rel_l2(exact, finer)


@pytest.mark.parametrize("factor", [2, 3, 4, 5, 7, 8])
def test_mirror_table_gives_the_direct_taps(factor):
    """The kernel's table for factors up to 8 (phases q and factor - q from one pass over sample
    pairs): S_q + D_q is phase q's tap t, S_q - D_q phase factor - q's, within float32 rounding of
    fir_taps (measured <= 3e-8 absolute on taps of at most 1); lanes of no phase are zero."""
    table = fir.mirror_vectors(factor).astype(np.float64)
    taps = fir.fir_taps(factor).astype(np.float64)
    half = fir.TAPS // 2
    for q in range(1, factor // 2 + 1):
        s, d = table[:, 2 * q], table[:, 2 * q + 1]
        assert np.max(np.abs((s + d) - taps[q, :half])) < 3e-7
        assert np.max(np.abs((s - d) - taps[q, fir.TAPS - 1:half - 1:-1])) < 3e-7
        assert np.max(np.abs((s + d) - taps[factor - q, fir.TAPS - 1:half - 1:-1])) < 3e-7
        assert np.max(np.abs((s - d) - taps[factor - q, :half])) < 3e-7
    assert not np.any(table[:, :2]) and not np.any(table[:, 2 * (factor // 2) + 2:])
    if factor % 2 == 0:
        assert not np.any(table[:, factor + 1])  # phase factor / 2 is its own mirror: no D
    with pytest.raises(ValueError, match="factor"):
        fir.mirror_vectors(9)
